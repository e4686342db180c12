//! The state machine the encoder drives: [`Ui`] (which screen, which
//! entry, the values being set), [`Ui::step`] (turns and presses in, a
//! [`Cmd`] for the firmware out), and the way between the screens.

use super::cmd::{Cmd, Reply, ToolOp, ALL_AXES};
use super::edit::{pow10, Edit, EDIT_ENTRIES};
use super::screen::{Screen, STATION_POINTS};
use super::tree::{Act, MenuId};
use super::view::{paused, View};
use crate::atc::N_POCKETS;
use crate::dollar;
use crate::machine::{Machine, State};
use crate::ui::render::ROWS;
use crate::ui::text::Text;

/// Spindle > Speed: rpm per detent.
const SPEED_STEP_RPM: i32 = 100;

/// Jog steps, µm.
pub(super) const JOG_STEPS_UM: [i32; 3] = [100, 1000, 10_000];

/// The UI state machine. RAM: 14 bytes on AVR (8 before the Tools reply).
pub struct Ui {
    pub screen: Screen,
    /// Selected entry and first entry shown, for list screens.
    pub sel: u8,
    pub top: u8,
    /// Jog axis 0..3 and step index into the jog steps.
    pub jog_axis: u8,
    pub jog_step: u8,
    /// The override being set.
    pub override_pct: u16,
    /// Outcome of the last Tools command (shown on [`Screen::Reply`]).
    pub reply: Reply,
    /// The value on the edit screen, thousandths, and its step: 10^k
    /// thousandths.
    pub edit_um: i32,
    pub edit_step: u8,
    /// The status screen shows the position in large digits (turn right on
    /// it; left: the full status).
    pub big: bool,
}

impl Default for Ui {
    fn default() -> Self {
        Ui::new()
    }
}

/// List rows below the title.
const LIST_ROWS: u8 = (ROWS - 1) as u8;
/// Entries of the tool lists: "< Back", T0..T12.
const TOOL_ENTRIES: u8 = N_POCKETS as u8 + 2;

impl Ui {
    pub const fn new() -> Ui {
        Ui {
            screen: Screen::Status,
            sel: 0,
            top: 0,
            jog_axis: 0,
            jog_step: 1,
            override_pct: 100,
            reply: Reply::Ok,
            edit_um: 0,
            edit_step: 3,
            big: false,
        }
    }

    pub(super) fn go(&mut self, s: Screen) {
        self.screen = s;
        self.sel = 0;
        self.top = 0;
    }

    /// Entries in the current list screen (0 for non-list screens).
    pub(super) fn entries(&self, v: &View) -> u8 {
        match self.screen {
            Screen::Menu(m) => m.len() as u8,
            Screen::Files => v.files + 1,
            // No | Yes | From line.
            Screen::ConfirmRun(_) => 3,
            Screen::ConfirmAbort | Screen::AskTool(_) => 2,
            Screen::PickTool(_) => TOOL_ENTRIES,
            Screen::Changer => STATION_POINTS + 1,
            Screen::Teach(_) => 2,
            Screen::Settings => dollar::count() + 1,
            Screen::Numbers => N_POCKETS as u8 + 1,
            Screen::Edit(..) => EDIT_ENTRIES,
            _ => 0,
        }
    }

    /// Move the selection by `d` within `n` entries and keep it visible.
    pub(super) fn scroll(&mut self, d: i8, n: u8) {
        if n == 0 {
            return;
        }
        let s = (self.sel as i16 + d as i16).clamp(0, n as i16 - 1) as u8;
        self.sel = s;
        if s < self.top {
            self.top = s;
        } else if s >= self.top + LIST_ROWS {
            self.top = s + 1 - LIST_ROWS;
        }
    }

    /// What the encoder did since the last call: `detents` (+ = clockwise)
    /// and `press`. Returns what the firmware should do.
    // layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
    #[inline(never)]
    pub fn step(&mut self, detents: i8, press: bool, v: &View) -> Cmd {
        match self.screen {
            Screen::Status => {
                if detents != 0 {
                    self.big = detents > 0;
                }
                if press && v.state == State::Alarm {
                    // What gets out of the alarm: unlock, home, jog, M61.
                    self.go(Screen::Menu(MenuId::Alarm));
                    return Cmd::None;
                }
                if press && v.state == State::Hold {
                    // Held (M0, feed hold, pause): the button resumes.
                    return Cmd::Resume;
                }
                if press {
                    self.go(Screen::Menu(MenuId::Main));
                }
                Cmd::None
            }
            Screen::Jogging => {
                if press {
                    self.screen = Screen::Menu(MenuId::Jog);
                    return Cmd::None;
                }
                if detents != 0 {
                    let step = JOG_STEPS_UM[self.jog_step as usize % 3];
                    return Cmd::Jog { axis: self.jog_axis, delta_um: step * detents as i32 };
                }
                Cmd::None
            }
            Screen::Override => {
                let p = self.override_pct as i16 + 5 * detents as i16;
                self.override_pct = p.clamp(10, 200) as u16;
                if press {
                    self.screen = Screen::Menu(MenuId::Job);
                    return Cmd::Override(self.override_pct);
                }
                Cmd::None
            }
            Screen::SpindleOverride => {
                // grbl's coarse step and range (0x9A/0x9B).
                let p = self.override_pct as i16 + 10 * detents as i16;
                self.override_pct = p.clamp(10, 200) as u16;
                if press {
                    self.screen = Screen::Menu(MenuId::Spindle);
                    return Cmd::SpindleOverride(self.override_pct as u8);
                }
                Cmd::None
            }
            Screen::SpindleSpeed => {
                self.edit_um = (self.edit_um + SPEED_STEP_RPM * detents as i32).clamp(0, u16::MAX as i32);
                if press {
                    self.screen = Screen::Menu(MenuId::Spindle);
                    return Cmd::Spindle { on: v.rpm != 0, rpm: self.edit_um as u16, set: true };
                }
                Cmd::None
            }
            Screen::Info => {
                if press {
                    self.back_to(MenuId::Main, 7);
                }
                Cmd::None
            }
            Screen::ToolTable => {
                // The view scrolls itself (no selection): 12 tools, 7 rows.
                let top = self.top as i16 + detents as i16;
                self.top = top.clamp(0, N_POCKETS as i16 - LIST_ROWS as i16) as u8;
                if press {
                    self.back_to(MenuId::Tools, 4);
                }
                Cmd::None
            }
            Screen::Reply(op) => {
                if press && !matches!(self.reply, Reply::Pending) {
                    // The reference tool's length stored: its diameter next;
                    // calibrated: back to Tools.
                    match op {
                        ToolOp::Store(Edit::RefLength) if self.reply == Reply::Ok => return self.open_edit(Edit::RefDia),
                        ToolOp::Store(Edit::RefDia) => {}
                        ToolOp::Store(e) => return self.open_edit(e),
                        _ => {}
                    }
                    self.back_to(op.menu(), op.entry().1);
                }
                Cmd::None
            }
            Screen::Edit(e, true) => {
                // Turning sets the value; a press ends it.
                if press {
                    self.screen = Screen::Edit(e, false);
                }
                self.edit_um = self.edit_um.saturating_add(detents as i32 * pow10(self.edit_step));
                Cmd::None
            }
            _ => {
                let n = self.entries(v);
                self.scroll(detents, n);
                if press {
                    self.press(v)
                } else {
                    Cmd::None
                }
            }
        }
    }

    /// Open the edit screen of `e` on its Value entry; the firmware loads
    /// the value ([`Cmd::Edit`]).
    fn open_edit(&mut self, e: Edit) -> Cmd {
        self.go(Screen::Edit(e, false));
        self.sel = 1;
        self.edit_step = 3;
        Cmd::Edit(e)
    }

    /// Keep the edited value in its range and the step within its kind's
    /// (0.001 … 1000 for a number, 1 … 100 for a whole one): called after
    /// every [`Ui::step`], with the machine that knows the setting.
    pub fn fit_edit(&mut self, m: &Machine) {
        if let Screen::Edit(e, _) = self.screen {
            let (lo, hi) = e.range(m);
            self.edit_um = self.edit_um.clamp(lo, hi);
            let (first, last) = match e {
                // Lines: 1, 10, 100 or 1000 a detent.
                Edit::FromLine(_) => (3, 6),
                _ if e.integer(m) => (3, 5),
                _ => (0, 6),
            };
            if !(first..=last).contains(&self.edit_step) {
                self.edit_step = first;
            }
        }
    }

    /// Open menu `m` with `entry` selected.
    fn back_to(&mut self, m: MenuId, entry: u8) {
        self.go(Screen::Menu(m));
        self.scroll(entry as i8, m.len() as u8);
    }

    /// Start Tools command `op` (the Reply screen shows how it goes), or
    /// refuse it at once while the machine is busy.
    fn run_tool(&mut self, op: ToolOp, v: &View) -> Cmd {
        self.go(Screen::Reply(op));
        if !v.may_run_tool() {
            self.reply = Reply::Err(Text::NotIdle.as_fstr());
            return Cmd::None;
        }
        self.reply = Reply::Pending;
        Cmd::Tool(op)
    }

    // layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
    #[inline(never)]
    fn press(&mut self, v: &View) -> Cmd {
        let sel = self.sel;
        match self.screen {
            Screen::Menu(m) => self.act(m, m.item(sel as usize).1, v),
            Screen::Files => {
                let i = sel.wrapping_sub(1);
                let row = i.wrapping_sub(self.visible_files().0);
                if sel == 0 && v.in_folder && v.card_in {
                    self.go(Screen::Files);
                    return Cmd::FolderUp;
                } else if sel == 0 || !v.card_in {
                    self.back_to(MenuId::Main, 1);
                } else if row < 8 && v.folder_rows & (1 << row) != 0 {
                    self.go(Screen::Files);
                    return Cmd::OpenFolder(i);
                } else if v.job_active() {
                    self.go(Screen::Status);
                } else {
                    self.go(Screen::ConfirmRun(i));
                }
                Cmd::None
            }
            Screen::ConfirmRun(i) => {
                if sel == 2 {
                    return self.open_edit(Edit::FromLine(i));
                }
                if sel == 1 {
                    self.go(Screen::Status);
                    Cmd::RunFile(i)
                } else {
                    self.go(Screen::Files);
                    self.scroll(i as i8 + 1, v.files + 1);
                    Cmd::None
                }
            }
            Screen::ConfirmAbort => {
                if sel == 1 {
                    self.go(Screen::Status);
                    Cmd::Abort
                } else {
                    self.go(Screen::Menu(MenuId::Job));
                    Cmd::None
                }
            }
            Screen::Settings => {
                if sel == 0 {
                    self.back_to(MenuId::Main, 6);
                    return Cmd::None;
                }
                self.open_edit(Edit::Setting(dollar::nth(sel - 1)))
            }
            Screen::Numbers => {
                if sel == 0 {
                    self.back_to(MenuId::Tools, 7);
                    return Cmd::None;
                }
                self.open_edit(Edit::Pocket(sel))
            }
            Screen::Edit(e, _) => match sel {
                0 => {
                    let (list, entry) = e.back();
                    self.go(list);
                    self.scroll(entry as i8, self.entries(v));
                    Cmd::None
                }
                1 => {
                    self.screen = Screen::Edit(e, true);
                    Cmd::None
                }
                // The next step ([`Ui::fit_edit`] wraps it round).
                2 => {
                    self.edit_step += 1;
                    Cmd::None
                }
                _ => {
                    self.go(Screen::Reply(ToolOp::Store(e)));
                    if !v.may_run_tool() {
                        self.reply = Reply::Err(Text::NotIdle.as_fstr());
                        return Cmd::None;
                    }
                    self.reply = Reply::Pending;
                    Cmd::Store(e, self.edit_um)
                }
            },
            Screen::PickTool(confirm) => {
                if sel == 0 {
                    self.back_to(MenuId::Tools, if confirm { 5 } else { 1 });
                } else {
                    let t = sel - 1;
                    self.go(Screen::AskTool(if confirm { ToolOp::Confirm(t) } else { ToolOp::Change(t) }));
                }
                Cmd::None
            }
            Screen::Changer => {
                if sel == 0 {
                    self.back_to(MenuId::Tools, 6);
                } else {
                    self.go(Screen::Teach(sel - 1));
                }
                Cmd::None
            }
            Screen::Teach(p) => {
                self.go(Screen::Changer);
                self.scroll(p as i8 + 1, STATION_POINTS + 1);
                if sel == 1 && v.state == State::Idle {
                    Cmd::Teach(p)
                } else {
                    Cmd::None
                }
            }
            Screen::AskTool(op) => {
                if sel == 1 {
                    return self.run_tool(op, v);
                }
                let (confirm, t) = match op {
                    ToolOp::Confirm(t) => (true, t),
                    ToolOp::Change(t) => (false, t),
                    ToolOp::Measure { .. } | ToolOp::Zero(_) | ToolOp::ProbeZ | ToolOp::Wcs(_) | ToolOp::Store(_) => (false, 0),
                };
                self.go(Screen::PickTool(confirm));
                self.scroll(t as i8 + 1, TOOL_ENTRIES);
                Cmd::None
            }
            _ => Cmd::None,
        }
    }

    // layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
    #[inline(never)]
    fn act(&mut self, m: MenuId, a: Act, v: &View) -> Cmd {
        let idle = v.state == State::Idle && !v.job_active();
        match a {
            Act::Back => {
                if m == MenuId::Main || m == MenuId::Alarm {
                    self.go(Screen::Status);
                } else {
                    let entry = match m {
                        MenuId::Job => 2,
                        MenuId::Jog => 3,
                        MenuId::Home => 4,
                        MenuId::Spindle => 8,
                        _ => 5,
                    };
                    self.back_to(MenuId::Main, entry);
                }
                Cmd::None
            }
            Act::Files => {
                self.go(Screen::Files);
                Cmd::ListFiles
            }
            Act::JobMenu => {
                self.go(Screen::Menu(MenuId::Job));
                Cmd::None
            }
            Act::JogMenu => {
                self.go(Screen::Menu(MenuId::Jog));
                // From the alarm menu: unlocked, so the axis can leave a
                // closed switch.
                if m == MenuId::Alarm {
                    Cmd::Unlock
                } else {
                    Cmd::None
                }
            }
            Act::Unlock => {
                self.go(Screen::Status);
                Cmd::Unlock
            }
            Act::HomeMenu => {
                self.go(Screen::Menu(MenuId::Home));
                Cmd::None
            }
            Act::Settings => {
                self.go(Screen::Settings);
                Cmd::None
            }
            Act::Info => {
                self.go(Screen::Info);
                Cmd::None
            }
            Act::SpindleMenu => {
                self.go(Screen::Menu(MenuId::Spindle));
                Cmd::None
            }
            // Not during a job: the job's M3/M5 are in charge (the override
            // is not: it is what an operator turns during a cut).
            Act::SpindleOnOff if !v.job_active() => {
                let on = v.rpm == 0;
                Cmd::Spindle { on, rpm: v.speed, set: false }
            }
            Act::SpindleSpeed if !v.job_active() => {
                self.edit_um = v.speed as i32;
                self.screen = Screen::SpindleSpeed;
                Cmd::None
            }
            Act::SpindleOnOff | Act::SpindleSpeed => Cmd::None,
            Act::SpindleOverride => {
                self.override_pct = v.spindle_pct as u16;
                self.screen = Screen::SpindleOverride;
                Cmd::None
            }
            Act::PauseResume => {
                if paused(v) {
                    Cmd::Resume
                } else {
                    Cmd::Pause
                }
            }
            Act::Abort => {
                if v.job_active() || v.state == State::Run || v.state == State::Hold {
                    self.go(Screen::ConfirmAbort);
                }
                Cmd::None
            }
            Act::Override => {
                self.override_pct = v.override_pct;
                self.screen = Screen::Override;
                Cmd::None
            }
            Act::OptStop => Cmd::OptionalStop(!v.opt_stop),
            Act::JogAxis => {
                self.jog_axis = (self.jog_axis + 1) % 3;
                Cmd::None
            }
            Act::JogStep => {
                self.jog_step = (self.jog_step + 1) % 3;
                Cmd::None
            }
            Act::JogNow => {
                if idle {
                    self.screen = Screen::Jogging;
                }
                Cmd::None
            }
            Act::ZeroAxis => self.run_tool(ToolOp::Zero(self.jog_axis % 3), v),
            Act::ZeroAll => self.run_tool(ToolOp::Zero(ALL_AXES), v),
            Act::ProbeZ => self.run_tool(ToolOp::ProbeZ, v),
            Act::WorkSystem => self.run_tool(ToolOp::Wcs((v.wcs + 1) % 6), v),
            Act::HomeAll | Act::HomeZ | Act::HomeY | Act::HomeX => {
                // Homing is also the way out of an alarm.
                if !idle && !(v.state == State::Alarm && !v.job_active()) {
                    return Cmd::None;
                }
                self.go(Screen::Status);
                Cmd::Home(match a {
                    Act::HomeZ => 0b100,
                    Act::HomeY => 0b010,
                    Act::HomeX => 0b001,
                    _ => 0b111,
                })
            }
            Act::ToolsMenu => {
                self.go(Screen::Menu(MenuId::Tools));
                Cmd::None
            }
            Act::ChangeTool => {
                // The list opens on the tool in the spindle.
                self.go(Screen::PickTool(false));
                self.scroll(v.tool as i8 + 1, TOOL_ENTRIES);
                Cmd::None
            }
            Act::MeasureLength | Act::MeasureDia => self.run_tool(ToolOp::Measure { diameter: a == Act::MeasureDia }, v),
            Act::ToolTable => {
                self.go(Screen::ToolTable);
                Cmd::None
            }
            Act::Changer => {
                self.go(Screen::Changer);
                Cmd::None
            }
            Act::CalibrateSetter => self.open_edit(Edit::RefLength),
            Act::ToolNumbers => {
                self.go(Screen::Numbers);
                Cmd::None
            }
            Act::ConfirmSpindle => {
                if v.interrupted.is_some() {
                    self.go(Screen::PickTool(true));
                } else {
                    self.go(Screen::Reply(ToolOp::Confirm(0)));
                    self.reply = Reply::Err(Text::NoChangeCut.as_fstr());
                }
                Cmd::None
            }
        }
    }

    /// The first file row shown on the Files screen (its index in directory
    /// order), and how many rows: the firmware keeps those names.
    pub fn visible_files(&self) -> (u8, u8) {
        // Row r (1..) shows entry top + r - 1; entry e ≥ 1 is file e - 1.
        let first_entry = self.top;
        let first_file = first_entry.saturating_sub(1);
        (first_file, LIST_ROWS)
    }
}

// The way back from an edit is navigation, and a screen: kept here, as
// `screen` names `edit` (the other way would be a cycle).
impl Edit {
    /// Where the edit came from: that list, with this entry selected.
    fn back(self) -> (Screen, u8) {
        match self {
            Edit::Setting(n) => (Screen::Settings, (0..dollar::count()).find(|&i| dollar::nth(i) == n).unwrap_or(0) + 1),
            Edit::Pocket(p) => (Screen::Numbers, p),
            Edit::FromLine(i) => (Screen::ConfirmRun(i), 2),
            Edit::RefLength | Edit::RefDia => (Screen::Menu(MenuId::Tools), ToolOp::Store(self).entry().1),
        }
    }
}
