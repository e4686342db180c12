//! The records the stepper ISR executes, and the producer that writes them
//! (docs/SPEC.md §6: "the ISR stays integer-only and short").
//!
//! Where it sits: prep ([`super::Prep`]) emits [`StepperCmd`]s in the main
//! loop; [`Splitter`], the first stage of [`super::rings::Rings::push`]
//! (also main loop), turns them into two kinds of small, fixed records
//! that it writes through [`Sink`] into the two rings the board's Timer1 ISR
//! reads **in place, by index** (nothing is copied per segment):
//!
//! - [`Chunk`] (26 B, defined with its arithmetic in [`super::bresenham`]):
//!   the Bresenham of one planner block, or of a piece of at
//!   most [`MAX_CHUNK_EVENTS`] step events of a longer block. Every count fits
//!   an `i16`, so the ISR's tick is 16-bit. The error counters live in the
//!   ring slot and the ISR updates them there.
//! - [`Seg`] (8 B): `ticks` step events, one every `period` timer counts, of
//!   the current chunk, or of the next one when `new_chunk` is set.
//!
//! Position is **not** counted per step in the ISR (it cost ~20 cycles per
//! stepping axis). The main loop knows every chunk it queued: a finished
//! chunk adds its `steps`, and the chunk in progress adds
//! [`Chunk::steps_done`], computed from its error counters. See
//! [`super::rings::Rings::position`].
//!
//! Splitting a long block: the pieces are cut at k = j·C events (C ≤ 32767),
//! and piece j makes `F(k_{j+1}) − F(k_j)` steps on each axis, where
//! `F(k) = ⌊(k·steps + ⌊N/2⌋) / N⌋` is where the block's own Bresenham is after
//! k events. Each piece is a Bresenham of its own, so inside a piece a step is
//! within 0.5 step of the piece's line, whose ends are within 0.5 step of the
//! block's line: within ±1 step overall (docs/SPEC.md §11), and the block's total is
//! exact. A block of ≤ 32767 events is one chunk and steps exactly as one
//! Bresenham.

pub use super::bresenham::Chunk;
use super::{Segment, StBlock, StepperCmd};
use crate::N_AXES;

/// Most step events in one chunk (the ISR's counters are `i16`).
pub const MAX_CHUNK_EVENTS: u32 = i16::MAX as u32;

/// Board-specific output bits, supplied by `board` (logic never sees a pin):
/// what to write for each axis' step pin, and where its direction pin sits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepMap {
    /// The step-output bit of each axis, X Y Z E. They must not overlap; the
    /// ISR's `pending` byte is their OR.
    pub step: [u8; N_AXES],
    /// The direction pin of each axis as (port number 0..3, bit mask).
    pub dir: [(u8, u8); N_AXES],
}

/// A run of step events (`#[repr(C)]`: the ISR reads it by offset).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Seg {
    /// Step events, ≥ 1.
    pub ticks: u16,
    /// OCR1A: timer counts between events.
    pub period: u16,
    /// TCCR1B value (CTC mode + clock select of the segment's prescaler).
    pub tccr: u8,
    /// Non-zero: this segment starts the next chunk of the ring.
    pub new_chunk: u8,
    /// Events of its chunk done at the end of this segment (main loop only:
    /// the position of a chunk in progress).
    pub k_end: u16,
}

/// TCCR1B for CTC mode (WGM12) with the given prescaler.
pub const fn tccr1b(p: super::Prescale) -> u8 {
    0x08 | p as u8
}

/// Where the records go (the board's rings; a `Vec` in tests).
pub trait Sink {
    /// Append a chunk (its slot must be free).
    fn chunk(&mut self, c: &Chunk);
    /// Append a segment.
    fn seg(&mut self, s: &Seg);
    /// Append a chunk written in place by `fill`, which must set every
    /// field (the slot holds a stale chunk). By default it is built aside
    /// and handed to [`Sink::chunk`]; the board's rings write the free slot.
    fn chunk_in_place(&mut self, fill: impl FnOnce(&mut Chunk)) {
        let mut c = Chunk::EMPTY;
        fill(&mut c);
        self.chunk(&c);
    }
}

/// What the ISR should watch on the chunks it is given (from the machine's
/// `Io::set_watch`), plus the direction inversion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ChunkWatch {
    /// Axes whose switch raises a hard-limit alarm (hard limits on, not homing).
    pub limits: u8,
    /// Homed axes (their switch closing at position 0 is expected).
    pub homed: u8,
    /// Direction-pin inversion mask (setting).
    pub invert_dir: u8,
    /// Per axis X, Y, Z: how far above 0, in steps, a homed axis' switch may
    /// still be closed (a real switch's hysteresis; the homing pull-off,
    /// which homing checked clears the switch).
    pub release: [u16; 3],
}

/// Turns prep's [`StepperCmd`] stream into [`Chunk`]s and [`Seg`]s.
///
/// A `Block` costs at most one chunk; a `Run` at most two segments and one
/// chunk (it may cross one chunk boundary, since a segment is far shorter than
/// 32767 events).
#[derive(Clone, Copy, Debug)]
pub struct Splitter {
    /// The block being cut.
    block: StBlock,
    /// Events of the block put in segments so far.
    k: u32,
    /// Events per chunk of this block.
    chunk_len: u32,
    /// k at which the current chunk starts / ends.
    chunk_start: u32,
    chunk_end: u32,
    /// F(chunk_end) per axis: steps of the block done at the end of the current chunk.
    f_end: [u32; N_AXES],
    /// The next segment is the first of a new chunk.
    new_chunk: bool,
    /// Counted position at the end of everything emitted, steps.
    plan_pos: [i32; N_AXES],
    /// Axes that reached 0 and have stayed within their release distance
    /// since (a real switch may still be closed there).
    held: u8,
}

impl Splitter {
    /// Idle, at position 0.
    pub const fn new() -> Self {
        Splitter {
            block: StBlock { steps: [0; N_AXES], step_event_count: 0, direction_bits: 0, take_up: false },
            k: 0,
            chunk_len: 1,
            chunk_start: 0,
            chunk_end: 0,
            f_end: [0; N_AXES],
            new_chunk: false,
            plan_pos: [0; N_AXES],
            held: 0,
        }
    }

    /// Forget the block in progress; everything queued ends at `position`.
    pub fn reset(&mut self, position: [i32; N_AXES]) {
        *self = Splitter::new();
        self.plan_pos = position;
    }

    /// Counted position at the end of everything emitted.
    pub fn plan_position(&self) -> [i32; N_AXES] {
        self.plan_pos
    }

    /// Feed one command to the sink.
    pub fn push(&mut self, cmd: &StepperCmd, map: &StepMap, w: &ChunkWatch, sink: &mut impl Sink) {
        match cmd {
            StepperCmd::Block(b) => {
                self.begin(b);
                if b.step_event_count <= MAX_CHUNK_EVENTS {
                    self.whole_chunk(map, w, sink);
                } else {
                    self.next_chunk(map, w, sink);
                }
            }
            StepperCmd::Run(s) => self.run(s, map, w, sink),
        }
    }

    /// Take `b` as the block being cut, none of it emitted yet.
    fn begin(&mut self, b: &StBlock) {
        self.block = *b;
        self.k = 0;
        let n = b.step_event_count;
        // Equal pieces of at most MAX_CHUNK_EVENTS (no division in the
        // usual case of a short block).
        self.chunk_len = if n <= MAX_CHUNK_EVENTS { n } else { n.div_ceil(n.div_ceil(MAX_CHUNK_EVENTS)) };
        self.chunk_end = 0;
        if n > MAX_CHUNK_EVENTS {
            self.f_end = [0; N_AXES];
        }
    }

    fn run(&mut self, s: &Segment, map: &StepMap, w: &ChunkWatch, sink: &mut impl Sink) {
        let mut left = s.ticks as u32;
        let tccr = tccr1b(s.prescale);
        while left > 0 {
            if self.k == self.chunk_end {
                if self.k >= self.block.step_event_count {
                    // More ticks than the block has events: prep never does this.
                    debug_assert!(false, "segment beyond its block");
                    return;
                }
                self.next_chunk(map, w, sink);
            }
            let take = left.min(self.chunk_end - self.k);
            self.k += take;
            left -= take;
            sink.seg(&Seg {
                ticks: take as u16,
                period: s.period,
                tccr,
                new_chunk: self.new_chunk as u8,
                k_end: (self.k - self.chunk_start) as u16,
            });
            self.new_chunk = false;
        }
    }

    /// [`Splitter::next_chunk`] for a block of one chunk (at most
    /// [`MAX_CHUNK_EVENTS`] events, the usual case), written in place into
    /// the sink's free slot: no F(k) arithmetic, no chunk built on the stack
    /// and copied (~1 100 instead of ~1 700 cycles a block on the AVR).
    /// `next_chunk` is its plain twin (the test
    /// `a_whole_chunk_written_in_place_is_the_plain_one`).
    // speed: one call per block, inlined into `push`'s one caller
    #[inline(always)]
    fn whole_chunk(&mut self, map: &StepMap, w: &ChunkWatch, sink: &mut impl Sink) {
        let n = self.block.step_event_count;
        let events = n as i16;
        let dir = self.block.direction_bits & 0x0F;
        let take_up = self.block.take_up;
        let steps = &self.block.steps;
        let plan_pos = &mut self.plan_pos;
        let held = &mut self.held;
        sink.chunk_in_place(|c| {
            let error0 = (events >> 1) - events;
            let (mut every, mut partial, mut dir_out, mut ends_at_zero) = (0u8, 0u8, [0u8; 3], 0u8);
            let mut h = *held;
            let high = !dir ^ w.invert_dir;
            // One axis (`i` and `bit` constants: unrolled, ~40 % fewer
            // cycles than the loop on the AVR).
            macro_rules! axis {
                ($i:literal, $release:expr) => {{
                    let bit = 1u8 << $i;
                    let p = plan_pos[$i];
                    if p == 0 {
                        h |= bit;
                    } else if p < 0 || p > $release {
                        h &= !bit;
                    }
                    let s = steps[$i] as i16;
                    c.steps[$i] = s;
                    c.error[$i] = error0;
                    let mut q = p;
                    if s != 0 {
                        if s == events {
                            every |= map.step[$i];
                        } else {
                            partial |= bit;
                        }
                        if !take_up {
                            q = if dir & bit != 0 { p - s as i32 } else { p + s as i32 };
                            plan_pos[$i] = q;
                        }
                    }
                    if q == 0 {
                        ends_at_zero |= bit;
                    }
                    if high & bit != 0 {
                        let (port, mask) = map.dir[$i];
                        dir_out[port as usize] |= mask;
                    }
                }};
            }
            const _: () = assert!(N_AXES == 4);
            axis!(0, w.release[0] as i32);
            axis!(1, w.release[1] as i32);
            axis!(2, w.release[2] as i32);
            axis!(3, 0);
            *held = h;
            c.events = events;
            c.every = every;
            c.partial = partial;
            c.dir_out = dir_out;
            // See `next_chunk` (an axis' held bit, once updated, is its
            // "starts at zero").
            c.limit = w.limits & !(w.homed & (h | ends_at_zero));
            c.axis_dir = dir;
            c.take_up = take_up;
        });
        self.chunk_start = 0;
        self.chunk_end = n;
        self.new_chunk = true;
    }

    /// Emit the chunk that starts at the current chunk end.
    fn next_chunk(&mut self, map: &StepMap, w: &ChunkWatch, sink: &mut impl Sink) {
        let n = self.block.step_event_count;
        let start = self.chunk_end;
        let end = if n <= MAX_CHUNK_EVENTS { n } else { (start + self.chunk_len).min(n) };
        // A block of one chunk (the usual case) needs none of the F(k) arithmetic.
        let whole = start == 0 && end == n;
        let events = (end - start) as i16;
        let dir = self.block.direction_bits & 0x0F;
        let mut c = Chunk { events, axis_dir: dir, take_up: self.block.take_up, ..Chunk::EMPTY };
        let error0 = (events >> 1) - events;
        let mut ends_at_zero = 0u8;
        let mut starts_at_zero = 0u8;
        // Pin high = positive, unless the axis is inverted.
        let high = !dir ^ w.invert_dir;
        for i in 0..N_AXES {
            let bit = 1u8 << i;
            let release = if i < 3 { w.release[i] as i32 } else { 0 };
            if self.plan_pos[i] == 0 {
                self.held |= bit;
            } else if self.plan_pos[i] < 0 || self.plan_pos[i] > release {
                self.held &= !bit;
            }
            if self.held & bit != 0 {
                starts_at_zero |= bit;
            }
            let s = if whole {
                self.block.steps[i]
            } else {
                let f = if end == n { self.block.steps[i] } else { mul_add_div(end, self.block.steps[i], n / 2, n) };
                let s = f - self.f_end[i];
                self.f_end[i] = f;
                s
            } as i16;
            c.steps[i] = s;
            c.error[i] = error0;
            if s != 0 {
                if s == events {
                    c.every |= map.step[i];
                } else {
                    c.partial |= bit;
                }
                if !self.block.take_up {
                    if dir & bit != 0 {
                        self.plan_pos[i] -= s as i32;
                    } else {
                        self.plan_pos[i] += s as i32;
                    }
                }
            }
            if self.plan_pos[i] == 0 {
                ends_at_zero |= bit;
            }
            if high & bit != 0 {
                let (port, mask) = map.dir[i];
                c.dir_out[port as usize] |= mask;
            }
        }
        // docs/SPEC.md §6: a switch tripping outside homing is an alarm, whether its
        // axis moves toward it, away from it or not at all. Not armed: a homed
        // axis that ends this chunk at 0, where its switch is closed by
        // definition (machine 0 is the trip point), or starts it between 0
        // and its release distance having been at 0 since it last left
        // that band: a real switch that closed at 0 stays closed for its
        // hysteresis. (After homing the band was left: the pull-off was
        // checked to clear the switch and the position reset.)
        c.limit = w.limits & !(w.homed & (starts_at_zero | ends_at_zero));
        sink.chunk(&c);
        self.chunk_start = start;
        self.chunk_end = end;
        self.new_chunk = true;
    }
}

impl Default for Splitter {
    fn default() -> Self {
        Self::new()
    }
}

/// ⌊(a·b + c) / d⌋ for a ≤ d, c < d, d > 0 (the result is then ≤ b). A 64-bit
/// product and a bit-by-bit division: no 64-bit division intrinsic on the AVR.
/// Used only when a block is longer than [`MAX_CHUNK_EVENTS`].
pub fn mul_add_div(a: u32, b: u32, c: u32, d: u32) -> u32 {
    let num = a as u64 * b as u64 + c as u64;
    let mut rem: u64 = 0;
    let mut q: u32 = 0;
    let mut i = 64;
    while i > 0 {
        i -= 1;
        rem = (rem << 1) | ((num >> i) & 1);
        q <<= 1;
        if rem >= d as u64 {
            rem -= d as u64;
            q |= 1;
        }
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stepper::Prescale;
    use crate::test_util::XorShift;

    const MAP: StepMap = StepMap { step: [0x01, 0x40, 0x08, 0x10], dir: [(0, 0x02), (0, 0x80), (1, 0x02), (2, 0x40)] };

    #[derive(Default)]
    struct Rec {
        chunks: Vec<Chunk>,
        segs: Vec<Seg>,
    }

    impl Sink for Rec {
        fn chunk(&mut self, c: &Chunk) {
            self.chunks.push(*c);
        }
        fn seg(&mut self, s: &Seg) {
            self.segs.push(*s);
        }
    }

    fn block(steps: [u32; N_AXES], dir: u8) -> StBlock {
        StBlock { steps, step_event_count: *steps.iter().max().unwrap(), direction_bits: dir, take_up: false }
    }

    fn run(s: u16) -> StepperCmd {
        StepperCmd::Run(Segment { ticks: s, period: 400, prescale: Prescale::Div1 })
    }

    /// Executes the records like the ISR; checks every event against the
    /// block's line (±1 step) and the position reconstruction at every event.
    fn execute(b: &StBlock, rec: &Rec) -> [i64; N_AXES] {
        let mut ci = usize::MAX;
        let mut chunk = Chunk::EMPTY;
        let mut pos = [0i64; N_AXES];
        let mut base = [0i64; N_AXES];
        let mut events = 0u64;
        let n = b.step_event_count as f64;
        for s in &rec.segs {
            if s.new_chunk != 0 {
                if ci != usize::MAX {
                    for a in 0..N_AXES {
                        base[a] += chunk.total()[a] as i64;
                    }
                }
                ci = ci.wrapping_add(1);
                chunk = rec.chunks[ci];
            }
            let k0 = s.k_end - s.ticks;
            for t in 0..s.ticks {
                let bits = chunk.tick();
                events += 1;
                for a in 0..N_AXES {
                    if bits & (1 << a) != 0 {
                        pos[a] += if chunk.axis_dir & (1 << a) != 0 { -1 } else { 1 };
                    }
                    let ideal = events as f64 * b.steps[a] as f64 / n;
                    assert!((pos[a].abs() as f64 - ideal).abs() <= 1.0 + 1e-9, "axis {a} event {events}");
                }
                let done = chunk.signed(chunk.steps_done(k0 + t + 1));
                for a in 0..N_AXES {
                    assert_eq!(base[a] + done[a] as i64, pos[a], "reconstructed position, axis {a}");
                }
            }
        }
        assert_eq!(events, b.step_event_count as u64);
        pos
    }

    #[test]
    fn a_short_block_is_one_chunk_and_steps_exactly_like_one_bresenham() {
        let b = block([1000, 999, 333, 0], 0b0010);
        let mut sp = Splitter::new();
        let mut rec = Rec::default();
        let w = ChunkWatch::default();
        sp.push(&StepperCmd::Block(b), &MAP, &w, &mut rec);
        for _ in 0..10 {
            sp.push(&run(100), &MAP, &w, &mut rec);
        }
        assert_eq!(rec.chunks.len(), 1);
        assert_eq!(rec.segs.len(), 10);
        let c = rec.chunks[0];
        assert_eq!((c.every, c.partial), (0x01, 0b0110));
        // X positive: pin high; Y negative: pin low; Z positive: pin high.
        assert_eq!(c.dir_out, [0x02, 0x02, 0x40]);
        // Exactly one Bresenham over the whole block: axis i has made
        // F(k) = ⌊(k·steps_i + ⌊N/2⌋) / N⌋ steps after k events.
        let mut ch = c;
        for k in 1..=1000u32 {
            let bits = ch.tick();
            for a in 0..N_AXES {
                let f = |k: u32| (k * b.steps[a] + 500) / 1000;
                assert_eq!(bits & (1 << a) != 0, f(k) > f(k - 1), "axis {a} event {k}");
            }
        }
        assert_eq!(execute(&b, &rec), [1000, -999, 333, 0]);
        assert_eq!(sp.plan_position(), [1000, -999, 333, 0]);
    }

    #[test]
    fn a_long_block_is_cut_into_chunks_with_exact_totals_and_segments_split_at_the_cuts() {
        let b = block([100_000, 77_777, 3, 99_999], 0b1001);
        let mut sp = Splitter::new();
        let mut rec = Rec::default();
        let w = ChunkWatch::default();
        sp.push(&StepperCmd::Block(b), &MAP, &w, &mut rec);
        let mut left = 100_000u32;
        while left > 0 {
            let t = left.min(1234);
            sp.push(&run(t as u16), &MAP, &w, &mut rec);
            left -= t;
        }
        assert_eq!(rec.chunks.len(), 4);
        assert!(rec.chunks.iter().all(|c| c.events as u32 <= MAX_CHUNK_EVENTS));
        assert_eq!(rec.segs.iter().filter(|s| s.new_chunk != 0).count(), 4);
        assert_eq!(execute(&b, &rec), [-100_000, 77_777, 3, -99_999]);
    }

    #[test]
    fn random_blocks_step_within_one_step_of_their_line_and_end_exactly() {
        let mut rng = XorShift(0xC0FFEE);
        for _ in 0..40 {
            let mut steps = [0u32; N_AXES];
            let big = rng.next().is_multiple_of(2);
            for v in steps.iter_mut() {
                *v = rng.next() % if big { 90_000 } else { 3000 };
            }
            if steps.iter().all(|&v| v == 0) {
                continue;
            }
            let dir = (rng.next() & 0x0F) as u8;
            let b = block(steps, dir);
            let mut sp = Splitter::new();
            let mut rec = Rec::default();
            sp.push(&StepperCmd::Block(b), &MAP, &ChunkWatch::default(), &mut rec);
            let mut left = b.step_event_count;
            while left > 0 {
                let t = left.min(1 + rng.next() % 2000);
                sp.push(&run(t as u16), &MAP, &ChunkWatch::default(), &mut rec);
                left -= t;
            }
            let pos = execute(&b, &rec);
            for a in 0..N_AXES {
                let want = if dir & (1 << a) != 0 { -(steps[a] as i64) } else { steps[a] as i64 };
                assert_eq!(pos[a], want);
            }
        }
    }

    #[test]
    fn hard_limits_arm_every_axis_but_a_homed_one_at_its_switch() {
        let w = ChunkWatch { limits: 0b111, homed: 0b001, invert_dir: 0, release: [0; 3] };
        let mut sp = Splitter::new();
        sp.reset([100, 100, 100, 0]);
        let mut rec = Rec::default();
        // X to exactly 0 (homed): not armed. Y toward its switch, Z away: armed.
        sp.push(&StepperCmd::Block(block([100, 50, 10, 0], 0b011)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks[0].limit, 0b110);
        // X from 0 further negative (starts at its switch): not armed; Y, Z idle: armed.
        sp.push(&StepperCmd::Block(block([5, 0, 0, 0], 0b001)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks[1].limit, 0b110);
        // X back through 0 to +5, then Y alone: X is off its switch: armed again.
        sp.push(&StepperCmd::Block(block([10, 0, 0, 0], 0)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks[2].limit, 0b111);
        sp.push(&StepperCmd::Block(block([0, 10, 0, 0], 0)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks[3].limit, 0b111);
        // An unhomed axis at 0 is armed (its position is not known).
        let unhomed = ChunkWatch { homed: 0, ..w };
        sp.reset([0, 100, 100, 0]);
        sp.push(&StepperCmd::Block(block([10, 0, 0, 0], 0)), &MAP, &unhomed, &mut rec);
        assert_eq!(rec.chunks[4].limit, 0b111);
        // Hard limits off (or homing): nothing armed.
        let off = ChunkWatch { limits: 0, ..w };
        sp.push(&StepperCmd::Block(block([0, 10, 0, 0], 0b010)), &MAP, &off, &mut rec);
        assert_eq!(rec.chunks[5].limit, 0);
    }

    #[test]
    fn a_homed_axis_starting_inside_its_release_distance_is_not_armed() {
        let w = ChunkWatch { limits: 0b111, homed: 0b011, invert_dir: 0, release: [5, 5, 5] };
        let mut sp = Splitter::new();
        sp.reset([0, 100, 100, 0]);
        let mut rec = Rec::default();
        // X from 0 to 3, 3 to 5 (the switch may still be closed), 5 to 6 (at
        // 5: still inside), 6 to 10 (outside: armed again).
        for (d, limit) in [(3, 0b110), (2, 0b110), (1, 0b110), (4, 0b111)] {
            sp.push(&StepperCmd::Block(block([d, 0, 0, 0], 0)), &MAP, &w, &mut rec);
            assert_eq!(rec.chunks.last().unwrap().limit, limit, "after +{d}");
        }
        // Back toward the switch to 2: starts outside, does not end at 0: armed.
        sp.push(&StepperCmd::Block(block([8, 0, 0, 0], 0b001)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks.last().unwrap().limit, 0b111);
        // Inside the band without having been at 0 (after homing: the
        // pull-off, then a position reset): armed.
        sp.reset([4, 100, 100, 0]);
        sp.push(&StepperCmd::Block(block([1, 0, 0, 0], 0)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks.last().unwrap().limit, 0b111);
        // Z (not homed) inside the window is armed all the same.
        sp.reset([100, 100, 3, 0]);
        sp.push(&StepperCmd::Block(block([0, 0, 1, 0], 0)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks.last().unwrap().limit, 0b111);
    }

    #[test]
    fn inverted_axes_flip_their_direction_pin() {
        let w = ChunkWatch { invert_dir: 0b1000, ..Default::default() };
        let mut sp = Splitter::new();
        let mut rec = Rec::default();
        sp.push(&StepperCmd::Block(block([0, 0, 0, 10], 0)), &MAP, &w, &mut rec);
        assert_eq!(rec.chunks[0].dir_out, [0x82, 0x02, 0x00]);
    }

    /// A sink whose free slot holds a stale chunk (random fields), as the
    /// board's ring slots do: a field the in-place writer forgets shows.
    struct Stale {
        slot: Chunk,
        chunks: Vec<Chunk>,
    }

    impl Sink for Stale {
        fn chunk(&mut self, c: &Chunk) {
            self.chunks.push(*c);
        }
        fn seg(&mut self, _s: &Seg) {}
        fn chunk_in_place(&mut self, fill: impl FnOnce(&mut Chunk)) {
            let mut c = self.slot;
            fill(&mut c);
            self.chunks.push(c);
        }
    }

    #[test]
    fn a_whole_chunk_written_in_place_is_the_plain_one() {
        let mut rng = XorShift(0x1DEA);
        let mut r = move |m: u32| rng.next() % m;
        for _ in 0..50_000 {
            let n = if r(4) == 0 { MAX_CHUNK_EVENTS - r(3) } else { r(40) };
            let mut steps = [0u32; N_AXES];
            for v in steps.iter_mut() {
                *v = match r(4) {
                    0 => 0,
                    1 => n,
                    _ => r(n + 1),
                };
            }
            let b = StBlock { steps, step_event_count: n, direction_bits: r(256) as u8, take_up: r(5) == 0 };
            // Positions at, near and far from the switches; any held bits.
            let pos: [i32; N_AXES] = core::array::from_fn(|_| match r(3) {
                0 => r(12) as i32 - 4,
                1 => -(r(40) as i32),
                _ => r(1 << 20) as i32 - (1 << 19),
            });
            let w = ChunkWatch {
                limits: r(16) as u8,
                homed: r(16) as u8,
                invert_dir: r(16) as u8,
                release: [r(6) as u16, r(6) as u16, r(6) as u16],
            };
            let mut fast = Splitter::new();
            fast.reset(pos);
            fast.held = r(16) as u8;
            let mut plain = fast;
            let mut stale = Chunk::with_steps([r(999) as i16, -7, 3, 0], r(999) as i16 + 1);
            (stale.limit, stale.dir_out, stale.axis_dir, stale.take_up) = (r(256) as u8, [0x5A; 3], 0xC3, r(2) == 0);
            let mut got = Stale { slot: stale, chunks: Vec::new() };
            fast.push(&StepperCmd::Block(b), &MAP, &w, &mut got);
            let mut want = Rec::default();
            plain.begin(&b);
            plain.next_chunk(&MAP, &w, &mut want);
            assert_eq!(got.chunks, want.chunks, "{b:?} from {pos:?}, {w:?}");
            let state = |s: &Splitter| (s.plan_pos, s.held, s.k, s.chunk_len, s.chunk_start, s.chunk_end, s.new_chunk);
            assert_eq!(state(&fast), state(&plain), "{b:?} from {pos:?}, {w:?}");
        }
    }

    #[test]
    fn mul_add_div_matches_64_bit_arithmetic() {
        let mut rng = XorShift(7);
        for _ in 0..10_000 {
            let d = rng.next() | 1;
            let a = (rng.next() as u64 % (d as u64 + 1)) as u32;
            let b = rng.next();
            let c = rng.next() % d;
            let want = ((a as u64 * b as u64 + c as u64) / d as u64) as u32;
            assert_eq!(mul_add_div(a, b, c, d), want);
        }
        assert_eq!(mul_add_div(u32::MAX, u32::MAX, u32::MAX - 1, u32::MAX), u32::MAX);
    }
}
