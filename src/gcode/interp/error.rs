//! The interpreter's [`Error`]: what is printed after `Error:` for a
//! refused line, and the nearest grbl 1.1 error code for grbl senders
//! ([`grbl`], `error:<n>`).

use crate::flash::FStr;
use crate::gcode::{ParseError, ParseErrorKind, Word};
use crate::planner::arc::ArcError;

/// Interpreter errors, printed as `Error:<message>`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Error {
    /// The line did not parse.
    Parse(ParseError),
    /// The machine is in alarm; motion refused.
    Alarm,
    /// Feed rate missing, zero or negative.
    BadFeed,
    /// A target outside the travel (soft limits).
    SoftLimit,
    /// M4: the DC spindle turns one way only.
    SpindleCcw,
    /// Arc with no solution or inconsistent centre.
    Arc(ArcError),
    /// A word needed by the code is missing or out of range.
    BadWord(FStr),
    /// A refusal whose grbl error code is not [`Error::BadWord`]'s 20: the
    /// code (checked against the real grbl-Mega, `tests/grbl_reference.rs`)
    /// and the text.
    Coded(u8, FStr),
    /// A code this build does not provide yet.
    NotAvailable(FStr),
    /// Homing failed (alarm raised).
    HomingFailed,
    /// Motion before homing or unlocking (homing lock, `$22`).
    NotHomed,
    /// G38.2 did not trip.
    ProbeFailed,
    /// The probe input was already triggered at the start.
    ProbeAlreadyTriggered,
    /// Tool changer or carousel (T, M6, M61, G201–G205).
    Atc(crate::atc::Fault),
    /// A T word the tool table has no pocket for (the tool number).
    NoPocket(u8),
    /// Tool setter (G37).
    Setter(crate::toolsetter::Fault),
    /// The line was cut short by an abort (SD job, menu).
    Aborted,
    /// An SD job is running: serial lines may only ask for status.
    JobRunning,
    /// An SD card error (its message in flash, printed after `Error:`).
    Sd(FStr),
    /// A `$` setting would put a tool change station point outside the
    /// travel of its axis: the setting (`$170`…) and the axis (0 X … 2 Z).
    StationOutside { setting: u8, axis: u8 },
    /// The move would enter the tool magazine's keep-out zone.
    KeepOut,
    /// A word no code on the line uses (LinuxCNC: "R word with no g code
    /// that uses it"); printed with its letter.
    UnusedWord(Word),
}

/// grbl 1.1's error codes (its `doc/csv/error_codes_en_US.csv`) that
/// [`Error::Coded`] gives.
pub mod grbl {
    /// "Invalid statement": a `$` command not recognised.
    pub const BAD_STATEMENT: u8 = 3;
    /// "Value < 0".
    pub const NEGATIVE: u8 = 4;
    /// "Invalid jog command".
    pub const BAD_JOG: u8 = 16;
    /// "G-code command is missing a required value word".
    pub const VALUE_MISSING: u8 = 28;
    /// "G59.x work coordinate systems are not supported" (a P out of range).
    pub const BAD_WCS: u8 = 29;
    /// "G2 and G3 arcs require at least one in-plane offset word".
    pub const ARC_NO_OFFSET: u8 = 35;
}

impl Error {
    /// Text printed after `Error:`.
    pub fn message(&self) -> FStr {
        match self {
            Error::Parse(p) => p.kind.message(),
            Error::Alarm => F!("alarm"),
            Error::BadFeed => F!("feed rate missing or not positive (F)"),
            Error::SoftLimit => F!("target outside travel (soft limit), nothing moved"),
            Error::SpindleCcw => F!("M4 not supported: the spindle turns one way only"),
            Error::Arc(e) => e.message(),
            Error::BadWord(m) | Error::Coded(_, m) => *m,
            Error::NotAvailable(m) => *m,
            Error::NotHomed => F!("not homed: home (G28) or unlock (M999) first, nothing moved"),
            Error::HomingFailed => F!("homing failed: switch not found"),
            Error::ProbeFailed => F!("probe failed: input did not trip"),
            Error::ProbeAlreadyTriggered => F!("probe input already triggered, nothing moved"),
            Error::Atc(f) => f.message(),
            Error::NoPocket(_) => F!("tool not in the tool table (G10 L1 P<tool> Q<pocket> assigns it)"),
            Error::Setter(f) => f.message(),
            Error::Aborted => F!("aborted"),
            Error::JobRunning => F!("SD job running: command refused (status only: ?, M27, M114)"),
            Error::Sd(_) => F!("SD card error"),
            Error::UnusedWord(_) => F!("word with no code that uses it"),
            Error::StationOutside { .. } => F!("tool change station point outside the travel"),
            Error::KeepOut => F!("move enters the tool magazine's keep-out zone ($183, $184), nothing moved"),
        }
    }

    /// The nearest grbl 1.1 error code, for grbl senders (`error:<n>`).
    pub fn grbl_code(&self) -> u8 {
        use ParseErrorKind as K;
        match self {
            Error::Parse(p) => match p.kind {
                K::BadNumber | K::Exponent | K::NumberOutOfRange => 2,
                K::Unexpected => 1,
                K::RepeatedWord => 25,
                K::ModalGroupConflict => 21,
                K::BadToolNumber => 23,
                K::LineTooLong => 11,
                _ => 20,
            },
            Error::Alarm | Error::NotHomed | Error::JobRunning => 9,
            Error::BadFeed => 22,
            Error::SoftLimit | Error::KeepOut => 15,
            Error::Arc(_) => 33,
            Error::Atc(crate::atc::Fault::ToolRange) => 38,
            Error::ProbeAlreadyTriggered | Error::ProbeFailed => 9,
            Error::UnusedWord(_) => 36,
            Error::Coded(c, _) => *c,
            _ => 20,
        }
    }
}
