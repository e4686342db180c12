//! Printer-only M codes that hosts send on their own (OctoPrint, Pronterface,
//! cncjs in Marlin mode, slicer start/end scripts): answered so that no host
//! sees an `Error:` for them (OctoPrint treats an unknown `Error:` as fatal:
//! it sends M112 and disconnects).
//!
//! ```text
//!  Machine::execute ─► hostcodes::code(line)? ─► hostcodes::run   (this file)
//!                   └► gcode::parse ─► interp                      (everything else)
//! ```
//!
//! Recognised before the G-code parser, like the SD commands
//! ([`sd_code`], run by `ui::sd`): a line that starts with one of these codes is taken
//! whole (`M117` keeps the rest of the line as its text). The same codes on a
//! line with other words (`G0 X1 M104`) stay parse errors.
//!
//! | code | here |
//! |---|---|
//! | M104, M109, M140, M190 | `echo:` note (a mill has no heaters); M109/M190 do not wait |
//! | M106, M107 | `echo:` note (no part-cooling fan) |
//! | M221 | `echo:` note (no extruder: OctoPrint's flow-rate slider) |
//! | M82, M83 | `echo:` note (E is the tool carousel and follows G90/G91) |
//! | M105 | `T:0.0 /0.0` (no temperatures), even during an SD job |
//! | M73 P<pct> | job progress shown on the status screen; P-1 clears it |
//! | M113 [S<s>] | busy keepalive interval, 0–60 s (0 = off); alone: prints it |
//! | M117 <text> | message on the status screen (first [`MSG_LEN`] characters) |
//! | M155, M300 | accepted, nothing to do (no temperatures, no buzzer) |

use crate::gcode::interp::Error;
use core::convert::Infallible;
use ufmt::uwriteln;

/// Characters of an M117 message kept for the status screen (RAM: this + 2 B).
pub const MSG_LEN: usize = 20;

/// Host-set display state and the keepalive interval (23 bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostState {
    /// M117 text, `msg_len` bytes used.
    pub msg: [u8; MSG_LEN],
    pub msg_len: u8,
    /// M73 job progress, percent; [`HostState::NO_PCT`] when unset.
    pub pct: u8,
    /// M113: seconds between `busy:processing` lines while a command waits; 0 = off.
    pub busy_interval_s: u8,
}

impl HostState {
    /// `pct` when no M73 was received.
    pub const NO_PCT: u8 = 0xFF;

    /// No message, no progress, keepalive every 2 s (Marlin's default).
    pub const fn new() -> HostState {
        HostState { msg: [0; MSG_LEN], msg_len: 0, pct: Self::NO_PCT, busy_interval_s: 2 }
    }

    /// The M117 message.
    pub fn message(&self) -> &[u8] {
        self.msg.get(..self.msg_len as usize).unwrap_or(&[])
    }

    /// M73 progress, if set.
    pub fn percent(&self) -> Option<u8> {
        (self.pct != Self::NO_PCT).then_some(self.pct)
    }

    /// Set the M117 message: printable ASCII kept, the rest shown as `?`.
    pub fn set_message(&mut self, text: &[u8]) {
        let n = text.len().min(MSG_LEN);
        for (d, &s) in self.msg.iter_mut().zip(text) {
            *d = if (0x20..0x7f).contains(&s) { s } else { b'?' };
        }
        self.msg_len = n as u8;
    }
}

impl Default for HostState {
    fn default() -> Self {
        Self::new()
    }
}

/// One of the codes of this module (a `match`: a table would be copied to
/// RAM on AVR).
fn is_host_code(c: u16) -> bool {
    matches!(c, 73 | 82 | 83 | 104 | 105 | 106 | 107 | 109 | 113 | 117 | 140 | 155 | 190 | 221 | 300)
}

/// If `text` starts with one of this module's codes (`M<n>`, any case, not
/// followed by a digit or `.`), the code and the rest of the line, trimmed.
///
/// Inlined (LLVM's choice), the first byte is looked at before anything
/// else: a line that starts with neither a blank nor an `M` (a streamed
/// `G1 …`) is answered with one compare instead of a call and a trim (~110
/// cycles a line).
pub fn code(text: &[u8]) -> Option<(u16, &[u8])> {
    if !matches!(text.first(), Some(b'M' | b'm' | b' ' | b'\t')) {
        return None;
    }
    code_of(text)
}

/// [`code`] past its first-byte test.
// speed: inlined into `Machine::execute`, ping-pong took 5.771 s, not 5.756
// (372 B less flash)
#[inline(never)]
fn code_of(text: &[u8]) -> Option<(u16, &[u8])> {
    let t = trim(text);
    let rest = t.strip_prefix(b"M").or_else(|| t.strip_prefix(b"m"))?;
    let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
    if digits == 0 || digits > 3 || rest.get(digits) == Some(&b'.') {
        return None;
    }
    let code = rest.iter().take(digits).fold(0u16, |a, &b| a * 10 + (b - b'0') as u16);
    is_host_code(code).then(|| (code, trim(rest.get(digits..).unwrap_or(&[]))))
}

/// Run one of this module's codes on the host state; `arg` is the rest of
/// the line, replies go to `io`.
// speed: inlined into `Machine::execute`, ping-pong took 5.743 s, not 5.739
#[inline(never)]
pub fn run(host: &mut HostState, io: &mut impl ufmt::uWrite<Error = Infallible>, code: u16, arg: &[u8]) -> Result<(), Error> {
    match code {
        104 | 109 | 140 | 190 => {
            uwriteln!(io, "{}{}{}", F!("echo:M"), code, F!(" ignored: a mill has no heaters")).ok();
        }
        106 | 107 => {
            uwriteln!(io, "{}{}{}", F!("echo:M"), code, F!(" ignored: no part-cooling fan")).ok();
        }
        221 => {
            uwriteln!(io, "{}", F!("echo:M221 ignored: no extruder (the feed override is M220)")).ok();
        }
        82 | 83 => {
            uwriteln!(io, "{}{}{}", F!("echo:M"), code, F!(" ignored: E (the tool carousel) follows G90/G91")).ok();
        }
        105 => {
            // Senders (printcore, Pronterface, OctoPrint) poll M105 for
            // temperatures, also during an SD job; a mill reports none.
            uwriteln!(io, "{}", F!("T:0.0 /0.0")).ok();
        }
        117 => host.set_message(strip_comment(arg)),
        73 => {
            if let Some(p) = word(arg, b'P') {
                host.pct = if (0..=100).contains(&p) { p as u8 } else { HostState::NO_PCT };
            }
        }
        113 => match word(arg, b'S') {
            Some(s) if (0..=60).contains(&s) => host.busy_interval_s = s as u8,
            Some(_) => return Err(Error::BadWord(F!("M113 S must be 0-60 seconds"))),
            None => {
                uwriteln!(io, "{}{}", F!("echo:M113 S"), host.busy_interval_s).ok();
            }
        },
        _ => {} // 155, 300: nothing to do.
    }
    Ok(())
}

/// If `text` is an SD command (M20–M29, M33 or M524), its code and argument
/// (trimmed, without a `;` comment).
///
/// Inline, the first byte is looked at before anything else, as in
/// [`code`] (~110 cycles a streamed line).
// speed: LLVM makes it a call otherwise (see above)
#[inline(always)]
pub fn sd_code(text: &[u8]) -> Option<(u16, &[u8])> {
    if !matches!(text.first(), Some(b'M' | b'm' | b' ' | b'\t')) {
        return None;
    }
    sd_code_of(text)
}

/// [`sd_code`] past its first-byte test.
fn sd_code_of(text: &[u8]) -> Option<(u16, &[u8])> {
    let t = trim(text);
    let rest = t.strip_prefix(b"M").or_else(|| t.strip_prefix(b"m"))?;
    let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
    if digits == 0 || digits > 4 {
        return None;
    }
    let mut code = 0u16;
    for &b in &rest[..digits] {
        code = code * 10 + (b - b'0') as u16;
    }
    if !(20..=29).contains(&code) && code != 33 && code != 524 {
        return None;
    }
    let mut arg = &rest[digits..];
    if let Some(i) = arg.iter().position(|&b| b == b';') {
        arg = &arg[..i];
    }
    Some((code, trim(arg)))
}

/// The integer part of word `letter` in `arg` (`P50`, `p 50.5`), if any.
fn word(arg: &[u8], letter: u8) -> Option<i32> {
    let arg = strip_comment(arg);
    let at = arg.iter().position(|b| b.eq_ignore_ascii_case(&letter))?;
    let rest = trim(arg.get(at + 1..)?);
    let (neg, digits) = match rest.first() {
        Some(b'-') => (true, rest.get(1..)?),
        _ => (false, rest),
    };
    let n = digits.iter().take_while(|b| b.is_ascii_digit()).count();
    if n == 0 || n > 6 {
        return None;
    }
    let v = digits.iter().take(n).fold(0i32, |a, &b| a * 10 + (b - b'0') as i32);
    Some(if neg { -v } else { v })
}

/// The text before a `;` comment, trimmed.
fn strip_comment(arg: &[u8]) -> &[u8] {
    trim(arg.split(|&b| b == b';').next().unwrap_or(&[]))
}

fn trim(mut s: &[u8]) -> &[u8] {
    while let [b' ' | b'\t', r @ ..] = s {
        s = r;
    }
    while let [r @ .., b' ' | b'\t'] = s {
        s = r;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_byte_test_only_skips_lines_without_an_sd_code() {
        for t in [&b"G1 X1"[..], b"M23 a.gco", b" M24", b"\tm20", b"M524", b"", b"  ", b"(M24)", b"N5 M24"] {
            assert_eq!(sd_code(t), sd_code_of(t), "{:?}", String::from_utf8_lossy(t));
        }
        for b in 0..=255u8 {
            if sd_code_of(&[b, b'2', b'4']).is_some() || sd_code_of(&[b, b'M', b'2', b'4']).is_some() {
                assert!(matches!(b, b'M' | b'm' | b' ' | b'\t'), "{b:#x}");
            }
        }
    }

    #[test]
    fn the_first_byte_test_only_skips_lines_without_a_code() {
        for t in [&b"G1 X1"[..], b"M117 hi", b" M117 hi", b"\tm73 P5", b"T1", b"", b"  ", b"M1", b"(M117)", b"N5 M117", b"$M117"] {
            assert_eq!(code(t), code_of(t), "{:?}", String::from_utf8_lossy(t));
        }
        for b in 0..=255u8 {
            let t = [b, b'7', b'3'];
            if code_of(&t).is_some() || code_of(&[b, b'M', b'7', b'3']).is_some() {
                assert!(matches!(b, b'M' | b'm' | b' ' | b'\t'), "{b:#x}");
            }
        }
    }

    #[test]
    fn host_codes_are_recognised_alone_and_only_alone() {
        assert_eq!(code(b"M104 S0"), Some((104, &b"S0"[..])));
        assert_eq!(code(b"  m117 Hello world "), Some((117, &b"Hello world"[..])));
        assert_eq!(code(b"M73 P50 R10"), Some((73, &b"P50 R10"[..])));
        assert_eq!(code(b"M1040"), None);
        assert_eq!(code(b"M104.1"), None);
        assert_eq!(code(b"M10"), None);
        assert_eq!(code(b"G0 M104"), None);
        assert_eq!(code(b"M3 S1000"), None, "spindle codes are not printer codes");
        let all = [73, 82, 83, 104, 105, 106, 107, 109, 113, 117, 140, 155, 190, 221, 300];
        for c in all {
            assert_eq!(code(format!("M{c}").as_bytes()), Some((c, &b""[..])));
        }
        assert_eq!((0..1000).filter(|&c| is_host_code(c)).count(), all.len());
    }

    #[test]
    fn words_are_read_from_the_argument() {
        assert_eq!(word(b"P50 R10", b'P'), Some(50));
        assert_eq!(word(b"p 7.5", b'P'), Some(7));
        assert_eq!(word(b"S-1", b'S'), Some(-1));
        assert_eq!(word(b"R10 ; P5", b'P'), None);
        assert_eq!(word(b"S", b'S'), None);
    }

    #[test]
    fn the_message_keeps_twenty_printable_characters() {
        let mut h = HostState::new();
        h.set_message(b"Layer 3 of 10: roughing pass");
        assert_eq!(h.message(), b"Layer 3 of 10: rough");
        h.set_message(b"a\x01b");
        assert_eq!(h.message(), b"a?b");
        h.set_message(b"");
        assert_eq!(h.message(), b"");
        assert_eq!(h.percent(), None);
    }
}
