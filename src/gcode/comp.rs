//! Cutter radius compensation (G41/G42, G41.1/G42.1, G40): the geometry of
//! the tool centre's path beside the programmed one, in the XY plane, as
//! LinuxCNC's interpreter works it out (`convert_straight_comp1/2`,
//! `convert_arc_comp1/2` in its `interp_convert.cc`; RS274/NGC 3.0 §2.5.19
//! and §3.5.20).
//!
//! ```text
//!  interp::Interp::motion_line ─► comp::entry / comp::offset / comp::corner
//!                                  (pure: points in, points or an error out)
//! ```
//!
//! - **Entry** (the first move after G41/G42): a line ends at the
//!   programmed end moved by the tool radius square to the line; an arc
//!   ends at its programmed end moved along the radius, on a circle through
//!   the tool's start whose centre lies on that radius (LinuxCNC's
//!   `convert_arc_comp1`).
//! - **Later moves**: each line or arc is offset by the radius to the left
//!   (G41) or right (G42) of its direction of travel. Where two moves meet,
//!   an **outside** corner gets an arc of the tool radius around the
//!   programmed corner; at an **inside** corner both moves stop at the
//!   intersection of their offset paths; a tangent junction needs nothing.
//! - Because an inside corner moves the end of the move before it, each
//!   compensated move is held back until the next one is known (the
//!   interpreter's [`Held`], one move of look-ahead).
//!
//! Refused, as LinuxCNC refuses them: an entry move not longer than the
//! tool radius, an arc on the inside whose radius is not larger than the
//! tool's (gouging), an inside corner the tool cannot reach without cutting
//! into a move (a move too short to compensate).
//!
//! All points are internal machine mm in the XY plane (X and Y are not
//! mirrored, so left and right, clockwise and counterclockwise are the
//! user's).

use crate::math::{atan2f, fabsf, sqrtf};

/// A point or vector in the XY plane, mm.
pub type P2 = [f32; 2];

/// Which side of the programmed path the tool runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// G41: left of the path, looking along the direction of travel.
    Left,
    /// G42: right of it.
    Right,
}

/// A line or an arc of the tool centre (or of the programmed path) in the
/// XY plane, from a start point kept elsewhere to `end`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seg {
    /// End point, mm.
    pub end: P2,
    /// Arc centre, mm (meaningless for a line).
    pub centre: P2,
    /// 0 a line, 1 a counterclockwise arc (G3), −1 a clockwise one (G2).
    pub turn: i8,
}

impl Seg {
    /// A straight move to `end`.
    pub const fn line(end: P2) -> Seg {
        Seg { end, centre: [0.0; 2], turn: 0 }
    }
}

/// A compensated move held back until the next one is known.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Held {
    /// The tool centre's move, from where the tool is (the interpreter's
    /// commanded position) to `seg.end`.
    pub seg: Seg,
    /// Its programmed end: the corner with the next move, mm.
    pub corner: P2,
    /// Z at its end, internal mm.
    pub z: f32,
    /// Its feed, mm/min before the override.
    pub feed: f32,
    /// G0.
    pub rapid: bool,
    /// Already sent to the planner (a line that is not a move in the plane
    /// released it): the next corner cannot move its end any more.
    pub sent: bool,
}

/// The interpreter's compensation state. RAM: 62 B (`size_of` on the AVR;
/// the host test `state_fits_its_ram_budget` keeps it there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    /// G41/G42 in force; `None`: G40.
    pub side: Option<Side>,
    /// Tool radius, mm (0: G41/G42 change nothing, as in LinuxCNC).
    pub radius_mm: f32,
    /// The next move in the plane is the entry move.
    pub entry: bool,
    /// The move held back for look-ahead.
    pub held: Option<Held>,
    /// An outside corner's arc still to run after the held move: (programmed
    /// corner, the arc's end, turn).
    pub corner_arc: Option<(P2, P2, i8)>,
}

impl State {
    /// G40, nothing held.
    pub const OFF: State = State { side: None, radius_mm: 0.0, entry: false, held: None, corner_arc: None };

    /// Set the mode: `side` (`None`: G40) with `radius_mm`, nothing held.
    /// Field by field: assigning a whole `State` made the AVR build keep a
    /// 59-byte copy of it in RAM (`.data`) to copy from.
    pub fn set(&mut self, side: Option<Side>, radius_mm: f32) {
        self.side = side;
        self.radius_mm = radius_mm;
        self.entry = side.is_some();
        self.held = None;
        self.corner_arc = None;
    }

    /// Compensation moves the tool: on, with a radius.
    pub fn active(&self) -> bool {
        self.side.is_some() && self.radius_mm > 0.0
    }
}

/// Why a compensated move was refused (the text after `Error:`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompError {
    /// The entry move is not longer than the tool radius.
    EntryTooShort,
    /// An arc with the tool on its inside is not larger than the tool.
    ConcaveArcTooSmall,
    /// At an inside corner the tool would have to cut into one of the moves.
    Gouge,
    /// The entry arc has no circle through its start and offset end.
    EntryArc,
}

impl CompError {
    /// Text printed after `Error:`.
    pub fn message(self) -> crate::flash::FStr {
        match self {
            CompError::EntryTooShort => F!("G41/G42: entry move not longer than the tool radius, nothing moved"),
            CompError::ConcaveArcTooSmall => F!("G41/G42: arc radius not larger than the tool radius on its inside (gouge), nothing moved"),
            CompError::Gouge => F!("G41/G42: move too short to compensate at an inside corner (gouge), nothing moved"),
            CompError::EntryArc => F!("G41/G42: no entry arc through the start and the offset end, nothing moved"),
        }
    }
}

/// Where two compensated moves meet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Corner {
    /// They meet already (a tangent junction).
    Tangent,
    /// An arc of the tool radius around the programmed corner joins them,
    /// turning `turn` (as [`Seg::turn`]).
    Outside { turn: i8 },
    /// Both stop at this point.
    Inside(P2),
}

// Everything here but `along` is inlined into its one caller
// (`Interp::comp_move`): on the AVR, calls that took two points by
// reference and an `f32`, or returned a point, came back wrong in simavr
// (`a[1] + v[1] * k` lost its product; the callee read the `f32` from its
// stack while the caller passed it in registers). The cause found since:
// LLVM-AVR reads arguments passed on the stack one byte off on the
// ATmega2560 (3-byte return addresses), and `tools/stack-args` fails the
// tests on any function that does (it caught `corner` as a call). `along`
// takes three references and returns an `f32`, all in registers: a call,
// checked by that tool. The host twin is the same code, so the host tests
// still check it; tests/dialect.rs checks the AVR build against the
// reference.

// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn sub(a: &P2, b: &P2) -> P2 {
    [a[0] - b[0], a[1] - b[1]]
}

// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn add_scaled(a: &P2, v: &P2, k: f32) -> P2 {
    [a[0] + v[0] * k, a[1] + v[1] * k]
}

// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn dot(a: &P2, b: &P2) -> f32 {
    a[0] * b[0] + a[1] * b[1]
}

// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn cross(a: &P2, b: &P2) -> f32 {
    a[0] * b[1] - a[1] * b[0]
}

// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn len(a: &P2) -> f32 {
    sqrtf(dot(a, a))
}

// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn dist(a: &P2, b: &P2) -> f32 {
    len(&sub(a, b))
}

/// `a` scaled to length 1 (`a` itself when it has no length).
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn unit(a: &P2) -> P2 {
    let l = len(a);
    if l > 0.0 {
        [a[0] / l, a[1] / l]
    } else {
        *a
    }
}

/// The unit normal on `side` of the unit direction `t`.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn normal(side: Side, t: &P2) -> P2 {
    match side {
        Side::Left => [-t[1], t[0]],
        Side::Right => [t[1], -t[0]],
    }
}

/// True when the tool runs on the inside of an arc turning `turn`.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn inside_arc(side: Side, turn: i8) -> bool {
    (side == Side::Left) == (turn > 0)
}

/// The unit direction of travel of `seg` (from `start`) at its start or end.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
pub fn tangent(start: &P2, seg: &Seg, at_end: bool) -> P2 {
    if seg.turn == 0 {
        return unit(&sub(&seg.end, start));
    }
    let u = unit(&sub(if at_end { &seg.end } else { start }, &seg.centre));
    if seg.turn > 0 {
        [-u[1], u[0]]
    } else {
        [u[1], -u[0]]
    }
}

/// The entry move (the first after G41/G42) from the tool at `from` for the
/// programmed move `prog` (from `from`): LinuxCNC's `convert_straight_comp1`
/// and `convert_arc_comp1`.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
pub fn entry(side: Side, r: f32, from: &P2, prog: &Seg) -> Result<Seg, CompError> {
    let p = &prog.end;
    if !(dist(p, from) > r) {
        return Err(CompError::EntryTooShort);
    }
    if prog.turn == 0 {
        let n = normal(side, &unit(&sub(p, from)));
        return Ok(Seg::line(add_scaled(p, &n, r)));
    }
    let radial = sub(p, &prog.centre);
    let radius = len(&radial);
    let inside = inside_arc(side, prog.turn);
    if inside && !(radius > r) {
        return Err(CompError::ConcaveArcTooSmall);
    }
    let u = unit(&radial);
    let end = add_scaled(p, &u, if inside { -r } else { r });
    // The centre lies on the line from the end through the programmed
    // centre, as far from the start as from the end.
    let w = unit(&sub(&prog.centre, &end));
    let chord = sub(from, &end);
    let c = len(&chord);
    let cos_a = dot(&chord, &w) / c;
    if !(fabsf(cos_a) > 1e-4) {
        return Err(CompError::EntryArc);
    }
    let centre = add_scaled(&end, &w, c * 0.5 / cos_a);
    Ok(Seg { end, centre, turn: prog.turn })
}

/// A later move: the programmed move `prog` from `pstart`, offset by `r`
/// to `side`. Returns the compensated start and the compensated move.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
pub fn offset(side: Side, r: f32, pstart: &P2, prog: &Seg) -> Result<(P2, Seg), CompError> {
    if prog.turn == 0 {
        let n = normal(side, &unit(&sub(&prog.end, pstart)));
        return Ok((add_scaled(pstart, &n, r), Seg::line(add_scaled(&prog.end, &n, r))));
    }
    let radius = dist(pstart, &prog.centre);
    let inside = inside_arc(side, prog.turn);
    if inside && !(radius > r) {
        return Err(CompError::ConcaveArcTooSmall);
    }
    let k = if inside { -r } else { r };
    let start = add_scaled(pstart, &unit(&sub(pstart, &prog.centre)), k);
    let end = add_scaled(&prog.end, &unit(&sub(&prog.end, &prog.centre)), k);
    Ok((start, Seg { end, centre: prog.centre, turn: prog.turn }))
}

/// The corner at the programmed point `p` between the held compensated
/// move `held` (from `held_start`, ending `r` from `p`) and the next one,
/// `next` from `next_start` (also `r` from `p`). An inside corner's point
/// is checked to lie on both moves.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
pub fn corner(side: Side, p: &P2, held_start: &P2, held: &Seg, next_start: &P2, next: &Seg) -> Result<Corner, CompError> {
    let n1 = unit(&sub(&held.end, p));
    let n2 = unit(&sub(next_start, p));
    let turn = cross(&n1, &n2);
    let left_turn = turn > 1e-4;
    let right_turn = turn < -1e-4;
    if !left_turn && !right_turn && dot(&n1, &n2) > 0.0 {
        return Ok(Corner::Tangent);
    }
    // The path turns toward the tool's side: the tool is inside the corner.
    let inside = match side {
        Side::Left => left_turn,
        Side::Right => right_turn,
    };
    if !inside {
        return Ok(Corner::Outside { turn: if side == Side::Left { -1 } else { 1 } });
    }
    let guess = [(held.end[0] + next_start[0]) * 0.5, (held.end[1] + next_start[1]) * 0.5];
    let x = intersect(held_start, held, next_start, next, &guess).ok_or(CompError::Gouge)?;
    // On the held move (not before its start) and on the next (not past its end).
    let on_held = along(held_start, held, &x);
    if !(on_held <= along(held_start, held, &held.end) + 1e-4)
        || on_held < -1e-4
        || !(along(next_start, next, &x) < along(next_start, next, &next.end))
    {
        return Err(CompError::Gouge);
    }
    Ok(Corner::Inside(x))
}

/// How far along `seg` (from `start`) the point `x` (on its path) lies: mm
/// for a line, radians of sweep for an arc (a full circle sweeps 2π).
// flash: a call (references in, an f32 out), not four inlined copies in `corner`
#[inline(never)]
fn along(start: &P2, seg: &Seg, x: &P2) -> f32 {
    if seg.turn == 0 {
        return dot(&sub(x, start), &unit(&sub(&seg.end, start)));
    }
    let a0 = atan2f(start[1] - seg.centre[1], start[0] - seg.centre[0]);
    let a = atan2f(x[1] - seg.centre[1], x[0] - seg.centre[0]);
    let mut sweep = (a - a0) * seg.turn as f32;
    let tau = 2.0 * core::f32::consts::PI;
    while sweep < -1e-5 {
        sweep += tau;
    }
    // The end of a full circle is a whole turn from its start.
    if seg.end == *start && *x == seg.end {
        return tau;
    }
    sweep
}

/// The crossing of the paths of two moves (lines or circles) nearest to
/// `guess`.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn intersect(s1: &P2, m1: &Seg, s2: &P2, m2: &Seg, guess: &P2) -> Option<P2> {
    match (m1.turn == 0, m2.turn == 0) {
        (true, true) => {
            let d1 = sub(&m1.end, s1);
            let d2 = sub(&m2.end, s2);
            let den = cross(&d1, &d2);
            if fabsf(den) < 1e-12 {
                return None;
            }
            let t = cross(&sub(s2, s1), &d2) / den;
            Some(add_scaled(s1, &d1, t))
        }
        (true, false) => line_circle(s1, &m1.end, &m2.centre, dist(s2, &m2.centre), guess),
        (false, true) => line_circle(s2, &m2.end, &m1.centre, dist(s1, &m1.centre), guess),
        (false, false) => circle_circle(&m1.centre, dist(s1, &m1.centre), &m2.centre, dist(s2, &m2.centre), guess),
    }
}

/// Of two points, the one nearer `guess`.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn nearer(a: P2, b: P2, guess: &P2) -> P2 {
    if dist(&a, guess) <= dist(&b, guess) {
        a
    } else {
        b
    }
}

/// The line through `a` and `b` crossing the circle (`c`, `r`).
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn line_circle(a: &P2, b: &P2, c: &P2, r: f32, guess: &P2) -> Option<P2> {
    let d = unit(&sub(b, a));
    let f = sub(a, c);
    let bq = dot(&f, &d);
    let disc = bq * bq - (dot(&f, &f) - r * r);
    if disc < 0.0 {
        return None;
    }
    let s = sqrtf(disc);
    Some(nearer(add_scaled(a, &d, -bq + s), add_scaled(a, &d, -bq - s), guess))
}

/// Two circles crossing.
// correctness: inlined into its one caller (the note above)
#[inline(always)]
fn circle_circle(c1: &P2, r1: f32, c2: &P2, r2: f32, guess: &P2) -> Option<P2> {
    let d = sub(c2, c1);
    let l = len(&d);
    if !(l > 0.0) || l > r1 + r2 || l < fabsf(r1 - r2) {
        return None;
    }
    let a = (r1 * r1 - r2 * r2 + l * l) / (2.0 * l);
    let h2 = r1 * r1 - a * a;
    let h = if h2 > 0.0 { sqrtf(h2) } else { 0.0 };
    let u = unit(&d);
    let m = add_scaled(c1, &u, a);
    let n = [-u[1], u[0]];
    Some(nearer(add_scaled(&m, &n, h), add_scaled(&m, &n, -h), guess))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: P2, b: P2) -> bool {
        fabsf(a[0] - b[0]) < 1e-4 && fabsf(a[1] - b[1]) < 1e-4
    }

    #[test]
    fn state_fits_its_ram_budget() {
        // f32 and P2 align to 1 on the AVR: the host's padding only adds.
        assert!(core::mem::size_of::<State>() <= 72, "{}", core::mem::size_of::<State>());
    }

    #[test]
    fn a_line_entry_ends_a_radius_square_to_the_line() {
        let e = entry(Side::Left, 1.0, &[0.0, 0.0], &Seg::line([10.0, 0.0])).unwrap();
        assert!(close(e.end, [10.0, 1.0]), "{e:?}");
        let e = entry(Side::Right, 1.0, &[0.0, 0.0], &Seg::line([10.0, 0.0])).unwrap();
        assert!(close(e.end, [10.0, -1.0]), "{e:?}");
        assert_eq!(entry(Side::Left, 1.0, &[0.0, 0.0], &Seg::line([1.0, 0.0])), Err(CompError::EntryTooShort));
    }

    #[test]
    fn an_arc_entry_ends_on_the_offset_circle_on_a_circle_through_the_start() {
        // G41 G3 from (50,50) to (70,50) around (60,50): the tool inside.
        let prog = Seg { end: [70.0, 50.0], centre: [60.0, 50.0], turn: 1 };
        let e = entry(Side::Left, 2.0, &[50.0, 50.0], &prog).unwrap();
        assert!(close(e.end, [68.0, 50.0]), "{e:?}");
        let r0 = dist(&[50.0, 50.0], &e.centre);
        let r1 = dist(&e.end, &e.centre);
        assert!(fabsf(r0 - r1) < 1e-4, "{r0} {r1}");
        assert!(fabsf(e.centre[1] - 50.0) < 1e-4, "centre on the end's radius: {e:?}");
        let small = Seg { end: [70.0, 50.0], centre: [68.0, 50.0], turn: 1 };
        assert_eq!(entry(Side::Left, 2.5, &[50.0, 50.0], &small), Err(CompError::ConcaveArcTooSmall));
    }

    #[test]
    fn offsets_go_left_or_right_of_the_direction_of_travel() {
        let (s, m) = offset(Side::Left, 1.0, &[0.0, 0.0], &Seg::line([0.0, 10.0])).unwrap();
        assert!(close(s, [-1.0, 0.0]) && close(m.end, [-1.0, 10.0]));
        // G2 (clockwise) with G41: the tool outside the arc.
        let arc = Seg { end: [10.0, 0.0], centre: [5.0, 0.0], turn: -1 };
        let (s, m) = offset(Side::Left, 1.0, &[0.0, 0.0], &arc).unwrap();
        assert!(close(s, [-1.0, 0.0]) && close(m.end, [11.0, 0.0]), "{s:?} {m:?}");
        let (s, m) = offset(Side::Right, 1.0, &[0.0, 0.0], &arc).unwrap();
        assert!(close(s, [1.0, 0.0]) && close(m.end, [9.0, 0.0]), "{s:?} {m:?}");
        let tight = Seg { end: [2.0, 0.0], centre: [1.0, 0.0], turn: -1 };
        assert_eq!(offset(Side::Right, 1.0, &[0.0, 0.0], &tight), Err(CompError::ConcaveArcTooSmall));
    }

    #[test]
    fn corners_are_outside_inside_or_tangent() {
        // Along +X, then +Y: a left turn. G41: inside; G42: outside.
        let p = [10.0, 0.0];
        let (hs, h) = offset(Side::Left, 1.0, &[0.0, 0.0], &Seg::line(p)).unwrap();
        let (ns, n) = offset(Side::Left, 1.0, &p, &Seg::line([10.0, 10.0])).unwrap();
        assert_eq!(corner(Side::Left, &p, &hs, &h, &ns, &n), Ok(Corner::Inside([9.0, 1.0])));
        let (hs, h) = offset(Side::Right, 1.0, &[0.0, 0.0], &Seg::line(p)).unwrap();
        let (ns, n) = offset(Side::Right, 1.0, &p, &Seg::line([10.0, 10.0])).unwrap();
        assert_eq!(corner(Side::Right, &p, &hs, &h, &ns, &n), Ok(Corner::Outside { turn: 1 }));
        // Straight on: tangent.
        let (ns, n) = offset(Side::Right, 1.0, &p, &Seg::line([20.0, 0.0])).unwrap();
        assert_eq!(corner(Side::Right, &p, &hs, &h, &ns, &n), Ok(Corner::Tangent));
        // A line into a tangent arc.
        let arc = Seg { end: [20.0, 10.0], centre: [10.0, 10.0], turn: 1 };
        let (ns, n) = offset(Side::Left, 1.0, &p, &arc).unwrap();
        let (hs, h) = offset(Side::Left, 1.0, &[0.0, 0.0], &Seg::line(p)).unwrap();
        assert_eq!(corner(Side::Left, &p, &hs, &h, &ns, &n), Ok(Corner::Tangent));
    }

    #[test]
    fn an_inside_corner_after_a_move_shorter_than_the_tool_gouges() {
        let p = [0.5, 0.0];
        let (hs, h) = offset(Side::Left, 1.0, &[0.0, 0.0], &Seg::line(p)).unwrap();
        let (ns, n) = offset(Side::Left, 1.0, &p, &Seg::line([0.5, 10.0])).unwrap();
        assert_eq!(corner(Side::Left, &p, &hs, &h, &ns, &n), Err(CompError::Gouge));
    }

    #[test]
    fn an_inside_corner_between_a_line_and_an_arc_meets_on_both() {
        // Along +X to (10,0), then a G2 starting toward +Y: a left turn.
        let p = [10.0, 0.0];
        let (hs, h) = offset(Side::Left, 1.0, &[0.0, 0.0], &Seg::line(p)).unwrap();
        let arc = Seg { end: [20.0, 10.0], centre: [20.0, 0.0], turn: -1 };
        let (ns, n) = offset(Side::Left, 1.0, &p, &arc).unwrap();
        match corner(Side::Left, &p, &hs, &h, &ns, &n).unwrap() {
            Corner::Inside(x) => {
                assert!(fabsf(x[1] - 1.0) < 1e-4, "{x:?}");
                assert!(fabsf(dist(&x, &arc.centre) - 11.0) < 1e-3, "{x:?}");
            }
            c => panic!("{c:?}"),
        }
    }
}
