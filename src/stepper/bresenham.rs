//! The block-level Bresenham step distributor (SPEC §6): the reference the
//! host tests run prep's segments through.
//!
//! The firmware's ISR runs the same arithmetic on 16-bit
//! [`super::queue::Chunk`]s (a block of ≤ 32767 events is one chunk and steps
//! exactly like this; a longer one is cut into chunks). Integer only, no
//! division, no float.
//!
//! Each axis counter starts at `step_event_count / 2`, so after event k axis i
//! has made ⌊(k·steps_i + ⌊N/2⌋) / N⌋ steps: the rounded ideal position, within
//! ±0.5 step of the straight line, and exactly `steps_i` after N events.
//!
//! `load` sorts the axes: those with as many steps as events step every time
//! and those with none never do, so neither needs arithmetic; the others cost
//! one add, a sign test and (when they step) one subtract.

use super::StBlock;
use crate::N_AXES;

/// Bresenham state of the block the ISR is executing.
#[derive(Clone, Copy, Debug)]
pub struct Bresenham {
    /// Error accumulators minus `step_event_count`: −N ≤ error < 0 between
    /// ticks, so "step now" is a sign test (one byte on the AVR) rather than a
    /// 4-byte compare.
    error: [i32; N_AXES],
    /// Steps of each axis in the block.
    steps: [i32; N_AXES],
    /// Step events of the block (the common denominator).
    step_event_count: i32,
    /// Axes that step on every event (steps == step_event_count): no arithmetic.
    every: u8,
    /// Axes that step on some events (0 < steps < step_event_count).
    partial: u8,
}

impl Bresenham {
    /// An idle distributor (ticks give no steps until a block is loaded).
    pub const fn new() -> Self {
        Bresenham { error: [i32::MIN; N_AXES], steps: [0; N_AXES], step_event_count: 0, every: 0, partial: 0 }
    }

    /// Start a new block. Counts above 2³¹ − 1 steps are not supported (a
    /// block is at most travel × steps/mm, far below).
    pub fn load(&mut self, b: &StBlock) {
        let n = b.step_event_count as i32;
        self.step_event_count = n;
        self.every = 0;
        self.partial = 0;
        for i in 0..N_AXES {
            let s = b.steps[i] as i32;
            self.steps[i] = s;
            if s == n && n > 0 {
                self.every |= 1 << i;
            } else if s > 0 {
                self.partial |= 1 << i;
            }
        }
        // ⌊N/2⌋ − N: the counter starts half way, as in grbl.
        self.error = [(n >> 1) - n; N_AXES];
    }

    /// One step event: bit i of the result set = axis i makes one step now.
    ///
    /// AVR cost (simavr, state in a static as in the ISR): ~45 cycles per axis
    /// that makes only some of the block's steps, a few cycles for the others;
    /// a single-axis or 45° move costs almost nothing.
    #[inline(always)]
    pub fn tick(&mut self) -> u8 {
        let n = self.step_event_count;
        let partial = self.partial;
        let mut bits = self.every;
        macro_rules! axis {
            ($i:expr, $bit:expr) => {
                if partial & $bit != 0 {
                    let e = self.error[$i].wrapping_add(self.steps[$i]);
                    if e >= 0 {
                        core::hint::cold_path();
                        self.error[$i] = e.wrapping_sub(n);
                        bits |= $bit;
                    } else {
                        self.error[$i] = e;
                    }
                }
            };
        }
        axis!(0, 0b0001);
        axis!(1, 0b0010);
        axis!(2, 0b0100);
        axis!(3, 0b1000);
        bits
    }
}

const _: () = assert!(N_AXES == 4, "Bresenham::tick is unrolled for 4 axes");

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
