//! G-code line parser (docs/SPEC.md §5): RS274/NGC word-address syntax → [`Line`].
//!
//! Sits between `protocol::LineChecker`, which hands over the command text
//! (`N<n>` and `*<cs>` already stripped), and the interpreter, which owns the
//! modal state. Zero allocation, no panics, f32 only; one [`Line`] is about
//! 100 bytes and lives on the stack.
//!
//! Syntax accepted:
//! - letters in any case; blanks (space, tab) are ignored between words,
//!   between a letter and its number and inside a number, as RS274/NGC says
//!   (`G1X10Y-2.5`, `X 10`, `X1 6.5` is X16.5, `X- 1` is X-1);
//! - `( … )` comments (no nesting; an unclosed `(` is an error) and `;` to the
//!   end of the line;
//! - numbers `[+|-][digits][.digits]` with at least one digit and below 1e6
//!   in magnitude, with any number of digits: beyond 9 significant digits
//!   the number is rounded to 9 (more than f32's 7), so `X24.985715729`
//!   reads as written would on a controller with doubles, to the step. There
//!   is no exponent:
//!   a number directly followed by `E` (`X1e99`) is an error, so write a
//!   blank before an `E` word (`X1 E5`);
//! - `#` parameters, `[` expressions, O-word subroutines and loops and the
//!   axis letters A, C, U, V, W are refused with errors that name
//!   them; an `O<n>` program number alone on a line (Fanuc/HAAS posts:
//!   `O1001`, `O0000(NAME)`) is accepted and does nothing;
//! - an axis word without a number (`G28 X Z`) names the axis, with the
//!   value 0; only a G28 line may do that, elsewhere it is a bad number;
//! - a leading `N<n>` is skipped (with or without a checksum: grbl-style
//!   senders stream files with `N` on every line); an `N` word later on the
//!   line is a value word (M110 reads it);
//! - a line that starts with `%` (a program delimiter in files, `% vfd
//!   enable`) is empty: what follows the `%` is not read;
//! - `@` and `^` are LinuxCNC's polar coordinates (radius, angle in degrees);
//! - a leading line number may have a fraction (`N4567.789`), as LinuxCNC
//!   allows;
//! - `M23` and `M28` take the rest of the line, up to `;`, as a file name.
//!
//! Every error points at a 1-based column of the text given to [`parse`]:
//! number errors at the word's letter, code errors at the `G`/`M`, the rest
//! at the offending character.

use super::cycles::{Kind, Retract};
use crate::flash::FStr;
use ufmt::{uDisplay, uWrite, uwrite};

/// Longest text [`parse`] accepts, in bytes: the protocol's line limit
/// (columns are `u8`: a problem in column 256 is reported at 255).
pub const MAX_PARSE_LEN: usize = crate::protocol::MAX_LINE_LEN;

/// Value words, in the bit order of [`Words`].
///
/// `B` is the G37 broken-tool tolerance (docs/SPEC.md §5); `A`, `C` (rotary axes),
/// `U`, `V`, `W` are axes this machine does not have, and `O` is a program
/// number or an O-word (see [`parse`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Word {
    B,
    D,
    E,
    F,
    H,
    I,
    J,
    K,
    L,
    N,
    P,
    Q,
    R,
    S,
    T,
    X,
    Y,
    Z,
    /// `@`: polar radius (LinuxCNC), mm or inches.
    At,
    /// `^`: polar angle (LinuxCNC), degrees counter-clockwise from +X.
    Caret,
}

impl Word {
    /// Number of value words.
    pub const COUNT: usize = 20;
    /// Every word, in bit order.
    pub const ALL: [Word; Word::COUNT] = [
        Word::B,
        Word::D,
        Word::E,
        Word::F,
        Word::H,
        Word::I,
        Word::J,
        Word::K,
        Word::L,
        Word::N,
        Word::P,
        Word::Q,
        Word::R,
        Word::S,
        Word::T,
        Word::X,
        Word::Y,
        Word::Z,
        Word::At,
        Word::Caret,
    ];

    /// The word for a letter, any case (and `@`, `^`); `None` for letters
    /// outside the dialect and for `G` and `M`, which are codes.
    pub fn from_letter(c: u8) -> Option<Word> {
        Some(match c.to_ascii_uppercase() {
            b'B' => Word::B,
            b'D' => Word::D,
            b'E' => Word::E,
            b'F' => Word::F,
            b'H' => Word::H,
            b'I' => Word::I,
            b'J' => Word::J,
            b'K' => Word::K,
            b'L' => Word::L,
            b'N' => Word::N,
            b'P' => Word::P,
            b'Q' => Word::Q,
            b'R' => Word::R,
            b'S' => Word::S,
            b'T' => Word::T,
            b'X' => Word::X,
            b'Y' => Word::Y,
            b'Z' => Word::Z,
            b'@' => Word::At,
            b'^' => Word::Caret,
            _ => return None,
        })
    }

    /// The upper-case letter of the word (`@`, `^` for the polar words). A
    /// match, not a table: on AVR a table would be copied into RAM.
    pub fn letter(self) -> u8 {
        match self {
            Word::B => b'B',
            Word::D => b'D',
            Word::E => b'E',
            Word::F => b'F',
            Word::H => b'H',
            Word::I => b'I',
            Word::J => b'J',
            Word::K => b'K',
            Word::L => b'L',
            Word::N => b'N',
            Word::P => b'P',
            Word::Q => b'Q',
            Word::R => b'R',
            Word::S => b'S',
            Word::T => b'T',
            Word::X => b'X',
            Word::Y => b'Y',
            Word::Z => b'Z',
            Word::At => b'@',
            Word::Caret => b'^',
        }
    }

    /// The word of bit `i` ([`Word::ALL`]`[i]`, by a match).
    fn from_index(i: u8) -> Option<Word> {
        let letter = match i {
            0 => b'B',
            1 => b'D',
            2 => b'E',
            3 => b'F',
            4 => b'H',
            5 => b'I',
            6 => b'J',
            7 => b'K',
            8 => b'L',
            9 => b'N',
            10 => b'P',
            11 => b'Q',
            12 => b'R',
            13 => b'S',
            14 => b'T',
            15 => b'X',
            16 => b'Y',
            17 => b'Z',
            18 => b'@',
            19 => b'^',
            _ => return None,
        };
        Word::from_letter(letter)
    }

    /// The presence mask of `words` (for [`Words::first_outside`]).
    pub const fn mask(words: &[Word]) -> u32 {
        let mut m = 0;
        let mut i = 0;
        while i < words.len() {
            m |= words[i].bit();
            i += 1;
        }
        m
    }

    /// Bit of this word in a presence mask.
    ///
    /// A variable 32-bit shift is a loop on the AVR (up to 17 turns of four
    /// shifts, ~100 cycles); a byte is shifted and placed instead.
    #[inline]
    const fn bit(self) -> u32 {
        let i = self as u8;
        let b = (1u8 << (i & 7)) as u32;
        match i >> 3 {
            0 => b,
            1 => b << 8,
            _ => b << 16,
        }
    }
}

/// The value words of one line: a presence mask and one f32 per word.
///
/// Values are in the units written on the line (the interpreter applies
/// G20/G21 and G90/G91); every value is finite and within ±1e6.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Words {
    /// Bit `w as u32` set when word `w` is present.
    present: u32,
    /// Value per word, 0.0 when absent.
    values: [f32; Word::COUNT],
}

impl Words {
    /// No words.
    pub const fn new() -> Self {
        Words { present: 0, values: [0.0; Word::COUNT] }
    }

    /// The value of word `w`, if present. Always inlined: the callers name
    /// the word, so the mask test folds to one byte test (as a call, ~110
    /// cycles with the variable shift building the mask).
    #[inline(always)]
    pub fn get(&self, w: Word) -> Option<f32> {
        if self.contains(w) {
            self.values.get(w as usize).copied()
        } else {
            None
        }
    }

    /// True if word `w` is present.
    #[inline(always)]
    pub fn contains(&self, w: Word) -> bool {
        self.present & w.bit() != 0
    }

    /// Set word `w`. Returns false (and changes nothing) if it was already
    /// present.
    pub fn insert(&mut self, w: Word, value: f32) -> bool {
        if self.contains(w) {
            return false;
        }
        if let Some(slot) = self.values.get_mut(w as usize) {
            *slot = value;
            self.present |= w.bit();
        }
        true
    }

    /// Take word `w` out, returning its value. An interpreter can take the
    /// words each code uses and then reject whatever is left over.
    pub fn remove(&mut self, w: Word) -> Option<f32> {
        let v = self.get(w);
        self.present &= !w.bit();
        if let Some(slot) = self.values.get_mut(w as usize) {
            *slot = 0.0;
        }
        v
    }

    /// True when any of X, Y, Z is present (one mask test).
    #[inline]
    pub fn has_xyz(&self) -> bool {
        const XYZ: u32 = Word::X.bit() | Word::Y.bit() | Word::Z.bit();
        self.present & XYZ != 0
    }

    /// True when no word is present.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.present == 0
    }

    /// True when any of X, Y, Z or the polar words `@`, `^` is present: the
    /// line names a point.
    #[inline]
    pub fn has_position(&self) -> bool {
        const POINT: u32 = Word::mask(&[Word::X, Word::Y, Word::Z, Word::At, Word::Caret]);
        self.present & POINT != 0
    }

    /// True when every present word is in `mask` (a [`Word::mask`]): one
    /// test.
    #[inline(always)]
    pub fn within(&self, mask: u32) -> bool {
        self.present & !mask == 0
    }

    /// True when `@` or `^` is present.
    #[inline]
    pub fn has_polar(&self) -> bool {
        const POLAR: u32 = Word::mask(&[Word::At, Word::Caret]);
        self.present & POLAR != 0
    }

    /// The first present word, in bit order, that is not in `allowed` (a
    /// [`Word::mask`]): a word no code on the line uses.
    pub fn first_outside(&self, allowed: u32) -> Option<Word> {
        let extra = self.present & !allowed;
        // `Word::ALL` is a table (RAM on AVR): the letters' match instead.
        let mut i = 0u8;
        while i < Word::COUNT as u8 {
            if extra & (1 << i) != 0 {
                return Word::from_index(i);
            }
            i += 1;
        }
        None
    }

    /// The first present word in bit order (e.g. to name a left-over word).
    pub fn first(&self) -> Option<Word> {
        Word::ALL.iter().copied().find(|&w| self.contains(w))
    }

    /// The present words and their values, in bit order.
    pub fn iter(&self) -> impl Iterator<Item = (Word, f32)> + '_ {
        Word::ALL.iter().filter_map(move |&w| self.get(w).map(|v| (w, v)))
    }
}

/// Motion group (NGC group 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// G0: rapid.
    Rapid,
    /// G1: linear feed.
    Linear,
    /// G2: clockwise arc.
    ArcCw,
    /// G3: counter-clockwise arc.
    ArcCcw,
    /// G38.2: probe toward the setter, error if it does not trip.
    ProbeToward,
    /// G38.3: probe toward the setter, no error if it does not trip.
    ProbeTowardNoError,
    /// G80: cancel motion mode.
    Cancel,
    /// G73, G81, G82, G83, G85, G89: a canned cycle (see [`super::cycles`]).
    Cycle(super::cycles::Kind),
}

/// Arc plane (NGC group 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// G17.
    Xy,
    /// G18.
    Zx,
    /// G19.
    Yz,
}

/// Length units (NGC group 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    /// G20.
    Inch,
    /// G21.
    Mm,
}

/// Distance mode (NGC group 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Distance {
    /// G90.
    Absolute,
    /// G91.
    Incremental,
}

/// Feed rate mode (NGC group 5). G93 is not supported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedMode {
    /// G94: units per minute.
    UnitsPerMinute,
}

/// Cutter radius compensation (NGC group 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CutterComp {
    /// G40: off.
    Off,
    /// G41 [D<tool>]: tool left of the path, radius from the tool table.
    Left,
    /// G42 [D<tool>]: right of it.
    Right,
    /// G41.1 D<diameter>: left, with the diameter given.
    LeftDiameter,
    /// G42.1 D<diameter>: right, with the diameter given.
    RightDiameter,
}

/// Tool length offset (NGC group 8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToolLength {
    /// G43 [H].
    Apply,
    /// G49.
    Cancel,
}

/// Non-modal codes (NGC group 0), at most one per line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NonModal {
    /// G4 P<ms> / S<s>: dwell.
    Dwell,
    /// G10 L1/L2/L20: set tool table or work offsets.
    SetOffsets,
    /// G28: home.
    Home,
    /// G53: machine coordinates for this line.
    MachineCoords,
    /// G92: set the current position.
    SetPosition,
    /// G92.1, G92.2: clear the G92 offsets.
    ClearG92,
    /// G37: measure the tool with the optical setter.
    MeasureTool,
    /// G201: auxiliary motor move.
    AuxMove,
    /// G202: auxiliary motor set position.
    AuxSetPosition,
    /// G203: auxiliary motor report.
    AuxReport,
    /// G204: auxiliary motor enable/disable.
    AuxEnable,
    /// G205: auxiliary motor home.
    AuxHome,
}

/// Program stopping (NGC group 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stopping {
    /// M0: pause.
    Pause,
    /// M1: optional pause.
    OptionalPause,
    /// M2: program end.
    End,
    /// M30: program end (never "delete file").
    EndRewind,
}

/// Coolant (NGC group 8). One output drives both: M7 and M8 switch it on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coolant {
    /// M7: mist.
    Mist,
    /// M8: flood.
    Flood,
    /// M9: off.
    Off,
}

/// Path control (NGC group 13): accepted, no effect on the path here (the
/// planner always blends corners within the junction deviation `$11`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathMode {
    /// G61: exact path.
    ExactPath,
    /// G61.1: exact stop.
    ExactStop,
    /// G64 [P<tol>] [Q<tol>]: blending.
    Blend,
}

/// Spindle (NGC group 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spindle {
    /// M3: on, clockwise.
    Cw,
    /// M4: on, counter-clockwise (parsed; the interpreter rejects it).
    Ccw,
    /// M5: off.
    Off,
}

/// M codes outside the stopping, tool-change and spindle groups: at most one
/// of them per line, in [`Line::other_m`]. Add new ones here.
pub const OTHER_M_CODES: &[u16] = &[
    17, 18, 20, 23, 24, 25, 26, 27, 28, 29, 61, 84, 92, 105, 108, 110, 112, 114, 115, 119, 201, 203, 220, 400, 500, 501, 502, 503, 999, 31,
];

/// M codes whose argument is the rest of the line (a file name).
const TEXT_ARG_M_CODES: &[u16] = &[23, 28];

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
    pub retract: Option<super::cycles::Retract>,
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
fn err<T>(kind: ParseErrorKind, col: u8) -> Result<T, ParseError> {
    Err(ParseError { kind, col })
}

/// 1-based column of byte index `i`, saturating.
fn col_of(i: usize) -> u8 {
    u8::try_from(i + 1).unwrap_or(u8::MAX)
}

/// A lexed decimal number: value = ±mantissa / 10^scale, trailing fraction
/// zeros dropped.
#[derive(Clone, Copy, Debug)]
struct Number {
    negative: bool,
    /// Significant digits, ≤ 1e9.
    mantissa: u32,
    /// Power of ten to divide by.
    scale: u16,
}

impl Number {
    /// The nearest f32 (exact rounding while the mantissa is below 2^24, i.e.
    /// up to 7 significant digits; within about one ulp above).
    ///
    /// One int → float conversion and one division by an exact power of ten
    /// (the division rounds once, a multiply by 10^−scale would not): about
    /// 600 cycles on the AVR for the usual scale ≤ 9.
    fn to_f32(self) -> f32 {
        if self.mantissa == 0 {
            return 0.0;
        }
        let mut v = self.mantissa as f32;
        let mut scale = self.scale;
        while scale > 10 {
            v /= 1e10;
            scale -= 10;
        }
        if scale != 0 {
            v /= pow10(scale as u8);
        }
        if self.negative {
            -v
        } else {
            v
        }
    }

    /// The value × 10 as a code number (`38.2` → 382), if it is a
    /// non-negative number with at most one decimal.
    fn code_x10(self) -> Option<u16> {
        if self.negative && self.mantissa != 0 {
            return None;
        }
        let m = u16::try_from(self.mantissa).ok()?;
        match self.scale {
            // Not `checked_mul`: LLVM-AVR widens it into a 32-bit
            // `__mulsi3` call (~90 cycles on every G and M word).
            0 if m <= u16::MAX / 10 => Some(m * 10),
            0 => None,
            1 => Some(m),
            _ => None,
        }
    }
}

/// 10^`n` for `n` in 1..=10, exact in f32 (5^10 < 2^24). A match, not a
/// table: on AVR a const table would be copied into RAM, and the build has no
/// jump or lookup tables, so this is a few compares.
fn pow10(n: u8) -> f32 {
    match n {
        1 => 1e1,
        2 => 1e2,
        3 => 1e3,
        4 => 1e4,
        5 => 1e5,
        6 => 1e6,
        7 => 1e7,
        8 => 1e8,
        9 => 1e9,
        _ => 1e10,
    }
}

/// Most significant digits a number may have.
const MAX_SIG_DIGITS: u8 = 9;
/// Most significant digits before the point (|value| < 1e6).
const MAX_INT_DIGITS: u8 = 6;

/// Skip spaces and tabs from `pos`. Inlined: called ~10 times a line, and
/// the call cost more than the usual single compare (~360 cycles a line).
#[inline(always)]
fn skip_blanks(s: &[u8], mut pos: usize) -> usize {
    while matches!(s.get(pos), Some(b' ' | b'\t')) {
        pos += 1;
    }
    pos
}

/// The digit value of byte `c`, or a value above 9 when it is no digit.
#[inline(always)]
fn digit(c: Option<&u8>) -> u8 {
    match c {
        Some(&c) => c.wrapping_sub(b'0'),
        None => 10,
    }
}

/// Lex the number of the word whose letter is at column `col`, starting at
/// `pos` (just after the letter). Returns the number and the index after it.
///
/// The digits go into a `u32` mantissa (leading zeros and trailing fraction
/// zeros dropped) with a power-of-ten scale; [`Number::to_f32`] converts once.
///
/// The usual number (no blank inside it, at most 9 digits) is read by
/// [`lex_plain`] in one pass; anything else by [`lex_spaced`], digit by
/// digit. The two agree wherever the plain one answers
/// (`plain_and_spaced_lexers_agree`), and together they match the lexer
/// before the split (`number_lexer_matches_its_reference`). On the AVR the
/// split saved ~300 cycles a streamed line (`profile --trace`: the
/// digit-by-digit loop's state did not fit in the registers).
///
/// Always inlined into `parse_into` (three call sites): as a call, its
/// frame and its result written to memory cost ~190 cycles a number.
#[inline(always)]
fn lex_number(s: &[u8], pos: usize, col: u8) -> Result<(Number, usize), ParseError> {
    let mut pos = skip_blanks(s, pos);
    let mut negative = false;
    match s.get(pos) {
        Some(b'-') => {
            negative = true;
            pos += 1;
        }
        Some(b'+') => pos += 1,
        _ => {}
    }
    pos = skip_blanks(s, pos);
    if matches!(s.get(pos), Some(b'#' | b'[')) {
        return err(ParseErrorKind::Parameter, col);
    }
    let (mantissa, scale, len) = lex_plain(s.get(pos..).unwrap_or(&[]));
    if len != 0 {
        let number = Number { negative, mantissa, scale: scale as u16 };
        return Ok((number, pos + len as usize));
    }
    lex_spaced(s, pos, negative, col)
}

/// The number at the start of `s` (after its sign) when it is a plain one:
/// at most [`MAX_SIG_DIGITS`] digits in all, below 10⁶, no blank inside it
/// and nothing after it that makes it an error. Returns its mantissa, its
/// scale and its length in bytes, or a length of 0 for any other text,
/// which [`lex_spaced`] reads (or refuses) instead. For a plain number both
/// give the same result (`plain_and_spaced_lexers_agree`).
///
/// One pass: the integer digits are multiplied in as they come (at most 9
/// digits in all, so no overflow), the fraction's zeros only once a
/// non-zero digit follows them, so that trailing zeros drop out of the
/// mantissa and the scale. Inlined (through `lex_number`) into
/// `parse_into`, with the blank scan after the number written out: as a
/// call, and with `Iterator::find` a call of its own, ~200 cycles a line
/// more (`profile --trace`).
#[inline(always)]
fn lex_plain(s: &[u8]) -> (u32, u8, u8) {
    const NOT_PLAIN: (u32, u8, u8) = (0, 0, 0);
    let mut rest = s;
    let mut mantissa: u32 = 0;
    // Digits read.
    let mut n: u8 = 0;
    while let [c, tail @ ..] = rest {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            break;
        }
        if n == MAX_SIG_DIGITS {
            return NOT_PLAIN;
        }
        mantissa = crate::math::times10_plus(mantissa, d);
        n += 1;
        rest = tail;
    }
    // Over MAX_INT_DIGITS significant digits before the point.
    if mantissa >= 1_000_000 {
        return NOT_PLAIN;
    }
    let int_digits = n;
    // Fraction zeros not yet multiplied in.
    let mut pending: u8 = 0;
    let point = matches!(rest, [b'.', ..]);
    if let [b'.', tail @ ..] = rest {
        rest = tail;
        while let [c, tail @ ..] = rest {
            let d = c.wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            if n == MAX_SIG_DIGITS {
                return NOT_PLAIN;
            }
            n += 1;
            rest = tail;
            if d == 0 {
                pending += 1;
                continue;
            }
            while pending != 0 {
                mantissa = crate::math::times10_plus(mantissa, 0);
                pending -= 1;
            }
            mantissa = crate::math::times10_plus(mantissa, d);
        }
    }
    if n == 0 {
        return NOT_PLAIN;
    }
    match rest {
        // An exponent, a second point or sign: errors.
        [b'e' | b'E' | b'.' | b'+' | b'-', ..] => return NOT_PLAIN,
        // Blanks, then more of the number.
        [b' ' | b'\t', tail @ ..] => {
            let mut after = tail;
            while let [b' ' | b'\t', more @ ..] = after {
                after = more;
            }
            match after {
                [b'0'..=b'9', ..] => return NOT_PLAIN,
                [b'.', ..] if !point => return NOT_PLAIN,
                _ => {}
            }
        }
        _ => {}
    }
    (mantissa, n - int_digits - pending, n + point as u8)
}

/// [`lex_number`] from `first` (after the sign), digit by digit, taking
/// blanks inside the number (RS274/NGC ignores them: `X1 6.5` is X16.5).
///
/// Digits beyond [`MAX_SIG_DIGITS`] significant ones (`X24.985715729`) are
/// read and dropped, the kept ones rounded half up on the first dropped
/// digit: 9 digits are more than f32 holds, so the value is the nearest
/// f32 of the number as written (within an ulp). Only a number of 10⁶ or
/// more is out of range.
#[inline(never)]
fn lex_spaced(s: &[u8], first: usize, negative: bool, col: u8) -> Result<(Number, usize), ParseError> {
    let mut pos = first;
    let mut mantissa: u32 = 0;
    // Significant digits in `mantissa`.
    let mut sig: u8 = 0;
    let mut too_long = false;
    // Integer part: at most MAX_INT_DIGITS significant digits.
    loop {
        let d = digit(s.get(pos));
        if d > 9 {
            if let Some(next) = blank_then(s, pos, true) {
                pos = next;
                continue;
            }
            break;
        }
        pos += 1;
        if mantissa != 0 || d != 0 {
            if sig == MAX_INT_DIGITS {
                too_long = true;
            } else {
                mantissa = crate::math::times10_plus(mantissa, d);
                sig += 1;
            }
        }
    }
    let mut digits = pos != first;
    let mut scale: u16 = 0;
    // Digits were dropped past MAX_SIG_DIGITS; the first dropped one was ≥ 5.
    let mut dropped = false;
    let mut round_up = false;
    if s.get(pos) == Some(&b'.') {
        pos += 1;
        // Fraction digits read, and the zeros among the last of them not yet
        // known to be followed by a non-zero digit.
        let mut frac: u16 = 0;
        let mut pending: u16 = 0;
        loop {
            let d = digit(s.get(pos));
            if d > 9 {
                if let Some(next) = blank_then(s, pos, false) {
                    pos = next;
                    continue;
                }
                break;
            }
            pos += 1;
            frac = frac.saturating_add(1);
            if d == 0 || dropped {
                pending = pending.saturating_add(1);
                continue;
            }
            if mantissa != 0 {
                // The zeros between two significant digits are significant.
                while pending != 0 {
                    if sig == MAX_SIG_DIGITS {
                        dropped = true;
                        break;
                    }
                    mantissa = crate::math::times10_plus(mantissa, 0);
                    sig += 1;
                    scale = frac - pending;
                    pending -= 1;
                }
            }
            pending = 0;
            if dropped {
                continue;
            }
            if sig == MAX_SIG_DIGITS {
                dropped = true;
                round_up = d >= 5;
            } else {
                mantissa = crate::math::times10_plus(mantissa, d);
                sig += 1;
                scale = frac;
            }
        }
        digits |= frac != 0;
    }
    if !digits {
        return err(ParseErrorKind::BadNumber, col);
    }
    match s.get(pos) {
        Some(b'e' | b'E') => return err(ParseErrorKind::Exponent, col),
        Some(b'.' | b'+' | b'-') => return err(ParseErrorKind::BadNumber, col),
        _ => {}
    }
    if too_long {
        return err(ParseErrorKind::NumberOutOfRange, col);
    }
    if dropped {
        mantissa += round_up as u32;
        // Trailing zeros out, as the other paths leave them (`1.9999999999`
        // rounds to 2, scale 0).
        while scale != 0 {
            let (q, r) = crate::math::div10(mantissa);
            if r != 0 {
                break;
            }
            mantissa = q;
            scale -= 1;
        }
    }
    Ok((Number { negative, mantissa, scale }, pos))
}

/// At a blank inside a number: the index of the digit (or, with `point`,
/// the decimal point) that continues the number after the blanks, if one
/// does. Only reached at the end of a number, so digits cost nothing more.
#[inline(never)]
fn blank_then(s: &[u8], pos: usize, point: bool) -> Option<usize> {
    if !matches!(s.get(pos), Some(b' ' | b'\t')) {
        return None;
    }
    let q = skip_blanks(s, pos);
    match s.get(q) {
        Some(b'0'..=b'9') => Some(q),
        Some(b'.') if point => Some(q),
        _ => None,
    }
}

/// Skip a leading `N<n>` line number (any length, optional sign, digits
/// with an optional fraction: LinuxCNC takes `N4567.789`).
fn skip_line_number(s: &[u8], pos: usize, col: u8) -> Result<usize, ParseError> {
    let mut pos = skip_blanks(s, pos);
    if matches!(s.get(pos), Some(b'-' | b'+')) {
        pos += 1;
    }
    let start = pos;
    while matches!(s.get(pos), Some(b'0'..=b'9')) {
        pos += 1;
    }
    if pos != start && s.get(pos) == Some(&b'.') {
        pos += 1;
        while matches!(s.get(pos), Some(b'0'..=b'9')) {
            pos += 1;
        }
    }
    if pos == start || matches!(s.get(pos), Some(b'.' | b'e' | b'E' | b'+' | b'-')) {
        return err(ParseErrorKind::BadNumber, col);
    }
    Ok(pos)
}

/// Put `v` in a modal group slot, or report the conflict at `col`.
fn set_group<T>(slot: &mut Option<T>, v: T, col: u8) -> Result<(), ParseError> {
    if slot.is_some() {
        return err(ParseErrorKind::ModalGroupConflict, col);
    }
    *slot = Some(v);
    Ok(())
}

/// Record G code `code_x10` (G38.2 → 382) in `line`.
fn apply_g(line: &mut Line, code_x10: u16, col: u8) -> Result<(), ParseError> {
    match code_x10 {
        0 => set_group(&mut line.motion, Motion::Rapid, col),
        10 => set_group(&mut line.motion, Motion::Linear, col),
        20 => set_group(&mut line.motion, Motion::ArcCw, col),
        30 => set_group(&mut line.motion, Motion::ArcCcw, col),
        382 => set_group(&mut line.motion, Motion::ProbeToward, col),
        383 => set_group(&mut line.motion, Motion::ProbeTowardNoError, col),
        800 => set_group(&mut line.motion, Motion::Cancel, col),
        730 => set_group(&mut line.motion, Motion::Cycle(Kind::ChipBreak), col),
        810 => set_group(&mut line.motion, Motion::Cycle(Kind::Drill), col),
        820 => set_group(&mut line.motion, Motion::Cycle(Kind::DrillDwell), col),
        830 => set_group(&mut line.motion, Motion::Cycle(Kind::Peck), col),
        850 => set_group(&mut line.motion, Motion::Cycle(Kind::Bore), col),
        890 => set_group(&mut line.motion, Motion::Cycle(Kind::BoreDwell), col),
        760 | 840 | 860 | 870 | 880 => err(ParseErrorKind::UnsupportedCycle, col),
        980 => set_group(&mut line.retract, Retract::Initial, col),
        990 => set_group(&mut line.retract, Retract::RPlane, col),
        170 => set_group(&mut line.plane, Plane::Xy, col),
        180 => set_group(&mut line.plane, Plane::Zx, col),
        190 => set_group(&mut line.plane, Plane::Yz, col),
        200 => set_group(&mut line.units, Units::Inch, col),
        210 => set_group(&mut line.units, Units::Mm, col),
        900 => set_group(&mut line.distance, Distance::Absolute, col),
        910 => set_group(&mut line.distance, Distance::Incremental, col),
        940 => set_group(&mut line.feed_mode, FeedMode::UnitsPerMinute, col),
        540 | 550 | 560 | 570 | 580 | 590 => set_group(&mut line.wcs, ((code_x10 - 540) / 10) as u8, col),
        430 => set_group(&mut line.tool_length, ToolLength::Apply, col),
        490 => set_group(&mut line.tool_length, ToolLength::Cancel, col),
        40 => set_group(&mut line.non_modal, NonModal::Dwell, col),
        400 => set_group(&mut line.cutter_comp, CutterComp::Off, col),
        410 => set_group(&mut line.cutter_comp, CutterComp::Left, col),
        420 => set_group(&mut line.cutter_comp, CutterComp::Right, col),
        411 => set_group(&mut line.cutter_comp, CutterComp::LeftDiameter, col),
        421 => set_group(&mut line.cutter_comp, CutterComp::RightDiameter, col),
        610 => set_group(&mut line.path_mode, PathMode::ExactPath, col),
        611 => set_group(&mut line.path_mode, PathMode::ExactStop, col),
        640 => set_group(&mut line.path_mode, PathMode::Blend, col),
        901 => set_group(&mut line.arc_absolute, true, col),
        911 => set_group(&mut line.arc_absolute, false, col),
        921 | 922 => set_group(&mut line.non_modal, NonModal::ClearG92, col),
        100 => set_group(&mut line.non_modal, NonModal::SetOffsets, col),
        280 => set_group(&mut line.non_modal, NonModal::Home, col),
        530 => set_group(&mut line.non_modal, NonModal::MachineCoords, col),
        920 => set_group(&mut line.non_modal, NonModal::SetPosition, col),
        370 => set_group(&mut line.non_modal, NonModal::MeasureTool, col),
        2010 => set_group(&mut line.non_modal, NonModal::AuxMove, col),
        2020 => set_group(&mut line.non_modal, NonModal::AuxSetPosition, col),
        2030 => set_group(&mut line.non_modal, NonModal::AuxReport, col),
        2040 => set_group(&mut line.non_modal, NonModal::AuxEnable, col),
        2050 => set_group(&mut line.non_modal, NonModal::AuxHome, col),
        _ => err(ParseErrorKind::UnsupportedCode, col),
    }
}

/// Record M code `code` in `line`.
fn apply_m(line: &mut Line, code: u16, col: u8) -> Result<(), ParseError> {
    match code {
        0 => set_group(&mut line.stopping, Stopping::Pause, col),
        1 => set_group(&mut line.stopping, Stopping::OptionalPause, col),
        2 => set_group(&mut line.stopping, Stopping::End, col),
        30 => set_group(&mut line.stopping, Stopping::EndRewind, col),
        3 => set_group(&mut line.spindle, Spindle::Cw, col),
        4 => set_group(&mut line.spindle, Spindle::Ccw, col),
        5 => set_group(&mut line.spindle, Spindle::Off, col),
        // M7 and M8 may share a line (LinuxCNC): both switch the one output on.
        7 | 8 if matches!(line.coolant, Some(Coolant::Mist | Coolant::Flood)) && line.coolant != Some(coolant_of(code)) => {
            line.coolant = Some(Coolant::Flood);
            Ok(())
        }
        7..=9 => set_group(&mut line.coolant, coolant_of(code), col),
        6 if line.tool_change => err(ParseErrorKind::ModalGroupConflict, col),
        6 => {
            line.tool_change = true;
            Ok(())
        }
        _ if OTHER_M_CODES.contains(&code) => set_group(&mut line.other_m, code, col),
        62..=65 => err(ParseErrorKind::NoOutputs, col),
        _ => err(ParseErrorKind::UnsupportedCode, col),
    }
}

/// The coolant code of M7, M8, M9.
fn coolant_of(code: u16) -> Coolant {
    match code {
        7 => Coolant::Mist,
        8 => Coolant::Flood,
        _ => Coolant::Off,
    }
}

/// An `O` word at `pos` (just after the letter, column `col`): a program
/// number alone on its line (`O1001`, `O0000(NAME)`; posts for Fanuc-style
/// controls write one) is accepted when it comes first; anything else
/// (`O100 sub`, `o<name> call`, `O10 while [...]`, an O word after other
/// words) is an O-word subroutine or loop and refused.
fn program_number(s: &[u8], pos: usize, col: u8, first: bool) -> Result<(), ParseError> {
    let refuse = err(ParseErrorKind::OWord, col);
    if !first {
        return refuse;
    }
    let Ok((n, mut pos)) = lex_number(s, pos, col) else {
        return refuse;
    };
    if n.negative || n.scale != 0 {
        return refuse;
    }
    // Only blanks and comments may follow.
    loop {
        pos = skip_blanks(s, pos);
        match s.get(pos) {
            None | Some(b';') => return Ok(()),
            Some(b'(') => match s.get(pos + 1..).and_then(|r| r.iter().position(|&b| b == b')')) {
                Some(i) => pos += i + 2,
                None => return err(ParseErrorKind::UnclosedComment, col_of(pos)),
            },
            Some(_) => return refuse,
        }
    }
}

/// The file name after M23/M28 starting at `pos`: up to `;`, blanks trimmed.
/// Returns (start, len).
fn text_arg(s: &[u8], pos: usize, col: u8) -> Result<(u8, u8), ParseError> {
    let start = skip_blanks(s, pos);
    let rest = s.get(start..).unwrap_or(&[]);
    let mut len = rest.iter().position(|&b| b == b';').unwrap_or(rest.len());
    while len > 0 && matches!(rest.get(len - 1), Some(b' ' | b'\t')) {
        len -= 1;
    }
    match (u8::try_from(start), u8::try_from(len)) {
        (Ok(start), Ok(len)) if len > 0 => Ok((start, len)),
        _ => err(ParseErrorKind::MissingFileName, col),
    }
}

/// Parse one line of G-code (the command text after protocol stripping).
///
/// A malformed line is rejected whole with the column of the first problem;
/// a blank or comment-only line gives an empty [`Line`].
pub fn parse(s: &[u8]) -> Result<Line, ParseError> {
    let mut line = Line::default();
    parse_into(s, &mut line)?;
    Ok(line)
}

/// [`parse`] into `line`, which must be empty (`Line::default()`), for
/// callers that keep the line in place: a `Result<Line, _>` is one more
/// 100-byte copy on AVR, and clearing the line here again cost ~150 cycles
/// per streamed line. On an error `line` holds what was parsed before it.
#[inline(never)]
pub fn parse_into(s: &[u8], line: &mut Line) -> Result<(), ParseError> {
    debug_assert!(*line == Line::default());
    if s.len() > MAX_PARSE_LEN {
        return err(ParseErrorKind::LineTooLong, col_of(MAX_PARSE_LEN));
    }
    let mut pos = 0;
    let mut seen_word = false;
    // Column of the first axis word without a number (`G28 X`), 0 if none.
    let mut bare_axis_col = 0u8;
    while let Some(&c) = s.get(pos) {
        let col = col_of(pos);
        match c {
            b' ' | b'\t' => pos += 1,
            b'(' => {
                let rest = s.get(pos + 1..).unwrap_or(&[]);
                match rest.iter().position(|&b| b == b')') {
                    Some(i) => pos += i + 2,
                    None => return err(ParseErrorKind::UnclosedComment, col),
                }
            }
            b';' => break,
            // A program marker (`%`, `% vfd enable`): the rest is not G-code.
            b'%' if !seen_word => break,
            // `@` and `^`: LinuxCNC's polar words, read like the letters.
            _ if c.is_ascii_alphabetic() || c == b'@' || c == b'^' => {
                pos += 1;
                match c.to_ascii_uppercase() {
                    b'G' => {
                        let (n, next) = lex_number(s, pos, col)?;
                        pos = next;
                        let code = n.code_x10();
                        let code = code.ok_or(ParseError { kind: ParseErrorKind::UnsupportedCode, col })?;
                        apply_g(line, code, col)?;
                    }
                    b'M' => {
                        let (n, next) = lex_number(s, pos, col)?;
                        pos = next;
                        let code = match n.code_x10() {
                            Some(c) if c % 10 == 0 => c / 10,
                            _ => return err(ParseErrorKind::UnsupportedCode, col),
                        };
                        apply_m(line, code, col)?;
                        if TEXT_ARG_M_CODES.contains(&code) {
                            line.text_arg = Some(text_arg(s, pos, col)?);
                            break;
                        }
                    }
                    b'N' if !seen_word => pos = skip_line_number(s, pos, col)?,
                    b'O' => {
                        // First on the line but for a line number.
                        program_number(s, pos, col, line.is_empty())?;
                        break;
                    }
                    up => {
                        // Every other letter is A, C, U, V or W.
                        let Some(w) = Word::from_letter(up) else {
                            return err(ParseErrorKind::NoSuchAxis, col);
                        };
                        if matches!(w, Word::X | Word::Y | Word::Z) && no_number_follows(s, pos) {
                            // `G28 X`: an axis named without a value. Only G28
                            // may do that; checked once the whole line is read.
                            if !line.words.insert(w, 0.0) {
                                return err(ParseErrorKind::RepeatedWord, col);
                            }
                            if bare_axis_col == 0 {
                                bare_axis_col = col;
                            }
                            seen_word = true;
                            continue;
                        }
                        let (n, next) = lex_number(s, pos, col)?;
                        pos = next;
                        if w == Word::T && (n.scale != 0 || (n.negative && n.mantissa != 0) || n.mantissa > 255) {
                            return err(ParseErrorKind::BadToolNumber, col);
                        }
                        if !line.words.insert(w, n.to_f32()) {
                            return err(ParseErrorKind::RepeatedWord, col);
                        }
                    }
                }
                seen_word = true;
            }
            b'#' | b'[' => return err(ParseErrorKind::Parameter, col),
            _ => return err(ParseErrorKind::Unexpected, col),
        }
    }
    if bare_axis_col != 0 && line.non_modal != Some(NonModal::Home) {
        return err(ParseErrorKind::BadNumber, bare_axis_col);
    }
    Ok(())
}

/// True when the word whose letter ends at `pos` has no number at all: the
/// next non-blank is the end of the line, a comment, or the letter of another
/// word (`G28 X Y`). `X-`, `X.` or `Xa` are not bare: they are bad numbers.
fn no_number_follows(s: &[u8], pos: usize) -> bool {
    match s.get(skip_blanks(s, pos)) {
        None | Some(b';' | b'(') => true,
        Some(&c) => c.is_ascii_alphabetic() && (matches!(c.to_ascii_uppercase(), b'G' | b'M') || Word::from_letter(c).is_some()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(s: &str) -> Line {
        match parse(s.as_bytes()) {
            Ok(l) => l,
            Err(e) => panic!("{:?} rejected: {:?}", s, e),
        }
    }

    fn fails(s: &str) -> (ParseErrorKind, u8) {
        match parse(s.as_bytes()) {
            Ok(l) => panic!("{:?} accepted: {:?}", s, l),
            Err(e) => (e.kind, e.col),
        }
    }

    fn x(s: &str) -> f32 {
        ok(s).word(Word::X).unwrap()
    }

    /// The number lexer spelled out on decimal text, the reference the
    /// one-pass lexer must match: the digits are gathered as characters
    /// (blanks inside the number skipped as RS274/NGC says), then cut to
    /// [`MAX_SIG_DIGITS`] significant digits with half-up rounding on the
    /// digit text, and only then turned into a mantissa and a scale.
    fn reference_lex_number(s: &[u8], pos: usize, col: u8) -> Result<(Number, usize), ParseError> {
        let mut pos = skip_blanks(s, pos);
        let mut negative = false;
        match s.get(pos) {
            Some(b'-') => {
                negative = true;
                pos += 1;
            }
            Some(b'+') => pos += 1,
            _ => {}
        }
        pos = skip_blanks(s, pos);
        if matches!(s.get(pos), Some(b'#' | b'[')) {
            return err(ParseErrorKind::Parameter, col);
        }
        let mut int = String::new();
        let mut frac = String::new();
        loop {
            match s.get(pos) {
                Some(c @ b'0'..=b'9') => {
                    int.push(*c as char);
                    pos += 1;
                }
                _ => match blank_then(s, pos, true) {
                    Some(next) => pos = next,
                    None => break,
                },
            }
        }
        let point = s.get(pos) == Some(&b'.');
        if point {
            pos += 1;
            loop {
                match s.get(pos) {
                    Some(c @ b'0'..=b'9') => {
                        frac.push(*c as char);
                        pos += 1;
                    }
                    _ => match blank_then(s, pos, false) {
                        Some(next) => pos = next,
                        None => break,
                    },
                }
            }
        }
        if int.is_empty() && frac.is_empty() {
            return err(ParseErrorKind::BadNumber, col);
        }
        match s.get(pos) {
            Some(b'e' | b'E') => return err(ParseErrorKind::Exponent, col),
            Some(b'.' | b'+' | b'-') => return err(ParseErrorKind::BadNumber, col),
            _ => {}
        }
        let int = int.trim_start_matches('0');
        if int.len() > MAX_INT_DIGITS as usize {
            return err(ParseErrorKind::NumberOutOfRange, col);
        }
        let frac = frac.trim_end_matches('0');
        // All the digits, and how many of them are fraction digits.
        let all = format!("{int}{frac}");
        let mut scale = frac.len();
        let lead = all.len() - all.trim_start_matches('0').len();
        let mut kept: Vec<u8> = all.bytes().skip(lead).collect();
        let mut up = false;
        if kept.len() > MAX_SIG_DIGITS as usize {
            let cut = kept.len() - MAX_SIG_DIGITS as usize;
            up = kept[MAX_SIG_DIGITS as usize] >= b'5';
            kept.truncate(MAX_SIG_DIGITS as usize);
            scale -= cut;
        }
        let mut mantissa: u64 = kept.iter().fold(0, |m, &d| m * 10 + (d - b'0') as u64) + up as u64;
        while scale > 0 && mantissa.is_multiple_of(10) && mantissa != 0 {
            mantissa /= 10;
            scale -= 1;
        }
        if mantissa == 0 {
            scale = 0;
        }
        Ok((Number { negative, mantissa: mantissa as u32, scale: scale as u16 }, pos))
    }

    /// Random number-ish texts: digits, points, signs, blanks, exponents,
    /// letters, `#`.
    fn number_texts() -> Vec<Vec<u8>> {
        const ALPHABET: &[u8] = b"0000123456789....  \t--+eEX#[Y;";
        let mut seed = 0x9E37_79B9_u32;
        let mut out = Vec::new();
        for len in 0..24 {
            for _ in 0..3000 {
                let mut t = Vec::new();
                for _ in 0..len {
                    seed ^= seed << 13;
                    seed ^= seed >> 17;
                    seed ^= seed << 5;
                    t.push(ALPHABET[(seed >> 8) as usize % ALPHABET.len()]);
                }
                out.push(t);
            }
        }
        for t in [
            &b"19.950"[..],
            b"-1.257",
            b"0.000",
            b"1.0000000000",
            b"0.0000000001",
            b"999999.999",
            b"1000000",
            b"123456789",
            b"1234567890",
            b"12345.6789",
            b"00000000000001.5",
            b"1.50000000000000",
            b"1 6.5",
            b"1 .5",
            b"1. 5",
            b"- 1",
            b"+.5",
            b".",
            b"-",
            b"",
            b"1e5",
            b"1.2.3",
            b"1-2",
            b"  7  ",
            b"007.0700",
        ] {
            out.push(t.to_vec());
        }
        out
    }

    fn same(a: Result<(Number, usize), ParseError>, b: Result<(Number, usize), ParseError>) -> bool {
        match (a, b) {
            (Ok((x, i)), Ok((y, j))) => (x.negative, x.mantissa, x.scale, i) == (y.negative, y.mantissa, y.scale, j),
            (Err(e), Err(f)) => e == f,
            _ => false,
        }
    }

    #[test]
    fn number_lexer_matches_its_reference() {
        let mut plain = 0;
        for t in number_texts() {
            for pos in 0..=t.len() {
                let new = lex_number(&t, pos, 7);
                let old = reference_lex_number(&t, pos, 7);
                assert!(
                    same(new, old),
                    "{:?} at {pos}: {:?} vs {:?}",
                    String::from_utf8_lossy(&t),
                    new.map(|(n, i)| (n.mantissa, n.scale, i)),
                    old.map(|(n, i)| (n.mantissa, n.scale, i))
                );
                if lex_plain(t.get(pos..).unwrap_or(&[])).2 != 0 {
                    plain += 1;
                }
            }
        }
        assert!(plain > 100_000, "{plain}");
    }

    #[test]
    fn plain_and_spaced_lexers_agree() {
        for t in number_texts() {
            for first in 0..=t.len() {
                let (mantissa, scale, len) = lex_plain(&t[first..]);
                if len == 0 {
                    continue;
                }
                let (n, end) = lex_spaced(&t, first, false, 1).unwrap();
                assert_eq!(
                    (n.mantissa, n.scale, end),
                    (mantissa, scale as u16, first + len as usize),
                    "{:?}",
                    String::from_utf8_lossy(&t[first..])
                );
            }
        }
    }

    #[test]
    fn line_fits_the_ram_budget() {
        let size = core::mem::size_of::<Line>();
        println!("size_of::<Line>() = {size} bytes (host)");
        assert!(size <= 120);
    }

    #[test]
    fn canned_cycles_are_motion_codes_and_g98_g99_their_own_group() {
        assert_eq!(ok("G81").motion, Some(Motion::Cycle(Kind::Drill)));
        assert_eq!(ok("G82").motion, Some(Motion::Cycle(Kind::DrillDwell)));
        assert_eq!(ok("G83").motion, Some(Motion::Cycle(Kind::Peck)));
        assert_eq!(ok("G73").motion, Some(Motion::Cycle(Kind::ChipBreak)));
        assert_eq!(ok("G85").motion, Some(Motion::Cycle(Kind::Bore)));
        assert_eq!(ok("g89").motion, Some(Motion::Cycle(Kind::BoreDwell)));
        let l = ok("G98 G83 X1 Y2 Z-3 R1 Q0.5 F100 L2");
        assert_eq!((l.retract, l.motion), (Some(Retract::Initial), Some(Motion::Cycle(Kind::Peck))));
        assert_eq!((l.word(Word::R), l.word(Word::Q), l.word(Word::L)), (Some(1.0), Some(0.5), Some(2.0)));
        assert_eq!(ok("G99").retract, Some(Retract::RPlane));
        assert_eq!(ok("G99").motion, None);
        // One motion group: a cycle and G0 (or two cycles) conflict; so do G98 and G99.
        assert_eq!(fails("G81 G0 X1"), (ParseErrorKind::ModalGroupConflict, 5));
        assert_eq!(fails("G81 G83"), (ParseErrorKind::ModalGroupConflict, 5));
        assert_eq!(fails("G98 G99"), (ParseErrorKind::ModalGroupConflict, 5));
        for c in ["G76", "G84", "G86", "G87", "G88"] {
            assert_eq!(fails(c), (ParseErrorKind::UnsupportedCycle, 1));
        }
    }

    #[test]
    fn every_supported_g_code_is_accepted_in_its_group() {
        assert_eq!(ok("G0").motion, Some(Motion::Rapid));
        assert_eq!(ok("G1").motion, Some(Motion::Linear));
        assert_eq!(ok("G2").motion, Some(Motion::ArcCw));
        assert_eq!(ok("G3").motion, Some(Motion::ArcCcw));
        assert_eq!(ok("G38.2").motion, Some(Motion::ProbeToward));
        assert_eq!(ok("G38.3").motion, Some(Motion::ProbeTowardNoError));
        assert_eq!(ok("G80").motion, Some(Motion::Cancel));
        assert_eq!(ok("G17").plane, Some(Plane::Xy));
        assert_eq!(ok("G18").plane, Some(Plane::Zx));
        assert_eq!(ok("G19").plane, Some(Plane::Yz));
        assert_eq!(ok("G20").units, Some(Units::Inch));
        assert_eq!(ok("G21").units, Some(Units::Mm));
        assert_eq!(ok("G90").distance, Some(Distance::Absolute));
        assert_eq!(ok("G91").distance, Some(Distance::Incremental));
        assert_eq!(ok("G94").feed_mode, Some(FeedMode::UnitsPerMinute));
        for (i, g) in ["G54", "G55", "G56", "G57", "G58", "G59"].iter().enumerate() {
            assert_eq!(ok(g).wcs, Some(i as u8));
        }
        assert_eq!(ok("G43 H3").tool_length, Some(ToolLength::Apply));
        assert_eq!(ok("G49").tool_length, Some(ToolLength::Cancel));
        let non_modal = [
            ("G4", NonModal::Dwell),
            ("G10", NonModal::SetOffsets),
            ("G28", NonModal::Home),
            ("G53", NonModal::MachineCoords),
            ("G92", NonModal::SetPosition),
            ("G37", NonModal::MeasureTool),
            ("G201", NonModal::AuxMove),
            ("G202", NonModal::AuxSetPosition),
            ("G203", NonModal::AuxReport),
            ("G204", NonModal::AuxEnable),
            ("G205", NonModal::AuxHome),
        ];
        for (g, want) in non_modal {
            assert_eq!(ok(g).non_modal, Some(want), "{g}");
        }
    }

    #[test]
    fn leading_zeros_and_zero_decimals_in_codes_are_the_same_code() {
        assert_eq!(ok("G00").motion, Some(Motion::Rapid));
        assert_eq!(ok("G01").motion, Some(Motion::Linear));
        assert_eq!(ok("G1.0").motion, Some(Motion::Linear));
        assert_eq!(ok("G038.20").motion, Some(Motion::ProbeToward));
        assert_eq!(ok("M03").spindle, Some(Spindle::Cw));
        assert_eq!(ok("M3.0").spindle, Some(Spindle::Cw));
    }

    #[test]
    fn every_supported_m_code_is_accepted_in_its_group() {
        assert_eq!(ok("M0").stopping, Some(Stopping::Pause));
        assert_eq!(ok("M1").stopping, Some(Stopping::OptionalPause));
        assert_eq!(ok("M2").stopping, Some(Stopping::End));
        assert_eq!(ok("M30").stopping, Some(Stopping::EndRewind));
        assert_eq!(ok("M3 S1000").spindle, Some(Spindle::Cw));
        assert_eq!(ok("M4").spindle, Some(Spindle::Ccw));
        assert_eq!(ok("M5").spindle, Some(Spindle::Off));
        assert!(ok("M6").tool_change);
        assert!(!ok("G0").tool_change);
        for &m in OTHER_M_CODES {
            let text = if TEXT_ARG_M_CODES.contains(&m) { format!("M{m} A.GCO") } else { format!("M{m}") };
            assert_eq!(ok(&text).other_m, Some(m), "{text}");
        }
    }

    #[test]
    fn g_codes_with_a_decimal_other_than_g38_2_and_g38_3_are_unsupported() {
        assert_eq!(fails("G1.5"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G38.1"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G38.25"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G38"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("M3.5"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G-1"), (ParseErrorKind::UnsupportedCode, 1));
    }

    #[test]
    fn unknown_g_and_m_codes_point_at_the_word() {
        assert_eq!(fails("G93"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G1 X1 G33.1"), (ParseErrorKind::UnsupportedCode, 7));
        assert_eq!(fails("M11"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G0 M104"), (ParseErrorKind::UnsupportedCode, 4));
        assert_eq!(fails("M65535"), (ParseErrorKind::UnsupportedCode, 1));
        assert_eq!(fails("G7000"), (ParseErrorKind::UnsupportedCode, 1));
    }

    #[test]
    fn two_codes_of_one_group_conflict_at_the_second() {
        assert_eq!(fails("G0 G1"), (ParseErrorKind::ModalGroupConflict, 4));
        assert_eq!(fails("G1 G1"), (ParseErrorKind::ModalGroupConflict, 4));
        assert_eq!(fails("G54 G55"), (ParseErrorKind::ModalGroupConflict, 5));
        assert_eq!(fails("G4 P1 G53"), (ParseErrorKind::ModalGroupConflict, 7));
        assert_eq!(fails("M3 M5"), (ParseErrorKind::ModalGroupConflict, 4));
        assert_eq!(fails("M6 M6"), (ParseErrorKind::ModalGroupConflict, 4));
        assert_eq!(fails("M114 M115"), (ParseErrorKind::ModalGroupConflict, 6));
        assert_eq!(fails("M0 M30"), (ParseErrorKind::ModalGroupConflict, 4));
    }

    #[test]
    fn codes_of_different_groups_share_a_line() {
        let l = ok("G90 G21 G17 G54 G94 G49 G53 G0 X1 M5 M6 T2 M400");
        assert_eq!(l.distance, Some(Distance::Absolute));
        assert_eq!(l.units, Some(Units::Mm));
        assert_eq!(l.plane, Some(Plane::Xy));
        assert_eq!(l.wcs, Some(0));
        assert_eq!(l.feed_mode, Some(FeedMode::UnitsPerMinute));
        assert_eq!(l.tool_length, Some(ToolLength::Cancel));
        assert_eq!(l.non_modal, Some(NonModal::MachineCoords));
        assert_eq!(l.motion, Some(Motion::Rapid));
        assert_eq!(l.spindle, Some(Spindle::Off));
        assert!(l.tool_change);
        assert_eq!(l.tool(), Some(2));
        assert_eq!(l.other_m, Some(400));
    }

    #[test]
    fn every_value_word_is_read() {
        let l = ok("B1 D2 E3 F4 H5 I6 J7 K8 L9 N10 P11 Q12 R13 S14 T15 X16 Y17 Z18 @19 ^20");
        for (i, w) in Word::ALL.iter().enumerate() {
            assert_eq!(l.word(*w), Some((i + 1) as f32), "{}", w.letter() as char);
        }
        assert_eq!(l.words.iter().count(), Word::COUNT);
    }

    #[test]
    fn axis_letters_of_axes_this_machine_lacks_are_refused_by_name() {
        // LinuxCNC refuses an axis its configuration lacks ("Cannot use A
        // word"); a 3-axis mill cannot honour A0 either (corpus 21).
        assert_eq!(fails("G1 A5"), (ParseErrorKind::NoSuchAxis, 4));
        assert_eq!(fails("C1"), (ParseErrorKind::NoSuchAxis, 1));
        assert_eq!(fails("G0 x1 u2"), (ParseErrorKind::NoSuchAxis, 7));
        assert_eq!(fails("N4 G0 G90 G54 X3. Y82.494 A0. S3183 M3 F300"), (ParseErrorKind::NoSuchAxis, 27));
        for c in b"VW" {
            assert_eq!(fails(&format!("G1 {}1", *c as char)).0, ParseErrorKind::NoSuchAxis);
        }
        assert!(ParseErrorKind::NoSuchAxis.message().bytes().map(char::from).collect::<String>().contains("X Y Z only"));
    }

    #[test]
    fn a_program_number_alone_is_accepted_and_o_word_control_flow_is_refused() {
        // Fanuc/HAAS-style posts (corpus 06, 21, 24).
        assert!(ok("O1001").is_empty());
        assert!(ok("O01023").is_empty());
        assert!(ok("O00001 ").is_empty());
        assert!(ok("O0000(3 HEATSINK PROFILE)").is_empty());
        assert!(ok("N10 O1001 (PART) ; end").is_empty());
        assert!(ok("o1001").is_empty());
        // LinuxCNC O-words: subroutines, loops, conditionals (corpus 01, 18).
        for l in ["o100 sub", "o100 endsub", "O100 call [1] [2]", "o10 while [#1 GT 0]", "o7 if [1]", "o<name> call", "O", "O-1", "O1.5"] {
            assert_eq!(fails(l), (ParseErrorKind::OWord, 1), "{l}");
        }
        assert_eq!(fails("G0 X1 O100"), (ParseErrorKind::OWord, 7));
        assert_eq!(fails("O100 G0 X1"), (ParseErrorKind::OWord, 1));
        assert!(ParseErrorKind::OWord.message().bytes().map(char::from).collect::<String>().contains("O-word"));
    }

    #[test]
    fn parameters_and_expressions_are_refused_by_name() {
        for (l, col) in [
            ("#1=5", 1),
            ("#<_feed> = 5", 1),
            ("G1 F#100", 4),
            ("g0 z#<_safe_Z>", 4),
            ("G1 X[#1+2]", 4),
            ("G1 X-#1", 4),
            ("X [1]", 1),
            ("[1]", 1),
        ] {
            assert_eq!(fails(l), (ParseErrorKind::Parameter, col), "{l}");
        }
        assert!(ParseErrorKind::Parameter.message().bytes().map(char::from).collect::<String>().contains("# parameters"));
    }

    #[test]
    fn cutter_compensation_codes_are_one_modal_group() {
        assert_eq!(ok("G41").cutter_comp, Some(CutterComp::Left));
        assert_eq!(ok("G42 D1").cutter_comp, Some(CutterComp::Right));
        assert_eq!(ok("G42 D1").word(Word::D), Some(1.0));
        assert_eq!(ok("G41.1 D2").cutter_comp, Some(CutterComp::LeftDiameter));
        assert_eq!(ok("g42.1").cutter_comp, Some(CutterComp::RightDiameter));
        assert_eq!(ok("G40").cutter_comp, Some(CutterComp::Off));
        let l = ok("G40 G1 X25 Y10");
        assert_eq!(l.cutter_comp, Some(CutterComp::Off));
        assert_eq!(l.motion, Some(Motion::Linear));
        assert_eq!(l.word(Word::X), Some(25.0));
        assert_eq!(fails("G40 G40"), (ParseErrorKind::ModalGroupConflict, 5));
        assert_eq!(fails("G41 G42"), (ParseErrorKind::ModalGroupConflict, 5));
        assert_eq!(ok("G17 G20 G40 G90").cutter_comp, Some(CutterComp::Off));
    }

    #[test]
    fn preamble_codes_path_mode_arc_distance_and_g92_1_are_accepted() {
        assert_eq!(ok("G64").path_mode, Some(PathMode::Blend));
        let l = ok("G64 P0.01");
        assert_eq!((l.path_mode, l.word(Word::P)), (Some(PathMode::Blend), Some(0.01)));
        assert_eq!(ok("G64 P0.01 Q0.005").path_mode, Some(PathMode::Blend));
        assert_eq!(ok("G61").path_mode, Some(PathMode::ExactPath));
        assert_eq!(ok("G61.1").path_mode, Some(PathMode::ExactStop));
        assert_eq!(fails("G61 G64"), (ParseErrorKind::ModalGroupConflict, 5));
        let l = ok("g20 g64");
        assert_eq!((l.units, l.path_mode), (Some(Units::Inch), Some(PathMode::Blend)));
        assert_eq!(ok("G90.1").arc_absolute, Some(true));
        assert_eq!(ok("G91.1").arc_absolute, Some(false));
        assert_eq!(ok("G91.1").distance, None, "G91.1 is not G91");
        assert_eq!(fails("G90.1 G91.1"), (ParseErrorKind::ModalGroupConflict, 7));
        let l = ok("G90 G90.1");
        assert_eq!((l.distance, l.arc_absolute), (Some(Distance::Absolute), Some(true)));
        assert_eq!(ok("G92.1").non_modal, Some(NonModal::ClearG92));
        assert_eq!(ok("G92.2").non_modal, Some(NonModal::ClearG92));
        assert_eq!(ok("G80").motion, Some(Motion::Cancel));
        assert_eq!(fails("G17.1").0, ParseErrorKind::UnsupportedCode);
        assert_eq!(fails("G33.1 Z-1 K0.05").0, ParseErrorKind::UnsupportedCode);
    }

    #[test]
    fn coolant_codes_m7_m8_m9() {
        assert_eq!(ok("M7").coolant, Some(Coolant::Mist));
        assert_eq!(ok("M8").coolant, Some(Coolant::Flood));
        assert_eq!(ok("M9").coolant, Some(Coolant::Off));
        assert_eq!(ok("S764 M3 M8").coolant, Some(Coolant::Flood));
        assert_eq!(ok("M5 M9").coolant, Some(Coolant::Off));
        // LinuxCNC allows M7 and M8 together: one output, on.
        assert_eq!(ok("M7 M8").coolant, Some(Coolant::Flood));
        assert_eq!(fails("M8 M9"), (ParseErrorKind::ModalGroupConflict, 4));
        assert_eq!(fails("M9 M9"), (ParseErrorKind::ModalGroupConflict, 4));
        assert_eq!(fails("M8 M8"), (ParseErrorKind::ModalGroupConflict, 4));
    }

    #[test]
    fn line_numbers_without_checksums_are_skipped() {
        // grbl-style senders stream N on every line (corpus 04, 06, 21).
        assert_eq!(ok("N5 G00 G90 G54 X3. Y82.494 S3183 M3"), ok("G00 G90 G54 X3. Y82.494 S3183 M3"));
        assert_eq!(ok("N0010 G17 G21 G90"), ok("G17 G21 G90"));
    }

    #[test]
    fn a_repeated_word_is_an_error_at_the_second() {
        assert_eq!(fails("G1 X1 X2"), (ParseErrorKind::RepeatedWord, 7));
        assert_eq!(fails("G1X1Y2x3"), (ParseErrorKind::RepeatedWord, 7));
        assert_eq!(fails("M110 N1 N2"), (ParseErrorKind::RepeatedWord, 9));
    }

    #[test]
    fn case_does_not_matter() {
        assert_eq!(ok("g1 x10 y-2.5 f300"), ok("G1 X10 Y-2.5 F300"));
        assert_eq!(ok("g38.2 z-5").motion, Some(Motion::ProbeToward));
    }

    #[test]
    fn blanks_are_optional_between_words_and_allowed_after_a_letter() {
        let l = ok("G1X10Y-2.5");
        assert_eq!(l.motion, Some(Motion::Linear));
        assert_eq!(l.word(Word::X), Some(10.0));
        assert_eq!(l.word(Word::Y), Some(-2.5));
        assert_eq!(ok("G1 X 10\tY -2.5"), l);
        assert_eq!(ok("  G 1   X10 Y-2.5  "), l);
    }

    #[test]
    fn non_ascii_text_is_ignored_in_comments_and_refused_outside_them() {
        assert_eq!(x("G0 X1 (Fräsen, Größe 3)"), 1.0);
        assert_eq!(x("G0 X2 ; Kühlung"), 2.0);
        assert_eq!(fails("G0 Xä1").0, ParseErrorKind::BadNumber);
        assert_eq!(fails("G0 ä X1"), (ParseErrorKind::Unexpected, 4));
    }

    #[test]
    fn blanks_inside_a_number_are_ignored_as_in_rs274ngc() {
        assert_eq!(x("X1 6.5"), 16.5);
        assert_eq!(x("X1 0"), 10.0);
        assert_eq!(x("X- 1"), -1.0);
        assert_eq!(x("X 1 . 5"), 1.5);
        assert_eq!(x("X1.2 5"), 1.25);
        assert_eq!(x("X - 0 . 0 0 1"), -0.001);
        let l = ok("G 0 1 X1 6.5 Y 2");
        assert_eq!((l.motion, l.word(Word::X), l.word(Word::Y)), (Some(Motion::Linear), Some(16.5), Some(2.0)));
        // A blank still ends a number before a letter: `X1 E5` is two words.
        let l = ok("G1 X1 E5");
        assert_eq!((l.word(Word::X), l.word(Word::E)), (Some(1.0), Some(5.0)));
        assert_eq!(ok("T1 2").tool(), Some(12));
        assert_eq!(fails("X1 .2 .3"), (ParseErrorKind::Unexpected, 7));
    }

    #[test]
    fn comments_are_ignored() {
        let l = ok("G1 (move) X1 ; to the end (not a comment");
        assert_eq!(l.motion, Some(Motion::Linear));
        assert_eq!(l.word(Word::X), Some(1.0));
        assert_eq!(ok("G1(no blanks)X2").word(Word::X), Some(2.0));
        assert_eq!(ok("(a (b) G0"), ok("G0"), "no nesting: the first ) closes");
        assert!(ok("(only a comment)").is_empty());
        assert!(ok("; only a comment").is_empty());
        assert!(ok("").is_empty());
        assert!(ok("   \t ").is_empty());
    }

    #[test]
    fn an_unclosed_comment_is_an_error_at_its_paren() {
        assert_eq!(fails("G1 X1 (oops"), (ParseErrorKind::UnclosedComment, 7));
        assert_eq!(fails("("), (ParseErrorKind::UnclosedComment, 1));
    }

    #[test]
    fn stray_characters_are_unexpected() {
        assert_eq!(fails("G1 )"), (ParseErrorKind::Unexpected, 4));
        assert_eq!(fails("&"), (ParseErrorKind::Unexpected, 1));
        assert_eq!(fails("G1 X1*12"), (ParseErrorKind::Unexpected, 6));
        assert_eq!(fails("$H"), (ParseErrorKind::Unexpected, 1));
    }

    #[test]
    fn a_line_starting_with_percent_is_a_program_marker_and_the_rest_is_not_read() {
        assert!(ok("%").is_empty());
        assert!(ok(" % (start)").is_empty());
        // A Fusion 360 post for the MPCNC writes text after it.
        assert!(ok("% vfd enable").is_empty());
        assert!(ok("% G1 X5").is_empty());
        assert!(ok("%%").is_empty());
        assert!(ok("%(unclosed").is_empty());
        // Anywhere else it is still a stray character.
        assert_eq!(fails("G1 %"), (ParseErrorKind::Unexpected, 4));
        assert_eq!(fails("N10 %"), (ParseErrorKind::Unexpected, 5));
    }

    #[test]
    fn word_bits_letters_and_indexes_agree() {
        for (i, &w) in Word::ALL.iter().enumerate() {
            assert_eq!(Word::from_index(i as u8), Some(w));
            assert_eq!(Word::from_letter(w.letter()), Some(w));
            assert_eq!(Word::mask(&[w]), 1 << i);
            let mut words = Words::new();
            words.insert(w, 1.0);
            assert_eq!(words.first_outside(0), Some(w));
            assert_eq!(words.first_outside(Word::mask(&[w])), None);
        }
        assert_eq!(Word::from_index(Word::COUNT as u8), None);
    }

    #[test]
    fn polar_words_at_and_caret_are_read_as_numbers() {
        let l = ok("G1 @.5 ^90");
        assert_eq!((l.word(Word::At), l.word(Word::Caret)), (Some(0.5), Some(90.0)));
        assert!(l.words.has_position() && l.words.has_polar() && !l.words.has_xyz());
        let l = ok("G81 R.1 Z-.1 ^60 L6");
        assert_eq!(l.word(Word::Caret), Some(60.0));
        assert!(!l.words.has_polar() || l.word(Word::At).is_none());
        assert_eq!(fails("G1 @1 @2"), (ParseErrorKind::RepeatedWord, 7));
        assert_eq!(fails("G1 ^"), (ParseErrorKind::BadNumber, 4));
        assert_eq!(fails("G1 @#1"), (ParseErrorKind::Parameter, 4));
    }

    #[test]
    fn outputs_m62_to_m65_are_refused_by_name_and_m31_is_a_code() {
        for m in ["M62 P1", "M63 P1", "M64 P0", "M65 P0"] {
            assert_eq!(fails(m), (ParseErrorKind::NoOutputs, 1), "{m}");
        }
        assert_eq!(ok("M31").other_m, Some(31));
        assert_eq!(fails("M66"), (ParseErrorKind::UnsupportedCode, 1));
    }

    #[test]
    fn a_leading_line_number_is_skipped() {
        assert_eq!(ok("N10 G1 X1"), ok("G1 X1"));
        assert_eq!(ok("n123456789012 G0"), ok("G0"));
        assert_eq!(ok("N-1 M110"), ok("M110"));
        assert_eq!(ok("M110 N100").word(Word::N), Some(100.0));
        assert_eq!(fails("N G1"), (ParseErrorKind::BadNumber, 1));
        // A fraction is accepted, as LinuxCNC does.
        assert_eq!(ok("N4567.789 S1200"), ok("S1200"));
        assert_eq!(ok("N1. G1"), ok("G1"));
        assert_eq!(fails("N.5 G1"), (ParseErrorKind::BadNumber, 1));
        assert_eq!(fails("N1.5.2 G1"), (ParseErrorKind::BadNumber, 1));
        assert_eq!(fails("N1e5 G1"), (ParseErrorKind::BadNumber, 1));
    }

    #[test]
    fn numbers_with_signs_points_and_leading_zeros() {
        assert_eq!(x("X-0.5"), -0.5);
        assert_eq!(x("X+1"), 1.0);
        assert_eq!(x("X.5"), 0.5);
        assert_eq!(x("X5."), 5.0);
        assert_eq!(x("X007"), 7.0);
        assert_eq!(x("X-.25"), -0.25);
        assert_eq!(x("X0"), 0.0);
        assert_eq!(x("X-0").to_bits(), 0.0f32.to_bits(), "no negative zero");
        assert_eq!(x("X000000000000.5"), 0.5, "leading zeros are not significant");
        assert_eq!(x("X1.50000000000"), 1.5, "trailing zeros are not significant");
        assert_eq!(x("X0.000000001"), 1e-9);
    }

    #[test]
    fn decimals_parse_to_the_nearest_f32() {
        assert_eq!(x("X0.1"), 0.1f32);
        assert_eq!(x("X-0.1"), -0.1f32);
        assert_eq!(x("X0.3"), 0.3f32);
        assert_eq!(x("X123.456"), 123.456f32);
        assert_eq!(x("X2.675"), 2.675f32);
        assert_eq!(x("X999999.9"), 999999.9f32);
        assert_eq!(x("X0.001"), 0.001f32);
        assert_eq!(x("X45.0005"), 45.0005f32);
        // Exhaustive over three decimals up to 100 mm.
        for i in 0..100_000u32 {
            let s = format!("X{}.{:03}", i / 1000, i % 1000);
            let want: f32 = s[1..].parse().unwrap();
            assert_eq!(x(&s), want, "{s}");
        }
    }

    #[test]
    fn malformed_numbers_are_bad_numbers_at_the_word() {
        for s in ["X", "X-", "X.", "X+.", "X-.", "X+", "X1.2.3", "X1-2", "X1+", "X--1", "X+-1"] {
            assert_eq!(fails(s), (ParseErrorKind::BadNumber, 1), "{s}");
        }
        assert_eq!(fails("G1 Y2 X"), (ParseErrorKind::BadNumber, 7));
        assert_eq!(fails("G1 Xa"), (ParseErrorKind::BadNumber, 4));
        assert_eq!(fails("G"), (ParseErrorKind::BadNumber, 1));
        assert_eq!(fails("M"), (ParseErrorKind::BadNumber, 1));
        assert_eq!(fails("G1 X10 F"), (ParseErrorKind::BadNumber, 8));
    }

    #[test]
    fn g28_may_name_axes_without_numbers_and_no_other_line_may() {
        let l = ok("G28 X Z");
        assert_eq!(l.non_modal, Some(NonModal::Home));
        assert_eq!((l.word(Word::X), l.word(Word::Y), l.word(Word::Z)), (Some(0.0), None, Some(0.0)));
        assert_eq!(ok("g28y"), ok("G28 Y0"));
        assert_eq!(ok("Y G28 (home Y)").word(Word::Y), Some(0.0));
        assert_eq!(ok("G28 X;all").word(Word::X), Some(0.0));
        assert_eq!(fails("G28 X X"), (ParseErrorKind::RepeatedWord, 7));
        assert_eq!(fails("G0 X"), (ParseErrorKind::BadNumber, 4));
        assert_eq!(fails("X Y1 G1"), (ParseErrorKind::BadNumber, 1));
        assert_eq!(fails("G28 X-"), (ParseErrorKind::BadNumber, 5));
        assert_eq!(fails("G28 X."), (ParseErrorKind::BadNumber, 5));
        assert_eq!(fails("G28 F"), (ParseErrorKind::BadNumber, 5));
    }

    #[test]
    fn an_exponent_is_rejected_but_an_e_word_after_a_blank_is_fine() {
        assert_eq!(fails("X1e99"), (ParseErrorKind::Exponent, 1));
        assert_eq!(fails("G1 X1E5"), (ParseErrorKind::Exponent, 4));
        assert_eq!(fails("X1.5e-3"), (ParseErrorKind::Exponent, 1));
        let l = ok("M92 X100 E3200");
        assert_eq!(l.word(Word::E), Some(3200.0));
    }

    #[test]
    fn numbers_too_big_are_out_of_range_and_long_ones_are_rounded() {
        assert_eq!(fails("X1000000"), (ParseErrorKind::NumberOutOfRange, 1));
        assert_eq!(fails("X-1000000.0"), (ParseErrorKind::NumberOutOfRange, 1));
        assert_eq!(fails("G1 F99999999999999999999999"), (ParseErrorKind::NumberOutOfRange, 4));
        // Any number of digits: the nearest f32 of the number as written.
        for t in [
            "24.985715729",
            "1.23456789012",
            "1.234567891",
            "-0.33333333333333333333",
            "7.99999999999",
            "0.0000000001234567891",
            "123456.78901234",
        ] {
            let v = x(&format!("X{t}"));
            let nearest: f32 = t.parse().unwrap();
            assert!((v - nearest).abs() <= nearest.abs() * 2.4e-7, "{t}: {v} vs {nearest}");
        }
        assert_eq!(x("X1.9999999999"), 2.0);
        assert_eq!(x("X1.00000000001"), 1.0);
        assert_eq!(x("X999999.99999"), 1_000_000.0);
        assert_eq!(ok("G1.00000000001").motion, Some(Motion::Linear));
        assert_eq!(ok("T2.0000000000").tool(), Some(2));
        assert_eq!(x("X999999.999"), 1_000_000.0, "9 digits round to the nearest f32");
        // Beyond 7 digits the mantissa itself rounds: within one ulp.
        let v = x("X-123.456789");
        let nearest: f32 = "-123.456789".parse().unwrap();
        assert!((v - nearest).abs() <= 8e-6, "{v} vs {nearest}");
        assert_eq!(fails("G1234567"), (ParseErrorKind::NumberOutOfRange, 1));
    }

    #[test]
    fn tiny_numbers_stay_finite() {
        let v = x("X0.000000000000000000000000000000000000000000000000001");
        assert!(v.is_finite() && v.abs() < 1e-30);
    }

    #[test]
    fn t_must_be_a_whole_number_up_to_255() {
        assert_eq!(ok("T0").tool(), Some(0));
        assert_eq!(ok("T12").tool(), Some(12));
        assert_eq!(ok("T255").tool(), Some(255));
        assert_eq!(ok("T5.0").tool(), Some(5));
        assert_eq!(ok("T5 M6").tool(), Some(5));
        assert_eq!(fails("T1.5"), (ParseErrorKind::BadToolNumber, 1));
        assert_eq!(fails("M6 T-1"), (ParseErrorKind::BadToolNumber, 4));
        assert_eq!(fails("T256"), (ParseErrorKind::BadToolNumber, 1));
    }

    #[test]
    fn m23_and_m28_take_the_rest_of_the_line_as_a_file_name() {
        let src = b"M23 Part-1 X5.GCO ; select";
        let l = parse(src).unwrap();
        assert_eq!(l.other_m, Some(23));
        assert_eq!(l.text(src), Some(&b"Part-1 X5.GCO"[..]));
        assert!(l.words.is_empty());
        let src = b"m28\tjob.nc  ";
        let l = parse(src).unwrap();
        assert_eq!(l.other_m, Some(28));
        assert_eq!(l.text(src), Some(&b"job.nc"[..]));
        assert_eq!(ok("M30").text_arg, None);
        assert_eq!(fails("M23"), (ParseErrorKind::MissingFileName, 1));
        assert_eq!(fails("G4 P1 M28   ; nothing"), (ParseErrorKind::MissingFileName, 7));
    }

    #[test]
    fn words_can_be_taken_out_one_by_one() {
        let mut w = ok("G1 X1 Y2").words;
        assert_eq!(w.first(), Some(Word::X));
        assert_eq!(w.remove(Word::X), Some(1.0));
        assert_eq!(w.remove(Word::X), None);
        assert_eq!(w.first(), Some(Word::Y));
        assert_eq!(w.remove(Word::Y), Some(2.0));
        assert!(w.is_empty());
        assert!(w.insert(Word::Z, 3.0));
        assert!(!w.insert(Word::Z, 4.0));
        assert_eq!(w.get(Word::Z), Some(3.0));
    }

    #[test]
    fn a_full_length_line_of_many_words_parses() {
        let mut s = String::from("G1M3");
        for w in Word::ALL {
            if w == Word::T {
                s.push_str("T12");
            } else if w == Word::E {
                // A blank before E, or `-1.5E` would read as an exponent.
                s.push_str(" E-1.5");
            } else {
                s.push(w.letter() as char);
                s.push_str("-1.5");
            }
        }
        s.push_str("G54");
        while s.len() < crate::protocol::MAX_LINE_LEN {
            s.push(' ');
        }
        assert_eq!(s.len(), crate::protocol::MAX_LINE_LEN);
        let l = ok(&s);
        assert_eq!(l.words.iter().count(), Word::COUNT);
        assert_eq!(l.word(Word::Z), Some(-1.5));
        assert_eq!(l.wcs, Some(0));
    }

    #[test]
    fn an_over_long_line_is_rejected() {
        let s = vec![b' '; MAX_PARSE_LEN + 1];
        assert_eq!(parse(&s).unwrap_err().kind, ParseErrorKind::LineTooLong);
        let s = vec![b' '; MAX_PARSE_LEN];
        assert!(parse(&s).unwrap().is_empty());
    }

    #[test]
    fn every_error_kind_has_a_message_and_prints_with_its_column() {
        let kinds = [
            ParseErrorKind::BadNumber,
            ParseErrorKind::Exponent,
            ParseErrorKind::NumberOutOfRange,
            ParseErrorKind::Unexpected,
            ParseErrorKind::UnsupportedCode,
            ParseErrorKind::RepeatedWord,
            ParseErrorKind::ModalGroupConflict,
            ParseErrorKind::UnclosedComment,
            ParseErrorKind::BadToolNumber,
            ParseErrorKind::MissingFileName,
            ParseErrorKind::LineTooLong,
            ParseErrorKind::Parameter,
            ParseErrorKind::OWord,
            ParseErrorKind::NoSuchAxis,
            ParseErrorKind::UnsupportedCycle,
            ParseErrorKind::NoOutputs,
        ];
        for k in kinds {
            assert!(!k.message().is_empty());
        }
        let e = parse(b"G1 X1 X2").unwrap_err();
        let mut out = String::new();
        ufmt::uwrite!(out, "Error:{}", e).unwrap();
        assert_eq!(out, "Error:word repeated at col 7");
    }

    #[test]
    fn every_error_kind_comes_from_some_line_with_the_column_of_its_cause() {
        let long = " ".repeat(MAX_PARSE_LEN + 1);
        let cases: [(&str, ParseErrorKind, u8); 16] = [
            ("G1 X1..2", ParseErrorKind::BadNumber, 4),
            ("G1 Y1e5", ParseErrorKind::Exponent, 4),
            ("G1 Z-1000000", ParseErrorKind::NumberOutOfRange, 4),
            ("G1 U3", ParseErrorKind::NoSuchAxis, 4),
            ("G1 X1 &", ParseErrorKind::Unexpected, 7),
            ("G1 M10", ParseErrorKind::UnsupportedCode, 4),
            ("G1 F1 F2", ParseErrorKind::RepeatedWord, 7),
            ("G17 G18", ParseErrorKind::ModalGroupConflict, 5),
            ("G1 (x", ParseErrorKind::UnclosedComment, 4),
            ("T2.5", ParseErrorKind::BadToolNumber, 1),
            ("M28 ;", ParseErrorKind::MissingFileName, 1),
            (long.as_str(), ParseErrorKind::LineTooLong, 255),
            ("G0 X#1", ParseErrorKind::Parameter, 4),
            ("o100 sub", ParseErrorKind::OWord, 1),
            ("G0 G84", ParseErrorKind::UnsupportedCycle, 4),
            ("G4 P1 M64 P2", ParseErrorKind::NoOutputs, 7),
        ];
        let mut seen = [false; 16];
        for (text, kind, col) in cases {
            assert_eq!(fails(text), (kind, col), "{text:?}");
            // Exhaustive: a new kind must be added to the table above.
            let i = match kind {
                ParseErrorKind::BadNumber => 0,
                ParseErrorKind::Exponent => 1,
                ParseErrorKind::NumberOutOfRange => 2,
                ParseErrorKind::NoSuchAxis => 3,
                ParseErrorKind::Unexpected => 4,
                ParseErrorKind::UnsupportedCode => 5,
                ParseErrorKind::RepeatedWord => 6,
                ParseErrorKind::ModalGroupConflict => 7,
                ParseErrorKind::UnclosedComment => 8,
                ParseErrorKind::BadToolNumber => 9,
                ParseErrorKind::MissingFileName => 10,
                ParseErrorKind::LineTooLong => 11,
                ParseErrorKind::Parameter => 12,
                ParseErrorKind::OWord => 13,
                ParseErrorKind::UnsupportedCycle => 14,
                ParseErrorKind::NoOutputs => 15,
            };
            seen[i] = true;
        }
        assert!(seen.iter().all(|&s| s), "{seen:?}");
    }

    use crate::test_util::XorShift;

    #[test]
    fn random_g_code_like_text_never_panics_and_values_stay_in_range() {
        let alphabet = b"GMXYZFNTSPE0123456789.-+ ();%eabc*\t";
        let mut rng = XorShift(0xdead_beef);
        for _ in 0..50_000 {
            let len = (rng.next() % 40) as usize;
            let s: Vec<u8> = (0..len).map(|_| alphabet[rng.next() as usize % alphabet.len()]).collect();
            match parse(&s) {
                Ok(l) => {
                    for (_, v) in l.words.iter() {
                        assert!(v.is_finite() && v.abs() <= 1e6, "{:?}", String::from_utf8_lossy(&s));
                    }
                }
                Err(e) => assert!(e.col >= 1 && e.col as usize <= s.len().max(1)),
            }
        }
    }
}
