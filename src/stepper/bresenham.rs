//! The Bresenham step distributor (docs/SPEC.md §6): the one model of the step ISR's
//! arithmetic, on the record the ISR runs, [`Chunk`].
//!
//! Where it sits: [`super::queue::Splitter`] (main loop) makes a chunk per
//! planner block, or per piece of at most 32767 events of a longer one; the
//! Timer1 ISR (`board::stepper`) ticks it in its ring slot, once per step
//! event. Integer only, 16-bit, no division, no float.
//!
//! - [`Chunk::tick`] is the reference: what every host test runs (prep's
//!   segments in `stepper::tests`, the splitter's cuts in `queue`, the rings'
//!   host ISR in `rings`).
//! - [`Chunk::tick_out`] is the plain host twin of the ISR's hand-written
//!   assembly (`board::stepper::tick`): the same shortcuts (the `every` and
//!   `partial` masks the splitter precomputes, step-output bits), checked
//!   against the reference by the tests below.
//! - [`Chunk::steps_done`] is the closed form of where the Bresenham is after
//!   k events, from its error counters: the main loop's position of the
//!   chunk in progress (`rings::Rings::position`).
//!
//! Each axis counter starts at `events / 2`, so after event k axis i has
//! made F(k) = ⌊(k·steps_i + ⌊N/2⌋) / N⌋ steps: the rounded ideal position,
//! within ±0.5 step of the straight line, and exactly `steps_i` after N
//! events. An axis with as many steps as events steps every time and one
//! with none never does, so neither needs arithmetic; the others cost one
//! add, a sign test and (when they step) one subtract.

use crate::N_AXES;

/// One piece of a planner block as the ISR runs it (`#[repr(C)]`: the ISR
/// addresses fields by offset from the slot pointer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Chunk {
    /// Bresenham errors minus `events`: −events ≤ error < 0 between ticks, so
    /// "step now" is a sign test. Owned by the ISR while the chunk runs.
    pub error: [i16; N_AXES],
    /// Steps each axis makes in this chunk.
    pub steps: [i16; N_AXES],
    /// Step events in this chunk (the Bresenham denominator), 1..=32767.
    pub events: i16,
    /// Step-output bits ([`super::queue::StepMap::step`]) of the axes that
    /// step on every event.
    pub every: u8,
    /// Axis bits of the axes that step on some events only (the ISR's work).
    pub partial: u8,
    /// Direction pin levels per port (0..3), over the
    /// [`super::queue::StepMap::dir`] masks.
    pub dir_out: [u8; 3],
    /// Axis bits whose home switch closing stops with a hard-limit alarm
    /// (every watched axis but a homed one at 0 at either end of the chunk).
    pub limit: u8,
    /// Axis bits moving negative.
    pub axis_dir: u8,
    /// Backlash take-up: the motors move, the counted position does not.
    pub take_up: bool,
}

impl Chunk {
    /// An empty chunk (no steps; all zero, so a ring of them lives in `.bss`).
    pub const EMPTY: Chunk = Chunk {
        error: [0; N_AXES],
        steps: [0; N_AXES],
        events: 0,
        every: 0,
        partial: 0,
        dir_out: [0; 3],
        limit: 0,
        axis_dir: 0,
        take_up: false,
    };

    /// A chunk of `events` step events making `steps` on each axis (each
    /// ≤ `events`), positive, counters at the start; `every` in axis bits.
    /// (The splitter fills in the same fields, with output bits, in its own
    /// loop.)
    pub fn with_steps(steps: [i16; N_AXES], events: i16) -> Chunk {
        let mut c = Chunk { steps, events, ..Chunk::EMPTY };
        for i in 0..N_AXES {
            c.error[i] = (events >> 1) - events;
            if steps[i] == events && events > 0 {
                c.every |= 1 << i;
            } else if steps[i] > 0 {
                c.partial |= 1 << i;
            }
        }
        c
    }

    /// One Bresenham step event (the reference): bit i of the result set =
    /// axis i steps now (axis bits, not output bits).
    pub fn tick(&mut self) -> u8 {
        let n = self.events;
        let mut bits = 0u8;
        for i in 0..N_AXES {
            let s = self.steps[i];
            if s == 0 {
                continue;
            }
            if s == n {
                bits |= 1 << i;
                continue;
            }
            let e = self.error[i] + s;
            if e >= 0 {
                self.error[i] = e - n;
                bits |= 1 << i;
            } else {
                self.error[i] = e;
            }
        }
        bits
    }

    /// One step event the way the ISR's assembly does it
    /// (`board::stepper::tick`), its plain twin: start from the `every`
    /// output bits, run the counters of the `partial` axes only (16-bit, a
    /// sign test after the add), and OR in `step[i]`, axis i's output bit.
    /// Equal to [`Chunk::tick`] mapped through `step` on every chunk the
    /// splitter makes (tested below).
    pub fn tick_out(&mut self, step: &[u8; N_AXES]) -> u8 {
        let mut bits = self.every;
        let p = self.partial;
        if p != 0 {
            let n = self.events;
            for i in 0..N_AXES {
                if p & (1 << i) != 0 {
                    let e = self.error[i].wrapping_add(self.steps[i]);
                    if e >= 0 {
                        self.error[i] = e.wrapping_sub(n);
                        bits |= step[i];
                    } else {
                        self.error[i] = e;
                    }
                }
            }
        }
        bits
    }

    /// Steps each axis has made after `k` events (0 ≤ k ≤ `events`), from the
    /// error counters as they are after those k events. Unsigned counts.
    pub fn steps_done(&self, k: u16) -> [u16; N_AXES] {
        let n = self.events as u16;
        let mut out = [0u16; N_AXES];
        for i in 0..N_AXES {
            let s = self.steps[i] as u16;
            out[i] = if k == 0 || s == 0 {
                0
            } else if s == n {
                k
            } else if k >= n {
                s
            } else {
                // error + n = (⌊n/2⌋ + k·s) mod n, so the quotient is exact.
                let r = (self.error[i] as i32 + n as i32) as u32;
                ((n as u32 / 2 + k as u32 * s as u32 - r) / n as u32) as u16
            };
        }
        out
    }

    /// Signed steps of `done` (from [`Chunk::steps_done`]) per axis.
    pub fn signed(&self, done: [u16; N_AXES]) -> [i32; N_AXES] {
        let mut out = [0i32; N_AXES];
        for i in 0..N_AXES {
            let d = done[i] as i32;
            out[i] = if self.axis_dir & (1 << i) != 0 { -d } else { d };
        }
        out
    }

    /// Signed steps of the whole chunk.
    pub fn total(&self) -> [i32; N_AXES] {
        let mut done = [0u16; N_AXES];
        for i in 0..N_AXES {
            done[i] = self.steps[i] as u16;
        }
        self.signed(done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stepper::queue::{ChunkWatch, Seg, Sink, Splitter, StepMap, MAX_CHUNK_EVENTS};
    use crate::stepper::{Prescale, Segment, StBlock, StepperCmd};
    use crate::test_util::XorShift;

    /// Where F(k) = ⌊(k·s + ⌊n/2⌋) / n⌋ says each axis is after k events.
    fn ideal(steps: [i16; N_AXES], n: i16, k: u32) -> [u32; N_AXES] {
        steps.map(|s| (k * s as u32 + n as u32 / 2) / n as u32)
    }

    /// Runs a chunk and checks every intermediate point against the ideal
    /// line, the closed form and `steps_done`.
    fn run_and_check(steps: [i16; N_AXES]) {
        let n = *steps.iter().max().unwrap();
        let mut c = Chunk::with_steps(steps, n);
        let mut pos = [0u32; N_AXES];
        for k in 1..=n as u32 {
            let bits = c.tick();
            for a in 0..N_AXES {
                if bits & (1 << a) != 0 {
                    pos[a] += 1;
                }
                let line = k as f64 * steps[a] as f64 / n as f64;
                let err = pos[a] as f64 - line;
                assert!(err.abs() <= 0.5 + 1e-9, "axis {a} event {k}: {} vs {line}", pos[a]);
            }
            assert_eq!(pos, ideal(steps, n, k), "closed form, event {k}");
            assert_eq!(c.steps_done(k as u16).map(|v| v as u32), pos, "steps_done, event {k}");
        }
        assert_eq!(pos, steps.map(|s| s as u32));
    }

    #[test]
    fn bresenham_makes_exact_step_counts_and_stays_within_half_a_step_of_the_line() {
        run_and_check([1, 0, 0, 0]);
        run_and_check([1, 1, 1, 1]);
        run_and_check([2, 1, 0, 0]);
        run_and_check([10, 3, 7, 1]);
        run_and_check([4500, 4499, 1, 2250]);
        run_and_check([997, 1000, 13, 0]);
        run_and_check([32767, 32766, 1, 16384]);
        let mut seed = 0x1234_5678u32;
        for _ in 0..200 {
            let mut s = [0i16; N_AXES];
            for v in s.iter_mut() {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                *v = ((seed >> 8) % 3000) as i16;
            }
            if s.iter().all(|&v| v == 0) {
                continue;
            }
            run_and_check(s);
        }
    }

    #[test]
    fn the_dominant_axis_steps_on_every_event() {
        let mut c = Chunk::with_steps([0, 50, 20, 0], 50);
        for _ in 0..50 {
            assert_ne!(c.tick() & 0b10, 0);
        }
    }

    #[test]
    fn an_empty_chunk_gives_no_steps() {
        let mut c = Chunk::EMPTY;
        for _ in 0..10 {
            assert_eq!(c.tick(), 0);
            assert_eq!(c.tick_out(&[1, 2, 4, 8]), 0);
        }
    }

    #[derive(Default)]
    struct Rec(Vec<Chunk>);

    impl Sink for Rec {
        fn chunk(&mut self, c: &Chunk) {
            self.0.push(*c);
        }
        fn seg(&mut self, _s: &Seg) {}
    }

    /// The ISR's shortcuts (the splitter's `every` output bits and `partial`
    /// axes, 16-bit wrapping counters) step exactly like the reference, on
    /// the board's pin map, through chunk cuts and every kind of axis.
    #[test]
    fn the_isr_twin_steps_exactly_like_the_reference_on_every_chunk_the_splitter_makes() {
        let map = StepMap { step: [0x01, 0x40, 0x08, 0x10], dir: [(0, 0x02), (0, 0x80), (1, 0x02), (2, 0x40)] };
        let mut rng = XorShift(0x5EED);
        let mut checked = 0u64;
        for n in 0..60 {
            let mut steps = [0u32; N_AXES];
            let big = n % 10 == 0;
            for v in steps.iter_mut() {
                *v = match rng.next() % 5 {
                    0 => 0,
                    _ => rng.next() % if big { 70_000 } else { 2000 },
                };
            }
            let events = *steps.iter().max().unwrap();
            if events == 0 {
                continue;
            }
            if n % 3 == 0 {
                steps[(rng.next() % 4) as usize] = events; // a second axis at full rate
            }
            let b = StBlock { steps, step_event_count: events, direction_bits: (rng.next() & 15) as u8, take_up: false };
            let mut rec = Rec::default();
            let mut sp = Splitter::new();
            sp.push(&StepperCmd::Block(b), &map, &ChunkWatch::default(), &mut rec);
            let mut left = events;
            while left > 0 {
                let t = left.min(20_000);
                let seg = Segment { ticks: t as u16, period: 400, prescale: Prescale::Div1 };
                sp.push(&StepperCmd::Run(seg), &map, &ChunkWatch::default(), &mut rec);
                left -= t;
            }
            let chunks = rec.0;
            assert_eq!(chunks.len() > 1, events > MAX_CHUNK_EVENTS);
            for (j, ch) in chunks.iter().enumerate() {
                let (mut model, mut isr) = (*ch, *ch);
                for k in 0..model.events {
                    let want = model.tick();
                    let mut out = 0;
                    for a in 0..N_AXES {
                        if want & (1 << a) != 0 {
                            out |= map.step[a];
                        }
                    }
                    assert_eq!(isr.tick_out(&map.step), out, "block {n}, chunk {j}, event {k}");
                    assert_eq!(isr.error, model.error);
                    checked += 1;
                }
            }
        }
        assert!(checked > 100_000);
    }
}
