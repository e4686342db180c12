//! Why a line was rejected ([`ParseErrorKind`]) and where ([`ParseError`],
//! a 1-based column).

use crate::flash::FStr;
use ufmt::{uDisplay, uWrite, uwrite};

crate::flash_messages! {
    /// What is wrong with a rejected line (`message`: the text printed after
    /// `Error:`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum ParseErrorKind {
        /// Not a number: `X`, `X-`, `X.`, `X+.`, `X1.2.3`, `X1-2`.
        BadNumber => "bad number",
        /// A number directly followed by `E`, read as an exponent: `X1e99`.
        Exponent => "bad number: exponent not allowed",
        /// |value| ≥ 1e6, or more than 9 significant digits.
        NumberOutOfRange => "number out of range",
        /// A character where a word should start (`X1 0`, `#`, `)`).
        Unexpected => "unexpected character",
        /// A G or M number that is not supported (`G93`, `G1.5`, `M7`).
        UnsupportedCode => "unsupported code",
        /// The same word twice on one line (`G1 X1 X2`).
        RepeatedWord => "word repeated",
        /// Two codes of one modal group (`G0 G1`, `M3 M5`).
        ModalGroupConflict => "two codes of one modal group",
        /// `(` without `)`.
        UnclosedComment => "unclosed comment",
        /// T that is not a whole number 0..=255.
        BadToolNumber => "tool number must be a whole number",
        /// M23 or M28 without a file name.
        MissingFileName => "missing file name",
        /// More than [`MAX_PARSE_LEN`] bytes.
        LineTooLong => "line too long",
        /// `#1=5`, `X#1`, `X[1+2]`.
        Parameter => "# parameters and [expressions] not supported",
        /// `O100 sub`, `o10 while [...]`, `O100 call`.
        OWord => "O-word subroutines and control flow not supported",
        /// A, C, U, V, W: axes this machine does not have.
        NoSuchAxis => "axis word for an axis this machine does not have (X Y Z only)",
        /// G76, G84, G86, G87, G88.
        UnsupportedCycle => "canned cycle not supported (G73 G81 G82 G83 G85 G89 are)",
        /// M62, M63, M64, M65: digital outputs this machine does not have.
        NoOutputs => "M62-M65 digital outputs not supported: this machine has none",
    }
}

/// A rejected line: what, and where (1-based column in the parsed text).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// What is wrong.
    pub kind: ParseErrorKind,
    /// 1-based column of the offending word or character.
    pub col: u8,
}

impl ParseError {
    /// Text printed after `Error:`, before ` at col <c>`.
    pub fn message(&self) -> FStr {
        self.kind.message()
    }
}

impl uDisplay for ParseError {
    /// `<message> at col <c>`, as printed after `Error:`.
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
        uwrite!(f, "{} at col {}", self.message(), self.col)
    }
}

/// Shorthand for an error at a column.
pub(super) fn err<T>(kind: ParseErrorKind, col: u8) -> Result<T, ParseError> {
    Err(ParseError { kind, col })
}

/// 1-based column of byte index `i`, saturating.
pub(super) fn col_of(i: usize) -> u8 {
    u8::try_from(i + 1).unwrap_or(u8::MAX)
}
