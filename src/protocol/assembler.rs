//! Bytes into lines: [`LineAssembler`] collects the main loop's bytes into
//! trimmed lines of at most [`MAX_LINE_LEN`] and flags the lines to drop
//! ([`Assembled`]: too long, overrun, binary byte).

use super::checker::checksum_star;
use super::line_cut::{folded_len, Keep, LineCut};
use super::rx_store::RX_GAP;
use super::{ProtoError, MAX_LINE_LEN};

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
/// A `(`, `)`, `*` or `;` arrived in this line (see [`LineAssembler::has_marks`]).
const F_MARKS: u8 = 1 << 4;

/// The UTF-8 byte-order mark that Windows editors write at the start of a
/// file: text, not data. Skipped at the start of a line.
pub const BOM: [u8; 3] = [0xEF, 0xBB, 0xBF];

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
    ///
    /// The usual byte (printable but `(` `)` `*` `;`, or a blank after the
    /// first byte; in code, with room left) is stored at once; every other byte goes through
    /// [`push_slow`](Self::push_slow), which treats it (and would treat the
    /// usual one) the same way (`the_assembler_fast_path_matches_the_slow_one`):
    /// ~360 cycles a streamed line less on the AVR (`profile --trace`).
    // speed: the per-byte path of every serial line (doc above)
    #[inline(always)]
    pub fn push(&mut self, b: u8) -> Option<Assembled> {
        if self.flags & F_READY != 0 {
            self.flags = 0;
            self.len = 0;
        }
        let len = self.len as usize;
        if usual(b, len != 0) && !self.cut.in_comment() {
            if let Some(slot) = self.buf.get_mut(len) {
                *slot = b;
                self.len += 1;
                return None;
            }
        }
        self.push_slow(b)
    }

    /// [`push`](Self::push) for each byte `src` gives, until it gives none
    /// (`None`) or a line ends (what `push` returned for that byte; `src`
    /// is not asked again until the following call).
    ///
    /// The usual byte (as in `push`) is stored with the line's length held
    /// in a register, written back once the run of usual bytes ends; the
    /// others go through [`push_slow`](Self::push_slow). A source that can
    /// ([`RxBytes::take_usual`]: the firmware's RX ring, in assembly) first
    /// copies its run of usual bytes into the free slots in one go. Byte for
    /// byte what `push_slow` does (`pushing_a_stream_matches_pushing_byte_by_byte`):
    /// on the AVR ~30 cycles a byte instead of ~63 through `push`, whose
    /// length and flags went through memory on every byte (`profile
    /// --trace`: `Machine::push_bytes`), and ~20 in the ring's copy.
    // speed: the per-byte loop of every serial line (doc above)
    #[inline(always)]
    pub fn push_from(&mut self, src: &mut impl RxBytes) -> Option<Assembled> {
        if self.flags & F_READY != 0 {
            self.flags = 0;
            self.len = 0;
        }
        // The free slots, none inside a comment (every byte goes slow
        // there): one test for the room and the comment. One call of
        // `next_byte` in the loop, so that it is inlined.
        let mut code = !self.cut.in_comment();
        let mut free = self.taken_and_free(src, code);
        loop {
            let Some(b) = src.next_byte() else {
                if code {
                    self.len = (MAX_LINE_LEN - free.len()) as u16;
                }
                return None;
            };
            if usual(b, free.len() != MAX_LINE_LEN) {
                if let Some(slot) = free.next() {
                    *slot = b;
                    continue;
                }
            }
            if code {
                self.len = (MAX_LINE_LEN - free.len()) as u16;
            }
            if let Some(done) = self.push_slow(b) {
                return Some(done);
            }
            code = !self.cut.in_comment();
            free = self.taken_and_free(src, code);
        }
    }

    /// The run of usual bytes `src` holds taken into the line (when `code`:
    /// outside a comment), then [`free_slots`](Self::free_slots).
    // speed: in `push_from`'s loop
    #[inline(always)]
    fn taken_and_free(&mut self, src: &mut impl RxBytes, code: bool) -> core::slice::IterMut<'_, u8> {
        if code {
            let len = self.len as usize;
            let n = src.take_usual(self.buf.get_mut(len..).unwrap_or_default(), len != 0);
            self.len = (len + n) as u16;
        }
        self.free_slots(code)
    }

    /// The slots after the line's bytes, or none when `code` is false.
    fn free_slots(&mut self, code: bool) -> core::slice::IterMut<'_, u8> {
        let from = if code { self.len as usize } else { MAX_LINE_LEN };
        self.buf.get_mut(from..).unwrap_or_default().iter_mut()
    }

    /// [`push`](Self::push) for any byte: line ends, blanks, comments,
    /// bad bytes, a full buffer.
    // speed: kept out of the per-byte loop's registers
    #[inline(never)]
    pub fn push_slow(&mut self, b: u8) -> Option<Assembled> {
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
                } else if is_mark(b) {
                    self.flags |= F_MARKS;
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

    /// False when no `(`, `)`, `*` or `;` arrived in the line that
    /// [`line`](Self::line) holds: then it has no comment and no checksum
    /// (`LineChecker::check_marked` need not look for its `*`).
    pub fn has_marks(&self) -> bool {
        self.flags & F_MARKS != 0
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
            self.flags = F_READY | (flags & F_MARKS);
        } else {
            self.dropped_n = self.len > 0 && matches!(self.buf.first(), Some(b'N' | b'n'));
            self.flags = 0;
            self.len = 0;
        }
        result
    }
}

/// A `(`, `)`, `*` or `;`: the bytes of comments and checksums.
pub(super) fn is_mark(b: u8) -> bool {
    b.wrapping_sub(b'(') <= b'*' - b'(' || b == b';'
}

/// True for the byte that [`LineAssembler::push`] stores at once:
/// printable but a mark ([`is_mark`]), or a blank once the line holds a
/// byte (`started`). The digits and `+ , - . / :` are tested first (most of
/// a G-code line), then the letters.
// speed: on every byte of the assembler's loop
#[inline(always)]
pub fn usual(b: u8, started: bool) -> bool {
    if b.wrapping_sub(b'+') < b';' - b'+' || b.wrapping_sub(b'<') < 0x7F - b'<' || b.wrapping_sub(0x21) < b'(' - 0x21 {
        true
    } else {
        (b == b' ' || b == b'\t') && started
    }
}

/// Where [`LineAssembler::push_from`] takes its bytes: one at a time, and,
/// where the source can, the run of usual bytes at its front in one go.
/// Every byte iterator is one (one at a time).
pub trait RxBytes {
    /// The next byte, if one is there.
    fn next_byte(&mut self) -> Option<u8>;

    /// Copy the bytes at the front that are [`usual`] (`started`: the line
    /// already holds a byte; once one is copied, it does) into `dst`, as
    /// many as fit, up to the first other byte, which stays for
    /// [`next_byte`](Self::next_byte); how many. [`take_usual_plain`] over
    /// a ring. None by default.
    fn take_usual(&mut self, dst: &mut [u8], started: bool) -> usize {
        let _ = (dst, started);
        0
    }
}

impl<I: Iterator<Item = u8>> RxBytes for I {
    fn next_byte(&mut self) -> Option<u8> {
        self.next()
    }
}

/// [`RxBytes::take_usual`] over a ring of 256 slots whose bytes wait from
/// `*tail` up to `head` (as the firmware's RX ring holds them), `*tail`
/// moved past what was taken. The plain twin of the firmware's
/// `mill_rx_take_usual` (`board::serial`, `tests/soft_float.rs`).
pub fn take_usual_plain(ring: &[u8; 256], head: u8, tail: &mut u8, dst: &mut [u8], mut started: bool) -> usize {
    let mut n = 0;
    for slot in dst.iter_mut() {
        let b = ring[*tail as usize];
        if *tail == head || !usual(b, started) {
            break;
        }
        *slot = b;
        started = true;
        *tail = tail.wrapping_add(1);
        n += 1;
    }
    n
}
