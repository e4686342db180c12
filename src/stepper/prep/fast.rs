//! The one-segment fast paths: a block that runs entirely at its nominal
//! speed ([`Prep::cruise_block`]), the rest of a block short enough for one
//! ramp segment timed in closed form from its speeds² before any profile
//! ([`Prep::ramp_block`]), or from the profile ([`Prep::short_block`]):
//! each one segment instead of the segment loop.

use super::timer::{per_tick, timer_for};
use super::{Prep, Ramp, F_CPU, SEGMENT_TIME_S};
use crate::math::float_bits::{half, lt_nn, positive, times2};
use crate::math::sqrt_1ulp;
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
        let b = pl.current_block()?;
        let nominal_bits = b.nominal_speed_sqr.to_bits();
        // The entry first: the exit's look-up adds the ramp's lift.
        if b.entry_speed_sqr.to_bits() != nominal_bits || nominal_bits == 0 {
            return None;
        }
        let exit_sqr = pl.exec_exit_speed_sqr().to_bits();
        if exit_sqr != nominal_bits {
            return None;
        }
        let (mm, n, nominal_sqr) = (b.millimeters, self.block_events, b.nominal_speed_sqr);
        let v = self.nominal_speed(nominal_sqr);
        let (cycles_per_mm, max_mm) = self.cruise_cache;
        if !(mm <= max_mm) || n == 0 || n != self.steps_remaining || n > u16::MAX as u32 {
            return None;
        }
        self.ramp = Ramp::Cruise;
        Some(self.whole_block(pl, mm * cycles_per_mm, n, v, nominal_bits, true))
    }

    /// Fast path for the rest of a block that takes at most one ramp
    /// segment ([`SEGMENT_TIME_S`]), tried before its profile: the time in
    /// closed form from the speeds² ([`ramp_cycles`]), so neither the
    /// profile nor [`Prep::short_block`] runs. A stream of short moves at
    /// the look-ahead's limit is made of such blocks, each accelerating
    /// a little and decelerating a little. `None` (and nothing changed but
    /// the caches) for a hold, an entry above the nominal speed, an exit
    /// out of reach, more than one segment: the profile decides those.
    pub(super) fn ramp_block(&mut self, pl: &mut Planner) -> Option<Segment> {
        let n = self.steps_remaining;
        if self.holding || n == 0 || n > u16::MAX as u32 {
            return None;
        }
        let exit_sqr = pl.exec_exit_speed_sqr();
        let b = pl.current_block()?;
        let nominal_sqr = b.nominal_speed_sqr;
        let vn = self.nominal_speed(nominal_sqr);
        let v0 = self.current_speed;
        // v0² is the exit² it was the root of, when it is the last exit
        // speed (the usual start of a block): no multiply.
        let entry_sqr = if v0.to_bits() == self.exit_speed.to_bits() && self.exit_speed_sqr_bits != u32::MAX {
            f32::from_bits(self.exit_speed_sqr_bits)
        } else {
            crate::math::mul_cold(v0, v0)
        };
        let speeds = Speeds { v0, entry_sqr, exit_sqr, delta_sqr: b.max_delta_speed_sqr, nominal_sqr, vn };
        let (cycles, v1) = ramp_cycles(&speeds, self.dv_cycles, self.cruise_cache.0)?;
        Some(self.whole_block(pl, cycles, n, v1, exit_sqr.to_bits(), true))
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
        Some(self.whole_block(pl, cycles, n, self.exit_speed, self.exit_speed_sqr_bits, false))
    }

    /// The one segment of a fast path: the block's last `n` steps over
    /// `cycles` (and the time carried from the segment before), ending at
    /// `v1`, whose square's bits are `v1_sqr_bits`. The block is dropped
    /// without a write-back: nothing reads it again (three soft-float
    /// multiplies saved per block on the AVR); `read_in_call`: v1² is the
    /// planner's exit speed² as read in this call.
    // speed: in the per-block path of the three fast paths
    #[inline(always)]
    fn whole_block(&mut self, pl: &mut Planner, cycles: f32, n: u32, v1: f32, v1_sqr_bits: u32, read_in_call: bool) -> Segment {
        let (period, prescale) = timer_for(per_tick(self.plus_remainder(cycles), n));
        self.profile_stale = false;
        self.current_speed = v1;
        self.exit_speed = v1;
        self.exit_speed_sqr_bits = v1_sqr_bits;
        self.dt_remainder = 0.0;
        self.steps_remaining = 0;
        self.finish_block_at(pl, read_in_call.then_some(f32::from_bits(v1_sqr_bits)));
        Segment { ticks: n as u16, period, prescale }
    }

    /// `cycles` plus the time carried from the last segment, in CPU cycles
    /// (nothing to add, the usual case: no multiply).
    // speed: a call for a test cost ~25 cycles a block
    #[inline(always)]
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
    /// cycles (the seconds cost two more multiplies on the AVR): Δv times the
    /// cycles per mm/s ([`crate::planner::Block::dv_cycles`]). `None`
    /// beyond one ramp segment ([`SEGMENT_TIME_S`]), for no time, or at a
    /// cruise speed that is not the cached one. Its plain twin, in seconds:
    /// `tests::short_time_plain`.
    fn short_cycles(&self, mm: f32) -> Option<f32> {
        let (v0, vmax, v1) = (self.current_speed, self.maximum_speed, self.exit_speed);
        let (dv, cruise_mm) = match self.ramp {
            Ramp::Accel => ((vmax - v0) + (vmax - v1), self.accelerate_until - self.decelerate_after),
            Ramp::Cruise => (vmax - v1, mm - self.decelerate_after),
            Ramp::Decel => (v0 - v1, 0.0),
            Ramp::DecelOverride => return None,
        };
        let mut cycles = dv * self.dv_cycles;
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

/// What [`ramp_cycles`] times: the rest of a block from the current speed
/// `v0` (mm/s; its square `entry_sqr`, within an ulp or two) to the planned
/// exit speed² `exit_sqr`, with `delta_sqr` = 2·a·mm left ((mm/s)²), at
/// most the nominal speed² `nominal_sqr`, whose root is `vn`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Speeds {
    pub(super) v0: f32,
    pub(super) entry_sqr: f32,
    pub(super) exit_sqr: f32,
    pub(super) delta_sqr: f32,
    pub(super) nominal_sqr: f32,
    pub(super) vn: f32,
}

/// CPU cycles of the rest of a block along its trapezoid, and its exit
/// speed, when that takes at most one ramp segment ([`SEGMENT_TIME_S`]):
/// accelerating from v0 and decelerating to v1 = √exit² meet at the peak²
/// p = (2a·mm + v0² + v1²) / 2; below the nominal speed² the block is a
/// triangle, (2√p − v0 − v1) / a, else a trapezoid,
/// (2vn − v0 − v1) / a plus (p − vn²) / a mm at vn (`cycles_per_mm` at vn).
/// About half the profile's and [`Prep::short_block`]'s soft-float calls:
/// `profile --count 254 --feed 12000 --accel 5000 --trace 300:1500` went
/// from 21 766 to 21 315 cycles a line. `None` where the profile must
/// decide: an entry or exit above the nominal speed, an exit out of reach
/// either way, more than one segment. `dv_cycles` is F_CPU / a (the
/// block's [`crate::planner::Block::dv_cycles`]): the ramps' time in cycles
/// is one multiply, not two (with 0.5 / a and F_CPU: `profile --count 254
/// --feed 12000 --accel 5000 --trace 300:1500` 19 722 -> 19 641 cycles a
/// line). Its plain twin, in f64 over the trapezoid's three phases:
/// `tests::ramp_time_plain`.
pub(super) fn ramp_cycles(s: &Speeds, dv_cycles: f32, cycles_per_mm: f32) -> Option<(f32, f32)> {
    let entry_sqr = s.entry_sqr;
    let peak_sqr = half(s.delta_sqr + entry_sqr + s.exit_sqr);
    if lt_nn(peak_sqr, entry_sqr) || lt_nn(peak_sqr, s.exit_sqr) || lt_nn(s.nominal_sqr, entry_sqr) || lt_nn(s.nominal_sqr, s.exit_sqr) {
        return None;
    }
    let v1 = super::profile::exit_speed(s.exit_sqr, s.nominal_sqr, s.vn);
    let triangle = lt_nn(peak_sqr, s.nominal_sqr);
    let vp = if triangle { sqrt_1ulp(peak_sqr) } else { s.vn };
    let mut dv = times2(vp) - s.v0 - v1;
    if !triangle {
        // The cruise between the ramps, (p − vn²) / a mm at vn, as the
        // speed change that takes as long: (p − vn²) / vn.
        dv += (peak_sqr - s.nominal_sqr) * (cycles_per_mm * (1.0 / F_CPU));
    }
    let cycles = dv * dv_cycles;
    // 0 < cycles ≤ one segment, on the bits (as in `short_cycles`).
    if !positive(cycles) || cycles.to_bits() > (SEGMENT_TIME_S * F_CPU).to_bits() {
        return None;
    }
    Some((cycles, v1))
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
    use super::{ramp_cycles, Speeds};
    use crate::test_util::XorShift;

    /// The plain duration `short_cycles` replaces, s: each ramp's Δv / a,
    /// the cruise at the cached cycles per mm, in seconds.
    fn short_time_plain(p: &Prep, mm: f32) -> Option<f32> {
        let inv_a = (p.dv_cycles as f64 / F_CPU as f64) as f32;
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
            p.dv_cycles = F_CPU / a;
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

    /// The plain twin of `ramp_cycles`: the rest of a block's time, s, in
    /// f64, phase by phase along the trapezoid (accelerate from v0, cruise
    /// at vn, decelerate to v1 = √exit²; a triangle where the ramps meet
    /// below vn). `None` for an entry or exit above vn or out of reach.
    fn ramp_time_plain(v0: f64, exit_sqr: f64, mm: f64, a: f64, vn: f64) -> Option<f64> {
        let v1 = exit_sqr.sqrt();
        if v0 > vn || v1 > vn {
            return None;
        }
        let (up, down) = ((vn * vn - v0 * v0) / (2.0 * a), (vn * vn - v1 * v1) / (2.0 * a));
        if up + down <= mm {
            return Some((vn - v0) / a + (mm - up - down) / vn + (vn - v1) / a);
        }
        let peak_sqr = a * mm + (v0 * v0 + v1 * v1) / 2.0;
        if peak_sqr < v0 * v0 || peak_sqr < v1 * v1 {
            return None;
        }
        let vp = peak_sqr.sqrt();
        Some((vp - v0) / a + (vp - v1) / a)
    }

    #[test]
    fn ramp_cycles_are_the_plain_trapezoid_time_in_cycles() {
        let mut rng = XorShift(0x7A3B);
        let mut u = move || (rng.next() >> 8) as f32 / (1u32 << 24) as f32;
        let (mut some, mut none, mut trapezoids) = (0, 0, 0);
        for i in 0..300_000 {
            let a = 20.0 + 8000.0 * u();
            let vn = 1.0 + 300.0 * u();
            // Mostly the reachable speeds of a planned block, some not.
            let v0 = vn * if i % 7 == 0 { 1.0 + 0.01 * u() } else { u() };
            let mm = vn * 0.005 * u() * u() + if i % 11 == 0 { 1e-4 } else { 0.0 };
            let reach = (v0 * v0 + 2.0 * a * mm).min(vn * vn);
            let exit_sqr = match i % 5 {
                0 => vn * vn,
                1 => 0.0,
                2 => reach * 1.01,
                _ => reach * u(),
            };
            let delta_sqr = 2.0 * a * mm;
            let s = Speeds { v0, entry_sqr: v0 * v0, exit_sqr, delta_sqr, nominal_sqr: vn * vn, vn };
            let fast = ramp_cycles(&s, F_CPU / a, F_CPU / vn);
            let plain = ramp_time_plain(v0 as f64, exit_sqr as f64, mm as f64, a as f64, vn as f64);
            let limit = (SEGMENT_TIME_S * F_CPU) as f64;
            // Decisions within rounding of a boundary may go either way.
            let peak_sqr = (a * mm) as f64 + ((v0 * v0) as f64 + exit_sqr as f64) / 2.0;
            let near = |x: f64, y: f64| (x - y).abs() <= 1e-5 * x.abs().max(y.abs());
            if near(peak_sqr, (v0 * v0) as f64) || near(peak_sqr, exit_sqr as f64) || near(exit_sqr as f64, (vn * vn) as f64) {
                continue;
            }
            if plain.is_some_and(|t| (t * F_CPU as f64 - limit).abs() < 1e-3 * limit || t < 1e-7) {
                continue;
            }
            let want = plain.map(|t| t * F_CPU as f64).filter(|&c| c <= limit);
            match (want, fast) {
                (None, None) => none += 1,
                (Some(c), Some((got, v1))) => {
                    some += 1;
                    trapezoids += (peak_sqr >= (vn * vn) as f64) as u32;
                    // f32 speeds cancel in v_peak − v0: a few ulps of the
                    // fastest speed, over a.
                    let ulp = f32::EPSILON as f64 * (v0.max(vn) as f64);
                    let tol = 1e-5 * c + 6.0 * ulp / a as f64 * F_CPU as f64;
                    assert!((got as f64 - c).abs() <= tol, "{s:?} a {a}: {got} vs {c} cycles");
                    assert!((v1 as f64 - (exit_sqr as f64).sqrt()).abs() <= 1e-6 * vn as f64, "{s:?}: exit {v1}");
                }
                (w, f) => panic!("{s:?} a {a} mm {mm}: plain {w:?}, fast {f:?}"),
            }
        }
        assert!(some > 30_000 && none > 100_000 && trapezoids > 3_000, "{some} timed, {none} left to the profile, {trapezoids} trapezoids");
    }
}
