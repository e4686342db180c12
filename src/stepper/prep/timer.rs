//! From time to the timer: the CPU cycles per step event of a segment
//! ([`per_tick`], a multiply by 1/n for the usual few ticks) and the
//! Timer1 period and prescaler for them ([`timer_for`]).

use crate::stepper::{Prescale, MIN_PERIOD_CYCLES};

/// ⌈x⌉ for 0 ≤ x < 2³².
#[inline]
pub(super) fn ceil_u32(x: f32) -> u32 {
    if x <= 0.0 {
        return 0;
    }
    let t = x as u32;
    if (t as f32) < x {
        t + 1
    } else {
        t
    }
}

/// `cycles / n`: the CPU cycles per step event of a segment of `n` ticks.
/// A 0.1 mm block makes at most ~10 ticks (100 steps/mm), so for small n
/// this multiplies by 1/n ([`crate::math::recip_small`]: ~140 cycles on the
/// AVR instead of a ~540-cycle division; within an ulp of it, far below the
/// timer count the period is rounded to).
// speed: as a call ~50 cycles a block (profile 18 366 -> 18 313 cycles a line, ~140 B of flash)
#[inline(always)]
pub(super) fn per_tick(cycles: f32, n: u32) -> f32 {
    match crate::math::recip_small(n) {
        Some(r) => cycles * r,
        None => crate::math::div_cold(cycles, n as f32),
    }
}

/// Timer setting for `cycles` CPU cycles per step event. Rounds up (by up to
/// one timer count), so a segment is never faster than planned.
pub(super) fn timer_for(cycles: f32) -> (u16, Prescale) {
    // Huge, negative or NaN values end at the slowest setting. The range test
    // is on the bit pattern: a saturating `as` costs three soft-float compares.
    let b = cycles.to_bits();
    let c = if b < 0x4B00_0000 {
        // SAFETY: 0 ≤ cycles < 2²³ (positive, exponent below 23): in range.
        (unsafe { cycles.to_int_unchecked::<u32>() }) + 1
    } else {
        u32::MAX // ≥ 2²³ cycles, negative or NaN: the slowest setting
    };
    if c <= 65535 {
        let p = c as u16;
        (if p < MIN_PERIOD_CYCLES { MIN_PERIOD_CYCLES } else { p }, Prescale::Div1)
    } else if c <= 8 * 65535 {
        (((c + 7) >> 3) as u16, Prescale::Div8)
    } else {
        (65535, Prescale::Div8)
    }
}

#[cfg(test)]
mod tests {
    use super::per_tick;

    #[test]
    fn per_tick_is_the_division_within_an_ulp() {
        let mut x = 1.0f32;
        for _ in 0..2000 {
            x = x * 1.37 % 800_000.0 + 31.0;
            for n in 1..=20u32 {
                let (got, want) = (per_tick(x, n), x / n as f32);
                let ulps = (got.to_bits() as i64 - want.to_bits() as i64).abs();
                assert!(ulps <= 1, "{x} / {n}: {got} vs {want}");
            }
        }
    }
}
