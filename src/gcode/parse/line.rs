//! [`Line`]: one parsed line, at most one code per modal group plus the
//! value words.

use super::codes::{Coolant, CutterComp, Distance, FeedMode, Motion, NonModal, PathMode, Plane, Spindle, Stopping, ToolLength, Units};
use super::words::{Word, Words};
use crate::gcode::cycles::Retract;

/// One parsed line: at most one code per modal group, and the value words.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Line {
    /// G0 G1 G2 G3 G38.2 G38.3 G80.
    pub motion: Option<Motion>,
    /// G17 G18 G19.
    pub plane: Option<Plane>,
    /// G20 G21.
    pub units: Option<Units>,
    /// G90 G91.
    pub distance: Option<Distance>,
    /// G94.
    pub feed_mode: Option<FeedMode>,
    /// G54..G59 as 0..=5.
    pub wcs: Option<u8>,
    /// G43 G49.
    pub tool_length: Option<ToolLength>,
    /// G98 G99 (canned cycle return level, NGC group 10).
    pub retract: Option<Retract>,
    /// G4 G10 G28 G53 G92 G92.1 G92.2 G37 G201..G205.
    pub non_modal: Option<NonModal>,
    /// M0 M1 M2 M30.
    pub stopping: Option<Stopping>,
    /// M6.
    pub tool_change: bool,
    /// M3 M4 M5.
    pub spindle: Option<Spindle>,
    /// M7 M8 M9.
    pub coolant: Option<Coolant>,
    /// G61 G61.1 G64.
    pub path_mode: Option<PathMode>,
    /// G90.1 (true: I/J/K absolute) / G91.1 (false: incremental).
    pub arc_absolute: Option<bool>,
    /// G40 G41 G42 G41.1 G42.1.
    pub cutter_comp: Option<CutterComp>,
    /// One of [`OTHER_M_CODES`], as its number.
    pub other_m: Option<u16>,
    /// For M23/M28: (start, len) of the file name in the parsed text; see
    /// [`Line::text`].
    pub text_arg: Option<(u8, u8)>,
    /// Value words.
    pub words: Words,
}

// RAM budget: a Line lives on the stack of the interpreter call.
const _: () = assert!(core::mem::size_of::<Line>() <= 120);

impl Line {
    /// The value of word `w`, if present (inlined, see [`Words::get`]).
    // speed: the word's mask folds to one byte test (see Words::get)
    #[inline(always)]
    pub fn word(&self, w: Word) -> Option<f32> {
        self.words.get(w)
    }

    /// The T word as a tool number (the parser guarantees a whole number
    /// 0..=255; the interpreter checks the carousel range).
    pub fn tool(&self) -> Option<u8> {
        self.words.get(Word::T).map(|t| t as u8)
    }

    /// The M23/M28 file name, out of `src`, the same text given to [`parse`].
    pub fn text<'a>(&self, src: &'a [u8]) -> Option<&'a [u8]> {
        let (start, len) = self.text_arg?;
        src.get(start as usize..start as usize + len as usize)
    }

    /// True when the line holds no code and no word (blank or comment only).
    pub fn is_empty(&self) -> bool {
        *self == Line::default()
    }
}
