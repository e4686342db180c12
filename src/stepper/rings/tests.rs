//! Host tests of the rings: plain arrays for the board's statics, and a host
//! ISR that consumes them the way `board::stepper`'s Timer1 ISR does (output
//! the step computed last time, load the next segment, compute the next
//! event with `Chunk::tick_out`, the twin of the ISR's assembly), counting
//! the position it puts on the pins.

use super::host;
use super::*;
use crate::stepper::queue::tccr1b;
use crate::stepper::{Prescale, Segment, StBlock};
use crate::test_util::XorShift;

const MAP: StepMap = StepMap { step: [0x01, 0x40, 0x08, 0x10], dir: [(0, 0x02), (0, 0x80), (1, 0x02), (2, 0x40)] };

/// The board's statics and its ISR, on the host: the shared ring side
/// ([`host::Statics`]) and the step pins.
struct Board {
    mem: host::Statics,
    running: bool,
    stopped: bool,
    /// Position output on the pins, take-up steps not counted.
    out: [i32; N_AXES],
    /// Motor position: every step output.
    motor: [i32; N_AXES],
    /// Step events run.
    events: u64,
}

impl core::ops::Deref for Board {
    type Target = host::Statics;
    fn deref(&self) -> &host::Statics {
        &self.mem
    }
}

impl Board {
    fn new() -> Self {
        Board { mem: host::Statics::new(), running: false, stopped: false, out: [0; N_AXES], motor: [0; N_AXES], events: 0 }
    }

    /// One timer interrupt.
    fn interrupt(&mut self) {
        if self.stopped {
            return;
        }
        let c = *self.mem.cur();
        let step = out_to_axes(&MAP, self.mem.pending);
        for i in 0..N_AXES {
            if step & (1 << i) != 0 {
                let d = if c.axis_dir & (1 << i) != 0 { -1 } else { 1 };
                self.motor[i] += d;
                if !c.take_up {
                    self.out[i] += d;
                }
            }
        }
        if self.mem.ticks_left == 0 {
            self.running = self.mem.load_segment().is_some();
        }
        if self.mem.ticks_left != 0 {
            self.events += 1;
        }
        self.mem.next_event(&MAP);
    }

    /// The ISR's reset after a stop (`board::stepper::clear_stop`).
    fn clear_isr(&mut self) {
        self.mem.clear_isr();
        self.running = false;
        self.stopped = false;
    }
}

fn block(steps: [u32; N_AXES], dir: u8, take_up: bool) -> StBlock {
    StBlock { steps, step_event_count: *steps.iter().max().unwrap(), direction_bits: dir, take_up }
}

fn run(ticks: u16, period: u16) -> StepperCmd {
    StepperCmd::Run(Segment { ticks, period, prescale: Prescale::Div1 })
}

/// A block and its runs of at most `max_ticks` events.
fn commands(b: StBlock, max_ticks: u32, rng: &mut XorShift) -> Vec<StepperCmd> {
    let mut v = vec![StepperCmd::Block(b)];
    let mut left = b.step_event_count;
    while left > 0 {
        let t = left.min(1 + rng.next() % max_ticks);
        let prescale = if rng.next().is_multiple_of(4) { Prescale::Div8 } else { Prescale::Div1 };
        v.push(StepperCmd::Run(Segment { ticks: t as u16, period: 300 + (rng.next() % 2000) as u16, prescale }));
        left -= t;
    }
    v
}

/// Signed steps of a block.
fn moved(b: &StBlock) -> [i32; N_AXES] {
    let mut d = [0; N_AXES];
    for i in 0..N_AXES {
        d[i] = if b.direction_bits & (1 << i) != 0 { -(b.steps[i] as i32) } else { b.steps[i] as i32 };
    }
    d
}

/// Pushes `cmds` as room appears, running the ISR otherwise, and checks the
/// position against what the pins did after every interrupt; then drains.
fn stream(r: &mut Rings, bd: &mut Board, cmds: &[StepperCmd]) {
    let mut next = 0;
    while next < cmds.len() || bd.queued_segs() != 0 || bd.ticks_left != 0 || bd.pending != 0 {
        if next < cmds.len() && r.space(&bd.mem) > 0 {
            assert!(r.push(&cmds[next], &MAP, &mut bd.mem));
            next += 1;
            continue;
        }
        bd.interrupt();
        assert_eq!(r.position(&MAP, &bd.mem), bd.out, "event {}", bd.events);
    }
}

#[test]
fn an_empty_ring_takes_a_block_and_fourteen_runs_then_refuses() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    // 15 free segment slots → 7 commands that surely fit; 14 free chunk slots.
    assert_eq!(r.space(&bd.mem), 7);
    assert!(r.push(&StepperCmd::Block(block([1000, 0, 0, 0], 0, false)), &MAP, &mut bd.mem));
    let mut runs = 0;
    while r.push(&run(10, 400), &MAP, &mut bd.mem) {
        runs += 1;
    }
    assert_eq!(runs, 14);
    assert_eq!(bd.queued_segs(), 14);
    assert_eq!(r.space(&bd.mem), 0);
    // The ISR takes two segments: room for one more command.
    for _ in 0..11 {
        bd.interrupt();
    }
    assert_eq!(bd.queued_segs(), 12);
    assert_eq!(r.space(&bd.mem), 1);
    assert!(r.push(&run(10, 400), &MAP, &mut bd.mem));
    assert_eq!(r.position(&MAP, &bd.mem), [10, 0, 0, 0]);
}

#[test]
fn queued_motion_is_capped_at_40_ms_and_drains_with_the_isr() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    assert!(r.push(&StepperCmd::Block(block([400, 0, 0, 0], 0, false)), &MAP, &mut bd.mem));
    // 100 events of 2000 counts: 200 000 cycles each at clk/1; 1.6 M at clk/8.
    assert!(r.push(&run(100, 2000), &MAP, &mut bd.mem));
    assert_eq!(r.queued_cycles(&bd.mem), 200_000);
    assert!(r.push(&StepperCmd::Run(Segment { ticks: 100, period: 2000, prescale: Prescale::Div8 }), &MAP, &mut bd.mem));
    assert_eq!(r.queued_cycles(&bd.mem), 1_800_000);
    assert!(r.queued_cycles(&bd.mem) >= MAX_QUEUED_CYCLES);
    assert_eq!(r.space(&bd.mem), 0);
    assert!(!r.push(&run(100, 2000), &MAP, &mut bd.mem), "over the cap: refused");
    // The ISR takes the first segment (no longer waiting), then the second.
    bd.interrupt();
    assert_eq!(r.queued_cycles(&bd.mem), 1_600_000);
    for _ in 0..100 {
        bd.interrupt();
    }
    assert_eq!(r.queued_cycles(&bd.mem), 0);
    assert_eq!(r.space(&bd.mem), 7);
}

#[test]
fn a_segments_cycles_count_clk8_eight_times_and_are_capped() {
    let s = |ticks, period, p| Seg { ticks, period, tccr: tccr1b(p), new_chunk: 0, k_end: 0 };
    assert_eq!(seg_cycles(&s(3, 1000, Prescale::Div1)), 3000);
    assert_eq!(seg_cycles(&s(3, 1000, Prescale::Div8)), 24_000);
    assert_eq!(seg_cycles(&s(u16::MAX, u16::MAX, Prescale::Div8)), u32::MAX / 32);
}

#[test]
fn chunk_slots_are_reused_once_the_isr_has_passed_them() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    let one = |r: &mut Rings, bd: &mut Board| {
        r.push(&StepperCmd::Block(block([3, 1, 0, 0], 0, false)), &MAP, &mut bd.mem) && r.push(&run(3, 400), &MAP, &mut bd.mem)
    };
    for _ in 0..3 {
        assert!(one(&mut r, &mut bd));
    }
    // Two blocks done, the third started.
    run_to(&mut bd, 7);
    assert_eq!(bd.cur, 3);
    assert!(r.space(&bd.mem) > 0);
    assert_eq!(r.position(&MAP, &bd.mem), [6, 2, 0, 0], "6 events output, the 7th pending");
    assert_eq!(bd.out, [6, 2, 0, 0]);
    // 40 more blocks through the 16 slots, the position never asked for:
    // each slot is written again only after the ISR has left it.
    for n in 0..40 {
        for c in [StepperCmd::Block(block([3, 1, 0, 0], 0, false)), run(3, 400)] {
            let mut spins = 0;
            while !r.push(&c, &MAP, &mut bd.mem) {
                bd.interrupt();
                spins += 1;
                assert!(spins < 100, "block {n}: no room ever");
            }
        }
    }
    stream(&mut r, &mut bd, &[]);
    assert_eq!(r.position(&MAP, &bd.mem), [129, 43, 0, 0]);
}

#[test]
fn the_position_follows_every_step_output_through_long_blocks_and_ring_wraps() {
    let mut rng = XorShift(0xBEEF);
    let mut r = Rings::new();
    let mut bd = Board::new();
    let mut want = [0i32; N_AXES];
    let mut cmds = Vec::new();
    for n in 0..30 {
        let big = n % 7 == 3;
        let mut steps = [0u32; N_AXES];
        for v in steps.iter_mut() {
            *v = rng.next() % if big { 80_000 } else { 400 };
        }
        if steps.iter().all(|&v| v == 0) {
            continue;
        }
        let take_up = n % 11 == 5;
        let b = block(steps, (rng.next() & 0x0F) as u8, take_up);
        if !take_up {
            let d = moved(&b);
            for i in 0..N_AXES {
                want[i] += d[i];
            }
        }
        cmds.extend(commands(b, if big { 3000 } else { 150 }, &mut rng));
    }
    stream(&mut r, &mut bd, &cmds);
    assert_eq!(r.position(&MAP, &bd.mem), want);
    assert_eq!(bd.out, want);
    assert_ne!(bd.motor, want, "take-up blocks moved the motors only");
    assert!(bd.seg_head as usize + 16 < cmds.len(), "the rings wrapped");
}

#[test]
fn a_take_up_block_moves_the_motors_but_not_the_position() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    let mut rng = XorShift(5);
    let mut cmds = commands(block([30, 10, 0, 0], 0, false), 7, &mut rng);
    cmds.extend(commands(block([5, 0, 0, 0], 0b0001, true), 2, &mut rng));
    cmds.extend(commands(block([0, 10, 0, 0], 0b0010, false), 3, &mut rng));
    stream(&mut r, &mut bd, &cmds);
    assert_eq!(r.position(&MAP, &bd.mem), [30, 0, 0, 0]);
    assert_eq!(bd.motor, [25, 0, 0, 0]);
    // The splitter's plan does not count take-up either.
    assert_eq!(r.split.plan_position(), [30, 0, 0, 0]);
}

#[test]
fn set_position_moves_the_count_and_the_plan_by_the_same_offset() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    let mut rng = XorShift(11);
    stream(&mut r, &mut bd, &commands(block([100, 50, 25, 0], 0b0100, false), 20, &mut rng));
    assert_eq!(r.position(&MAP, &bd.mem), [100, 50, -25, 0]);
    r.set_position([0, 0, 0, 7], false, &MAP, &bd.mem);
    bd.out = [0, 0, 0, 7];
    assert_eq!(r.position(&MAP, &bd.mem), [0, 0, 0, 7]);
    assert_eq!(r.split.plan_position(), [0, 0, 0, 7]);
    stream(&mut r, &mut bd, &commands(block([10, 0, 0, 3], 0b0001, false), 4, &mut rng));
    assert_eq!(r.position(&MAP, &bd.mem), [-10, 0, 0, 10]);
    assert_eq!(r.split.plan_position(), [-10, 0, 0, 10]);
}

/// Runs until `events` step events have been computed.
fn run_to(bd: &mut Board, events: u64) {
    let mut idle = 0;
    while bd.events < events {
        let e = bd.events;
        bd.interrupt();
        idle = if bd.events == e { idle + 1 } else { 0 };
        assert!(idle < 3, "the ring ran dry at event {e}");
    }
}

#[test]
fn a_trip_is_latched_where_it_stopped_and_forgotten_by_clear() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    let mut rng = XorShift(13);
    assert!(r.push(&StepperCmd::Block(block([0, 0, 1000, 0], 0b0100, false)), &MAP, &mut bd.mem));
    for _ in 0..4 {
        assert!(r.push(&run(50, 400), &MAP, &mut bd.mem));
    }
    run_to(&mut bd, 137);
    // The switch trips: the ISR stops with one step computed, not output.
    bd.stopped = true;
    assert_ne!(bd.pending, 0);
    assert_eq!(bd.out, [0, 0, -136, 0]);
    assert_eq!(r.trip_position(true, &MAP, &bd.mem), [0, 0, -136, 0]);
    // Homing sets the position at the trip; the latched trip stays.
    r.set_position([0, 0, 0, 0], true, &MAP, &bd.mem);
    assert_eq!(r.position(&MAP, &bd.mem), [0, 0, 0, 0]);
    assert_eq!(r.trip_position(true, &MAP, &bd.mem), [0, 0, -136, 0]);
    // Clear: the queue is dropped, the position stays; a new trip latches anew.
    let q = r.position(&MAP, &bd.mem);
    let cur = bd.cur;
    bd.clear_isr();
    r.clear(cur, q, &mut bd.mem);
    assert_eq!(r.position(&MAP, &bd.mem), [0, 0, 0, 0]);
    for c in commands(block([0, 0, 40, 0], 0, false), 100, &mut rng) {
        assert!(r.push(&c, &MAP, &mut bd.mem));
    }
    run_to(&mut bd, 137 + 21);
    bd.stopped = true;
    assert_eq!(r.trip_position(true, &MAP, &bd.mem), [0, 0, 20, 0]);
}

#[test]
fn clear_drops_the_queue_keeps_what_was_output_and_the_stopped_chunk_adds_nothing() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    let mut rng = XorShift(17);
    assert!(r.push(&StepperCmd::Block(block([500, 300, 0, 0], 0, false)), &MAP, &mut bd.mem));
    for _ in 0..6 {
        assert!(r.push(&run(20, 400), &MAP, &mut bd.mem));
    }
    run_to(&mut bd, 77);
    bd.stopped = true;
    let q = r.position(&MAP, &bd.mem);
    assert_eq!(q, bd.out);
    assert_eq!(q[0], 76);
    let cur = bd.cur;
    bd.clear_isr();
    r.clear(cur, q, &mut bd.mem);
    assert_eq!(r.space(&bd.mem), 7);
    // A new move from there; retiring the stopped chunk later adds nothing.
    let mut more = Vec::new();
    for _ in 0..20 {
        more.extend(commands(block([10, 0, 0, 0], 0b0001, false), 5, &mut rng));
    }
    stream(&mut r, &mut bd, &more);
    assert_eq!(r.position(&MAP, &bd.mem), [q[0] - 200, q[1], 0, 0]);
}

#[test]
fn step_output_bits_map_back_to_axes() {
    assert_eq!(out_to_axes(&MAP, 0x01 | 0x08), 0b0101);
    assert_eq!(out_to_axes(&MAP, 0x40 | 0x10), 0b1010);
    assert_eq!(out_to_axes(&MAP, 0x02 | 0x80), 0);
}

#[test]
fn the_watch_gives_the_splitter_its_limit_masks() {
    let mut r = Rings::new();
    let mut bd = Board::new();
    let w = Watch { homing: 0, probe: false, limits: 0b111, homed: 0b001, invert_dir: 0b0010, invert_inputs: 0, release: [4, 0, 0] };
    r.set_watch(w);
    assert_eq!(r.watch(), w);
    // X homed at 0: its chunk starting there is not armed; Y inverted: pin high when negative.
    assert!(r.push(&StepperCmd::Block(block([3, 2, 0, 0], 0b0010, false)), &MAP, &mut bd.mem));
    let c = bd.chunks[1];
    assert_eq!(c.limit, 0b110);
    assert_eq!(c.dir_out[0], 0x02 | 0x80);
}

#[test]
fn push_fitting_queues_what_push_queues_and_answers_the_space_after() {
    let mut rng = XorShift(0xF17);
    let mut cmds = Vec::new();
    for n in 0..40u32 {
        let steps = [rng.next() % 300, rng.next() % 300, rng.next() % 20, if n % 9 == 0 { 70_000 } else { 0 }];
        if steps.iter().all(|&v| v == 0) {
            continue;
        }
        cmds.extend(commands(block(steps, (rng.next() & 0x0F) as u8, false), 120, &mut rng));
    }
    // The plain way (space, then push) and push_fitting, the ISR running
    // between fills the same way in both.
    let (mut plain, mut fast) = (Rings::new(), Rings::new());
    let (mut bp, mut bf) = (Board::new(), Board::new());
    let (mut next, mut isr_runs) = (0, 0u32);
    while next < cmds.len() {
        let start = next;
        let mut space = fast.space(&bf.mem);
        assert_eq!(space, plain.space(&bp.mem));
        while space > 0 && next < cmds.len() {
            assert!(plain.push(&cmds[next], &MAP, &mut bp.mem));
            space = fast.push_fitting(&cmds[next], &MAP, &mut bf.mem);
            assert_eq!(space, plain.space(&bp.mem), "command {next}");
            next += 1;
        }
        assert_eq!((bf.seg_head, bf.queued_segs()), (bp.seg_head, bp.queued_segs()), "after commands {start}..{next}");
        for _ in 0..=(rng.next() % 40) {
            bp.interrupt();
            bf.interrupt();
            isr_runs += 1;
        }
        assert_eq!(fast.position(&MAP, &bf.mem), plain.position(&MAP, &bp.mem));
        assert_eq!(bf.out, bp.out);
    }
    assert!(isr_runs > 100);
}
