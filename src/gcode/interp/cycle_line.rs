//! A line that runs a canned cycle (G73, G81–G89, or bare X/Y/Z while one
//! is modal): its words resolved against the sticky ones ([`cycles`]),
//! every point checked against the travel, then committed.

use super::command::Command;
use super::error::Error;
use super::limits::keep_out_box;
use super::line_run::{cycle_target, CycleRun, Progress};
use super::modal::ModalCopy;
use super::units::{deg_to_rad, to_mm};
use super::{Ctx, Interp};
use crate::frame;
use crate::gcode::cycles;
use crate::gcode::{Line, Motion, Plane, Word};

impl Interp {
    /// A line that runs a canned cycle (G73, G81–G89, or bare X/Y/Z while
    /// one is modal): resolve the words against the sticky ones, check every
    /// point the cycle can reach against the soft limits, then commit the
    /// line with it. A bad cycle line changes nothing and moves nothing.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn cycle_line(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line, kind: cycles::Kind) -> Result<Option<Command>, Error> {
        match g.plane {
            Plane::Xy => {}
            Plane::Zx => return Err(Error::BadWord(F!("canned cycles only in the XY plane (G17); G18 (ZX) is active, nothing moved"))),
            Plane::Yz => return Err(Error::BadWord(F!("canned cycles only in the XY plane (G17); G19 (YZ) is active, nothing moved"))),
        }
        if !(g.feed > 0.0) {
            return Err(Error::BadFeed);
        }
        let mm = |w: Word| l.word(w).map(|v| to_mm(g.inches, v));
        let mut words = cycles::LineWords {
            x: mm(Word::X),
            y: mm(Word::Y),
            z: mm(Word::Z),
            r: mm(Word::R),
            q: mm(Word::Q),
            p: l.word(Word::P),
            l: l.word(Word::L),
            polar: None,
        };
        if l.words.has_polar() {
            if g.incremental {
                // Radius and angle added per hole (LinuxCNC's CYCLE_MACRO).
                words.polar = Some([mm(Word::At).unwrap_or(0.0), deg_to_rad(l.word(Word::Caret).unwrap_or(0.0))]);
            } else {
                let p = self.polar_point(g, l)?;
                (words.x, words.y) = (Some(p[0]), Some(p[1]));
            }
        }
        let mut off = [0.0f32; 3];
        let mut pos = [0.0f32; 3];
        for a in 0..3 {
            let tlo = if a == 2 { g.tlo } else { 0.0 };
            off[a] = self.wcs_mm[g.wcs as usize][a] + self.g92_mm[a] + tlo;
            pos[a] = frame::axis_user_from_internal(a, self.pos_mm[a] - off[a]);
        }
        let prev = match self.motion {
            Motion::Cycle(k) => Some(k),
            _ => None,
        };
        let bad = |e: cycles::Error| Error::BadWord(e.message());
        let (params, sticky) = cycles::resolve(kind, g.retract, g.incremental, prev, &self.cycle, &words, pos).map_err(bad)?;
        let cycle = cycles::Cycle::new(params, pos).map_err(bad)?;
        let run = CycleRun { cycle, sticky, off };
        let (lo, hi) = run.cycle.bounds();
        let (lo4, hi4) = (cycle_target(self.pos_mm, &run, lo), cycle_target(self.pos_mm, &run, hi));
        self.check_soft_limits(cx.settings, &lo4)?;
        self.check_soft_limits(cx.settings, &hi4)?;
        keep_out_box(cx.settings, &self.pos_mm, &lo4, &hi4)?;
        self.run.target = self.pos_mm;
        self.commit_line(g, Some(g.motion));
        self.cycle = run.sticky;
        self.run.progress = Progress::Cycle(run);
        Ok(None)
    }
}
