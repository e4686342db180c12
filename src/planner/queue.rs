//! Queuing a move (grbl's `plan_buffer_line`): from a target in steps and a
//! speed to a [`Block`] in the ring, with its backlash take-up, path length
//! and unit vector, acceleration and nominal speed (per-axis and step-rate
//! limits) and its junction with the previous block; then the look-ahead. A
//! plain feed move may be accepted now and planned on the next call
//! ([`Planner::accept_line`]).

use super::axis_cache::{INV_MAX_STEP_RATE, INV_MIN_STEP_RATE};
use super::block::{Block, PlanError, Push, Speed, Steps24};
use super::junction::{cos_theta, junction_sqr, previous_unit, reversing, short_cos, short_unit};
use super::ring::{next_index, Planner, Short, BLOCK_BUFFER_LEN, SHORTS_LEN};
use crate::config::{Settings, MAX_STEP_RATE_HZ, MIN_STEP_RATE_HZ};
use crate::math::float_bits::{abs_f32, lt_nn, max_nn, min_nn, times2};
use crate::math::{round_i32, sqrt_1ulp};
use crate::{F_CPU, N_AXES};

/// (s/mm at `feed` mm/min times `pct` %, the feed rounded) for the feed
/// cache. Not inlined: LLVM-AVR hoisted the rounding's soft-float calls
/// above the cache test, so every move paid for them.
// speed: inlined, (f + 0.5) as u16 ran on every move (~300 cycles)
#[inline(never)]
fn feed_entry(feed: f32, pct: u16) -> (f32, u16) {
    (crate::math::div_cold(6000.0, feed * pct as f32), ((feed + 0.5) as u16).max(1))
}

/// The [`Short`] for Σd² = `sum_sqr` ≥ 1 and `n` dominant steps, as
/// `queue_block` would compute it without the cache (the twin test
/// `a_cached_short_move_is_planned_as_computed`). Not inlined: behind a
/// cache test LLVM-AVR would compute it every time (`math::div_cold`).
// speed: inlined (LLVM's choice), the cache miss is computed on every call
#[inline(never)]
fn short_entry(sum_sqr: u32, n: u32, ax: &super::axis_cache::AxisCache, a0: f32) -> Short {
    let root = sqrt_1ulp(sum_sqr as f32);
    let inv_root = 1.0 / root;
    let mm = root * ax.mm_per_step[0];
    // |u|max: the dominant axis' n·(1/√S), the very product its unit
    // component takes (`the_largest_unit_component_is_the_dominant_axis_share`).
    let u_max = n as f32 * inv_root;
    // a₀·√S·(1/n), 1/n from a table for short moves (two multiplies).
    let inv_accel = u_max * ax.inv_accel[0];
    let accel = match crate::math::recip_small(n) {
        Some(r) => a0 * root * r,
        None => 1.0 / inv_accel,
    };
    Short {
        sum_sqr,
        n: n as u16,
        inv_root,
        mm,
        accel,
        dv_cycles: inv_accel * F_CPU,
        t_axes: u_max * ax.inv_max_speed[0],
        max_delta: times2(accel * mm),
    }
}

/// The backlash take-up of the `reversing` axes (bits; `dir`: the new
/// directions, bit set = negative) into `out`, steps; false if none has a
/// backlash of a step or more.
// speed: inlined, so that the common path (no reversal) does not clear an array
#[inline(always)]
fn take_up_steps(reversing: u8, dir: u8, s: &Settings, out: &mut [i32; N_AXES]) -> bool {
    let mut any = false;
    for i in 0..3 {
        if reversing & (1 << i) != 0 && s.backlash_mm[i] > 0.0 {
            let n = round_i32(s.backlash_mm[i] * s.steps_per_mm[i]);
            if n > 0 {
                out[i] = if dir & (1 << i) != 0 { -n } else { n };
                any = true;
            }
        }
    }
    any
}

impl Planner {
    /// Queue a straight move to `target` (absolute steps, X Y Z E) at
    /// `feed_mm_per_min` (mm/min along the path, ignored when `rapid`: then each
    /// axis may run at its max feed). Zero-length moves queue nothing.
    pub fn push_line(&mut self, target: [i32; N_AXES], feed_mm_per_min: f32, rapid: bool, s: &Settings) -> Result<Push, PlanError> {
        self.push(&target, if rapid { Speed::Rapid } else { Speed::Feed(feed_mm_per_min) }, s, false)
    }

    /// [`Planner::push_line`] at `speed`.
    pub fn push_move(&mut self, target: [i32; N_AXES], speed: Speed, s: &Settings) -> Result<Push, PlanError> {
        self.push(&target, speed, s, false)
    }

    /// [`Planner::push_line`] for the firmware, which calls
    /// [`Planner::settings_changed`] whenever it replaces the settings. A plain
    /// feed move (X/Y/Z, no
    /// backlash take-up, too slow to ever be rate-capped, so nothing to
    /// report but `queued`) is only accepted:
    /// it takes its slot and moves [`Planner::position`], and is planned by
    /// the next [`Planner::flush`] (which the next accept does first, and
    /// prep's caller before taking segments). The firmware sends `ok` in
    /// between, so a host that waits for it (ping-pong) sends the next line
    /// while this one is planned (~10 k cycles on the AVR).
    pub fn accept_line(&mut self, target: &[i32; N_AXES], speed: Speed, s: &Settings) -> Result<Push, PlanError> {
        self.push(target, speed, s, true)
    }

    /// [`Planner::push_move`] (`may_defer` false) or [`Planner::accept_line`].
    fn push(&mut self, target: &[i32; N_AXES], speed: Speed, s: &Settings, may_defer: bool) -> Result<Push, PlanError> {
        let rapid = speed == Speed::Rapid;
        let (feed_mm_per_min, pct, follows) = match speed {
            Speed::Rapid => (0.0, 100, false),
            Speed::Feed(f) => (f, self.feed_pct, true),
            Speed::Fixed(f) => (f, 100, false),
        };
        let (inv_feed, programmed) = if rapid {
            (0.0, 0)
        } else {
            // 0 < feed < ∞ on the bits: positive finite floats are 1 ..
            // 0x7F7F_FFFF (no soft-float compare).
            if feed_mm_per_min.to_bits().wrapping_sub(1) >= 0x7F7F_FFFF {
                return Err(PlanError::BadFeed);
            }
            // s/mm at the feed times the override: 6000 / (feed · percent),
            // and the feed rounded for the block (`Block::feed`). The key:
            // the feed's bits (a feed is > 0: the sign bit is free) and
            // whether the override applies; `set_overrides` clears it.
            let bits = feed_mm_per_min.to_bits() | ((pct != 100) as u32) << 31;
            if self.feed_cache.0 != bits {
                let (inv, rounded) = feed_entry(feed_mm_per_min, pct);
                self.feed_cache = (bits, inv, rounded);
            }
            (self.feed_cache.1, if follows { self.feed_cache.2 } else { 0 })
        };

        // The move accepted before this one is planned first (it holds
        // `self.delta`).
        self.flush(s);
        // The steps go straight into `self.delta`, where the block is built
        // from, now or when it is flushed: no copy.
        let mut moving = 0u8;
        let mut dir = 0u8;
        // Non-zero when an axis moves more than a block holds
        // (`Block::MAX_STEPS`: the top byte of d + 2²³ is zero within it).
        let mut over = 0u8;
        // One axis, written out (as `queue_block`'s `count_axis`).
        macro_rules! delta_axis {
            ($i:literal) => {{
                let d = target[$i].wrapping_sub(self.position[$i]);
                self.delta[$i] = d;
                over |= ((d as u32).wrapping_add(1 << 23) >> 24) as u8;
                if d != 0 {
                    moving |= 1 << $i;
                    if d < 0 {
                        dir |= 1 << $i;
                    }
                }
            }};
        }
        delta_axis!(0);
        delta_axis!(1);
        delta_axis!(2);
        delta_axis!(3);
        if moving == 0 {
            return Ok(Push::default());
        }
        if over != 0 {
            return Err(PlanError::TooLong);
        }

        // Backlash: axes that reverse with a known previous direction.
        let reversing = moving & self.dir_known & (dir ^ self.last_dir);
        let take_up_any = reversing != 0 && take_up_steps(reversing, dir, s, &mut [0; N_AXES]);
        let need = 1 + take_up_any as usize;
        if BLOCK_BUFFER_LEN - (self.len as usize) < need {
            return Err(PlanError::Full);
        }
        // The slot(s) this move takes, deferred or not, carry its line.
        self.blocks[self.head as usize].line = self.line_tag;
        if take_up_any {
            self.blocks[next_index(self.head) as usize].line = self.line_tag;
        }

        if !(may_defer && self.axis_fresh) {
            if self.axis.refresh(s) {
                // Limits changed: the same direction no longer means the same
                // limits, nor the same short move the same values.
                self.previous_limits_valid = false;
                self.shorts = [Short::EMPTY; SHORTS_LEN];
            }
            self.axis_fresh = may_defer;
        }
        let mut push = Push::default();
        if may_defer && !take_up_any && !rapid && moving & 0b1000 == 0 && lt_nn(self.axis.defer_min_inv_feed, inv_feed) {
            // Never capped (see `AxisCache::defer_min_inv_feed`); floored or
            // not, which is not reported, prep runs it the same.
            self.pending = Some((inv_feed, programmed));
            push.queued = 1;
        } else {
            if take_up_any {
                let mut take_up = [0; N_AXES];
                take_up_steps(reversing, dir, s, &mut take_up);
                let delta = core::mem::replace(&mut self.delta, take_up);
                let (capped, floored) = self.queue_block(0.0, Block::TAKE_UP, 0, s);
                self.delta = delta;
                for i in 0..3 {
                    self.backlash_offset[i] += take_up[i];
                }
                push.queued += 1;
                push.rate_capped |= capped;
                push.rate_floored |= floored;
            }
            let flags = if rapid { Block::RAPID } else { 0 };
            let (capped, floored) = self.queue_block(inv_feed, flags, programmed, s);
            push.queued += 1;
            push.rate_capped |= capped;
            push.rate_floored |= floored;
        }
        crate::math::copy16(&mut self.position, target);
        self.last_dir = (self.last_dir & !moving) | (dir & moving);
        self.dir_known |= moving;
        if !may_defer {
            self.recalculate();
        }
        Ok(push)
    }

    /// The first piece of a move to `target` that has more steps on some
    /// axis than a block holds ([`PlanError::TooLong`]; [`Block::MAX_STEPS`],
    /// 21 m at 400 steps/mm: only a runaway target without soft limits
    /// asks for it): along its line from [`Planner::position`], the move
    /// halved until it fits, ending within a step of the line.
    // flash: the split stays out of the per-line path
    #[inline(never)]
    pub fn first_piece(&self, target: &[i32; N_AXES]) -> [i32; N_AXES] {
        let mut shift = 1;
        loop {
            let mut piece = [0i32; N_AXES];
            let mut fits = true;
            for i in 0..N_AXES {
                // Rounded: each axis within half a step of its share.
                let d = (target[i] as i64 - self.position[i] as i64 + (1 << (shift - 1))) >> shift;
                fits &= -(Block::MAX_STEPS as i64) <= d && d < Block::MAX_STEPS as i64;
                piece[i] = (self.position[i] as i64 + d) as i32;
            }
            if fits {
                return piece;
            }
            shift += 1;
        }
    }

    /// The settings changed: the next [`Planner::accept_line`] compares them
    /// with what the per-axis cache was made from ([`Planner::push_line`]
    /// always does).
    pub fn settings_changed(&mut self) {
        self.axis_fresh = false;
    }

    /// Plan the move [`Planner::accept_line`] left pending, if any (with the
    /// settings it was accepted under: the per-axis cache is as it was then).
    pub fn flush(&mut self, s: &Settings) {
        if let Some((inv_feed, programmed)) = self.pending.take() {
            self.queue_block(inv_feed, 0, programmed, s);
        }
    }

    /// Build a block for `self.delta` (steps, not all zero) at `inv_feed` s/mm (0 =
    /// rapid), link it to the previous one and re-plan. Returns (rate capped,
    /// rate floored). The caller has checked there is room.
    ///
    /// AVR cost (simavr, 16 MHz, see the module doc): ~9–13 k cycles including
    /// the re-plan; every f32 multiply is ~170 cycles, a divide or sqrt ~500.
    fn queue_block(&mut self, inv_feed: f32, flags: u8, feed: u16, s: &Settings) -> (bool, bool) {
        let delta = &self.delta;
        let prev_nominal_sqr = self.previous_nominal_speed_sqr;
        let prev_accel = (self.previous_acceleration, self.previous_dv_cycles);
        let prev_t_axes = self.previous_t_axes;
        let prev_valid = self.previous_limits_valid;
        let first = self.len == 0;
        let ax = &self.axis;
        // Built in place in its slot.
        let b = &mut self.blocks[self.head as usize];
        b.feed = feed;
        b.entry_speed_sqr = 0.0;
        // Counted in registers, stored once.
        let mut moving = 0u8;
        let mut dir = 0u8;
        let mut step_event_count = 0u32;
        let mut dominant = 0u8;
        // Σd² of X, Y and Z in 16 bits an axis, for a short move (below):
        // summed here, where each delta is in registers (a loop reading
        // them again: `profile --count 254 --feed 12000 --accel 5000
        // --trace 300:1500` 53 cycles a line more, for 100 B less flash).
        let mut sum_sqr = 0u32;
        // One axis, its index and bit constants: written out, ~100 cycles
        // a block fewer on the AVR than the loop (which indexed and
        // shifted at run time).
        macro_rules! count_axis {
            ($i:literal) => {{
                let d = delta[$i];
                let n = d.unsigned_abs();
                if $i < 3 {
                    // (Wrapping: a long move's garbage is not used.)
                    sum_sqr = sum_sqr.wrapping_add(crate::math::mul_u16(n as u16, n as u16));
                }
                b.steps[$i] = Steps24::new(n);
                if n > step_event_count {
                    step_event_count = n;
                    dominant = $i << Block::DOMINANT_SHIFT;
                }
                if d != 0 {
                    moving |= 1 << $i;
                    if d < 0 {
                        dir |= 1 << $i;
                    }
                }
            }};
        }
        count_axis!(0);
        count_axis!(1);
        count_axis!(2);
        count_axis!(3);
        b.bits = dir | flags | dominant;
        // Path length and unit vector.
        let (mm, inv_mm);
        let mut unit = [0.0f32; N_AXES];
        // The cached values of a short move: see below.
        let mut short: Option<&Short> = None;
        // A short move's deltas (`self.delta`) and 1/√Σd² stand for its
        // unit vector (`short_cos`; `inv_root` 0: `unit` holds it, or
        // must be made by `short_unit` where something needs it).
        let mut inv_root = 0.0f32;
        if moving & 0b1000 == 0 && ax.xyz_same_steps && step_event_count < 0x8000 {
            // X/Y/Z at one steps/mm: the length is √(Σd²) steps, and a stream
            // of short moves repeats a few dozen values of the integer Σd²,
            // whose root, inverse root and what follows from them are cached
            // ([`Short`]): no square root, no division and five multiplies
            // fewer (~1.7 k cycles on the AVR) on a hit.
            // Any entry may hold it; a miss replaces the oldest (first in,
            // first out: the circle's chords come back in runs).
            let n16 = step_event_count as u16;
            let i = match self.shorts.iter().position(|e| e.sum_sqr == sum_sqr && e.n == n16) {
                Some(i) => i,
                None => {
                    let i = self.short_next as usize & (SHORTS_LEN - 1);
                    self.short_next = (i as u8 + 1) & (SHORTS_LEN as u8 - 1);
                    self.shorts[i] = short_entry(sum_sqr, step_event_count, ax, s.accel_mm_per_s2[0]);
                    i
                }
            };
            let e = &self.shorts[i];
            mm = e.mm;
            short = Some(e);
            // 1/mm = (1/√S)·steps/mm: only the step-rate test needs it.
            inv_mm = e.inv_root;
            if n16 < 0x4000 {
                inv_root = e.inv_root;
            } else {
                // Too long for `short_cos`' integers.
                unit = short_unit(delta, e.inv_root);
            }
        } else {
            // Path length: XYZ distance, or the E distance for an E-only move.
            // (Zero components are skipped: a multiply costs ~170 cycles on the AVR.)
            for i in 0..N_AXES {
                if moving & (1 << i) != 0 {
                    unit[i] = delta[i] as f32 * ax.mm_per_step[i];
                }
            }
            let mut xyz_sqr = 0.0f32;
            for i in 0..3 {
                if moving & (1 << i) != 0 {
                    xyz_sqr += unit[i] * unit[i];
                }
            }
            mm = if xyz_sqr.to_bits() != 0 { sqrt_1ulp(xyz_sqr) } else { abs_f32(unit[3]) };
            inv_mm = 1.0 / mm;
            for i in 0..N_AXES {
                if moving & (1 << i) != 0 {
                    unit[i] *= inv_mm;
                }
            }
        }
        // Both short: the junction from the deltas. Otherwise the unit
        // vectors, the previous one made from its deltas if it was short.
        let prev_short = self.previous_inv_root.to_bits() != 0;
        let from_deltas = inv_root.to_bits() != 0 && prev_short;
        if inv_root.to_bits() != 0 && (!prev_short || moving & !ax.uniform != 0) {
            unit = short_unit(delta, inv_root);
        }
        let prev_unit = || previous_unit(&self.previous_unit_vec, &self.previous_delta, self.previous_inv_root);
        // Stops at the first axis that differs: a stream of chords changes
        // direction on every move (~110 cycles a line on the AVR). Two
        // short moves: the same deltas (a move in the same direction but
        // of another length is a junction, straight by the rule).
        let same_dir = prev_valid
            && if from_deltas {
                delta[0] as i16 == self.previous_delta[0]
                    && delta[1] as i16 == self.previous_delta[1]
                    && delta[2] as i16 == self.previous_delta[2]
            } else {
                unit.iter().zip(&prev_unit()).all(|(u, p)| u.to_bits() == p.to_bits())
            };

        // Per-axis limits: the path may go at most as fast (and accelerate at most
        // as hard) as the slowest axis allows, scaled by its share of the motion.
        // They depend on the direction only: a block in the same direction as the
        // last one (a stream of collinear moves) reuses them.
        // A short move's cached 2·a·mm, when its acceleration is the cached one.
        let mut max_delta = None;
        // (The acceleration, F_CPU over it: from the one division.)
        let ((acceleration, dv_cycles), t_axes) = if same_dir {
            (prev_accel, prev_t_axes)
        } else if moving & !ax.uniform == 0 {
            // Every moving axis has axis 0's limits: the largest |u| decides
            // (exactly: rounding keeps the order of the products).
            if let Some(e) = short {
                max_delta = Some(e.max_delta);
                ((e.accel, e.dv_cycles), e.t_axes)
            } else {
                let mut u_max = 0.0f32;
                for u in &unit {
                    u_max = max_nn(u_max, abs_f32(*u));
                }
                let inv_accel = u_max * ax.inv_accel[0];
                ((1.0 / inv_accel, inv_accel * F_CPU), u_max * ax.inv_max_speed[0])
            }
        } else {
            let mut inv_accel = 0.0f32; // s²/mm along the path
            let mut t_axes = 0.0f32; // s/mm along the path
            for i in 0..N_AXES {
                if moving & (1 << i) != 0 {
                    let u = abs_f32(unit[i]);
                    let ia = u * ax.inv_accel[i];
                    if lt_nn(inv_accel, ia) {
                        inv_accel = ia;
                    }
                    let t = u * ax.inv_max_speed[i];
                    if lt_nn(t_axes, t) {
                        t_axes = t;
                    }
                }
            }
            ((1.0 / inv_accel, inv_accel * F_CPU), t_axes)
        };
        let mut t = if lt_nn(t_axes, inv_feed) { inv_feed } else { t_axes };
        if flags & Block::RAPID != 0 && self.rapid_pct != 100 {
            t *= 100.0 / self.rapid_pct as f32;
        }
        // Step-rate limits: the dominant axis makes step_event_count steps
        // over mm. At time per mm t the rate stays within them while the
        // steps per mm of path lie within t·MIN_STEP_RATE_HZ and
        // t·MAX_STEP_RATE_HZ. An X/Y/Z move at a t within `AxisCache::rate_free_inv_feed` can meet
        // neither limit: then no test (a conversion and two multiplies).
        let mut capped = false;
        let mut floored = false;
        let (t_lo, t_hi) = ax.rate_free_inv_feed;
        if moving & 0b1000 != 0 || lt_nn(t, t_lo) || lt_nn(t_hi, t) {
            let mut steps_per_mm = step_event_count as f32 * inv_mm;
            if short.is_some() {
                steps_per_mm *= s.steps_per_mm[0];
            }
            if lt_nn(t * MAX_STEP_RATE_HZ, steps_per_mm) {
                t = steps_per_mm * INV_MAX_STEP_RATE;
                capped = true;
            } else if lt_nn(steps_per_mm, t * MIN_STEP_RATE_HZ) {
                t = steps_per_mm * INV_MIN_STEP_RATE;
                floored = true;
            }
        }
        // t is usually the same as for the last block (the feed is modal).
        if self.nominal_cache.0 != t.to_bits() {
            let v = crate::math::div_cold(1.0, t);
            self.nominal_cache = (t.to_bits(), v * v);
        }
        let nominal_speed_sqr = self.nominal_cache.1;

        // Junction with the previous block (grbl): max entry speed from the
        // junction deviation, never above either block's nominal speed.
        b.max_entry_speed_sqr = if first {
            0.0
        } else {
            let cap = min_nn(nominal_speed_sqr, prev_nominal_sqr);
            let reversing = reversing(self.previous_axes, (moving, dir));
            let unit_now = || if inv_root.to_bits() != 0 { short_unit(delta, inv_root) } else { unit };
            let junction_sqr = junction_sqr(
                same_dir,
                || {
                    if from_deltas {
                        short_cos(delta, inv_root, &self.previous_delta, self.previous_inv_root)
                    } else {
                        cos_theta(&prev_unit(), &unit, moving)
                    }
                },
                (moving | self.previous_axes.0) & 0b1000 != 0,
                reversing,
                || (prev_unit(), unit_now()),
                || min_nn(acceleration, prev_accel.0),
                cap,
                &mut self.cap_sqr_cache,
                s,
            );
            min_nn(junction_sqr, min_nn(nominal_speed_sqr, prev_nominal_sqr))
        };
        b.millimeters = mm;
        b.dv_cycles = dv_cycles;
        b.nominal_speed_sqr = nominal_speed_sqr;
        b.max_delta_speed_sqr = match max_delta {
            Some(d) => d,
            None => times2(acceleration * mm),
        };

        if inv_root.to_bits() != 0 {
            // One axis at a time: an array store went through `memcpy`.
            self.previous_delta[0] = delta[0] as i16;
            self.previous_delta[1] = delta[1] as i16;
            self.previous_delta[2] = delta[2] as i16;
        } else {
            crate::math::copy16(&mut self.previous_unit_vec, &unit);
        }
        self.previous_inv_root = inv_root;
        self.previous_axes = (moving, dir);
        self.previous_nominal_speed_sqr = nominal_speed_sqr;
        self.previous_acceleration = acceleration;
        self.previous_dv_cycles = dv_cycles;
        self.previous_t_axes = t_axes;
        self.previous_limits_valid = true;

        self.head = next_index(self.head);
        self.len += 1;
        self.stale = true;
        (capped, floored)
    }
}
