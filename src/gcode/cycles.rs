//! Canned drilling cycles (G73, G81, G82, G83, G85, G89), LinuxCNC semantics.
//!
//! Sits inside the interpreter's motion step: when the motion mode is a
//! canned cycle, [`super::interp`] resolves the line's words into a
//! [`Cycle`] (absolute positions in the user's frame, +Z up, mm) and queues
//! the moves it yields, one at a time, through the same entry point as a
//! `G0`/`G1`. Nothing here knows the planner or the machine: a cycle is a
//! small state machine that yields [`Step`]s, so it is tested on the host
//! move by move.
//!
//! The sequence for each hole (LinuxCNC, "Canned cycles", G81–G89):
//! 0. once, before the first hole: if Z is below the R plane, rapid Z up to R;
//! 1. rapid X/Y to the hole;
//! 2. rapid Z down to the R plane;
//! 3. the cycle's own motion to the bottom Z:
//!    - G81 feed down; G82 feed down, dwell P;
//!    - G83 peck: feed down by Q, rapid out to R, rapid back to
//!      [`PECK_CLEARANCE_MM`] above the depth reached, feed on, until Z;
//!    - G73 chip break: feed down by Q, rapid up [`PECK_CLEARANCE_MM`], feed on;
//!    - G85 feed down, feed back up to R (then rapid to the clearance plane);
//!    - G89 feed down, dwell P, feed back up to the clearance plane itself
//!      (LinuxCNC's `convert_cycle_g89` feeds all the way to clear Z);
//! 4. rapid up to the clearance plane: the initial Z under G98 (or R if R is
//!    higher), R under G99.
//!
//! The X/Y move to the first hole is made at the current Z when that is above
//! R, else at the clearance plane; the following holes are reached at the
//! clearance plane (LinuxCNC's `CYCLE_MACRO`). The initial Z ("initial
//! level") is the Z where the first cycle line of a run of cycle lines
//! started; it is kept across lines until a non-cycle motion mode (G80,
//! G0–G3) ends the run ([`resolve`]).
//!
//! `L` repeats the hole: under G91 each repeat moves by the X/Y increment,
//! or with the polar words adds `@` to the radius and `^` to the angle about
//! the work origin (`G91 G81 R.1 Z-.1 ^60 L6`: six holes on a circle);
//! under G90 the same hole is drilled again (as LinuxCNC does).

/// How far above the depth already reached a peck comes back down at rapid
/// (G83), and how far G73 backs off to break the chip: LinuxCNC's
/// `G83_RAPID_DELTA`, 0.010 inch.
pub const PECK_CLEARANCE_MM: f32 = 0.254;

/// The canned cycle (NGC motion group 1, G73 and G81–G89).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// G81: drill.
    Drill,
    /// G82: drill, dwell at the bottom.
    DrillDwell,
    /// G83: peck drill, full retract to R between pecks.
    Peck,
    /// G73: chip-breaking peck, a short back-off between pecks.
    ChipBreak,
    /// G85: bore, feed out.
    Bore,
    /// G89: bore, dwell at the bottom, feed out.
    BoreDwell,
}

impl Kind {
    /// True for the cycles that need a Q (peck depth).
    pub fn pecks(self) -> bool {
        matches!(self, Kind::Peck | Kind::ChipBreak)
    }

    /// True for the cycles that dwell P seconds at the bottom.
    pub fn dwells(self) -> bool {
        matches!(self, Kind::DrillDwell | Kind::BoreDwell)
    }

    /// True for the cycles that feed (not rapid) back out to R.
    fn feeds_out(self) -> bool {
        matches!(self, Kind::Bore | Kind::BoreDwell)
    }

    /// The G number (for messages and tests).
    pub fn code(self) -> u8 {
        match self {
            Kind::Drill => 81,
            Kind::DrillDwell => 82,
            Kind::Peck => 83,
            Kind::ChipBreak => 73,
            Kind::Bore => 85,
            Kind::BoreDwell => 89,
        }
    }
}

/// Where a hole ends (NGC group 10).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Retract {
    /// G98: back to the Z held before the cycles began (or R if higher).
    Initial,
    /// G99: back to the R plane.
    RPlane,
}

/// One move of a cycle, in the user's frame (mm, +Z up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Rapid (G0) to X, Y, Z.
    Rapid([f32; 3]),
    /// Feed (G1 at the modal feed) to X, Y, Z.
    Feed([f32; 3]),
    /// Dwell, seconds.
    Dwell(f32),
}

/// Why a cycle cannot run; the line is refused and nothing moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The bottom Z is above the R plane.
    ZAboveR,
    /// G73/G83 without a positive Q.
    BadPeck,
    /// A negative dwell.
    BadDwell,
    /// L is not a whole number from 1 to 1000.
    BadRepeat,
    /// No Z on the first line of this cycle (it is modal after that).
    MissingZ,
    /// No R on the first line of this cycle.
    MissingR,
    /// G73/G83 started without Q.
    MissingQ,
    /// G82/G89 started without P.
    MissingP,
    /// G91 polar words with the tool at the work origin.
    PolarAtOrigin,
}

impl Error {
    /// Text printed after `Error:`; the line is refused, nothing moved.
    pub fn message(self) -> crate::flash::FStr {
        match self {
            Error::ZAboveR => F!("canned cycle: Z is above R, nothing moved"),
            Error::BadPeck => F!("G73/G83: Q (peck depth) must be positive, nothing moved"),
            Error::BadDwell => F!("G82/G89: P (dwell, seconds) must not be negative, nothing moved"),
            Error::BadRepeat => F!("canned cycle: L must be a whole number 1-1000, nothing moved"),
            Error::MissingZ => F!("canned cycle: Z missing (needed on the cycle's first line), nothing moved"),
            Error::MissingR => F!("canned cycle: R missing (needed on the cycle's first line), nothing moved"),
            Error::MissingQ => F!("G73/G83: Q (peck depth) missing, nothing moved"),
            Error::MissingP => F!("G82/G89: P (dwell, seconds) missing, nothing moved"),
            Error::PolarAtOrigin => F!("G91 polar move from the origin is indeterminate, nothing moved"),
        }
    }
}

/// The resolved words of one cycle line (absolute, user frame, mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    pub kind: Kind,
    pub retract: Retract,
    /// The first hole's X, Y.
    pub hole_xy: [f32; 2],
    /// Added to X, Y for each repeat (G91 `L`); zero under G90. With
    /// `polar`: added to the radius (mm) and the angle (radians) instead.
    pub repeat_xy: [f32; 2],
    /// The repeats step in polar coordinates about the work origin.
    pub polar: bool,
    /// R plane Z, mm.
    pub r_z: f32,
    /// Bottom Z, mm.
    pub bottom_z: f32,
    /// The initial level: Z where this run of cycle lines began (G98).
    pub initial_z: f32,
    /// Peck depth Q, mm (G73/G83).
    pub peck_mm: f32,
    /// Dwell P, seconds (G82/G89).
    pub dwell_s: f32,
    /// Holes to drill (L), at least 1.
    pub repeats: u16,
}

/// Where the state machine is within a hole.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Before the first hole: lift to R if below it.
    Lift,
    /// Rapid X/Y to the hole.
    ToHole,
    /// Rapid Z down to R.
    ToR,
    /// Feed down to `depth` (the next peck's end, or the bottom).
    Down,
    /// After a peck that was not the last: the back-off rapid.
    BackOff,
    /// G83 after the back-off to R: rapid back down near the depth reached.
    Reenter,
    /// At the bottom: dwell (G82/G89) if asked.
    Bottom,
    /// Out of the hole: feed to R (G85/G89) or rapid to the clearance plane.
    Out,
    /// G85/G89 under G98 with the clearance plane above R: the last rapid.
    Clear,
    /// Done with this hole: next hole or the end.
    Next,
    Done,
}

/// A canned cycle in progress: yields its moves one at a time.
#[derive(Clone, Copy, Debug)]
pub struct Cycle {
    p: Params,
    /// Z of the clearance plane the hole ends at.
    clear_z: f32,
    /// Z the cycle started at.
    start_z: f32,
    /// The current hole's X, Y.
    xy: [f32; 2],
    /// Depth reached so far in this hole.
    reached_z: f32,
    /// Holes left after the current one.
    left: u16,
    phase: Phase,
}

impl Cycle {
    /// Check `p` and start the cycle from the user position `start`.
    pub fn new(p: Params, start: [f32; 3]) -> Result<Cycle, Error> {
        if p.bottom_z > p.r_z {
            return Err(Error::ZAboveR);
        }
        if p.kind.pecks() && !(p.peck_mm > 0.0) {
            return Err(Error::BadPeck);
        }
        if p.kind.dwells() && !(p.dwell_s >= 0.0) {
            return Err(Error::BadDwell);
        }
        if p.repeats == 0 || p.repeats > 1000 {
            return Err(Error::BadRepeat);
        }
        let clear_z = match p.retract {
            Retract::Initial if p.initial_z > p.r_z => p.initial_z,
            _ => p.r_z,
        };
        Ok(Cycle { p, clear_z, start_z: start[2], xy: p.hole_xy, reached_z: p.r_z, left: p.repeats - 1, phase: Phase::Lift })
    }

    /// The Z of the plane each hole ends at.
    pub fn clearance_z(&self) -> f32 {
        self.clear_z
    }

    /// Every X, Y, Z the cycle can reach: (low corner, high corner), for the
    /// soft-limit check before anything moves. Not inlined: its frame
    /// stays out of the interpreter's cycle line.
    // stack: its frame stays out of the interpreter's cycle line
    #[inline(never)]
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = self.p.hole_xy;
        let mut hi = self.p.hole_xy;
        if self.p.polar {
            // Holes on a circle or a spiral: every one of them.
            let mut xy = self.p.hole_xy;
            for _ in 1..self.p.repeats {
                xy = polar_step(xy, self.p.repeat_xy);
                for a in 0..2 {
                    lo[a] = min(lo[a], xy[a]);
                    hi[a] = max(hi[a], xy[a]);
                }
            }
        } else {
            for a in 0..2 {
                let last = self.p.hole_xy[a] + self.p.repeat_xy[a] * (self.p.repeats - 1) as f32;
                lo[a] = min(lo[a], last);
                hi[a] = max(hi[a], last);
            }
        }
        let top = if self.start_z > self.clear_z { self.start_z } else { self.clear_z };
        ([lo[0], lo[1], self.p.bottom_z], [hi[0], hi[1], top])
    }

    /// The next move, `None` when the cycle is done.
    pub fn next_step(&mut self) -> Option<Step> {
        loop {
            let (step, next) = self.transition();
            self.phase = next;
            if step.is_some() || next == Phase::Done {
                return step;
            }
        }
    }

    fn at(&self, z: f32) -> [f32; 3] {
        [self.xy[0], self.xy[1], z]
    }

    /// The move of the current phase (if any) and the phase after it.
    fn transition(&mut self) -> (Option<Step>, Phase) {
        let p = self.p;
        match self.phase {
            Phase::Lift => {
                if self.start_z < p.r_z {
                    // The tool is below R: straight up first, where it is.
                    (Some(Step::Rapid([f32::NAN, f32::NAN, p.r_z])), Phase::ToHole)
                } else {
                    (None, Phase::ToHole)
                }
            }
            Phase::ToHole => {
                // The first hole from the current Z if above R, else (and for
                // every later hole) at the clearance plane.
                let z = if self.left + 1 == p.repeats && self.start_z > p.r_z { self.start_z } else { self.clear_z };
                (Some(Step::Rapid([self.xy[0], self.xy[1], z])), Phase::ToR)
            }
            Phase::ToR => {
                self.reached_z = p.r_z;
                (Some(Step::Rapid(self.at(p.r_z))), Phase::Down)
            }
            Phase::Down => {
                let depth = if p.kind.pecks() { max(self.reached_z - p.peck_mm, p.bottom_z) } else { p.bottom_z };
                self.reached_z = depth;
                let next = if depth > p.bottom_z { Phase::BackOff } else { Phase::Bottom };
                (Some(Step::Feed(self.at(depth))), next)
            }
            Phase::BackOff => match p.kind {
                Kind::Peck => (Some(Step::Rapid(self.at(p.r_z))), Phase::Reenter),
                _ => (Some(Step::Rapid(self.at(self.reached_z + PECK_CLEARANCE_MM))), Phase::Down),
            },
            Phase::Reenter => {
                let z = min(self.reached_z + PECK_CLEARANCE_MM, p.r_z);
                (Some(Step::Rapid(self.at(z))), Phase::Down)
            }
            Phase::Bottom => {
                if p.kind.dwells() {
                    (Some(Step::Dwell(p.dwell_s)), Phase::Out)
                } else {
                    (None, Phase::Out)
                }
            }
            Phase::Out => {
                if p.kind == Kind::BoreDwell {
                    (Some(Step::Feed(self.at(self.clear_z))), Phase::Next)
                } else if p.kind.feeds_out() {
                    (Some(Step::Feed(self.at(p.r_z))), Phase::Clear)
                } else {
                    (Some(Step::Rapid(self.at(self.clear_z))), Phase::Next)
                }
            }
            Phase::Clear => {
                if self.clear_z > p.r_z {
                    (Some(Step::Rapid(self.at(self.clear_z))), Phase::Next)
                } else {
                    (None, Phase::Next)
                }
            }
            Phase::Next => {
                if self.left == 0 {
                    (None, Phase::Done)
                } else {
                    self.left -= 1;
                    self.xy =
                        if p.polar { polar_step(self.xy, p.repeat_xy) } else { [self.xy[0] + p.repeat_xy[0], self.xy[1] + p.repeat_xy[1]] };
                    (None, Phase::ToHole)
                }
            }
            Phase::Done => (None, Phase::Done),
        }
    }
}

/// The cycle words that stay in force from line to line (LinuxCNC's
/// `cycle_r`, `cycle_cc`, `cycle_q`, `cycle_p`, `cycle_il`): R and Z as
/// written (absolute under G90, increments under G91), in mm, user frame;
/// Q in mm; P in seconds; the initial level Z, absolute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sticky {
    pub r: f32,
    pub z: f32,
    pub q: f32,
    pub p: f32,
    pub initial_z: f32,
}

impl Sticky {
    /// Nothing given yet (power-up).
    pub const NONE: Sticky = Sticky { r: 0.0, z: 0.0, q: 0.0, p: 0.0, initial_z: 0.0 };
}

/// The words of one cycle line: X, Y, Z, R, Q in mm (user frame, inches
/// already converted), P in seconds, L as written; `None` when absent.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LineWords {
    pub x: Option<f32>,
    pub y: Option<f32>,
    pub z: Option<f32>,
    pub r: Option<f32>,
    pub q: Option<f32>,
    pub p: Option<f32>,
    pub l: Option<f32>,
    /// G91 polar words: added to the radius (mm) and the angle (radians)
    /// of the position for each hole; X and Y are then absent.
    pub polar: Option<[f32; 2]>,
}

/// Resolve one cycle line into the [`Params`] of its holes and the sticky
/// words to keep, LinuxCNC's `convert_cycle`/`convert_cycle_xy`:
/// - `prev`: the cycle in force before the line (`None` after G80, G0–G3 or
///   at power-up). Z and R must be on the line unless `prev` is this same
///   cycle; likewise Q for G73/G83 and P for G82/G89;
/// - the initial level is the Z at `pos` when no cycle was in force,
///   else the one kept in `sticky`;
/// - G90: X, Y, R, Z absolute; a missing X or Y is the current one; `L`
///   drills the same hole L times;
/// - G91: X, Y are increments, applied once per repeat (`L` holes in a row);
///   R is relative to the initial level, Z relative to R.
///
/// `pos` is the current position (user frame, work coordinates).
pub fn resolve(
    kind: Kind,
    retract: Retract,
    incremental: bool,
    prev: Option<Kind>,
    sticky: &Sticky,
    w: &LineWords,
    pos: [f32; 3],
) -> Result<(Params, Sticky), Error> {
    let same = prev == Some(kind);
    let need = |v: Option<f32>, old: f32, needed: bool, e: Error| match v {
        Some(v) => Ok(v),
        None if same || !needed => Ok(old),
        None => Err(e),
    };
    let z = need(w.z, sticky.z, true, Error::MissingZ)?;
    let r = need(w.r, sticky.r, true, Error::MissingR)?;
    let q = need(w.q, sticky.q, kind.pecks(), Error::MissingQ)?;
    let p = need(w.p, sticky.p, kind.dwells(), Error::MissingP)?;
    let repeats = match w.l {
        None => 1,
        Some(l) if (1.0..=1000.0).contains(&l) && (l as u16) as f32 == l => l as u16,
        Some(_) => return Err(Error::BadRepeat),
    };
    let initial_z = if prev.is_some() { sticky.initial_z } else { pos[2] };
    let polar = incremental && w.polar.is_some();
    let (hole_xy, repeat_xy, r_z, bottom_z) = if incremental {
        let r_z = initial_z + r;
        if let Some(step) = w.polar {
            if pos[0] == 0.0 && pos[1] == 0.0 {
                return Err(Error::PolarAtOrigin);
            }
            (polar_step([pos[0], pos[1]], step), step, r_z, r_z + z)
        } else {
            let inc = [w.x.unwrap_or(0.0), w.y.unwrap_or(0.0)];
            ([pos[0] + inc[0], pos[1] + inc[1]], inc, r_z, r_z + z)
        }
    } else {
        ([w.x.unwrap_or(pos[0]), w.y.unwrap_or(pos[1])], [0.0, 0.0], r, z)
    };
    let params = Params { kind, retract, hole_xy, repeat_xy, polar, r_z, bottom_z, initial_z, peck_mm: q, dwell_s: p, repeats };
    Ok((params, Sticky { r, z, q, p, initial_z }))
}

/// `xy` (about the work origin) with `step[0]` mm added to its radius and
/// `step[1]` radians to its angle (LinuxCNC's `CYCLE_MACRO`).
fn polar_step(xy: [f32; 2], step: [f32; 2]) -> [f32; 2] {
    let r = crate::math::sqrtf(xy[0] * xy[0] + xy[1] * xy[1]) + step[0];
    let a = crate::math::atan2f(xy[1], xy[0]) + step[1];
    let (sin, cos) = crate::math::sincosf(a);
    [r * cos, r * sin]
}

fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(kind: Kind, retract: Retract) -> Params {
        Params {
            kind,
            retract,
            hole_xy: [10.0, 5.0],
            repeat_xy: [0.0, 0.0],
            polar: false,
            r_z: 2.0,
            bottom_z: -3.0,
            initial_z: 10.0,
            peck_mm: 1.0,
            dwell_s: 0.5,
            repeats: 1,
        }
    }

    /// Every step of a cycle started at `start`, with NaN (axis unchanged)
    /// filled in from the position before it, so tests compare plain points.
    fn run(p: Params, start: [f32; 3]) -> Vec<Step> {
        let mut c = Cycle::new(p, start).unwrap();
        let mut pos = start;
        let mut out = Vec::new();
        while let Some(s) = c.next_step() {
            let fill = |t: [f32; 3], pos: &mut [f32; 3]| {
                for a in 0..3 {
                    if !t[a].is_nan() {
                        pos[a] = t[a];
                    }
                }
                *pos
            };
            out.push(match s {
                Step::Rapid(t) => Step::Rapid(fill(t, &mut pos)),
                Step::Feed(t) => Step::Feed(fill(t, &mut pos)),
                d => d,
            });
            assert!(out.len() < 10_000, "cycle never ends");
        }
        out
    }

    use Step::{Dwell, Feed, Rapid};

    #[test]
    fn g81_from_above_rapids_to_the_hole_and_r_feeds_to_z_and_returns_to_the_initial_z_under_g98() {
        let s = run(params(Kind::Drill, Retract::Initial), [0.0, 0.0, 10.0]);
        assert_eq!(s, vec![Rapid([10.0, 5.0, 10.0]), Rapid([10.0, 5.0, 2.0]), Feed([10.0, 5.0, -3.0]), Rapid([10.0, 5.0, 10.0])]);
    }

    #[test]
    fn g81_under_g99_returns_to_the_r_plane() {
        let s = run(params(Kind::Drill, Retract::RPlane), [0.0, 0.0, 10.0]);
        assert_eq!(*s.last().unwrap(), Rapid([10.0, 5.0, 2.0]));
    }

    #[test]
    fn starting_below_r_lifts_straight_up_to_r_first_and_g98_then_clears_at_r() {
        let mut p = params(Kind::Drill, Retract::Initial);
        p.initial_z = 1.0;
        let s = run(p, [0.0, 0.0, 1.0]);
        assert_eq!(s[0], Rapid([0.0, 0.0, 2.0]));
        assert_eq!(s[1], Rapid([10.0, 5.0, 2.0]));
        assert_eq!(*s.last().unwrap(), Rapid([10.0, 5.0, 2.0]));
    }

    #[test]
    fn g82_dwells_p_seconds_at_the_bottom() {
        let s = run(params(Kind::DrillDwell, Retract::RPlane), [0.0, 0.0, 10.0]);
        assert_eq!(s[2], Feed([10.0, 5.0, -3.0]));
        assert_eq!(s[3], Dwell(0.5));
        assert_eq!(s[4], Rapid([10.0, 5.0, 2.0]));
    }

    #[test]
    fn g83_pecks_q_deep_with_a_full_retract_to_r_and_a_rapid_back_near_the_depth_reached() {
        let mut p = params(Kind::Peck, Retract::RPlane);
        p.peck_mm = 2.0; // R 2 → Z -3: pecks to 0, -2, -3
        let s = run(p, [0.0, 0.0, 10.0]);
        let c = PECK_CLEARANCE_MM;
        let at = |z: f32| [10.0, 5.0, z];
        assert_eq!(
            s,
            vec![
                Rapid(at(10.0)),
                Rapid(at(2.0)),
                Feed(at(0.0)),
                Rapid(at(2.0)),
                Rapid(at(0.0 + c)),
                Feed(at(-2.0)),
                Rapid(at(2.0)),
                Rapid(at(-2.0 + c)),
                Feed(at(-3.0)),
                Rapid(at(2.0)),
            ]
        );
    }

    #[test]
    fn g73_breaks_the_chip_with_a_short_back_off_not_a_full_retract() {
        let mut p = params(Kind::ChipBreak, Retract::RPlane);
        p.peck_mm = 2.0;
        let s = run(p, [0.0, 0.0, 10.0]);
        let c = PECK_CLEARANCE_MM;
        let at = |z: f32| [10.0, 5.0, z];
        assert_eq!(
            s,
            vec![
                Rapid(at(10.0)),
                Rapid(at(2.0)),
                Feed(at(0.0)),
                Rapid(at(c)),
                Feed(at(-2.0)),
                Rapid(at(-2.0 + c)),
                Feed(at(-3.0)),
                Rapid(at(2.0))
            ]
        );
    }

    #[test]
    fn every_peck_is_at_most_q_deeper_than_the_last_and_the_bottom_is_reached_exactly() {
        for q in [0.1f32, 0.3, 0.7, 1.0, 2.5, 5.0, 10.0] {
            for kind in [Kind::Peck, Kind::ChipBreak] {
                let mut p = params(kind, Retract::RPlane);
                p.peck_mm = q;
                let mut deepest = p.r_z;
                for s in run(p, [0.0, 0.0, 10.0]) {
                    if let Feed(t) = s {
                        assert!(t[2] < deepest && deepest - t[2] <= q + 1e-5, "q {q}: {deepest} -> {}", t[2]);
                        deepest = t[2];
                    }
                }
                assert_eq!(deepest, p.bottom_z);
            }
        }
    }

    #[test]
    fn g85_feeds_out_to_r_and_g89_dwells_first_and_g98_then_rapids_to_the_initial_z() {
        let s = run(params(Kind::Bore, Retract::Initial), [0.0, 0.0, 10.0]);
        let at = |z: f32| [10.0, 5.0, z];
        assert_eq!(s, vec![Rapid(at(10.0)), Rapid(at(2.0)), Feed(at(-3.0)), Feed(at(2.0)), Rapid(at(10.0))]);
        let s = run(params(Kind::BoreDwell, Retract::RPlane), [0.0, 0.0, 10.0]);
        assert_eq!(s, vec![Rapid(at(10.0)), Rapid(at(2.0)), Feed(at(-3.0)), Dwell(0.5), Feed(at(2.0))]);
    }

    #[test]
    fn l_repeats_step_by_the_increment_and_each_hole_is_drilled_from_the_clearance_plane() {
        let mut p = params(Kind::Drill, Retract::RPlane);
        p.repeat_xy = [3.0, 0.0];
        p.hole_xy = [3.0, 5.0];
        p.repeats = 3;
        let s = run(p, [0.0, 5.0, 10.0]);
        let feeds: Vec<_> = s.iter().filter_map(|s| if let Feed(t) = s { Some(*t) } else { None }).collect();
        assert_eq!(feeds, vec![[3.0, 5.0, -3.0], [6.0, 5.0, -3.0], [9.0, 5.0, -3.0]]);
        // Between holes the tool travels at the R plane, never lower.
        for w in s.windows(2) {
            if let (Rapid(a), Rapid(b)) = (w[0], w[1]) {
                if a[0] != b[0] {
                    assert_eq!(a[2], 2.0);
                }
            }
        }
    }

    #[test]
    fn nonsense_is_refused_before_anything_moves() {
        let mut p = params(Kind::Drill, Retract::RPlane);
        p.bottom_z = 3.0;
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::ZAboveR);
        let mut p = params(Kind::Peck, Retract::RPlane);
        p.peck_mm = 0.0;
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::BadPeck);
        p.peck_mm = f32::NAN;
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::BadPeck);
        let mut p = params(Kind::DrillDwell, Retract::RPlane);
        p.dwell_s = -1.0;
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::BadDwell);
        let mut p = params(Kind::Drill, Retract::RPlane);
        p.repeats = 0;
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::BadRepeat);
    }

    #[test]
    fn bounds_cover_every_point_the_cycle_visits() {
        let mut p = params(Kind::Peck, Retract::Initial);
        p.repeat_xy = [-2.0, 1.5];
        p.repeats = 4;
        let c = Cycle::new(p, [0.0, 0.0, 12.0]).unwrap();
        let (lo, hi) = c.bounds();
        for s in run(p, [0.0, 0.0, 12.0]) {
            if let Rapid(t) | Feed(t) = s {
                for a in 0..3 {
                    // The first rapid starts from where the tool is, which
                    // the interpreter has already checked.
                    if t[0] != 0.0 || t[1] != 0.0 {
                        assert!(t[a] >= lo[a] - 1e-5 && t[a] <= hi[a] + 1e-5, "{t:?} outside {lo:?}..{hi:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn g89_under_g98_feeds_all_the_way_out_to_the_initial_z_as_linuxcnc() {
        let s = run(params(Kind::BoreDwell, Retract::Initial), [0.0, 0.0, 10.0]);
        let at = |z: f32| [10.0, 5.0, z];
        assert_eq!(s, vec![Rapid(at(10.0)), Rapid(at(2.0)), Feed(at(-3.0)), Dwell(0.5), Feed(at(10.0))]);
    }

    #[test]
    fn a_later_line_under_g98_reaches_its_hole_at_the_initial_level_even_from_r() {
        // G99 left the tool at R 2; this G98 line clears at the initial level 10.
        let s = run(params(Kind::Drill, Retract::Initial), [0.0, 0.0, 2.0]);
        assert_eq!(s[0], Rapid([10.0, 5.0, 10.0]));
        assert_eq!(*s.last().unwrap(), Rapid([10.0, 5.0, 10.0]));
    }

    fn words() -> LineWords {
        LineWords { x: Some(4.0), y: Some(6.0), z: Some(-3.0), r: Some(2.0), q: Some(1.5), p: Some(0.25), l: None, polar: None }
    }

    #[test]
    fn resolve_g90_takes_absolute_words_and_the_start_z_as_the_initial_level() {
        let (p, st) = resolve(Kind::Peck, Retract::Initial, false, None, &Sticky::NONE, &words(), [1.0, 1.0, 12.0]).unwrap();
        assert_eq!(
            (p.hole_xy, p.repeat_xy, p.r_z, p.bottom_z, p.initial_z, p.peck_mm, p.repeats),
            ([4.0, 6.0], [0.0, 0.0], 2.0, -3.0, 12.0, 1.5, 1)
        );
        assert_eq!(st, Sticky { r: 2.0, z: -3.0, q: 1.5, p: 0.25, initial_z: 12.0 });
        // A bare X on the next line: R, Z, Q and the initial level stay.
        let w = LineWords { x: Some(9.0), ..LineWords::default() };
        let (p2, st2) = resolve(Kind::Peck, Retract::Initial, false, Some(Kind::Peck), &st, &w, [4.0, 6.0, 12.0]).unwrap();
        assert_eq!((p2.hole_xy, p2.r_z, p2.bottom_z, p2.peck_mm, p2.initial_z), ([9.0, 6.0], 2.0, -3.0, 1.5, 12.0));
        assert_eq!(st2, st);
    }

    #[test]
    fn resolve_g91_r_from_the_initial_level_z_from_r_and_xy_per_repeat() {
        let w = LineWords { x: Some(5.0), y: None, z: Some(-4.0), r: Some(-1.0), l: Some(3.0), ..LineWords::default() };
        let (p, _) = resolve(Kind::Drill, Retract::RPlane, true, None, &Sticky::NONE, &w, [10.0, 20.0, 3.0]).unwrap();
        assert_eq!((p.hole_xy, p.repeat_xy, p.r_z, p.bottom_z, p.repeats), ([15.0, 20.0], [5.0, 0.0], 2.0, -2.0, 3));
        let holes: Vec<[f32; 3]> =
            run(p, [10.0, 20.0, 3.0]).into_iter().filter_map(|s| if let Feed(t) = s { Some(t) } else { None }).collect();
        assert_eq!(holes, vec![[15.0, 20.0, -2.0], [20.0, 20.0, -2.0], [25.0, 20.0, -2.0]]);
    }

    #[test]
    fn resolve_refuses_what_linuxcnc_refuses() {
        let none = Sticky::NONE;
        let r = |k, prev, w: LineWords| resolve(k, Retract::Initial, false, prev, &none, &w, [0.0, 0.0, 10.0]).map(|_| ()).unwrap_err();
        assert_eq!(r(Kind::Drill, None, LineWords { z: None, ..words() }), Error::MissingZ);
        assert_eq!(r(Kind::Drill, None, LineWords { r: None, ..words() }), Error::MissingR);
        assert_eq!(r(Kind::Peck, None, LineWords { q: None, ..words() }), Error::MissingQ);
        assert_eq!(r(Kind::ChipBreak, Some(Kind::Peck), LineWords { q: None, ..words() }), Error::MissingQ);
        assert_eq!(r(Kind::DrillDwell, None, LineWords { p: None, ..words() }), Error::MissingP);
        // Switching cycles asks for Z and R again.
        assert_eq!(r(Kind::Peck, Some(Kind::Drill), LineWords { z: None, ..words() }), Error::MissingZ);
        for l in [0.0, -1.0, 2.5, 1001.0] {
            assert_eq!(r(Kind::Drill, None, LineWords { l: Some(l), ..words() }), Error::BadRepeat);
        }
        // A valid line passes, and Cycle::new catches the rest.
        let (p, _) = resolve(Kind::Peck, Retract::Initial, false, None, &none, &LineWords { q: Some(0.0), ..words() }, [0.0; 3]).unwrap();
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::BadPeck);
        let (p, _) = resolve(Kind::Drill, Retract::Initial, false, None, &none, &LineWords { z: Some(3.0), ..words() }, [0.0; 3]).unwrap();
        assert_eq!(Cycle::new(p, [0.0; 3]).unwrap_err(), Error::ZAboveR);
    }

    #[test]
    fn linuxcnc_manual_example_g91_g81_g98_l3_move_by_move() {
        // LinuxCNC manual, G81 example 2: from (1, 2, 3),
        // `G91 G81 G98 X4 Y5 Z-0.6 R1.8 L3`: clear Z 4.8, bottom 4.2; first
        // straight up to 4.8 (old Z 3 is below R), then three holes, each
        // reached at 4.8 and drilled to 4.2.
        let w = LineWords { x: Some(4.0), y: Some(5.0), z: Some(-0.6), r: Some(1.8), l: Some(3.0), ..LineWords::default() };
        let (p, _) = resolve(Kind::Drill, Retract::Initial, true, None, &Sticky::NONE, &w, [1.0, 2.0, 3.0]).unwrap();
        let s = run(p, [1.0, 2.0, 3.0]);
        let r = |v: [f32; 3]| v.map(|c| (c * 1000.0).round() / 1000.0);
        let s: Vec<Step> = s
            .into_iter()
            .map(|st| match st {
                Rapid(t) => Rapid(r(t)),
                Feed(t) => Feed(r(t)),
                d => d,
            })
            .collect();
        let mut want = vec![Rapid([1.0, 2.0, 4.8])];
        for (x, y) in [(5.0, 7.0), (9.0, 12.0), (13.0, 17.0)] {
            want.extend([Rapid([x, y, 4.8]), Rapid([x, y, 4.8]), Feed([x, y, 4.2]), Rapid([x, y, 4.8])]);
        }
        assert_eq!(s, want);
    }

    #[test]
    fn g91_polar_words_drill_holes_on_a_circle_about_the_work_origin() {
        // `G91 G81 R1 Z-2 ^60 L6` from (10, 0, 5): six holes 60° apart on
        // the 10 mm circle, the first at 60°, the last back at 0°.
        let w = LineWords { z: Some(-2.0), r: Some(1.0), l: Some(6.0), polar: Some([0.0, 60f32.to_radians()]), ..LineWords::default() };
        let (p, _) = resolve(Kind::Drill, Retract::Initial, true, None, &Sticky::NONE, &w, [10.0, 0.0, 5.0]).unwrap();
        let holes: Vec<[f32; 2]> = run(p, [10.0, 0.0, 5.0])
            .into_iter()
            .filter_map(|s| match s {
                Feed(t) => Some([t[0], t[1]]),
                _ => None,
            })
            .collect();
        assert_eq!(holes.len(), 6);
        for (i, h) in holes.iter().enumerate() {
            let a = (60.0 * (i + 1) as f32).to_radians();
            assert!((h[0] - 10.0 * a.cos()).abs() < 1e-4 && (h[1] - 10.0 * a.sin()).abs() < 1e-4, "hole {i}: {h:?}");
        }
        // The soft-limit box holds every hole of the circle.
        let (lo, hi) = Cycle::new(p, [10.0, 0.0, 5.0]).unwrap().bounds();
        assert!(lo[0] < -9.99 && hi[0] > 9.99 && lo[1] < -8.6 && hi[1] > 8.6, "{lo:?} {hi:?}");
        // At the origin the angle is undefined: refused.
        assert_eq!(
            resolve(Kind::Drill, Retract::Initial, true, None, &Sticky::NONE, &w, [0.0, 0.0, 5.0]).unwrap_err(),
            Error::PolarAtOrigin
        );
    }
}
