//! A machine builder's setup, on the real firmware: what differs from one
//! mill to the next is set over serial (`$` settings) and stored, with no
//! recompile.
//!
//! Normally-closed switches: every input of the virtual machine wired the
//! other way (`MachineConfig::inverted_inputs`), then `$5` tells the
//! firmware. Homing, hard limits, `M119`, `?`'s `Pn:`, the carousel's home
//! switch (a tool change) and the tool setter (`G37`) all read them right,
//! checked on the recorded steps.

mod common;
#[path = "common/panel.rs"]
mod panel;
use common::*;
use panel::{golden, press, screen, turn};
use sim::{AtcConfig, Axis, Input, OpticalBeam, Tool, ToolSetter, Vm, VmConfig};

/// Every switch normally-closed and the setter's output inverted: the
/// electrical level of each input is the opposite of the stock machine's.
fn inverted_machine() -> VmConfig {
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = 120.0;
    cfg.machine.inverted_inputs = 0b1_1111;
    cfg.machine.tool_setter = ToolSetter::Optical(OpticalBeam::demo());
    cfg
}

/// The inputs in M119's order.
const INPUTS: [Input; 5] = [Input::HomeX, Input::HomeY, Input::HomeZ, Input::CarouselHome, Input::ToolSetter];

/// M119's five lines as (name, triggered).
fn m119(vm: &mut Vm) -> Vec<(String, bool)> {
    ok(vm, "M119").iter().filter_map(|l| l.split_once(": ").map(|(n, v)| (n.to_string(), v == "TRIGGERED"))).collect()
}

#[test]
fn normally_closed_inputs_work_everywhere_once_dollar_5_says_so() {
    let mut vm = boot_with(inverted_machine());
    // As wired, with the stock setting, every input reads the opposite of
    // what it is: the switches untouched read triggered, the carousel's,
    // closed at home, reads open. The builder sees it in M119 and sets $5.
    let physical = |vm: &Vm| INPUTS.map(|i| vm.input_active(i)).to_vec();
    let before = m119(&mut vm);
    assert_eq!(before.len(), 5, "{before:?}");
    let truth = physical(&vm);
    assert_eq!(truth, [false, false, false, true, false], "the machine at power-on: only the carousel at home");
    assert_eq!(before.iter().map(|(_, t)| !*t).collect::<Vec<_>>(), truth, "with $5=0 every input reads inverted: {before:?}");

    ok(&mut vm, "$5=31");
    let after = m119(&mut vm);
    assert_eq!(after.iter().map(|(_, t)| *t).collect::<Vec<_>>(), truth, "with $5=31 each input reads as it is: {after:?}");
    assert!(!status(&mut vm).contains("Pn:X"), "{}", status(&mut vm));
    // Stored: M503 shows it, and it survives a power cycle.
    assert!(ok(&mut vm, "M503").iter().any(|l| l == "$5=31"));

    // Homing through the inverted switches ends 1 mm off each, as on the
    // stock machine.
    ok(&mut vm, "G28");
    assert_eq!(steps(&vm)[..3], [100, 100, 100]);

    // The carousel's home switch: a tool change homes the carousel, takes
    // T3 from its pocket, and the changer model sees no collision.
    ok(&mut vm, "T3 M6");
    assert_eq!(vm.atc().spindle.map(|t| t.id), Some(3));
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);

    // The tool setter: G37 measures T3 (the demo changer's tool n is
    // 18 + 1.5 n mm long, 1 + 0.5 n across) against the beam.
    let r = ok(&mut vm, "G37 L22.5 R1.25");
    assert!(r.iter().any(|l| l.starts_with("[SETTER Z:-48.0")), "{r:?}");

    // A hard limit: soft limits off, X driven into its switch. The switch
    // opens (an NC switch triggers by opening): the alarm stops X there.
    ok(&mut vm, "G53 G0 Z-1");
    ok(&mut vm, "G53 G0 X5 Y5");
    ok(&mut vm, "$20=0");
    vm.command("G53 G1 X-3 F600").unwrap();
    settle(&mut vm, 0.5);
    let s = status(&mut vm);
    assert!(s.starts_with("<Alarm"), "{s}");
    assert!(s.contains("Pn:X"), "the closed switch in Pn: {s}");
    let x = vm.position(Axis::X);
    assert!((-30..=5).contains(&x), "X stopped at the switch, not at the target: {x}");

    // After a power cycle the setting is still there.
    vm.power_cycle();
    settle(&mut vm, 0.5);
    ok(&mut vm, "M999");
    assert!(!vm.input_level(Input::HomeY), "the NC switch holds its pin low while untouched");
    let m = m119(&mut vm);
    let triggered: Vec<bool> = m.iter().map(|(_, t)| *t).collect();
    assert_eq!(triggered, physical(&vm), "after the power cycle each input still reads as it is: {m:?}");
}

#[test]
fn a_broken_wire_on_a_normally_closed_switch_reads_triggered() {
    // The X switch's wire cut: its pin floats high on the pull-up, as an
    // NC switch that opened. With $5 set for NC switches that reads
    // "triggered", and homing X finds its switch at once instead of
    // driving into the frame.
    let mut vm = boot_with(inverted_machine());
    ok(&mut vm, "$5=31");
    vm.set_input(Input::HomeX, Some(true));
    assert!(vm.input_level(Input::HomeX), "a cut wire: the pull-up holds the pin high");
    let m = m119(&mut vm);
    assert_eq!(m[0], ("x_min".to_string(), true), "{m:?}");
    let before = vm.position(Axis::X);
    let _ = vm.command("$HX");
    settle(&mut vm, 0.5);
    assert!(vm.position(Axis::X) >= before - 10, "X drove {} steps toward a switch that reads closed", before - vm.position(Axis::X));
}

/// The station moved, the carousel's motor turning the other way and its
/// pockets one pitch further round, every input the other way: the VM
/// built so, and the firmware told over serial with `$` commands only.
fn other_machine() -> VmConfig {
    let mut cfg = inverted_machine();
    cfg.machine.invert_dir_mask = 0b1000;
    let atc = &mut cfg.machine.atc;
    (atc.x1, atc.y_a, atc.y_b, atc.z1, atc.z2) = (3000, 2500, 4000, 3800, 4250);
    atc.pocket1_deg = 100.0;
    cfg
}

/// What the builder sends for [`other_machine`].
const OTHER_SETUP: [&str; 8] = ["$5=31", "$3=8", "$170=30", "$171=25", "$172=40", "$173=38", "$174=42.5", "$180=4"];

/// The shop's tool numbers: T20 in pocket 5, T7 in pocket 11, pocket 7
/// empty and without a number.
const TOOL_NUMBERS: [&str; 6] = ["G10 L1 P5 Q0", "G10 L1 P20 Q5", "G10 L1 P7 Q0", "G10 L1 P11 Q0", "G10 L1 P7 Q11", "M61 P7 S0"];

/// The VM's changer loaded as [`TOOL_NUMBERS`] says.
fn shop_tools(atc: &mut AtcConfig) {
    atc.pockets[4] = Some(Tool { id: 20, ..AtcConfig::default_tool(5) });
    atc.pockets[10] = Some(Tool { id: 7, ..AtcConfig::default_tool(11) });
    atc.pockets[6] = None;
}

/// The changer's physical state: the spindle's tool and every pocket's.
fn changer(vm: &Vm) -> (Option<u8>, Vec<Option<u8>>) {
    let a = vm.atc();
    (a.spindle.map(|t| t.id), a.pockets.iter().map(|p| p.map(|t| t.id)).collect())
}

#[test]
fn the_station_and_the_carousel_are_settings_and_a_moved_station_changes_tools() {
    let mut vm = boot_with(other_machine());
    for l in OTHER_SETUP {
        ok(&mut vm, l);
    }
    let m503 = ok(&mut vm, "M503");
    for want in ["$170=30.000", "$172=40.000", "$174=42.500", "$180=4.000"] {
        assert!(m503.iter().any(|l| l == want), "{want} in M503: {m503:?}");
    }
    ok(&mut vm, "G28");
    ok(&mut vm, "G0 X10 Y10");
    for (t, spindle) in [(3, Some(3)), (7, Some(7)), (0, None)] {
        ok(&mut vm, &format!("T{t} M6"));
        let (s, pockets) = changer(&vm);
        assert_eq!(s, spindle, "after T{t} M6");
        for (i, p) in pockets.iter().enumerate() {
            let here = Some(i as u8 + 1) != spindle;
            assert_eq!(p.is_some(), here, "pocket {} after T{t} M6: {pockets:?}", i + 1);
        }
        assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    }
    ok(&mut vm, "M400");
    // Back where the job was: X 10, Y 10 (machine Z at the travel height).
    assert_eq!(steps(&vm)[..2], [1000, 1000]);
    assert_eq!(vm.atc().transfers.len(), 4, "{:?}", vm.atc().transfers);
}

#[test]
fn station_settings_outside_the_travel_are_refused_naming_the_setting_and_the_limit() {
    let mut vm = boot();
    let eeprom = vm.eeprom();
    let e = refused(&mut vm, "$172=50");
    assert!(e.contains("$172 (tool change station) outside the Y travel 0..$131, nothing changed"), "{e}");
    for (bad, want) in [("$174=-1", "out of range"), ("$180=18", "out of range"), ("$176=0", "out of range"), ("$183=-2", "out of range")] {
        let e = refused(&mut vm, bad);
        assert!(e.contains(want), "{bad}: {e}");
    }
    assert_eq!(vm.eeprom(), eeprom, "nothing stored");
    let m503 = ok(&mut vm, "M503");
    assert!(m503.iter().any(|l| l == "$172=44.000"), "{m503:?}");
    // The travel made shorter under the station is taken (a machine
    // without a changer); a tool change then refuses to start.
    ok(&mut vm, "$131=40");
    let e = refused(&mut vm, "$172=41");
    assert!(e.contains("$172 (tool change station) outside the Y travel 0..$131"), "{e}");
    ok(&mut vm, "G28");
    let e = refused(&mut vm, "T1 M6");
    assert!(e.contains("tool change station outside travel"), "{e}");
}

#[test]
fn tool_numbers_are_not_pockets_a_shop_numbered_changer_runs_t20_t7_t0() {
    let mut cfg = other_machine();
    shop_tools(&mut cfg.machine.atc);
    let mut vm = boot_with(cfg);
    for l in OTHER_SETUP.iter().chain(TOOL_NUMBERS.iter()) {
        ok(&mut vm, l);
    }
    let m503 = ok(&mut vm, "M503");
    for want in ["G10 L1 P20 Q5", "G10 L1 P7 Q11", "G10 L1 P1 Q1"] {
        assert!(m503.iter().any(|l| l == want), "{want} in M503: {m503:?}");
    }
    assert!(!m503.iter().any(|l| l.ends_with(" Q7")), "pocket 7 has no number: {m503:?}");
    // Unknown tool numbers are refused before anything moves.
    ok(&mut vm, "G28");
    let before = steps(&vm);
    let e = refused(&mut vm, "T5 M6");
    assert!(e.contains("tool T5 not in the tool table: G10 L1 P5 Q<pocket> assigns it"), "{e}");
    let e = refused(&mut vm, "T99 M6");
    assert!(e.contains("T99"), "{e}");
    assert_eq!(steps(&vm), before);
    // The job.
    ok(&mut vm, "G0 X10 Y10");
    for (t, pocket) in [(20u8, 5usize), (7, 11), (0, 0)] {
        let r = ok(&mut vm, &format!("T{t} M6"));
        assert!(r.iter().any(|l| *l == format!("NowSelectedTool:{t}")), "T{t} M6: {r:?}");
        let (spindle, pockets) = changer(&vm);
        assert_eq!(spindle, (t != 0).then_some(t), "the VM's spindle after T{t} M6");
        if pocket != 0 {
            assert_eq!(pockets[pocket - 1], None, "pocket {pocket} empty while T{t} is in the spindle");
        }
        assert!(status(&mut vm).contains(&format!("T:{t}>")), "{}", status(&mut vm));
        assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    }
    let (_, pockets) = changer(&vm);
    assert_eq!((pockets[4], pockets[10], pockets[6]), (Some(20), Some(7), None), "{pockets:?}");
    ok(&mut vm, "M400");
    assert_eq!(steps(&vm)[..2], [1000, 1000]);
    // After a power cycle: still numbered, still set.
    vm.power_cycle();
    settle(&mut vm, 0.5);
    let m503 = ok(&mut vm, "M503");
    assert!(m503.iter().any(|l| l == "G10 L1 P20 Q5") && m503.iter().any(|l| l == "$170=30.000"), "{m503:?}");
}

/// Screen rows as one text, the word-wrapping undone.
fn words(s: &[String]) -> String {
    s.join(" ").split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The edit screen's Value row, as a number (`[ Value   23.000]`, `T20`).
fn value_shown(vm: &Vm) -> f64 {
    let row = screen(vm)[5].trim_matches(|c| c == '[' || c == ']').to_string();
    let v = row.split_whitespace().last().unwrap_or_else(|| panic!("{row}"));
    if v == "none" {
        return 0.0;
    }
    v.trim_start_matches('T').parse().unwrap_or_else(|_| panic!("value row {row:?}"))
}

/// On an edit screen, the Value entry selected: turn it to `to` (tenths
/// with the step 0.1) and save; returns the reply screen.
fn edit_and_save(vm: &mut Vm, to: f64) -> Vec<String> {
    let delta = ((to - value_shown(vm)) * 10.0).round() as i32;
    let (whole, tenths) = (delta / 10, delta % 10);
    if whole != 0 {
        press(vm);
        turn(vm, whole);
        press(vm);
    }
    if tenths != 0 {
        // The step: 1 → 10 → 100 → 1000 → 0.001 → 0.01 → 0.1.
        turn(vm, 1);
        for _ in 0..6 {
            press(vm);
        }
        assert!(screen(vm)[6].contains("0.100"), "{:?}", screen(vm));
        turn(vm, -1);
        press(vm);
        turn(vm, tenths);
        press(vm);
    }
    assert!((value_shown(vm) - to).abs() < 1e-6, "{to}: {:?}", screen(vm));
    turn(vm, 2);
    press(vm);
    vm.run_for(0.5).unwrap();
    screen(vm)
}

/// The Settings list open, `at` its selected entry: edit `$n` to `v`, check
/// the reply, and come back to the list (now on `$n`'s entry).
fn set_from_menu(vm: &mut Vm, at: &mut i32, n: u8, v: f64) {
    let entry = (0..mill::dollar::count()).position(|i| mill::dollar::nth(i) == n).unwrap() as i32 + 1;
    turn(vm, entry - *at);
    press(vm);
    assert_eq!(screen(vm)[0], format!("[ ${n}]"), "{:?}", screen(vm));
    let r = edit_and_save(vm, v);
    assert_eq!(r[0], "[ Settings]", "{r:?}");
    let want = if v.fract() == 0.0 && (n == 3 || n == 5) { format!("{v}") } else { format!("{v:.3}") };
    assert!(r[2].starts_with(&format!(" ${n} ")) && r[2].ends_with(&format!(" {want}")), "${n}={v}: {r:?}");
    press(vm); // back to the edit screen
    turn(vm, -1);
    press(vm); // the list, on $n
    *at = entry;
}

/// In Tools › Tool numbers, `at` the selected entry: give pocket `p` tool
/// number `t` (0 = none); returns the reply screen, back on the list.
fn number_from_menu(vm: &mut Vm, at: &mut i32, p: i32, t: f64) -> Vec<String> {
    turn(vm, p - *at);
    press(vm);
    assert_eq!(screen(vm)[0], format!("[ Pocket {p}]"), "{:?}", screen(vm));
    let r = edit_and_save(vm, t);
    press(vm);
    turn(vm, -1);
    press(vm);
    *at = p;
    r
}

/// The machine of `the_station_and_the_carousel…` and the shop's tool
/// numbers, set up with the encoder alone: every `$` value on Settings,
/// the numbers on Tools › Tool numbers. After a power cycle everything is
/// still set, and the job with T20, T7 and T0 runs.
#[test]
fn the_same_setup_from_the_menu_with_the_encoder_survives_a_power_cycle() {
    let mut cfg = other_machine();
    shop_tools(&mut cfg.machine.atc);
    // Pocket 7 keeps its tool, without a number (the menu has no M61 P S).
    cfg.machine.atc.pockets[6] = Some(Tool { id: 107, ..AtcConfig::default_tool(7) });
    let mut vm = boot_with(cfg);
    vm.run_for(0.5).unwrap();
    // Menu › Settings.
    press(&mut vm);
    turn(&mut vm, 6);
    press(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[0..3], ["[ Settings]", "[ < Back]", " $3                 0"], "{s:?}");
    golden(&vm, "settings_list");
    let mut at = 0;
    for (n, v) in [(5, 31.0), (3, 8.0), (170, 30.0), (171, 25.0), (172, 40.0), (173, 38.0), (174, 42.5), (180, 4.0)] {
        set_from_menu(&mut vm, &mut at, n, v);
        if n == 174 {
            // The list shows the stored value.
            assert_eq!(screen(&vm).iter().filter(|l| l.starts_with("[ $174")).count(), 1, "{:?}", screen(&vm));
        }
    }
    // A station point outside the travel: refused, named, nothing stored.
    let eeprom = vm.eeprom();
    let entry = (0..mill::dollar::count()).position(|i| mill::dollar::nth(i) == 172).unwrap() as i32 + 1;
    turn(&mut vm, entry - at);
    press(&mut vm);
    golden(&vm, "settings_edit");
    let r = edit_and_save(&mut vm, 50.0);
    assert!(words(&r[2..7]).contains("tool change station point outside the travel"), "{r:?}");
    assert_eq!(vm.eeprom(), eeprom, "nothing stored");
    press(&mut vm);
    turn(&mut vm, -1);
    press(&mut vm);
    at = entry;
    turn(&mut vm, -at);
    press(&mut vm); // < Back: the main menu, on Settings
                    // Tools › Tool numbers: T20 in pocket 5, pocket 7 without a number,
                    // T7 in pocket 11.
    turn(&mut vm, -1);
    press(&mut vm);
    turn(&mut vm, 7);
    press(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[0..3], ["[ Tool numbers]", "[ < Back]", " Pocket 1          T1"], "{s:?}");
    let mut at = 0;
    let r = number_from_menu(&mut vm, &mut at, 5, 20.0);
    assert_eq!(r[2], " Pocket 5         T20", "{r:?}");
    // T20 a second time: refused, pocket 11 keeps its number.
    let r = number_from_menu(&mut vm, &mut at, 11, 20.0);
    assert!(words(&r[2..7]).contains("another pocket"), "{r:?}");
    let r = number_from_menu(&mut vm, &mut at, 7, 0.0);
    assert_eq!(r[2], " Pocket 7        none", "{r:?}");
    let r = number_from_menu(&mut vm, &mut at, 11, 7.0);
    assert_eq!(r[2], " Pocket 11         T7", "{r:?}");
    golden(&vm, "tool_numbers");
    // After a power cycle: everything still set, on the screen and in M503.
    vm.power_cycle();
    vm.run_for(1.0).unwrap();
    vm.take_lines();
    let list = ok(&mut vm, "$$");
    for want in ["$5=31", "$3=8", "$170=30.000", "$171=25.000", "$172=40.000", "$173=38.000", "$174=42.500", "$180=4.000"] {
        assert!(list.iter().any(|l| l.starts_with(&format!("{want} "))), "{want} in $$: {list:?}");
    }
    let m503 = ok(&mut vm, "M503");
    for want in ["G10 L1 P20 Q5", "G10 L1 P7 Q11"] {
        assert!(m503.iter().any(|l| l == want), "{want} in M503: {m503:?}");
    }
    assert!(!m503.iter().any(|l| l.ends_with(" Q7") || l.starts_with("G10 L1 P11 ")), "pocket 7 without a number, T11 gone: {m503:?}");
    // The job: homes through the NC switches and changes T20, T7, T0 at the
    // moved station with the carousel reversed.
    ok(&mut vm, "G28");
    ok(&mut vm, "G0 X10 Y10");
    for (t, pocket) in [(20u8, 5usize), (7, 11), (0, 0)] {
        ok(&mut vm, &format!("T{t} M6"));
        let (spindle, pockets) = changer(&vm);
        assert_eq!(spindle, (t != 0).then_some(t), "the VM's spindle after T{t} M6");
        if pocket != 0 {
            assert_eq!(pockets[pocket - 1], None, "pocket {pocket} empty while T{t} is in the spindle");
        }
        assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    }
    let (_, pockets) = changer(&vm);
    assert_eq!((pockets[4], pockets[10], pockets[6]), (Some(20), Some(7), Some(107)), "{pockets:?}");
    ok(&mut vm, "M400");
    assert_eq!(steps(&vm)[..2], [1000, 1000]);
}

#[test]
fn tool_numbers_that_clash_are_refused_and_nothing_is_stored() {
    let mut vm = boot();
    let eeprom = vm.eeprom();
    for (line, want) in [
        ("G10 L1 P20 Q5", "that pocket holds another tool"),
        ("G10 L1 P3 Q5", "that pocket holds another tool"),
        ("G10 L1 P20 Q13", "G10 L1 P<tool 1-254> Q<pocket 1-12"),
        ("G10 L1 P255 Q1", "G10 L1 P<tool 1-254>"),
        ("G10 L1 P0 Q1", "G10 L1 P<tool 1-254>"),
        ("G10 L1 P2.5 Q1", "G10 L1 P<tool 1-254>"),
    ] {
        let e = refused(&mut vm, line);
        assert!(e.contains(want), "{line}: {e}");
    }
    // Freed, pocket 5 takes T20; T20 cannot then go to a second pocket.
    ok(&mut vm, "G10 L1 P5 Q0");
    ok(&mut vm, "G10 L1 P20 Q5");
    ok(&mut vm, "G10 L1 P9 Q0");
    let e = refused(&mut vm, "G10 L1 P20 Q9");
    assert!(e.contains("that tool is in another pocket"), "{e}");
    assert_ne!(vm.eeprom(), eeprom);
    let stored = vm.eeprom();
    let e = refused(&mut vm, "T5 M6");
    assert!(e.contains("T5 not in the tool table"), "{e}");
    assert_eq!(vm.eeprom(), stored, "a refused line stores nothing");
}

/// The first step of any axis after `cycle`.
fn first_step_after(vm: &Vm, cycle: u64) -> u64 {
    vm.recorder().trace().iter().find(|t| t.cycle > cycle).map(|t| t.cycle).expect("a step after it")
}

#[test]
fn the_spindle_waits_its_spin_up_and_spin_down_and_keeps_its_minimum_speed() {
    let mut vm = boot();
    let hz = f64::from(vm.frequency());
    for l in ["$31=3000", "$181=1.5", "$182=0.8", "G28"] {
        ok(&mut vm, l);
    }
    // S1000 is below $31: the spindle runs at 3000 rpm of $30's 10300.
    ok(&mut vm, "M3 S1000");
    ok(&mut vm, "G1 X10 F600");
    ok(&mut vm, "M400");
    let &(on, duty) = vm.spindle_history().iter().rev().find(|(_, d)| *d > 0.0).expect("spindle on");
    assert!((duty - 3000.0 / 10300.0).abs() < 0.01, "duty {duty}");
    let waited = (first_step_after(&vm, on) - on) as f64 / hz;
    assert!(waited >= 1.5, "the move started {waited:.3} s after M3, before the spin-up ($181=1.5)");
    // M5: the next move waits the spin-down.
    ok(&mut vm, "M5");
    ok(&mut vm, "G1 X5");
    ok(&mut vm, "M400");
    let &(off, _) = vm.spindle_history().last().unwrap();
    let waited = (first_step_after(&vm, off) - off) as f64 / hz;
    assert!(waited >= 0.8, "the move started {waited:.3} s after M5 ($182=0.8)");
    // A tool change with the spindle on: it stops, and the changer's first
    // move waits the spin-down.
    ok(&mut vm, "M3 S8000");
    ok(&mut vm, "T2 M6");
    let &(off, _) = vm.spindle_history().iter().rev().find(|(_, d)| *d == 0.0).unwrap();
    let waited = (first_step_after(&vm, off) - off) as f64 / hz;
    assert!(waited >= 0.8, "the tool change moved {waited:.3} s after stopping the spindle");
    assert_eq!(vm.atc().spindle.map(|t| t.id), Some(2));
    // Values out of range are refused.
    for bad in ["$31=20000", "$181=-1", "$182=61"] {
        let e = refused(&mut vm, bad);
        assert!(e.contains("out of range"), "{bad}: {e}");
    }
}

/// Steps inside the keep-out zone of `$183=10` (X 13–33, Y past 28, deeper
/// than 1 mm below the top; the VM counts steps from each switch, where
/// machine 0 is), outside the cycle windows given (the tool changes).
fn steps_in_keep_out(vm: &Vm, allowed: &[(u64, u64)]) -> Vec<[i64; 4]> {
    let mut inside = Vec::new();
    vm.recorder().for_each_step(|p| {
        let [x, y, z, _] = p.position;
        let zone = x > 1300 && x < 3300 && y > 2800 && z > 100;
        if zone && !allowed.iter().any(|&(a, b)| (a..=b).contains(&p.cycle)) {
            inside.push(p.position);
        }
    });
    inside
}

#[test]
fn no_ordinary_move_enters_the_tool_magazine_and_a_tool_change_still_does() {
    let mut vm = boot();
    // Off by default ($183=0): the same move goes in.
    ok(&mut vm, "G28");
    ok(&mut vm, "G0 X23 Y42");
    ok(&mut vm, "G0 Z-44");
    ok(&mut vm, "M400");
    assert!(!steps_in_keep_out(&vm, &[]).is_empty());
    vm.power_cycle();
    settle(&mut vm, 0.5);
    ok(&mut vm, "$183=10");
    ok(&mut vm, "G28");
    let homed_at = vm.cycles();
    // The example: over the magazine at the top, then down.
    ok(&mut vm, "G0 X23 Y42");
    ok(&mut vm, "M400");
    let before = steps(&vm);
    let e = refused(&mut vm, "G0 Z-44");
    assert!(e.contains("keep-out zone ($183, $184), nothing moved"), "{e}");
    assert_eq!(steps(&vm), before);
    ok(&mut vm, "G0 Y10");
    ok(&mut vm, "G0 Z-10");
    ok(&mut vm, "M400");
    // A line across it, an arc and a drilling cycle reaching into it.
    let before = steps(&vm);
    for l in ["G1 X23 Y40 F1000", "G2 X23 Y30 I0 J10 F1000", "G81 X23 Y35 Z-12 R-8 F200", "G80"] {
        let r = vm.command(l).unwrap();
        if l != "G80" {
            assert!(r.iter().any(|x| x.contains("keep-out")), "{l}: {r:?}");
        }
    }
    ok(&mut vm, "M400");
    assert_eq!(steps(&vm), before, "refused moves moved nothing");
    // A jog toward it stops at its edge (Y 28 - a step or two).
    ok(&mut vm, "$J=G91 Y30 F1000");
    ok(&mut vm, "M400");
    let y = steps(&vm)[1];
    assert!((2790..=2800).contains(&y), "the jog stopped at Y steps {y}, the zone starts past 2800");
    // The tool change goes in, as it must.
    let t0 = vm.cycles();
    ok(&mut vm, "T4 M6");
    let changes = vec![(0, homed_at), (t0, vm.cycles())];
    assert_eq!(vm.atc().spindle.map(|t| t.id), Some(4));
    assert!(vm.atc().collisions.is_empty());
    assert_eq!(steps_in_keep_out(&vm, &changes), Vec::<[i64; 4]>::new());
    assert!(!steps_in_keep_out(&vm, &[(0, homed_at)]).is_empty(), "the tool change itself is in the zone (the check can see it)");
}

#[test]
fn random_moves_around_and_through_the_magazine_never_enter_it() {
    let mut vm = boot();
    ok(&mut vm, "$183=10");
    ok(&mut vm, "G28");
    ok(&mut vm, "G0 Z-5");
    let mut rng = Rng(0x5eed_1234);
    let mut changes = Vec::new();
    let coord = |rng: &mut Rng, lo: f64, hi: f64| lo + (hi - lo) * f64::from(rng.next() % 10_000) / 10_000.0;
    let mut refused_n = 0;
    for i in 0..120 {
        let (x, y, z) = (coord(&mut rng, 2.0, 43.0), coord(&mut rng, 15.0, 44.0), -coord(&mut rng, 0.0, 30.0));
        let line = match rng.next() % 6 {
            0 => format!("G0 X{x:.3} Y{y:.3} Z{z:.3}"),
            1 => format!("G1 X{x:.3} Y{y:.3} F3000"),
            2 => format!("G2 X{x:.3} Y{y:.3} R{:.3} F3000", coord(&mut rng, 25.0, 40.0)),
            3 => format!("$J=G90 X{x:.3} Y{y:.3} F3000"),
            4 => format!("G81 X{x:.3} Y{y:.3} Z{:.3} R{:.3} F500\nG80", z - 1.0, z),
            _ => format!("G0 Z{z:.3}"),
        };
        for l in line.lines() {
            let before = steps(&vm);
            let r = vm.command(l).unwrap();
            ok(&mut vm, "M400");
            if r.iter().any(|x| x.contains("keep-out")) {
                refused_n += 1;
                assert_eq!(steps(&vm), before, "{l}: refused, yet moved");
            }
        }
        if i % 40 == 39 {
            let t0 = vm.cycles();
            ok(&mut vm, &format!("T{} M6", 1 + i / 40));
            changes.push((t0, vm.cycles()));
            assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
        }
    }
    assert!(refused_n >= 10, "only {refused_n} moves met the zone: the test does not reach it");
    assert_eq!(steps_in_keep_out(&vm, &changes), Vec::<[i64; 4]>::new());
}
