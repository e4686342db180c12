//! G2/G3 arcs → chords (docs/SPEC.md §5, seed 003), grbl's `mc_arc` as an iterator.
//!
//! Where it sits: the interpreter validates an arc with [`Arc::new`] before it
//! commits any modal state, then pulls chord end points from the iterator and
//! queues each one with [`super::Planner::push_line`] (retrying on `Full`).
//!
//! - Any plane: `(axis_0, axis_1, axis_linear)` = (0, 1, 2) for G17, (2, 0, 1)
//!   for G18, (1, 2, 0) for G19; a clockwise arc turns from `axis_0` towards
//!   −`axis_1` as seen from +`axis_linear` (RS274/NGC, grbl).
//! - Helical motion: the linear axis moves in proportion to the angle.
//! - Centre by I/J/K offsets from the start, or by R (R > 0: the arc of at most
//!   180°, R < 0: the longer one, RS274/NGC §3.5.3). Start == end in the
//!   plane with I/J/K is a full circle, always: the angle is not measured
//!   then (f32 round-off in `end − centre` made it a few µrad either way, and
//!   one sign of it turned a full circle into a 2 µrad arc). The interpreter
//!   sets the end to the start when both round to the same steps. With R,
//!   start == end is an error.
//! - Chord count: each chord spans at most φ = √(8·tol/r), whose sagitta
//!   r(1 − cos φ/2) ≤ r·φ²/8 = tol, so the chord error never exceeds the
//!   tolerance (grbl's own count rounds down and can exceed it slightly).
//! - No accumulated error: points come from rotating the previous radius vector
//!   by the exact cos/sin of the step, recomputed from `start angle + i·step`
//!   every [`ARC_CORRECTION`] chords; the last chord ends exactly at the
//!   programmed end point. When an I/J/K end radius differs slightly from the
//!   start radius (allowed up to grbl's limit), the radius is interpolated
//!   along the arc so the path has no jump at the end.
//!
//! All lengths in mm, angles in radians, f32 (the AVR has no f64 hardware).

use crate::flash::FStr;
use crate::math::{atan2f, fabsf, sincosf, sqrtf};

/// Chords between exact sin/cos recomputations.
pub const ARC_CORRECTION: u32 = 16;
/// Angular travel below which a same-direction arc counts as a full circle, rad
/// (grbl's ARC_ANGULAR_TRAVEL_EPSILON).
const ANGULAR_TRAVEL_EPSILON: f32 = 5e-7;
const TWO_PI: f32 = 2.0 * core::f32::consts::PI;
/// I/J/K end radius mismatch always accepted, mm: LinuxCNC's
/// `CENTER_ARC_RADIUS_TOLERANCE_MM` (2 · 0.01 · √2). grbl's 0.005 mm refused
/// a Fusion 360 HAAS post's 0.3 mm fillet 0.0056 mm off (corpus 06, in
/// inches: 4 decimals of an inch are 2.5 µm each). Above it the mismatch must
/// stay within 0.1 % of the radius (both), and never beyond 0.5 mm (grbl).
pub const RADIUS_ABS_TOLERANCE_MM: f32 = 0.028_284_27;

/// How the arc's centre is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Centre {
    /// I, J, K: offsets from the start point to the centre, mm, in X Y Z order
    /// (the component on the plane's normal axis is ignored).
    Offset([f32; 3]),
    /// R word, mm: > 0 for the short arc, < 0 for the long one.
    Radius(f32),
}

/// Why an arc was refused (docs/SPEC.md §10: an arc with no solution is an error).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArcError {
    /// R is smaller than half the distance between start and end.
    RadiusTooSmall,
    /// I/J/K: the end point is not on the circle (start and end radius differ by
    /// more than [`RADIUS_ABS_TOLERANCE_MM`] and by more than 0.1 % of the
    /// radius, or by > 0.5 mm).
    RadiusMismatch,
    /// Zero radius (R0, or I/J/K all zero in the plane).
    ZeroRadius,
    /// R with the end point equal to the start point (a full circle needs I/J/K).
    FullCircleWithRadius,
    /// A coordinate, offset, radius or tolerance is NaN or infinite, or the
    /// tolerance is not positive.
    NotFinite,
}

impl ArcError {
    /// Text printed after `Error:`.
    pub fn message(&self) -> FStr {
        match self {
            ArcError::RadiusTooSmall => F!("arc: R too small for the distance to the end point"),
            ArcError::RadiusMismatch => F!("arc: end point not on the circle (I/J/K radius mismatch)"),
            ArcError::ZeroRadius => F!("arc: zero radius"),
            ArcError::FullCircleWithRadius => F!("arc: full circle needs I/J/K, not R"),
            ArcError::NotFinite => F!("arc: invalid number"),
        }
    }
}

/// A validated arc; iterate it for the chord end points (mm, X Y Z).
#[derive(Clone, Copy, Debug)]
pub struct Arc {
    /// Plane axes and the linear (normal) axis.
    axes: (usize, usize, usize),
    /// Centre in the plane, mm.
    centre: [f32; 2],
    /// Start radius, mm.
    radius: f32,
    /// Radius change per chord (I/J/K end-radius mismatch), mm.
    radius_per_chord: f32,
    /// Angle of the start point around the centre, rad.
    start_angle: f32,
    /// Signed angular travel, rad (negative = clockwise).
    angular_travel: f32,
    /// Angle per chord, rad.
    theta_per_chord: f32,
    /// cos and sin of `theta_per_chord`.
    cos_t: f32,
    sin_t: f32,
    /// Start point, mm.
    start: [f32; 3],
    /// Linear-axis travel per chord, mm.
    linear_per_chord: f32,
    /// Programmed end point, mm (the last chord ends here exactly).
    end: [f32; 3],
    /// Unit radius vector of the last point (plane coordinates).
    dir: [f32; 2],
    /// Chords in the arc (≥ 1).
    chords: u32,
    /// Chords already yielded.
    done: u32,
}

fn hypot(a: f32, b: f32) -> f32 {
    sqrtf(a * a + b * b)
}

impl Arc {
    /// Validate an arc from `start` to `end` (mm, X Y Z) and plan its chords.
    /// `plane` = (axis_0, axis_1, axis_linear); `clockwise` = G2.
    pub fn new(
        start: [f32; 3],
        end: [f32; 3],
        centre: Centre,
        plane: (usize, usize, usize),
        clockwise: bool,
        tolerance_mm: f32,
    ) -> Result<Arc, ArcError> {
        let (a0, a1, al) = plane;
        let finite = start.iter().chain(end.iter()).all(|v| v.is_finite());
        if !finite || !(tolerance_mm > 0.0 && tolerance_mm.is_finite()) || a0 > 2 || a1 > 2 || al > 2 {
            return Err(ArcError::NotFinite);
        }
        let dx = end[a0] - start[a0];
        let dy = end[a1] - start[a1];
        // Offset from start to centre in the plane, and the radius.
        let (off0, off1, radius, end_radius) = match centre {
            Centre::Radius(r) => {
                if !r.is_finite() {
                    return Err(ArcError::NotFinite);
                }
                if r == 0.0 {
                    return Err(ArcError::ZeroRadius);
                }
                let d2 = dx * dx + dy * dy;
                if d2 == 0.0 {
                    return Err(ArcError::FullCircleWithRadius);
                }
                // grbl gc_execute_line: centre on the chord's perpendicular bisector.
                let mut h2 = 4.0 * r * r - d2;
                if h2 < 0.0 {
                    // Allow float round-off on an exact half circle.
                    if h2 < -1e-5 * 4.0 * r * r {
                        return Err(ArcError::RadiusTooSmall);
                    }
                    h2 = 0.0;
                }
                let mut h_x2_div_d = -sqrtf(h2) / sqrtf(d2);
                if !clockwise {
                    h_x2_div_d = -h_x2_div_d;
                }
                if r < 0.0 {
                    h_x2_div_d = -h_x2_div_d;
                }
                let o0 = 0.5 * (dx - dy * h_x2_div_d);
                let o1 = 0.5 * (dy + dx * h_x2_div_d);
                let rr = hypot(o0, o1);
                (o0, o1, rr, rr)
            }
            Centre::Offset(ijk) => {
                if !ijk.iter().all(|v| v.is_finite()) {
                    return Err(ArcError::NotFinite);
                }
                let (o0, o1) = (ijk[a0], ijk[a1]);
                let r0 = hypot(o0, o1);
                if r0 == 0.0 {
                    return Err(ArcError::ZeroRadius);
                }
                let r1 = hypot(dx - o0, dy - o1);
                let delta_r = fabsf(r1 - r0);
                if delta_r > RADIUS_ABS_TOLERANCE_MM && (delta_r > 0.5 || delta_r > 0.001 * r0) {
                    return Err(ArcError::RadiusMismatch);
                }
                (o0, o1, r0, r1)
            }
        };
        let c0 = start[a0] + off0;
        let c1 = start[a1] + off1;
        // Radius vectors from the centre to the start and to the end.
        let (r0x, r0y) = (-off0, -off1);
        let (r1x, r1y) = (end[a0] - c0, end[a1] - c1);
        let full_circle = dx == 0.0 && dy == 0.0;
        let mut angular_travel = if full_circle { 0.0 } else { atan2f(r0x * r1y - r0y * r1x, r0x * r1x + r0y * r1y) };
        if clockwise {
            if angular_travel >= -ANGULAR_TRAVEL_EPSILON {
                angular_travel -= TWO_PI;
            }
        } else if angular_travel <= ANGULAR_TRAVEL_EPSILON {
            angular_travel += TWO_PI;
        }
        // Max angle per chord for the tolerance (see module doc).
        let r_max = if end_radius > radius { end_radius } else { radius };
        let phi = sqrtf(8.0 * tolerance_mm / r_max);
        let n = fabsf(angular_travel) / phi;
        let mut chords = n as u32;
        if (chords as f32) < n {
            chords += 1;
        }
        if chords == 0 {
            chords = 1;
        }
        let theta_per_chord = angular_travel / chords as f32;
        let (sin_t, cos_t) = sincosf(theta_per_chord);
        Ok(Arc {
            axes: plane,
            centre: [c0, c1],
            radius,
            radius_per_chord: (end_radius - radius) / chords as f32,
            start_angle: atan2f(r0y, r0x),
            angular_travel,
            theta_per_chord,
            cos_t,
            sin_t,
            start,
            linear_per_chord: (end[al] - start[al]) / chords as f32,
            end,
            dir: [r0x / radius, r0y / radius],
            chords,
            done: 0,
        })
    }

    /// Number of chords (points the iterator yields in all).
    pub fn chords(&self) -> u32 {
        self.chords
    }

    /// Signed angular travel, rad (negative = clockwise).
    pub fn angular_travel(&self) -> f32 {
        self.angular_travel
    }

    /// Centre in the plane (axis_0, axis_1), mm.
    pub fn centre(&self) -> [f32; 2] {
        self.centre
    }

    /// Start radius, mm.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Bounding box (min, max) of the whole arc, mm, X Y Z: start, end and every
    /// quadrant point the arc passes, for soft-limit checks before queueing.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [0f32; 3];
        let mut hi = [0f32; 3];
        for a in 0..3 {
            lo[a] = if self.start[a] < self.end[a] { self.start[a] } else { self.end[a] };
            hi[a] = if self.start[a] > self.end[a] { self.start[a] } else { self.end[a] };
        }
        let (a0, a1, _) = self.axes;
        let r_end = self.radius + self.radius_per_chord * self.chords as f32;
        let r = if r_end > self.radius { r_end } else { self.radius };
        // Quadrant points at angles k·π/2; include those inside the sweep.
        let (from, to) = if self.angular_travel >= 0.0 {
            (self.start_angle, self.start_angle + self.angular_travel)
        } else {
            (self.start_angle + self.angular_travel, self.start_angle)
        };
        let quarter = 0.5 * core::f32::consts::PI;
        // First multiple of π/2 at or after `from`.
        let mut k = {
            let q = from / quarter;
            let t = q as i32;
            if (t as f32) < q {
                t + 1
            } else {
                t
            }
        };
        while (k as f32) * quarter <= to {
            let (p0, p1) = match k.rem_euclid(4) {
                0 => (self.centre[0] + r, self.centre[1]),
                1 => (self.centre[0], self.centre[1] + r),
                2 => (self.centre[0] - r, self.centre[1]),
                _ => (self.centre[0], self.centre[1] - r),
            };
            lo[a0] = if p0 < lo[a0] { p0 } else { lo[a0] };
            hi[a0] = if p0 > hi[a0] { p0 } else { hi[a0] };
            lo[a1] = if p1 < lo[a1] { p1 } else { lo[a1] };
            hi[a1] = if p1 > hi[a1] { p1 } else { hi[a1] };
            k += 1;
        }
        (lo, hi)
    }
}

impl Iterator for Arc {
    type Item = [f32; 3];

    /// The next chord end point, mm, X Y Z. The last one is the programmed end.
    fn next(&mut self) -> Option<[f32; 3]> {
        if self.done >= self.chords {
            return None;
        }
        self.done += 1;
        let i = self.done;
        if i == self.chords {
            return Some(self.end);
        }
        if i.is_multiple_of(ARC_CORRECTION) {
            let (s, c) = sincosf(self.start_angle + i as f32 * self.theta_per_chord);
            self.dir = [c, s];
        } else {
            let [x, y] = self.dir;
            self.dir = [x * self.cos_t - y * self.sin_t, x * self.sin_t + y * self.cos_t];
        }
        let (a0, a1, al) = self.axes;
        let fi = i as f32;
        let r = if self.radius_per_chord.to_bits() == 0 { self.radius } else { self.radius + self.radius_per_chord * fi };
        let mut p = self.start;
        p[a0] = self.centre[0] + r * self.dir[0];
        p[a1] = self.centre[1] + r * self.dir[1];
        if self.linear_per_chord.to_bits() != 0 {
            p[al] = self.start[al] + self.linear_per_chord * fi;
        }
        Some(p)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = (self.chords - self.done) as usize;
        (n, Some(n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G17: (usize, usize, usize) = (0, 1, 2);
    const G18: (usize, usize, usize) = (2, 0, 1);
    const G19: (usize, usize, usize) = (1, 2, 0);
    const TOL: f32 = 0.002;

    /// All points, with the start prepended.
    fn points(start: [f32; 3], arc: Arc) -> Vec<[f32; 3]> {
        let mut v = vec![start];
        v.extend(arc);
        v
    }

    /// Checks every chord end on the circle and every chord's midpoint within
    /// the tolerance of it (f32 rounding allowed for). Returns the chord count.
    fn check_chords(start: [f32; 3], arc: Arc, tol: f32) -> usize {
        let (a0, a1, _) = arc.axes;
        let c = arc.centre();
        let r = arc.radius();
        let pts = points(start, arc);
        for w in pts.windows(2) {
            let (p, q) = (w[0], w[1]);
            for e in [p, q] {
                let d = ((e[a0] - c[0]).powi(2) + (e[a1] - c[1]).powi(2)).sqrt();
                assert!((d - r).abs() < 2e-5 * r.max(1.0), "point {e:?} off the circle: {d} vs {r}");
            }
            let m0 = 0.5 * (p[a0] + q[a0]) - c[0];
            let m1 = 0.5 * (p[a1] + q[a1]) - c[1];
            let sagitta = r - (m0 * m0 + m1 * m1).sqrt();
            assert!(sagitta <= tol + 2e-5 * r.max(1.0), "chord error {sagitta}");
            assert!(sagitta >= -2e-5 * r.max(1.0));
        }
        pts.len() - 1
    }

    /// Signed swept angle from the points (positive = counter-clockwise in the
    /// plane's (axis_0, axis_1) coordinates).
    fn swept(start: [f32; 3], arc: Arc) -> f32 {
        let (a0, a1, _) = arc.axes;
        let c = arc.centre();
        let pts = points(start, arc);
        let mut total = 0.0;
        for w in pts.windows(2) {
            let u = (w[0][a0] - c[0], w[0][a1] - c[1]);
            let v = (w[1][a0] - c[0], w[1][a1] - c[1]);
            total += (u.0 * v.1 - u.1 * v.0).atan2(u.0 * v.0 + u.1 * v.1);
        }
        total
    }

    /// A reported job: `G0 X18.087536 Y33.329412`, `G3 X18.087536 Y33.329412
    /// I-0.4 J-0.69282` moved 2 µrad instead of a full 0.8 mm circle: the
    /// angle between start and end came out of `end − centre` with f32
    /// round-off. Start == end in the plane is a full circle in every plane,
    /// both ways, helical or not, at any radius and any start.
    #[test]
    #[allow(clippy::excessive_precision)] // the coordinates as the job that found it wrote them
    fn start_equal_to_end_is_always_a_full_circle() {
        let start = [18.087536f32, 33.329412, 5.0];
        for cw in [false, true] {
            let arc = Arc::new(start, start, Centre::Offset([-0.4, -0.69282, 0.0]), G17, cw, TOL).unwrap();
            let want = if cw { -TWO_PI } else { TWO_PI };
            assert_eq!(arc.angular_travel(), want);
            assert!((swept(start, arc) - want).abs() < 1e-3, "cw {cw}: swept {}", swept(start, arc));
        }
        let mut skipped = 0;
        for plane in [G17, G18, G19] {
            let (a0, a1, al) = plane;
            for k in 0..36 {
                for &r in &[0.05f32, 0.8, 2.0, 7.3, 20.0] {
                    for cw in [false, true] {
                        for helix in [0.0f32, 1.5] {
                            let t = (k as f32 * 10.0 + 3.0).to_radians();
                            let mut start = [0.0f32; 3];
                            start[a0] = 18.087536 + 0.37 * k as f32;
                            start[a1] = 33.329412 - 0.11 * k as f32;
                            start[al] = 5.0;
                            let mut end = start;
                            end[al] += helix;
                            let mut off = [0.0f32; 3];
                            off[a0] = -r * t.cos();
                            off[a1] = -r * t.sin();
                            let arc = Arc::new(start, end, Centre::Offset(off), plane, cw, TOL).unwrap();
                            let sw = swept(start, arc);
                            if (sw.abs() - TWO_PI).abs() > 1e-3 || (sw < 0.0) != cw {
                                skipped += 1;
                            }
                            check_chords(start, arc, TOL);
                            assert_eq!(arc.last(), Some(end));
                        }
                    }
                }
            }
        }
        assert_eq!(skipped, 0, "arcs that were not full circles");
    }

    #[test]
    fn a_quarter_circle_in_g17_ends_exactly_at_the_end_within_tolerance() {
        let start = [10.0, 0.0, 1.0];
        let end = [0.0, 10.0, 1.0];
        let arc = Arc::new(start, end, Centre::Offset([-10.0, 0.0, 0.0]), G17, false, TOL).unwrap();
        assert_eq!(arc.centre(), [0.0, 0.0]);
        let n = check_chords(start, arc, TOL);
        // φ = √(8·0.002/10) = 0.04 rad → ⌈(π/2)/0.04⌉ = 40 chords.
        assert_eq!(n, 40);
        assert_eq!(arc.last(), Some(end));
        assert!((swept(start, arc) - core::f32::consts::FRAC_PI_2).abs() < 1e-4);
        assert!(points(start, arc).iter().all(|p| p[2] == 1.0));
    }

    #[test]
    fn g2_turns_clockwise_and_g3_counter_clockwise_in_every_plane() {
        for plane in [G17, G18, G19] {
            let (a0, a1, _) = plane;
            let mut start = [0.0f32; 3];
            let mut end = [0.0f32; 3];
            let mut off = [0.0f32; 3];
            // Centre at the origin, start on +axis_0, end on +axis_1.
            start[a0] = 5.0;
            end[a1] = 5.0;
            off[a0] = -5.0;
            let ccw = Arc::new(start, end, Centre::Offset(off), plane, false, TOL).unwrap();
            assert!((swept(start, ccw) - core::f32::consts::FRAC_PI_2).abs() < 1e-4, "{plane:?}");
            check_chords(start, ccw, TOL);
            let cw = Arc::new(start, end, Centre::Offset(off), plane, true, TOL).unwrap();
            assert!((swept(start, cw) + 1.5 * core::f32::consts::PI).abs() < 1e-4, "{plane:?}");
            check_chords(start, cw, TOL);
            assert_eq!(cw.last(), Some(end));
        }
    }

    #[test]
    fn g18_is_the_zx_plane_and_g19_the_yz_plane() {
        // G18 G3 from X5 Z0 to X0 Z5 around the origin passes X3.5 Z3.5 with Y fixed.
        let start = [5.0, 2.0, 0.0];
        let end = [0.0, 2.0, 5.0];
        let g18 = Arc::new(start, end, Centre::Offset([-5.0, 0.0, 0.0]), G18, true, TOL).unwrap();
        // In (Z, X) coordinates the start is at angle 90° and the end at 0°:
        // clockwise (G2) is the short way.
        assert!((g18.angular_travel() + core::f32::consts::FRAC_PI_2).abs() < 1e-5);
        assert!(points(start, g18).iter().all(|p| p[1] == 2.0));
        let mid = g18.clone().nth(g18.chords() as usize / 2 - 1).unwrap();
        assert!((mid[0] - mid[2]).abs() < 0.2 && mid[0] > 3.0, "{mid:?}");
        // G19 G3 from Y5 Z0 to Y0 Z5: counter-clockwise in (Y, Z), the short way.
        let start = [1.0, 5.0, 0.0];
        let end = [1.0, 0.0, 5.0];
        let g19 = Arc::new(start, end, Centre::Offset([0.0, -5.0, 0.0]), G19, false, TOL).unwrap();
        assert!((g19.angular_travel() - core::f32::consts::FRAC_PI_2).abs() < 1e-5);
        assert!(points(start, g19).iter().all(|p| p[0] == 1.0));
    }

    #[test]
    fn positive_r_takes_the_short_arc_and_negative_r_the_long_one() {
        let start = [0.0, 0.0, 0.0];
        let end = [10.0, 0.0, 0.0];
        let short = Arc::new(start, end, Centre::Radius(10.0), G17, false, TOL).unwrap();
        let long = Arc::new(start, end, Centre::Radius(-10.0), G17, false, TOL).unwrap();
        let sixty = core::f32::consts::PI / 3.0;
        assert!((short.angular_travel() - sixty).abs() < 1e-4);
        assert!((long.angular_travel() - (2.0 * core::f32::consts::PI - sixty)).abs() < 1e-4);
        assert!((short.radius() - 10.0).abs() < 1e-5 && (long.radius() - 10.0).abs() < 1e-5);
        // G3 from (0,0) to (10,0) turns left, so the short way has its centre
        // above the chord, at (5, 8.66).
        assert!((short.centre()[0] - 5.0).abs() < 1e-5 && (short.centre()[1] - 8.660254).abs() < 1e-4);
        assert!(long.centre()[1] < 0.0);
        check_chords(start, short, TOL);
        check_chords(start, long, TOL);
        assert_eq!(long.last(), Some(end));
        // G2 mirrors it.
        let cw = Arc::new(start, end, Centre::Radius(10.0), G17, true, TOL).unwrap();
        assert!(cw.centre()[1] < 0.0);
        assert!((cw.angular_travel() + sixty).abs() < 1e-4);
    }

    #[test]
    fn r_equal_to_half_the_chord_is_a_half_circle() {
        let start = [0.0, 0.0, 0.0];
        let end = [10.0, 0.0, 0.0];
        let arc = Arc::new(start, end, Centre::Radius(5.0), G17, true, TOL).unwrap();
        assert!((arc.angular_travel() + core::f32::consts::PI).abs() < 1e-4);
        assert_eq!(arc.centre(), [5.0, 0.0]);
    }

    #[test]
    fn a_full_circle_by_ijk_turns_360_degrees_and_returns_to_the_start() {
        let start = [20.0, 10.0, -1.0];
        let arc = Arc::new(start, start, Centre::Offset([-5.0, 0.0, 0.0]), G17, true, TOL).unwrap();
        assert!((arc.angular_travel() + 2.0 * core::f32::consts::PI).abs() < 1e-5);
        let n = check_chords(start, arc, TOL);
        assert_eq!(arc.last(), Some(start));
        // φ = √(8·0.002/5) = 0.0566 rad → ⌈2π/0.0566⌉ = 112 chords.
        assert_eq!(n, 112);
        assert!((swept(start, arc) + 2.0 * core::f32::consts::PI).abs() < 1e-3);
    }

    #[test]
    fn a_helix_moves_the_normal_axis_in_proportion_to_the_angle() {
        let start = [5.0, 0.0, 0.0];
        let end = [5.0, 0.0, -3.0];
        let arc = Arc::new(start, end, Centre::Offset([-5.0, 0.0, 0.0]), G17, false, TOL).unwrap();
        let n = arc.chords() as f32;
        for (i, p) in arc.enumerate() {
            let expect = -3.0 * (i as f32 + 1.0) / n;
            assert!((p[2] - expect).abs() < 1e-5, "{p:?}");
        }
        assert_eq!(arc.last(), Some(end));
        check_chords(start, arc, TOL);
        // Helical G19 too: X is the normal axis.
        let s2 = [0.0, 5.0, 0.0];
        let e2 = [2.0, 0.0, 5.0];
        let h = Arc::new(s2, e2, Centre::Offset([0.0, -5.0, 0.0]), G19, false, TOL).unwrap();
        assert_eq!(h.last(), Some(e2));
        assert!(h.clone().all(|p| p[0] >= 0.0 && p[0] <= 2.0));
    }

    #[test]
    fn chord_error_stays_within_tolerance_for_small_and_large_radii() {
        for (r, tol) in [(0.05f32, 0.002f32), (0.5, 0.002), (3.0, 0.01), (22.5, 0.002), (45.0, 0.0005)] {
            let start = [r, 0.0, 0.0];
            let end = [0.0, -r, 0.0];
            let arc = Arc::new(start, end, Centre::Offset([-r, 0.0, 0.0]), G17, false, tol).unwrap();
            check_chords(start, arc, tol);
            assert_eq!(arc.last(), Some(end));
        }
    }

    #[test]
    fn many_chords_do_not_accumulate_angle_error() {
        // 45 mm radius, fine tolerance: over a thousand chords.
        let start = [45.0, 0.0, 0.0];
        let arc = Arc::new(start, start, Centre::Offset([-45.0, 0.0, 0.0]), G17, false, 0.0001).unwrap();
        assert!(arc.chords() > 1000);
        let n = arc.chords();
        let step = 2.0 * core::f64::consts::PI / n as f64;
        for (i, p) in arc.enumerate().take(n as usize - 1) {
            let a = step * (i + 1) as f64;
            let (x, y) = (45.0 * a.cos(), 45.0 * a.sin());
            assert!((p[0] as f64 - x).abs() < 2e-4 && (p[1] as f64 - y).abs() < 2e-4, "{i}: {p:?}");
        }
    }

    #[test]
    fn an_ijk_end_slightly_off_the_circle_is_accepted_and_reached_smoothly() {
        // End radius 5.004 vs start 5: within 0.005 mm.
        let start = [5.0, 0.0, 0.0];
        let end = [0.0, 5.004, 0.0];
        let arc = Arc::new(start, end, Centre::Offset([-5.0, 0.0, 0.0]), G17, false, TOL).unwrap();
        let pts = points(start, arc);
        let last_chord = pts[pts.len() - 2];
        let d = ((last_chord[0] - end[0]).powi(2) + (last_chord[1] - end[1]).powi(2)).sqrt();
        // No jump: the last chord is as long as the others (r·φ = 0.283 mm).
        let chord = ((pts[1][0] - pts[0][0]).powi(2) + (pts[1][1] - pts[0][1]).powi(2)).sqrt();
        assert!(d < chord * 1.05, "last chord {d} vs {chord}");
        assert_eq!(arc.last(), Some(end));
    }

    #[test]
    fn every_invalid_arc_is_an_error() {
        let o = [0.0; 3];
        let x10 = [10.0, 0.0, 0.0];
        // R too small for a 10 mm chord.
        assert_eq!(Arc::new(o, x10, Centre::Radius(4.0), G17, true, TOL).unwrap_err(), ArcError::RadiusTooSmall);
        assert_eq!(Arc::new(o, x10, Centre::Radius(-4.9), G17, true, TOL).unwrap_err(), ArcError::RadiusTooSmall);
        // Zero radius.
        assert_eq!(Arc::new(o, x10, Centre::Radius(0.0), G17, true, TOL).unwrap_err(), ArcError::ZeroRadius);
        assert_eq!(Arc::new(o, x10, Centre::Offset([0.0, 0.0, 3.0]), G17, true, TOL).unwrap_err(), ArcError::ZeroRadius);
        // R full circle.
        assert_eq!(Arc::new(x10, x10, Centre::Radius(5.0), G17, true, TOL).unwrap_err(), ArcError::FullCircleWithRadius);
        // Start==end in the plane but a Z move is still a full circle with R.
        let z = [10.0, 0.0, 2.0];
        assert_eq!(Arc::new(x10, z, Centre::Radius(5.0), G17, true, TOL).unwrap_err(), ArcError::FullCircleWithRadius);
        // I/J/K end not on the circle: 5 vs 5.099 mm (> 0.005 mm and > 0.1 %).
        let e = [10.0, 1.0, 0.0];
        assert_eq!(Arc::new(o, e, Centre::Offset([5.0, 0.0, 0.0]), G17, true, TOL).unwrap_err(), ArcError::RadiusMismatch);
        // 0.03 mm off on a 5 mm radius: over 0.0283 mm and 0.1 % (0.005 mm).
        let e = [10.0, 0.0, 0.0];
        let c = Centre::Offset([5.015, 0.0, 0.0]);
        assert_eq!(Arc::new(o, e, c, G17, true, TOL).unwrap_err(), ArcError::RadiusMismatch);
        // 0.006 mm off on a 5 mm radius: over 0.1 % but under 0.0283 mm (LinuxCNC).
        let c = Centre::Offset([5.003, 0.0, 0.0]);
        assert!(Arc::new(o, e, c, G17, true, TOL).is_ok());
        // Corpus 06 (Fusion 360 HAAS post, inches): a 0.3 mm fillet whose end
        // radius is 0.0056 mm longer; grbl's 0.005 mm refused it.
        let s06 = [1.5919 * 25.4, 1.0709 * 25.4, 0.0];
        let e06 = [1.6139 * 25.4, 1.0797 * 25.4, 0.0];
        assert!(Arc::new(s06, e06, Centre::Offset([0.0114 * 25.4, 0.0031 * 25.4, 0.0]), G17, true, TOL).is_ok());
        // 0.04 mm off on a 50 mm radius: over 0.0283 mm but under 0.1 % (0.05 mm).
        let e = [100.0, 0.0, 0.0];
        let c = Centre::Offset([50.02, 0.0, 0.0]);
        assert!(Arc::new(o, e, c, G17, true, TOL).is_ok());
        // 0.6 mm off on a 1000 mm radius: under 0.1 % but over 0.5 mm.
        let e = [2000.0, 0.0, 0.0];
        let c = Centre::Offset([1000.3, 0.0, 0.0]);
        assert_eq!(Arc::new(o, e, c, G17, true, TOL).unwrap_err(), ArcError::RadiusMismatch);
        // Bad numbers.
        assert_eq!(Arc::new([f32::NAN, 0.0, 0.0], x10, Centre::Radius(6.0), G17, true, TOL).unwrap_err(), ArcError::NotFinite);
        assert_eq!(Arc::new(o, x10, Centre::Radius(f32::INFINITY), G17, true, TOL).unwrap_err(), ArcError::NotFinite);
        assert_eq!(Arc::new(o, x10, Centre::Radius(6.0), G17, true, 0.0).unwrap_err(), ArcError::NotFinite);
        for e in
            [ArcError::RadiusTooSmall, ArcError::RadiusMismatch, ArcError::ZeroRadius, ArcError::FullCircleWithRadius, ArcError::NotFinite]
        {
            assert!(e.message().starts_with("arc: "));
        }
    }

    #[test]
    fn full_circles_in_every_plane_by_ijk_and_by_two_r_halves_come_back_to_the_start() {
        for plane in [G17, G18, G19] {
            let (a0, _, al) = plane;
            // Start 7.5 mm from a centre at (22.5, 22.5) on axis_0.
            let mut start = [22.5f32; 3];
            start[a0] = 30.0;
            start[al] = 10.0;
            let mut off = [0.0f32; 3];
            off[a0] = -7.5;
            for clockwise in [true, false] {
                let arc = Arc::new(start, start, Centre::Offset(off), plane, clockwise, TOL).unwrap();
                assert_eq!(arc.centre(), [22.5, 22.5], "{plane:?}");
                let turn = if clockwise { -2.0 } else { 2.0 } * core::f32::consts::PI;
                assert!((arc.angular_travel() - turn).abs() < 1e-5, "{plane:?} cw={clockwise}");
                assert!((swept(start, arc) - turn).abs() < 1e-3, "{plane:?} cw={clockwise}");
                let n = check_chords(start, arc, TOL);
                // φ = √(8·0.002/7.5) = 0.0462 rad → ⌈2π/0.0462⌉ = 137 chords.
                assert_eq!(n, 137);
                assert_eq!(arc.last(), Some(start));
                assert!(points(start, arc).iter().all(|p| p[al] == 10.0), "{plane:?}: normal axis moved");
            }
            // The same circle as two half circles by R (a full circle by R alone
            // is refused): R equal to half the chord has one centre.
            let mut mid = start;
            mid[a0] = 15.0;
            let first = Arc::new(start, mid, Centre::Radius(7.5), plane, false, TOL).unwrap();
            let second = Arc::new(mid, start, Centre::Radius(7.5), plane, false, TOL).unwrap();
            for (h, from) in [(first, start), (second, mid)] {
                assert!((h.centre()[0] - 22.5).abs() < 1e-4 && (h.centre()[1] - 22.5).abs() < 1e-4, "{plane:?}");
                assert!((swept(from, h) - core::f32::consts::PI).abs() < 1e-3, "{plane:?}");
                check_chords(from, h, TOL);
            }
            assert_eq!(first.last(), Some(mid));
            assert_eq!(second.last(), Some(start));
            assert_eq!(Arc::new(start, start, Centre::Radius(7.5), plane, false, TOL).unwrap_err(), ArcError::FullCircleWithRadius);
        }
    }

    #[test]
    fn a_full_turn_helix_in_every_plane_ends_on_the_programmed_normal_coordinate() {
        for plane in [G17, G18, G19] {
            let (a0, _, al) = plane;
            let mut start = [20.0f32; 3];
            start[a0] = 25.0;
            let mut end = start;
            end[al] = 26.0;
            let mut off = [0.0f32; 3];
            off[a0] = -5.0;
            let arc = Arc::new(start, end, Centre::Offset(off), plane, true, TOL).unwrap();
            assert!((arc.angular_travel() + 2.0 * core::f32::consts::PI).abs() < 1e-5, "{plane:?}");
            let n = arc.chords() as f32;
            for (i, p) in arc.enumerate() {
                let want = 20.0 + 6.0 * (i as f32 + 1.0) / n;
                assert!((p[al] - want).abs() < 1e-4, "{plane:?}: {p:?}");
            }
            check_chords(start, arc, TOL);
            assert_eq!(arc.last(), Some(end));
        }
    }

    #[test]
    fn bounds_cover_every_chord_end_and_the_quadrant_points_passed() {
        let start = [10.0, 5.0, 0.0];
        let end = [0.0, 5.0, 2.0];
        // G3 from the right of centre (5,5) to the left, over the top: passes (5,10).
        let arc = Arc::new(start, end, Centre::Offset([-5.0, 0.0, 0.0]), G17, false, TOL).unwrap();
        let (lo, hi) = arc.bounds();
        assert!((hi[1] - 10.0).abs() < 1e-5 && (lo[1] - 5.0).abs() < 1e-5);
        assert_eq!((lo[0], hi[0]), (0.0, 10.0));
        assert_eq!((lo[2], hi[2]), (0.0, 2.0));
        for p in points(start, arc) {
            for a in 0..3 {
                assert!(p[a] >= lo[a] - 1e-5 && p[a] <= hi[a] + 1e-5, "{p:?}");
            }
        }
        // A full circle spans the whole disc.
        let c = Arc::new(start, start, Centre::Offset([-5.0, 0.0, 0.0]), G17, true, TOL).unwrap();
        let (lo, hi) = c.bounds();
        assert!((lo[0] - 0.0).abs() < 1e-5 && (hi[0] - 10.0).abs() < 1e-5);
        assert!((lo[1] - 0.0).abs() < 1e-5 && (hi[1] - 10.0).abs() < 1e-5);
    }
}
