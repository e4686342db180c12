//! Stepper segment preparation, the step-event records and the rings the
//! ISR reads them from (docs/SPEC.md §6).
//!
//! Where this sits in the pipeline (grbl's `stepper.c` split in parts):
//!
//! ```text
//!  planner::Planner (block ring, look-ahead, f32)
//!      │  current_block(), exec_exit_speed_sqr(), discard_current_block()
//!      ▼
//!  prep::Prep::next_segment   (main loop; f32 speed profile → integer segments)
//!      │  StepperCmd::{Block(StBlock), Run(Segment)}  through Io::push_segment
//!      ▼
//!  rings::Rings::push         (main loop; queue::Splitter cuts the commands
//!      │                       into records, written through queue::Sink)
//!      │  queue::Chunk, queue::Seg in the board's two rings
//!      ▼
//!  TIMER1_COMPA ISR           (src/board; reads the records in place, 16-bit
//!                              Bresenham: the assembly twin of Chunk::tick)
//! ```
//!
//! One data shape crosses each boundary:
//!
//! | stage (file)                  | runs in   | takes                         | emits                              |
//! |-------------------------------|-----------|-------------------------------|------------------------------------|
//! | planner (`planner/mod.rs`)    | main loop | `push_line` targets           | `planner::Block` (read in place)   |
//! | prep (`stepper/prep.rs`)      | main loop | the executing `planner::Block`| [`StepperCmd`] (`Io::push_segment`)|
//! | rings (`stepper/rings.rs`)    | main loop | [`StepperCmd`]                | [`queue::Chunk`] + [`queue::Seg`] slots |
//! | ISR (`board/stepper.rs`)      | Timer1    | the slots, by index           | step and direction pins            |
//!
//! Prep does not emit the ring records itself: the records carry board
//! facts (step-output bits, direction-pin levels, the hard-limit mask of the
//! current watch) and ring bookkeeping (a segment's `new_chunk`, its
//! `k_end`), so the splitter is the first stage of the rings, not the last
//! of prep, and `Io::push_segment` stays one small `Copy` enum.
//!
//! This module owns the types that cross the main-loop → ISR boundary. They are
//! small, `Copy` and integer-only, so the ISR never sees a float:
//!
//! - [`StBlock`] is made once at the start of each planner block; the
//!   splitter turns it into one [`queue::Chunk`] (or several for a block of
//!   more than 32767 step events).
//! - [`Segment`] is a run of `ticks` step events, one every `period` timer counts,
//!   with Timer1 clocked at F_CPU / `prescale` (ATmega2560 datasheet §17, 16-bit
//!   Timer/Counter1, CTC mode with OCR1A = `period`). The `ticks` of a block's
//!   segments add up to its `step_event_count` exactly. Segments last about
//!   5 ms on ramps and 20 ms at cruise ([`prep::SEGMENT_TIME_S`],
//!   [`prep::CRUISE_SEGMENT_TIME_S`]); a short block is one segment.
//! - [`bresenham`] holds the one Bresenham model, [`queue::Chunk::tick`],
//!   which every host test runs, and [`queue::Chunk::tick_out`], the plain
//!   twin of the ISR's assembly, tested against it.
//!
//! RAM on AVR: the ISR's rings are 16 [`queue::Seg`]s (8 B) and 16
//! [`queue::Chunk`]s (26 B), 544 B (`board::stepper`); [`rings::Rings`]
//! 171 B; `Prep` about 80 B.

pub mod bresenham;
pub mod prep;
pub mod queue;
pub mod rings;

pub use prep::{Prep, CRUISE_SEGMENT_TIME_S, SEGMENT_TIME_S};

#[cfg(test)]
mod tests;

use crate::config::MAX_STEP_RATE_HZ;
use crate::{F_CPU_HZ, N_AXES};

/// Timer1 clock prescaler of a segment (the TCCR1B `CS1[2:0]` bits are the discriminant,
/// so the ISR can write `prescale as u8` into CS1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Prescale {
    /// clk/1: one count = 62.5 ns; periods 267..=65535 counts (60 kHz .. 244 Hz).
    Div1 = 0b001,
    /// clk/8: one count = 0.5 µs; periods up to 65535 counts (down to 30.5 Hz).
    Div8 = 0b010,
}

impl Prescale {
    /// CPU cycles per timer count.
    pub const fn divisor(self) -> u32 {
        match self {
            Prescale::Div1 => 1,
            Prescale::Div8 => 8,
        }
    }
}

/// Bresenham data of one planner block, sent to the ISR when the block starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StBlock {
    /// Steps each axis makes in this block (absolute counts), X Y Z E.
    pub steps: [u32; N_AXES],
    /// Step events in the block: max of `steps`; the Bresenham's denominator.
    pub step_event_count: u32,
    /// Bit i set: axis i moves in the negative direction (before `invert_dir_mask`).
    pub direction_bits: u8,
    /// The steps of this block are backlash take-up (docs/SPEC.md §6): the motors move but
    /// the commanded position does not. A firmware that counts machine position in
    /// the ISR should count these steps apart (or subtract
    /// [`Planner::backlash_offset_steps`](crate::planner::Planner::backlash_offset_steps)
    /// once the queue is idle).
    pub take_up: bool,
}

/// A run of equally spaced step events of the current block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Segment {
    /// Step events in this segment (≥ 1).
    pub ticks: u16,
    /// Timer counts between step events (OCR1A value), in units of `prescale`
    /// CPU cycles. With `Div1` it is never below [`MIN_PERIOD_CYCLES`].
    pub period: u16,
    /// Timer1 clock for this segment.
    pub prescale: Prescale,
}

impl Segment {
    /// Step event rate of this segment, events/s (host-side analysis helper).
    pub fn rate_hz(&self) -> f32 {
        F_CPU_HZ as f32 / (self.period as f32 * self.prescale.divisor() as f32)
    }

    /// Duration of this segment, s (host-side analysis helper).
    pub fn duration_s(&self) -> f32 {
        self.ticks as f32 * self.period as f32 * self.prescale.divisor() as f32 / F_CPU_HZ as f32
    }
}

/// One entry of the prep → ISR queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepperCmd {
    /// A new planner block starts: load the Bresenham, set direction pins.
    Block(StBlock),
    /// Run `ticks` step events of the loaded block.
    Run(Segment),
}

/// Shortest step period ever produced, CPU cycles: ⌈F_CPU / MAX_STEP_RATE_HZ⌉
/// (267 at 16 MHz / 60 kHz). The planner caps nominal rates at MAX_STEP_RATE_HZ
/// and prep clamps every segment to this period, so the ISR is never asked for
/// more than MAX_STEP_RATE_HZ step events per second.
pub const MIN_PERIOD_CYCLES: u16 = {
    let p = F_CPU_HZ as f32 / MAX_STEP_RATE_HZ;
    let t = p as u16;
    if (t as f32) < p {
        t + 1
    } else {
        t
    }
};

const _: () = assert!(MIN_PERIOD_CYCLES as u32 * MAX_STEP_RATE_HZ as u32 >= F_CPU_HZ);
const _: () = assert!(core::mem::size_of::<Segment>() <= 6);
