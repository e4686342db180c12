//! Faults, feed hold, settings and streams on the real firmware (docs/SPEC.md §4,
//! §6, §10; issue #3), in the virtual machine, checked against the recorded
//! steps: hard limits, M112, `!`/`~`, M500 across a reboot, 2,000 short
//! segments, and bad input that must change nothing.

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;
use sim::{Axis, Flow, Input, StreamOptions, ViolationKind, Vm};

/// Runs until no step has been recorded for `quiet_s`; returns the VM cycle
/// of the last step (or now if none). Errors after `timeout_s`.
fn run_until_still(vm: &mut Vm, quiet_s: f64, timeout_s: f64) -> u64 {
    let quiet = (quiet_s * 16e6) as u64;
    vm.run_until(
        |vm| {
            let last = vm.recorder().trace().last().map_or(0, |t| t.cycle);
            vm.cycles() > last + quiet
        },
        timeout_s,
    )
    .expect("motion stops");
    vm.recorder().trace().last().map_or(vm.cycles(), |t| t.cycle)
}

// ------------------------------------------------------------ hard limits

/// Drives `input` closed while `axis` moves toward it at F600 (10 mm/s) and
/// checks the alarm: steps stop within the deceleration distance
/// (v²/2a = 0.05 mm = 5 steps; the ISR stops at once), the spindle goes off
/// and motion is refused. Leaves the input closed.
fn trip_hard_limit(vm: &mut Vm, axis: Axis, input: Input, line: &str) {
    ok(vm, "M3 S5000");
    assert!(vm.spindle_on(), "M3 S5000 turns the spindle on");
    mark(vm);
    ok(vm, line);
    vm.run_for(0.4).unwrap();
    let moved = steps_since_mark(vm);
    assert!(moved > 100, "the move is under way ({moved} steps)");
    let tripped_at = vm.cycles();
    vm.set_input(input, Some(true));
    let alarm = vm.wait_line(|l| l.starts_with("ALARM:"), 0.5).expect("alarm");
    assert_eq!(alarm, "ALARM:hard limit");
    let after_all = || vm.recorder().trace().iter().filter(|t| t.cycle > tripped_at).count();
    let after = after_all();
    assert!(after <= 5, "{after} steps after the {axis} switch closed");
    assert!(steps_after(vm, axis, tripped_at) >= 1, "the switch is seen on the next {axis} step");
    vm.run_for(0.3).unwrap();
    let after_all = || vm.recorder().trace().iter().filter(|t| t.cycle > tripped_at).count();
    assert_eq!(after_all(), after, "steps went on after the alarm");
    // The spindle went off with the steps (within a millisecond of the trip).
    assert!(!vm.spindle_on(), "spindle still on after a hard limit");
    let off = vm.spindle_history().last().unwrap().0;
    assert!(off >= tripped_at && off - tripped_at < 16_000, "spindle off {} cycles after the trip", off - tripped_at);
    vm.take_lines();
    let e = refused(vm, "G1 X20 Y20 F600");
    assert!(e.starts_with("Error:alarm hard limit"), "{e}");
    let e = refused(vm, "G0 Z-20");
    assert!(e.starts_with("Error:alarm hard limit"), "{e}");
    assert!(status(vm).starts_with("<Alarm|"));
}

#[test]
fn a_home_switch_closing_mid_move_raises_a_hard_limit_alarm_until_m999_or_g28() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X40 Y30 Z-10");
    trip_hard_limit(&mut vm, Axis::X, Input::HomeX, "G1 X5 F600");
    let stopped = xyz_now(&vm);
    assert!(stopped[0] > 500 && stopped[0] < 4000, "stopped mid-move at {stopped:?}");
    // The switch opens again (the test releases it); M999 clears the alarm.
    vm.set_input(Input::HomeX, None);
    ok(&mut vm, "M999");
    // The spindle stays off: an S word alone must not restart it.
    ok(&mut vm, "S6000");
    vm.run_for(0.05).unwrap();
    assert!(!vm.spindle_on(), "S after the alarm restarted the spindle");
    let st = status(&mut vm);
    assert!(st.contains("|FS:600,0|"), "status reports the spindle on: {st}");
    // Motion is accepted again and counted from where the steps stopped.
    mark(&mut vm);
    run(&mut vm, "G1 X30 F600");
    assert_eq!(xyz_now(&vm), [3000, stopped[1], stopped[2]]);
    check_polyline(&vm, &[stopped, [3000, stopped[1], stopped[2]]], 1.0);

    // A second trip, on Y, is cleared by homing instead.
    trip_hard_limit(&mut vm, Axis::Y, Input::HomeY, "G1 Y2 F600");
    vm.set_input(Input::HomeY, None);
    ok(&mut vm, "G28");
    assert_eq!(steps(&vm), [100, 100, 100, 0]);
    assert!(status(&mut vm).starts_with("<Idle|"));
    run(&mut vm, "G0 X10 Y10");
    assert_eq!(xyz_now(&vm), [1000, 1000, 100]);
    assert!(vm.recorder().violations_of(ViolationKind::StepWhileDisabled).is_empty());
    assert_no_violations(&vm);
}

// -------------------------------------------------------------- feed hold

#[test]
fn feed_hold_stops_within_the_acceleration_limit_and_resume_ends_exactly() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X5 Y5");
    mark(&mut vm);
    // 35 mm at 25 mm/s: 1.4 s of cruise.
    ok(&mut vm, "G1 X40 Y12 F1500");
    vm.run_for(0.5).unwrap();
    let at_hold = xyz_now(&vm);
    let hold_cycle = vm.cycles();
    vm.send(b"!");
    let last_step = run_until_still(&mut vm, 0.2, 2.0);
    let stopped = xyz_now(&vm);
    assert!(stopped[0] > at_hold[0] && stopped[0] < 4000, "held mid-move: {at_hold:?} -> {stopped:?}");
    assert!(status(&mut vm).starts_with("<Hold|"));
    // Still while held.
    vm.run_for(0.5).unwrap();
    assert_eq!(xyz_now(&vm), stopped, "moved during the hold");
    // It decelerated (no abrupt stop): the steps before the stop slow down
    // within the acceleration limit (+5 %, docs/SPEC.md §11).
    // The deceleration starts after the motion already queued for the ISR
    // (capped at 40 ms, plus the segment in progress, up to 20 ms) and lasts
    // 25 ms at 25 mm/s: ~90 ms in all (it was ~330 ms with 16 queued
    // segments). Bound it so that it cannot get worse unnoticed.
    let hold_ms = (last_step - hold_cycle) as f64 / 16e3;
    eprintln!("feed hold: {hold_ms:.1} ms from ! to the last step");
    assert!(hold_ms < 120.0, "the hold took {hold_ms:.0} ms to stop");
    let ax = vm.recorder().max_accel(Axis::X).unwrap();
    assert!(ax <= 1.05 * 1000.0 * SPMM, "X acceleration {ax} steps/s² (hold took {hold_ms:.1} ms)");
    // Resume: the rest of the same line, to the exact end, no step lost.
    vm.send(b"~");
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [4000, 1200, 100]);
    check_polyline(&vm, &[[500, 500, 100], [4000, 1200, 100]], 1.0);
    assert_eq!(steps_pos_neg(&vm, Axis::X), (3500, 0));
    assert_eq!(steps_pos_neg(&vm, Axis::Y), (700, 0));
    let ax = vm.recorder().max_accel(Axis::X).unwrap();
    assert!(ax <= 1.05 * 1000.0 * SPMM, "X acceleration {ax} steps/s² after resume");
    assert!(status(&mut vm).starts_with("<Idle|"));
    assert_eq!(m114_counts(&mut vm), [4000, 1200, -100]);
    assert_no_violations(&vm);
}

#[test]
fn feed_hold_in_a_queue_of_moves_resumes_through_every_corner() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X5 Y5");
    mark(&mut vm);
    let corners = [[500, 500, 100], [2500, 500, 100], [2500, 2500, 100], [500, 2500, 100], [500, 500, 100]];
    for c in &corners[1..] {
        ok(&mut vm, &format!("G1 X{} Y{} F1800", c[0] as f64 / 100.0, c[1] as f64 / 100.0));
    }
    // Hold twice, at different places.
    for wait in [0.6, 1.1] {
        vm.run_for(wait).unwrap();
        vm.send(b"!");
        run_until_still(&mut vm, 0.1, 2.0);
        let held = xyz_now(&vm);
        vm.run_for(0.3).unwrap();
        assert_eq!(xyz_now(&vm), held);
        vm.send(b"~");
    }
    ok(&mut vm, "M400");
    check_polyline(&vm, &corners, 1.0);
    assert_eq!(steps_pos_neg(&vm, Axis::X), (2000, 2000));
    assert_eq!(steps_pos_neg(&vm, Axis::Y), (2000, 2000));
    assert_no_violations(&vm);
}

// ------------------------------------------------------------------ M112

#[test]
fn m112_mid_move_stops_everything_and_only_m999_then_g28_recover() {
    let mut vm = boot_homed();
    ok(&mut vm, "M3 S8000");
    mark(&mut vm);
    ok(&mut vm, "G1 X40 Y30 F1200");
    // The host waits for the move with M400; the firmware sits in that wait
    // when the M112 arrives.
    vm.send(b"M400\n");
    vm.run_for(0.4).unwrap();
    assert!(steps_since_mark(&vm) > 100);
    let sent = vm.cycles();
    vm.send(b"M112\n");
    vm.wait_line(|l| l == "ALARM:emergency stop", 0.1).expect("alarm");
    let stopped = xyz_now(&vm);
    // Caught by the RX interrupt: the last step within a few ms of the bytes.
    let last = vm.recorder().trace().last().unwrap().cycle;
    assert!(last < sent + 16_000 * 5, "steps for {} ms after M112", (last - sent) / 16_000);
    vm.run_for(0.5).unwrap();
    assert_eq!(xyz_now(&vm), stopped, "steps after M112");
    for a in [Axis::X, Axis::Y, Axis::Z, Axis::E] {
        assert!(!vm.driver_enabled(a), "{a} driver enabled after M112");
    }
    assert!(!vm.spindle_on());
    // One alarm, although both the RX scanner and the M112 line itself see it.
    vm.run_for(0.05).unwrap();
    let alarms = vm.line_log().iter().filter(|(_, l)| l.starts_with("ALARM:")).count();
    assert_eq!(alarms, 1, "{}", vm.output());
    let lines = vm.take_lines();
    assert!(lines.iter().any(|l| l.starts_with("Error:alarm emergency stop")), "M400 fails: {lines:?}");
    assert_eq!(lines.iter().filter(|l| *l == "ok").count(), 2, "one ok each for M400 and M112: {lines:?}");
    // Motion, and even homing, is refused until M999.
    for line in ["G1 X10", "G0 Y5", "G28", "G2 X10 Y10 I1 J1", "M3 S100"] {
        let e = refused(&mut vm, line);
        assert!(e.starts_with("Error:alarm emergency stop"), "{line}: {e}");
    }
    assert!(!vm.spindle_on());
    assert_eq!(xyz_now(&vm), stopped);
    ok(&mut vm, "M999");
    ok(&mut vm, "G28");
    assert_eq!(steps(&vm), [100, 100, 100, 0]);
    assert!(vm.recorder().violations_of(ViolationKind::StepWhileDisabled).is_empty());
    assert_no_violations(&vm);
}

// ------------------------------------------------------ settings, EEPROM

#[test]
fn m500_settings_survive_a_reboot_and_drive_the_motion_after_it() {
    let mut vm = boot();
    ok(&mut vm, "M92 Z400");
    ok(&mut vm, "M203 X40 Y30");
    ok(&mut vm, "M201 Y500");
    let r = ok(&mut vm, "M500");
    assert!(r.iter().any(|l| l == "echo:settings stored"), "{r:?}");
    // Changed after M500: lost at the reboot.
    ok(&mut vm, "M201 Z200");
    vm.power_cycle();
    let banner = vm.wait_banner().expect("boot after power cycle");
    assert!(!banner.iter().any(|l| l.contains("EEPROM settings invalid")));
    let r = ok(&mut vm, "M503");
    let has = |want: &str| assert!(r.iter().any(|l| l == want), "{want} not in {r:?}");
    // After a power cycle the homing lock ($22) refuses motion until homed
    // or unlocked; this test unlocks.
    let e = refused(&mut vm, "G1 X1 F600");
    assert!(e.starts_with("Error:not homed"), "{e}");
    ok(&mut vm, "M999");
    has("M92 X100.000 Y100.000 Z400.000 E177.778");
    has("M203 X40.000 Y30.000 Z50.000 E10.000");
    has("M201 X1000.000 Y500.000 Z1000.000 E50.000");
    // The recorded steps follow the stored settings: Z makes 400 steps/mm
    // (down 1 mm: 400 physical steps away from the top switch),
    // Y cruises at 30 mm/s with 500 mm/s², X rapids at 40 mm/s.
    let start = xyz_now(&vm);
    mark(&mut vm);
    run(&mut vm, "G1 Z-1 F600");
    assert_eq!(xyz_now(&vm), [start[0], start[1], start[2] + 400]);
    mark(&mut vm);
    run(&mut vm, "G1 Y15 F3000");
    assert_eq!(xyz_now(&vm)[1], start[1] + 1500);
    let vy = vm.recorder().velocity_profile(Axis::Y, 0.02).iter().map(|p| p.1).fold(0.0, f64::max);
    assert!((vy / 3000.0 - 1.0).abs() < 0.02, "Y cruise {vy} steps/s, M203 Y30 allows 3000");
    let ay = vm.recorder().max_accel(Axis::Y).unwrap();
    assert!((0.9 * 500.0 * SPMM..=1.05 * 500.0 * SPMM).contains(&ay), "Y acceleration {ay} steps/s²");
    mark(&mut vm);
    run(&mut vm, "G0 X20");
    let vx = vm.recorder().velocity_profile(Axis::X, 0.02).iter().map(|p| p.1).fold(0.0, f64::max);
    assert!((vx / 4000.0 - 1.0).abs() < 0.02, "X rapid {vx} steps/s, M203 X40 allows 4000");
    assert_no_violations(&vm);
}

// --------------------------------------------------------------- streams

#[test]
fn a_stream_of_2000_short_segments_completes_at_the_exact_final_position() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X5 Y5");
    ok(&mut vm, "G1 F3000");
    mark(&mut vm);
    // Rows of 0.1 mm segments along X, each also climbing 0.013 mm in Y (so
    // every segment's Y end is a rounding), back and forth.
    let mut lines = Vec::new();
    let mut corners = vec![[500i64, 500, 100]];
    let (mut x, mut y, mut dir) = (5.0f64, 5.0f64, 1.0f64);
    for _ in 0..2000 {
        if (x >= 39.95 && dir > 0.0) || (x <= 5.05 && dir < 0.0) {
            dir = -dir;
        }
        x += 0.1 * dir;
        y += 0.013;
        let (xs, ys) = (format!("{x:.3}"), format!("{y:.3}"));
        lines.push(format!("G1 X{xs} Y{ys}"));
        // Rounded as the firmware rounds: the f32 value × 100 steps/mm, halves up.
        let steps = |s: &str| mill::math::round_i32(s.parse::<f32>().unwrap() * 100.0) as i64;
        let t = [steps(&xs), steps(&ys), 100];
        corners.push(t);
    }
    let job = vm.stream(&lines, StreamOptions::new(Flow::CharCount(200))).unwrap();
    assert!(!job.timed_out, "stream timed out");
    assert_eq!(job.oks, 2000);
    assert!(job.errors.is_empty(), "{:?}", job.errors);
    ok(&mut vm, "M400");
    let end = *corners.last().unwrap();
    assert_eq!(xyz_now(&vm), end);
    // M114 counts Z up (the user's frame): the physical Z steps negated.
    assert_eq!(m114_counts(&mut vm), [end[0], end[1], -end[2]]);
    // Every step on its segment; not one step more or less than the targets ask.
    check_polyline(&vm, &corners, 1.0);
    let (mut xp, mut xn) = (0u64, 0u64);
    for w in corners.windows(2) {
        let d = w[1][0] - w[0][0];
        if d > 0 {
            xp += d as u64;
        } else {
            xn += (-d) as u64;
        }
    }
    assert_eq!(steps_pos_neg(&vm, Axis::X), (xp, xn));
    assert_eq!(steps_pos_neg(&vm, Axis::Y), ((end[1] - 500) as u64, 0));
    eprintln!("2000 segments: {:.3} s simulated (ideal at F3000: {:.3} s)", job.duration_s, 2000.0 * 0.1004 / 50.0);
    assert_no_violations(&vm);
}

// ------------------------------------------------------------- bad input

#[test]
fn bad_input_gets_a_clear_error_and_changes_nothing() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-10");
    ok(&mut vm, "G1 F600");
    // G80 as LinuxCNC has it (no motion mode after it), for `G80 X20` below.
    ok(&mut vm, "$154=0");
    let settings = ok(&mut vm, "M503");
    mark(&mut vm);
    let cases: &[(&str, &str)] = &[
        ("X1e99", "Error:bad number: exponent not allowed at col 1"),
        ("X-", "Error:bad number at col 1"),
        ("G1 X1e99", "Error:bad number: exponent not allowed at col 4"),
        ("G1 X-", "Error:bad number at col 4"),
        ("G1 X.", "Error:bad number at col 4"),
        ("G1 X", "Error:bad number at col 4"),
        ("G91 G1 X1 X2", "Error:word repeated at col 11"),
        ("G0 G1 X20", "Error:two codes of one modal group at col 4"),
        ("G2 X20 Y10 R2", "Error:arc: R too small"),
        ("G3 X20 Y10 I3 J0", "Error:arc: end point not on the circle"),
        ("G2 X10 Y10 R5", "Error:arc: full circle needs I/J/K"),
        ("G2 X20 Y10", "Error:arc needs R or I/J/K"),
        ("G2 X20 Y10 R5 I5", "Error:arc: give R or I/J/K"),
        ("G93 X20", "Error:unsupported code at col 1"),
        ("G19 G1 X20 G41", "Error:G41/G42 only in the XY plane (G17); G19 (YZ) is active"),
        ("M11", "Error:unsupported code at col 1"),
        // M104 alone is a printer code hosts send on their own (echo, no
        // error: tests/hosts_protocol.rs); on a line with motion it is refused.
        ("G0 X20 M104 S200", "Error:unsupported code at col 8"),
        ("G1.5 X20", "Error:unsupported code at col 1"),
        ("G1 X1000000", "Error:number out of range at col 4"),
        ("G1 X-1234567.891", "Error:number out of range at col 4"),
        ("G1 X20 F99999999999", "Error:number out of range at col 8"),
        ("G1 X99999", "Error:target outside travel"),
        // +Z is up: above the top switch (machine Z 0) is outside travel.
        ("G0 Z0.5", "Error:target outside travel"),
        ("G1 X20 F-5", "Error:F must not be negative"),
        ("G1 X20 F0", "Error:feed rate missing or not positive"),
        ("G1 A5", "Error:axis word for an axis this machine does not have (X Y Z only) at col 4"),
        ("G1 X20 (oops", "Error:unclosed comment at col 8"),
        ("G1 X20 #", "Error:# parameters and [expressions] not supported at col 8"),
        ("G1 X20 &", "Error:unexpected character at col 8"),
        ("G1 X20 @", "Error:bad number at col 8"),
        ("G1 X20 @5", "Error:polar coordinates (@ ^) with X or Y on one line"),
        ("G61 R0.5", "Error:R word with no code that uses it"),
        ("G1 X20 I1", "Error:I word with no code that uses it"),
        ("G38.2 F100", "Error:G38.2/G38.3: all axes missing with motion code"),
        ("M62 P1", "Error:M62-M65 digital outputs not supported: this machine has none at col 1"),
        ("M4 S1000", "Error:M4 not supported"),
        ("G4 P-1", "Error:G4: the dwell must not be negative"),
        ("G10 L3 P1 X0", "Error:G10: L must be 1, 2 or 20"),
        ("G10 L2 P9 X0", "Error:G10 L2/L20: P must be 0-6"),
        ("M220 S5", "Error:M220 S must be 10-500"),
        ("M92 X0", "Error:value must be positive"),
        ("M201 Y-5", "Error:value must be positive"),
        ("M203 Z0", "Error:value must be positive"),
        ("G80 X20", "Error:axis words without a motion mode"),
    ];
    for (line, want) in cases {
        let r = vm.command(line).unwrap();
        assert_eq!(r.last().map(String::as_str), Some("ok"), "{line}: {r:?}");
        let errors: Vec<&String> = r.iter().filter(|l| l.starts_with("Error:")).collect();
        assert_eq!(errors.len(), 1, "{line}: {r:?}");
        assert!(errors[0].starts_with(want), "{line}: got {:?}, want {want:?}", errors[0]);
    }
    ok(&mut vm, "M400");
    vm.run_for(0.1).unwrap();
    assert_eq!(steps_since_mark(&vm), 0, "a refused line moved the machine");
    assert_eq!(xyz_now(&vm), [1000, 1000, 1000]);
    assert_eq!(m114_counts(&mut vm), [1000, 1000, -1000]);
    // Nothing of the refused lines stuck: settings, offsets, modes, feed.
    assert_eq!(ok(&mut vm, "M503"), settings, "settings changed");
    mark(&mut vm);
    run(&mut vm, "G1 X12");
    assert_eq!(xyz_now(&vm), [1200, 1000, 1000], "still G90 and G54 with no offset");
    let vx = vm.recorder().velocity_profile(Axis::X, 0.02).iter().map(|p| p.1).fold(0.0, f64::max);
    assert!((vx / 1000.0 - 1.0).abs() < 0.02, "still F600: X ran at {vx} steps/s");
    assert!(!vm.output().contains("ALARM"));
    assert_no_violations(&vm);
}
