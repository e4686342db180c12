//! The main loop's turn ([`Machine::idle`]): segments topped up, then the
//! realtime requests served (soft reset, M112, hard limit, feed hold and
//! resume, jog cancel, abort, grbl's overrides, `?`), and M0/M1's wait.

use super::{Alarm, CmdResult, Io, Machine, State};
use crate::gcode::interp;

impl Machine {
    /// Main-loop housekeeping: segments, realtime requests, state.
    // speed: keeps idle's frame small (realtime/alarm/status attributes removed: ping-pong 5.756 -> 5.793 s)
    #[inline(never)]
    pub fn idle(&mut self, io: &mut impl Io) {
        self.fill_segments(io);
        let rt = io.poll();
        self.tripped = rt.home_tripped || rt.probe_tripped;
        if rt.reset {
            self.soft_reset(io, rt.reset_moving);
        }
        if rt.estop && self.alarm != Some(Alarm::EmergencyStop) {
            self.raise(io, Alarm::EmergencyStop);
        }
        if rt.limit && self.alarm.is_none() {
            self.limit_axes = io.switches().home & 0b111;
            self.raise(io, Alarm::HardLimit);
        }
        if rt.hold && self.alarm.is_none() && !self.holding {
            self.holding = true;
            self.prep.hold();
            if self.state == State::Run || self.state == State::Idle {
                self.state = State::Hold;
            }
        }
        if rt.motion_ovr | rt.accessory_ovr != 0 {
            self.apply_overrides(io, rt.motion_ovr, rt.accessory_ovr);
        }
        if rt.resume && self.holding && !self.aborting {
            self.holding = false;
            if self.spindle_stopped {
                // 0x9E stopped it in the hold: back on before the motion.
                self.spindle_stopped = false;
                io.spindle(crate::overrides::spindle_duty(self.spindle_duty, self.spindle_pct));
            }
            if self.prep.is_held() || !io.stepper_busy() {
                self.planner.cycle_reinitialize();
            }
            self.prep.resume();
            if self.state == State::Hold {
                self.state = State::Run;
            }
            self.fill_segments(io);
        }
        // grbl: a jog ends on 0x85 or on a feed hold, decelerating, with
        // every queued jog move dropped.
        if (rt.jog_cancel || rt.hold) && self.state == State::Jog && !self.aborting {
            self.aborting = true;
            if !self.holding {
                self.holding = true;
                self.prep.hold();
            }
        }
        if rt.abort && self.alarm.is_none() && !self.aborting {
            self.aborting = true;
            self.abort_keeps_spindle = rt.abort_keep_spindle;
            if !self.holding {
                self.holding = true;
                self.prep.hold();
            }
        }
        if self.aborting && (self.prep.is_held() || self.motion_done(io)) && !io.stepper_busy() {
            self.finish_abort(io);
        }
        if self.limits_held != 0 {
            self.rearm_limits(io);
        }
        // Before the report: a `?` right after M400's `ok` says Idle.
        if matches!(self.state, State::Run | State::Jog) && self.motion_done(io) {
            self.state = State::Idle;
        }
        if rt.status {
            self.status_report(io);
        }
        io.background(self);
    }

    /// grbl's realtime overrides: the feed and rapid overrides re-plan the
    /// queued moves at once ([`Planner::set_overrides`](crate::planner::Planner::set_overrides)); the spindle
    /// override scales the spindle's duty now; 0x9E stops the spindle in a
    /// hold (again: on; `~` restores it); 0xA0/0xA1 toggle the coolant in
    /// Idle, Run or Hold (grbl's states for them).
    // speed: keeps idle's frame small (realtime/alarm/status attributes removed: ping-pong 5.756 -> 5.793 s)
    #[inline(never)]
    pub(super) fn apply_overrides(&mut self, io: &mut impl Io, motion: u8, accessory: u8) {
        use crate::overrides::{accessory as acc, spindle_duty, Percent};
        let mut p = Percent { feed: self.planner.feed_override(), rapid: self.planner.rapid_override(), spindle: self.spindle_pct };
        p.apply_motion(motion);
        p.apply_spindle(accessory);
        if p != self.overrides() {
            // The next status report carries `Ov:` (grbl's refresh rule).
            self.report_count = 0;
        }
        self.planner.set_overrides(p.feed, p.rapid, &self.settings);
        let on = self.interp.spindle_on;
        if p.spindle != self.spindle_pct {
            self.spindle_pct = p.spindle;
            if on && !self.spindle_stopped {
                io.spindle(spindle_duty(self.spindle_duty, p.spindle));
            }
        }
        if accessory & acc::SPINDLE_STOP != 0 && self.holding && on {
            self.spindle_stopped = !self.spindle_stopped;
            io.spindle(if self.spindle_stopped { 0 } else { spindle_duty(self.spindle_duty, p.spindle) });
        }
        if accessory & (acc::FLOOD | acc::MIST) != 0 && matches!(self.state, State::Idle | State::Run | State::Hold) {
            let m = if self.interp.coolant_m != 9 {
                9
            } else if accessory & acc::FLOOD != 0 {
                8
            } else {
                7
            };
            self.interp.coolant_m = m;
            io.coolant(m != 9);
        }
    }

    /// The spindle override (the menu), percent within grbl's 10–200 %: the
    /// output follows at once when the spindle turns, as with 0x9A/0x9B.
    pub fn set_spindle_override(&mut self, io: &mut impl Io, pct: u8) {
        let pct = pct.clamp(crate::overrides::MIN_PCT as u8, crate::overrides::MAX_PCT as u8);
        if pct != self.spindle_pct {
            self.spindle_pct = pct;
            // The next status report carries `Ov:`.
            self.report_count = 0;
            if self.interp.spindle_on && !self.spindle_stopped {
                io.spindle(crate::overrides::spindle_duty(self.spindle_duty, pct));
            }
        }
    }

    /// The feed override (M220, the menu), for the queued moves too.
    pub fn set_feed_override(&mut self, pct: u16) {
        self.planner.set_overrides(pct, self.planner.rapid_override(), &self.settings);
    }

    /// The feed (programmed, times the feed override) and the spindle
    /// speed (times the spindle override; 0 when off), for `FS:` and the
    /// status screen.
    pub fn feed_and_speed(&self) -> (f32, f32) {
        let (f, s) = self.interp.feed_and_speed();
        (f * self.planner.feed_override() as f32 * 0.01, s * self.spindle_pct as f32 * 0.01)
    }

    /// The feed, rapid and spindle overrides in force, percent (`Ov:`).
    pub fn overrides(&self) -> crate::overrides::Percent {
        crate::overrides::Percent { feed: self.planner.feed_override(), rapid: self.planner.rapid_override(), spindle: self.spindle_pct }
    }

    /// M0/M1: wait for `~` (resume).
    // speed: keeps idle's frame small (realtime/alarm/status attributes removed: ping-pong 5.756 -> 5.793 s)
    #[inline(never)]
    pub fn pause_until_resume(&mut self, io: &mut impl Io) -> CmdResult {
        let prev = self.state;
        self.state = State::Hold;
        loop {
            self.keepalive(io);
            self.fill_segments(io);
            let rt = io.poll();
            self.tripped = rt.home_tripped || rt.probe_tripped;
            if rt.estop {
                self.raise(io, Alarm::EmergencyStop);
                return Err(interp::Error::Alarm);
            }
            if rt.status {
                self.status_report(io);
            }
            if rt.resume {
                self.state = prev;
                return Ok(());
            }
            if rt.abort {
                // Nothing is moving during M0/M1 (the queue drained first).
                self.finish_abort(io);
                return Err(interp::Error::Aborted);
            }
            io.background(self);
        }
    }
}
