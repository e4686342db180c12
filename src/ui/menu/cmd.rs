//! What the menu asks of the firmware: [`Cmd`], the result of every
//! [`Ui::step`]; the Tools and Jog commands it runs as G-code lines
//! ([`ToolOp`]) and how they went ([`Reply`]).
//!
//! [`Ui::step`]: super::Ui::step

use super::edit::Edit;
use super::tree::MenuId;
use crate::flash::FStr;
use crate::ui::render::Line;
use crate::ui::text::Text;

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
    /// axis 0..3 where the machine is; 3: of all three (`X0 Y0 Z0`).
    Zero(u8),
    /// Jog menu: probe Z down (G38.2 on the probe input, at most
    /// [`PROBE_Z_MM`]), then the Z work zero where it touched.
    ProbeZ,
    /// Jog menu: `G54` + n, work system n (0..6) active.
    Wcs(u8),
    /// An edit stored (the line is [`Edit::gcode`]'s).
    Store(Edit),
}

/// [`ToolOp::Zero`] of X, Y and Z at once.
pub const ALL_AXES: u8 = 3;

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
            ToolOp::Zero(ALL_AXES) => l.text(0, Text::LineZeroAll),
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
    pub(super) fn menu(self) -> MenuId {
        match self {
            ToolOp::Zero(_) | ToolOp::ProbeZ | ToolOp::Wcs(_) => MenuId::Jog,
            _ => MenuId::Tools,
        }
    }

    /// Its entry in the Tools menu (label and position).
    pub(super) fn entry(self) -> (Text, u8) {
        match self {
            ToolOp::Change(_) => (Text::ChangeTool, 1),
            ToolOp::Measure { diameter: false } => (Text::MeasureLength, 2),
            ToolOp::Measure { diameter: true } => (Text::MeasureDia, 3),
            ToolOp::Confirm(_) => (Text::ConfirmSpindle, 5),
            ToolOp::Zero(ALL_AXES) => (Text::ZeroAll, 5),
            ToolOp::Zero(_) => (Text::ZeroAxis, 4),
            ToolOp::ProbeZ => (Text::ProbeZ, 6),
            ToolOp::Wcs(_) => (Text::WorkSystem, 7),
            ToolOp::Store(Edit::Setting(_)) => (Text::Settings, 6),
            ToolOp::Store(Edit::Pocket(_)) => (Text::ToolNumbers, 7),
            ToolOp::Store(Edit::FromLine(_)) => (Text::FromLine, 0),
            ToolOp::Store(Edit::RefLength | Edit::RefDia) => (Text::CalibrateSetter, 8),
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

/// What the firmware should do after [`Ui::step`](super::Ui::step).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Cmd {
    None,
    /// Read the card's file list again (the Files screen opened).
    ListFiles,
    /// Start SD file number i (directory order).
    RunFile(u8),
    /// Make folder number i of the list the current folder.
    OpenFolder(u8),
    /// Go up to the current folder's parent.
    FolderUp,
    Pause,
    Resume,
    Abort,
    /// Set the feed override, percent.
    Override(u16),
    /// The spindle: on (M3 at `rpm`) or off (M5); or, with `set`, only the
    /// speed (`S<rpm>`, and M3 S when it turns).
    Spindle {
        on: bool,
        rpm: u16,
        set: bool,
    },
    /// Set the spindle override, percent.
    SpindleOverride(u8),
    /// Optional stop (M1 pauses) on or off.
    OptionalStop(bool),
    /// Move `axis` by `delta_um` micrometres.
    Jog {
        axis: u8,
        delta_um: i32,
    },
    /// Home the axes of the mask (bit 0 X, 1 Y, 2 Z).
    Home(u8),
    /// Run a Tools command; the firmware puts its outcome in [`Ui::reply`](super::Ui::reply).
    /// A spindle confirmation (M61) clears an alarm first.
    Tool(ToolOp),
    /// Leave the alarm state (`$X`/M999; nothing outside an alarm).
    Unlock,
    /// Store the current position as station point `i` (`$170 + i`).
    Teach(u8),
    /// An edit screen opened: put the value as it is into
    /// [`Ui::edit_um`](super::Ui::edit_um) ([`Edit::current`]).
    Edit(Edit),
    /// Store the edited value, thousandths ([`Edit::gcode`]); the firmware
    /// puts the outcome in [`Ui::reply`](super::Ui::reply).
    Store(Edit, i32),
}
