//! G37's executor: performs the actions of [`crate::toolsetter::Measure`] and
//! [`crate::toolsetter::Seek`] through the planner, with the stepper ISR's probe latch
//! watching the beam, and stores the results.
//!
//! Replies (one line each, docs/SPEC.md §8):
//! - `[TOOL:<n> L:<mm>]`, with D1 `[TOOL:<n> L:<mm> D:<mm>]`;
//! - with B: `[TOOL:<n> L:<mm> dL:<mm>]`, then `ALARM:broken tool` when off by more than tol;
//! - calibration: `[SETTER Z:<beam tip height, machine mm, +Z up> W:<beam width mm>]`.

use super::{Alarm, Io, Machine, State};
use crate::atc::tools::EEPROM_SETTER_ADDR;
use crate::fixed::Micros;
use crate::gcode::interp::Error;
use crate::math::round_i32;
use crate::planner::Speed;
use crate::toolsetter::{Action, Event, Fault, Measure, Mode, Outcome, Request, Seek, SeekAction, SeekEvent};
use crate::N_AXES;
use ufmt::{uwrite, uwriteln};

/// G37 [D1] [B<tol>] / G37 L<len> R<radius> [X Y].
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn g37(m: &mut Machine, io: &mut impl Io, mode: Mode, x: Option<f32>, y: Option<f32>) -> Result<(), Error> {
    m.wait_idle(io)?;
    let mut setter = m.setter;
    if let Some(x) = x {
        setter.x_um = round_i32(x * 1000.0);
    }
    if let Some(y) = y {
        setter.y_um = round_i32(y * 1000.0);
    }
    let tool = m.atc.spindle();
    let s = &m.settings;
    let req = Request {
        mode,
        setter,
        tool,
        stored_length_um: m.atc.table.length_um(tool),
        homed: m.homed & 0b111 == 0b111,
        travel_mm: s.travel_mm,
        steps_per_mm: [s.steps_per_mm[0], s.steps_per_mm[1], s.steps_per_mm[2]],
    };
    let mut meas = Measure::new(&req).map_err(Error::Setter)?;
    if io.switches().tool_setter {
        return Err(Error::Setter(Fault::BeamBlocked));
    }
    let prev = m.state;
    m.state = State::Probe;
    let (out, failure) = run_actions(m, io, &mut meas);
    if m.state == State::Probe {
        m.state = if prev == State::Run { State::Idle } else { prev };
    }
    match out {
        Some(Ok(o)) => store(m, io, tool, o),
        Some(Err(f)) => {
            // (An abort or an alarm on the way ends as `Fault::Stopped`.)
            if f == Fault::BeamNeverBroke && m.alarm.is_none() && m.wait_idle(io).is_ok() {
                // As a G38.2 that touches nothing (grbl's ALARM:5): what
                // follows must not run with a tool that was never measured.
                m.raise(io, Alarm::ProbeFailed);
            }
            Err(failure.unwrap_or(Error::Setter(f)))
        }
        None => Err(Error::Setter(Fault::Stopped)),
    }
}

/// Perform the measurement's actions until it ends: its result, and the
/// error of the first action that failed.
fn run_actions(m: &mut Machine, io: &mut impl Io, meas: &mut Measure) -> (Option<Result<Outcome, Fault>>, Option<Error>) {
    let mut failure = None;
    let mut a = meas.start();
    let out = loop {
        let r = match a {
            Action::Done => break meas.result(),
            Action::Abort(_) => break meas.result(),
            Action::Move { xyz } => rapid(m, io, xyz).map(|_| Event::Done),
            Action::Seek { axis, dir, max_mm } => seek(m, io, axis as usize, dir, max_mm).map(Event::Tripped),
        };
        let ev = match r {
            Ok(ev) => ev,
            Err(e) => {
                let f = match e {
                    Error::Setter(f) => f,
                    _ => Fault::Stopped,
                };
                failure.get_or_insert(e);
                Event::Failed(f)
            }
        };
        a = meas.step(ev);
    };
    (out, failure)
}

/// Keep a measurement's result and report it in one line.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
fn store(m: &mut Machine, io: &mut impl Io, tool: u8, o: Outcome) -> Result<(), Error> {
    let before = m.atc.table;
    match o {
        Outcome::Measured { length_um, diameter_um } => {
            let i = tool as usize - 1;
            m.atc.table.length_um[i] = length_um;
            uwrite!(io, "{}{}{}{}", F!("[TOOL:"), tool, F!(" L:"), Micros(length_um)).ok();
            if let Some(d) = diameter_um {
                m.atc.table.diameter_um[i] = d.clamp(0, u16::MAX as i32) as u16;
                uwrite!(io, "{}{}", F!(" D:"), Micros(d)).ok();
            }
            uwriteln!(io, "]").ok();
        }
        Outcome::Checked { length_um, diff_um, broken } => {
            uwrite!(io, "{}{}{}{}", F!("[TOOL:"), tool, F!(" L:"), Micros(length_um)).ok();
            uwriteln!(io, "{}{}]", F!(" dL:"), Micros(diff_um)).ok();
            if broken {
                m.raise(io, Alarm::BrokenTool);
                return Err(Error::Alarm);
            }
        }
        Outcome::Calibrated(s) => {
            store_setter(m, io, s);
            if tool != 0 {
                let i = tool as usize - 1;
                m.atc.table.length_um[i] = s.ref_length_um;
                m.atc.table.diameter_um[i] = s.ref_diameter_um.clamp(0, u16::MAX as i32) as u16;
            }
            uwriteln!(
                io,
                "{}{}{}{}]",
                F!("[SETTER Z:"),
                Micros(crate::frame::z_user_from_internal_i32(s.beam_z_um)),
                F!(" W:"),
                Micros(s.beam_width_um)
            )
            .ok();
        }
    }
    super::toolchange::store_table(m, io, &before);
    super::toolchange::apply_offset(m);
    Ok(())
}

/// The setter record as `s` (its reference tool, say), in EEPROM when it
/// changed.
pub fn store_setter(m: &mut Machine, io: &mut impl Io, s: crate::toolsetter::Setter) {
    if s != m.setter {
        m.setter = s;
        io.eeprom_write(EEPROM_SETTER_ADDR, &s.to_bytes());
    }
}

/// Rapid to machine mm (`None` keeps the axis) and wait.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
fn rapid(m: &mut Machine, io: &mut impl Io, xyz: [Option<f32>; 3]) -> Result<(), Error> {
    let mut t = m.interp.pos_mm;
    for (i, v) in xyz.iter().enumerate() {
        if let Some(v) = v {
            t[i] = *v;
        }
    }
    m.move_mm(io, &t, Speed::Rapid)?;
    m.wait_motion_or_trip(io).map(|_| ())
}

/// One seek (fast, back off, slow) on `axis`; the latched step of the slow trip.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
fn seek(m: &mut Machine, io: &mut impl Io, axis: usize, dir: i8, max_mm: f32) -> Result<i32, Error> {
    let (mut s, mut a) = Seek::start(max_mm, dir);
    loop {
        let ev = match a {
            SeekAction::Probe { mm, feed_mm_per_min } => match probe(m, io, axis, mm, Some(feed_mm_per_min))? {
                Some(p) => SeekEvent::Tripped(p),
                None => SeekEvent::Missed,
            },
            SeekAction::Move { mm } => {
                probe(m, io, axis, mm, None)?;
                SeekEvent::Moved
            }
            SeekAction::ReadBeam => SeekEvent::Beam(io.switches().tool_setter),
            SeekAction::Found(p) => return Ok(p),
            SeekAction::Fail(f) => return Err(Error::Setter(f)),
        };
        (s, a) = s.step(dir, ev);
    }
}

/// Move `axis` by `mm`. With a feed, the ISR watches the beam and stops on
/// the step that breaks it: returns that step. Without, a plain move at the
/// slow-seek feed.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
fn probe(m: &mut Machine, io: &mut impl Io, axis: usize, mm: f32, feed: Option<f32>) -> Result<Option<i32>, Error> {
    let watch = feed.is_some();
    let mut target: [i32; N_AXES] = io.stepper().position;
    target[axis] += round_i32(mm * m.settings.steps_per_mm[axis]);
    m.apply_watch(io, 0, watch);
    let r = m
        .queue_line(io, &target, Speed::Fixed(feed.unwrap_or(crate::toolsetter::SEEK_FAST_MM_PER_MIN)))
        .and_then(|_| m.wait_motion_or_trip(io));
    m.apply_watch(io, 0, false);
    let tripped = r?;
    let trip = io.stepper().trip_position[axis];
    m.resync_after_stop(io);
    Ok((watch && tripped).then_some(trip))
}
