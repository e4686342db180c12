//! The benchmark's motion limit (`sim::ceiling`, `tools/bench`'s *motion
//! limit* column) against this firmware's planner: the model is an f64
//! reimplementation of grbl's planner rules that shares no code with the
//! planner, and the bench's claim that the in-flight and SD rows run at
//! the job's limit rests on the two agreeing.

use mill::config::Settings;
use mill::planner::{Planner, BLOCK_BUFFER_LEN};
use mill::N_AXES;

/// The model's joints are this planner's: the maximum entry speed of every
/// joint of the side-by-side job at its settings (100 steps/mm, 1000
/// mm/s², the X/Y rate at F6000) is the model's within 1 %, so the bench's
/// column is this planner's limit. The job goes through the planner in
/// windows of a ring's worth.
#[test]
fn the_bench_motion_limit_has_this_planners_junction_speeds() {
    let (feed, accel) = (6000.0f32, 1000.0f32);
    let mut s = Settings::default();
    s.steps_per_mm = [100.0; N_AXES];
    s.max_feed_mm_per_min[0] = feed;
    s.max_feed_mm_per_min[1] = feed;
    s.accel_mm_per_s2[0] = accel;
    s.accel_mm_per_s2[1] = accel;
    let joints = sim::ceiling::step_joints(feed as f64, accel as f64);
    let window = BLOCK_BUFFER_LEN - 2;
    let mut checked = 0;
    let (x0, y0) = sim::circle::point(0);
    let mut start = [sim::ceiling::steps(x0), sim::ceiling::steps(y0)];
    for (w, chunk) in joints.chunks(window).enumerate() {
        let mut pl = Planner::new();
        pl.set_position([start[0], start[1], 0, 0]);
        for (end, _) in chunk {
            pl.push_line([end[0], end[1], 0, 0], feed, false, &s).unwrap();
        }
        pl.flush(&s);
        // Each window's first block starts from rest here: its joint (one
        // in 32) is left unchecked.
        for (i, (_, want)) in chunk.iter().enumerate().skip(1) {
            let got = pl.block(i).unwrap().max_entry_speed_sqr as f64;
            assert!((got - want).abs() <= 0.01 * want, "chord {}: {got} vs the model's {want} (mm/s)²", w * window + i + 1);
            checked += 1;
        }
        start = chunk[chunk.len() - 1].0;
    }
    assert!(checked > 1900, "{checked}");
}

/// The model's look-ahead (`sim::ceiling::RING_AHEAD`, what `tools/bench`
/// prints the look-ahead-bound limit for) is this planner's: a full ring
/// less the running block.
#[test]
fn the_bench_look_ahead_is_this_planners_ring() {
    assert_eq!(sim::ceiling::RING_AHEAD, BLOCK_BUFFER_LEN - 1);
}
