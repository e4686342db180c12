//! Host tests of the interpreter alone: lines in, [`Command`]s out, with no
//! machine (the step API of `interp.rs`). The parent module runs whole
//! lines through the controller.

use crate::atc::Atc;
use crate::config::Settings;
use crate::gcode::interp::*;

/// Every command of `text`, with the target of each move (`None` for the
/// others), as a controller that carries each out at once would see them.
/// A command and, for a move, the interpreter's target after it.
type Emitted = (Command, Option<[f32; N_AXES]>);

fn commands(i: &mut Interp, s: &Settings, text: &str) -> Result<Vec<Emitted>, Error> {
    commands_with(i, s, &Atc::new(), text)
}

/// [`commands`] with the changer state `atc` (its tool table).
fn commands_with(i: &mut Interp, s: &Settings, atc: &Atc, text: &str) -> Result<Vec<Emitted>, Error> {
    let cx = Ctx { settings: s, atc, alarm: false, estop: false, status_only: false };
    let l = crate::gcode::parse(text.as_bytes()).expect("parses");
    i.begin_line();
    let mut out = Vec::new();
    while let Some(c) = i.next(&cx, &l)? {
        let t = match c {
            Command::Move { .. } | Command::CycleMove { .. } | Command::Probe { .. } => {
                // The controller queues it, then the position follows.
                let t = *i.target();
                i.target_reached();
                Some(t)
            }
            _ => None,
        };
        out.push((c, t));
    }
    Ok(out)
}

fn interp() -> (Interp, Settings) {
    let s = Settings::DEFAULT;
    let mut i = Interp::new();
    i.load_settings(&s);
    (i, s)
}

#[test]
fn a_g1_line_is_one_move_to_its_target_with_its_feed() {
    let (mut i, s) = interp();
    let c = commands(&mut i, &s, "G1 X10 Y5 F600").unwrap();
    assert_eq!(c.len(), 1);
    assert_eq!(c[0].0, Command::Move { feed_mm_per_min: 600.0, rapid: false });
    assert_eq!(c[0].1, Some([10.0, 5.0, 0.0, 0.0]));
    assert!(i.line_done());
}

#[test]
fn a_line_of_several_actions_runs_them_in_rs274_order() {
    let (mut i, s) = interp();
    // Tool change before the spindle, the spindle before M9, M9 before the
    // other M codes, program end last.
    let c = commands(&mut i, &s, "S5150 M3 T2 M6 M9 M400 M2").unwrap();
    let kinds: Vec<Command> = c.iter().map(|c| c.0).collect();
    assert_eq!(
        kinds,
        vec![
            Command::SelectTool { to: Some(2) },
            // Half the maximum speed (10 300 rpm): 127.5 of 255, rounded.
            Command::Spindle { on: true, duty: 128 },
            Command::Coolant { m: 9 },
            Command::M(400),
            Command::ProgramEnd,
        ]
    );
}

#[test]
fn an_arc_is_handed_out_chord_by_chord_and_ends_on_its_programmed_end() {
    let (mut i, s) = interp();
    commands(&mut i, &s, "G0 X20 Y10").unwrap();
    let c = commands(&mut i, &s, "G2 X30 Y20 I10 J0 F300").unwrap();
    assert!(c.len() > 5, "a quarter circle of radius 10 is many chords: {}", c.len());
    for (cmd, t) in &c {
        assert_eq!(*cmd, Command::Move { feed_mm_per_min: 300.0, rapid: false });
        let t = t.unwrap();
        let r = ((t[0] - 30.0).powi(2) + (t[1] - 10.0).powi(2)).sqrt();
        assert!((r - 10.0).abs() < 0.01, "chord end {t:?} off the circle");
    }
    assert_eq!(c.last().unwrap().1, Some([30.0, 20.0, 0.0, 0.0]));
    assert_eq!(i.pos_mm, [30.0, 20.0, 0.0, 0.0]);
}

#[test]
fn a_canned_cycle_is_handed_out_step_by_step() {
    let (mut i, s) = interp();
    commands(&mut i, &s, "G0 X10 Y10 Z-2").unwrap();
    let c = commands(&mut i, &s, "G82 X20 Y10 Z-5 R-3 P0.5 F100").unwrap();
    let kinds: Vec<Command> = c.iter().map(|c| c.0).collect();
    assert!(kinds.contains(&Command::Dwell { ms: 500.0 }), "{kinds:?}");
    assert!(kinds.iter().all(|k| matches!(k, Command::CycleMove { .. } | Command::Dwell { .. })));
    // The hole's bottom is reached (user Z −5 is internal Z 5).
    assert!(c.iter().any(|(_, t)| t.is_some_and(|t| t[0] == 20.0 && t[2] == 5.0)), "{c:?}");
}

#[test]
fn a_bad_line_is_an_error_from_the_first_call_and_changes_nothing() {
    let (mut i, s) = interp();
    commands(&mut i, &s, "G1 X1 F100").unwrap();
    let before = (i.pos_mm, i.feed_mm_per_min, i.inches, i.motion);
    // Outside the travel: refused before anything is committed.
    assert_eq!(commands(&mut i, &s, "G20 G0 X-5").unwrap_err(), Error::SoftLimit);
    assert_eq!(commands(&mut i, &s, "G1 X5 F0").unwrap_err(), Error::BadFeed);
    assert_eq!((i.pos_mm, i.feed_mm_per_min, i.inches, i.motion), before);
}

#[test]
fn the_context_locks_motion_in_an_alarm_but_not_homing() {
    let (mut i, s) = interp();
    let atc = Atc::new();
    let cx = Ctx { settings: &s, atc: &atc, alarm: true, estop: false, status_only: false };
    let g0 = crate::gcode::parse(b"G0 X1").unwrap();
    i.begin_line();
    assert_eq!(i.next(&cx, &g0), Err(Error::Alarm));
    let g28 = crate::gcode::parse(b"G28 Z").unwrap();
    i.begin_line();
    assert_eq!(i.next(&cx, &g28), Ok(Some(Command::Home { mask: 0b100 })));
    assert!(i.line_done());
}

/// [`commands`] with a tool table: tool 1 is 1 mm across (radius 0.5).
fn commands_t1(i: &mut Interp, s: &Settings, text: &str) -> Result<Vec<Emitted>, Error> {
    let mut atc = Atc::new();
    atc.table.diameter_um[0] = 1000;
    commands_with(i, s, &atc, text)
}

/// The XY ends of the moves of `lines`, run one after another.
fn comp_path(lines: &[&str]) -> Vec<[f32; 2]> {
    let (mut i, s) = interp();
    let mut v = Vec::new();
    for l in lines {
        for (_, t) in commands_t1(&mut i, &s, l).unwrap_or_else(|e| panic!("{l}: {e:?}")) {
            if let Some(t) = t {
                v.push([t[0], t[1]]);
            }
        }
    }
    v
}

fn near(a: [f32; 2], b: [f32; 2]) -> bool {
    (a[0] - b[0]).abs() < 2e-3 && (a[1] - b[1]).abs() < 2e-3
}

#[test]
fn compensation_holds_each_move_back_until_the_next_one_is_known() {
    let (mut i, s) = interp();
    for l in ["G21 G90 G17", "G0 X10 Y10 Z-5"] {
        commands_t1(&mut i, &s, l).unwrap();
    }
    // The entry move is held: nothing moves on its line.
    assert_eq!(commands_t1(&mut i, &s, "G41 G1 X20 D1 F600").unwrap(), vec![]);
    // The next line sends it, ending a radius to the left of X20 Y10.
    let c = commands_t1(&mut i, &s, "G1 X30").unwrap();
    assert_eq!(c.len(), 1);
    let t = c[0].1.unwrap();
    assert!(near([t[0], t[1]], [20.0, 10.5]), "{t:?}");
    // G40 sends the held move, then the exit move to the programmed point.
    let c = commands_t1(&mut i, &s, "G40 G1 X35 Y10").unwrap();
    let ends: Vec<[f32; 2]> = c.iter().map(|c| c.1.unwrap()).map(|t| [t[0], t[1]]).collect();
    assert!(near(ends[0], [30.0, 10.5]) && near(ends[1], [35.0, 10.0]), "{ends:?}");
    assert_eq!(i.comp.side, None);
}

#[test]
fn an_outside_corner_gets_an_arc_and_an_inside_corner_the_intersection() {
    // A square, counterclockwise, G42 (tool right of the path: outside).
    let p = comp_path(&["G0 X5 Y5", "G42 G1 X10 Y10 D1 F600", "G1 X20", "G1 Y20", "G1 X10", "G40 G0 X5"]);
    assert!(p.iter().any(|&q| near(q, [20.0, 9.5])), "{p:?}");
    // Around the corner (20,10): points a radius from it, up to (20.5,10).
    let d = |q: &[f32; 2]| ((q[0] - 20.0).powi(2) + (q[1] - 10.0).powi(2)).sqrt();
    let around: Vec<_> = p.iter().filter(|q| q[0] > 20.0 && q[1] > 9.5 && q[1] <= 10.0).collect();
    assert!(around.len() > 1, "{p:?}");
    assert!(around.iter().all(|q| (d(q) - 0.5).abs() < 1e-3), "{around:?}");
    assert!(p.iter().any(|&q| near(q, [20.5, 10.0])), "{p:?}");
    // The same square with G41: inside corners at the intersections.
    let p = comp_path(&["G0 X5 Y5", "G41 G1 X10 Y10 D1 F600", "G1 X20", "G1 Y20", "G1 X10", "G40 G0 X5"]);
    assert!(p.iter().any(|&q| near(q, [19.5, 10.5])), "{p:?}");
    assert!(p.iter().any(|&q| near(q, [19.5, 19.5])), "{p:?}");
}

#[test]
fn the_issue_example_runs_arc_and_lines_on_the_offset_path() {
    let p = comp_path(&["G21 G90 G17", "G0 X10 Y10 Z-10", "G1 Z-12 F100", "G41 X12 Y10 D1", "G3 X14 Y12 I0 J2", "G1 X20", "G40 X25"]);
    // Entry to (12, 10.5); the arc on radius 1.5 around (12,12) to (13.5,12);
    // the outside corner's arc around (14,12) to (14,12.5); X20 on Y12.5; exit.
    for q in [[12.0, 10.5], [13.5, 12.0], [14.0, 12.5], [20.0, 12.5], [25.0, 12.0]] {
        assert!(p.iter().any(|&r| near(r, q)), "{q:?} not in {p:?}");
    }
}

#[test]
fn under_compensation_a_move_without_z_keeps_the_held_moves_z() {
    let (mut i, s) = interp();
    let mut ends = Vec::new();
    for l in ["G21 G90 G0 X10 Y10 Z-5", "G41 G1 X20 Z-6 D1 F600", "G1 X30", "G40 G1 X35"] {
        for (_, t) in commands_t1(&mut i, &s, l).unwrap() {
            ends.push(t.unwrap());
        }
    }
    // Internal Z counts down: user Z-6 is 6.
    assert!(ends.iter().skip(1).all(|t| (t[2] - 6.0).abs() < 1e-6), "{ends:?}");
}

#[test]
fn under_compensation_a_move_after_a_z_move_stays_at_that_z() {
    // LinuxCNC's gmoccapy sample: an exit arc, Z up, then a bare X Y.
    let (mut i, s) = interp();
    let mut last = [0.0; N_AXES];
    for l in [
        "G21 G90 G0 X22.5 Y14 Z-10",
        "G1 Z-19 F400",
        "G41 D1",
        "G3 X30.75 Y14 Z-21.05 I4.125 J0",
        "G3 I-8.25",
        "G3 X22.5 Y14 Z-19.95 I-4.125 J0",
        "G0 Z-4",
        "G0 X22.5 Y14",
        "M2",
    ] {
        for (_, t) in commands_t1(&mut i, &s, l).unwrap() {
            last = t.unwrap_or(last);
        }
    }
    assert!((last[2] - 4.0).abs() < 1e-6, "{last:?}");
}

#[test]
fn compensation_refuses_what_linuxcnc_refuses_and_changes_nothing() {
    let (mut i, s) = interp();
    for l in ["G21 G90 G0 X10 Y10", "G18"] {
        commands_t1(&mut i, &s, l).unwrap();
    }
    let e = commands_t1(&mut i, &s, "G41 D1 G1 X20 F600").unwrap_err();
    assert!(e.message().bytes().map(char::from).collect::<String>().contains("XY plane"), "{e:?}");
    commands_t1(&mut i, &s, "G17").unwrap();
    // Entry not longer than the radius.
    let e = commands_t1(&mut i, &s, "G41 D1 G1 X10.4 F600").unwrap_err();
    assert!(e.message().bytes().map(char::from).collect::<String>().contains("entry"), "{e:?}");
    assert_eq!(i.comp.side, None);
    // A concave arc smaller than the tool.
    commands_t1(&mut i, &s, "G41 D1 G1 X20 F600").unwrap();
    let e = commands_t1(&mut i, &s, "G3 X20.6 Y10 I0.3 J0").unwrap_err();
    assert!(e.message().bytes().map(char::from).collect::<String>().contains("arc radius"), "{e:?}");
    // A move too short at an inside corner (G41, left turn after 0.3 mm).
    commands_t1(&mut i, &s, "G1 X30").unwrap();
    commands_t1(&mut i, &s, "G1 X30.3").unwrap();
    let before = i.pos_mm;
    let e = commands_t1(&mut i, &s, "G1 Y20").unwrap_err();
    assert!(e.message().bytes().map(char::from).collect::<String>().contains("too short"), "{e:?}");
    assert_eq!(i.pos_mm, before, "nothing moved");
    // G2/G3 as the exit move, a tool change, G28: refused while on.
    assert!(commands_t1(&mut i, &s, "G40 G2 X40 Y10 R5").is_err());
    assert!(commands_t1(&mut i, &s, "T2 M6").is_err());
    assert!(commands_t1(&mut i, &s, "G28").is_err());
    assert!(commands_t1(&mut i, &s, "G41 D1").is_err(), "already on");
    commands_t1(&mut i, &s, "G40").unwrap();
    assert_eq!(i.comp.side, None);
}
