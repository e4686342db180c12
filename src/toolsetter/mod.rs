//! Optical tool setter (docs/SPEC.md §8, thesis §4.1.11 and §5.4): G37 length and
//! diameter measurement, broken-tool check and reference calibration.
//!
//! ```text
//!  gcode::interp ─ Command::Measure ─► machine::setter::g37 ─► Measure (pure table) ─► actions ─► planner
//!                                                             ▲ events: trip steps latched by the stepper ISR
//! ```
//!
//! The beam input (PD2) is the probe input of the stepper ISR: while a seek
//! runs, the ISR checks it after every step and latches the position of the
//! step that broke the beam (the same latch G38.2/G38.3 use), then stops.
//! The main loop never polls the beam during a seek.
//!
//! Geometry, in the internal frame of [`crate::frame`] (Z grows downward,
//! the tip hangs `length` below the spindle; the user sees every Z here
//! negated, `[SETTER Z:…]` included):
//! the beam runs along X at the setter's Y, at a tip height `beam_z`. A
//! tool's tip reaches the beam when the spindle is at `beam_z - length`,
//! so `length = beam_z - trip_z`. Approaching in Y with the tip below the
//! beam, the tool breaks it at `y - (d + w)/2` from −Y and at `y + (d + w)/2`
//! from +Y, where `w` is the beam width: `d = |Y2 − Y1| − w`. Each edge lies
//! half a step before its trip step, so the span is `Y2 − Y1 + 1` steps.
//!
//! Calibration (`G37 L<length> R<radius>` with a reference tool in the
//! spindle) stores `beam_z = trip_z + length` and `w = span − 2·radius`.
//!
//! Commands (docs/SPEC.md §5):
//! - `G37`: length of the tool in the spindle → tool table, `[TOOL:n L:…]`;
//! - `G37 D1`: length and diameter, `[TOOL:n L:… D:…]`;
//! - `G37 B<tol>`: length compared with the table; more than `tol` mm off is
//!   the alarm `broken tool`; `[TOOL:n L:… dL:…]`, the table is unchanged;
//! - `G37 L<len> R<radius> [X<x> Y<y>]`: calibration with a reference tool
//!   (optionally moving the setter position first), `[SETTER Z:… W:…]`.

use crate::atc::tools::{seal, valid};

/// Fast seek feed, mm/min.
pub const SEEK_FAST_MM_PER_MIN: f32 = 600.0;
/// Slow seek feed, mm/min.
pub const SEEK_SLOW_MM_PER_MIN: f32 = 60.0;
/// Back-off between the fast and the slow seek, mm.
pub const BACKOFF_MM: f32 = 0.5;
/// Diameter: start this far beside the beam centre line in Y, mm.
pub const SIDE_MM: f32 = 6.0;
/// Diameter: the tip goes this far below the beam, mm.
pub const TIP_BELOW_MM: f32 = 1.0;
/// Travel height, internal machine Z mm (Z grows downward: the user's
/// machine Z −1).
pub const Z_SAFE_MM: f32 = 1.0;

crate::flash_messages! {
    /// Why G37 was refused or stopped (`message`: the text after `Error:`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Fault {
        /// The beam is broken before anything moves.
        BeamBlocked => "tool setter beam blocked at start, nothing moved",
        /// A seek reached its end without breaking the beam.
        BeamNeverBroke => "tool setter beam never broke; tool retracted, nothing stored",
        /// After the back-off the beam is still broken.
        BeamStuck => "tool setter beam stays blocked after back-off",
        /// No calibration yet.
        NotCalibrated => "tool setter not calibrated (G37 L<len> R<radius>)",
        /// No tool in the spindle to measure.
        NoTool => "no tool in the spindle",
        /// B given but the table has no length for the tool.
        NothingToCheck => "no stored length to check against",
        /// Bad words: D not 1, B negative, L without R, …
        Words => "G37 [D1] [B<tol>] or G37 L<len> R<radius> [X Y]",
        /// The setter or a seek end is outside travel.
        SoftLimit => "tool setter outside travel (soft limit)",
        /// Not homed.
        NotHomed => "home X Y Z (G28) before G37",
        /// An alarm (M112, limit, …) stopped the measurement.
        Stopped => "G37 stopped",
    }
}

/// Setter position and calibration (EEPROM record after the tool table).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setter {
    /// X of the setter (where the tool is lowered), machine µm.
    pub x_um: i32,
    /// Y of the beam centre line, machine µm.
    pub y_um: i32,
    /// Tip height at which the beam breaks, machine µm; [`Setter::UNCALIBRATED`] until calibrated.
    pub beam_z_um: i32,
    /// What the beam adds to a tool's diameter in the Y span, µm.
    pub beam_width_um: i32,
    /// Reference tool of the last calibration: length and diameter, µm.
    pub ref_length_um: i32,
    pub ref_diameter_um: i32,
}

impl Setter {
    /// `beam_z_um` before any calibration.
    pub const UNCALIBRATED: i32 = i32::MIN;
    /// Defaults: setter at X 5, Y 10, not calibrated.
    pub const DEFAULT: Setter =
        Setter { x_um: 5_000, y_um: 10_000, beam_z_um: Setter::UNCALIBRATED, beam_width_um: 0, ref_length_um: 0, ref_diameter_um: 0 };
    /// Image: version, 6 × i32, checksum.
    pub const IMAGE_LEN: usize = 1 + 6 * 4 + 1;

    /// [`Setter::DEFAULT`], read from flash: used as a value at run time,
    /// the constant is a 24-byte copy in RAM (`.data`) on AVR.
    pub fn factory() -> Setter {
        DEFAULT_IN_FLASH.get()
    }

    /// True once a calibration stored the beam height.
    pub fn calibrated(&self) -> bool {
        self.beam_z_um != Setter::UNCALIBRATED
    }

    /// The EEPROM image.
    pub fn to_bytes(&self) -> [u8; Self::IMAGE_LEN] {
        let mut img = [0u8; Self::IMAGE_LEN];
        let v = [self.x_um, self.y_um, self.beam_z_um, self.beam_width_um, self.ref_length_um, self.ref_diameter_um];
        for (i, x) in v.iter().enumerate() {
            img[1 + 4 * i..5 + 4 * i].copy_from_slice(&x.to_le_bytes());
        }
        seal(&mut img);
        img
    }

    /// Parse; `None` when blank or corrupt.
    pub fn from_bytes(img: &[u8; Self::IMAGE_LEN]) -> Option<Setter> {
        if !valid(img) {
            return None;
        }
        let f = |i: usize| i32::from_le_bytes([img[1 + 4 * i], img[2 + 4 * i], img[3 + 4 * i], img[4 + 4 * i]]);
        Some(Setter { x_um: f(0), y_um: f(1), beam_z_um: f(2), beam_width_um: f(3), ref_length_um: f(4), ref_diameter_um: f(5) })
    }
}

impl Default for Setter {
    fn default() -> Self {
        Setter::DEFAULT
    }
}

/// What G37 is asked to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// `G37`: length.
    Length,
    /// `G37 D1`: length and diameter.
    Diameter,
    /// `G37 B<tol>`: length checked against the table, tolerance µm.
    Check { tol_um: i32 },
    /// `G37 L R`: calibrate with a reference tool of this length and diameter, µm.
    Calibrate { length_um: i32, diameter_um: i32 },
}

impl Mode {
    fn wants_diameter(self) -> bool {
        matches!(self, Mode::Diameter | Mode::Calibrate { .. })
    }
}

/// One state of a measurement (one row of [`TABLE`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Rapid Z up to the travel height.
    LiftToSafe,
    /// Rapid to the setter's X/Y.
    ToSetter,
    /// Seek down (+Z) until the tip breaks the beam.
    SeekZ,
    /// Rapid Z up again.
    LiftAfterZ,
    /// Diameter: rapid beside the beam on the −Y side.
    ToMinusSide,
    /// Diameter: rapid down, tip 1 mm below the beam.
    DownMinus,
    /// Diameter: seek +Y until the beam breaks (Y1).
    SeekPlusY,
    /// Rapid Z up.
    LiftMinus,
    /// Rapid beside the beam on the +Y side (going around above it).
    ToPlusSide,
    /// Rapid down, tip 1 mm below the beam.
    DownPlus,
    /// Seek −Y until the beam breaks (Y2).
    SeekMinusY,
    /// Rapid Z up.
    LiftPlus,
}

/// When a row runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    Always,
    /// D1 and calibration.
    Diameter,
}

/// What a row does, as data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Do {
    ZSafe,
    SetterXY,
    /// Setter Y plus this many [`SIDE_MM`] (−1 or +1).
    Side(i8),
    /// Z to the tip-below-beam height.
    Down,
    /// Seek on an axis (1 = Y, 2 = Z) in a direction (+1 or −1).
    Seek(u8, i8),
}

/// One row: a state, when it runs, what it does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Row {
    pub state: State,
    pub when: When,
    pub act: Do,
}

const fn row(state: State, when: When, act: Do) -> Row {
    Row { state, when, act }
}

/// The measurement, in order (thesis Figures 28 and 30).
pub const TABLE: [Row; 12] = [
    row(State::LiftToSafe, When::Always, Do::ZSafe),
    row(State::ToSetter, When::Always, Do::SetterXY),
    row(State::SeekZ, When::Always, Do::Seek(2, 1)),
    row(State::LiftAfterZ, When::Always, Do::ZSafe),
    row(State::ToMinusSide, When::Diameter, Do::Side(-1)),
    row(State::DownMinus, When::Diameter, Do::Down),
    row(State::SeekPlusY, When::Diameter, Do::Seek(1, 1)),
    row(State::LiftMinus, When::Diameter, Do::ZSafe),
    row(State::ToPlusSide, When::Diameter, Do::Side(1)),
    row(State::DownPlus, When::Diameter, Do::Down),
    row(State::SeekMinusY, When::Diameter, Do::Seek(1, -1)),
    row(State::LiftPlus, When::Diameter, Do::ZSafe),
];

in_flash! {
    /// [`Setter::DEFAULT`] kept in flash ([`Setter::factory`]).
    static DEFAULT_IN_FLASH: Setter = Setter::DEFAULT;
}

in_flash! {
    /// [`TABLE`] kept in flash (a run-time `const` table would sit in RAM on AVR).
    static TABLE_IN_FLASH: [Row; TABLE.len()] = TABLE;
}

/// Row `i` of [`TABLE`], read from flash.
fn row_at(i: usize) -> Option<Row> {
    TABLE_IN_FLASH.row(i)
}

/// What the executor is asked to do next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Rapid to machine mm; `None` keeps the axis.
    Move { xyz: [Option<f32>; 3] },
    /// Run a [`Seek`] on `axis` (1 = Y, 2 = Z) in `dir` for at most `max_mm`;
    /// answer [`Event::Tripped`] with the latched step.
    Seek { axis: u8, dir: i8, max_mm: f32 },
    /// Measurement complete: see [`Measure::result`].
    Done,
    /// Stopped on a fault (after the retract, if one was possible).
    Abort(Fault),
}

/// The executor's answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// A move completed.
    Done,
    /// A seek found the beam at this step position of its axis.
    Tripped(i32),
    /// The action failed.
    Failed(Fault),
}

/// What a measurement needs to know when it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub mode: Mode,
    pub setter: Setter,
    /// Tool in the spindle.
    pub tool: u8,
    /// Its stored length, µm.
    pub stored_length_um: i32,
    /// X, Y, Z homed.
    pub homed: bool,
    /// Travel X, Y, Z, mm.
    pub travel_mm: [f32; 3],
    /// Steps per mm of Y and Z (index 1 and 2).
    pub steps_per_mm: [f32; 3],
}

/// The outcome of a completed measurement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Length (and diameter) of the tool, µm.
    Measured { length_um: i32, diameter_um: Option<i32> },
    /// B check: the length now and its difference from the table, µm.
    Checked { length_um: i32, diff_um: i32, broken: bool },
    /// The new calibration.
    Calibrated(Setter),
}

/// A running G37.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measure {
    req: Request,
    /// Index of the current row in [`TABLE`]; `TABLE.len()` at the end.
    at: u8,
    /// Latched trips: Z down, Y from −Y (Y1), Y from +Y (Y2), steps.
    trip_z: i32,
    y1: i32,
    y2: i32,
    /// A fault waiting for the retract to finish.
    pending: Option<Fault>,
    result: Option<Result<Outcome, Fault>>,
}

/// Steps → µm.
fn um(steps: i32, steps_per_mm: f32) -> i32 {
    crate::math::round_i32(steps as f32 * 1000.0 / steps_per_mm)
}

impl Measure {
    /// Check a request before anything moves.
    pub fn new(req: &Request) -> Result<Measure, Fault> {
        if !req.homed {
            return Err(Fault::NotHomed);
        }
        match req.mode {
            Mode::Calibrate { .. } => {}
            _ if !req.setter.calibrated() => return Err(Fault::NotCalibrated),
            _ if req.tool == 0 => return Err(Fault::NoTool),
            Mode::Check { .. } if req.stored_length_um == 0 => return Err(Fault::NothingToCheck),
            _ => {}
        }
        let s = &req.setter;
        let (x, y) = (s.x_um as f32 / 1000.0, s.y_um as f32 / 1000.0);
        let inside = |v: f32, a: usize| v >= 0.0 && v <= req.travel_mm[a];
        let mut ok = inside(x, 0) && inside(y, 1) && inside(Z_SAFE_MM, 2);
        if req.mode.wants_diameter() {
            ok &= inside(y - SIDE_MM, 1) && inside(y + SIDE_MM, 1);
        }
        if !ok {
            return Err(Fault::SoftLimit);
        }
        Ok(Measure { req: *req, at: 0, trip_z: 0, y1: 0, y2: 0, pending: None, result: None })
    }

    /// The current state; `None` once ended or while retracting after a fault.
    pub fn state(&self) -> Option<State> {
        if self.result.is_some() || self.pending.is_some() {
            None
        } else {
            row_at(self.at as usize).map(|r| r.state)
        }
    }

    /// How it ended: `None` while running.
    pub fn result(&self) -> Option<Result<Outcome, Fault>> {
        self.result
    }

    fn applies(&self, w: When) -> bool {
        match w {
            When::Always => true,
            When::Diameter => self.req.mode.wants_diameter(),
        }
    }

    /// Move to the first row at or after `i` that applies.
    fn go_to(&mut self, mut i: usize) {
        while i < TABLE.len() && !row_at(i).is_some_and(|r| self.applies(r.when)) {
            i += 1;
        }
        self.at = i as u8;
    }

    /// The first action.
    pub fn start(&mut self) -> Action {
        self.go_to(0);
        self.action()
    }

    /// Feed the outcome of the last action; returns the next one.
    pub fn step(&mut self, ev: Event) -> Action {
        if let Some(r) = self.result {
            return match r {
                Ok(_) => Action::Done,
                Err(f) => Action::Abort(f),
            };
        }
        if let Some(f) = self.pending {
            // The retract after a fault has ended (or failed too): stop.
            self.result = Some(Err(f));
            return Action::Abort(f);
        }
        match ev {
            Event::Failed(f) => self.retract_then_abort(f),
            Event::Tripped(p) => {
                match row_at(self.at as usize).map(|r| r.act) {
                    Some(Do::Seek(2, _)) => self.trip_z = p,
                    Some(Do::Seek(_, 1)) => self.y1 = p,
                    Some(Do::Seek(_, _)) => self.y2 = p,
                    _ => {}
                }
                self.go_to(self.at as usize + 1);
                self.action()
            }
            Event::Done => {
                self.go_to(self.at as usize + 1);
                self.action()
            }
        }
    }

    /// Retract the tool, then stop with `f`; nothing is stored.
    fn retract_then_abort(&mut self, f: Fault) -> Action {
        self.pending = Some(f);
        Action::Move { xyz: [None, None, Some(Z_SAFE_MM)] }
    }

    /// The action of the current row, or the result at the end.
    fn action(&mut self) -> Action {
        let Some(row) = row_at(self.at as usize) else {
            self.result = Some(Ok(self.outcome()));
            return Action::Done;
        };
        let s = &self.req.setter;
        let (x, y) = (s.x_um as f32 / 1000.0, s.y_um as f32 / 1000.0);
        match row.act {
            Do::ZSafe => Action::Move { xyz: [None, None, Some(Z_SAFE_MM)] },
            Do::SetterXY => Action::Move { xyz: [Some(x), Some(y), None] },
            Do::Side(k) => Action::Move { xyz: [Some(x), Some(y + k as f32 * SIDE_MM), None] },
            Do::Down => {
                let z = self.trip_z as f32 / self.req.steps_per_mm[2] + TIP_BELOW_MM;
                if z > self.req.travel_mm[2] {
                    return self.retract_then_abort(Fault::SoftLimit);
                }
                Action::Move { xyz: [None, None, Some(z)] }
            }
            Do::Seek(2, dir) => Action::Seek { axis: 2, dir, max_mm: self.req.travel_mm[2] - Z_SAFE_MM },
            Do::Seek(axis, dir) => Action::Seek { axis, dir, max_mm: 2.0 * SIDE_MM },
        }
    }

    /// The result from the latched trips.
    fn outcome(&self) -> Outcome {
        let r = &self.req;
        let trip_z_um = um(self.trip_z, r.steps_per_mm[2]);
        let span_um = um(self.y2 - self.y1 + 1, r.steps_per_mm[1]);
        let length_um = r.setter.beam_z_um.wrapping_sub(trip_z_um);
        match r.mode {
            Mode::Length => Outcome::Measured { length_um, diameter_um: None },
            Mode::Diameter => Outcome::Measured { length_um, diameter_um: Some(span_um - r.setter.beam_width_um) },
            Mode::Check { tol_um } => {
                let diff_um = length_um - r.stored_length_um;
                Outcome::Checked { length_um, diff_um, broken: diff_um.abs() > tol_um }
            }
            Mode::Calibrate { length_um, diameter_um } => Outcome::Calibrated(Setter {
                beam_z_um: trip_z_um + length_um,
                beam_width_um: span_um - diameter_um,
                ref_length_um: length_um,
                ref_diameter_um: diameter_um,
                ..r.setter
            }),
        }
    }
}

/// One seek toward the beam (docs/SPEC.md §8: fast seek, back off, slow re-seek),
/// as a state machine. Distances are signed mm along the seek axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seek {
    /// Fast toward the beam, for at most the search distance.
    Fast,
    /// Back off from the first trip.
    Back,
    /// Check the beam cleared after the back-off.
    CheckClear,
    /// Slow toward the beam again, for at most twice the back-off.
    Slow,
    /// Found: the slow trip is the result.
    Found(i32),
    /// Failed.
    Failed(Fault),
}

/// What a seek asks the executor for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SeekAction {
    /// Move toward the beam by `mm` (signed) at `feed`, stopping when it
    /// breaks; answer `Tripped(step)` or `Missed`.
    Probe { mm: f32, feed_mm_per_min: f32 },
    /// Plain move by `mm` (signed); answer `Moved`.
    Move { mm: f32 },
    /// Read the beam; answer `Beam(broken)`.
    ReadBeam,
    /// Done: the latched step of the slow approach.
    Found(i32),
    /// Failed.
    Fail(Fault),
}

/// The executor's answer to a [`SeekAction`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeekEvent {
    Tripped(i32),
    Missed,
    Moved,
    Beam(bool),
}

impl Seek {
    /// Start a seek in `dir` (+1/−1) of at most `max_mm`.
    pub fn start(max_mm: f32, dir: i8) -> (Seek, SeekAction) {
        (Seek::Fast, SeekAction::Probe { mm: dir as f32 * max_mm, feed_mm_per_min: SEEK_FAST_MM_PER_MIN })
    }

    /// Next step of a seek in `dir`.
    pub fn step(self, dir: i8, ev: SeekEvent) -> (Seek, SeekAction) {
        let d = dir as f32;
        let fail = |f| (Seek::Failed(f), SeekAction::Fail(f));
        match (self, ev) {
            (Seek::Fast, SeekEvent::Tripped(_)) => (Seek::Back, SeekAction::Move { mm: -d * BACKOFF_MM }),
            (Seek::Fast, _) => fail(Fault::BeamNeverBroke),
            (Seek::Back, SeekEvent::Moved) => (Seek::CheckClear, SeekAction::ReadBeam),
            (Seek::CheckClear, SeekEvent::Beam(false)) => {
                (Seek::Slow, SeekAction::Probe { mm: d * 2.0 * BACKOFF_MM, feed_mm_per_min: SEEK_SLOW_MM_PER_MIN })
            }
            (Seek::CheckClear, SeekEvent::Beam(true)) => fail(Fault::BeamStuck),
            (Seek::Slow, SeekEvent::Tripped(p)) => (Seek::Found(p), SeekAction::Found(p)),
            (Seek::Slow, _) => fail(Fault::BeamNeverBroke),
            (Seek::Found(p), _) => (Seek::Found(p), SeekAction::Found(p)),
            (Seek::Failed(f), _) => fail(f),
            (_, _) => fail(Fault::BeamNeverBroke),
        }
    }
}

#[cfg(test)]
mod tests;
