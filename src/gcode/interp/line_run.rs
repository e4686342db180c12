//! The line in progress ([`LineRun`]): where [`Interp::next`] is within it
//! ([`Phase`]), the target of the move handed out last, and an arc's or a
//! canned cycle's state between its moves ([`Progress`]); committing a
//! line and its motion command.

use super::command::Command;
use super::modal::ModalCopy;
use super::units::add_nz;
use super::Interp;
use crate::frame;
use crate::gcode::cycles;
use crate::gcode::Motion;
use crate::planner::arc;
use crate::N_AXES;

/// Where [`Interp::next`] is within the current line.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Phase {
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
pub(super) enum Progress {
    None,
    Arc(arc::Arc, [f32; 3]),
    Cycle(CycleRun),
}

/// The line in progress (see [`Interp::next`]).
pub(super) struct LineRun {
    pub(super) phase: Phase,
    /// The target of the move handed out last (the line's end point, a
    /// chord's, a cycle step's), internal machine mm.
    pub(super) target: [f32; N_AXES],
    /// The motion to run, if the line moves.
    pub(super) motion: Option<Motion>,
    /// `Phase::Tlo`: the tool length offset to put back.
    pub(super) tlo_mm: f32,
    /// The line has a T word, M6, S, M3/M5 or M7–M9 (set by [`early`]).
    pub(super) extras: bool,
    pub(super) progress: Progress,
    /// The phase after `Chords` or `CompFlush`.
    pub(super) then: Phase,
    /// The feed of the chords or held move being handed out, mm/min with
    /// the override, and whether they are rapids.
    pub(super) chord_feed: f32,
    pub(super) chord_rapid: bool,
}

impl LineRun {
    pub(super) const fn new() -> LineRun {
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

/// A canned cycle resolved and checked, ready to run once the line commits.
pub(super) struct CycleRun {
    pub(super) cycle: cycles::Cycle,
    /// The sticky words to keep after this line.
    pub(super) sticky: cycles::Sticky,
    /// Machine − work offset per axis (work offset, G92, tool length),
    /// internal frame.
    pub(super) off: [f32; 3],
}

/// A cycle's point `t` (user frame, work coordinates; NaN: the axis stays)
/// → internal machine mm, the other axes at `pos` (where the tool is).
pub(super) fn cycle_target(pos: [f32; N_AXES], run: &CycleRun, t: [f32; 3]) -> [f32; N_AXES] {
    let mut target = pos;
    for a in 0..3 {
        if !t[a].is_nan() {
            target[a] = add_nz(frame::axis_internal_from_user(a, t[a]), run.off[a]);
        }
    }
    target
}

impl Interp {
    /// Commit the modal state and go on with the line's actions: the
    /// motion `motion` to `run.target` (an arc's or a cycle's line sets
    /// `run.progress` too). `progress` is only looked at for an arc or a
    /// cycle, whose lines set it.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn commit_line(&mut self, g: &ModalCopy, motion: Option<Motion>) {
        g.commit(self);
        self.run.motion = motion;
        self.run.phase = Phase::Tool;
    }

    /// The line's motion: one move, a probe, or the start of an arc's
    /// chords or a cycle's steps.
    // speed: a streamed G1 line ends here (a call cost ping-pong lines/s)
    #[inline(always)]
    pub(super) fn motion(&mut self) -> Option<Command> {
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
}
