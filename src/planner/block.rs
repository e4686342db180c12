//! What the planner queues and what it answers: the [`Block`] (one linear
//! move in the ring, shared with segment prep while it executes), the
//! [`Speed`] a move is asked at, and the [`Push`] / [`PlanError`] results of
//! queuing one.

use crate::N_AXES;

/// One linear move in the ring. 41 B on AVR: the step counts take 3 bytes
/// an axis, the step event count is derived from them, and the flags share
/// the direction byte (50 B before).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    /// Steps per axis, absolute counts, X Y Z E ([`Block::steps`]).
    pub(super) steps: [Steps24; N_AXES],
    /// Path length, mm (E-only moves: pitches). While the block executes, prep
    /// keeps this at the distance still to go.
    pub millimeters: f32,
    /// F_CPU / the acceleration along the path (the acceleration is
    /// limited so no axis exceeds its own): the CPU cycles a change of
    /// speed of 1 mm/s takes, cycles·s/mm. What prep's ramps need: a ramp's
    /// cycles are its Δv times this, with no division (or cache of them)
    /// and one multiply on the usual block; the planner has it from the
    /// division it makes for the acceleration anyway, times F_CPU.
    pub dv_cycles: f32,
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
    /// Bits 0-3: axis i moves in the negative direction
    /// ([`Block::direction_bits`]); above them [`Block::TAKE_UP`] and
    /// [`Block::RAPID`]; bits 6-7: the axis with the most steps (the
    /// first of equals), [`Block::step_event_count`].
    pub(super) bits: u8,
    /// [`Planner::line_tag`](super::Planner::line_tag) when the block was
    /// queued (low 16 bits of the SD job's line number): which line a stop
    /// happened in.
    pub line: u16,
    /// The programmed feed, mm/min (rounded), for a move that follows the
    /// feed override ([`Speed::Feed`]); 0 for any other.
    pub feed: u16,
}

impl Block {
    /// A block moves each axis at most this many steps back, one fewer
    /// forward (2²³: 21 m at 400 steps/mm); a longer move is queued in
    /// pieces ([`PlanError::TooLong`]).
    pub const MAX_STEPS: u32 = 1 << 23;
    /// The direction bits within [`Block::bits`].
    pub(super) const DIRECTIONS: u8 = (1 << N_AXES) - 1;
    /// Flag: a backlash take-up block (see the module doc).
    pub const TAKE_UP: u8 = 1 << N_AXES;
    /// Flag: a rapid move ([`Speed::Rapid`]), which follows the rapid
    /// override.
    pub const RAPID: u8 = 1 << (N_AXES + 1);
    /// Where the dominant axis' index starts in [`Block::bits`].
    pub(super) const DOMINANT_SHIFT: u8 = N_AXES as u8 + 2;

    /// Steps per axis, X Y Z E.
    #[inline(always)]
    pub fn steps(&self) -> [u32; N_AXES] {
        [self.steps[0].get(), self.steps[1].get(), self.steps[2].get(), self.steps[3].get()]
    }

    /// Step events: the largest of [`Block::steps`], the dominant axis'
    /// (its index kept in [`Block::bits`]: finding the largest took ~110
    /// cycles a block on the AVR).
    // speed: as a call ~12 cycles a line more (profile 18 313 -> 18 301)
    #[inline(always)]
    pub fn step_event_count(&self) -> u32 {
        self.steps[(self.bits >> Self::DOMINANT_SHIFT) as usize].get()
    }

    /// Bit i set: axis i moves in the negative direction.
    #[inline]
    pub fn direction_bits(&self) -> u8 {
        self.bits & Self::DIRECTIONS
    }

    /// `flag` ([`Block::TAKE_UP`], [`Block::RAPID`]) is set.
    #[inline]
    pub fn has(&self, flag: u8) -> bool {
        self.bits & flag != 0
    }

    /// A block of nothing: what [`Planner::new`](super::Planner::new)'s
    /// zeroed blocks are.
    #[cfg(test)]
    pub(super) const EMPTY: Block = Block {
        steps: [Steps24::ZERO; N_AXES],
        millimeters: 0.0,
        dv_cycles: 0.0,
        entry_speed_sqr: 0.0,
        max_entry_speed_sqr: 0.0,
        nominal_speed_sqr: 0.0,
        max_delta_speed_sqr: 0.0,
        bits: 0,
        line: 0,
        feed: 0,
    };
}

// The dominant axis' index (2 bits) fits above the directions and flags.
const _: () = assert!(N_AXES <= 4 && Block::DOMINANT_SHIFT + 2 <= 8);

/// A block's step count on one axis in 3 bytes (at most
/// [`Block::MAX_STEPS`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Steps24([u8; 3]);

impl Steps24 {
    #[cfg(test)]
    pub(super) const ZERO: Steps24 = Steps24([0; 3]);

    /// `n` < 2²⁴ (the bits above are dropped).
    #[inline]
    pub(super) fn new(n: u32) -> Steps24 {
        debug_assert!(n >> 24 == 0);
        let [a, b, c, _] = n.to_le_bytes();
        Steps24([a, b, c])
    }

    #[inline(always)]
    pub(super) fn get(self) -> u32 {
        let [a, b, c] = self.0;
        u32::from_le_bytes([a, b, c, 0])
    }
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
    /// More steps on some axis than a block holds ([`Block::MAX_STEPS`]): queue
    /// [`Planner::first_piece`](super::Planner::first_piece) first, then the
    /// move again.
    TooLong,
}
