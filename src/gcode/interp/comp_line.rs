//! The interpreter's side of cutter radius compensation: which lines it
//! takes, what it refuses, and how a held move, an outside corner's arc and
//! the line's own actions are handed out one per call. The geometry is in
//! [`super::super::comp`].

use super::arc_line::new_arc;
use super::command::Command;
use super::error::Error;
use super::line_run::{Phase, Progress};
use super::modal::ModalCopy;
use super::tool_words::{is_tool_change, tool_pocket};
use super::units::{same_f32, to_mm, to_steps};
use super::{Ctx, Interp};
use crate::gcode::comp::{self, Corner, Held, Seg, Side, P2};
use crate::gcode::{CutterComp, Line, Motion, Plane, Stopping, Word};
use crate::planner::arc;

/// What [`Interp::comp_line`] leaves to the ordinary path of a line.
pub(super) enum CompOutcome {
    /// The line was handled here: return this.
    Done(Result<Option<Command>, Error>),
    /// The ordinary path runs the line; on success the compensation mode
    /// becomes this (`None`: unchanged).
    Ordinary(Option<(Option<Side>, f32)>),
}

/// True when `l` turns compensation on (G41, G42, G41.1, G42.1).
pub(super) fn turns_on(l: &Line) -> bool {
    matches!(l.cutter_comp, Some(c) if c != CutterComp::Off)
}

impl Interp {
    /// The programmed position of axis `a`: under compensation X and Y are
    /// the programmed end of the last move in the plane, and Z is the held
    /// move's until it is sent (then the tool's: Z has no offset).
    pub(super) fn prog_pos(&self, a: usize) -> f32 {
        match &self.comp.held {
            Some(h) if a < 2 && self.comp.side.is_some() => h.corner[a],
            Some(h) if a == 2 && self.comp.side.is_some() && !h.sent => h.z,
            _ => self.pos_mm[a],
        }
    }

    /// Apply a mode change the ordinary path earned (see [`CompOutcome`]).
    // correctness: an f32 argument miscompiled as a call on the AVR (the note in comp.rs)
    #[inline(always)]
    pub(super) fn comp_apply(&mut self, mode: Option<(Option<Side>, f32)>) {
        if let Some((side, radius_mm)) = mode {
            self.comp.set(side, radius_mm);
        }
    }

    /// A line while compensation is on, or turned on or off by it.
    /// `motion`: the line's motion mode; `target`: in `run.target`.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn comp_line(
        &mut self,
        cx: &Ctx,
        g: &ModalCopy,
        l: &Line,
        motion: Motion,
        any_axis: bool,
        e_word: bool,
    ) -> Result<CompOutcome, Error> {
        let on = self.comp.side.is_some();
        let turning_on = turns_on(l);
        if !on && !turning_on {
            return Ok(CompOutcome::Ordinary(None));
        }
        let is_arc =
            matches!(motion, Motion::ArcCw | Motion::ArcCcw) && (any_axis || matches!(l.motion, Some(Motion::ArcCw | Motion::ArcCcw)));
        let moves = any_axis || is_arc;
        if moves && !matches!(motion, Motion::Rapid | Motion::Linear | Motion::ArcCw | Motion::ArcCcw) {
            return Err(Error::BadWord(F!("G41/G42: only G0-G3 moves with compensation on (G40 first), nothing moved")));
        }
        if is_tool_change(cx, l) {
            return Err(Error::BadWord(F!("G41/G42: no tool change with compensation on (G40 first), nothing moved")));
        }
        if e_word {
            return Err(Error::BadWord(F!("G41/G42: no E move with compensation on (G40 first), nothing moved")));
        }
        if turning_on && on {
            return Err(Error::BadWord(F!("G41/G42: compensation is already on (G40 first), nothing moved")));
        }
        match g.plane {
            Plane::Xy => {}
            Plane::Zx => return Err(Error::BadWord(F!("G41/G42 only in the XY plane (G17); G18 (ZX) is active, nothing moved"))),
            Plane::Yz => return Err(Error::BadWord(F!("G41/G42 only in the XY plane (G17); G19 (YZ) is active, nothing moved"))),
        }
        let off = l.cutter_comp == Some(CutterComp::Off) || matches!(l.stopping, Some(Stopping::End | Stopping::EndRewind));
        if turning_on {
            let (side, radius) = comp_mode(cx, g, l)?;
            if radius > 0.0 && moves {
                // The entry move is on this line.
                self.comp.set(Some(side), radius);
                return match self.comp_move(cx, g, l, motion, is_arc) {
                    Ok(r) => Ok(CompOutcome::Done(Ok(r))),
                    Err(e) => {
                        self.comp.set(None, 0.0);
                        Err(e)
                    }
                };
            }
            return Ok(CompOutcome::Ordinary(Some((Some(side), radius))));
        }
        // On, and stays on or goes off on this line.
        if !self.comp.active() {
            // Radius 0: compensation changes nothing.
            return Ok(CompOutcome::Ordinary(if off { Some((None, 0.0)) } else { None }));
        }
        let pxy = [self.prog_pos(0), self.prog_pos(1)];
        let xy_move = !off && (is_arc || (moves && (!same_f32(self.run.target[0], pxy[0]) || !same_f32(self.run.target[1], pxy[1]))));
        if off && is_arc {
            return Err(Error::BadWord(F!("G40: the exit move must be a line (G0/G1), nothing moved")));
        }
        if !xy_move {
            let modal_only = !moves && !self.run.extras && l.other_m.is_none() && l.stopping.is_none() && !off;
            if let Some(h) = self.comp.held.filter(|h| !h.sent && !modal_only) {
                // Send the held move as it is, then run the line afresh.
                self.comp_flush(cx, &h, &h.seg.end, Phase::Restart)?;
                if let Some(held) = &mut self.comp.held {
                    held.sent = true;
                }
                return Ok(CompOutcome::Done(Ok(None)));
            }
            // A move without X or Y (Z only) stays where the tool is.
            if moves && !off {
                self.run.target[0] = self.pos_mm[0];
                self.run.target[1] = self.pos_mm[1];
            }
            return Ok(CompOutcome::Ordinary(if off { Some((None, 0.0)) } else { None }));
        }
        self.comp_move(cx, g, l, motion, is_arc).map(|r| CompOutcome::Done(Ok(r)))
    }

    /// A move in the plane under compensation: the entry move, or the
    /// corner with the held move; the new move is held back. Validated
    /// completely before anything is committed.
    fn comp_move(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line, motion: Motion, is_arc: bool) -> Result<Option<Command>, Error> {
        if motion != Motion::Rapid && !(g.feed > 0.0) {
            return Err(Error::BadFeed);
        }
        let side = self.comp.side.unwrap_or(Side::Left);
        let r = self.comp.radius_mm;
        let pstart = [self.prog_pos(0), self.prog_pos(1)];
        let mut end: P2 = [self.run.target[0], self.run.target[1]];
        let z = self.run.target[2];
        let prog = if is_arc {
            let start3 = [pstart[0], pstart[1], self.pos_mm[2]];
            let spm = cx.settings.steps_per_mm;
            if to_steps(start3[0], spm[0]) == to_steps(end[0], spm[0]) && to_steps(start3[1], spm[1]) == to_steps(end[1], spm[1]) {
                end = pstart;
            }
            let spec = self.arc_spec(g, l, start3)?;
            let cw = motion == Motion::ArcCw;
            let plan = new_arc(start3, [end[0], end[1], z], spec, (0, 1, 2), cw, cx.settings.arc_tolerance_mm)?;
            Seg { end, centre: plan.centre(), turn: if cw { -1 } else { 1 } }
        } else {
            Seg::line(end)
        };
        let bad = |e: comp::CompError| Error::BadWord(e.message());
        let tool = [self.pos_mm[0], self.pos_mm[1]];
        let mut flush: Option<(Held, P2)> = None;
        let mut corner_arc = None;
        let seg = if self.comp.entry || self.comp.held.is_none() {
            comp::entry(side, r, &tool, &prog).map_err(bad)?
        } else {
            let h = self.comp.held.unwrap_or(Held { seg: Seg::line(tool), corner: pstart, z, feed: 0.0, rapid: true, sent: true });
            let (q, seg) = comp::offset(side, r, &pstart, &prog).map_err(bad)?;
            match comp::corner(side, &h.corner, &tool, &h.seg, &q, &seg) {
                Ok(Corner::Tangent) => {}
                Ok(Corner::Outside { turn }) => corner_arc = Some((h.corner, q, turn)),
                Ok(Corner::Inside(x)) if !h.sent => flush = Some((h, x)),
                Ok(Corner::Inside(_)) => {
                    return Err(Error::BadWord(F!(
                    "G41/G42: inside corner right after a line that is not a move in the plane (it sent the move before), nothing moved"
                )))
                }
                Err(e) => return Err(bad(e)),
            }
            if flush.is_none() && !h.sent {
                flush = Some((h, h.seg.end));
            }
            seg
        };
        // Soft limits: the new move's end, the corner arc's square, the
        // flushed move (its arc's box is checked when it is built).
        let mut t = self.pos_mm;
        t[0] = seg.end[0];
        t[1] = seg.end[1];
        t[2] = z;
        self.check_soft_limits(cx.settings, &t)?;
        if let Some((p, _, _)) = corner_arc {
            for (dx, dy) in [(-r, -r), (r, r)] {
                let mut c = self.pos_mm;
                c[0] = p[0] + dx;
                c[1] = p[1] + dy;
                self.check_soft_limits(cx.settings, &c)?;
            }
        }
        if let Some((h, e)) = flush {
            self.comp_flush(cx, &h, &e, Phase::CompCorner)?;
        }
        // Valid: commit.
        self.commit_line(g, None);
        self.comp.entry = false;
        self.comp.corner_arc = corner_arc;
        self.comp.held = Some(Held { seg, corner: prog.end, z, feed: g.feed, rapid: motion == Motion::Rapid, sent: false });
        self.run.phase = if flush.is_some() { Phase::CompFlush } else { Phase::CompCorner };
        Ok(None)
    }

    /// Set up the held move `h` to run to `end` (its own end, or an inside
    /// corner's point), then phase `then`.
    // stack: a frame of its own; inlined into comp_line and comp_move, its arc and temporaries were in both frames (the deepest stack path)
    #[inline(never)]
    fn comp_flush(&mut self, cx: &Ctx, h: &Held, end: &P2, then: Phase) -> Result<(), Error> {
        let end3 = [end[0], end[1], h.z];
        self.run.chord_feed = h.feed;
        self.run.chord_rapid = h.rapid;
        self.run.then = then;
        if h.seg.turn == 0 {
            self.run.target = self.pos_mm;
            self.run.target[..3].copy_from_slice(&end3);
            let t = self.run.target;
            self.check_soft_limits(cx.settings, &t)?;
            self.run.progress = Progress::None;
        } else {
            let start = [self.pos_mm[0], self.pos_mm[1], self.pos_mm[2]];
            let mut end3 = end3;
            // As for a programmed arc: an end that rounds to the start's
            // steps is the start, a full circle (the offsets of a full
            // circle's ends come out a few µm apart in f32).
            let spm = cx.settings.steps_per_mm;
            if to_steps(start[0], spm[0]) == to_steps(end3[0], spm[0]) && to_steps(start[1], spm[1]) == to_steps(end3[1], spm[1]) {
                end3[0] = start[0];
                end3[1] = start[1];
            }
            let off = [h.seg.centre[0] - start[0], h.seg.centre[1] - start[1], 0.0];
            let plan = new_arc(start, end3, arc::Centre::Offset(off), (0, 1, 2), h.seg.turn < 0, cx.settings.arc_tolerance_mm)?;
            // The arc goes in place first, then its box is checked: one
            // copy of it in this frame, not three (the deepest stack path).
            let (lo, hi) = plan.bounds();
            self.run.progress = Progress::Arc(plan, end3);
            if let Err(e) = self.check_arc_limits(cx, &lo, &hi) {
                self.run.progress = Progress::None;
                return Err(e);
            }
        }
        self.run.phase = Phase::CompFlush;
        Ok(())
    }

    /// `Phase::CompFlush`: the held move (one move, or its chords).
    pub(super) fn comp_flush_step(&mut self) -> Option<Command> {
        if matches!(self.run.progress, Progress::Arc(..)) {
            self.run.phase = Phase::Chords;
            return None;
        }
        self.run.phase = self.run.then;
        Some(Command::Move { feed_mm_per_min: self.run.chord_feed, rapid: self.run.chord_rapid })
    }

    /// `Phase::CompCorner`: an outside corner's arc around the programmed
    /// corner, at the new move's feed.
    pub(super) fn comp_corner_step(&mut self, cx: &Ctx) -> Option<Command> {
        self.run.phase = Phase::Tool;
        let (p, q, turn) = self.comp.corner_arc.take()?;
        let rapid = self.comp.held.is_some_and(|h| h.rapid);
        let feed = self.feed_mm_per_min;
        let start = [self.pos_mm[0], self.pos_mm[1], self.pos_mm[2]];
        let end = [q[0], q[1], start[2]];
        let gap = (q[0] - start[0]) * (q[0] - start[0]) + (q[1] - start[1]) * (q[1] - start[1]);
        if gap > 1e-6 {
            let off = [p[0] - start[0], p[1] - start[1], 0.0];
            if let Ok(plan) = new_arc(start, end, arc::Centre::Offset(off), (0, 1, 2), turn < 0, cx.settings.arc_tolerance_mm) {
                self.run.progress = Progress::Arc(plan, end);
                self.run.chord_feed = feed;
                self.run.chord_rapid = rapid;
                self.run.then = Phase::Tool;
                self.run.phase = Phase::Chords;
                return None;
            }
        }
        if gap == 0.0 {
            return None;
        }
        self.run.target[..3].copy_from_slice(&end);
        Some(Command::Move { feed_mm_per_min: feed, rapid })
    }
}

/// The side and radius a G41/G42/G41.1/G42.1 line asks for: G41/G42 D<tool>
/// (the spindle tool without D) take the tool table's diameter; G41.1/G42.1
/// D<diameter> give it.
// correctness: an (f32, Side) result miscompiled as a call on the AVR (the note in comp.rs)
#[inline(always)]
fn comp_mode(cx: &Ctx, g: &ModalCopy, l: &Line) -> Result<(Side, f32), Error> {
    let (side, direct) = match l.cutter_comp {
        Some(CutterComp::Left) => (Side::Left, false),
        Some(CutterComp::Right) => (Side::Right, false),
        Some(CutterComp::LeftDiameter) => (Side::Left, true),
        _ => (Side::Right, true),
    };
    let d = l.word(Word::D);
    let diameter = if direct {
        let d = d.ok_or(Error::BadWord(F!("G41.1/G42.1 need D<diameter>")))?;
        if !(d >= 0.0) {
            return Err(Error::BadWord(F!("G41.1/G42.1: D (diameter) must not be negative")));
        }
        to_mm(g.inches, d)
    } else {
        let t = match d {
            Some(d) => tool_pocket(cx, d).ok_or(Error::BadWord(F!("G41/G42: D must be a tool of the tool table")))?,
            None => cx.atc.spindle() as usize,
        };
        match t {
            0 => 0.0,
            t => cx.atc.table.diameter_um.get(t - 1).map_or(0, |&d| d) as f32 / 1000.0,
        }
    };
    Ok((side, diameter * 0.5))
}
