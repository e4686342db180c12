//! LinuxCNC's polar coordinates (`@` radius, `^` angle): what is refused
//! with them, and the point they name.

use super::error::Error;
use super::modal::ModalCopy;
use super::units::{deg_to_rad, to_mm};
use super::Interp;
use crate::gcode::{Line, Plane, Word};

impl Interp {
    /// What LinuxCNC refuses of polar words: with X or Y, outside G17, with
    /// G53.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn polar_checks(&self, g: &ModalCopy, l: &Line, machine_coords: bool) -> Result<(), Error> {
        if l.words.contains(Word::X) || l.words.contains(Word::Y) {
            return Err(Error::BadWord(F!("polar coordinates (@ ^) with X or Y on one line")));
        }
        if g.plane != Plane::Xy {
            return Err(Error::BadWord(F!("polar coordinates (@ ^) only in the XY plane (G17)")));
        }
        if machine_coords {
            return Err(Error::BadWord(F!("polar coordinates (@ ^) not with G53")));
        }
        Ok(())
    }

    /// The X, Y (work coordinates, mm) of a line's polar words `@` radius
    /// and `^` angle (degrees, counter-clockwise from +X) about the work
    /// origin, as LinuxCNC reads them: under G90 a missing one is the
    /// current position's; under G91 both are added to the current
    /// position's radius and angle (indeterminate at the origin).
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn polar_point(&self, g: &ModalCopy, l: &Line) -> Result<[f32; 2], Error> {
        let at = l.word(Word::At).map(|v| to_mm(g.inches, v));
        let angle = l.word(Word::Caret).map(deg_to_rad);
        let cur = [
            self.pos_mm[0] - self.wcs_mm[g.wcs as usize][0] - self.g92_mm[0],
            self.pos_mm[1] - self.wcs_mm[g.wcs as usize][1] - self.g92_mm[1],
        ];
        let at_origin = cur[0] == 0.0 && cur[1] == 0.0;
        let r0 = crate::math::sqrtf(cur[0] * cur[0] + cur[1] * cur[1]);
        let a0 = crate::math::atan2f(cur[1], cur[0]);
        let (r, a) = if g.incremental {
            if at_origin {
                return Err(Error::BadWord(F!("G91 polar move from the origin is indeterminate, nothing moved")));
            }
            (r0 + at.unwrap_or(0.0), a0 + angle.unwrap_or(0.0))
        } else {
            if angle.is_none() && at_origin {
                return Err(Error::BadWord(F!("polar move from the origin needs ^ (the angle), nothing moved")));
            }
            (at.unwrap_or(r0), angle.unwrap_or(a0))
        };
        let (sin, cos) = crate::math::sincosf(a);
        Ok([r * cos, r * sin])
    }
}
