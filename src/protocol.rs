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
//!
//! The files: the RX ISR's side in `realtime` ([`RxText`]),
//! `mcode_scanner` ([`MCodeScanner`]) and `rx_store` ([`RxStore`]); the
//! main loop's side in `line_cut` ([`LineCut`]), `assembler`
//! ([`LineAssembler`]) and `checker` ([`LineChecker`]).

mod assembler;
mod checker;
mod line_cut;
mod mcode_scanner;
mod realtime;
mod rx_store;

pub use assembler::{take_usual_plain, usual, Assembled, LineAssembler, RxBytes, BOM};
pub use checker::{block_number, checksum_star, LineChecker, Retry, MAX_TRIES};
pub use line_cut::{code_run, folded_len, Keep, LineCut};
pub use mcode_scanner::{MCodeScanner, Urgent};
pub use realtime::{is_realtime, RxText, SOFT_RESET};
pub use rx_store::{rx_fast_mode, RxStore, RX_ALL_SLOW, RX_FAST, RX_GAP, RX_LINE_START};

/// Longest accepted line, in characters from its first to its last non-blank
/// (blanks at either end and the terminator do not count): 256, LinuxCNC's
/// limit. A longer line is rejected whole ([`Assembled::TooLong`]), never
/// truncated and run. RAM: the assembler's buffer, plus a copy of the line on
/// the stack while it runs, plus the SD job's line buffer.
pub const MAX_LINE_LEN: usize = 256;

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

#[cfg(test)]
mod tests;
