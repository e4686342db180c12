//! Tool changer (docs/SPEC.md §7) on the real firmware, checked against the virtual
//! machine's physical changer: which tool is really in the spindle and in
//! each pocket, every transfer, every collision, and the EEPROM records.

mod common;
use common::*;
use mill::atc::tools::{pocket_bit, Journal, ToolState, ALL_POCKETS, EEPROM_JOURNAL_ADDR, EEPROM_STATE_ADDR};
use sim::{Axis, Vm, VmConfig};

/// Steps per pocket pitch (3200 / 18), and the travel height, steps.
const PITCH: f64 = 3200.0 / 18.0;
const Z_SAFE: i64 = 100;

fn atc_vm() -> Vm {
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = 120.0;
    boot_with(cfg)
}

/// Tool changes in these tests are written `T<n> M6` (RS274/NGC, the
/// default since issue 13): a `T<n>` alone only selects the next tool.
/// Home X, Y, Z and move somewhere in the work area.
fn ready(vm: &mut Vm) {
    ok(vm, "G28");
    ok(vm, "G0 X10 Y5 Z-3");
    ok(vm, "M400");
}

/// The tool state and journal records in EEPROM.
fn records(vm: &Vm) -> (Option<ToolState>, Option<Journal>) {
    let e = vm.eeprom();
    let s = EEPROM_STATE_ADDR as usize;
    let j = EEPROM_JOURNAL_ADDR as usize;
    let st: [u8; 5] = e[s..s + 5].try_into().unwrap();
    let jb: [u8; 5] = e[j..j + 5].try_into().unwrap();
    (ToolState::from_bytes(&st), Journal::from_bytes(&jb))
}

fn spindle_id(vm: &Vm) -> u8 {
    vm.atc().spindle.map_or(0, |t| t.id)
}

/// The EEPROM record matches the physical changer exactly.
fn assert_records_match_the_machine(vm: &Vm) {
    let (st, j) = records(vm);
    let st = st.expect("a valid tool record");
    assert_eq!(j, None, "no change in progress");
    assert_eq!(st.spindle, spindle_id(vm), "spindle tool");
    for p in 1..=12u8 {
        assert_eq!(st.pocket_full(p), vm.atc().pocket(p).is_some(), "pocket {p}");
    }
}

/// One `?` status line.
fn status(vm: &mut Vm) -> String {
    vm.send("?");
    vm.wait_line(|l| l.starts_with('<'), 1.0).unwrap()
}

fn change(vm: &mut Vm, line: &str) -> Vec<String> {
    ok(vm, line)
}

#[test]
fn conditions_1_2_3_pick_change_and_empty_the_spindle() {
    let mut vm = atc_vm();
    ready(&mut vm);
    let before = steps(&vm);

    // Condition 1: empty spindle, T3.
    let r = change(&mut vm, "T3 M6");
    assert!(r.iter().any(|l| l == "SelectTool:3"), "{r:?}");
    assert!(r.iter().any(|l| l == "NowSelectedTool:3"), "{r:?}");
    assert_eq!(spindle_id(&vm), 3);
    assert_eq!(vm.atc().pocket(3), None);
    let t = vm.atc().transfers.clone();
    assert_eq!(t.len(), 1);
    assert!(t[0].to_spindle && t[0].tool == 3 && t[0].pocket == 3);
    // Back at the pre-change X/Y, at safe Z.
    let now = steps(&vm);
    assert_eq!((now[0], now[1], now[2]), (before[0], before[1], Z_SAFE));
    assert_records_match_the_machine(&vm);
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    let st = status(&mut vm);
    assert!(st.split(['|', '>']).any(|f| f == "T:3"), "{st}");

    // Condition 2: T3 in the spindle, T7 asked: T3 goes back first.
    let r = change(&mut vm, "M6 T7");
    assert!(r.iter().any(|l| l == "NowSelectedTool:7"), "{r:?}");
    let t = &vm.atc().transfers[1..];
    assert_eq!(t.len(), 2);
    assert!(!t[0].to_spindle && t[0].tool == 3 && t[0].pocket == 3, "{t:?}");
    assert!(t[1].to_spindle && t[1].tool == 7 && t[1].pocket == 7, "{t:?}");
    assert_eq!(spindle_id(&vm), 7);
    assert_records_match_the_machine(&vm);

    // Condition 3: T0 returns T7 and leaves the spindle empty, Y out at point A.
    let r = change(&mut vm, "T0 M6");
    assert!(r.iter().any(|l| l == "NowSelectedTool:0"), "{r:?}");
    assert_eq!(spindle_id(&vm), 0);
    assert_eq!(vm.atc().pocket_ids(), [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    assert_records_match_the_machine(&vm);
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
    // The spindle was off the whole time.
    assert!(!vm.spindle_on());
    // RAM: the change's call chain fits the stack (docs/SPEC.md §11 budget: static + stack ≤ 7 KiB).
    let stack = vm.stack_high_water_bytes().expect("stack paint");
    eprintln!("stack high-water after three changes: {stack} bytes");
    assert!(stack <= 4096, "{stack}");
}

#[test]
fn repeats_and_bounds() {
    let mut vm = atc_vm();
    ready(&mut vm);
    change(&mut vm, "T5 M6");
    let n = total_steps(&vm);
    // The tool already in the spindle: nothing moves, nothing printed.
    let r = ok(&mut vm, "T5 M6");
    assert_eq!(r, ["ok"]);
    let r = ok(&mut vm, "M6");
    assert_eq!(r, ["ok"], "M6 alone changes to the selected (last) T");
    assert_eq!(total_steps(&vm), n);
    // Out of range and malformed tool numbers are errors; nothing moves.
    assert!(refused(&mut vm, "T13 M6").contains("tool T13 not in the tool table"));
    assert!(refused(&mut vm, "T-1").starts_with("Error:"));
    assert!(refused(&mut vm, "T2 M6 G0 X5").contains("without motion"));
    assert_eq!(total_steps(&vm), n);
    assert_eq!(spindle_id(&vm), 5);
    assert_records_match_the_machine(&vm);
}

/// Issue 13 item 5: `T<n>` alone pre-stages (nothing moves, the spindle tool
/// stays), `M6` changes to it; `$151=1` brings back Repetier's immediate T
/// (the thesis macros).
#[test]
fn t_alone_selects_the_next_tool_and_m6_changes_to_it() {
    let mut vm = atc_vm();
    ready(&mut vm);
    let n = total_steps(&vm);
    let r = ok(&mut vm, "T3");
    assert_eq!(r, ["ok"], "T alone changes nothing");
    // A selection may share a line with a move (posts pre-stage that way).
    ok(&mut vm, "G0 X12 T3");
    ok(&mut vm, "M400");
    assert_eq!(spindle_id(&vm), 0);
    let moved = total_steps(&vm) - n;
    assert_eq!(moved, 200, "only the 2 mm X move");
    let r = change(&mut vm, "M6");
    assert!(r.iter().any(|l| l == "SelectTool:3"), "{r:?}");
    assert_eq!(spindle_id(&vm), 3);
    // `M6 T2` and `T2 M6` are one change each.
    let r = change(&mut vm, "M6 T2");
    assert!(r.iter().any(|l| l == "NowSelectedTool:2"), "{r:?}");
    assert_eq!(spindle_id(&vm), 2);
    // Repetier's immediate T, as a setting.
    ok(&mut vm, "$151=1");
    let r = change(&mut vm, "T4");
    assert!(r.iter().any(|l| l == "NowSelectedTool:4"), "{r:?}");
    assert_eq!(spindle_id(&vm), 4);
    assert_records_match_the_machine(&vm);
}

#[test]
fn a_change_before_homing_is_refused() {
    let mut vm = atc_vm();
    assert!(refused(&mut vm, "T1 M6").contains("G28"));
    assert_eq!(total_steps(&vm), 0);
}

#[test]
fn repetier_carousel_commands() {
    let mut vm = atc_vm();
    // X/Y/Z are not homed here: unlock them (the homing lock does not
    // guard carousel-only moves, which have their own homing, G205).
    ok(&mut vm, "M999");
    // G205 P0 S0 E0: home; the switch closes at 0°.
    ok(&mut vm, "G205 P0 S0 E0");
    assert_eq!(vm.position(Axis::E).rem_euclid(3200), 0);
    let r = ok(&mut vm, "G203 P0");
    assert_eq!(r[0], "Motor0 Pos:0.000 Endstop Hit:1");
    // G201 P0 X5: five pitches (100°), through the planner.
    let e0 = vm.position(Axis::E);
    vm.recorder_mut().clear_trace(); // homing stops dead on the switch; judge the move alone
    ok(&mut vm, "G201 P0 X5");
    assert_eq!(vm.position(Axis::E) - e0, (5.0 * PITCH).round() as i64);
    let r = ok(&mut vm, "G203 P0");
    assert_eq!(r[0], "Motor0 Pos:5.000 Endstop Hit:0");
    // It accelerated: the E setting is 50 pitches/s². At these low step
    // rates (< 1.8 kHz) the recorder needs a 50 ms window to estimate it.
    let acc = vm.recorder().max_accel_with_window(Axis::E, 0.05).expect("E moved");
    eprintln!("E acceleration {:.1} pitches/s²", acc / PITCH);
    assert!((50.0 * PITCH * 0.8..=50.0 * PITCH * 1.05).contains(&acc), "E acceleration {acc} steps/s²");
    // G202 P0 X2: set the position, no motion.
    let e1 = vm.position(Axis::E);
    ok(&mut vm, "G202 P0 X2");
    assert_eq!(vm.position(Axis::E), e1);
    assert_eq!(ok(&mut vm, "G203 P0")[0], "Motor0 Pos:2.000 Endstop Hit:0");
    // G205 E1: already homed, nothing moves.
    ok(&mut vm, "G205 P0 E1");
    assert_eq!(vm.position(Axis::E), e1);
    // G205 S1: home, then back to the position held before (2 pitches from the new 0).
    ok(&mut vm, "G205 P0 S1");
    assert_eq!(vm.position(Axis::E).rem_euclid(3200), (2.0 * PITCH).round() as i64);
    // G204 P0 S0 / S1: the carousel driver alone.
    ok(&mut vm, "G0 X1");
    ok(&mut vm, "M400");
    ok(&mut vm, "G204 P0 S0");
    assert!(!vm.driver_enabled(Axis::E) && vm.driver_enabled(Axis::X));
    ok(&mut vm, "G204 P0 S1");
    assert!(vm.driver_enabled(Axis::E));
    // A missing or wrong P is an error, not motor 0.
    assert!(refused(&mut vm, "G201 X3").contains("P must be 0"));
    assert!(refused(&mut vm, "G201 P1 X3").contains("P must be 0"));
    assert!(refused(&mut vm, "G204 P0 S2").contains("0 or 1"));
    assert!(refused(&mut vm, "G201 P0").contains("X missing"));
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}

#[test]
fn carousel_moves_keep_status_and_send_busy() {
    let mut vm = atc_vm();
    ok(&mut vm, "G205 P0");
    vm.send_line("G201 P0 X200");
    vm.run_for(0.5).unwrap();
    vm.send("?");
    let st = vm.wait_line(|l| l.starts_with('<'), 1.0).unwrap();
    assert!(st.starts_with("<Run|"), "{st}");
    vm.wait_line(|l| l == "busy:processing", 3.0).unwrap();
    // M112 stops the carousel at once.
    let e = vm.position(Axis::E);
    vm.send_line("M112");
    vm.wait_line(|l| l.starts_with("ALARM:"), 1.0).unwrap();
    vm.run_for(0.05).unwrap();
    let stopped = vm.position(Axis::E);
    vm.run_for(0.5).unwrap();
    assert_eq!(vm.position(Axis::E), stopped);
    assert!(stopped - e < 200, "stopped within a few steps of the M112");
}

#[test]
fn g205_with_the_carousel_switch_disconnected_alarms() {
    let mut vm = atc_vm();
    vm.set_carousel_connected(false);
    let r = vm.command("G205 P0 S0 E0").unwrap();
    assert!(r.iter().any(|l| l == "ALARM:carousel home switch not found"), "{r:?}");
    assert!(r.iter().any(|l| l.starts_with("Error:alarm")), "{r:?}");
    // It gave up after about a revolution and a quarter.
    let e = vm.recorder().axis_stats(Axis::E);
    assert!(e.steps_pos <= (3200.0 * 1.25) as u64 + 10, "{e:?}");
    assert!(e.steps_pos >= 3200, "{e:?}");
    assert!(refused(&mut vm, "G201 P0 X1").contains("alarm"));
}

#[test]
fn a_change_with_the_carousel_switch_disconnected_stops_safe() {
    let mut vm = atc_vm();
    ready(&mut vm);
    vm.set_carousel_connected(false);
    let r = vm.command("T4 M6").unwrap();
    assert!(r.iter().any(|l| l == "ALARM:carousel home switch not found"), "{r:?}");
    assert!(!vm.spindle_on());
    // Nothing was transferred; the record says so and marks the change interrupted.
    assert!(vm.atc().transfers.is_empty());
    let (st, j) = records(&vm);
    assert_eq!(st.map(|s| s.spindle), Some(0));
    assert_eq!(j, Some(Journal { from: 0, to: 4 }));
    // Motion is refused until the operator confirms the spindle, even after M999.
    ok(&mut vm, "M999");
    assert!(refused(&mut vm, "G28").contains("M61"));
    ok(&mut vm, "M61 Q0");
    assert_records_match_the_machine(&vm);
    vm.set_carousel_connected(true);
    ok(&mut vm, "G28");
    change(&mut vm, "T4 M6");
    assert_eq!(spindle_id(&vm), 4);
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
}

#[test]
fn an_empty_target_pocket_is_refused_before_anything_moves() {
    let mut vm = atc_vm();
    ready(&mut vm);
    // The operator took tool 6 out and says so.
    vm.with_atc(|a| a.pockets[5] = None);
    ok(&mut vm, "M61 P6 S0");
    let (st, _) = records(&vm);
    assert_eq!(st.unwrap().occupied, ALL_POCKETS & !pocket_bit(6));
    let n = total_steps(&vm);
    assert!(refused(&mut vm, "T6 M6").contains("pocket of that tool is empty"));
    assert_eq!(total_steps(&vm), n);
    assert!(!vm.command("T6 M6").unwrap().iter().any(|l| l.starts_with("SelectTool")));
    assert_records_match_the_machine(&vm);
}

#[test]
fn m112_mid_change_stops_safe_and_the_record_matches_the_machine() {
    let mut vm = atc_vm();
    ready(&mut vm);
    change(&mut vm, "T2 M6");
    vm.send_line("T9 M6");
    // Stop it while T2 goes back in (Y on its way in to point B, before the release).
    vm.run_until(|vm| vm.position(Axis::Y) > 3700, 30.0).unwrap();
    vm.send_line("M112");
    vm.wait_line(|l| l == "ALARM:emergency stop", 1.0).unwrap();
    vm.run_for(0.2).unwrap();
    let p = steps(&vm);
    vm.run_for(0.5).unwrap();
    assert_eq!(steps(&vm), p, "motion stopped");
    assert!(!vm.spindle_on());
    assert!(!vm.driver_enabled(Axis::Y));
    let (st, j) = records(&vm);
    assert_eq!(j, Some(Journal { from: 2, to: 9 }));
    assert_eq!(st.unwrap().spindle, spindle_id(&vm));
    assert_eq!(spindle_id(&vm), 2);
    vm.take_lines();
    ok(&mut vm, "M999");
    assert!(refused(&mut vm, "G0 X1").contains("M61"));
    // The operator backs the spindle out by hand, sees T2, confirms.
    ok(&mut vm, "M61 Q2");
    assert_records_match_the_machine(&vm);
    ok(&mut vm, "G28");
    change(&mut vm, "T9 M6");
    assert_eq!(spindle_id(&vm), 9);
    assert_records_match_the_machine(&vm);
}

#[test]
fn chip_reset_mid_change_refuses_motion_until_confirmed_then_changes_again() {
    let mut vm = atc_vm();
    ready(&mut vm);
    change(&mut vm, "T2 M6");
    vm.send_line("T5 M6");
    // Reset after T2 went back into its pocket, before T5 is clamped.
    vm.run_until(|vm| vm.atc().transfers.len() == 2, 60.0).unwrap();
    vm.run_for(0.3).unwrap();
    assert_eq!(spindle_id(&vm), 0);
    vm.reset();
    vm.wait_for_start(3.0).unwrap();
    let banner = vm.wait_line(|l| l.contains("interrupted"), 1.0).unwrap();
    assert!(banner.contains("T2->T5") && banner.contains("M61"), "{banner}");
    let (_, j) = records(&vm);
    assert_eq!(j, Some(Journal { from: 2, to: 5 }));
    vm.take_lines();
    let n = total_steps(&vm);
    assert!(refused(&mut vm, "G28").contains("M61"));
    assert!(refused(&mut vm, "G0 X1").contains("M61"));
    assert!(refused(&mut vm, "T5 M6").contains("M61"));
    assert_eq!(total_steps(&vm), n);
    // The operator finds the spindle empty.
    ok(&mut vm, "M61 Q0");
    assert_records_match_the_machine(&vm);
    ok(&mut vm, "G28");
    change(&mut vm, "T5 M6");
    assert_eq!(spindle_id(&vm), 5);
    assert_records_match_the_machine(&vm);
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
}

#[test]
fn power_cycle_keeps_the_tool_and_its_offset() {
    let mut vm = atc_vm();
    ready(&mut vm);
    ok(&mut vm, "G10 L1 P4 Z30");
    change(&mut vm, "T4 M6");
    vm.power_cycle();
    vm.wait_for_start(3.0).unwrap();
    let l = vm.wait_line(|l| l.starts_with("echo:tool in spindle"), 1.0).unwrap();
    assert_eq!(l, "echo:tool in spindle: T4");
    vm.run_for(0.05).unwrap();
    vm.take_lines();
    let st = status(&mut vm);
    assert!(st.split(['|', '>']).any(|f| f == "T:4"), "{st}");
    ok(&mut vm, "G28");
    // Work Z is the tip, 30 mm below the spindle (LinuxCNC's G43, +Z up):
    // Z-40 puts the spindle 30 mm higher, at machine Z −10 (physical step
    // 1000 below the top switch).
    ok(&mut vm, "G0 Z-40");
    ok(&mut vm, "M400");
    assert_eq!(vm.position(Axis::Z), 1000);
    let st = status(&mut vm);
    assert!(st.contains("|MPos:1.000,1.000,-10.000|"), "{st}");
    ok(&mut vm, "$10=0");
    let st = status(&mut vm);
    assert!(st.contains("|WPos:1.000,1.000,-40.000|"), "{st}");
    assert_eq!(spindle_id(&vm), 4);
    assert_records_match_the_machine(&vm);
}
