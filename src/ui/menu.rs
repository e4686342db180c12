//! The menu tree (docs/SPEC.md §9) as data, and the state machine the encoder drives.
//!
//! ```text
//!  Status ──press──► Menu: < Status | Run from SD | Job | Jog | Home | Tools | Settings | Info
//!    Run from SD: < Back, files (scrolling) ──► "Run NAME?" No/Yes
//!    Job:  < Back | Pause/Resume | Abort ──► "Abort the job?" No/Yes | Feed override nnn%
//!    Jog:  < Back | Axis X/Y/Z | Step 0.1/1/10 mm | Jog now (turn = move, press = done)
//!    Home: < Back | Home all | Home Z | Home Y | Home X
//!    Tools: < Back | Change tool ──► < Back, T0..T12 ──► "Change to Tn?" No/Yes ──► reply
//!           | Measure length (G37) ──► reply | Measure len+dia (G37 D1) ──► reply
//!           | Tool table (view, scrolling)
//!           | Confirm spindle ──► < Back, T0..T12 ──► "Spindle holds Tn?" No/Yes ──► reply
//!           | Changer (station points, teach) | Tool numbers ──► < Back, pockets 1..12 ──► edit
//!    Settings: < Back, every `$` setting (scrolling) ──► edit
//!    Info (version, free RAM, card)
//!    edit: what it is | < Back | Value (press, turn, press) | Step | Save ──► reply
//! ```
//!
//! [`Ui::step`] takes what the encoder did (detents, presses) and returns a
//! [`Cmd`] for the firmware to carry out; [`Ui::line`] gives the text of any
//! row of the current screen from a [`View`] (a snapshot of the machine
//! taken once per frame) and the [`Machine`] (settings, tool table).
//!
//! The Tools entries run G-code lines through the machine's command path
//! ([`ToolOp::gcode`]: `T<n>`, `G37`, `G37 D1`, `M61 Q<t>`), so they are
//! refused exactly as over serial; the reply screen shows the result or
//! the refusal ([`Reply`], set by the firmware when the line returns).

use super::flash;
use super::render::{Line, Style, BIG_COLS, COLS, ROWS};
use super::sd::{Name, Outcome, Phase};
use super::text::Text;
use crate::atc::{Journal, N_POCKETS};
use crate::dollar;
use crate::flash::FStr;
use crate::machine::{Alarm, Machine, State};

/// A fieldless `u8` enum and its checked inverse `from_u8` (a compare
/// chain: no transmute, and no table that the AVR would copy to RAM).
macro_rules! u8_enum {
    ($(#[$m:meta])* $vis:vis enum $name:ident { $($(#[$vm:meta])* $v:ident,)* }) => {
        $(#[$m])*
        #[derive(Clone, Copy, PartialEq, Eq, Debug)]
        #[repr(u8)]
        $vis enum $name { $($(#[$vm])* $v,)* }

        impl $name {
            /// The variant whose discriminant is `b`, if there is one.
            fn from_u8(b: u8) -> Option<$name> {
                $(if b == $name::$v as u8 {
                    return Some($name::$v);
                })*
                None
            }
        }
    };
}

u8_enum! {
    /// What an entry does when pressed.
    pub enum Act {
        Back,
        Files,
        JobMenu,
        JogMenu,
        HomeMenu,
        Settings,
        Info,
        PauseResume,
        Abort,
        Override,
        JogAxis,
        JogStep,
        JogNow,
        HomeAll,
        HomeZ,
        HomeY,
        HomeX,
        ToolsMenu,
        ChangeTool,
        MeasureLength,
        MeasureDia,
        ToolTable,
        ConfirmSpindle,
        /// Leave the alarm state (`$X`/M999).
        Unlock,
        /// Tools > Changer: the station's points.
        Changer,
        /// Jog > Zero <axis>: the work zero of the jog axis here.
        ZeroAxis,
        /// Jog > Probe Z zero: probe down, Z zero where it touches.
        ProbeZ,
        /// Jog > Work G5x: the next work system (G54 … G59, round).
        WorkSystem,
        /// Tools > Tool numbers: the tool number kept in each pocket.
        ToolNumbers,
        OptStop,
    }
}

/// The menus with fixed entries.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[repr(u8)]
pub enum MenuId {
    Main,
    Job,
    Jog,
    Home,
    Tools,
    /// Opened from the status screen in an alarm: what gets out of it.
    Alarm,
}

const fn item(t: Text, a: Act) -> [u8; 2] {
    [t as u8, a as u8]
}

/// Every fixed entry, menu after menu (see MENU_START), in flash.
#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
static ITEMS: [[u8; 2]; 38] = [
    // Main
    item(Text::Status, Act::Back),
    item(Text::RunFromSd, Act::Files),
    item(Text::Job, Act::JobMenu),
    item(Text::Jog, Act::JogMenu),
    item(Text::Home, Act::HomeMenu),
    item(Text::Tools, Act::ToolsMenu),
    item(Text::Settings, Act::Settings),
    item(Text::Info, Act::Info),
    // Job
    item(Text::Back, Act::Back),
    item(Text::Pause, Act::PauseResume),
    item(Text::Abort, Act::Abort),
    item(Text::FeedOverride, Act::Override),
    item(Text::OptStop, Act::OptStop),
    // Jog
    item(Text::Back, Act::Back),
    item(Text::Axis, Act::JogAxis),
    item(Text::Step, Act::JogStep),
    item(Text::JogNow, Act::JogNow),
    item(Text::ZeroAxis, Act::ZeroAxis),
    item(Text::ProbeZ, Act::ProbeZ),
    item(Text::WorkSystem, Act::WorkSystem),
    // Home
    item(Text::Back, Act::Back),
    item(Text::HomeAll, Act::HomeAll),
    item(Text::HomeZ, Act::HomeZ),
    item(Text::HomeY, Act::HomeY),
    item(Text::HomeX, Act::HomeX),
    // Tools
    item(Text::Back, Act::Back),
    item(Text::ChangeTool, Act::ChangeTool),
    item(Text::MeasureLength, Act::MeasureLength),
    item(Text::MeasureDia, Act::MeasureDia),
    item(Text::ToolTable, Act::ToolTable),
    item(Text::ConfirmSpindle, Act::ConfirmSpindle),
    item(Text::Changer, Act::Changer),
    item(Text::ToolNumbers, Act::ToolNumbers),
    // Alarm
    item(Text::Status, Act::Back),
    item(Text::Unlock, Act::Unlock),
    item(Text::HomeAll, Act::HomeAll),
    item(Text::Jog, Act::JogMenu),
    item(Text::ConfirmSpindle, Act::ConfirmSpindle),
];

/// First entry of each menu in ITEMS, plus the end.
#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
static MENU_START: [u8; 7] = [0, 8, 13, 20, 25, 33, 38];

impl MenuId {
    fn range(self) -> (usize, usize) {
        let i = self as usize;
        let a = flash::read_byte(&MENU_START[i]) as usize;
        let b = flash::read_byte(&MENU_START[i + 1]) as usize;
        (a, b)
    }

    /// Number of entries.
    pub fn len(self) -> usize {
        let (a, b) = self.range();
        b - a
    }

    /// True for a menu without entries (none is).
    pub fn is_empty(self) -> bool {
        self.len() == 0
    }

    /// Entry `i`: its label and action.
    pub fn item(self, i: usize) -> (Text, Act) {
        let (a, _) = self.range();
        let e = &ITEMS[a + i];
        let (t, c) = (flash::read_byte(&e[0]), flash::read_byte(&e[1]));
        // `item` made both bytes from a Text and an Act: the fallback is
        // never taken.
        (Text::from_u8(t).unwrap_or(Text::Back), Act::from_u8(c).unwrap_or(Act::Back))
    }

    fn title(self) -> Text {
        match self {
            MenuId::Main => Text::MainMenu,
            MenuId::Job => Text::Job,
            MenuId::Jog => Text::Jog,
            MenuId::Home => Text::Home,
            MenuId::Tools => Text::Tools,
            MenuId::Alarm => Text::AlarmMenu,
        }
    }
}

/// The screen on the display.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Screen {
    Status,
    Menu(MenuId),
    /// The SD file list: entry 0 is "< Back", entry i is file i - 1.
    Files,
    /// "Run NAME?" for file index i.
    ConfirmRun(u8),
    ConfirmAbort,
    /// Feed override being set.
    Override,
    /// Jogging: each detent moves the axis one step.
    Jogging,
    /// Every `$` setting (entry 0 "< Back", entry i is setting
    /// `dollar::nth(i - 1)`) with its value.
    Settings,
    Info,
    /// The tool list (entry 0 "< Back", entry i is T(i - 1)): for a change,
    /// or (true) for confirming the spindle after an interrupted change.
    PickTool(bool),
    /// "Change to Tn?" / "Spindle holds Tn?" No/Yes.
    AskTool(ToolOp),
    /// A Tools command running, then its result or refusal ([`Ui::reply`]).
    Reply(ToolOp),
    /// T1..T12 length and diameter (view, scrolling).
    ToolTable,
    /// The tool change station's points (entry 0 "< Back", entry i is
    /// point i - 1 of [`STATION_POINTS`]) with their machine coordinates.
    Changer,
    /// "Teach <point>?" No/Yes: store the current position as the point.
    Teach(u8),
    /// The tool number of each pocket (entry 0 "< Back", entry i is
    /// pocket i).
    Numbers,
    /// Editing a value: what it is, then < Back | Value | Step | Save; true
    /// while the encoder turns the value ([`Ui::edit_um`]).
    Edit(Edit, bool),
}

/// What an edit screen changes.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Edit {
    /// Setting `$n`, stored by running the line `$n=<value>`.
    Setting(u8),
    /// The tool number kept in pocket p (1..=12; 0 = none), stored by
    /// running `G10 L1 P<tool> Q<p>` (after `G10 L1 P<old> Q0`).
    Pocket(u8),
}

/// Entries of the edit screen: < Back, Value, Step, Save.
const EDIT_ENTRIES: u8 = 4;
/// The edit screen's first entry row (rows 1..3 say what is edited).
const EDIT_ROW: usize = 4;

impl Edit {
    /// The value as it is now, in thousandths.
    pub fn current(self, m: &Machine) -> i32 {
        match self {
            Edit::Setting(n) => dollar::value(&m.settings, n).map_or(0, |(v, _)| v.micros()),
            Edit::Pocket(p) => m.atc.table.number_of(p) as i32 * 1000,
        }
    }

    /// A whole number (a flag, a mask, a tool number)?
    fn integer(self, m: &Machine) -> bool {
        match self {
            Edit::Setting(n) => !matches!(dollar::value(&m.settings, n), Some((dollar::Value::Num(_), _))),
            Edit::Pocket(_) => true,
        }
    }

    /// The range the encoder may turn the value through, thousandths
    /// (the machine checks the value itself when it is stored).
    fn range(self, m: &Machine) -> (i32, i32) {
        match self {
            Edit::Setting(n) => match dollar::value(&m.settings, n) {
                Some((dollar::Value::Flag(_), _)) => (0, 1000),
                Some((dollar::Value::Mask(_, max), _)) => (0, max as i32 * 1000),
                _ => (-99_999_999, 99_999_999),
            },
            Edit::Pocket(_) => (0, 254_000),
        }
    }

    /// Where the edit came from: that list, with this entry selected.
    fn back(self) -> (Screen, u8) {
        match self {
            Edit::Setting(n) => (Screen::Settings, (0..dollar::count()).find(|&i| dollar::nth(i) == n).unwrap_or(0) + 1),
            Edit::Pocket(p) => (Screen::Numbers, p),
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
        }
    }
}

/// The station's points on the Changer screen, `$170`–`$175`.
const STATION_POINTS: u8 = 6;

/// The name of station point `p` (a `match`: a table of them would be
/// copied to RAM).
fn point_text(p: u8) -> Text {
    match p {
        0 => Text::PointX1,
        1 => Text::PointYA,
        2 => Text::PointYB,
        3 => Text::PointZ1,
        4 => Text::PointZ2,
        _ => Text::PointTravel,
    }
}

/// A Tools-menu command: one G-code line run through the machine.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum ToolOp {
    /// `M6 T<n>`: change to tool n (0 = empty the spindle).
    Change(u8),
    /// `G37` (length) or `G37 D1` (length and diameter) of the spindle tool.
    Measure { diameter: bool },
    /// `M61 Q<t>`: the spindle holds tool t (after an interrupted change).
    Confirm(u8),
    /// Jog menu: `G10 L20 P0 <axis>0`, the active work system's zero of
    /// axis 0..3 where the machine is.
    Zero(u8),
    /// Jog menu: probe Z down (G38.2 on the probe input, at most
    /// [`PROBE_Z_MM`]), then the Z work zero where it touched.
    ProbeZ,
    /// Jog menu: `G54` + n, work system n (0..6) active.
    Wcs(u8),
    /// An edit stored (the line is [`Edit::gcode`]'s).
    Store(Edit),
}

/// How far the menu's Z probe goes down at most, mm, and its feed, mm/min.
pub const PROBE_Z_MM: f32 = 20.0;
pub const PROBE_Z_FEED: f32 = 100.0;

impl ToolOp {
    /// Write the G-code line into `l` from column 0; returns its length.
    pub fn gcode(self, l: &mut Line) -> usize {
        match self {
            ToolOp::Change(t) => {
                // `M6 T<n>`: a T alone only selects the tool (RS274/NGC).
                let c = l.put(0, b"M6 T");
                l.uint(c, t as u32)
            }
            ToolOp::Confirm(t) => {
                let c = l.text(0, Text::LineM61Q);
                l.uint(c, t as u32)
            }
            ToolOp::Measure { diameter } => {
                let c = l.text(0, Text::LineG37D1);
                if diameter {
                    c
                } else {
                    3
                }
            }
            // The probe itself is the firmware's (`Machine::probe`); the
            // line is what follows it.
            ToolOp::Zero(_) | ToolOp::ProbeZ => {
                let a = if let ToolOp::Zero(a) = self { a } else { 2 };
                let c = l.text(0, Text::LineZero);
                l.put(c, &[b"XYZ"[a as usize % 3], b'0'])
            }
            ToolOp::Wcs(n) => l.put(0, &[b'G', b'5', b'4' + n % 6]),
            ToolOp::Store(_) => 0,
        }
    }

    /// The menu it came from.
    fn menu(self) -> MenuId {
        match self {
            ToolOp::Zero(_) | ToolOp::ProbeZ | ToolOp::Wcs(_) => MenuId::Jog,
            _ => MenuId::Tools,
        }
    }

    /// Its entry in the Tools menu (label and position).
    fn entry(self) -> (Text, u8) {
        match self {
            ToolOp::Change(_) => (Text::ChangeTool, 1),
            ToolOp::Measure { diameter: false } => (Text::MeasureLength, 2),
            ToolOp::Measure { diameter: true } => (Text::MeasureDia, 3),
            ToolOp::Confirm(_) => (Text::ConfirmSpindle, 5),
            ToolOp::Zero(_) => (Text::ZeroAxis, 4),
            ToolOp::ProbeZ => (Text::ProbeZ, 5),
            ToolOp::Wcs(_) => (Text::WorkSystem, 6),
            ToolOp::Store(Edit::Setting(_)) => (Text::Settings, 6),
            ToolOp::Store(Edit::Pocket(_)) => (Text::ToolNumbers, 7),
        }
    }
}

/// How the last Tools command went.
#[derive(Clone, Copy, PartialEq, Debug)]
pub enum Reply {
    /// Sent to the firmware, not finished yet.
    Pending,
    Ok,
    /// Refused or failed: the message printed after `Error:` (in flash).
    Err(FStr),
}

/// What the firmware should do after [`Ui::step`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Cmd {
    None,
    /// Read the card's file list again (the Files screen opened).
    ListFiles,
    /// Start SD file number i (directory order).
    RunFile(u8),
    Pause,
    Resume,
    Abort,
    /// Set the feed override, percent.
    Override(u16),
    /// Optional stop (M1 pauses) on or off.
    OptionalStop(bool),
    /// Move `axis` by `delta_um` micrometres.
    Jog {
        axis: u8,
        delta_um: i32,
    },
    /// Home the axes of the mask (bit 0 X, 1 Y, 2 Z).
    Home(u8),
    /// Run a Tools command; the firmware puts its outcome in [`Ui::reply`].
    /// A spindle confirmation (M61) clears an alarm first.
    Tool(ToolOp),
    /// Leave the alarm state (`$X`/M999; nothing outside an alarm).
    Unlock,
    /// Store the current position as station point `i` (`$170 + i`).
    Teach(u8),
    /// An edit screen opened: put the value as it is into
    /// [`Ui::edit_um`] ([`Edit::current`]).
    Edit(Edit),
    /// Store the edited value, thousandths ([`Edit::gcode`]); the firmware
    /// puts the outcome in [`Ui::reply`].
    Store(Edit, i32),
}

/// A snapshot of what the screens show, taken once per frame.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub state: State,
    /// Work position, µm.
    pub wpos_um: [i32; 3],
    pub tool: u8,
    /// Programmed feed with override, mm/min.
    pub feed: u16,
    pub override_pct: u16,
    /// Optional stop on: M1 pauses (`$152`).
    pub opt_stop: bool,
    /// The active work system, 0 (G54) … 5 (G59).
    pub wcs: u8,
    /// Spindle speed, rpm (0 = off).
    pub rpm: u16,
    pub job: Phase,
    pub job_pct: u8,
    pub job_name: Name,
    pub card_in: bool,
    /// Files on the card (after the last listing).
    pub files: u8,
    pub free_ram: u16,
    /// A tool change that did not finish and awaits M61 (`Atc::interrupted`).
    pub interrupted: Option<Journal>,
    /// The alarm in force, and for a hard limit the switches that were
    /// closed (bit i = axis i, `Machine::limit_axes`).
    pub alarm: Option<Alarm>,
    pub limit_axes: u8,
    /// X, Y and Z are homed.
    pub homed: bool,
}

impl View {
    pub const fn new() -> View {
        View {
            state: State::Idle,
            wpos_um: [0; 3],
            tool: 0,
            feed: 0,
            override_pct: 100,
            opt_stop: false,
            wcs: 0,
            rpm: 0,
            job: Phase::Idle,
            job_pct: 0,
            job_name: Name::EMPTY,
            card_in: false,
            files: 0,
            free_ram: 0,
            interrupted: None,
            alarm: None,
            limit_axes: 0,
            homed: true,
        }
    }

    fn job_active(&self) -> bool {
        matches!(self.job, Phase::Running | Phase::Paused | Phase::Draining(_) | Phase::Aborting(_))
    }

    /// A Tools command may start: no job, and the machine idle (or in alarm,
    /// where the machine itself answers with the alarm).
    fn may_run_tool(&self) -> bool {
        !self.job_active() && matches!(self.state, State::Idle | State::Alarm)
    }
}

impl Default for View {
    fn default() -> Self {
        View::new()
    }
}

/// 10^k.
fn pow10(k: u8) -> i32 {
    let mut p = 1;
    for _ in 0..k {
        p *= 10;
    }
    p
}

/// Jog steps, µm.
const JOG_STEPS_UM: [i32; 3] = [100, 1000, 10_000];

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

    fn go(&mut self, s: Screen) {
        self.screen = s;
        self.sel = 0;
        self.top = 0;
    }

    /// Entries in the current list screen (0 for non-list screens).
    fn entries(&self, v: &View) -> u8 {
        match self.screen {
            Screen::Menu(m) => m.len() as u8,
            Screen::Files => v.files + 1,
            Screen::ConfirmRun(_) | Screen::ConfirmAbort | Screen::AskTool(_) => 2,
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
    fn scroll(&mut self, d: i8, n: u8) {
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
                    if let ToolOp::Store(e) = op {
                        return self.open_edit(e);
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
            let (first, last) = if e.integer(m) { (3, 5) } else { (0, 6) };
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

    #[inline(never)]
    fn press(&mut self, v: &View) -> Cmd {
        let sel = self.sel;
        match self.screen {
            Screen::Menu(m) => self.act(m, m.item(sel as usize).1, v),
            Screen::Files => {
                if sel == 0 || !v.card_in {
                    self.back_to(MenuId::Main, 1);
                } else if v.job_active() {
                    self.go(Screen::Status);
                } else {
                    self.go(Screen::ConfirmRun(sel - 1));
                }
                Cmd::None
            }
            Screen::ConfirmRun(i) => {
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

    /// Text of `row` of the current screen. `file(i)` gives the name of
    /// file i (only the visible ones are asked for).
    #[inline(never)]
    pub fn line(&self, row: usize, v: &View, m: &Machine, file: &dyn Fn(u8) -> Option<Name>) -> Line {
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
                            let n = file(i).unwrap_or_default();
                            let c = l.put(c, n.as_bytes());
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
                    Screen::Override => {
                        if row == 2 {
                            l.uint_right(12, self.override_pct as u32);
                            l.text(12, Text::Pct);
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
                        } else if let Some(n) = file(e - 1) {
                            l.put(1, n.as_bytes());
                        }
                    }
                    Screen::Changer => {
                        if e == 0 {
                            l.text(1, Text::Back);
                        } else {
                            station_line(e - 1, &m.settings.station, &mut l);
                        }
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
    #[inline(never)]
    fn edit_line(&self, row: usize, ed: Edit, adjusting: bool, m: &Machine, l: &mut Line) {
        if row < EDIT_ROW {
            let what = match ed {
                Edit::Setting(n) => dollar::value(&m.settings, n).map(|(_, w)| w),
                Edit::Pocket(_) => Some(Text::NumberHelp.as_fstr()),
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
                l.text(1, if adjusting { Text::TurnToSet } else { Text::Value });
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
                l.text(1, Text::Save);
            }
        }
    }

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

fn paused(v: &View) -> bool {
    v.job == Phase::Paused || (!v.job_active() && v.state == State::Hold)
}

/// The machine state's name on the display.
/// (`Not homed` for Idle before the axes are homed: the position means
/// nothing yet.)
pub fn state_text(s: State, homed: bool) -> Text {
    match s {
        State::Idle if !homed => Text::StNotHomed,
        State::Idle | State::Check => Text::StIdle,
        State::Run | State::Jog => Text::StRun,
        State::Hold => Text::StHold,
        State::Alarm => Text::StAlarm,
        State::Home => Text::StHoming,
        State::Tool => Text::StTool,
        State::Probe => Text::StProbe,
    }
}

/// The status screen to read from a step away: the state and the tool,
/// the work position in double-size digits, then the feed (or the alarm).
#[inline(never)]
fn big_status_line(row: usize, v: &View, tool: u8, host: &crate::hostcodes::HostState, l: &mut Line) {
    match row {
        1..=6 => {
            let a = (row - 1) / 2;
            l.style = if row % 2 == 1 { Style::BigTop } else { Style::BigBottom };
            l.put(0, &[b"XYZ"[a]]);
            l.micros_right(BIG_COLS, v.wpos_um[a]);
        }
        7 if v.alarm.is_some() => alarm_line(v, l),
        7 => status_line(4, v, tool, host, l),
        _ => status_line(0, v, tool, host, l),
    }
}

#[inline(never)]
fn status_line(row: usize, v: &View, tool: u8, host: &crate::hostcodes::HostState, l: &mut Line) {
    match row {
        0 => {
            l.invert = true;
            l.style = Style::Title;
            l.text(1, state_text(v.state, v.homed));
            let c = l.put(COLS - 4, b"T");
            l.uint(c, tool as u32);
        }
        1..=3 => {
            l.put(0, &[b"XYZ"[row - 1]]);
            l.micros_right(12, v.wpos_um[row - 1]);
            l.text(12, Text::Mm);
        }
        4 => {
            l.put(0, b"F");
            l.uint_right(7, v.feed as u32);
            l.text(8, Text::MmMin);
            l.uint_right(COLS - 1, v.override_pct as u32);
            l.text(COLS - 1, Text::Pct);
        }
        // In an alarm the spindle is off: the line says which alarm.
        5 if v.alarm.is_some() => alarm_line(v, l),
        5 => {
            l.put(0, b"S");
            if v.rpm == 0 {
                l.text(2, Text::Off);
            } else {
                l.uint_right(7, v.rpm as u32);
                l.text(8, Text::Rpm);
            }
        }
        // An interrupted change outranks the job: nothing moves until confirmed.
        6 if v.interrupted.is_some() => {
            l.text(0, Text::ChangeCut);
        }
        // No SD job: what the host says (M117 message, M73 progress).
        6 if matches!(v.job, Phase::Idle | Phase::Writing) && (host.msg_len > 0 || host.percent().is_some()) => {
            l.put(0, host.message());
            if let Some(p) = host.percent() {
                l.put(COLS - 5, b"     ");
                l.uint_right(COLS - 1, p as u32);
                l.text(COLS - 1, Text::Pct);
            }
        }
        6 => job_status(v, l),
        7 => {
            l.text(
                0,
                if v.state == State::Alarm {
                    Text::HintRecover
                } else if v.interrupted.is_some() {
                    Text::HintConfirm
                } else if v.state == State::Hold && !matches!(v.job, Phase::Aborting(_)) {
                    Text::HintResume
                } else {
                    Text::HintMenu
                },
            );
        }
        _ => {}
    }
}

#[inline(never)]
fn job_status(v: &View, l: &mut Line) {
    let pct = |l: &mut Line| {
        l.uint_right(COLS - 1, v.job_pct as u32);
        l.text(COLS - 1, Text::Pct);
    };
    match v.job {
        Phase::Idle | Phase::Writing => {
            l.text(0, Text::NoJob);
        }
        Phase::Selected => {
            l.put(0, v.job_name.as_bytes());
        }
        Phase::Running | Phase::Draining(_) => {
            l.put(0, v.job_name.as_bytes());
            pct(l);
        }
        Phase::Paused => {
            l.text(0, Text::JobPaused);
            pct(l);
        }
        Phase::Aborting(Outcome::CardRemoved(n)) => {
            let c = l.text(0, Text::JobCardOut);
            l.uint(c, n);
        }
        Phase::Aborting(_) => {
            l.text(0, Text::JobStopping);
        }
        Phase::Ended(o) => match o {
            Outcome::Done => {
                let c = l.text(0, Text::JobDone);
                l.put(c + 1, v.job_name.as_bytes());
            }
            Outcome::Aborted => {
                l.text(0, Text::JobAborted);
            }
            Outcome::BadLine(n) => {
                let c = l.text(0, Text::JobLine);
                l.uint(c, n);
            }
            Outcome::ReadError(_) => {
                l.text(0, Text::JobReadErr);
            }
            Outcome::CardRemoved(n) => {
                let c = l.text(0, Text::JobCardOut);
                l.uint(c, n);
            }
        },
    }
}

/// Which alarm, in the operator's words; a hard limit names its switch.
#[inline(never)]
fn alarm_line(v: &View, l: &mut Line) {
    let t = match v.alarm {
        Some(Alarm::HardLimit) => Text::AlHardLimit,
        Some(Alarm::ProbeFailed) => Text::AlProbe,
        Some(Alarm::EmergencyStop) => Text::AlEstop,
        Some(Alarm::HomingFailed) => Text::AlHoming,
        Some(Alarm::WatchdogReset) => Text::AlWatchdog,
        Some(Alarm::CarouselHome) => Text::AlCarousel,
        Some(Alarm::BrokenTool) => Text::AlBrokenTool,
        Some(Alarm::ResetWhileMoving) => Text::AlResetMoving,
        None => return,
    };
    let mut c = l.text(0, t);
    if v.alarm == Some(Alarm::HardLimit) {
        for a in 0..3 {
            if v.limit_axes & (1 << a) != 0 {
                c = l.put(c + 1, &[b"XYZ"[a]]) - 1;
            }
        }
    }
}

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

/// " T<t>" at column 1 and, when given, a note after it; returns the
/// column after the number.
fn tool_and_note(l: &mut Line, m: &Machine, t: u8, note: Option<Text>) -> usize {
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
#[inline(never)]
fn pick_line(e: u8, confirm: bool, v: &View, m: &Machine, l: &mut Line) {
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
#[inline(never)]
fn table_line(t: u8, v: &View, m: &Machine, l: &mut Line) {
    let c = tool_and_note(l, m, t, None);
    if t == v.tool {
        l.chars[c] = b'*';
    }
    l.micros_right(12, m.atc.table.length_um(t));
    l.micros_right(COLS, m.atc.table.diameter_um(t) as i32);
}

/// The reply screen of a Tools command: the machine state while it runs,
/// then the result (tool in the spindle; the measured tool's table row) or
/// the refusal, word-wrapped.
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
            _ => {}
        },
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
#[inline(never)]
fn wrapped(msg: FStr, k: usize, l: &mut Line) {
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

/// Point `p` of the station (`$170 + p`) and its machine coordinate, as
/// `?` and `M114` show it (+Z up: the heights below the Z home switch
/// are negative).
#[inline(never)]
fn station_line(p: u8, s: &crate::config::Station, l: &mut Line) {
    l.text(1, point_text(p));
    let (mm, axis, _) = s.points()[p as usize % STATION_POINTS as usize];
    let user = if axis == 2 { -mm } else { mm };
    l.micros_right(COLS, crate::math::round_i32(user * 1000.0));
}

/// Setting `$n` and its value, as `$$` lists it (a flag or a mask as a
/// whole number).
#[inline(never)]
fn setting_line(n: u8, m: &Machine, l: &mut Line) {
    let c = l.put(1, b"$");
    l.uint(c, n as u32);
    match dollar::value(&m.settings, n) {
        Some((dollar::Value::Num(x), _)) => l.micros_right(COLS, crate::math::round_i32(x * 1000.0)),
        Some((v, _)) => l.uint_right(COLS, (v.micros() / 1000) as u32),
        None => {}
    }
}

/// Tool number `t` as `T20`, or "none" for 0, right-aligned before `end`.
fn number_text(t: u8, end: usize, l: &mut Line) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn screen(ui: &Ui, v: &View) -> Vec<String> {
        screen_of(ui, v, &Machine::new())
    }

    fn screen_of(ui: &Ui, v: &View, m: &Machine) -> Vec<String> {
        let names = |i: u8| Name::parse(format!("FILE{i}.NC").as_bytes());
        (0..ROWS)
            .map(|r| {
                let l = ui.line(r, v, m, &names);
                let s = String::from_utf8(l.chars.to_vec()).unwrap();
                if l.invert {
                    format!("[{}]", s.trim_end())
                } else {
                    s.trim_end().to_string()
                }
            })
            .collect()
    }

    #[test]
    fn the_menu_tree_is_laid_out_as_the_spec_says() {
        assert_eq!(MenuId::Main.len(), 8);
        assert_eq!(MenuId::Main.item(1), (Text::RunFromSd, Act::Files));
        assert_eq!(MenuId::Main.item(5), (Text::Tools, Act::ToolsMenu));
        assert_eq!(MenuId::Main.item(7), (Text::Info, Act::Info));
        assert_eq!(MenuId::Tools.len(), 8);
        assert_eq!(MenuId::Jog.len(), 7);
        assert_eq!(MenuId::Jog.item(4), (Text::ZeroAxis, Act::ZeroAxis));
        assert_eq!(MenuId::Tools.item(5), (Text::ConfirmSpindle, Act::ConfirmSpindle));
        assert_eq!(MenuId::Tools.item(6), (Text::Changer, Act::Changer));
        assert_eq!(MenuId::Tools.item(7), (Text::ToolNumbers, Act::ToolNumbers));
        assert_eq!(MenuId::Job.item(2), (Text::Abort, Act::Abort));
        assert_eq!(MenuId::Home.item(4), (Text::HomeX, Act::HomeX));
    }

    #[test]
    fn every_menu_entry_reads_back_as_a_text_and_an_action() {
        for [t, a] in ITEMS {
            assert!(Text::from_u8(t).is_some() && Act::from_u8(a).is_some(), "entry {t} {a}");
        }
        for b in 0..=255u8 {
            assert_eq!(Act::from_u8(b).map(|a| a as u8), (b <= Act::OptStop as u8).then_some(b), "{b}");
        }
    }

    #[test]
    fn status_screen_shows_state_position_feed_spindle_and_job() {
        let mut v = View::new();
        v.state = State::Run;
        v.wpos_um = [12_345, -5, 45_000];
        v.tool = 3;
        v.feed = 1200;
        v.override_pct = 90;
        v.rpm = 10300;
        v.job = Phase::Running;
        v.job_pct = 45;
        v.job_name = Name::parse(b"PART.NC").unwrap();
        let s = screen(&Ui::new(), &v);
        assert_eq!(s[0], "[ Run             T3]");
        assert_eq!(s[1], "X     12.345 mm");
        assert_eq!(s[2], "Y     -0.005 mm");
        assert_eq!(s[3], "Z     45.000 mm");
        assert_eq!(s[4], "F  1200 mm/min    90%");
        assert_eq!(s[5], "S 10300 rpm");
        assert_eq!(s[6], "PART.NC           45%");
        v.job = Phase::Ended(Outcome::BadLine(40));
        assert_eq!(screen(&Ui::new(), &v)[6], "Stopped: line 40");
    }

    #[test]
    fn status_screen_shows_the_host_message_and_progress_when_no_sd_job_runs() {
        let v = View::new();
        let mut m = Machine::new();
        assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "No job");
        m.host.set_message(b"Layer 3 of 10: roughing");
        assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "Layer 3 of 10: rough");
        m.host.pct = 7;
        assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "Layer 3 of 10: r   7%");
        m.host.set_message(b"");
        assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "                   7%".trim_end());
        // An SD job shows its own name and progress.
        let mut v = v;
        v.job = Phase::Running;
        v.job_pct = 45;
        v.job_name = Name::parse(b"PART.NC").unwrap();
        assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "PART.NC           45%");
    }

    #[test]
    fn choosing_a_file_asks_for_confirmation_then_runs_it() {
        let mut ui = Ui::new();
        let mut v = View::new();
        v.card_in = true;
        v.files = 3;
        assert_eq!(ui.step(0, true, &v), Cmd::None); // status -> menu
        assert_eq!(ui.step(1, true, &v), Cmd::ListFiles); // "Run from SD"
        assert_eq!(ui.screen, Screen::Files);
        assert_eq!(screen(&ui, &v)[1..4], ["[ < Back]", " FILE0.NC", " FILE1.NC"]);
        ui.step(2, false, &v);
        assert_eq!(ui.step(0, true, &v), Cmd::None);
        assert_eq!(ui.screen, Screen::ConfirmRun(1));
        assert_eq!(screen(&ui, &v)[0], "[ Run FILE1.NC?]");
        assert_eq!(ui.step(1, true, &v), Cmd::RunFile(1));
        assert_eq!(ui.screen, Screen::Status);
    }

    #[test]
    fn a_long_file_list_scrolls_with_the_selection() {
        let mut ui = Ui::new();
        let mut v = View::new();
        v.card_in = true;
        v.files = 20;
        ui.go(Screen::Files);
        ui.step(9, false, &v);
        assert_eq!((ui.sel, ui.top), (9, 3));
        assert_eq!(ui.visible_files(), (2, 7));
        assert_eq!(screen(&ui, &v)[7], "[ FILE8.NC]");
        ui.step(100, false, &v);
        assert_eq!(ui.sel, 20);
        ui.step(-100, false, &v);
        assert_eq!((ui.sel, ui.top), (0, 0));
    }

    #[test]
    fn abort_needs_a_confirmation_and_pause_turns_into_resume() {
        let mut ui = Ui::new();
        let mut v = View::new();
        v.job = Phase::Running;
        ui.go(Screen::Menu(MenuId::Job));
        assert_eq!(ui.step(1, true, &v), Cmd::Pause);
        v.job = Phase::Paused;
        assert_eq!(screen(&ui, &v)[2], "[ Resume]");
        assert_eq!(ui.step(0, true, &v), Cmd::Resume);
        ui.step(1, true, &v);
        assert_eq!(ui.screen, Screen::ConfirmAbort);
        assert_eq!(ui.step(0, true, &v), Cmd::None); // "No" is the default
        assert_eq!(ui.screen, Screen::Menu(MenuId::Job));
        ui.step(2, true, &v);
        assert_eq!(ui.step(1, true, &v), Cmd::Abort);
    }

    /// Optional stop (M1) is a Job-menu switch, the same
    /// setting as `$152`.
    #[test]
    fn optional_stop_is_switched_in_the_job_menu() {
        let mut ui = Ui::new();
        let mut v = View::new();
        ui.go(Screen::Menu(MenuId::Job));
        assert_eq!(screen(&ui, &v)[5].trim_end(), " Opt. stop M1     off");
        assert_eq!(ui.step(4, true, &v), Cmd::OptionalStop(true));
        v.opt_stop = true;
        assert_eq!(screen(&ui, &v)[5], "[ Opt. stop M1      on]");
        assert_eq!(ui.step(0, true, &v), Cmd::OptionalStop(false));
    }

    #[test]
    fn feed_override_is_set_in_steps_of_five() {
        let mut ui = Ui::new();
        let v = View::new();
        ui.go(Screen::Menu(MenuId::Job));
        ui.step(3, true, &v);
        assert_eq!(ui.screen, Screen::Override);
        ui.step(-4, false, &v);
        assert_eq!(screen(&ui, &v)[2], "          80%");
        assert_eq!(ui.step(0, true, &v), Cmd::Override(80));
    }

    #[test]
    fn jogging_moves_by_the_step_per_detent_and_home_needs_idle() {
        let mut ui = Ui::new();
        let mut v = View::new();
        ui.go(Screen::Menu(MenuId::Jog));
        ui.step(1, true, &v); // axis X -> Y
        ui.step(1, true, &v); // step 1 -> 10 mm
        assert_eq!(screen(&ui, &v)[2..4], [" Axis Y", "[ Step 10 mm]"]);
        ui.step(1, true, &v); // jog now
        assert_eq!(ui.screen, Screen::Jogging);
        assert_eq!(ui.step(-2, false, &v), Cmd::Jog { axis: 1, delta_um: -20_000 });
        ui.step(0, true, &v);
        ui.go(Screen::Menu(MenuId::Home));
        v.state = State::Run;
        assert_eq!(ui.step(2, true, &v), Cmd::None);
        v.state = State::Idle;
        assert_eq!(ui.step(0, true, &v), Cmd::Home(0b100));
    }

    #[test]
    fn info_and_settings_are_views() {
        let mut ui = Ui::new();
        let mut v = View::new();
        v.free_ram = 1234;
        ui.go(Screen::Info);
        let s = screen(&ui, &v);
        assert_eq!(s[4], " Free RAM 1234 B");
        ui.go(Screen::Settings);
        let s = screen(&ui, &v);
        assert_eq!(s[1..4], ["[ < Back]", " $3                 0", " $5                 0"], "{s:?}");
        ui.step(0, true, &v);
        assert_eq!(ui.screen, Screen::Menu(MenuId::Main));
    }

    /// What the firmware does after each encoder step (`firmware.rs`).
    fn edit_step(ui: &mut Ui, d: i8, press: bool, v: &View, m: &Machine) -> Cmd {
        let c = ui.step(d, press, v);
        if let Cmd::Edit(e) = c {
            ui.edit_um = e.current(m);
        }
        ui.fit_edit(m);
        c
    }

    #[test]
    fn every_setting_is_listed_in_order_and_read_like_dollar_dollar() {
        let mut s = crate::config::Settings::default();
        let n: Vec<u8> = (0..dollar::count()).map(dollar::nth).collect();
        let listed: Vec<u8> = (0..=255).filter(|&k| dollar::field(&mut s, k).is_some()).collect();
        assert_eq!(n, listed);
        assert!(n.len() > 30, "{n:?}");
        let m = Machine::new();
        let mut ui = Ui::new();
        ui.go(Screen::Settings);
        let i = n.iter().position(|&k| k == 110).unwrap() as i8;
        ui.scroll(i + 1, dollar::count() + 1);
        let s = screen_of(&ui, &View::new(), &m);
        assert_eq!(s[7], format!("[ $110{:>16}]", format!("{:.3}", m.settings.max_feed_mm_per_min[0])), "{s:?}");
    }

    #[test]
    fn a_setting_is_edited_with_the_encoder_and_stored_through_its_dollar_line() {
        let m = Machine::new();
        let v = View::new();
        let mut ui = Ui::new();
        ui.go(Screen::Settings);
        let i = (0..dollar::count()).position(|k| dollar::nth(k) == 170).unwrap() as i8;
        assert_eq!(edit_step(&mut ui, i + 1, true, &v, &m), Cmd::Edit(Edit::Setting(170)));
        let s = screen_of(&ui, &v, &m);
        assert_eq!(s[0], "[ $170]");
        assert_eq!(s[1..4].join(" ").split_whitespace().collect::<Vec<_>>().join(" "), "tool change X1 (in front of the magazine), mm");
        assert_eq!(s[4..8], [" < Back", "[ Value         23.000]", " Step           1.000", " Save"], "{s:?}");
        // Press: the value turns; 7 detents of 1, then the step 0.1 (4
        // presses round from 1: 10, 100, 1000, 0.001 … 0.1) and 5 more.
        edit_step(&mut ui, 0, true, &v, &m);
        assert_eq!(screen_of(&ui, &v, &m)[5], "[ Turn >        23.000]");
        edit_step(&mut ui, 7, true, &v, &m);
        assert_eq!(screen_of(&ui, &v, &m)[5], "[ Value         30.000]");
        edit_step(&mut ui, 1, false, &v, &m);
        for _ in 0..6 {
            edit_step(&mut ui, 0, true, &v, &m);
        }
        assert_eq!(screen_of(&ui, &v, &m)[6], "[ Step           0.100]");
        edit_step(&mut ui, -1, true, &v, &m);
        edit_step(&mut ui, 5, true, &v, &m);
        assert_eq!(screen_of(&ui, &v, &m)[5], "[ Value         30.500]");
        // Save: the line `$170=30.500`, the same as over serial.
        let c = edit_step(&mut ui, 2, true, &v, &m);
        assert_eq!(c, Cmd::Store(Edit::Setting(170), 30_500));
        let mut l = Line::blank();
        let n = Edit::Setting(170).gcode(30_500, None, &mut l);
        assert_eq!(&l.chars[..n], b"$170=30.500");
        assert_eq!(ui.screen, Screen::Reply(ToolOp::Store(Edit::Setting(170))));
        // The reply; a press goes back to the edit screen.
        ui.reply = Reply::Ok;
        edit_step(&mut ui, 0, true, &v, &m);
        assert_eq!(ui.screen, Screen::Edit(Edit::Setting(170), false));
        // Back: the list, on $170.
        edit_step(&mut ui, -1, true, &v, &m);
        assert_eq!(ui.screen, Screen::Settings);
        assert_eq!(dollar::nth(ui.sel - 1), 170);
    }

    #[test]
    fn flags_and_masks_turn_within_their_range_in_whole_steps() {
        let m = Machine::new();
        let v = View::new();
        let mut ui = Ui::new();
        ui.go(Screen::Settings);
        // $5 (mask, 0..31).
        edit_step(&mut ui, 2, true, &v, &m);
        assert_eq!(ui.screen, Screen::Edit(Edit::Setting(5), false));
        edit_step(&mut ui, 0, true, &v, &m);
        edit_step(&mut ui, 40, false, &v, &m);
        assert_eq!(ui.edit_um, 31_000);
        assert_eq!(screen_of(&ui, &v, &m)[5], "[ Turn >            31]");
        edit_step(&mut ui, -50, true, &v, &m);
        assert_eq!(ui.edit_um, 0);
        // The step goes 1, 10, 100, 1.
        edit_step(&mut ui, 1, false, &v, &m);
        for want in ["10", "100", "1"] {
            edit_step(&mut ui, 0, true, &v, &m);
            assert_eq!(screen_of(&ui, &v, &m)[6], format!("[ Step{want:>16}]"));
        }
    }

    #[test]
    fn a_pockets_tool_number_is_edited_and_stored_as_g10_l1_lines() {
        let m = Machine::new();
        let v = View::new();
        let mut ui = Ui::new();
        tools_entry(&mut ui, &v, 7);
        assert_eq!(ui.screen, Screen::Numbers);
        let s = screen_of(&ui, &v, &m);
        assert_eq!(s[0..3], ["[ Tool numbers]", "[ < Back]", " Pocket 1          T1"], "{s:?}");
        edit_step(&mut ui, 5, true, &v, &m);
        assert_eq!(ui.screen, Screen::Edit(Edit::Pocket(5), false));
        assert_eq!(screen_of(&ui, &v, &m)[0], "[ Pocket 5]");
        assert_eq!(screen_of(&ui, &v, &m)[5], "[ Value             T5]");
        edit_step(&mut ui, 0, true, &v, &m);
        edit_step(&mut ui, 15, true, &v, &m);
        assert_eq!(ui.edit_um, 20_000);
        edit_step(&mut ui, 2, false, &v, &m);
        assert_eq!(edit_step(&mut ui, 0, true, &v, &m), Cmd::Store(Edit::Pocket(5), 20_000));
        let line = |clear| {
            let mut l = Line::blank();
            let n = Edit::Pocket(5).gcode(20_000, clear, &mut l);
            String::from_utf8(l.chars[..n].to_vec()).unwrap()
        };
        assert_eq!(line(Some(5)), "G10 L1 P5 Q0");
        assert_eq!(line(None), "G10 L1 P20 Q5");
        // 0 reads "none"; no further than 254.
        let mut ui = Ui::new();
        ui.go(Screen::Numbers);
        edit_step(&mut ui, 1, true, &v, &m);
        edit_step(&mut ui, 0, true, &v, &m);
        edit_step(&mut ui, -3, false, &v, &m);
        assert_eq!(screen_of(&ui, &v, &m)[5], "[ Turn >          none]");
        ui.edit_step = 5;
        edit_step(&mut ui, 9, false, &v, &m);
        assert_eq!(ui.edit_um, 254_000);
    }

    /// Open the Tools menu from the status screen and press entry `i`.
    fn tools_entry(ui: &mut Ui, v: &View, i: i8) -> Cmd {
        *ui = Ui::new();
        // The main menu (a press on the status screen, outside an alarm).
        ui.go(Screen::Menu(MenuId::Main));
        ui.step(5, true, v); // Tools
        assert_eq!(ui.screen, Screen::Menu(MenuId::Tools));
        ui.step(i, true, v)
    }

    #[test]
    fn tools_menu_lists_change_measure_table_and_confirm() {
        let mut ui = Ui::new();
        let v = View::new();
        tools_entry(&mut ui, &v, 0);
        assert_eq!(ui.screen, Screen::Menu(MenuId::Main), "< Back");
        assert_eq!(ui.sel, 5, "back on Tools");
        ui.step(0, true, &v);
        let s = screen(&ui, &v);
        assert_eq!(
            s[..7],
            ["[ Tools]", "[ < Back]", " Change tool", " Measure length", " Measure len+dia", " Tool table", " Confirm spindle"]
        );
    }

    #[test]
    fn change_tool_picks_a_tool_asks_then_runs_t_n_and_shows_the_outcome() {
        let mut ui = Ui::new();
        let mut v = View::new();
        let mut m = Machine::new();
        v.tool = 3;
        m.atc.tools.spindle = 3;
        m.atc.tools.occupied &= !(crate::atc::tools::pocket_bit(3) | crate::atc::tools::pocket_bit(6));
        assert_eq!(tools_entry(&mut ui, &v, 1), Cmd::None);
        assert_eq!(ui.screen, Screen::PickTool(false));
        let s = screen_of(&ui, &v, &m);
        assert_eq!(s[0], "[ Change tool]");
        assert_eq!(s[1..6], [" < Back", " T0 no tool", " T1", " T2", "[ T3 in spindle]"], "opens on the spindle tool");
        ui.step(3, false, &v);
        assert_eq!(screen_of(&ui, &v, &m)[7], "[ T6 pocket empty]");
        // T2: "Change to T2?", No goes back to the list on T2.
        ui.step(-4, true, &v);
        assert_eq!(ui.screen, Screen::AskTool(ToolOp::Change(2)));
        assert_eq!(screen(&ui, &v)[0..3], ["[ Change to T2?]", "[ No]", " Yes"]);
        assert_eq!(ui.step(0, true, &v), Cmd::None);
        assert_eq!((ui.screen, ui.sel), (Screen::PickTool(false), 3));
        ui.step(0, true, &v);
        assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Change(2)));
        assert_eq!((ui.screen, ui.reply), (Screen::Reply(ToolOp::Change(2)), Reply::Pending));
        // While it runs: the state; presses do nothing.
        v.state = State::Tool;
        assert_eq!(screen(&ui, &v)[0..3], ["[ Change tool]", "", " Tool change"]);
        assert_eq!(ui.step(1, true, &v), Cmd::None);
        assert_eq!(ui.screen, Screen::Reply(ToolOp::Change(2)));
        // Done.
        v.state = State::Idle;
        v.tool = 2;
        ui.reply = Reply::Ok;
        let s = screen(&ui, &v);
        assert_eq!((s[2].as_str(), s[7].as_str()), (" T2 in spindle", "Press: back"));
        ui.step(0, true, &v);
        assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 1));
    }

    #[test]
    fn a_refused_change_shows_the_machine_error_word_wrapped() {
        let mut ui = Ui::new();
        let v = View::new();
        tools_entry(&mut ui, &v, 1);
        ui.step(1, true, &v);
        assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Change(1)));
        ui.reply = Reply::Err(crate::atc::Fault::PocketEmpty.message());
        let s = screen(&ui, &v);
        // "pocket of that tool is empty (M61 P<n> S1 if loaded)"
        assert_eq!(s[2..6], [" pocket of that tool", " is empty (M61 P<n>", " S1 if loaded)", ""]);
        let long = crate::gcode::interp::Error::NotHomed.message();
        ui.reply = Reply::Err(long);
        let s = screen(&ui, &v);
        assert_eq!(s[2..6], [" not homed: home", " (G28) or unlock", " (M999) first,", " nothing moved"]);
        // A word longer than a line is cut.
        let mut l = Line::blank();
        wrapped(F!("a abcdefghijklmnopqrstuvwxyz b"), 1, &mut l);
        assert_eq!(String::from_utf8(l.chars.to_vec()).unwrap(), " abcdefghijklmnopqrst");
        let mut l = Line::blank();
        wrapped(F!("a abcdefghijklmnopqrstuvwxyz b"), 2, &mut l);
        assert_eq!(String::from_utf8(l.chars.to_vec()).unwrap().trim_end(), " b");
    }

    #[test]
    fn tool_commands_are_refused_while_the_machine_is_busy() {
        let mut ui = Ui::new();
        let mut v = View::new();
        v.state = State::Run;
        assert_eq!(tools_entry(&mut ui, &v, 2), Cmd::None);
        assert_eq!(ui.screen, Screen::Reply(ToolOp::Measure { diameter: false }));
        assert_eq!(screen(&ui, &v)[2], " Machine busy");
        v.state = State::Idle;
        v.job = Phase::Running;
        ui.step(0, true, &v);
        assert_eq!(ui.sel, 2, "back on Measure length");
        assert_eq!(ui.step(1, true, &v), Cmd::None, "measure during an SD job");
        // In alarm the machine itself answers (with the alarm).
        v.job = Phase::Idle;
        v.state = State::Alarm;
        assert_eq!(tools_entry(&mut ui, &v, 3), Cmd::Tool(ToolOp::Measure { diameter: true }));
    }

    #[test]
    fn measuring_runs_g37_or_g37_d1_and_shows_the_table_entry() {
        let mut ui = Ui::new();
        let mut v = View::new();
        let mut m = Machine::new();
        v.tool = 4;
        m.atc.table.length_um[3] = 24_511;
        m.atc.table.diameter_um[3] = 1_590;
        assert_eq!(tools_entry(&mut ui, &v, 2), Cmd::Tool(ToolOp::Measure { diameter: false }));
        ui.reply = Reply::Ok;
        let s = screen_of(&ui, &v, &m);
        assert_eq!(s[0..5], ["[ Measure length]", "", " T      L mm     D mm", " T4*  24.511    1.590", ""]);
        assert_eq!(tools_entry(&mut ui, &v, 3), Cmd::Tool(ToolOp::Measure { diameter: true }));
        ui.reply = Reply::Ok;
        let s = screen_of(&ui, &v, &m);
        assert_eq!(s[0..4], ["[ Measure len+dia]", "", " T      L mm     D mm", " T4*  24.511    1.590"]);
        ui.step(0, true, &v);
        assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 3));
    }

    #[test]
    fn tool_ops_are_the_gcode_lines_of_the_serial_commands() {
        let line = |op: ToolOp| {
            let mut l = Line::blank();
            let n = op.gcode(&mut l);
            String::from_utf8(l.chars[..n].to_vec()).unwrap()
        };
        assert_eq!(line(ToolOp::Change(2)), "M6 T2");
        assert_eq!(line(ToolOp::Change(12)), "M6 T12");
        assert_eq!(line(ToolOp::Measure { diameter: false }), "G37");
        assert_eq!(line(ToolOp::Measure { diameter: true }), "G37 D1");
        assert_eq!(line(ToolOp::Confirm(0)), "M61 Q0");
        for t in 0..=12u8 {
            let g = line(ToolOp::Change(t));
            let l = crate::gcode::parse(g.as_bytes()).unwrap();
            assert_eq!(l.tool(), Some(t));
        }
    }

    #[test]
    fn the_tool_table_scrolls_through_t1_to_t12() {
        let mut ui = Ui::new();
        let mut v = View::new();
        let mut m = Machine::new();
        v.tool = 3;
        m.atc.table.length_um[2] = 25_000;
        m.atc.table.diameter_um[2] = 2_000;
        m.atc.table.length_um[11] = 105_250;
        tools_entry(&mut ui, &v, 4);
        assert_eq!(ui.screen, Screen::ToolTable);
        let s = screen_of(&ui, &v, &m);
        assert_eq!(s[0], "[ T      L mm     D mm]");
        assert_eq!(s[1], " T1    0.000    0.000");
        assert_eq!(s[3], " T3*  25.000    2.000");
        assert_eq!(s[7], " T7    0.000    0.000");
        ui.step(100, false, &v);
        let s = screen_of(&ui, &v, &m);
        assert_eq!((s[1].as_str(), s[7].as_str()), (" T6    0.000    0.000", " T12 105.250    0.000"));
        ui.step(-1, false, &v);
        assert_eq!(screen_of(&ui, &v, &m)[1], " T5    0.000    0.000");
        ui.step(0, true, &v);
        assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 4));
    }

    #[test]
    fn confirm_spindle_works_only_after_an_interrupted_change_and_sends_m61() {
        let mut ui = Ui::new();
        let mut v = View::new();
        // Nothing interrupted: it says so.
        assert_eq!(tools_entry(&mut ui, &v, 5), Cmd::None);
        let s = screen(&ui, &v);
        assert_eq!(s[0..4], ["[ Confirm spindle]", "", " No interrupted tool", " change"]);
        // Interrupted T2 -> T5: the status screen says so.
        v.interrupted = Some(Journal { from: 2, to: 5 });
        let s = screen(&Ui::new(), &v);
        assert_eq!(s[6..8], ["Change interrupted:", "Tools>Confirm spindle"]);
        ui.step(0, true, &v);
        assert_eq!(ui.step(0, true, &v), Cmd::None);
        assert_eq!(ui.screen, Screen::PickTool(true));
        let s = screen(&ui, &v);
        assert_eq!(s[0..5], ["[ In spindle now?]", "[ < Back]", " T0 no tool", " T1", " T2 old tool"]);
        assert_eq!(s[7], " T5 new tool");
        ui.step(1, true, &v);
        assert_eq!(screen(&ui, &v)[0], "[ Spindle holds T0?]");
        assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Confirm(0)));
        assert_eq!(ui.screen, Screen::Reply(ToolOp::Confirm(0)));
        // In alarm (M112 mid-change) the confirmation still goes to the machine.
        v.state = State::Alarm;
        tools_entry(&mut ui, &v, 5);
        ui.step(3, true, &v);
        assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Confirm(2)));
    }

    #[test]
    fn in_an_alarm_the_status_screen_names_it_and_a_press_opens_the_way_out() {
        let mut ui = Ui::new();
        let mut v = View::new();
        v.state = State::Alarm;
        v.alarm = Some(Alarm::HardLimit);
        v.limit_axes = 0b001;
        let s = screen(&ui, &v);
        assert_eq!(s[0], "[ ALARM           T0]");
        assert_eq!(s[5], "Hard limit X");
        assert_eq!(s[7], "Press to recover");
        v.limit_axes = 0b110;
        assert_eq!(screen(&ui, &v)[5], "Hard limit YZ");
        v.alarm = Some(Alarm::ProbeFailed);
        assert_eq!(screen(&ui, &v)[5], "Probe missed");
        assert_eq!(ui.step(0, true, &v), Cmd::None);
        assert_eq!(ui.screen, Screen::Menu(MenuId::Alarm));
        assert_eq!(screen(&ui, &v)[..6], ["[ Alarm]", "[ Status]", " Unlock", " Home all", " Jog", " Confirm spindle"]);
        // Unlock: back on the status screen.
        assert_eq!(ui.step(1, true, &v), Cmd::Unlock);
        assert_eq!(ui.screen, Screen::Status);
        // Home all homes from the alarm.
        ui.step(0, true, &v);
        assert_eq!(ui.step(2, true, &v), Cmd::Home(0b111));
        // Jog unlocks and opens the Jog menu.
        ui.step(0, true, &v);
        assert_eq!(ui.step(3, true, &v), Cmd::Unlock);
        assert_eq!(ui.screen, Screen::Menu(MenuId::Jog));
        // Confirm spindle opens the tool list.
        ui.go(Screen::Status);
        v.interrupted = Some(Journal { from: 1, to: 2 });
        ui.step(0, true, &v);
        ui.step(4, true, &v);
        assert_eq!(ui.screen, Screen::PickTool(true));
        // < Status goes back.
        ui.go(Screen::Status);
        ui.step(0, true, &v);
        assert_eq!(ui.step(0, true, &v), Cmd::None);
        assert_eq!(ui.screen, Screen::Status);
    }

    #[test]
    fn a_card_pulled_mid_job_shows_the_line_it_stopped_at() {
        let ui = Ui::new();
        let mut v = View::new();
        v.state = State::Hold;
        v.job = Phase::Aborting(Outcome::CardRemoved(41));
        let s = screen(&ui, &v);
        assert_eq!(s[6], "Card out: line 41");
        assert_eq!(s[7], "Press for menu", "no resume offered");
        v.state = State::Idle;
        v.job = Phase::Ended(Outcome::CardRemoved(41));
        assert_eq!(screen(&ui, &v)[6], "Card out: line 41");
    }
}
