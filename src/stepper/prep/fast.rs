//! The two one-segment fast paths: a block that runs entirely at its
//! nominal speed ([`Prep::cruise_block`]) and the rest of a block short
//! enough for one ramp segment ([`Prep::short_block`]), each one segment
//! with one division instead of the profile and the segment loop.

use super::timer::{per_tick, timer_for};
use super::{Prep, Ramp, F_CPU, SEGMENT_TIME_S};
use crate::planner::Planner;
use crate::stepper::Segment;

impl Prep {
    /// Fast path for a block that runs entirely at its nominal speed (entry,
    /// exit and nominal speed² equal, the usual case inside a stream of short
    /// moves) and is short enough for one cruise segment: the whole block as
    /// one segment with one division, instead of the profile and the segment
    /// loop (~1 k instead of ~8 k cycles on the AVR). It produces the segment
    /// the general path would (same ticks, period within a timer count).
    pub(super) fn cruise_block(&mut self, pl: &mut Planner) -> Option<Segment> {
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
        // No write-back: the block is dropped here (see `short_block`).
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
    pub(super) fn short_block(&mut self, pl: &mut Planner) -> Option<Segment> {
        if self.holding || self.ramp == Ramp::DecelOverride {
            return None;
        }
        let inv_a = super::timer::times2(self.inv_2_accel_cache.1); // s² / mm
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
        // No write-back: the block is dropped here, nothing reads it again
        // (three soft-float multiplies saved per block on the AVR).
        self.finish_block(pl);
        Some(Segment { ticks: n as u16, period, prescale })
    }
}
