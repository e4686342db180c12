//! Overload (docs/SPEC.md §11): a feed asking for more steps per second than the
//! stepper ISR can deliver is capped by the planner at
//! `config::MAX_STEP_RATE_HZ`, with a warning, and the move still ends on the
//! exact step, with no crash, no reset and no driver timing violation. grbl-Mega
//! in simavr crashes there (ISR nesting runaway above ~44 kHz commanded).

mod common;

use common::*;
use mill::config::MAX_STEP_RATE_HZ;
use sim::{Axis, Vm, VmConfig};

const WARNING: &str = "echo:warning: feed capped to the maximum step rate";

/// Boots with no travel check in the VM (the tests raise steps/mm) and
/// unlocks the homing lock.
fn boot_unlocked() -> Vm {
    let mut cfg = VmConfig::default();
    cfg.machine.travel_steps = [None; 4];
    // Off the switches: an unhomed axis starting on its closed switch would
    // (rightly) raise a hard-limit alarm on the first move.
    cfg.machine.initial_position = [100, 100, 100, 0];
    let mut vm = boot_with(cfg);
    ok(&mut vm, "M999");
    vm
}

/// Step rate over the middle half of an axis' steps (the cruise), Hz.
fn cruise_rate(vm: &Vm, axis: Axis) -> f64 {
    let t: Vec<u64> = vm.recorder().trace().iter().filter(|p| p.axis == axis).map(|p| p.cycle).collect();
    assert!(t.len() > 100, "{axis}: only {} steps", t.len());
    let (a, b) = (t.len() / 4, 3 * t.len() / 4);
    (b - a) as f64 * 16e6 / (t[b] - t[a]) as f64
}

/// Checks what every overloaded move must leave behind.
fn assert_clean(vm: &Vm) {
    assert_eq!(vm.resets().len(), 1, "the firmware reset: {:?}", vm.resets());
    assert!(vm.violations().is_empty(), "{:?}", &vm.violations()[..vm.violations().len().min(5)]);
    assert!(vm.fatal_error().is_none(), "{:?}", vm.fatal_error());
    assert_eq!(vm.max_interrupt_depth(), 1, "interrupts nested");
    let isr = vm.stepper_isr_stats().expect("stepper ISR ran");
    assert!(isr.max_cycles <= 400, "stepper ISR worst case {} cycles", isr.max_cycles);
}

#[test]
fn a_single_axis_feed_at_twice_the_isr_rate_is_capped_with_a_warning_and_ends_on_the_exact_step() {
    let mut vm = boot_unlocked();
    ok(&mut vm, "M92 X1000");
    ok(&mut vm, "M203 X1000"); // mm/s: far above what the ISR allows
    ok(&mut vm, "M201 X2000");
    // 2 × MAX_STEP_RATE_HZ at 1000 steps/mm, in mm/min.
    let feed = 2.0 * MAX_STEP_RATE_HZ as f64 / 1000.0 * 60.0;
    let reply = ok(&mut vm, &format!("G1 X40 F{feed:.0}"));
    assert!(reply.iter().any(|l| l == WARNING), "no warning: {reply:?}");
    ok(&mut vm, "M400");
    vm.run_for(0.01).unwrap();
    // Every step, in the right direction, and the firmware agrees.
    let x = vm.recorder().axis_stats(Axis::X);
    assert_eq!((x.steps_pos, x.steps_neg), (40_000, 0));
    let m114 = ok(&mut vm, "M114");
    assert!(m114[0].contains("Count X:40000 "), "{m114:?}");
    // The rate is the cap: not more, and not much less (no stall).
    let rate = cruise_rate(&vm, Axis::X);
    let cap = MAX_STEP_RATE_HZ as f64;
    assert!(rate <= cap * 1.001 && rate >= cap * 0.98, "cruise at {rate:.0} Hz, cap {cap:.0} Hz");
    assert_clean(&vm);
    // Still answering, still moving (back to 1 mm from the start).
    ok(&mut vm, "G1 X1 F600");
    ok(&mut vm, "M400");
    assert_eq!(vm.position(Axis::X), 100 + 1000);
}

#[test]
fn four_axes_at_twice_the_isr_rate_are_capped_and_every_axis_ends_on_the_exact_step() {
    let mut vm = boot_unlocked();
    ok(&mut vm, "M92 X400 Y400 Z400 E400");
    ok(&mut vm, "M203 X1000 Y1000 Z1000 E1000");
    ok(&mut vm, "M201 X5000 Y5000 Z5000 E5000");
    // The dominant axis asks for 2 × the cap; the others make slightly fewer
    // steps, so the Bresenham works on every axis (the ISR's worst case).
    // Z-29.98 is down (+Z up): physical Z steps count down from the switch.
    let feed = 2.0 * MAX_STEP_RATE_HZ as f64 / 400.0 * 60.0 * 2.0; // along a 4-axis diagonal
    let reply = ok(&mut vm, &format!("G1 X30 Y29.99 Z-29.98 E29.97 F{feed:.0}"));
    assert!(reply.iter().any(|l| l == WARNING), "no warning: {reply:?}");
    ok(&mut vm, "M400");
    vm.run_for(0.01).unwrap();
    assert_eq!(vm.positions(), [100 + 12_000, 100 + 11_996, 100 + 11_992, 11_988]);
    let cap = MAX_STEP_RATE_HZ as f64;
    for a in [Axis::X, Axis::Y, Axis::Z, Axis::E] {
        let rate = cruise_rate(&vm, a);
        assert!(rate <= cap * 1.001 && rate >= cap * 0.97, "{a} cruise at {rate:.0} Hz, cap {cap:.0} Hz");
    }
    assert_clean(&vm);
}

/// A stream the CPU cannot keep up with (`tools/bench`'s CPU row: the
/// 2,000 chords of 0.1 mm at F12000 and 5000 mm/s², 254 bytes in flight,
/// over 3 s): every line is answered, without an error, and the firmware
/// never resets. Lines waiting back to back must not keep the main loop
/// from its turn for longer than the watchdog's 2 s (topping the segment
/// ring up from inside the line loop did: the board reset mid-stream).
#[test]
fn a_stream_of_short_moves_faster_than_the_cpu_is_answered_without_a_reset() {
    let mut vm = boot_unlocked();
    ok(&mut vm, "M201 X5000 Y5000");
    for l in sim::circle::setup(12_000.0) {
        ok(&mut vm, &l);
    }
    let moves = sim::circle::moves();
    let rep = vm.stream(&moves, sim::StreamOptions::new(sim::Flow::CharCount(254)).timeout(20.0)).unwrap();
    assert!(!rep.timed_out, "stream timed out after {} of {} oks; resets {:?}", rep.oks, moves.len(), vm.resets());
    assert_eq!(rep.oks, moves.len(), "every line answered");
    assert!(rep.errors.is_empty(), "{:?}", rep.errors);
    ok(&mut vm, "M400");
    vm.run_for(0.01).unwrap();
    assert_clean(&vm);
}
