//! The modal state a line may change ([`ModalCopy`]), worked on as a copy
//! and committed only when the whole line is valid, and the line's modal
//! words read into it (units, distance, plane, offsets, motion, feed, G43).

use super::error::Error;
use super::tool_words::tool_pocket;
use super::units::to_mm;
use super::{Ctx, Interp};
use crate::gcode::cycles::Retract;
use crate::gcode::{Distance, Line, Motion, Plane, ToolLength, Units, Word};

/// The modal fields a line may change, copied so an invalid line changes
/// nothing. The G92 offset is not among them: only a G92 line sets it, and
/// that line moves nothing, so it is read from the [`Interp`] itself (a
/// copy was a 12-byte `memcpy` call on every line).
pub(super) struct ModalCopy {
    pub(super) inches: bool,
    pub(super) incremental: bool,
    pub(super) plane: Plane,
    pub(super) arc_absolute: bool,
    pub(super) motion: Motion,
    pub(super) before_cycle: Motion,
    pub(super) retract: Retract,
    pub(super) feed: f32,
    pub(super) wcs: u8,
    pub(super) tlo: f32,
}

impl ModalCopy {
    pub(super) fn from(i: &Interp) -> ModalCopy {
        ModalCopy {
            inches: i.inches,
            incremental: i.incremental,
            plane: i.plane,
            arc_absolute: i.arc_absolute,
            motion: i.motion,
            before_cycle: i.motion_before_cycle,
            retract: i.retract,
            feed: i.feed_mm_per_min,
            wcs: i.wcs,
            tlo: i.tlo_mm,
        }
    }

    pub(super) fn commit(&self, i: &mut Interp) {
        i.inches = self.inches;
        i.incremental = self.incremental;
        i.plane = self.plane;
        i.arc_absolute = self.arc_absolute;
        i.motion = self.motion;
        i.motion_before_cycle = self.before_cycle;
        i.retract = self.retract;
        i.feed_mm_per_min = self.feed;
        i.wcs = self.wcs;
        i.tlo_mm = self.tlo;
    }
}

/// The line's modal words into the copy `g` (nothing is committed yet).
// speed: inlined into its one caller, Interp::start, a streamed line spares
// the call and a 12-register save (profile --trace 20 289 → 20 211 cycles a line)
#[inline(always)]
pub(super) fn modal_words(cx: &Ctx, l: &Line, g: &mut ModalCopy) -> Result<(), Error> {
    if let Some(u) = l.units {
        g.inches = u == Units::Inch;
    }
    if let Some(d) = l.distance {
        g.incremental = d == Distance::Incremental;
    }
    if let Some(p) = l.plane {
        g.plane = p;
    }
    if let Some(a) = l.arc_absolute {
        g.arc_absolute = a;
    }
    if let Some(w) = l.wcs {
        g.wcs = w;
    }
    if let Some(f) = l.word(Word::F) {
        g.feed = to_mm(g.inches, f);
    }
    if let Some(mo) = l.motion {
        g.motion = match mo {
            Motion::Cycle(_) if !matches!(g.motion, Motion::Cycle(_)) => {
                g.before_cycle = g.motion;
                mo
            }
            // `$154=1`: G80 cancels the cycle only (Fanuc's group 9): the
            // motion mode before it stays, so `G80` then `Z-4` moves.
            Motion::Cancel if cx.settings.g80_keeps_motion => match g.motion {
                Motion::Cycle(_) => g.before_cycle,
                other => other,
            },
            _ => mo,
        };
    }
    if let Some(r) = l.retract {
        g.retract = r;
    }
    if let Some(tl) = l.tool_length {
        g.tlo = match tl {
            ToolLength::Cancel => 0.0,
            ToolLength::Apply => {
                let t = match l.word(Word::H) {
                    Some(h) => tool_pocket(cx, h).ok_or(Error::BadWord(F!("H: no such tool in the tool table")))?,
                    None => cx.atc.spindle() as usize,
                };
                crate::atc::tool_length_offset_mm(cx.atc.length_mm(t as u8))
            }
        };
    }
    Ok(())
}
