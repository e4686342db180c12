//! Numbers of a line into the interpreter's units: inches to mm, an axis
//! word into the internal frame (+Z down, [`crate::frame`]), degrees to
//! radians, mm to steps, and the bit-pattern float helpers that spare the
//! AVR a soft-float compare or addition.

use crate::frame;
use crate::math::round_i32;

/// Millimetres per inch.
const MM_PER_INCH: f32 = 25.4;

/// `v` in mm: × 25.4 under G20. The multiply is a call only made under
/// G20: LLVM-AVR turned `if inches { v * 25.4 } else { v }` into a select
/// that multiplied every axis word (~145 cycles each) in millimetres too.
#[inline]
pub(super) fn to_mm(inches: bool, v: f32) -> f32 {
    if inches {
        inch_to_mm(v)
    } else {
        v
    }
}

/// An axis word's value (`axis` 0 X, 1 Y, 2 Z) in internal mm: inches
/// converted, Z mirrored from the user's +Z up into the internal frame
/// (see [`crate::frame`]). Offsets, G92, G53 and increments all follow.
// speed: with `axis` a constant the Z test folds; as a call ~140 cycles a word
#[inline(always)]
pub(super) fn word_mm(inches: bool, axis: usize, v: f32) -> f32 {
    frame::axis_internal_from_user(axis, to_mm(inches, v))
}

/// `v` × 25.4, as a call (see [`to_mm`]).
// speed: the × 25.4 stays a call made only under G20 (see to_mm)
#[inline(never)]
fn inch_to_mm(v: f32) -> f32 {
    v * MM_PER_INCH
}

/// Degrees → radians.
pub(super) fn deg_to_rad(deg: f32) -> f32 {
    deg * (core::f32::consts::PI / 180.0)
}

/// `round(mm · steps_per_mm)`.
pub(super) fn to_steps(mm: f32, steps_per_mm: f32) -> i32 {
    round_i32(mm * steps_per_mm)
}

/// `a == b` for finite floats (+0.0 equals −0.0), on the bit patterns: a
/// soft-float compare costs ~50 cycles on the AVR.
#[inline]
pub fn same_f32(a: f32, b: f32) -> bool {
    let (a, b) = (a.to_bits(), b.to_bits());
    a == b || (a | b) & 0x7FFF_FFFF == 0
}

/// `a + b`, without the ~90-cycle soft-float addition when `b` is +0.0 (no
/// offset): `a + 0.0 == a` for every `a` but −0.0, which the parser never
/// gives.
#[inline]
pub(super) fn add_nz(a: f32, b: f32) -> f32 {
    if b.to_bits() == 0 {
        a
    } else {
        add_cold(a, b)
    }
}

/// `a + b`, as a call: LLVM-AVR would otherwise turn [`add_nz`]'s branch
/// into a select that always adds (see `math::div_cold`).
// speed: the addition stays a call made only for a non-zero offset (see add_nz)
#[inline(never)]
fn add_cold(a: f32, b: f32) -> f32 {
    a + b
}
