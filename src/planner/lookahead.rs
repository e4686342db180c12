//! The look-ahead (grbl's `planner_recalculate`): the backward and forward
//! passes over the ring that set each block's entry speed, when they run
//! ([`Planner::settle`]), and the full re-plans after a feed hold or an
//! override.

use super::block::Block;
use super::float_bits::{lt_nn, min_nn};
use super::ring::{prev_index, Planner, BLOCK_BUFFER_LEN};

impl Planner {
    /// Run the look-ahead if blocks were queued since the last pass and it
    /// could change the executing block's exit speed (`planned` is the
    /// executing block). Otherwise the blocks up to `planned`, the next one
    /// included, are final, and the newer ones wait: their entry speeds are
    /// those of a stop at the end of the ring as it was, never too fast, and
    /// one pass later covers every block queued meanwhile. Prep calls this
    /// before every segment; with a stream of short moves it saves most
    /// passes (each visits every block of the final deceleration ramp).
    pub fn settle(&mut self) {
        if self.stale && self.planned == self.tail {
            self.recalculate();
        }
    }

    /// grbl's `planner_recalculate`: backward pass from the newest block to
    /// `planned`, then forward pass from `planned` to the newest block.
    /// The blocks from `planned` to the newest are one or two runs of the
    /// array (the ring may wrap), walked as slices: on the AVR a step to the
    /// next block is then a pointer add, not an index times the block size
    /// with a bounds check.
    pub(super) fn recalculate(&mut self) {
        self.stale = false;
        let newest = prev_index(self.head) as usize;
        let planned = self.planned as usize;
        if newest == planned {
            return;
        }
        // The block after the executing one is about to change.
        if self.planned == self.tail {
            self.exec_replanned = true;
        }
        // The newest block always ends at zero speed.
        let mut next_entry = {
            let b = &mut self.blocks[newest];
            b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, b.max_delta_speed_sqr);
            b.entry_speed_sqr
        };
        // Backward pass over the blocks strictly between `planned` and the
        // newest: [planned + 1, newest) in one run, or [0, newest) then
        // [planned + 1, LEN) when the ring wraps.
        let (a, b) = if planned < newest { (planned + 1..newest, 0..0) } else { (0..newest, planned + 1..BLOCK_BUFFER_LEN) };
        for blk in self.blocks[a].iter_mut().rev() {
            next_entry = backward(blk, next_entry);
        }
        for blk in self.blocks[b].iter_mut().rev() {
            next_entry = backward(blk, next_entry);
        }
        // Forward pass: each block after `planned` against the one before:
        // [planned + 1, newest] in one run, or [planned + 1, LEN) then [0, newest].
        let mut f = {
            let c = &self.blocks[planned];
            Forward { entry: c.entry_speed_sqr, delta: c.max_delta_speed_sqr, planned: self.planned }
        };
        let (a, b) = if planned < newest { (planned + 1..newest + 1, 0..0) } else { (planned + 1..BLOCK_BUFFER_LEN, 0..newest + 1) };
        let mut i = planned as u8;
        for blk in self.blocks[a].iter_mut() {
            i += 1;
            f.step(blk, i);
        }
        i = u8::MAX;
        for blk in self.blocks[b].iter_mut() {
            i = i.wrapping_add(1);
            f.step(blk, i);
        }
        self.planned = f.planned;
    }

    /// grbl's `plan_cycle_reinitialize`, for the end of a feed hold: the machine
    /// is stopped, so the executing block restarts from zero speed with the
    /// distance it has left, and the whole ring is re-planned from it.
    pub fn cycle_reinitialize(&mut self) {
        if self.len == 0 {
            return;
        }
        self.blocks[self.tail as usize].entry_speed_sqr = 0.0;
        self.replan();
    }

    /// Re-plan the whole ring from the executing block's current state.
    pub fn replan(&mut self) {
        if self.len == 0 {
            return;
        }
        self.planned = self.tail;
        self.exec_replanned = true;
        self.recalculate();
    }
}

/// One block of the backward pass: its entry speed² as high as stopping
/// at `next_entry` allows, within its limit. Returns its entry speed².
// speed: once per block and pass, in the loop
#[inline(always)]
fn backward(b: &mut Block, next_entry: f32) -> f32 {
    if b.entry_speed_sqr.to_bits() != b.max_entry_speed_sqr.to_bits() {
        b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, next_entry + b.max_delta_speed_sqr);
    }
    b.entry_speed_sqr
}

/// The forward pass' state: the previous block's entry speed² and the
/// speed² it can gain, and the newest optimal block so far.
struct Forward {
    entry: f32,
    delta: f32,
    planned: u8,
}

impl Forward {
    /// Block `i` after the previous one: its entry speed² no higher than
    /// accelerating through the previous block gives.
    // speed: once per block, in the loop
    #[inline(always)]
    fn step(&mut self, n: &mut Block, i: u8) {
        if lt_nn(self.entry, n.entry_speed_sqr) {
            let e = self.entry + self.delta;
            if lt_nn(e, n.entry_speed_sqr) {
                // Acceleration-limited: optimal, nothing before it can change.
                n.entry_speed_sqr = e;
                self.planned = i;
            }
        }
        if n.entry_speed_sqr.to_bits() == n.max_entry_speed_sqr.to_bits() {
            self.planned = i;
        }
        self.entry = n.entry_speed_sqr;
        self.delta = n.max_delta_speed_sqr;
    }
}
