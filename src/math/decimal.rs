//! A decimal number of a G-code word: its digits read ([`lex_plain`]) and
//! its digits and power of ten into the nearest f32 without a division
//! ([`quotient_f32`]), the parser's usual route for every word's value
//! (`gcode::parse::number`). The `_plain` functions are the Rust; on the
//! AVR both run in assembly (`mill_lex_plain` in the firmware's
//! `board::lex`, `mill_quotient_f32` in `board::decimal`), bit for bit the
//! same (`tests/soft_float.rs`).

/// Most significant digits a number may have.
pub const MAX_SIG_DIGITS: u8 = 9;
/// Most significant digits before the point (|value| < 1e6).
pub const MAX_INT_DIGITS: u8 = 6;

/// [`lex_plain_plain`]; on the AVR its steps in assembly (`mill_lex_plain`,
/// in the firmware's `board::lex`), bit for bit the same
/// (`tests/soft_float.rs`). Every value word of a line goes through it:
/// 319 cycles from call to return for `19.998`, about what the Rust took
/// inlined at its two call sites (`profile --count 254 --feed 12000 --accel
/// 5000 --trace 300:1500` 18 522 -> 18 489 cycles a line), in ~1.2 KB
/// less flash than those two copies.
// speed: as a call of its own ~40 cycles a number
#[inline(always)]
pub fn lex_plain(s: &[u8]) -> (u32, u8, u8) {
    #[cfg(target_arch = "avr")]
    {
        extern "C" {
            fn mill_lex_plain(s: *const u8, len: u8) -> u64;
        }
        // A number after a word's letter has at most 255 bytes after it
        // (a line has 256); a longer slice (none in the parser) is not
        // plain: the general route (`lex_spaced`) reads it.
        let Ok(len) = u8::try_from(s.len()) else {
            return (0, 0, 0);
        };
        // SAFETY: reads `len` bytes from `s.as_ptr()` on, inside `s`, and
        // nothing else; avr-gcc's calling convention (the pointer in
        // r24–r25, the length in r22, the result in r18–r25); it changes
        // only call-clobbered registers (r16 and r17 are saved), r1 zero
        // again at the return.
        let r = unsafe { mill_lex_plain(s.as_ptr(), len) };
        (r as u32, (r >> 32) as u8, (r >> 40) as u8)
    }
    #[cfg(not(target_arch = "avr"))]
    {
        lex_plain_plain(s)
    }
}

/// The number at the start of `s` (after its sign) when it is a plain one:
/// at most [`MAX_SIG_DIGITS`] digits in all, below 10⁶, no blank inside it
/// and nothing after it that makes it an error. Returns its mantissa, its
/// scale and its length in bytes, or a length of 0 for any other text,
/// which the parser's `lex_spaced` reads (or refuses) instead. For a plain
/// number both give the same result (`plain_and_spaced_lexers_agree`).
///
/// One pass: the integer digits are multiplied in as they come (at most 9
/// digits in all, so no overflow), the fraction's zeros only once a
/// non-zero digit follows them, so that trailing zeros drop out of the
/// mantissa and the scale. The host's [`lex_plain`], and the twin of the
/// AVR's assembly.
pub fn lex_plain_plain(s: &[u8]) -> (u32, u8, u8) {
    const NOT_PLAIN: (u32, u8, u8) = (0, 0, 0);
    let mut rest = s;
    let mut mantissa: u32 = 0;
    // Digits read.
    let mut n: u8 = 0;
    while let Some(d) = next_digit(&mut rest, &mut n) {
        let Ok(d) = d else { return NOT_PLAIN };
        mantissa = crate::math::times10_plus(mantissa, d);
    }
    // Over MAX_INT_DIGITS significant digits before the point.
    if mantissa >= 1_000_000 {
        return NOT_PLAIN;
    }
    let int_digits = n;
    // Fraction zeros not yet multiplied in.
    let mut pending: u8 = 0;
    let point = matches!(rest, [b'.', ..]);
    if let [b'.', tail @ ..] = rest {
        rest = tail;
        while let Some(d) = next_digit(&mut rest, &mut n) {
            let Ok(d) = d else { return NOT_PLAIN };
            if d == 0 {
                pending += 1;
                continue;
            }
            while pending != 0 {
                mantissa = crate::math::times10_plus(mantissa, 0);
                pending -= 1;
            }
            mantissa = crate::math::times10_plus(mantissa, d);
        }
    }
    if n == 0 {
        return NOT_PLAIN;
    }
    match rest {
        // An exponent, a second point or sign: errors.
        [b'e' | b'E' | b'.' | b'+' | b'-', ..] => return NOT_PLAIN,
        // Blanks, then more of the number.
        [b' ' | b'\t', tail @ ..] => {
            let mut after = tail;
            while let [b' ' | b'\t', more @ ..] = after {
                after = more;
            }
            match after {
                [b'0'..=b'9', ..] => return NOT_PLAIN,
                [b'.', ..] if !point => return NOT_PLAIN,
                _ => {}
            }
        }
        _ => {}
    }
    (mantissa, n - int_digits - pending, n + point as u8)
}

/// [`lex_plain_plain`]'s digit: the one at the front of `rest`, taken, `n`
/// counting it; `None` at anything else, `Some(Err(()))` for a digit past
/// [`MAX_SIG_DIGITS`] (the number is not plain).
fn next_digit(rest: &mut &[u8], n: &mut u8) -> Option<Result<u8, ()>> {
    let [c, tail @ ..] = *rest else { return None };
    let d = c.wrapping_sub(b'0');
    if d > 9 {
        return None;
    }
    if *n == MAX_SIG_DIGITS {
        return Some(Err(()));
    }
    *n += 1;
    *rest = tail;
    Some(Ok(d))
}

/// [`quotient_f32_plain`]; on the AVR its steps in assembly
/// (`mill_quotient_f32`): 148 cycles from call to return on average, 190 at
/// most (`tests/soft_float.rs` times it). The Rust compiled into the parser
/// took ~290 a number: `profile --count 254 --feed 12000 --accel 5000
/// --trace 300:1500` 18 978 -> 18 806 cycles a line (and 18 585 -> 18 522
/// with the multiply by a0 made one byte's), and ~400 B less flash.
#[inline]
pub fn quotient_f32(m: u32, s: u16) -> Option<f32> {
    #[cfg(target_arch = "avr")]
    {
        extern "C" {
            fn mill_quotient_f32(m: u32, s: u8) -> u32;
        }
        let s = u8::try_from(s).ok()?;
        // SAFETY: a pure function of its arguments (it reads only
        // [`QUOTIENT_TABLE`] in flash), with avr-gcc's calling convention:
        // m in r22–r25, s in r20, the result in r22–r25; only call-clobbered
        // registers changed, r1 zero again at the return.
        let bits = unsafe { mill_quotient_f32(m, s) };
        // 0 is "no answer": a quotient of m ≥ 1 is never +0.0.
        (bits != 0).then(|| f32::from_bits(bits))
    }
    #[cfg(not(target_arch = "avr"))]
    {
        quotient_f32_plain(m, s)
    }
}

/// `m / 10^s` rounded to the nearest f32, without a division, for the
/// usual number (`1 ≤ m < 2^24`, `1 ≤ s ≤ 9`); `None` otherwise and in the
/// rare case where the fast route cannot decide the rounding (then
/// the parser's division answers). Bit for bit what the division
/// gives (the parser's `the_division_free_conversion_matches_the_division`):
/// compiled for the AVR ~350 cycles instead of the division's ~670
/// (`__floatunsisf` and `__divsf3`), and 148 in the assembly
/// ([`quotient_f32`]).
///
/// How: `m / 10^s = (m / 5^s) · 2^−s`. With `m` shifted left by `z` to
/// fill 32 bits (`a`) and `R = ⌈2^(31+e) / 5^s⌉` (`e` = bit length of
/// `5^s`, so `R` fills 32 bits too), `Q = a · 2^(31+e) / 5^s` lies in
/// `[2^62, 2^64)` and `P = a · R` in `[Q, Q + 2^32)`. `H`, the top 32
/// bits of `P` from three of the four 16-bit partial products, is at most
/// 3 below `P / 2^32`, so `Q / 2^32` lies in `(H − 1, H + 3)`. The top 24
/// bits of `H` are the significand; the `k` bits below it (7 or 8) decide
/// the rounding unless they are within that window of one half (then
/// `None`: ~2 % of numbers): a tie
/// itself cannot occur (`m / 10^s` is a dyadic number only when `5^s`
/// divides `m`, and then it has at most 22 significant bits).
pub fn quotient_f32_plain(m: u32, s: u16) -> Option<f32> {
    if m == 0 || m >= 1 << 24 {
        return None;
    }
    let (r, e) = match s {
        1 => RECIP[0],
        2 => RECIP[1],
        3 => RECIP[2],
        4 => RECIP[3],
        5 => RECIP[4],
        6 => RECIP[5],
        7 => RECIP[6],
        8 => RECIP[7],
        9 => RECIP[8],
        _ => return None,
    };
    // Normalise: the top bit of `a` at bit 31 (m < 2^24: z ≥ 8), in its
    // 16-bit halves `a1`, `a0` made of m's bytes: LLVM turned a choice
    // between two shifts of one 32-bit value (by 16 or 8) into a variable
    // shift, a loop on the AVR (~230 cycles a streamed line, `profile
    // --trace --hist parse_into`).
    let [b0, b1, b2, _] = m.to_le_bytes();
    let (mut a1, mut a0, mut z) =
        if b2 == 0 { (u16::from_le_bytes([b0, b1]), 0u16, 16u8) } else { (u16::from_le_bytes([b1, b2]), u16::from_le_bytes([0, b0]), 8u8) };
    while a1 < 1 << 15 {
        a1 = (a1 << 1) | (a0 >> 15);
        a0 <<= 1;
        z += 1;
    }
    let (r1, r0) = ((r >> 16) as u16, r as u16);
    let mul = crate::math::mul_u16;
    let h = mul(a1, r1) + (mul(a1, r0) >> 16) + (mul(a0, r1) >> 16);
    // H's top bit is bit 31 or 30: `hh` is H with its top bit at 31 (the
    // same choice-of-shift concern), so the significand is `hh >> 8` and
    // the 8 bits below it are the rest, in halves of H's units when H was
    // doubled (k = 7 bits of H below the significand, else 8).
    let top = h >= 1 << 31;
    let hh = if top { h } else { h.wrapping_add(h) };
    let (sig, rest) = (hh >> 8, hh & 0xFF);
    // Q / 2^32 lies in (H − 1, H + 3): rounded down for sure while the
    // rest is at most half less 3 units of H (123 covers 128 − 3·2 too),
    // up once above half; in between, undecided.
    let sig = if rest <= 123 {
        sig
    } else if rest > 128 {
        sig + 1
    } else {
        return None;
    };
    // value = sig · 2^(1 + k − e − z − s); f32's biased exponent for a
    // significand in [2^23, 2^24) is 127 + 23 + that. `sig` carries its
    // leading bit into the exponent field (a carry to 2^24 as well).
    let exp = 151 + 7 + top as i16 - e as i16 - z as i16 - s as i16;
    let high = ((exp - 1) as u16) << 7;
    Some(f32::from_bits(((high as u32) << 16) + sig))
}

/// `(⌈2^(31+e) / 5^s⌉, e)` for `s` in 1..=9, `e` the bit length of `5^s`.
const RECIP: [(u32, u8); 9] = {
    let mut t = [(0u32, 0u8); 9];
    let mut s = 1;
    while s <= 9 {
        let d = 5u64.pow(s as u32);
        let e = 64 - d.leading_zeros();
        let n = 1u64 << (31 + e);
        t[s - 1] = (n.div_ceil(d) as u32, e as u8);
        s += 1;
    }
    t
};

crate::in_flash! {
    /// [`RECIP`] as the assembly reads it with `lpm`: per power of ten
    /// 1..=9, the reciprocal's four bytes (least significant first) and
    /// the bit length `e`.
    pub static QUOTIENT_TABLE: [[u8; 5]; 9] = {
        let mut t = [[0u8; 5]; 9];
        let mut i = 0;
        while i < 9 {
            let (r, e) = RECIP[i];
            let b = r.to_le_bytes();
            t[i] = [b[0], b[1], b[2], b[3], e];
            i += 1;
        }
        t
    };
}
