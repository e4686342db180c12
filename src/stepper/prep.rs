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

use super::{Prescale, Segment, StBlock, StepperCmd};
use crate::config::{Settings, MIN_STEP_RATE_HZ};
use crate::math::sqrtf;
use crate::planner::Planner;
use crate::F_CPU_HZ;

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

const F_CPU: f32 = F_CPU_HZ as f32;

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
    /// Steps (of the dominant axis) per mm of path.
    step_per_mm: f32,
    /// Time of the step fraction carried into the next segment, s.
    dt_remainder: f32,
    /// Acceleration of the active block, mm/s².
    acceleration: f32,
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
    /// (bits of an acceleration a, 0.5 / a).
    inv_2_accel_cache: (u32, f32),
}

/// |x| by clearing the sign bit (no soft-float compare).
#[inline(always)]
fn abs_f32(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & 0x7FFF_FFFF)
}

/// ⌈x⌉ for 0 ≤ x < 2³².
#[inline]
fn ceil_u32(x: f32) -> u32 {
    if x <= 0.0 {
        return 0;
    }
    let t = x as u32;
    if (t as f32) < x {
        t + 1
    } else {
        t
    }
}

in_flash! {
    /// 1/n for n = 1..=12 (entry 0 unused), in flash on the AVR (a RAM table
    /// would take 52 bytes of the 8 KiB; a `match` of constants took 270 bytes
    /// of flash).
    static RECIPROCALS: [f32; 13] = {
        let mut t = [0.0f32; 13];
        let mut i = 1;
        while i < 13 {
            t[i] = 1.0 / i as f32;
            i += 1;
        }
        t
    };
}

/// `cycles / n`: the CPU cycles per step event of a segment of `n` ticks.
/// A 0.1 mm block makes at most ~10 ticks (100 steps/mm), so for n ≤ 12
/// this multiplies by 1/n (~140 cycles on the AVR instead of a ~540-cycle
/// division; within an ulp of it, far below the timer count the period is
/// rounded to).
#[inline(never)]
fn per_tick(cycles: f32, n: u32) -> f32 {
    match RECIPROCALS.row(n as usize) {
        Some(r) if n != 0 => cycles * r,
        _ => crate::math::div_cold(cycles, n as f32),
    }
}

/// Timer setting for `cycles` CPU cycles per step event. Rounds up (by up to
/// one timer count), so a segment is never faster than planned.
fn timer_for(cycles: f32) -> (u16, Prescale) {
    // Huge, negative or NaN values end at the slowest setting. The range test
    // is on the bit pattern: a saturating `as` costs three soft-float compares.
    let b = cycles.to_bits();
    let c = if b < 0x4B00_0000 {
        // SAFETY: 0 ≤ cycles < 2²³ (positive, exponent below 23): in range.
        (unsafe { cycles.to_int_unchecked::<u32>() }) + 1
    } else {
        u32::MAX // ≥ 2²³ cycles, negative or NaN: the slowest setting
    };
    if c <= 65535 {
        let p = c as u16;
        (if p < MIN_PERIOD_CYCLES { MIN_PERIOD_CYCLES } else { p }, Prescale::Div1)
    } else if c <= 8 * 65535 {
        (((c + 7) >> 3) as u16, Prescale::Div8)
    } else {
        (65535, Prescale::Div8)
    }
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
            step_per_mm: 0.0,
            dt_remainder: 0.0,
            acceleration: 0.0,
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
            inv_2_accel_cache: (u32::MAX, 0.0),
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
    pub fn fill<const N: usize>(&mut self, pl: &mut Planner, s: &Settings, q: &mut heapless::spsc::Producer<'_, StepperCmd, N>) {
        while q.ready() {
            match self.next_segment(pl, s) {
                Some(c) => {
                    // Cannot fail: ready() was true and we are the only producer.
                    let _ = q.enqueue(c);
                }
                None => break,
            }
        }
    }

    /// The next command for the ISR, or `None` when there is nothing to do (no
    /// block, or a hold has stopped). `_s` is unused today (kept so callers need
    /// not change if prep ever needs a setting).
    pub fn next_segment(&mut self, pl: &mut Planner, _s: &Settings) -> Option<StepperCmd> {
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
                self.steps_remaining = b.step_event_count;
                self.step_per_mm_valid = false;
                self.dt_remainder = 0.0;
                self.acceleration = b.acceleration;
                if self.holding || self.decel_override {
                    // Enter the block at the speed the previous one left us at.
                    self.current_speed = self.exit_speed;
                    b.entry_speed_sqr = self.exit_speed * self.exit_speed;
                    self.decel_override = false;
                } else if b.entry_speed_sqr.to_bits() == self.exit_speed_sqr_bits {
                    // The planned entry is the exit we just reached.
                    self.current_speed = self.exit_speed;
                } else {
                    self.current_speed = sqrtf(b.entry_speed_sqr);
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
                    steps: b.steps,
                    step_event_count: b.step_event_count,
                    direction_bits: b.direction_bits,
                    take_up: b.flags & crate::planner::Block::TAKE_UP != 0,
                }));
            }
            if pl.take_exec_replanned() {
                self.profile_stale = true;
            }
            if let Some(seg) = self.cruise_block(pl) {
                return Some(StepperCmd::Run(seg));
            }
            if self.profile_stale {
                self.profile_stale = false;
                self.compute_profile(pl);
            }
            if let Some(seg) = self.short_block(pl) {
                return Some(StepperCmd::Run(seg));
            }
            if !self.step_per_mm_valid {
                let b = pl.current_block()?;
                self.step_per_mm = b.step_event_count as f32 / b.millimeters;
                self.step_per_mm_valid = true;
            }
            if let Some(seg) = self.make_segment(pl) {
                return Some(StepperCmd::Run(seg));
            }
            // No segment: either the hold stopped (held), or a zero-step piece
            // was absorbed; loop to continue with the next block.
        }
    }

    /// The square root of a nominal speed², cached with the cruise figures.
    fn nominal_speed(&mut self, nominal_sqr: f32) -> f32 {
        if self.nominal_cache.0 != nominal_sqr.to_bits() {
            let v = sqrtf(nominal_sqr);
            self.nominal_cache = (nominal_sqr.to_bits(), v);
            let cycles_per_mm = if v > 0.0 { crate::math::div_cold(F_CPU, v) } else { 0.0 };
            self.cruise_cache = (cycles_per_mm, CRUISE_SEGMENT_TIME_S * v);
        }
        self.nominal_cache.1
    }

    /// Fast path for a block that runs entirely at its nominal speed (entry,
    /// exit and nominal speed² equal, the usual case inside a stream of short
    /// moves) and is short enough for one cruise segment: the whole block as
    /// one segment with one division, instead of the profile and the segment
    /// loop (~1 k instead of ~8 k cycles on the AVR). It produces the segment
    /// the general path would (same ticks, period within a timer count).
    fn cruise_block(&mut self, pl: &mut Planner) -> Option<Segment> {
        if !self.profile_stale || self.holding || self.decel_override {
            return None;
        }
        let exit_sqr = pl.exec_exit_speed_sqr().to_bits();
        let b = pl.current_block()?;
        let nominal_bits = b.nominal_speed_sqr.to_bits();
        if b.entry_speed_sqr.to_bits() != nominal_bits || exit_sqr != nominal_bits || nominal_bits == 0 {
            return None;
        }
        let (mm, n, nominal_sqr) = (b.millimeters, b.step_event_count, b.nominal_speed_sqr);
        let v = self.nominal_speed(nominal_sqr);
        let (cycles_per_mm, max_mm) = self.cruise_cache;
        if !(mm <= max_mm) || n == 0 || n != self.steps_remaining || n > u16::MAX as u32 {
            return None;
        }
        let (period, prescale) = timer_for(per_tick(mm * cycles_per_mm + self.dt_remainder * F_CPU, n));
        self.profile_stale = false;
        self.current_speed = v;
        self.exit_speed = v;
        self.exit_speed_sqr_bits = nominal_bits;
        self.dt_remainder = 0.0;
        self.steps_remaining = 0;
        self.ramp = Ramp::Cruise;
        if let Some(b) = pl.current_block_mut() {
            b.millimeters = 0.0;
            b.entry_speed_sqr = nominal_sqr;
            b.max_delta_speed_sqr = 0.0;
        }
        self.finish_block(pl);
        Some(Segment { ticks: n as u16, period, prescale })
    }

    /// Fast path for the rest of a block that takes at most one ramp segment
    /// ([`SEGMENT_TIME_S`]) in all: one segment for all of it, its duration
    /// from the profile in closed form (Δv / a on the ramps, distance × the
    /// cached cycles per mm at cruise), one division. A stream of short moves
    /// is made of such blocks; the segment loop costs ~3× more on the AVR. The
    /// ticks are evenly spaced over the block like in any one segment: at most
    /// a·T²/8 (0.3 step at 1000 mm/s², 100 steps/mm) from the ideal trapezoid.
    fn short_block(&mut self, pl: &mut Planner) -> Option<Segment> {
        if self.holding || self.ramp == Ramp::DecelOverride {
            return None;
        }
        let inv_a = 2.0 * self.inv_2_accel_cache.1; // s² / mm
        let b = pl.current_block()?;
        let mm = b.millimeters;
        let v0 = self.current_speed;
        let (vmax, v1) = (self.maximum_speed, self.exit_speed);
        let mut t; // s
        let cruise_mm; // distance at vmax
        match self.ramp {
            Ramp::Accel => {
                t = (vmax - v0) * inv_a + (vmax - v1) * inv_a;
                cruise_mm = self.accelerate_until - self.decelerate_after;
            }
            Ramp::Cruise => {
                t = (vmax - v1) * inv_a;
                cruise_mm = mm - self.decelerate_after;
            }
            Ramp::Decel => {
                t = (v0 - v1) * inv_a;
                cruise_mm = 0.0;
            }
            Ramp::DecelOverride => return None,
        }
        if cruise_mm > 0.0 {
            if self.nominal_cache.1.to_bits() != vmax.to_bits() {
                return None;
            }
            t += cruise_mm * self.cruise_cache.0 * (1.0 / F_CPU);
        }
        let n = self.steps_remaining;
        if !(t <= SEGMENT_TIME_S) || !(t > 0.0) || n == 0 || n > u16::MAX as u32 {
            return None;
        }
        let (period, prescale) = timer_for(per_tick((t + self.dt_remainder) * F_CPU, n));
        self.current_speed = v1;
        self.dt_remainder = 0.0;
        self.steps_remaining = 0;
        if let Some(b) = pl.current_block_mut() {
            self.write_back(b, 0.0);
        }
        self.finish_block(pl);
        Some(Segment { ticks: n as u16, period, prescale })
    }

    /// The velocity profile of the rest of the executing block (grbl).
    fn compute_profile(&mut self, pl: &mut Planner) {
        let exit_speed_sqr = pl.exec_exit_speed_sqr();
        let Some(b) = pl.current_block_mut() else { return };
        // The executing block starts "now", at the current speed.
        b.entry_speed_sqr = self.current_speed * self.current_speed;
        let entry_sqr = b.entry_speed_sqr;
        let mm = b.millimeters;
        let a = self.acceleration;
        if self.inv_2_accel_cache.0 != a.to_bits() {
            self.inv_2_accel_cache = (a.to_bits(), crate::math::div_cold(0.5, a));
        }
        let inv_2_accel = self.inv_2_accel_cache.1;
        self.mm_complete = 0.0;
        self.decelerate_after = 0.0;
        // Any exit speed set below other than sqrt(planned exit²) clears this.
        self.exit_speed_sqr_bits = u32::MAX;
        if self.holding {
            // Forced deceleration to zero speed.
            self.ramp = Ramp::Decel;
            let decel_dist = mm - inv_2_accel * entry_sqr;
            if decel_dist < 0.0 {
                // The stop is beyond this block.
                self.exit_speed = sqrtf(entry_sqr - 2.0 * a * mm);
            } else {
                self.mm_complete = decel_dist;
                self.exit_speed = 0.0;
            }
            return;
        }
        self.ramp = Ramp::Accel;
        self.accelerate_until = mm;
        let nominal_sqr = b.nominal_speed_sqr;
        let nominal = self.nominal_speed(nominal_sqr);
        self.exit_speed = if exit_speed_sqr.to_bits() == nominal_sqr.to_bits() {
            nominal
        } else if exit_speed_sqr.to_bits() == 0 {
            0.0
        } else {
            sqrtf(exit_speed_sqr)
        };
        self.exit_speed_sqr_bits = exit_speed_sqr.to_bits();
        let intersect = 0.5 * (mm + inv_2_accel * (entry_sqr - exit_speed_sqr));
        if entry_sqr > nominal_sqr {
            self.accelerate_until = mm - inv_2_accel * (entry_sqr - nominal_sqr);
            if self.accelerate_until <= 0.0 {
                // Deceleration only; the next block starts at our exit speed.
                self.ramp = Ramp::Decel;
                let v2 = entry_sqr - 2.0 * a * mm;
                self.exit_speed = if v2 > 0.0 { sqrtf(v2) } else { 0.0 };
                self.exit_speed_sqr_bits = u32::MAX;
                self.decel_override = true;
            } else {
                self.decelerate_after = inv_2_accel * (nominal_sqr - exit_speed_sqr);
                self.maximum_speed = nominal;
                self.ramp = Ramp::DecelOverride;
            }
        } else if intersect > 0.0 {
            if intersect < mm {
                // Trapezoid or triangle.
                self.decelerate_after = inv_2_accel * (nominal_sqr - exit_speed_sqr);
                if self.decelerate_after < intersect {
                    self.maximum_speed = nominal;
                    if entry_sqr == nominal_sqr {
                        self.ramp = Ramp::Cruise;
                    } else {
                        self.accelerate_until -= inv_2_accel * (nominal_sqr - entry_sqr);
                    }
                } else {
                    self.accelerate_until = intersect;
                    self.decelerate_after = intersect;
                    self.maximum_speed = sqrtf(2.0 * a * intersect + exit_speed_sqr);
                }
            } else {
                // Deceleration only.
                self.ramp = Ramp::Decel;
            }
        } else {
            // Acceleration only.
            self.accelerate_until = 0.0;
            self.maximum_speed = self.exit_speed;
        }
    }

    /// Cut the next segment off the executing block (grbl's segment loop).
    /// `None` when the hold has stopped or the piece had no step.
    fn make_segment(&mut self, pl: &mut Planner) -> Option<Segment> {
        let a = self.acceleration;
        let b = pl.current_block_mut()?;
        let mut dt_max = if self.ramp == Ramp::Cruise { CRUISE_SEGMENT_TIME_S } else { SEGMENT_TIME_S };
        let mut dt = 0.0f32;
        let mut time_var = dt_max;
        let mut mm_remaining = b.millimeters;
        let mm_segment_start = mm_remaining;
        loop {
            let mm_start = mm_remaining;
            match self.ramp {
                Ramp::DecelOverride => {
                    let speed_var = a * time_var;
                    let mm_var = time_var * (self.current_speed - 0.5 * speed_var);
                    mm_remaining -= mm_var;
                    if mm_remaining < self.accelerate_until || mm_var <= 0.0 {
                        mm_remaining = self.accelerate_until;
                        time_var = 2.0 * (mm_start - mm_remaining) / (self.current_speed + self.maximum_speed);
                        self.ramp = Ramp::Cruise;
                        self.current_speed = self.maximum_speed;
                    } else {
                        self.current_speed -= speed_var;
                    }
                }
                Ramp::Accel => {
                    let speed_var = a * time_var;
                    mm_remaining -= time_var * (self.current_speed + 0.5 * speed_var);
                    if mm_remaining < self.accelerate_until {
                        mm_remaining = self.accelerate_until;
                        time_var = 2.0 * (mm_start - mm_remaining) / (self.current_speed + self.maximum_speed);
                        self.ramp = if mm_remaining == self.decelerate_after { Ramp::Decel } else { Ramp::Cruise };
                        self.current_speed = self.maximum_speed;
                    } else {
                        self.current_speed += speed_var;
                    }
                }
                Ramp::Cruise => {
                    let mm_var = mm_remaining - self.maximum_speed * time_var;
                    if mm_var < self.decelerate_after {
                        time_var = (mm_remaining - self.decelerate_after) / self.maximum_speed;
                        mm_remaining = self.decelerate_after;
                        self.ramp = Ramp::Decel;
                        // End the segment here (or one ramp segment later if it
                        // has no step yet).
                        dt_max = dt + time_var;
                    } else {
                        mm_remaining = mm_var;
                    }
                }
                Ramp::Decel => {
                    let speed_var = a * time_var;
                    let mut in_ramp = false;
                    if self.current_speed > speed_var {
                        let mm_var = mm_remaining - time_var * (self.current_speed - 0.5 * speed_var);
                        // Float residue (a millionth of a step left at almost zero
                        // speed) would make the last piece take ages: end here.
                        if (mm_var - self.mm_complete) * self.step_per_mm > RAMP_END_EPSILON {
                            mm_remaining = mm_var;
                            self.current_speed -= speed_var;
                            in_ramp = true;
                        }
                    }
                    if !in_ramp {
                        // End of the block or of the hold's deceleration.
                        let v = self.current_speed + self.exit_speed;
                        time_var = if v > 0.0 { 2.0 * (mm_remaining - self.mm_complete) / v } else { 0.0 };
                        mm_remaining = self.mm_complete;
                        self.current_speed = self.exit_speed;
                    }
                }
            }
            dt += time_var;
            if dt < dt_max {
                time_var = dt_max - dt;
            } else if mm_remaining > 0.0 && (mm_segment_start - mm_remaining) * self.step_per_mm < REQ_STEPS_PER_SEGMENT {
                // Too slow for a step yet: stretch the segment.
                dt_max += SEGMENT_TIME_S;
                time_var = dt_max - dt;
            } else {
                break;
            }
            if mm_remaining <= self.mm_complete {
                break;
            }
        }

        let step_dist_remaining = self.step_per_mm * mm_remaining;
        let mut n_steps_remaining = ceil_u32(step_dist_remaining);
        if n_steps_remaining > self.steps_remaining {
            n_steps_remaining = self.steps_remaining;
        }
        if mm_remaining <= 0.0 {
            n_steps_remaining = 0;
        }
        let ticks = self.steps_remaining - n_steps_remaining;
        let profile_done = mm_remaining == self.mm_complete;

        if ticks == 0 {
            if self.holding {
                // Stopped less than a step before the hold point: the stop is
                // complete; keep the block as it was (grbl).
                self.held = true;
                return None;
            }
            // A piece with no whole step: carry its time, keep going.
            self.dt_remainder += dt;
            self.write_back(b, mm_remaining);
            if profile_done && mm_remaining <= 0.0 {
                self.finish_block(pl);
            }
            return None;
        }

        // The ticks run from the previous segment's last tick (dt_remainder
        // before this segment's start) to this segment's last tick, which comes
        // `tail` before its end: the time to cover the fraction of a step left.
        let window = dt + self.dt_remainder;
        let frac = n_steps_remaining as f32 - step_dist_remaining;
        let n = ticks as f32;
        let inv_rate; // s per step event
        if frac > 0.0 && mm_remaining > 0.0 {
            // tail = time to cover `frac` steps ending at speed v with
            // acceleration ±a: frac = v·t ∓ a·t²/2. To second order in a·frac/v²,
            // t = 2·frac·v / (2v² ± a·frac) = N / D, and then
            // inv_rate = (window − N/D) / n = (window·D − N) / (D·n): one division.
            let v = self.current_speed * self.step_per_mm; // steps/s at the end
            let v2 = v * v;
            let x = match self.ramp {
                Ramp::Accel => -(self.acceleration * self.step_per_mm * frac),
                Ramp::Decel => self.acceleration * self.step_per_mm * frac,
                _ => 0.0,
            };
            let num = 2.0 * frac * v;
            let den = 2.0 * v2 + x;
            // Well conditioned (|x| ≤ v²/4) and the last tick after mid-window.
            if 4.0 * abs_f32(x) < v2 && num < 0.5 * window * den {
                inv_rate = (window * den - num) / (den * n);
                self.dt_remainder = window - inv_rate * n;
            } else {
                // Near a stop: exact, with a square root.
                let tail = self.fraction_time(frac, window);
                inv_rate = (window - tail) / n;
                self.dt_remainder = tail;
            }
        } else {
            inv_rate = window / n;
            self.dt_remainder = 0.0;
        }
        self.steps_remaining = n_steps_remaining;
        let (period, prescale) = timer_for(F_CPU * inv_rate);
        debug_assert!(ticks <= u16::MAX as u32);
        let seg = Segment { ticks: ticks as u16, period, prescale };

        self.write_back(b, mm_remaining);
        if profile_done {
            if mm_remaining > 0.0 {
                // A hold stopped inside the block.
                self.held = true;
            } else {
                self.finish_block(pl);
            }
        }
        Some(seg)
    }

    /// Record progress in the executing block: distance left, current speed².
    /// Stored values stay ≥ +0.0 (the planner compares them as bit patterns).
    fn write_back(&self, b: &mut crate::planner::Block, mm_remaining: f32) {
        let mm = if mm_remaining > 0.0 { mm_remaining } else { 0.0 };
        b.millimeters = mm;
        b.entry_speed_sqr = self.current_speed * self.current_speed;
        b.max_delta_speed_sqr = 2.0 * self.acceleration * mm;
    }

    /// Time to cover the last `frac` (< 1) step of a segment that ends at the
    /// current speed, s: the last tick comes that long before the segment ends.
    /// grbl charges it at the segment's mean speed, which puts the last tick of
    /// every ramp segment early (accelerating) or late (decelerating).
    fn fraction_time(&self, frac: f32, window: f32) -> f32 {
        let v = self.current_speed * self.step_per_mm; // steps/s at the end
        let t = if self.ramp == Ramp::Decel {
            // Decelerating into the end: frac = v·t + a·t²/2.
            let a = self.acceleration * self.step_per_mm;
            2.0 * frac / (v + sqrtf(v * v + 2.0 * a * frac))
        } else if v > 0.0 {
            frac / v
        } else {
            0.0
        };
        // Never let the last tick come before the window's midpoint.
        let max = 0.5 * window;
        if t > max {
            max
        } else {
            t
        }
    }

    /// The executing block is fully prepared: drop it from the planner.
    fn finish_block(&mut self, pl: &mut Planner) {
        self.active = false;
        pl.discard_current_block();
    }
}

impl Default for Prep {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod per_tick_tests {
    use super::per_tick;

    #[test]
    fn per_tick_is_the_division_within_an_ulp() {
        let mut x = 1.0f32;
        for _ in 0..2000 {
            x = x * 1.37 % 800_000.0 + 31.0;
            for n in 1..=20u32 {
                let (got, want) = (per_tick(x, n), x / n as f32);
                let ulps = (got.to_bits() as i64 - want.to_bits() as i64).abs();
                assert!(ulps <= 1, "{x} / {n}: {got} vs {want}");
            }
        }
    }
}
