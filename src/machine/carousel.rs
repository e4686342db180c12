//! G201–G205: Repetier's auxiliary-motor commands on motor P0, the tool
//! carousel on the E0 axis (docs/SPEC.md §7), and carousel homing.
//!
//! Positions are in carousel units: one pocket pitch (20°), 0 = the home
//! switch. Unlike Repetier:
//! - moves go through the planner (they accelerate), and while they run the
//!   main loop keeps serving `?`, `!`, `~`, M112 and sends `busy:processing`
//!   every 2 s;
//! - homing that never finds the switch within a revolution + 25 % raises an
//!   alarm (`ALARM:carousel home switch not found`);
//! - a missing P, or a P other than 0, is an error.
//!
//! Homing seeks in the positive direction, so the switch (closed from 0° on)
//! is met at its leading edge; like the linear axes it is fast seek, back
//! off, slow seek, and position 0 is the step where the switch closed on the
//! slow approach. The carousel stays there (0°).

use super::{Alarm, CmdResult, Inputs, Io, Machine, State};
use crate::axis;
use crate::fixed::Micros;
use crate::gcode::interp::Error;
use crate::math::round_i32;
use crate::planner::Speed;
use ufmt::uwriteln;

/// Bit of the carousel in `Machine::homed`.
pub const HOMED_BIT: u8 = 1 << axis::E;
/// Pocket pitches per revolution (20° each).
pub const PITCHES_PER_REV: f32 = 18.0;
/// Homing search: one revolution plus 25 %, pitches.
const SEARCH: f32 = PITCHES_PER_REV * 1.25;
/// Back-off between the fast and the slow approach, pitches.
const PULLOFF: f32 = 0.5;
/// Fast seek feed, pitches/min (half the default maximum).
const SEEK_FEED: f32 = 300.0;
/// Slow (locate) feed, pitches/min.
const LOCATE_FEED: f32 = 30.0;
/// G202: the carousel is at `x` pitches (the step counter follows).
pub fn set_position(m: &mut Machine, io: &mut impl Io, x: f32) -> CmdResult {
    m.wait_idle(io)?;
    let mut p = io.stepper().position;
    p[axis::E] = round_i32(x * m.settings.steps_per_mm[axis::E]);
    io.set_stepper_position(p);
    m.planner.set_position(p);
    m.interp.pos_mm[axis::E] = x;
    Ok(())
}

/// G204: the carousel driver on or off.
pub fn enable(m: &mut Machine, io: &mut impl Io, on: bool) -> CmdResult {
    m.wait_idle(io)?;
    io.carousel_driver(on);
    if !on {
        // A free carousel can be turned by hand: its position is lost.
        m.homed &= !HOMED_BIT;
    }
    Ok(())
}

/// G205 `[S1] [E1]`: home the carousel; `back`: turn back to where it was;
/// `only_if_unhomed`: nothing when it is homed.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn home_command(m: &mut Machine, io: &mut impl Io, back: bool, only_if_unhomed: bool) -> CmdResult {
    if only_if_unhomed && m.homed & HOMED_BIT != 0 {
        return Ok(());
    }
    let before = m.interp.pos_mm[axis::E];
    home(m, io)?;
    if back {
        turn_to(m, io, before)?;
    }
    Ok(())
}

/// G203: `Motor0 Pos:<pitches> Endstop Hit:<0|1>`. The position is the
/// commanded one (where G201 put it), as Repetier reports it; the switch is
/// read now.
pub fn report(m: &Machine, io: &mut (impl Inputs + ufmt::uWrite)) {
    let pos = Micros::from_mm(m.interp.pos_mm[axis::E]);
    let hit = io.switches().carousel_home as u8;
    uwriteln!(io, "{}{}{}{}", F!("Motor0 Pos:"), pos, F!(" Endstop Hit:"), hit).ok();
}

/// Turn the carousel to `position` pitches through the planner and wait
/// until it is there (serving realtime requests, sending busy).
pub fn turn_to(m: &mut Machine, io: &mut impl Io, position: f32) -> CmdResult {
    let mut t = m.interp.pos_mm;
    t[axis::E] = position;
    let feed = m.settings.max_feed_mm_per_min[axis::E];
    m.move_mm(io, &t, Speed::Fixed(feed))?;
    m.wait_motion_or_trip(io).map(|_| ())
}

/// Home the carousel. Raises the alarm `carousel home switch not found`
/// when the switch does not close within a revolution + 25 %.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn home(m: &mut Machine, io: &mut impl Io) -> CmdResult {
    m.wait_idle(io)?;
    let prev = m.state;
    m.state = State::Home;
    m.homed &= !HOMED_BIT;
    let r = home_steps(m, io);
    if m.state == State::Home {
        m.state = if prev == State::Run { State::Idle } else { prev };
    }
    // Hard limits were off while in `State::Home` (see `Machine::apply_watch`).
    m.apply_watch(io, 0, false);
    match r {
        Ok(true) => {
            m.homed |= HOMED_BIT;
            Ok(())
        }
        Ok(false) => {
            m.raise(io, Alarm::CarouselHome);
            Err(Error::Alarm)
        }
        Err(e) => Err(e),
    }
}

/// Fast seek, back off, slow seek. `Ok(false)`: the switch was not found.
fn home_steps(m: &mut Machine, io: &mut impl Io) -> Result<bool, Error> {
    if io.switches().carousel_home {
        // Starting on the switch: back off it first.
        nudge(m, io, -PULLOFF, SEEK_FEED)?;
        if io.switches().carousel_home {
            return Ok(false);
        }
    }
    if !seek(m, io, SEARCH, SEEK_FEED)? {
        return Ok(false);
    }
    nudge(m, io, -PULLOFF, SEEK_FEED)?;
    seek(m, io, 2.0 * PULLOFF, LOCATE_FEED)
}

/// Relative carousel move without watching the switch.
fn nudge(m: &mut Machine, io: &mut impl Io, pitches: f32, feed: f32) -> CmdResult {
    let mut target = io.stepper().position;
    target[axis::E] += round_i32(pitches * m.settings.steps_per_mm[axis::E]);
    m.queue_line(io, &target, Speed::Fixed(feed))?;
    m.wait_motion_or_trip(io).map(|_| ())
}

/// Turn forward by up to `pitches` until the ISR latches the switch; the
/// carousel position is then 0 at the latched step (the same seek as the
/// linear axes', [`Machine::seek_switch`]).
fn seek(m: &mut Machine, io: &mut impl Io, pitches: f32, feed: f32) -> Result<bool, Error> {
    let steps = round_i32(pitches * m.settings.steps_per_mm[axis::E]);
    m.seek_switch(io, axis::E, steps, feed)
}
