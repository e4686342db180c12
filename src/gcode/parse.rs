//! G-code line parser (docs/SPEC.md §5): RS274/NGC word-address syntax → [`Line`].
//!
//! Sits between `protocol::LineChecker`, which hands over the command text
//! (`N<n>` and `*<cs>` already stripped), and the interpreter, which owns the
//! modal state. Zero allocation, no panics, f32 only; one [`Line`] is about
//! 100 bytes and lives on the stack.
//!
//! Syntax accepted:
//! - letters in any case; blanks (space, tab) are ignored between words,
//!   between a letter and its number and inside a number, as RS274/NGC says
//!   (`G1X10Y-2.5`, `X 10`, `X1 6.5` is X16.5, `X- 1` is X-1);
//! - `( … )` comments (no nesting; an unclosed `(` is an error) and `;` to the
//!   end of the line;
//! - numbers `[+|-][digits][.digits]` with at least one digit and below 1e6
//!   in magnitude, with any number of digits: beyond 9 significant digits
//!   the number is rounded to 9 (more than f32's 7), so `X24.985715729`
//!   reads as written would on a controller with doubles, to the step. There
//!   is no exponent:
//!   a number directly followed by `E` (`X1e99`) is an error, so write a
//!   blank before an `E` word (`X1 E5`);
//! - `#` parameters, `[` expressions, O-word subroutines and loops and the
//!   axis letters A, C, U, V, W are refused with errors that name
//!   them; an `O<n>` program number alone on a line (Fanuc/HAAS posts:
//!   `O1001`, `O0000(NAME)`) is accepted and does nothing;
//! - an axis word without a number (`G28 X Z`) names the axis, with the
//!   value 0; only a G28 line may do that, elsewhere it is a bad number;
//! - a leading `N<n>` is skipped (with or without a checksum: grbl-style
//!   senders stream files with `N` on every line); an `N` word later on the
//!   line is a value word (M110 reads it);
//! - a line that starts with `%` (a program delimiter in files, `% vfd
//!   enable`) is empty: what follows the `%` is not read;
//! - `@` and `^` are LinuxCNC's polar coordinates (radius, angle in degrees);
//! - a leading line number may have a fraction (`N4567.789`), as LinuxCNC
//!   allows;
//! - `M23` and `M28` take the rest of the line, up to `;`, as a file name.
//!
//! Every error points at a 1-based column of the text given to [`parse`]:
//! number errors at the word's letter, code errors at the `G`/`M`, the rest
//! at the offending character.

//!
//! The files: [`Word`]/[`Words`] in `words`, the codes of each modal group
//! in `codes`, [`Line`] in `line`, [`ParseError`] in `error`, the number
//! lexer in `number`, the code → modal group table in `groups`; this file
//! reads a line word by word.

mod codes;
mod error;
mod groups;
mod line;
mod number;
mod words;

pub use codes::{
    Coolant, CutterComp, Distance, FeedMode, Motion, NonModal, PathMode, Plane, Spindle, Stopping, ToolLength, Units, OTHER_M_CODES,
};
pub use error::{ParseError, ParseErrorKind};
pub use line::Line;
pub use words::{Word, Words};

use error::{col_of, err};
use groups::{apply_g, apply_m};
use number::{lex_number, lex_plain, skip_blanks, skip_line_number, Number};

/// Longest text [`parse`] accepts, in bytes: the protocol's line limit
/// (columns are `u8`: a problem in column 256 is reported at 255).
pub const MAX_PARSE_LEN: usize = crate::protocol::MAX_LINE_LEN;

/// M codes whose argument is the rest of the line (a file name).
const TEXT_ARG_M_CODES: &[u16] = &[23, 28];

/// An `O` word at `pos` (just after the letter, column `col`): a program
/// number alone on its line (`O1001`, `O0000(NAME)`; posts for Fanuc-style
/// controls write one) is accepted when it comes first; anything else
/// (`O100 sub`, `o<name> call`, `O10 while [...]`, an O word after other
/// words) is an O-word subroutine or loop and refused.
fn program_number(s: &[u8], pos: usize, col: u8, first: bool) -> Result<(), ParseError> {
    let refuse = err(ParseErrorKind::OWord, col);
    if !first {
        return refuse;
    }
    let Ok((n, mut pos)) = lex_number(s, pos, col) else {
        return refuse;
    };
    if n.negative || n.scale != 0 {
        return refuse;
    }
    // Only blanks and comments may follow.
    loop {
        pos = skip_blanks(s, pos);
        match s.get(pos) {
            None | Some(b';') => return Ok(()),
            Some(b'(') => match s.get(pos + 1..).and_then(|r| r.iter().position(|&b| b == b')')) {
                Some(i) => pos += i + 2,
                None => return err(ParseErrorKind::UnclosedComment, col_of(pos)),
            },
            Some(_) => return refuse,
        }
    }
}

/// The file name after M23/M28 starting at `pos`: up to `;`, blanks trimmed.
/// Returns (start, len).
fn text_arg(s: &[u8], pos: usize, col: u8) -> Result<(u8, u8), ParseError> {
    let start = skip_blanks(s, pos);
    let rest = s.get(start..).unwrap_or(&[]);
    let mut len = rest.iter().position(|&b| b == b';').unwrap_or(rest.len());
    while len > 0 && matches!(rest.get(len - 1), Some(b' ' | b'\t')) {
        len -= 1;
    }
    match (u8::try_from(start), u8::try_from(len)) {
        (Ok(start), Ok(len)) if len > 0 => Ok((start, len)),
        _ => err(ParseErrorKind::MissingFileName, col),
    }
}

/// Parse one line of G-code (the command text after protocol stripping).
///
/// A malformed line is rejected whole with the column of the first problem;
/// a blank or comment-only line gives an empty [`Line`].
pub fn parse(s: &[u8]) -> Result<Line, ParseError> {
    let mut line = Line::default();
    parse_into(s, &mut line)?;
    Ok(line)
}

/// [`parse`] into `line`, which must be empty (`Line::default()`), for
/// callers that keep the line in place: a `Result<Line, _>` is one more
/// 100-byte copy on AVR, and clearing the line here again cost ~150 cycles
/// per streamed line. On an error `line` holds what was parsed before it.
pub fn parse_into(s: &[u8], line: &mut Line) -> Result<(), ParseError> {
    debug_assert!(*line == Line::default());
    if s.len() > MAX_PARSE_LEN {
        return err(ParseErrorKind::LineTooLong, col_of(MAX_PARSE_LEN));
    }
    let mut pos = 0;
    let mut seen_word = false;
    // Column of the first axis word without a number (`G28 X`), 0 if none.
    let mut bare_axis_col = 0u8;
    while let Some(&c) = s.get(pos) {
        let col = col_of(pos);
        match c {
            b' ' | b'\t' => pos += 1,
            b'(' => {
                let rest = s.get(pos + 1..).unwrap_or(&[]);
                match rest.iter().position(|&b| b == b')') {
                    Some(i) => pos += i + 2,
                    None => return err(ParseErrorKind::UnclosedComment, col),
                }
            }
            b';' => break,
            // A program marker (`%`, `% vfd enable`): the rest is not G-code.
            b'%' if !seen_word => break,
            // `@` and `^`: LinuxCNC's polar words, read like the letters.
            _ if c.is_ascii_alphabetic() || c == b'@' || c == b'^' => {
                pos += 1;
                match c.to_ascii_uppercase() {
                    b'G' => match plain_g(s, pos) {
                        Some((code, len)) => {
                            apply_g(line, code, col)?;
                            pos += len;
                        }
                        None => pos = g_word(s, pos, col, line)?,
                    },
                    b'M' => {
                        let (n, next) = lex_number(s, pos, col)?;
                        pos = next;
                        let code = match n.code_x10() {
                            Some(c) if c % 10 == 0 => c / 10,
                            _ => return err(ParseErrorKind::UnsupportedCode, col),
                        };
                        apply_m(line, code, col)?;
                        if TEXT_ARG_M_CODES.contains(&code) {
                            line.text_arg = Some(text_arg(s, pos, col)?);
                            break;
                        }
                    }
                    b'N' if !seen_word => pos = skip_line_number(s, pos, col)?,
                    b'O' => {
                        // First on the line but for a line number.
                        program_number(s, pos, col, line.is_empty())?;
                        break;
                    }
                    up => {
                        // Every other letter is A, C, U, V or W.
                        let Some(w) = Word::from_letter(up) else {
                            return err(ParseErrorKind::NoSuchAxis, col);
                        };
                        // The usual word: a plain number right after the
                        // letter (`X-12.345`), what the general route
                        // (`general_value`) reads it as
                        // (`plain_words_read_as_the_general_route_reads_them`).
                        let n = match plain_value(s, pos) {
                            Some((n, len)) if w != Word::T => {
                                pos += len;
                                n
                            }
                            _ => match general_value(s, pos, col, w)? {
                                (Some(n), next) => {
                                    pos = next;
                                    n
                                }
                                (None, _) => {
                                    // `G28 X`: an axis named without a value. Only G28
                                    // may do that; checked once the whole line is read.
                                    if !line.words.insert(w, 0.0) {
                                        return err(ParseErrorKind::RepeatedWord, col);
                                    }
                                    if bare_axis_col == 0 {
                                        bare_axis_col = col;
                                    }
                                    seen_word = true;
                                    continue;
                                }
                            },
                        };
                        if !line.words.insert(w, n.to_f32()) {
                            return err(ParseErrorKind::RepeatedWord, col);
                        }
                    }
                }
                seen_word = true;
            }
            b'#' | b'[' => return err(ParseErrorKind::Parameter, col),
            _ => return err(ParseErrorKind::Unexpected, col),
        }
    }
    if bare_axis_col != 0 && line.non_modal != Some(NonModal::Home) {
        return err(ParseErrorKind::BadNumber, bare_axis_col);
    }
    Ok(())
}

/// The code × 10 of a G word whose letter ends at `pos` when it is the
/// usual one, one or two digits followed by the end of the line, a letter
/// (not an exponent's `e`) or a blank and a letter (`G1 X…`), and the
/// digits' length; `None` for anything else, which [`g_word`] reads. Where
/// it answers, `g_word` gives the same code and end
/// (`plain_g_reads_as_the_general_route_reads_it`). With the general route
/// out of line in `g_word`, ~200 cycles a streamed line less on the AVR
/// (`profile --trace`: 21 558 → 21 362; `parse_into` 2 393 → 2 219 itself).
// speed: the G word of every streamed line (doc above)
#[inline(always)]
fn plain_g(s: &[u8], pos: usize) -> Option<(u16, usize)> {
    let (code, len, after) = match s.get(pos..)? {
        [a @ b'0'..=b'9', b @ b'0'..=b'9', after @ ..] => (((a - b'0') * 10 + (b - b'0')) as u16 * 10, 2, after),
        [a @ b'0'..=b'9', after @ ..] => ((a - b'0') as u16 * 10, 1, after),
        _ => return None,
    };
    let usual = match after {
        [] => true,
        [b' ', c, ..] => c.is_ascii_alphabetic(),
        [c, ..] => c.is_ascii_alphabetic() && !matches!(c, b'e' | b'E'),
    };
    usual.then_some((code, len))
}

/// A G word whose letter ends at `pos` (column `col`) into `line`;
/// returns the index after its number.
// speed: the rare route kept out of parse_into's registers (see plain_g)
#[inline(never)]
fn g_word(s: &[u8], pos: usize, col: u8, line: &mut Line) -> Result<usize, ParseError> {
    // `G1`: as for a value word.
    let (n, next) = match plain_value(s, pos) {
        Some((n, len)) => (n, pos + len),
        None => lex_number(s, pos, col)?,
    };
    let code = n.code_x10().ok_or(ParseError { kind: ParseErrorKind::UnsupportedCode, col })?;
    apply_g(line, code, col)?;
    Ok(next)
}

/// The number of value word `w` (letter at column `col`, its number from
/// `pos`) by the general route, and the index after it; `None` for an
/// axis named without a number (`G28 X`). Out of line: in `parse_into`
/// this rare route cost the usual word ~70 cycles a streamed line on the
/// AVR in registers saved and spilled (`profile --trace`: 21 362 → 21 293).
// speed: the rare route kept out of parse_into's registers (doc above)
#[inline(never)]
fn general_value(s: &[u8], pos: usize, col: u8, w: Word) -> Result<(Option<Number>, usize), ParseError> {
    if matches!(w, Word::X | Word::Y | Word::Z) && no_number_follows(s, pos) {
        return Ok((None, pos));
    }
    let (n, next) = lex_number(s, pos, col)?;
    if w == Word::T && (n.scale != 0 || (n.negative && n.mantissa != 0) || n.mantissa > 255) {
        return err(ParseErrorKind::BadToolNumber, col);
    }
    Ok((Some(n), next))
}

/// The number of a word whose letter ends at `pos` when it follows the
/// letter at once as a plain number (an optional `-`, then what
/// [`lex_plain`] reads), and its length with the sign; `None` for anything
/// else, which [`lex_number`] reads. Where it answers, `lex_number` gives
/// the same number and end (`plain_words_read_as_the_general_route_reads_them`),
/// without its blank and sign scans and the bare-axis test before it: ~100
/// cycles a word less on the AVR (`profile --trace`).
// speed: on every value word of a streamed line (doc above)
#[inline(always)]
fn plain_value(s: &[u8], pos: usize) -> Option<(Number, usize)> {
    let rest = s.get(pos..).unwrap_or(&[]);
    let (negative, body) = match rest {
        [b'-', tail @ ..] => (true, tail),
        _ => (false, rest),
    };
    let (mantissa, scale, len) = lex_plain(body);
    if len == 0 {
        return None;
    }
    Some((Number { negative, mantissa, scale: scale as u16 }, negative as usize + len as usize))
}

/// True when the word whose letter ends at `pos` has no number at all: the
/// next non-blank is the end of the line, a comment, or the letter of another
/// word (`G28 X Y`). `X-`, `X.` or `Xa` are not bare: they are bad numbers.
fn no_number_follows(s: &[u8], pos: usize) -> bool {
    match s.get(skip_blanks(s, pos)) {
        None | Some(b';' | b'(') => true,
        Some(&c) => c.is_ascii_alphabetic() && (matches!(c.to_ascii_uppercase(), b'G' | b'M') || Word::from_letter(c).is_some()),
    }
}

#[cfg(test)]
mod tests;
