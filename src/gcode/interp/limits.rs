//! The travel checks of a move: soft limits on the target rounded to steps,
//! the tool magazine's keep-out zone, and the mm → steps conversion cache
//! that the checks and the queued move share ([`Interp::steps_of`]).

use super::error::Error;
use super::units::to_steps;
use super::Interp;
use crate::config::Settings;
use crate::N_AXES;

impl Interp {
    /// Absolute mm → absolute steps, rounded per axis (no accumulated
    /// error). An axis whose mm value is that of its last conversion reuses
    /// the result (a float multiply and a rounding, ~330 cycles on the AVR;
    /// a streamed XY move leaves Z and E where they were).
    pub fn steps_of(&mut self, s: &Settings, mm: &[f32; N_AXES]) -> [i32; N_AXES] {
        if !self.conv_fresh {
            self.refresh_conv(s);
        }
        steps_cached(&mut self.steps_cache, s, mm)
    }

    /// Soft limits: the target, rounded to steps as it will be queued, must
    /// lie within 0..=travel (rounded to steps) on X, Y and Z. Integer
    /// compares on the steps [`Interp::steps_of`] caches for the move itself.
    ///
    /// Through [`Interp::steps_of`], E converted too (its code is then in
    /// flash once): only arcs, canned cycles, compensation and the menu's
    /// jog come here; a move's target is checked by [`soft_limits`],
    /// inlined, which gives the same answer
    /// (`check_soft_limits_matches_the_inlined_check`).
    pub fn check_soft_limits(&mut self, s: &Settings, t: &[f32; N_AXES]) -> Result<(), Error> {
        let st = self.steps_of(s, t);
        if !s.soft_limits {
            return Ok(());
        }
        for a in 0..3 {
            if st[a] < 0 || st[a] > self.travel_steps[a] {
                return Err(Error::SoftLimit);
            }
        }
        Ok(())
    }

    /// [`Interp::target`] in steps (see [`Interp::steps_of`]).
    pub fn target_steps(&mut self, s: &Settings) -> [i32; N_AXES] {
        if !self.conv_fresh {
            self.refresh_conv(s);
        }
        steps_cached(&mut self.steps_cache, s, &self.run.target)
    }

    /// The settings changed: the step conversions are made afresh.
    pub fn settings_changed(&mut self) {
        self.conv_fresh = false;
    }

    /// Empty the steps cache (an all-ones pattern is a NaN, never a
    /// position) and convert the travel.
    pub(super) fn refresh_conv(&mut self, s: &Settings) {
        for c in self.steps_cache.iter_mut() {
            c.0 = u32::MAX;
        }
        for a in 0..3 {
            self.travel_steps[a] = to_steps(s.travel_mm[a], s.steps_per_mm[a]);
        }
        self.uncapped_feed_bits = uncapped_feed(s).to_bits();
        self.conv_fresh = true;
    }

    /// True when a feed move at `feed_mm_per_min` (100 % override) can
    /// never be slowed by the planner's step-rate cap, so that queuing it
    /// prints no warning (the firmware then sends the line's `ok` before
    /// queuing it). Conservative: false until the caches are fresh.
    #[inline]
    pub fn never_rate_capped(&self, feed_mm_per_min: f32) -> bool {
        // Positive floats order as their bits.
        self.conv_fresh && feed_mm_per_min.to_bits() <= self.uncapped_feed_bits
    }
}

/// The largest feed, mm/min, at which no axis can step faster than
/// `MAX_STEP_RATE_HZ` less 1 % (an axis never moves faster than the path,
/// and the planner only slows a move below its feed), and 0 when a
/// backlash take-up (a rapid, at the axis' maximum speed) could reach the
/// cap.
fn uncapped_feed(s: &Settings) -> f32 {
    const RATE: f32 = crate::config::MAX_STEP_RATE_HZ * 60.0 / 1.01;
    let mut top = 0.0f32;
    for a in 0..N_AXES {
        let spm = s.steps_per_mm[a];
        if !(spm > 0.0) || !spm.is_finite() {
            return 0.0;
        }
        if spm > top {
            top = spm;
        }
        if a < 3 && s.backlash_mm[a] > 0.0 && !(s.max_feed_mm_per_min[a] * spm <= RATE) {
            return 0.0;
        }
    }
    RATE / top
}

/// [`Interp::check_soft_limits`] over the interpreter's caches (fresh),
/// for a move's target in `motion_line`.
// speed: inlined into its one caller, motion_line: no call and no
// 10-register save on every streamed line (profile --trace 20 079 → 20 000
// cycles a line); the other checks go through Interp::check_soft_limits
#[inline(always)]
pub(super) fn soft_limits(cache: &mut [(u32, i32); N_AXES], travel_steps: &[i32; 3], s: &Settings, t: &[f32; N_AXES]) -> Result<(), Error> {
    if !s.soft_limits {
        return Ok(());
    }
    // X, Y, Z only, each checked as it is converted through its cache
    // entry (no array of all four axes built and read back: ~330 cycles a
    // streamed line on the AVR), written out per axis: as a loop the
    // indexing cost ~250 cycles more.
    let x = step_cached(&mut cache[0], s.steps_per_mm[0], t[0]);
    if x < 0 || x > travel_steps[0] {
        return Err(Error::SoftLimit);
    }
    let y = step_cached(&mut cache[1], s.steps_per_mm[1], t[1]);
    if y < 0 || y > travel_steps[1] {
        return Err(Error::SoftLimit);
    }
    let z = step_cached(&mut cache[2], s.steps_per_mm[2], t[2]);
    if z < 0 || z > travel_steps[2] {
        return Err(Error::SoftLimit);
    }
    Ok(())
}

/// One axis of [`steps_cached`]: `mm` in steps through its cache entry.
// speed: on every axis of every move (see steps_cached)
#[inline(always)]
fn step_cached(c: &mut (u32, i32), steps_per_mm: f32, mm: f32) -> i32 {
    let bits = mm.to_bits();
    if c.0 != bits {
        *c = (bits, to_steps(mm, steps_per_mm));
    }
    c.1
}

/// [`Interp::steps_of`]'s conversion through `cache`.
// speed: every move converts its target here (a call cost ping-pong lines/s)
#[inline(always)]
fn steps_cached(cache: &mut [(u32, i32); N_AXES], s: &Settings, mm: &[f32; N_AXES]) -> [i32; N_AXES] {
    // Each element written once (a loop over a zeroed array cost a
    // memset on the AVR).
    let [c0, c1, c2, c3] = cache;
    [
        step_cached(c0, s.steps_per_mm[0], mm[0]),
        step_cached(c1, s.steps_per_mm[1], mm[1]),
        step_cached(c2, s.steps_per_mm[2], mm[2]),
        step_cached(c3, s.steps_per_mm[3], mm[3]),
    ]
}

/// A straight move from `a` to `b` must not enter the tool magazine's
/// keep-out zone (only the tool change, which does not come through here,
/// goes in).
pub(super) fn keep_out(s: &Settings, a: &[f32; N_AXES], b: &[f32; N_AXES]) -> Result<(), Error> {
    // Tested first: the points below are built before the call, zone or not.
    if s.station.keep_out_on() && s.station.enters_keep_out([a[0], a[1], a[2]], [b[0], b[1], b[2]]) {
        return Err(Error::KeepOut);
    }
    Ok(())
}

/// An arc or a canned cycle by its bounding box, with the start point
/// (the cycle's first move starts there). `a` and `b` are opposite
/// corners, in either order per axis (the Z flip of a cycle's user bounds
/// swaps them).
pub(super) fn keep_out_box(s: &Settings, from: &[f32; N_AXES], a: &[f32; N_AXES], b: &[f32; N_AXES]) -> Result<(), Error> {
    let min = |x: f32, y: f32| if x < y { x } else { y };
    let max = |x: f32, y: f32| if x > y { x } else { y };
    let l = core::array::from_fn(|i| min(from[i], min(a[i], b[i])));
    let h = core::array::from_fn(|i| max(from[i], max(a[i], b[i])));
    if s.station.box_enters_keep_out(l, h) {
        return Err(Error::KeepOut);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_soft_limits_matches_the_inlined_check() {
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        let mut s = Settings::DEFAULT;
        let mut i = Interp::new();
        let mut inside = 0;
        for n in 0..100_000 {
            s.soft_limits = n % 9 != 0;
            for a in 0..3 {
                s.travel_mm[a] = (rng.next() % 400_000) as f32 * 0.001;
            }
            i.settings_changed();
            i.refresh_conv(&s);
            // Targets around and on the travel's ends, some cached already.
            let mut t = [0.0f32; N_AXES];
            for a in 0..N_AXES {
                let end = if a < 3 && rng.next().is_multiple_of(2) { i.travel_steps[a] } else { 0 };
                t[a] = (end + (rng.next() % 7) as i32 - 3) as f32 / s.steps_per_mm[a] + (rng.next() % 5) as f32 * 0.001;
                if rng.next().is_multiple_of(3) {
                    i.steps_cache[a] = (t[a].to_bits(), to_steps(t[a], s.steps_per_mm[a]));
                }
            }
            let mut cache = i.steps_cache;
            let r1 = soft_limits(&mut cache, &i.travel_steps, &s, &t);
            let r2 = i.check_soft_limits(&s, &t);
            assert_eq!(r1, r2, "{t:?} {:?}", i.travel_steps);
            inside += r1.is_ok() as u32;
        }
        assert!(inside > 10_000 && inside < 80_000, "{inside}");
    }
}
