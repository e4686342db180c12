//! The physical tool changer (docs/SPEC.md §12): a 12-pocket carousel holding tools
//! with real lengths and diameters, the spindle's clamp, and the collisions
//! a wrong sequence would cause. Pure: fed one step at a time by the VM.
//!
//! Geometry, in steps (Z grows downward; thesis Table 8 by default):
//! - Pocket `p` is at the station when the carousel angle is
//!   `80° + 20°·(p − 1)` within `align_tol_steps` of E.
//! - The spindle is *in the magazine* when |X − X1| ≤ `x_tol_steps`, Y is past
//!   the fork entry (halfway from point A to point B) and Z is at or below Z1
//!   (minus `pos_tol_steps`).
//! - A transfer happens only with a pocket aligned, Y at point B and Z
//!   reaching Z2 (each within `pos_tol_steps`): a tool in the spindle is
//!   pushed into an empty pocket and released; an empty spindle coming down on
//!   a full pocket clamps its tool. The spindle leaves a clamped tool's pocket
//!   sideways (Y out); a released tool stays when Z goes up.
//!
//! Collisions (recorded, never fatal):
//! - a tool in the spindle (or the bare spindle below Z1) enters the magazine
//!   where the aligned pocket is full ([`CollisionKind::OccupiedPocket`]) or
//!   where no pocket is aligned ([`CollisionKind::NoPocket`]);
//! - Z goes up while a just-clamped tool still sits in its pocket
//!   ([`CollisionKind::LeftWithToolClamped`]);
//! - the carousel turns while a tool (or the spindle below Z1) is in the
//!   magazine ([`CollisionKind::CarouselTurnedWhileEngaged`]).

use serde::Serialize;

/// Number of pockets.
pub const POCKETS: usize = 12;

/// A tool: its id and its geometry.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Tool {
    pub id: u8,
    /// Gauge line (spindle nose) to tip, mm.
    pub length_mm: f64,
    /// Cutting diameter, mm.
    pub diameter_mm: f64,
}

/// What can go wrong physically.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum CollisionKind {
    /// Driven into a pocket that already holds a tool.
    OccupiedPocket { pocket: u8 },
    /// Entered the magazine with no pocket aligned (hit the carousel disc).
    NoPocket,
    /// Z went up with the clamped tool still held by its pocket.
    LeftWithToolClamped { pocket: u8 },
    /// The carousel turned while something was in a pocket.
    CarouselTurnedWhileEngaged,
}

/// One collision and the physical position (steps) where it happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Collision {
    pub kind: CollisionKind,
    pub position: [i64; 4],
}

/// One tool movement between spindle and pocket.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Transfer {
    pub tool: u8,
    pub pocket: u8,
    /// true: pocket → spindle (clamp); false: spindle → pocket (release).
    pub to_spindle: bool,
}

/// The changer's configuration and initial contents.
#[derive(Clone, Debug)]
pub struct AtcConfig {
    /// Pocket contents at power-on (index = pocket − 1).
    pub pockets: [Option<Tool>; POCKETS],
    /// Tool in the spindle at power-on.
    pub spindle: Option<Tool>,
    /// Station X1, Y point A, Y point B, Z1, Z2, steps.
    pub x1: i64,
    pub y_a: i64,
    pub y_b: i64,
    pub z1: i64,
    pub z2: i64,
    /// E steps per carousel revolution.
    pub steps_per_rev: i64,
    /// Angle of pocket 1 and the pitch, degrees.
    pub pocket1_deg: f64,
    pub pitch_deg: f64,
    /// A pocket is aligned within this many E steps.
    pub align_tol_steps: f64,
    /// Y at point B and Z at Z2 within this many steps.
    pub pos_tol_steps: i64,
    /// Half the width of the pocket opening in X, steps.
    pub x_tol_steps: i64,
}

impl AtcConfig {
    /// The default tool in pocket `p`: length 18 + 1.5·p mm, diameter 1 + 0.5·p mm.
    pub fn default_tool(p: u8) -> Tool {
        Tool { id: p, length_mm: 18.0 + 1.5 * p as f64, diameter_mm: 1.0 + 0.5 * p as f64 }
    }
}

impl Default for AtcConfig {
    fn default() -> Self {
        let mut pockets = [None; POCKETS];
        for (i, slot) in pockets.iter_mut().enumerate() {
            *slot = Some(AtcConfig::default_tool(i as u8 + 1));
        }
        AtcConfig {
            pockets,
            spindle: None,
            x1: 2300,
            y_a: 2800,
            y_b: 4400,
            z1: 4050,
            z2: 4500,
            steps_per_rev: 3200,
            pocket1_deg: 80.0,
            pitch_deg: 20.0,
            align_tol_steps: 2.0,
            pos_tol_steps: 10,
            x_tol_steps: 100,
        }
    }
}

/// A clamp or release at Z2 that the spindle has not moved away from yet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Latch {
    Released,
    Clamped(u8),
}

/// The changer's physical state.
#[derive(Clone, Debug)]
pub struct AtcModel {
    config: AtcConfig,
    /// Tool in the spindle.
    pub spindle: Option<Tool>,
    /// Pocket contents (index = pocket − 1).
    pub pockets: [Option<Tool>; POCKETS],
    /// Every collision so far.
    pub collisions: Vec<Collision>,
    /// Every transfer so far.
    pub transfers: Vec<Transfer>,
    in_magazine: bool,
    latch: Option<Latch>,
    turn_reported: bool,
}

impl AtcModel {
    /// A changer as configured, with the machine at `pos`.
    pub fn new(config: AtcConfig, pos: &[i64; 4]) -> AtcModel {
        let mut m = AtcModel {
            spindle: config.spindle,
            pockets: config.pockets,
            config,
            collisions: Vec::new(),
            transfers: Vec::new(),
            in_magazine: false,
            latch: None,
            turn_reported: false,
        };
        m.in_magazine = m.in_zone(pos);
        m
    }

    /// The configuration.
    pub fn config(&self) -> &AtcConfig {
        &self.config
    }

    /// The pocket facing the station at carousel position `e` (steps), if one is aligned.
    pub fn aligned_pocket(&self, e: i64) -> Option<u8> {
        let c = &self.config;
        let rev = c.steps_per_rev as f64;
        let a = e.rem_euclid(c.steps_per_rev) as f64;
        (1..=POCKETS as u8).find(|&p| {
            let centre = (c.pocket1_deg + c.pitch_deg * (p - 1) as f64) / 360.0 * rev;
            let d = (a - centre).abs();
            d.min(rev - d) <= c.align_tol_steps
        })
    }

    /// Pocket `p` (1..=12) contents.
    pub fn pocket(&self, p: u8) -> Option<Tool> {
        self.pockets[p as usize - 1]
    }

    /// Ids of the tools in pockets 1..=12 (0 = empty).
    pub fn pocket_ids(&self) -> [u8; POCKETS] {
        let mut ids = [0; POCKETS];
        for (i, t) in self.pockets.iter().enumerate() {
            ids[i] = t.map_or(0, |t| t.id);
        }
        ids
    }

    fn in_zone(&self, p: &[i64; 4]) -> bool {
        let c = &self.config;
        let y_entry = (c.y_a + c.y_b) / 2;
        (p[0] - c.x1).abs() <= c.x_tol_steps && p[1] >= y_entry && p[2] >= c.z1 - c.pos_tol_steps
    }

    fn collide(&mut self, kind: CollisionKind, p: &[i64; 4]) {
        self.collisions.push(Collision { kind, position: *p });
    }

    /// The machine made one step on `axis` (0..=3) and is now at `p`.
    pub fn on_step(&mut self, p: &[i64; 4], axis: usize) {
        let c = self.config.clone();
        let zone = self.in_zone(p);
        let low = p[2] > c.z1 + c.pos_tol_steps;
        if axis == 3 {
            if zone && (self.spindle.is_some() || low) && !self.turn_reported {
                self.turn_reported = true;
                self.collide(CollisionKind::CarouselTurnedWhileEngaged, p);
            }
            return;
        }
        let aligned = self.aligned_pocket(p[3]);
        if zone && !self.in_magazine && (self.spindle.is_some() || low) {
            match aligned {
                None => self.collide(CollisionKind::NoPocket, p),
                Some(k) if self.pocket(k).is_some() => self.collide(CollisionKind::OccupiedPocket { pocket: k }, p),
                Some(_) => {}
            }
        }
        if zone && axis == 2 {
            let at_b = (p[1] - c.y_b).abs() <= c.pos_tol_steps;
            let at_z2 = (p[2] - c.z2).abs() <= c.pos_tol_steps;
            if at_b && at_z2 && self.latch.is_none() {
                if let Some(k) = aligned {
                    let slot = k as usize - 1;
                    match (self.spindle, self.pockets[slot]) {
                        (Some(t), None) => {
                            self.pockets[slot] = Some(t);
                            self.spindle = None;
                            self.latch = Some(Latch::Released);
                            self.transfers.push(Transfer { tool: t.id, pocket: k, to_spindle: false });
                        }
                        (None, Some(t)) => {
                            self.spindle = Some(t);
                            self.pockets[slot] = None;
                            self.latch = Some(Latch::Clamped(k));
                            self.transfers.push(Transfer { tool: t.id, pocket: k, to_spindle: true });
                        }
                        (Some(_), Some(_)) => self.collide(CollisionKind::OccupiedPocket { pocket: k }, p),
                        (None, None) => {}
                    }
                }
            }
            if p[2] < c.z2 - c.pos_tol_steps {
                if let Some(Latch::Clamped(k)) = self.latch {
                    self.collide(CollisionKind::LeftWithToolClamped { pocket: k }, p);
                }
                self.latch = None;
            }
        }
        if !zone {
            self.latch = None;
            self.turn_reported = false;
        }
        self.in_magazine = zone;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Walk one axis from the current position to `to`, a step at a time.
    fn walk(m: &mut AtcModel, pos: &mut [i64; 4], axis: usize, to: i64) {
        while pos[axis] != to {
            pos[axis] += (to - pos[axis]).signum();
            m.on_step(pos, axis);
        }
    }

    fn pocket_e(p: u8) -> i64 {
        ((80.0 + 20.0 * (p - 1) as f64) / 360.0 * 3200.0).round() as i64
    }

    #[test]
    fn pocket_alignment_follows_the_thesis_angles() {
        let m = AtcModel::new(AtcConfig::default(), &[0; 4]);
        assert_eq!(m.aligned_pocket(711), Some(1));
        assert_eq!(m.aligned_pocket(0), None);
        assert_eq!(m.aligned_pocket(pocket_e(12)), Some(12));
        assert_eq!(m.aligned_pocket(pocket_e(5) + 3200), Some(5));
        assert_eq!(m.aligned_pocket(pocket_e(5) + 5), None);
    }

    #[test]
    fn thesis_sequence_picks_and_returns_without_collision() {
        let c = AtcConfig::default();
        let mut pos = [c.x1, c.y_a, c.z1, 0];
        let mut m = AtcModel::new(c.clone(), &pos);
        // Condition 1: pick T3.
        walk(&mut m, &mut pos, 3, pocket_e(3));
        walk(&mut m, &mut pos, 1, c.y_b);
        walk(&mut m, &mut pos, 2, c.z2);
        walk(&mut m, &mut pos, 1, c.y_a);
        assert_eq!(m.spindle.map(|t| t.id), Some(3));
        assert_eq!(m.pocket(3), None);
        // Condition 2: return T3, pick T4.
        walk(&mut m, &mut pos, 2, c.z1);
        walk(&mut m, &mut pos, 1, c.y_b);
        walk(&mut m, &mut pos, 2, c.z2);
        walk(&mut m, &mut pos, 2, c.z1);
        assert_eq!(m.spindle, None);
        assert_eq!(m.pocket(3).map(|t| t.id), Some(3));
        walk(&mut m, &mut pos, 3, pocket_e(4));
        walk(&mut m, &mut pos, 2, c.z2);
        walk(&mut m, &mut pos, 1, c.y_a);
        assert_eq!(m.spindle.map(|t| t.id), Some(4));
        assert!(m.collisions.is_empty(), "{:?}", m.collisions);
        assert_eq!(m.transfers.len(), 3);
    }

    #[test]
    fn a_tool_driven_into_a_full_pocket_collides() {
        let mut c = AtcConfig::default();
        c.spindle = Some(AtcConfig::default_tool(3));
        let mut pos = [c.x1, c.y_a, c.z1, pocket_e(2)];
        let mut m = AtcModel::new(c.clone(), &pos);
        walk(&mut m, &mut pos, 1, c.y_b);
        assert_eq!(m.collisions[0].kind, CollisionKind::OccupiedPocket { pocket: 2 });
    }

    #[test]
    fn lifting_a_clamped_tool_out_of_its_pocket_collides() {
        let c = AtcConfig::default();
        let mut pos = [c.x1, c.y_b, c.z1, pocket_e(6)];
        let mut m = AtcModel::new(c.clone(), &pos);
        walk(&mut m, &mut pos, 2, c.z2);
        assert_eq!(m.spindle.map(|t| t.id), Some(6));
        walk(&mut m, &mut pos, 2, c.z1);
        assert_eq!(m.collisions[0].kind, CollisionKind::LeftWithToolClamped { pocket: 6 });
    }

    #[test]
    fn turning_the_carousel_with_a_tool_in_the_magazine_collides() {
        let c = AtcConfig::default();
        let mut pos = [c.x1, c.y_b, c.z1, pocket_e(6)];
        let mut m = AtcModel::new(c.clone(), &pos);
        walk(&mut m, &mut pos, 2, c.z2);
        walk(&mut m, &mut pos, 3, pocket_e(7));
        assert_eq!(m.collisions.len(), 1);
        assert_eq!(m.collisions[0].kind, CollisionKind::CarouselTurnedWhileEngaged);
        // The empty spindle above the tools at Z1 may watch the carousel turn.
        let mut pos = [c.x1, c.y_b, c.z1, pocket_e(6)];
        let mut m = AtcModel::new(c.clone(), &pos);
        walk(&mut m, &mut pos, 3, pocket_e(9));
        assert!(m.collisions.is_empty());
    }

    #[test]
    fn nothing_happens_away_from_the_station() {
        let c = AtcConfig::default();
        let mut pos = [1000, 1000, 4500, 0];
        let mut m = AtcModel::new(c.clone(), &pos);
        walk(&mut m, &mut pos, 1, 4400);
        walk(&mut m, &mut pos, 3, 900);
        assert!(m.collisions.is_empty() && m.transfers.is_empty());
    }
}
