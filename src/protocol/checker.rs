//! Marlin/Repetier line numbers and checksums ([`LineChecker`]:
//! `N<n> … *<xor>`, M110, resends and giving a line up), and the small
//! readers they need (the checksum's `*`, a line's block number).

use super::ProtoError;

/// The position of a line's checksum `*`: the last `*` outside comments.
/// A `*` inside `( )` or after `;` is comment text (`( *** move *** )`).
///
/// Most lines hold no `(`, `)`, `*` or `;` at all: one quick pass looks
/// for the first of them (a range and a compare per byte), and only from
/// there is the line read with its comments
/// (`the_quick_star_scan_matches_the_plain_one`): 461 cycles a streamed
/// line on the AVR instead of 668 (`profile --trace`).
pub fn checksum_star(line: &[u8]) -> Option<usize> {
    let first = line.iter().position(|&b| b.wrapping_sub(b'(') <= b'*' - b'(' || b == b';')?;
    let mut paren = false;
    let mut star = None;
    for (i, &b) in line.iter().enumerate().skip(first) {
        match b {
            b')' if paren => paren = false,
            _ if paren => {}
            b'(' => paren = true,
            b';' => break,
            b'*' => star = Some(i),
            _ => {}
        }
    }
    star
}

/// Checks Marlin/Repetier line numbers and checksums (`N<n> <command>*<xor>`).
///
/// - `N<n> … *<cs>`: `cs` is the XOR of every byte before the last `*`
///   outside comments ([`checksum_star`]), starting at `N`. The line must be
///   number last+1, unless it is M110. A `*` inside a comment is text, in
///   any line.
/// - `N<n> M110 [N<m>]*<cs>` sets the last line number to `m`, or to `n`
///   without one (printcore sends `N-1 M110*cs`).
/// - A line with neither `N` nor `*` passes as it is (manual console); a bare
///   `M110 N<m>` still sets the last line number to `m`.
/// - `N<n> …` without `*` passes as it is, unchecked (grbl-style senders
///   stream files whose blocks carry their own N numbers); the parser skips
///   the leading `N<n>`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineChecker {
    /// Number of the last accepted numbered line.
    last: i32,
    /// Failed tries of line `last + 1` so far (see [`LineChecker::failed`]).
    tries: u8,
}

/// Tries of one numbered line that fail a protocol check (checksum, too
/// long, overrun, binary byte) before it is given up: no input can keep a
/// host resending the same line forever.
pub const MAX_TRIES: u8 = 3;

/// What to tell the host after a numbered line failed its checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Retry {
    /// `Resend:<n>`: send line `n` again.
    Resend(i32),
    /// Line `n` failed [`MAX_TRIES`] times: it is given up (not run) and the
    /// next line expected is `n + 1`.
    GiveUp(i32),
}

impl LineChecker {
    /// A checker whose last line number is 0.
    pub const fn new() -> Self {
        LineChecker { last: 0, tries: 0 }
    }

    /// The next line (`last + 1`) failed a protocol check: ask for it again,
    /// or, at the [`MAX_TRIES`]th failure in a row, give it up and move the
    /// line number past it. A line-number error (the host sent a later line)
    /// is not a try and must not be reported here.
    pub fn failed(&mut self) -> Retry {
        let n = self.resend_line();
        self.tries = self.tries.saturating_add(1);
        if self.tries >= MAX_TRIES {
            self.tries = 0;
            self.last = n;
            Retry::GiveUp(n)
        } else {
            Retry::Resend(n)
        }
    }

    /// Number of the last accepted line (printed as `Last Line: <n>`).
    pub fn last_line(&self) -> i32 {
        self.last
    }

    /// Number the host must resend after an error (`Resend: <n>`): last + 1.
    pub fn resend_line(&self) -> i32 {
        self.last.wrapping_add(1)
    }

    /// Check one assembled line. On success returns the command text, without
    /// the `N<n>` prefix and the `*<cs>` suffix, trimmed. On error the last
    /// line number is unchanged.
    pub fn check<'a>(&mut self, line: &'a [u8]) -> Result<&'a [u8], ProtoError> {
        self.check_marked(line, true)
    }

    /// [`check`](Self::check), told whether the line may hold a `(`, `)`,
    /// `*` or `;` (`LineAssembler::has_marks`): without any, it has no
    /// checksum and its `*` is not looked for. The same result as `check`
    /// (`checking_a_line_without_marks_skips_the_star_scan`): ~530 cycles a
    /// streamed line less on the AVR (`profile --trace`: `checksum_star`).
    pub fn check_marked<'a>(&mut self, line: &'a [u8], marks: bool) -> Result<&'a [u8], ProtoError> {
        let line = trim(line);
        let star = if marks { checksum_star(line) } else { None };
        let numbered = matches!(line.first(), Some(b'N' | b'n'));
        if !numbered {
            // A `$` line is grbl's and never checksummed (`$RST=*`).
            if star.is_some() && line.first() != Some(&b'$') {
                return Err(ProtoError::MissingLineNumber);
            }
            if let Some(m) = m110_param(line) {
                self.last = m;
            }
            return Ok(line);
        }
        // `N<n>` without a checksum: a file streamed by a grbl-style sender
        // (Fusion/HAAS posts number every block, N10, N20, …). Not part of
        // the resend protocol: no sequence check, and the parser skips the N.
        let Some(star) = star else {
            return Ok(line);
        };
        let (body, tail) = line.split_at(star);
        let sum = body.iter().fold(0u8, |acc, &b| acc ^ b);
        if parse_checksum(tail.get(1..).unwrap_or(&[])) != Some(sum) {
            return Err(ProtoError::Checksum);
        }
        let (n, used) = parse_i32(body.get(1..).unwrap_or(&[])).ok_or(ProtoError::BadLineNumber)?;
        let command = trim(body.get(1 + used..).unwrap_or(&[]));
        if is_m110(command) {
            self.last = m110_param(command).unwrap_or(n);
        } else if n != self.last.wrapping_add(1) {
            return Err(ProtoError::LineNumber);
        } else {
            self.last = n;
        }
        self.tries = 0;
        Ok(command)
    }
}

/// Strip leading and trailing spaces and tabs. Inline: every line comes
/// here, usually with nothing to strip (two compares).
// speed: every line comes here, usually for two compares
#[inline(always)]
pub(super) fn trim(mut s: &[u8]) -> &[u8] {
    while let [b' ' | b'\t', rest @ ..] = s {
        s = rest;
    }
    while let [rest @ .., b' ' | b'\t'] = s {
        s = rest;
    }
    s
}

/// Parse blanks, an optional sign and decimal digits into an i32. Returns the
/// value and the bytes used; `None` without digits or on overflow.
fn parse_i32(s: &[u8]) -> Option<(i32, usize)> {
    let mut i = 0;
    while matches!(s.get(i), Some(b' ' | b'\t')) {
        i += 1;
    }
    let negative = match s.get(i) {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    let start = i;
    // At most 10 digits, accumulated in a u32 with the range checked before
    // each digit: no overflow-checked multiply (i32::checked_mul hung on AVR,
    // through compiler-builtins' __mulosi4) and no 64-bit arithmetic.
    let mut v: u32 = 0;
    while let Some(&d) = s.get(i) {
        if !d.is_ascii_digit() {
            break;
        }
        if i - start >= 10 || v > 214_748_364 {
            // Too long, or the next digit takes it past i32 either way.
            return None;
        }
        v = v * 10 + (d - b'0') as u32;
        i += 1;
    }
    if i == start {
        return None;
    }
    let limit = if negative { 1u32 << 31 } else { i32::MAX as u32 };
    if v > limit {
        return None;
    }
    let v = v as i32;
    Some((if negative { v.wrapping_neg() } else { v }, i))
}

/// The checksum after `*`: decimal 0..=255, blanks around it allowed.
fn parse_checksum(s: &[u8]) -> Option<u8> {
    let s = trim(s);
    if s.is_empty() || s.len() > 3 || !s.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let v = s.iter().fold(0u16, |acc, &d| acc * 10 + (d - b'0') as u16);
    u8::try_from(v).ok()
}

/// True if the command is M110 (not M1100), case-insensitive.
fn is_m110(cmd: &[u8]) -> bool {
    match cmd {
        [m, b'1', b'1', b'0', rest @ ..] if m.eq_ignore_ascii_case(&b'M') => {
            !matches!(rest.first(), Some(d) if d.is_ascii_digit() || *d == b'.')
        }
        _ => false,
    }
}

/// For an M110 command, its own `N<m>` parameter. Inline, the first byte
/// is tested before the call: every unnumbered line comes here.
// speed: the first-byte test inline, the rest a call (m110_param_of)
#[inline(always)]
fn m110_param(cmd: &[u8]) -> Option<i32> {
    if !matches!(cmd.first(), Some(b'M' | b'm')) {
        return None;
    }
    m110_param_of(cmd)
}

/// The block number a line starts with (`N10 G1 …`; the parser skips it),
/// low 16 bits; 0 without one (or a negative one).
pub fn block_number(text: &[u8]) -> u16 {
    match trim(text).split_first() {
        Some((b'N' | b'n', rest)) => parse_i32(rest).map_or(0, |(v, _)| if v < 0 { 0 } else { v as u16 }),
        _ => 0,
    }
}

/// [`m110_param`] past its first-byte test.
fn m110_param_of(cmd: &[u8]) -> Option<i32> {
    if !is_m110(cmd) {
        return None;
    }
    let rest = cmd.get(4..)?;
    let n = rest.iter().position(|b| b.eq_ignore_ascii_case(&b'N'))?;
    parse_i32(rest.get(n + 1..)?).map(|(v, _)| v)
}
