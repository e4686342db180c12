//! Host tests of the G37 state machines, driven by a fake beam.

use super::*;

fn req(mode: Mode, setter: Setter) -> Request {
    Request { mode, setter, tool: 2, stored_length_um: 20_000, homed: true, travel_mm: [45.0; 3], steps_per_mm: [100.0; 3] }
}

fn calibrated() -> Setter {
    Setter { beam_z_um: 50_000, beam_width_um: 500, ref_length_um: 25_000, ref_diameter_um: 6_000, ..Setter::DEFAULT }
}

/// A beam in steps: breaks when the tip (spindle Z + length) reaches
/// `z_beam`, or when the tool (diameter `d`, beam width `w`) comes within
/// (d + w)/2 of `y_beam` with the tip below the beam.
struct FakeBeam {
    z_beam: f64,
    y_beam: f64,
    w: f64,
    len: f64,
    d: f64,
}

impl FakeBeam {
    fn broken(&self, y: i32, z: i32) -> bool {
        let tip = z as f64 + self.len;
        let near = (y as f64 - self.y_beam).abs() <= (self.d + self.w) / 2.0;
        tip >= self.z_beam && near
    }

    /// Run a whole measurement: moves are instant, seeks step one step at a
    /// time until the beam breaks. Returns the actions seen and the result.
    fn run(&self, r: &Request) -> (Vec<Action>, Result<Outcome, Fault>) {
        let mut pos = [2250i32, 2250, 100];
        let mut m = Measure::new(r).unwrap();
        let mut seen = Vec::new();
        let mut a = m.start();
        loop {
            seen.push(a);
            let ev = match a {
                Action::Done => return (seen, m.result().unwrap()),
                Action::Abort(f) => return (seen, Err(f)),
                Action::Move { xyz } => {
                    for i in 0..3 {
                        if let Some(v) = xyz[i] {
                            pos[i] = (v * 100.0).round() as i32;
                        }
                    }
                    Event::Done
                }
                Action::Seek { axis, dir, max_mm } => {
                    let (mut s, mut sa) = Seek::start(max_mm, dir);
                    loop {
                        let sev = match sa {
                            SeekAction::Probe { mm, .. } => {
                                let n = (mm.abs() * 100.0).round() as i32;
                                let step = if mm > 0.0 { 1 } else { -1 };
                                let mut hit = None;
                                for _ in 0..n {
                                    pos[axis as usize] += step;
                                    if self.broken(pos[1], pos[2]) {
                                        hit = Some(pos[axis as usize]);
                                        break;
                                    }
                                }
                                hit.map_or(SeekEvent::Missed, SeekEvent::Tripped)
                            }
                            SeekAction::Move { mm } => {
                                pos[axis as usize] += (mm * 100.0).round() as i32;
                                SeekEvent::Moved
                            }
                            SeekAction::ReadBeam => SeekEvent::Beam(self.broken(pos[1], pos[2])),
                            SeekAction::Found(p) => break Event::Tripped(p),
                            SeekAction::Fail(f) => break Event::Failed(f),
                        };
                        (s, sa) = s.step(dir, sev);
                    }
                }
            };
            a = m.step(ev);
        }
    }
}

#[test]
fn length_is_measured_from_the_z_trip_only() {
    let beam = FakeBeam { z_beam: 5000.0, y_beam: 1000.0, w: 50.0, len: 2230.4, d: 600.0 };
    let (actions, r) = beam.run(&req(Mode::Length, calibrated()));
    assert_eq!(actions[0], Action::Move { xyz: [None, None, Some(1.0)] });
    assert_eq!(actions[1], Action::Move { xyz: [Some(5.0), Some(10.0), None] });
    assert_eq!(actions[2], Action::Seek { axis: 2, dir: 1, max_mm: 44.0 });
    assert_eq!(actions[3], Action::Move { xyz: [None, None, Some(1.0)] });
    assert_eq!(actions[4], Action::Done);
    // Tip reaches 5000 at spindle 2769.6: trips at 2770 -> 50 - 27.70 = 22.30 mm.
    assert_eq!(r, Ok(Outcome::Measured { length_um: 22_300, diameter_um: None }));
}

#[test]
fn calibration_then_three_tools_come_out_within_one_step_of_length_and_two_of_diameter() {
    let setter = Setter::DEFAULT;
    let reference = FakeBeam { z_beam: 5012.0, y_beam: 1000.0, w: 50.0, len: 2500.0, d: 600.0 };
    let (_, r) = reference.run(&req(Mode::Calibrate { length_um: 25_000, diameter_um: 6_000 }, setter));
    let Ok(Outcome::Calibrated(cal)) = r else { panic!("{r:?}") };
    assert!(cal.calibrated());
    assert_eq!(cal.ref_length_um, 25_000);
    assert!((cal.beam_width_um - 500).abs() <= 10, "{cal:?}");
    for (len, d) in [(2000.0, 317.5), (3150.3, 600.0), (1712.7, 1000.0)] {
        let tool = FakeBeam { len, d, ..reference };
        let (_, r) = tool.run(&req(Mode::Diameter, cal));
        let Ok(Outcome::Measured { length_um, diameter_um: Some(d_um) }) = r else { panic!("{r:?}") };
        assert!((length_um as f64 - len * 10.0).abs() <= 10.0, "length {length_um} vs {len}");
        assert!((d_um as f64 - d * 10.0).abs() <= 20.0, "diameter {d_um} vs {d}");
    }
}

/// The quantisation bounds over many tools and beam positions between
/// steps: each trip is within one step of its edge, so a length (one trip
/// against the reference's) is within 1 step and a diameter (two edges
/// against the reference's two) within 2 steps.
#[test]
fn measurement_error_stays_within_the_step_quantisation_bounds() {
    let mut rng = crate::test_util::XorShift(0x1234_5678);
    let mut frac = || (rng.next() % 1000) as f64 / 1000.0;
    let (mut worst_l, mut worst_d) = (0.0f64, 0.0f64);
    for _ in 0..200 {
        let reference = FakeBeam { z_beam: 5000.0 + frac(), y_beam: 1000.0 + frac(), w: 40.0 + 20.0 * frac(), len: 2500.0, d: 600.0 };
        let (_, r) = reference.run(&req(Mode::Calibrate { length_um: 25_000, diameter_um: 6_000 }, Setter::DEFAULT));
        let Ok(Outcome::Calibrated(cal)) = r else { panic!("{r:?}") };
        let tool = FakeBeam { len: 1500.0 + 1500.0 * frac(), d: 100.0 + 900.0 * frac(), ..reference };
        let (_, r) = tool.run(&req(Mode::Diameter, cal));
        let Ok(Outcome::Measured { length_um, diameter_um: Some(d_um) }) = r else { panic!("{r:?}") };
        worst_l = worst_l.max((length_um as f64 / 10.0 - tool.len).abs());
        worst_d = worst_d.max((d_um as f64 / 10.0 - tool.d).abs());
    }
    assert!(worst_l <= 1.0 + 0.1, "length error {worst_l} steps");
    assert!(worst_d <= 2.0 + 0.1, "diameter error {worst_d} steps");
}

#[test]
fn diameter_approaches_from_both_sides_with_the_tip_below_the_beam() {
    let beam = FakeBeam { z_beam: 5000.0, y_beam: 1000.0, w: 50.0, len: 2000.0, d: 600.0 };
    let (actions, _) = beam.run(&req(Mode::Diameter, calibrated()));
    let moves: Vec<_> = actions.iter().filter(|a| !matches!(a, Action::Seek { .. })).collect();
    // Z trip at 3000 → tip 1 mm below the beam means spindle Z 31.0.
    assert!(moves.contains(&&Action::Move { xyz: [Some(5.0), Some(4.0), None] }));
    assert!(moves.contains(&&Action::Move { xyz: [Some(5.0), Some(16.0), None] }));
    assert_eq!(moves.iter().filter(|a| ***a == Action::Move { xyz: [None, None, Some(31.0)] }).count(), 2);
    let seeks: Vec<_> = actions.iter().filter(|a| matches!(a, Action::Seek { .. })).collect();
    assert_eq!(
        seeks,
        [
            &Action::Seek { axis: 2, dir: 1, max_mm: 44.0 },
            &Action::Seek { axis: 1, dir: 1, max_mm: 12.0 },
            &Action::Seek { axis: 1, dir: -1, max_mm: 12.0 }
        ]
    );
}

#[test]
fn broken_tool_check_flags_a_tool_half_a_millimetre_short() {
    let ok = FakeBeam { z_beam: 5000.0, y_beam: 1000.0, w: 50.0, len: 2000.0, d: 600.0 };
    let (_, r) = ok.run(&req(Mode::Check { tol_um: 200 }, calibrated()));
    assert_eq!(r, Ok(Outcome::Checked { length_um: 20_000, diff_um: 0, broken: false }));
    let short = FakeBeam { len: 1950.0, ..ok };
    let (_, r) = short.run(&req(Mode::Check { tol_um: 200 }, calibrated()));
    assert_eq!(r, Ok(Outcome::Checked { length_um: 19_500, diff_um: -500, broken: true }));
}

#[test]
fn a_beam_that_never_breaks_retracts_and_stores_nothing() {
    let never = FakeBeam { z_beam: 1e9, y_beam: 1000.0, w: 50.0, len: 2000.0, d: 600.0 };
    let (actions, r) = never.run(&req(Mode::Length, calibrated()));
    assert_eq!(r, Err(Fault::BeamNeverBroke));
    let n = actions.len();
    assert_eq!(actions[n - 2], Action::Move { xyz: [None, None, Some(Z_SAFE_MM)] });
    assert_eq!(actions[n - 1], Action::Abort(Fault::BeamNeverBroke));
}

#[test]
fn requests_that_cannot_run_are_refused_before_anything_moves() {
    assert_eq!(Measure::new(&req(Mode::Length, Setter::DEFAULT)), Err(Fault::NotCalibrated));
    let mut r = req(Mode::Length, calibrated());
    r.tool = 0;
    assert_eq!(Measure::new(&r), Err(Fault::NoTool));
    let mut r = req(Mode::Check { tol_um: 100 }, calibrated());
    r.stored_length_um = 0;
    assert_eq!(Measure::new(&r), Err(Fault::NothingToCheck));
    let mut r = req(Mode::Length, calibrated());
    r.homed = false;
    assert_eq!(Measure::new(&r), Err(Fault::NotHomed));
    let mut s = calibrated();
    s.y_um = 3_000; // 3 - 6 mm is outside travel
    assert_eq!(Measure::new(&req(Mode::Diameter, s)), Err(Fault::SoftLimit));
    assert!(Measure::new(&req(Mode::Length, s)).is_ok());
    // Calibration needs neither a calibration nor a numbered tool.
    let mut r = req(Mode::Calibrate { length_um: 1, diameter_um: 1 }, Setter::DEFAULT);
    r.tool = 0;
    assert!(Measure::new(&r).is_ok());
}

#[test]
fn seek_is_fast_then_back_off_then_slow() {
    let (s, a) = Seek::start(10.0, -1);
    assert_eq!(a, SeekAction::Probe { mm: -10.0, feed_mm_per_min: SEEK_FAST_MM_PER_MIN });
    let (s, a) = s.step(-1, SeekEvent::Tripped(500));
    assert_eq!(a, SeekAction::Move { mm: BACKOFF_MM });
    let (s, a) = s.step(-1, SeekEvent::Moved);
    assert_eq!(a, SeekAction::ReadBeam);
    let (s, a) = s.step(-1, SeekEvent::Beam(false));
    assert_eq!(a, SeekAction::Probe { mm: -2.0 * BACKOFF_MM, feed_mm_per_min: SEEK_SLOW_MM_PER_MIN });
    let (s, a) = s.step(-1, SeekEvent::Tripped(502));
    assert_eq!(a, SeekAction::Found(502));
    assert_eq!(s, Seek::Found(502));
}

#[test]
fn seek_faults() {
    let (s, _) = Seek::start(10.0, 1);
    assert_eq!(s.step(1, SeekEvent::Missed).1, SeekAction::Fail(Fault::BeamNeverBroke));
    let (s, _) = s.step(1, SeekEvent::Tripped(1));
    let (s, _) = s.step(1, SeekEvent::Moved);
    assert_eq!(s.step(1, SeekEvent::Beam(true)).1, SeekAction::Fail(Fault::BeamStuck));
    let (s, _) = s.step(1, SeekEvent::Beam(false));
    assert_eq!(s.step(1, SeekEvent::Missed).1, SeekAction::Fail(Fault::BeamNeverBroke));
}

#[test]
fn a_fault_at_any_state_retracts_then_aborts() {
    let r = req(Mode::Diameter, calibrated());
    let n_rows = TABLE.len();
    for fail_at in 0..n_rows {
        let mut m = Measure::new(&r).unwrap();
        let mut a = m.start();
        for _ in 0..fail_at {
            a = m.step(match a {
                Action::Seek { .. } => Event::Tripped(3000),
                _ => Event::Done,
            });
        }
        assert!(m.state().is_some());
        let a = m.step(Event::Failed(Fault::BeamStuck));
        assert_eq!(a, Action::Move { xyz: [None, None, Some(Z_SAFE_MM)] });
        assert_eq!(m.state(), None);
        assert_eq!(m.step(Event::Done), Action::Abort(Fault::BeamStuck));
        assert_eq!(m.result(), Some(Err(Fault::BeamStuck)));
    }
}

#[test]
fn setter_record_round_trips() {
    let s = calibrated();
    assert_eq!(Setter::from_bytes(&s.to_bytes()), Some(s));
    assert_eq!(Setter::from_bytes(&[0xFF; Setter::IMAGE_LEN]), None);
    assert!(!Setter::DEFAULT.calibrated());
}
