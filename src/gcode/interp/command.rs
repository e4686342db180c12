//! What a line asks of the controller ([`Command`], one action at a time)
//! and the reports it can ask for ([`Report`]).

use crate::N_AXES;

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
