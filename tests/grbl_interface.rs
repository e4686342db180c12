//! The grbl 1.1 interface a grbl sender uses, on the real firmware and
//! checked against the recorded steps: `$J=` jogging and its cancel byte
//! 0x85, and the Marlin codes a host's sliders send (M220, M221).

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;
use sim::{Axis, Flow, Input, StreamOptions, Vm};

/// The `$G` line.
fn modes(vm: &mut Vm) -> String {
    ok(vm, "$G").into_iter().find(|l| l.starts_with("[GC:")).expect("[GC:...]")
}

#[test]
fn a_jog_moves_in_its_own_modes_and_leaves_the_modal_state_alone() {
    let mut vm = boot_homed();
    run(&mut vm, "G90 G0 X10 Y10 Z-5");
    let g = modes(&mut vm);
    assert!(g.contains("G90") && g.contains("G21"), "{g}");
    ok(&mut vm, "$J=G91 X5 Y-2 F600");
    vm.run_for(0.2).unwrap();
    assert!(status(&mut vm).starts_with("<Jog|"));
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [1500, 800, 500]);
    assert!(status(&mut vm).starts_with("<Idle|"));
    assert_eq!(modes(&mut vm), g, "a jog changes no modal state");
    // Absolute in inches and in machine coordinates, with a work offset.
    ok(&mut vm, "G10 L20 P1 X0 Y0");
    run(&mut vm, "$J=G20 G90 X0.5 F20");
    assert_eq!(xyz_now(&vm), [1500 + 1270, 800, 500]);
    run(&mut vm, "$J=G53 X3 Y4 F600");
    assert_eq!(xyz_now(&vm), [300, 400, 500]);
    // A jog that ended and a plain move after it: the commanded position
    // followed the jog.
    run(&mut vm, "G91 G1 X1 F600");
    assert_eq!(xyz_now(&vm), [400, 400, 500]);
    assert_no_violations(&vm);
}

#[test]
fn a_jog_beyond_the_travel_or_without_a_feed_is_refused_and_nothing_moves() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10");
    let n = total_steps(&vm);
    for bad in ["$J=X50 F600", "$J=G91 Y-20 F600", "$J=X5", "$J=G1 X5 F600", "$J=X5 S100 F600", "$J=X5 M3 F600"] {
        let e = refused(&mut vm, bad);
        assert!(e.starts_with("Error:"), "{bad}: {e}");
    }
    vm.run_for(0.2).unwrap();
    assert_eq!(total_steps(&vm), n, "a refused jog moved");
    // A feed above the maximum rate is clamped (bCNC's jog buttons send
    // F100000), as grbl does.
    run(&mut vm, "$J=G91 X10 F100000");
    assert_eq!(xyz_now(&vm)[0], 2000);
    // Not while a program's moves run.
    ok(&mut vm, "G1 X30 F300");
    assert!(refused(&mut vm, "$J=G91 X1 F600").contains("idle"));
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm)[0], 3000);
}

#[test]
fn jog_cancel_stops_with_the_position_exact_and_the_next_jog_runs_at_once() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X5 Y5");
    ok(&mut vm, "M3 S5000");
    ok(&mut vm, "$J=G91 X30 F600");
    vm.run_for(0.5).unwrap();
    let at = xyz_now(&vm);
    assert!(at[0] > 500 && at[0] < 3500, "{at:?}");
    vm.send([0x85]);
    settle(&mut vm, 0.05);
    let stopped = xyz_now(&vm);
    // 10 mm/s at 1000 mm/s²: 0.05 mm of deceleration, plus what the
    // stepper had queued (tens of ms at 10 mm/s).
    assert!(stopped[0] - at[0] < 100, "{at:?} -> {stopped:?}");
    let st = status(&mut vm);
    assert!(st.starts_with("<Idle|"), "{st}");
    let mpos = format!("MPos:{:.3},{:.3},", stopped[0] as f64 / 100.0, stopped[1] as f64 / 100.0);
    assert!(st.contains(&mpos), "{st} vs {stopped:?}");
    assert!(vm.spindle_on(), "a jog cancel leaves the spindle as it was");
    run(&mut vm, "$J=G91 X1 F600");
    assert_eq!(xyz_now(&vm)[0], stopped[0] + 100);
    // 0x85 outside a jog changes nothing.
    ok(&mut vm, "G1 X20 F600");
    vm.run_for(0.2).unwrap();
    vm.send([0x85]);
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm)[0], 2000);
    assert_no_violations(&vm);
}

#[test]
fn continuous_jogging_runs_without_stops_and_cancel_drops_the_queued_jogs() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X2 Y2");
    mark(&mut vm);
    // A key held in a sender: short jogs, several in flight.
    let jogs: Vec<String> = (0..30).map(|_| "$J=G91 X1 F1200".to_string()).collect();
    let r = vm.stream(&jogs, StreamOptions::new(Flow::CharCount(120))).unwrap();
    assert!(!r.timed_out);
    // The key released: cancel while several jogs still wait.
    vm.run_for(0.3).unwrap();
    let at = xyz_now(&vm)[0];
    vm.send([0x85]);
    settle(&mut vm, 0.05);
    let end = xyz_now(&vm)[0];
    assert!(end < 3200, "queued jogs were dropped: X ended at {end}");
    assert!(end - at < 150, "stopped within about a block: {at} -> {end}");
    // No stop between the jogs: the X steps never pause for 20 ms.
    let xs: Vec<u64> = vm.recorder().trace().iter().filter(|t| t.axis == Axis::X).map(|t| t.cycle).collect();
    let longest = xs.windows(2).map(|w| w[1] - w[0]).max().unwrap();
    assert!(longest < 20 * 16_000, "a pause of {} ms between jogs", longest / 16_000);
    assert!(status(&mut vm).starts_with("<Idle|"));
    run(&mut vm, "$J=G90 X10 F1200");
    assert_eq!(xyz_now(&vm)[0], 1000);
}

#[test]
fn m220_keeps_the_spindle_speed_and_m221_is_a_note() {
    let mut vm = boot_homed();
    ok(&mut vm, "M3 S8000");
    ok(&mut vm, "M220 S120");
    let g = modes(&mut vm);
    assert!(g.contains("S8000"), "M220's S became the spindle speed: {g}");
    // OctoPrint's flow-rate slider: a note, never an error (OctoPrint
    // disconnects on an unknown error).
    let r = ok(&mut vm, "M221 S95");
    assert!(r.iter().any(|l| l.starts_with("echo:M221")), "{r:?}");
}

/// A grbl sender matches `error:<n>`, sent instead of the `ok`, and
/// `ALARM:<n>`, with grbl's numbers; a Marlin host keeps `Error:` + `ok`.
#[test]
fn a_grbl_sender_gets_grbl_errors_and_a_marlin_host_marlin_ones() {
    let mut vm = boot_homed();
    // Marlin's replies until the host speaks grbl.
    let r = vm.command("G5 X1").unwrap();
    assert!(r[0].starts_with("Error:unsupported code") && r.last().unwrap() == "ok", "{r:?}");
    // cncjs's first line on connecting.
    ok(&mut vm, "$$");
    let r = vm.command("G5 X1").unwrap();
    assert_eq!(r.last().map(String::as_str), Some("error:20"), "{r:?}");
    assert!(r.iter().any(|l| l.starts_with("[MSG:unsupported code")), "{r:?}");
    assert!(!r.iter().any(|l| l == "ok"), "grbl sends the error instead of the ok: {r:?}");
    assert_eq!(vm.command("G1 X10").unwrap().last().map(String::as_str), Some("error:22"));
    assert_eq!(vm.command("G0 X99").unwrap().last().map(String::as_str), Some("error:15"));
    // Too long: 320 characters of code (a long comment is cut, not refused).
    let long = format!("G0 X1 {}", "G90 ".repeat(80));
    let r = vm.command(&long).unwrap();
    assert_eq!(r.last().map(String::as_str), Some("error:11"), "{r:?}");
    // A probe that touches nothing: ALARM:5 and, as grbl-Mega answers
    // (tests/grbl_reference.rs), `ok` for the probe line; the line after it
    // error:9.
    run(&mut vm, "G0 X30 Y30 Z-2");
    vm.send_line("G38.2 Z-8 F300");
    vm.send_line("G92 Z0");
    assert_eq!(vm.wait_line(|l| l.starts_with("ALARM:"), 10.0).unwrap(), "ALARM:5");
    let mut ends = Vec::new();
    while ends.len() < 2 {
        let l = vm.wait_line(|_| true, 2.0).unwrap();
        if l == "ok" || l.starts_with("error:") {
            ends.push(l);
        }
    }
    assert_eq!(ends, ["ok", "error:9"]);
    ok(&mut vm, "$X");
    // A job streamed the grbl way (characters counted): the error line is
    // acknowledged by its error, the others by ok, nothing waits.
    let job = ["G1 X20 F600", "G5 X1", "G1 Y20"];
    let rep = vm.stream(&job, StreamOptions::new(Flow::CharCount(120))).unwrap();
    assert!(!rep.timed_out);
    assert_eq!(rep.errors, ["error:20"]);
    // A Marlin host's first words (M110, a numbered line) bring Marlin's back.
    ok(&mut vm, "M110 N0");
    let r = vm.command("G5 X1").unwrap();
    assert!(r[0].starts_with("Error:unsupported code") && r.last().unwrap() == "ok", "{r:?}");
}

/// grbl 1.1's status fields: Bf, FS, Pn (the inputs that read triggered),
/// WCO and Ov on a refresh count, A (spindle and coolant).
#[test]
fn the_status_report_carries_grbls_fields() {
    let mut vm = boot_homed();
    ok(&mut vm, "G10 L20 P1 X5 Y6 Z0");
    let mut wco = None;
    let mut ov = None;
    for _ in 0..10 {
        let st = status(&mut vm);
        assert!(st.starts_with("<Idle|MPos:") && !st.contains("|Bf:") && !st.contains("WPos") && st.contains("|FS:"), "{st}");
        // The carousel's home switch (C) is closed at 0°; nothing else is.
        assert!(!st.contains("|A:"), "{st}");
        let pn = st.trim_matches(['<', '>']).split('|').find_map(|f| f.strip_prefix("Pn:")).unwrap_or("");
        assert_eq!(pn, "C", "{st}");
        for f in st.trim_matches(['<', '>']).split('|') {
            if let Some(v) = f.strip_prefix("WCO:") {
                wco = Some(v.to_string());
            }
            if let Some(v) = f.strip_prefix("Ov:") {
                ov = Some(v.to_string());
            }
        }
    }
    // MPos 1,1,-1 is work 5,6,... : WCO = MPos - WPos.
    assert_eq!(wco.as_deref(), Some("-4.000,-5.000,-1.000"));
    assert_eq!(ov.as_deref(), Some("100,100,100"));
    ok(&mut vm, "M220 S120");
    ok(&mut vm, "M3 S6000");
    ok(&mut vm, "M8");
    vm.set_input(Input::HomeY, Some(true));
    vm.set_input(Input::ToolSetter, Some(true));
    let mut seen_ov = None;
    for _ in 0..10 {
        let st = status(&mut vm);
        assert!(st.contains("|Pn:YP") && st.contains("|A:SF"), "{st}");
        if let Some(f) = st.trim_matches(['<', '>']).split('|').find_map(|f| f.strip_prefix("Ov:")) {
            seen_ov = Some(f.to_string());
        }
    }
    assert_eq!(seen_ov.as_deref(), Some("120,100,100"));
}

/// `$10` chooses the position (bit 0: MPos, else WPos) and the buffer
/// field (bit 1), `$13` reports in inches: as grbl 1.1 (its default
/// `$10=1`: MPos, no Bf).
#[test]
fn dollar_10_picks_the_position_and_bf_and_dollar_13_reports_inches() {
    let mut vm = boot_homed();
    ok(&mut vm, "G10 L20 P1 X5 Y6 Z0");
    ok(&mut vm, "G1 F600");
    let st = status(&mut vm);
    assert_eq!(fields(&st)[..3], ["Idle", "MPos", "FS"], "{st}");
    ok(&mut vm, "$10=2");
    let st = status(&mut vm);
    assert_eq!(fields(&st)[..4], ["Idle", "WPos", "Bf", "FS"], "{st}");
    assert!(st.contains("|WPos:5.000,6.000,0.000|") && st.contains("|FS:600,0"), "{st}");
    ok(&mut vm, "$10=3");
    let st = status(&mut vm);
    assert!(st.starts_with("<Idle|MPos:1.000,1.000,-1.000|Bf:"), "{st}");
    // Inches: positions with four decimals, the feed with one.
    ok(&mut vm, "$10=0");
    ok(&mut vm, "$13=1");
    let st = status(&mut vm);
    assert!(st.contains("|WPos:0.1969,0.2362,0.0000|") && st.contains("|FS:23.6,0"), "{st}");
    let p = ok(&mut vm, "$#");
    assert!(p.iter().any(|l| l == "[G54:-0.1575,-0.1969,-0.0394]"), "{p:?}");
    // Bad values: refused, nothing changed.
    for bad in ["$10=4", "$10=-1", "$13=2"] {
        let e = refused(&mut vm, bad);
        assert!(e.contains("bad value") || e.contains("out of range"), "{bad}: {e}");
    }
    assert!(ok(&mut vm, "$$").iter().any(|l| l.starts_with("$10=0 ")));
}

/// `Ln:` in `?`: the block number (`N…`) of the move being run, from a
/// grbl sender's `N10 G1 …` and from a Marlin host's numbered lines; none
/// for lines without a number.
#[test]
fn the_status_report_names_the_block_number_of_the_move_being_run() {
    let mut vm = boot_homed();
    ok(&mut vm, "$$");
    let ln = |st: &str| st.trim_matches(['<', '>']).split('|').find_map(|f| f.strip_prefix("Ln:")).map(str::to_string);
    vm.send_line("N10 G1 X20 F600");
    vm.send_line("N11 G1 X2");
    vm.run_for(0.3).unwrap();
    let st = status(&mut vm);
    assert_eq!(ln(&st).as_deref(), Some("10"), "{st}");
    vm.run_until(|v| v.position(Axis::X) >= 1990, 10.0).unwrap();
    vm.run_for(0.3).unwrap();
    let st = status(&mut vm);
    assert_eq!(ln(&st).as_deref(), Some("11"), "{st}");
    vm.run_until(|v| v.position(Axis::X) <= 200, 10.0).unwrap();
    settle(&mut vm, 0.3);
    ok(&mut vm, "G1 X10");
    vm.run_for(0.2).unwrap();
    let st = status(&mut vm);
    assert!(st.starts_with("<Run") && ln(&st).is_none(), "{st}");
    ok(&mut vm, "M400");
    // A Marlin host's numbered, checksummed line.
    let numbered = |l: &str| format!("{l}*{}", checksum(l));
    ok(&mut vm, &numbered("N0 M110 N0"));
    ok(&mut vm, &numbered("N1 G1 X30"));
    vm.run_for(0.2).unwrap();
    let st = status(&mut vm);
    assert_eq!(ln(&st).as_deref(), Some("1"), "{st}");
}

/// grbl's other `$` commands: startup blocks (stored, checked, run at
/// boot with their echo), `$I=`, `$RST=`, `$SLP`, `$HX`.
#[test]
fn startup_blocks_info_restore_sleep_and_one_axis_homing() {
    let mut vm = boot_homed();
    ok(&mut vm, "$N0=G20 G91");
    ok(&mut vm, "$N1=G55");
    let r = ok(&mut vm, "$N");
    assert_eq!(r[..2], ["$N0=G20 G91", "$N1=G55"]);
    // A line that would not run, or a `$` line, is refused and not stored.
    assert!(refused(&mut vm, "$N0=G5 X1").contains("unsupported"));
    assert!(refused(&mut vm, "$N1=$H").contains("$N"));
    assert_eq!(ok(&mut vm, "$N")[..2], ["$N0=G20 G91", "$N1=G55"]);
    ok(&mut vm, "$I=shop mill 2");
    assert!(ok(&mut vm, "$I")[0].ends_with(":shop mill 2]"));
    // After a power cycle the blocks run, each echoed with its result.
    vm.power_cycle();
    let banner = vm.wait_banner().unwrap();
    assert!(banner.iter().any(|l| l == ">G20 G91:ok") && banner.iter().any(|l| l == ">G55:ok"), "{banner:?}");
    let g = modes(&mut vm);
    assert!(g.contains("G20") && g.contains("G91") && g.contains("G55"), "{g}");
    assert!(ok(&mut vm, "$I")[0].ends_with(":shop mill 2]"), "the info text survives");
    ok(&mut vm, "G21 G90 G54");
    // `$RST=*` is not a checksum: settings, offsets, blocks and text go.
    ok(&mut vm, "$100=200");
    ok(&mut vm, "G10 L2 P1 X3");
    ok(&mut vm, "$RST=$");
    assert!(ok(&mut vm, "$$").iter().any(|l| l.starts_with("$100=100")));
    assert!(ok(&mut vm, "$#")[0].starts_with("[G54:3.000,"), "$RST=$ keeps the offsets");
    ok(&mut vm, "$RST=#");
    assert!(ok(&mut vm, "$#")[0].starts_with("[G54:0.000,0.000,0.000"));
    ok(&mut vm, "$RST=*");
    assert_eq!(ok(&mut vm, "$N")[..2], ["$N0=", "$N1="]);
    assert!(ok(&mut vm, "$I")[0].ends_with(":]"));
    // `$HX` homes X alone; `$SLP` turns everything off.
    // (The power cycle kept the physical position, X and Y at 1 mm, and
    // forgot the homing: the moves count from there.)
    ok(&mut vm, "M999");
    run(&mut vm, "G0 X20 Y20");
    ok(&mut vm, "$HX");
    assert_eq!(xyz_now(&vm)[..2], [100, 2100]);
    ok(&mut vm, "M3 S5000");
    let r = ok(&mut vm, "$SLP");
    assert!(r.iter().any(|l| l == "[MSG:Sleeping]"), "{r:?}");
    assert!(!vm.spindle_on() && !vm.driver_enabled(Axis::X));
}

/// `$C`: every line is read and checked, nothing moves, nothing is stored;
/// leaving it, the commanded position is the machine's again.
#[test]
fn check_mode_reads_every_line_and_moves_nothing() {
    let mut vm = boot_homed();
    let n = total_steps(&vm);
    assert!(ok(&mut vm, "$C").iter().any(|l| l == "[MSG:Enabled]"));
    assert!(status(&mut vm).starts_with("<Check|"));
    let started = vm.seconds();
    for l in ["G0 X20 Y20", "G91 G1 X5 F300", "M3 S5000", "G4 P5", "G10 L20 P1 X0", "G28", "T2 M6"] {
        ok(&mut vm, l);
    }
    assert!(vm.seconds() - started < 1.0, "the dwell and the homing were skipped");
    // Errors are still found: beyond the travel, an unknown code.
    assert!(refused(&mut vm, "G1 X99").contains("soft limit"));
    assert!(refused(&mut vm, "G5 X1").contains("unsupported"));
    assert!(refused(&mut vm, "$J=X5 F100").contains("idle"));
    vm.run_for(0.3).unwrap();
    assert_eq!(total_steps(&vm), n, "check mode moved");
    assert!(!vm.spindle_on());
    assert!(ok(&mut vm, "$C").iter().any(|l| l == "[MSG:Disabled]"));
    assert!(status(&mut vm).starts_with("<Idle|"));
    // The stored G54 (0) is back and moves count from where the machine is.
    run(&mut vm, "G90 G54 G1 X10 F600");
    assert_eq!(xyz_now(&vm)[0], 1000);
}

/// grbl's realtime overrides on the real firmware, the feed bytes written as
/// cncjs writes them (UTF-8, `C2 91`): the move in progress speeds up and
/// slows down at once, the rapid override slows a G0, the spindle override
/// changes the PWM, the coolant byte toggles the output, `Ov:` reports each,
/// every line still ends where it should, and Ctrl-X puts them back to 100.
#[test]
fn realtime_overrides_act_on_the_move_in_progress_and_every_line_still_runs() {
    let mut vm = boot_homed();
    run(&mut vm, "G90 G0 X2 Y2 Z-2");
    // F600: 10 mm/s, 1000 steps/s; 38 mm take 3.8 s.
    ok(&mut vm, "G1 X40 F600");
    vm.run_for(1.0).unwrap();
    let t = vm.cycles();
    let hz = u64::from(vm.frequency());
    let before = x_rate(&vm, t - hz / 2, t);
    assert!((before - 1000.0).abs() < 20.0, "F600: {before} steps/s");
    // Three clicks, 50 ms apart (bytes that arrive between two turns of the
    // main loop count once, as grbl's request flags do).
    for _ in 0..3 {
        vm.send([0xC2, 0x91]);
        vm.run_for(0.05).unwrap();
    }
    vm.run_for(0.15).unwrap();
    let t = vm.cycles();
    let faster = x_rate(&vm, t - hz / 5, t);
    assert!((faster - 1300.0).abs() < 30.0, "130 %: {faster} steps/s");
    assert_eq!(ov(&mut vm, 12), "130,100,100");
    // 0x94 four times: 126 %; 0x90: back to 100 %.
    for _ in 0..4 {
        vm.send([0x94]);
        vm.run_for(0.05).unwrap();
    }
    assert_eq!(ov(&mut vm, 12), "126,100,100");
    vm.send([0x90]);
    vm.run_for(0.3).unwrap();
    let t = vm.cycles();
    let back = x_rate(&vm, t - hz / 5, t);
    assert!((back - 1000.0).abs() < 20.0, "100 %: {back} steps/s");
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [4000, 200, 200]);
    // Rapid 25 %: a G0 at 3000 mm/min goes at 750 (1250 steps/s).
    vm.send([0x97]);
    ok(&mut vm, "G0 X10");
    vm.run_for(1.0).unwrap();
    let t = vm.cycles();
    let rapid = x_rate(&vm, t - hz / 2, t);
    assert!((rapid - 1250.0).abs() < 30.0, "rapid at 25 %: {rapid} steps/s");
    assert_eq!(ov(&mut vm, 12), "100,25,100");
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [1000, 200, 200]);
    // Spindle +10 %, then the coolant output on and off.
    ok(&mut vm, "M3 S5000");
    let duty = |vm: &Vm| vm.spindle_history().last().unwrap().1;
    let d0 = duty(&vm);
    vm.send([0x9A]);
    vm.run_for(0.1).unwrap();
    assert!((duty(&vm) / d0 - 1.1).abs() < 0.02, "{d0} -> {}", duty(&vm));
    assert_eq!(ov(&mut vm, 12), "100,25,110");
    assert!(!vm.coolant_on());
    vm.send([0xA0]);
    vm.run_for(0.1).unwrap();
    assert!(vm.coolant_on());
    assert!(ok(&mut vm, "$G")[0].contains(" M8 "), "the modal state follows");
    vm.send([0xA0]);
    vm.run_for(0.1).unwrap();
    assert!(!vm.coolant_on());
    // Ctrl-X: every override back to 100 %.
    vm.send([0x18]);
    vm.run_for(0.3).unwrap();
    vm.take_lines();
    assert_eq!(ov(&mut vm, 12), "100,100,100");
}
