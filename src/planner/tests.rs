//! Host tests of the planner: junction and entry speeds, trapezoids,
//! look-ahead over long runs of tiny moves, the overrides' re-plan, and
//! the ring's bookkeeping.

use super::junction::REVERSAL_STEP_S;
use super::*;
use crate::config::Settings;
use crate::N_AXES;
use core::mem::size_of;

fn s() -> Settings {
    Settings::DEFAULT
}

fn blocks(p: &Planner) -> Vec<Block> {
    (0..p.len()).map(|i| p.block(i).unwrap()).collect()
}

/// The optimal plan computed the slow way: a full backward then forward pass
/// over every block, from the executing block's current entry speed.
fn brute_force_entries(p: &Planner) -> Vec<f32> {
    let b = blocks(p);
    let n = b.len();
    let mut e: Vec<f32> = b.iter().map(|x| x.max_entry_speed_sqr).collect();
    e[0] = b[0].entry_speed_sqr;
    let mut exit = 0.0f32;
    for i in (1..n).rev() {
        e[i] = e[i].min(exit + 2.0 * b[i].millimeters * (crate::F_CPU / b[i].dv_cycles));
        exit = e[i];
    }
    for i in 1..n {
        e[i] = e[i].min(e[i - 1] + 2.0 * b[i - 1].millimeters * (crate::F_CPU / b[i - 1].dv_cycles));
    }
    e
}

fn assert_close(a: f32, b: f32, rel: f32) {
    assert!((a - b).abs() <= rel * b.abs().max(1e-6), "{a} vs {b}");
}

const _: () = assert!(BLOCK_BUFFER_LEN >= 16, "SPEC §6: at least 16 blocks");
const _: () = assert!(size_of::<Planner>() <= PLANNER_RAM_BUDGET);

#[test]
fn new_blocks_are_empty() {
    // `Planner::new` zeroes its blocks (see there): each is `Block::EMPTY`,
    // field for field and bit for bit.
    let p = Planner::new();
    for b in &p.blocks {
        assert_eq!(*b, Block::EMPTY);
        assert_eq!(b.millimeters.to_bits() | b.entry_speed_sqr.to_bits() | b.max_delta_speed_sqr.to_bits(), 0);
    }
}

#[test]
fn a_straight_continuation_keeps_its_speed_through_the_junction() {
    let mut p = Planner::new();
    p.push_line([1000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    p.push_line([2000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    let b = blocks(&p);
    assert_eq!(b[0].entry_speed_sqr, 0.0, "the first block starts from rest");
    assert_close(b[1].max_entry_speed_sqr, 2500.0, 1e-5);
    assert_close(b[1].entry_speed_sqr, 2500.0, 1e-5);
    assert_eq!(p.exec_exit_speed_sqr(), b[1].entry_speed_sqr);
}

#[test]
fn a_right_angle_corner_enters_at_the_junction_deviation_speed() {
    let mut p = Planner::new();
    p.push_line([1000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    p.push_line([1000, 1000, 0, 0], 3000.0, false, &s()).unwrap();
    // grbl: v² = a·δ·sin(θ/2)/(1 − sin(θ/2)), θ = 90° between the directions.
    let sin = (0.5f32).sqrt();
    let expect = 1000.0 * 0.01 * sin / (1.0 - sin);
    let b = blocks(&p);
    assert_close(b[1].max_entry_speed_sqr, expect, 1e-4);
    assert_close(b[1].entry_speed_sqr, expect, 1e-4);
    assert!((b[1].entry_speed_sqr.sqrt() - 4.91).abs() < 0.01);
}

#[test]
fn a_reversal_stops_at_the_junction() {
    let mut p = Planner::new();
    p.push_line([1000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    p.push_line([0, 0, 0, 0], 3000.0, false, &s()).unwrap();
    assert_eq!(blocks(&p)[1].max_entry_speed_sqr, 0.0);
    assert_eq!(blocks(&p)[1].entry_speed_sqr, 0.0);
}

#[test]
fn the_newest_block_always_ends_at_rest() {
    let mut p = Planner::new();
    for i in 1..=5 {
        p.push_line([i * 100, 0, 0, 0], 3000.0, false, &s()).unwrap();
    }
    // Each 1 mm block can shed 2·a·d = 2000 (mm/s)²: entries 2500 capped, …
    let e: Vec<f32> = blocks(&p).iter().map(|b| b.entry_speed_sqr).collect();
    assert_eq!(e[0], 0.0);
    assert_close(e[4], 2000.0, 1e-5);
    assert_close(e[3], 2500.0, 1e-5);
    assert_close(e[1], 2000.0, 1e-5); // limited by accelerating from rest
}

#[test]
fn look_ahead_matches_a_full_replan_after_every_block() {
    let st = s();
    let mut p = Planner::new();
    let mut seed = 7u32;
    let mut pos = [0i32; N_AXES];
    for i in 0..400 {
        seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        let dx = ((seed >> 16) % 60) as i32 - 10;
        let dy = ((seed >> 8) % 40) as i32 - 20;
        pos[0] += dx;
        pos[1] += dy;
        let feed = [3000.0, 600.0, 1800.0][i % 3];
        if p.is_full() {
            p.discard_current_block();
            // As prep would: the new executing block starts at its entry speed.
        }
        p.push_line(pos, feed, false, &st).unwrap();
        let got: Vec<f32> = blocks(&p).iter().map(|b| b.entry_speed_sqr).collect();
        let want = brute_force_entries(&p);
        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
            assert!((g - w).abs() <= 1e-3 * w.max(1.0), "push {i} block {k}: {g} vs {w}");
        }
    }
}

#[test]
fn a_diagonal_is_limited_by_the_slower_axis() {
    let mut st = s();
    st.max_feed_mm_per_min[1] = 1500.0;
    st.accel_mm_per_s2[1] = 250.0;
    let mut p = Planner::new();
    p.push_line([1000, 1000, 0, 0], 6000.0, false, &st).unwrap();
    let b = p.current_block().unwrap();
    let k = core::f32::consts::SQRT_2;
    assert_close(b.millimeters, 10.0 * k, 1e-6);
    // Y may do 25 mm/s and 250 mm/s²; it is 1/√2 of the path.
    assert_close(b.nominal_speed_sqr.sqrt(), 25.0 * k, 1e-5);
    assert_close(crate::F_CPU / b.dv_cycles, 250.0 * k, 1e-5);
    assert_eq!(b.steps(), [1000, 1000, 0, 0]);
    assert_eq!(b.step_event_count(), 1000);
    assert_eq!(b.direction_bits(), 0);
}

#[test]
fn a_rapid_uses_each_axis_max_feed() {
    let mut st = s();
    st.max_feed_mm_per_min[0] = 2400.0;
    let mut p = Planner::new();
    p.push_line([-500, 0, 0, 0], 1.0, true, &st).unwrap();
    let b = p.current_block().unwrap();
    assert_close(b.nominal_speed_sqr.sqrt(), 40.0, 1e-5);
    assert_eq!(b.direction_bits(), 0b0001);
}

#[test]
fn an_e_only_move_is_planned_in_pitches_with_the_e_limits() {
    let st = s();
    let mut p = Planner::new();
    let spp = st.steps_per_mm[3];
    let target = crate::math::round_i32(3.0 * spp);
    p.push_line([0, 0, 0, target], 6000.0, false, &st).unwrap();
    let b = p.current_block().unwrap();
    assert_close(b.millimeters, target as f32 / spp, 1e-6);
    assert_close(b.nominal_speed_sqr.sqrt(), 600.0 / 60.0, 1e-5);
    assert_close(crate::F_CPU / b.dv_cycles, 50.0, 1e-5);
}

#[test]
fn a_feed_beyond_the_step_rate_cap_is_capped_and_reported() {
    let mut st = s();
    st.steps_per_mm[0] = 1000.0;
    st.max_feed_mm_per_min[0] = 10_000.0;
    let mut p = Planner::new();
    // 100 mm/s × 1000 steps/mm = 100 kHz > 60 kHz.
    let r = p.push_line([10_000, 0, 0, 0], 6000.0, false, &st).unwrap();
    assert!(r.rate_capped);
    let v = p.current_block().unwrap().nominal_speed_sqr.sqrt();
    assert_close(v * 1000.0, crate::config::MAX_STEP_RATE_HZ, 1e-5);
    // 50 mm/s = 50 kHz is fine.
    let r = p.push_line([20_000, 0, 0, 0], 3000.0, false, &st).unwrap();
    assert!(!r.rate_capped);
    assert_eq!(r.queued, 1);
}

#[test]
fn a_feed_below_the_slowest_timer_rate_is_raised_and_reported() {
    let st = s();
    let mut p = Planner::new();
    // F1 = 1/60 mm/s = 1.7 steps/s < 30.5 Hz.
    let r = p.push_line([100, 0, 0, 0], 1.0, false, &st).unwrap();
    assert!(r.rate_floored);
    let v = p.current_block().unwrap().nominal_speed_sqr.sqrt();
    assert_close(v * 100.0, crate::config::MIN_STEP_RATE_HZ, 1e-4);
}

#[test]
fn zero_length_moves_queue_nothing_and_bad_feeds_are_refused() {
    let mut p = Planner::new();
    assert_eq!(p.push_line([0; 4], 100.0, false, &s()), Ok(Push::default()));
    assert!(p.is_empty());
    assert_eq!(p.push_line([10, 0, 0, 0], 0.0, false, &s()), Err(PlanError::BadFeed));
    assert_eq!(p.push_line([10, 0, 0, 0], -5.0, false, &s()), Err(PlanError::BadFeed));
    assert_eq!(p.push_line([10, 0, 0, 0], f32::NAN, false, &s()), Err(PlanError::BadFeed));
    assert_eq!(p.push_line([10, 0, 0, 0], f32::INFINITY, false, &s()), Err(PlanError::BadFeed));
    assert_eq!(p.push_line([10, 0, 0, 0], -0.0, false, &s()), Err(PlanError::BadFeed));
    assert_eq!(p.push_line([10, 0, 0, 0], f32::NEG_INFINITY, false, &s()), Err(PlanError::BadFeed));
    assert_eq!(p.push_line([10, 0, 0, 0], -f32::NAN, false, &s()), Err(PlanError::BadFeed));
    assert!(p.is_empty());
    assert_eq!(p.position(), [0; 4]);
}

#[test]
fn a_block_keeps_its_programmed_feed_only_when_it_follows_the_override() {
    // The rounded feed shares the 1/feed cache; the same feed as a fixed
    // speed (a jog, the tool changer's moves) still carries none.
    let mut p = Planner::new();
    let speeds = [
        (Speed::Fixed(1500.0), 0),
        (Speed::Feed(1500.0), 1500),
        (Speed::Fixed(1500.0), 0),
        (Speed::Feed(1234.4), 1234),
        (Speed::Feed(1234.6), 1235),
        (Speed::Feed(0.2), 1),
        (Speed::Rapid, 0),
        (Speed::Feed(0.2), 1),
    ];
    for (i, (speed, want)) in speeds.into_iter().enumerate() {
        p.push_move([10 * (i as i32 + 1), 0, 0, 0], speed, &s()).unwrap();
        let b = p.block(p.len() - 1).unwrap();
        assert_eq!(b.feed, want, "{speed:?}");
    }
}

#[test]
fn a_full_ring_refuses_until_a_block_is_discarded() {
    let mut p = Planner::new();
    for i in 1..=BLOCK_BUFFER_LEN as i32 {
        p.push_line([i * 10, 0, 0, 0], 600.0, false, &s()).unwrap();
    }
    assert!(p.is_full());
    assert_eq!(p.free(), 0);
    let before = p.position();
    assert_eq!(p.push_line([9999, 0, 0, 0], 600.0, false, &s()), Err(PlanError::Full));
    assert_eq!(p.position(), before);
    p.discard_current_block();
    assert_eq!(p.len(), BLOCK_BUFFER_LEN - 1);
    p.push_line([9999, 0, 0, 0], 600.0, false, &s()).unwrap();
    assert_eq!(p.block(BLOCK_BUFFER_LEN - 1).unwrap().steps()[0], 9999 - BLOCK_BUFFER_LEN as u32 * 10);
}

/// The step event count a block keeps as its dominant axis' index is the
/// largest step count, on random moves of one to four axes.
#[test]
fn the_step_event_count_is_the_largest_step_count() {
    let mut rng = crate::test_util::XorShift(0x5e7);
    let mut p = Planner::new();
    let mut target = [0i32; N_AXES];
    for _ in 0..20_000 {
        for t in target.iter_mut() {
            if !rng.next().is_multiple_of(3) {
                *t += (rng.next() % 2001) as i32 - 1000;
            }
        }
        if p.is_full() {
            p.discard_current_block();
        }
        if p.push_line(target, 600.0, false, &s()).unwrap().queued == 0 {
            continue;
        }
        let b = p.block(p.len() - 1).unwrap();
        assert_eq!(b.step_event_count(), *b.steps().iter().max().unwrap(), "{:?}", b.steps());
    }
}

/// A move of more steps than a block holds (`Block::MAX_STEPS` on an axis) is
/// refused as too long, and queued in the pieces `first_piece` gives: every
/// step is there, and each piece ends within a step of the line from its
/// start to the target.
#[test]
fn a_move_longer_than_a_block_holds_is_queued_in_pieces_along_its_line() {
    let targets = [[40_000_000, -25_000_000, 3, 0], [i32::MAX, i32::MIN, 0, 0], [-30_000_000, 0, 0, 16_777_215]];
    for target in targets {
        let mut p = Planner::new();
        // One slot left: the first piece goes in, the rest waits for room.
        for i in 1..BLOCK_BUFFER_LEN as i32 {
            p.push_line([0, 0, 0, i], 600.0, false, &s()).unwrap();
        }
        let start = p.position();
        // As `Machine::queue_line` does. Every block queued, those dropped
        // to make room first.
        let mut queued = Vec::new();
        let mut to = target;
        loop {
            match p.push_line(to, 600.0, false, &s()) {
                Ok(_) if to == target => break,
                Ok(_) => to = target,
                Err(PlanError::TooLong) => to = p.first_piece(&to),
                Err(e) => {
                    assert_eq!(e, PlanError::Full);
                    queued.push(*p.current_block().unwrap());
                    p.discard_current_block();
                }
            }
        }
        assert_eq!(p.position(), target);
        assert!(!queued.is_empty(), "{target:?}: the ring was never full");
        queued.extend(blocks(&p));
        let pieces: Vec<Block> = queued.into_iter().filter(|b| b.steps()[..3] != [0, 0, 0]).collect();
        assert!(pieces.len() >= 2, "{target:?}: {} pieces", pieces.len());
        let mut at = start.map(|v| v as i64);
        for piece in &pieces {
            let (steps, dir) = (piece.steps(), piece.direction_bits());
            let from = at;
            for a in 0..N_AXES {
                assert!(steps[a] <= Block::MAX_STEPS);
                let d = steps[a] as i64;
                at[a] += if dir & (1 << a) != 0 { -d } else { d };
            }
            // On the line from where the piece starts to the target, within
            // a step per axis at the dominant axis' position.
            let k = (0..N_AXES).max_by_key(|&a| (target[a] as i64 - from[a]).abs()).unwrap();
            let (dk, done) = (target[k] as i64 - from[k], at[k] - from[k]);
            for a in 0..N_AXES {
                let ideal = (target[a] as i64 - from[a]) as f64 * done as f64 / dk as f64;
                let off = (at[a] - from[a]) as f64 - ideal;
                assert!(off.abs() <= 1.0 + 1e-6, "{target:?}: axis {a} at {at:?}, {off} off the line");
            }
        }
        assert_eq!(at, target.map(|v| v as i64), "every step queued");
    }
}

#[test]
fn targets_are_absolute_steps_so_tiny_moves_do_not_drift() {
    let mut st = s();
    st.steps_per_mm = [80.0, 80.0, 400.0, 177.777_78];
    let mut p = Planner::new();
    let mut total = [0u32; N_AXES];
    for i in 1..=1000 {
        let mm = i as f32 * 0.001;
        let t = [
            crate::math::round_i32(mm * st.steps_per_mm[0]),
            crate::math::round_i32(-mm * st.steps_per_mm[1]),
            crate::math::round_i32(mm * st.steps_per_mm[2]),
            0,
        ];
        p.push_line(t, 300.0, false, &st).unwrap();
        while let Some(b) = p.current_block() {
            for a in 0..N_AXES {
                total[a] += b.steps()[a];
            }
            p.discard_current_block();
        }
    }
    assert_eq!(p.position(), [80, -80, 400, 0]);
    assert_eq!(total, [80, 80, 400, 0]);
}

#[test]
fn cycle_reinitialize_restarts_the_executing_block_from_rest() {
    let mut p = Planner::new();
    for i in 1..=4 {
        p.push_line([i * 1000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    }
    // Prep has run half of the first block and is at full speed; it stops.
    {
        let b = p.current_block_mut().unwrap();
        b.millimeters = 5.0;
        b.max_delta_speed_sqr = 10.0 * (crate::F_CPU / b.dv_cycles);
        b.entry_speed_sqr = 2500.0;
    }
    p.take_exec_replanned();
    p.cycle_reinitialize();
    assert!(p.take_exec_replanned());
    assert_eq!(p.current_block().unwrap().entry_speed_sqr, 0.0);
    // The next block can only be entered as fast as 5 mm from rest allows.
    assert_close(p.exec_exit_speed_sqr(), 2500.0f32.min(2.0 * 1000.0 * 5.0), 1e-5);
    let want = brute_force_entries(&p);
    for (b, w) in blocks(&p).iter().zip(&want) {
        assert_close(b.entry_speed_sqr.max(1e-3), w.max(1e-3), 1e-4);
    }
}

#[test]
fn a_new_block_behind_the_executing_one_flags_a_replan() {
    let mut p = Planner::new();
    p.push_line([1000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    p.take_exec_replanned();
    p.push_line([2000, 0, 0, 0], 3000.0, false, &s()).unwrap();
    assert!(p.take_exec_replanned(), "the executing block's exit speed changed");
    assert!(!p.take_exec_replanned());
}

#[test]
fn backlash_inserts_a_take_up_block_on_reversal_only() {
    let mut st = s();
    st.backlash_mm = [0.05, 0.02, 0.0];
    let mut p = Planner::new();
    // First moves: directions unknown, no take-up.
    assert_eq!(p.push_line([100, 100, 100, 0], 600.0, false, &st).unwrap().queued, 1);
    // Same direction: none.
    assert_eq!(p.push_line([200, 200, 200, 0], 600.0, false, &st).unwrap().queued, 1);
    // X and Y and Z reverse: one take-up block for X (5 steps) and Y (2 steps);
    // Z has no backlash setting.
    let r = p.push_line([150, 100, 0, 0], 600.0, false, &st).unwrap();
    assert_eq!(r.queued, 2);
    let b = blocks(&p);
    let tu = b[2];
    assert!(tu.has(Block::TAKE_UP));
    assert_eq!(tu.steps(), [5, 2, 0, 0]);
    assert_eq!(tu.direction_bits(), 0b011);
    // Planned like any block: a sharp corner, entered at a crawl.
    assert!(tu.max_entry_speed_sqr < 25.0);
    assert_close(tu.nominal_speed_sqr.sqrt(), 50.0 * 0.05f32.hypot(0.02) / 0.05, 1e-5);
    assert!(!b[3].has(Block::TAKE_UP) && !b[3].has(Block::RAPID));
    assert_eq!(b[3].steps(), [50, 100, 200, 0]);
    assert_eq!(p.position(), [150, 100, 0, 0]);
    assert_eq!(p.backlash_offset_steps(), [-5, -2, 0]);
    // Y continues negative, X reverses back: +5 on X only.
    p.push_line([250, 50, 0, 0], 600.0, false, &st).unwrap();
    assert_eq!(p.backlash_offset_steps(), [0, -2, 0]);
    // set_position (after homing) makes motors and position agree again.
    while !p.is_empty() {
        p.discard_current_block();
    }
    p.set_position([0; 4]);
    assert_eq!(p.backlash_offset_steps(), [0, 0, 0]);
}

#[test]
fn a_reversal_needing_a_take_up_waits_for_two_free_slots() {
    let mut st = s();
    st.backlash_mm = [0.05, 0.0, 0.0];
    let mut p = Planner::new();
    for i in 1..BLOCK_BUFFER_LEN as i32 {
        p.push_line([i * 10, 0, 0, 0], 600.0, false, &st).unwrap();
    }
    assert_eq!(p.free(), 1);
    assert_eq!(p.push_line([0, 0, 0, 0], 600.0, false, &st), Err(PlanError::Full));
    assert_eq!(p.backlash_offset_steps(), [0, 0, 0]);
    p.discard_current_block();
    assert_eq!(p.push_line([0, 0, 0, 0], 600.0, false, &st).unwrap().queued, 2);
}

#[test]
fn clear_forgets_blocks_and_backlash_directions() {
    let mut st = s();
    st.backlash_mm = [0.05, 0.0, 0.0];
    let mut p = Planner::new();
    p.push_line([100, 0, 0, 0], 600.0, false, &st).unwrap();
    p.clear();
    assert!(p.is_empty() && p.current_block().is_none());
    p.set_position([100, 0, 0, 0]);
    // Direction unknown after clear: no take-up on the next reversal.
    assert_eq!(p.push_line([0, 0, 0, 0], 600.0, false, &st).unwrap().queued, 1);
    assert_eq!(p.current_block().unwrap().entry_speed_sqr, 0.0);
}

/// grbl's junction rule for a turn of `turn_deg` away from straight on.
fn junction_v2(turn_deg: f32, accel: f32, deviation: f32) -> f32 {
    // θ between the reversed first direction and the second: 180° − turn.
    let sin_half = ((180.0 - turn_deg).to_radians() / 2.0).sin();
    accel * deviation * sin_half / (1.0 - sin_half)
}

#[test]
fn the_junction_speed_follows_the_deviation_rule_at_every_angle_and_is_capped_by_the_feed() {
    let st = s();
    let mut last = f32::INFINITY;
    for turn in [5.0f32, 10.0, 30.0, 45.0, 60.0, 90.0, 120.0, 135.0, 150.0, 175.0] {
        let mut p = Planner::new();
        p.push_line([1000, 0, 0, 0], 3000.0, false, &st).unwrap();
        let (sin, cos) = turn.to_radians().sin_cos();
        let t = [1000 + crate::math::round_i32(1000.0 * cos), crate::math::round_i32(1000.0 * sin), 0, 0];
        p.push_line(t, 3000.0, false, &st).unwrap();
        let b = blocks(&p);
        // Both blocks accelerate at ≥ 1000 mm/s² along the path, so the
        // junction uses X's 1000 (a diagonal allows more: 1000 / max |u_i|).
        let mut want = junction_v2(turn, 1000.0, st.junction_deviation_mm).min(2500.0);
        if turn > 90.0 {
            // X reverses: its speed step is capped at REVERSAL_STEP_S × 1000 mm/s².
            let dv = REVERSAL_STEP_S * 1000.0 / (1.0 - cos);
            want = want.min(dv * dv);
        }
        // The integer target bends the direction by up to 0.03°.
        assert_close(b[1].max_entry_speed_sqr, want, 2e-3);
        assert!(b[1].max_entry_speed_sqr <= last, "{turn}°: sharper turns are slower");
        last = b[1].max_entry_speed_sqr;
        if turn <= 10.0 {
            assert_eq!(b[1].max_entry_speed_sqr, 2500.0, "{turn}°: capped at the feed (50 mm/s)");
        }
    }
}

#[test]
fn an_axis_reversing_at_a_junction_changes_speed_by_at_most_half_a_millisecond_of_its_acceleration() {
    let st = s();
    // The demo job's corner: +X from (10, 10) to (20, 10), then back toward
    // the origin (a 153° turn).
    let mut p = Planner::new();
    p.set_position([1000, 1000, 0, 0]);
    p.push_line([2000, 1000, 0, 0], 1200.0, false, &st).unwrap();
    p.push_line([0, 0, 0, 0], 1200.0, false, &st).unwrap();
    let b = blocks(&p);
    let (u0, u1) = (1.0f32, 2000.0 / 2000f32.hypot(1000.0));
    let v = b[1].max_entry_speed_sqr.sqrt();
    let step = v * (u0 + u1);
    assert!(step <= 0.5 * 1.0001, "X steps by {step} mm/s at the reversal");
    assert!(step >= 0.5 * 0.999, "the cap, not something slower: {step} mm/s");
    // Without a reversal (a 45° turn) the deviation rule alone decides.
    let mut p = Planner::new();
    p.push_line([1000, 0, 0, 0], 1200.0, false, &st).unwrap();
    p.push_line([2000, 1000, 0, 0], 1200.0, false, &st).unwrap();
    let want = junction_v2(45.0, 1000.0, st.junction_deviation_mm);
    assert_close(blocks(&p)[1].max_entry_speed_sqr, want, 2e-3);
}

#[test]
fn a_junction_is_never_faster_than_the_slower_of_its_two_blocks() {
    let st = s();
    let mut p = Planner::new();
    p.push_line([2000, 0, 0, 0], 3000.0, false, &st).unwrap();
    p.push_line([4000, 0, 0, 0], 600.0, false, &st).unwrap();
    p.push_line([6000, 0, 0, 0], 3000.0, false, &st).unwrap();
    let b = blocks(&p);
    // Straight on: only the nominal speeds limit the junctions, 10 mm/s each.
    assert_close(b[1].max_entry_speed_sqr, 100.0, 1e-5);
    assert_close(b[2].max_entry_speed_sqr, 100.0, 1e-5);
    assert_close(b[1].entry_speed_sqr, 100.0, 1e-5);
    assert_close(b[2].entry_speed_sqr, 100.0, 1e-5);
}

#[test]
fn a_block_too_short_to_stop_in_lowers_the_entry_of_the_blocks_before_it() {
    let st = s();
    let mut p = Planner::new();
    // 20 mm, then four 0.1 mm blocks to a stop: the last 0.4 mm can shed only
    // 2·a·d = 800 (mm/s)², so the first junction is entered at √800 mm/s.
    p.push_line([2000, 0, 0, 0], 3000.0, false, &st).unwrap();
    for i in 1..=4 {
        p.push_line([2000 + 10 * i, 0, 0, 0], 3000.0, false, &st).unwrap();
    }
    let e: Vec<f32> = blocks(&p).iter().map(|b| b.entry_speed_sqr).collect();
    for (k, want) in [800.0f32, 600.0, 400.0, 200.0].iter().enumerate() {
        assert_close(e[k + 1], *want, 1e-4);
    }
    // One more block makes room: every entry rises by 200 (mm/s)².
    p.push_line([2050, 0, 0, 0], 3000.0, false, &st).unwrap();
    let e: Vec<f32> = blocks(&p).iter().map(|b| b.entry_speed_sqr).collect();
    assert_close(e[1], 1000.0, 1e-4);
    assert_close(e[5], 200.0, 1e-4);
}

/// Speed profile of planner block `index` (0-based) of `moves`, as prep cuts
/// it: (distance from the block start at the segment's middle, mm; speed, mm/s).
fn block_profile(moves: &[([i32; N_AXES], f32)], index: usize, st: &Settings) -> Vec<(f32, f32)> {
    use crate::stepper::{Prep, StepperCmd};
    let mut p = Planner::new();
    for &(t, f) in moves {
        p.push_line(t, f, false, st).unwrap();
    }
    let mut prep = Prep::new();
    let mut block = usize::MAX;
    let mut ticks = 0u32;
    let mut out = Vec::new();
    while let Some(cmd) = prep.next_segment(&mut p) {
        match cmd {
            StepperCmd::Block(_) => {
                block = block.wrapping_add(1);
                ticks = 0;
            }
            StepperCmd::Run(seg) if block == index => {
                let mid = (ticks as f32 + seg.ticks as f32 / 2.0) / st.steps_per_mm[0];
                out.push((mid, seg.rate_hz() / st.steps_per_mm[0]));
                ticks += seg.ticks as u32;
            }
            StepperCmd::Run(_) => {}
        }
    }
    out
}

#[test]
fn a_block_between_slower_ones_is_a_trapezoid_from_entry_to_feed_to_exit() {
    let st = s();
    // 10 mm at 10 mm/s, 20 mm at 50 mm/s, 10 mm at 10 mm/s, all along X.
    let moves = [([1000, 0, 0, 0], 600.0), ([3000, 0, 0, 0], 3000.0), ([4000, 0, 0, 0], 600.0)];
    let prof = block_profile(&moves, 1, &st);
    let a = 1000.0f32;
    let (v_in, v_nom, v_out, len) = (10.0f32, 50.0f32, 10.0f32, 20.0f32);
    // Ramps of (50² − 10²)/(2a) = 1.2 mm at each end, 17.6 mm of cruise.
    let ramp = (v_nom * v_nom - v_in * v_in) / (2.0 * a);
    let first = prof.first().unwrap().1;
    let last = prof.last().unwrap().1;
    assert!((first - v_in).abs() < 5.0 && first >= v_in, "starts at the entry speed: {first}");
    assert!((last - v_out).abs() < 5.0 && last >= v_out * 0.9, "ends at the exit speed: {last}");
    for &(d, v) in &prof {
        // Never above the trapezoid (one 5 ms segment of a·T = 5 mm/s slack).
        let up = (v_in * v_in + 2.0 * a * d).sqrt();
        let down = (v_out * v_out + 2.0 * a * (len - d)).sqrt();
        assert!(v <= up.min(down).min(v_nom) + 2.5, "{v} mm/s at {d} mm");
    }
    let cruise: f32 = {
        let mut covered = 0.0;
        for w in prof.windows(2) {
            if (w[0].1 - v_nom).abs() < 0.05 * v_nom {
                covered += w[1].0 - w[0].0;
            }
        }
        covered
    };
    assert!((cruise - (len - 2.0 * ramp)).abs() < 0.6, "cruise {cruise} mm, want {}", len - 2.0 * ramp);
    // The same block on its own is a symmetric trapezoid from and to rest.
    let alone = block_profile(&[([2000, 0, 0, 0], 3000.0)], 0, &st);
    assert!(alone.first().unwrap().1 < 10.0 && alone.last().unwrap().1 < 10.0);
}

#[test]
fn an_accepted_feed_move_is_planned_on_flush_and_settle_exactly_as_push_line_plans_it() {
    let st = s();
    let (mut a, mut b) = (Planner::new(), Planner::new());
    for k in 1..=12i32 {
        let t = [k * 37, k * k * 5, 0, 0];
        a.push_line(t, 3000.0, false, &st).unwrap();
        assert_eq!(b.accept_line(&t, Speed::Feed(3000.0), &st).unwrap().queued, 1);
        // The pending move holds its slot and the position already moved.
        assert_eq!((b.len(), b.position()), (a.len(), a.position()));
    }
    b.flush(&st);
    // Accepted moves wait for the look-ahead until prep settles the ring.
    b.settle();
    assert_eq!(blocks(&a), blocks(&b));
    // Rapids and E moves are planned at once (they may be rate-capped).
    b.accept_line(&[0, 0, 0, 0], Speed::Rapid, &st).unwrap();
    assert_eq!(blocks(&b).len(), 13);
    b.accept_line(&[0, 0, 0, 100], Speed::Feed(600.0), &st).unwrap();
    assert_eq!(blocks(&b).len(), 14);
    b.clear();
    assert!(b.is_empty());
}

#[test]
fn a_move_at_one_steps_per_mm_gets_its_length_from_the_cached_root() {
    // X, Y, Z share 100 steps/mm: lengths come from √(Σd²) (cached).
    let st = s();
    let mut p = Planner::new();
    let mut at = [0i32; 4];
    for &(dx, dy, dz) in &[(10, 0, 0), (8, 6, 0), (6, 8, 0), (10, 0, 0), (3, 4, 12), (-7, 9, 0)] {
        at = [at[0] + dx, at[1] + dy, at[2] + dz, 0];
        p.push_line(at, 3000.0, false, &st).unwrap();
        let b = p.block(p.len() - 1).unwrap();
        let want = (((dx * dx + dy * dy + dz * dz) as f64).sqrt() / 100.0) as f32;
        assert_close(b.millimeters, want, 1e-6);
    }
}

/// A path of chords, corners and a rapid, in steps (X Y Z E): feed moves
/// at `feed`, one rapid, one fixed-feed move.
fn override_path() -> Vec<([i32; N_AXES], Speed)> {
    let mut v = Vec::new();
    let mut rng = 0x2545_F491u32;
    let mut p = [0i32; N_AXES];
    for i in 0..14 {
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        p[0] += 50 + (rng % 400) as i32;
        p[1] += (rng >> 8) as i32 % 300 - 150;
        p[2] += if i % 5 == 0 { 40 } else { 0 };
        let speed = match i {
            3 => Speed::Rapid,
            9 => Speed::Fixed(900.0),
            _ => Speed::Feed(1200.0 + 100.0 * (i % 4) as f32),
        };
        v.push((p, speed));
    }
    v
}

fn planned_with(pct: u16, rapid: u8) -> Planner {
    let mut p = Planner::new();
    p.set_overrides(pct, rapid, &s());
    for (t, sp) in override_path() {
        p.push_move(t, sp, &s()).unwrap();
    }
    p
}

#[test]
fn an_override_re_plans_the_queued_moves_as_if_they_had_been_queued_under_it() {
    for (pct, rapid) in [(150, 100), (10, 25), (200, 50), (37, 100)] {
        let mut p = planned_with(100, 100);
        p.set_overrides(pct, rapid, &s());
        let fresh = planned_with(pct, rapid);
        let (a, b) = (blocks(&p), blocks(&fresh));
        assert_eq!(a.len(), b.len());
        for (i, (x, y)) in a.iter().zip(&b).enumerate() {
            assert_close(x.nominal_speed_sqr, y.nominal_speed_sqr, 1e-4);
            if i > 0 {
                assert_close(x.max_entry_speed_sqr, y.max_entry_speed_sqr, 1e-3);
                assert_close(x.entry_speed_sqr, y.entry_speed_sqr, 1e-3);
            }
        }
        assert!(p.take_exec_replanned(), "prep recomputes the executing block");
        // The look-ahead is the optimal plan.
        let want = brute_force_entries(&p);
        for (x, w) in blocks(&p).iter().zip(&want) {
            assert_close(x.entry_speed_sqr, *w, 1e-3);
        }
        // And back to 100 %: the plan queued without an override.
        p.set_overrides(100, 100, &s());
        for (x, y) in blocks(&p).iter().zip(&blocks(&planned_with(100, 100))).skip(1) {
            assert_close(x.nominal_speed_sqr, y.nominal_speed_sqr, 1e-4);
            assert_close(x.entry_speed_sqr, y.entry_speed_sqr, 1e-3);
        }
    }
}

#[test]
fn the_feed_override_scales_feeds_the_rapid_override_rapids_and_fixed_feeds_stay() {
    let base = blocks(&planned_with(100, 100));
    let mut p = planned_with(100, 100);
    p.set_overrides(50, 25, &s());
    let b = blocks(&p);
    let path = override_path();
    for i in 0..b.len() {
        let ratio = (b[i].nominal_speed_sqr / base[i].nominal_speed_sqr).sqrt();
        let want = match path[i].1 {
            Speed::Feed(_) => 0.5,
            Speed::Rapid => 0.25,
            Speed::Fixed(_) => 1.0,
        };
        assert_close(ratio, want, 1e-4);
    }
    // Faster than the axes allow: held at their limit (3000 mm/min), and a
    // rapid at 100 % is exactly that limit.
    let mut q = Planner::new();
    q.push_move([3000, 0, 0, 0], Speed::Feed(2500.0), &s()).unwrap();
    q.push_move([6000, 0, 0, 0], Speed::Rapid, &s()).unwrap();
    q.set_overrides(200, 100, &s());
    let b = blocks(&q);
    assert_close(b[0].nominal_speed_sqr, 2500.0, 1e-5);
    assert_close(b[1].nominal_speed_sqr, 2500.0, 1e-5);
    q.set_overrides(50, 50, &s());
    let b = blocks(&q);
    assert_close(b[0].nominal_speed_sqr, (2500.0f32 / 120.0).powi(2), 1e-4);
    assert_close(b[1].nominal_speed_sqr, 625.0, 1e-5);
}

/// A ring as a stream leaves it before a look-ahead pass: moves accepted
/// (not yet planned) at `feed`, the executing block part done at some
/// speed or dropped, as the random number `r` picks.
fn drive_ring(p: &mut Planner, pos: &mut [i32; N_AXES], r: u32, feed: f32, st: &Settings) {
    match r % 16 {
        // Prep finished the executing block.
        0..=2 if p.len() > 1 => p.discard_current_block(),
        // Prep is part way through it, at some speed (a feed hold or a
        // slow start leaves it below what the plan had).
        3 => {
            if let Some(b) = p.current_block_mut() {
                b.entry_speed_sqr = b.nominal_speed_sqr * ((r >> 8) % 101) as f32 / 100.0;
                b.millimeters *= ((r >> 16) % 100) as f32 / 100.0;
                b.max_delta_speed_sqr = 2.0 * b.millimeters * (crate::F_CPU / b.dv_cycles);
            }
        }
        _ if !p.is_full() => queue_stream_move(p, pos, (r >> 4) % 8, r, feed, st),
        _ => {}
    }
}

/// Queue (accept and plan) the next move of a random stream from `pos`:
/// kind 0 a long move in any direction (from `r`), 1 a turn, any other a
/// 0.1 mm chord of a circle (mostly, so the ring becomes one deceleration
/// ramp at the higher feeds).
fn queue_stream_move(p: &mut Planner, pos: &mut [i32; N_AXES], kind: u32, r: u32, feed: f32, st: &Settings) {
    let (dx, dy) = match kind {
        0 => (((r >> 8) % 2001) as i32 - 1000, ((r >> 12) % 2001) as i32 - 1000),
        1 => (-(pos[0] % 40), 8),
        _ => (8 - (pos[1] / 50) % 3, 3 + (pos[0] / 70) % 3),
    };
    pos[0] += dx;
    pos[1] += dy;
    p.accept_line(pos, Speed::Feed(feed), st).unwrap();
    p.flush(st);
}

#[test]
fn the_look_ahead_without_an_idle_forward_pass_plans_as_both_passes_do() {
    let st = s();
    let mut p = Planner::new();
    let mut pos = [0i32; N_AXES];
    let mut rng = crate::test_util::XorShift(99);
    let mut passes = 0;
    let mut longest = 0;
    let mut worst = 0.0f64;
    for i in 0..20_000 {
        let seed = rng.next();
        // Runs of a few hundred moves at one feed: at the higher ones the
        // whole ring is a deceleration ramp.
        let feed = [3300.0, 600.0, 5000.0, 1800.0, 20.0][(i / 700) % 5];
        drive_ring(&mut p, &mut pos, seed, feed, &st);
        if !(seed >> 24).is_multiple_of(3) {
            continue;
        }
        let span = (p.head as usize + BLOCK_BUFFER_LEN - 1 - p.planned as usize) % BLOCK_BUFFER_LEN;
        longest = longest.max(span);
        let mut plain = p.clone();
        plain.recalculate_plain();
        p.recalculate();
        passes += 1;
        assert_eq!(p.planned, plain.planned, "step {i}: planned");
        assert_eq!(p.exec_replanned, plain.exec_replanned, "step {i}: replanned flag");
        for k in 0..p.len() {
            let (a, b) = (p.block(k).unwrap(), plain.block(k).unwrap());
            let (x, y) = (a.entry_speed_sqr as f64, b.entry_speed_sqr as f64);
            worst = worst.max((x - y).abs() / y.max(1e-3));
            assert!((x - y).abs() <= 1e-4 * y + 1e-6, "step {i} block {k}: {a:?} vs {b:?}");
        }
    }
    // Long deceleration ramps were covered (the ring is at least 16).
    assert!(passes > 5000 && longest >= 14, "{passes} passes, at most {longest} blocks after `planned`");
    println!("worst relative difference {worst:e}");
}

#[test]
fn the_junction_cosine_summed_then_negated_is_grbls_subtraction_from_zero() {
    use super::junction::{cos_theta, cos_theta_plain};
    let mut rng = crate::test_util::XorShift(12_345);
    let mut next = move || rng.next();
    let (mut nonzero, mut zero) = (0, 0);
    for k in 0..200_000 {
        // Components from a few steps (exact repeats, opposite and zero
        // ones) and from random floats, on random axes.
        let comp = |r: u32| -> f32 {
            match r % 4 {
                0 => 0.0,
                1 => ((r >> 4) % 9) as f32 / 8.0 - 0.5,
                _ => f32::from_bits(0x3C00_0000 + (r >> 8) % 0x0380_0000) * if r & 0x80 != 0 { -1.0 } else { 1.0 },
            }
        };
        let p = [comp(next()), comp(next()), comp(next()), comp(next())];
        let mut u = [comp(next()), comp(next()), comp(next()), comp(next())];
        if k % 5 == 0 {
            // Perpendicular: the products cancel exactly.
            u = [p[1], -p[0], 0.0, 0.0];
        }
        let moving = (next() % 16) as u8;
        let (fast, plain) = (cos_theta(&p, &u, moving), cos_theta_plain(&p, &u, moving));
        if plain == 0.0 {
            // Only the sign of an exact zero may differ.
            assert_eq!(fast, 0.0, "{p:?} · {u:?} on {moving:#b}");
            zero += 1;
        } else {
            assert_eq!(fast.to_bits(), plain.to_bits(), "{p:?} · {u:?} on {moving:#b}");
            nonzero += 1;
        }
    }
    assert!(zero > 1000 && nonzero > 100_000, "{zero} zero, {nonzero} not");
}

/// The junction cosine of two short moves from their deltas
/// ([`junction::short_cos`]) is the plain cosine of the unit vectors
/// `queue_block` would make from them ([`junction::short_unit`]), within
/// 2⁻²¹ (grbl's straight-line limit is 10⁻⁶ from ±1), and the same when
/// the moves are perpendicular; random deltas of 1 to 2¹⁴ − 1 steps,
/// either sign, some axes still, exact repeats and reversals.
#[test]
fn the_cosine_from_the_deltas_is_the_cosine_from_the_unit_vectors() {
    use super::junction::{cos_theta_plain, short_cos, short_unit};
    let mut rng = crate::test_util::XorShift(2_718);
    let mut next = move || rng.next();
    let mut worst = 0.0f64;
    for k in 0..200_000 {
        let range = if k % 2 == 0 { 40 } else { 0x4000 };
        let mut delta = || {
            let r = next();
            let v = (r >> 8) as i32 % range;
            (if r & 1 != 0 { -v } else { v }) as i16
        };
        let pd = [delta(), delta(), delta()];
        let mut d = [delta(), delta(), delta()];
        match k % 7 {
            0 => d = pd,
            1 => d = pd.map(|x| -x),
            2 => d = [pd[1], -pd[0], 0],
            _ => {}
        }
        if pd == [0; 3] || d == [0; 3] {
            continue;
        }
        let inv = |d: [i16; 3]| 1.0 / crate::math::sqrtf(d.iter().map(|&x| (x as i32 * x as i32) as u32).sum::<u32>() as f32);
        let (ir, pir) = (inv(d), inv(pd));
        let moving = (0..3).fold(0u8, |m, i| if d[i] != 0 { m | 1 << i } else { m });
        let wide = |d: [i16; 3]| [d[0] as i32, d[1] as i32, d[2] as i32, 0];
        let fast = short_cos(&wide(d), ir, &pd, pir);
        let plain = cos_theta_plain(&short_unit(&wide(pd), pir), &short_unit(&wide(d), ir), moving);
        let diff = (fast as f64 - plain as f64).abs();
        worst = worst.max(diff);
        assert!(diff <= 1.0 / (1u32 << 21) as f64, "{pd:?} → {d:?}: {fast} vs {plain}");
        if k % 7 == 2 {
            assert_eq!(fast, 0.0, "{pd:?} → {d:?}: perpendicular");
        }
    }
    println!("worst {worst:e}");
}

/// The junction's reversing axes from the moving axes and directions the
/// planner keeps ([`junction::reversing`]) are what the plain reading of
/// the two unit vectors gives ([`junction::reversing_plain`]), on random
/// moves of one to four axes, short and long (both of `queue_block`'s
/// unit-vector routes), either sign, E included.
#[test]
fn reversing_from_the_bits_is_reversing_from_the_units() {
    use super::junction::{reversing, reversing_plain};
    let mut rng = crate::test_util::XorShift(777);
    let st = s();
    let mut p = Planner::new();
    let mut target = [0i32; N_AXES];
    let (mut some, mut none) = (0, 0);
    for k in 0..20_000 {
        for a in 0..N_AXES {
            let r = rng.next();
            let reach = if k % 3 == 0 { 5_000 } else { 40 };
            target[a] = match r % 3 {
                0 => target[a],
                _ => ((r >> 8) % (2 * reach + 1)) as i32 - reach as i32,
            };
        }
        let (before_axes, before_unit) = (p.previous_axes, p.previous_unit());
        let queued = p.push_line(target, 3000.0, k % 7 == 0, &st).unwrap().queued;
        if p.len as usize == BLOCK_BUFFER_LEN {
            p.clear();
            p.set_position(target);
            continue;
        }
        if queued != 1 {
            continue;
        }
        let (fast, plain) = (reversing(before_axes, p.previous_axes), reversing_plain(&before_unit, &p.previous_unit()));
        assert_eq!(fast, plain, "move {k}: {before_unit:?} → {:?}", p.previous_unit());
        if plain != 0 {
            some += 1;
        } else {
            none += 1;
        }
    }
    assert!(some > 2000 && none > 2000, "{some} reversing, {none} not");
}

/// The short-move cache ([`ring::Short`]) against the values computed
/// without it (square root, division, the unit vector's largest component,
/// a₀·√S·(1/n) or a₀/|u|max): bit for bit, on its hits and its misses
/// (moves of up to 40 steps in random order, so that entries collide and
/// are replaced), and after the settings change (an entry of the old
/// acceleration must not be used).
#[test]
fn a_cached_short_move_is_planned_as_computed() {
    let mut rng = crate::test_util::XorShift(4242);
    let mut st = s();
    let mut p = Planner::new();
    let mut pos = [0i32; N_AXES];
    let (mut repeats, mut checked) = (0, 0);
    let mut seen = std::collections::HashSet::new();
    let mut pool = [[0i32; 3]; 12];
    let mut last = [0i32; 3];
    for (j, m) in pool.iter_mut().enumerate() {
        // Up to 40 steps (the reciprocal table ends at 16), some without Z.
        *m = [(rng.next() % 40) as i32 + 1, (rng.next() % 41) as i32, if j % 3 == 0 { 0 } else { (rng.next() % 20) as i32 }];
    }
    // One Σd² for two moves of different dominant steps (5 and 4).
    (pool[0], pool[1]) = ([5, 0, 0], [3, 4, 0]);
    for k in 0..20_000 {
        if k == 10_000 {
            st.accel_mm_per_s2 = [1700.0, 1700.0, 1700.0, st.accel_mm_per_s2[3]];
            st.max_feed_mm_per_min = [4200.0, 4200.0, 4200.0, st.max_feed_mm_per_min[3]];
            seen.clear();
        }
        // From a pool of 12 moves, signs at random: a third of them hit;
        // right after the settings change the last move again (its entry
        // is cached, with the old limits).
        let r = rng.next();
        let mut d = pool[(r % 12) as usize];
        for (i, x) in d.iter_mut().enumerate() {
            if r >> (8 + i) & 1 != 0 {
                *x = -*x;
            }
        }
        if k == 10_000 {
            d = last;
        }
        last = d;
        if p.is_full() {
            p.discard_current_block();
        }
        for i in 0..3 {
            pos[i] += d[i];
        }
        // Feeds above the axes' limit: the per-axis limit sets the speed.
        p.push_line(pos, 1.0e5, false, &st).unwrap();
        let b = p.block(p.len() - 1).unwrap();
        let sum = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) as u32;
        let n = d.iter().map(|x| x.unsigned_abs()).max().unwrap();
        let root = crate::math::sqrtf(sum as f32);
        let inv_root = 1.0 / root;
        let mm = root * (1.0 / st.steps_per_mm[0]);
        let mut u_max = 0.0f32;
        for x in d {
            u_max = u_max.max((x as f32 * inv_root).abs());
        }
        let accel = match crate::math::recip_small(n) {
            Some(r) => st.accel_mm_per_s2[0] * root * r,
            None => 1.0 / (u_max * (1.0 / st.accel_mm_per_s2[0])),
        };
        let v = 1.0 / (u_max * (60.0 / st.max_feed_mm_per_min[0]));
        let what = format!("move {k} {d:?}");
        assert_eq!(b.millimeters.to_bits(), mm.to_bits(), "{what}: mm");
        if !seen.insert((sum, n)) {
            repeats += 1;
        }
        let dv_cycles = u_max * (1.0 / st.accel_mm_per_s2[0]) * crate::F_CPU;
        assert_eq!(b.dv_cycles.to_bits(), dv_cycles.to_bits(), "{what}: F_CPU / acceleration");
        assert_eq!(b.nominal_speed_sqr.to_bits(), (v * v).to_bits(), "{what}: nominal");
        assert_eq!(b.max_delta_speed_sqr.to_bits(), (2.0 * (accel * mm)).to_bits(), "{what}: 2·a·mm");
        checked += 1;
    }
    assert!(repeats > 19_000 && checked == 20_000, "{repeats} repeated moves, {checked} checked");
}

/// Prep drops a block it ran in one segment with the exit speed² it read
/// (`Planner::discard_current_block_at`): the ring is left as the plain
/// discard leaves it, bit for bit, at every drop of streams of short
/// moves at feeds where the ring is one deceleration ramp (whose front
/// block is then entered at its entry plus the ramp's lift), and of
/// longer and turning moves between.
#[test]
fn an_exit_given_back_is_the_exit_computed() {
    let st = s();
    let mut p = Planner::new();
    let mut pos = [0i32; N_AXES];
    let mut rng = crate::test_util::XorShift(0xD15C);
    let mut ramps = 0;
    for i in 0..40_000 {
        let r = rng.next();
        let feed = [3300.0, 600.0, 5000.0, 1800.0, 12000.0][(i / 900) % 5];
        // Queue while the ring has room, drop about as often (prep).
        if r % 8 < 4 && !p.is_full() {
            queue_stream_move(&mut p, &mut pos, (r >> 4) % 16, r, feed, &st);
        } else if p.len() > 1 {
            // As prep does: settle, read the exit, drop the block.
            p.settle();
            ramps += (p.planned == p.tail && p.ramp_end != p.planned) as u32;
            let mut plain = p.clone();
            plain.discard_current_block();
            let exit = p.exec_exit_speed_sqr();
            p.discard_current_block_at(Some(exit));
            assert_eq!(
                (p.planned, p.ramp_end, p.ramp_ok, p.lift.to_bits()),
                (plain.planned, plain.ramp_end, plain.ramp_ok, plain.lift.to_bits()),
                "step {i}"
            );
            for k in 0..p.len() {
                let (a, b) = (p.block(k).unwrap(), plain.block(k).unwrap());
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "step {i} block {k}");
                assert_eq!(a.entry_speed_sqr.to_bits(), b.entry_speed_sqr.to_bits(), "step {i} block {k}");
            }
        }
    }
    assert!(ramps > 500, "{ramps} drops at the front of a ramp");
}
