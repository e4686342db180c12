//! Host tests of the canned cycles wired into the interpreter (G73,
//! G81–G89): whole lines through [`Machine::execute`] on a fake board whose
//! stepper applies each planner block at once. The path is the list of
//! block end points in machine steps (internal frame: Z counts down from
//! the top switch, so user Z −8 mm is step 800 at 100 steps/mm); step
//! timing and speeds are the simavr test's business (tests/cycles.rs).
//! The fake board and the helpers are `interp::tests`'s.

use super::cycles::{Kind, Retract};
use super::interp::tests::{machine, refused, run};
use super::Motion;
use crate::fake_board::FakeBoard;

/// The block end points since the last call, as user-frame mm (X, Y, Z up).
fn take(io: &mut FakeBoard) -> Vec<[f32; 3]> {
    io.path_ms.clear();
    io.path.drain(..).map(|p| [p[0] as f32 / 100.0, p[1] as f32 / 100.0, -(p[2] as f32) / 100.0]).collect()
}

/// Z of every block end, user mm.
fn zs(path: &[[f32; 3]]) -> Vec<f32> {
    path.iter().map(|p| p[2]).collect()
}

#[test]
fn g81_under_g98_drills_and_returns_to_the_initial_z_and_a_bare_x_drills_the_next_hole() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    take(&mut io);
    run(&mut m, &mut io, "G81 X20 Y10 Z-15 R-8 F300");
    assert_eq!(take(&mut io), vec![[20.0, 10.0, -5.0], [20.0, 10.0, -8.0], [20.0, 10.0, -15.0], [20.0, 10.0, -5.0]]);
    assert_eq!((m.interp.motion, m.interp.retract), (Motion::Cycle(Kind::Drill), Retract::Initial));
    // Sticky R and Z: a bare X drills at X30; a bare Y at (30, 15).
    run(&mut m, &mut io, "X30");
    assert_eq!(take(&mut io), vec![[30.0, 10.0, -5.0], [30.0, 10.0, -8.0], [30.0, 10.0, -15.0], [30.0, 10.0, -5.0]]);
    run(&mut m, &mut io, "Y15 Z-12");
    assert_eq!(take(&mut io), vec![[30.0, 15.0, -5.0], [30.0, 15.0, -8.0], [30.0, 15.0, -12.0], [30.0, 15.0, -5.0]]);
}

#[test]
fn g99_returns_to_r_and_the_next_hole_travels_at_r() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    take(&mut io);
    run(&mut m, &mut io, "G99 G81 X20 Z-15 R-8 F300");
    assert_eq!(zs(&take(&mut io)), vec![-5.0, -8.0, -15.0, -8.0]);
    run(&mut m, &mut io, "X30");
    assert_eq!(take(&mut io), vec![[30.0, 10.0, -8.0], [30.0, 10.0, -15.0], [30.0, 10.0, -8.0]]);
    // G98 mid-run: back to the initial level (-5) of the run, as LinuxCNC.
    run(&mut m, &mut io, "G98 X40");
    assert_eq!(take(&mut io), vec![[40.0, 10.0, -5.0], [40.0, 10.0, -8.0], [40.0, 10.0, -15.0], [40.0, 10.0, -5.0]]);
}

#[test]
fn g80_and_g0_end_the_cycle_and_its_sticky_words() {
    let (mut m, mut io) = machine();
    m.settings.g80_keeps_motion = false;
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    run(&mut m, &mut io, "G81 X20 Z-15 R-8 F300");
    run(&mut m, &mut io, "G80");
    assert_eq!(m.interp.motion, Motion::Cancel);
    take(&mut io);
    assert!(refused(&mut m, &mut io, "X30").contains("G80"));
    assert!(refused(&mut m, &mut io, "G81 X30").contains("Z missing"));
    assert!(refused(&mut m, &mut io, "G81 X30 Z-15").contains("R missing"));
    assert!(io.path.is_empty());
    run(&mut m, &mut io, "G81 X30 Z-15 R-8");
    assert_eq!(zs(&take(&mut io)), vec![-5.0, -8.0, -15.0, -5.0]);
    // G0 cancels too: a bare X is then a rapid.
    run(&mut m, &mut io, "G0 X35");
    run(&mut m, &mut io, "X40");
    assert_eq!(take(&mut io), vec![[35.0, 10.0, -5.0], [40.0, 10.0, -5.0]]);
    assert!(refused(&mut m, &mut io, "G81 X30 Z-15").contains("R missing"));
    // Another cycle code asks for its words again (LinuxCNC).
    run(&mut m, &mut io, "G81 X30 Z-15 R-8");
    assert!(refused(&mut m, &mut io, "G82 X31 P0.1").contains("Z missing"));
}

#[test]
fn g91_with_l_drills_a_row_r_from_the_start_z_and_z_from_r() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    take(&mut io);
    run(&mut m, &mut io, "G91 G99 G81 X5 R-3 Z-7 L3 F300");
    let p = take(&mut io);
    let bottoms: Vec<[f32; 3]> = p.iter().copied().filter(|q| q[2] == -15.0).collect();
    assert_eq!(bottoms, vec![[15.0, 10.0, -15.0], [20.0, 10.0, -15.0], [25.0, 10.0, -15.0]]);
    assert_eq!(*p.last().unwrap(), [25.0, 10.0, -8.0]);
    // Incremental moves in between stay at R.
    assert!(p.iter().all(|q| q[2] <= -5.0 && q[2] >= -15.0));
    // The next G91 line: X is an increment from the last hole, R from the initial level.
    run(&mut m, &mut io, "X-10");
    assert_eq!(take(&mut io), vec![[15.0, 10.0, -8.0], [15.0, 10.0, -15.0], [15.0, 10.0, -8.0]]);
}

#[test]
fn g20_converts_every_word() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G20 G0 X1 Y1 Z-0.2");
    take(&mut io);
    run(&mut m, &mut io, "G83 X1.5 Z-0.5 R-0.3 Q0.1 F10");
    let p = take(&mut io);
    let z = zs(&p);
    assert_eq!(p[0], [38.1, 25.4, -5.08]);
    assert_eq!(z[1], -7.62);
    // Pecks of 0.1 inch from R -0.3 inch: -0.4, -0.5 (the bottom).
    let feeds: Vec<f32> = z.windows(2).filter(|w| w[1] < w[0]).map(|w| w[1]).collect();
    assert!(feeds.contains(&-10.16) && feeds.contains(&-12.7), "{z:?}");
    assert_eq!(*z.last().unwrap(), -5.08);
    assert_eq!(m.interp.feed_mm_per_min, 254.0);
}

#[test]
fn g82_dwells_p_seconds_at_the_bottom() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    let from = io.steps.len();
    run(&mut m, &mut io, "G82 X20 Z-15 R-8 P0.5 F300");
    // From the step that reaches the bottom (Z 15 mm down) to the first
    // step after it: the dwell, as the motors saw it.
    let bottom = io.phys[2] - io.pos[2] as i64 + 1500;
    let steps = &io.steps[from..];
    let arrive = steps.iter().position(|s| s.axes & 4 != 0 && s.phys[2] == bottom).unwrap();
    let leave = &steps[arrive + 1];
    let waited = (leave.cycle - steps[arrive].cycle) / (crate::F_CPU_HZ as u64 / 1000);
    assert!(leave.phys[2] < bottom, "the first step after the bottom goes up");
    assert!((500..520).contains(&waited), "{waited} ms");
}

#[test]
fn refused_cycle_lines_change_nothing_and_move_nothing() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    run(&mut m, &mut io, "F300");
    io.path.clear();
    io.path_ms.clear();
    let cases = [
        ("G81 X20 R-8", "Z missing"),
        ("G81 X20 Z-15", "R missing"),
        ("G83 X20 Z-15 R-8", "Q (peck depth) missing"),
        ("G83 X20 Z-15 R-8 Q0", "Q (peck depth) must be positive"),
        ("G73 X20 Z-15 R-8 Q-1", "Q (peck depth) must be positive"),
        ("G82 X20 Z-15 R-8", "P (dwell, seconds) missing"),
        ("G81 X20 Z-6 R-8", "Z is above R"),
        ("G81 X20 Z-15 R-8 L0", "L must be"),
        ("G18 G81 X20 Z-15 R-8", "G18 (ZX)"),
        ("G19 G81 X20 Z-15 R-8", "G19 (YZ)"),
        ("G81 X20 Z-50 R-8", "soft limit"),
        ("G91 G81 X20 Z-15 R-8 L20", "soft limit"),
        ("G53 G81 X20 Z-15 R-8", "G53"),
        ("G99 G91 G20 G81 X20 Z-15 R-8 E1", "E only"),
    ];
    for (line, why) in cases {
        let e = refused(&mut m, &mut io, line);
        assert!(e.contains(why), "{line}: {e}");
        assert!(io.path.is_empty(), "{line} moved");
        assert_eq!(m.interp.motion, Motion::Rapid, "{line}");
        assert_eq!((m.interp.incremental, m.interp.inches, m.interp.retract), (false, false, Retract::Initial), "{line}");
        assert_eq!(m.interp.plane, super::Plane::Xy, "{line}");
    }
    // Without a feed rate.
    let (mut m, mut io) = machine();
    assert!(refused(&mut m, &mut io, "G81 X20 Z-15 R-8").contains("feed"));
    assert!(io.path.is_empty());
}

#[test]
fn g83_pecks_back_to_r_and_g73_backs_off_a_little() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    take(&mut io);
    run(&mut m, &mut io, "G99 G83 X20 Z-14 R-8 Q2.5 F300");
    let z = zs(&take(&mut io));
    // R -8, pecks to -10.5, -13, -14; out to R each time, back in 0.254 above (rounded to steps).
    assert_eq!(z, vec![-5.0, -8.0, -10.5, -8.0, -10.25, -13.0, -8.0, -12.75, -14.0, -8.0]);
    run(&mut m, &mut io, "G73 X30 Z-14 R-8 Q2.5");
    let z = zs(&take(&mut io));
    assert_eq!(z, vec![-8.0, -10.5, -10.25, -13.0, -12.75, -14.0, -8.0]);
}

#[test]
fn a_pcb2gcode_drill_block_runs_in_work_coordinates() {
    // pcb2gcode's pattern (corpus 09), with G54 at machine X5 Y5 Z-20.
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G10 L2 P1 X5 Y5 Z-20");
    run(&mut m, &mut io, "G0 Z10");
    run(&mut m, &mut io, "G0 Z1.5");
    take(&mut io);
    run(&mut m, &mut io, "G81 R1.50000 Z-1.75000 F100.00000 X12.00000 Y9.54000");
    run(&mut m, &mut io, "X12.00000 Y12.00000");
    run(&mut m, &mut io, "G80");
    // Machine frame: R at -18.5, the bottom at -21.75, back to R (the start Z).
    assert_eq!(
        take(&mut io),
        vec![
            [17.0, 14.54, -18.5],
            [17.0, 14.54, -21.75],
            [17.0, 14.54, -18.5],
            [17.0, 17.0, -18.5],
            [17.0, 17.0, -21.75],
            [17.0, 17.0, -18.5],
        ]
    );
}
