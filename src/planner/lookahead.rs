//! The look-ahead (grbl's `planner_recalculate`): the backward and forward
//! passes over the ring that set each block's entry speed, when they run
//! ([`Planner::settle`]), and the full re-plans after a feed hold or an
//! override.
//!
//! **The ramp.** With a stream of short moves that the ring cannot hold
//! at speed (a host sending one line at a time, 0.1 mm chords) no block
//! after `planned` is at its maximum entry speed: they are one
//! deceleration ramp down to the stop after the newest block, and each new
//! block raises every entry speed² of it by the same amount (the new
//! block's entry speed², which the old newest block no longer has to shed).
//! grbl's passes then visit the whole ramp for every line (~15 float adds
//! a line on the AVR). Instead the ramp's blocks store their entry speed²
//! less a common `lift`, and a new block raises `lift` once
//! ([`Planner::extend_ramp`]); prep reads the ramp's first block through
//! [`Planner::exec_exit_speed_sqr`], and a block leaving the ramp gets
//! `lift` added back. The full pass runs when that shortcut does not hold
//! (a block would reach its maximum: `slack`; a new block at its maximum;
//! a re-plan; `lift` grown 2⁷ times the newest entry speed², whose
//! rounding would show), and leaves the ramp with no lift. The tests hold
//! the result to grbl's passes within 10⁻⁴ (`recalculate_plain`) and to an
//! f64 planner within 1 % (`reference`).

use super::block::Block;
use super::ring::{next_index, prev_index, Planner, BLOCK_BUFFER_LEN};
use crate::math::float_bits::{lt_nn, min_nn};

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
        let newest = prev_index(self.head);
        if newest == self.planned {
            self.ramp_end = newest;
            self.lift = 0.0;
            self.ramp_ok = true;
            return;
        }
        // The block after the executing one is about to change.
        if self.planned == self.tail {
            self.exec_replanned = true;
        }
        if self.ramp_ok && self.ramp_end != newest && self.extend_ramp(newest) {
            return;
        }
        self.recalculate_full(newest as usize);
    }

    /// The ramp (the module doc): the blocks queued since the last pass
    /// extend the deceleration ramp it left after `planned`, which every
    /// block of it then enters faster by the same speed² (the entry speed²
    /// of the first new block: the old newest block no longer stops). That
    /// is `lift` raised once, not a float add per block. False, and nothing
    /// changed that the full pass does not redo, when that does not hold:
    /// a new block at its maximum entry speed, a ramp block that would
    /// reach its own (`slack`), or a `lift` so far above the newest entry
    /// speed² (2⁷ times) that its rounding would show.
    // speed: apart from the full pass (inlined: the streamed line 26.53k -> 26.78k cycles)
    #[inline(never)]
    fn extend_ramp(&mut self, newest: u8) -> bool {
        let end = self.ramp_end;
        let ramp = self.planned != end;
        // The new blocks are a ramp down to a stop at the newest one's end:
        // each enters at the sum of its own and the later new blocks'
        // `max_delta_speed_sqr` (`x`), below its maximum, and the ramp
        // before them rises by the oldest one's. Stored less the new
        // `lift`, that is `−lift` for the oldest and one `max_delta` less
        // for each after it: one subtraction a block, summed from the
        // oldest, where `x` then `x − lift` took two
        // (`the_look_ahead_without_an_idle_forward_pass_plans_as_both_passes_do`);
        // the newest one's `x` is its own `max_delta`, so the new `lift` is
        // that less its stored entry. Their headroom, maximum less stored
        // entry, is what `slack` keeps; a new block reaches its maximum
        // when the new `lift` reaches its headroom. (The entries are
        // written as they are: the full pass redoes them from scratch if
        // this returns false.)
        let newest_entry = self.blocks[newest as usize].max_delta_speed_sqr;
        let (mut lift, mut new_slack) = if ramp { self.stored_from_oldest(end, newest) } else { self.stop_ramp(end, newest) };
        if !lt_nn(lift, new_slack) {
            return false;
        }
        if ramp && !lt_nn(lift, self.slack) {
            // `slack` may be that of a block no longer in the ramp: the
            // ramp's own; and the blocks the lift would raise to their
            // maximum enter at it and are final ([`Planner::cap_front`]).
            let (cap, slack) = self.ramp_cap(end, lift);
            self.slack = slack;
            if cap != self.planned {
                self.cap_front(cap);
                if cap == end {
                    // The whole ramp was: the new blocks start a new one,
                    // with their entries as they are (rare: the stream
                    // reached its feed).
                    new_slack = self.unlift_new(end, newest, lift);
                    lift = 0.0;
                }
            }
        }
        let ramp = self.planned != end;
        // (Exponents: no multiply.)
        if (lift.to_bits() >> 23) > (newest_entry.to_bits() >> 23) + 6 {
            return false;
        }
        self.slack = if ramp { min_nn(self.slack, new_slack) } else { new_slack };
        self.lift = lift;
        self.ramp_end = newest;
        // Forward pass from `planned`: a block the one before it cannot
        // reach by accelerating enters at what it can reach, is final, and
        // leaves the ramp; the first one that can be reached ends the pass.
        let (entry, delta) = {
            let c = &self.blocks[self.planned as usize];
            (c.entry_speed_sqr, c.max_delta_speed_sqr)
        };
        let (mut entry, mut delta) = (entry, delta);
        loop {
            let n = next_index(self.planned);
            let b = &mut self.blocks[n as usize];
            let planned_entry = b.entry_speed_sqr + self.lift;
            if !lt_nn(entry, planned_entry) {
                break;
            }
            let x = entry + delta;
            if !lt_nn(x, planned_entry) {
                break;
            }
            b.entry_speed_sqr = x;
            self.planned = n;
            if n == self.ramp_end {
                self.lift = 0.0;
                break;
            }
            entry = x;
            delta = b.max_delta_speed_sqr;
        }
        true
    }

    /// The new blocks after `end` up to `newest`, behind a ramp with
    /// `lift`: stored entries summed from the oldest (`extend_ramp`), and
    /// (the new lift, their least headroom).
    fn stored_from_oldest(&mut self, end: u8, newest: u8) -> (f32, f32) {
        // (+0.0 under no lift: a stored entry is never −0.0.)
        let mut stored = if self.lift.to_bits() == 0 { 0.0 } else { -self.lift };
        let mut headroom = f32::MAX;
        let mut k = next_index(end);
        loop {
            let b = &mut self.blocks[k as usize];
            b.entry_speed_sqr = stored;
            headroom = min_nn(headroom, b.max_entry_speed_sqr - stored);
            if k == newest {
                return (b.max_delta_speed_sqr - stored, headroom);
            }
            stored -= b.max_delta_speed_sqr;
            k = next_index(k);
        }
    }

    /// The new blocks after `end` up to `newest` with nothing before them
    /// to lift: their entries `x` as they are, summed from the newest,
    /// and (lift 0, their least headroom).
    fn stop_ramp(&mut self, end: u8, newest: u8) -> (f32, f32) {
        let mut x = 0.0f32;
        let mut headroom = f32::MAX;
        let mut k = newest;
        while k != end {
            let b = &mut self.blocks[k as usize];
            x = if x.to_bits() == 0 { b.max_delta_speed_sqr } else { x + b.max_delta_speed_sqr };
            if !lt_nn(x, b.max_entry_speed_sqr) {
                // At its maximum: (0, 0) fails `extend_ramp`'s test of
                // the lift against the headroom, and the full pass plans
                // the new blocks.
                return (0.0, 0.0);
            }
            b.entry_speed_sqr = x;
            headroom = min_nn(headroom, b.max_entry_speed_sqr - x);
            k = prev_index(k);
        }
        (0.0, headroom)
    }

    /// The new blocks after `end` up to `newest` back to their entries
    /// `x` (stored less `lift`), when the ramp before them became final:
    /// their least headroom.
    fn unlift_new(&mut self, end: u8, newest: u8, lift: f32) -> f32 {
        let mut headroom = f32::MAX;
        let mut k = newest;
        while k != end {
            let b = &mut self.blocks[k as usize];
            b.entry_speed_sqr += lift;
            headroom = min_nn(headroom, b.max_entry_speed_sqr - b.entry_speed_sqr);
            k = prev_index(k);
        }
        headroom
    }

    /// The ramp's blocks up to `end` under `lift`: the newest of them that
    /// it raises to its maximum entry speed² (`planned` if none), and the
    /// least of maximum entry speed² less stored entry speed² over the
    /// blocks after that one (the ramp reaches no maximum while `lift`
    /// stays below it).
    fn ramp_cap(&self, end: u8, lift: f32) -> (u8, f32) {
        let mut slack = f32::MAX;
        let mut k = end;
        while k != self.planned {
            let b = &self.blocks[k as usize];
            let room = b.max_entry_speed_sqr - b.entry_speed_sqr;
            if !lt_nn(lift, room) {
                return (k, slack);
            }
            slack = min_nn(slack, room);
            k = prev_index(k);
        }
        (k, slack)
    }

    /// The ramp's blocks up to `k`, which the lift raises to its maximum
    /// entry speed², become final, as grbl's passes would leave them: `k`
    /// at its maximum (the backward pass through the ramp after it gives
    /// at least that), the blocks before it from the backward pass from
    /// `k`, then the forward pass from `planned` to `k`, which is then the
    /// newest final block. The blocks after `k` stay the ramp. With a
    /// stream at the feed's cruise speed this is the usual way a pass
    /// ends; before, it was a full pass over the ring (~11 k cycles on the
    /// AVR, every ~13 lines of the benchmark's stream at 1000 mm/s²).
    fn cap_front(&mut self, k: u8) {
        let planned = self.planned;
        let mut next = {
            let b = &mut self.blocks[k as usize];
            b.entry_speed_sqr = b.max_entry_speed_sqr;
            b.entry_speed_sqr
        };
        let mut j = prev_index(k);
        while j != planned {
            next = backward(&mut self.blocks[j as usize], next);
            j = prev_index(j);
        }
        let mut f = {
            let c = &self.blocks[planned as usize];
            Forward { entry: c.entry_speed_sqr, delta: c.max_delta_speed_sqr, planned }
        };
        let mut j = planned;
        while j != k {
            j = next_index(j);
            f.step(&mut self.blocks[j as usize], j);
        }
        self.planned = k;
    }

    /// [`Planner::recalculate`] over every block after `planned`: the
    /// backward and the forward pass; the ramp it leaves has no `lift`.
    // speed: see extend_ramp
    #[inline(never)]
    fn recalculate_full(&mut self, newest: usize) {
        let planned = self.planned as usize;
        // Blocks after `planned`, the newest included.
        let len = if planned < newest { newest - planned } else { newest + BLOCK_BUFFER_LEN - planned } as u8;
        // The newest block always ends at zero speed.
        let mut bw = {
            let b = &mut self.blocks[newest];
            b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, b.max_delta_speed_sqr);
            let top = if b.entry_speed_sqr.to_bits() == b.max_entry_speed_sqr.to_bits() { len } else { 0 };
            let slack = if top == 0 { b.max_entry_speed_sqr - b.entry_speed_sqr } else { 0.0 };
            Backward { next: b.entry_speed_sqr, d: len, rise: 0, top, slack }
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
        // What follows `planned` now is a ramp (no block after the newest
        // at its maximum), which the next pass may extend.
        self.ramp_end = newest as u8;
        self.lift = 0.0;
        self.slack = bw.slack;
        self.ramp_ok = true;
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
        self.ramp_end = newest as u8;
        self.lift = 0.0;
        self.ramp_ok = false;
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
        self.settle_ramp();
        self.planned = self.tail;
        self.exec_replanned = true;
        self.recalculate();
    }
}

impl Planner {
    /// Write the ramp's entry speeds² out (`lift` added) and end it: the
    /// next pass is a full one.
    fn settle_ramp(&mut self) {
        if self.ramp_end != self.planned && self.lift.to_bits() != 0 {
            let mut k = self.ramp_end;
            while k != self.planned {
                self.blocks[k as usize].entry_speed_sqr += self.lift;
                k = prev_index(k);
            }
        }
        self.lift = 0.0;
        self.ramp_end = self.planned;
        self.ramp_ok = false;
    }
}

/// One block of the backward pass as grbl writes it: its entry speed² as
/// high as stopping at `next_entry` allows, within its limit. Returns its
/// entry speed². The plain twin of [`Backward::step`], and
/// [`Planner::cap_front`]'s step (its blocks are below their maximum).
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
    /// The least headroom (maximum less entry speed²) of the blocks after
    /// `top` (the ramp the pass leaves: [`Planner::extend_ramp`]).
    slack: f32,
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
                if self.top == 0 {
                    self.slack = min_nn(self.slack, b.max_entry_speed_sqr - e);
                }
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
