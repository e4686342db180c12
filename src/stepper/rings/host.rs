//! The board's ring statics on the host (test builds only): the arrays and
//! indexes `board::stepper` keeps in `SEGS`, `SEG_HEAD`, `CHUNKS` and the
//! ISR's state `ST`, as a [`RingMem`], with the ring side of the Timer1 ISR
//! (load the next segment, compute the next step event with
//! [`Chunk::tick_out`], reset after a stop).
//!
//! Shared by the rings' own tests (`tests.rs`) and the controller's fake
//! board (`crate::fake_board`): each adds what it models around it (step
//! output, switch trips, timer periods), in `TIMER1_COMPA`'s order.

use super::{IsrSnapshot, RingMem, CHUNK_MASK, CHUNK_RING_LEN, SEG_MASK, SEG_RING_LEN};
use crate::stepper::queue::{Chunk, Seg, StepMap};

/// The rings and the ISR's position in them.
pub struct Statics {
    pub segs: [Seg; SEG_RING_LEN],
    /// Next free segment slot (main writes it).
    pub seg_head: u8,
    pub chunks: [Chunk; CHUNK_RING_LEN],
    /// Next segment slot the ISR reads.
    pub seg_tail: u8,
    /// Ring index of the running chunk.
    pub cur: u8,
    /// Events left in the running segment, and its `k_end`.
    pub ticks_left: u16,
    pub k_end: u16,
    /// Step bits computed, not yet output.
    pub pending: u8,
}

impl Statics {
    /// Empty rings, as at boot.
    pub fn new() -> Statics {
        Statics {
            segs: [Seg { ticks: 0, period: 0, tccr: 0, new_chunk: 0, k_end: 0 }; SEG_RING_LEN],
            seg_head: 0,
            chunks: [Chunk::EMPTY; CHUNK_RING_LEN],
            seg_tail: 0,
            cur: 0,
            ticks_left: 0,
            k_end: 0,
            pending: 0,
        }
    }

    /// The running chunk.
    pub fn cur(&self) -> &Chunk {
        &self.chunks[self.cur as usize]
    }

    /// Segments queued and not yet loaded by the ISR.
    pub fn queued_segs(&self) -> u8 {
        self.seg_head.wrapping_sub(self.seg_tail) & SEG_MASK
    }

    /// Steps still to come: a running segment, a step not yet output, or
    /// queued segments (`board::stepper::busy`, without its stop flag).
    pub fn busy(&self) -> bool {
        self.ticks_left != 0 || self.pending != 0 || self.seg_tail != self.seg_head
    }

    /// The ISR's `load_segment`: take the next segment, moving on to its
    /// chunk when it starts one. `None` when the ring is empty.
    pub fn load_segment(&mut self) -> Option<Seg> {
        if self.seg_tail == self.seg_head {
            return None;
        }
        let s = self.segs[self.seg_tail as usize];
        self.ticks_left = s.ticks;
        self.k_end = s.k_end;
        if s.new_chunk != 0 {
            self.cur = (self.cur + 1) & CHUNK_MASK;
        }
        self.seg_tail = (self.seg_tail + 1) & SEG_MASK;
        Some(s)
    }

    /// Compute the next step event of the running segment into `pending`
    /// (0 when there is none).
    pub fn next_event(&mut self, map: &StepMap) {
        let mut next = 0;
        if self.ticks_left != 0 {
            self.ticks_left -= 1;
            next = self.chunks[self.cur as usize].tick_out(&map.step);
        }
        self.pending = next;
    }

    /// The ISR's reset after a stop (`board::stepper::clear_stop`): the
    /// queued segments are dropped, the pending step is never output.
    pub fn clear_isr(&mut self) {
        self.ticks_left = 0;
        self.k_end = 0;
        self.pending = 0;
        self.seg_tail = self.seg_head;
    }
}

impl Default for Statics {
    fn default() -> Self {
        Self::new()
    }
}

impl RingMem for Statics {
    fn seg_tail(&self) -> u8 {
        self.seg_tail
    }
    fn seg_head(&self) -> u8 {
        self.seg_head
    }
    fn chunk_cur(&self) -> u8 {
        self.cur
    }
    fn chunk(&self, i: u8) -> &Chunk {
        &self.chunks[i as usize]
    }
    fn set_chunk(&mut self, i: u8, c: &Chunk) {
        assert!(i != self.cur || self.ticks_left == 0 && self.pending == 0, "writing the running chunk");
        self.chunks[i as usize] = *c;
    }
    fn chunk_mut(&mut self, i: u8) -> &mut Chunk {
        assert!(i != self.cur || self.ticks_left == 0 && self.pending == 0, "writing the running chunk");
        &mut self.chunks[i as usize]
    }
    fn set_seg(&mut self, i: u8, s: &Seg) {
        assert_eq!(i, self.seg_head);
        assert!(self.queued_segs() < SEG_MASK, "segment ring overrun");
        self.segs[i as usize] = *s;
    }
    fn publish_seg_head(&mut self, head: u8) {
        self.seg_head = head;
    }
    fn snapshot(&self) -> IsrSnapshot {
        IsrSnapshot { cur: self.cur, k: self.k_end.wrapping_sub(self.ticks_left), pending: self.pending, chunk: *self.cur() }
    }
}
