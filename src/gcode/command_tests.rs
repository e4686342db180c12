//! Host tests of the interpreter alone: lines in, [`Command`]s out, with no
//! machine (the step API of `interp.rs`). `interp_tests.rs` runs whole
//! lines through the controller.

use super::*;
use crate::atc::Atc;
use crate::config::Settings;

/// Every command of `text`, with the target of each move (`None` for the
/// others), as a controller that carries each out at once would see them.
fn commands(i: &mut Interp, s: &Settings, text: &str) -> Result<Vec<(Command, Option<[f32; N_AXES]>)>, Error> {
    let atc = Atc::new();
    let cx = Ctx { settings: s, atc: &atc, alarm: false, estop: false, status_only: false };
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
