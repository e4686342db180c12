//! G-code (docs/SPEC.md §5): word-address parser and interpreter.
//!
//! ```text
//!  protocol::LineChecker (command text) ─► parse::parse ─► parse::Line
//!                                       ─► interpreter (modal state) ─► planner
//! ```
//!
//! [`parse`] is pure syntax: it turns one line of text into a [`Line`], codes
//! sorted by modal group plus the value words, or rejects the whole line with
//! a [`ParseError`] that carries a column. It keeps no state between lines.
//! Meaning (modal state, units, offsets, which words a code needs, tool range)
//! belongs to the interpreter.

pub mod comp;
pub mod cycles;
pub mod interp;
pub mod parse;

pub use parse::{
    parse, parse_into, Coolant, CutterComp, Distance, FeedMode, Line, Motion, NonModal, ParseError, ParseErrorKind, PathMode, Plane,
    Spindle, Stopping, ToolLength, Units, Word, Words, OTHER_M_CODES,
};

#[cfg(test)]
mod tests;
