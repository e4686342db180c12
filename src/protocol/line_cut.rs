//! What happens to a line longer than [`MAX_LINE_LEN`]: [`LineCut`]
//! follows code, `( )` and `;` comments byte by byte, so comment text past
//! the buffer is dropped (a `( )` comment folded to `()`) and only code
//! makes a line too long.

use super::MAX_LINE_LEN;

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

/// Copies the bytes of `src` up to the first that [`LineCut`] would have
/// to classify (a line end, a comment's `(` or `;`, a control or non-ASCII
/// byte) into `dst`, as far as `dst` has room; returns how many. Outside a
/// comment, with room, [`LineCut::keep`] stores each of them.
pub fn code_run(src: &[u8], dst: &mut [u8]) -> usize {
    let mut k = 0;
    for (d, &b) in dst.iter_mut().zip(src) {
        if !matches!(b, b'\t' | 0x20..=0x7E) || b == b'(' || b == b';' {
            break;
        }
        *d = b;
        k += 1;
    }
    k
}

/// The length a line keeps after [`Keep::Fold`]: up to and with the last
/// `(` stored (the comment's own, or a `(` inside its text, which leaves a
/// comment that reads the same).
pub fn folded_len(line: &[u8]) -> usize {
    line.iter().rposition(|&c| c == b'(').map_or(line.len(), |i| i + 1)
}
