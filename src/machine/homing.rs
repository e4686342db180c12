//! Homing: G28 / `$H` for X, Y, Z (fast seek, back off, slow seek, back
//! off, per axis in the order Z, Y, X) and the one switch seek that it and
//! the carousel's homing share ([`Machine::seek_switch`]).

use super::{Alarm, CmdResult, Io, Machine, State};
use crate::gcode::interp;
use crate::planner::Speed;

impl Machine {
    /// One homing seek, the only one (G28's axes and the carousel's G205):
    /// move `axis` by up to `steps` (signed, toward its switch) with the ISR
    /// watching the switch (`set_watch`'s homing mask bit `axis`: X, Y, Z or
    /// the carousel on E). Returns true when the switch tripped; the axis
    /// position is then 0 at the trip step (docs/SPEC.md §6: Marlin's convention).
    pub(crate) fn seek_switch(&mut self, io: &mut impl Io, axis: usize, steps: i32, feed: f32) -> Result<bool, interp::Error> {
        self.apply_watch(io, 1 << axis, false);
        let mut target = io.stepper().position;
        target[axis] += steps;
        let r = self.queue_line(io, target, Speed::Fixed(feed)).and_then(|_| self.wait_motion_or_trip(io));
        self.apply_watch(io, 0, false);
        let tripped = r?;
        if tripped {
            let trip = io.stepper().trip_position;
            let mut now = io.stepper().position;
            now[axis] -= trip[axis];
            io.set_stepper_position(now);
        }
        self.resync_after_stop(io);
        Ok(tripped)
    }

    /// A linear axis' homing seek toward its switch (−) by up to `dist_mm`.
    pub(super) fn home_seek(&mut self, io: &mut impl Io, axis: usize, dist_mm: f32, feed: f32) -> Result<bool, interp::Error> {
        let steps = crate::math::round_i32(dist_mm * self.settings.steps_per_mm[axis]);
        self.seek_switch(io, axis, -steps, feed)
    }

    /// Move `axis` away from its switch by `dist_mm` (no switch watching:
    /// the caller is in `State::Home`, so hard limits are off), then check
    /// the switch let go: a pull-off shorter than the switch's hysteresis
    /// fails here, not later as a hard limit on the first move (grbl's
    /// alarm 8). The switch opened hysteresis-worth of travel before the
    /// end of the pull-off, so its bounce is long over.
    pub(super) fn home_pulloff(&mut self, io: &mut impl Io, axis: usize, dist_mm: f32, feed: f32) -> CmdResult {
        let mut target = io.stepper().position;
        target[axis] += crate::math::round_i32(dist_mm * self.settings.steps_per_mm[axis]);
        self.queue_line(io, target, Speed::Fixed(feed))?;
        self.wait_idle(io)?;
        if io.switches().home & (1 << axis) != 0 {
            return self.home_fail(io);
        }
        Ok(())
    }

    pub(super) fn home_fail(&mut self, io: &mut impl Io) -> CmdResult {
        self.raise(io, Alarm::HomingFailed);
        Err(interp::Error::HomingFailed)
    }
}

/// G28: home the axes in `mask` in the order Z, Y, X: fast seek, back off,
/// slow seek, back off. Position 0 is where the switch trips on the slow
/// approach; the final back-off is counted (position = pull-off distance).
#[inline(never)]
pub fn home(m: &mut Machine, io: &mut impl Io, mask: u8) -> CmdResult {
    if m.alarm.is_some() {
        // Homing is the way out of an alarm (except M112, checked by the
        // caller). Clear it first: waiting for the (already stopped) motion
        // fails while an alarm is set.
        m.clear_alarm(io);
    }
    m.wait_idle(io)?;
    io.drivers(true);
    let prev = m.state;
    m.state = State::Home;
    // Hard limits off for the whole cycle (see `apply_watch`).
    m.apply_watch(io, 0, false);
    let r = home_axes(m, io, mask);
    if m.state == State::Home {
        m.state = if prev == State::Alarm || prev == State::Home { State::Idle } else { prev };
    }
    // Re-armed only now, with every homed axis pulled off its switch (or
    // after a failure, with the alarm raised).
    m.limits_held &= !m.homed;
    m.apply_watch(io, 0, false);
    r?;
    let p = io.stepper().position;
    // Also starts the hard-limit bookkeeping afresh: the homed axes left
    // their switches (`ChunkWatch::release`).
    io.set_stepper_position(p);
    m.planner.set_position(p);
    m.interp.sync_position(&m.settings, p);
    Ok(())
}

/// The per-axis part of [`home`], in `State::Home`.
fn home_axes(m: &mut Machine, io: &mut impl Io, mask: u8) -> CmdResult {
    let s = m.settings;
    for axis in [2usize, 1, 0] {
        if mask & (1 << axis) == 0 {
            continue;
        }
        m.homed &= !(1 << axis);
        // `max` without f32::max (compiler-builtins' fmaximum_numf, 142 bytes).
        let pulloff = if s.homing_pulloff_mm >= 0.1 { s.homing_pulloff_mm } else { 0.1 };
        if io.switches().home & (1 << axis) != 0 {
            // Starting on the switch: move off it first (fails if it stays closed).
            m.home_pulloff(io, axis, pulloff, s.homing_feed_mm_per_min)?;
        }
        let travel = s.travel_mm[axis] * 1.1;
        if !m.home_seek(io, axis, travel, s.homing_seek_mm_per_min)? {
            return m.home_fail(io);
        }
        m.home_pulloff(io, axis, pulloff, s.homing_seek_mm_per_min)?;
        if !m.home_seek(io, axis, pulloff * 2.0, s.homing_feed_mm_per_min)? {
            return m.home_fail(io);
        }
        m.home_pulloff(io, axis, pulloff, s.homing_feed_mm_per_min)?;
        m.homed |= 1 << axis;
    }
    Ok(())
}
