//! Host line protocol (docs/SPEC.md §4): bytes in, checked command text out.
//!
//! ```text
//!  USART0 RX ISR ── MCodeScanner (M112, M108), RxText (? ! ~ 0x18 taken out,
//!                   except ? ! ~ inside a comment or a numbered line)
//!       │ 256-byte ring
//!       ▼
//!  main loop ─► LineAssembler (lines ≤ MAX_LINE_LEN, garbage and overruns flagged)
//!            ─► LineChecker   (Marlin/Repetier `N<n> … *<xor>`, M110)
//!            ─► gcode::parse
//! ```
//!
//! Everything here is pure: no I/O, no allocation, no panics. The firmware
//! owns the replies. For a rejected line it prints
//! `Error:<message>, Last Line: <last>`, then `Resend:<last+1>`, then `ok`
//! (Marlin's format, which Pronterface/printcore, Repetier-Host and OctoPrint
//! understand); see [`ProtoError::message`] and [`LineChecker::resend_line`].

/// Longest accepted line, in characters from its first to its last non-blank
/// (blanks at either end and the terminator do not count): 256, LinuxCNC's
/// limit. A longer line is rejected whole ([`Assembled::TooLong`]), never
/// truncated and run. RAM: the assembler's buffer, plus a copy of the line on
/// the stack while it runs, plus the SD job's line buffer.
pub const MAX_LINE_LEN: usize = 256;

/// True for the bytes that can be realtime commands: `?` (status), `!` (feed
/// hold), `~` (resume) and 0x18 (Ctrl-X, grbl's soft reset). Whether one is
/// taken out of the stream depends on where it arrives: see [`RxText`].
#[inline]
pub fn is_realtime(b: u8) -> bool {
    matches!(b, b'?' | b'!' | b'~' | SOFT_RESET)
}

/// Ctrl-X: grbl's soft reset, a realtime byte wherever it arrives.
pub const SOFT_RESET: u8 = 0x18;

/// [`RxText`] state bits.
const T_START: u8 = 1 << 0;
const T_NUMBERED: u8 = 1 << 1;
const T_PAREN: u8 = 1 << 2;
const T_SEMI: u8 = 1 << 3;

/// The RX ISR's view of the line being received, so that `?`, `!`, `~` are
/// realtime commands only where they cannot be text (one byte of state).
///
/// Inside a comment (`( … )` or after `;`) and anywhere in a numbered line
/// (first non-blank character `N`, Marlin/Repetier's `N<n> … *<xor>`) they
/// are text: they reach the line buffer and the checksum covers them.
/// Elsewhere (grbl hosts send them between or inside unnumbered lines) they
/// are taken out and act at once. 0x18 (soft reset) always acts.
///
/// After lost bytes the state is "mid-line, no comment": a lost `(` or `N`
/// can only make a `?`, `!`, `~` act that was meant as text, never the other
/// way round.
///
/// The RX ISR's assembly fast path skips [`RxText::classify`] for the usual
/// bytes: while [`RxText::at_line_start`] is false, a byte from 0x20 to 0x7D
/// other than `!`, `?`, `(`, `)`, `;` changes nothing
/// (`the_fast_path_bytes_change_nothing` checks it for every state). It also
/// does `classify`'s work for the two bytes every line has, writing the
/// state byte itself (hence `repr(transparent)`): a line end (`\n`, `\r`)
/// in any state gives [`RxText::LINE_START`], and at a line start (the
/// state is then exactly `LINE_START`) one of those usual bytes other than
/// a blank, `N` or `n` gives [`RxText::MID_LINE`]
/// (`the_fast_path_line_ends_and_line_starts`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(transparent)]
pub struct RxText {
    state: u8,
}

impl Default for RxText {
    fn default() -> Self {
        Self::new()
    }
}

impl RxText {
    /// The state byte at the start of a line (the only state in which
    /// [`RxText::at_line_start`] is true).
    pub const LINE_START: u8 = T_START;
    /// The state byte in the middle of a line, outside comments, not numbered.
    pub const MID_LINE: u8 = 0;

    /// At the start of a line.
    pub const fn new() -> Self {
        RxText { state: T_START }
    }

    /// True while only blanks were received since the line began: the next
    /// byte may make the line a numbered one, so it must see `classify`.
    #[inline(always)]
    pub fn at_line_start(&self) -> bool {
        self.state & T_START != 0
    }

    /// Bytes were lost: assume mid-line, outside any comment.
    pub fn note_loss(&mut self) {
        self.state = 0;
    }

    /// Classify the received byte `b`: true when it is a realtime command
    /// (taken out of the stream), false when it is text (the state follows it).
    #[inline(always)]
    pub fn classify(&mut self, b: u8) -> bool {
        if b == SOFT_RESET {
            // The main loop drops the line in progress: a new one starts.
            self.state = T_START;
            return true;
        }
        let s = self.state;
        if matches!(b, b'?' | b'!' | b'~') && s & (T_NUMBERED | T_PAREN | T_SEMI) == 0 {
            return true;
        }
        // grbl takes every byte from 0x80 up out of the stream (its realtime
        // overrides; the rest dropped), wherever it falls, so that none can
        // spoil the line it lands in. A numbered line keeps its bytes: its
        // checksum counts them.
        if b >= 0x80 && s & T_NUMBERED == 0 {
            return true;
        }
        self.state = match b {
            b'\n' | b'\r' => T_START,
            _ if s & T_PAREN != 0 => {
                if b == b')' {
                    s & !T_PAREN
                } else {
                    s
                }
            }
            _ if s & T_SEMI != 0 => s,
            b' ' | b'\t' => s,
            b'(' => (s & !T_START) | T_PAREN,
            b';' => (s & !T_START) | T_SEMI,
            b'N' | b'n' if s & T_START != 0 => T_NUMBERED,
            _ => s & !T_START,
        };
        false
    }
}

crate::flash_messages! {
    /// A line-level protocol error: the line is dropped and the host is asked to
    /// resend it (`message`: the text printed after `Error:`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum ProtoError {
        /// The XOR of the bytes before `*` differs from the number after it.
        Checksum => "checksum mismatch",
        /// `N<n>` is not the last line number + 1 (and the line is not M110).
        LineNumber => "line number is not last line number+1",
        /// `N<n>` without `*<checksum>`.
        MissingChecksum => "no checksum with line number",
        /// `*<checksum>` without a leading `N<n>`.
        MissingLineNumber => "no line number with checksum",
        /// `N` not followed by an integer that fits in an i32.
        BadLineNumber => "bad line number",
        /// The line was longer than [`MAX_LINE_LEN`].
        TooLong => "line too long",
        /// The RX ring overflowed while this line arrived: bytes are missing.
        Overrun => "serial receive overrun, line dropped",
        /// The line held a non-ASCII or control byte (other than tab).
        BadByte => "binary or control byte in line",
    }
}

/// `b` as text when it is all ASCII, else "". (`core::str::from_utf8`
/// would put core's 256-byte UTF-8 width table in RAM on the AVR.)
pub fn ascii_str(b: &[u8]) -> &str {
    if !b.is_ascii() {
        return "";
    }
    // SAFETY: every byte is ASCII, so `b` is valid UTF-8.
    unsafe { core::str::from_utf8_unchecked(b) }
}

/// What [`LineAssembler::push`] reports when a line ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Assembled {
    /// A complete, non-empty line: read it with [`LineAssembler::line`].
    Line,
    /// The line was longer than [`MAX_LINE_LEN`]; it is dropped.
    TooLong,
    /// [`LineAssembler::mark_overrun`] was called during this line; it is dropped.
    Overrun,
    /// The line held a byte outside printable ASCII and tab; it is dropped.
    BadByte,
}

impl Assembled {
    /// The protocol error for a dropped line, `None` for [`Assembled::Line`].
    pub fn error(self) -> Option<ProtoError> {
        match self {
            Assembled::Line => None,
            Assembled::TooLong => Some(ProtoError::TooLong),
            Assembled::Overrun => Some(ProtoError::Overrun),
            Assembled::BadByte => Some(ProtoError::BadByte),
        }
    }
}

/// Flag bits of [`LineAssembler`].
const F_TOO_LONG: u8 = 1 << 0;
const F_OVERRUN: u8 = 1 << 1;
const F_BAD_BYTE: u8 = 1 << 2;
/// The last push completed a line that `line()` may return.
const F_READY: u8 = 1 << 3;

/// The UTF-8 byte-order mark that Windows editors write at the start of a
/// file: text, not data. Skipped at the start of a line.
pub const BOM: [u8; 3] = [0xEF, 0xBB, 0xBF];

/// [`LineCut`] state bits.
const C_PAREN: u8 = 1 << 0;
const C_SEMI: u8 = 1 << 1;
/// This `( )` comment overflowed: its text is dropped, its `)` stored.
const C_SKIP: u8 = 1 << 2;
/// This `( )` comment is not stored at all (no room for `()`).
const C_HIDDEN: u8 = 1 << 3;
/// Comment text was dropped from this line.
const C_CUT: u8 = 1 << 4;

/// What to do with the next byte of a line (see [`LineCut::keep`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Keep {
    /// Store it.
    Store,
    /// Comment text past the buffer: drop it, the line stays good.
    Drop,
    /// The `( )` comment in progress overflowed: drop this byte and the
    /// comment's stored text, back to just after the last `(` stored.
    Fold,
    /// Code past the buffer: the line is too long.
    Full,
}

/// Where the bytes of a line fall (code, a `( )` comment, a `;` comment)
/// and so what happens when a line runs past [`MAX_LINE_LEN`]: as in grbl,
/// comment text past the buffer is dropped (a Fusion 360 header line is
/// mostly comment), code past it makes the line too long. A `( )` comment
/// that overflows is folded to `()`, so the code after it still has the
/// room it had; what is stored always parses as the line did. One byte; the
/// serial assembler and the SD reader each keep one for the line in
/// progress.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineCut(u8);

impl LineCut {
    /// At the start of a line.
    pub const fn new() -> Self {
        LineCut(0)
    }

    /// True inside a comment: bytes from 0x80 up are text there (UTF-8,
    /// Latin-1), not data.
    #[inline]
    pub fn in_comment(self) -> bool {
        self.0 & (C_PAREN | C_SEMI) != 0
    }

    /// True when comment text was dropped from this line.
    pub fn cut(self) -> bool {
        self.0 & C_CUT != 0
    }

    /// Classify the next byte `b` (not a line end) of a line that holds
    /// `len` bytes so far. A `( )` comment's text is stored only while a
    /// slot is left for its `)`.
    pub fn keep(&mut self, b: u8, len: usize) -> Keep {
        let s = self.0;
        if s & C_SEMI != 0 {
            if len < MAX_LINE_LEN {
                return Keep::Store;
            }
            self.0 |= C_CUT;
            return Keep::Drop;
        }
        if s & C_PAREN != 0 {
            if b == b')' {
                self.0 = s & !(C_PAREN | C_SKIP | C_HIDDEN);
                return if s & C_HIDDEN != 0 { Keep::Drop } else { Keep::Store };
            }
            if s & (C_SKIP | C_HIDDEN) != 0 {
                return Keep::Drop;
            }
            if len + 1 < MAX_LINE_LEN {
                return Keep::Store;
            }
            self.0 |= C_SKIP | C_CUT;
            return Keep::Fold;
        }
        match b {
            b'(' if len + 2 > MAX_LINE_LEN => {
                self.0 |= C_PAREN | C_HIDDEN | C_CUT;
                Keep::Drop
            }
            b'(' => {
                self.0 |= C_PAREN;
                Keep::Store
            }
            b';' if len == MAX_LINE_LEN => {
                self.0 |= C_SEMI | C_CUT;
                Keep::Drop
            }
            b';' => {
                self.0 |= C_SEMI;
                Keep::Store
            }
            _ if len < MAX_LINE_LEN => Keep::Store,
            _ => Keep::Full,
        }
    }
}

/// The length a line keeps after [`Keep::Fold`]: up to and with the last
/// `(` stored (the comment's own, or a `(` inside its text, which leaves a
/// comment that reads the same).
pub fn folded_len(line: &[u8]) -> usize {
    line.iter().rposition(|&c| c == b'(').map_or(line.len(), |i| i + 1)
}

/// The position of a line's checksum `*`: the last `*` outside comments.
/// A `*` inside `( )` or after `;` is comment text (`( *** move *** )`).
pub fn checksum_star(line: &[u8]) -> Option<usize> {
    let mut paren = false;
    let mut star = None;
    for (i, &b) in line.iter().enumerate() {
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

/// The byte the serial RX ISR stores in its ring at the place where it had to
/// drop received bytes (ring full, or a UART overrun). The assembler turns it
/// into [`LineAssembler::mark_overrun`], so exactly the damaged line is
/// dropped, wherever the main loop happens to be reading when the loss
/// occurs. A real 0xFF from the host is stored as 0xFE: still a bad byte.
pub const RX_GAP: u8 = 0xFF;

/// The RX ISR's side of [`RX_GAP`]: stores received bytes into a ring and,
/// after a loss, a gap marker before the next byte that fits. One byte of
/// state; the ring is any `enqueue` that can refuse.
///
/// With no gap pending, storing a byte other than [`RX_GAP`] is just
/// `enqueue(b)`, and only a refusal changes the state: the RX ISR's fast
/// path stores such bytes itself and leaves everything else to `store`.
#[derive(Default)]
pub struct RxStore {
    gap: bool,
}

impl RxStore {
    pub const fn new() -> Self {
        RxStore { gap: false }
    }

    /// True while a gap marker waits to be stored.
    pub fn gap_pending(&self) -> bool {
        self.gap
    }

    /// Bytes were lost before the next one (the UART's data overrun flag).
    pub fn note_loss(&mut self) {
        self.gap = true;
    }

    /// Store `b`; `enqueue` returns false when the ring is full. After a
    /// loss the gap marker goes first, then `b`; whatever does not fit is
    /// dropped and leaves the gap pending. (`enqueue` has one call site, so
    /// that it is inlined into the ISR.)
    #[inline(always)]
    pub fn store(&mut self, b: u8, mut enqueue: impl FnMut(u8) -> bool) {
        let b = if b == RX_GAP { RX_GAP - 1 } else { b };
        let mut x = if self.gap { RX_GAP } else { b };
        loop {
            if !enqueue(x) {
                self.gap = true;
                return;
            }
            self.gap = false;
            if x == b {
                return;
            }
            x = b;
        }
    }
}

/// Collects bytes into lines in a fixed buffer (RAM: `MAX_LINE_LEN` + 3 bytes).
///
/// `\n` or `\r` ends a line, so `\r\n` gives one line and one ignored empty
/// line. Leading blanks are not stored; trailing blanks are trimmed. Blank
/// lines give no result, hence no `ok`.
pub struct LineAssembler {
    buf: [u8; MAX_LINE_LEN],
    /// Bytes stored for the line in progress (or of the completed line while
    /// `F_READY` is set), ≤ MAX_LINE_LEN.
    len: u16,
    /// `F_*` bits.
    flags: u8,
    /// The last dropped line started with `N` (see [`LineAssembler::dropped_numbered`]).
    dropped_n: bool,
    /// Comments of the line in progress (1 byte).
    cut: LineCut,
}

impl Default for LineAssembler {
    fn default() -> Self {
        Self::new()
    }
}

impl LineAssembler {
    /// An empty assembler.
    pub const fn new() -> Self {
        LineAssembler { buf: [0; MAX_LINE_LEN], len: 0, flags: 0, dropped_n: false, cut: LineCut::new() }
    }

    /// True when the line just reported as dropped (too long, overrun, bad
    /// byte) started with `N`: a numbered line, to be asked for again.
    pub fn dropped_numbered(&self) -> bool {
        self.dropped_n
    }

    /// Feed one byte from the RX ring. Returns `Some` when a line ends; after
    /// `Some(Assembled::Line)`, [`line`](Self::line) holds its text until the
    /// next push.
    pub fn push(&mut self, b: u8) -> Option<Assembled> {
        if self.flags & F_READY != 0 {
            self.flags = 0;
            self.len = 0;
        }
        match b {
            b'\n' | b'\r' => self.finish(),
            RX_GAP => {
                self.mark_overrun();
                None
            }
            // Blanks before the text are not stored; blanks that arrive with
            // the buffer full are dropped, since only a later non-blank can
            // make the line too long.
            b' ' | b'\t' if self.len == 0 || self.len as usize == MAX_LINE_LEN => None,
            _ => {
                let len = self.len as usize;
                if b >= 0x80 && !self.cut.in_comment() {
                    // Text, not data: a byte-order mark at the start of the
                    // line is dropped once whole (`finish` refuses a part).
                    if len < BOM.len() && self.buf.get(..len) == BOM.get(..len) && BOM.get(len) == Some(&b) {
                        if len + 1 == BOM.len() {
                            self.len = 0;
                            return None;
                        }
                    } else {
                        self.flags |= F_BAD_BYTE;
                    }
                } else if (b < 0x20 && b != b'\t') || b == 0x7f {
                    self.flags |= F_BAD_BYTE;
                }
                match self.cut.keep(b, len) {
                    Keep::Store => {
                        if let Some(slot) = self.buf.get_mut(len) {
                            *slot = b;
                            self.len += 1;
                        }
                    }
                    Keep::Drop => {}
                    Keep::Fold => self.len = folded_len(self.buf.get(..len).unwrap_or(&[])) as u16,
                    Keep::Full => self.flags |= F_TOO_LONG,
                }
                None
            }
        }
    }

    /// The RX ring dropped bytes: the line in progress is reported as
    /// [`Assembled::Overrun`] when it ends, even if what arrived of it is blank
    /// (the lost bytes may have held whole lines).
    ///
    /// Call it just before pushing the first byte that the ISR stored after it
    /// dropped one, so that the damaged line, not an earlier one, is marked.
    pub fn mark_overrun(&mut self) {
        if self.flags & F_READY != 0 {
            self.flags = 0;
            self.len = 0;
        }
        self.flags |= F_OVERRUN;
    }

    /// Forget the line in progress (after an e-stop, or when a job aborts).
    pub fn reset(&mut self) {
        self.flags = 0;
        self.len = 0;
        self.cut = LineCut::new();
    }

    /// The line completed by the last [`push`](Self::push), trimmed, without
    /// its terminator. Empty unless that push returned `Some(Assembled::Line)`.
    pub fn line(&self) -> &[u8] {
        if self.flags & F_READY == 0 {
            return &[];
        }
        self.buf.get(..self.len as usize).unwrap_or(&[])
    }

    /// End of line: classify it and set up `line()`.
    fn finish(&mut self) -> Option<Assembled> {
        let flags = self.flags;
        // Trim trailing blanks (leading ones were never stored).
        while self.len > 0 && matches!(self.buf.get(self.len as usize - 1), Some(b' ' | b'\t')) {
            self.len -= 1;
        }
        let line = self.buf.get(..self.len as usize).unwrap_or(&[]);
        // Comment text was dropped from a checksummed line: its checksum
        // covered that text and can no longer be checked.
        let cut_checksum = self.cut.cut() && matches!(line.first(), Some(b'N' | b'n')) && checksum_star(line).is_some();
        self.cut = LineCut::new();
        let result = if flags & F_OVERRUN != 0 {
            Some(Assembled::Overrun)
        } else if flags & F_TOO_LONG != 0 || cut_checksum {
            Some(Assembled::TooLong)
        } else if flags & F_BAD_BYTE != 0 || line.first() == BOM.first() {
            Some(Assembled::BadByte)
        } else if self.len == 0 {
            None
        } else {
            Some(Assembled::Line)
        };
        if result == Some(Assembled::Line) {
            self.flags = F_READY;
        } else {
            self.dropped_n = self.len > 0 && matches!(self.buf.first(), Some(b'N' | b'n'));
            self.flags = 0;
            self.len = 0;
        }
        result
    }
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
        let line = trim(line);
        let star = checksum_star(line);
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
#[inline(always)]
fn trim(mut s: &[u8]) -> &[u8] {
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
#[inline(never)]
fn m110_param_of(cmd: &[u8]) -> Option<i32> {
    if !is_m110(cmd) {
        return None;
    }
    let rest = cmd.get(4..)?;
    let n = rest.iter().position(|b| b.eq_ignore_ascii_case(&b'N'))?;
    parse_i32(rest.get(n + 1..)?).map(|(v, _)| v)
}

/// What [`MCodeScanner::feed`] spotted on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Urgent {
    /// Nothing: the usual answer.
    Nothing,
    /// `M112`, emergency stop.
    Estop,
    /// `M108`, continue after M0/M1 (Marlin's emergency parser takes it too).
    Continue,
}

/// Watches the raw RX stream inside the ISR for the two M-codes that act as
/// the bytes arrive, not when the line is parsed (docs/SPEC.md §4): `M112` and
/// `M108`. One byte of state, O(1) per byte; the caller keeps the previous
/// byte, which only matters before an `M`.
///
/// Triggers on `M112` / `M108` (any case, no blanks inside) that does not
/// follow a letter, once the next byte shows it is not a longer number:
/// `M112\n`, `N7 M112*40`, `G0M112 ` trigger; `M1120`, `M11 2`, `AM112.GCO`
/// do not. It does not know about comments: `(M112)` triggers, which errs on
/// the safe side.
///
/// Most bytes neither start a match (no `M`) nor continue one, and
/// [`MCodeScanner::ignores`] says so with one compare: the RX ISR's fast
/// path checks that itself and skips the scanner for those bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MCodeScanner {
    /// How much of `M112` / `M108` matched: one of the `S_*` states.
    state: u8,
}

/// [`MCodeScanner`] states: the prefix matched so far (0: none).
const S_M: u8 = 1;
const S_M1: u8 = 2;
const S_M11: u8 = 3;
const S_M112: u8 = 4;
const S_M10: u8 = 5;
const S_M108: u8 = 6;

impl MCodeScanner {
    /// A scanner that has seen nothing.
    pub const fn new() -> Self {
        MCodeScanner { state: 0 }
    }

    /// True when nothing is matched.
    pub fn is_idle(&self) -> bool {
        self.state == 0
    }

    /// True when feeding `b` changes nothing and finds nothing: nothing is
    /// matched and `b` is no `M` or `m`.
    #[inline(always)]
    pub fn ignores(&self, b: u8) -> bool {
        self.state == 0 && b | 0x20 != b'm'
    }

    /// Feed one received byte `b`; `prev` is the byte fed before it (any
    /// non-letter at the start). Says which code `b` completes, if any.
    #[inline(always)]
    pub fn feed(&mut self, prev: u8, b: u8) -> Urgent {
        if self.ignores(b) {
            return Urgent::Nothing;
        }
        let mut found = Urgent::Nothing;
        let next = match (self.state, b) {
            (S_M112 | S_M108, b'0'..=b'9') => 0,
            (S_M112, _) => {
                found = Urgent::Estop;
                0
            }
            (S_M108, _) => {
                found = Urgent::Continue;
                0
            }
            (S_M, b'1') => S_M1,
            (S_M1, b'1') => S_M11,
            (S_M1, b'0') => S_M10,
            (S_M11, b'2') => S_M112,
            (S_M10, b'8') => S_M108,
            _ => 0,
        };
        // Only a non-digit ends a match, so an `M` may start the next one.
        self.state = if b | 0x20 == b'm' && !prev.is_ascii_alphabetic() { S_M } else { next };
        found
    }
}

/// What the RX ISR's assembly fast path may do with the next byte (the
/// `RX_SLOW` byte of `board::serial`, set by the slow path from
/// [`rx_fast_mode`]): store the usual bytes itself, ...
pub const RX_FAST: u8 = 0;
/// ... hand every byte to the slow path (an M-code match in progress, or a
/// gap marker pending), ...
pub const RX_ALL_SLOW: u8 = 1;
/// ... or, at the start of a line, also mark the line as begun for a first
/// byte that cannot make it a numbered one (see [`RxText`]). In this mode
/// and in [`RX_FAST`] it also takes line ends itself.
pub const RX_LINE_START: u8 = 2;

/// The fast-path mode after the slow path has handled a byte.
#[inline(always)]
pub fn rx_fast_mode(scan: &MCodeScanner, store: &RxStore, text: &RxText) -> u8 {
    if !scan.is_idle() || store.gap_pending() {
        RX_ALL_SLOW
    } else if text.at_line_start() {
        RX_LINE_START
    } else {
        RX_FAST
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_number_a_line_starts_with() {
        assert_eq!(block_number(b"N10 G1 X5"), 10);
        assert_eq!(block_number(b"  n7G0"), 7);
        assert_eq!(block_number(b"N70000 G0"), (70000u32 & 0xFFFF) as u16);
        assert_eq!(block_number(b"G1 N10"), 0);
        assert_eq!(block_number(b"N-5 G0"), 0);
        assert_eq!(block_number(b"N G0"), 0);
    }

    /// Feed `bytes`, collecting each result with its line text.
    fn assemble(a: &mut LineAssembler, bytes: &[u8]) -> Vec<(Assembled, Vec<u8>)> {
        let mut out = Vec::new();
        for &b in bytes {
            if let Some(r) = a.push(b) {
                out.push((r, a.line().to_vec()));
            }
        }
        out
    }

    fn xor(s: &[u8]) -> u8 {
        s.iter().fold(0, |a, &b| a ^ b)
    }

    /// `N<n> <cmd>` with its correct checksum.
    fn numbered(n: i32, cmd: &str) -> Vec<u8> {
        let body = format!("N{} {}", n, cmd);
        format!("{}*{}", body, xor(body.as_bytes())).into_bytes()
    }

    #[test]
    fn realtime_bytes_are_question_bang_tilde_and_ctrl_x() {
        assert!(is_realtime(b'?') && is_realtime(b'!') && is_realtime(b'~') && is_realtime(0x18));
        assert!(!is_realtime(b'G') && !is_realtime(b'\n') && !is_realtime(b'*'));
    }

    /// The bytes of `stream` that `RxText` takes out as realtime commands,
    /// and the text that is left.
    fn split_realtime(stream: &[u8]) -> (Vec<u8>, Vec<u8>) {
        let mut t = RxText::new();
        let (mut rt, mut text) = (Vec::new(), Vec::new());
        for &b in stream {
            if t.classify(b) {
                rt.push(b);
            } else {
                text.push(b);
            }
        }
        (rt, text)
    }

    #[test]
    fn realtime_bytes_in_comments_and_numbered_lines_are_text() {
        assert_eq!(split_realtime(b"G0 X5 Y5 (is this right?)\n"), (vec![], b"G0 X5 Y5 (is this right?)\n".to_vec()));
        assert_eq!(split_realtime(b"(Warning! check the clamp)\n").0, vec![]);
        assert_eq!(split_realtime(b"G1 X1 ; ok? ~!\n").0, vec![]);
        assert_eq!(split_realtime(b"  N12 G1 X1 ?!~*99\n").0, vec![]);
        assert_eq!(split_realtime(b"n3 M117 Hi!*1\n").0, vec![]);
        // Outside those: realtime, wherever in the line.
        assert_eq!(split_realtime(b"G1 X?1 (a) !\n~G1 Y1 N2\n"), (b"?!~".to_vec(), b"G1 X1 (a) \nG1 Y1 N2\n".to_vec()));
        // The comment and the numbered line end with the line.
        assert_eq!(split_realtime(b"(open\n?N1*3\n!;x\n~").0, b"?!~".to_vec());
        // Ctrl-X always acts, and the line after it starts afresh.
        assert_eq!(split_realtime(b"N1 (\x18)\x18\n").0, vec![0x18, 0x18]);
        assert_eq!(split_realtime(b"N1 (a\x18?").0, vec![0x18, b'?']);
    }

    #[test]
    fn after_a_loss_realtime_bytes_act() {
        let mut t = RxText::new();
        for &b in b"N1 G1 (" {
            assert!(!t.classify(b));
        }
        t.note_loss();
        assert!(t.classify(b'!'));
        assert!(!t.at_line_start());
    }

    /// The rule, spelled out on the text of the line so far.
    fn rx_text_reference(line: &[u8], b: u8) -> bool {
        if b == 0x18 {
            return true;
        }
        let trimmed: Vec<u8> = line.iter().copied().skip_while(|c| *c == b' ' || *c == b'\t').collect();
        let numbered = matches!(trimmed.first(), Some(b'N' | b'n'));
        // Bytes from 0x80 up leave every line but a numbered one, comments
        // included.
        if b >= 0x80 {
            return !numbered;
        }
        if !matches!(b, b'?' | b'!' | b'~') || numbered {
            return false;
        }
        let mut in_paren = false;
        for &c in line {
            match c {
                b'(' if !in_paren => in_paren = true,
                b')' if in_paren => in_paren = false,
                b';' if !in_paren => return false,
                _ => {}
            }
        }
        !in_paren
    }

    #[test]
    fn rx_text_matches_the_rule_on_random_streams() {
        const PIECES: &[&[u8]] = &[
            b"N",
            b"n",
            b" ",
            b"\t",
            b"(",
            b")",
            b";",
            b"?",
            b"!",
            b"~",
            b"\n",
            b"\r",
            b"G1",
            b"X5",
            b"*",
            b"\x18",
            b"M112",
            b"\xfe",
            b"\x00",
            b"\xc2\x91",
            b"\x85",
        ];
        let mut rng = XorShift(0x5EED);
        let mut t = RxText::new();
        let mut line: Vec<u8> = Vec::new();
        let (mut acted, mut kept) = (0, 0);
        for _ in 0..200_000 {
            for &b in PIECES[rng.next() as usize % PIECES.len()] {
                let want = rx_text_reference(&line, b);
                assert_eq!(t.classify(b), want, "{:?} then {:?}", String::from_utf8_lossy(&line), b as char);
                if want {
                    acted += 1;
                    if b == 0x18 {
                        line.clear();
                    }
                } else {
                    if matches!(b, b'?' | b'!' | b'~') {
                        kept += 1;
                    }
                    if b == b'\n' || b == b'\r' {
                        line.clear();
                    } else {
                        line.push(b);
                    }
                }
            }
        }
        assert!(acted > 5000 && kept > 5000, "{acted} acted, {kept} kept as text");
    }

    /// What the RX ISR's assembly fast path stores without calling the slow
    /// path: 0x20..=0x7D except `!` `?` `(` `)` `;` `M` `m`.
    fn fast_path_byte(b: u8) -> bool {
        (0x20..0x7e).contains(&b) && !matches!(b, b'!' | b'?' | b'(' | b')' | b';' | b'M' | b'm')
    }

    /// Every `RxText` state reachable from a line start, over any bytes and
    /// losses.
    fn reachable_text_states() -> Vec<u8> {
        let mut seen = vec![RxText::new().state];
        let mut i = 0;
        while i < seen.len() {
            let t0 = RxText { state: seen[i] };
            let mut next = vec![RxText::MID_LINE];
            for b in 0..=255u8 {
                let mut t = t0;
                t.classify(b);
                next.push(t.state);
            }
            for s in next {
                if !seen.contains(&s) {
                    seen.push(s);
                }
            }
            i += 1;
        }
        seen
    }

    /// The RX ISR's assembly fast path (`__vector_25` in `board/serial.rs`),
    /// step for step: stores `b` and updates `mode` and `text` when it
    /// takes the byte (true), or leaves everything to the slow path (false).
    fn asm_fast_path(mode: &mut u8, text: &mut RxText, prev: &mut u8, ring: &mut Vec<u8>, b: u8) -> bool {
        if b >= 0x7e {
            return false;
        }
        if b < 0x20 {
            if !(b == b'\n' || b == b'\r') || *mode == RX_ALL_SLOW {
                return false;
            }
            ring.push(b);
            *prev = b;
            text.state = RxText::LINE_START;
            *mode = RX_LINE_START;
            return true;
        }
        if matches!(b, b'!' | b'?' | b';' | b'(' | b')' | b'M' | b'm') {
            return false;
        }
        match *mode {
            RX_FAST => {}
            RX_LINE_START if b | 0x20 == b'n' => return false,
            RX_LINE_START if b == b' ' => {}
            RX_LINE_START => {
                text.state = RxText::MID_LINE;
                *mode = RX_FAST;
            }
            _ => return false,
        }
        ring.push(b);
        *prev = b;
        true
    }

    /// The RX ISR's slow path (`usart0_rx_slow`) on an unbounded ring,
    /// without losses; true when `b` was a realtime byte.
    fn slow_path(
        scan: &mut MCodeScanner,
        store: &mut RxStore,
        text: &mut RxText,
        prev: &mut u8,
        ring: &mut Vec<u8>,
        b: u8,
    ) -> (bool, Urgent) {
        let mut urgent = Urgent::Nothing;
        let realtime = text.classify(b);
        if !realtime {
            urgent = scan.feed(*prev, b);
            *prev = b;
            store.store(b, |x| {
                ring.push(x);
                true
            });
        }
        (realtime, urgent)
    }

    #[test]
    fn the_fast_path_line_ends_and_line_starts() {
        let states = reachable_text_states();
        assert!(states.len() >= 4, "{states:?}");
        for &state in &states {
            let t0 = RxText { state };
            if t0.at_line_start() {
                assert_eq!(state, RxText::LINE_START);
            }
            for b in *b"\n\r" {
                let mut t = t0;
                assert!(!t.classify(b));
                assert_eq!(t.state, RxText::LINE_START, "state {state:#x}");
            }
        }
        assert!(MCodeScanner::new().ignores(b'\n') && MCodeScanner::new().ignores(b'\r'));
        let mut n = 0;
        for b in 0..=255u8 {
            if fast_path_byte(b) && !matches!(b, b' ' | b'N' | b'n') {
                let mut t = RxText::new();
                assert!(!t.classify(b));
                assert_eq!(t.state, RxText::MID_LINE, "byte {b:#x}");
                n += 1;
            }
        }
        assert_eq!(n, 0x7e - 0x20 - 7 - 3);
        let mut t = RxText::new();
        assert!(!t.classify(b' '));
        assert_eq!(t.state, RxText::LINE_START);
    }

    /// The slow path alone and the fast path with the slow path behind it
    /// store the same bytes and end in the same states, byte for byte, over
    /// random streams of G-code-ish bytes (line ends, `N`, `M112`, comments,
    /// realtime bytes, Ctrl-X).
    #[test]
    fn the_fast_path_twin_matches_the_slow_path() {
        const ALPHABET: &[u8] = b"G1 X2.5Y-3\n\r\n\nNnMm1128(;)?!~\x18\tZ*0 \n";
        let mut seed = 0x2545_F491_u32;
        let mut fast_bytes = 0;
        for _ in 0..400 {
            let (mut scan_a, mut store_a, mut text_a, mut prev_a, mut ring_a) =
                (MCodeScanner::new(), RxStore::new(), RxText::new(), 0u8, Vec::new());
            let (mut scan_b, mut store_b, mut text_b, mut prev_b, mut ring_b) =
                (MCodeScanner::new(), RxStore::new(), RxText::new(), 0u8, Vec::new());
            let mut mode = rx_fast_mode(&scan_b, &store_b, &text_b);
            for _ in 0..200 {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                let b = ALPHABET[seed as usize % ALPHABET.len()];
                let (rt_a, urgent_a) = slow_path(&mut scan_a, &mut store_a, &mut text_a, &mut prev_a, &mut ring_a, b);
                if asm_fast_path(&mut mode, &mut text_b, &mut prev_b, &mut ring_b, b) {
                    fast_bytes += 1;
                    assert!(!rt_a && urgent_a == Urgent::Nothing, "byte {b:#x}");
                } else {
                    let (rt_b, urgent_b) = slow_path(&mut scan_b, &mut store_b, &mut text_b, &mut prev_b, &mut ring_b, b);
                    assert_eq!((rt_a, urgent_a), (rt_b, urgent_b));
                    mode = rx_fast_mode(&scan_b, &store_b, &text_b);
                }
                assert_eq!((text_a, scan_a, prev_a), (text_b, scan_b, prev_b));
                assert_eq!(mode, rx_fast_mode(&scan_a, &store_a, &text_a));
            }
            assert_eq!(ring_a, ring_b);
        }
        assert!(fast_bytes > 20_000, "{fast_bytes}");
    }

    #[test]
    fn the_fast_path_bytes_change_nothing() {
        let mut n = 0;
        for state in 0..16u8 {
            let t0 = RxText { state };
            if t0.at_line_start() {
                continue;
            }
            for b in 0..=255u8 {
                if fast_path_byte(b) {
                    let mut t = t0;
                    assert!(!t.classify(b));
                    assert_eq!(t, t0, "state {state:#x}, byte {b:#x}");
                    n += 1;
                }
            }
        }
        assert_eq!(n, 8 * (0x7e - 0x20 - 7));
    }

    #[test]
    fn newline_or_carriage_return_ends_a_trimmed_line() {
        let mut a = LineAssembler::new();
        let out = assemble(&mut a, b"  G1 X10 \t\r\nM114\n");
        assert_eq!(out, vec![(Assembled::Line, b"G1 X10".to_vec()), (Assembled::Line, b"M114".to_vec())]);
    }

    #[test]
    fn blank_lines_give_no_result() {
        let mut a = LineAssembler::new();
        assert!(assemble(&mut a, b"\n\r\n   \t \n\r\r").is_empty());
    }

    #[test]
    fn line_is_empty_when_no_line_just_completed() {
        let mut a = LineAssembler::new();
        assert_eq!(a.push(b'G'), None);
        assert_eq!(a.line(), b"");
        assert_eq!(a.push(b'\n'), Some(Assembled::Line));
        assert_eq!(a.line(), b"G");
        assert_eq!(a.push(b'X'), None);
        assert_eq!(a.line(), b"");
    }

    #[test]
    fn a_line_of_exactly_max_len_is_accepted() {
        let mut a = LineAssembler::new();
        let mut bytes = vec![b'X'; MAX_LINE_LEN];
        bytes.push(b'\n');
        let out = assemble(&mut a, &bytes);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].0, Assembled::Line);
        assert_eq!(out[0].1.len(), MAX_LINE_LEN);
    }

    #[test]
    fn an_over_long_line_is_rejected_whole_and_the_next_line_is_clean() {
        let mut a = LineAssembler::new();
        let mut bytes = vec![b'Y'; MAX_LINE_LEN + 1];
        bytes.extend_from_slice(b"\nG0 X1\n");
        let out = assemble(&mut a, &bytes);
        assert_eq!(out, vec![(Assembled::TooLong, vec![]), (Assembled::Line, b"G0 X1".to_vec())]);
        assert_eq!(Assembled::TooLong.error(), Some(ProtoError::TooLong));
    }

    #[test]
    fn trailing_blanks_do_not_count_toward_the_limit() {
        let mut a = LineAssembler::new();
        let mut bytes = vec![b'X'; MAX_LINE_LEN];
        bytes.extend([b' '; 200]);
        bytes.push(b'\n');
        let out = assemble(&mut a, &bytes);
        assert_eq!(out, vec![(Assembled::Line, vec![b'X'; MAX_LINE_LEN])]);
    }

    #[test]
    fn text_after_blanks_past_the_limit_is_too_long() {
        let mut a = LineAssembler::new();
        let mut bytes = vec![b'X'; MAX_LINE_LEN];
        bytes.extend_from_slice(b"   Y\n");
        assert_eq!(assemble(&mut a, &bytes), vec![(Assembled::TooLong, vec![])]);
    }

    #[test]
    fn leading_blanks_do_not_count_toward_the_limit() {
        let mut a = LineAssembler::new();
        let mut bytes = vec![b' '; 50];
        bytes.extend(vec![b'Z'; MAX_LINE_LEN]);
        bytes.push(b'\n');
        let out = assemble(&mut a, &bytes);
        assert_eq!(out[0].0, Assembled::Line);
    }

    #[test]
    fn an_overrun_drops_the_line_in_progress_only() {
        let mut a = LineAssembler::new();
        let mut out = assemble(&mut a, b"G1 X");
        a.mark_overrun();
        out.extend(assemble(&mut a, b"10\nG1 X2\n"));
        assert_eq!(out, vec![(Assembled::Overrun, vec![]), (Assembled::Line, b"G1 X2".to_vec())]);
    }

    #[test]
    fn an_overrun_at_a_line_start_is_reported_even_if_the_rest_is_blank() {
        let mut a = LineAssembler::new();
        assert_eq!(a.push(b'\r'), None);
        a.mark_overrun();
        assert_eq!(a.push(b'\n'), Some(Assembled::Overrun));
        assert_eq!(assemble(&mut a, b"M5\n"), vec![(Assembled::Line, b"M5".to_vec())]);
    }

    #[test]
    fn binary_bytes_reject_the_line() {
        let mut a = LineAssembler::new();
        let out = assemble(&mut a, b"G1 X\x0010\nG1\xfe\nM3\x1b\nG1\tX1\n");
        assert_eq!(
            out,
            vec![
                (Assembled::BadByte, vec![]),
                (Assembled::BadByte, vec![]),
                (Assembled::BadByte, vec![]),
                (Assembled::Line, b"G1\tX1".to_vec()),
            ]
        );
    }

    #[test]
    fn a_byte_order_mark_at_a_line_start_and_utf8_in_comments_are_text() {
        let mut a = LineAssembler::new();
        let out = assemble(&mut a, "\u{feff}G1 X1\n(Ø3 end mill)\nG1 X2 ; Größe\n\u{feff}  G0\n".as_bytes());
        let lines: Vec<_> = out.iter().map(|(r, l)| (*r, String::from_utf8(l.clone()).unwrap())).collect();
        assert_eq!(
            lines,
            [
                (Assembled::Line, "G1 X1".into()),
                (Assembled::Line, "(Ø3 end mill)".into()),
                (Assembled::Line, "G1 X2 ; Größe".into()),
                (Assembled::Line, "G0".into()),
            ]
        );
        // Outside a comment, or a mark cut short or not at the start: data.
        for bad in [&b"G1 X\xc3\x981\n"[..], b"\xef\xbbG1\n", b"\xef\n", b"G1 \xef\xbb\xbf\n", b"(a)\xc3\n", b"(\x01)\n"] {
            assert_eq!(assemble(&mut a, bad), [(Assembled::BadByte, vec![])], "{bad:?}");
        }
        // A mark alone is a blank line.
        assert_eq!(assemble(&mut a, b"\xef\xbb\xbf\nG0\n"), [(Assembled::Line, b"G0".to_vec())]);
    }

    #[test]
    fn comment_text_past_the_limit_is_dropped_and_code_keeps_its_limit() {
        let mut a = LineAssembler::new();
        let semi = format!("G0 X1 ; {}\n", "d".repeat(300));
        let out = assemble(&mut a, semi.as_bytes());
        assert_eq!(out[0].0, Assembled::Line);
        assert_eq!(out[0].1, semi.as_bytes()[..MAX_LINE_LEN].to_vec());
        // An overflowing ( ) comment folds to (), the code after it stays.
        let paren = format!("G0 X1 ({}) Y2 (short)\n", "d".repeat(300));
        assert_eq!(assemble(&mut a, paren.as_bytes()), [(Assembled::Line, b"G0 X1 () Y2 (short)".to_vec())]);
        // A `(` inside the comment text leaves a comment that reads the same.
        let inner = format!("G0 X1 (a ({}) Y2\n", "d".repeat(300));
        assert_eq!(assemble(&mut a, inner.as_bytes()), [(Assembled::Line, b"G0 X1 (a () Y2".to_vec())]);
        // Code past the limit is too long, comment or not before it.
        let code = format!("G0 X1 ({}) Y{}\n", "d".repeat(300), "2".repeat(MAX_LINE_LEN));
        assert_eq!(assemble(&mut a, code.as_bytes()), [(Assembled::TooLong, vec![])]);
        // A `(` with no room for `()` is not stored; the code after it is.
        let edge = format!("{} (comment) \n", "G4".repeat(MAX_LINE_LEN / 2 - 1));
        let out = assemble(&mut a, edge.as_bytes());
        assert_eq!(out, [(Assembled::Line, "G4".repeat(MAX_LINE_LEN / 2 - 1).into_bytes())]);
        // A checksummed line whose comment was cut cannot be checked: too long.
        let numbered = format!("N5 G0 X1 ({})*12\n", "d".repeat(300));
        assert_eq!(assemble(&mut a, numbered.as_bytes()), [(Assembled::TooLong, vec![])]);
        let unchecked = format!("N5 G0 X1 ({})\n", "d".repeat(300));
        assert_eq!(assemble(&mut a, unchecked.as_bytes()), [(Assembled::Line, b"N5 G0 X1 ()".to_vec())]);
    }

    /// The line with its comments taken out.
    fn code_of(line: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut paren = false;
        for &b in line {
            match b {
                b')' if paren => paren = false,
                _ if paren => {}
                b'(' => paren = true,
                b';' => break,
                _ => out.push(b),
            }
        }
        out
    }

    #[test]
    fn long_lines_keep_their_code_exactly_on_random_lines() {
        let mut rng = XorShift(0x51ed_2701);
        let pieces: [&[u8]; 9] = [b"G1 ", b"X12.5", b"(", b")", b";", b"dddddddddddddddd", "Ø".as_bytes(), b" ", b"*7"];
        let mut a = LineAssembler::new();
        for _ in 0..20_000 {
            let mut line = Vec::new();
            let target = 1 + rng.next() as usize % 400;
            while line.len() < target {
                line.extend_from_slice(pieces[rng.next() as usize % pieces.len()]);
            }
            // Only text, not data: bytes from 0x80 up stay inside comments.
            let mut cut = LineCut::new();
            let mut text = Vec::new();
            for &b in &line {
                if b < 0x80 || cut.in_comment() {
                    cut.keep(b, 0);
                    text.push(b);
                }
            }
            let code = code_of(trim(&text));
            text.push(b'\n');
            let out = assemble(&mut a, &text);
            match out.first() {
                Some((Assembled::Line, got)) => {
                    assert!(got.len() <= MAX_LINE_LEN);
                    assert_eq!(trim(&code_of(got)), trim(&code), "{:?}", String::from_utf8_lossy(&text));
                }
                // Only a line over the limit is ever refused.
                Some((Assembled::TooLong, _)) => assert!(trim(&text[..text.len() - 1]).len() > MAX_LINE_LEN),
                None => assert!(code.is_empty() || trim(&code).is_empty()),
                other => panic!("{other:?} for {:?}", String::from_utf8_lossy(&text)),
            }
        }
    }

    #[test]
    fn a_star_inside_a_comment_is_not_a_checksum() {
        let mut c = LineChecker::new();
        assert_eq!(c.check(b"G0 X5 ( *** move *** )"), Ok(&b"G0 X5 ( *** move *** )"[..]));
        assert_eq!(c.check(b"G0 X5 ; ** done **"), Ok(&b"G0 X5 ; ** done **"[..]));
        assert_eq!(c.check(b"G0 X5 (a*b) *12"), Err(ProtoError::MissingLineNumber));
        let body = "N1 G0 X1 ( *** move *** )";
        let l = format!("{}*{}", body, xor(body.as_bytes()));
        assert_eq!(c.check(l.as_bytes()), Ok(&b"G0 X1 ( *** move *** )"[..]));
        assert_eq!(c.last_line(), 1);
        assert_eq!(checksum_star(b"N1 G0 (*) X1*5 ; *"), Some(12));
        assert_eq!(checksum_star(b"G0 (*"), None);
    }

    #[test]
    fn reset_forgets_the_line_in_progress() {
        let mut a = LineAssembler::new();
        assemble(&mut a, b"G1 X1");
        a.mark_overrun();
        a.reset();
        assert_eq!(assemble(&mut a, b"M5\n"), vec![(Assembled::Line, b"M5".to_vec())]);
    }

    use crate::test_util::XorShift;

    #[test]
    fn random_bytes_never_panic_and_never_give_a_line_over_the_limit() {
        let mut rng = XorShift(0x1234_5678);
        let mut a = LineAssembler::new();
        let mut checker = LineChecker::new();
        let mut lines = 0;
        for i in 0..200_000u32 {
            let r = rng.next();
            // Bias toward printable text and terminators so that lines end.
            let b = match r % 8 {
                0 => b'\n',
                1 => (r >> 8) as u8,
                _ => b' ' + ((r >> 8) % 95) as u8,
            };
            if i % 9973 == 0 {
                a.mark_overrun();
            }
            if let Some(Assembled::Line) = a.push(b) {
                let line = a.line();
                assert!(!line.is_empty() && line.len() <= MAX_LINE_LEN);
                // Bytes from 0x80 up only inside a comment.
                let mut cut = LineCut::new();
                for (k, &c) in line.iter().enumerate() {
                    assert!((0x20..0x7f).contains(&c) || c == b'\t' || (c >= 0x80 && cut.in_comment()), "{line:?}");
                    cut.keep(c, k);
                }
                let _ = checker.check(line);
                lines += 1;
            }
        }
        assert!(lines > 1000);
    }

    #[test]
    fn unnumbered_lines_pass_as_they_are() {
        let mut c = LineChecker::new();
        assert_eq!(c.check(b"G1 X10"), Ok(&b"G1 X10"[..]));
        assert_eq!(c.last_line(), 0);
    }

    #[test]
    fn numbered_lines_with_good_checksums_advance_the_line_number() {
        let mut c = LineChecker::new();
        let l1 = numbered(1, "G1 X10");
        assert_eq!(c.check(&l1), Ok(&b"G1 X10"[..]));
        let l2 = numbered(2, "M114");
        assert_eq!(c.check(&l2), Ok(&b"M114"[..]));
        assert_eq!(c.last_line(), 2);
        assert_eq!(c.resend_line(), 3);
    }

    #[test]
    fn a_known_printcore_line_checks() {
        // printcore: prefix = "N1 G28", checksum = XOR of the prefix.
        let mut c = LineChecker::new();
        assert_eq!(xor(b"N1 G28"), 18);
        assert_eq!(c.check(b"N1 G28*18"), Ok(&b"G28"[..]));
    }

    #[test]
    fn a_wrong_checksum_is_rejected_and_keeps_the_last_line() {
        let mut c = LineChecker::new();
        let mut l = numbered(1, "G1 X10");
        let n = l.len();
        l[n - 1] = if l[n - 1] == b'0' { b'1' } else { b'0' };
        assert_eq!(c.check(&l), Err(ProtoError::Checksum));
        assert_eq!(c.check(b"N1 G1*"), Err(ProtoError::Checksum));
        assert_eq!(c.check(b"N1 G1*abc"), Err(ProtoError::Checksum));
        assert_eq!(c.check(b"N1 G1*1000"), Err(ProtoError::Checksum));
        assert_eq!(c.last_line(), 0);
        assert_eq!(c.resend_line(), 1);
    }

    #[test]
    fn a_skipped_or_repeated_line_number_is_rejected() {
        let mut c = LineChecker::new();
        assert_eq!(c.check(&numbered(2, "G0 X1")), Err(ProtoError::LineNumber));
        assert_eq!(c.check(&numbered(1, "G0 X1")), Ok(&b"G0 X1"[..]));
        assert_eq!(c.check(&numbered(1, "G0 X1")), Err(ProtoError::LineNumber));
        assert_eq!(c.resend_line(), 2);
    }

    #[test]
    fn line_number_without_checksum_and_checksum_without_number_are_errors() {
        let mut c = LineChecker::new();
        // N without a checksum is a numbered file block, not the protocol's:
        // it passes unchecked, and the last line number stays.
        assert_eq!(c.check(b"N1 G1 X1"), Ok(&b"N1 G1 X1"[..]));
        assert_eq!(c.check(b"N0070 G1 X1"), Ok(&b"N0070 G1 X1"[..]));
        assert_eq!(c.last_line(), 0);
        assert_eq!(c.check(b"G1 X1*12"), Err(ProtoError::MissingLineNumber));
        let body = "NX G1";
        let l = format!("{}*{}", body, xor(body.as_bytes()));
        assert_eq!(c.check(l.as_bytes()), Err(ProtoError::BadLineNumber));
        assert_eq!(c.last_line(), 0);
    }

    /// A host that resends line 1 with the same bad checksum every time.
    #[test]
    fn a_line_that_keeps_failing_is_given_up_after_three_tries() {
        let mut c = LineChecker::new();
        let mut bad = numbered(1, "G1 X10");
        let n = bad.len();
        bad[n - 1] = if bad[n - 1] == b'0' { b'1' } else { b'0' };
        let mut replies = Vec::new();
        for _ in 0..3 {
            assert_eq!(c.check(&bad), Err(ProtoError::Checksum));
            replies.push(c.failed());
        }
        assert_eq!(replies, [Retry::Resend(1), Retry::Resend(1), Retry::GiveUp(1)]);
        // The host moves on: line 2 is accepted.
        assert_eq!(c.check(&numbered(2, "G1 X2")), Ok(&b"G1 X2"[..]));
    }

    #[test]
    fn a_good_line_resets_the_tries_and_line_number_errors_are_not_tries() {
        let mut c = LineChecker::new();
        assert_eq!(c.failed(), Retry::Resend(1));
        assert_eq!(c.failed(), Retry::Resend(1));
        // Lines the host had in flight: line-number errors, not reported.
        assert_eq!(c.check(&numbered(2, "G0")), Err(ProtoError::LineNumber));
        assert!(c.check(&numbered(1, "G0")).is_ok());
        // Line 2 starts with a clean slate.
        assert_eq!(c.failed(), Retry::Resend(2));
        assert_eq!(c.failed(), Retry::Resend(2));
        assert_eq!(c.failed(), Retry::GiveUp(2));
        assert_eq!(c.last_line(), 2);
        assert_eq!(c.failed(), Retry::Resend(3));
    }

    /// Whatever a host sends, the same line is never asked for more than
    /// MAX_TRIES - 1 times in a row by `failed`.
    #[test]
    fn random_failures_never_ask_for_the_same_line_more_than_twice() {
        let mut rng = XorShift(99);
        let mut c = LineChecker::new();
        let (mut same, mut last_req) = (0, i32::MIN);
        for _ in 0..100_000 {
            let n = c.resend_line();
            let line = if rng.next().is_multiple_of(3) { numbered(n, "G0") } else { b"N1 G0*0".to_vec() };
            match c.check(&line) {
                Ok(_) => same = 0,
                Err(ProtoError::LineNumber) => {}
                Err(_) => match c.failed() {
                    Retry::Resend(r) => {
                        same = if r == last_req { same + 1 } else { 1 };
                        last_req = r;
                        assert!(same < MAX_TRIES as i32, "line {r} asked for {same} times");
                    }
                    Retry::GiveUp(_) => same = 0,
                },
            }
        }
    }

    #[test]
    fn m110_sets_the_line_number_from_its_own_n_word() {
        let mut c = LineChecker::new();
        assert_eq!(c.check(&numbered(5, "M110 N100")), Ok(&b"M110 N100"[..]));
        assert_eq!(c.last_line(), 100);
        assert!(c.check(&numbered(101, "G1 X1")).is_ok());
    }

    #[test]
    fn m110_without_n_word_uses_the_line_number_even_when_negative() {
        let mut c = LineChecker::new();
        c.check(&numbered(40, "M110")).unwrap();
        assert_eq!(c.last_line(), 40);
        // printcore resets with N-1 M110.
        assert_eq!(c.check(&numbered(-1, "M110")), Ok(&b"M110"[..]));
        assert_eq!(c.last_line(), -1);
        assert!(c.check(&numbered(0, "G28")).is_ok());
        assert_eq!(c.last_line(), 0);
    }

    #[test]
    fn m1100_is_not_m110() {
        let mut c = LineChecker::new();
        assert_eq!(c.check(&numbered(7, "M1100 N3")), Err(ProtoError::LineNumber));
    }

    #[test]
    fn a_bare_m110_sets_the_line_number() {
        let mut c = LineChecker::new();
        assert_eq!(c.check(b"M110 N42"), Ok(&b"M110 N42"[..]));
        assert_eq!(c.last_line(), 42);
        assert_eq!(c.check(b"m110 n-7"), Ok(&b"m110 n-7"[..]));
        assert_eq!(c.last_line(), -7);
        // Without an N word nothing changes.
        c.check(b"M110").unwrap();
        assert_eq!(c.last_line(), -7);
    }

    #[test]
    fn extreme_line_numbers_do_not_overflow() {
        let mut c = LineChecker::new();
        c.check(&numbered(1, "M110 N2147483647")).unwrap();
        assert_eq!(c.resend_line(), i32::MIN);
        assert!(c.check(&numbered(-2147483648, "G0")).is_ok());
        assert_eq!(c.check(&numbered(1, "M110 N2147483648")), Ok(&b"M110 N2147483648"[..]));
        // An unparsable M110 N falls back to the line's own number.
        assert_eq!(c.last_line(), 1);
        let body = "N99999999999 G0";
        let l = format!("{}*{}", body, xor(body.as_bytes()));
        assert_eq!(c.check(l.as_bytes()), Err(ProtoError::BadLineNumber));
    }

    #[test]
    fn the_checksum_covers_everything_before_the_last_star() {
        let mut c = LineChecker::new();
        let body = "N1 G1 (a*b) X1";
        let l = format!("{}*{}", body, xor(body.as_bytes()));
        assert_eq!(c.check(l.as_bytes()), Ok(&b"G1 (a*b) X1"[..]));
    }

    #[test]
    fn every_error_has_a_message() {
        for e in [
            ProtoError::Checksum,
            ProtoError::LineNumber,
            ProtoError::MissingChecksum,
            ProtoError::MissingLineNumber,
            ProtoError::BadLineNumber,
            ProtoError::TooLong,
            ProtoError::Overrun,
            ProtoError::BadByte,
        ] {
            assert!(!e.message().is_empty());
        }
        assert_eq!(ProtoError::Checksum.message(), "checksum mismatch");
    }

    /// (M112s, M108s) that the scanner spots in `stream`.
    fn urgent_fires(stream: &[u8]) -> (usize, usize) {
        let mut s = MCodeScanner::new();
        let (mut estops, mut continues) = (0, 0);
        let mut prev = 0;
        for &b in stream {
            match s.feed(prev, b) {
                Urgent::Estop => estops += 1,
                Urgent::Continue => continues += 1,
                Urgent::Nothing => {}
            }
            prev = b;
        }
        (estops, continues)
    }

    fn estop_fires(stream: &[u8]) -> usize {
        urgent_fires(stream).0
    }

    #[test]
    fn m112_followed_by_a_non_digit_triggers_the_estop() {
        assert_eq!(estop_fires(b"M112\n"), 1);
        assert_eq!(estop_fires(b"m112 "), 1);
        assert_eq!(estop_fires(b"N7 M112*40\n"), 1);
        assert_eq!(estop_fires(b"G1 X5 M112;\n"), 1);
        assert_eq!(estop_fires(b"G0M112\n"), 1);
        assert_eq!(estop_fires(b"MM112\n"), 0);
        assert_eq!(estop_fires(b"M11M112\n"), 1);
        assert_eq!(estop_fires(b"M112\nM112\n"), 2);
        assert_eq!(estop_fires(b"M112M112 "), 2, "the M that ends one starts the next");
    }

    #[test]
    fn near_misses_do_not_trigger_the_estop() {
        assert_eq!(estop_fires(b"M1120\n"), 0);
        assert_eq!(estop_fires(b"M11 2\n"), 0);
        assert_eq!(estop_fires(b"M 112\n"), 0);
        assert_eq!(estop_fires(b"M111\n"), 0);
        assert_eq!(estop_fires(b"M23 AM112.GCO\n"), 0);
        assert_eq!(estop_fires(b"zm112\n"), 0, "a lower-case letter before the M counts too");
        assert_eq!(estop_fires(b"M112"), 0, "needs the next byte to decide");
    }

    #[test]
    fn m_code_scanner_is_one_byte() {
        assert_eq!(core::mem::size_of::<MCodeScanner>(), 1);
    }

    /// The RX ISR's fast path skips the scanner for the bytes it ignores:
    /// in every state, after any byte, those must change nothing.
    #[test]
    fn a_byte_the_scanner_ignores_changes_nothing() {
        let mut skipped = 0;
        for state in 0..=S_M108 {
            for prev in 0..=255u8 {
                for b in 0..=255u8 {
                    let mut s = MCodeScanner { state };
                    if s.ignores(b) {
                        assert_eq!(s.feed(prev, b), Urgent::Nothing);
                        assert_eq!(s.state, state);
                        skipped += 1;
                    }
                }
            }
        }
        assert_eq!(skipped, 254 * 256, "all but M and m when idle, nothing otherwise");
    }

    /// What the scanner must answer for the newest byte of `hist` (oldest
    /// first): the code `M<abc>` (any case) not after a letter, then a
    /// non-digit, spelled out from the rule instead of a state machine.
    fn urgent_reference(hist: &[u8]) -> Urgent {
        let n = hist.len();
        if n < 5 || hist[n - 1].is_ascii_digit() {
            return Urgent::Nothing;
        }
        if n > 5 && hist[n - 6].is_ascii_alphabetic() {
            return Urgent::Nothing;
        }
        match hist[n - 5..n - 1].to_ascii_uppercase().as_slice() {
            b"M112" => Urgent::Estop,
            b"M108" => Urgent::Continue,
            _ => Urgent::Nothing,
        }
    }

    /// Random streams of near misses and hits (pieces of both codes in
    /// both cases, letters, digits, blanks and a few others) agree with
    /// [`urgent_reference`] byte for byte.
    #[test]
    fn the_m_code_scanner_matches_the_rule_on_random_streams() {
        const PIECES: &[&[u8]] = &[
            b"M112", b"m108", b"M11", b"M10", b"M1", b"M", b"m", b"1", b"0", b"2", b"8", b"9", b" ", b"\n", b"A", b"z", b"G", b"(", b"*",
            b"\xff", b"\x00",
        ];
        let mut rng = XorShift(0xC0DE);
        let mut s = MCodeScanner::new();
        let mut hist: Vec<u8> = Vec::new();
        let (mut estops, mut continues) = (0, 0);
        for _ in 0..100_000 {
            for &b in PIECES[rng.next() as usize % PIECES.len()] {
                let got = s.feed(hist.last().copied().unwrap_or(0), b);
                hist.push(b);
                let tail = &hist[hist.len().saturating_sub(8)..];
                assert_eq!(got, urgent_reference(&hist), "after {:?}", String::from_utf8_lossy(tail));
                estops += (got == Urgent::Estop) as u32;
                continues += (got == Urgent::Continue) as u32;
            }
        }
        assert!(estops > 1000 && continues > 1000, "{estops} M112, {continues} M108");
    }

    /// A model of the serial RX path: a 255-byte ring filled by the ISR's
    /// `RxStore` faster than the main loop drains it into a `LineAssembler`.
    /// The host sends numbered lines `N<i> G4 P<i>`; every line that arrives
    /// complete must come out intact, every damaged one must come out as
    /// `Overrun`, and nothing else.
    #[test]
    fn rx_losses_drop_exactly_the_damaged_lines() {
        use std::collections::VecDeque;
        let mut rng = XorShift(7);
        let mut store = RxStore::new();
        let mut asm = LineAssembler::new();
        let mut ring: VecDeque<u8> = VecDeque::new();
        let mut sent: Vec<u8> = Vec::new();
        let mut markers = 0;
        for i in 0..3000 {
            for b in format!("N{i} G4 P{i}\n").bytes() {
                sent.push(b);
            }
        }
        let (mut next, mut intact, mut overruns) = (0usize, 0, 0);
        let mut got: Vec<Result<String, ()>> = Vec::new();
        while next < sent.len() || !ring.is_empty() {
            for _ in 0..rng.next() % 4 {
                if let Some(&b) = sent.get(next) {
                    store.store(b, |x| {
                        if ring.len() < 255 {
                            markers += (x == RX_GAP) as usize;
                            ring.push_back(x);
                            true
                        } else {
                            false
                        }
                    });
                    next += 1;
                }
            }
            for _ in 0..rng.next() % 4 {
                if let Some(b) = ring.pop_front() {
                    match asm.push(b) {
                        Some(Assembled::Line) => {
                            intact += 1;
                            got.push(Ok(String::from_utf8(asm.line().to_vec()).unwrap()));
                        }
                        Some(Assembled::Overrun) => {
                            overruns += 1;
                            got.push(Err(()));
                        }
                        None => {}
                        other => panic!("{other:?}"),
                    }
                }
            }
        }
        // Every intact line is one the host sent, in order, unchanged.
        let mut expect = 0;
        for l in got.iter().flatten() {
            let n: usize = l[1..l.find(' ').unwrap()].parse().unwrap();
            assert!(n >= expect, "{l} out of order");
            assert_eq!(*l, format!("N{n} G4 P{n}"));
            expect = n + 1;
        }
        assert!(intact > 2000 && overruns >= 10, "{intact} intact, {overruns} overruns");
        // Each loss costs at most the one line it hit.
        assert!(overruns <= markers, "{overruns} lines dropped for {markers} losses");
    }

    #[test]
    fn a_real_0xff_from_the_host_is_a_bad_byte_not_a_gap() {
        let mut store = RxStore::new();
        let mut ring = Vec::new();
        store.store(0xFF, |x| {
            ring.push(x);
            true
        });
        assert_eq!(ring, vec![0xFE]);
        let mut asm = LineAssembler::new();
        ring.push(b'\n');
        let out: Vec<_> = ring.iter().filter_map(|&b| asm.push(b)).collect();
        assert_eq!(out, vec![Assembled::BadByte]);
    }

    #[test]
    fn m108_is_caught_like_m112_and_neither_fires_for_the_other() {
        assert_eq!(urgent_fires(b"M108\n"), (0, 1));
        assert_eq!(urgent_fires(b"N3 m108*55\n"), (0, 1));
        assert_eq!(urgent_fires(b"M1080\nM10 8\nAM108\n"), (0, 0));
        assert_eq!(urgent_fires(b"M112\nM108\nM112 "), (2, 1));
        assert_eq!(urgent_fires(b"M118\nM102\nM10M112;M11M108;"), (1, 1));
    }
}
