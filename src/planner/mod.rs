//! Motion planner (docs/SPEC.md §6): the block ring and its look-ahead, grbl's
//! `plan_buffer_line` / `planner_recalculate` in Rust.
//!
//! Where it sits: the G-code interpreter rounds each absolute target to integer
//! steps and calls [`Planner::push_line`] (arcs are first cut into chords by
//! [`arc`]). The planner queues a [`Block`] per move and re-plans the entry
//! speeds of the whole ring; [`crate::stepper::prep`] takes the oldest block
//! (the *executing* block, [`Planner::current_block`]) and turns it into step
//! segments for the ISR.
//!
//! Units: lengths in mm (the E axis in pocket pitches), speeds in mm/s, speeds
//! squared in (mm/s)², accelerations in mm/s². Integer steps are the truth:
//! targets arrive in steps, so rounding never accumulates.
//!
//! **Look-ahead** (grbl 1.1 planner.c): each block gets a maximum entry speed from
//! the junction deviation rule and the nominal speeds of both blocks; then a
//! backward pass from the newest block (which always ends at zero speed) raises
//! entry speeds as far as deceleration allows, and a forward pass lowers them to
//! what acceleration allows. `planned` marks the newest block whose entry speed
//! can no longer improve, so both passes stop there: with a stream of short
//! collinear moves only the blocks in the final deceleration ramp are visited.
//! The forward pass also ends at the first block it leaves unchanged once past
//! the newest block the backward pass left faster than the one before it: in
//! a ring that is one deceleration ramp it visits a block or two, and the
//! backward pass is replaced by one raise of the whole ramp (`lookahead`,
//! "The ramp").
//!
//! **The executing block** is shared with prep: prep writes its remaining
//! distance (`millimeters`) and current speed (`entry_speed_sqr`) into it after
//! every segment, so the tail block always describes "the rest of the move from
//! the speed we are at". When a re-plan may change its exit speed, the planner
//! raises a flag ([`Planner::take_exec_replanned`], grbl's
//! `st_update_plan_block_parameters`) and prep recomputes its profile.
//!
//! **Backlash** (docs/SPEC.md §6, seed 003; default off): when X, Y or Z reverses and its
//! `backlash_mm` is > 0, a separate *take-up block* is queued just before the
//! reversing move. It moves only the reversing axes, by the backlash in steps, in
//! the new direction, at their max rate, and carries [`Block::TAKE_UP`]. The
//! commanded position ([`Planner::position`]) does not change; the motors run
//! ahead of it by [`Planner::backlash_offset_steps`]. The planned path is not
//! disturbed: the tool does not move while the slack is taken up, the take-up is
//! planned like any block (it stops at the reversal, as the motor reverses there
//! anyway) and the reversing move then starts from where the slack is gone. An
//! axis' direction is unknown after power-up and [`Planner::clear`]; its first
//! move sets it without compensation (homing does that).
//!
//! **AVR cost** (measured in simavr at 16 MHz with avr-libc float, 0.1 mm
//! moves at F3000 through `push_line` + [`crate::stepper::prep`]): push
//! ≈ 9.8 k cycles for a collinear stream, ≈ 12.5 k on a curve (junction maths),
//! of which the two look-ahead passes take ≈ 4 k; prep ≈ 5.7–6.2 k per block at
//! cruise, ≈ 11 k when every block is a ramp (a sharp zigzag). An f32 multiply
//! costs ≈ 170 cycles, a division or square root ≈ 500, so the code avoids
//! them where it can: non-negative floats are compared as bit patterns
//! (`lt_nn`), settings-derived inverses are cached, and a block in the same
//! direction as the previous one reuses its limits and needs no junction maths.
//! A junction is first compared with a cached sin²(θ/2) threshold above which
//! the speed cap decides (`junction::CapCache`), a short move's length,
//! acceleration and speed limit are cached by its Σd² and dominant steps
//! (`ring::Short`; on a miss its acceleration takes 1/n from a flash table,
//! `math::recip_small`, instead of a division),
//! and an X/Y/Z move whose time per mm can meet neither step-rate limit
//! (`AxisCache::rate_free_inv_feed`) skips that test. `reference` (tests)
//! holds all of it to a plain f64 planner within 1 %.
//! RAM on AVR: `Block` 50 B, 28 of them (`ring`).
//!
//! **Files**: `block` the block and the results of queuing one, `ring` the
//! ring and the planner's state, `queue` queuing a move, `junction` the
//! junction speed, `lookahead` the look-ahead passes, `overrides` the feed
//! and rapid overrides, `axis_cache` the settings-derived per-axis values;
//! the float shortcuts on bit patterns are `math::float_bits` (segment prep
//! uses them too).

pub mod arc;
mod axis_cache;
mod block;
mod junction;
mod lookahead;
mod overrides;
mod queue;
mod ring;

#[cfg(test)]
mod reference;
#[cfg(test)]
mod tests;

pub use block::{Block, PlanError, Push, Speed};
pub use ring::{Planner, BLOCK_BUFFER_LEN, PLANNER_RAM_BUDGET};
