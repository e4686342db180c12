//! What the planner queues and what it answers: the [`Block`] (one linear
//! move in the ring, shared with segment prep while it executes), the
//! [`Speed`] a move is asked at, and the [`Push`] / [`PlanError`] results of
//! queuing one.

use crate::N_AXES;

/// One linear move in the ring.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    /// Steps per axis, absolute counts, X Y Z E.
    pub steps: [u32; N_AXES],
    /// Step events: max of `steps`.
    pub step_event_count: u32,
    /// Path length, mm (E-only moves: pitches). While the block executes, prep
    /// keeps this at the distance still to go.
    pub millimeters: f32,
    /// Acceleration along the path, mm/s², limited so no axis exceeds its own.
    pub acceleration: f32,
    /// Planned entry speed², (mm/s)². While the block executes, prep keeps this at
    /// the current speed².
    pub entry_speed_sqr: f32,
    /// Upper bound of the entry speed² from the junction and nominal speeds, (mm/s)².
    pub max_entry_speed_sqr: f32,
    /// Cruise speed², (mm/s)², after feed, per-axis and step-rate limits.
    pub nominal_speed_sqr: f32,
    /// Twice the acceleration times the path length: the speed² this block can
    /// gain or lose, (mm/s)². Cached for the look-ahead passes; prep keeps it in
    /// step with `millimeters` while the block executes.
    pub max_delta_speed_sqr: f32,
    /// Bit i set: axis i moves in the negative direction.
    pub direction_bits: u8,
    /// [`Block::TAKE_UP`] and future flags.
    pub flags: u8,
    /// [`Planner::line_tag`](super::Planner::line_tag) when the block was
    /// queued (low 16 bits of the SD job's line number): which line a stop
    /// happened in.
    pub line: u16,
    /// The programmed feed, mm/min (rounded), for a move that follows the
    /// feed override ([`Speed::Feed`]); 0 for any other.
    pub feed: u16,
}

impl Block {
    /// Flag: a backlash take-up block (see the module doc).
    pub const TAKE_UP: u8 = 1 << 0;
    /// Flag: a rapid move ([`Speed::Rapid`]), which follows the rapid
    /// override.
    pub const RAPID: u8 = 1 << 1;

    /// A block of nothing: what [`Planner::new`](super::Planner::new)'s
    /// zeroed blocks are.
    #[cfg(test)]
    pub(super) const EMPTY: Block = Block {
        steps: [0; N_AXES],
        step_event_count: 0,
        millimeters: 0.0,
        acceleration: 0.0,
        entry_speed_sqr: 0.0,
        max_entry_speed_sqr: 0.0,
        nominal_speed_sqr: 0.0,
        max_delta_speed_sqr: 0.0,
        direction_bits: 0,
        flags: 0,
        line: 0,
        feed: 0,
    };
}

/// How fast a move goes, and which override it follows (grbl 1.1's
/// realtime overrides, [`Planner::set_overrides`](super::Planner::set_overrides)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Speed {
    /// Each axis at most at its max rate, times the rapid override (G0, the
    /// tool changer's travels).
    Rapid,
    /// A programmed feed, mm/min, times the feed override (G1/G2/G3, canned
    /// cycles, probing).
    Feed(f32),
    /// A feed, mm/min, that no override changes (jogs, homing, the tool
    /// changer's and the setter's feed moves: grbl exempts its jogs and
    /// homing too).
    Fixed(f32),
}

/// What [`Planner::push_line`](super::Planner::push_line) did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Push {
    /// Blocks queued: 0 for a zero-length move, 2 with a backlash take-up.
    pub queued: u8,
    /// The nominal rate was lowered so the dominant axis stays within
    /// `config::MAX_STEP_RATE_HZ` (docs/SPEC.md §11 overload row: warn the operator).
    pub rate_capped: bool,
    /// The nominal rate was raised to [`crate::config::MIN_STEP_RATE_HZ`] on the
    /// dominant axis: the feed was slower than the step timer can go.
    pub rate_floored: bool,
}

/// Why a move was not queued.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanError {
    /// No room in the ring (2 slots are needed with a backlash take-up): run prep
    /// and try again.
    Full,
    /// Feed ≤ 0 or not finite.
    BadFeed,
}
