//! The main-loop side of the step ISR's two rings: everything about them
//! that is logic, host-tested (docs/SPEC.md §6).
//!
//! Where it sits: the firmware's `Io::push_segment` hands prep's
//! [`StepperCmd`]s to [`Rings::push`], which cuts them ([`Splitter`]) into
//! [`Chunk`] and [`Seg`] records and writes them, through the [`Sink`]
//! trait, into ring slots that the Timer1 ISR (`board::stepper`) reads in
//! place. The slots and the ISR's own state are statics of the board; this
//! module sees them only through [`RingMem`] (one-byte index reads, slot
//! writes, and a snapshot of the ISR's progress taken in a critical section),
//! so the same code runs against plain arrays in the tests below.
//!
//! What it owns:
//!
//! - **Heads and free slots.** The segment head is published (after the
//!   slot is written) by [`RingMem::publish_seg_head`]; the chunk head is
//!   private to the main loop, since the ISR moves to the next chunk only when
//!   a segment says so. One slot of each ring stays free.
//! - **Queued motion time.** Each segment's CPU cycles are kept beside its
//!   slot, with their running total, so [`Rings::space`] can cap what waits in
//!   the ring at [`MAX_QUEUED_CYCLES`] in O(1) amortised.
//! - **Position.** The ISR does not count steps, and neither does this side
//!   per chunk: the splitter keeps the position at the end of everything
//!   queued ([`Splitter::plan_position`]), and [`Rings::position`] takes off
//!   the chunks from the ISR's running one on, adds the running chunk's
//!   progress from its error counters ([`Chunk::steps_done`]) and takes off
//!   the step computed but not yet output (`pending`). (Adding each finished
//!   chunk into a counted position instead cost ~190 cycles a streamed line
//!   on the AVR; the position is asked for a few times a second.)
//! - **Trips.** The position at a homing or probe trip is latched the first
//!   time it is asked for; [`Rings::clear`] forgets it with the queue.
//! - **Watch.** What the ISR watches ([`Watch`]) and the hard-limit masks of
//!   new chunks ([`ChunkWatch`], computed by the splitter).
//!
//! RAM on AVR: [`Rings`] is 171 B (16 × 4 B of segment cycles, the splitter's
//! 72 B, the trip position 16 B, the watch 11 B, indices).

use super::queue::{Chunk, ChunkWatch, Seg, Sink, Splitter, StepMap};
use super::StepperCmd;
use crate::{F_CPU_HZ, N_AXES};

/// Segment ring length (one slot stays free). RAM (board): 16 × 8 B = 128 B.
pub const SEG_RING_LEN: usize = 16;
/// Chunk ring length (one slot stays free, one is the ISR's current chunk).
/// A stream of short moves needs one chunk per segment. RAM (board): 16 × 26 B = 416 B.
pub const CHUNK_RING_LEN: usize = 16;
/// Index mask of the segment ring.
pub const SEG_MASK: u8 = SEG_RING_LEN as u8 - 1;
/// Index mask of the chunk ring.
pub const CHUNK_MASK: u8 = CHUNK_RING_LEN as u8 - 1;
const _: () = assert!(SEG_RING_LEN.is_power_of_two() && CHUNK_RING_LEN.is_power_of_two());
const _: () = assert!(core::mem::size_of::<Seg>() == 8 && core::mem::size_of::<Chunk>() == 26);

/// At most this much motion (CPU cycles: 40 ms) waits in the segment ring.
/// A feed hold or an abort decelerates from the end of what is queued, so
/// this bounds their latency (16 segments of up to 20 ms queued made it
/// 320 ms); 40 ms still covers the longest main-loop turn (a line's parse
/// and plan, ~3 ms; an SD block read; an OLED slice).
pub const MAX_QUEUED_CYCLES: u32 = F_CPU_HZ / 25;

/// What the ISR watches (written by main through `board::stepper::set_watch`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Watch {
    /// Axes being homed: a closed home switch on one of them latches and
    /// stops (bit 3, E0: the carousel home switch).
    pub homing: u8,
    /// Probe active: the tool-setter input latches and stops.
    pub probe: bool,
    /// Axes whose home switch raises a hard-limit alarm while moving toward it.
    pub limits: u8,
    /// Axes homed (their switch closing at position 0 is expected).
    pub homed: u8,
    /// Direction-pin inversion mask (setting).
    pub invert_dir: u8,
    /// Inputs read inverted (`$5`, for normally-closed switches and sensors
    /// of the other polarity): bits 0–2 the X, Y, Z home switches, bit 3 the
    /// carousel home switch, bit 4 the tool setter / probe.
    pub invert_inputs: u8,
    /// How far above 0 (steps, X Y Z) a homed axis' switch may still be
    /// closed: its chunks starting there are not armed (`ChunkWatch::release`).
    pub release: [u16; 3],
}

impl Watch {
    /// Nothing watched.
    pub const NONE: Watch = Watch { homing: 0, probe: false, limits: 0, homed: 0, invert_dir: 0, invert_inputs: 0, release: [0; 3] };

    /// The part of the watch the splitter bakes into each new chunk.
    pub fn chunk_watch(&self) -> ChunkWatch {
        ChunkWatch { limits: self.limits, homed: self.homed, invert_dir: self.invert_dir, release: self.release }
    }
}

/// The ISR's progress, read in one critical section.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IsrSnapshot {
    /// Ring index of the running chunk.
    pub cur: u8,
    /// Events of the running chunk done (the running segment's `k_end`
    /// minus its ticks left).
    pub k: u16,
    /// Step-output bits computed but not yet output.
    pub pending: u8,
    /// A copy of the running chunk (its error counters say how far it is).
    pub chunk: Chunk,
}

/// The memory the rings live in: the board's statics, shared with the ISR
/// (arrays in the tests). Main-loop side only.
pub trait RingMem {
    /// The next segment slot the ISR will read (a one-byte read of what the
    /// ISR writes).
    fn seg_tail(&self) -> u8;
    /// The next free segment slot (written by main only, through
    /// [`RingMem::publish_seg_head`]).
    fn seg_head(&self) -> u8;
    /// Ring index of the ISR's running chunk (a one-byte read).
    fn chunk_cur(&self) -> u8;
    /// Chunk slot `i`, which the ISR has finished or not yet started.
    fn chunk(&self, i: u8) -> &Chunk;
    /// Write chunk slot `i`; the caller guarantees the ISR does not use it.
    fn set_chunk(&mut self, i: u8, c: &Chunk);
    /// Chunk slot `i` to write in place; the caller guarantees the ISR does
    /// not use it.
    fn chunk_mut(&mut self, i: u8) -> &mut Chunk;
    /// Write segment slot `i` (free: between head and tail).
    fn set_seg(&mut self, i: u8, s: &Seg);
    /// Hand the segments before `head` to the ISR (after their slots are written).
    fn publish_seg_head(&mut self, head: u8);
    /// The ISR's progress, consistent (taken with the ISR unable to run).
    fn snapshot(&self) -> IsrSnapshot;
}

/// Main-loop bookkeeping of the rings (one static in the board).
#[derive(Clone, Copy, Debug)]
pub struct Rings {
    /// What the sink writes.
    w: Writer,
    split: Splitter,
    /// What the ISR watches: the part the splitter bakes into each chunk,
    /// kept as it reads it (no copy per command queued), and the rest.
    chunk_watch: ChunkWatch,
    homing: u8,
    probe: bool,
    invert_inputs: u8,
    /// Position latched at the last homing or probe trip, steps.
    trip: [i32; N_AXES],
    /// The current trip has been latched into `trip`.
    trip_latched: bool,
}

/// The writing side: chunk head and the segments' queued cycles.
#[derive(Clone, Copy, Debug)]
struct Writer {
    /// Next free chunk slot.
    chunk_head: u8,
    /// First slot whose cycles are still in `seg_queued` (trails the ISR's tail).
    seg_done: u8,
    /// Running total of `seg_cycles` over the slots from `seg_done` to the head.
    seg_queued: u32,
    /// CPU cycles of each segment slot, written with the slot.
    seg_cycles: [u32; SEG_RING_LEN],
}

/// The [`Sink`] the splitter writes through.
struct SlotSink<'a, M: RingMem> {
    w: &'a mut Writer,
    mem: &'a mut M,
}

impl<M: RingMem> Sink for SlotSink<'_, M> {
    // speed: with `seg`, `seg_cycles` (and planner's `abs_f32`) left to LLVM,
    // ping-pong took 5.754 s, not 5.739
    #[inline(always)]
    fn chunk(&mut self, c: &Chunk) {
        // The slot at chunk_head is free (checked by `space`).
        self.mem.set_chunk(self.w.chunk_head, c);
        self.w.chunk_head = (self.w.chunk_head + 1) & CHUNK_MASK;
    }

    // speed: per block queued (see `chunk`)
    #[inline(always)]
    fn chunk_in_place(&mut self, fill: impl FnOnce(&mut Chunk)) {
        // The slot at chunk_head is free (checked by `space`).
        fill(self.mem.chunk_mut(self.w.chunk_head));
        self.w.chunk_head = (self.w.chunk_head + 1) & CHUNK_MASK;
    }

    // speed: per segment queued (see `chunk`)
    #[inline(always)]
    fn seg(&mut self, s: &Seg) {
        // The slot at the head is free (checked by `space`), and written
        // before the head that publishes it.
        let h = self.mem.seg_head();
        self.mem.set_seg(h, s);
        let cycles = seg_cycles(s);
        self.w.seg_cycles[h as usize] = cycles;
        self.w.seg_queued += cycles;
        self.mem.publish_seg_head((h + 1) & SEG_MASK);
    }
}

/// CPU cycles of a segment: ticks · period < 2³² (16-bit factors), then ×8
/// for clk/8, capped at 2³² / 32 (the sum of a full ring must not wrap).
// speed: per segment queued (see `SlotSink::chunk`)
#[inline(always)]
pub fn seg_cycles(s: &Seg) -> u32 {
    let counts = crate::math::mul_u16(s.ticks, s.period);
    if s.tccr & 0x07 == 1 { counts } else { counts.saturating_mul(8) }.min(u32::MAX / 32)
}

/// Step-output bits → axis bits.
pub fn out_to_axes(map: &StepMap, out: u8) -> u8 {
    let mut a = 0;
    for (i, s) in map.step.iter().enumerate() {
        if out & s != 0 {
            a |= 1 << i;
        }
    }
    a
}

impl Rings {
    /// Empty rings at position 0; the ISR starts on chunk slot 0 (empty).
    pub const fn new() -> Self {
        Rings {
            w: Writer { chunk_head: 1, seg_done: 0, seg_queued: 0, seg_cycles: [0; SEG_RING_LEN] },
            split: Splitter::new(),
            chunk_watch: ChunkWatch { limits: 0, homed: 0, invert_dir: 0, release: [0; 3] },
            homing: 0,
            probe: false,
            invert_inputs: 0,
            trip: [0; N_AXES],
            trip_latched: false,
        }
    }

    /// CPU cycles of motion in the segments waiting in the ring (not counting
    /// the one the ISR is running). O(1) amortised.
    pub fn queued_cycles(&mut self, mem: &impl RingMem) -> u32 {
        let tail = mem.seg_tail();
        let w = &mut self.w;
        while w.seg_done != tail {
            w.seg_queued = w.seg_queued.wrapping_sub(w.seg_cycles[w.seg_done as usize]);
            w.seg_done = (w.seg_done + 1) & SEG_MASK;
        }
        w.seg_queued
    }

    /// Free (segment, chunk) slots: a chunk's slot is free once the ISR
    /// has moved past it.
    // flash: left to LLVM (with `push`), `Rings::space` grows by 4 B
    #[inline(always)]
    fn free_slots(&mut self, mem: &impl RingMem) -> (u8, u8) {
        let seg_free = SEG_MASK - (mem.seg_head().wrapping_sub(mem.seg_tail()) & SEG_MASK);
        let chunk_free = CHUNK_MASK - (self.w.chunk_head.wrapping_sub(mem.chunk_cur()) & CHUNK_MASK);
        (seg_free, chunk_free)
    }

    /// Commands that surely fit now (a `Run` may take 2 segments and a
    /// chunk); 0 while [`MAX_QUEUED_CYCLES`] of motion wait.
    pub fn space(&mut self, mem: &impl RingMem) -> usize {
        if self.queued_cycles(mem) >= MAX_QUEUED_CYCLES {
            return 0;
        }
        self.slot_space(mem)
    }

    /// [`Rings::space`] by the free slots alone (the queued motion is
    /// known to be below [`MAX_QUEUED_CYCLES`]).
    // flash: see `free_slots`
    #[inline(always)]
    fn slot_space(&mut self, mem: &impl RingMem) -> usize {
        let (s, c) = self.free_slots(mem);
        if s >= 2 && c >= 1 {
            (s / 2).min(c) as usize
        } else {
            0
        }
    }

    /// Queue one command from prep. False (nothing queued) without room.
    // flash: see `free_slots`
    #[inline(always)]
    pub fn push(&mut self, cmd: &StepperCmd, map: &StepMap, mem: &mut impl RingMem) -> bool {
        if self.space(mem) == 0 {
            return false;
        }
        self.split.push(cmd, map, &self.chunk_watch, &mut SlotSink { w: &mut self.w, mem });
        true
    }

    /// Queue one command that fits: the caller saw [`Rings::space`] > 0
    /// and has not queued anything since (the ISR only frees room). Returns
    /// [`Rings::space`] after it, so that a fill loop asks once per command,
    /// not twice (~150 cycles each on the AVR).
    // flash: see `free_slots`
    #[inline(always)]
    pub fn push_fitting(&mut self, cmd: &StepperCmd, map: &StepMap, mem: &mut impl RingMem) -> usize {
        self.split.push(cmd, map, &self.chunk_watch, &mut SlotSink { w: &mut self.w, mem });
        if matches!(cmd, StepperCmd::Block(_)) {
            // A chunk adds no queued motion: below the cap before (space
            // was > 0), below it still.
            self.slot_space(mem)
        } else {
            self.space(mem)
        }
    }

    /// Machine position in steps: what has been output on the pins. The
    /// splitter's plan (the position at the end of every chunk queued)
    /// less the chunks from the ISR's running one on, plus the running
    /// chunk's progress: O(chunks queued) when asked, nothing per chunk.
    pub fn position(&self, map: &StepMap, mem: &impl RingMem) -> [i32; N_AXES] {
        let s = mem.snapshot();
        let mut p = self.split.plan_position();
        let mut i = s.cur;
        while i != self.w.chunk_head {
            let c = if i == s.cur { &s.chunk } else { mem.chunk(i) };
            if !c.take_up {
                let t = c.total();
                for a in 0..N_AXES {
                    p[a] -= t[a];
                }
            }
            i = (i + 1) & CHUNK_MASK;
        }
        let chunk = &s.chunk;
        if !chunk.take_up {
            let done = chunk.signed(chunk.steps_done(s.k));
            let pend = out_to_axes(map, s.pending);
            for i in 0..N_AXES {
                p[i] += done[i];
                // Computed but not output (yet, or never after a stop).
                if pend & (1 << i) != 0 {
                    p[i] -= if chunk.axis_dir & (1 << i) != 0 { -1 } else { 1 };
                }
            }
        }
        p
    }

    /// Latch the position of a homing/probe trip the first time it is asked
    /// for (`tripped`: the ISR stopped at a trip, so the position is frozen
    /// until [`Rings::clear`]).
    fn latch_trip(&mut self, tripped: bool, map: &StepMap, mem: &impl RingMem) {
        if tripped && !self.trip_latched {
            self.trip = self.position(map, mem);
            self.trip_latched = true;
        }
    }

    /// Position latched at the last homing or probe trip.
    pub fn trip_position(&mut self, tripped: bool, map: &StepMap, mem: &impl RingMem) -> [i32; N_AXES] {
        self.latch_trip(tripped, map, mem);
        self.trip
    }

    /// Set the machine position to `p` (only while the ISR is idle or
    /// stopped): the counted position and the splitter's plan move by the
    /// same offset.
    pub fn set_position(&mut self, p: [i32; N_AXES], tripped: bool, map: &StepMap, mem: &impl RingMem) {
        self.latch_trip(tripped, map, mem);
        let q = self.position(map, mem);
        let mut plan = self.split.plan_position();
        for i in 0..N_AXES {
            plan[i] += p[i] - q[i];
        }
        self.split.reset(plan);
    }

    /// After a stop: forget everything queued; the position stays `q`, what
    /// was output. Call with the ISR unable to run and its state reset to "no
    /// segment" on chunk `cur`. The interrupted chunk is accounted for in
    /// `q`: its slot is emptied so that it neither counts as queued nor as
    /// progress.
    pub fn clear(&mut self, cur: u8, q: [i32; N_AXES], mem: &mut impl RingMem) {
        let mut c = *mem.chunk(cur);
        c.steps = [0; N_AXES];
        mem.set_chunk(cur, &c);
        self.w.chunk_head = (cur + 1) & CHUNK_MASK;
        self.split.reset(q);
        self.trip_latched = false;
    }

    /// Replace what the ISR watches (the caller also updates the ISR's copy).
    pub fn set_watch(&mut self, w: Watch) {
        self.chunk_watch = w.chunk_watch();
        (self.homing, self.probe, self.invert_inputs) = (w.homing, w.probe, w.invert_inputs);
    }

    /// What the ISR watches now.
    pub fn watch(&self) -> Watch {
        let c = &self.chunk_watch;
        Watch {
            homing: self.homing,
            probe: self.probe,
            limits: c.limits,
            homed: c.homed,
            invert_dir: c.invert_dir,
            invert_inputs: self.invert_inputs,
            release: c.release,
        }
    }
}

#[cfg(target_arch = "avr")]
const _: () = assert!(core::mem::size_of::<Rings>() == 171);

impl Default for Rings {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
pub mod host;
#[cfg(test)]
mod tests;
