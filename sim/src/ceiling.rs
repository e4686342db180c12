//! The motion limit of the side-by-side job: the fastest any firmware can
//! run the circle's 2,000 chords under grbl's planner rules, with unbounded
//! look-ahead and an infinitely fast CPU. Each chord runs the trapezoid the
//! time-optimal plan gives it (a backward and a forward pass over the whole
//! job, not a ring), with grbl's junction deviation at each joint and the
//! per-axis speed and acceleration limits; the rate is counted over the
//! middle half of the job by time, as the measured rows are.
//!
//! The joints' directions come from the chords' step deltas, as grbl's
//! `plan_buffer_line`, Marlin's planner and this firmware all take them.
//! Rounding each chord's ends to whole steps (10 steps a chord at 100
//! steps/mm) turns it by up to several degrees, so the joints of a smooth
//! circle are corners of a few degrees whose junction speeds hold the tool
//! below the feed: that, not the look-ahead or the CPU, is what keeps the
//! F6000 rows near 790/s. [`Path::Commanded`] takes the directions from
//! the programmed (unrounded) chords instead, as LinuxCNC plans them.
//!
//! An f64 model of its own: it shares no code with the firmware's planner.
//! It leaves out the firmware's cap on an axis' speed step where the axis
//! reverses (`planner::junction::REVERSAL_STEP_S`), which does not bind on
//! this circle: `tests/motion_limit.rs` holds the two to each other.

use crate::circle;

/// Where a joint's directions come from.
#[derive(Clone, Copy)]
pub enum Path {
    /// The chords' step deltas (grbl, Marlin, this firmware).
    Steps,
    /// The programmed chords, in mm, before rounding to steps.
    Commanded,
}

/// The job's settings on both firmwares (`tools/bench`'s `side::boot`).
const STEPS_PER_MM: f64 = 100.0;
/// grbl's `$11` and this firmware's default junction deviation, mm.
const JUNCTION_DEVIATION_MM: f64 = 0.01;

/// One chord of the job: its length (mm), unit vector, acceleration
/// (mm/s²) and nominal speed (mm/s).
struct Chord {
    len: f64,
    unit: [f64; 2],
    accel: f64,
    nominal: f64,
}

impl Chord {
    /// The speed² the chord's acceleration gains or sheds over its length,
    /// (mm/s)².
    fn reach(&self) -> f64 {
        2.0 * self.accel * self.len
    }
}

/// The job's point `k` (0: the start) as the planner sees it, mm.
fn point(k: usize, path: Path) -> [f64; 2] {
    let (x, y) = circle::point(k);
    match path {
        Path::Steps => [f64::from(steps(x)) / STEPS_PER_MM, f64::from(steps(y)) / STEPS_PER_MM],
        Path::Commanded => [x, y],
    }
}

/// The whole steps of `mm` at the job's steps/mm, as grbl's `lround(target
/// * steps_per_mm)` on the AVR's 32-bit floats and this firmware's
/// `units::to_steps` round it.
pub fn steps(mm: f64) -> i32 {
    ((mm as f32) * STEPS_PER_MM as f32).round() as i32
}

/// The chords at `feed` mm/min and `accel` mm/s² on X and Y, the X/Y rate
/// limit raised to the feed (as `tools/bench` sets it).
fn chords(feed: f64, accel: f64, path: Path) -> Vec<Chord> {
    let nominal = feed / 60.0;
    let axis_rate = nominal.max(50.0);
    (1..=circle::MOVES)
        .map(|k| {
            let (a, b) = (point(k - 1, path), point(k, path));
            let d = [b[0] - a[0], b[1] - a[1]];
            let len = d[0].hypot(d[1]);
            let unit = [d[0] / len, d[1] / len];
            let limit = |per_axis: f64| unit.iter().filter(|c| **c != 0.0).map(|c| per_axis / c.abs()).fold(f64::INFINITY, f64::min);
            Chord { len, unit, accel: limit(accel), nominal: nominal.min(limit(axis_rate)) }
        })
        .collect()
}

/// The entry speed² each chord's start allows, (mm/s)²: 0 for the first,
/// then grbl's junction deviation at each joint, at most the smaller
/// nominal speed² of its two chords.
fn joint_limits(c: &[Chord]) -> Vec<f64> {
    let mut entry = vec![0.0f64; c.len()];
    for k in 1..c.len() {
        let (p, u) = (&c[k - 1], &c[k]);
        let cos = -(p.unit[0] * u.unit[0] + p.unit[1] * u.unit[1]);
        let junction = if cos > 0.999_999 {
            0.0
        } else if cos < -0.999_999 {
            f64::INFINITY
        } else {
            let s = (0.5 * (1.0 - cos)).sqrt();
            p.accel.min(u.accel) * JUNCTION_DEVIATION_MM * s / (1.0 - s)
        };
        entry[k] = junction.min(p.nominal.min(u.nominal).powi(2));
    }
    entry
}

/// [`joint_limits`] of the job at `feed` and `accel`, joints from the
/// step deltas, with each chord's end in steps: what a planner following
/// grbl's rules must give as the chords' maximum entry speeds².
pub fn step_joints(feed: f64, accel: f64) -> Vec<([i32; 2], f64)> {
    let limits = joint_limits(&chords(feed, accel, Path::Steps));
    (1..=circle::MOVES)
        .map(|k| {
            let (x, y) = circle::point(k);
            [steps(x), steps(y)]
        })
        .zip(limits)
        .collect()
}

/// Lines per second over the middle half of the circle job at `feed`
/// mm/min and `accel` mm/s² on X and Y (the X/Y rate limit raised to the
/// feed, as `tools/bench` sets it), under grbl's planner rules.
pub fn lines_per_s(feed: f64, accel: f64, path: Path) -> f64 {
    let c = chords(feed, accel, path);
    let n = c.len();
    let mut entry = joint_limits(&c);
    entry.push(0.0);
    // Time-optimal: what the joint allows, reachable from both ends.
    for k in (0..n).rev() {
        entry[k] = entry[k].min(entry[k + 1] + c[k].reach());
    }
    for k in 0..n {
        entry[k + 1] = entry[k + 1].min(entry[k] + c[k].reach());
    }
    middle_rate(&c, &entry)
}

/// Chords the firmware's planner holds ahead of the running one while a
/// host keeps its ring full: `planner::BLOCK_BUFFER_LEN` − 1
/// (`tests/motion_limit.rs` holds the two together).
pub const RING_AHEAD: usize = 33;

/// The longest look-ahead [`ahead_for`] tries, chords.
pub const MAX_AHEAD: usize = 200;

/// The fewest chords ahead with which the job reaches `rate` lines/s
/// with joints from `path` (`None`: not with [`MAX_AHEAD`]).
pub fn ahead_for(feed: f64, accel: f64, path: Path, rate: f64) -> Option<usize> {
    (1..=MAX_AHEAD).find(|&a| lines_per_s_ahead(feed, accel, path, a) >= rate)
}

/// [`lines_per_s`] with a look-ahead of `ahead` chords, as a streaming
/// firmware plans: while a chord runs, the planner holds it and the next
/// `ahead` (the host keeps the ring full), the newest of them must be able
/// to stop at its end, and the running chord leaves at the speed that
/// plan allows. A ring of n blocks has n − 1 ahead of the running one.
pub fn lines_per_s_ahead(feed: f64, accel: f64, path: Path, ahead: usize) -> f64 {
    let c = chords(feed, accel, path);
    let n = c.len();
    let joint = joint_limits(&c);
    let mut speed = vec![0.0f64; n + 1];
    for k in 0..n {
        // Backward from a stop at the end of the newest chord queued.
        let newest = (k + ahead).min(n - 1);
        let mut e = 0.0f64;
        for j in (k + 1..=newest).rev() {
            e = joint[j].min(e + c[j].reach());
        }
        speed[k + 1] = e.min(speed[k] + c[k].reach());
    }
    middle_rate(&c, &speed)
}

/// Lines per second over the middle half of the job by time, each chord
/// along its trapezoid (or triangle) from entry speed² `entry[k]` to
/// `entry[k + 1]`.
fn middle_rate(c: &[Chord], entry: &[f64]) -> f64 {
    let n = c.len();
    let mut ends = Vec::with_capacity(n);
    let mut t = 0.0;
    for (k, ch) in c.iter().enumerate() {
        let (len, a, vn, e0, e1) = (ch.len, ch.accel, ch.nominal, entry[k], entry[k + 1]);
        let (up, down) = ((vn * vn - e0) / (2.0 * a), (vn * vn - e1) / (2.0 * a));
        t += if up + down <= len {
            (vn - e0.sqrt()) / a + (len - up - down) / vn + (vn - e1.sqrt()) / a
        } else {
            let peak = ((ch.reach() + e0 + e1) / 2.0).sqrt();
            (2.0 * peak - e0.sqrt() - e1.sqrt()) / a
        };
        ends.push(t);
    }
    let chord_at = |f: f64| ends.iter().position(|&e| e >= f * t).unwrap_or(n) as f64;
    (chord_at(0.75) - chord_at(0.25)) / (0.5 * t)
}

#[cfg(test)]
mod tests {
    use super::{lines_per_s, lines_per_s_ahead, Path};

    #[test]
    fn a_circle_planned_from_its_commanded_path_runs_at_the_feed() {
        // 0.1 mm chords at F3000 are 500 a second once the joints are
        // smooth; the rounding to steps makes them corners and slows them.
        let commanded = lines_per_s(3000.0, 1000.0, Path::Commanded);
        assert!((commanded - 500.0).abs() < 1.0, "{commanded}");
        let steps = lines_per_s(6000.0, 1000.0, Path::Steps);
        assert!(steps < 0.9 * lines_per_s(6000.0, 1000.0, Path::Commanded), "{steps}");
    }

    #[test]
    fn a_look_ahead_as_long_as_the_job_is_the_unbounded_plan() {
        for path in [Path::Steps, Path::Commanded] {
            let (full, long) = (lines_per_s(6000.0, 1000.0, path), lines_per_s_ahead(6000.0, 1000.0, path, 2000));
            assert!((full - long).abs() < 0.5, "{full} {long}");
        }
    }

    #[test]
    fn a_short_look_ahead_holds_the_smooth_circle_below_the_feed() {
        // A ring's 33 chords of 0.1 mm ahead must stop the tool within
        // 3.3 mm: at 1000 mm/s² on each axis (up to √2 times that along a
        // diagonal) that is at most √(2·1414·3.3) = 97 mm/s, below the
        // feed's 100 even with smooth joints.
        let smooth = lines_per_s_ahead(6000.0, 1000.0, Path::Commanded, 33);
        assert!(smooth < 970.0, "{smooth}");
        let mut last = 0.0;
        for ahead in [10, 20, 33, 40, 60] {
            let r = lines_per_s_ahead(6000.0, 1000.0, Path::Commanded, ahead);
            assert!(r > last, "{ahead}: {r}");
            last = r;
        }
        // With the joints from the steps, the look-ahead and the joints
        // both bind: below either limit alone.
        let steps = lines_per_s_ahead(6000.0, 1000.0, Path::Steps, 33);
        assert!(steps < smooth && steps < lines_per_s(6000.0, 1000.0, Path::Steps), "{steps}");
    }
}
