//! The per-axis values the planner derives from the settings (mm per step,
//! inverse acceleration and speed limits, which axes share axis 0's limits),
//! recomputed only when the settings change, and the step-rate limits as time
//! per step.

use crate::config::{Settings, MAX_STEP_RATE_HZ, MIN_STEP_RATE_HZ};
use crate::N_AXES;

/// s per step at the ISR's max rate.
pub(super) const INV_MAX_STEP_RATE: f32 = 1.0 / MAX_STEP_RATE_HZ;
/// s per step at the timer's min rate.
pub(super) const INV_MIN_STEP_RATE: f32 = 1.0 / MIN_STEP_RATE_HZ;

/// Per-axis values derived from the settings, recomputed only when the settings
/// change (saves 2–3 divisions per axis and block on the AVR).
#[derive(Clone, Copy, Debug)]
pub(super) struct AxisCache {
    /// Bits of steps_per_mm, accel_mm_per_s2, max_feed_mm_per_min they were made from.
    pub(super) src: [[u32; N_AXES]; 3],
    /// mm per step.
    pub(super) mm_per_step: [f32; N_AXES],
    /// 1 / max acceleration, s²/mm.
    pub(super) inv_accel: [f32; N_AXES],
    /// 1 / max speed, s/mm.
    pub(super) inv_max_speed: [f32; N_AXES],
    /// Time per mm above which an X/Y/Z move can never hit the step-rate cap
    /// (1 % above the largest steps/mm over `MAX_STEP_RATE_HZ`), s/mm: such a
    /// move may be planned later
    /// ([`Planner::accept_line`](super::Planner::accept_line)).
    pub(super) defer_min_inv_feed: f32,
    /// Times per mm (s/mm) between which an X/Y/Z move meets neither
    /// step-rate limit: from `defer_min_inv_feed` up to 1 % below
    /// min(steps/mm) / (√3 · `MIN_STEP_RATE_HZ`) (along any X/Y/Z path the
    /// dominant axis makes at least min(steps/mm) / √3 steps per mm).
    pub(super) rate_free_inv_feed: (f32, f32),
    /// X, Y and Z have the same steps/mm (bit for bit).
    pub(super) xyz_same_steps: bool,
    /// Bit i: axis i has the acceleration and speed limits of axis 0 (bit
    /// for bit). A move on such axes alone takes its limits from its
    /// largest unit component: two multiplies instead of two per axis.
    pub(super) uniform: u8,
}

impl AxisCache {
    pub(super) const EMPTY: AxisCache = AxisCache {
        src: [[0; N_AXES]; 3],
        mm_per_step: [0.0; N_AXES],
        inv_accel: [0.0; N_AXES],
        inv_max_speed: [0.0; N_AXES],
        defer_min_inv_feed: 0.0,
        rate_free_inv_feed: (0.0, 0.0),
        xyz_same_steps: false,
        uniform: 0,
    };

    /// Recompute the derived values if `s` differs from what they came from.
    /// True if it did.
    pub(super) fn refresh(&mut self, s: &Settings) -> bool {
        let mut same = true;
        for i in 0..N_AXES {
            same &= self.src[0][i] == s.steps_per_mm[i].to_bits()
                && self.src[1][i] == s.accel_mm_per_s2[i].to_bits()
                && self.src[2][i] == s.max_feed_mm_per_min[i].to_bits();
        }
        if same {
            return false;
        }
        for i in 0..N_AXES {
            self.src[0][i] = s.steps_per_mm[i].to_bits();
            self.src[1][i] = s.accel_mm_per_s2[i].to_bits();
            self.src[2][i] = s.max_feed_mm_per_min[i].to_bits();
            self.mm_per_step[i] = 1.0 / s.steps_per_mm[i];
            self.inv_accel[i] = 1.0 / s.accel_mm_per_s2[i];
            self.inv_max_speed[i] = 60.0 / s.max_feed_mm_per_min[i];
        }
        // Along any X/Y/Z path the dominant axis makes at most its own
        // steps/mm (the path is at least as long as that axis' share).
        let mut spm = 0.0f32;
        for i in 0..3 {
            if s.steps_per_mm[i] > spm {
                spm = s.steps_per_mm[i];
            }
        }
        self.defer_min_inv_feed = 1.01 * spm * INV_MAX_STEP_RATE;
        let mut spm_min = s.steps_per_mm[0];
        for i in 1..3 {
            if s.steps_per_mm[i] < spm_min {
                spm_min = s.steps_per_mm[i];
            }
        }
        // 0.99 / √3.
        let hi = 0.571_577 * spm_min * INV_MIN_STEP_RATE;
        // An empty range (lo > hi, or settings not valid) tests every move.
        self.rate_free_inv_feed = if hi.is_finite() && hi > self.defer_min_inv_feed { (self.defer_min_inv_feed, hi) } else { (1.0, 0.0) };
        self.xyz_same_steps =
            s.steps_per_mm[1].to_bits() == s.steps_per_mm[0].to_bits() && s.steps_per_mm[2].to_bits() == s.steps_per_mm[0].to_bits();
        self.uniform = 0;
        for i in 0..N_AXES {
            if self.inv_accel[i].to_bits() == self.inv_accel[0].to_bits()
                && self.inv_max_speed[i].to_bits() == self.inv_max_speed[0].to_bits()
            {
                self.uniform |= 1 << i;
            }
        }
        true
    }
}
