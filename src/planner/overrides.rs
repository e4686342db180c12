//! The feed and rapid overrides (grbl 1.1's realtime overrides): a new
//! override gives every queued block its nominal speed again and each
//! junction its entry limit, then re-plans the ring from the executing block.

use super::axis_cache::{INV_MAX_STEP_RATE, INV_MIN_STEP_RATE};
use super::block::Block;
use super::junction::{cos_theta, junction_sqr, reversing};
use super::ring::{next_index, Planner};
use crate::config::{Settings, MAX_STEP_RATE_HZ, MIN_STEP_RATE_HZ};
use crate::math::float_bits::{abs_f32, lt_nn, max_nn, min_nn};
use crate::math::sqrt_1ulp;
use crate::N_AXES;

impl Planner {
    /// The feed override (percent) and the rapid override (100, 50 or 25)
    /// from now on, for the queued moves too (grbl's realtime overrides:
    /// `plan_update_velocity_profile_parameters`, then a re-plan from the
    /// executing block). Each block that follows an override gets its
    /// nominal speed again, from its programmed feed and its limits (per
    /// axis and step rate, from its steps), and each junction its entry
    /// limit; the executing block keeps its current speed, and prep
    /// recomputes its profile ([`Planner::take_exec_replanned`]): it slows
    /// down or speeds up at the block's acceleration. AVR cost: a square
    /// root and two or three divisions per queued block, a few ms for a
    /// full ring; only when an override changes.
    pub fn set_overrides(&mut self, feed_pct: u16, rapid_pct: u8, s: &Settings) {
        if feed_pct == self.feed_pct && rapid_pct == self.rapid_pct {
            return;
        }
        self.flush(s);
        self.feed_pct = feed_pct;
        self.rapid_pct = rapid_pct;
        self.feed_cache = (0, 0.0, 0);
        let ax = &self.axis;
        // (unit vector, F_CPU / acceleration, nominal speed², (moving axes, directions))
        // of the block before.
        let mut prev: Option<([f32; N_AXES], _, _, _)> = None;
        let mut i = self.tail;
        for _ in 0..self.len {
            let b = &mut self.blocks[i as usize];
            let steps = b.steps();
            // The unit vector and the length, from the steps.
            let mut unit = [0f32; N_AXES];
            let mut moving = 0u8;
            let mut xyz_sqr = 0.0f32;
            for a in 0..N_AXES {
                if steps[a] != 0 {
                    moving |= 1 << a;
                    let v = steps[a] as f32 * ax.mm_per_step[a];
                    unit[a] = if b.direction_bits() & (1 << a) != 0 { -v } else { v };
                    if a < 3 {
                        xyz_sqr += v * v;
                    }
                }
            }
            let mm = if xyz_sqr.to_bits() != 0 { sqrt_1ulp(xyz_sqr) } else { abs_f32(unit[3]) };
            let inv_mm = 1.0 / mm;
            for u in unit.iter_mut() {
                *u *= inv_mm;
            }
            if b.has(Block::RAPID) || b.feed != 0 {
                let mut t_axes = 0.0f32;
                for a in 0..N_AXES {
                    if moving & (1 << a) != 0 {
                        t_axes = max_nn(t_axes, abs_f32(unit[a]) * ax.inv_max_speed[a]);
                    }
                }
                let mut t = if b.has(Block::RAPID) {
                    t_axes * (100.0 / rapid_pct as f32)
                } else {
                    max_nn(t_axes, 6000.0 / (b.feed as f32 * feed_pct as f32))
                };
                let steps_per_mm = b.step_event_count() as f32 * inv_mm;
                if lt_nn(t * MAX_STEP_RATE_HZ, steps_per_mm) {
                    t = steps_per_mm * INV_MAX_STEP_RATE;
                } else if lt_nn(steps_per_mm, t * MIN_STEP_RATE_HZ) {
                    t = steps_per_mm * INV_MIN_STEP_RATE;
                }
                let v = 1.0 / t;
                b.nominal_speed_sqr = v * v;
            }
            let nominal = b.nominal_speed_sqr;
            let dir = b.direction_bits() & moving;
            if let (Some((pu, pa, pn, p_axes)), true) = (prev, i != self.tail) {
                let mut same_dir = true;
                for a in 0..N_AXES {
                    same_dir &= unit[a].to_bits() == pu[a].to_bits();
                }
                let cap = min_nn(nominal, pn);
                let reversing = reversing(p_axes, (moving, dir));
                let k = b.dv_cycles;
                let min_accel = || crate::math::div_cold(crate::F_CPU, max_nn(k, pa));
                let e_axis = (moving | p_axes.0) & 0b1000 != 0;
                let cos = || cos_theta(&pu, &unit, moving);
                let j = junction_sqr(same_dir, cos, e_axis, reversing, || (pu, unit), min_accel, cap, &mut self.cap_sqr_cache, s);
                b.max_entry_speed_sqr = min_nn(j, cap);
            }
            prev = Some((unit, b.dv_cycles, nominal, (moving, dir)));
            i = next_index(i);
        }
        if let Some((_, _, n, _)) = prev {
            self.previous_nominal_speed_sqr = n;
        }
        self.replan();
    }

    /// The feed override in force, percent.
    pub fn feed_override(&self) -> u16 {
        self.feed_pct
    }

    /// The rapid override in force, percent.
    pub fn rapid_override(&self) -> u8 {
        self.rapid_pct
    }
}
