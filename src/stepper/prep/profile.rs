//! The velocity profile of the rest of the executing block (grbl's
//! trapezoid: accelerate, cruise, decelerate; a forced deceleration for a
//! hold), and the cached square root of its nominal speed².

use super::{Prep, Ramp, CRUISE_SEGMENT_TIME_S, F_CPU};
use crate::math::float_bits::{lt_nn, lt_of_positive, positive};
use crate::math::sqrt_1ulp;
use crate::planner::Planner;

impl Prep {
    /// The square root of a nominal speed², cached with the cruise figures.
    pub(super) fn nominal_speed(&mut self, nominal_sqr: f32) -> f32 {
        if self.nominal_cache.0 != nominal_sqr.to_bits() {
            let v = sqrt_1ulp(nominal_sqr);
            self.nominal_cache = (nominal_sqr.to_bits(), v);
            let cycles_per_mm = if v > 0.0 { crate::math::div_cold(F_CPU, v) } else { 0.0 };
            self.cruise_cache = (cycles_per_mm, CRUISE_SEGMENT_TIME_S * v);
        }
        self.nominal_cache.1
    }

    /// The velocity profile of the rest of the executing block (grbl).
    pub(super) fn compute_profile(&mut self, pl: &mut Planner) {
        let exit_speed_sqr = pl.exec_exit_speed_sqr();
        let Some(b) = pl.current_block_mut() else { return };
        // The executing block starts "now", at the current speed.
        b.entry_speed_sqr = self.current_speed * self.current_speed;
        let entry_sqr = b.entry_speed_sqr;
        let mm = b.millimeters;
        let a = self.acceleration;
        let inv_2_accel = self.inv_2_accel.get(a);
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
                self.exit_speed = sqrt_1ulp(entry_sqr - 2.0 * a * mm);
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
                let v2 = entry_sqr - 2.0 * a * mm;
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
                    self.maximum_speed = sqrt_1ulp(2.0 * a * intersect + exit_speed_sqr);
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

/// 0.5 / a for the last three accelerations a, the latest first. A stream
/// of short moves in changing directions cycles through a few
/// accelerations (a chord's depends on its direction: the benchmark's
/// circle has 21, in runs), and each miss is a division (~540 cycles on
/// the AVR): one entry hit 29 % of the circle's blocks, three hit 85 %
/// (`profile --count 254 --feed 12000 --accel 5000`: −320 cycles a line).
/// RAM: 24 B (16 more than one entry).
// Three named entries, not an array (the array's entries moved by
// `memcpy`, +140 cycles a line on the AVR), each keyed by the complement
// of the acceleration's bits, so that the empty cache is all zeros (the
// complement of a NaN's bits, never an acceleration's): an empty value of
// 0xFF bytes was a 24-byte `.data` constant copied in.
#[derive(Clone, Copy, Debug)]
pub(super) struct HalfInvCache {
    latest: (u32, f32),
    second: (u32, f32),
    third: (u32, f32),
}

impl HalfInvCache {
    /// No entry (all zeros: see the type's note).
    pub(super) const EMPTY: HalfInvCache = HalfInvCache { latest: (0, 0.0), second: (0, 0.0), third: (0, 0.0) };

    /// 0.5 / `a`, as `div_cold` gives it, from the cache or computed; the
    /// entry moves to the front.
    pub(super) fn get(&mut self, a: f32) -> f32 {
        let bits = !a.to_bits();
        if self.latest.0 != bits {
            let older = self.latest;
            if self.second.0 == bits {
                self.latest = self.second;
            } else {
                self.latest = if self.third.0 == bits { self.third } else { (bits, crate::math::div_cold(0.5, a)) };
                self.third = self.second;
            }
            self.second = older;
        }
        self.latest.1
    }

    /// 0.5 / a of the latest acceleration given to [`HalfInvCache::get`].
    pub(super) fn latest(&self) -> f32 {
        self.latest.1
    }

    /// Make `a` the latest entry, 0.5 / a computed (the tests' set-up).
    #[cfg(test)]
    pub(super) fn set(&mut self, a: f32) {
        *self = HalfInvCache::EMPTY;
        self.get(a);
    }

    /// The accelerations' bits held, any order (the tests).
    #[cfg(test)]
    fn keys(&self) -> [u32; 3] {
        let mut k = [self.latest.0, self.second.0, self.third.0];
        k.sort();
        k
    }
}

#[cfg(test)]
mod tests {
    use super::HalfInvCache;
    use crate::test_util::XorShift;

    /// Every answer is the division's, bit for bit, whatever the order of
    /// the accelerations (a stale or misplaced entry gives another's), and
    /// a run over three values divides only for their first appearance.
    #[test]
    fn the_half_inverse_cache_answers_what_the_division_gives() {
        let mut rng = XorShift(0x1A55);
        let values: [f32; 5] = [1000.0, 1414.2135, 1250.5, 5000.0, 3333.3333];
        let mut c = HalfInvCache::EMPTY;
        for _ in 0..100_000 {
            let a = values[(rng.next() % 5) as usize];
            assert_eq!(c.get(a).to_bits(), crate::math::div_cold(0.5, a).to_bits(), "{a}");
            assert_eq!(c.latest().to_bits(), (0.5 / a).to_bits());
        }
        // Three values in any order: all hits after the first round.
        let mut c = HalfInvCache::EMPTY;
        let three = [values[0], values[1], values[2]];
        for &a in &three {
            c.get(a);
        }
        let want = c.keys();
        for _ in 0..1000 {
            let a = three[(rng.next() % 3) as usize];
            c.get(a);
            assert_eq!(c.keys(), want, "an entry of the three was dropped");
        }
    }
}
