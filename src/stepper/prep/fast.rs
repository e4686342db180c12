//! The two one-segment fast paths: a block that runs entirely at its
//! nominal speed ([`Prep::cruise_block`]) and the rest of a block short
//! enough for one ramp segment ([`Prep::short_block`]), each one segment
//! with one division instead of the profile and the segment loop.

use super::timer::{per_tick, timer_for};
use super::{Prep, Ramp, F_CPU, SEGMENT_TIME_S};
use crate::math::float_bits::{positive, times2};
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
        let (mm, n, nominal_sqr) = (b.millimeters, self.block_events, b.nominal_speed_sqr);
        let v = self.nominal_speed(nominal_sqr);
        let (cycles_per_mm, max_mm) = self.cruise_cache;
        if !(mm <= max_mm) || n == 0 || n != self.steps_remaining || n > u16::MAX as u32 {
            return None;
        }
        let (period, prescale) = timer_for(per_tick(self.plus_remainder(mm * cycles_per_mm), n));
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
        let b = pl.current_block()?;
        let cycles = self.short_cycles(b.millimeters)?;
        let n = self.steps_remaining;
        if n == 0 || n > u16::MAX as u32 {
            return None;
        }
        let (period, prescale) = timer_for(per_tick(self.plus_remainder(cycles), n));
        self.current_speed = self.exit_speed;
        self.dt_remainder = 0.0;
        self.steps_remaining = 0;
        // No write-back: the block is dropped here, nothing reads it again
        // (three soft-float multiplies saved per block on the AVR).
        self.finish_block(pl);
        Some(Segment { ticks: n as u16, period, prescale })
    }

    /// `cycles` plus the time carried from the last segment, in CPU cycles
    /// (nothing to add, the usual case: no multiply).
    fn plus_remainder(&self, cycles: f32) -> f32 {
        if self.dt_remainder.to_bits() == 0 {
            cycles
        } else {
            plus_time(cycles, self.dt_remainder)
        }
    }

    /// CPU cycles the rest of the executing block (`mm` left) takes along
    /// its profile: Δv / a on the ramps (one multiply for both ramps of a
    /// trapezoid), distance × the cached cycles per mm at cruise, added in
    /// cycles (the seconds cost two more multiplies on the AVR). `None`
    /// beyond one ramp segment ([`SEGMENT_TIME_S`]), for no time, or at a
    /// cruise speed that is not the cached one. Its plain twin, in seconds:
    /// `tests::short_time_plain`.
    fn short_cycles(&self, mm: f32) -> Option<f32> {
        let inv_a = times2(self.inv_2_accel.latest()); // s² / mm
        let (v0, vmax, v1) = (self.current_speed, self.maximum_speed, self.exit_speed);
        let (dv, cruise_mm) = match self.ramp {
            Ramp::Accel => ((vmax - v0) + (vmax - v1), self.accelerate_until - self.decelerate_after),
            Ramp::Cruise => (vmax - v1, mm - self.decelerate_after),
            Ramp::Decel => (v0 - v1, 0.0),
            Ramp::DecelOverride => return None,
        };
        let mut cycles = dv * inv_a * F_CPU;
        if positive(cruise_mm) {
            if self.nominal_cache.1.to_bits() != vmax.to_bits() {
                return None;
            }
            cycles += cruise_mm * self.cruise_cache.0;
        }
        // 0 < cycles ≤ one segment, on the bits (positive floats order like
        // them; a NaN fails both, as the float compares it replaces).
        if !positive(cycles) || cycles.to_bits() > (SEGMENT_TIME_S * F_CPU).to_bits() {
            return None;
        }
        Some(cycles)
    }
}

/// `cycles` + `dt_s` in CPU cycles. Not inlined: behind the test in
/// `plus_remainder` LLVM-AVR computes it every time (`math::div_cold`).
// speed: see above
#[inline(never)]
fn plus_time(cycles: f32, dt_s: f32) -> f32 {
    cycles + dt_s * F_CPU
}

#[cfg(test)]
mod tests {
    use super::super::timer::{per_tick, timer_for};
    use super::super::{Prep, Ramp, F_CPU, SEGMENT_TIME_S};
    use crate::math::float_bits::times2;
    use crate::test_util::XorShift;

    /// The plain duration `short_cycles` replaces, s: each ramp's Δv / a,
    /// the cruise at the cached cycles per mm, in seconds.
    fn short_time_plain(p: &Prep, mm: f32) -> Option<f32> {
        let inv_a = times2(p.inv_2_accel.latest());
        let (v0, vmax, v1) = (p.current_speed, p.maximum_speed, p.exit_speed);
        let (mut t, cruise_mm) = match p.ramp {
            Ramp::Accel => ((vmax - v0) * inv_a + (vmax - v1) * inv_a, p.accelerate_until - p.decelerate_after),
            Ramp::Cruise => ((vmax - v1) * inv_a, mm - p.decelerate_after),
            Ramp::Decel => ((v0 - v1) * inv_a, 0.0),
            Ramp::DecelOverride => return None,
        };
        if cruise_mm > 0.0 {
            if p.nominal_cache.1.to_bits() != vmax.to_bits() {
                return None;
            }
            t += cruise_mm * p.cruise_cache.0 * (1.0 / F_CPU);
        }
        if !(t <= SEGMENT_TIME_S) || !(t > 0.0) {
            return None;
        }
        Some(t)
    }

    #[test]
    fn short_cycles_are_the_plain_time_in_cycles_and_give_the_same_timer() {
        let mut rng = XorShift(0x5407);
        let mut u = move || (rng.next() >> 8) as f32 / (1u32 << 24) as f32;
        let (mut some, mut checked) = (0, 0);
        for _ in 0..200_000 {
            let a = 50.0 + 5000.0 * u();
            let mut p = Prep::new();
            p.inv_2_accel.set(a);
            let v0 = 100.0 * u();
            let vmax = v0 + a * 0.004 * u();
            let v1 = (vmax - a * 0.004 * u()).max(0.0);
            let cruise_mm = if u() < 0.5 { 0.0 } else { vmax * 0.003 * u() };
            p.decelerate_after = (vmax * vmax - v1 * v1) * 0.5 / a;
            p.accelerate_until = p.decelerate_after + cruise_mm;
            let mm = p.accelerate_until + (vmax * vmax - v0 * v0) * 0.5 / a;
            (p.current_speed, p.maximum_speed, p.exit_speed) = (v0, vmax, v1);
            p.ramp = [Ramp::Accel, Ramp::Cruise, Ramp::Decel][(u() * 3.0) as usize];
            let v = if u() < 0.9 { vmax } else { vmax * 1.01 };
            p.nominal_cache = (0, v);
            p.cruise_cache = (F_CPU / v, 0.0);
            p.dt_remainder = if u() < 0.5 { 0.0 } else { 1e-4 * u() };
            let plain = short_time_plain(&p, mm);
            let fast = p.short_cycles(mm);
            if let Some(t) = plain {
                // The limit may fall on either side within rounding.
                if (t - SEGMENT_TIME_S).abs() < 1e-9 {
                    continue;
                }
            }
            assert_eq!(plain.is_some(), fast.is_some(), "{p:?} {mm}: {plain:?} vs {fast:?}");
            checked += 1;
            let (Some(t), Some(c)) = (plain, fast) else { continue };
            some += 1;
            let want = (t + p.dt_remainder) * F_CPU;
            let got = p.plus_remainder(c);
            assert!((got - want).abs() <= 4e-7 * want + 1e-3, "{p:?}: {got} vs {want} cycles");
            for n in [1u32, 2, 3, 7, 10, 33, 250] {
                let (pw, sw) = timer_for(per_tick(want, n));
                let (pg, sg) = timer_for(per_tick(got, n));
                let (w, g) = (pw as i64 * sw.divisor() as i64, pg as i64 * sg.divisor() as i64);
                assert!((w - g).abs() <= sw.divisor().max(sg.divisor()) as i64, "{n} ticks: {pw}/{sw:?} vs {pg}/{sg:?}");
            }
        }
        assert!(some > 50_000 && checked > 150_000, "{some} of {checked}");
    }
}
