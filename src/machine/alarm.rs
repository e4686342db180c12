//! How the machine stops: alarms ([`Alarm`], [`Machine::raise`],
//! [`Machine::clear_alarm`]), the hard limits the ISR watches and their
//! re-arming, an abort's end, and grbl's soft reset (0x18).

use super::{Inputs, Io, LineSource, Machine, Outputs, State, Stepper, LIMIT_REARM_MS};
use crate::stepper::rings::Watch;
use ufmt::{uwrite, uwriteln};

crate::flash_messages! {
    /// Why the machine is in alarm (docs/SPEC.md §10); `message`: the text after
    /// `Error:alarm ` / `ALARM:`.
    #[derive(Clone, Copy, PartialEq, Eq, Debug)]
    pub enum Alarm {
        /// M112 received.
        EmergencyStop => "emergency stop",
        /// A home switch closed outside homing.
        HardLimit => "hard limit",
        /// G28 did not find a switch within travel + 10 %.
        HomingFailed => "homing failed",
        /// The probe input did not trip (G38.2).
        ProbeFailed => "probe failed",
        /// Booted after a watchdog reset.
        WatchdogReset => "watchdog reset",
        /// G205 / a tool change did not find the carousel switch.
        CarouselHome => "carousel home switch not found",
        /// G37 B: the tool's length is off by more than the tolerance.
        BrokenTool => "broken tool",
        /// 0x18 (soft reset) while steps were being produced: the stop was
        /// abrupt, steps may be lost (grbl's ALARM:3).
        ResetWhileMoving => "reset while moving",
    }
}

impl Alarm {
    /// grbl 1.1's alarm number (grblHAL's 10 for the emergency stop), for
    /// grbl senders (`ALARM:<n>`).
    pub fn grbl_code(self) -> u8 {
        match self {
            Alarm::HardLimit => 1,
            Alarm::ResetWhileMoving | Alarm::WatchdogReset => 3,
            Alarm::ProbeFailed | Alarm::BrokenTool => 5,
            Alarm::HomingFailed | Alarm::CarouselHome => 9,
            Alarm::EmergencyStop => 10,
        }
    }
}

impl Machine {
    /// Enter the alarm state: stop steps, spindle off, forget the queue.
    // speed: not inlined into idle (realtime/alarm/status attributes removed: ping-pong 5.756 -> 5.793 s)
    #[inline(never)]
    pub fn raise(&mut self, io: &mut (impl Stepper + Outputs + ufmt::uWrite), alarm: Alarm) {
        io.stop_motion();
        io.spindle(0);
        io.coolant(false);
        // Off for the interpreter too: an S word alone must not restart it.
        self.interp.spindle_on = false;
        self.interp.coolant_m = 9;
        if alarm == Alarm::EmergencyStop {
            io.drivers(false);
        }
        self.alarm = Some(alarm);
        self.state = State::Alarm;
        // A probe that ended its move untouched stopped cleanly: the
        // position is still exact. Every other alarm may have lost steps.
        if alarm != Alarm::ProbeFailed {
            self.homed = 0;
        }
        self.limits_held = 0;
        self.unlocked = false;
        self.holding = false;
        self.aborting = false;
        self.planner.clear();
        self.prep.reset();
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        if self.grbl_replies {
            let (code, why) = (alarm.grbl_code(), alarm.message());
            uwriteln!(io, "{}{}{}{}{}", F!("ALARM:"), code, F!("\n[MSG:"), why, F!("; $H or $X to continue]")).ok();
        } else {
            uwriteln!(io, "{}{}", F!("ALARM:"), alarm.message()).ok();
            uwriteln!(io, "{}", F!("echo:home (G28) or M999 to continue")).ok();
        }
    }

    /// M999: leave the alarm state. Position stays unknown until homed.
    pub fn clear_alarm(&mut self, io: &mut (impl Inputs + Stepper)) {
        // A switch still closed (the axis stopped on it) is not armed until
        // it opens, or the alarm would come back at once.
        self.limits_held = io.switches().home & 0b111;
        self.held_since_ms = io.millis() as u16;
        io.clear_stop();
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        self.alarm = None;
        self.unlocked = true;
        self.state = State::Idle;
        self.apply_watch(io, 0, false);
    }

    /// Arm the hard limit of each held axis (see [`Machine::limits_held`])
    /// whose switch has read open for [`LIMIT_REARM_MS`]: longer than a
    /// switch's bounce, so it is not re-armed on a bounce.
    pub(super) fn rearm_limits(&mut self, io: &mut (impl Inputs + Stepper)) {
        let now = io.millis() as u16;
        let open = self.limits_held & !io.switches().home;
        if open == 0 {
            self.held_since_ms = now;
        } else if now.wrapping_sub(self.held_since_ms) >= LIMIT_REARM_MS {
            self.limits_held &= !open;
            self.apply_watch(io, 0, false);
        }
    }

    /// Tell the ISR what to watch. Hard limits stay off through a whole
    /// homing cycle (`State::Home`), pull-offs included, as in grbl: an axis
    /// not yet homed may rest on its closed switch, and a real switch stays
    /// closed for its hysteresis and bounces after it opens.
    pub fn apply_watch(&mut self, io: &mut impl Stepper, homing: u8, probe: bool) {
        let arm = self.settings.hard_limits && homing == 0 && self.state != State::Home;
        let limits = if arm { 0b111 & !self.limits_held } else { 0 };
        // A real switch that closed at machine 0 may stay closed for its
        // hysteresis; homing checked that the pull-off clears it.
        let mut release = [0u16; 3];
        let pulloff = super::homing::cycle::pulloff_mm(self.settings.homing_pulloff_mm);
        for (a, r) in release.iter_mut().enumerate() {
            let steps = crate::math::round_i32(pulloff * self.settings.steps_per_mm[a]);
            *r = steps.clamp(0, u16::MAX as i32) as u16;
        }
        io.set_watch(Watch {
            homing,
            probe,
            limits,
            homed: self.homed,
            invert_dir: self.settings.invert_dir_mask,
            invert_inputs: self.settings.invert_input_mask,
            release,
        });
    }

    /// The abort's deceleration has ended: drop the queue, keep the
    /// position, turn the spindle off. Waits in progress fail with
    /// `Error::Aborted`, so the line that was running stops too.
    pub(super) fn finish_abort(&mut self, io: &mut (impl Stepper + Outputs)) {
        self.aborting = false;
        self.holding = false;
        io.stop_motion();
        self.planner.clear();
        self.prep.reset();
        io.clear_stop();
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        // A cancelled jog leaves the spindle as it was (grbl); so does an
        // abort whose caller retracts the tool first.
        if self.state != State::Jog && !core::mem::take(&mut self.abort_keeps_spindle) {
            self.spindle_off(io);
        }
        if matches!(self.state, State::Hold | State::Run | State::Jog) {
            self.state = State::Idle;
        }
        self.aborts = self.aborts.wrapping_add(1);
    }

    /// 0x18 (Ctrl-X), grbl's soft reset. The RX interrupt has halted the
    /// stepper already; here every queue is dropped (planner, segments, the
    /// RX ring and the line being assembled), the spindle goes off, holds
    /// and aborts end, and the line being run (if any) stops without a
    /// reply. The position is kept, unless steps were still being produced
    /// (an abrupt stop may lose steps): then `ALARM:reset while moving`
    /// (grbl's ALARM:3), and homing or `$X` is needed. An alarm in force
    /// stays. Then grbl 1.1's banner, which grbl hosts (cncjs) wait for.
    // speed: not inlined into idle (realtime/alarm/status attributes removed: ping-pong 5.756 -> 5.793 s)
    #[inline(never)]
    pub fn soft_reset(&mut self, io: &mut impl Io, moving: bool) {
        io.stop_motion();
        self.planner.clear();
        self.prep.reset();
        if self.alarm.is_none() {
            io.clear_stop();
        }
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        self.spindle_off(io);
        // grbl's soft reset puts every override back to 100 %.
        self.planner.set_overrides(100, 100, &self.settings);
        self.spindle_pct = 100;
        self.holding = false;
        self.aborting = false;
        self.tripped = false;
        self.apply_watch(io, 0, false);
        io.flush_rx();
        self.input_flushed = true;
        self.aborts = self.aborts.wrapping_add(1);
        if self.source == LineSource::Serial {
            self.source = LineSource::SerialReset;
        }
        if self.alarm.is_none() {
            // Whatever ran (a move, homing, a tool change, a probe) is over.
            self.state = State::Idle;
        }
        if moving && self.alarm.is_none() {
            self.raise(io, Alarm::ResetWhileMoving);
        }
        uwrite!(io, "{}", F!("\r\nGrbl 1.1h ['$' for help]\r\n")).ok();
        if self.alarm.is_some() {
            uwriteln!(io, "{}", F!("[MSG:'$H'|'$X' to unlock]")).ok();
        }
    }

    /// Spindle and coolant off (and remembered as off): aborts, program end.
    pub fn spindle_off(&mut self, io: &mut impl Outputs) {
        self.interp.spindle_on = false;
        self.spindle_stopped = false;
        self.interp.coolant_m = 9;
        io.spindle(0);
        io.coolant(false);
    }
}
