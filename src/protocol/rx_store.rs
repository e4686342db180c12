//! The RX ISR's side of the ring: [`RxStore`] stores received bytes and,
//! after a loss, the [`RX_GAP`] marker; and the mode its assembly fast path
//! runs in after the slow path handled a byte ([`rx_fast_mode`]).

use super::mcode_scanner::MCodeScanner;
use super::realtime::RxText;

/// The byte the serial RX ISR stores in its ring at the place where it had to
/// drop received bytes (ring full, or a UART overrun). The assembler turns it
/// into [`LineAssembler::mark_overrun`], so exactly the damaged line is
/// dropped, wherever the main loop happens to be reading when the loss
/// occurs. A real 0xFF from the host is stored as 0xFE: still a bad byte.
pub const RX_GAP: u8 = 0xFF;

/// The RX ISR's side of [`RX_GAP`]: stores received bytes into a ring and,
/// after a loss, the markers that keep one reply per line the host sent.
/// Two bytes of state; the ring is any `enqueue` that can refuse.
///
/// A dropped line end is not lost with its line: it is counted, and stored
/// later as a gap marker and a `\n`, so the line it ended still ends (and is
/// dropped as an overrun) even when no byte follows it. A `\r`, or a `\n`
/// not right after a `\r`, counts as a line end, as the assembler reads
/// them (`\r\n` is one line). Bytes dropped after the last dropped line end
/// leave a gap marker to go before the next byte that fits.
///
/// With nothing pending, storing a byte other than [`RX_GAP`] is just
/// `enqueue(b)`, and only a refusal changes the state: the RX ISR's fast
/// path stores such bytes itself and leaves everything else to `store`.
#[derive(Default)]
pub struct RxStore {
    /// [`RxStore::GAP`], and in the bits below it the dropped line ends
    /// not yet stored (at most [`RxStore::MAX_ENDS`]).
    state: u16,
}

impl RxStore {
    /// Bytes were dropped after the last dropped line end.
    const GAP: u16 = 0x8000;
    /// Dropped line ends counted, at most (a flood of short lines without
    /// flow control loses hundreds: tests/protocol.rs).
    const MAX_ENDS: u16 = Self::GAP - 1;

    pub const fn new() -> Self {
        RxStore { state: 0 }
    }

    /// True while a gap marker or a dropped line end waits to be stored.
    pub fn gap_pending(&self) -> bool {
        self.state != 0
    }

    /// Bytes were lost before the next one (the UART's data overrun flag).
    pub fn note_loss(&mut self) {
        self.state |= Self::GAP;
    }

    /// Store `b` (`prev`: the byte received before it); `enqueue` returns
    /// false when the ring is full. After a loss the dropped line ends go
    /// first (a gap marker and a `\n` each), then the gap marker, then `b`;
    /// whatever does not fit is dropped and stays pending (a gap marker
    /// stored twice in one line is still one overrun).
    pub fn store(&mut self, b: u8, prev: u8, mut enqueue: impl FnMut(u8) -> bool) {
        let b = if b == RX_GAP { RX_GAP - 1 } else { b };
        let stored = self.store_lost_ends(&mut enqueue)
            && (self.state == 0 || {
                let marked = enqueue(RX_GAP);
                if marked {
                    self.state = 0;
                }
                marked
            })
            && enqueue(b);
        if stored {
            return;
        }
        match b {
            // The `\n` of a `\r\n`: the `\r` ended the line.
            b'\n' if prev == b'\r' => {}
            b'\n' | b'\r' => {
                if self.state & Self::MAX_ENDS != Self::MAX_ENDS {
                    self.state += 1;
                }
                self.state &= !Self::GAP;
            }
            _ => self.state |= Self::GAP,
        }
    }

    /// Forget the dropped line ends (a soft reset flushed the ring: the
    /// host expects no reply for what it sent before). A gap stays pending.
    pub fn forget_lost_ends(&mut self) {
        self.state &= Self::GAP;
    }

    /// Store the dropped line ends that fit; true when none is left. The
    /// main loop calls it too (interrupts off): when the host sent nothing
    /// after them, nothing else would. A gap marker stays pending for the
    /// next byte.
    pub fn store_lost_ends(&mut self, enqueue: &mut impl FnMut(u8) -> bool) -> bool {
        while self.state & Self::MAX_ENDS != 0 {
            if !enqueue(RX_GAP) || !enqueue(b'\n') {
                return false;
            }
            self.state -= 1;
        }
        true
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
pub fn rx_fast_mode(scan: &MCodeScanner, store: &RxStore, text: &RxText) -> u8 {
    if !scan.is_idle() || store.gap_pending() {
        RX_ALL_SLOW
    } else if text.at_line_start() {
        RX_LINE_START
    } else {
        RX_FAST
    }
}
