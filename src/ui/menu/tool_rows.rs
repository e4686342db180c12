//! Rows of the Tools pages: the tool lists (change, confirm), the tool
//! table, the changer station's points and the pockets' tool numbers.

use super::screen::{point_text, STATION_POINTS};
use super::view::View;
use crate::machine::Machine;
use crate::ui::render::{Line, COLS};
use crate::ui::text::Text;

/// " T<t>" at column 1 and, when given, a note after it; returns the
/// column after the number.
pub(super) fn tool_and_note(l: &mut Line, m: &Machine, t: u8, note: Option<Text>) -> usize {
    // `t` is a pocket; the operator sees its tool's number (`T20`), or `T-`
    // for a pocket the tool table gives no number.
    let c = l.put(1, b"T");
    let n = m.atc.table.number_of(t);
    let c = if t != 0 && n == 0 { l.put(c, b"-") } else { l.uint(c, n as u32) };
    if let Some(n) = note {
        l.text(c + 1, n);
    }
    c
}

/// Entry `e` of a tool list: "< Back", then T0..T12 with what is known of
/// each (for a change: in the spindle, pocket empty; for a confirmation:
/// the old and new tool of the interrupted change).
// flash: 8 B less out of line (and 2 B less stack on the display path)
#[inline(never)]
pub(super) fn pick_line(e: u8, confirm: bool, v: &View, m: &Machine, l: &mut Line) {
    if e == 0 {
        l.text(1, Text::Back);
        return;
    }
    let t = e - 1;
    let note = if t == 0 {
        Some(Text::NoTool)
    } else if confirm {
        match v.interrupted {
            Some(j) if j.from == t => Some(Text::OldTool),
            Some(j) if j.to == t => Some(Text::NewTool),
            _ => None,
        }
    } else if t == v.tool {
        Some(Text::InSpindle)
    } else if !m.atc.tools.pocket_full(t) {
        Some(Text::PocketEmpty)
    } else {
        None
    };
    tool_and_note(l, m, t, note);
}

/// Row `t` (1..=12) of the tool table, `T3*  25.000    2.000` (length and
/// diameter, mm; * = in the spindle), from the tool table in RAM.
pub(super) fn table_line(t: u8, v: &View, m: &Machine, l: &mut Line) {
    let c = tool_and_note(l, m, t, None);
    if t == v.tool {
        l.chars[c] = b'*';
    }
    l.micros_right(12, m.atc.table.length_um(t));
    l.micros_right(COLS, m.atc.table.diameter_um(t) as i32);
}

/// Point `p` of the station (`$170 + p`) and its machine coordinate, as
/// `?` and `M114` show it (+Z up: the heights below the Z home switch
/// are negative).
// flash: 12 B less out of line (inlined, the display path's stack
// would be 5 B shallower: it is not the deepest)
#[inline(never)]
pub(super) fn station_line(p: u8, s: &crate::config::Station, l: &mut Line) {
    l.text(1, point_text(p));
    let (mm, axis, _) = s.points()[p as usize % STATION_POINTS as usize];
    let user = if axis == 2 { -mm } else { mm };
    l.micros_right(COLS, crate::math::round_i32(user * 1000.0));
}

/// Tool number `t` as `T20`, or "none" for 0, right-aligned before `end`.
pub(super) fn number_text(t: u8, end: usize, l: &mut Line) {
    if t == 0 {
        l.text(end - 4, Text::NoNumber);
    } else {
        let w = if t >= 100 {
            4
        } else if t >= 10 {
            3
        } else {
            2
        };
        let c = l.put(end - w, b"T");
        l.uint(c, t as u32);
    }
}
