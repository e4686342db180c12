//! Float shortcuts on bit patterns for the planner's and segment prep's
//! hot paths: compare, take the larger or smaller of non-negative floats,
//! double or halve any float exactly, and take |x|, without a soft-float
//! call on the AVR.

/// `a < b` for finite `a`, `b` ≥ +0.0. Non-negative IEEE-754 floats order like
/// their bit patterns, so this is a 10-cycle u32 compare on the AVR instead of
/// a ~60-cycle soft-float call. Every speed², acceleration, distance and time
/// the planner compares is ≥ +0.0 by construction (squares, sums of
/// non-negative terms, clamped distances), never −0.0 or NaN.
pub(crate) fn lt_nn(a: f32, b: f32) -> bool {
    debug_assert!(a.is_sign_positive() && b.is_sign_positive() && !a.is_nan() && !b.is_nan());
    a.to_bits() < b.to_bits()
}

/// `v > 0.0`, on the bit pattern (sign clear, not +0.0, not a NaN): the
/// soft-float compare costs ~50 cycles on the AVR. Exact for every input
/// (`positive_matches_the_float_compare`).
#[inline(always)]
pub(crate) fn positive(v: f32) -> bool {
    let b = v.to_bits();
    b as i32 > 0 && b <= 0x7F80_0000
}

/// `a < b` for a `b` > +0.0 that is no NaN, and any `a` but a NaN with its
/// sign bit set: the bit patterns compared as signed integers (a negative
/// `a`, −0.0 included, is below every positive `b`; positive floats order
/// like their bits). `lt_of_positive_matches_the_float_compare`.
#[inline(always)]
pub(crate) fn lt_of_positive(a: f32, b: f32) -> bool {
    debug_assert!(positive(b) && !(a.is_nan() && a.is_sign_negative()));
    (a.to_bits() as i32) < (b.to_bits() as i32)
}

/// The larger of two finite floats ≥ +0.0 (see `lt_nn`).
pub(crate) fn max_nn(a: f32, b: f32) -> f32 {
    if lt_nn(a, b) {
        b
    } else {
        a
    }
}

/// The smaller of two finite floats ≥ +0.0 (see `lt_nn`).
pub(crate) fn min_nn(a: f32, b: f32) -> f32 {
    if lt_nn(a, b) {
        a
    } else {
        b
    }
}

/// |x| by clearing the sign bit (no soft-float compare).
// speed: left to LLVM (with rings' `seg_cycles` and `SlotSink`), ping-pong took 5.754 s, not 5.739
#[inline(always)]
pub(crate) fn abs_f32(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & 0x7FFF_FFFF)
}

/// 2·x exactly, by adding one to the exponent of a normal x below 2¹²⁶
/// (a ~145-cycle soft-float multiply on the AVR otherwise); ±0 is itself;
/// other values take the multiply.
// speed: a call cost ~37 cycles a use (profile --count 254 --feed 12000 --accel 5000 --trace 300:1500 18 489 -> 18 419 cycles a line, ~270 B of flash)
#[inline(always)]
pub(crate) fn times2(x: f32) -> f32 {
    let e = x.to_bits() & 0x7F80_0000;
    if e != 0 && e < 0x7E80_0000 {
        f32::from_bits(x.to_bits() + 0x0080_0000)
    } else if x.to_bits() << 1 == 0 {
        x
    } else {
        2.0 * x
    }
}

/// x / 2 exactly, by taking one from the exponent of a normal x whose half
/// is normal too (a soft-float multiply on the AVR otherwise); other values
/// take the multiply.
// speed: LLVM makes it a call from the inlined `junction_sqr` otherwise
#[inline(always)]
pub(crate) fn half(x: f32) -> f32 {
    let e = x.to_bits() & 0x7F80_0000;
    if e > 0x0080_0000 && e != 0x7F80_0000 {
        f32::from_bits(x.to_bits() - 0x0080_0000)
    } else {
        // A call: LLVM-AVR ran the multiply on every call otherwise.
        crate::math::mul_cold(0.5, x)
    }
}

#[cfg(test)]
mod tests {
    use super::{half, lt_of_positive, positive, times2};

    /// `fast` against the multiply it replaces, bit for bit, on random bit
    /// patterns (every class: normal, subnormal, zero, infinite, NaN) and on
    /// the edge cases `special`.
    fn same_bits(fast: fn(f32) -> f32, plain: fn(f32) -> f32, seed: u32, special: &[f32]) {
        let mut b = seed;
        for _ in 0..200_000 {
            b = b.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let x = f32::from_bits(b);
            let (got, want) = (fast(x), plain(x));
            assert!(got.to_bits() == want.to_bits() || (x.is_nan() && got.is_nan()), "{x:e}: {got:e} vs {want:e}");
        }
        for &x in special {
            assert_eq!(fast(x).to_bits(), plain(x).to_bits(), "{x:e}");
        }
    }

    #[test]
    fn half_is_the_multiply_bit_for_bit() {
        let m = f32::MIN_POSITIVE;
        let special = [0.0f32, -0.0, m, 2.0 * m, 3.0 * m, 1e-45, f32::MAX, -f32::MAX, f32::INFINITY, -f32::INFINITY];
        same_bits(half, |x| 0.5 * x, 7, &special);
    }

    #[test]
    fn times2_is_the_multiply_bit_for_bit() {
        let special = [0.0f32, -0.0, f32::MIN_POSITIVE, 1e-45, f32::MAX, -f32::MAX, 1.7e38, f32::INFINITY];
        same_bits(times2, |x| 2.0 * x, 1, &special);
    }

    #[test]
    fn positive_matches_the_float_compare() {
        let check = |b: u32| assert_eq!(positive(f32::from_bits(b)), f32::from_bits(b) > 0.0, "{b:#x}");
        // The edges: ±0, the smallest subnormals, ±infinity, the NaNs.
        for b in [0, 1, 0x7F7F_FFFF, 0x7F80_0000, 0x7F80_0001, 0x7FC0_0000, 0x7FFF_FFFF, 0x8000_0000, 0xFFFF_FFFF] {
            check(b);
            check(b ^ 0x8000_0000);
        }
        // Every pattern with its low 12 bits fixed: all signs and exponents.
        for hi in 0..0x10_0000u32 {
            check(hi << 12 | 0x5A5);
            check(hi << 12);
        }
    }

    #[test]
    fn lt_of_positive_matches_the_float_compare() {
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        let mut next = move || rng.next();
        let edges =
            [0u32, 1, 0x0080_0000, 0x3F80_0000, 0x7F7F_FFFF, 0x7F80_0000, 0x7FC0_0000, 0x8000_0000, 0x8000_0001, 0xBF80_0000, 0xFF80_0000];
        let mut checked = 0;
        for i in 0..2_000_000u32 {
            let a = if i % 7 == 0 { edges[(i / 7) as usize % edges.len()] } else { next() };
            let b = if i % 5 == 0 { edges[(i / 5) as usize % edges.len()] } else { next() & 0x7FFF_FFFF };
            let (fa, fb) = (f32::from_bits(a), f32::from_bits(b));
            if !positive(fb) || (fa.is_nan() && fa.is_sign_negative()) {
                continue;
            }
            assert_eq!(lt_of_positive(fa, fb), fa < fb, "{a:#x} < {b:#x}");
            checked += 1;
        }
        assert!(checked > 1_000_000, "{checked}");
    }
}
