//! The look-ahead (grbl's `planner_recalculate`): the backward and forward
//! passes over the ring that set each block's entry speed, when they run
//! ([`Planner::settle`]), and the full re-plans after a feed hold or an
//! override.

use super::block::Block;
use super::float_bits::{lt_nn, min_nn};
#[cfg(test)]
use super::ring::next_index;
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
    ///
    /// The forward pass only changes a block that enters faster than the
    /// one before it allows. Past the newest block that the backward pass
    /// left entering faster than the one before it, the first block the
    /// forward pass leaves as it was ends it: every later block is as the
    /// backward pass left it, and `planned` moves at most to the newest of
    /// them at its maximum entry speed, which the backward pass noted. With
    /// a ring that is one deceleration ramp (a stream of short moves at
    /// speed) the forward pass then visits a block or two, not the ring
    /// (~50 cycles a block on the AVR). [`Planner::recalculate_plain`]
    /// (tests) always runs it to the end.
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
        // Blocks after `planned`, the newest included.
        let len = if planned < newest { newest - planned } else { newest + BLOCK_BUFFER_LEN - planned } as u8;
        // The newest block always ends at zero speed.
        let mut bw = {
            let b = &mut self.blocks[newest];
            b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, b.max_delta_speed_sqr);
            let top = if b.entry_speed_sqr.to_bits() == b.max_entry_speed_sqr.to_bits() { len } else { 0 };
            Backward { next: b.entry_speed_sqr, d: len, rise: 0, top }
        };
        // Backward pass over the blocks strictly between `planned` and the
        // newest: [planned + 1, newest) in one run, or [0, newest) then
        // [planned + 1, LEN) when the ring wraps.
        let (a, b) = if planned < newest { (planned + 1..newest, 0..0) } else { (0..newest, planned + 1..BLOCK_BUFFER_LEN) };
        for blk in self.blocks[a].iter_mut().rev() {
            bw.step(blk);
        }
        for blk in self.blocks[b].iter_mut().rev() {
            bw.step(blk);
        }
        let stop = self.forward(planned, newest, bw.rise.max(1));
        if bw.top > stop {
            let i = planned + bw.top as usize;
            self.planned = if i >= BLOCK_BUFFER_LEN { i - BLOCK_BUFFER_LEN } else { i } as u8;
        }
    }

    /// The forward pass of [`Planner::recalculate`]: each block after
    /// `planned` against the one before: [planned + 1, newest] in one run,
    /// or [planned + 1, LEN) then [0, newest]. It ends early at the first
    /// block it leaves as it was from the `stop_from`-th block after
    /// `planned` on. Returns how many blocks it visited.
    fn forward(&mut self, planned: usize, newest: usize, stop_from: u8) -> u8 {
        let mut f = {
            let c = &self.blocks[planned];
            Forward { entry: c.entry_speed_sqr, delta: c.max_delta_speed_sqr, planned: self.planned }
        };
        let (a, b) = if planned < newest { (planned + 1..newest + 1, 0..0) } else { (planned + 1..BLOCK_BUFFER_LEN, 0..newest + 1) };
        let mut i = planned as u8;
        let mut d = 0u8;
        for blk in self.blocks[a].iter_mut() {
            i += 1;
            d += 1;
            if !f.step(blk, i) && d >= stop_from {
                self.planned = f.planned;
                return d;
            }
        }
        i = u8::MAX;
        for blk in self.blocks[b].iter_mut() {
            i = i.wrapping_add(1);
            d += 1;
            if !f.step(blk, i) && d >= stop_from {
                self.planned = f.planned;
                return d;
            }
        }
        self.planned = f.planned;
        d
    }

    /// [`Planner::recalculate`] as grbl writes it, both passes always: the
    /// twin the tests hold the skipped forward pass to.
    #[cfg(test)]
    pub(super) fn recalculate_plain(&mut self) {
        self.stale = false;
        let newest = prev_index(self.head) as usize;
        let planned = self.planned as usize;
        if newest == planned {
            return;
        }
        if self.planned == self.tail {
            self.exec_replanned = true;
        }
        let mut next_entry = {
            let b = &mut self.blocks[newest];
            b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, b.max_delta_speed_sqr);
            b.entry_speed_sqr
        };
        let stop = next_index(self.planned);
        let mut k = newest as u8;
        while k != stop {
            k = prev_index(k);
            next_entry = backward(&mut self.blocks[k as usize], next_entry);
        }
        self.forward(planned, newest, u8::MAX);
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

/// One block of the backward pass as grbl writes it: its entry speed² as
/// high as stopping at `next_entry` allows, within its limit. Returns its
/// entry speed². The plain twin of [`Backward::step`].
#[cfg(test)]
fn backward(b: &mut Block, next_entry: f32) -> f32 {
    if b.entry_speed_sqr.to_bits() != b.max_entry_speed_sqr.to_bits() {
        b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, next_entry + b.max_delta_speed_sqr);
    }
    b.entry_speed_sqr
}

/// The backward pass' state, counting blocks from `planned` (which it
/// never reaches, so 0 means none): the entry speed² of the block after the
/// one at hand and that block's count, the newest block that enters faster
/// than the one before it (the forward pass has work up to it), and the
/// newest block at its maximum entry speed².
struct Backward {
    next: f32,
    d: u8,
    rise: u8,
    top: u8,
}

impl Backward {
    /// The block before the last one stepped: grbl's backward step
    /// ([`backward`], the tests' twin), with the notes. A block below its
    /// maximum entry speed² enters at the next block's entry speed² plus
    /// what it can shed, which is never less: only a block at its maximum
    /// can enter slower than the next one.
    // speed: once per block and pass, in the loop
    #[inline(always)]
    fn step(&mut self, b: &mut Block) {
        let next = self.next;
        if b.entry_speed_sqr.to_bits() != b.max_entry_speed_sqr.to_bits() {
            let e = next + b.max_delta_speed_sqr;
            if lt_nn(e, b.max_entry_speed_sqr) {
                b.entry_speed_sqr = e;
                self.next = e;
                self.d -= 1;
                return;
            }
            b.entry_speed_sqr = b.max_entry_speed_sqr;
        }
        let e = b.entry_speed_sqr;
        if self.rise == 0 && lt_nn(e, next) {
            self.rise = self.d;
        }
        self.d -= 1;
        if self.top == 0 {
            self.top = self.d;
        }
        self.next = e;
    }
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
    /// accelerating through the previous block gives. True if it lowered it.
    // speed: once per block, in the loop
    #[inline(always)]
    fn step(&mut self, n: &mut Block, i: u8) -> bool {
        let mut lowered = false;
        if lt_nn(self.entry, n.entry_speed_sqr) {
            let e = self.entry + self.delta;
            if lt_nn(e, n.entry_speed_sqr) {
                // Acceleration-limited: optimal, nothing before it can change.
                n.entry_speed_sqr = e;
                self.planned = i;
                lowered = true;
            }
        }
        if n.entry_speed_sqr.to_bits() == n.max_entry_speed_sqr.to_bits() {
            self.planned = i;
        }
        self.entry = n.entry_speed_sqr;
        self.delta = n.max_delta_speed_sqr;
        lowered
    }
}
