//! The block ring: the [`Planner`] state (the ring of [`Block`]s, the
//! look-ahead marks, the commanded position and the caches the other planner
//! files fill), its size and RAM budget, and the ring's bookkeeping: which
//! block executes, dropping it, the position, emptying the ring.

use super::axis_cache::AxisCache;
use super::block::Block;
use super::junction::CapCache;
use crate::N_AXES;
use core::mem::size_of;

/// Blocks in the ring. RAM: 41 B a block on AVR (34 × 41 = 1 394 B;
/// [`Block`]). grbl-Mega keeps 36, Marlin and Repetier 16 (docs/SPEC.md
/// §11). The newest block must be able to stop, so with n blocks of 0.1 mm
/// behind the executing one at 1000 mm/s² an axis-parallel stream runs at
/// most √(2 · 1000 · n · 0.1) mm/s: 33 blocks ahead allow 81 mm/s, 810
/// lines/s (on the benchmark's circle, whose path may accelerate faster
/// off the axes, 860/s with smooth joints and 775/s with grbl's:
/// `sim::ceiling::lines_per_s_ahead`).
/// A longer ring re-plans longer on an override byte (each change re-plans
/// the whole ring, ~0.5 ms a block on the AVR), which can keep the main
/// loop away from the RX ring for longer than it lasts at 250000 baud: a
/// host that sends without flow control then loses bytes, and the line
/// they were in is dropped with an error (its end, if lost, still ends it:
/// `protocol::RxStore`; `tests/faults.rs`). What limits the length is RAM:
/// 34 leaves 114 B of the budget on the deepest path measured
/// (tests/dialect.rs). Any length works: indices wrap by compares
/// ([`next_index`], [`prev_index`]), not masks.
pub const BLOCK_BUFFER_LEN: usize = 34;

/// RAM budget of the whole planner (ring + state), bytes.
pub const PLANNER_RAM_BUDGET: usize = 2050;

const _: () = assert!(size_of::<Block>() * BLOCK_BUFFER_LEN <= 1536);
const _: () = assert!(size_of::<Planner>() <= PLANNER_RAM_BUDGET);
const _: () = assert!(BLOCK_BUFFER_LEN <= 128);

/// Entries of the short-move cache ([`Short`], a power of two). 4 entries
/// searched all, replaced first in first out, hit 89 % of the benchmark's
/// 0.1 mm circle (21 distinct moves; 4 direct mapped on Σd² hit 78 %, 8
/// direct mapped 88 % for 104 B more).
pub(super) const SHORTS_LEN: usize = 4;

/// A short X/Y/Z move's path values, cached by its Σd² (steps², X/Y/Z at
/// one steps/mm) and its dominant axis' steps n: a stream of short moves
/// repeats a few dozen of them. RAM: 30 B each.
#[derive(Clone, Copy, Debug)]
pub(super) struct Short {
    /// Σd² and n it is for (Σd² = 0: empty).
    pub(super) sum_sqr: u32,
    pub(super) n: u16,
    /// 1/√S.
    pub(super) inv_root: f32,
    /// Path length, mm: √S · mm/step.
    pub(super) mm: f32,
    /// On axes with axis 0's limits: the acceleration a₀/|u|max = a₀·√S·(1/n)
    /// (mm/s²) and F_CPU over it ([`Block::dv_cycles`](super::Block::dv_cycles)), the time per mm at the speed limit
    /// |u|max/v₀ (s/mm), and twice the acceleration times the length
    /// ((mm/s)²).
    pub(super) accel: f32,
    pub(super) dv_cycles: f32,
    pub(super) t_axes: f32,
    pub(super) max_delta: f32,
}

impl Short {
    pub(super) const EMPTY: Short =
        Short { sum_sqr: 0, n: 0, inv_root: 0.0, mm: 0.0, accel: 0.0, dv_cycles: 0.0, t_axes: 0.0, max_delta: 0.0 };
}

/// The block ring and the look-ahead state.
#[cfg_attr(test, derive(Clone))]
pub struct Planner {
    /// The ring; valid blocks are `tail`, tail+1, … (`len` of them).
    pub(super) blocks: [Block; BLOCK_BUFFER_LEN],
    /// Copied into each block queued ([`Block::line`]); the SD job sets it
    /// to the line it hands out.
    pub line_tag: u16,
    /// The feed override, percent (M220, grbl's 0x90-0x94, the menu), and
    /// the rapid override (100, 50 or 25): [`Planner::set_overrides`].
    pub(super) feed_pct: u16,
    pub(super) rapid_pct: u8,
    /// Index of the executing (oldest) block.
    pub(super) tail: u8,
    /// Index where the next block goes.
    pub(super) head: u8,
    /// Blocks queued.
    pub(super) len: u8,
    /// Newest block whose entry speed is optimal (grbl `block_buffer_planned`).
    pub(super) planned: u8,
    /// A re-plan may have changed the executing block's exit speed.
    pub(super) exec_replanned: bool,
    /// Blocks were queued since the last look-ahead pass (see
    /// [`Planner::settle`]).
    pub(super) stale: bool,
    /// The deceleration ramp the last look-ahead pass left after `planned`
    /// (lookahead.rs, "The ramp"): its newest block, and whether the next
    /// pass may extend it rather than re-plan it. The blocks after
    /// `planned` up to `ramp_end` hold their entry speed² less `lift`;
    /// `slack` is the least of their maximum entry speed² less that, so no
    /// block of the ramp reaches its maximum while `lift` stays below it.
    pub(super) ramp_end: u8,
    pub(super) ramp_ok: bool,
    pub(super) lift: f32,
    pub(super) slack: f32,
    /// Axes (bits) whose last direction is known, for backlash.
    pub(super) dir_known: u8,
    /// Last direction of each axis (bit set = negative), for backlash.
    pub(super) last_dir: u8,
    /// Commanded position after the last queued block, steps.
    pub(super) position: [i32; N_AXES],
    /// Motor position minus commanded position after the last queued block
    /// (backlash take-ups), steps, X Y Z.
    pub(super) backlash_offset: [i32; 3],
    /// Unit vector of the last queued block, unless it was a short move
    /// (`previous_inv_root` not 0): then its deltas (steps) and its
    /// 1/√Σd² stand for it (`junction::short_cos`, `junction::short_unit`).
    pub(super) previous_unit_vec: [f32; N_AXES],
    pub(super) previous_delta: [i16; 3],
    pub(super) previous_inv_root: f32,
    /// (moving axes, their negative directions) of the last queued block,
    /// in axis bits: the axes `previous_unit_vec` has non-zero, and their
    /// signs.
    pub(super) previous_axes: (u8, u8),
    /// Nominal speed² of the last queued block, (mm/s)².
    pub(super) previous_nominal_speed_sqr: f32,
    /// Acceleration of the last queued block, mm/s², and F_CPU over it.
    pub(super) previous_acceleration: f32,
    pub(super) previous_dv_cycles: f32,
    /// Per-axis speed limit of the last queued block as time per mm, s/mm.
    pub(super) previous_t_axes: f32,
    /// `previous_acceleration` and `previous_t_axes` match the current settings.
    pub(super) previous_limits_valid: bool,
    /// Bits of the last feed seen, 1/feed, s/mm, and the feed rounded,
    /// mm/min (the feed is modal, so it rarely changes between blocks).
    pub(super) feed_cache: (u32, f32, u16),
    /// Bits of the last time per mm `t` and the nominal speed² 1/t², (mm/s)².
    pub(super) nominal_cache: (u32, f32),
    /// What the junction rule derives from the last junction cap.
    pub(super) cap_sqr_cache: CapCache,
    /// Short moves' path values ([`Short`]), any entry for any move.
    /// RAM: 30 B each.
    pub(super) shorts: [Short; SHORTS_LEN],
    /// The entry of `shorts` the next miss replaces (the oldest).
    pub(super) short_next: u8,
    /// Settings-derived per-axis values.
    pub(super) axis: AxisCache,
    /// A move accepted by [`Planner::accept_line`] and not planned yet: its
    /// time per mm (s/mm) and programmed feed ([`Block::feed`]); its steps
    /// are `delta`. It holds a ring slot.
    pub(super) pending: Option<(f32, u16)>,
    /// Steps of the move being queued, or of the pending one, X Y Z E.
    pub(super) delta: [i32; N_AXES],
    /// `axis` matches the settings [`Planner::accept_line`] is given, until
    /// [`Planner::settings_changed`] (saves comparing 12 settings per move).
    pub(super) axis_fresh: bool,
}

#[inline]
pub(super) const fn next_index(i: u8) -> u8 {
    if i as usize + 1 == BLOCK_BUFFER_LEN {
        0
    } else {
        i + 1
    }
}

#[inline]
pub(super) const fn prev_index(i: u8) -> u8 {
    if i == 0 {
        BLOCK_BUFFER_LEN as u8 - 1
    } else {
        i - 1
    }
}

impl Planner {
    /// An empty planner at position 0.
    pub const fn new() -> Self {
        Planner {
            // All zero, which is `Block::EMPTY` (`new_blocks_are_empty`):
            // written as `[Block::EMPTY; N]`, LLVM-AVR built the array in a
            // temporary of `Machine::init`'s frame (1 318 B, the deepest
            // stack of the boot) and copied it in; zeroed, it writes it in
            // place (a 268-B frame).
            // SAFETY: every field of `Block` is an integer or an f32 (arrays
            // of them): all-zero bytes are a valid value of each (0, 0.0).
            blocks: unsafe { core::mem::zeroed() },
            line_tag: 0,
            feed_pct: 100,
            rapid_pct: 100,
            tail: 0,
            head: 0,
            len: 0,
            planned: 0,
            exec_replanned: false,
            stale: false,
            ramp_end: 0,
            ramp_ok: false,
            lift: 0.0,
            slack: 0.0,
            dir_known: 0,
            last_dir: 0,
            position: [0; N_AXES],
            backlash_offset: [0; 3],
            previous_unit_vec: [0.0; N_AXES],
            previous_delta: [0; 3],
            previous_inv_root: 0.0,
            previous_axes: (0, 0),
            previous_nominal_speed_sqr: 0.0,
            previous_acceleration: 0.0,
            previous_dv_cycles: 0.0,
            previous_t_axes: 0.0,
            previous_limits_valid: false,
            feed_cache: (0, 0.0, 0),
            nominal_cache: (0, 0.0),
            cap_sqr_cache: CapCache::EMPTY,
            shorts: [Short::EMPTY; SHORTS_LEN],
            short_next: 0,
            axis: AxisCache::EMPTY,
            pending: None,
            delta: [0; N_AXES],
            axis_fresh: false,
        }
    }

    /// The executing (oldest) block, if any. (`get`: `tail` is always in
    /// the ring, and this way there is no bounds-check panic to branch to.)
    // speed: prep asks for it several times a segment; inlined it is a few loads
    #[inline]
    pub fn current_block(&self) -> Option<&Block> {
        if self.len == 0 {
            None
        } else {
            self.blocks.get(self.tail as usize)
        }
    }

    /// The executing block, for prep to record progress in.
    // speed: as `current_block`
    #[inline]
    pub fn current_block_mut(&mut self) -> Option<&mut Block> {
        if self.len == 0 {
            None
        } else {
            self.blocks.get_mut(self.tail as usize)
        }
    }

    /// The i-th queued block, 0 = executing (a copy: its entry speed² with
    /// the ramp's `lift` added, as the look-ahead planned it).
    pub fn block(&self, i: usize) -> Option<Block> {
        if i >= self.len as usize {
            return None;
        }
        let k = (self.tail as usize + i) % BLOCK_BUFFER_LEN;
        let mut b = self.blocks[k];
        if self.in_ramp(k as u8) {
            b.entry_speed_sqr += self.lift;
        }
        Some(b)
    }

    /// Block `k` is in the ramp: after `planned`, up to `ramp_end`.
    pub(super) fn in_ramp(&self, k: u8) -> bool {
        let from = |i: u8| (i as usize + BLOCK_BUFFER_LEN - self.planned as usize) % BLOCK_BUFFER_LEN;
        let d = from(k);
        d != 0 && d <= from(self.ramp_end) && from(self.ramp_end) < self.len as usize
    }

    /// Drop the executing block (prep has prepared all its steps).
    pub fn discard_current_block(&mut self) {
        self.discard_current_block_at(None);
    }

    /// [`Planner::discard_current_block`], given the exit speed²
    /// [`Planner::exec_exit_speed_sqr`] answered since the planner last
    /// changed, if the caller has it: the next block's entry speed² is then
    /// that value, not the same sum again (one soft-float add a streamed
    /// block on the AVR; the test `an_exit_given_back_is_the_exit_computed`).
    pub fn discard_current_block_at(&mut self, exit_sqr: Option<f32>) {
        if self.len == 0 {
            return;
        }
        if self.planned == self.tail {
            let n = next_index(self.tail);
            if self.ramp_end == self.planned {
                // No ramp: the next block was not planned yet, or is
                // the newest.
                self.ramp_ok = false;
            } else {
                // The ramp's first block becomes final: its entry speed²
                // as planned.
                let b = &mut self.blocks[n as usize];
                b.entry_speed_sqr = match exit_sqr {
                    Some(e) if self.len > 1 => e,
                    _ => b.entry_speed_sqr + self.lift,
                };
                if n == self.ramp_end {
                    self.lift = 0.0;
                }
            }
            self.planned = n;
        }
        self.tail = next_index(self.tail);
        self.len -= 1;
    }

    /// Exit speed² of the executing block, (mm/s)²: the next block's entry speed,
    /// or 0 when it is the last one.
    // speed: as `current_block` (LLVM keeps it a call with a mere hint)
    #[inline(always)]
    pub fn exec_exit_speed_sqr(&self) -> f32 {
        match self.blocks.get(next_index(self.tail) as usize) {
            // The ramp's first block: planned as its entry plus `lift`.
            Some(b) if self.len > 1 && self.planned == self.tail && self.ramp_end != self.planned => b.entry_speed_sqr + self.lift,
            Some(b) if self.len > 1 => b.entry_speed_sqr,
            _ => 0.0,
        }
    }

    /// True once (then cleared) when a re-plan may have changed the executing
    /// block's exit speed, so prep must recompute its profile.
    pub fn take_exec_replanned(&mut self) -> bool {
        core::mem::replace(&mut self.exec_replanned, false)
    }

    /// Commanded position after the last queued block, steps (X Y Z E). Backlash
    /// take-ups are not included.
    pub fn position(&self) -> [i32; N_AXES] {
        self.position
    }

    /// Set the commanded position (after homing, G92-free resync after an
    /// abort). Call with the queue empty. Resets the backlash offset to 0: the
    /// motors are where the new position says; the slack state (last direction)
    /// is kept.
    pub fn set_position(&mut self, p: [i32; N_AXES]) {
        self.position = p;
        self.backlash_offset = [0; 3];
    }

    /// Motor steps minus commanded steps after the last queued block, X Y Z: the
    /// sum of the queued backlash take-ups since the last `set_position`. When the
    /// queue is idle, reported position = motor step count − this.
    pub fn backlash_offset_steps(&self) -> [i32; 3] {
        self.backlash_offset
    }

    /// Blocks queued (including the executing one and a pending move).
    pub fn len(&self) -> usize {
        self.len as usize + self.pending.is_some() as usize
    }

    /// No block queued (and none pending).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// No free slot (a move with a backlash take-up needs 2).
    pub fn is_full(&self) -> bool {
        self.len() == BLOCK_BUFFER_LEN
    }

    /// Free slots.
    pub fn free(&self) -> usize {
        BLOCK_BUFFER_LEN - self.len()
    }

    /// Drop every block (e-stop, limit, abort). The position is kept as the end
    /// of the dropped moves: the caller must `set_position` to the true motor
    /// position. Backlash directions become unknown.
    pub fn clear(&mut self) {
        self.pending = None;
        self.stale = false;
        self.tail = 0;
        self.head = 0;
        self.len = 0;
        self.planned = 0;
        self.ramp_end = 0;
        self.ramp_ok = false;
        self.lift = 0.0;
        self.exec_replanned = false;
        self.dir_known = 0;
        self.previous_unit_vec = [0.0; N_AXES];
        self.previous_inv_root = 0.0;
        self.previous_axes = (0, 0);
        self.previous_nominal_speed_sqr = 0.0;
        self.previous_acceleration = 0.0;
        self.previous_limits_valid = false;
    }
}

#[cfg(test)]
impl Planner {
    /// The last queued block's unit vector, from its deltas if it was a
    /// short move.
    pub(super) fn previous_unit(&self) -> [f32; N_AXES] {
        super::junction::previous_unit(&self.previous_unit_vec, &self.previous_delta, self.previous_inv_root)
    }
}

impl Default for Planner {
    fn default() -> Self {
        Self::new()
    }
}
