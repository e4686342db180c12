//! The number lexer: the decimal number after a word's letter (blanks
//! inside it as RS274/NGC allows, no exponent, at most 9 significant
//! digits kept) into a [`Number`] converted once to f32, and the leading
//! `N<n>` line number skipped.

use super::error::{err, ParseError, ParseErrorKind};
use crate::math::decimal::quotient_f32;

/// A lexed decimal number: value = ±mantissa / 10^scale, trailing fraction
/// zeros dropped.
#[derive(Clone, Copy, Debug)]
pub(super) struct Number {
    pub(super) negative: bool,
    /// Significant digits, ≤ 1e9.
    pub(super) mantissa: u32,
    /// Power of ten to divide by.
    pub(super) scale: u16,
}

impl Number {
    /// The nearest f32 (exact rounding while the mantissa is below 2^24, i.e.
    /// up to 7 significant digits; within about one ulp above): by
    /// [`quotient_f32`], else by [`divide_f32`], which gives the same bits.
    pub(super) fn to_f32(self) -> f32 {
        let v = match quotient_f32(self.mantissa, self.scale) {
            Some(v) => v,
            None => divide_f32(self.mantissa, self.scale),
        };
        // `X-0` is +0.0: the parser never gives a negative zero.
        if self.negative && self.mantissa != 0 {
            -v
        } else {
            v
        }
    }

    /// [`Number::to_f32`] by the plain route alone (the reference of
    /// [`quotient_f32`]).
    #[cfg(test)]
    pub(super) fn to_f32_by_division(self) -> f32 {
        if self.mantissa == 0 {
            return 0.0;
        }
        let mut v = self.mantissa as f32;
        let mut scale = self.scale;
        while scale > 10 {
            v /= 1e10;
            scale -= 10;
        }
        if scale != 0 {
            v /= pow10(scale as u8);
        }
        if self.negative {
            -v
        } else {
            v
        }
    }

    /// The value × 10 as a code number (`38.2` → 382), if it is a
    /// non-negative number with at most one decimal.
    pub(super) fn code_x10(self) -> Option<u16> {
        if self.negative {
            return None;
        }
        let m = u16::try_from(self.mantissa).ok()?;
        match self.scale {
            // Not `checked_mul`: LLVM-AVR widens it into a 32-bit
            // `__mulsi3` call (~90 cycles on every G and M word).
            0 if m <= u16::MAX / 10 => Some(m * 10),
            0 => None,
            1 => Some(m),
            _ => None,
        }
    }
}

/// `m / 10^s` by an int → float conversion and a soft-float division by
/// an exact power of ten (which rounds once; a multiply by 10^−s would
/// not): exact rounding while `m` is below 2^24, within about one ulp
/// above. ~670 cycles on the AVR; [`quotient_f32`] spares it nearly always.
#[inline(never)]
fn divide_f32(m: u32, scale: u16) -> f32 {
    if m == 0 {
        return 0.0;
    }
    let mut v = m as f32;
    let mut scale = scale;
    while scale > 10 {
        v /= 1e10;
        scale -= 10;
    }
    if scale != 0 {
        v /= pow10(scale as u8);
    }
    v
}

/// 10^`n` for `n` in 1..=10, exact in f32 (5^10 < 2^24). A match, not a
/// table: on AVR a const table would be copied into RAM, and the build has no
/// jump or lookup tables, so this is a few compares.
fn pow10(n: u8) -> f32 {
    match n {
        1 => 1e1,
        2 => 1e2,
        3 => 1e3,
        4 => 1e4,
        5 => 1e5,
        6 => 1e6,
        7 => 1e7,
        8 => 1e8,
        9 => 1e9,
        _ => 1e10,
    }
}

pub(super) use crate::math::decimal::{lex_plain, MAX_INT_DIGITS, MAX_SIG_DIGITS};

/// Skip spaces and tabs from `pos`. Inlined: called ~10 times a line, and
/// the call cost more than the usual single compare (~360 cycles a line).
// speed: ~360 cycles a line as a call (doc above)
#[inline(always)]
pub(super) fn skip_blanks(s: &[u8], mut pos: usize) -> usize {
    while matches!(s.get(pos), Some(b' ' | b'\t')) {
        pos += 1;
    }
    pos
}

/// The digit value of byte `c`, or a value above 9 when it is no digit.
pub(super) fn digit(c: Option<&u8>) -> u8 {
    match c {
        Some(&c) => c.wrapping_sub(b'0'),
        None => 10,
    }
}

/// Lex the number of the word whose letter is at column `col`, starting at
/// `pos` (just after the letter). Returns the number and the index after it.
///
/// The digits go into a `u32` mantissa (leading zeros and trailing fraction
/// zeros dropped) with a power-of-ten scale; [`Number::to_f32`] converts once.
///
/// The usual number (no blank inside it, at most 9 digits) is read by
/// [`lex_plain`] in one pass; anything else by [`lex_spaced`], digit by
/// digit. The two agree wherever the plain one answers
/// (`plain_and_spaced_lexers_agree`), and together they match the lexer
/// before the split (`number_lexer_matches_its_reference`). On the AVR the
/// split saved ~300 cycles a streamed line (`profile --trace`: the
/// digit-by-digit loop's state did not fit in the registers).
///
/// Not inlined: the usual value and G word are read by `parse_into`'s
/// own `plain_value` first, so this is the route of M codes and of
/// numbers with a sign, blanks or a `+` (~190 cycles more a number as a
/// call). Inlined at its four call sites it was ~1 KB of flash.
// flash: four inlined copies (doc above)
#[inline(never)]
pub(super) fn lex_number(s: &[u8], pos: usize, col: u8) -> Result<(Number, usize), ParseError> {
    let mut pos = skip_blanks(s, pos);
    let mut negative = false;
    match s.get(pos) {
        Some(b'-') => {
            negative = true;
            pos += 1;
        }
        Some(b'+') => pos += 1,
        _ => {}
    }
    pos = skip_blanks(s, pos);
    if matches!(s.get(pos), Some(b'#' | b'[')) {
        return err(ParseErrorKind::Parameter, col);
    }
    let (mantissa, scale, len) = lex_plain(s.get(pos..).unwrap_or(&[]));
    if len != 0 {
        let number = Number { negative, mantissa, scale: scale as u16 };
        return Ok((number, pos + len as usize));
    }
    lex_spaced(s, pos, negative, col)
}

/// [`lex_number`] from `first` (after the sign), digit by digit, taking
/// blanks inside the number (RS274/NGC ignores them: `X1 6.5` is X16.5).
///
/// Digits beyond [`MAX_SIG_DIGITS`] significant ones (`X24.985715729`) are
/// read and dropped, the kept ones rounded half up on the first dropped
/// digit: 9 digits are more than f32 holds, so the value is the nearest
/// f32 of the number as written (within an ulp). Only a number of 10⁶ or
/// more is out of range.
// speed: the rare path kept out of parse_into's registers (~300 cycles a line, see lex_number)
#[inline(never)]
pub(super) fn lex_spaced(s: &[u8], first: usize, negative: bool, col: u8) -> Result<(Number, usize), ParseError> {
    let mut pos = first;
    let mut mantissa: u32 = 0;
    // Significant digits in `mantissa`.
    let mut sig: u8 = 0;
    let mut too_long = false;
    // Integer part: at most MAX_INT_DIGITS significant digits.
    loop {
        let d = digit(s.get(pos));
        if d > 9 {
            if let Some(next) = blank_then(s, pos, true) {
                pos = next;
                continue;
            }
            break;
        }
        pos += 1;
        if mantissa != 0 || d != 0 {
            if sig == MAX_INT_DIGITS {
                too_long = true;
            } else {
                mantissa = crate::math::times10_plus(mantissa, d);
                sig += 1;
            }
        }
    }
    let mut digits = pos != first;
    let mut scale: u16 = 0;
    // Digits were dropped past MAX_SIG_DIGITS; the first dropped one was ≥ 5.
    let mut dropped = false;
    let mut round_up = false;
    if s.get(pos) == Some(&b'.') {
        pos += 1;
        // Fraction digits read, and the zeros among the last of them not yet
        // known to be followed by a non-zero digit.
        let mut frac: u16 = 0;
        let mut pending: u16 = 0;
        loop {
            let d = digit(s.get(pos));
            if d > 9 {
                if let Some(next) = blank_then(s, pos, false) {
                    pos = next;
                    continue;
                }
                break;
            }
            pos += 1;
            frac = frac.saturating_add(1);
            if d == 0 || dropped {
                pending = pending.saturating_add(1);
                continue;
            }
            if mantissa != 0 {
                // The zeros between two significant digits are significant.
                while pending != 0 {
                    if sig == MAX_SIG_DIGITS {
                        dropped = true;
                        break;
                    }
                    mantissa = crate::math::times10_plus(mantissa, 0);
                    sig += 1;
                    scale = frac - pending;
                    pending -= 1;
                }
            }
            pending = 0;
            if dropped {
                continue;
            }
            if sig == MAX_SIG_DIGITS {
                dropped = true;
                round_up = d >= 5;
            } else {
                mantissa = crate::math::times10_plus(mantissa, d);
                sig += 1;
                scale = frac;
            }
        }
        digits |= frac != 0;
    }
    if !digits {
        return err(ParseErrorKind::BadNumber, col);
    }
    match s.get(pos) {
        Some(b'e' | b'E') => return err(ParseErrorKind::Exponent, col),
        Some(b'.' | b'+' | b'-') => return err(ParseErrorKind::BadNumber, col),
        _ => {}
    }
    if too_long {
        return err(ParseErrorKind::NumberOutOfRange, col);
    }
    if dropped {
        mantissa += round_up as u32;
        // Trailing zeros out, as the other paths leave them (`1.9999999999`
        // rounds to 2, scale 0).
        while scale != 0 {
            let (q, r) = crate::math::div10(mantissa);
            if r != 0 {
                break;
            }
            mantissa = q;
            scale -= 1;
        }
    }
    Ok((Number { negative, mantissa, scale }, pos))
}

/// At a blank inside a number: the index of the digit (or, with `point`,
/// the decimal point) that continues the number after the blanks, if one
/// does. Only reached at the end of a number, so digits cost nothing more.
pub(super) fn blank_then(s: &[u8], pos: usize, point: bool) -> Option<usize> {
    if !matches!(s.get(pos), Some(b' ' | b'\t')) {
        return None;
    }
    let q = skip_blanks(s, pos);
    match s.get(q) {
        Some(b'0'..=b'9') => Some(q),
        Some(b'.') if point => Some(q),
        _ => None,
    }
}

/// Skip a leading `N<n>` line number (any length, optional sign, digits
/// with an optional fraction: LinuxCNC takes `N4567.789`).
pub(super) fn skip_line_number(s: &[u8], pos: usize, col: u8) -> Result<usize, ParseError> {
    let mut pos = skip_blanks(s, pos);
    if matches!(s.get(pos), Some(b'-' | b'+')) {
        pos += 1;
    }
    let start = pos;
    while matches!(s.get(pos), Some(b'0'..=b'9')) {
        pos += 1;
    }
    if pos != start && s.get(pos) == Some(&b'.') {
        pos += 1;
        while matches!(s.get(pos), Some(b'0'..=b'9')) {
            pos += 1;
        }
    }
    if pos == start || matches!(s.get(pos), Some(b'.' | b'e' | b'E' | b'+' | b'-')) {
        return err(ParseErrorKind::BadNumber, col);
    }
    Ok(pos)
}
