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
//!
//! The files, each with one job (a module names only those above it in
//! this list, never one below):
//!
//! | module | owns |
//! |---|---|
//! | this file | [`Interp`] (the modal state and commanded position), [`Ctx`] |
//! | `error` | [`Error`] and its grbl codes ([`grbl`]) |
//! | `command` | [`Command`], [`Report`] |
//! | `units` | inches, the Z frame, degrees, steps; cheap float helpers |
//! | `limits` | soft limits, keep-out zone, the mm → steps cache |
//! | `tool_words` | T, M6, M61, a tool number as a pocket |
//! | `modal` | the modal copy a line works on, its modal words |
//! | `line_run` | the line in progress: phase, target, arc or cycle state |
//! | `offsets` | work offsets, G92, tool length offset; G10 |
//! | `jog` | `$J=` |
//! | `mcodes` | S, M3, M5; the other M codes |
//! | `checks` | the checks before the modal words; unused words |
//! | `non_modal` | G4, G10, G92, G28, G37, G201–G205 |
//! | `polar` | `@` and `^` |
//! | `arc_line` | G2/G3 lines |
//! | `cycle_line` | canned cycle lines |
//! | `comp_line` | lines under cutter radius compensation |
//! | `motion` | the motion part of a line |
//! | `step` | [`Interp::begin_line`], [`Interp::next`]: the line's actions in order |

mod arc_line;
mod checks;
mod command;
mod comp_line;
mod cycle_line;
mod error;
mod jog;
mod limits;
mod line_run;
mod mcodes;
mod modal;
mod motion;
mod non_modal;
mod offsets;
mod polar;
mod step;
mod tool_words;
mod units;

pub use command::{Command, Report};
pub use error::{grbl, Error};
pub use units::same_f32;

use super::comp;
use super::cycles::{self, Retract};
use super::{Line, Motion, Plane, Word};
use crate::config::{Settings, N_WCS};
use crate::N_AXES;
use line_run::LineRun;

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
    /// Bits of the largest feed, mm/min, at which no move can reach the
    /// step-rate cap (0: any may). Valid while `conv_fresh`. See
    /// [`Interp::never_rate_capped`].
    uncapped_feed_bits: u32,
    /// The caches above match the settings; cleared by
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
            uncapped_feed_bits: 0,
            conv_fresh: false,
            run: LineRun::new(),
            comp: comp::State::OFF,
        }
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

#[cfg(test)]
pub(crate) mod tests;
