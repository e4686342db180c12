//! Panics stop the machine (issue 11): any panic or `abort` of the firmware
//! ends in the same safe state as M112 (stepper drivers disabled, spindle
//! off), with an `ALARM:` line on the serial port, and stays halted: no
//! further step, no answer, and no watchdog reset that would restart it
//! silently (`src/board/halt.rs`).
//!
//! The firmware has no panic a host can reach on purpose, so these tests run
//! a test build (`--features panic-test`, `target/variants/panic-test.elf`
//! from tools/build-variants, `$MILL_ELF_PANIC`) in which the line `M9999`
//! panics and `M9998` calls the abort intrinsic (what every panic becomes
//! with `panic = "immediate-abort"`; LLVM's AVR backend makes it a call to
//! `abort`, which the firmware defines) from the serial → parser path, in the
//! middle of a move with the spindle on.

mod common;
use common::*;
use sim::{Axis, Vm, VmConfig};
use std::path::PathBuf;

fn panic_elf() -> PathBuf {
    let p = std::env::var_os("MILL_ELF_PANIC")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/variants/panic-test.elf"));
    assert!(p.exists(), "{} missing: run tools/build-variants (tools/test does)", p.display());
    p
}

const AXES: [Axis; 4] = [Axis::X, Axis::Y, Axis::Z, Axis::E];

/// Start a long move with the spindle on, send `trigger` mid-move, and check
/// the halt; returns the alarm line.
fn stops_mid_move(trigger: &str) -> String {
    let mut vm: Vm = boot_with(VmConfig::new(panic_elf()));
    ok(&mut vm, "M999");
    ok(&mut vm, "M3 S5000");
    ok(&mut vm, "G1 X40 E2 F600");
    vm.run_for(0.5).unwrap();
    assert!(vm.spindle_on() && vm.spindle_duty() > 0.4, "spindle {}", vm.spindle_duty());
    assert!(AXES.iter().all(|&a| vm.driver_enabled(a)), "drivers on while moving");
    let moving = total_steps(&vm);
    assert!(moving > 100, "{moving} steps before the trigger");
    vm.take_lines();

    vm.send_line(trigger);
    let alarm = vm.wait_line(|l| l.starts_with("ALARM:"), 0.5).unwrap_or_else(|e| panic!("{e}: {}", vm.output()));
    let at = vm.cycles();
    // The M112 state: every driver disabled (enable pins high), spindle PWM off.
    assert!(AXES.iter().all(|&a| !vm.driver_enabled(a)), "a driver is still enabled");
    assert!(!vm.spindle_on() && vm.spindle_duty() == 0.0, "spindle {}", vm.spindle_duty());
    // Halted for good: 5 s (past the 2 s watchdog) without a step, a reset,
    // a line, or an answer.
    let steps = total_steps(&vm);
    vm.run_for(5.0).unwrap();
    let e = vm.command_timeout("M115", 1.0);
    assert!(e.is_err(), "a halted firmware answered: {e:?}");
    assert_eq!(total_steps(&vm), steps, "steps after the alarm");
    assert!(vm.recorder().trace().iter().all(|t| t.cycle <= at), "steps after the alarm");
    assert_eq!(vm.resets().len(), 1, "reset after the halt: {:?}", vm.resets());
    assert!(vm.take_lines().is_empty(), "output after the alarm");
    assert!(AXES.iter().all(|&a| !vm.driver_enabled(a)) && !vm.spindle_on());
    alarm
}

#[test]
fn a_panic_mid_move_stops_like_m112_reports_an_alarm_and_halts() {
    let alarm = stops_mid_move("M9999");
    assert_eq!(alarm, "ALARM:firmware panic, halted: reset the board");
}

#[test]
fn an_abort_mid_move_stops_like_m112_reports_an_alarm_and_halts() {
    let alarm = stops_mid_move("M9998");
    assert_eq!(alarm, "ALARM:firmware abort, halted: reset the board");
}
