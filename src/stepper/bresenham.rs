//! The Bresenham step distributor run by the Timer1 compare ISR (SPEC §6).
//!
//! Last stage of the pipeline: `board`'s ISR loads a [`StBlock`] when
//! prep sends one, then calls [`Bresenham::tick`] once per step event and writes
//! the returned bits to the step pins. Integer only: per axis one u32 add, one
//! compare and (when it steps) one u32 subtract; no division, no float.
//!
//! Each axis counter starts at `step_event_count / 2`, so after event k axis i
//! has made ⌊(k·steps_i + ⌊N/2⌋) / N⌋ steps: the rounded ideal position, within
//! ±0.5 step of the straight line, and exactly `steps_i` after N events.

use super::StBlock;
use crate::N_AXES;

/// Bresenham state of the block the ISR is executing.
#[derive(Clone, Copy, Debug)]
pub struct Bresenham {
    /// Error accumulators, 0 ≤ counter < step_event_count.
    counter: [u32; N_AXES],
    /// Steps of each axis in the block.
    steps: [u32; N_AXES],
    /// Step events of the block (the common denominator).
    step_event_count: u32,
}

impl Bresenham {
    /// An idle distributor (ticks give no steps until a block is loaded).
    pub const fn new() -> Self {
        Bresenham { counter: [0; N_AXES], steps: [0; N_AXES], step_event_count: u32::MAX }
    }

    /// Start a new block.
    pub fn load(&mut self, b: &StBlock) {
        self.steps = b.steps;
        self.step_event_count = b.step_event_count;
        self.counter = [b.step_event_count >> 1; N_AXES];
    }

    /// One step event: bit i of the result set = axis i makes one step now.
    #[inline(always)]
    pub fn tick(&mut self) -> u8 {
        let n = self.step_event_count;
        let mut bits = 0u8;
        // Unrolled by the compiler (N_AXES is a constant 4).
        let mut i = 0;
        while i < N_AXES {
            let c = self.counter[i].wrapping_add(self.steps[i]);
            if c >= n {
                self.counter[i] = c.wrapping_sub(n);
                bits |= 1 << i;
            } else {
                self.counter[i] = c;
            }
            i += 1;
        }
        bits
    }
}

impl Default for Bresenham {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(steps: [u32; N_AXES]) -> StBlock {
        StBlock {
            steps,
            step_event_count: *steps.iter().max().unwrap(),
            direction_bits: 0,
            take_up: false,
        }
    }

    /// Runs a block and checks every intermediate point against the ideal line.
    fn run_and_check(steps: [u32; N_AXES]) {
        let b = block(steps);
        let mut br = Bresenham::new();
        br.load(&b);
        let n = b.step_event_count;
        let mut pos = [0u32; N_AXES];
        for k in 1..=n {
            let bits = br.tick();
            for a in 0..N_AXES {
                if bits & (1 << a) != 0 {
                    pos[a] += 1;
                }
                let ideal = k as f64 * steps[a] as f64 / n as f64;
                let err = pos[a] as f64 - ideal;
                assert!(err.abs() <= 0.5 + 1e-9, "axis {a} event {k}: {} vs {ideal}", pos[a]);
            }
        }
        assert_eq!(pos, steps);
    }

    #[test]
    fn bresenham_makes_exact_step_counts_and_stays_within_half_a_step_of_the_line() {
        run_and_check([1, 0, 0, 0]);
        run_and_check([1, 1, 1, 1]);
        run_and_check([2, 1, 0, 0]);
        run_and_check([10, 3, 7, 1]);
        run_and_check([4500, 4499, 1, 2250]);
        run_and_check([997, 1000, 13, 0]);
        let mut seed = 0x1234_5678u32;
        for _ in 0..200 {
            let mut s = [0u32; N_AXES];
            for v in s.iter_mut() {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                *v = (seed >> 8) % 3000;
            }
            if s.iter().all(|&v| v == 0) {
                continue;
            }
            run_and_check(s);
        }
    }

    #[test]
    fn the_dominant_axis_steps_on_every_event() {
        let mut br = Bresenham::new();
        br.load(&block([0, 50, 20, 0]));
        for _ in 0..50 {
            assert_ne!(br.tick() & 0b10, 0);
        }
    }

    #[test]
    fn an_unloaded_distributor_gives_no_steps() {
        let mut br = Bresenham::new();
        for _ in 0..10 {
            assert_eq!(br.tick(), 0);
        }
    }
}
