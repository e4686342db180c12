//! Work coordinates: the offsets between machine and work coordinates (the
//! work offsets G54–G59, G92, the tool length offset on Z), G10 L2/L20
//! (and G10 L1, the tool table entry the same code sets), and the
//! conversions both ways.

use super::command::Command;
use super::error::{grbl, Error};
use super::line_run::Phase;
use super::modal::ModalCopy;
use super::tool_words::{tool_pocket, whole_in};
use super::units::{add_nz, to_mm, word_mm};
use super::{Ctx, Interp, AXIS_WORDS};
use crate::config::N_WCS;
use crate::frame;
use crate::gcode::{Line, Word};
use crate::math::round_i32;
use crate::N_AXES;

impl Interp {
    /// Sum of the offsets between machine and work coordinates, per axis.
    pub(super) fn offset(&self, axis: usize) -> f32 {
        let tlo = if axis == 2 { self.tlo_mm } else { 0.0 };
        self.wcs_mm[self.wcs as usize][axis] + self.g92_mm[axis] + tlo
    }

    /// Machine mm → work mm (X, Y, Z; E unchanged), both internal.
    pub fn machine_to_work(&self, m: [f32; N_AXES]) -> [f32; N_AXES] {
        let mut w = m;
        for a in 0..3 {
            w[a] = m[a] - self.offset(a);
        }
        w
    }

    /// Internal machine mm → the user's work coordinates (+Z up), for
    /// reports (M114, `?`, `[PRB:…]`, the OLED).
    pub fn work_user(&self, m: [f32; N_AXES]) -> [f32; N_AXES] {
        frame::user_from_internal(self.machine_to_work(m))
    }

    /// G10 L1 / L2 / L20.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn set_offsets(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line) -> Result<Option<Command>, Error> {
        let lv = l.word(Word::L).ok_or(Error::BadWord(F!("G10 needs L1, L2 or L20")))?;
        let p = l.word(Word::P).ok_or(Error::BadWord(F!("G10 needs P")))?;
        let conv = |v: f32| to_mm(g.inches, v);
        match round_i32(lv) {
            1 if lv == 1.0 => {
                if let Some(q) = l.word(Word::Q) {
                    // `G10 L1 P<tool> Q<pocket>`: the tool table's numbering.
                    let (tool, pocket) = (whole_in(p, 1, 254), whole_in(q, 0, crate::atc::N_POCKETS as i32));
                    let (Some(tool), Some(pocket)) = (tool, pocket) else {
                        return Err(Error::BadWord(F!("G10 L1 P<tool 1-254> Q<pocket 1-12, 0 takes the tool out>")));
                    };
                    return Ok(Some(Command::AssignTool { tool, pocket }));
                }
                let t = tool_pocket(cx, p).ok_or(Error::BadWord(F!("G10 L1: P must be a tool of the tool table")))?;
                if t == 0 {
                    return Err(Error::BadWord(F!("G10 L1: P must be a tool of the tool table, not 0")));
                }
                let r = l.word(Word::R);
                if r.is_some_and(|r| r < 0.0) {
                    return Err(Error::BadWord(F!("G10 L1: R must not be negative")));
                }
                g.commit(self);
                // The line leaves the modal tool length offset in force, even
                // when the entry is the spindle tool's (as it always did: the
                // table entry applies at the next change, M61 or G43).
                self.run.tlo_mm = g.tlo;
                self.run.phase = Phase::Tlo;
                Ok(Some(Command::SetTool { tool: t as u8, length_mm: l.word(Word::Z).map(conv), radius_mm: r.map(conv) }))
            }
            n @ (2 | 20) if lv == n as f32 => {
                let idx = round_i32(p);
                if idx as f32 != p || !(0..=N_WCS as i32).contains(&idx) {
                    return Err(Error::Coded(grbl::BAD_WCS, F!("G10 L2/L20: P must be 0-6")));
                }
                let w = if idx == 0 { g.wcs as usize } else { (idx - 1) as usize };
                let mut off = self.wcs_mm[w];
                for (a, &aw) in AXIS_WORDS.iter().enumerate() {
                    if let Some(v) = l.word(aw) {
                        let v = word_mm(g.inches, a, v);
                        off[a] = if n == 2 {
                            v
                        } else {
                            let tlo = if a == 2 { g.tlo } else { 0.0 };
                            self.pos_mm[a] - self.g92_mm[a] - tlo - v
                        };
                    }
                }
                self.wcs_mm[w] = off;
                g.commit(self);
                // Work offsets are persistent (docs/SPEC.md §5): stored now; the
                // EEPROM layer programs only the bytes that changed.
                Ok(Some(Command::StoreOffsets))
            }
            _ => Err(Error::BadWord(F!("G10: L must be 1, 2 or 20"))),
        }
    }
}

/// Absolute work coordinate `v` (mm) of axis `a` → machine mm, with the
/// line's modal offsets (axis words under G90, I/J/K under G90.1).
pub(super) fn work_to_machine(i: &Interp, g: &ModalCopy, a: usize, v: f32) -> f32 {
    let tlo = if a == 2 { g.tlo } else { 0.0 };
    add_nz(add_nz(add_nz(v, i.wcs_mm[g.wcs as usize][a]), i.g92_mm[a]), tlo)
}

/// [`work_to_machine`] for an axis word of a move, inlined with `a` a
/// constant: an axis without offsets (the work offset, G92 and, on Z, the
/// tool length all +0.0, as in most jobs) is `v` after one test of the
/// offsets' bit patterns, instead of a call and three `add_nz` calls (~240
/// cycles on the AVR). The reference, plain float additions:
/// `work_to_machine_fast_matches_the_plain_sum`.
// speed: inlined per axis at a streamed move's axis words (see above)
#[inline(always)]
pub(super) fn work_to_machine_fast(i: &Interp, g: &ModalCopy, a: usize, v: f32) -> f32 {
    let tlo = if a == 2 { g.tlo.to_bits() } else { 0 };
    if i.wcs_mm[g.wcs as usize][a].to_bits() | i.g92_mm[a].to_bits() | tlo == 0 {
        v
    } else {
        work_to_machine(i, g, a, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_to_machine_fast_matches_the_plain_sum() {
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        let mut next = move || rng.next();
        // Offsets: mostly none (the fast path), some −0.0, some real ones.
        let off = |n: u32| match n % 4 {
            0 | 1 => 0.0,
            2 => -0.0,
            _ => (n >> 2) as f32 * 0.0137 - 137.0,
        };
        let mut i = Interp::new();
        let mut fast = 0;
        for _ in 0..200_000 {
            let (r, q) = (next(), next());
            i.wcs = (r % N_WCS as u32) as u8;
            for a in 0..3 {
                i.wcs_mm[i.wcs as usize][a] = off((r >> (4 + 8 * a)) & 0xFF);
                i.g92_mm[a] = off((q >> (8 * a)) & 0xFF);
            }
            i.tlo_mm = off(q >> 24);
            let g = ModalCopy::from(&i);
            // A word's value in mm (never −0.0: the parser and the Z flip give +0.0).
            let v = (next() % 400_000) as f32 * 0.001 - 200.0;
            for a in 0..3 {
                let tlo = if a == 2 { i.tlo_mm } else { 0.0 };
                let plain = v + i.wcs_mm[i.wcs as usize][a] + i.g92_mm[a] + tlo;
                let f = work_to_machine_fast(&i, &g, a, v);
                assert_eq!(f.to_bits(), plain.to_bits(), "axis {a}: {v} + {:?}", (i.wcs_mm[i.wcs as usize][a], i.g92_mm[a], tlo));
                fast += (f.to_bits() == v.to_bits()) as u32;
            }
        }
        assert!(fast > 100_000, "{fast}");
    }
}
