//! The motion part of a line: its target (G90/G91, G53, polar words, E),
//! the checks every move gets (feed, soft limits, keep-out zone), then the
//! move itself or, through their own modules, an arc, a canned cycle or
//! compensation.

use super::command::Command;
use super::comp_line::{self, CompOutcome};
use super::error::Error;
use super::limits::{keep_out, soft_limits};
use super::line_run::Phase;
use super::modal::ModalCopy;
use super::offsets::{work_to_machine, work_to_machine_fast};
use super::units::word_mm;
use super::{axis_words_are_settings, has_axis_words, Ctx, Interp};
use crate::gcode::{Line, Motion, NonModal, Word};
use crate::math::float_bits::positive;

impl Interp {
    /// The motion part of a line: target, checks, then (through
    /// [`Interp::arc_line`] for arcs, [`Interp::cycle_line`] for cycles)
    /// [`Interp::commit_line`].
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn motion_line(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line) -> Result<Option<Command>, Error> {
        let machine_coords = l.non_modal == Some(NonModal::MachineCoords);
        // The target is worked out in place (`run.target` means nothing
        // until the line commits): no copy on the way to the move. An axis
        // the line does not name stays where it is (under compensation X, Y
        // and Z at the programmed position, not the tool's), each set by
        // `axis_target` (an array copy first was a 16-byte `memcpy` call).
        self.run.target[3] = self.pos_mm[3];
        let any_axis = has_axis_words(l) && !axis_words_are_settings(l);
        // One call per axis with the axis a constant: each word's presence
        // is a bit test, its Z flip and offsets fold (a loop over the axes
        // made them calls, ~700 cycles a streamed XY line on the AVR).
        self.axis_target(g, l, machine_coords, 0, Word::X);
        self.axis_target(g, l, machine_coords, 1, Word::Y);
        self.axis_target(g, l, machine_coords, 2, Word::Z);
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
        // Without compensation, on or turned on by this line, there is
        // nothing for `comp_line` to do (its test, made here, spares a call
        // and the copy of its result).
        let mode = if self.comp.side.is_none() && !comp_line::turns_on(l) {
            None
        } else {
            match self.comp_line(cx, g, l, motion, any_axis, e_word.is_some())? {
                CompOutcome::Done(r) => return r,
                CompOutcome::Ordinary(mode) => mode,
            }
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
                    if !positive(g.feed) {
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

    /// The target of axis `a` (word `w`) in `run.target`, if the line names
    /// it: G53 machine coordinates, G91 increments, or G90 work coordinates.
    // speed: inlined with `a` and `w` constants (see motion_line)
    #[inline(always)]
    fn axis_target(&mut self, g: &ModalCopy, l: &Line, machine_coords: bool, a: usize, w: Word) {
        self.run.target[a] = match l.word(w) {
            Some(v) => {
                let v = word_mm(g.inches, a, v);
                if machine_coords {
                    v
                } else if g.incremental {
                    self.prog_pos(a) + v
                } else {
                    work_to_machine_fast(self, g, a, v)
                }
            }
            // `prog_pos` is `pos_mm` without compensation: no call then.
            None if self.comp.side.is_some() => self.prog_pos(a),
            None => self.pos_mm[a],
        };
    }
}
