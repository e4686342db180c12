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
