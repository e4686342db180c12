//! Float helpers that pick the fast implementation per target.
//!
//! On AVR, `sqrt` comes from avr-libc's hand-written assembly (linked through
//! `-lm` in `avr-atmega2560.json`); `libm`'s generic version would put a
//! 256-byte table in RAM. On the host the same functions use `libm`.

/// Square root of `x` (f32).
#[inline]
pub fn sqrtf(x: f32) -> f32 {
    #[cfg(target_arch = "avr")]
    {
        extern "C" {
            // avr-libc: `double` is 32 bits wide, so this is an f32 sqrt.
            fn sqrt(x: f32) -> f32;
        }
        // SAFETY: avr-libc's sqrt is a pure function with no preconditions.
        unsafe { sqrt(x) }
    }
    #[cfg(not(target_arch = "avr"))]
    {
        libm::sqrtf(x)
    }
}

/// Absolute value of `x`.
#[inline]
pub fn fabsf(x: f32) -> f32 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

/// Round to nearest, halves away from zero, as an i32 (saturating).
#[inline]
pub fn round_i32(x: f32) -> i32 {
    if x >= 2_147_483_520.0 {
        i32::MAX
    } else if x <= -2_147_483_520.0 {
        i32::MIN
    } else if x >= 0.0 {
        (x + 0.5) as i32
    } else {
        (x - 0.5) as i32
    }
}

/// Sine and cosine for arc chords. On AVR these are avr-libc's assembly
/// routines (tables in flash); `libm`'s argument reduction would put a
/// 264-byte table and 64 bytes of constants in RAM.
#[inline]
pub fn sincosf(x: f32) -> (f32, f32) {
    #[cfg(target_arch = "avr")]
    {
        extern "C" {
            // avr-libc: `double` is 32 bits wide.
            fn sin(x: f32) -> f32;
            fn cos(x: f32) -> f32;
        }
        // SAFETY: pure avr-libc functions with no preconditions.
        unsafe { (sin(x), cos(x)) }
    }
    #[cfg(not(target_arch = "avr"))]
    {
        libm::sincosf(x)
    }
}

/// atan2 for arc angles (avr-libc's on AVR, as for [`sincosf`]).
#[inline]
pub fn atan2f(y: f32, x: f32) -> f32 {
    #[cfg(target_arch = "avr")]
    {
        extern "C" {
            fn atan2(y: f32, x: f32) -> f32;
        }
        // SAFETY: pure avr-libc function with no preconditions.
        unsafe { atan2(y, x) }
    }
    #[cfg(not(target_arch = "avr"))]
    {
        libm::atan2f(y, x)
    }
}
