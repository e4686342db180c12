//! The fixed menus as data: what each entry says ([`Text`]) and does
//! ([`Act`]), menu after menu ([`MenuId`]), two bytes an entry in flash.

use crate::ui::flash;
use crate::ui::text::Text;

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
            pub(super) fn from_u8(b: u8) -> Option<$name> {
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
        /// Jog > Zero X Y Z: the work zero of all three axes here.
        ZeroAll,
        /// Tools > Calibrate setter: the reference tool's length and
        /// diameter, then `G37 L R` with it.
        CalibrateSetter,
        /// Jog > Probe Z zero: probe down, Z zero where it touches.
        ProbeZ,
        /// Jog > Work G5x: the next work system (G54 … G59, round).
        WorkSystem,
        /// Tools > Tool numbers: the tool number kept in each pocket.
        ToolNumbers,
        OptStop,
        /// Main > Spindle.
        SpindleMenu,
        /// Spindle > On/off: M3 at the speed set, or M5.
        SpindleOnOff,
        /// Spindle > Speed: the S word (and M3 S when the spindle turns).
        SpindleSpeed,
        /// Spindle > Override: the spindle override, as 0x9A/0x9B set it.
        SpindleOverride,
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
    Spindle,
}

const fn item(t: Text, a: Act) -> [u8; 2] {
    [t as u8, a as u8]
}

/// Every fixed entry, menu after menu (see MENU_START), in flash.
#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
pub(super) static ITEMS: [[u8; 2]; 45] = [
    // Main
    item(Text::Status, Act::Back),
    item(Text::RunFromSd, Act::Files),
    item(Text::Job, Act::JobMenu),
    item(Text::Jog, Act::JogMenu),
    item(Text::Home, Act::HomeMenu),
    item(Text::Tools, Act::ToolsMenu),
    item(Text::Settings, Act::Settings),
    item(Text::Info, Act::Info),
    item(Text::Spindle, Act::SpindleMenu),
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
    item(Text::ZeroAll, Act::ZeroAll),
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
    item(Text::CalibrateSetter, Act::CalibrateSetter),
    // Alarm
    item(Text::Status, Act::Back),
    item(Text::Unlock, Act::Unlock),
    item(Text::HomeAll, Act::HomeAll),
    item(Text::Jog, Act::JogMenu),
    item(Text::ConfirmSpindle, Act::ConfirmSpindle),
    // Spindle
    item(Text::Back, Act::Back),
    item(Text::Spindle, Act::SpindleOnOff),
    item(Text::SpindleSpeed, Act::SpindleSpeed),
    item(Text::OverrideShort, Act::SpindleOverride),
];

/// First entry of each menu in ITEMS, plus the end.
#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
static MENU_START: [u8; 8] = [0, 9, 14, 22, 27, 36, 41, 45];

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

    pub(super) fn title(self) -> Text {
        match self {
            MenuId::Main => Text::MainMenu,
            MenuId::Job => Text::Job,
            MenuId::Jog => Text::Jog,
            MenuId::Home => Text::Home,
            MenuId::Tools => Text::Tools,
            MenuId::Alarm => Text::AlarmMenu,
            MenuId::Spindle => Text::Spindle,
        }
    }
}
