//! The realtime bytes (`?`, `!`, `~`, 0x18): which bytes they are, and
//! the RX ISR's one-byte view of the line being received ([`RxText`]) that
//! says where `?`, `!`, `~` act at once and where they are text.

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
    pub(super) state: u8,
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
    pub fn at_line_start(&self) -> bool {
        self.state & T_START != 0
    }

    /// Bytes were lost: assume mid-line, outside any comment.
    pub fn note_loss(&mut self) {
        self.state = 0;
    }

    /// Classify the received byte `b`: true when it is a realtime command
    /// (taken out of the stream), false when it is text (the state follows it).
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
