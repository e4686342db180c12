//! The menu tree (SPEC §9) as data, and the state machine the encoder drives.
//!
//! ```text
//!  Status ──press──► Menu: < Status | Run from SD | Job | Jog | Home | Settings | Info
//!    Run from SD: < Back, files (scrolling) ──► "Run NAME?" No/Yes
//!    Job:  < Back | Pause/Resume | Abort ──► "Abort the job?" No/Yes | Feed override nnn%
//!    Jog:  < Back | Axis X/Y/Z | Step 0.1/1/10 mm | Jog now (turn = move, press = done)
//!    Home: < Back | Home all | Home Z | Home Y | Home X
//!    Settings (view, scrolling), Info (version, free RAM, card)
//! ```
//!
//! [`Ui::step`] takes what the encoder did (detents, presses) and returns a
//! [`Cmd`] for the firmware to carry out; [`Ui::line`] gives the text of any
//! row of the current screen from a [`View`] (a snapshot of the machine
//! taken once per frame). Tool-changer entries are left out until the tool
//! changer lands.

use super::flash;
use super::render::{Line, COLS, ROWS};
use super::sd::{Name, Outcome, Phase};
use super::text::Text;
use crate::config::Settings;
use crate::machine::State;

/// What an entry does when pressed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[repr(u8)]
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
}

/// The menus with fixed entries.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[repr(u8)]
pub enum MenuId {
    Main,
    Job,
    Jog,
    Home,
}

const fn item(t: Text, a: Act) -> [u8; 2] {
    [t as u8, a as u8]
}

/// Every fixed entry, menu after menu (see MENU_START), in flash.
#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
static ITEMS: [[u8; 2]; 20] = [
    // Main
    item(Text::Status, Act::Back),
    item(Text::RunFromSd, Act::Files),
    item(Text::Job, Act::JobMenu),
    item(Text::Jog, Act::JogMenu),
    item(Text::Home, Act::HomeMenu),
    item(Text::Settings, Act::Settings),
    item(Text::Info, Act::Info),
    // Job
    item(Text::Back, Act::Back),
    item(Text::Pause, Act::PauseResume),
    item(Text::Abort, Act::Abort),
    item(Text::FeedOverride, Act::Override),
    // Jog
    item(Text::Back, Act::Back),
    item(Text::Axis, Act::JogAxis),
    item(Text::Step, Act::JogStep),
    item(Text::JogNow, Act::JogNow),
    // Home
    item(Text::Back, Act::Back),
    item(Text::HomeAll, Act::HomeAll),
    item(Text::HomeZ, Act::HomeZ),
    item(Text::HomeY, Act::HomeY),
    item(Text::HomeX, Act::HomeX),
];

/// First entry of each menu in ITEMS, plus the end.
#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
static MENU_START: [u8; 5] = [0, 7, 11, 15, 20];

impl MenuId {
    fn range(self) -> (usize, usize) {
        let i = self as usize;
        // SAFETY: i + 1 < 5.
        let a = flash::read_byte(unsafe { MENU_START.as_ptr().add(i) }) as usize;
        // SAFETY: as above.
        let b = flash::read_byte(unsafe { MENU_START.as_ptr().add(i + 1) }) as usize;
        (a, b)
    }

    /// Number of entries.
    pub fn len(self) -> usize {
        let (a, b) = self.range();
        b - a
    }

    /// Entry `i`: its label and action.
    pub fn item(self, i: usize) -> (Text, Act) {
        let (a, _) = self.range();
        let p = ITEMS.as_ptr() as *const u8;
        // SAFETY: a + i is an entry of ITEMS; both bytes were made from a
        // Text and an Act (repr(u8)) by `item`, so they are valid values.
        unsafe {
            let t = flash::read_byte(p.add(2 * (a + i)));
            let c = flash::read_byte(p.add(2 * (a + i) + 1));
            (core::mem::transmute::<u8, Text>(t), core::mem::transmute::<u8, Act>(c))
        }
    }

    fn title(self) -> Text {
        match self {
            MenuId::Main => Text::MainMenu,
            MenuId::Job => Text::Job,
            MenuId::Jog => Text::Jog,
            MenuId::Home => Text::Home,
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
    Settings,
    Info,
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
    /// Move `axis` by `delta_um` micrometres.
    Jog { axis: u8, delta_um: i32 },
    /// Home the axes of the mask (bit 0 X, 1 Y, 2 Z).
    Home(u8),
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
    /// Spindle speed, rpm (0 = off).
    pub rpm: u16,
    pub job: Phase,
    pub job_pct: u8,
    pub job_name: Name,
    pub card_in: bool,
    /// Files on the card (after the last listing).
    pub files: u8,
    pub free_ram: u16,
}

impl View {
    pub const fn new() -> View {
        View {
            state: State::Idle,
            wpos_um: [0; 3],
            tool: 0,
            feed: 0,
            override_pct: 100,
            rpm: 0,
            job: Phase::Idle,
            job_pct: 0,
            job_name: Name::EMPTY,
            card_in: false,
            files: 0,
            free_ram: 0,
        }
    }

    fn job_active(&self) -> bool {
        matches!(self.job, Phase::Running | Phase::Paused | Phase::CardLost | Phase::Draining(_) | Phase::Aborting(_))
    }
}

impl Default for View {
    fn default() -> Self {
        View::new()
    }
}

/// Jog steps, µm.
const JOG_STEPS_UM: [i32; 3] = [100, 1000, 10_000];

/// The UI state machine. RAM: 8 bytes.
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
}

impl Default for Ui {
    fn default() -> Self {
        Ui::new()
    }
}

/// List rows below the title.
const LIST_ROWS: u8 = (ROWS - 1) as u8;
/// Entries on the Settings screen.
const SETTINGS_LINES: u8 = 13;

impl Ui {
    pub const fn new() -> Ui {
        Ui { screen: Screen::Status, sel: 0, top: 0, jog_axis: 0, jog_step: 1, override_pct: 100 }
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
            Screen::ConfirmRun(_) | Screen::ConfirmAbort => 2,
            Screen::Settings => SETTINGS_LINES,
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
                    self.back_to_main(6);
                }
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

    fn back_to_main(&mut self, entry: u8) {
        self.go(Screen::Menu(MenuId::Main));
        self.scroll(entry as i8, MenuId::Main.len() as u8);
    }

    #[inline(never)]
    fn press(&mut self, v: &View) -> Cmd {
        let sel = self.sel;
        match self.screen {
            Screen::Menu(m) => self.act(m, m.item(sel as usize).1, v),
            Screen::Files => {
                if sel == 0 || !v.card_in {
                    self.back_to_main(1);
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
                self.back_to_main(5);
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
                if m == MenuId::Main {
                    self.go(Screen::Status);
                } else {
                    let entry = match m {
                        MenuId::Job => 2,
                        MenuId::Jog => 3,
                        _ => 4,
                    };
                    self.back_to_main(entry);
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
                Cmd::None
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
            Act::HomeAll | Act::HomeZ | Act::HomeY | Act::HomeX => {
                if !idle {
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
    pub fn line(&self, row: usize, v: &View, s: &Settings, file: &dyn Fn(u8) -> Option<Name>) -> Line {
        let mut l = Line::blank();
        match self.screen {
            Screen::Status => status_line(row, v, &mut l),
            Screen::Info => info_line(row, v, &mut l),
            _ => {
                if row == 0 {
                    l.invert = true;
                    let t = match self.screen {
                        Screen::Menu(m) => m.title(),
                        Screen::Files => Text::Files,
                        Screen::ConfirmRun(_) => Text::RunQ,
                        Screen::ConfirmAbort => Text::AbortQ,
                        Screen::Override => Text::FeedOverride,
                        Screen::Jogging => Text::Jog,
                        _ => Text::Settings,
                    };
                    let c = l.text(1, t);
                    if let Screen::ConfirmRun(i) = self.screen {
                        let n = file(i).unwrap_or_default();
                        let c = l.put(c, n.as_bytes());
                        l.put(c, b"?");
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
                    _ => {}
                }
                if e >= self.entries(v) {
                    if self.screen == Screen::Files && e == 1 && row == 2 {
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
                    Screen::ConfirmRun(_) | Screen::ConfirmAbort => {
                        l.text(1, if e == 0 { Text::No } else { Text::Yes });
                    }
                    Screen::Settings => {
                        l.invert = false;
                        settings_line(e, s, &mut l);
                    }
                    _ => {}
                }
            }
        }
        l
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
            Act::JogAxis => {
                l.put(c + 1, &[b"XYZ"[self.jog_axis as usize % 3]]);
            }
            Act::JogStep => {
                let um = JOG_STEPS_UM[self.jog_step as usize % 3];
                let c = c + 1;
                let c = if um < 1000 {
                    l.put(c, b"0.1")
                } else {
                    l.uint(c, (um / 1000) as u32)
                };
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
pub fn state_text(s: State) -> Text {
    match s {
        State::Idle => Text::StIdle,
        State::Run => Text::StRun,
        State::Hold => Text::StHold,
        State::Alarm => Text::StAlarm,
        State::Home => Text::StHoming,
        State::Tool => Text::StTool,
        State::Probe => Text::StProbe,
    }
}

#[inline(never)]
fn status_line(row: usize, v: &View, l: &mut Line) {
    match row {
        0 => {
            l.invert = true;
            l.text(1, state_text(v.state));
            let c = l.put(COLS - 4, b"T");
            l.uint(c, v.tool as u32);
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
        5 => {
            l.put(0, b"S");
            if v.rpm == 0 {
                l.text(2, Text::Off);
            } else {
                l.uint_right(7, v.rpm as u32);
                l.text(8, Text::Rpm);
            }
        }
        6 => job_status(v, l),
        7 => {
            l.text(0, if v.state == State::Hold { Text::HintResume } else { Text::HintMenu });
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
        Phase::Aborting(_) => {
            l.text(0, Text::JobStopping);
        }
        Phase::CardLost => {
            l.text(0, Text::JobCardOut);
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
            Outcome::CardRemoved => {
                l.text(0, Text::JobCardOut);
            }
        },
    }
}

#[inline(never)]
fn info_line(row: usize, v: &View, l: &mut Line) {
    match row {
        0 => {
            l.invert = true;
            l.text(1, Text::Info);
        }
        2 => {
            l.put(1, crate::FIRMWARE_NAME.as_bytes());
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

#[inline(never)]
fn settings_line(e: u8, s: &Settings, l: &mut Line) {
    let axis = (e % 3) as usize;
    l.put(0, &[b"XYZ"[axis]]);
    let (v, t) = match e / 3 {
        0 => (s.steps_per_mm[axis], Text::StepsMm),
        1 => (s.max_feed_mm_per_min[axis], Text::MaxFeed),
        2 => (s.accel_mm_per_s2[axis], Text::Accel),
        _ => (s.travel_mm[axis], Text::Travel),
    };
    if e >= 12 {
        l.put(0, b" ");
        return;
    }
    l.uint_right(7, crate::math::round_i32(v).max(0) as u32);
    l.text(7, t);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn screen(ui: &Ui, v: &View) -> Vec<String> {
        let names = |i: u8| Name::parse(format!("FILE{i}.NC").as_bytes());
        (0..ROWS)
            .map(|r| {
                let l = ui.line(r, v, &Settings::DEFAULT, &names);
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
        assert_eq!(MenuId::Main.len(), 7);
        assert_eq!(MenuId::Main.item(1), (Text::RunFromSd, Act::Files));
        assert_eq!(MenuId::Job.item(2), (Text::Abort, Act::Abort));
        assert_eq!(MenuId::Home.item(4), (Text::HomeX, Act::HomeX));
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
        assert_eq!(s[1], "X   100 steps/mm");
        ui.step(0, true, &v);
        assert_eq!(ui.screen, Screen::Menu(MenuId::Main));
    }
}
