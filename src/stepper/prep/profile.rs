//! The velocity profile of the rest of the executing block (grbl's
//! trapezoid: accelerate, cruise, decelerate; a forced deceleration for a
//! hold), and the cached square root of its nominal speed².

use super::{Prep, Ramp, CRUISE_SEGMENT_TIME_S, F_CPU};
use crate::math::float_bits::{lt_nn, lt_of_positive, positive};
use crate::math::sqrt_1ulp;
use crate::planner::Planner;

impl Prep {
    /// The square root of a nominal speed², cached with the cruise figures.
    // speed: the cache's test in line, its refill a call (as one call ~50 cycles a block)
    #[inline(always)]
    pub(super) fn nominal_speed(&mut self, nominal_sqr: f32) -> f32 {
        if self.nominal_cache.0 != nominal_sqr.to_bits() {
            self.refill_nominal(nominal_sqr);
        }
        self.nominal_cache.1
    }

    /// [`Prep::nominal_speed`]'s caches for another nominal speed².
    // speed: see nominal_speed
    #[inline(never)]
    fn refill_nominal(&mut self, nominal_sqr: f32) {
        let v = sqrt_1ulp(nominal_sqr);
        self.nominal_cache = (nominal_sqr.to_bits(), v);
        let cycles_per_mm = if v > 0.0 { crate::math::div_cold(F_CPU, v) } else { 0.0 };
        self.cruise_cache = (cycles_per_mm, CRUISE_SEGMENT_TIME_S * v);
    }

    /// The velocity profile of the rest of the executing block (grbl).
    pub(super) fn compute_profile(&mut self, pl: &mut Planner) {
        let exit_speed_sqr = pl.exec_exit_speed_sqr();
        let Some(b) = pl.current_block_mut() else { return };
        // The executing block starts "now", at the current speed.
        b.entry_speed_sqr = self.current_speed * self.current_speed;
        let entry_sqr = b.entry_speed_sqr;
        let mm = b.millimeters;
        let inv_2_accel = self.dv_cycles * (0.5 / F_CPU);
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
                self.exit_speed = sqrt_1ulp(entry_sqr - 2.0 * self.accel() * mm);
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
        self.exit_speed = exit_speed(exit_speed_sqr, nominal_sqr, nominal);
        self.exit_speed_sqr_bits = exit_speed_sqr.to_bits();
        let intersect = crate::math::float_bits::half(mm + inv_2_accel * (entry_sqr - exit_speed_sqr));
        // The compares on the bits (exact here, see each helper): a
        // soft-float compare is a ~50-cycle call on the AVR, and a block
        // runs four or five of them.
        if lt_nn(nominal_sqr, entry_sqr) {
            self.accelerate_until = mm - inv_2_accel * (entry_sqr - nominal_sqr);
            if self.accelerate_until <= 0.0 {
                // Deceleration only; the next block starts at our exit speed.
                self.ramp = Ramp::Decel;
                let v2 = entry_sqr - 2.0 * self.accel() * mm;
                self.exit_speed = if v2 > 0.0 { sqrt_1ulp(v2) } else { 0.0 };
                self.exit_speed_sqr_bits = u32::MAX;
                self.decel_override = true;
            } else {
                self.decelerate_after = inv_2_accel * (nominal_sqr - exit_speed_sqr);
                self.maximum_speed = nominal;
                self.ramp = Ramp::DecelOverride;
            }
        } else if positive(intersect) {
            if lt_nn(intersect, mm) {
                // Trapezoid or triangle.
                self.decelerate_after = inv_2_accel * (nominal_sqr - exit_speed_sqr);
                if lt_of_positive(self.decelerate_after, intersect) {
                    self.maximum_speed = nominal;
                    if entry_sqr == nominal_sqr {
                        self.ramp = Ramp::Cruise;
                    } else {
                        self.accelerate_until -= inv_2_accel * (nominal_sqr - entry_sqr);
                    }
                } else {
                    self.accelerate_until = intersect;
                    self.decelerate_after = intersect;
                    self.maximum_speed = sqrt_1ulp(2.0 * self.accel() * intersect + exit_speed_sqr);
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
}

/// The exit speed for the exit speed² `exit_sqr`: the nominal speed
/// `nominal` (the root of `nominal_sqr`, cached) when it is the nominal
/// speed², 0 for 0, else its square root. The profile and
/// `fast::ramp_cycles` take it the same way.
// speed: in the per-block path of both callers
#[inline(always)]
pub(super) fn exit_speed(exit_sqr: f32, nominal_sqr: f32, nominal: f32) -> f32 {
    if exit_sqr.to_bits() == nominal_sqr.to_bits() {
        nominal
    } else if exit_sqr.to_bits() == 0 {
        0.0
    } else {
        sqrt_1ulp(exit_sqr)
    }
}
