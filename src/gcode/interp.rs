//! G-code interpreter (docs/SPEC.md §5): modal state and the meaning of each code,
//! as a pure function of (modal state, parsed line, a read-only [`Ctx`]).
//!
//! ```text
//!  gcode::parse ─► Line ─► Interp::next ─► Command ─► machine::Machine (dispatch)
//!                                ▲                         │
//!                                └──── called again ◄──────┘  until None
//! ```
//!
//! Sits between [`super::parse`] and the controller (`machine`), and names
//! nothing above it: no `Machine`, no `Io`, no tool-changer or tool-setter
//! runner, no UI. It owns the modal state (units, distance mode, plane, work
//! offsets, tool length offset, feed) and the commanded position in machine
//! millimetres, and turns each parsed [`Line`] into [`Command`]s: a move
//! with its feed, home a mask, dwell, spindle, coolant, select or change a
//! tool, measure, probe, carousel, settings, reports.
//!
//! Design: a step API. The controller calls [`Interp::begin_line`], then
//! [`Interp::next`] until it returns `None`, carrying out each command
//! before asking for the next (calling again means the last one was done).
//! Lines that need several actions run in RS274/NGC order
//! (`S1000 M3 T2 M6` is a tool change, then the spindle); an arc's chords
//! and a canned cycle's moves are worked out one per call, their progress
//! kept in the interpreter (`LineRun`, ~110 B static), so no list of
//! commands is built and the stack stays as small as before. A move's
//! target stays here too ([`Interp::target`]): the `Command` is a few bytes.
//! A streamed `G1 X.. Y..` is one call: its first step validates the line,
//! commits it and returns its move.
//!
//! Everything it keeps is in the internal frame (Z counts down from the top
//! switch); G-code words come in, and reports go out, in the user's frame
//! (+Z up) through [`crate::frame`]: [`word_mm`] for every axis word,
//! [`Interp::work_user`] and `frame::user_from_internal` for every report.
//! Targets are absolute mm; [`Interp::steps_of`] rounds them to absolute
//! integer steps, so rounding never accumulates.
//!
//! A line is validated completely before anything on it runs: a bad word,
//! a missing feed or a target outside travel returns an [`Error`] from the
//! first [`Interp::next`] and leaves the machine exactly as it was.

use super::comp;
use super::cycles::{self, Retract};
use super::{Coolant, Distance, Line, Motion, NonModal, Plane, Spindle, Stopping, ToolLength, Units, Word};
use crate::flash::FStr;

#[path = "comp_line.rs"]
mod comp_line;
use crate::config::{Settings, N_WCS};
use crate::frame;
use crate::math::round_i32;
use crate::planner::arc::{self, ArcError};
use crate::N_AXES;
use comp_line::CompOutcome;

/// Millimetres per inch.
const MM_PER_INCH: f32 = 25.4;
/// `v` in mm: × 25.4 under G20. The multiply is a call only made under
/// G20: LLVM-AVR turned `if inches { v * 25.4 } else { v }` into a select
/// that multiplied every axis word (~145 cycles each) in millimetres too.
#[inline]
fn to_mm(inches: bool, v: f32) -> f32 {
    if inches {
        inch_to_mm(v)
    } else {
        v
    }
}

/// An axis word's value (`axis` 0 X, 1 Y, 2 Z) in internal mm: inches
/// converted, Z mirrored from the user's +Z up into the internal frame
/// (see [`crate::frame`]). Offsets, G92, G53 and increments all follow.
#[inline]
fn word_mm(inches: bool, axis: usize, v: f32) -> f32 {
    frame::axis_internal_from_user(axis, to_mm(inches, v))
}

/// `v` × 25.4, as a call (see [`to_mm`]).
#[inline(never)]
fn inch_to_mm(v: f32) -> f32 {
    v * MM_PER_INCH
}

/// Interpreter errors, printed as `Error:<message>`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Error {
    /// The line did not parse.
    Parse(super::ParseError),
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
        use super::ParseErrorKind as K;
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

/// Modal state and commanded position.
pub struct Interp {
    /// G20 active.
    pub inches: bool,
    /// G91 active.
    pub incremental: bool,
    /// Arc plane.
    pub plane: Plane,
    /// G90.1 active: I/J/K are absolute centre coordinates (G91.1, the
    /// default: offsets from the start).
    pub arc_absolute: bool,
    /// Modal motion (G0/G1/G2/G3/G80, a canned cycle).
    pub motion: Motion,
    /// The motion mode in force when the canned cycle now modal began: what
    /// G80 goes back to with `$154=1` (Fanuc, Haas, Mach3 posts).
    motion_before_cycle: Motion,
    /// Canned cycle return level (G98/G99, NGC group 10).
    pub retract: Retract,
    /// The canned cycle words kept from line to line (R, Z, Q, P, the
    /// initial level); meaningful while `motion` is a cycle.
    pub cycle: cycles::Sticky,
    /// Programmed feed, mm/min (0 = none yet).
    pub feed_mm_per_min: f32,
    /// Spindle speed, rpm (S), and whether it is on.
    pub spindle_rpm: f32,
    pub spindle_on: bool,
    /// Coolant as its M code: 7 (mist) or 8 (flood) on, 9 off (one output).
    pub coolant_m: u8,
    /// Active work coordinate system, 0 = G54.
    pub wcs: u8,
    /// Work offsets G54..G59, machine mm (internal frame: the user's
    /// `G10 L2 P1 Z-5` is stored as Z 5; see [`crate::frame`]).
    pub wcs_mm: [[f32; 3]; N_WCS],
    /// G92 offset, mm (internal frame).
    pub g92_mm: [f32; 3],
    /// Tool length offset applied to Z, mm, internal frame: −length (the
    /// user sees +length, LinuxCNC's G43; the tool table and the tool in
    /// the spindle live in `atc`).
    pub tlo_mm: f32,
    /// Commanded position, internal machine mm (E in carousel units).
    pub pos_mm: [f32; N_AXES],
    /// Per axis, the last mm → steps conversion: (bits of the mm value,
    /// steps). Valid while `conv_fresh`. See [`Interp::steps_of`].
    steps_cache: [(u32, i32); N_AXES],
    /// The travel of X, Y, Z in steps, rounded. Valid while `conv_fresh`.
    travel_steps: [i32; 3],
    /// The two caches above match the settings; cleared by
    /// [`Interp::settings_changed`].
    conv_fresh: bool,
    /// The line in progress: where [`Interp::next`] is, and an arc's or a
    /// canned cycle's state between its moves (~110 B, static: on the stack
    /// it would sit under every wait of the line).
    run: LineRun,
    /// Cutter radius compensation (G41/G42): the side, the radius and the
    /// move held back for look-ahead (see [`comp::State`] for its RAM).
    pub comp: comp::State,
}

impl Interp {
    /// Power-up modal state: G21 G90 G17 G54 G49 G0 (grbl's G0: a bare
    /// axis word before any motion code is a rapid; LinuxCNC starts in G80
    /// and refuses it) G98, feed unset.
    pub const fn new() -> Interp {
        Interp {
            inches: false,
            incremental: false,
            plane: Plane::Xy,
            arc_absolute: false,
            motion: Motion::Rapid,
            motion_before_cycle: Motion::Rapid,
            retract: Retract::Initial,
            cycle: cycles::Sticky::NONE,
            feed_mm_per_min: 0.0,
            spindle_rpm: 0.0,
            spindle_on: false,
            coolant_m: 9,
            wcs: 0,
            wcs_mm: [[0.0; 3]; N_WCS],
            g92_mm: [0.0; 3],
            tlo_mm: 0.0,
            pos_mm: [0.0; N_AXES],
            steps_cache: [(0, 0); N_AXES],
            travel_steps: [0; 3],
            conv_fresh: false,
            run: LineRun::new(),
            comp: comp::State::OFF,
        }
    }

    /// Absolute mm → absolute steps, rounded per axis (no accumulated
    /// error). An axis whose mm value is that of its last conversion reuses
    /// the result (a float multiply and a rounding, ~330 cycles on the AVR;
    /// a streamed XY move leaves Z and E where they were).
    pub fn steps_of(&mut self, s: &Settings, mm: &[f32; N_AXES]) -> [i32; N_AXES] {
        if !self.conv_fresh {
            self.refresh_conv(s);
        }
        steps_cached(&mut self.steps_cache, s, mm)
    }

    /// Soft limits: the target, rounded to steps as it will be queued, must
    /// lie within 0..=travel (rounded to steps) on X, Y and Z. Integer
    /// compares on the steps [`Interp::steps_of`] caches for the move itself.
    pub fn check_soft_limits(&mut self, s: &Settings, t: &[f32; N_AXES]) -> Result<(), Error> {
        if !self.conv_fresh {
            self.refresh_conv(s);
        }
        soft_limits(&mut self.steps_cache, &self.travel_steps, s, t)
    }

    /// The settings changed: the step conversions are made afresh.
    pub fn settings_changed(&mut self) {
        self.conv_fresh = false;
    }

    /// Empty the steps cache (an all-ones pattern is a NaN, never a
    /// position) and convert the travel.
    #[inline(never)]
    fn refresh_conv(&mut self, s: &Settings) {
        for c in self.steps_cache.iter_mut() {
            c.0 = u32::MAX;
        }
        for a in 0..3 {
            self.travel_steps[a] = to_steps(s.travel_mm[a], s.steps_per_mm[a]);
        }
        self.conv_fresh = true;
    }

    /// Take the persistent parts (work offsets) from the settings.
    pub fn load_settings(&mut self, s: &Settings) {
        self.wcs_mm = s.wcs_mm;
    }

    /// Put the persistent parts back into the settings (before M500).
    pub fn store_settings(&self, s: &mut Settings) {
        s.wcs_mm = self.wcs_mm;
    }

    /// Reset the commanded position to where the steppers are.
    /// A contour under compensation cannot go on from there: G40.
    pub fn sync_position(&mut self, s: &Settings, steps: [i32; N_AXES]) {
        for a in 0..N_AXES {
            self.pos_mm[a] = steps[a] as f32 / s.steps_per_mm[a];
        }
        self.comp.set(None, 0.0);
    }

    /// Sum of the offsets between machine and work coordinates, per axis.
    fn offset(&self, axis: usize) -> f32 {
        let tlo = if axis == 2 { self.tlo_mm } else { 0.0 };
        self.wcs_mm[self.wcs as usize][axis] + self.g92_mm[axis] + tlo
    }

    /// Machine mm → work mm (X, Y, Z; E unchanged), both internal.
    pub fn machine_to_work(&self, m: [f32; N_AXES]) -> [f32; N_AXES] {
        let mut w = m;
        for a in 0..3 {
            w[a] = m[a] - self.offset(a);
        }
        w
    }

    /// Internal machine mm → the user's work coordinates (+Z up), for
    /// reports (M114, `?`, `[PRB:…]`, the OLED).
    pub fn work_user(&self, m: [f32; N_AXES]) -> [f32; N_AXES] {
        frame::user_from_internal(self.machine_to_work(m))
    }

    /// `$J=<words>` (grbl 1.1 jogging): the target (internal machine mm)
    /// and the feed (mm/min) of a jog line. As grbl: X, Y, Z and a required
    /// F, with G20/G21, G90/G91 and G53 for this line alone (the modal
    /// state does not change); any other word or code is refused. The
    /// caller checks the soft limits.
    pub fn jog_target(&self, l: &Line) -> Result<([f32; N_AXES], f32), Error> {
        let codes = l.motion.is_some()
            || l.plane.is_some()
            || l.feed_mode.is_some()
            || l.wcs.is_some()
            || l.tool_length.is_some()
            || l.retract.is_some()
            || !matches!(l.non_modal, None | Some(NonModal::MachineCoords))
            || l.stopping.is_some()
            || l.tool_change
            || l.spindle.is_some()
            || l.coolant.is_some()
            || l.path_mode.is_some()
            || l.arc_absolute.is_some()
            || l.cutter_comp.is_some()
            || l.other_m.is_some();
        let words = Word::ALL.iter().any(|&w| !matches!(w, Word::X | Word::Y | Word::Z | Word::F | Word::N) && l.words.contains(w));
        if codes || words {
            return Err(Error::Coded(grbl::BAD_JOG, F!("$J= takes X Y Z F and G20 G21 G90 G91 G53 only")));
        }
        let inches = l.units.map_or(self.inches, |u| u == Units::Inch);
        let incremental = l.distance.map_or(self.incremental, |d| d == Distance::Incremental);
        let machine = l.non_modal == Some(NonModal::MachineCoords);
        let feed = match l.word(Word::F) {
            Some(f) if f > 0.0 => to_mm(inches, f),
            _ => return Err(Error::BadFeed),
        };
        let mut t = self.pos_mm;
        for (a, w) in [Word::X, Word::Y, Word::Z].into_iter().enumerate() {
            if let Some(v) = l.word(w) {
                let v = word_mm(inches, a, v);
                t[a] = if incremental {
                    self.pos_mm[a] + v
                } else if machine {
                    v
                } else {
                    v + self.offset(a)
                };
            }
        }
        Ok((t, feed))
    }

    /// Programmed feed (the planner applies the override), and spindle
    /// rpm (0 when off).
    pub fn feed_and_speed(&self) -> (f32, f32) {
        let rpm = if self.spindle_on { self.spindle_rpm } else { 0.0 };
        (self.feed_mm_per_min, rpm)
    }
}

impl Default for Interp {
    fn default() -> Self {
        Interp::new()
    }
}

const AXIS_WORDS: [Word; 3] = [Word::X, Word::Y, Word::Z];

/// True when a line names a point: any of X, Y, Z, or the polar `@`, `^`.
fn has_axis_words(l: &Line) -> bool {
    l.words.has_position()
}

/// True when the line's X, Y, Z words are the arguments of its M code
/// (M92, M201, M203: per-axis settings), not a move.
fn axis_words_are_settings(l: &Line) -> bool {
    matches!(l.other_m, Some(92 | 201 | 203))
}

/// What a line asks of the controller: one action, as data. [`Interp::next`]
/// hands them out one at a time, in RS274/NGC order; `Machine` performs
/// them (`machine::Machine::dispatch`). Positions are internal machine mm
/// (E in carousel units), feeds mm/min with the override applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Queue a straight move (G0/G1, an arc chord or its end, G53) to
    /// [`Interp::target`] (the target stays in the interpreter: copying it
    /// through the command cost ~300 cycles a streamed line).
    Move { feed_mm_per_min: f32, rapid: bool },
    /// A canned cycle's move to [`Interp::target`]: send the keepalive and
    /// wait for two planner slots first (a cycle of many holes is one long line).
    CycleMove { feed_mm_per_min: f32, rapid: bool },
    /// G38.2 (`must_trip`) / G38.3: move toward [`Interp::target`] until the
    /// probe trips.
    Probe { feed_mm_per_min: f32, must_trip: bool },
    /// G4, a cycle's P: let the queue drain, then wait `ms` milliseconds.
    Dwell { ms: f32 },
    /// G28: home the axes of `mask` (bit 0 X, 1 Y, 2 Z).
    Home { mask: u8 },
    /// G37 in `mode`; X/Y (mm) move the setter first (calibration only).
    Measure { mode: crate::toolsetter::Mode, x_mm: Option<f32>, y_mm: Option<f32> },
    /// M6 / T with `$151=1`: change to tool `to` (`None`: the last T word).
    SelectTool { to: Option<u16> },
    /// A T word alone (NGC): the tool the next M6 changes to.
    PreselectTool(u8),
    /// M61 Q<tool>: the operator confirms the tool in the spindle (0: none).
    ConfirmTool { tool: u8 },
    /// M61 P<pocket> S<0|1>: the pocket holds its tool (`full`) or is empty.
    SetPocket { pocket: u8, full: bool },
    /// G10 L1: tool table entry `tool` (mm, converted from inches).
    SetTool { tool: u8, length_mm: Option<f32>, radius_mm: Option<f32> },
    /// `G10 L1 P<tool> Q<pocket>`: tool number `tool` is kept in `pocket`
    /// (0: the tool leaves the table).
    AssignTool { tool: u8, pocket: u8 },
    /// G10 L2/L20 changed a work offset: store the settings image.
    StoreOffsets,
    /// G201: turn the carousel to `x` pitches.
    CarouselTurn { x: f32 },
    /// G202: the carousel is at `x` pitches.
    CarouselSetPosition { x: f32 },
    /// G203: report the carousel.
    CarouselReport,
    /// G204 S0/S1: carousel driver off/on.
    CarouselEnable { on: bool },
    /// G205 `[S1] [E1]`: home the carousel (`back`: return to where it was;
    /// `only_if_unhomed`: skip when homed).
    CarouselHome { back: bool, only_if_unhomed: bool },
    /// M3 (`on`, `duty` from S) / M5, or a new S with the spindle on: in
    /// step with the motion.
    Spindle { on: bool, duty: u8 },
    /// M7 / M8 / M9 (`m` is the code), in step with the motion.
    Coolant { m: u8 },
    /// M92 / M201 / M203 (`code`) with the X Y Z E values (NaN: absent).
    AxisSettings { code: u16, values: [f32; N_AXES] },
    /// An M code the controller runs as it is: 17, 18, 84, 400, 500, 501, 502.
    M(u16),
    /// M114, M115, M105, M119, M503.
    Report(Report),
    /// M999: leave the alarm state.
    ClearAlarm,
    /// M220 S<percent>: the feed override, for the queued moves too.
    FeedOverride { pct: u16 },
    /// M112.
    EmergencyStop,
    /// M2 / M30: drain, spindle and coolant off.
    ProgramEnd,
    /// M0, or M1 with optional stop on: drain, then wait for `~`.
    Pause,
}

/// The reports a line can ask for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Report {
    /// M114.
    Position,
    /// M115.
    Firmware,
    /// M105 (no heaters).
    Temperatures,
    /// M119.
    Switches,
    /// M503.
    Settings,
    /// M31: the running SD job's time, as Marlin prints it.
    PrintTime,
}

/// What the interpreter may read of the rest of the machine while it
/// works out a line (built by the controller for each call).
pub struct Ctx<'a> {
    pub settings: &'a Settings,
    /// The tool table and the tool in the spindle (G43 H, interrupted changes).
    pub atc: &'a crate::atc::Atc,
    /// The machine is in alarm.
    pub alarm: bool,
    /// The alarm is the emergency stop (G28 does not clear it).
    pub estop: bool,
    /// A serial line while an SD job runs: status requests only (docs/SPEC.md §9).
    pub status_only: bool,
}

/// Where [`Interp::next`] is within the current line.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Phase {
    /// Validate and work out the whole line.
    Start,
    /// Tool change or tool selection.
    Tool,
    /// S, M3, M5.
    Spindle,
    /// M7, M8, M9.
    Coolant,
    /// G4 (after the spindle and coolant, before the motion: RS274/NGC).
    Dwell,
    /// The line's motion.
    Motion,
    /// An arc's chords, then its end; then `LineRun::then`.
    Chords,
    /// Compensation: the held move (or its chords), then `LineRun::then`.
    CompFlush,
    /// Compensation: an outside corner's arc, then the line's actions.
    CompCorner,
    /// Run the line from its start again (after a held move was sent).
    Restart,
    /// A canned cycle's steps.
    Cycle,
    /// Other M codes.
    OtherM,
    /// M0, M1, M2, M30.
    Stop,
    /// After G10 L1: the tool length offset the line leaves in force.
    Tlo,
    /// Nothing more on this line.
    Done,
}

/// An arc's chords (and its end, X Y Z) or a canned cycle's steps still
/// to hand out.
enum Progress {
    None,
    Arc(arc::Arc, [f32; 3]),
    Cycle(CycleRun),
}

/// The line in progress (see [`Interp::next`]).
pub struct LineRun {
    phase: Phase,
    /// The target of the move handed out last (the line's end point, a
    /// chord's, a cycle step's), internal machine mm.
    target: [f32; N_AXES],
    /// The motion to run, if the line moves.
    motion: Option<Motion>,
    /// `Phase::Tlo`: the tool length offset to put back.
    tlo_mm: f32,
    /// The line has a T word, M6, S, M3/M5 or M7–M9 (set by [`early`]).
    extras: bool,
    progress: Progress,
    /// The phase after `Chords` or `CompFlush`.
    then: Phase,
    /// The feed of the chords or held move being handed out, mm/min with
    /// the override, and whether they are rapids.
    chord_feed: f32,
    chord_rapid: bool,
}

impl LineRun {
    const fn new() -> LineRun {
        LineRun {
            phase: Phase::Done,
            target: [0.0; N_AXES],
            motion: None,
            tlo_mm: 0.0,
            extras: false,
            progress: Progress::None,
            then: Phase::OtherM,
            chord_feed: 0.0,
            chord_rapid: false,
        }
    }
}

impl Interp {
    /// Start a new line: the next [`Interp::next`] validates it.
    pub fn begin_line(&mut self) {
        self.run.phase = Phase::Start;
    }

    /// The target of the last `Move`, `CycleMove` or `Probe`, internal
    /// machine mm (E in carousel units).
    pub fn target(&self) -> &[f32; N_AXES] {
        &self.run.target
    }

    /// [`Interp::target`] in steps (see [`Interp::steps_of`]).
    pub fn target_steps(&mut self, s: &Settings) -> [i32; N_AXES] {
        if !self.conv_fresh {
            self.refresh_conv(s);
        }
        steps_cached(&mut self.steps_cache, s, &self.run.target)
    }

    /// The move to [`Interp::target`] was queued: it is the commanded position.
    pub fn target_reached(&mut self) {
        self.pos_mm = self.run.target;
    }

    /// The line begun last has nothing more to do: [`Interp::next`] would
    /// return `None`.
    #[inline]
    pub fn line_done(&self) -> bool {
        self.run.phase == Phase::Done
    }

    /// The next action of line `l` (begun with [`Interp::begin_line`]), or
    /// `None` when the line is done. The first call validates the whole
    /// line: an error then has changed nothing. Calling again means the
    /// previous command was carried out; after an error the caller stops.
    ///
    /// Chords and canned-cycle steps are worked out one per call, so that a
    /// line of many moves needs no list of them (RAM).
    ///
    /// Small and inlined: the first call goes straight to `Interp::start`
    /// (a streamed G1 is done there), the others to `Interp::resume`.
    #[inline]
    pub fn next(&mut self, cx: &Ctx, l: &Line) -> Result<Option<Command>, Error> {
        if self.run.phase == Phase::Start {
            self.run.phase = Phase::Done;
            // Returned as it is, not unwrapped and wrapped again (that was
            // an 18-byte copy a line).
            let r = self.start(cx, l);
            if !matches!(r, Ok(None)) || self.run.phase == Phase::Done {
                return r;
            }
        }
        self.resume(cx, l)
    }

    /// [`Interp::next`] after the first step: the line's phases in order.
    #[inline(never)]
    fn resume(&mut self, cx: &Ctx, l: &Line) -> Result<Option<Command>, Error> {
        loop {
            match self.run.phase {
                Phase::Start => return Ok(None),
                Phase::Tool => {
                    self.run.phase = Phase::Spindle;
                    // T is a tool number; the commands carry its pocket
                    // (checked against the tool table in `early`).
                    let pocket = l.tool().map(|t| cx.atc.table.pocket_of(t).unwrap_or(u8::MAX));
                    if is_tool_change(cx, l) {
                        return Ok(Some(Command::SelectTool { to: pocket.map(u16::from) }));
                    } else if let Some(p) = pocket {
                        return Ok(Some(Command::PreselectTool(p)));
                    }
                }
                Phase::Spindle => {
                    self.run.phase = Phase::Coolant;
                    if let Some(c) = self.spindle(cx, l) {
                        return Ok(Some(c));
                    }
                }
                Phase::Coolant => {
                    self.run.phase = Phase::Dwell;
                    if let Some(c) = l.coolant {
                        let m = match c {
                            Coolant::Mist => 7,
                            Coolant::Flood => 8,
                            Coolant::Off => 9,
                        };
                        return Ok(Some(Command::Coolant { m }));
                    }
                }
                Phase::Dwell => {
                    self.run.phase = Phase::Motion;
                    if l.non_modal == Some(NonModal::Dwell) {
                        if let Ok(ms) = dwell(cx.settings, l) {
                            return Ok(Some(Command::Dwell { ms }));
                        }
                    }
                }
                Phase::Motion => {
                    // Nothing after the motion on most lines: done at once.
                    self.run.phase = if l.other_m.is_none() && l.stopping.is_none() { Phase::Done } else { Phase::OtherM };
                    if let Some(c) = self.motion() {
                        return Ok(Some(c));
                    }
                }
                Phase::Chords => {
                    let run = &mut self.run;
                    match &mut run.progress {
                        Progress::Arc(plan, end) => match next_chord(plan) {
                            Some(p) => run.target[..3].copy_from_slice(&p),
                            None => {
                                // The programmed end last.
                                run.target[..3].copy_from_slice(end);
                                run.phase = run.then;
                                run.progress = Progress::None;
                            }
                        },
                        _ => run.phase = run.then,
                    }
                    return Ok(Some(Command::Move { feed_mm_per_min: run.chord_feed, rapid: run.chord_rapid }));
                }
                Phase::CompFlush => {
                    if let Some(c) = self.comp_flush_step() {
                        return Ok(Some(c));
                    }
                }
                Phase::CompCorner => {
                    if let Some(c) = self.comp_corner_step(cx) {
                        return Ok(Some(c));
                    }
                }
                Phase::Restart => {
                    self.run.phase = Phase::Done;
                    let r = self.start(cx, l);
                    if !matches!(r, Ok(None)) || self.run.phase == Phase::Done {
                        return r;
                    }
                }
                Phase::Cycle => {
                    if let Some(c) = self.cycle_step() {
                        return Ok(Some(c));
                    }
                    self.run.phase = Phase::OtherM;
                }
                Phase::OtherM => {
                    self.run.phase = Phase::Stop;
                    if let Some(code) = l.other_m {
                        if let Some(c) = self.other_m(l, code)? {
                            return Ok(Some(c));
                        }
                    }
                }
                Phase::Stop => {
                    self.run.phase = Phase::Done;
                    match l.stopping {
                        Some(Stopping::End | Stopping::EndRewind) => return Ok(Some(Command::ProgramEnd)),
                        // M1 pauses only with optional stop on (`$152`, Job menu).
                        Some(Stopping::OptionalPause) if !cx.settings.optional_stop => {}
                        Some(Stopping::Pause | Stopping::OptionalPause) => return Ok(Some(Command::Pause)),
                        None => {}
                    }
                }
                Phase::Tlo => {
                    self.run.phase = Phase::Done;
                    self.tlo_mm = self.run.tlo_mm;
                }
                Phase::Done => return Ok(None),
            }
        }
    }

    /// The first step of a line: the checks that need no modal state, the
    /// modal words, the non-modal codes and the motion's target. A command
    /// that ends the line is returned with `phase` left at `Done`; a line
    /// that goes on is committed ([`Interp::commit_line`]).
    ///
    /// The work is split over small non-inlined steps on purpose: AVR loads
    /// and stores reach only 63 bytes into a stack frame, and in one function
    /// with all of this inlined (a 445-byte frame) every access beyond that
    /// cost 10 extra bytes of code (about 6 KB in all). Measured again with
    /// the 248 KiB budget (the application space), in simavr on the real ELF: inlining
    /// them all cost +4 176 B of flash, +117 B of stack and +716 cycles per
    /// G1 line; the four arc helpers alone +1 760 B for no arc speed-up.
    #[inline(never)]
    fn start(&mut self, cx: &Ctx, l: &Line) -> Result<Option<Command>, Error> {
        if let Some(done) = early(cx, l, &mut self.run.extras) {
            return done;
        }
        // Work on a copy of the modal state; commit only when the line is valid.
        let mut g = ModalCopy::from(self);
        modal_words(cx, l, &mut g)?;
        if !l.words.within(ALWAYS_USED) {
            unused_word(l, &g)?;
        }
        if l.non_modal.is_some() && (self.comp.side.is_some() || comp_line::turns_on(l)) {
            return Err(Error::BadWord(F!(
                "G41/G42: no G4, G10, G28, G37, G38, G53, G92 or carousel code with compensation on (G40 first), nothing moved"
            )));
        }
        if l.non_modal.is_some() {
            if let Some(done) = self.non_modal(cx, &g, l) {
                return done;
            }
        }
        self.motion_line(cx, &g, l)
    }

    /// Commit the modal state and go on with the line's actions: the
    /// motion `motion` to `run.target` (an arc's or a cycle's line sets
    /// `run.progress` too).
    #[inline(never)]
    /// `progress` is only looked at for an arc or a cycle, whose lines set it.
    fn commit_line(&mut self, g: &ModalCopy, motion: Option<Motion>) {
        g.commit(self);
        self.run.motion = motion;
        self.run.phase = Phase::Tool;
    }

    /// S, M3, M5: the spindle command, if any.
    fn spindle(&mut self, cx: &Ctx, l: &Line) -> Option<Command> {
        let s = spindle_speed(l);
        if let Some(s) = s {
            self.spindle_rpm = s;
        }
        match l.spindle {
            Some(Spindle::Cw) => Some(Command::Spindle { on: true, duty: spindle_duty(cx.settings, self.spindle_rpm) }),
            Some(Spindle::Off) => Some(Command::Spindle { on: false, duty: 0 }),
            _ if s.is_some() && self.spindle_on => Some(Command::Spindle { on: true, duty: spindle_duty(cx.settings, self.spindle_rpm) }),
            _ => None,
        }
    }

    /// The line's motion: one move, a probe, or the start of an arc's
    /// chords or a cycle's steps.
    #[inline(always)]
    fn motion(&mut self) -> Option<Command> {
        let mo = self.run.motion?;
        let feed = self.feed_mm_per_min;
        match mo {
            Motion::ArcCw | Motion::ArcCcw if matches!(self.run.progress, Progress::Arc(..)) => {
                self.run.phase = Phase::Chords;
                self.run.then = Phase::OtherM;
                self.run.chord_feed = feed;
                self.run.chord_rapid = false;
                None
            }
            Motion::ProbeToward | Motion::ProbeTowardNoError => {
                Some(Command::Probe { feed_mm_per_min: feed, must_trip: mo == Motion::ProbeToward })
            }
            Motion::Cycle(_) => {
                if matches!(self.run.progress, Progress::Cycle(_)) {
                    self.run.phase = Phase::Cycle;
                }
                None
            }
            _ => Some(Command::Move { feed_mm_per_min: feed, rapid: mo == Motion::Rapid }),
        }
    }

    /// The cycle's next move or dwell, `None` when it is done.
    #[inline(never)]
    fn cycle_step(&mut self) -> Option<Command> {
        let feed = self.feed_mm_per_min;
        let pos = self.pos_mm;
        let Progress::Cycle(run) = &mut self.run.progress else {
            return None;
        };
        let (t, rapid) = match run.cycle.next_step()? {
            cycles::Step::Dwell(s) => return Some(Command::Dwell { ms: s * 1000.0 }),
            cycles::Step::Rapid(t) => (t, true),
            cycles::Step::Feed(t) => (t, false),
        };
        self.run.target = cycle_target(pos, run, t);
        Some(Command::CycleMove { feed_mm_per_min: feed, rapid })
    }
}

/// The checks and commands before the modal state: the SD-job filter, the
/// codes that work in any state, the alarm and interrupted-change locks and
/// the validation of words that need no modal state. `Some` ends the line.
#[inline(never)]
fn early(cx: &Ctx, l: &Line, extras: &mut bool) -> Option<Result<Option<Command>, Error>> {
    // During an SD job the serial line may only ask for status (docs/SPEC.md §9).
    if cx.status_only {
        let status_only = l.motion.is_none()
            && !has_axis_words(l)
            && l.non_modal.is_none()
            && l.spindle.is_none()
            && l.coolant.is_none()
            && !l.tool_change
            && l.stopping.is_none()
            && matches!(l.other_m, Some(31 | 114 | 115 | 119 | 220 | 503));
        if !status_only {
            return Some(Err(Error::JobRunning));
        }
    }
    // Commands that work in any state first.
    if let Some(code) = l.other_m {
        let c = match code {
            115 => Some(Command::Report(Report::Firmware)),
            114 => Some(Command::Report(Report::Position)),
            // Senders (printcore, Pronterface, OctoPrint) poll M105 for
            // temperatures; a mill has no heaters, so it reports none
            // rather than an error every few seconds.
            105 => Some(Command::Report(Report::Temperatures)),
            119 => Some(Command::Report(Report::Switches)),
            503 => Some(Command::Report(Report::Settings)),
            31 => Some(Command::Report(Report::PrintTime)),
            61 => return Some(m61(cx, l).map(Some)),
            999 => Some(Command::ClearAlarm),
            110 => return Some(Ok(None)), // handled by the line checker
            // The RX interrupt's scanner has usually raised it already.
            112 => Some(Command::EmergencyStop),
            _ => None,
        };
        if c.is_some() {
            return Some(Ok(c));
        }
    }
    early_checks(cx, l, extras)
}

/// The locks and the validation of [`early`]; `extras`: the line has more
/// than its motion (T, M6, S, M3/M5, M7–M9), from the lookups made here.
#[inline(always)]
fn early_checks(cx: &Ctx, l: &Line, extras: &mut bool) -> Option<Result<Option<Command>, Error>> {
    let moves = l.motion.is_some()
        || has_axis_words(l)
        || l.words.contains(Word::E)
        || l.non_modal.is_some()
        || l.spindle == Some(Spindle::Cw)
        || matches!(l.coolant, Some(Coolant::Mist | Coolant::Flood))
        || l.tool_change
        || l.words.contains(Word::T)
        || l.other_m.is_some()
        || l.stopping.is_some();
    if l.non_modal == Some(NonModal::AuxReport) {
        return Some(Ok(Some(Command::CarouselReport)));
    }
    let harmless = matches!(l.other_m, Some(500..=502) | Some(17) | Some(18) | Some(84)) || l.spindle == Some(Spindle::Off);
    if cx.alarm && moves {
        let homing_allowed = l.non_modal == Some(NonModal::Home) && !cx.estop;
        if !homing_allowed && !harmless {
            return Some(Err(Error::Alarm));
        }
    }
    // After an interrupted tool change nothing moves until M61 confirms the spindle.
    if cx.atc.interrupted.is_some() && moves && !harmless {
        return Some(Err(Error::Atc(crate::atc::Fault::Interrupted)));
    }

    // ---- Validate everything before changing anything -----------------
    if l.spindle == Some(Spindle::Ccw) {
        return Some(Err(Error::SpindleCcw));
    }
    let tool = l.tool();
    if let Some(t) = tool.filter(|&t| cx.atc.table.pocket_of(t).is_none()) {
        return Some(Err(Error::NoPocket(t)));
    }
    if is_tool_change(cx, l) && (l.motion.is_some() || has_axis_words(l) || l.non_modal.is_some()) {
        return Some(Err(Error::Atc(crate::atc::Fault::WithMotion)));
    }
    if let Some(code) = l.other_m {
        if (20..=29).contains(&code) {
            return Some(Err(Error::NotAvailable(F!("SD card not available in this build"))));
        }
    }
    if let Some(f) = l.word(Word::F) {
        if f < 0.0 {
            return Some(Err(Error::Coded(grbl::NEGATIVE, F!("F must not be negative"))));
        }
        if !(f > 0.0) {
            return Some(Err(Error::BadFeed));
        }
    }
    let s_word = spindle_speed(l);
    if let Some(s) = s_word {
        if s < 0.0 {
            return Some(Err(Error::Coded(grbl::NEGATIVE, F!("S must not be negative"))));
        }
    }
    *extras = l.tool_change
        || l.spindle.is_some()
        || l.coolant.is_some()
        || tool.is_some()
        || s_word.is_some()
        || l.non_modal == Some(NonModal::Dwell);
    None
}

/// The line's S word as a spindle speed: on a G4 line without P, S is the
/// dwell in seconds (grbl, Marlin), otherwise the speed (RS274/NGC:
/// `G4 P.5 G0 X10 S1000 M3` dwells, then starts the spindle at 1000).
#[inline]
fn spindle_speed(l: &Line) -> Option<f32> {
    // The usual line has no S: one mask test.
    let s = l.word(Word::S)?;
    if l.non_modal == Some(NonModal::Dwell) && !l.words.contains(Word::P) {
        return None;
    }
    // M220's S is its percentage, not a speed.
    if l.other_m == Some(220) {
        return None;
    }
    Some(s)
}

/// The words any line may carry: F, S, T, and the words of a point (X, Y,
/// Z, `@`, `^`, E), which the motion checks itself (no motion mode, E only
/// with G0/G1). A streamed line has only these: one mask test.
const ALWAYS_USED: u32 = Word::mask(&[Word::F, Word::S, Word::T, Word::X, Word::Y, Word::Z, Word::At, Word::Caret, Word::E]);

/// LinuxCNC's rule, which grbl shares (error 20/36): a word that no code on
/// the line uses is an error ("R word with no g code that uses it"), not
/// silently dropped (`G61 R0.5`, `G0 X1 I2`). `g` holds the line's modal
/// state: I, J, K, R belong to an arc, R, L, P (G82, G89) and Q (G73, G83)
/// to a canned cycle, when the line moves.
#[inline(never)]
fn unused_word(l: &Line, g: &ModalCopy) -> Result<(), Error> {
    use Word::*;
    // Consts: a mask built at run time would keep its word list in RAM.
    const ARC: u32 = Word::mask(&[I, J, K, R]);
    const CYCLE: u32 = Word::mask(&[R, L]);
    const P_: u32 = Word::mask(&[P]);
    const Q_: u32 = Word::mask(&[Q]);
    const PQ: u32 = Word::mask(&[P, Q]);
    const G10: u32 = Word::mask(&[L, P, R]);
    const G37: u32 = Word::mask(&[B, D, L, R]);
    const H_: u32 = Word::mask(&[H]);
    const N_: u32 = Word::mask(&[N]);
    const D_: u32 = Word::mask(&[D]);
    let mut used = ALWAYS_USED;
    let moves = has_axis_words(l) || l.motion.is_some();
    match g.motion {
        Motion::ArcCw | Motion::ArcCcw if moves => used |= ARC,
        Motion::Cycle(kind) if moves => {
            used |= CYCLE;
            if kind.dwells() {
                used |= P_;
            }
            if kind.pecks() {
                used |= Q_;
            }
        }
        _ => {}
    }
    used |= match l.non_modal {
        Some(NonModal::Dwell) => P_,
        // G10 L1 P<tool> Q<pocket>: the tool numbers.
        Some(NonModal::SetOffsets) if l.word(L) == Some(1.0) => G10 | Q_,
        Some(NonModal::SetOffsets) => G10,
        Some(NonModal::MeasureTool) => G37,
        Some(NonModal::AuxMove | NonModal::AuxSetPosition | NonModal::AuxReport | NonModal::AuxEnable | NonModal::AuxHome) => P_,
        _ => 0,
    };
    if l.path_mode == Some(super::PathMode::Blend) {
        used |= PQ;
    }
    if l.tool_length == Some(ToolLength::Apply) {
        used |= H_;
    }
    // G41/G42 D<tool>, G41.1/G42.1 D<diameter>.
    if l.cutter_comp.is_some_and(|c| c != super::CutterComp::Off) {
        used |= D_;
    }
    match l.other_m {
        Some(61) => used |= PQ,
        Some(110) => used |= N_,
        _ => {}
    }
    match l.words.first_outside(used) {
        Some(w) => Err(Error::UnusedWord(w)),
        None => Ok(()),
    }
}

/// True when the line changes tools: M6 (with or without a T word), or,
/// with the Repetier setting `$151=1`, a T word alone. By default (NGC) a T
/// word alone only selects the tool the next M6 changes to.
fn is_tool_change(cx: &Ctx, l: &Line) -> bool {
    l.tool_change || (cx.settings.immediate_tool_change && l.words.contains(Word::T))
}

/// The line's modal words into the copy `g` (nothing is committed yet).
#[inline(never)]
fn modal_words(cx: &Ctx, l: &Line, g: &mut ModalCopy) -> Result<(), Error> {
    if let Some(u) = l.units {
        g.inches = u == Units::Inch;
    }
    if let Some(d) = l.distance {
        g.incremental = d == Distance::Incremental;
    }
    if let Some(p) = l.plane {
        g.plane = p;
    }
    if let Some(a) = l.arc_absolute {
        g.arc_absolute = a;
    }
    if let Some(w) = l.wcs {
        g.wcs = w;
    }
    if let Some(f) = l.word(Word::F) {
        g.feed = to_mm(g.inches, f);
    }
    if let Some(mo) = l.motion {
        g.motion = match mo {
            Motion::Cycle(_) if !matches!(g.motion, Motion::Cycle(_)) => {
                g.before_cycle = g.motion;
                mo
            }
            // `$154=1`: G80 cancels the cycle only (Fanuc's group 9): the
            // motion mode before it stays, so `G80` then `Z-4` moves.
            Motion::Cancel if cx.settings.g80_keeps_motion => match g.motion {
                Motion::Cycle(_) => g.before_cycle,
                other => other,
            },
            _ => mo,
        };
    }
    if let Some(r) = l.retract {
        g.retract = r;
    }
    if let Some(tl) = l.tool_length {
        g.tlo = match tl {
            ToolLength::Cancel => 0.0,
            ToolLength::Apply => {
                let t = match l.word(Word::H) {
                    Some(h) => tool_pocket(cx, h).ok_or(Error::BadWord(F!("H: no such tool in the tool table")))?,
                    None => cx.atc.spindle() as usize,
                };
                crate::atc::tool_length_offset_mm(cx.atc.length_mm(t as u8))
            }
        };
    }
    Ok(())
}

impl Interp {
    /// Non-modal codes that end the line (G4, G10, G92, G28, G37,
    /// G201–G205); `None` for the others (G53), which go on to the motion.
    #[inline(never)]
    fn non_modal(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line) -> Option<Result<Option<Command>, Error>> {
        Some(match l.non_modal {
            // Checked here; run in its own phase, after the spindle and the
            // coolant of its line and before its motion.
            Some(NonModal::Dwell) => match dwell(cx.settings, l) {
                Ok(_) => return None,
                Err(e) => Err(e),
            },
            Some(NonModal::SetOffsets) => self.set_offsets(cx, g, l),
            Some(NonModal::SetPosition) => {
                let mut off = self.g92_mm;
                for (a, &w) in AXIS_WORDS.iter().enumerate() {
                    if let Some(v) = l.word(w) {
                        let v = word_mm(g.inches, a, v);
                        // work = machine - wcs - g92 - tlo  =>  g92 = machine - wcs - tlo - v
                        let tlo = if a == 2 { g.tlo } else { 0.0 };
                        off[a] = self.pos_mm[a] - self.wcs_mm[g.wcs as usize][a] - tlo - v;
                    }
                }
                g.commit(self);
                self.g92_mm = off;
                Ok(None)
            }
            Some(NonModal::ClearG92) => {
                g.commit(self);
                self.g92_mm = [0.0; 3];
                Ok(None)
            }
            Some(NonModal::Home) => {
                g.commit(self);
                let mut mask = 0u8;
                for (a, &w) in AXIS_WORDS.iter().enumerate() {
                    if l.word(w).is_some() {
                        mask |= 1 << a;
                    }
                }
                if mask == 0 {
                    mask = 0b111;
                }
                Ok(Some(Command::Home { mask }))
            }
            Some(NonModal::MeasureTool) => {
                g.commit(self);
                measure_mode(self.inches, l).map(|(mode, x_mm, y_mm)| Some(Command::Measure { mode, x_mm, y_mm }))
            }
            Some(nm @ (NonModal::AuxMove | NonModal::AuxSetPosition | NonModal::AuxEnable | NonModal::AuxHome)) => {
                g.commit(self);
                carousel_command(l, nm).map(Some)
            }
            _ => return None,
        })
    }

    /// The motion part of a line: target, checks, then (through
    /// [`Interp::arc_line`] for arcs, [`Interp::cycle_line`] for cycles)
    /// [`Interp::commit_line`].
    #[inline(never)]
    fn motion_line(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line) -> Result<Option<Command>, Error> {
        let machine_coords = l.non_modal == Some(NonModal::MachineCoords);
        // The target is worked out in place (`run.target` means nothing
        // until the line commits): no copy on the way to the move.
        self.run.target = self.pos_mm;
        if self.comp.side.is_some() {
            // Under compensation the programmed position, not the tool's.
            for a in 0..3 {
                self.run.target[a] = self.prog_pos(a);
            }
        }
        let any_axis = has_axis_words(l) && !axis_words_are_settings(l);
        for (a, &w) in AXIS_WORDS.iter().enumerate() {
            if let Some(v) = l.word(w) {
                let v = word_mm(g.inches, a, v);
                self.run.target[a] = if machine_coords {
                    v
                } else if g.incremental {
                    self.prog_pos(a) + v
                } else {
                    work_to_machine(self, g, a, v)
                };
            }
        }
        if machine_coords && matches!(g.motion, Motion::Cycle(_)) {
            return Err(Error::BadWord(F!("G53 not allowed with a canned cycle (G80 first)")));
        }
        if l.words.has_polar() {
            self.polar_checks(g, l, machine_coords)?;
            if !(g.incremental && matches!(g.motion, Motion::Cycle(_))) {
                let p = self.polar_point(g, l)?;
                self.run.target[0] = work_to_machine(self, g, 0, p[0]);
                self.run.target[1] = work_to_machine(self, g, 1, p[1]);
            }
        }
        if !any_axis && matches!(l.motion, Some(Motion::ProbeToward | Motion::ProbeTowardNoError)) {
            return Err(Error::BadWord(F!("G38.2/G38.3: all axes missing with motion code, nothing moved")));
        }
        let motion = if machine_coords && !matches!(g.motion, Motion::Rapid | Motion::Linear) { Motion::Linear } else { g.motion };
        // E0 (the carousel) moves with G0/G1 `E`, in its own units and without
        // offsets (Repetier's E0 motor), so all four motors can move at once.
        let e_word = if axis_words_are_settings(l) { None } else { l.word(Word::E) };
        if let Some(v) = e_word {
            if !matches!(motion, Motion::Rapid | Motion::Linear) {
                return Err(Error::BadWord(F!("E only with G0/G1")));
            }
            self.run.target[3] = if g.incremental { self.pos_mm[3] + v } else { v };
        }
        let mode = match self.comp_line(cx, g, l, motion, any_axis, e_word.is_some())? {
            CompOutcome::Done(r) => return r,
            CompOutcome::Ordinary(mode) => mode,
        };
        if let Motion::Cycle(kind) = g.motion {
            if any_axis || l.motion.is_some() {
                return self.cycle_line(cx, g, l, kind);
            }
        }
        let mut do_motion = None;
        if any_axis || e_word.is_some() || matches!(l.motion, Some(Motion::ArcCw | Motion::ArcCcw)) {
            match motion {
                Motion::Cancel => {
                    return Err(Error::BadWord(F!(
                        "axis words without a motion mode (G80 active; $154=1 keeps the mode from before a cycle)"
                    )))
                }
                Motion::Rapid => {}
                _ => {
                    if !(g.feed > 0.0) {
                        return Err(Error::BadFeed);
                    }
                }
            }
            if !self.conv_fresh {
                self.refresh_conv(cx.settings);
            }
            soft_limits(&mut self.steps_cache, &self.travel_steps, cx.settings, &self.run.target)?;
            keep_out(cx.settings, &self.pos_mm, &self.run.target)?;
            do_motion = Some(motion);
        }
        match do_motion {
            Some(mo @ (Motion::ArcCw | Motion::ArcCcw)) => {
                let target = self.run.target;
                let r = self.arc_line(cx, g, l, &target, mo);
                if r.is_ok() {
                    self.comp_apply(mode);
                }
                r
            }
            _ => {
                self.commit_line(g, do_motion);
                self.comp_apply(mode);
                // A line with nothing but its move (a streamed G1): the move
                // now, without a turn of `next`'s phases.
                if do_motion.is_some() && !self.run.extras {
                    self.run.phase = if l.other_m.is_none() && l.stopping.is_none() { Phase::Done } else { Phase::OtherM };
                    return Ok(self.motion());
                }
                Ok(None)
            }
        }
    }

    /// A line that runs a canned cycle (G73, G81–G89, or bare X/Y/Z while
    /// one is modal): resolve the words against the sticky ones, check every
    /// point the cycle can reach against the soft limits, then commit the
    /// line with it. A bad cycle line changes nothing and moves nothing.
    #[inline(never)]
    fn cycle_line(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line, kind: cycles::Kind) -> Result<Option<Command>, Error> {
        match g.plane {
            Plane::Xy => {}
            Plane::Zx => return Err(Error::BadWord(F!("canned cycles only in the XY plane (G17); G18 (ZX) is active, nothing moved"))),
            Plane::Yz => return Err(Error::BadWord(F!("canned cycles only in the XY plane (G17); G19 (YZ) is active, nothing moved"))),
        }
        if !(g.feed > 0.0) {
            return Err(Error::BadFeed);
        }
        let mm = |w: Word| l.word(w).map(|v| to_mm(g.inches, v));
        let mut words = cycles::LineWords {
            x: mm(Word::X),
            y: mm(Word::Y),
            z: mm(Word::Z),
            r: mm(Word::R),
            q: mm(Word::Q),
            p: l.word(Word::P),
            l: l.word(Word::L),
            polar: None,
        };
        if l.words.has_polar() {
            if g.incremental {
                // Radius and angle added per hole (LinuxCNC's CYCLE_MACRO).
                words.polar = Some([mm(Word::At).unwrap_or(0.0), deg_to_rad(l.word(Word::Caret).unwrap_or(0.0))]);
            } else {
                let p = self.polar_point(g, l)?;
                (words.x, words.y) = (Some(p[0]), Some(p[1]));
            }
        }
        let mut off = [0.0f32; 3];
        let mut pos = [0.0f32; 3];
        for a in 0..3 {
            let tlo = if a == 2 { g.tlo } else { 0.0 };
            off[a] = self.wcs_mm[g.wcs as usize][a] + g.g92[a] + tlo;
            pos[a] = frame::axis_user_from_internal(a, self.pos_mm[a] - off[a]);
        }
        let prev = match self.motion {
            Motion::Cycle(k) => Some(k),
            _ => None,
        };
        let bad = |e: cycles::Error| Error::BadWord(e.message());
        let (params, sticky) = cycles::resolve(kind, g.retract, g.incremental, prev, &self.cycle, &words, pos).map_err(bad)?;
        let cycle = cycles::Cycle::new(params, pos).map_err(bad)?;
        let run = CycleRun { cycle, sticky, off };
        let (lo, hi) = run.cycle.bounds();
        let (lo4, hi4) = (cycle_target(self.pos_mm, &run, lo), cycle_target(self.pos_mm, &run, hi));
        self.check_soft_limits(cx.settings, &lo4)?;
        self.check_soft_limits(cx.settings, &hi4)?;
        keep_out_box(cx.settings, &self.pos_mm, &lo4, &hi4)?;
        self.run.target = self.pos_mm;
        self.commit_line(g, Some(g.motion));
        self.cycle = run.sticky;
        self.run.progress = Progress::Cycle(run);
        Ok(None)
    }

    /// What LinuxCNC refuses of polar words: with X or Y, outside G17, with
    /// G53.
    #[inline(never)]
    fn polar_checks(&self, g: &ModalCopy, l: &Line, machine_coords: bool) -> Result<(), Error> {
        if l.words.contains(Word::X) || l.words.contains(Word::Y) {
            return Err(Error::BadWord(F!("polar coordinates (@ ^) with X or Y on one line")));
        }
        if g.plane != Plane::Xy {
            return Err(Error::BadWord(F!("polar coordinates (@ ^) only in the XY plane (G17)")));
        }
        if machine_coords {
            return Err(Error::BadWord(F!("polar coordinates (@ ^) not with G53")));
        }
        Ok(())
    }

    /// The X, Y (work coordinates, mm) of a line's polar words `@` radius
    /// and `^` angle (degrees, counter-clockwise from +X) about the work
    /// origin, as LinuxCNC reads them: under G90 a missing one is the
    /// current position's; under G91 both are added to the current
    /// position's radius and angle (indeterminate at the origin).
    #[inline(never)]
    fn polar_point(&self, g: &ModalCopy, l: &Line) -> Result<[f32; 2], Error> {
        let at = l.word(Word::At).map(|v| to_mm(g.inches, v));
        let angle = l.word(Word::Caret).map(deg_to_rad);
        let cur = [self.pos_mm[0] - self.wcs_mm[g.wcs as usize][0] - g.g92[0], self.pos_mm[1] - self.wcs_mm[g.wcs as usize][1] - g.g92[1]];
        let at_origin = cur[0] == 0.0 && cur[1] == 0.0;
        let r0 = crate::math::sqrtf(cur[0] * cur[0] + cur[1] * cur[1]);
        let a0 = crate::math::atan2f(cur[1], cur[0]);
        let (r, a) = if g.incremental {
            if at_origin {
                return Err(Error::BadWord(F!("G91 polar move from the origin is indeterminate, nothing moved")));
            }
            (r0 + at.unwrap_or(0.0), a0 + angle.unwrap_or(0.0))
        } else {
            if angle.is_none() && at_origin {
                return Err(Error::BadWord(F!("polar move from the origin needs ^ (the angle), nothing moved")));
            }
            (at.unwrap_or(r0), angle.unwrap_or(a0))
        };
        let (sin, cos) = crate::math::sincosf(a);
        Ok([r * cos, r * sin])
    }

    /// Arcs: compute the chord plan before committing anything, then commit
    /// the line with it.
    #[inline(never)]
    fn arc_line(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line, target: &[f32; N_AXES], mo: Motion) -> Result<Option<Command>, Error> {
        let (a0, a1, a2) = match g.plane {
            Plane::Xy => (0, 1, 2),
            Plane::Zx => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        };
        let start = [self.pos_mm[0], self.pos_mm[1], self.pos_mm[2]];
        let spec = self.arc_spec(g, l, start)?;
        // An end that rounds to the start's steps in the plane is the start: a
        // full circle (arc.rs), never a sliver of an arc from float round-off.
        let mut target = *target;
        let spm = cx.settings.steps_per_mm;
        if to_steps(start[a0], spm[a0]) == to_steps(target[a0], spm[a0]) && to_steps(start[a1], spm[a1]) == to_steps(target[a1], spm[a1]) {
            target[a0] = start[a0];
            target[a1] = start[a1];
        }
        let end = [target[0], target[1], target[2]];
        // G18 and G19 contain Z: mirrored into the internal frame, they turn the other way.
        let cw = frame::internal_clockwise(mo == Motion::ArcCw, g.plane != Plane::Xy);
        let plan = new_arc(start, end, spec, (a0, a1, a2), cw, cx.settings.arc_tolerance_mm)?;
        self.check_arc_limits(cx, &plan)?;
        self.run.target = target;
        self.commit_line(g, Some(mo));
        self.run.progress = Progress::Arc(plan, end);
        Ok(None)
    }

    /// Every chord end stays inside the arc's bounding box; check it.
    #[inline(never)]
    fn check_arc_limits(&mut self, cx: &Ctx, plan: &arc::Arc) -> Result<(), Error> {
        let (lo, hi) = plan.bounds();
        let mut lo4 = self.pos_mm;
        let mut hi4 = self.pos_mm;
        lo4[..3].copy_from_slice(&lo);
        hi4[..3].copy_from_slice(&hi);
        self.check_soft_limits(cx.settings, &lo4)?;
        self.check_soft_limits(cx.settings, &hi4)?;
        keep_out_box(cx.settings, &self.pos_mm, &lo4, &hi4)
    }

    /// G10 L1 / L2 / L20.
    #[inline(never)]
    fn set_offsets(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line) -> Result<Option<Command>, Error> {
        let lv = l.word(Word::L).ok_or(Error::BadWord(F!("G10 needs L1, L2 or L20")))?;
        let p = l.word(Word::P).ok_or(Error::BadWord(F!("G10 needs P")))?;
        let conv = |v: f32| to_mm(g.inches, v);
        match round_i32(lv) {
            1 if lv == 1.0 => {
                if let Some(q) = l.word(Word::Q) {
                    // `G10 L1 P<tool> Q<pocket>`: the tool table's numbering.
                    let (tool, pocket) = (whole_in(p, 1, 254), whole_in(q, 0, crate::atc::N_POCKETS as i32));
                    let (Some(tool), Some(pocket)) = (tool, pocket) else {
                        return Err(Error::BadWord(F!("G10 L1 P<tool 1-254> Q<pocket 1-12, 0 takes the tool out>")));
                    };
                    return Ok(Some(Command::AssignTool { tool, pocket }));
                }
                let t = tool_pocket(cx, p).ok_or(Error::BadWord(F!("G10 L1: P must be a tool of the tool table")))?;
                if t == 0 {
                    return Err(Error::BadWord(F!("G10 L1: P must be a tool of the tool table, not 0")));
                }
                let r = l.word(Word::R);
                if r.is_some_and(|r| r < 0.0) {
                    return Err(Error::BadWord(F!("G10 L1: R must not be negative")));
                }
                g.commit(self);
                // The line leaves the modal tool length offset in force, even
                // when the entry is the spindle tool's (as it always did: the
                // table entry applies at the next change, M61 or G43).
                self.run.tlo_mm = g.tlo;
                self.run.phase = Phase::Tlo;
                Ok(Some(Command::SetTool { tool: t as u8, length_mm: l.word(Word::Z).map(conv), radius_mm: r.map(conv) }))
            }
            n @ (2 | 20) if lv == n as f32 => {
                let idx = round_i32(p);
                if idx as f32 != p || !(0..=N_WCS as i32).contains(&idx) {
                    return Err(Error::Coded(grbl::BAD_WCS, F!("G10 L2/L20: P must be 0-6")));
                }
                let w = if idx == 0 { g.wcs as usize } else { (idx - 1) as usize };
                let mut off = self.wcs_mm[w];
                for (a, &aw) in AXIS_WORDS.iter().enumerate() {
                    if let Some(v) = l.word(aw) {
                        let v = word_mm(g.inches, a, v);
                        off[a] = if n == 2 {
                            v
                        } else {
                            let tlo = if a == 2 { g.tlo } else { 0.0 };
                            self.pos_mm[a] - g.g92[a] - tlo - v
                        };
                    }
                }
                self.wcs_mm[w] = off;
                g.commit(self);
                // Work offsets are persistent (docs/SPEC.md §5): stored now; the
                // EEPROM layer programs only the bytes that changed.
                Ok(Some(Command::StoreOffsets))
            }
            _ => Err(Error::BadWord(F!("G10: L must be 1, 2 or 20"))),
        }
    }

    /// M codes of the "other" group: M220 here, the rest for the controller.
    #[inline(never)]
    fn other_m(&mut self, l: &Line, code: u16) -> Result<Option<Command>, Error> {
        Ok(Some(match code {
            17 | 18 | 84 | 400 | 500 | 501 | 502 => Command::M(code),
            92 | 201 | 203 => {
                let mut values = [f32::NAN; N_AXES];
                for (a, &w) in [Word::X, Word::Y, Word::Z, Word::E].iter().enumerate() {
                    if let Some(v) = l.word(w) {
                        values[a] = v;
                    }
                }
                Command::AxisSettings { code, values }
            }
            220 => {
                let s = l.word(Word::S).ok_or(Error::BadWord(F!("M220 needs S<percent>")))?;
                if !(10.0..=500.0).contains(&s) {
                    return Err(Error::BadWord(F!("M220 S must be 10-500")));
                }
                Command::FeedOverride { pct: round_i32(s) as u16 }
            }
            108 => return Ok(None),
            _ => return Err(Error::NotAvailable(F!("M code not supported"))),
        }))
    }
}

/// M61's words: `Q<tool>` (a tool of the tool table, 0: empty), or
/// `P<1-12> S<0|1>`.
#[inline(never)]
fn m61(cx: &Ctx, l: &Line) -> Result<Command, Error> {
    let whole = |v: f32, lo: i32, hi: i32| {
        let n = round_i32(v);
        (n as f32 == v && (lo..=hi).contains(&n)).then_some(n as u8)
    };
    let bad = Error::Atc(crate::atc::Fault::M61Words);
    match (l.word(Word::Q), l.word(Word::P), l.word(Word::S)) {
        (Some(q), None, None) => Ok(Command::ConfirmTool { tool: tool_pocket(cx, q).ok_or(bad)? as u8 }),
        (None, Some(p), Some(s)) => {
            let pocket = whole(p, 1, 12).ok_or(bad)?;
            let full = whole(s, 0, 1).ok_or(bad)? == 1;
            Ok(Command::SetPocket { pocket, full })
        }
        _ => Err(bad),
    }
}

/// G4's time, in ms: P in seconds (RS274/NGC, grbl, LinuxCNC and every CAM
/// file of the corpus) or, with `$153=1`, in milliseconds (Mach3 and UCCNC
/// posts, Marlin: docs/gcode.md "G4"); without P, S in seconds (grbl, Marlin).
/// With P, an S on the line is the spindle speed.
fn dwell(s: &Settings, l: &Line) -> Result<f32, Error> {
    let ms = match (l.word(Word::P), l.word(Word::S)) {
        (Some(p), _) if s.dwell_p_ms => p,
        (Some(secs), _) | (None, Some(secs)) => secs * 1000.0,
        (None, None) => return Err(Error::Coded(grbl::VALUE_MISSING, F!("G4 needs P (or S in seconds)"))),
    };
    if !(ms >= 0.0) {
        return Err(Error::Coded(grbl::NEGATIVE, F!("G4: the dwell must not be negative")));
    }
    Ok(ms)
}

/// G37's words as a measurement mode, with the setter position (mm) for a
/// calibration.
#[inline(never)]
fn measure_mode(inches: bool, l: &Line) -> Result<(crate::toolsetter::Mode, Option<f32>, Option<f32>), Error> {
    use crate::toolsetter::{Fault, Mode};
    let bad = Error::Setter(Fault::Words);
    let k = if inches { 25.4 } else { 1.0 };
    let um = |v: f32| round_i32(v * k * 1000.0);
    let (d, b, len, r) = (l.word(Word::D), l.word(Word::B), l.word(Word::L), l.word(Word::R));
    let (x, y) = (l.word(Word::X).map(|v| v * k), l.word(Word::Y).map(|v| v * k));
    let mode = match (d, b, len, r) {
        (None, None, None, None) => Mode::Length,
        (Some(1.0), None, None, None) => Mode::Diameter,
        (None, Some(t), None, None) if t >= 0.0 => Mode::Check { tol_um: um(t) },
        (None, None, Some(len), Some(r)) if len > 0.0 && r >= 0.0 => Mode::Calibrate { length_um: um(len), diameter_um: 2 * um(r) },
        _ => return Err(bad),
    };
    if (x.is_some() || y.is_some()) && !matches!(mode, Mode::Calibrate { .. }) {
        return Err(bad);
    }
    Ok((mode, x, y))
}

/// Largest |X| accepted by G201/G202, pitches (20 revolutions).
const CAROUSEL_MAX_X: f32 = 360.0;

/// G201, G202, G204, G205 (motor P0, the carousel): the words checked.
#[inline(never)]
fn carousel_command(l: &Line, nm: NonModal) -> Result<Command, Error> {
    use crate::atc::Fault;
    if l.word(Word::P) != Some(0.0) {
        return Err(Error::Atc(Fault::Motor));
    }
    let bit = |w: Word| match l.word(w) {
        None => Ok(None),
        Some(v) if v == 0.0 || v == 1.0 => Ok(Some(v == 1.0)),
        Some(_) => Err(Error::Atc(Fault::OnOff)),
    };
    let x = match l.word(Word::X) {
        Some(x) if x.abs() <= CAROUSEL_MAX_X => Some(x),
        Some(_) => return Err(Error::Atc(Fault::CarouselX)),
        None => None,
    };
    Ok(match nm {
        NonModal::AuxMove => Command::CarouselTurn { x: x.ok_or(Error::Atc(Fault::CarouselX))? },
        NonModal::AuxSetPosition => Command::CarouselSetPosition { x: x.ok_or(Error::Atc(Fault::CarouselX))? },
        NonModal::AuxEnable => Command::CarouselEnable { on: bit(Word::S)?.ok_or(Error::Atc(Fault::OnOff))? },
        _ => Command::CarouselHome { back: bit(Word::S)?.unwrap_or(false), only_if_unhomed: bit(Word::E)?.unwrap_or(false) },
    })
}

/// A canned cycle resolved and checked, ready to run once the line commits.
struct CycleRun {
    cycle: cycles::Cycle,
    /// The sticky words to keep after this line.
    sticky: cycles::Sticky,
    /// Machine − work offset per axis (work offset, G92, tool length),
    /// internal frame.
    off: [f32; 3],
}

/// A cycle's point `t` (user frame, work coordinates; NaN: the axis stays)
/// → internal machine mm, the other axes at `pos` (where the tool is).
fn cycle_target(pos: [f32; N_AXES], run: &CycleRun, t: [f32; 3]) -> [f32; N_AXES] {
    let mut target = pos;
    for a in 0..3 {
        if !t[a].is_nan() {
            target[a] = add_nz(frame::axis_internal_from_user(a, t[a]), run.off[a]);
        }
    }
    target
}

/// Absolute work coordinate `v` (mm) of axis `a` → machine mm, with the
/// line's modal offsets (axis words under G90, I/J/K under G90.1).
fn work_to_machine(i: &Interp, g: &ModalCopy, a: usize, v: f32) -> f32 {
    let tlo = if a == 2 { g.tlo } else { 0.0 };
    add_nz(add_nz(add_nz(v, i.wcs_mm[g.wcs as usize][a]), g.g92[a]), tlo)
}

/// The next chord end of `plan`, in a frame of its own (see [`new_arc`]).
#[inline(never)]
fn next_chord(plan: &mut arc::Arc) -> Option<[f32; 3]> {
    plan.next()
}

/// [`arc::Arc::new`] in a frame of its own (its many f32 temporaries
/// would otherwise push [`Interp::arc_line`]'s locals out of `ldd` reach).
#[inline(never)]
fn new_arc(
    start: [f32; 3],
    end: [f32; 3],
    spec: arc::Centre,
    axes: (usize, usize, usize),
    clockwise: bool,
    tolerance_mm: f32,
) -> Result<arc::Arc, Error> {
    arc::Arc::new(start, end, spec, axes, clockwise, tolerance_mm).map_err(Error::Arc)
}

/// `a == b` for finite floats (+0.0 equals −0.0), on the bit patterns: a
/// soft-float compare costs ~50 cycles on the AVR.
#[inline]
pub fn same_f32(a: f32, b: f32) -> bool {
    let (a, b) = (a.to_bits(), b.to_bits());
    a == b || (a | b) & 0x7FFF_FFFF == 0
}

/// `a + b`, without the ~90-cycle soft-float addition when `b` is +0.0 (no
/// offset): `a + 0.0 == a` for every `a` but −0.0, which the parser never
/// gives.
#[inline]
fn add_nz(a: f32, b: f32) -> f32 {
    if b.to_bits() == 0 {
        a
    } else {
        add_cold(a, b)
    }
}

/// `a + b`, as a call: LLVM-AVR would otherwise turn [`add_nz`]'s branch
/// into a select that always adds (see `math::div_cold`).
#[inline(never)]
fn add_cold(a: f32, b: f32) -> f32 {
    a + b
}

/// A straight move from `a` to `b` must not enter the tool magazine's
/// keep-out zone (only the tool change, which does not come through here,
/// goes in).
#[inline(never)]
fn keep_out(s: &Settings, a: &[f32; N_AXES], b: &[f32; N_AXES]) -> Result<(), Error> {
    if s.station.enters_keep_out([a[0], a[1], a[2]], [b[0], b[1], b[2]]) {
        return Err(Error::KeepOut);
    }
    Ok(())
}

/// An arc or a canned cycle by its bounding box, with the start point
/// (the cycle's first move starts there). `a` and `b` are opposite
/// corners, in either order per axis (the Z flip of a cycle's user bounds
/// swaps them).
#[inline(never)]
fn keep_out_box(s: &Settings, from: &[f32; N_AXES], a: &[f32; N_AXES], b: &[f32; N_AXES]) -> Result<(), Error> {
    let min = |x: f32, y: f32| if x < y { x } else { y };
    let max = |x: f32, y: f32| if x > y { x } else { y };
    let l = core::array::from_fn(|i| min(from[i], min(a[i], b[i])));
    let h = core::array::from_fn(|i| max(from[i], max(a[i], b[i])));
    if s.station.box_enters_keep_out(l, h) {
        return Err(Error::KeepOut);
    }
    Ok(())
}

/// [`Interp::check_soft_limits`] over the interpreter's caches (fresh).
#[inline(never)]
fn soft_limits(cache: &mut [(u32, i32); N_AXES], travel_steps: &[i32; 3], s: &Settings, t: &[f32; N_AXES]) -> Result<(), Error> {
    if !s.soft_limits {
        return Ok(());
    }
    let st = steps_cached(cache, s, t);
    for a in 0..3 {
        if st[a] < 0 || st[a] > travel_steps[a] {
            return Err(Error::SoftLimit);
        }
    }
    Ok(())
}

/// [`Interp::steps_of`]'s conversion through `cache`.
#[inline(always)]
fn steps_cached(cache: &mut [(u32, i32); N_AXES], s: &Settings, mm: &[f32; N_AXES]) -> [i32; N_AXES] {
    let mut st = [0i32; N_AXES];
    for a in 0..N_AXES {
        let c = &mut cache[a];
        if c.0 != mm[a].to_bits() {
            *c = (mm[a].to_bits(), to_steps(mm[a], s.steps_per_mm[a]));
        }
        st[a] = c.1;
    }
    st
}

/// Degrees → radians.
pub(crate) fn deg_to_rad(deg: f32) -> f32 {
    deg * (core::f32::consts::PI / 180.0)
}

/// `round(mm · steps_per_mm)`.
#[inline(never)]
fn to_steps(mm: f32, steps_per_mm: f32) -> i32 {
    round_i32(mm * steps_per_mm)
}

fn spindle_duty(s: &Settings, rpm: f32) -> u8 {
    let rpm = if rpm > 0.0 && rpm < s.spindle_min_rpm { s.spindle_min_rpm } else { rpm };
    let d = rpm / s.spindle_max_rpm * 255.0;
    if d <= 0.0 {
        0
    } else if d >= 255.0 {
        255
    } else {
        let v = round_i32(d) as u8;
        v.max(1)
    }
}

/// `v` as a whole number within `lo..=hi`.
#[inline(never)]
fn whole_in(v: f32, lo: i32, hi: i32) -> Option<u8> {
    let n = round_i32(v);
    (n as f32 == v && (lo..=hi).contains(&n)).then_some(n as u8)
}

/// The pocket of the tool numbered `v` (a T, H, D, G10 L1 P or M61 Q word):
/// a whole number the tool table has; 0 is the empty spindle.
#[inline(never)]
pub(crate) fn tool_pocket(cx: &Ctx, v: f32) -> Option<usize> {
    let t = whole_in(v, 0, 255)?;
    cx.atc.table.pocket_of(t).map(usize::from)
}

/// The modal fields a line may change, copied so an invalid line changes nothing.
struct ModalCopy {
    inches: bool,
    incremental: bool,
    plane: Plane,
    arc_absolute: bool,
    motion: Motion,
    before_cycle: Motion,
    retract: Retract,
    feed: f32,
    wcs: u8,
    tlo: f32,
    g92: [f32; 3],
}

impl ModalCopy {
    fn from(i: &Interp) -> ModalCopy {
        ModalCopy {
            inches: i.inches,
            incremental: i.incremental,
            plane: i.plane,
            arc_absolute: i.arc_absolute,
            motion: i.motion,
            before_cycle: i.motion_before_cycle,
            retract: i.retract,
            feed: i.feed_mm_per_min,
            wcs: i.wcs,
            tlo: i.tlo_mm,
            g92: i.g92_mm,
        }
    }

    fn commit(&self, i: &mut Interp) {
        i.inches = self.inches;
        i.incremental = self.incremental;
        i.plane = self.plane;
        i.arc_absolute = self.arc_absolute;
        i.motion = self.motion;
        i.motion_before_cycle = self.before_cycle;
        i.retract = self.retract;
        i.feed_mm_per_min = self.feed;
        i.wcs = self.wcs;
        i.tlo_mm = self.tlo;
    }
}

#[cfg(test)]
#[path = "interp_tests.rs"]
pub(crate) mod tests;

#[cfg(test)]
#[path = "command_tests.rs"]
mod command_tests;
