//! The text of the screens: [`Ui::line`] gives any row of the current
//! screen; here are the list and menu rows, the edit, jog, info and
//! reply screens (the status screen is `status`'s, the Tools pages' rows
//! `tool_rows`').

use super::cmd::{Reply, ToolOp, ALL_AXES};
use super::edit::{pow10, Edit, EDIT_ROW};
use super::nav::{Ui, JOG_STEPS_UM};
use super::screen::{point_text, Screen};
use super::status::{big_status_line, state_text, status_line};
use super::tool_rows::{number_text, pick_line, station_line, table_line, tool_and_note};
use super::tree::{Act, MenuId};
use super::view::{paused, View};
use crate::dollar;
use crate::flash::FStr;
use crate::machine::Machine;
use crate::ui::files::FileList;
use crate::ui::render::{Line, Style, COLS};
use crate::ui::text::Text;

impl Ui {
    /// Text of `row` of the current screen. `files` holds the visible rows
    /// of the Files screen.
    // flash: 56 B less out of line, and 14 B less stack on the display
    // path (its rows' frames stay out of the caller's)
    #[inline(never)]
    pub fn line(&self, row: usize, v: &View, m: &Machine, files: &FileList) -> Line {
        let mut l = Line::blank();
        match self.screen {
            Screen::Status if self.big => big_status_line(row, v, m.atc.table.number_of(v.tool), &m.host, &mut l),
            Screen::Status => status_line(row, v, m.atc.table.number_of(v.tool), &m.host, &mut l),
            Screen::Info => info_line(row, v, &mut l),
            _ => {
                if row == 0 {
                    l.invert = true;
                    l.style = Style::Title;
                    let t = match self.screen {
                        Screen::Menu(m) => m.title(),
                        Screen::Files => Text::Files,
                        Screen::ConfirmRun(_) => Text::RunQ,
                        Screen::ConfirmAbort => Text::AbortQ,
                        Screen::Override => Text::FeedOverride,
                        Screen::SpindleOverride => Text::SpindleOverride,
                        Screen::SpindleSpeed => Text::SpindleSpeed,
                        Screen::Jogging => Text::Jog,
                        Screen::PickTool(false) => Text::ChangeTool,
                        Screen::PickTool(true) => Text::InSpindleQ,
                        Screen::AskTool(ToolOp::Change(_)) => Text::ChangeToQ,
                        Screen::AskTool(_) => Text::HoldsQ,
                        Screen::Reply(op) => op.entry().0,
                        Screen::ToolTable => Text::TableHead,
                        Screen::Changer => Text::Changer,
                        Screen::Teach(_) => Text::TeachQ,
                        Screen::Numbers => Text::ToolNumbers,
                        Screen::Edit(Edit::Pocket(_), _) => Text::Pocket,
                        Screen::Edit(Edit::FromLine(_), _) => Text::FromLine,
                        Screen::Edit(Edit::RefLength | Edit::RefDia, _) => Text::CalibrateSetter,
                        _ => Text::Settings,
                    };
                    if let Screen::Edit(Edit::Setting(n), _) = self.screen {
                        let c = l.put(1, b"$");
                        l.uint(c, n as u32);
                        return l;
                    }
                    let c = l.text(1, t);
                    match self.screen {
                        Screen::ConfirmRun(i) => {
                            // The `?` stays: a longer name is cut with `~`.
                            let n = files.row(i).map_or(&[][..], |(n, _)| n);
                            let room = COLS.saturating_sub(c + 1);
                            let c = if n.len() > room {
                                let c = l.put(c, &n[..room - 1]);
                                l.put(c, b"~")
                            } else {
                                l.put(c, n)
                            };
                            l.put(c, b"?");
                        }
                        Screen::AskTool(ToolOp::Change(t) | ToolOp::Confirm(t)) => {
                            let c = l.uint(c, t as u32);
                            l.put(c, b"?");
                        }
                        Screen::Teach(p) => {
                            let c = l.text(c, point_text(p));
                            l.put(c, b"?");
                        }
                        Screen::Edit(Edit::Pocket(p), _) => {
                            l.uint(c, p as u32);
                        }
                        _ => {}
                    }
                    return l;
                }
                let e = self.top + row as u8 - 1;
                match self.screen {
                    Screen::Override | Screen::SpindleOverride | Screen::SpindleSpeed => {
                        if row == 2 {
                            if self.screen == Screen::SpindleSpeed {
                                l.uint_right(12, self.edit_um as u32);
                                l.text(13, Text::Rpm);
                            } else {
                                l.uint_right(12, self.override_pct as u32);
                                l.text(12, Text::Pct);
                            }
                        }
                        if row == 7 {
                            l.text(0, Text::HintEdit);
                        }
                        return l;
                    }
                    Screen::Jogging => {
                        jog_line(row, self, v, &mut l);
                        return l;
                    }
                    Screen::Reply(op) => {
                        reply_line(row, op, self.reply, v, m, &mut l);
                        return l;
                    }
                    Screen::ToolTable => {
                        table_line(e + 1, v, m, &mut l);
                        return l;
                    }
                    Screen::Edit(ed, adjusting) => {
                        self.edit_line(row, ed, adjusting, m, &mut l);
                        return l;
                    }
                    _ => {}
                }
                if e >= self.entries(v) {
                    if matches!(self.screen, Screen::Files) && e == 1 && row == 2 {
                        l.text(2, if v.card_in { Text::NoFiles } else { Text::NoCard });
                    }
                    return l;
                }
                l.invert = e == self.sel;
                match self.screen {
                    Screen::Menu(m) => self.menu_line(m, e, v, &mut l),
                    Screen::Files => {
                        if e == 0 {
                            l.text(1, Text::Back);
                        } else if let Some((n, dir)) = files.row(e - 1) {
                            // A folder ends in `/`.
                            let c = l.put(1, n);
                            if dir {
                                l.put(c, b"/");
                            }
                        }
                    }
                    Screen::Changer => {
                        if e == 0 {
                            l.text(1, Text::Back);
                        } else {
                            station_line(e - 1, &m.settings.station, &mut l);
                        }
                    }
                    Screen::ConfirmRun(_) if e == 2 => {
                        l.text(1, Text::FromLine);
                    }
                    Screen::ConfirmRun(_) | Screen::ConfirmAbort | Screen::AskTool(_) | Screen::Teach(_) => {
                        l.text(1, if e == 0 { Text::No } else { Text::Yes });
                    }
                    Screen::Settings | Screen::Numbers if e == 0 => {
                        l.text(1, Text::Back);
                    }
                    Screen::Settings => setting_line(dollar::nth(e - 1), m, &mut l),
                    Screen::Numbers => {
                        let c = l.text(1, Text::Pocket);
                        l.uint(c, e as u32);
                        number_text(m.atc.table.number_of(e), COLS, &mut l);
                    }
                    Screen::PickTool(confirm) => pick_line(e, confirm, v, m, &mut l),
                    _ => {}
                }
            }
        }
        l
    }

    /// Row `row` of the edit screen: what is edited (rows 1-3), then
    /// < Back | Value | Step | Save.
    // layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
    #[inline(never)]
    fn edit_line(&self, row: usize, ed: Edit, adjusting: bool, m: &Machine, l: &mut Line) {
        if row < EDIT_ROW {
            let what = match ed {
                Edit::Setting(n) => dollar::value(&m.settings, n).map(|(_, w)| w),
                Edit::Pocket(_) => Some(Text::NumberHelp.as_fstr()),
                // The firmware's note on the line proposed (a file changed,
                // no earlier run), or where it comes from.
                Edit::FromLine(_) => Some(match self.reply {
                    Reply::Err(note) => note,
                    _ => Text::FromLineHelp.as_fstr(),
                }),
                Edit::RefLength => Some(Text::RefLengthHelp.as_fstr()),
                Edit::RefDia => Some(Text::RefDiaHelp.as_fstr()),
            };
            if let Some(w) = what {
                wrapped(w, row - 1, l);
            }
            return;
        }
        let e = (row - EDIT_ROW) as u8;
        l.invert = e == self.sel;
        let integer = ed.integer(m);
        match e {
            0 => {
                l.text(1, Text::Back);
            }
            1 => {
                let label = if matches!(ed, Edit::FromLine(_)) { Text::LineWord } else { Text::Value };
                l.text(1, if adjusting { Text::TurnToSet } else { label });
                match ed {
                    Edit::Pocket(_) => number_text((self.edit_um / 1000) as u8, COLS, l),
                    _ if integer => l.uint_right(COLS, (self.edit_um / 1000) as u32),
                    _ => l.micros_right(COLS, self.edit_um),
                }
            }
            2 => {
                l.text(1, Text::Step);
                let p = pow10(self.edit_step);
                if integer {
                    l.uint_right(COLS, (p / 1000) as u32);
                } else {
                    l.micros_right(COLS, p);
                }
            }
            _ => {
                l.text(1, if matches!(ed, Edit::FromLine(_)) { Text::Start } else { Text::Save });
            }
        }
    }

    // layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
    #[inline(never)]
    fn menu_line(&self, m: MenuId, e: u8, v: &View, l: &mut Line) {
        let (t, a) = m.item(e as usize);
        let t = if a == Act::PauseResume && paused(v) { Text::Resume } else { t };
        let c = l.text(1, t);
        match a {
            Act::Override => {
                l.uint_right(COLS - 1, v.override_pct as u32);
                l.text(COLS - 1, Text::Pct);
            }
            Act::JogAxis | Act::ZeroAxis => {
                l.put(c + 1, &[b"XYZ"[self.jog_axis as usize % 3]]);
            }
            Act::WorkSystem => {
                l.put(c, &[b'4' + v.wcs % 6]);
            }
            Act::OptStop => {
                l.text(COLS - 3, if v.opt_stop { Text::On } else { Text::Off });
            }
            Act::SpindleOnOff => {
                l.text(COLS - 3, if v.rpm != 0 { Text::On } else { Text::Off });
            }
            Act::SpindleSpeed => {
                l.uint_right(COLS - 4, v.speed as u32);
                l.text(COLS - 3, Text::Rpm);
            }
            Act::SpindleOverride => {
                l.uint_right(COLS - 1, v.spindle_pct as u32);
                l.text(COLS - 1, Text::Pct);
            }
            Act::JogStep => {
                let um = JOG_STEPS_UM[self.jog_step as usize % 3];
                let c = c + 1;
                let c = if um < 1000 { l.put(c, b"0.1") } else { l.uint(c, (um / 1000) as u32) };
                l.text(c, Text::Mm);
            }
            _ => {}
        }
    }
}

// layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
#[inline(never)]
fn info_line(row: usize, v: &View, l: &mut Line) {
    match row {
        0 => {
            l.invert = true;
            l.style = Style::Title;
            l.text(1, Text::Info);
        }
        2 => {
            l.text(1, Text::FirmwareName);
        }
        3 => {
            let c = l.text(1, Text::Version);
            l.put(c, crate::FIRMWARE_VERSION.as_bytes());
        }
        4 => {
            let c = l.text(1, Text::FreeRam);
            let c = l.uint(c, v.free_ram as u32);
            l.text(c, Text::Bytes);
        }
        5 => {
            let c = l.text(1, Text::SdCard);
            l.text(c, if v.card_in { Text::CardIn } else { Text::CardOut });
        }
        _ => {}
    }
}

// layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
#[inline(never)]
fn jog_line(row: usize, ui: &Ui, v: &View, l: &mut Line) {
    let axis = ui.jog_axis as usize % 3;
    match row {
        2 => {
            l.put(1, &[b"XYZ"[axis]]);
            l.micros_right(12, v.wpos_um[axis]);
            l.text(12, Text::Mm);
        }
        3 => {
            let c = l.text(1, Text::Step);
            let um = JOG_STEPS_UM[ui.jog_step as usize % 3];
            l.micros_right(c + 8, um);
            l.text(c + 8, Text::Mm);
        }
        7 => {
            l.text(0, Text::HintJog);
        }
        _ => {}
    }
}

/// The reply screen of a Tools command: the machine state while it runs,
/// then the result (tool in the spindle; the measured tool's table row) or
/// the refusal, word-wrapped.
// layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
#[inline(never)]
fn reply_line(row: usize, op: ToolOp, r: Reply, v: &View, m: &Machine, l: &mut Line) {
    let t = v.tool;
    match (r, row) {
        (Reply::Pending, 2) => {
            l.text(1, state_text(v.state, v.homed));
        }
        (Reply::Pending, _) => {}
        (Reply::Err(msg), 2..=6) => wrapped(msg, row - 2, l),
        // Measured: the spindle tool's row of the tool table, under its head.
        (Reply::Ok, 2) if matches!(op, ToolOp::Measure { .. }) => {
            l.text(1, Text::TableHead);
        }
        (Reply::Ok, 3) if matches!(op, ToolOp::Measure { .. }) => table_line(t, v, m, l),
        // A work system chosen: the one now active.
        (Reply::Ok, 2) if matches!(op, ToolOp::Wcs(_)) => {
            let c = l.text(1, Text::WorkSystem);
            l.put(c, &[b'4' + v.wcs % 6]);
        }
        // All three zeroed: their work positions now, a row each.
        (Reply::Ok, 2..=4) if op == ToolOp::Zero(ALL_AXES) => {
            let a = row - 2;
            l.put(1, &[b"XYZ"[a]]);
            l.micros_right(COLS, v.wpos_um[a]);
        }
        // A work zero: the axis' work position now (0.000).
        (Reply::Ok, 2) if matches!(op, ToolOp::Zero(_) | ToolOp::ProbeZ) => {
            let a = if let ToolOp::Zero(a) = op { a as usize % 3 } else { 2 };
            l.put(1, &[b"XYZ"[a]]);
            l.micros_right(COLS, v.wpos_um[a]);
        }
        // Stored: the setting or the pocket as it is now.
        (Reply::Ok, 2) if matches!(op, ToolOp::Store(_)) => match op {
            ToolOp::Store(Edit::Pocket(p)) => {
                let c = l.text(1, Text::Pocket);
                l.uint(c, p as u32);
                number_text(m.atc.table.number_of(p), COLS, l);
            }
            ToolOp::Store(Edit::Setting(n)) => setting_line(n, m, l),
            ToolOp::Store(Edit::RefLength) => {
                l.text(1, Text::RefLength);
                l.micros_right(COLS, m.setter.ref_length_um);
            }
            // Calibrated: where the beam is (the user's machine Z) and
            // what it adds to a diameter.
            ToolOp::Store(Edit::RefDia) => {
                l.text(1, Text::BeamZ);
                l.micros_right(COLS, crate::frame::z_user_from_internal_i32(m.setter.beam_z_um));
            }
            _ => {}
        },
        (Reply::Ok, 3) if op == ToolOp::Store(Edit::RefDia) => {
            l.text(1, Text::BeamWidth);
            l.micros_right(COLS, m.setter.beam_width_um);
        }
        (Reply::Ok, 2) => {
            tool_and_note(l, m, t, Some(Text::InSpindle));
        }
        (_, 7) => {
            l.text(0, Text::HintBack);
        }
        _ => {}
    }
}

/// Line `k` of `msg` word-wrapped to the 20 columns from column 1 (a
/// word longer than a line is cut).
pub(super) fn wrapped(msg: FStr, k: usize, l: &mut Line) {
    let n = msg.len();
    let (mut line, mut col, mut i) = (0, 1, 0);
    while i < n {
        // The word i..j.
        let mut j = i;
        while msg.get(j).is_some_and(|b| b != b' ') {
            j += 1;
        }
        if col > 1 && col + (j - i) > COLS {
            line += 1;
            col = 1;
        }
        while i < j {
            if line == k && col < COLS {
                l.chars[col] = msg.get(i).unwrap_or(b' ');
            }
            col += 1;
            i += 1;
        }
        col += 1;
        i += 1;
    }
}

/// Setting `$n` and its value, as `$$` lists it (a flag or a mask as a
/// whole number).
fn setting_line(n: u8, m: &Machine, l: &mut Line) {
    let c = l.put(1, b"$");
    l.uint(c, n as u32);
    match dollar::value(&m.settings, n) {
        Some((dollar::Value::Num(x), _)) => l.micros_right(COLS, crate::math::round_i32(x * 1000.0)),
        Some((v, _)) => l.uint_right(COLS, (v.micros() / 1000) as u32),
        None => {}
    }
}
