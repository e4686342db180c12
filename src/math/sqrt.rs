//! A square root by table, for speeds and short lengths: segment prep
//! takes a speed from a speed² for every block it starts (`v = √v²`), the
//! planner a chord's length from its steps, and avr-libc's `sqrt` costs
//! ~550 cycles on the AVR. [`sqrt_1ulp`] reads a knot, the rise to the
//! next one and a bow from a 1.5 KB table in flash and interpolates:
//! 119 cycles a call in the firmware's assembly (`board::sqrt`, 240
//! compiled from [`sqrt_1ulp_plain`]), within one unit in the last place of
//! the correctly rounded root (`sqrt_1ulp_is_within_one_ulp`: every float
//! of two octaves, and the exponents between; four in five are correctly
//! rounded), exact at the knots. Geometry that ends in positions (arcs,
//! cutter compensation, polar words) keeps [`super::sqrtf`].
//!
//! The argument's exponent parity and its top 7 mantissa bits pick the
//! knot: with u = 1.m in [1, 2) for an odd biased exponent and 2·1.m in
//! [2, 4) for an even one, √u lies in [1, 2), and knot i is √u at u = 1 +
//! i/128 (i < 128) or 2 + (i − 128)/64. Between two knots the root is the
//! chord plus a parabola through the midpoint (the bow; the root is
//! concave): r(t) = r₀ + t·(r₁ − r₀) + t·(1 − t)·bow, t the low 16 mantissa bits.
//! The result's exponent is half the argument's.

use super::mul_u16;

/// ⌊√n⌋ (Newton's method on integers), for the tables at compile time.
const fn isqrt(n: u128) -> u128 {
    if n < 2 {
        return n;
    }
    let mut x = n;
    let mut y = x.div_ceil(2);
    while y < x {
        x = y;
        y = (x + n / x) / 2;
    }
    x
}

/// √n rounded to the nearest integer.
const fn round_sqrt(n: u128) -> u128 {
    let q = isqrt(n);
    // (q + ½)² = q² + q + ¼: above it when n − q² > q.
    if n - q * q > q {
        q + 1
    } else {
        q
    }
}

/// u·2⁴⁶ at knot i, and at the midpoint after it, times 2^`extra`.
const fn knot_arg(i: usize, half: bool, extra: u32) -> u128 {
    let s = (i / 128) as u32;
    let j = (i % 128) as u128;
    if half {
        (256 + 2 * j + 1) << (38 + s + extra)
    } else {
        (128 + j) << (39 + s + extra)
    }
}

/// Knot i, √u·2²³ rounded (0 ≤ i ≤ 256).
const fn knot(i: usize) -> u32 {
    round_sqrt(knot_arg(i, false, 0)) as u32
}

/// The bow between knots i and i + 1: 4·(root − chord) at the midpoint,
/// units of 2⁻²³, from roots carried to 2⁻³¹.
const fn bow(i: usize) -> u8 {
    let r0 = round_sqrt(knot_arg(i, false, 16));
    let r1 = round_sqrt(knot_arg(i + 1, false, 16));
    let mid = round_sqrt(knot_arg(i, true, 16));
    ((4 * mid - 2 * (r0 + r1) + 128) / 256) as u8
}

/// The columns of [`SQRT_TABLE`].
const KNOT_LO: usize = 0;
const KNOT_MID: usize = 1;
const KNOT_HI: usize = 2;
const RISE_LO: usize = 3;
const RISE_HI: usize = 4;
const BOW: usize = 5;

/// Per interval i: its first knot less the leading 1 (2²³), three bytes;
/// the knots' difference (the rise, < 2¹⁶), two; the bow, one. Byte
/// columns, so each is one `lpm` at a constant base plus i. (The rise from
/// the next knot's columns instead: 512 B less flash, ~20 cycles more a
/// call.)
const fn table() -> [[u8; 256]; 6] {
    let mut t = [[0u8; 256]; 6];
    let mut i = 0;
    while i < 256 {
        let r0 = knot(i) - (1 << 23);
        let rise = knot(i + 1) - knot(i);
        t[KNOT_LO][i] = r0 as u8;
        t[KNOT_MID][i] = (r0 >> 8) as u8;
        t[KNOT_HI][i] = (r0 >> 16) as u8;
        t[RISE_LO][i] = rise as u8;
        t[RISE_HI][i] = (rise >> 8) as u8;
        t[BOW][i] = bow(i);
        i += 1;
    }
    t
}

crate::in_flash! {
    /// Read by [`sqrt_1ulp_plain`] and, on the AVR, `mill_sqrt_1ulp`
    /// (the firmware's `board::sqrt`), whose assembly steps through its
    /// columns 256 bytes apart.
    pub static SQRT_TABLE: [[u8; 256]; 6] = table();
}
const _: () = assert!(KNOT_LO == 0 && KNOT_MID == 1 && KNOT_HI == 2 && RISE_LO == 3 && RISE_HI == 4 && BOW == 5);

/// √x for a speed² (or any float): within one unit in the last place of
/// the correctly rounded root for a positive normal `x` (see the module
/// doc); anything else (±0, negative, subnormal, infinite, NaN) goes to
/// [`super::sqrtf`]. On the AVR [`sqrt_1ulp_plain`]'s steps in assembly
/// (`mill_sqrt_1ulp`, in the firmware's `board::sqrt`), bit for bit
/// (`tests/soft_float.rs`).
#[inline]
pub fn sqrt_1ulp(x: f32) -> f32 {
    #[cfg(target_arch = "avr")]
    {
        super::sqrt_1ulp_avr(x)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        sqrt_1ulp_plain(x)
    }
}

/// [`sqrt_1ulp`] in Rust: the host's, and the twin the AVR's assembly is
/// held to.
pub fn sqrt_1ulp_plain(x: f32) -> f32 {
    let b = x.to_bits();
    // Positive normal numbers: biased exponent 1..=254, sign clear.
    if b.wrapping_sub(0x0080_0000) >= 0x7F00_0000 {
        return super::sqrtf(x);
    }
    let top = (b >> 16) as u16;
    // The exponent's low bit is bit 7 of the third byte, the top mantissa
    // bits its other seven: interval i is that byte with bit 7 flipped.
    let i = top as u8 ^ 0x80;
    let t = b as u16;
    let r0 =
        (SQRT_TABLE.at(KNOT_HI, i) as u32) << 16 | ((SQRT_TABLE.at(KNOT_MID, i) as u16) << 8 | SQRT_TABLE.at(KNOT_LO, i) as u16) as u32;
    let rise = (SQRT_TABLE.at(RISE_HI, i) as u16) << 8 | SQRT_TABLE.at(RISE_LO, i) as u16;
    // The rise is < 2¹⁶ (the steepest, at u = 2: 46 341) and t·(1 − t) ≤
    // ¼, so the chord's rise and the bow's sag sum below 2³² in units of
    // 2⁻³⁹, rounded once.
    let tt = (mul_u16(t, 0u16.wrapping_sub(t)) >> 16) as u16;
    let up = mul_u16(rise, t) + mul_u16(SQRT_TABLE.at(BOW, i) as u16, tt) + 0x8000;
    // Half the exponent: (E + 127) / 2 biased, for the biased E; the
    // leading 1 of the root's mantissa carries into it.
    let e = ((top >> 7) + 127) >> 1;
    f32::from_bits((((e << 7) as u32) << 16) + r0 + (up >> 16))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two positive floats.
    fn ulps(a: f32, b: f32) -> u32 {
        a.to_bits().abs_diff(b.to_bits())
    }

    fn exact(x: f32) -> f32 {
        (x as f64).sqrt() as f32
    }

    #[test]
    fn sqrt_1ulp_is_within_one_ulp() {
        // Every float of the two octaves [1, 4): both exponent parities.
        let mut worst = 0;
        let mut off = 0u32;
        for bits in 1.0f32.to_bits()..4.0f32.to_bits() {
            let x = f32::from_bits(bits);
            let d = ulps(sqrt_1ulp(x), exact(x));
            worst = worst.max(d);
            off += (d != 0) as u32;
        }
        assert!(worst <= 1, "worst {worst} ulp");
        // Four in five are correctly rounded (3 419 382 of 2²⁴ are not).
        assert!(off < (1 << 24) / 4, "{off} of 2^24 not correctly rounded");
        // The exponents between: every 4099th float.
        for bits in (f32::MIN_POSITIVE.to_bits()..f32::MAX.to_bits()).step_by(4099) {
            let x = f32::from_bits(bits);
            assert!(ulps(sqrt_1ulp(x), exact(x)) <= 1, "{x}");
        }
    }

    #[test]
    fn sqrt_1ulp_is_exact_at_the_knots_and_near_at_the_edges() {
        // t = 0: the knot itself, rounded once.
        for i in 0..256u32 {
            // u = 1.m with the top 7 mantissa bits i % 128, doubled for i ≥ 128.
            let x = f32::from_bits((127 << 23) | (i % 128) << 16) * if i < 128 { 1.0 } else { 2.0 };
            assert_eq!(sqrt_1ulp(x), exact(x), "knot {i}");
        }
        for x in [100.0f32, 2500.0, 1e6, f32::MIN_POSITIVE, f32::MAX, 3.9999998] {
            assert!(ulps(sqrt_1ulp(x), exact(x)) <= 1, "{x}");
        }
        for v in 1..=3000u32 {
            let v = v as f32;
            assert!(ulps(sqrt_1ulp(v * v), v) <= 1, "{v}²");
        }
    }

    #[test]
    fn sqrt_1ulp_leaves_the_odd_cases_to_sqrtf() {
        assert_eq!(sqrt_1ulp(0.0).to_bits(), 0.0f32.to_bits());
        assert_eq!(sqrt_1ulp(-0.0).to_bits(), (-0.0f32).to_bits());
        assert!(sqrt_1ulp(-1.0).is_nan());
        assert!(sqrt_1ulp(f32::NAN).is_nan());
        assert_eq!(sqrt_1ulp(f32::INFINITY), f32::INFINITY);
        let sub = f32::from_bits(1);
        assert_eq!(sqrt_1ulp(sub), crate::math::sqrtf(sub));
    }
}
