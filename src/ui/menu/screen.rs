//! The screens ([`Screen`]): which one is up, and what it is about; and
//! the tool change station's points that the Changer screen lists.

use super::cmd::ToolOp;
use super::edit::Edit;
use super::tree::MenuId;
use crate::ui::text::Text;

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
    /// Spindle > Speed: the S being set (rpm, in `Ui::edit_um`).
    SpindleSpeed,
    /// Spindle > Override: the percentage being set (`Ui::override_pct`).
    SpindleOverride,
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
    /// A Tools command running, then its result or refusal ([`Ui::reply`](super::Ui::reply)).
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
    /// while the encoder turns the value ([`Ui::edit_um`](super::Ui::edit_um)).
    Edit(Edit, bool),
}

/// The station's points on the Changer screen, `$170`–`$175`.
pub(super) const STATION_POINTS: u8 = 6;

/// The name of station point `p` (a `match`: a table of them would be
/// copied to RAM).
pub(super) fn point_text(p: u8) -> Text {
    match p {
        0 => Text::PointX1,
        1 => Text::PointYA,
        2 => Text::PointYB,
        3 => Text::PointZ1,
        4 => Text::PointZ2,
        _ => Text::PointTravel,
    }
}
