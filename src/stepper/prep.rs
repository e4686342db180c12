//! Segment preparation (grbl's `st_prep_buffer`), run from the main loop.
//!
//! Where it sits: between the planner's executing block and the ISR's segment
//! queue. [`Prep::next_segment`] returns the next [`StepperCmd`]: a
//! [`StepperCmd::Block`] when a planner block starts, then
//! [`StepperCmd::Run`] segments of about [`SEGMENT_TIME_S`] each that follow the
//! block's trapezoid (accelerate, cruise, decelerate to the exit speed the
//! planner gives). The main loop calls it while the queue has room.
//!
//! - **Segment length.** [`SEGMENT_TIME_S`] (5 ms) on ramps,
//!   [`CRUISE_SEGMENT_TIME_S`] (20 ms) at cruise; a segment never spans two
//!   planner blocks, so a stream of short moves gives one segment per block.
//! - **Exact steps.** The remaining step count is an integer; each segment takes
//!   `ticks = steps_remaining − ⌈remaining_mm · steps/mm⌉`, so a block's ticks add
//!   up to its `step_event_count` exactly.
//! - **Step timing.** A segment's ticks are evenly spaced from the previous
//!   segment's last tick to the instant the profile reaches this segment's last
//!   whole step (the leftover fraction of a step is timed at the segment's end
//!   speed and carried into the next one). Every step then comes within one
//!   step of the ideal trapezoid, and the rate of consecutive segments changes by
//!   the planned acceleration (grbl times the fraction at the segment's mean
//!   speed, which puts ramp ticks early or late by up to a step).
//! - **Minimum speed.** A segment is stretched in `SEGMENT_TIME_S` steps until
//!   it covers at least 1.25 steps (grbl's REQ_MM_INCREMENT_SCALAR), so a ramp
//!   from zero speed gives a first period of one segment or so, never an
//!   absurdly long one. The timer's slowest rate is clk/8 with OCR1A = 65535
//!   ([`crate::config::MIN_STEP_RATE_HZ`], 30.5 Hz); slower segments (only possible at
//!   the very start or end of a ramp with tiny accelerations) are clamped to it:
//!   their steps still come out, a little early.
//! - **Fastest rate.** Periods never go below [`MIN_PERIOD_CYCLES`].
//! - **Feed hold** ([`Prep::hold`]): from the current speed, decelerate at the
//!   block's acceleration, across block boundaries if needed, and stop with
//!   every step counted (the executing block keeps the distance left in
//!   `millimeters`). [`Prep::is_held`] turns true when the last segment of the
//!   stop is queued; the firmware then waits for the ISR to drain it. After
//!   [`Prep::resume`] the same block restarts from zero speed on the same path;
//!   prep re-plans the ring itself on its next call.
//! - **Abort** ([`Prep::reset`]): forget the block in progress (e-stop, limit).
//!
//! The ISR's rings ([`super::rings`]) take one chunk per `Block` and one
//! segment per `Run` (two when a run crosses a chunk cut). With 0.1 mm moves
//! at 50 mm/s a block lasts 2 ms, so the 16-slot rings cover only ~16 ms of
//! motion: the main loop must call [`Prep::next_segment`] at least that often
//! (or the rings must be longer) or the ISR starves.
//!
//! The planner's executing block is shared: after every segment prep writes its
//! remaining distance and current speed² back into it, and it recomputes its
//! profile when [`Planner::take_exec_replanned`] says a new block changed the
//! exit speed (grbl's `st_update_plan_block_parameters`).
//!
//! The files: the block-to-segment driver and the state here; the profile
//! in `profile`, the one-segment fast paths in `fast`, the segment loop in
//! `segment`, time to timer settings in `timer`.

mod fast;
mod profile;
mod segment;
mod timer;

use super::{StBlock, StepperCmd};
use crate::config::MIN_STEP_RATE_HZ;
use crate::math::sqrt_1ulp;
use crate::planner::Planner;
use crate::F_CPU;

pub use super::MIN_PERIOD_CYCLES;

/// Duration of a segment on a ramp, s. grbl uses 1/100 s; half that keeps every
/// step within one step of the ideal trapezoid (a constant-rate segment of time
/// T on a ramp of acceleration a deviates from the parabola by up to a·T²/8:
/// 0.03 mm at 10 ms, 0.003 mm at 5 ms, both at 1000 mm/s²), and the speed
/// changes by at most a·T between segments (5 mm/s at 1000 mm/s²).
pub const SEGMENT_TIME_S: f32 = 0.005;

/// Duration of a segment that starts at cruise speed, s. Constant speed needs
/// no short segments; longer ones halve prep's CPU time on long moves (it
/// matters at high step rates, where the ISR takes most of the CPU). A segment
/// ends where the cruise ends, so deceleration gets `SEGMENT_TIME_S` segments.
pub const CRUISE_SEGMENT_TIME_S: f32 = 0.02;

/// A segment covers at least this many steps (stretched in time if needed).
const REQ_STEPS_PER_SEGMENT: f32 = 1.25;
/// A deceleration ends early when less than this many steps would be left
/// after a full piece.
const RAMP_END_EPSILON: f32 = 1e-3;

const _: () = assert!(MIN_STEP_RATE_HZ > 0.0);

/// Which part of the trapezoid the next segment starts in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ramp {
    Accel,
    Cruise,
    Decel,
    /// Entry above nominal (after a hold crossed into a slower block):
    /// decelerate to nominal, then cruise.
    DecelOverride,
}

/// Segment-prep state (grbl's `st_prep_t`).
#[derive(Clone, Copy, Debug)]
pub struct Prep {
    /// A planner block is being cut into segments (its StBlock was sent).
    active: bool,
    /// The StBlock of the active block is still to be sent.
    block_pending: bool,
    /// The profile must be (re)computed before the next segment.
    profile_stale: bool,
    /// The ring must be re-planned from the executing block (after resume).
    replan_pending: bool,
    /// The next block starts at `exit_speed`, not its planned entry speed.
    decel_override: bool,
    /// Feed hold requested: decelerate to a stop.
    holding: bool,
    /// The hold's last segment is queued: produce nothing until resume.
    held: bool,
    ramp: Ramp,
    /// Steps of the active block not yet put in a segment.
    steps_remaining: u32,
    /// Step events of the active block ([`crate::planner::Block::step_event_count`],
    /// read once: derived at each of its four uses instead, `profile
    /// --trace 300:1500` read 20 062 cycles a line against 20 011, for 4 B).
    block_events: u32,
    /// Steps (of the dominant axis) per mm of path.
    step_per_mm: f32,
    /// Time of the step fraction carried into the next segment, s.
    dt_remainder: f32,
    /// Acceleration of the active block, mm/s²: F_CPU / `dv_cycles`,
    /// divided on first use ([`Prep::accel`]; 0: not yet), which only the
    /// profile and the segment loop make, not the one-segment fast paths.
    acceleration: f32,
    /// F_CPU / the acceleration of the active block: CPU cycles per mm/s
    /// of speed change ([`crate::planner::Block::dv_cycles`]).
    dv_cycles: f32,
    /// Speed at the end of the last segment, mm/s.
    current_speed: f32,
    /// Speed the profile ends at, mm/s.
    exit_speed: f32,
    /// Peak speed of the profile, mm/s.
    maximum_speed: f32,
    /// Remaining distance where acceleration ends, mm.
    accelerate_until: f32,
    /// Remaining distance where deceleration starts, mm.
    decelerate_after: f32,
    /// Remaining distance where the profile ends (> 0 only for a hold stop), mm.
    mm_complete: f32,
    /// Bits of the exit speed² `exit_speed` was computed from (u32::MAX: none).
    /// The next block's entry speed² is usually the same value: no sqrt then.
    exit_speed_sqr_bits: u32,
    /// (bits of a nominal speed², its square root): consecutive blocks at the
    /// same feed share it (saves a 500-cycle sqrt per block on the AVR).
    nominal_cache: (u32, f32),
    /// For the nominal speed v of `nominal_cache`: (CPU cycles per mm at v,
    /// the longest block that fits one cruise segment at v, mm).
    cruise_cache: (f32, f32),
    /// `step_per_mm` is valid for the active block (computed on first use:
    /// the cruise fast path does not need it).
    step_per_mm_valid: bool,
}

impl Prep {
    /// Idle prep.
    pub const fn new() -> Self {
        Prep {
            active: false,
            block_pending: false,
            profile_stale: false,
            replan_pending: false,
            decel_override: false,
            holding: false,
            held: false,
            ramp: Ramp::Accel,
            steps_remaining: 0,
            block_events: 0,
            step_per_mm: 0.0,
            dt_remainder: 0.0,
            acceleration: 0.0,
            dv_cycles: 0.0,
            current_speed: 0.0,
            exit_speed: 0.0,
            maximum_speed: 0.0,
            accelerate_until: 0.0,
            decelerate_after: 0.0,
            mm_complete: 0.0,
            exit_speed_sqr_bits: 0,
            nominal_cache: (0, 0.0),
            cruise_cache: (0.0, 0.0),
            step_per_mm_valid: false,
        }
    }

    /// Feed hold: decelerate to a stop within the acceleration limit.
    pub fn hold(&mut self) {
        if !self.holding {
            self.holding = true;
            self.profile_stale = true;
        }
    }

    /// A hold was requested and not yet resumed.
    pub fn is_holding(&self) -> bool {
        self.holding
    }

    /// The hold's stop is fully prepared: nothing more comes until `resume`.
    /// The machine has stopped once the ISR has also drained its queue.
    pub fn is_held(&self) -> bool {
        self.held
    }

    /// Same as [`Prep::is_held`].
    pub fn held(&self) -> bool {
        self.held
    }

    /// A planner block is partly prepared (its end not yet queued).
    pub fn is_busy(&self) -> bool {
        self.active
    }

    /// Current speed at the end of the last prepared segment, mm/s.
    pub fn current_speed(&self) -> f32 {
        self.current_speed
    }

    /// Leave a feed hold. After the stop (`is_held`) the executing block
    /// restarts from zero speed with its remaining distance; if the stop was not
    /// complete yet, motion re-accelerates from the current speed. The ring is
    /// re-planned on the next [`Prep::next_segment`] call (calling
    /// [`Planner::cycle_reinitialize`] before this is allowed, not required).
    pub fn resume(&mut self) {
        if !self.holding {
            return;
        }
        if self.held {
            self.current_speed = 0.0;
            self.exit_speed = 0.0;
            self.exit_speed_sqr_bits = u32::MAX;
            // The machine stood still: the next tick is timed from now.
            self.dt_remainder = 0.0;
        }
        self.holding = false;
        self.held = false;
        self.decel_override = false;
        self.profile_stale = true;
        self.replan_pending = true;
    }

    /// Forget everything in progress (e-stop, limit, probe trip). The caller
    /// also clears the planner and re-syncs its position.
    pub fn reset(&mut self) {
        *self = Prep::new();
    }

    /// Fill a segment queue: call [`Prep::next_segment`] while `q` has room.
    pub fn fill<const N: usize>(&mut self, pl: &mut Planner, q: &mut heapless::spsc::Producer<'_, StepperCmd, N>) {
        while q.ready() {
            match self.next_segment(pl) {
                Some(c) => {
                    // Cannot fail: ready() was true and we are the only producer.
                    let _ = q.enqueue(c);
                }
                None => break,
            }
        }
    }

    /// The next command for the ISR, or `None` when there is nothing to do (no
    /// block, or a hold has stopped).
    pub fn next_segment(&mut self, pl: &mut Planner) -> Option<StepperCmd> {
        loop {
            if self.held {
                return None;
            }
            // The executing block's exit speed must be final before it is used.
            pl.settle();
            if self.replan_pending {
                self.replan_pending = false;
                if self.active {
                    if let Some(b) = pl.current_block_mut() {
                        b.entry_speed_sqr = self.current_speed * self.current_speed;
                    }
                }
                pl.replan();
            }
            if !self.active {
                let Some(b) = pl.current_block_mut() else {
                    if self.holding {
                        // Nothing left to stop: the hold is complete.
                        self.held = true;
                    }
                    return None;
                };
                self.block_events = b.step_event_count();
                self.steps_remaining = self.block_events;
                self.step_per_mm_valid = false;
                self.dt_remainder = 0.0;
                self.dv_cycles = b.dv_cycles;
                self.acceleration = 0.0;
                if self.holding || self.decel_override {
                    // Enter the block at the speed the previous one left us at.
                    self.current_speed = self.exit_speed;
                    b.entry_speed_sqr = self.exit_speed * self.exit_speed;
                    self.decel_override = false;
                } else if b.entry_speed_sqr.to_bits() == self.exit_speed_sqr_bits {
                    // The planned entry is the exit we just reached.
                    self.current_speed = self.exit_speed;
                } else {
                    self.current_speed = sqrt_1ulp(b.entry_speed_sqr);
                }
                self.active = true;
                self.block_pending = true;
                self.profile_stale = true;
                pl.take_exec_replanned();
            }
            if self.block_pending {
                self.block_pending = false;
                let b = pl.current_block()?;
                return Some(StepperCmd::Block(StBlock {
                    steps: b.steps(),
                    step_event_count: self.block_events,
                    direction_bits: b.direction_bits(),
                    take_up: b.has(crate::planner::Block::TAKE_UP),
                }));
            }
            if pl.take_exec_replanned() {
                self.profile_stale = true;
            }
            if let Some(seg) = self.cruise_block(pl) {
                return Some(StepperCmd::Run(seg));
            }
            if self.profile_stale {
                if let Some(seg) = self.ramp_block(pl) {
                    return Some(StepperCmd::Run(seg));
                }
                self.profile_stale = false;
                self.compute_profile(pl);
            }
            if let Some(seg) = self.short_block(pl) {
                return Some(StepperCmd::Run(seg));
            }
            if !self.step_per_mm_valid {
                let b = pl.current_block()?;
                self.step_per_mm = self.block_events as f32 / b.millimeters;
                self.step_per_mm_valid = true;
            }
            if let Some(seg) = self.make_segment(pl) {
                return Some(StepperCmd::Run(seg));
            }
            // No segment: either the hold stopped (held), or a zero-step piece
            // was absorbed; loop to continue with the next block.
        }
    }

    /// The active block's acceleration, mm/s² (see `acceleration`).
    pub(super) fn accel(&mut self) -> f32 {
        if self.acceleration.to_bits() == 0 {
            self.acceleration = crate::math::div_cold(F_CPU, self.dv_cycles);
        }
        self.acceleration
    }

    /// Record progress in the executing block: distance left, current speed².
    /// Stored values stay ≥ +0.0 (the planner compares them as bit patterns).
    fn write_back(&self, b: &mut crate::planner::Block, mm_remaining: f32) {
        let mm = if mm_remaining > 0.0 { mm_remaining } else { 0.0 };
        b.millimeters = mm;
        b.entry_speed_sqr = self.current_speed * self.current_speed;
        b.max_delta_speed_sqr = 2.0 * self.acceleration * mm;
    }

    /// The executing block is fully prepared: drop it from the planner.
    fn finish_block(&mut self, pl: &mut Planner) {
        self.finish_block_at(pl, None);
    }

    /// [`Prep::finish_block`], with the exit speed² read from the planner
    /// in this call, if any ([`Planner::discard_current_block_at`]).
    fn finish_block_at(&mut self, pl: &mut Planner, exit_sqr: Option<f32>) {
        self.active = false;
        pl.discard_current_block_at(exit_sqr);
    }
}

impl Default for Prep {
    fn default() -> Self {
        Self::new()
    }
}
