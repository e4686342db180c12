//! The user's coordinate frame and the internal one.
//!
//! Sits at the boundary between the user and the machine: the G-code
//! interpreter converts the words it reads with it, and every report (M114,
//! `?`, `[PRB:…]`, `[SETTER Z:…]`, M503's work offsets, the OLED) converts
//! what it prints.
//!
//! **Internal frame** (steps, planner, stepper, soft limits, the tool
//! changer's station and the tool setter's constants, the stored work
//! offsets and setter calibration, the virtual machine's physical model):
//! machine Z counts *downward* from the home switch at the top, 0 … +travel,
//! as the thesis machine measures it (docs/SPEC.md §3; Table 8: Z1 40.5, Z2 45).
//!
//! **User frame** (every G-code word, work and G53 machine coordinates, every
//! report): +Z is *up*, away from the work, as in RS274/NGC, LinuxCNC, grbl
//! and every CAM post. Home stays at the top switch, so machine Z runs
//! 0 … −travel (grbl's convention); the thesis's Z1 40.5 is machine Z −40.5.
//!
//! The two frames differ only in the sign of Z (X, Y and the carousel E are
//! the same numbers). These functions are the only place that flips it.
//! Mirroring Z also mirrors the G18 and G19 arc planes, which contain Z: a
//! clockwise arc there is counter-clockwise in the internal frame
//! ([`internal_clockwise`]).

/// Index of Z in a position array.
pub const Z: usize = 2;

/// `-v`, with zero always `+0.0` (never `-0.0`): a flip of the sign bit,
/// on the bit pattern. Written as `v == ±0.0 ? 0.0 : -v` (`flip_plain`, the
/// reference: `flip_matches_its_float_reference`), LLVM-AVR made the zero
/// test a soft-float compare (~50 cycles, on every Z word and report).
#[inline]
fn flip(v: f32) -> f32 {
    let b = v.to_bits() ^ 0x8000_0000;
    // Only +0.0 flips to the pattern 0x8000_0000 (−0.0 flips to +0.0).
    f32::from_bits(if b == 0x8000_0000 { 0 } else { b })
}

/// [`flip`] by a float test and negation: its reference.
#[cfg(test)]
fn flip_plain(v: f32) -> f32 {
    if v == 0.0 {
        0.0
    } else {
        -v
    }
}

/// One coordinate of `axis` (0 X … 3 E), user → internal.
#[inline]
pub fn axis_internal_from_user(axis: usize, v: f32) -> f32 {
    if axis == Z {
        flip(v)
    } else {
        v
    }
}

/// One coordinate of `axis` (0 X … 3 E), internal → user.
#[inline]
pub fn axis_user_from_internal(axis: usize, v: f32) -> f32 {
    axis_internal_from_user(axis, v)
}

/// A position (X, Y, Z[, E]), internal → user.
#[inline]
pub fn user_from_internal<const N: usize>(v: [f32; N]) -> [f32; N] {
    let mut u = v;
    u[Z] = flip(v[Z]);
    u
}

/// A position (X, Y, Z[, E]), user → internal.
#[inline]
pub fn internal_from_user<const N: usize>(v: [f32; N]) -> [f32; N] {
    user_from_internal(v)
}

/// A Z in whole units (steps, µm), internal → user.
#[inline]
pub fn z_user_from_internal_i32(z: i32) -> i32 {
    z.wrapping_neg()
}

/// Step counters (X, Y, Z, E), internal → user: Z counts up.
#[inline]
pub fn steps_user_from_internal<const N: usize>(s: [i32; N]) -> [i32; N] {
    let mut u = s;
    u[Z] = z_user_from_internal_i32(s[Z]);
    u
}

/// The internal turning sense of an arc the user programmed clockwise
/// (`cw`) in a plane that contains Z (`plane_has_z`: G18, G19) or not (G17):
/// mirroring Z reverses the sense in G18 and G19.
#[inline]
pub fn internal_clockwise(cw: bool, plane_has_z: bool) -> bool {
    cw != plane_has_z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_flips_and_nothing_else() {
        assert_eq!(user_from_internal([1.0, 2.0, 40.5, 4.0]), [1.0, 2.0, -40.5, 4.0]);
        assert_eq!(internal_from_user([1.0, 2.0, -45.0]), [1.0, 2.0, 45.0]);
        assert_eq!(axis_internal_from_user(0, 5.0), 5.0);
        assert_eq!(axis_internal_from_user(1, -5.0), -5.0);
        assert_eq!(axis_internal_from_user(2, 5.0), -5.0);
        assert_eq!(axis_user_from_internal(3, 5.0), 5.0);
        assert_eq!(steps_user_from_internal([100, 200, 300, 7]), [100, 200, -300, 7]);
        for v in [0.0f32, 1.0, -1.0, 45.0, 0.01, -123.456] {
            assert_eq!(internal_from_user(user_from_internal([0.0, 0.0, v]))[Z], v);
        }
    }

    #[test]
    fn flip_matches_its_float_reference() {
        let check = |b: u32| {
            let v = f32::from_bits(b);
            let (f, p) = (flip(v), flip_plain(v));
            // NaN: any NaN (no G-code word is one); else the same bits.
            assert!(f.to_bits() == p.to_bits() || (f.is_nan() && p.is_nan()), "{v:e} ({b:#x})");
        };
        for b in [0, 0x8000_0000, 1, 0x8000_0001, 0x7F80_0000, 0xFF80_0000, 0x3F80_0000, 0xBF80_0000, 0x7FFF_FFFF, 0xFFFF_FFFF] {
            check(b);
        }
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        for _ in 0..1_000_000 {
            check(rng.next());
        }
    }

    #[test]
    fn zero_stays_positive_zero() {
        assert_eq!(axis_internal_from_user(Z, 0.0).to_bits(), 0.0f32.to_bits());
        assert_eq!(axis_internal_from_user(Z, -0.0).to_bits(), 0.0f32.to_bits());
    }

    #[test]
    fn work_z_of_the_tip_is_machine_z_less_the_offset_and_the_tool_length() {
        // G54 at user machine Z −2 (stored internally as +2), a 3 mm tool
        // (G43), the spindle at user machine Z −8: the tip is at work Z
        // −8 − (−2) − 3 = −9, as LinuxCNC computes it.
        let mut i = crate::gcode::interp::Interp::new();
        i.wcs_mm[0] = internal_from_user([10.0, 5.0, -2.0]);
        i.tlo_mm = crate::atc::tool_length_offset_mm(3.0);
        let spindle = internal_from_user([13.0, 9.0, -8.0, 0.0]);
        assert_eq!(i.work_user(spindle), [3.0, 4.0, -9.0, 0.0]);
        // A longer tool's tip is lower.
        i.tlo_mm = crate::atc::tool_length_offset_mm(5.0);
        assert_eq!(i.work_user(spindle)[Z], -11.0);
    }

    #[test]
    fn arcs_in_planes_with_z_turn_the_other_way_internally() {
        assert!(internal_clockwise(true, false));
        assert!(!internal_clockwise(false, false));
        assert!(!internal_clockwise(true, true));
        assert!(internal_clockwise(false, true));
    }
}
