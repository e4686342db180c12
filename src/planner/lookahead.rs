//! The look-ahead (grbl's `planner_recalculate`): the backward and forward
//! passes over the ring that set each block's entry speed, when they run
//! ([`Planner::settle`]), and the full re-plans after a feed hold or an
//! override.

use super::float_bits::{lt_nn, min_nn};
use super::ring::{next_index, prev_index, Planner};

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
    pub(super) fn recalculate(&mut self) {
        self.stale = false;
        let mut idx = prev_index(self.head);
        if idx == self.planned {
            return;
        }
        // The newest block always ends at zero speed.
        let mut cur = idx;
        {
            let b = &mut self.blocks[cur as usize];
            b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, b.max_delta_speed_sqr);
        }
        idx = prev_index(idx);
        if idx == self.planned {
            if idx == self.tail {
                self.exec_replanned = true;
            }
        } else {
            while idx != self.planned {
                let next_entry = self.blocks[cur as usize].entry_speed_sqr;
                cur = idx;
                idx = prev_index(idx);
                if idx == self.tail {
                    // The block after the executing one is about to change.
                    self.exec_replanned = true;
                }
                let b = &mut self.blocks[cur as usize];
                if b.entry_speed_sqr.to_bits() != b.max_entry_speed_sqr.to_bits() {
                    b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, next_entry + b.max_delta_speed_sqr);
                }
            }
        }
        // Forward pass.
        let mut cur = self.planned;
        let mut idx = next_index(cur);
        while idx != self.head {
            let (cur_entry, cur_delta) = {
                let c = &self.blocks[cur as usize];
                (c.entry_speed_sqr, c.max_delta_speed_sqr)
            };
            let n = &mut self.blocks[idx as usize];
            if lt_nn(cur_entry, n.entry_speed_sqr) {
                let e = cur_entry + cur_delta;
                if lt_nn(e, n.entry_speed_sqr) {
                    // Acceleration-limited: optimal, nothing before it can change.
                    n.entry_speed_sqr = e;
                    self.planned = idx;
                }
            }
            if n.entry_speed_sqr.to_bits() == n.max_entry_speed_sqr.to_bits() {
                self.planned = idx;
            }
            cur = idx;
            idx = next_index(idx);
        }
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
