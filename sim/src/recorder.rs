//! Step/dir/enable recorder: what the four DRV8825 drivers saw.
//!
//! A pure state machine fed with `(cycle, axis, signal, level)` pin events, so
//! it is unit-tested without simavr. In the VM the events come from simavr's
//! IOPORT pin IRQ notifications (one call per pin *change*, never per
//! instruction); the cycle stamp is the VM's monotonic clock.
//!
//! What it models (DRV8825 datasheet, docs/SPEC.md §2):
//! - A microstep happens on the rising edge of STEP, in the direction DIR has
//!   at that edge (HIGH = positive unless the axis is in `invert_dir_mask`).
//! - While ENABLE is HIGH the driver is off: the edge is flagged
//!   [`ViolationKind::StepWhileDisabled`] and the motor does *not* move.
//! - Timing limits: STEP high ≥ 1.9 µs and low ≥ 1.9 µs (31 cycles at 16 MHz,
//!   30.4 rounded up), DIR set ≥ 650 ns before a rising STEP edge and held
//!   ≥ 650 ns after it (11 cycles). Each breach is a [`Violation`] with the
//!   measured value.
//! - Travel: a position below `-margin` or above `travel + margin` is a crash
//!   ([`ViolationKind::BeyondTravelMin`]/[`ViolationKind::BeyondTravelMax`]),
//!   flagged once per excursion.
//!
//! Note on the cycle stamps: simavr notifies a pin change while executing the
//! writing instruction, with the clock at that instruction's first cycle. Both
//! edges of a pulse are shifted the same way, so widths and intervals are
//! exact.
//!
//! Statistics: steps per direction, peak rate from the shortest interval
//! between rising edges, peak rate over a sliding window (default 1 ms), and a
//! smoothed acceleration estimate ([`Recorder::max_accel`], method documented
//! there).

use crate::physics::MachineConfig;
use crate::pins::{Axis, SignalKind};
use serde::Serialize;
use std::collections::VecDeque;

/// Timing limits and analysis parameters.
#[derive(Clone, Debug)]
pub struct RecorderConfig {
    /// CPU clock, Hz (for converting cycles to seconds).
    pub frequency_hz: u32,
    /// Minimum STEP high time, cycles (DRV8825: 1.9 µs → 31 at 16 MHz).
    pub min_step_high_cycles: u64,
    /// Minimum STEP low time, cycles (DRV8825: 1.9 µs → 31 at 16 MHz).
    pub min_step_low_cycles: u64,
    /// Minimum DIR setup before a rising STEP edge, cycles (650 ns → 11).
    pub dir_setup_cycles: u64,
    /// Minimum DIR hold after a rising STEP edge, cycles (650 ns → 11).
    pub dir_hold_cycles: u64,
    /// Window of the sliding step-rate measure, cycles (default 1 ms).
    pub rate_window_cycles: u64,
    /// Smoothing window of the acceleration estimate, s (default 20 ms).
    pub accel_window_s: f64,
    /// Sampling grid of the acceleration estimate, s (default 0.5 ms).
    pub accel_grid_s: f64,
    /// Keep every step in [`Recorder::trace`] (24 bytes per step). Needed for
    /// the acceleration estimate, the path and the CSV.
    pub record_trace: bool,
    /// At most this many violations are stored (all are counted).
    pub max_violations_kept: usize,
}

impl Default for RecorderConfig {
    fn default() -> Self {
        RecorderConfig {
            frequency_hz: 16_000_000,
            min_step_high_cycles: 31,
            min_step_low_cycles: 31,
            dir_setup_cycles: 11,
            dir_hold_cycles: 11,
            rate_window_cycles: 16_000,
            accel_window_s: 0.020,
            accel_grid_s: 0.0005,
            record_trace: true,
            max_violations_kept: 10_000,
        }
    }
}

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum ViolationKind {
    /// STEP was high for less than the minimum (measured: cycles).
    StepHighTooShort,
    /// STEP was low for less than the minimum before rising again (cycles).
    StepLowTooShort,
    /// DIR changed less than the setup time before a rising STEP edge (cycles).
    DirSetupTooShort,
    /// DIR changed less than the hold time after a rising STEP edge (cycles).
    DirHoldTooShort,
    /// A rising STEP edge while ENABLE was high (measured: the step's sign).
    StepWhileDisabled,
    /// Position went below `-margin` (measured: position, steps).
    BeyondTravelMin,
    /// Position went above `travel + margin` (measured: position, steps).
    BeyondTravelMax,
}

/// One breach of the driver timing or of the machine's travel.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Violation {
    pub axis: Axis,
    /// VM cycle of the offending edge.
    pub cycle: u64,
    /// The same in seconds.
    pub time_s: f64,
    pub kind: ViolationKind,
    /// Measured value: cycles for timing kinds, steps for travel kinds.
    pub measured: i64,
    /// The limit it was compared with, same unit.
    pub limit: i64,
}

/// One recorded microstep: the axis' position *after* it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TracePoint {
    pub cycle: u64,
    pub axis: Axis,
    pub position: i64,
}

/// All axes' positions right after one step of one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathPoint {
    pub cycle: u64,
    /// The axis that stepped.
    pub axis: Axis,
    /// Positions of X, Y, Z, E after the step, in steps.
    pub position: [i64; 4],
}

/// A step that moved the machine (returned by [`Recorder::on_pin`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepEvent {
    pub cycle: u64,
    pub axis: Axis,
    /// +1 or -1.
    pub delta: i8,
    /// New position, steps.
    pub position: i64,
}

/// Summary of one axis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AxisStats {
    pub axis: Axis,
    /// Steps in the positive direction.
    pub steps_pos: u64,
    /// Steps in the negative direction.
    pub steps_neg: u64,
    /// Rising edges while the driver was disabled (did not move).
    pub steps_while_disabled: u64,
    /// Current position, steps.
    pub position: i64,
    /// Shortest interval between two rising edges, cycles.
    pub min_step_interval_cycles: Option<u64>,
    /// Shortest and longest STEP high time, cycles.
    pub min_step_high_cycles: Option<u64>,
    pub max_step_high_cycles: Option<u64>,
    /// Shortest STEP low time between two pulses, cycles.
    pub min_step_low_cycles: Option<u64>,
    /// `frequency / min_step_interval`, Hz.
    pub peak_rate_hz: f64,
    /// Most rising edges in any sliding window, divided by the window, Hz.
    pub peak_rate_windowed_hz: f64,
    /// Largest smoothed |acceleration|, steps/s² (None without a trace).
    pub max_accel_steps_per_s2: Option<f64>,
}

#[derive(Clone, Debug, Default)]
struct AxisState {
    step: bool,
    dir: bool,
    /// Pin level: HIGH = driver disabled.
    enable: bool,
    last_rise: Option<u64>,
    last_fall: Option<u64>,
    last_dir_change: Option<u64>,
    position: i64,
    steps_pos: u64,
    steps_neg: u64,
    steps_while_disabled: u64,
    min_interval: Option<u64>,
    min_high: Option<u64>,
    max_high: Option<u64>,
    min_low: Option<u64>,
    window: VecDeque<u64>,
    max_in_window: usize,
    beyond: bool,
}

/// The recorder. See the module docs.
#[derive(Clone, Debug)]
pub struct Recorder {
    config: RecorderConfig,
    initial: [i64; 4],
    travel: [Option<i64>; 4],
    margin: [i64; 4],
    invert_dir_mask: u8,
    axes: [AxisState; 4],
    violations: Vec<Violation>,
    violation_count: u64,
    trace: Vec<TracePoint>,
}

impl Recorder {
    /// A recorder for a machine starting at `machine.initial_position`.
    pub fn new(config: RecorderConfig, machine: &MachineConfig) -> Recorder {
        let mut axes: [AxisState; 4] = Default::default();
        for (i, a) in axes.iter_mut().enumerate() {
            a.position = machine.initial_position[i];
        }
        Recorder {
            config,
            initial: machine.initial_position,
            travel: machine.travel_steps,
            margin: machine.travel_margin_steps,
            invert_dir_mask: machine.invert_dir_mask,
            axes,
            violations: Vec::new(),
            violation_count: 0,
            trace: Vec::new(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &RecorderConfig {
        &self.config
    }

    fn seconds(&self, cycle: u64) -> f64 {
        cycle as f64 / self.config.frequency_hz as f64
    }

    fn flag(&mut self, axis: Axis, cycle: u64, kind: ViolationKind, measured: i64, limit: i64) {
        self.violation_count += 1;
        if self.violations.len() < self.config.max_violations_kept {
            let time_s = self.seconds(cycle);
            self.violations.push(Violation { axis, cycle, time_s, kind, measured, limit });
        }
    }

    /// Feed one pin level change. Returns the step if the machine moved.
    pub fn on_pin(&mut self, cycle: u64, axis: Axis, kind: SignalKind, level: bool) -> Option<StepEvent> {
        let i = axis.index();
        match kind {
            SignalKind::Enable => {
                self.axes[i].enable = level;
                None
            }
            SignalKind::Dir => {
                let a = &mut self.axes[i];
                if a.dir == level {
                    return None;
                }
                a.dir = level;
                a.last_dir_change = Some(cycle);
                if let Some(rise) = a.last_rise {
                    let held = cycle - rise;
                    if held < self.config.dir_hold_cycles {
                        let limit = self.config.dir_hold_cycles as i64;
                        self.flag(axis, cycle, ViolationKind::DirHoldTooShort, held as i64, limit);
                    }
                }
                None
            }
            SignalKind::Step => {
                if self.axes[i].step == level {
                    return None;
                }
                self.axes[i].step = level;
                if level {
                    self.rising(cycle, axis)
                } else {
                    let a = &mut self.axes[i];
                    a.last_fall = Some(cycle);
                    if let Some(rise) = a.last_rise {
                        let high = cycle - rise;
                        a.min_high = Some(a.min_high.map_or(high, |m| m.min(high)));
                        a.max_high = Some(a.max_high.map_or(high, |m| m.max(high)));
                        if high < self.config.min_step_high_cycles {
                            let limit = self.config.min_step_high_cycles as i64;
                            self.flag(axis, cycle, ViolationKind::StepHighTooShort, high as i64, limit);
                        }
                    }
                    None
                }
            }
        }
    }

    fn rising(&mut self, cycle: u64, axis: Axis) -> Option<StepEvent> {
        let i = axis.index();
        let cfg = self.config.clone();
        // Timing checks against the previous edges.
        if let Some(fall) = self.axes[i].last_fall {
            let low = cycle - fall;
            let a = &mut self.axes[i];
            a.min_low = Some(a.min_low.map_or(low, |m| m.min(low)));
            if low < cfg.min_step_low_cycles {
                self.flag(axis, cycle, ViolationKind::StepLowTooShort, low as i64, cfg.min_step_low_cycles as i64);
            }
        }
        if let Some(change) = self.axes[i].last_dir_change {
            let setup = cycle - change;
            if setup < cfg.dir_setup_cycles {
                self.flag(axis, cycle, ViolationKind::DirSetupTooShort, setup as i64, cfg.dir_setup_cycles as i64);
            }
        }
        // Rate statistics (every rising edge, moving or not).
        {
            let a = &mut self.axes[i];
            if let Some(prev) = a.last_rise {
                let dt = cycle - prev;
                a.min_interval = Some(a.min_interval.map_or(dt, |m| m.min(dt)));
            }
            a.last_rise = Some(cycle);
            while a.window.front().is_some_and(|&t| t + cfg.rate_window_cycles <= cycle) {
                a.window.pop_front();
            }
            a.window.push_back(cycle);
            a.max_in_window = a.max_in_window.max(a.window.len());
        }
        let positive = self.axes[i].dir != (self.invert_dir_mask & (1 << i) != 0);
        let delta: i8 = if positive { 1 } else { -1 };
        if self.axes[i].enable {
            self.axes[i].steps_while_disabled += 1;
            self.flag(axis, cycle, ViolationKind::StepWhileDisabled, delta as i64, 0);
            return None;
        }
        let a = &mut self.axes[i];
        a.position += delta as i64;
        if positive {
            a.steps_pos += 1;
        } else {
            a.steps_neg += 1;
        }
        let position = a.position;
        // Travel.
        if let Some(travel) = self.travel[i] {
            let lo = -self.margin[i];
            let hi = travel + self.margin[i];
            let beyond = position < lo || position > hi;
            if beyond && !self.axes[i].beyond {
                if position < lo {
                    self.flag(axis, cycle, ViolationKind::BeyondTravelMin, position, lo);
                } else {
                    self.flag(axis, cycle, ViolationKind::BeyondTravelMax, position, hi);
                }
            }
            self.axes[i].beyond = beyond;
        }
        if self.config.record_trace {
            self.trace.push(TracePoint { cycle, axis, position });
        }
        Some(StepEvent { cycle, axis, delta, position })
    }

    /// The chip was reset: every pin floats, which the DRV8825's internal
    /// pull-downs read as STEP low, DIR low, ENABLE low (enabled). No timing
    /// checks are made on these implied edges.
    pub fn on_reset(&mut self, cycle: u64) {
        for a in &mut self.axes {
            if a.step {
                a.last_fall = Some(cycle);
            }
            if a.dir {
                a.last_dir_change = Some(cycle);
            }
            a.step = false;
            a.dir = false;
            a.enable = false;
        }
    }

    /// Physical position of an axis, steps.
    pub fn position(&self, axis: Axis) -> i64 {
        self.axes[axis.index()].position
    }

    /// Physical positions of X, Y, Z, E, steps.
    pub fn positions(&self) -> [i64; 4] {
        [0, 1, 2, 3].map(|i| self.axes[i].position)
    }

    /// Every step recorded so far, all axes and both directions, with the
    /// steps taken while a driver was disabled. Cheap (counters), unlike
    /// [`Recorder::axis_stats`], which analyses the whole trace.
    pub fn total_steps(&self) -> u64 {
        self.axes.iter().map(|a| a.steps_pos + a.steps_neg + a.steps_while_disabled).sum()
    }

    /// Positions at power-on.
    pub fn initial_positions(&self) -> [i64; 4] {
        self.initial
    }

    /// Is the driver enabled (ENABLE pin low)?
    pub fn driver_enabled(&self, axis: Axis) -> bool {
        !self.axes[axis.index()].enable
    }

    /// Current pin levels (step, dir, enable) as last recorded.
    pub fn pin_levels(&self, axis: Axis) -> (bool, bool, bool) {
        let a = &self.axes[axis.index()];
        (a.step, a.dir, a.enable)
    }

    /// Stored violations, oldest first (at most `max_violations_kept`).
    pub fn violations(&self) -> &[Violation] {
        &self.violations
    }

    /// All violations ever flagged, including those not stored.
    pub fn violation_count(&self) -> u64 {
        self.violation_count
    }

    /// Stored violations of one kind.
    pub fn violations_of(&self, kind: ViolationKind) -> Vec<&Violation> {
        self.violations.iter().filter(|v| v.kind == kind).collect()
    }

    /// Every recorded step, in time order (empty if `record_trace` is off).
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }

    /// Forget the stored trace (positions and counters are kept). The path
    /// replay then starts from the current positions.
    pub fn clear_trace(&mut self) {
        self.trace.clear();
        self.initial = self.positions();
    }

    /// Forget violations (counted and stored).
    pub fn clear_violations(&mut self) {
        self.violations.clear();
        self.violation_count = 0;
    }

    /// Calls `f` once per recorded step with all four positions right after it.
    /// This is the "sample positions at every step" view for path checks.
    pub fn for_each_step(&self, mut f: impl FnMut(&PathPoint)) {
        let mut pos = self.initial;
        for t in &self.trace {
            pos[t.axis.index()] = t.position;
            f(&PathPoint { cycle: t.cycle, axis: t.axis, position: pos });
        }
    }

    /// The whole path: positions after every recorded step.
    pub fn path(&self) -> Vec<PathPoint> {
        let mut out = Vec::with_capacity(self.trace.len());
        self.for_each_step(|p| out.push(*p));
        out
    }

    /// Cycle of the first and last recorded step, if any.
    pub fn step_span(&self) -> Option<(u64, u64)> {
        Some((self.trace.first()?.cycle, self.trace.last()?.cycle))
    }

    /// Summary of one axis.
    pub fn axis_stats(&self, axis: Axis) -> AxisStats {
        let a = &self.axes[axis.index()];
        let f = self.config.frequency_hz as f64;
        AxisStats {
            axis,
            steps_pos: a.steps_pos,
            steps_neg: a.steps_neg,
            steps_while_disabled: a.steps_while_disabled,
            position: a.position,
            min_step_interval_cycles: a.min_interval,
            min_step_high_cycles: a.min_high,
            max_step_high_cycles: a.max_high,
            min_step_low_cycles: a.min_low,
            peak_rate_hz: a.min_interval.map_or(0.0, |m| f / m as f64),
            peak_rate_windowed_hz: a.max_in_window as f64 * f / self.config.rate_window_cycles as f64,
            max_accel_steps_per_s2: self.max_accel(axis),
        }
    }

    /// Largest |acceleration| of an axis, steps/s², with the configured window.
    /// `None` without a trace or with fewer than 3 steps.
    ///
    /// Method (robust against Bresenham jitter and the quantisation of steps):
    /// 1. The position is taken as the piecewise-linear curve through the
    ///    recorded steps `(t_i, p_i)`. Before a step that follows a pause longer
    ///    than the window, the axis is taken to rest until one step interval
    ///    before it (so a start from rest is not smeared over the pause).
    /// 2. That curve is sampled on a grid (`accel_grid_s`), per stretch of
    ///    motion.
    /// 3. `a(t) = (p(t+W) - 2 p(t) + p(t-W)) / W²` with `W = accel_window_s`:
    ///    the difference of two W-averaged velocities, i.e. the true
    ///    acceleration smoothed by a triangular kernel of half-width W.
    ///
    /// Exact for constant-acceleration phases longer than 2W; shorter ramps are
    /// under-estimated. A non-dominant Bresenham axis has its steps up to one
    /// tick late, a position error below 1 step, which bounds the error of the
    /// estimate by `2 / W²` (5000 steps/s² at W = 20 ms); the dominant axis has
    /// no such error. A corner taken at a junction speed shows as a short
    /// acceleration of about `Δv / W` on each axis.
    pub fn max_accel(&self, axis: Axis) -> Option<f64> {
        self.max_accel_with_window(axis, self.config.accel_window_s)
    }

    /// [`Recorder::max_accel`] with another smoothing window, s.
    pub fn max_accel_with_window(&self, axis: Axis, window_s: f64) -> Option<f64> {
        let mut max: Option<f64> = None;
        self.accel_series(axis, window_s, |_, a| {
            let a = a.abs();
            max = Some(max.map_or(a, |m: f64| m.max(a)));
        })?;
        max
    }

    /// Smoothed velocity of an axis on the analysis grid: `(t_s, steps/s)`,
    /// central difference over `window_s`. Only stretches of motion.
    pub fn velocity_profile(&self, axis: Axis, window_s: f64) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let f = self.config.frequency_hz as f64;
        let g = (self.config.accel_grid_s * f).max(1.0);
        let half = ((window_s * f / 2.0) / g).round().max(1.0) as usize;
        for (t0, p) in self.motion_stretches(axis, window_s) {
            for k in half..p.len().saturating_sub(half) {
                let v = (p[k + half] - p[k - half]) / (2.0 * half as f64 * g / f);
                out.push(((t0 + k as f64 * g) / f, v));
            }
        }
        out
    }

    /// Calls `f(t_s, accel)` for every grid point of every stretch of motion.
    fn accel_series(&self, axis: Axis, window_s: f64, mut f: impl FnMut(f64, f64)) -> Option<()> {
        let hz = self.config.frequency_hz as f64;
        let g = (self.config.accel_grid_s * hz).max(1.0);
        let m = ((window_s * hz) / g).round().max(1.0) as usize;
        let w = m as f64 * g / hz;
        let stretches = self.motion_stretches(axis, window_s);
        if stretches.is_empty() {
            return None;
        }
        for (t0, p) in stretches {
            for k in m..p.len().saturating_sub(m) {
                let a = (p[k + m] - 2.0 * p[k] + p[k - m]) / (w * w);
                f((t0 + k as f64 * g) / hz, a);
            }
        }
        Some(())
    }

    /// The axis' position sampled on the grid, one vector per stretch of
    /// motion (stretches are separated by rests longer than 3 windows; each is
    /// padded with 2 windows of rest on both sides). Returns (start cycle, samples).
    fn motion_stretches(&self, axis: Axis, window_s: f64) -> Vec<(f64, Vec<f64>)> {
        let hz = self.config.frequency_hz as f64;
        let g = (self.config.accel_grid_s * hz).max(1.0);
        let w = window_s * hz;
        let steps: Vec<&TracePoint> = self.trace.iter().filter(|t| t.axis == axis).collect();
        if steps.len() < 3 {
            return Vec::new();
        }
        // Knots (cycle, position) of the piecewise-linear position curve.
        // Position before the first recorded step of this axis: the trace
        // starts at `initial`, and this axis has no earlier entry.
        let before_first = self.initial[axis.index()];
        let mut knots: Vec<(f64, f64)> = Vec::with_capacity(steps.len() * 2);
        let mut prev: (f64, f64) = (f64::NEG_INFINITY, before_first as f64);
        for (idx, s) in steps.iter().enumerate() {
            let t = s.cycle as f64;
            let gap = t - prev.0;
            if gap > w {
                let next_interval = steps.get(idx + 1).map(|n| n.cycle as f64 - t).filter(|d| *d < w);
                let d = next_interval.unwrap_or(w).min(gap);
                knots.push((t - d, prev.1));
            }
            prev = (t, s.position as f64);
            knots.push(prev);
        }
        // Split into stretches at rests longer than 3 windows.
        let mut out = Vec::new();
        let mut start = 0;
        for i in 1..=knots.len() {
            let split = i == knots.len() || knots[i].0 - knots[i - 1].0 > 3.0 * w;
            if split {
                let seg = &knots[start..i];
                let t_begin = seg[0].0 - 2.0 * w;
                let t_end = seg[seg.len() - 1].0 + 2.0 * w;
                let n = ((t_end - t_begin) / g).ceil() as usize + 1;
                let mut samples = Vec::with_capacity(n);
                let mut j = 0;
                for k in 0..n {
                    let t = t_begin + k as f64 * g;
                    while j + 1 < seg.len() && seg[j + 1].0 <= t {
                        j += 1;
                    }
                    let p = if t <= seg[0].0 {
                        seg[0].1
                    } else if j + 1 >= seg.len() {
                        seg[seg.len() - 1].1
                    } else {
                        let (t1, p1) = seg[j];
                        let (t2, p2) = seg[j + 1];
                        p1 + (p2 - p1) * (t - t1) / (t2 - t1)
                    };
                    samples.push(p);
                }
                out.push((t_begin, samples));
                start = i;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec() -> Recorder {
        let m = MachineConfig { initial_position: [100, 100, 100, 0], ..Default::default() };
        Recorder::new(RecorderConfig::default(), &m)
    }

    /// Emits one clean pulse: dir set long before, high 40 cycles.
    fn pulse(r: &mut Recorder, t: u64, axis: Axis, high: u64) -> Option<StepEvent> {
        let e = r.on_pin(t, axis, SignalKind::Step, true);
        r.on_pin(t + high, axis, SignalKind::Step, false);
        e
    }

    #[test]
    fn counts_steps_with_direction_from_dir_pin() {
        let mut r = rec();
        r.on_pin(0, Axis::X, SignalKind::Dir, true);
        for k in 0..10 {
            pulse(&mut r, 1000 + k * 1000, Axis::X, 40);
        }
        r.on_pin(20_000, Axis::X, SignalKind::Dir, false);
        for k in 0..3 {
            pulse(&mut r, 30_000 + k * 1000, Axis::X, 40);
        }
        assert_eq!(r.position(Axis::X), 107);
        let s = r.axis_stats(Axis::X);
        assert_eq!((s.steps_pos, s.steps_neg), (10, 3));
        assert_eq!(s.min_step_interval_cycles, Some(1000));
        assert_eq!(s.peak_rate_hz, 16_000.0);
        assert_eq!((s.min_step_high_cycles, s.max_step_high_cycles), (Some(40), Some(40)));
        assert_eq!(s.min_step_low_cycles, Some(960));
        assert!(r.violations().is_empty(), "{:?}", r.violations());
    }

    #[test]
    fn inverted_axis_counts_the_other_way() {
        let m = MachineConfig { invert_dir_mask: 0b0010, ..Default::default() };
        let mut r = Recorder::new(RecorderConfig::default(), &m);
        r.on_pin(0, Axis::Y, SignalKind::Dir, true);
        pulse(&mut r, 100, Axis::Y, 40);
        assert_eq!(r.position(Axis::Y), 2249);
    }

    #[test]
    fn flags_short_high_and_short_low() {
        let mut r = rec();
        pulse(&mut r, 100, Axis::Y, 8);
        r.on_pin(120, Axis::Y, SignalKind::Step, true); // low for 12 cycles
        r.on_pin(200, Axis::Y, SignalKind::Step, false);
        let v = r.violations();
        assert_eq!(v.len(), 2);
        assert_eq!((v[0].kind, v[0].measured, v[0].cycle), (ViolationKind::StepHighTooShort, 8, 108));
        assert_eq!((v[1].kind, v[1].measured), (ViolationKind::StepLowTooShort, 12));
        assert_eq!(v[1].axis, Axis::Y);
    }

    #[test]
    fn flags_dir_setup_and_hold() {
        let mut r = rec();
        r.on_pin(1000, Axis::Z, SignalKind::Dir, true);
        pulse(&mut r, 1002, Axis::Z, 40); // setup 2
        r.on_pin(1047, Axis::Z, SignalKind::Dir, false); // 45 after rise: fine
        pulse(&mut r, 5000, Axis::Z, 40);
        r.on_pin(5005, Axis::Z, SignalKind::Dir, true); // hold 5 (while high)
        let kinds: Vec<_> = r.violations().iter().map(|v| (v.kind, v.measured)).collect();
        assert_eq!(kinds, vec![(ViolationKind::DirSetupTooShort, 2), (ViolationKind::DirHoldTooShort, 5)]);
    }

    #[test]
    fn step_while_disabled_is_flagged_and_does_not_move() {
        let mut r = rec();
        r.on_pin(0, Axis::E, SignalKind::Dir, true);
        r.on_pin(0, Axis::E, SignalKind::Enable, true);
        assert!(pulse(&mut r, 100, Axis::E, 40).is_none());
        assert_eq!(r.position(Axis::E), 0);
        assert_eq!(r.violations()[0].kind, ViolationKind::StepWhileDisabled);
        r.on_pin(200, Axis::E, SignalKind::Enable, false);
        assert!(pulse(&mut r, 300, Axis::E, 40).is_some());
        assert_eq!(r.position(Axis::E), 1);
        assert_eq!(r.axis_stats(Axis::E).steps_while_disabled, 1);
    }

    #[test]
    fn travel_excursion_is_flagged_once() {
        let m = MachineConfig { initial_position: [2, 0, 0, 0], travel_margin_steps: [1, 1, 1, 0], ..Default::default() };
        let mut r = Recorder::new(RecorderConfig::default(), &m);
        for k in 0..6 {
            pulse(&mut r, 100 + k * 100, Axis::X, 40); // dir low = negative: 1,0,-1,-2,-3,-4
        }
        let v = r.violations();
        assert_eq!(v.len(), 1);
        assert_eq!((v[0].kind, v[0].measured, v[0].limit), (ViolationKind::BeyondTravelMin, -2, -1));
    }

    #[test]
    fn windowed_rate_counts_edges_in_one_ms() {
        let mut r = rec();
        r.on_pin(0, Axis::X, SignalKind::Dir, true);
        // 20 steps 400 cycles apart (40 kHz), then slow.
        for k in 0..20 {
            pulse(&mut r, 1000 + k * 400, Axis::X, 40);
        }
        let s = r.axis_stats(Axis::X);
        assert_eq!(s.peak_rate_hz, 40_000.0);
        assert_eq!(s.peak_rate_windowed_hz, 20_000.0); // 20 edges in one 1 ms window
    }

    #[test]
    fn path_replays_every_step() {
        let mut r = rec();
        r.on_pin(0, Axis::X, SignalKind::Dir, true);
        r.on_pin(0, Axis::Y, SignalKind::Dir, true);
        pulse(&mut r, 100, Axis::X, 40);
        pulse(&mut r, 200, Axis::Y, 40);
        pulse(&mut r, 300, Axis::X, 40);
        let p: Vec<[i64; 4]> = r.path().iter().map(|p| p.position).collect();
        assert_eq!(p, vec![[101, 100, 100, 0], [101, 101, 100, 0], [102, 101, 100, 0]]);
    }

    /// Steps of a trapezoid: accel `a` to `v`, cruise, symmetric decel; the
    /// axis steps when its ideal position crosses an integer (ticks at `tick`).
    fn trapezoid_ticks(a: f64, v: f64, total: f64, tick_s: f64) -> Vec<f64> {
        // Dominant axis positions as a continuous function, sampled per tick.
        let ta = v / a;
        let da = 0.5 * a * ta * ta;
        let tc = (total - 2.0 * da) / v;
        let end = 2.0 * ta + tc;
        let pos = |t: f64| {
            if t < ta {
                0.5 * a * t * t
            } else if t < ta + tc {
                da + v * (t - ta)
            } else if t < end {
                let u = t - ta - tc;
                da + v * tc + v * u - 0.5 * a * u * u
            } else {
                total
            }
        };
        let mut times = Vec::new();
        let mut stepped = 0.0;
        let mut t = 0.0;
        while t < end + tick_s {
            while pos(t) >= stepped + 1.0 - 1e-9 {
                stepped += 1.0;
                times.push(t);
            }
            t += tick_s;
        }
        times
    }

    #[test]
    fn accel_estimate_matches_a_trapezoid_and_ignores_bresenham_jitter() {
        let a = 100_000.0; // steps/s²
        let hz = 16e6;
        let mut r = rec();
        r.on_pin(0, Axis::X, SignalKind::Dir, true);
        r.on_pin(0, Axis::Y, SignalKind::Dir, true);
        // Dominant X: steps at the exact times of the ideal profile.
        let x = trapezoid_ticks(a, 20_000.0, 10_000.0, 1e-7);
        // Minor Y (ratio 0.37): Bresenham on X's steps.
        let mut events: Vec<(u64, Axis)> = Vec::new();
        let mut acc = 0.0;
        for &t in &x {
            let c = 1000 + (t * hz) as u64;
            events.push((c, Axis::X));
            acc += 0.37;
            if acc >= 1.0 {
                acc -= 1.0;
                events.push((c + 50, Axis::Y));
            }
        }
        for (c, axis) in events {
            pulse(&mut r, c, axis, 40);
        }
        let ax = r.max_accel(Axis::X).unwrap();
        assert!((ax - a).abs() / a < 0.02, "X accel {ax}");
        let ay = r.max_accel(Axis::Y).unwrap();
        assert!((ay - 0.37 * a).abs() < 0.05 * a, "Y accel {ay}");
        // Cruise velocity of X is 20 000 steps/s.
        let vmax = r.velocity_profile(Axis::X, 0.01).iter().map(|p| p.1).fold(0.0, f64::max);
        assert!((vmax - 20_000.0).abs() < 200.0, "{vmax}");
    }
}
