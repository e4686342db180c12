//! Homing: the runner of G28 / `$H` for X, Y, Z, which performs the
//! actions of the pure cycle ([`cycle`]: fast seek, back off, slow seek,
//! back off, per axis in the order Z, Y, X) through the planner, and the
//! one switch seek that it and the carousel's homing share
//! (`Machine::seek_switch`).

pub mod cycle;

use super::{Alarm, CmdResult, Inputs, Io, Machine, State};
use crate::gcode::interp;
use crate::math::round_i32;
use crate::planner::Speed;
use cycle::{Action, Cycle, Event, Request};

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
        let r = self.queue_line(io, &target, Speed::Fixed(feed)).and_then(|_| self.wait_motion_or_trip(io));
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
}

/// G28: home the axes in `mask` in the order Z, Y, X: fast seek, back off,
/// slow seek, back off ([`cycle`]'s table). Position 0 is where the switch
/// trips on the slow approach; the final back-off is counted (position =
/// pull-off distance).
// flash: one copy (the runners' attributes removed: +1034 B flash)
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
    let r = run(m, io, mask);
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

/// Perform the cycle's actions until it ends, in `State::Home`.
fn run(m: &mut Machine, io: &mut impl Io, mask: u8) -> CmdResult {
    let s = &m.settings;
    let req = Request {
        mask,
        travel_mm: [s.travel_mm[0], s.travel_mm[1], s.travel_mm[2]],
        pulloff_mm: s.homing_pulloff_mm,
        seek_feed_mm_per_min: s.homing_seek_mm_per_min,
        locate_feed_mm_per_min: s.homing_feed_mm_per_min,
    };
    let mut c = Cycle::new(&req);
    // The error of the action that was stopped (an alarm, an abort).
    let mut stopped = interp::Error::Aborted;
    let mut a = c.start();
    loop {
        let ev = match a {
            Action::Done => return Ok(()),
            Action::Fail => {
                m.raise(io, Alarm::HomingFailed);
                return Err(interp::Error::HomingFailed);
            }
            Action::Stop => return Err(stopped),
            Action::Unhome { axis } => {
                m.homed &= !(1 << axis);
                Event::Done
            }
            Action::Homed { axis } => {
                m.homed |= 1 << axis;
                Event::Done
            }
            Action::ReadSwitch { axis } => switch(io, axis),
            Action::PullOff { axis, mm, feed_mm_per_min } => match pull_off(m, io, axis as usize, mm, feed_mm_per_min) {
                Ok(()) => switch(io, axis),
                Err(e) => {
                    stopped = e;
                    Event::Stopped
                }
            },
            Action::Seek { axis, mm, feed_mm_per_min } => {
                // Toward the switch (−).
                let steps = round_i32(mm * m.settings.steps_per_mm[axis as usize]);
                match m.seek_switch(io, axis as usize, -steps, feed_mm_per_min) {
                    Ok(tripped) => Event::Seek(tripped),
                    Err(e) => {
                        stopped = e;
                        Event::Stopped
                    }
                }
            }
        };
        a = c.step(ev);
    }
}

/// The cycle's answer when it asks for `axis`' home switch.
fn switch(io: &impl Inputs, axis: u8) -> Event {
    Event::Switch(io.switches().home & (1 << axis) != 0)
}

/// Move `axis` away from its switch by `mm` (no switch watching: the
/// caller is in `State::Home`, so hard limits are off) and wait until it
/// stands; the cycle then reads the switch, which must have let go. The
/// switch opened hysteresis-worth of travel before the end of the
/// pull-off, so its bounce is long over.
fn pull_off(m: &mut Machine, io: &mut impl Io, axis: usize, mm: f32, feed: f32) -> CmdResult {
    let mut target = io.stepper().position;
    target[axis] += round_i32(mm * m.settings.steps_per_mm[axis]);
    m.queue_line(io, &target, Speed::Fixed(feed))?;
    m.wait_idle(io)
}
