//! Motion: the one way into the planner ([`Machine::queue_line`] and
//! [`Machine::move_mm`] over it), the homing lock and the keep-out clip,
//! jogs (`$J=`, the menu's), G38 probing, the card-out retract, and every
//! wait ([`Machine::wait_step`]: top up the segment ring, serve realtime
//! requests, send the keepalive).

use super::{after_eq, Alarm, CmdResult, Inputs, Io, Machine, State, Stepper, RETRACT_FEED_MM_PER_MIN};
use crate::gcode::interp;
use crate::planner::{PlanError, Speed};
use crate::N_AXES;
use ufmt::{uwrite, uwriteln};

impl Machine {
    /// Queue a straight move to `target` (absolute steps). Waits for planner
    /// space while serving realtime requests.
    // speed: keeps the per-move path lean (this file's attributes removed: ping-pong stream 5.756 -> 5.807 s)
    #[inline(never)]
    pub fn queue_line(&mut self, io: &mut impl Io, target: &[i32; N_AXES], speed: Speed) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        // Drivers switch on with the first move (Marlin, grbl); M18/M84 turn
        // them off again.
        io.drivers(true);
        // A full planner refuses the move: wait for a slot before asking it
        // (each refusal costs ~500 cycles on the AVR, ~0.4 of them a line
        // in a stream). A move to where the planner already is queues
        // nothing and does not wait.
        while self.planner.is_full() && *target != self.planner.position() {
            self.wait_step(io)?;
        }
        loop {
            match self.planner.accept_line(target, speed, &self.settings) {
                Ok(p) => {
                    if p.rate_capped {
                        uwriteln!(io, "{}", F!("echo:warning: feed capped to the maximum step rate")).ok();
                    }
                    if self.state == State::Idle {
                        self.state = State::Run;
                    }
                    return Ok(());
                }
                Err(PlanError::Full) => self.wait_step(io)?,
                // More steps than a block holds: the move in pieces.
                Err(PlanError::TooLong) => {
                    let piece = self.planner.first_piece(target);
                    self.queue_line(io, &piece, speed)?;
                }
                Err(PlanError::BadFeed) => return Err(interp::Error::BadFeed),
            }
        }
    }

    /// Queue a straight move to `target` (internal machine mm, E in carousel
    /// units): the one entry point of every move in mm (the interpreter's
    /// moves, chords and cycle steps, the tool changer's and the tool
    /// setter's rapids, the carousel's turns, the menu's jog). The homing
    /// lock guards X/Y/Z (the carousel alone has its own homing, G205); the
    /// commanded position follows once the planner took the move.
    // speed: keeps the per-move path lean (this file's attributes removed: ping-pong stream 5.756 -> 5.807 s)
    #[inline(never)]
    pub fn move_mm(&mut self, io: &mut impl Io, target: &[f32; N_AXES], speed: Speed) -> CmdResult {
        self.may_move_to(target)?;
        let steps = self.interp.steps_of(&self.settings, target);
        self.queue_line(io, &steps, speed)?;
        crate::math::copy16(&mut self.interp.pos_mm, target);
        Ok(())
    }

    /// [`Machine::move_mm`] to the interpreter's [`Interp::target`](crate::gcode::interp::Interp::target)
    /// (`Command::Move`), without copying it out.
    // speed: keeps the per-move path lean (this file's attributes removed: ping-pong stream 5.756 -> 5.807 s)
    #[inline(never)]
    pub(super) fn move_interp(&mut self, io: &mut impl Io, feed_mm_per_min: f32, rapid: bool) -> CmdResult {
        self.may_move_to(self.interp.target())?;
        let steps = self.interp.target_steps(&self.settings);
        let speed = if rapid { Speed::Rapid } else { Speed::Feed(feed_mm_per_min) };
        self.queue_line(io, &steps, speed)?;
        self.interp.target_reached();
        Ok(())
    }

    /// Motion to `target` is allowed: no alarm, and the homing lock
    /// (`$22`) guards X/Y/Z (the carousel alone has its own homing, G205;
    /// an interrupted tool change is locked separately).
    // speed: keeps the per-move path lean (this file's attributes removed: ping-pong stream 5.756 -> 5.807 s)
    #[inline(always)]
    pub(super) fn may_move_to(&self, target: &[f32; N_AXES]) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        // The cheap test first: homed or unlocked, any target goes.
        if self.motion_allowed() {
            return Ok(());
        }
        let xyz_moves = (0..3).any(|a| !interp::same_f32(target[a], self.interp.pos_mm[a]));
        if xyz_moves {
            return Err(interp::Error::NotHomed);
        }
        Ok(())
    }

    /// The menu's jog: `axis` (0..3) by `delta_mm` (user frame: +Z up) at
    /// `feed` mm/min from the commanded position; soft limits apply, the
    /// modal state is untouched.
    pub fn jog(&mut self, io: &mut impl Io, axis: usize, delta_mm: f32, feed: f32) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        let mut target = self.interp.pos_mm;
        target[axis] += crate::frame::axis_internal_from_user(axis, delta_mm);
        self.interp.check_soft_limits(&self.settings, &target)?;
        let target = self.keep_out_clip(&target);
        self.move_mm(io, &target, Speed::Fixed(feed))
    }

    /// `$J=<words>`: a grbl 1.1 jog (see [`Interp::jog_target`](crate::gcode::interp::Interp::jog_target)), only
    /// from Idle or Jog; the soft limits refuse a target beyond the travel
    /// before anything moves. Queued like any move, so a stream of short
    /// jogs runs without stopping between them; 0x85 or `!` ends it.
    pub(super) fn jog_line(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        if !matches!(self.state, State::Idle | State::Jog) || self.holding {
            return Err(interp::Error::BadWord(F!("$J= only while idle or jogging")));
        }
        let mut line = crate::gcode::Line::default();
        crate::gcode::parse_into(after_eq(text), &mut line).map_err(interp::Error::Parse)?;
        let (target, feed) = self.interp.jog_target(&line)?;
        if !self.motion_allowed() {
            return Err(interp::Error::NotHomed);
        }
        self.interp.check_soft_limits(&self.settings, &target)?;
        let target = self.keep_out_clip(&target);
        self.move_mm(io, &target, Speed::Fixed(feed))?;
        self.state = State::Jog;
        Ok(())
    }

    /// A jog (`$J=`, the menu's) toward the tool magazine stops at the edge
    /// of its keep-out zone, a step's width short of it: the target moved
    /// back along the jog. One that starts at the edge going in moves nothing.
    pub(super) fn keep_out_clip(&self, target: &[f32; N_AXES]) -> [f32; N_AXES] {
        let a = self.interp.pos_mm;
        let xyz = |p: &[f32; N_AXES]| [p[0], p[1], p[2]];
        let Some(t) = self.settings.station.keep_out_entry(xyz(&a), xyz(target)) else {
            return *target;
        };
        let d: [f32; 3] = core::array::from_fn(|i| target[i] - a[i]);
        let len = crate::math::sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        // 0.02 mm: two steps at the default 100 steps/mm, so the step grid
        // does not round the end point into the zone.
        let t = if len > 0.0 { t - 0.02 / len } else { 0.0 };
        let t = if t > 0.0 { t } else { 0.0 };
        let mut c = a;
        for i in 0..3 {
            c[i] = a[i] + d[i] * t;
        }
        c
    }

    /// The SD card was pulled mid-job and the job's moves are dropped: lift
    /// Z to `$160` below its home switch at [`RETRACT_FEED_MM_PER_MIN`]
    /// (only up: a tool above that height stays), wait for it, then the
    /// spindle and coolant off. Without a known Z (not homed) nothing moves.
    pub fn retract_and_stop_spindle(&mut self, io: &mut impl Io) -> CmdResult {
        // The job's abort is over: this move's wait must not fail on it.
        self.line_aborts = self.aborts;
        let r = self.retract_z(io);
        self.spindle_off(io);
        r
    }

    pub(super) fn retract_z(&mut self, io: &mut impl Io) -> CmdResult {
        if self.alarm.is_some() || self.homed & 0b100 == 0 {
            return Ok(());
        }
        let mut target = self.interp.pos_mm;
        // Internal frame: Z counts down from the switch.
        let safe = self.settings.card_out_retract_mm;
        if target[2] > safe {
            target[2] = safe;
            self.move_mm(io, &target, Speed::Fixed(RETRACT_FEED_MM_PER_MIN))?;
            self.wait_idle(io)?;
        }
        Ok(())
    }

    /// G38.2/G38.3: move toward `target` until the tool-setter input trips.
    pub(super) fn probe(&mut self, io: &mut impl Io, target: [f32; N_AXES], speed: Speed, must_trip: bool) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        if !self.motion_allowed() {
            return Err(interp::Error::NotHomed);
        }
        self.wait_idle(io)?;
        if io.switches().tool_setter {
            return Err(interp::Error::ProbeAlreadyTriggered);
        }
        let prev = self.state;
        self.state = State::Probe;
        self.apply_watch(io, 0, true);
        let steps = self.interp.steps_of(&self.settings, &target);
        let r = self.queue_line(io, &steps, speed).and_then(|_| self.wait_motion_or_trip(io));
        self.apply_watch(io, 0, false);
        self.state = prev;
        let tripped = r?;
        let pos = if tripped { io.stepper().trip_position } else { io.stepper().position };
        self.resync_after_stop(io);
        let mm = self.steps_to_mm(pos);
        uwrite!(io, "{}", F!("[PRB:")).ok();
        self.write_xyz(io, self.interp.work_user(mm));
        uwriteln!(io, ":{}]", if tripped { 1u8 } else { 0u8 }).ok();
        if !tripped && must_trip {
            // grbl's ALARM:5: the lines after a probe (G92, G10 L20) must
            // not set a zero where nothing was touched. G38.3 may miss.
            self.raise(io, Alarm::ProbeFailed);
            return Err(interp::Error::ProbeFailed);
        }
        Ok(())
    }

    /// The menu's Z probe: G38.2 straight down by `mm` (at most to the end
    /// of the Z travel) from where the machine is, at `feed` (the probe input; a miss raises the probe-fail
    /// alarm, as G38.2 does). Refused until homed.
    pub fn probe_z_down(&mut self, io: &mut impl Io, mm: f32, feed: f32) -> CmdResult {
        if !self.motion_allowed() {
            return Err(interp::Error::NotHomed);
        }
        // The internal frame counts Z down from the home switch: down by
        // `mm`, no deeper than the Z travel.
        let mut target = self.interp.pos_mm;
        let depth = target[2] + mm;
        let travel = self.settings.travel_mm[2];
        target[2] = if depth < travel { depth } else { travel };
        self.probe(io, target, Speed::Fixed(feed), true)
    }

    /// One turn of every wait loop: top up segments, serve realtime.
    /// Fails when an alarm stops the machine meanwhile.
    pub fn wait_step(&mut self, io: &mut impl Io) -> CmdResult {
        self.keepalive(io);
        self.idle(io);
        if self.alarm.is_some() {
            Err(interp::Error::Alarm)
        } else if self.aborts != self.line_aborts {
            Err(interp::Error::Aborted)
        } else {
            Ok(())
        }
    }

    /// True when nothing is planned, prepared or stepping.
    pub fn motion_done(&self, io: &impl Stepper) -> bool {
        self.planner.is_empty() && !self.prep.is_busy() && !io.stepper_busy()
    }

    /// Wait until every queued move has been stepped out.
    pub fn wait_idle(&mut self, io: &mut impl Io) -> CmdResult {
        loop {
            self.wait_step(io)?;
            if self.motion_done(io) {
                return Ok(());
            }
        }
    }

    /// Wait until the queued motion ends or the ISR latched a trip
    /// (homing switch or probe). Returns true if it tripped.
    pub fn wait_motion_or_trip(&mut self, io: &mut impl Io) -> Result<bool, interp::Error> {
        loop {
            self.keepalive(io);
            self.wait_step(io)?;
            if self.tripped {
                return Ok(true);
            }
            if self.motion_done(io) {
                // The trip may have stopped the ISR after this loop's poll:
                // ask the stepper itself, or a trip in the last queued
                // segments reads as "never tripped".
                return Ok(io.stepper().tripped);
            }
        }
    }

    /// After the ISR stopped on a trip (or a finished move): drop whatever is
    /// left of the queue and take the stepper's position as the truth.
    pub fn resync_after_stop(&mut self, io: &mut impl Stepper) {
        io.stop_motion();
        self.planner.clear();
        self.prep.reset();
        io.clear_stop();
        self.tripped = false;
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
    }

    /// While a serial line waits (M400, G4, G28, M0, a tool change, G37, a
    /// full planner ...): `busy:processing` every M113 interval (2 s by
    /// default, Marlin's), counted from the start of the line, so that no
    /// host times out (docs/SPEC.md §4). Every wait loop calls it through
    /// [`Machine::wait_step`]. Not for SD-job or menu lines: no host waits
    /// for those.
    pub fn keepalive(&mut self, io: &mut (impl Inputs + ufmt::uWrite)) {
        // (`mul_u16`: a `u32` product is a `__mulsi3` call on the AVR, on
        // every wait's turn.)
        let every = crate::math::mul_u16(self.host.busy_interval_s as u16, 1000);
        if !self.in_serial_line() || every == 0 {
            return;
        }
        let now = io.millis();
        if now.wrapping_sub(self.last_busy_ms) >= every {
            self.last_busy_ms = now;
            uwriteln!(io, "{}", F!("busy:processing")).ok();
        }
    }

    /// Top up the segment ring from the planner. Not while the ISR is
    /// stopped: it drops what it is given, so the whole queue would be
    /// prepared into it before the stop is served (an M112 sent behind a
    /// full queue was reported 0.75 s late).
    pub fn fill_segments(&mut self, io: &mut impl Stepper) {
        // A move the planner accepted without planning it yet (so that `ok`
        // went out sooner) is planned now, before prep looks at the ring.
        self.planner.flush(&self.settings);
        // At most one ring's worth per call, and none while the ISR is
        // stopped (after an emergency stop it throws segments away as fast
        // as they come: the whole planner queue was prepped before the next
        // poll, 0.7 s before the alarm was even reported). The space is asked
        // again after each segment (the push answers it): the board caps the
        // queued motion time, not only the slots.
        let mut room = io.segment_space();
        let mut space = room;
        while room > 0 && space > 0 && !io.stepper_stopped() {
            room -= 1;
            match self.prep.next_segment(&mut self.planner) {
                Some(cmd) => space = io.push_fitting(cmd),
                None => break,
            }
        }
    }
}
