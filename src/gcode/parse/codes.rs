//! The G and M codes a line may hold, one enum per modal group (RS274/NGC
//! §3.4), as the parser records them in a [`super::Line`]; and the M codes
//! of the "other" group ([`OTHER_M_CODES`]).

use crate::gcode::cycles::Kind;

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
    Cycle(Kind),
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

crate::in_flash! {
    /// M codes outside the stopping, tool-change and spindle groups: at most
    /// one of them per line, in [`Line::other_m`]. Add new ones here. In
    /// flash: as a `const` slice it was a 60-byte table in RAM (`.data`).
    pub static OTHER_M_CODES: [u16; 30] = [
        17, 18, 20, 23, 24, 25, 26, 27, 28, 29, 61, 84, 92, 105, 108, 110, 112, 114, 115, 119, 201, 203, 220, 400, 500, 501, 502, 503, 999, 31,
    ];
}

/// `code` is one of [`OTHER_M_CODES`].
pub fn is_other_m(code: u16) -> bool {
    (0..).map_while(|i| OTHER_M_CODES.row(i)).any(|m| m == code)
}
