//! Interrupt service time per vector, from simavr's per-vector "running" IRQs.
//!
//! simavr raises `vector->irq[AVR_INT_IRQ_RUNNING]` with 1 when it dispatches
//! a vector and with 0 when the matching RETI executes (sim_interrupts.c);
//! those IRQs are not filtered, so re-entry of the same vector is seen too.
//! The tracker keeps a stack of entry times per vector and closes the newest
//! one on each RETI. No single-stepping is involved.
//!
//! Cycle accounting, made to match the hardware: simavr charges nothing for
//! the interrupt response (the ATmega2560 with its 3-byte PC takes 5 cycles:
//! push PC, clear I, fetch vector) and reports RETI before charging its 5
//! cycles. Each sample is therefore `RETI start - dispatch + 10`
//! ([`HW_OVERHEAD_CYCLES`]): response + vector JMP + body + RETI, the figure
//! the datasheet arithmetic gives. Nested interrupts count inside the outer
//! one's time (wall time from entry to RETI).

use serde::Serialize;

/// Cycles the hardware spends that the raw measurement misses: 5 for the
/// interrupt response (not charged by simavr) + 5 for RETI (charged after the
/// notification).
pub const HW_OVERHEAD_CYCLES: u64 = 10;

/// The stepper ISR: TIMER1_COMPA is vector 17 on the ATmega2560
/// (iom2560.h `TIMER1_COMPA_vect_num`).
pub const STEPPER_VECTOR: u8 = 17;

/// Service-time statistics of one vector, in CPU cycles.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct IsrStats {
    pub vector: u8,
    /// Completed services (entry followed by RETI).
    pub count: u64,
    pub min_cycles: u64,
    pub max_cycles: u64,
    pub mean_cycles: f64,
    pub total_cycles: u64,
}

#[derive(Clone, Debug, Default)]
struct VectorState {
    open: Vec<u64>,
    count: u64,
    min: u64,
    max: u64,
    total: u64,
}

/// Per-vector accumulator. Vectors 0..64.
#[derive(Clone, Debug)]
pub struct IsrTracker {
    vectors: Vec<VectorState>,
    max_depth: u32,
}

impl Default for IsrTracker {
    fn default() -> Self {
        IsrTracker { vectors: vec![VectorState::default(); 64], max_depth: 0 }
    }
}

impl IsrTracker {
    /// A vector was dispatched at `cycle`; `depth` is the nesting depth
    /// including this one.
    pub fn enter(&mut self, vector: u8, cycle: u64, depth: u32) {
        if let Some(v) = self.vectors.get_mut(vector as usize) {
            v.open.push(cycle);
        }
        self.max_depth = self.max_depth.max(depth);
    }

    /// The RETI of `vector` started at `cycle`.
    pub fn exit(&mut self, vector: u8, cycle: u64) {
        let Some(v) = self.vectors.get_mut(vector as usize) else { return };
        let Some(start) = v.open.pop() else { return };
        let d = cycle.saturating_sub(start) + HW_OVERHEAD_CYCLES;
        if v.count == 0 {
            v.min = d;
            v.max = d;
        } else {
            v.min = v.min.min(d);
            v.max = v.max.max(d);
        }
        v.count += 1;
        v.total += d;
    }

    /// The chip was reset: open services will never return.
    pub fn on_reset(&mut self) {
        for v in &mut self.vectors {
            v.open.clear();
        }
    }

    /// Statistics of one vector, `None` if it never completed.
    pub fn stats(&self, vector: u8) -> Option<IsrStats> {
        let v = self.vectors.get(vector as usize)?;
        (v.count > 0).then(|| IsrStats {
            vector,
            count: v.count,
            min_cycles: v.min,
            max_cycles: v.max,
            mean_cycles: v.total as f64 / v.count as f64,
            total_cycles: v.total,
        })
    }

    /// Statistics of every vector that ran, by vector number.
    pub fn all(&self) -> Vec<IsrStats> {
        (0..self.vectors.len() as u8).filter_map(|v| self.stats(v)).collect()
    }

    /// Deepest nesting seen.
    pub fn max_depth(&self) -> u32 {
        self.max_depth
    }

    /// Forget all statistics (open services are kept).
    pub fn clear(&mut self) {
        for v in &mut self.vectors {
            let open = std::mem::take(&mut v.open);
            *v = VectorState { open, ..Default::default() };
        }
        self.max_depth = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_services_close_innermost_first() {
        let mut t = IsrTracker::default();
        t.enter(17, 100, 1);
        t.enter(25, 120, 2);
        t.exit(25, 150);
        t.exit(17, 300);
        t.enter(17, 1000, 1);
        t.exit(17, 1100);
        let s = t.stats(17).unwrap();
        assert_eq!((s.count, s.min_cycles, s.max_cycles), (2, 110, 210));
        assert_eq!(s.mean_cycles, 160.0);
        assert_eq!(t.stats(25).unwrap().max_cycles, 40);
        assert_eq!(t.max_depth(), 2);
        assert!(t.stats(3).is_none());
    }
}
