//! The menu tree (docs/SPEC.md §9) as data, and the state machine the encoder drives.
//!
//! ```text
//!  Status ──press──► Menu: < Status | Run from SD | Job | Jog | Home | Tools | Settings | Info
//!    Run from SD: < Back, files (scrolling) ──► "Run NAME?" No/Yes/From line ──► edit (the line)
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
//! taken once per frame) and the [`Machine`](crate::machine::Machine)
//! (settings, tool table).
//!
//! The Tools entries run G-code lines through the machine's command path
//! ([`ToolOp::gcode`]: `T<n>`, `G37`, `G37 D1`, `M61 Q<t>`), so they are
//! refused exactly as over serial; the reply screen shows the result or
//! the refusal ([`Reply`], set by the firmware when the line returns).
//!
//! The files, lowest first (each names only those above it in this list):
//!
//! - `tree`: the fixed menus' entries, in flash ([`Act`], [`MenuId`]);
//! - `edit`: what an edit screen changes ([`Edit`]), its range, its line;
//! - `cmd`: what the menu asks of the firmware ([`Cmd`], [`ToolOp`], [`Reply`]);
//! - `screen`: the screens ([`Screen`]) and the changer's station points;
//! - `view`: the per-frame snapshot the screens show ([`View`]);
//! - `nav`: the state machine ([`Ui`], [`Ui::step`]) and the way between screens;
//! - `status`, `tool_rows`: the status screen's rows, the Tools pages' rows;
//! - `draw`: [`Ui::line`], any row of the current screen.
//!
//! Inlining. Out of line pays for `Ui::line` (56 B of flash, 14 B of
//! stack on the display path), `tool_rows::pick_line` (8 B) and
//! `tool_rows::station_line` (12 B): each says so above it. The ten
//! `#[inline(never)]` marked `layout:` (`Ui::step`, `press`, `act`, the
//! edit, menu, info, jog and reply rows, the big status screen, the job
//! line) do not pay: without them the firmware is 632 B smaller (218 454
//! -> 217 822 B before the landing pad's gap; the display path's stack
//! 2 B deeper, 172 B short of the deepest path, by a static walk of the
//! ELF's calls), but the menu's small functions then straddle 0x20000 and
//! `tools/link-firmware` gives up after its 8 tries (each section it
//! moves up puts an `rcall` out of reach). They can go once that link
//! takes such a layout.

mod cmd;
mod draw;
mod edit;
mod nav;
mod screen;
mod status;
mod tool_rows;
mod tree;
mod view;

pub use cmd::{Cmd, Reply, ToolOp, ALL_AXES, PROBE_Z_FEED, PROBE_Z_MM};
pub use edit::{calibrate_line, Edit};
pub use nav::Ui;
pub use screen::Screen;
pub use status::state_text;
pub use tree::{Act, MenuId};
pub use view::View;

#[cfg(test)]
mod tests;
