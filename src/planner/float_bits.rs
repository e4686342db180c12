//! Float shortcuts on bit patterns for the planner's hot paths: compare, take
//! the larger or smaller of, and double or halve non-negative floats, and
//! take |x|, without a soft-float call on the AVR.

/// `a < b` for finite `a`, `b` ≥ +0.0. Non-negative IEEE-754 floats order like
/// their bit patterns, so this is a 10-cycle u32 compare on the AVR instead of
/// a ~60-cycle soft-float call. Every speed², acceleration, distance and time
/// the planner compares is ≥ +0.0 by construction (squares, sums of
/// non-negative terms, clamped distances), never −0.0 or NaN.
pub(crate) fn lt_nn(a: f32, b: f32) -> bool {
    debug_assert!(a.is_sign_positive() && b.is_sign_positive() && !a.is_nan() && !b.is_nan());
    a.to_bits() < b.to_bits()
}

/// The larger of two finite floats ≥ +0.0 (see `lt_nn`).
pub(super) fn max_nn(a: f32, b: f32) -> f32 {
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
pub(super) fn abs_f32(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & 0x7FFF_FFFF)
}

/// 2·x for a finite x ≥ +0.0, exactly, by adding one to the exponent (a
/// ~145-cycle soft-float multiply on the AVR otherwise). Zero, subnormals
/// and values near the top of the range take the multiply.
pub(super) fn times2(x: f32) -> f32 {
    let b = x.to_bits();
    if (0x0080_0000..0x7F00_0000).contains(&b) {
        f32::from_bits(b + 0x0080_0000)
    } else {
        2.0 * x
    }
}

/// x / 2 for a finite x ≥ +0.0, exactly while x/2 is a normal number (by
/// subtracting one from the exponent); smaller values take the multiply.
// speed: LLVM makes it a call from the inlined `junction_sqr` otherwise
#[inline(always)]
pub(super) fn half(x: f32) -> f32 {
    let b = x.to_bits();
    if b >= 0x0100_0000 {
        f32::from_bits(b - 0x0080_0000)
    } else {
        0.5 * x
    }
}
