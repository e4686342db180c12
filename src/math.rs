//! Arithmetic that picks the fast implementation per target: the one place
//! outside `board/` for cycle tricks (inline assembly included; `tools/test`
//! fails on an `asm!` anywhere else). Each AVR version sits next to its
//! plain host twin, which is what the host tests run; the simavr tests run
//! the AVR versions through the parser, planner and prep.
//!
//! On AVR, `sqrt` comes from avr-libc's hand-written assembly (linked through
//! `-lm` in `avr-atmega2560.json`); `libm`'s generic version would put a
//! 256-byte table in RAM. On the host the same functions use `libm`.

pub mod decimal;
pub mod float_bits;
mod sqrt;
pub use sqrt::{sqrt_1ulp, sqrt_1ulp_plain, SQRT_TABLE};

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

/// Round to nearest, halves away from zero, as an i32 (saturating; NaN → 0):
/// `x ± 0.5` in f32, truncated (so the f32 addition's own rounding shows:
/// 0.49999997 gives 1, as it always did). Worked out on the bit pattern
/// with integer shifts, no soft-float addition or conversion
/// (`round_i32_plain`, the reference: `round_i32_matches_its_float_reference`).
/// On the AVR the usual case (|x| below 2²³) is assembly, a call: ~60
/// cycles instead of ~200 for the compiled shifts (`tests/soft_float.rs`
/// calls it in the real ELF against this twin).
#[inline]
pub fn round_i32(x: f32) -> i32 {
    #[cfg(target_arch = "avr")]
    {
        round_i32_avr(x)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        round_i32_bits(x)
    }
}

/// [`round_i32`] on the AVR: for 0.5 ≤ |x| < 2²³ (the biased exponent
/// 126..=149) the twin's own steps in assembly: the significand shifted
/// right by 149 − exponent, whole bytes first, then t → (t + 1) >> 1 and
/// the sign; [`round_i32_bits`] for the rest. A function of its own, so
/// that the test can call it by name.
#[cfg(target_arch = "avr")]
#[export_name = "mill_round_i32"]
#[inline(never)]
extern "C" fn round_i32_avr(x: f32) -> i32 {
    let b = x.to_bits();
    let (mut lo, mut hi) = (b as u16, (b >> 16) as u16);
    let ok: u8;
    // SAFETY: register arithmetic only (T is SREG's, which asm may change).
    unsafe {
        core::arch::asm!(
            "mov {e}, {hi:l}",
            "lsl {e}",
            "mov {e}, {hi:h}",
            "rol {e}", // the biased exponent
            "ldi {ok}, 0",
            "subi {e}, 126",
            "cpi {e}, 24",
            "brsh 9f",
            "bst {hi:h}, 7", // T: the sign
            "ldi {s}, 0x80",
            "or {hi:l}, {s}", // the hidden bit
            "clr {hi:h}",
            "ldi {s}, 23",
            "sub {s}, {e}", // the shift, 0..=23
            "cpi {s}, 16",
            "brlo 1f",
            "mov {lo:l}, {hi:l}",
            "clr {lo:h}",
            "clr {hi:l}",
            "subi {s}, 16",
            "rjmp 2f",
            "1: cpi {s}, 8",
            "brlo 2f",
            "mov {lo:l}, {lo:h}",
            "mov {lo:h}, {hi:l}",
            "clr {hi:l}",
            "subi {s}, 8",
            "2: subi {s}, 1",
            "brcs 3f",
            "lsr {hi:l}",
            "ror {lo:h}",
            "ror {lo:l}",
            "rjmp 2b",
            "3: sec", // (t + 1) >> 1
            "adc {lo:l}, r1",
            "adc {lo:h}, r1",
            "adc {hi:l}, r1",
            "adc {hi:h}, r1",
            "lsr {hi:h}",
            "ror {hi:l}",
            "ror {lo:h}",
            "ror {lo:l}",
            "brtc 4f",
            "com {lo:l}", // − r
            "com {lo:h}",
            "com {hi:l}",
            "com {hi:h}",
            "sec",
            "adc {lo:l}, r1",
            "adc {lo:h}, r1",
            "adc {hi:l}, r1",
            "adc {hi:h}, r1",
            "4: ldi {ok}, 1",
            "9:",
            lo = inout(reg_pair) lo,
            hi = inout(reg_pair) hi,
            e = out(reg_upper) _,
            s = out(reg_upper) _,
            ok = out(reg_upper) ok,
            options(pure, nomem, nostack),
        );
    }
    if ok == 0 {
        return round_i32_cold(x);
    }
    ((hi as u32) << 16 | lo as u32) as i32
}

/// [`round_i32_bits`] as a call, for the rare cases of `round_i32_avr`.
#[cfg(target_arch = "avr")]
#[inline(never)]
fn round_i32_cold(x: f32) -> i32 {
    round_i32_bits(x)
}

/// [`round_i32`] in Rust: the host's, the AVR's rare cases, and the twin
/// of the AVR's assembly.
#[cfg_attr(target_arch = "avr", inline(always))]
pub fn round_i32_bits(x: f32) -> i32 {
    let b = x.to_bits();
    let mag = b & 0x7FFF_FFFF;
    if mag > 0x7F80_0000 {
        return 0; // NaN
    }
    if mag >= 0x4EFF_FFFF {
        return if b & 0x8000_0000 != 0 { i32::MIN } else { i32::MAX };
    }
    let ex = (mag >> 23) as i16 - 127;
    let sig = (mag & 0x7F_FFFF) | 0x80_0000;
    let r = if ex < -1 {
        // |x| < 0.5: |x| + 0.5 rounds up to 1.0 only from 0.5 − 2^−25.
        (mag == 0x3EFF_FFFF) as u32
    } else if ex >= 24 {
        // An integer that adding 0.5 leaves alone (half an ulp or less).
        sig << (ex - 23) as u32
    } else if ex == 23 {
        // The sum is a tie between two integers: the even one.
        sig + (sig & 1)
    } else {
        // sh = 23 − ex fraction bits (1..=24): the sum in those units,
        // truncated.
        // (sig + 2^(sh−1)) >> sh is (t + 1) >> 1 with t = sig >> (sh − 1).
        // When the sum carries into a 25th bit, f32 rounds away its last
        // bit, which changes nothing above bit sh − 1 (the sum is then
        // below 2^24 + 2^(sh−1)).
        let t = shr_u32(sig, (22 - ex) as u8);
        (t + 1) >> 1
    };
    if b & 0x8000_0000 != 0 {
        -(r as i32)
    } else {
        r as i32
    }
}

/// `v >> n` for `n` ≤ 31, whole bytes first: on the AVR a variable 32-bit
/// shift is a loop of one bit per turn.
#[inline(always)]
fn shr_u32(mut v: u32, mut n: u8) -> u32 {
    while n >= 8 {
        v >>= 8;
        n -= 8;
    }
    v >> n
}

/// [`round_i32`] by soft-float: its reference.
#[cfg(test)]
pub fn round_i32_plain(x: f32) -> i32 {
    let b = x.to_bits();
    let mag = b & 0x7FFF_FFFF;
    if mag > 0x7F80_0000 {
        0 // NaN
    } else if mag >= 0x4EFF_FFFF {
        // |x| ≥ 2147483520, the largest f32 below 2³¹.
        if b & 0x8000_0000 != 0 {
            i32::MIN
        } else {
            i32::MAX
        }
    } else if b & 0x8000_0000 == 0 {
        // SAFETY: 0 ≤ x + 0.5 < 2³¹ (checked above): in range, not NaN. The
        // saturating `as` would add three soft-float compares (~300 cycles).
        unsafe { (x + 0.5).to_int_unchecked::<i32>() }
    } else {
        // SAFETY: −2³¹ < x − 0.5 ≤ 0, as above.
        unsafe { (x - 0.5).to_int_unchecked::<i32>() }
    }
}

/// `a / b`, never computed speculatively. LLVM's AVR backend turns
/// `if cache_miss { cache = a / b }` into a select that runs the ~500-cycle
/// soft-float division on every call; a call it cannot speculate. Use it for
/// divisions behind a cache check.
// speed: LLVM inlines it otherwise, and then speculates the division (above)
#[inline(never)]
pub fn div_cold(a: f32, b: f32) -> f32 {
    a / b
}

/// `a · b`, never computed speculatively: [`div_cold`] for a multiply
/// (~120 cycles on the AVR) behind a test.
// speed: LLVM inlines it otherwise, and then speculates the multiply (div_cold)
#[inline(never)]
pub fn mul_cold(a: f32, b: f32) -> f32 {
    a * b
}

in_flash! {
    /// 1/n for n = 1..=16 (entry 0 unused), in flash on the AVR (a RAM table
    /// would take 68 bytes of the 8 KiB; a `match` of constants took 270
    /// bytes of flash for 12 entries).
    static RECIPROCALS: [f32; 17] = {
        let mut t = [0.0f32; 17];
        let mut i = 1;
        while i < 17 {
            t[i] = 1.0 / i as f32;
            i += 1;
        }
        t
    };
}

/// 1/n, correctly rounded, for 1 ≤ n ≤ 16 (a flash read: the small step
/// counts of short moves and segments); `None` otherwise.
// speed: as a call ~47 cycles a use (profile 18 419 -> 18 366 cycles a line, and 32 B less flash)
#[inline(always)]
pub fn recip_small(n: u32) -> Option<f32> {
    if n == 0 {
        None
    } else {
        RECIPROCALS.row(n as usize)
    }
}

/// [`sqrt_1ulp`] on the AVR: [`sqrt_1ulp_plain`]'s steps in assembly
/// (`mill_sqrt_1ulp`, in the firmware's `board::sqrt`).
#[cfg(target_arch = "avr")]
#[inline(always)]
fn sqrt_1ulp_avr(x: f32) -> f32 {
    extern "C" {
        fn mill_sqrt_1ulp(x: f32) -> f32;
    }
    // SAFETY: a pure function of its argument (it reads only the table in
    // flash), with the C calling convention of avr-gcc: x and the result
    // in r22–r25, only call-clobbered registers changed (r16 and r17 are
    // saved), r1 zero again at the return.
    unsafe { mill_sqrt_1ulp(x) }
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

/// `m · 10 + d` (no overflow: the callers keep it within `u32`; the number
/// lexer in `gcode::parse` keeps `m` below 10⁸, [`div10`] below 2³²/10).
#[cfg(not(target_arch = "avr"))]
pub fn times10_plus(m: u32, d: u8) -> u32 {
    m * 10 + d as u32
}

/// `m · 10 + d` (no overflow: the callers keep it within `u32`), as
/// (4m + m)·2 + d in 24 single-cycle instructions: LLVM-AVR turns any form
/// of `m * 10` it can see through into a call to the ~90-cycle `__mulsi3`.
/// `m` goes in and out as two register pairs: as four bytes, LLVM spent
/// ~30 more instructions putting the `u32` back together.
#[cfg(target_arch = "avr")]
pub fn times10_plus(m: u32, d: u8) -> u32 {
    let (mut lo, mut hi) = (m as u16, (m >> 16) as u16);
    // SAFETY: register arithmetic only; r1 is LLVM-AVR's zero register.
    unsafe {
        core::arch::asm!(
            "movw {tl}, {lo}", "movw {th}, {hi}",
            "lsl {lo:l}", "rol {lo:h}", "rol {hi:l}", "rol {hi:h}",
            "lsl {lo:l}", "rol {lo:h}", "rol {hi:l}", "rol {hi:h}",
            "add {lo:l}, {tl:l}", "adc {lo:h}, {tl:h}", "adc {hi:l}, {th:l}", "adc {hi:h}, {th:h}",
            "lsl {lo:l}", "rol {lo:h}", "rol {hi:l}", "rol {hi:h}",
            "add {lo:l}, {d}", "adc {lo:h}, r1", "adc {hi:l}, r1", "adc {hi:h}, r1",
            lo = inout(reg_pair) lo,
            hi = inout(reg_pair) hi,
            tl = out(reg_pair) _,
            th = out(reg_pair) _,
            d = in(reg) d,
            options(pure, nomem, nostack),
        );
    }
    (hi as u32) << 16 | lo as u32
}

/// `a · b`, the full 32-bit product of two 16-bit factors. On the AVR four
/// hardware `mul`s (~20 cycles): LLVM-AVR calls the 32 × 32-bit `__mulsi3`
/// (~86 cycles) even when both factors are zero-extended `u16`s.
#[cfg(target_arch = "avr")]
pub fn mul_u16(a: u16, b: u16) -> u32 {
    let (lo, hi): (u16, u16);
    // SAFETY: register arithmetic only. `mul` writes r1:r0 (r0 is LLVM-AVR's
    // scratch register); r1, its zero register, is cleared again at the end.
    unsafe {
        core::arch::asm!(
            "mul {a:l}, {b:l}",
            "movw {lo}, r0",
            "mul {a:h}, {b:h}",
            "movw {hi}, r0",
            "eor {z}, {z}",
            "mul {a:l}, {b:h}",
            "add {lo:h}, r0",
            "adc {hi:l}, r1",
            "adc {hi:h}, {z}",
            "mul {a:h}, {b:l}",
            "add {lo:h}, r0",
            "adc {hi:l}, r1",
            "adc {hi:h}, {z}",
            "eor r1, r1",
            a = in(reg_pair) a,
            b = in(reg_pair) b,
            lo = out(reg_pair) lo,
            hi = out(reg_pair) hi,
            z = out(reg) _,
            options(pure, nomem, nostack),
        );
    }
    (hi as u32) << 16 | lo as u32
}

/// `a · b`, the full 32-bit product of two 16-bit factors.
#[cfg(not(target_arch = "avr"))]
pub fn mul_u16(a: u16, b: u16) -> u32 {
    a as u32 * b as u32
}

/// `*dst = *src` for a 16-byte value (a move's four axes). On the AVR 16
/// `ld`/`st` pairs in line, ~70 cycles: at opt-level "z" LLVM-AVR calls
/// `memcpy` for it, ~120 cycles with the call and its loop.
// speed: a call otherwise (doc above)
#[inline(always)]
pub fn copy16<T: Copy>(dst: &mut T, src: &T) {
    const { assert!(core::mem::size_of::<T>() == 16) };
    #[cfg(target_arch = "avr")]
    // SAFETY: reads the 16 bytes of `*src` and writes the 16 bytes of
    // `*dst`, two valid references to values of one `Copy` type of that
    // size (asserted above); they cannot overlap (`&mut`).
    unsafe {
        core::arch::asm!(
            ".rept 16",
            "ld {t}, Z+",
            "st X+, {t}",
            ".endr",
            inout("Z") src as *const T => _,
            inout("X") dst as *mut T => _,
            t = out(reg) _,
            options(nostack),
        );
    }
    #[cfg(not(target_arch = "avr"))]
    {
        *dst = *src;
    }
}

/// `(v / 10, v % 10)` by shifts and adds (Hacker's Delight, `divu10`):
/// LLVM-AVR calls `__udivmodsi4` for a `u32` division by a constant,
/// ~600 cycles; this is ~100. Exact for every `u32` (`div10_is_exact`).
// speed: LLVM makes it a call (in the number lexer and formatters) otherwise
#[inline(always)]
pub fn div10(v: u32) -> (u32, u8) {
    let mut q = (v >> 1) + (v >> 2);
    q += q >> 4;
    q += q >> 8;
    q += q >> 16;
    q >>= 3;
    // v − 10q is in 0..20: one correction step. (10q by `times10_plus`:
    // LLVM-AVR turns `(q << 2) + q) << 1` back into a `__mulsi3` call,
    // which also made this the deepest call of the OLED status row.)
    let r = (v - times10_plus(q, 0)) as u8;
    if r > 9 {
        (q + 1, r - 10)
    } else {
        (q, r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_i32_matches_its_float_reference() {
        let check = |b: u32| {
            let x = f32::from_bits(b);
            assert_eq!(round_i32(x), round_i32_plain(x), "{x:e} ({b:#x})");
        };
        // Every float in the binades around ±0.5 .. ±2^25, and edges.
        for e in 100u32..=160 {
            for m in (0..0x80_0000).step_by(97).chain(0..64).chain(0x7F_FFC0..0x80_0000) {
                check(e << 23 | m);
                check(0x8000_0000 | e << 23 | m);
            }
        }
        for b in [0, 0x8000_0000, 0x3EFF_FFFF, 0x3F00_0000, 0x4EFF_FFFE, 0x4EFF_FFFF, 0x4F00_0000, 0x7F80_0000, 0x7F80_0001, 0xFFFF_FFFF, 1]
        {
            check(b);
            check(b ^ 0x8000_0000);
        }
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        for _ in 0..4_000_000 {
            check(rng.next());
        }
        // Halves and near-halves of the step counts a move gives.
        for i in -300_000i32..300_000 {
            let v = i as f32 * 0.5;
            check(v.to_bits());
            check(v.to_bits() + 1);
            check(v.to_bits().wrapping_sub(1));
        }
    }

    #[test]
    fn div10_is_exact() {
        let check = |v: u32| assert_eq!(div10(v), (v / 10, (v % 10) as u8), "{v}");
        for v in 0..2_000_000 {
            check(v);
        }
        for k in 0..=32 {
            let p = if k == 32 { u32::MAX } else { 1u32 << k };
            for d in 0..1000 {
                check(p.wrapping_sub(d));
                check(p.wrapping_add(d));
            }
        }
        let mut rng = crate::test_util::XorShift(0x1234_5678);
        for _ in 0..2_000_000 {
            check(rng.next());
        }
    }
}
