//! Helpers for the motion regression tests (tests/motion*.rs): a homed
//! machine, and checks of the recorded step path against ideal lines and arcs.
//!
//! Coordinates: after G28 the firmware's machine 0 is where each switch trips,
//! and the virtual machine's switch trips at physical step 0, so firmware steps
//! and the recorder's physical steps are the same numbers (100 steps/mm) on X
//! and Y. Z's switch is at the top and physical Z steps count downward, while
//! G-code and reports have +Z up: machine Z −5 mm is physical step 500
//! ([`user_to_physical_mm`]).
#![allow(dead_code)]

use super::*;
use sim::{Axis, PathPoint, Vm, VmConfig};

/// Steps per mm on X, Y, Z (docs/SPEC.md §3 default).
pub const SPMM: f64 = 100.0;
/// Arc tolerance setting (docs/SPEC.md §5 default), mm.
pub const ARC_TOL_MM: f64 = 0.002;

/// Boot with the machine at `start` physical steps (X, Y, Z) and home it.
/// The trace and violations are cleared afterwards.
pub fn boot_homed_from(start: [i64; 3]) -> Vm {
    let mut cfg = VmConfig::default();
    cfg.machine.initial_position = [start[0], start[1], start[2], 0];
    let mut vm = boot_with(cfg);
    ok(&mut vm, "G28");
    assert_eq!(steps(&vm), [100, 100, 100, 0], "G28 ends 1 mm off each switch");
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
    mark(&mut vm);
    vm
}

/// Boot near the switches (short homing) and home.
pub fn boot_homed() -> Vm {
    boot_homed_from([600, 600, 600])
}

/// Forget the recorded trace so far (positions are kept): later checks see
/// only what happens next.
pub fn mark(vm: &mut Vm) {
    vm.recorder_mut().clear_trace();
}

/// A position in the user's frame (G-code, +Z up) → the recorder's physical
/// mm (Z down from the top switch).
pub fn user_to_physical_mm(mm: [f64; 3]) -> [f64; 3] {
    [mm[0], mm[1], -mm[2]]
}

/// Steps of a position in mm (X, Y, Z), rounded as the firmware rounds.
pub fn mm_to_steps(mm: [f64; 3]) -> [i64; 3] {
    mm.map(|v| (v * SPMM).round() as i64)
}

/// The first three recorded positions.
pub fn xyz(p: &PathPoint) -> [f64; 3] {
    [p.position[0] as f64, p.position[1] as f64, p.position[2] as f64]
}

/// Current physical X, Y, Z in steps.
pub fn xyz_now(vm: &Vm) -> [i64; 3] {
    let p = vm.positions();
    [p[0], p[1], p[2]]
}

/// Distance (steps) of `p` from the segment `a`–`b`.
pub fn dist_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab.iter().map(|v| v * v).sum::<f64>();
    let t = if len2 == 0.0 { 0.0 } else { (ap.iter().zip(&ab).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0) };
    let q = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// Steps closer together than this (cycles) belong to one step event: the ISR
/// writes the step bits of one event to PINF, PINL and PINA with consecutive
/// instructions, and the recorder lists the axes of one port write one after
/// the other. Far below the shortest step period (267 cycles).
pub const EVENT_CYCLES: u64 = 32;

/// The recorded path since the last [`mark`], one point per step event (the
/// positions after all of its steps).
pub fn events(vm: &Vm) -> Vec<PathPoint> {
    let path = vm.recorder().path();
    let mut out: Vec<PathPoint> = Vec::with_capacity(path.len());
    for (i, p) in path.iter().enumerate() {
        let same_event_follows = path.get(i + 1).is_some_and(|n| n.cycle - p.cycle <= EVENT_CYCLES);
        if !same_event_follows {
            out.push(*p);
        }
    }
    out
}

/// Checks the recorded path since the last [`mark`] against a polyline of
/// corners (physical steps, the first one being where the path starts):
/// every step event lies within `max_dev` steps (Euclidean) of the segment it
/// belongs to, the path passes through every corner, and it ends exactly at
/// the last one. Returns the largest deviation seen.
pub fn check_polyline(vm: &Vm, corners: &[[i64; 3]], max_dev: f64) -> f64 {
    let path = events(vm);
    assert!(!path.is_empty(), "no steps recorded");
    let c: Vec<[f64; 3]> = corners.iter().map(|c| c.map(|v| v as f64)).collect();
    let mut seg = 0usize;
    let mut worst = 0.0f64;
    for (i, p) in path.iter().enumerate() {
        let q = xyz(p);
        let d = dist_to_segment(q, c[seg], c[seg + 1]);
        assert!(d <= max_dev, "step {i} at {:?} is {d:.3} steps off the segment {:?} -> {:?}", p.position, corners[seg], corners[seg + 1]);
        worst = worst.max(d);
        // Reached this segment's end: the next steps belong to the next one.
        while seg + 2 < c.len() && q == c[seg + 1] {
            seg += 1;
        }
    }
    assert_eq!(seg + 2, c.len(), "the path never reached corner {:?}", corners[seg + 1]);
    let end = *corners.last().unwrap();
    assert_eq!(xyz_now(vm), end, "final position");
    worst
}

/// What [`check_arc`] measured.
#[derive(Debug)]
pub struct ArcCheck {
    /// Largest per-axis distance from the ideal circle, steps (see [`check_arc`]).
    pub worst_per_axis: f64,
    /// Largest |distance to the centre − radius|, steps (for information: it
    /// may exceed the per-axis figure by up to √2 near 45°).
    pub worst_radial: f64,
    /// Largest distance of the normal axis from its helical ideal, steps.
    pub worst_linear: f64,
    /// Signed angle swept in the plane's (axis_0, axis_1) coordinates, rad.
    pub swept: f64,
}

/// Per-axis (Chebyshev) distance from `(u, v)` (relative to the centre) to
/// the circle of radius `r`: min over θ of max(|u − r cos θ|, |v − r sin θ|).
pub fn per_axis_distance_to_circle(u: f64, v: f64, r: f64) -> f64 {
    let f = |t: f64| (u - r * t.cos()).abs().max((v - r * t.sin()).abs());
    let t0 = v.atan2(u);
    // The minimum lies within a few steps of the radial projection.
    let span = 4.0 / r.max(1.0);
    let n = 400;
    let mut best = (f64::INFINITY, t0);
    for k in 0..=n {
        let t = t0 - span + 2.0 * span * k as f64 / n as f64;
        let d = f(t);
        if d < best.0 {
            best = (d, t);
        }
    }
    // Refine around the best sample.
    let (mut lo, mut hi) = (best.1 - 2.0 * span / n as f64, best.1 + 2.0 * span / n as f64);
    for _ in 0..60 {
        let m1 = lo + (hi - lo) / 3.0;
        let m2 = hi - (hi - lo) / 3.0;
        if f(m1) < f(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    best.0.min(f(0.5 * (lo + hi)))
}

/// Checks the recorded path since the last [`mark`] against an ideal arc or
/// helix: `plane` = (axis_0, axis_1, normal) as in RS274/NGC (G17 (0,1,2),
/// G18 (2,0,1), G19 (1,2,0)); `centre` and `radius` in steps in the plane;
/// the normal axis runs linearly with the angle from `start` to `end`.
///
/// "Within tolerance + 1 step" (docs/SPEC.md §11) is taken per axis, like the ±1 step
/// of a Bresenham line: every step event must lie within `max_dev` steps of a
/// point of the ideal circle on each axis. (Radially, integer chord ends, each
/// up to ½ step off per axis, plus the Bresenham's ½ step can add up to
/// tolerance + 1.21 steps near 45°: no integer-step firmware can promise less.)
pub fn check_arc(
    vm: &Vm,
    plane: (usize, usize, usize),
    centre: [f64; 2],
    radius: f64,
    start: [i64; 3],
    end: [i64; 3],
    max_dev: f64,
) -> ArcCheck {
    let (a0, a1, al) = plane;
    let path = events(vm);
    assert!(!path.is_empty(), "no steps recorded");
    let angle = |q: [f64; 3]| (q[a1] - centre[1]).atan2(q[a0] - centre[0]);
    let s = start.map(|v| v as f64);
    let mut prev = angle(s);
    let mut swept = 0.0f64;
    let mut worst_radial = 0.0f64;
    let mut worst_per_axis = 0.0f64;
    // First pass: distance to the circle and the total sweep.
    let mut sweeps = Vec::with_capacity(path.len());
    for (i, p) in path.iter().enumerate() {
        let q = xyz(p);
        let (u, v) = (q[a0] - centre[0], q[a1] - centre[1]);
        let r = (u * u + v * v).sqrt();
        worst_radial = worst_radial.max((r - radius).abs());
        let d = per_axis_distance_to_circle(u, v, radius);
        assert!(
            d <= max_dev,
            "step {i} at {:?}: {d:.3} steps from the ideal circle on some axis (radius {r:.3} vs {radius:.3})",
            p.position
        );
        worst_per_axis = worst_per_axis.max(d);
        let a = angle(q);
        let mut da = a - prev;
        if da > std::f64::consts::PI {
            da -= 2.0 * std::f64::consts::PI;
        } else if da < -std::f64::consts::PI {
            da += 2.0 * std::f64::consts::PI;
        }
        swept += da;
        prev = a;
        sweeps.push(swept);
    }
    // Second pass: the normal axis follows the angle (helix).
    let lin = (end[al] - start[al]) as f64;
    let mut worst_linear = 0.0f64;
    for (p, sw) in path.iter().zip(&sweeps) {
        let ideal = s[al] + lin * (sw / swept);
        let d = (p.position[al] as f64 - ideal).abs();
        worst_linear = worst_linear.max(d);
    }
    assert_eq!(xyz_now(vm), end, "final position");
    ArcCheck { worst_per_axis, worst_radial, worst_linear, swept }
}

/// Steps recorded since the last [`mark`], per axis.
pub fn steps_since_mark(vm: &Vm) -> usize {
    vm.recorder().trace().len()
}

/// Steps of one axis recorded after VM cycle `cycle`.
pub fn steps_after(vm: &Vm, axis: Axis, cycle: u64) -> usize {
    vm.recorder().trace().iter().filter(|t| t.axis == axis && t.cycle > cycle).count()
}

/// Sends `line`, expects `ok` without error, then waits until all motion is done.
pub fn run(vm: &mut Vm, line: &str) {
    ok(vm, line);
    ok(vm, "M400");
}

/// The `Count X:.. Y:.. Z:..` step counters the firmware reports with M114.
pub fn m114_counts(vm: &mut Vm) -> [i64; 3] {
    let r = ok(vm, "M114");
    let l = r.iter().find(|l| l.contains("Count")).unwrap_or_else(|| panic!("{r:?}"));
    let count = l.split("Count").nth(1).unwrap();
    let get = |axis: &str| -> i64 {
        count.split_whitespace().find_map(|w| w.strip_prefix(axis)).unwrap_or_else(|| panic!("{l}")).parse().unwrap()
    };
    [get("X:"), get("Y:"), get("Z:")]
}

/// The work position the firmware reports with M114 (`X:.. Y:.. Z:..`), mm.
pub fn m114_work(vm: &mut Vm) -> [f64; 3] {
    let r = ok(vm, "M114");
    let l = r.iter().find(|l| l.contains("Count")).unwrap_or_else(|| panic!("{r:?}"));
    let head = l.split("Count").next().unwrap();
    let get = |axis: &str| -> f64 {
        head.split_whitespace().find_map(|w| w.strip_prefix(axis)).unwrap_or_else(|| panic!("{l}")).parse().unwrap()
    };
    [get("X:"), get("Y:"), get("Z:")]
}

/// No timing, travel or disabled-step violation was recorded.
pub fn assert_no_violations(vm: &Vm) {
    assert!(vm.violations().is_empty(), "violations: {:?}", &vm.violations()[..vm.violations().len().min(5)]);
}

/// Steps of `axis` recorded since the last [`mark`]: (positive, negative).
pub fn steps_pos_neg(vm: &Vm, axis: Axis) -> (u64, u64) {
    let mut prev = vm.recorder().initial_positions()[axis.index()];
    let (mut pos, mut neg) = (0, 0);
    for t in vm.recorder().trace().iter().filter(|t| t.axis == axis) {
        if t.position > prev {
            pos += 1;
        } else {
            neg += 1;
        }
        prev = t.position;
    }
    (pos, neg)
}
