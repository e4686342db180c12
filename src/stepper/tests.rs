//! Planner + prep + splitter + Bresenham run together on the host: what the
//! ISR would do (each block cut into the ISR's records by
//! [`queue::Splitter`], stepped by the model [`queue::Chunk::tick`]).

use super::queue::{Chunk, ChunkWatch, Seg, Sink, Splitter, StepMap};
use super::*;
use crate::config::Settings;
use crate::planner::{PlanError, Planner, BLOCK_BUFFER_LEN};

/// One executed segment, as the ISR would run it.
#[derive(Clone, Copy, Debug)]
struct Ran {
    seg: Segment,
    /// Path speed of the segment, mm/s (XYZ length, or E for E-only blocks).
    speed: f32,
    /// Duration, s.
    dt: f64,
}

/// Step bits = axis bits on the host.
const AXES: StepMap = StepMap { step: [1, 2, 4, 8], dir: [(0, 1), (0, 2), (0, 4), (0, 8)] };

/// The splitter's records of the current block.
#[derive(Default)]
struct Records {
    chunks: Vec<Chunk>,
    segs: std::collections::VecDeque<Seg>,
}

impl Sink for Records {
    fn chunk(&mut self, c: &Chunk) {
        self.chunks.push(*c);
    }
    fn seg(&mut self, s: &Seg) {
        self.segs.push_back(*s);
    }
}

/// A host stand-in for the ISR: runs the commands, counts steps and time.
struct Machine {
    split: Splitter,
    rec: Records,
    /// The running chunk, its index in `rec.chunks`, events left in the running seg.
    chunk: Chunk,
    chunk_index: usize,
    seg_left: u16,
    st: Option<StBlock>,
    /// Motor position, steps.
    motor: [i64; N_AXES],
    /// Position excluding take-up blocks, steps.
    counted: [i64; N_AXES],
    /// Events done in the current block.
    events: u32,
    blocks: usize,
    time: f64,
    ran: Vec<Ran>,
    /// Path mm per step event of the current block.
    mm_per_event: f32,
    /// Motor position when the current block started.
    block_start: [i64; N_AXES],
    /// Check every step against the block's ideal line (±1 step).
    check_line: bool,
    /// Time of every X step, s.
    x_step_times: Vec<f64>,
    s: Settings,
}

impl Machine {
    fn new(s: &Settings) -> Self {
        Machine {
            split: Splitter::new(),
            rec: Records::default(),
            chunk: Chunk::EMPTY,
            chunk_index: usize::MAX,
            seg_left: 0,
            st: None,
            motor: [0; N_AXES],
            counted: [0; N_AXES],
            events: 0,
            blocks: 0,
            time: 0.0,
            ran: Vec::new(),
            mm_per_event: 0.0,
            block_start: [0; N_AXES],
            check_line: true,
            x_step_times: Vec::new(),
            s: *s,
        }
    }

    /// One step event of the current block's records: axis bits.
    fn tick(&mut self) -> u8 {
        if self.seg_left == 0 {
            let s = self.rec.segs.pop_front().expect("a tick without a segment");
            self.seg_left = s.ticks;
            if s.new_chunk != 0 {
                self.chunk_index = self.chunk_index.wrapping_add(1);
                self.chunk = self.rec.chunks[self.chunk_index];
            }
        }
        self.seg_left -= 1;
        self.chunk.tick()
    }

    fn exec(&mut self, cmd: StepperCmd) {
        if let StepperCmd::Block(_) = cmd {
            assert!(self.rec.segs.is_empty() && self.seg_left == 0, "records of the previous block left");
            self.rec.chunks.clear();
            self.chunk_index = usize::MAX;
        }
        self.split.push(&cmd, &AXES, &ChunkWatch::default(), &mut self.rec);
        match cmd {
            StepperCmd::Block(b) => {
                if let Some(prev) = self.st {
                    assert_eq!(self.events, prev.step_event_count, "previous block not finished");
                }
                self.st = Some(b);
                self.events = 0;
                self.blocks += 1;
                self.block_start = self.motor;
                let mut xyz = 0.0f32;
                for a in 0..3 {
                    let d = b.steps[a] as f32 / self.s.steps_per_mm[a];
                    xyz += d * d;
                }
                let mm = if xyz > 0.0 { xyz.sqrt() } else { b.steps[3] as f32 / self.s.steps_per_mm[3] };
                self.mm_per_event = mm / b.step_event_count as f32;
            }
            StepperCmd::Run(seg) => {
                let b = self.st.expect("segment before block");
                assert!(seg.ticks >= 1);
                if seg.prescale == Prescale::Div1 {
                    assert!(seg.period >= MIN_PERIOD_CYCLES, "period {} too short", seg.period);
                }
                let tick_s = seg.period as f64 * seg.prescale.divisor() as f64 / crate::F_CPU_HZ as f64;
                for k in 0..seg.ticks {
                    let bits = self.tick();
                    if bits & 1 != 0 {
                        self.x_step_times.push(self.time + (k as f64 + 1.0) * tick_s);
                    }
                    self.events += 1;
                    assert!(self.events <= b.step_event_count, "more events than the block has");
                    for a in 0..N_AXES {
                        if bits & (1 << a) != 0 {
                            let d = if b.direction_bits & (1 << a) != 0 { -1 } else { 1 };
                            self.motor[a] += d;
                            if !b.take_up {
                                self.counted[a] += d;
                            }
                        }
                    }
                    if self.check_line {
                        // Position within the block against the ideal line.
                        let k = self.events as f64;
                        for a in 0..N_AXES {
                            let done = (self.motor[a] - self.block_start[a]).abs() as f64;
                            let ideal = k * b.steps[a] as f64 / b.step_event_count as f64;
                            assert!((done - ideal).abs() <= 1.0, "axis {a}: {done} vs {ideal}");
                        }
                    }
                }
                let dt = seg.duration_s() as f64;
                self.ran.push(Ran { seg, speed: seg.rate_hz() * self.mm_per_event, dt });
                self.time += dt;
            }
        }
    }
}

/// Drain planner + prep into the machine, feeding `moves` as room appears.
/// Returns the machine.
fn run_moves(s: &Settings, moves: &[([i32; N_AXES], f32, bool)]) -> (Machine, Planner) {
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    let mut m = Machine::new(s);
    let mut next = 0;
    loop {
        while next < moves.len() {
            let (t, f, r) = moves[next];
            match pl.push_line(t, f, r, s) {
                Ok(_) => next += 1,
                Err(PlanError::Full) => break,
                Err(e) => panic!("{e:?}"),
            }
        }
        match prep.next_segment(&mut pl) {
            Some(c) => m.exec(c),
            None => {
                if next >= moves.len() {
                    break;
                }
            }
        }
    }
    assert!(pl.is_empty());
    (m, pl)
}

fn x_moves(mm: &[f32], feed: f32, s: &Settings) -> Vec<([i32; N_AXES], f32, bool)> {
    let mut pos = 0.0f32;
    mm.iter()
        .map(|d| {
            pos += d;
            ([crate::math::round_i32(pos * s.steps_per_mm[0]), 0, 0, 0], feed, false)
        })
        .collect()
}

/// Max path acceleration between consecutive segments (of the same block or
/// of collinear blocks), mm/s². A segment of one or two ticks has a "speed"
/// that is a single step interval, so segments are first merged into windows
/// of at least 4 ticks (only ramp ends and block ends are ever merged).
fn max_accel(ran: &[Ran]) -> f32 {
    // (speed mm/s, duration s) of each window.
    let mut windows: Vec<(f32, f64)> = Vec::new();
    let (mut mm, mut t, mut ticks) = (0.0f64, 0.0f64, 0u32);
    for r in ran {
        mm += r.speed as f64 * r.dt;
        t += r.dt;
        ticks += r.seg.ticks as u32;
        if ticks >= 4 {
            windows.push(((mm / t) as f32, t));
            (mm, t, ticks) = (0.0, 0.0, 0);
        }
    }
    let mut worst = 0.0f32;
    for w in windows.windows(2) {
        let dt = ((w[0].1 + w[1].1) / 2.0) as f32;
        worst = worst.max((w[1].0 - w[0].0).abs() / dt);
    }
    worst
}

fn peak_speed(ran: &[Ran]) -> f32 {
    ran.iter().map(|r| r.speed).fold(0.0, f32::max)
}

#[test]
fn segment_ticks_add_up_to_each_blocks_step_event_count() {
    let s = Settings::DEFAULT;
    let mut seed = 0x9E37_79B9u32;
    let mut rnd = |m: i32| {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        ((seed >> 8) as i32).rem_euclid(2 * m + 1) - m
    };
    let mut moves = Vec::new();
    let mut p = [0i32; N_AXES];
    for i in 0..300 {
        let scale = [3, 40, 400, 4000][i % 4];
        for a in 0..N_AXES {
            p[a] += if a == 3 { rnd(scale / 4) } else { rnd(scale) };
        }
        let feed = 100.0 + (rnd(1000) + 1000) as f32 * 2.0;
        moves.push((p, feed, i % 7 == 0));
    }
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    let mut m = Machine::new(&s);
    let mut next = 0;
    let mut per_block: Vec<(u32, u32)> = Vec::new(); // (step_event_count, ticks)
    loop {
        while next < moves.len() && pl.push_line(moves[next].0, moves[next].1, moves[next].2, &s).is_ok() {
            next += 1;
        }
        match prep.next_segment(&mut pl) {
            Some(c) => {
                match c {
                    StepperCmd::Block(b) => per_block.push((b.step_event_count, 0)),
                    StepperCmd::Run(g) => per_block.last_mut().unwrap().1 += g.ticks as u32,
                }
                m.exec(c);
            }
            None if next >= moves.len() => break,
            None => {}
        }
    }
    assert!(per_block.len() >= 290);
    for (i, (n, t)) in per_block.iter().enumerate() {
        assert_eq!(n, t, "block {i}");
    }
    assert_eq!(m.motor, [p[0] as i64, p[1] as i64, p[2] as i64, p[3] as i64]);
}

#[test]
fn a_short_move_is_a_triangle_below_the_feed() {
    let s = Settings::DEFAULT;
    // 0.5 mm at F3000 (50 mm/s): peak = √(a·d) = √(1000·0.5) = 22.4 mm/s.
    let (m, _) = run_moves(&s, &x_moves(&[0.5], 3000.0, &s));
    let peak = peak_speed(&m.ran);
    assert!(peak < 22.4 * 1.05 && peak > 22.4 * 0.8, "peak {peak}");
    assert_eq!(m.motor[0], 50);
}

#[test]
fn a_long_move_reaches_the_feed_and_cruises() {
    let s = Settings::DEFAULT;
    let (m, _) = run_moves(&s, &x_moves(&[20.0], 3000.0, &s));
    let peak = peak_speed(&m.ran);
    assert!((peak - 50.0).abs() < 0.5, "peak {peak}");
    // 350 ms of cruise in segments of CRUISE_SEGMENT_TIME_S.
    let cruising: Vec<_> = m.ran.iter().filter(|r| (r.speed - 50.0).abs() < 0.5).collect();
    assert!(cruising.len() >= 15, "{} segments at the feed", cruising.len());
    assert!(cruising.iter().all(|r| r.dt <= prep::CRUISE_SEGMENT_TIME_S as f64 * 1.001));
    let ramp = m.ran.iter().filter(|r| r.speed < 45.0).count();
    assert!(ramp >= 18, "ramps use short segments: {ramp}");
    // Ideal time: 20/50 + 50/1000 (ramps) = 0.45 s.
    assert!((m.time - 0.45).abs() < 0.01, "time {}", m.time);
}

#[test]
fn acceleration_between_segments_never_exceeds_the_limit() {
    let mut s = Settings::DEFAULT;
    for (moves, accel) in [
        (x_moves(&[20.0], 3000.0, &s), 1000.0),
        (x_moves(&[0.3, 2.0, 0.05, 7.0, 0.1, 0.1, 0.1], 3000.0, &s), 1000.0),
        (x_moves(&[10.0, 10.0], 1200.0, &s), 1000.0),
    ] {
        let (m, _) = run_moves(&s, &moves);
        let worst = max_accel(&m.ran);
        assert!(worst <= accel * 1.05, "accel {worst}");
        assert!(worst > accel * 0.8, "accel {worst} suspiciously low");
    }
    // A low acceleration and a different steps/mm.
    s.accel_mm_per_s2[0] = 50.0;
    s.steps_per_mm[0] = 80.0;
    let (m, _) = run_moves(&s, &x_moves(&[5.0], 3000.0, &s));
    let worst = max_accel(&m.ran);
    assert!(worst <= 50.0 * 1.05, "accel {worst}");
}

#[test]
fn a_diagonal_respects_each_axis_feed_and_acceleration() {
    let mut s = Settings::DEFAULT;
    s.max_feed_mm_per_min[1] = 1500.0;
    s.accel_mm_per_s2[1] = 250.0;
    let (m, _) = run_moves(&s, &[([2000, 2000, 0, 0], 6000.0, false)]);
    let k = core::f32::consts::FRAC_1_SQRT_2;
    // Y's share of the path speed: speed · 1/√2.
    let y_peak = peak_speed(&m.ran) * k;
    assert!(y_peak <= 25.0 * 1.01, "Y speed {y_peak}");
    assert!(y_peak >= 25.0 * 0.98, "Y speed {y_peak}");
    let y_accel = max_accel(&m.ran) * k;
    assert!(y_accel <= 250.0 * 1.05, "Y accel {y_accel}");
    assert_eq!(m.motor, [2000, 2000, 0, 0]);
}

#[test]
fn periods_never_go_below_the_minimum_even_when_the_feed_asks_for_more() {
    let mut s = Settings::DEFAULT;
    s.steps_per_mm[0] = 1000.0;
    s.max_feed_mm_per_min[0] = 10_000.0;
    let (m, _) = run_moves(&s, &[([40_000, 0, 0, 0], 0.0, true)]);
    let fastest = m.ran.iter().filter(|r| r.seg.prescale == Prescale::Div1).map(|r| r.seg.period).min().unwrap();
    assert_eq!(fastest, MIN_PERIOD_CYCLES);
    let peak_rate = m.ran.iter().map(|r| r.seg.rate_hz()).fold(0.0, f32::max);
    assert!(peak_rate <= crate::config::MAX_STEP_RATE_HZ);
    assert_eq!(m.motor[0], 40_000);
}

#[test]
fn slow_feeds_use_the_clk8_prescaler_and_keep_their_rate() {
    let s = Settings::DEFAULT;
    // F60 = 1 mm/s = 100 steps/s: period 160 000 cycles = 20 000 at clk/8.
    let (m, _) = run_moves(&s, &x_moves(&[1.0], 60.0, &s));
    let cruise: Vec<_> = m.ran.iter().filter(|r| (r.speed - 1.0).abs() < 0.01).collect();
    assert!(!cruise.is_empty());
    assert!(cruise.iter().all(|r| r.seg.prescale == Prescale::Div8));
    assert!(cruise.iter().any(|r| r.seg.period == 20_000));
    assert_eq!(m.motor[0], 100);
}

#[test]
fn moves_of_a_thousandth_of_a_millimetre_end_where_one_millimetre_ends() {
    for spm in [100.0f32, 80.0, 177.777_78] {
        let mut s = Settings::DEFAULT;
        s.steps_per_mm[0] = spm;
        s.steps_per_mm[1] = spm;
        // The caller rounds absolute targets; the planner only sees steps.
        let moves: Vec<_> = (1..=1000)
            .map(|i| {
                let mm = i as f32 * 0.001;
                let st = crate::math::round_i32(mm * spm);
                ([st, st, 0, 0], 600.0, false)
            })
            .collect();
        let (m1, p1) = run_moves(&s, &moves);
        let one = crate::math::round_i32(1.0 * spm);
        let (m2, p2) = run_moves(&s, &[([one, one, 0, 0], 600.0, false)]);
        assert_eq!(p1.position(), p2.position());
        assert_eq!(m1.motor, m2.motor);
        assert_eq!(m1.motor[0], one as i64);
    }
}

#[test]
fn a_stream_of_short_collinear_moves_runs_at_the_feed() {
    // docs/SPEC.md §11: 2,000 × 0.1 mm at F3000 (50 mm/s): ideal 4 s + 0.05 s of ramps.
    let s = Settings::DEFAULT;
    let (m, _) = run_moves(&s, &x_moves(&[0.1; 2000], 3000.0, &s));
    assert_eq!(m.motor[0], 20_000);
    assert_eq!(m.blocks, 2000);
    assert!(m.time > 4.04 && m.time < 4.05 * 1.01, "time {}", m.time);
    assert!(max_accel(&m.ran) <= 1000.0 * 1.05);
}

#[test]
fn a_stream_of_short_diagonal_moves_with_rounding_jitter_runs_at_the_feed() {
    // 0.1 mm steps along a shallow slope: the step rounding makes each block's
    // direction differ slightly; the junctions must not slow the path down.
    let s = Settings::DEFAULT;
    let moves: Vec<_> = (1..=1000)
        .map(|i| {
            let d = i as f32 * 0.1;
            ([crate::math::round_i32(d * 100.0), crate::math::round_i32(d * 0.3 * 100.0), 0, 0], 3000.0, false)
        })
        .collect();
    let (m, _) = run_moves(&s, &moves);
    let len = (100.0f32 * 100.0 + 30.0 * 30.0).sqrt();
    let ideal = len / 50.0 + 0.05;
    assert!((m.time as f32) < ideal * 1.02, "time {} vs {ideal}", m.time);
}

#[test]
fn feed_hold_decelerates_within_the_limit_then_resume_reaches_the_exact_end() {
    let s = Settings::DEFAULT;
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    let mut m = Machine::new(&s);
    pl.push_line([2000, 0, 0, 0], 3000.0, false, &s).unwrap();
    // Run until 5 mm are done (cruising).
    while m.motor[0] < 500 {
        m.exec(prep.next_segment(&mut pl).unwrap());
    }
    let before = m.ran.len();
    let at_hold = m.motor[0];
    let v0 = m.ran.last().unwrap().speed;
    assert!((v0 - 50.0).abs() < 0.5);
    prep.hold();
    assert!(prep.is_holding() && !prep.is_held());
    while let Some(c) = prep.next_segment(&mut pl) {
        m.exec(c);
    }
    assert!(prep.is_held());
    let stop = m.motor[0];
    // Stopping from 50 mm/s at 1000 mm/s² takes 1.25 mm (125 steps).
    assert!(stop > at_hold + 115 && stop < at_hold + 135, "held at {at_hold}, stopped at {stop}");
    let decel = &m.ran[before - 1..];
    assert!(max_accel(decel) <= 1000.0 * 1.05, "decel {}", max_accel(decel));
    assert!(decel.last().unwrap().speed < 5.0);
    // The block is still there with the distance left.
    let left = pl.current_block().unwrap().millimeters;
    assert!((left - (2000 - stop) as f32 / 100.0).abs() < 0.02, "left {left}");
    assert!(prep.next_segment(&mut pl).is_none());

    prep.resume();
    let after = m.ran.len();
    while let Some(c) = prep.next_segment(&mut pl) {
        m.exec(c);
    }
    assert_eq!(m.motor[0], 2000);
    assert!(pl.is_empty());
    // Restarts from rest within the limit.
    assert!(m.ran[after].speed < 10.0);
    assert!(max_accel(&m.ran[after..]) <= 1000.0 * 1.05);
}

#[test]
fn feed_hold_in_a_stream_of_short_moves_stops_across_blocks_and_resumes() {
    let s = Settings::DEFAULT;
    let moves = x_moves(&[0.1; 300], 3000.0, &s);
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    let mut m = Machine::new(&s);
    let mut next = 0;
    let mut held_at = None;
    loop {
        while next < moves.len() && pl.push_line(moves[next].0, moves[next].1, false, &s).is_ok() {
            next += 1;
        }
        if m.motor[0] >= 1000 && held_at.is_none() && !prep.is_holding() {
            prep.hold();
            held_at = Some(m.ran.len());
        }
        match prep.next_segment(&mut pl) {
            Some(c) => m.exec(c),
            None if prep.is_held() => {
                let stop = m.motor[0];
                assert!(stop > 1100 && stop < 1150, "stopped at {stop}");
                let from = held_at.unwrap() - 1;
                assert!(max_accel(&m.ran[from..]) <= 1000.0 * 1.05);
                // The machine is stopped; the host keeps streaming meanwhile.
                pl.cycle_reinitialize();
                prep.resume();
            }
            None if next >= moves.len() => break,
            None => {}
        }
    }
    assert_eq!(m.motor[0], 3000);
    assert!(max_accel(&m.ran) <= 1000.0 * 1.05, "{}", max_accel(&m.ran));
}

#[test]
fn a_hold_with_nothing_queued_is_complete_at_once() {
    let s = Settings::DEFAULT;
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    prep.hold();
    assert!(prep.next_segment(&mut pl).is_none());
    assert!(prep.is_held());
    prep.resume();
    pl.push_line([100, 0, 0, 0], 600.0, false, &s).unwrap();
    let mut m = Machine::new(&s);
    while let Some(c) = prep.next_segment(&mut pl) {
        m.exec(c);
    }
    assert_eq!(m.motor[0], 100);
}

#[test]
fn reset_forgets_the_block_in_progress() {
    let s = Settings::DEFAULT;
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    pl.push_line([2000, 0, 0, 0], 3000.0, false, &s).unwrap();
    for _ in 0..5 {
        prep.next_segment(&mut pl).unwrap();
    }
    assert!(prep.is_busy());
    prep.reset();
    pl.clear();
    pl.set_position([123, 0, 0, 0]);
    assert!(!prep.is_busy());
    assert!(prep.next_segment(&mut pl).is_none());
    pl.push_line([223, 0, 0, 0], 600.0, false, &s).unwrap();
    let mut m = Machine::new(&s);
    while let Some(c) = prep.next_segment(&mut pl) {
        m.exec(c);
    }
    assert_eq!(m.motor[0], 100);
}

#[test]
fn backlash_take_up_moves_the_motor_but_not_the_counted_position() {
    let mut s = Settings::DEFAULT;
    s.backlash_mm = [0.05, 0.0, 0.0];
    let moves = [([100, 100, 0, 0], 1200.0, false), ([0, 0, 0, 0], 1200.0, false), ([50, 0, 0, 0], 1200.0, false)];
    let (m, pl) = run_moves(&s, &moves);
    // X reversed twice: −5 then +5 take-up steps; Y has no backlash.
    assert_eq!(m.blocks, 5);
    assert_eq!(m.counted, [50, 0, 0, 0]);
    assert_eq!(m.motor, [50, 0, 0, 0]);
    assert_eq!(pl.backlash_offset_steps(), [0, 0, 0]);
    assert_eq!(pl.position(), [50, 0, 0, 0]);
}

#[test]
fn the_segment_queue_can_be_filled_through_a_heapless_producer() {
    let s = Settings::DEFAULT;
    let mut pl = Planner::new();
    let mut prep = Prep::new();
    pl.push_line([1000, 0, 0, 0], 3000.0, false, &s).unwrap();
    let mut q: heapless::spsc::Queue<StepperCmd, 8> = heapless::spsc::Queue::new();
    let (mut p, mut c) = q.split();
    let mut m = Machine::new(&s);
    loop {
        prep.fill(&mut pl, &mut p);
        if c.len() == 0 {
            break;
        }
        while let Some(cmd) = c.dequeue() {
            m.exec(cmd);
        }
    }
    assert_eq!(m.motor[0], 1000);
    assert!(pl.len() < BLOCK_BUFFER_LEN);
}

#[test]
fn every_step_comes_within_one_step_of_the_ideal_trapezoid() {
    // 20 mm at 50 mm/s, 1000 mm/s², 100 steps/mm: accelerate 50 ms (1.25 mm),
    // cruise 350 ms, decelerate 50 ms.
    let s = Settings::DEFAULT;
    let (m, _) = run_moves(&s, &x_moves(&[20.0], 3000.0, &s));
    let ideal_steps = |t: f64| -> f64 {
        let (a, v, ta, tc) = (1000.0, 50.0, 0.05, 0.35);
        let mm = if t < ta {
            0.5 * a * t * t
        } else if t < ta + tc {
            1.25 + v * (t - ta)
        } else {
            let td = (t - ta - tc).min(ta);
            18.75 + v * td - 0.5 * a * td * td
        };
        mm * 100.0
    };
    assert_eq!(m.x_step_times.len(), 2000);
    for (k, &t) in m.x_step_times.iter().enumerate() {
        let err = (k + 1) as f64 - ideal_steps(t);
        assert!(err.abs() <= 1.0, "step {} at {t:.5} s: {err:+.3} steps from the ideal", k + 1);
    }
    assert!((m.x_step_times[1999] - 0.45).abs() < 0.002);
}
