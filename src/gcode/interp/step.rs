//! The step API ([`Interp::begin_line`], [`Interp::next`]): a line's
//! actions handed out one per call in RS274/NGC order (tool, spindle,
//! coolant, dwell, motion, other M codes, stop), the first call validating
//! and committing the whole line.

use super::arc_line::next_chord;
use super::checks::{early, move_only, unused_word, ALWAYS_USED};
use super::command::Command;
use super::comp_line;
use super::error::Error;
use super::line_run::{cycle_target, Phase, Progress};
use super::modal::{modal_words, ModalCopy};
use super::non_modal::dwell;
use super::tool_words::is_tool_change;
use super::{Ctx, Interp};
use crate::gcode::cycles;
use crate::gcode::{Coolant, Line, NonModal, Stopping};
use crate::N_AXES;

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

    /// The move to [`Interp::target`] was queued: it is the commanded position.
    pub fn target_reached(&mut self) {
        crate::math::copy16(&mut self.pos_mm, &self.run.target);
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
    // flash: `next` is inlined at its callers; this one inlined too (into
    // the main loop, with `cycle_step`) measured +326 B.
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
    // stack: the line step's first frame; its helpers inlined cost flash, stack and cycles (doc above)
    #[inline(never)]
    fn start(&mut self, cx: &Ctx, l: &Line) -> Result<Option<Command>, Error> {
        let move_only = move_only(cx, l);
        if let Some(done) = early(cx, l, move_only, &mut self.run.extras) {
            return done;
        }
        // Work on a copy of the modal state; commit only when the line is valid.
        let mut g = ModalCopy::from(self);
        modal_words(cx, l, &mut g)?;
        // A line that is only a move has neither a word outside
        // ALWAYS_USED nor a non-modal code (asserted in `checks`): no test
        // of either (profile --trace 20 123 → 20 079 cycles a line).
        if !move_only {
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
        }
        self.motion_line(cx, &g, l)
    }

    /// The cycle's next move or dwell, `None` when it is done.
    // flash: +522 B inlined into `resume` (measured).
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
