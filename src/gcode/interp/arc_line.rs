//! G2/G3 lines: the arc's centre from R or I/J/K, its chord plan worked out
//! and checked against the travel before the line commits, and the chord
//! plan's calls kept in frames of their own.

use super::command::Command;
use super::error::{grbl, Error};
use super::limits::keep_out_box;
use super::line_run::Progress;
use super::modal::ModalCopy;
use super::offsets::work_to_machine;
use super::units::{to_mm, to_steps, word_mm};
use super::{Ctx, Interp};
use crate::frame;
use crate::gcode::{Line, Motion, Plane, Word};
use crate::planner::arc;
use crate::N_AXES;

impl Interp {
    /// Arcs: compute the chord plan before committing anything, then commit
    /// the line with it.
    // flash: the arc helpers inlined cost +1 760 B for no speed-up (Interp::start's doc)
    #[inline(never)]
    pub(super) fn arc_line(
        &mut self,
        cx: &Ctx,
        g: &ModalCopy,
        l: &Line,
        target: &[f32; N_AXES],
        mo: Motion,
    ) -> Result<Option<Command>, Error> {
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
        let (lo, hi) = plan.bounds();
        self.check_arc_limits(cx, &lo, &hi)?;
        self.run.target = target;
        self.commit_line(g, Some(mo));
        self.run.progress = Progress::Arc(plan, end);
        Ok(None)
    }

    /// Every chord end of an arc stays inside its bounding box (`lo`,
    /// `hi`: [`arc::Arc::bounds`]); check the box.
    // flash: the arc helpers inlined cost +1 760 B for no speed-up (Interp::start's doc)
    #[inline(never)]
    pub(super) fn check_arc_limits(&mut self, cx: &Ctx, lo: &[f32; 3], hi: &[f32; 3]) -> Result<(), Error> {
        let mut lo4 = self.pos_mm;
        let mut hi4 = self.pos_mm;
        lo4[..3].copy_from_slice(lo);
        hi4[..3].copy_from_slice(hi);
        self.check_soft_limits(cx.settings, &lo4)?;
        self.check_soft_limits(cx.settings, &hi4)?;
        keep_out_box(cx.settings, &self.pos_mm, &lo4, &hi4)
    }
}

/// The next chord end of `plan`, in a frame of its own (see [`new_arc`]).
// stack: `Arc::next`'s f32 temporaries in a frame of their own (as new_arc)
#[inline(never)]
pub(super) fn next_chord(plan: &mut arc::Arc) -> Option<[f32; 3]> {
    plan.next()
}

/// [`arc::Arc::new`] in a frame of its own (its many f32 temporaries
/// would otherwise push [`Interp::arc_line`]'s locals out of `ldd` reach).
// stack: its f32 temporaries would push arc_line's locals out of ldd reach
#[inline(never)]
pub(super) fn new_arc(
    start: [f32; 3],
    end: [f32; 3],
    spec: arc::Centre,
    axes: (usize, usize, usize),
    clockwise: bool,
    tolerance_mm: f32,
) -> Result<arc::Arc, Error> {
    arc::Arc::new(start, end, spec, axes, clockwise, tolerance_mm).map_err(Error::Arc)
}

impl Interp {
    /// The centre of an arc line from `start` (R, or I/J/K as offsets or,
    /// under G90.1, work coordinates).
    pub(super) fn arc_spec(&self, g: &ModalCopy, l: &Line, start: [f32; 3]) -> Result<arc::Centre, Error> {
        let (a0, a1) = match g.plane {
            Plane::Xy => (0, 1),
            Plane::Zx => (2, 0),
            Plane::Yz => (1, 2),
        };
        let off_words = [Word::I, Word::J, Word::K];
        let r = l.word(Word::R).map(|r| to_mm(g.inches, r));
        let mut centre_off = [0.0f32; 3];
        let mut any_off = false;
        for (a, &w) in off_words.iter().enumerate() {
            if let Some(v) = l.word(w) {
                let v = word_mm(g.inches, a, v);
                // G90.1: the word is the centre's work coordinate.
                centre_off[a] = if g.arc_absolute { work_to_machine(self, g, a, v) - start[a] } else { v };
                any_off = true;
            }
        }
        if g.arc_absolute && any_off && (l.word(off_words[a0]).is_none() || l.word(off_words[a1]).is_none()) {
            return Err(Error::BadWord(F!("arc under G90.1: give both centre coordinates of the plane")));
        }
        match (r, any_off) {
            (Some(r), false) => Ok(arc::Centre::Radius(r)),
            (None, true) => Ok(arc::Centre::Offset(centre_off)),
            (Some(_), true) => Err(Error::BadWord(F!("arc: give R or I/J/K, not both"))),
            (None, false) => Err(Error::Coded(grbl::ARC_NO_OFFSET, F!("arc needs R or I/J/K"))),
        }
    }
}
