//! Automatic tool changer (docs/SPEC.md §7, thesis §4.1.10 and §5.3): the T/M6
//! tool change, the G201–G205 carousel commands, and what the firmware
//! remembers about the tools.
//!
//! ```text
//!  gcode::interp ─ Command::SelectTool ─► machine::toolchange::select
//!        ─► change::Change (pure table) ─► actions ─► Machine::move_mm, carousel, EEPROM
//!                     ▲ events ◄────────────────────────┘
//!  gcode::interp ─ Command::Carousel… ─► machine::carousel (E0 axis through the planner)
//! ```
//!
//! This module is the pure part, below `gcode` in the layers (`src/lib.rs`):
//! the runners that move the machine are in `machine` (`machine::toolchange`,
//! `machine::carousel`).
//!
//! - [`change`]: the sequence as a state machine whose transitions are a
//!   table; pure, host-tested.
//! - [`tools`]: tool table, spindle/pocket state, change journal and their
//!   EEPROM records.
//! - `machine::carousel`: G201–G205 on motor P0 (the E0 axis) and carousel homing.
//! - `machine::toolchange`: the executor over `machine::Machine`, boot, M61, G10 L1.
//!
//! Carousel units: one unit is one pocket pitch (20°), counted from the home
//! switch (0°). Pocket `p` sits at position `p + offset` (`$180`, default
//! 3: pocket 1 at 80°), the thesis's `ATC_OFFSET + id` with `ATC_OFFSET = 3`
//! in these units.
//!
//! All operator-facing ATC texts are in [`Fault::message`] and in
//! `machine::toolchange::report_*`, so they can move to flash in one place.

pub mod change;
pub mod tools;

pub use tools::{Journal, ToolState, ToolTable, N_POCKETS};

pub use crate::config::Station;

/// Carousel position (pitches from home) of pocket `p` on a carousel whose
/// pocket 1 sits `pocket_offset + 1` pitches from its home switch.
pub fn pocket_position(p: u8, pocket_offset: f32) -> f32 {
    p as f32 + pocket_offset
}

crate::flash_messages! {
    /// Why an ATC command was refused or stopped (`message`: the text after `Error:`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Fault {
        /// A pocket outside 0..=12.
        ToolRange => "tool must be T0-T12",
        /// X, Y, Z not homed.
        NotHomed => "home X Y Z (G28) before a tool change",
        /// The pocket of the tool asked for is empty.
        PocketEmpty => "pocket of that tool is empty (M61 P<n> S1 if loaded)",
        /// The pocket of the tool in the spindle is full.
        ReturnPocketFull => "pocket of the spindle tool is full, cannot return it",
        /// A station point or the return point is outside travel.
        SoftLimit => "tool change station outside travel (soft limit)",
        /// A change was interrupted; the operator must confirm the spindle (M61).
        Interrupted => "tool change interrupted: check spindle, then M61 Q<tool>",
        /// The carousel home switch did not close within a revolution + margin.
        CarouselHome => "carousel home switch not found",
        /// An alarm (M112, limit, …) stopped the change.
        Stopped => "tool change stopped",
        /// G201–G205 without `P0`.
        Motor => "P must be 0 (the carousel)",
        /// G201/G202 without X, or X out of range.
        CarouselX => "X missing or out of range (-360..360)",
        /// G204 S must be 0 or 1; G205 S/E must be 0 or 1.
        OnOff => "S and E must be 0 or 1",
        /// T or M6 on a line that also moves.
        WithMotion => "T/M6 must be on a line without motion",
        /// M6 without any T word so far.
        NoTool => "M6 needs a T word",
        /// M61: Q must be a tool 0–12, or P a pocket 1–12 with S0/S1.
        M61Words => "M61 Q<0-12>, or M61 P<1-12> S<0|1>",
        /// M61 P S1 for the pocket of the tool in the spindle.
        PocketOfSpindleTool => "that tool is in the spindle",
        /// G10 L1 P Q: the pocket holds another tool number.
        PocketTaken => "that pocket holds another tool: take it out first (G10 L1 P<its number> Q0)",
        /// The menu: a pocket the tool table gives no tool number.
        NoNumber => "that pocket has no tool number (G10 L1 P<tool> Q<pocket>)",
        /// G10 L1 P Q: the tool is in another pocket.
        ToolElsewhere => "that tool is in another pocket: take it out first (G10 L1 P<tool> Q0)",
    }
}

/// The ATC's state in RAM (about 80 bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Atc {
    /// Where the tools are (EEPROM record).
    pub tools: ToolState,
    /// Tool lengths and diameters (EEPROM record).
    pub table: ToolTable,
    /// A change that did not finish: from the EEPROM journal at boot, or a
    /// fault in this session. Motion is refused until M61 confirms.
    pub interrupted: Option<Journal>,
    /// Last T word (0..=12); M6 without T changes to it. 0xFF = none yet.
    pub last_t: u8,
}

impl Atc {
    /// Power-up state, before the EEPROM is read.
    pub const fn new() -> Atc {
        Atc { tools: ToolState::FACTORY, table: ToolTable::EMPTY, interrupted: None, last_t: 0xFF }
    }

    /// Tool in the spindle, as the pocket it comes from (0: empty).
    pub fn spindle(&self) -> u8 {
        self.tools.spindle
    }

    /// The tool number of the tool in the spindle (0: empty): what the
    /// operator and the host see (`T20`).
    pub fn spindle_tool(&self) -> u8 {
        self.table.number_of(self.tools.spindle)
    }

    /// Length of tool `t`, mm.
    pub fn length_mm(&self, t: u8) -> f32 {
        self.table.length_um(t) as f32 / 1000.0
    }
}

impl Default for Atc {
    fn default() -> Self {
        Atc::new()
    }
}

/// The G43 tool length offset for a tool of `length_mm`, in the internal
/// frame of [`crate::frame`]: Z grows downward there and the tool tip hangs
/// `length` below the spindle nose, so the spindle must stay `length` higher:
/// the offset is negative, and work Z is the tip's Z. In the user's frame
/// (+Z up) it is +length, as LinuxCNC's and grbl's G43: work Z of the tip =
/// machine Z − length.
pub fn tool_length_offset_mm(length_mm: f32) -> f32 {
    -length_mm
}
