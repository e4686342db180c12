//! Host tests of the interpreter (`interp.rs`): whole lines through
//! [`Machine::execute`] on the fake board of the controller tests
//! ([`crate::fake_board`]: its ISR twin steps every move out in machine
//! time). The path is the list of block end points as the blocks are
//! handed to the board (one per chord of an arc,
//! [`FakeBoard::path`]), which is what these tests check; the step timing
//! is the controller tests' and the simavr tests' business.
//! `gcode::tests` (the canned cycles) drives the same fake board; the
//! interpreter alone, without a machine, is tested in [`commands`].

use crate::fake_board::FakeBoard;
use crate::machine::Machine;
use crate::N_AXES;

/// A machine that may move (as if homed), with the stepper at machine 0.
pub fn machine() -> (Box<Machine>, FakeBoard) {
    let mut m = Box::new(Machine::new());
    let mut io = FakeBoard::new();
    m.boot(&mut io, F!("test"), false);
    m.homed = 0b111;
    io.out.clear();
    (m, io)
}

/// Run `line`; panic on an error. Waits until the motion is done.
pub fn run(m: &mut Machine, io: &mut FakeBoard, line: &str) {
    if let Err(e) = m.execute(line.as_bytes(), io) {
        panic!("{line:?} refused: {}", msg(e));
    }
    m.wait_idle(io).unwrap();
}

/// Run `line`, which must be refused: the error's text.
pub fn refused(m: &mut Machine, io: &mut FakeBoard, line: &str) -> String {
    match m.execute(line.as_bytes(), io) {
        Ok(()) => panic!("{line:?} accepted"),
        Err(e) => msg(e),
    }
}

/// The text printed after `Error:`.
pub fn msg(e: super::Error) -> String {
    let mut s = String::new();
    e.message().write_to(&mut s).unwrap();
    s
}

/// Machine steps of X, Y, Z now.
pub fn xyz(io: &FakeBoard) -> [i32; 3] {
    [io.pos[0], io.pos[1], io.pos[2]]
}

/// Largest distance (steps) in the plane (a0, a1) of any block end from `p`.
fn max_dist_from(path: &[[i32; N_AXES]], p: [i32; N_AXES], a0: usize, a1: usize) -> f64 {
    path.iter().map(|q| (((q[a0] - p[a0]) as f64).powi(2) + ((q[a1] - p[a1]) as f64).powi(2)).sqrt()).fold(0.0, f64::max)
}

/// The reported case: a 0.8 mm circle from an off-grid
/// start that moved almost nothing.
#[test]
fn the_reported_full_circle_goes_all_the_way_round() {
    for g in ["G3", "G2"] {
        let (mut m, mut io) = machine();
        run(&mut m, &mut io, "G0 X18.087536 Y33.329412 Z-5");
        let start = io.pos;
        io.path.clear();
        run(&mut m, &mut io, &format!("{g} X18.087536 Y33.329412 I-0.4 J-0.69282 F600"));
        assert_eq!(io.pos, start, "{g}: back at the start");
        let d = max_dist_from(&io.path, start, 0, 1);
        assert!((d - 160.0).abs() <= 1.5, "{g}: farthest point {d} steps from the start, want 2r = 160");
        assert!(io.path.len() > 20, "{g}: {} chords", io.path.len());
    }
}

/// Every plane, both directions, 36 off-grid start angles, radii 0.05 to
/// 20 mm, some helical, and ends that differ from the start by less than
/// half a step: every one is a full turn around the centre.
#[test]
fn an_arc_ending_on_its_start_step_is_a_full_circle_in_every_plane() {
    let planes = [("G17", 0usize, 1usize, 2usize, ["I", "J", "K"]), ("G18", 2, 0, 1, ["I", "J", "K"]), ("G19", 1, 2, 0, ["I", "J", "K"])];
    let letters = ["X", "Y", "Z"];
    // Centre in the user's frame (+Z up; machine Z runs 0 … -45) and the sign
    // of each axis in the internal frame the fake board counts in.
    let cu = [22.5f64, 22.5, -22.5];
    let flip = |a: usize| if a == 2 { -1 } else { 1 };
    let (mut m, mut io) = machine();
    // 864 circles at their feed: more machine time than a test usually takes.
    io.poll_limit = u64::MAX;
    let mut failures = Vec::new();
    let (mut n, mut perturbed) = (0, 0);
    for (code, a0, a1, al, words) in planes {
        for k in 0..36 {
            for (ri, &r) in [0.05f64, 0.8, 2.0, 20.0].iter().enumerate() {
                for g in ["G2", "G3"] {
                    let t = ((k * 10 + 3) as f64).to_radians();
                    let mut start = cu;
                    start[a0] = cu[a0] + r * t.cos();
                    start[a1] = cu[a1] + r * t.sin();
                    start[al] = 10.0 * flip(al) as f64;
                    let mut end = start;
                    // Some ends a little off the start (within half a step),
                    // some helical.
                    if (k + ri) % 3 == 1 {
                        end[a0] += 0.003;
                        end[a1] -= 0.002;
                        // Only where both still round to the start's steps.
                        let st = |v: f64| (v * 100.0).round();
                        if st(end[a0]) != st(start[a0]) || st(end[a1]) != st(start[a1]) {
                            end[a0] -= 0.006;
                            end[a1] += 0.004;
                        }
                        if st(end[a0]) != st(start[a0]) || st(end[a1]) != st(start[a1]) {
                            end = start;
                        }
                    }
                    if (k + ri) % 4 == 2 {
                        end[al] += 1.0;
                    }
                    let g0 = format!("{code} G0 X{:.6} Y{:.6} Z{:.6}", start[0], start[1], start[2]);
                    run(&mut m, &mut io, &g0);
                    let s = io.pos;
                    io.path.clear();
                    let mut line = g.to_string();
                    for a in 0..3 {
                        line += &format!(" {}{:.6}", letters[a], end[a]);
                    }
                    line += &format!(" {}{:.6} {}{:.6} F3000", words[a0], cu[a0] - start[a0], words[a1], cu[a1] - start[a1]);
                    run(&mut m, &mut io, &line);
                    n += 1;
                    let d = max_dist_from(&io.path, s, a0, a1);
                    let want = 2.0 * r * 100.0;
                    // Swept angle around the centre, from the block ends.
                    // In the user's frame: G2 is clockwise seen from +normal.
                    let user = |q: &[i32; N_AXES]| [q[0] as f64, q[1] as f64, -(q[2] as f64)];
                    let c = [cu[a0] * 100.0, cu[a1] * 100.0];
                    let mut swept = 0.0;
                    let mut prev = user(&s);
                    for q in &io.path {
                        let q = user(q);
                        let u = (prev[a0] - c[0], prev[a1] - c[1]);
                        let v = (q[a0] - c[0], q[a1] - c[1]);
                        swept += (u.0 * v.1 - u.1 * v.0).atan2(u.0 * v.0 + u.1 * v.1);
                        prev = q;
                    }
                    let want_sweep = if g == "G2" { -std::f64::consts::TAU } else { std::f64::consts::TAU };
                    let end_steps = [(end[0] * 100.0).round() as i32, (end[1] * 100.0).round() as i32, -(end[2] * 100.0).round() as i32];
                    perturbed += (end[a0] != start[a0]) as usize;
                    if (d - want).abs() > 1.5 || (swept - want_sweep).abs() > 0.35 || xyz(&io) != end_steps {
                        failures.push(format!("{line}: farthest {d:.1} (want {want}), swept {swept:.3}"));
                    }
                }
            }
        }
    }
    assert_eq!(n, 3 * 36 * 4 * 2);
    assert!(perturbed > 150, "{perturbed} ends off the start within a step");
    assert!(failures.is_empty(), "{} of {n} not full circles: {:#?}", failures.len(), &failures[..failures.len().min(5)]);
}

#[test]
fn g90_1_takes_i_j_k_as_the_absolute_centre_and_g91_1_as_offsets() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X10 Y10 Z-5");
    // G90.1: centre (15, 10): a clockwise quarter to (15, 15).
    run(&mut m, &mut io, "G90.1 G2 X15 Y15 I15 J10 F600");
    assert_eq!(xyz(&io), [1500, 1500, 500]);
    assert!(m.interp.arc_absolute, "G90.1 is modal");
    for q in &io.path {
        let r = (((q[0] - 1500) as f64).powi(2) + ((q[1] - 1000) as f64).powi(2)).sqrt();
        assert!((r - 500.0).abs() <= 1.0, "{q:?} {r}");
    }
    // In a work offset the centre is a work coordinate too.
    run(&mut m, &mut io, "G10 L2 P1 X5 Y0");
    run(&mut m, &mut io, "G0 X5 Y15");
    assert_eq!(xyz(&io), [1000, 1500, 500]);
    io.path.clear();
    run(&mut m, &mut io, "G3 X5 Y15 I10 J15");
    assert_eq!(xyz(&io), [1000, 1500, 500]);
    assert_eq!(max_dist_from(&io.path, io.pos, 0, 1).round(), 1000.0, "a full circle about work (10, 15)");
    // Both centre words of the plane are needed.
    let e = refused(&mut m, &mut io, "G2 X5 Y15 I10");
    assert!(e.contains("G90.1"), "{e}");
    // G91.1: offsets again.
    run(&mut m, &mut io, "G91.1 G2 X10 Y20 I5 J0");
    assert!(!m.interp.arc_absolute);
    assert_eq!(xyz(&io), [1500, 2000, 500]);
    assert!(io.path.iter().all(|q| (((q[0] - 1500) as f64).powi(2) + ((q[1] - 1500) as f64).powi(2)).sqrt() <= 501.0));
}

#[test]
fn g92_1_and_g92_2_clear_the_g92_offsets() {
    for code in ["G92.1", "G92.2"] {
        let (mut m, mut io) = machine();
        run(&mut m, &mut io, "G0 X10 Y10");
        run(&mut m, &mut io, "G92 X0 Y0");
        run(&mut m, &mut io, "G0 X5");
        assert_eq!(xyz(&io)[0], 1500);
        run(&mut m, &mut io, code);
        assert_eq!(m.interp.g92_mm, [0.0; 3]);
        run(&mut m, &mut io, "G0 X5");
        assert_eq!(xyz(&io)[0], 500, "{code}");
    }
}

#[test]
fn preamble_codes_run_and_leave_the_rest_of_their_line_in_force() {
    let (mut m, mut io) = machine();
    // Whole preambles of the corpus (07, 11, 01, 17, 09, 06).
    for l in [
        "G20 G90 G64 G40",
        "G64 P0.00040 ( set maximum deviation )",
        "G17 G20 G40 G90",
        "G61 (exact path mode)",
        "G61.1",
        "G91.1",
        "G80",
        "G94 G90.1",
        "G91.1",
        "O1001",
        "O0000(3 HEATSINK PROFILE)",
        "G64 P0.01 Q0.01",
        "%",
    ] {
        let e = m.execute(l.as_bytes(), &mut io);
        assert!(e.is_ok(), "{l}: {}", msg(e.unwrap_err()));
    }
    // `g20 g64` sets inches (it was refused whole: an inch job ran 25.4× small).
    run(&mut m, &mut io, "g21");
    run(&mut m, &mut io, "g20 g64");
    assert!(m.interp.inches);
    run(&mut m, &mut io, "G1 X0.5 F10");
    assert_eq!(xyz(&io)[0], 1270);
    // `G40 G1 X25 Y10` moves (refused, it left G2 modal and 70 lines failed).
    run(&mut m, &mut io, "G21 G0 X0 Y0");
    run(&mut m, &mut io, "G40 G1 X25 Y10 F600");
    assert_eq!(xyz(&io), [2500, 1000, 0]);
    assert_eq!(m.interp.motion, super::Motion::Linear);
    // Blanks inside numbers, an N block number.
    run(&mut m, &mut io, "N0010 G1 X1 6.5 Y 1 0");
    assert_eq!(xyz(&io), [1650, 1000, 0]);
}

#[test]
fn g80_cancels_the_motion_mode_and_axis_words_need_one_as_in_linuxcnc() {
    let (mut m, mut io) = machine();
    m.settings.g80_keeps_motion = false;
    run(&mut m, &mut io, "G1 X1 F600");
    run(&mut m, &mut io, "G80");
    assert_eq!(m.interp.motion, super::Motion::Cancel);
    // LinuxCNC: "Cannot use axis values with G80" / "without a g code that uses them".
    for l in ["G80 X2", "X2 Y3"] {
        let e = refused(&mut m, &mut io, l);
        assert!(e.contains("G80"), "{l}: {e}");
    }
    assert_eq!(xyz(&io), [100, 0, 0], "nothing moved");
    run(&mut m, &mut io, "G0 X2");
    assert_eq!(xyz(&io), [200, 0, 0]);
}

#[test]
fn refusals_name_what_is_not_supported_and_move_nothing() {
    let (mut m, mut io) = machine();
    for (l, what) in [
        ("G18 G41 D1", "only in the XY plane"),
        ("#100=10.0", "# parameters"),
        ("G1 X#1 F600", "# parameters"),
        ("o100 sub", "O-word"),
        ("G0 X3. A0.", "X Y Z only"),
        ("G84 R-1 Z-2 X1 Y1 F100", "canned cycle not supported"),
        ("G18 G81 R-1 Z-2 X1 Y1 F100", "G18 (ZX)"),
    ] {
        let e = refused(&mut m, &mut io, l);
        assert!(e.contains(what), "{l}: {e}");
    }
    assert_eq!(io.pos, [0; N_AXES]);
}

#[test]
fn coolant_m7_m8_on_m9_off_and_off_at_program_end_and_alarms() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "M8");
    assert!(io.coolant && m.interp.coolant_m == 8, "$G shows M8");
    run(&mut m, &mut io, "M9");
    assert!(!io.coolant && m.interp.coolant_m == 9);
    run(&mut m, &mut io, "M7");
    assert!(io.coolant && m.interp.coolant_m == 7);
    run(&mut m, &mut io, "M2");
    assert!(!io.coolant && m.interp.coolant_m == 9, "M2");
    run(&mut m, &mut io, "S1000 M3 M8");
    assert!(io.coolant && io.spindle > 0);
    run(&mut m, &mut io, "M30");
    assert!(!io.coolant && io.spindle == 0, "M30");
    run(&mut m, &mut io, "M7 M8");
    assert!(io.coolant);
    let _ = m.execute(b"M112", &mut io);
    assert!(!io.coolant && m.interp.coolant_m == 9, "M112");
    // In alarm M8 is refused, M9 is not.
    assert!(m.execute(b"M8", &mut io).is_err());
    assert!(!io.coolant);
    m.execute(b"M9", &mut io).unwrap();
    run(&mut m, &mut io, "M999");
    m.homed = 0b111;
    run(&mut m, &mut io, "M8");
    m.raise(&mut io, crate::machine::Alarm::HardLimit);
    assert!(!io.coolant && m.interp.coolant_m == 9, "alarm");
}

#[test]
fn t_alone_selects_and_m6_changes_unless_immediate_t_is_set() {
    let (mut m, mut io) = machine();
    // NGC: T2 pre-stages, nothing moves, no change.
    run(&mut m, &mut io, "T2");
    assert!(!io.out.contains("SelectTool"), "{}", io.out);
    assert_eq!(m.atc.last_t, 2);
    assert_eq!(io.pos, [0; N_AXES]);
    // T with motion on one line is allowed (it only selects).
    run(&mut m, &mut io, "G0 X1 T3");
    assert_eq!((xyz(&io)[0], m.atc.last_t), (100, 3));
    assert!(!io.out.contains("SelectTool"));
    assert!(m.execute(b"T13", &mut io).is_err(), "T13 is out of range");
    // M6 changes to the selected tool.
    let _ = m.execute(b"M6", &mut io);
    assert!(io.out.contains("SelectTool:3"), "{}", io.out);
    for (l, t) in [("M6 T5", 5), ("T6 M6", 6)] {
        let (mut m, mut io) = machine();
        let _ = m.execute(l.as_bytes(), &mut io);
        assert!(io.out.contains(&format!("SelectTool:{t}")), "{l}: {}", io.out);
    }
    // M6 with motion on the line is still refused.
    let (mut m, mut io) = machine();
    assert!(m.execute(b"G0 X1 M6 T2", &mut io).is_err());
    // `$151=1`: Repetier's immediate T (the thesis macros).
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "$151=1");
    assert!(m.settings.immediate_tool_change);
    let _ = m.execute(b"T4", &mut io);
    assert!(io.out.contains("SelectTool:4"), "{}", io.out);
    assert!(m.execute(b"G0 X1 T2", &mut io).is_err(), "an immediate T with motion is refused");
}

#[test]
fn m1_is_skipped_unless_optional_stop_is_on_and_m0_always_pauses() {
    let (mut m, mut io) = machine();
    io.auto_resume = true;
    run(&mut m, &mut io, "M1");
    assert!(!io.out.contains("paused"), "{}", io.out);
    run(&mut m, &mut io, "M0");
    assert!(io.out.contains("paused"));
    io.out.clear();
    run(&mut m, &mut io, "$152=1");
    assert!(m.settings.optional_stop);
    run(&mut m, &mut io, "M1");
    assert!(io.out.contains("paused"), "{}", io.out);
}

/// Power-up motion mode is G0, as grbl (Fusion's generic post writes a bare
/// `Z10` after its first M6, corpus 05); LinuxCNC starts in G80.
#[test]
fn bare_axis_words_at_power_up_are_a_rapid() {
    let (mut m, mut io) = machine();
    assert_eq!(m.interp.motion, super::Motion::Rapid);
    run(&mut m, &mut io, "Z-10");
    assert_eq!(xyz(&io), [0, 0, 1000], "10 mm below the top (internal steps count down)");
    assert!(refused(&mut m, &mut io, "G0 G80 X1").contains("modal group"), "G0 and G80 share group 1, as in LinuxCNC and grbl");
}

#[test]
fn g80_goes_back_to_the_motion_mode_before_the_cycle_by_default_as_fanuc_and_mach3() {
    let (mut m, mut io) = machine();
    assert!(m.settings.g80_keeps_motion, "$154=1 is the default");
    run(&mut m, &mut io, "G0 X5 Y5 Z-2");
    run(&mut m, &mut io, "G98 G81 X10 Y10 Z-11 R-5 F250");
    run(&mut m, &mut io, "G80");
    assert_eq!(m.interp.motion, super::Motion::Rapid, "the G0 before the cycle");
    // Fusion 360's Mach3 post: bare axis words after G80.
    run(&mut m, &mut io, "Z-4");
    run(&mut m, &mut io, "X12 Y12 Z-4");
    assert_eq!(xyz(&io), [1200, 1200, 400]);
    // A G80 with no cycle in force changes nothing (a preamble's G80).
    run(&mut m, &mut io, "G1 X13 F600");
    run(&mut m, &mut io, "G80");
    assert_eq!(m.interp.motion, super::Motion::Linear);
    // A feed move before the cycle: G80 goes back to G1.
    run(&mut m, &mut io, "G81 X14 Z-11 R-5");
    run(&mut m, &mut io, "G80");
    assert_eq!(m.interp.motion, super::Motion::Linear);
}

#[test]
fn g4_with_p_on_a_motion_line_dwells_after_the_spindle_and_before_the_move() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X5 Y5");
    let before = io.path.len();
    let t0 = io.ms();
    run(&mut m, &mut io, "G04 P.5 G0 X10 Y10 S1000 M3");
    assert_eq!(xyz(&io), [1000, 1000, 0], "the move ran");
    assert!(io.spindle > 0, "S1000 M3 ran");
    assert_eq!(m.interp.spindle_rpm, 1000.0, "S is the speed when P is there");
    // The move was queued after the dwell.
    assert!(io.path_ms[before] - t0 >= 500, "queued {} ms after the line began", io.path_ms[before] - t0);
    // Without P, S is the dwell in seconds and the speed stays.
    let t0 = io.ms();
    run(&mut m, &mut io, "G4 S0.2");
    assert!(io.ms() - t0 >= 200);
    assert_eq!(m.interp.spindle_rpm, 1000.0);
    assert!(refused(&mut m, &mut io, "G4").contains("G4 needs P"));
    assert!(refused(&mut m, &mut io, "G4 P-1").contains("negative"));
}

#[test]
fn g4_p_is_milliseconds_with_setting_153() {
    let (mut m, mut io) = machine();
    m.settings.dwell_p_ms = true;
    let t0 = io.ms();
    run(&mut m, &mut io, "G04 P400");
    let t = io.ms() - t0;
    assert!((400..450).contains(&t), "{t} ms");
    // S stays seconds.
    let t0 = io.ms();
    run(&mut m, &mut io, "G4 S0.3");
    assert!((300..350).contains(&(io.ms() - t0)));
}

#[test]
fn words_no_code_uses_are_refused_and_nothing_moves() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G1 X1 F600");
    for (l, w) in [
        ("G61 R0.5", 'R'),
        ("G0 X2 I1", 'I'),
        ("G1 X2 P2", 'P'),
        ("G0 X2 H1", 'H'),
        ("G1 X2 Q1", 'Q'),
        ("G0 X2 L2", 'L'),
        ("G0 X2 D1", 'D'),
        ("G0 X2 B1", 'B'),
        ("G1 X2 N5", 'N'),
        ("G81 X2 R0 Z-1 P1", 'P'),
        ("G82 X2 R0 Z-1 P1 Q1", 'Q'),
    ] {
        match m.execute(l.as_bytes(), &mut io) {
            Err(super::Error::UnusedWord(got)) => assert_eq!(got.letter() as char, w, "{l}"),
            other => panic!("{l}: {other:?}"),
        }
    }
    assert!(refused(&mut m, &mut io, "G38.2 F1").contains("all axes missing"));
    assert_eq!(xyz(&io), [100, 0, 0], "nothing moved");
    // The words the codes of the line use pass.
    for l in [
        "G2 X3 I1 F600",
        "G3 X1 R1",
        "G64 P0.01 Q0.01",
        "G4 P0",
        "G43 H0",
        "G49",
        "G10 L2 P1 X0",
        "G83 X2 R0 Z-1 Q0.5 F300",
        "X3",
        "G82 X2 R0 Z-1 P0.1 L2",
        "G89 X4 R0 Z-1 P0.1",
        "G80",
        "N4567.789 S1200",
        "M5",
    ] {
        run(&mut m, &mut io, l);
    }
}

#[test]
fn polar_words_move_about_the_work_origin_as_in_linuxcnc() {
    let (mut m, mut io) = machine();
    run(&mut m, &mut io, "G0 X20 Y20");
    run(&mut m, &mut io, "G92 X0 Y0");
    run(&mut m, &mut io, "G1 @10 ^90 F600");
    assert_eq!(xyz(&io), [2000, 3000, 0]);
    run(&mut m, &mut io, "G91 ^-90");
    assert_eq!(xyz(&io), [3000, 2000, 0]);
    run(&mut m, &mut io, "@-5");
    assert_eq!(xyz(&io), [2500, 2000, 0]);
    run(&mut m, &mut io, "G90 @2");
    assert_eq!(xyz(&io), [2200, 2000, 0], "G90: the angle stays");
    for l in ["G1 @1 X1", "G18 G1 @1 ^0", "G53 G0 @1 ^0"] {
        assert!(refused(&mut m, &mut io, l).contains("polar"), "{l}");
    }
    run(&mut m, &mut io, "G0 X0 Y0");
    assert!(refused(&mut m, &mut io, "G1 @3").contains("origin"));
    assert!(refused(&mut m, &mut io, "G91 G1 ^10").contains("origin"));
    assert_eq!(xyz(&io), [2000, 2000, 0], "nothing moved");
}

#[test]
fn the_compensation_example_runs_on_the_controller() {
    let (mut m, mut io) = machine();
    for l in ["G10 L1 P1 R0.5", "G21 G90 G17", "G0 X10 Y10 Z-10", "G1 Z-12 F100", "G41 X12 Y10 D1", "G3 X14 Y12 I0 J2", "G1 X20", "G40 X25"]
    {
        run(&mut m, &mut io, l);
    }
    assert!((m.interp.pos_mm[0] - 25.0).abs() < 1e-4 && (m.interp.pos_mm[1] - 12.0).abs() < 1e-4, "{:?}", m.interp.pos_mm);
}

mod commands;
