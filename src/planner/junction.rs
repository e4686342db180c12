//! Junction maths: the entry speed² allowed where one block meets the next
//! (grbl's junction deviation rule), with the cap on an axis' speed step where
//! it reverses. Used when a block is queued and when the overrides re-plan the
//! ring.

use crate::config::Settings;
use crate::math::float_bits::{abs_f32, half, lt_nn, min_nn};
use crate::math::sqrt_1ulp;
use crate::N_AXES;

/// Cosine beyond which a junction counts as a full reversal / a straight line.
const JUNCTION_COS_LIMIT: f32 = 0.999_999;
/// At a junction where an axis reverses, its speed steps from +v·|u_prev| to
/// −v·|u| at once, between a deceleration and an acceleration of the same
/// sign. Seen through the recorder's 20 ms window (docs/SPEC.md §11 "measured
/// acceleration") that step adds step/20 ms to the ramps' acceleration: the
/// demo job's 153° corner (junction deviation alone: 1.7 mm/s, a 3.2 mm/s
/// step on X) measured 1157 mm/s² at a 1000 mm/s² setting. The step is kept
/// to the speed change the axis' own acceleration gives in this time (0.5 mm/s
/// at 1000 mm/s², +2.5 %). Junctions where no axis reverses (curves, the
/// short chords of arcs) are not affected.
pub(super) const REVERSAL_STEP_S: f32 = 0.0005;
/// Entry speed² used for a straight junction (then limited by the nominal speeds).
const JUNCTION_SPEED_SQR_STRAIGHT: f32 = 1.0e30;

/// The junction speed² between a block along a unit vector p and the next
/// along u (grbl's junction deviation rule), (mm/s)²: `cos_theta` gives
/// −p·u ([`cos_theta`], or [`short_cos`] from two short moves' deltas),
/// `e_axis` whether E moves in either block, `reversing` the axes (bits)
/// that move in both and change sign ([`reversing`]), `units` gives (p, u)
/// for the reversal's speed step (asked only where an axis reverses), `min_accel`
/// gives the smaller of the two blocks' accelerations (asked only where
/// the rule needs it: the override re-plan divides for it), `cap` the smaller nominal
/// speed² of the two: a junction at least as fast as that is
/// [`JUNCTION_SPEED_SQR_STRAIGHT`] without the square root (`cap_cache`,
/// see [`CapCache`]). Used when a block is queued and when the overrides
/// re-plan the ring.
// Seven numbers of one junction, passed as they are: a struct would be
// built on the per-line path only to be taken apart here.
#[allow(clippy::too_many_arguments)]
// correctness: as a call, `cap` goes on the stack, and LLVM-AVR reads stack
// arguments one byte low on the ATmega2560 (it counts a 2-byte return address;
// the PC is 3 bytes): `cap_sqr_cache` then held garbage and tools/bench's corner
// job measured 2499 mm/s², not 1033. Speed too: ping-pong 5.794 s, not 5.739.
#[inline(always)]
pub(super) fn junction_sqr(
    same_dir: bool,
    cos_theta: impl FnOnce() -> f32,
    e_axis: bool,
    reversing: u8,
    units: impl FnOnce() -> ([f32; N_AXES], [f32; N_AXES]),
    min_accel: impl FnOnce() -> f32,
    cap: f32,
    cap_cache: &mut CapCache,
    s: &Settings,
) -> f32 {
    if same_dir {
        return JUNCTION_SPEED_SQR_STRAIGHT;
    }
    let cos_theta = cos_theta();
    // |cos θ| beyond the limit, on the bit pattern (a soft-float
    // compare costs ~50 cycles).
    let cos_bits = cos_theta.to_bits();
    let beyond = cos_bits & 0x7FFF_FFFF > JUNCTION_COS_LIMIT.to_bits();
    if beyond && cos_bits & 0x8000_0000 == 0 {
        0.0 // full reversal
    } else if beyond {
        JUNCTION_SPEED_SQR_STRAIGHT
    } else {
        // sin²(θ/2)
        let h = half(1.0 - cos_theta);
        // The deviation rule gives v² = a·δ·s / (1 − s), s = sin(θ/2).
        // It reaches the cap L = min(nominal²) when s ≥ L / (a·δ + L),
        // i.e. h·(a·δ + L)² ≥ L²: then skip the square root and the
        // division (most junctions of a smooth curve). First against the
        // cached h_min of the smallest acceleration these axes allow (a
        // compare instead of three multiplies), then exactly.
        let h_min = cap_cache.h_min(cap, e_axis as u32, s);
        if reversing == 0 && !lt_nn(h, h_min) {
            return JUNCTION_SPEED_SQR_STRAIGHT;
        }
        let a = min_accel();
        if reversing == 0 && !lt_nn(h * cap_cache.k_sqr(a, cap, s), cap_cache.cap_sqr) {
            JUNCTION_SPEED_SQR_STRAIGHT
        } else {
            let ad = a * s.junction_deviation_mm;
            let sin_theta_d2 = sqrt_1ulp(h);
            let mut v_sqr = ad * sin_theta_d2 / (1.0 - sin_theta_d2);
            // An axis that reverses here jumps from +v·u_prev to −v·u
            // in one step, between a deceleration and an acceleration of
            // the same sign: limit that jump to what the axis'
            // acceleration gives in REVERSAL_STEP_S (see there).
            if reversing != 0 {
                let (prev_unit, unit) = units();
                for i in 0..N_AXES {
                    if reversing & (1 << i) != 0 {
                        let dv = REVERSAL_STEP_S * s.accel_mm_per_s2[i] / (abs_f32(prev_unit[i]) + abs_f32(unit[i]));
                        v_sqr = min_nn(v_sqr, dv * dv);
                    }
                }
            }
            v_sqr
        }
    }
}

/// The axes (bits) that reverse from the block with `prev` (its moving
/// axes, their negative directions) to the one with `next`: they move in
/// both, in opposite directions. A unit vector's non-zero components are
/// its moving axes, their signs its directions, so this is what
/// [`reversing_plain`] reads from the two unit vectors, in one byte
/// operation (the loop over the vectors' bits cost ~100 cycles a line on
/// the AVR; the twin test `reversing_from_the_bits_is_reversing_from_the_units`).
#[inline(always)]
pub(super) fn reversing(prev: (u8, u8), next: (u8, u8)) -> u8 {
    (prev.1 ^ next.1) & prev.0 & next.0
}

/// The axes whose components of `prev_unit` and `unit` are both non-zero
/// and of opposite signs: [`reversing`]'s plain twin.
#[cfg(test)]
pub(super) fn reversing_plain(prev_unit: &[f32; N_AXES], unit: &[f32; N_AXES]) -> u8 {
    let mut r = 0u8;
    for i in 0..N_AXES {
        let (p, u) = (prev_unit[i].to_bits(), unit[i].to_bits());
        if (p ^ u) & 0x8000_0000 != 0 && p & 0x7FFF_FFFF != 0 && u & 0x7FFF_FFFF != 0 {
            r |= 1 << i;
        }
    }
    r
}

/// cos θ = −prev_unit · unit over the `moving` axes (grbl's junction
/// cosine, −1 straight on). Summed as +prev·unit from the first product on,
/// then negated: the same bits as grbl's 0 − p₀u₀ − p₁u₁ … (negation
/// commutes with rounding) but for the sign of an exact 0, which the rule
/// does not look at, and one soft-float subtraction fewer (~110 cycles on
/// the AVR). [`cos_theta_plain`] is the twin the tests hold it to.
// speed: inlined into `junction_sqr`, on the per-block path
#[inline(always)]
pub(super) fn cos_theta(prev_unit: &[f32; N_AXES], unit: &[f32; N_AXES], moving: u8) -> f32 {
    let mut dot: Option<f32> = None;
    let mut bit = 1u8;
    for i in 0..N_AXES {
        if moving & bit != 0 && prev_unit[i].to_bits() != 0 {
            let p = prev_unit[i] * unit[i];
            dot = Some(match dot {
                Some(d) => d + p,
                None => p,
            });
        }
        bit <<= 1;
    }
    match dot {
        Some(d) => -d,
        None => 0.0,
    }
}

/// cos θ = −p·u for two short moves of X/Y/Z at one steps/mm, from their
/// deltas `d`, `pd` (steps, |d| < 2¹⁴) and their 1/√Σd² `inv_root`,
/// `prev_inv_root`: each unit vector is its deltas times its 1/√Σd², so
/// −p·u = −(pd·d)·(1/√S′)(1/√S), the dot product exact in integers (the
/// hardware multiplier) and one conversion and two soft-float multiplies
/// after it, where [`cos_theta`] needs both unit vectors (two more
/// conversions and multiplies for u) and a multiply and a sum an axis:
/// ~300 cycles a streamed line less on the AVR. Within 2⁻²¹ of
/// [`cos_theta_plain`] on the unit vectors (the twin test
/// `the_cosine_from_the_deltas_is_the_cosine_from_the_unit_vectors`).
// speed: inlined into `queue_block`, on the per-block path
#[inline(always)]
pub(super) fn short_cos(d: &[i32; N_AXES], inv_root: f32, pd: &[i16; 3], prev_inv_root: f32) -> f32 {
    let mut dot = 0i32;
    for i in 0..3 {
        // |d|, |pd| < 2¹⁴: each product below 2²⁸, the sum below 2³⁰.
        let d = d[i] as i16;
        let p = crate::math::mul_u16(d.unsigned_abs(), pd[i].unsigned_abs()) as i32;
        dot += if (d ^ pd[i]) < 0 { -p } else { p };
    }
    -(dot as f32 * (inv_root * prev_inv_root))
}

/// A short move's unit vector: its deltas `d` (steps) times its 1/√Σd²,
/// 0 where an axis does not move, as `queue_block` computes it for the
/// moves [`short_cos`] does not take (bit for bit the vector it stored
/// before the deltas stood for it).
// flash: only where a short move meets another kind of move
#[inline(never)]
pub(super) fn short_unit(d: &[i32; N_AXES], inv_root: f32) -> [f32; N_AXES] {
    let mut u = [0.0; N_AXES];
    for i in 0..3 {
        if d[i] != 0 {
            u[i] = d[i] as f32 * inv_root;
        }
    }
    u
}

/// The last queued block's unit vector: `unit_vec`, or made from its
/// deltas `d` by [`short_unit`] when it was a short move (`inv_root` not 0).
// flash: only where a short move meets another kind of move
#[inline(never)]
pub(super) fn previous_unit(unit_vec: &[f32; N_AXES], d: &[i16; 3], inv_root: f32) -> [f32; N_AXES] {
    if inv_root.to_bits() != 0 {
        short_unit(&[d[0] as i32, d[1] as i32, d[2] as i32, 0], inv_root)
    } else {
        *unit_vec
    }
}

/// grbl's junction cosine as written: 0 − Σ prev·unit.
#[cfg(test)]
pub(super) fn cos_theta_plain(prev_unit: &[f32; N_AXES], unit: &[f32; N_AXES], moving: u8) -> f32 {
    let mut cos_theta = 0.0f32;
    for i in 0..N_AXES {
        if moving & (1 << i) != 0 && prev_unit[i].to_bits() != 0 {
            cos_theta -= prev_unit[i] * unit[i];
        }
    }
    cos_theta
}

/// What the junction rule derives from a cap L (the smaller nominal speed²
/// of two blocks), cached: L changes only with the feed. RAM: 28 B.
#[derive(Clone, Copy, Debug)]
pub(super) struct CapCache {
    /// Bits of L, with bit 31 set when the E axis takes part (L > 0, so
    /// its sign bit is free).
    key: u32,
    /// Bits of the smallest acceleration of the axes (mm/s², X Y Z, and E
    /// when it takes part) and of the junction deviation (mm) `h_min` is for.
    limits: (u32, u32),
    /// L², (mm/s)⁴.
    pub(super) cap_sqr: f32,
    /// sin²(θ/2) from which a junction reaches L even at the smallest
    /// acceleration: (L / (a_min·δ + L))². A path's acceleration is never
    /// below its slowest axis' (1 / max(|uᵢ| / aᵢ) ≥ min aᵢ).
    h_min: f32,
    /// Bits of the acceleration a (mm/s²) `k_sqr` is for (with this L and
    /// δ; a refill forgets it), and (a·δ + L)²: a stream's chords repeat
    /// a few accelerations in runs, and the exact test then costs one
    /// multiply instead of three and a sum (`k_sqr`).
    k_key: u32,
    k_sqr: f32,
}

impl CapCache {
    /// All zero (so it needs no RAM image). It only matches a cap of +0.0,
    /// where any junction is 0 whatever `h_min` says.
    pub(super) const EMPTY: CapCache = CapCache { key: 0, limits: (0, 0), cap_sqr: 0.0, h_min: 0.0, k_key: 0, k_sqr: 0.0 };

    /// `h_min` for `cap` (e_axis: 1 when the E axis takes part), from the
    /// cache when the cap and the settings are the ones it holds.
    // speed: inlined into `junction_sqr`, on the per-block path
    #[inline(always)]
    fn h_min(&mut self, cap: f32, e_axis: u32, s: &Settings) -> f32 {
        let mut a_min = min_nn(min_nn(s.accel_mm_per_s2[0], s.accel_mm_per_s2[1]), s.accel_mm_per_s2[2]);
        if e_axis != 0 {
            a_min = min_nn(a_min, s.accel_mm_per_s2[3]);
        }
        let key = cap.to_bits() | e_axis << 31;
        let limits = (a_min.to_bits(), s.junction_deviation_mm.to_bits());
        if self.key != key || self.limits != limits {
            self.key = key;
            self.limits = limits;
            self.refill(cap, a_min * s.junction_deviation_mm);
        }
        self.h_min
    }

    /// (a·δ + L)² for the acceleration `a` and `cap` (L, the cap `h_min`
    /// was asked for last), from the cache when `a` is the one it holds:
    /// the very product the exact test computed before the cache
    /// (`the_junction_threshold_cache_gives_the_plain_junction_rule`
    /// holds both caches to the plain rule).
    // speed: inlined into `junction_sqr`, on the per-block path
    #[inline(always)]
    fn k_sqr(&mut self, a: f32, cap: f32, s: &Settings) -> f32 {
        if self.k_key != a.to_bits() {
            self.k_key = a.to_bits();
            self.k_sqr = k_sqr(a, cap, s.junction_deviation_mm);
        }
        self.k_sqr
    }

    /// Recompute L² and `h_min` for `cap` (`ad_min`: the smallest a·δ, mm²/s²).
    // speed: a cold call, so that LLVM-AVR does not speculate the division
    #[inline(never)]
    fn refill(&mut self, cap: f32, ad_min: f32) {
        // Not an acceleration's bits (a NaN): `k_sqr` was for the old L.
        self.k_key = u32::MAX;
        let r = cap / (ad_min + cap);
        // Never straight on a cap of 0 or a non-finite ratio (settings not
        // yet valid): 2 is above any sin².
        self.h_min = if r.is_finite() && r > 0.0 { r * r } else { 2.0 };
        self.cap_sqr = cap * cap;
    }
}

/// (a·δ + L)², the exact junction test's factor ([`CapCache::k_sqr`]). A
/// cold call: behind the cache test LLVM-AVR would compute it every time.
// speed: see above
#[inline(never)]
fn k_sqr(a: f32, cap: f32, deviation_mm: f32) -> f32 {
    let k = a * deviation_mm + cap;
    k * k
}
