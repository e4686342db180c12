//! grbl 1.1 jogging (`$J=<words>`): a jog line's target and feed, worked
//! out against the modal state without changing it.

use super::error::{grbl, Error};
use super::units::{to_mm, word_mm};
use super::Interp;
use crate::gcode::{Distance, Line, NonModal, Units, Word};
use crate::N_AXES;

impl Interp {
    /// `$J=<words>` (grbl 1.1 jogging): the target (internal machine mm)
    /// and the feed (mm/min) of a jog line. As grbl: X, Y, Z and a required
    /// F, with G20/G21, G90/G91 and G53 for this line alone (the modal
    /// state does not change); any other word or code is refused. The
    /// caller checks the soft limits.
    pub fn jog_target(&self, l: &Line) -> Result<([f32; N_AXES], f32), Error> {
        let codes = l.motion.is_some()
            || l.plane.is_some()
            || l.feed_mode.is_some()
            || l.wcs.is_some()
            || l.tool_length.is_some()
            || l.retract.is_some()
            || !matches!(l.non_modal, None | Some(NonModal::MachineCoords))
            || l.stopping.is_some()
            || l.tool_change
            || l.spindle.is_some()
            || l.coolant.is_some()
            || l.path_mode.is_some()
            || l.arc_absolute.is_some()
            || l.cutter_comp.is_some()
            || l.other_m.is_some();
        let words = Word::ALL.iter().any(|&w| !matches!(w, Word::X | Word::Y | Word::Z | Word::F | Word::N) && l.words.contains(w));
        if codes || words {
            return Err(Error::Coded(grbl::BAD_JOG, F!("$J= takes X Y Z F and G20 G21 G90 G91 G53 only")));
        }
        let inches = l.units.map_or(self.inches, |u| u == Units::Inch);
        let incremental = l.distance.map_or(self.incremental, |d| d == Distance::Incremental);
        let machine = l.non_modal == Some(NonModal::MachineCoords);
        let feed = match l.word(Word::F) {
            Some(f) if f > 0.0 => to_mm(inches, f),
            _ => return Err(Error::BadFeed),
        };
        let mut t = self.pos_mm;
        for (a, w) in [Word::X, Word::Y, Word::Z].into_iter().enumerate() {
            if let Some(v) = l.word(w) {
                let v = word_mm(inches, a, v);
                t[a] = if incremental {
                    self.pos_mm[a] + v
                } else if machine {
                    v
                } else {
                    v + self.offset(a)
                };
            }
        }
        Ok((t, feed))
    }
}
