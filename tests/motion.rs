//! Motion on the real firmware (docs/SPEC.md §5, §6), in the virtual
//! machine: homing, straight lines, arcs, units, offsets and soft limits, each
//! checked against the steps the recorder saw, not only the firmware's replies.
//! Faults, feed hold, settings and streams are in `tests/motion_faults.rs`.
//!
//! G-code and reports are in the user's frame (+Z up, machine Z 0 at the top
//! switch, negative below it); the recorder's physical steps count Z downward
//! from the switch, so G-code `Z-5` is physical Z step 500.

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;
use sim::{Axis, Flow, Input, StreamOptions, VmConfig};

// ---------------------------------------------------------------- homing

/// Positions where an axis turned around, with the VM cycle of the turn.
fn turning_points(vm: &sim::Vm, axis: Axis) -> Vec<(u64, i64)> {
    let tr: Vec<_> = vm.recorder().trace().iter().filter(|t| t.axis == axis).copied().collect();
    let mut out = Vec::new();
    for w in tr.windows(3) {
        let (a, b, c) = (w[0].position, w[1].position, w[2].position);
        if (b - a) * (c - b) < 0 {
            out.push((w[1].cycle, b));
        }
    }
    if let Some(l) = tr.last() {
        out.push((l.cycle, l.position));
    }
    out
}

#[test]
fn g28_homes_z_then_y_then_x_and_machine_zero_is_where_each_switch_trips() {
    let mut cfg = VmConfig::default();
    cfg.machine.initial_position = [1500, 1200, 900, 0];
    let mut vm = boot_with(cfg);
    ok(&mut vm, "G28");
    assert_no_violations(&vm);
    let tr = vm.recorder().trace();
    let span = |a: Axis| {
        let c: Vec<u64> = tr.iter().filter(|t| t.axis == a).map(|t| t.cycle).collect();
        (*c.first().unwrap(), *c.last().unwrap())
    };
    let (z, y, x) = (span(Axis::Z), span(Axis::Y), span(Axis::X));
    assert!(z.1 < y.0, "Y started before Z finished: Z {z:?} Y {y:?}");
    assert!(y.1 < x.0, "X started before Y finished: Y {y:?} X {x:?}");
    assert!(tr.iter().all(|t| t.axis != Axis::E), "the carousel moved");
    // Each axis: fast seek to the switch (physical 0), back off 1 mm, slow
    // re-seek to the switch, back off 1 mm. It never goes past the switch.
    for a in [Axis::X, Axis::Y, Axis::Z] {
        let turns: Vec<i64> = turning_points(&vm, a).iter().map(|t| t.1).collect();
        assert_eq!(turns, vec![0, 100, 0, 100], "{a} turning points");
        let min = tr.iter().filter(|t| t.axis == a).map(|t| t.position).min().unwrap();
        assert_eq!(min, 0, "{a} went past its switch");
        // The re-seek is slow (homing feed 100 mm/min = 166.7 steps/s) and
        // the first seek fast (1200 mm/min).
        let turns = turning_points(&vm, a);
        let steps: Vec<_> = tr.iter().filter(|t| t.axis == a).collect();
        let interval_before = |cycle: u64| {
            let i = steps.iter().position(|t| t.cycle == cycle).unwrap();
            steps[i].cycle - steps[i - 1].cycle
        };
        let slow = interval_before(turns[2].0) as f64 / 16e6;
        let fast = interval_before(turns[0].0) as f64 / 16e6;
        assert!((slow * 166.67 - 1.0).abs() < 0.05, "{a}: slow approach step interval {slow} s");
        assert!((fast * 2000.0 - 1.0).abs() < 0.05, "{a}: fast seek step interval {fast} s");
    }
    assert_eq!(steps(&vm), [100, 100, 100, 0]);
    // Z 1 mm below its top switch: −1 with +Z up.
    assert_eq!(m114_counts(&mut vm), [100, 100, -100]);
    assert_eq!(m114_work(&mut vm), [1.0, 1.0, -1.0]);
    // Machine 0 is exactly the switch point: at X0 the switch reads closed;
    // the VM's real switches (0.05 mm of hysteresis) stay closed one and
    // five steps off it and open at six, and none of these moves near the
    // switch raises a hard limit.
    mark(&mut vm);
    run(&mut vm, "G0 X0 Y0 Z0");
    assert_eq!(steps(&vm), [0, 0, 0, 0]);
    let m119 = |vm: &mut sim::Vm, want: &str| {
        // Past the contacts' bounce (3 ms).
        vm.run_for(0.01).unwrap();
        let r = ok(vm, "M119");
        for axis in ["x_min", "y_min", "z_min"] {
            assert!(r.iter().any(|l| l == &format!("{axis}: {want}")), "{r:?}");
        }
    };
    m119(&mut vm, "TRIGGERED");
    run(&mut vm, "G0 X0.01 Y0.01 Z-0.01");
    assert_eq!(steps(&vm), [1, 1, 1, 0]);
    m119(&mut vm, "TRIGGERED");
    run(&mut vm, "G0 X0.05 Y0.05 Z-0.05");
    m119(&mut vm, "TRIGGERED");
    run(&mut vm, "G0 X0.06 Y0.06 Z-0.06");
    assert_eq!(steps(&vm), [6, 6, 6, 0]);
    m119(&mut vm, "open");
    assert!(!vm.output().contains("ALARM"), "{}", vm.output());
    assert_no_violations(&vm);
}

#[test]
fn g28_with_named_axes_homes_only_those_still_in_z_y_x_order() {
    let mut cfg = VmConfig::default();
    cfg.machine.initial_position = [700, 800, 900, 0];
    let mut vm = boot_with(cfg);
    ok(&mut vm, "G28 Y");
    assert_eq!(steps(&vm), [700, 100, 900, 0]);
    assert!(vm.recorder().trace().iter().all(|t| t.axis == Axis::Y));
    mark(&mut vm);
    // Words with values name axes too (G28 X0 Z0); Z still goes first.
    ok(&mut vm, "G28 X0 Z0");
    assert_eq!(steps(&vm), [100, 100, 100, 0]);
    let tr = vm.recorder().trace();
    assert!(tr.iter().all(|t| t.axis != Axis::Y), "Y moved");
    let last_z = tr.iter().filter(|t| t.axis == Axis::Z).map(|t| t.cycle).max().unwrap();
    let first_x = tr.iter().filter(|t| t.axis == Axis::X).map(|t| t.cycle).min().unwrap();
    assert!(last_z < first_x, "X homed before Z");
    // The homed axes report 1 mm off their switches (Z below its top one);
    // the work position follows the machine's.
    assert_eq!(m114_counts(&mut vm), [100, 100, -100]);
    assert_no_violations(&vm);
}

#[test]
fn g28_starting_on_a_switch_moves_off_it_first() {
    let mut cfg = VmConfig::default();
    cfg.machine.initial_position = [0, 300, 300, 0];
    let mut vm = boot_with(cfg);
    assert!(vm.input_active(Input::HomeX));
    ok(&mut vm, "G28 X");
    assert_eq!(steps(&vm), [100, 300, 300, 0]);
    let min = vm.recorder().trace().iter().map(|t| t.position).min().unwrap();
    assert_eq!(min, 0, "never past the switch");
    assert_no_violations(&vm);
}

#[test]
fn g28_raises_an_alarm_when_a_switch_is_not_found_within_travel_plus_10_percent() {
    let mut cfg = VmConfig::default();
    cfg.machine.initial_position = [300, 300, 300, 0];
    // Z's switch is broken: it never closes.
    cfg.machine.travel_margin_steps = [100, 100, 10_000, 0];
    let mut vm = boot_with(cfg);
    vm.set_input(Input::HomeZ, Some(false));
    let r = vm.command("G28").unwrap();
    assert!(r.iter().any(|l| l == "ALARM:homing failed"), "{r:?}");
    assert!(r.iter().any(|l| l.starts_with("Error:homing failed")), "{r:?}");
    // Z searched exactly 49.5 mm (45 mm + 10 %) and stopped; Y and X never moved.
    assert_eq!(steps(&vm), [300, 300, 300 - 4950, 0]);
    assert!(vm.recorder().trace().iter().all(|t| t.axis == Axis::Z));
    let e = refused(&mut vm, "G0 Z-10");
    assert!(e.starts_with("Error:alarm homing failed"), "{e}");
}

// ---------------------------------------------------------------- lines

#[test]
fn a_square_stays_within_one_step_of_its_sides_and_closes_exactly() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10");
    mark(&mut vm);
    ok(&mut vm, "G1 X30 F1500");
    ok(&mut vm, "Y30");
    ok(&mut vm, "X10");
    ok(&mut vm, "Y10");
    ok(&mut vm, "M400");
    let corners = [[1000, 1000, 100], [3000, 1000, 100], [3000, 3000, 100], [1000, 3000, 100], [1000, 1000, 100]];
    let worst = check_polyline(&vm, &corners, 1.0);
    assert_eq!(worst, 0.0, "axis-parallel sides leave no room for error");
    // Each side is exactly 2000 steps on one axis, no step lost or added.
    assert_eq!(steps_pos_neg(&vm, Axis::X), (2000, 2000));
    assert_eq!(steps_pos_neg(&vm, Axis::Y), (2000, 2000));
    assert_eq!(m114_counts(&mut vm), [1000, 1000, -100]);
    assert_no_violations(&vm);
}

#[test]
fn diagonals_in_two_and_three_axes_stay_within_one_step_and_end_exactly() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X5 Y5 Z-5");
    mark(&mut vm);
    // Slopes that never divide evenly: every minor-axis step is a rounding.
    ok(&mut vm, "G1 X38.73 Y17.29 F2000");
    ok(&mut vm, "X12.34 Y41.07 Z-23.45");
    ok(&mut vm, "X5 Y5 Z-5");
    ok(&mut vm, "M400");
    let corners = [[500, 500, 500], [3873, 1729, 500], [1234, 4107, 2345], [500, 500, 500]];
    let worst = check_polyline(&vm, &corners, 1.0);
    assert!(worst > 0.0);
    assert_eq!(m114_counts(&mut vm), [500, 500, -500]);
    assert_no_violations(&vm);
}

// ----------------------------------------------------------------- arcs

/// Max distance from the ideal arc, per axis: the chord error (tolerance) + 1 step.
const ARC_DEV: f64 = ARC_TOL_MM * SPMM + 1.0;
const TWO_PI: f64 = 2.0 * std::f64::consts::PI;

/// Runs a full circle (one command, or two half circles with R) and checks
/// every recorded step against the ideal circle. `start_mm`, `centre_mm`
/// and `expect_sweep` (signed, in the plane's (axis_0, axis_1)) are in the
/// user's frame (+Z up); the check runs on the physical steps (Z down),
/// where a plane containing Z (G18, G19) is mirrored and turns the other way.
fn circle(plane_code: &str, plane: (usize, usize, usize), start_mm: [f64; 3], centre_mm: [f64; 2], cmds: &[&str], expect_sweep: f64) {
    let mut vm = boot_homed();
    ok(&mut vm, plane_code);
    run(&mut vm, &format!("G0 X{} Y{} Z{}", start_mm[0], start_mm[1], start_mm[2]));
    mark(&mut vm);
    for c in cmds {
        ok(&mut vm, c);
    }
    ok(&mut vm, "M400");
    let start = mm_to_steps(user_to_physical_mm(start_mm));
    let (a0, a1, _) = plane;
    let r = ((start_mm[a0] - centre_mm[0]).powi(2) + (start_mm[a1] - centre_mm[1]).powi(2)).sqrt() * SPMM;
    let flip = |a: usize| if a == 2 { -1.0 } else { 1.0 };
    let c = [centre_mm[0] * SPMM * flip(a0), centre_mm[1] * SPMM * flip(a1)];
    let got = check_arc(&vm, plane, c, r, start, start, ARC_DEV);
    let user_swept = got.swept * flip(a0) * flip(a1);
    assert!((user_swept - expect_sweep).abs() < 0.01, "{plane_code} {cmds:?}: swept {user_swept} rad (+Z up), want {expect_sweep}");
    // The off-plane axis never moves.
    let normal = plane.2;
    assert!(vm.recorder().trace().iter().all(|t| t.axis.index() != normal), "{plane_code}: normal axis moved");
    assert_no_violations(&vm);
}

#[test]
fn g17_full_circles_g2_ijk_and_g3_by_two_r_halves_follow_the_ideal_circle() {
    // G2 is clockwise seen from +Z: the angle in (X, Y) decreases.
    circle("G17", (0, 1, 2), [30.0, 22.5, -10.0], [22.5, 22.5], &["G2 X30 Y22.5 I-7.5 J0 F1500"], -TWO_PI);
    circle("G17", (0, 1, 2), [30.0, 22.5, -10.0], [22.5, 22.5], &["G3 X15 Y22.5 R7.5 F1500", "G3 X30 Y22.5 R7.5"], TWO_PI);
}

#[test]
fn g18_full_circles_g2_ijk_and_g3_by_two_r_halves_follow_the_ideal_circle() {
    // G18 is the ZX plane: angles are measured in (Z, X); G2 is clockwise
    // seen from +Y (RS274/NGC, right-handed with +Z up): the angle decreases.
    circle("G18", (2, 0, 1), [22.5, 10.0, -30.0], [-22.5, 22.5], &["G2 X22.5 Z-30 I0 K7.5 F1500"], -TWO_PI);
    circle("G18", (2, 0, 1), [22.5, 10.0, -30.0], [-22.5, 22.5], &["G3 Z-15 R7.5 F1500", "G3 Z-30 R7.5"], TWO_PI);
}

#[test]
fn g19_full_circles_g2_ijk_and_g3_by_two_r_halves_follow_the_ideal_circle() {
    // G19 is the YZ plane: angles in (Y, Z); G2 is clockwise seen from +X.
    circle("G19", (1, 2, 0), [10.0, 30.0, -22.5], [22.5, -22.5], &["G2 Y30 Z-22.5 J-7.5 K0 F1500"], -TWO_PI);
    circle("G19", (1, 2, 0), [10.0, 30.0, -22.5], [22.5, -22.5], &["G3 Y15 R7.5 F1500", "G3 Y30 R7.5"], TWO_PI);
}

#[test]
fn a_helix_follows_the_circle_and_descends_in_proportion_to_the_angle() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X30 Y22.5 Z-5");
    mark(&mut vm);
    // One and a bit turns are not expressible in one G2: a full turn that
    // moves Z down by 6 mm (physical Z steps grow downward).
    ok(&mut vm, "G17 G2 X30 Y22.5 Z-11 I-7.5 J0 F1200");
    ok(&mut vm, "M400");
    let got = check_arc(&vm, (0, 1, 2), [2250.0, 2250.0], 750.0, [3000, 2250, 500], [3000, 2250, 1100], ARC_DEV);
    assert!((got.swept + TWO_PI).abs() < 0.01, "swept {}", got.swept);
    assert!(got.worst_linear <= 1.0 + 1e-9, "Z off the helix by {} steps", got.worst_linear);
    assert_eq!(steps_pos_neg(&vm, Axis::Z), (600, 0), "Z moves one way only");
    assert_no_violations(&vm);
}

#[test]
fn a_quarter_arc_with_r_takes_the_short_way_and_negative_r_the_long_way() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X30 Y22.5 Z-5");
    mark(&mut vm);
    // From (30, 22.5) to (22.5, 30) counter-clockwise: R+ is the quarter
    // around (22.5, 22.5), R- the three quarters around (30, 30).
    ok(&mut vm, "G3 X22.5 Y30 R7.5 F1500");
    ok(&mut vm, "M400");
    let got = check_arc(&vm, (0, 1, 2), [2250.0, 2250.0], 750.0, [3000, 2250, 500], [2250, 3000, 500], ARC_DEV);
    assert!((got.swept - TWO_PI / 4.0).abs() < 0.01, "{}", got.swept);
    mark(&mut vm);
    ok(&mut vm, "G2 X30 Y22.5 R-7.5");
    ok(&mut vm, "M400");
    let got = check_arc(&vm, (0, 1, 2), [3000.0, 3000.0], 750.0, [2250, 3000, 500], [3000, 2250, 500], ARC_DEV);
    assert!((got.swept + 0.75 * TWO_PI).abs() < 0.01, "{}", got.swept);
    assert_no_violations(&vm);
}

// ------------------------------------------------- units, modes, offsets

#[test]
fn g20_takes_inches_for_positions_and_feed() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X2 Y2");
    mark(&mut vm);
    // 1.2 in = 30.48 mm; F20 in/min = 508 mm/min = 846.7 steps/s.
    run(&mut vm, "G20 G1 X1.2 Y0.3 F20");
    assert_eq!(xyz_now(&vm), [3048, 762, 100]);
    check_polyline(&vm, &[[200, 200, 100], [3048, 762, 100]], 1.0);
    // The cruise speed along the path: the dominant X runs at 20 in/min × its share.
    let share = 28.48 / (28.48f64.powi(2) + 5.62f64.powi(2)).sqrt();
    let want = 508.0 / 60.0 * SPMM * share;
    let vmax = vm.recorder().velocity_profile(Axis::X, 0.02).iter().map(|p| p.1).fold(0.0, f64::max);
    assert!((vmax / want - 1.0).abs() < 0.02, "X cruise {vmax} steps/s, want {want}");
    // Back to mm: the same numbers are millimetres again.
    mark(&mut vm);
    run(&mut vm, "G21 G1 X1.2 Y0.3");
    assert_eq!(xyz_now(&vm), [120, 30, 100]);
    // M114 reports in mm.
    assert_eq!(m114_work(&mut vm), [1.2, 0.3, -1.0]);
    assert_no_violations(&vm);
}

#[test]
fn g91_moves_are_relative_to_the_last_position_and_g90_restores_absolute() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-10");
    mark(&mut vm);
    ok(&mut vm, "G91 G1 X5 Y-2.5 F1500");
    ok(&mut vm, "X5 Y-2.5");
    // An increment of −0.01 mm goes down: one physical step further from the switch.
    ok(&mut vm, "Z-0.01");
    ok(&mut vm, "M400");
    let corners = [[1000, 1000, 1000], [1500, 750, 1000], [2000, 500, 1000], [2000, 500, 1001]];
    check_polyline(&vm, &corners, 1.0);
    // 100 relative moves of 0.07 mm end exactly 7 mm further: no rounding drift.
    mark(&mut vm);
    for _ in 0..100 {
        ok(&mut vm, "G1 X0.07");
    }
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [2700, 500, 1001]);
    assert_eq!(steps_pos_neg(&vm, Axis::X), (700, 0));
    run(&mut vm, "G90 G1 X10");
    assert_eq!(xyz_now(&vm), [1000, 500, 1001]);
    assert_no_violations(&vm);
}

#[test]
fn a_thousand_g91_moves_of_a_micrometre_end_where_one_millimetre_ends() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X40 Y10");
    ok(&mut vm, "G91 G1 F600");
    mark(&mut vm);
    let lines = vec!["X0.001 Y-0.001"; 1000];
    let job = vm.stream(&lines, StreamOptions::new(Flow::CharCount(200))).unwrap();
    assert!(!job.timed_out && job.oks == 1000 && job.errors.is_empty(), "{:?}", job.errors);
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [4100, 900, 100]);
    assert_eq!(steps_pos_neg(&vm, Axis::X), (100, 0));
    assert_eq!(steps_pos_neg(&vm, Axis::Y), (0, 100));
    check_polyline(&vm, &[[4000, 1000, 100], [4100, 900, 100]], 1.0);
    assert_no_violations(&vm);
}

#[test]
fn g54_to_g59_offsets_from_g10_l2_and_l20_shift_moves_and_g53_ignores_them() {
    let mut vm = boot_homed();
    // G10 L2: G54 origin at machine (10, 5, −2): 2 mm below the top switch.
    ok(&mut vm, "G10 L2 P1 X10 Y5 Z-2");
    run(&mut vm, "G0 X0 Y0 Z0");
    assert_eq!(xyz_now(&vm), [1000, 500, 200]);
    assert_eq!(m114_work(&mut vm), [0.0, 0.0, 0.0]);
    run(&mut vm, "G1 X3 Y4 Z-1 F1200");
    assert_eq!(xyz_now(&vm), [1300, 900, 300]);
    assert_eq!(m114_work(&mut vm), [3.0, 4.0, -1.0]);
    // G10 L20 P2: make the current point G55 (1, 2, −3).
    ok(&mut vm, "G10 L20 P2 X1 Y2 Z-3");
    run(&mut vm, "G55 G0 X0 Y0 Z-3");
    assert_eq!(xyz_now(&vm), [1200, 700, 300]);
    assert_eq!(m114_work(&mut vm), [0.0, 0.0, -3.0]);
    // G53: machine coordinates for this line only.
    mark(&mut vm);
    run(&mut vm, "G53 G1 X20 Y20 Z-20");
    assert_eq!(xyz_now(&vm), [2000, 2000, 2000]);
    check_polyline(&vm, &[[1200, 700, 300], [2000, 2000, 2000]], 1.0);
    run(&mut vm, "G1 X0 Y0 Z-3");
    assert_eq!(xyz_now(&vm), [1200, 700, 300], "G55 is still active after the G53 line");
    // Back in G54.
    run(&mut vm, "G54 G0 X0 Y0 Z0");
    assert_eq!(xyz_now(&vm), [1000, 500, 200]);
    // The offsets are listed by M503.
    let r = ok(&mut vm, "M503");
    assert!(r.iter().any(|l| l == "G10 L2 P1 X10.000 Y5.000 Z-2.000"), "{r:?}");
    assert!(r.iter().any(|l| l == "G10 L2 P2 X12.000 Y7.000 Z0.000"), "{r:?}");
    assert_no_violations(&vm);
}

#[test]
fn g92_and_g43_shift_the_work_position_without_moving() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-10");
    mark(&mut vm);
    // G92: here is work (0, 0, 0). Nothing moves.
    ok(&mut vm, "G92 X0 Y0 Z0");
    ok(&mut vm, "M400");
    assert_eq!(steps_since_mark(&vm), 0);
    assert_eq!(m114_work(&mut vm), [0.0, 0.0, 0.0]);
    run(&mut vm, "G1 X5 Y5 Z-5 F1200");
    assert_eq!(xyz_now(&vm), [1500, 1500, 1500]);
    assert_eq!(m114_work(&mut vm), [5.0, 5.0, -5.0]);
    // G10 L20 on top of G92: the current point becomes work X0.
    ok(&mut vm, "G10 L20 P1 X0");
    run(&mut vm, "G0 X2");
    assert_eq!(xyz_now(&vm), [1700, 1500, 1500]);
    ok(&mut vm, "G10 L2 P1 X0");
    // G43 H2 applies tool 2's length (3 mm) to Z; G49 cancels it. As in
    // LinuxCNC and grbl, work Z is the tool tip, `length` below the spindle
    // nose: work Z = machine Z − G92 − length. Here machine −15, G92 −10:
    // work −5 for the nose, −8 for the tip.
    ok(&mut vm, "G10 L1 P2 Z3");
    mark(&mut vm);
    ok(&mut vm, "G43 H2");
    ok(&mut vm, "M400");
    assert_eq!(steps_since_mark(&vm), 0, "G43 alone moves nothing");
    assert_eq!(m114_work(&mut vm)[2], -8.0);
    // Tip at work −5: the spindle 3 mm higher than without the offset.
    run(&mut vm, "G0 Z-5");
    assert_eq!(xyz_now(&vm)[2], 1200);
    run(&mut vm, "G49 G0 Z-5");
    assert_eq!(xyz_now(&vm)[2], 1500);
    // G53 ignores G92 too.
    run(&mut vm, "G53 G0 X20 Y20 Z-20");
    assert_eq!(xyz_now(&vm), [2000, 2000, 2000]);
    assert_no_violations(&vm);
}

#[test]
fn an_arc_in_a_work_offset_is_centred_in_work_coordinates() {
    let mut vm = boot_homed();
    ok(&mut vm, "G10 L2 P1 X20 Y20 Z-5");
    run(&mut vm, "G0 X5 Y0 Z0");
    mark(&mut vm);
    run(&mut vm, "G3 X5 Y0 I-5 J0 F1500");
    let got = check_arc(&vm, (0, 1, 2), [2000.0, 2000.0], 500.0, [2500, 2000, 500], [2500, 2000, 500], ARC_DEV);
    assert!((got.swept - TWO_PI).abs() < 0.01);
    assert_no_violations(&vm);
}

// ------------------------------------------------------------ soft limits

#[test]
fn a_target_outside_travel_is_refused_with_nothing_moved_and_no_state_changed() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-10");
    mark(&mut vm);
    let before = steps(&vm);
    for line in [
        "G0 X45.1",
        "G1 Y-0.1 F600",
        // Machine Z runs 0 (top switch) … −45: neither above home nor below the travel.
        "G0 Z-46",
        "G0 Z0.1",
        "G53 G0 Z0.01",
        "G91 G0 Z10.1",
        "G91 G0 X40",
        "G53 G0 X50",
        // An arc whose ends are inside but whose sweep leaves the travel.
        "G17 G2 X10 Y10 I-15 J0 F600",
    ] {
        let e = refused(&mut vm, line);
        assert!(e.contains("soft limit"), "{line}: {e}");
    }
    // A work offset can push a work target out of travel too.
    ok(&mut vm, "G10 L2 P1 X40");
    let e = refused(&mut vm, "G0 X6");
    assert!(e.contains("soft limit"), "{e}");
    ok(&mut vm, "G10 L2 P1 X0");
    ok(&mut vm, "M400");
    vm.run_for(0.1).unwrap();
    assert_eq!(steps(&vm), before);
    assert_eq!(steps_since_mark(&vm), 0, "a refused line moved the machine");
    // The refused `G91` and `F600` lines changed no modal state: still G90, no feed.
    let e = refused(&mut vm, "G1 X12");
    assert!(e.contains("feed"), "F600 on a refused line must not stick: {e}");
    run(&mut vm, "G1 X12 F600");
    assert_eq!(xyz_now(&vm), [1200, 1000, 1000], "G91 on a refused line must not stick");
    // Exactly at the limits is fine.
    run(&mut vm, "G0 X45 Y0 Z-45");
    assert_eq!(xyz_now(&vm), [4500, 0, 4500]);
    run(&mut vm, "G0 Z0");
    assert_eq!(xyz_now(&vm), [4500, 0, 0]);
    assert!(!vm.output().contains("ALARM"), "{}", vm.output());
    assert_no_violations(&vm);
}

// ------------------------------------------ the step interrupt's two paths

/// The job's steps, (axis, position, cycles after its first step), and the
/// step interrupt's mean cycles over the job. With `rust_only` every event
/// takes the interrupt's Rust path (`board::stepper::step_slow`), the
/// reference of its assembly (`board/stepper/fast.rs`): the probe is
/// watched, which sends the assembly to the Rust path, with the input's
/// `$5` inversion bit poked to its idle level so that it never trips. The
/// offsets are `board::stepper::Isr`'s (`repr(C)`).
fn steps_of_job(lines: &[&str], rust_only: bool) -> (Vec<(Axis, i64, u64)>, f64) {
    const ARMED: u16 = 10;
    const PROBE: u16 = 12;
    const INVERT: u16 = 15;
    const PROBE_BIT: u8 = 1 << 3;
    const SETTER_INVERT: u8 = 1 << 4;
    let mut vm = boot_homed();
    if rust_only {
        let st = vm
            .symbols()
            .find("7stepper2ST")
            .into_iter()
            .find(|s| s.name.ends_with("7stepper2ST"))
            .expect("the step interrupt's state")
            .addr as u16;
        // The tool setter's input: PD2 (PIND, data address 0x29).
        let idle_high = vm.read_u8(0x29) & (1 << 2) != 0;
        let invert = vm.read_u8(st + INVERT) & !SETTER_INVERT | if idle_high { SETTER_INVERT } else { 0 };
        vm.write_ram(st + INVERT, &[invert]);
        vm.write_ram(st + PROBE, &[PROBE_BIT]);
        let armed = vm.read_u8(st + ARMED) | PROBE_BIT;
        vm.write_ram(st + ARMED, &[armed]);
    }
    let before = vm.stepper_isr_stats().expect("the step interrupt ran");
    for l in lines {
        ok(&mut vm, l);
    }
    ok(&mut vm, "M400");
    assert_no_violations(&vm);
    let after = vm.stepper_isr_stats().unwrap();
    let mean = (after.total_cycles - before.total_cycles) as f64 / (after.count - before.count) as f64;
    let tr = vm.recorder().trace();
    let t0 = tr.first().expect("the job moved").cycle;
    (tr.iter().map(|t| (t.axis, t.position, t.cycle - t0)).collect(), mean)
}

#[test]
fn the_step_interrupts_assembly_makes_the_steps_its_rust_path_makes() {
    // Partial axes of every kind, segments and chunks of all lengths,
    // accelerations and a full stop, an arc.
    let job =
        ["G1 X10.37 Y7.13 Z-1.91 F1500", "G1 X2.5 Y11 Z-0.4 F3000", "G2 X8.5 Y11 I3 J0 F1200", "G1 X8.52 Y10.99 F300", "G0 X1 Y1 Z-1"];
    let (fast, fast_mean) = steps_of_job(&job, false);
    let (rust, rust_mean) = steps_of_job(&job, true);
    assert!(fast.len() > 3_000, "{} steps", fast.len());
    assert!(fast_mean + 15.0 < rust_mean, "the assembly did not run: {fast_mean:.0} vs {rust_mean:.0} cycles an event");
    assert_eq!(fast.len(), rust.len(), "step counts");
    for (i, (f, r)) in fast.iter().zip(&rust).enumerate() {
        assert_eq!((f.0, f.1), (r.0, r.1), "step {i}: the assembly's {f:?}, the Rust path's {r:?}");
        // The same timer instants: an edge moves only by the paths' cycles
        // (and an interrupt that lands in the longer one; 258 at most).
        assert!(f.2.abs_diff(r.2) <= 400, "step {i}: at {} and {} cycles", f.2, r.2);
    }
}
