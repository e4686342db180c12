//! What a grbl sender's buttons and bytes must never do, on the real
//! firmware, checked against the recorded steps: an unlock (`$X`, `M999`)
//! outside an alarm changes nothing, a hard-limit alarm is recovered over
//! serial with its switch still closed, a probe that touches nothing is an
//! alarm that stops what follows, and bytes 0x80–0xFF (grbl's override
//! commands, as cncjs writes them: `C2 91`) never change which lines run.

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;
use sim::{Axis, Input, Vm};

/// User-frame mm (X, Y, Z with +Z up) to physical steps.
fn at(x: f64, y: f64, z: f64) -> [i64; 3] {
    mm_to_steps(user_to_physical_mm([x, y, z]))
}

/// The four moves of a grbl sender's job; `$X` / `M999` arrive during the
/// second one.
const JOB: [&str; 4] = ["G90 G1 X25 Y5 Z-5 F600", "G1 X5 Y6", "G1 X25 Y7", "G1 X5 Y8"];

fn unlock_mid_job(unlock: &str) {
    let mut vm = boot_homed();
    let start = xyz_now(&vm);
    for l in JOB {
        ok(&mut vm, l);
    }
    vm.run_for(1.0).unwrap();
    let before = xyz_now(&vm);
    assert_ne!(before, start, "the job is under way");
    let r = ok(&mut vm, unlock);
    assert!(!r.iter().any(|l| l.contains("cleared")), "{unlock} outside an alarm answered {r:?}");
    // While steps are produced, `?` never says Idle.
    for _ in 0..5 {
        let before = xyz_now(&vm);
        let st = status(&mut vm);
        vm.run_for(0.05).unwrap();
        if xyz_now(&vm) != before {
            assert!(st.starts_with("<Run|"), "moving, yet {st}");
        }
    }
    ok(&mut vm, "M400");
    // The whole path is the job's, corner to corner, and ends on its end.
    let corners = [start, at(25.0, 5.0, -5.0), at(5.0, 6.0, -5.0), at(25.0, 7.0, -5.0), at(5.0, 8.0, -5.0)];
    check_polyline(&vm, &corners, 1.0);
    assert!(status(&mut vm).starts_with("<Idle|"));
    assert!(!vm.output().contains("ALARM"), "{}", vm.output());
    assert_no_violations(&vm);
}

#[test]
fn dollar_x_during_motion_changes_nothing() {
    unlock_mid_job("$X");
}

#[test]
fn m999_during_motion_changes_nothing() {
    unlock_mid_job("M999");
}

/// Soft limits off, X driven into its own switch: a hard limit with the
/// switch held closed (the axis stopped on it).
fn onto_the_x_switch() -> Vm {
    let mut vm = boot_homed();
    ok(&mut vm, "$20=0");
    run(&mut vm, "G0 X10 Y20 Z-10");
    ok(&mut vm, "G1 X-5 F300");
    let alarm = vm.wait_line(|l| l.starts_with("ALARM:"), 5.0).expect("hard limit");
    assert_eq!(alarm, "ALARM:hard limit");
    vm.run_for(0.3).unwrap();
    assert!(vm.position(Axis::X) <= 5, "stopped at the switch: X {}", vm.position(Axis::X));
    assert!(vm.input_active(Input::HomeX), "the X switch is still closed");
    vm.take_lines();
    vm
}

#[test]
fn unlock_then_jog_off_a_closed_switch_with_the_other_limits_armed() {
    let mut vm = onto_the_x_switch();
    ok(&mut vm, "$X");
    vm.run_for(0.2).unwrap();
    assert!(!vm.output().rsplit("ALARM:hard limit").next().unwrap().contains("ALARM"), "re-alarmed at once");
    assert!(status(&mut vm).starts_with("<Idle|"));
    // Off the switch: the jog runs to its end, the switch opens.
    let x0 = vm.position(Axis::X);
    run(&mut vm, "G91 G1 X3 F300");
    assert_eq!(vm.position(Axis::X), x0 + 300);
    assert!(!vm.input_active(Input::HomeX));
    assert!(!vm.output().rsplit("ALARM:hard limit").next().unwrap().contains("ALARM"));
    // X is watched again once its switch opened: back into it is an alarm
    // (a Marlin host's text; a grbl sender would read ALARM:1).
    ok(&mut vm, "G1 X-5 F300");
    assert_eq!(vm.wait_line(|l| l.starts_with("ALARM:"), 3.0).unwrap(), "ALARM:hard limit");
    vm.run_for(0.2).unwrap();
    assert!(vm.position(Axis::X) <= 5, "X {}", vm.position(Axis::X));
    // Y stayed watched all along, even while X was not.
    ok(&mut vm, "$X");
    ok(&mut vm, "G1 Y-30 F600");
    assert_eq!(vm.wait_line(|l| l.starts_with("ALARM:"), 5.0).unwrap(), "ALARM:hard limit");
    vm.run_for(0.2).unwrap();
    assert!(vm.position(Axis::Y) <= 5, "Y {}", vm.position(Axis::Y));
}

#[test]
fn unlock_then_home_with_the_switch_still_closed() {
    for unlock in ["$X", "M999"] {
        let mut vm = onto_the_x_switch();
        ok(&mut vm, unlock);
        vm.run_for(0.2).unwrap();
        ok(&mut vm, "$H");
        assert_eq!(steps(&vm), [100, 100, 100, 0], "{unlock}, then $H");
        assert!(status(&mut vm).starts_with("<Idle|"));
        // Homed again: the soft limits are back with `$20=1`, hard limits watch.
        ok(&mut vm, "$20=1");
        run(&mut vm, "G0 X20 Y20");
        assert_eq!(xyz_now(&vm)[..2], [2000, 2000]);
    }
}

#[test]
fn a_probe_that_touches_nothing_is_an_alarm_and_stops_what_follows() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X30 Y30 Z-2");
    // G38.3 may miss: no alarm.
    let r = ok(&mut vm, "G38.3 Z-6 F300");
    assert!(r.iter().any(|l| l.ends_with(":0]")), "{r:?}");
    assert!(status(&mut vm).starts_with("<Idle|"));
    // G38.2 must touch: reaching its target is ALARM (grbl's ALARM:5).
    vm.send_line("G38.2 Z-10 F300");
    vm.send_line("G92 Z0");
    vm.send_line("G10 L20 P1 X0 Y0");
    assert_eq!(vm.wait_line(|l| l.starts_with("ALARM:"), 10.0).unwrap(), "ALARM:probe failed");
    let mut replies = Vec::new();
    while replies.iter().filter(|l| *l == "ok").count() < 3 {
        replies.push(vm.wait_line(|_| true, 2.0).expect("a reply to each line"));
    }
    let errors: Vec<_> = replies.iter().filter(|l| l.starts_with("Error:")).collect();
    assert_eq!(errors.len(), 3, "the probe line and both zeroing lines after it are refused: {replies:?}");
    assert!(errors[1..].iter().all(|e| e.starts_with("Error:alarm probe failed")), "{replies:?}");
    assert!(status(&mut vm).starts_with("<Alarm|"));
    // Nothing was zeroed: the work position is the machine position.
    ok(&mut vm, "M999");
    let st = status(&mut vm);
    assert!(st.contains("|MPos:30.000,30.000,-10.000|"), "{st}");
    ok(&mut vm, "$10=0");
    let st = status(&mut vm);
    assert!(st.contains("|WPos:30.000,30.000,-10.000|"), "{st}");
    // The position is still exact, so the machine stays homed.
    run(&mut vm, "G0 Z-2");
    assert_eq!(xyz_now(&vm), at(30.0, 30.0, -2.0));
}

/// `G91 G1 X0.2` lines sent one at a time (as a grbl sender in
/// send-response mode); `inject(i)` gives bytes to put inside line `i`.
fn run_with_bytes(n: usize, mut inject: impl FnMut(usize) -> Vec<u8>) -> Vm {
    let mut vm = boot_homed();
    run(&mut vm, "G90 G0 X2 Y2 Z-2");
    ok(&mut vm, "G91");
    mark(&mut vm);
    for i in 0..n {
        let mut bytes = b"G1 X0.2".to_vec();
        bytes.extend(inject(i));
        bytes.extend(b" F1200\n");
        vm.send(&bytes);
        let ok_line = vm.wait_line(|l| l == "ok", 5.0).unwrap_or_else(|e| panic!("line {i}: {e}"));
        assert_eq!(ok_line, "ok");
    }
    ok(&mut vm, "G90");
    ok(&mut vm, "M400");
    vm
}

#[test]
fn override_bytes_as_cncjs_sends_them_drop_no_line() {
    // cncjs's feed +10 % button: 0x91 written as UTF-8, C2 91.
    let vm = run_with_bytes(80, |i| if i % 7 == 3 { vec![0xC2, 0x91] } else { vec![] });
    assert!(!vm.output().contains("Error"), "{}", vm.output());
    assert_eq!(xyz_now(&vm), at(2.0 + 80.0 * 0.2, 2.0, -2.0));
}

#[test]
fn every_byte_from_0x80_to_0xff_is_taken_out_of_the_line() {
    let vm = run_with_bytes(128, |i| vec![0x80 + i as u8]);
    assert!(!vm.output().contains("Error"), "{}", vm.output());
    assert_eq!(xyz_now(&vm), at(2.0 + 128.0 * 0.2, 2.0, -2.0));
}

/// 200 random moves inside the travel, sent with 0x80–0xFF, `?`, `!` and
/// `~` injected at random instants (between bytes of a line, and while it
/// runs): every line runs, in order, the path stays the job's and inside
/// the soft limits, and it ends on the job's own end.
#[test]
fn random_realtime_bytes_never_change_which_lines_run() {
    let mut rng = Rng(0x5AFE_1234);
    let mut vm = boot_homed();
    let mut corners = vec![xyz_now(&vm)];
    let mut lines = Vec::new();
    for _ in 0..200 {
        let mut p = [0.0; 3];
        for (a, v) in p.iter_mut().enumerate() {
            let r = (rng.next() % 4000) as f64 / 100.0 + 2.0; // 2..42 mm
            *v = if a == 2 { -r } else { r };
        }
        // Whole steps: the path's corners are exact.
        p = p.map(|v| (v * 100.0).round() / 100.0);
        lines.push(format!("G1 X{:.2} Y{:.2} Z{:.2} F6000", p[0], p[1], p[2]));
        corners.push(at(p[0], p[1], p[2]));
    }
    let mut held = false;
    for (i, l) in lines.iter().enumerate() {
        for &b in l.as_bytes().iter().chain(b"\n") {
            if rng.next().is_multiple_of(8) {
                let k = match rng.next() % 6 {
                    0 => b'?',
                    1 => b'!',
                    2 => b'~',
                    _ => 0x80 + (rng.next() % 128) as u8,
                };
                held = (held || k == b'!') && k != b'~';
                vm.send([k]);
            }
            vm.send([b]);
        }
        // Let it run a little, sometimes held; then resume and take the ok.
        vm.run_for((rng.next() % 20) as f64 / 1000.0).unwrap();
        if held {
            vm.send(b"~");
            held = false;
        }
        let got = vm.wait_line(|l| l == "ok" || l.starts_with("Error"), 20.0).unwrap_or_else(|e| panic!("line {i}: {e}"));
        assert_eq!(got, "ok", "line {i} ({l}): {}", vm.output());
    }
    vm.send(b"~");
    ok(&mut vm, "M400");
    assert!(!vm.output().contains("Error") && !vm.output().contains("ALARM"), "{}", vm.output());
    check_polyline(&vm, &corners, 1.0);
    for p in events(&vm) {
        for a in 0..3 {
            assert!((0..=4500).contains(&p.position[a]), "outside the travel: {:?}", p.position);
        }
    }
}
