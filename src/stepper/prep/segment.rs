//! The segment loop (grbl's): the next segment cut off the executing block
//! along its profile, its ticks timed from the previous segment's last
//! tick to this one's last whole step.

use super::timer::{ceil_u32, timer_for};
use super::{Prep, Ramp, CRUISE_SEGMENT_TIME_S, F_CPU, RAMP_END_EPSILON, REQ_STEPS_PER_SEGMENT, SEGMENT_TIME_S};
use crate::math::float_bits::abs_f32;
use crate::math::sqrt_1ulp;
use crate::planner::Planner;
use crate::stepper::Segment;

impl Prep {
    /// Cut the next segment off the executing block (grbl's segment loop).
    /// `None` when the hold has stopped or the piece had no step.
    pub(super) fn make_segment(&mut self, pl: &mut Planner) -> Option<Segment> {
        // (`fraction_time` and `write_back` below read the field it fills.)
        let a = self.accel();
        let b = pl.current_block_mut()?;
        let mut dt_max = if self.ramp == Ramp::Cruise { CRUISE_SEGMENT_TIME_S } else { SEGMENT_TIME_S };
        let mut dt = 0.0f32;
        let mut time_var = dt_max;
        let mut mm_remaining = b.millimeters;
        let mm_segment_start = mm_remaining;
        loop {
            let mm_start = mm_remaining;
            match self.ramp {
                Ramp::DecelOverride => {
                    let speed_var = a * time_var;
                    let mm_var = time_var * (self.current_speed - 0.5 * speed_var);
                    mm_remaining -= mm_var;
                    if mm_remaining < self.accelerate_until || mm_var <= 0.0 {
                        mm_remaining = self.accelerate_until;
                        time_var = 2.0 * (mm_start - mm_remaining) / (self.current_speed + self.maximum_speed);
                        self.ramp = Ramp::Cruise;
                        self.current_speed = self.maximum_speed;
                    } else {
                        self.current_speed -= speed_var;
                    }
                }
                Ramp::Accel => {
                    let speed_var = a * time_var;
                    mm_remaining -= time_var * (self.current_speed + 0.5 * speed_var);
                    if mm_remaining < self.accelerate_until {
                        mm_remaining = self.accelerate_until;
                        time_var = 2.0 * (mm_start - mm_remaining) / (self.current_speed + self.maximum_speed);
                        self.ramp = if mm_remaining == self.decelerate_after { Ramp::Decel } else { Ramp::Cruise };
                        self.current_speed = self.maximum_speed;
                    } else {
                        self.current_speed += speed_var;
                    }
                }
                Ramp::Cruise => {
                    let mm_var = mm_remaining - self.maximum_speed * time_var;
                    if mm_var < self.decelerate_after {
                        time_var = (mm_remaining - self.decelerate_after) / self.maximum_speed;
                        mm_remaining = self.decelerate_after;
                        self.ramp = Ramp::Decel;
                        // End the segment here (or one ramp segment later if it
                        // has no step yet).
                        dt_max = dt + time_var;
                    } else {
                        mm_remaining = mm_var;
                    }
                }
                Ramp::Decel => {
                    let speed_var = a * time_var;
                    let mut in_ramp = false;
                    if self.current_speed > speed_var {
                        let mm_var = mm_remaining - time_var * (self.current_speed - 0.5 * speed_var);
                        // Float residue (a millionth of a step left at almost zero
                        // speed) would make the last piece take ages: end here.
                        if (mm_var - self.mm_complete) * self.step_per_mm > RAMP_END_EPSILON {
                            mm_remaining = mm_var;
                            self.current_speed -= speed_var;
                            in_ramp = true;
                        }
                    }
                    if !in_ramp {
                        // End of the block or of the hold's deceleration.
                        let v = self.current_speed + self.exit_speed;
                        time_var = if v > 0.0 { 2.0 * (mm_remaining - self.mm_complete) / v } else { 0.0 };
                        mm_remaining = self.mm_complete;
                        self.current_speed = self.exit_speed;
                    }
                }
            }
            dt += time_var;
            if dt < dt_max {
                time_var = dt_max - dt;
            } else if mm_remaining > 0.0 && (mm_segment_start - mm_remaining) * self.step_per_mm < REQ_STEPS_PER_SEGMENT {
                // Too slow for a step yet: stretch the segment.
                dt_max += SEGMENT_TIME_S;
                time_var = dt_max - dt;
            } else {
                break;
            }
            if mm_remaining <= self.mm_complete {
                break;
            }
        }

        let step_dist_remaining = self.step_per_mm * mm_remaining;
        let mut n_steps_remaining = ceil_u32(step_dist_remaining);
        if n_steps_remaining > self.steps_remaining {
            n_steps_remaining = self.steps_remaining;
        }
        if mm_remaining <= 0.0 {
            n_steps_remaining = 0;
        }
        let ticks = self.steps_remaining - n_steps_remaining;
        let profile_done = mm_remaining == self.mm_complete;

        if ticks == 0 {
            if self.holding {
                // Stopped less than a step before the hold point: the stop is
                // complete; keep the block as it was (grbl).
                self.held = true;
                return None;
            }
            // A piece with no whole step: carry its time, keep going.
            self.dt_remainder += dt;
            self.write_back(b, mm_remaining);
            if profile_done && mm_remaining <= 0.0 {
                self.finish_block(pl);
            }
            return None;
        }

        // The ticks run from the previous segment's last tick (dt_remainder
        // before this segment's start) to this segment's last tick, which comes
        // `tail` before its end: the time to cover the fraction of a step left.
        let window = dt + self.dt_remainder;
        let frac = n_steps_remaining as f32 - step_dist_remaining;
        let n = ticks as f32;
        let inv_rate; // s per step event
        if frac > 0.0 && mm_remaining > 0.0 {
            // tail = time to cover `frac` steps ending at speed v with
            // acceleration ±a: frac = v·t ∓ a·t²/2. To second order in a·frac/v²,
            // t = 2·frac·v / (2v² ± a·frac) = N / D, and then
            // inv_rate = (window − N/D) / n = (window·D − N) / (D·n): one division.
            let v = self.current_speed * self.step_per_mm; // steps/s at the end
            let v2 = v * v;
            let x = match self.ramp {
                Ramp::Accel => -(self.acceleration * self.step_per_mm * frac),
                Ramp::Decel => self.acceleration * self.step_per_mm * frac,
                _ => 0.0,
            };
            let num = 2.0 * frac * v;
            let den = 2.0 * v2 + x;
            // Well conditioned (|x| ≤ v²/4) and the last tick after mid-window.
            if 4.0 * abs_f32(x) < v2 && num < 0.5 * window * den {
                inv_rate = (window * den - num) / (den * n);
                self.dt_remainder = window - inv_rate * n;
            } else {
                // Near a stop: exact, with a square root.
                let tail = self.fraction_time(frac, window);
                inv_rate = (window - tail) / n;
                self.dt_remainder = tail;
            }
        } else {
            inv_rate = window / n;
            self.dt_remainder = 0.0;
        }
        self.steps_remaining = n_steps_remaining;
        let (period, prescale) = timer_for(F_CPU * inv_rate);
        debug_assert!(ticks <= u16::MAX as u32);
        let seg = Segment { ticks: ticks as u16, period, prescale };

        self.write_back(b, mm_remaining);
        if profile_done {
            if mm_remaining > 0.0 {
                // A hold stopped inside the block.
                self.held = true;
            } else {
                self.finish_block(pl);
            }
        }
        Some(seg)
    }

    /// Time to cover the last `frac` (< 1) step of a segment that ends at the
    /// current speed, s: the last tick comes that long before the segment ends.
    /// grbl charges it at the segment's mean speed, which puts the last tick of
    /// every ramp segment early (accelerating) or late (decelerating).
    fn fraction_time(&self, frac: f32, window: f32) -> f32 {
        let v = self.current_speed * self.step_per_mm; // steps/s at the end
        let t = if self.ramp == Ramp::Decel {
            // Decelerating into the end: frac = v·t + a·t²/2.
            let a = self.acceleration * self.step_per_mm;
            2.0 * frac / (v + sqrt_1ulp(v * v + 2.0 * a * frac))
        } else if v > 0.0 {
            frac / v
        } else {
            0.0
        };
        // Never let the last tick come before the window's midpoint.
        let max = 0.5 * window;
        if t > max {
            max
        } else {
            t
        }
    }
}
