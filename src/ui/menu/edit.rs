//! The value editor's subject: what an edit screen changes ([`Edit`]), the
//! value as it is, the range the encoder turns it through, and the line
//! that stores it. (The editor's screen is [`Screen::Edit`], its turns and
//! presses `nav`'s, its rows `draw`'s.)
//!
//! [`Screen::Edit`]: super::Screen::Edit

use crate::dollar;
use crate::machine::Machine;
use crate::ui::render::Line;
use crate::ui::text::Text;

/// What an edit screen changes.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Edit {
    /// Setting `$n`, stored by running the line `$n=<value>`.
    Setting(u8),
    /// The tool number kept in pocket p (1..=12; 0 = none), stored by
    /// running `G10 L1 P<tool> Q<p>` (after `G10 L1 P<old> Q0`).
    Pocket(u8),
    /// Run from line: the line of file i of the list to start at, stored by
    /// starting the job there (the firmware proposes the line, `ui::resume`).
    FromLine(u8),
    /// The tool setter's reference tool: its length (stored in the setter
    /// record), then its diameter, whose Save runs the calibration
    /// [`calibrate_line`].
    RefLength,
    RefDia,
}

/// Entries of the edit screen: < Back, Value, Step, Save.
pub(super) const EDIT_ENTRIES: u8 = 4;
/// The edit screen's first entry row (rows 1..3 say what is edited).
pub(super) const EDIT_ROW: usize = 4;

impl Edit {
    /// The value as it is now, in thousandths.
    pub fn current(self, m: &Machine) -> i32 {
        match self {
            Edit::Setting(n) => dollar::value(&m.settings, n).map_or(0, |(v, _)| v.micros()),
            Edit::Pocket(p) => m.atc.table.number_of(p) as i32 * 1000,
            Edit::FromLine(_) => 1000,
            Edit::RefLength => m.setter.ref_length_um,
            Edit::RefDia => m.setter.ref_diameter_um,
        }
    }

    /// A whole number (a flag, a mask, a tool number)?
    pub(super) fn integer(self, m: &Machine) -> bool {
        match self {
            Edit::Setting(n) => !matches!(dollar::value(&m.settings, n), Some((dollar::Value::Num(_), _))),
            Edit::Pocket(_) | Edit::FromLine(_) => true,
            Edit::RefLength | Edit::RefDia => false,
        }
    }

    /// The range the encoder may turn the value through, thousandths
    /// (the machine checks the value itself when it is stored).
    pub(super) fn range(self, m: &Machine) -> (i32, i32) {
        match self {
            Edit::Setting(n) => match dollar::value(&m.settings, n) {
                Some((dollar::Value::Flag(_), _)) => (0, 1000),
                Some((dollar::Value::Mask(_, max), _)) => (0, max as i32 * 1000),
                _ => (-99_999_999, 99_999_999),
            },
            Edit::Pocket(_) => (0, 254_000),
            Edit::FromLine(_) => (1000, 2_000_000_000),
            Edit::RefLength => (0, 300_000),
            Edit::RefDia => (0, 50_000),
        }
    }

    /// The line that stores `um`: `$n=<value>`, or for a pocket
    /// `G10 L1 P<tool> Q<pocket>` (`Q0` with `P` = the pocket's old
    /// number when `clear`, to free the pocket first). Written into `l`
    /// from column 0; returns its length.
    pub fn gcode(self, um: i32, clear: Option<u8>, l: &mut Line) -> usize {
        match self {
            Edit::Setting(n) => {
                let c = l.put(0, b"$");
                let c = l.uint(c, n as u32);
                let c = l.put(c, b"=");
                l.micros(c, um)
            }
            Edit::Pocket(p) => {
                let c = l.text(0, Text::LineG10L1P);
                let (t, q) = match clear {
                    Some(old) => (old, 0),
                    None => ((um / 1000) as u32 as u8, p),
                };
                let c = l.uint(c, t as u32);
                let c = l.put(c, b" Q");
                l.uint(c, q as u32)
            }
            Edit::FromLine(_) => 0,
            // Stored in the setter record, not by a line.
            Edit::RefLength | Edit::RefDia => 0,
        }
    }
}

/// The calibration line of a reference tool `length_um` long and
/// `diameter_um` thick: `G37 L<length> R<radius>`, the radius to the
/// micrometre below (G37 keeps the diameter as twice the radius). Written
/// into `l` from column 0; returns its length.
pub fn calibrate_line(length_um: i32, diameter_um: i32, l: &mut Line) -> usize {
    let c = l.text(0, Text::LineG37L);
    let c = l.micros(c, length_um);
    let c = l.text(c, Text::LineR);
    l.micros(c, diameter_um / 2)
}

/// 10^k: the edit step k in thousandths.
pub(super) fn pow10(k: u8) -> i32 {
    let mut p = 1;
    for _ in 0..k {
        p *= 10;
    }
    p
}
