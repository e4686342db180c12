//! [`View`]: the snapshot of the machine and the SD job that the screens
//! show and the state machine decides on, taken once per frame.

use crate::atc::Journal;
use crate::flash::FStr;
use crate::machine::{Alarm, State};
use crate::ui::sd::{Name, Phase};

/// A snapshot of what the screens show, taken once per frame.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub state: State,
    /// Work position, µm.
    pub wpos_um: [i32; 3],
    pub tool: u8,
    /// Programmed feed with override, mm/min.
    pub feed: u16,
    pub override_pct: u16,
    /// Optional stop on: M1 pauses (`$152`).
    pub opt_stop: bool,
    /// The active work system, 0 (G54) … 5 (G59).
    pub wcs: u8,
    /// Spindle speed, rpm (0 = off).
    pub rpm: u16,
    /// The programmed speed (the S word in force), rpm, and the spindle
    /// override, percent.
    pub speed: u16,
    pub spindle_pct: u8,
    pub job: Phase,
    pub job_pct: u8,
    /// Seconds since the job started (while it runs).
    pub job_s: u16,
    /// Why a job stopped on a bad line (the refusal's message).
    pub job_why: Option<FStr>,
    pub job_name: Name,
    pub card_in: bool,
    /// Entries in the card's current folder (after the last listing).
    pub files: u8,
    /// The list shows a folder below the root ("< Back" goes up).
    pub in_folder: bool,
    /// Bit r: file row r on screen (entry `visible_files().0 + r`) is a folder.
    pub folder_rows: u8,
    pub free_ram: u16,
    /// A tool change that did not finish and awaits M61 (`Atc::interrupted`).
    pub interrupted: Option<Journal>,
    /// The alarm in force, and for a hard limit the switches that were
    /// closed (bit i = axis i, `Machine::limit_axes`).
    pub alarm: Option<Alarm>,
    pub limit_axes: u8,
    /// X, Y and Z are homed.
    pub homed: bool,
}

impl View {
    pub const fn new() -> View {
        View {
            state: State::Idle,
            wpos_um: [0; 3],
            tool: 0,
            feed: 0,
            override_pct: 100,
            opt_stop: false,
            wcs: 0,
            rpm: 0,
            speed: 0,
            spindle_pct: 100,
            job: Phase::Idle,
            job_pct: 0,
            job_s: 0,
            job_why: None,
            job_name: Name::EMPTY,
            card_in: false,
            files: 0,
            in_folder: false,
            folder_rows: 0,
            free_ram: 0,
            interrupted: None,
            alarm: None,
            limit_axes: 0,
            homed: true,
        }
    }

    /// An SD job runs, is paused, or is ending.
    pub(super) fn job_active(&self) -> bool {
        matches!(self.job, Phase::Running | Phase::Paused | Phase::Draining(_) | Phase::Aborting(_) | Phase::Scanning(_))
    }

    /// A Tools command may start: no job, and the machine idle (or in alarm,
    /// where the machine itself answers with the alarm).
    pub(super) fn may_run_tool(&self) -> bool {
        !self.job_active() && matches!(self.state, State::Idle | State::Alarm)
    }
}

impl Default for View {
    fn default() -> Self {
        View::new()
    }
}

/// Paused: the SD job, or (no job) the machine held; Pause/Resume resumes.
pub(super) fn paused(v: &View) -> bool {
    v.job == Phase::Paused || (!v.job_active() && v.state == State::Hold)
}
