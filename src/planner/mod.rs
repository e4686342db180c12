//! Motion planner (docs/SPEC.md §6): the block ring and its look-ahead, grbl's
//! `plan_buffer_line` / `planner_recalculate` in Rust.
//!
//! Where it sits: the G-code interpreter rounds each absolute target to integer
//! steps and calls [`Planner::push_line`] (arcs are first cut into chords by
//! [`arc`]). The planner queues a [`Block`] per move and re-plans the entry
//! speeds of the whole ring; [`crate::stepper::prep`] takes the oldest block
//! (the *executing* block, [`Planner::current_block`]) and turns it into step
//! segments for the ISR.
//!
//! Units: lengths in mm (the E axis in pocket pitches), speeds in mm/s, speeds
//! squared in (mm/s)², accelerations in mm/s². Integer steps are the truth:
//! targets arrive in steps, so rounding never accumulates.
//!
//! **Look-ahead** (grbl 1.1 planner.c): each block gets a maximum entry speed from
//! the junction deviation rule and the nominal speeds of both blocks; then a
//! backward pass from the newest block (which always ends at zero speed) raises
//! entry speeds as far as deceleration allows, and a forward pass lowers them to
//! what acceleration allows. `planned` marks the newest block whose entry speed
//! can no longer improve, so both passes stop there: with a stream of short
//! collinear moves only the blocks in the final deceleration ramp are visited.
//!
//! **The executing block** is shared with prep: prep writes its remaining
//! distance (`millimeters`) and current speed (`entry_speed_sqr`) into it after
//! every segment, so the tail block always describes "the rest of the move from
//! the speed we are at". When a re-plan may change its exit speed, the planner
//! raises a flag ([`Planner::take_exec_replanned`], grbl's
//! `st_update_plan_block_parameters`) and prep recomputes its profile.
//!
//! **Backlash** (docs/SPEC.md §6, seed 003; default off): when X, Y or Z reverses and its
//! `backlash_mm` is > 0, a separate *take-up block* is queued just before the
//! reversing move. It moves only the reversing axes, by the backlash in steps, in
//! the new direction, at their max rate, and carries [`Block::TAKE_UP`]. The
//! commanded position ([`Planner::position`]) does not change; the motors run
//! ahead of it by [`Planner::backlash_offset_steps`]. The planned path is not
//! disturbed: the tool does not move while the slack is taken up, the take-up is
//! planned like any block (it stops at the reversal, as the motor reverses there
//! anyway) and the reversing move then starts from where the slack is gone. An
//! axis' direction is unknown after power-up and [`Planner::clear`]; its first
//! move sets it without compensation (homing does that).
//!
//! **AVR cost** (measured in simavr at 16 MHz with avr-libc float, 0.1 mm
//! moves at F3000 through `push_line` + [`crate::stepper::prep`]): push
//! ≈ 9.8 k cycles for a collinear stream, ≈ 12.5 k on a curve (junction maths),
//! of which the two look-ahead passes take ≈ 4 k; prep ≈ 5.7–6.2 k per block at
//! cruise, ≈ 11 k when every block is a ramp (a sharp zigzag). An f32 multiply
//! costs ≈ 170 cycles, a division or square root ≈ 500, so the code avoids
//! them where it can: non-negative floats are compared as bit patterns
//! (`lt_nn`), settings-derived inverses are cached, and a block in the same
//! direction as the previous one reuses its limits and needs no junction maths.
//! RAM on AVR: `Block` 46 B, `Planner` 904 B with 16 blocks.

pub mod arc;

#[cfg(test)]
mod tests;

use crate::config::{Settings, MAX_STEP_RATE_HZ, MIN_STEP_RATE_HZ};
use crate::math::{round_i32, sqrtf};
use crate::N_AXES;
use core::mem::size_of;

/// Blocks in the ring. RAM: 16 × 48 B = 768 B (host layout; 46 B per block on
/// AVR, 736 B). grbl-Mega keeps 36, Marlin and Repetier 16 (docs/SPEC.md §11). 16 blocks
/// of 0.1 mm hold 1.6 mm of look-ahead, more than the 1.25 mm needed to stop from
/// 50 mm/s at 1000 mm/s², so a stream of short moves can still run at full feed.
/// 32 blocks overflowed the stack: every string literal is copied to RAM on AVR
/// (about 3.5 KB here), which leaves too little room; see docs/ARCHITECTURE.md "RAM".
pub const BLOCK_BUFFER_LEN: usize = 16;

/// RAM budget of the whole planner (ring + state), bytes.
pub const PLANNER_RAM_BUDGET: usize = 1700;

const _: () = assert!(size_of::<Block>() * BLOCK_BUFFER_LEN <= 1536);
const _: () = assert!(size_of::<Planner>() <= PLANNER_RAM_BUDGET);
const _: () = assert!(BLOCK_BUFFER_LEN <= 128);

/// Entries of the square-root cache (a power of two). 8 entries hit 88 % of
/// the benchmark's 0.1 mm circle (19 distinct lengths).
const ROOTS_LEN: usize = 8;

/// The square-root cache's entry for `n` ≥ 1: (n, √n, 1/√n). Not inlined:
/// behind a cache test LLVM-AVR would compute it every time (`math::div_cold`).
// speed: inlined (LLVM's choice), the cache miss is computed on every call
#[inline(never)]
fn root_entry(n: u32) -> (u32, f32, f32) {
    let r = sqrtf(n as f32);
    (n, r, 1.0 / r)
}

/// Cosine beyond which a junction counts as a full reversal / a straight line.
const JUNCTION_COS_LIMIT: f32 = 0.999_999;
/// At a junction where an axis reverses, its speed steps from +v·|u_prev| to
/// −v·|u| at once, between a deceleration and an acceleration of the same
/// sign. Seen through the recorder's 20 ms window (docs/SPEC.md §11 "measured
/// acceleration") that step adds step/20 ms to the ramps' acceleration: the
/// demo job's 153° corner (junction deviation alone: 1.7 mm/s, a 3.2 mm/s
/// step on X) measured 1157 mm/s² at a 1000 mm/s² setting. The step is kept
/// to the speed change the axis' own acceleration gives in this time (0.5 mm/s
/// at 1000 mm/s², +2.5 %). Junctions where no axis reverses (curves, the
/// short chords of arcs) are not affected.
const REVERSAL_STEP_S: f32 = 0.0005;
/// Entry speed² used for a straight junction (then limited by the nominal speeds).
const JUNCTION_SPEED_SQR_STRAIGHT: f32 = 1.0e30;
/// s per step at the ISR's max rate.
const INV_MAX_STEP_RATE: f32 = 1.0 / MAX_STEP_RATE_HZ;
/// s per step at the timer's min rate.
const INV_MIN_STEP_RATE: f32 = 1.0 / MIN_STEP_RATE_HZ;

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
    /// [`Planner::line_tag`] when the block was queued (low 16 bits of the
    /// SD job's line number): which line a stop happened in.
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

    const EMPTY: Block = Block {
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
/// realtime overrides, [`Planner::set_overrides`]).
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

/// What [`Planner::push_line`] did.
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

/// Per-axis values derived from the settings, recomputed only when the settings
/// change (saves 2–3 divisions per axis and block on the AVR).
#[derive(Clone, Copy, Debug)]
struct AxisCache {
    /// Bits of steps_per_mm, accel_mm_per_s2, max_feed_mm_per_min they were made from.
    src: [[u32; N_AXES]; 3],
    /// mm per step.
    mm_per_step: [f32; N_AXES],
    /// 1 / max acceleration, s²/mm.
    inv_accel: [f32; N_AXES],
    /// 1 / max speed, s/mm.
    inv_max_speed: [f32; N_AXES],
    /// Time per mm above which an X/Y/Z move can never hit the step-rate cap
    /// (1 % above the largest steps/mm over `MAX_STEP_RATE_HZ`), s/mm: such a
    /// move may be planned later ([`Planner::accept_line`]).
    defer_min_inv_feed: f32,
    /// X, Y and Z have the same steps/mm (bit for bit).
    xyz_same_steps: bool,
    /// Bit i: axis i has the acceleration and speed limits of axis 0 (bit
    /// for bit). A move on such axes alone takes its limits from its
    /// largest unit component: two multiplies instead of two per axis.
    uniform: u8,
}

impl AxisCache {
    const EMPTY: AxisCache = AxisCache {
        src: [[0; N_AXES]; 3],
        mm_per_step: [0.0; N_AXES],
        inv_accel: [0.0; N_AXES],
        inv_max_speed: [0.0; N_AXES],
        defer_min_inv_feed: 0.0,
        xyz_same_steps: false,
        uniform: 0,
    };

    /// Recompute the derived values if `s` differs from what they came from.
    /// True if it did.
    fn refresh(&mut self, s: &Settings) -> bool {
        let mut same = true;
        for i in 0..N_AXES {
            same &= self.src[0][i] == s.steps_per_mm[i].to_bits()
                && self.src[1][i] == s.accel_mm_per_s2[i].to_bits()
                && self.src[2][i] == s.max_feed_mm_per_min[i].to_bits();
        }
        if same {
            return false;
        }
        for i in 0..N_AXES {
            self.src[0][i] = s.steps_per_mm[i].to_bits();
            self.src[1][i] = s.accel_mm_per_s2[i].to_bits();
            self.src[2][i] = s.max_feed_mm_per_min[i].to_bits();
            self.mm_per_step[i] = 1.0 / s.steps_per_mm[i];
            self.inv_accel[i] = 1.0 / s.accel_mm_per_s2[i];
            self.inv_max_speed[i] = 60.0 / s.max_feed_mm_per_min[i];
        }
        // Along any X/Y/Z path the dominant axis makes at most its own
        // steps/mm (the path is at least as long as that axis' share).
        let mut spm = 0.0f32;
        for i in 0..3 {
            if s.steps_per_mm[i] > spm {
                spm = s.steps_per_mm[i];
            }
        }
        self.defer_min_inv_feed = 1.01 * spm * INV_MAX_STEP_RATE;
        self.xyz_same_steps =
            s.steps_per_mm[1].to_bits() == s.steps_per_mm[0].to_bits() && s.steps_per_mm[2].to_bits() == s.steps_per_mm[0].to_bits();
        self.uniform = 0;
        for i in 0..N_AXES {
            if self.inv_accel[i].to_bits() == self.inv_accel[0].to_bits()
                && self.inv_max_speed[i].to_bits() == self.inv_max_speed[0].to_bits()
            {
                self.uniform |= 1 << i;
            }
        }
        true
    }
}

/// The block ring and the look-ahead state.
pub struct Planner {
    /// The ring; valid blocks are `tail`, tail+1, … (`len` of them).
    blocks: [Block; BLOCK_BUFFER_LEN],
    /// Copied into each block queued ([`Block::line`]); the SD job sets it
    /// to the line it hands out.
    pub line_tag: u16,
    /// The feed override, percent (M220, grbl's 0x90-0x94, the menu), and
    /// the rapid override (100, 50 or 25): [`Planner::set_overrides`].
    feed_pct: u16,
    rapid_pct: u8,
    /// Index of the executing (oldest) block.
    tail: u8,
    /// Index where the next block goes.
    head: u8,
    /// Blocks queued.
    len: u8,
    /// Newest block whose entry speed is optimal (grbl `block_buffer_planned`).
    planned: u8,
    /// A re-plan may have changed the executing block's exit speed.
    exec_replanned: bool,
    /// Blocks were queued since the last look-ahead pass (see
    /// [`Planner::settle`]).
    stale: bool,
    /// Axes (bits) whose last direction is known, for backlash.
    dir_known: u8,
    /// Last direction of each axis (bit set = negative), for backlash.
    last_dir: u8,
    /// Commanded position after the last queued block, steps.
    position: [i32; N_AXES],
    /// Motor position minus commanded position after the last queued block
    /// (backlash take-ups), steps, X Y Z.
    backlash_offset: [i32; 3],
    /// Unit vector of the last queued block.
    previous_unit_vec: [f32; N_AXES],
    /// Nominal speed² of the last queued block, (mm/s)².
    previous_nominal_speed_sqr: f32,
    /// Acceleration of the last queued block, mm/s².
    previous_acceleration: f32,
    /// Per-axis speed limit of the last queued block as time per mm, s/mm.
    previous_t_axes: f32,
    /// `previous_acceleration` and `previous_t_axes` match the current settings.
    previous_limits_valid: bool,
    /// Bits of the last feed seen and 1/feed, s/mm (the feed is modal, so it
    /// rarely changes between blocks).
    feed_cache: (u32, f32),
    /// Bits of the last time per mm `t` and the nominal speed² 1/t², (mm/s)².
    nominal_cache: (u32, f32),
    /// Bits of the last time per mm before the step-rate limits, and it
    /// times `MAX_STEP_RATE_HZ` and `MIN_STEP_RATE_HZ`, steps/mm.
    rate_cache: (u32, f32, f32),
    /// Bits of the last junction cap `L` (a speed²) and L².
    cap_sqr_cache: (u32, f32),
    /// (n, √n, 1/√n) for path lengths in steps, squared (n ≥ 1), direct
    /// mapped on n's low bits. RAM: 12 B each.
    roots: [(u32, f32, f32); ROOTS_LEN],
    /// Settings-derived per-axis values.
    axis: AxisCache,
    /// A move accepted by [`Planner::accept_line`] and not planned yet: its
    /// steps, time per mm (s/mm) and programmed feed ([`Block::feed`]). It
    /// holds a ring slot.
    pending: Option<([i32; N_AXES], f32, u16)>,
    /// `axis` matches the settings [`Planner::accept_line`] is given, until
    /// [`Planner::settings_changed`] (saves comparing 12 settings per move).
    axis_fresh: bool,
}

#[inline]
const fn next_index(i: u8) -> u8 {
    if i as usize + 1 == BLOCK_BUFFER_LEN {
        0
    } else {
        i + 1
    }
}

#[inline]
const fn prev_index(i: u8) -> u8 {
    if i == 0 {
        BLOCK_BUFFER_LEN as u8 - 1
    } else {
        i - 1
    }
}

/// `a < b` for finite `a`, `b` ≥ +0.0. Non-negative IEEE-754 floats order like
/// their bit patterns, so this is a 10-cycle u32 compare on the AVR instead of
/// a ~60-cycle soft-float call. Every speed², acceleration, distance and time
/// the planner compares is ≥ +0.0 by construction (squares, sums of
/// non-negative terms, clamped distances), never −0.0 or NaN.
pub(crate) fn lt_nn(a: f32, b: f32) -> bool {
    debug_assert!(a.is_sign_positive() && b.is_sign_positive() && !a.is_nan() && !b.is_nan());
    a.to_bits() < b.to_bits()
}

/// The larger of two finite floats ≥ +0.0 (see `lt_nn`).
fn max_nn(a: f32, b: f32) -> f32 {
    if lt_nn(a, b) {
        b
    } else {
        a
    }
}

/// The smaller of two finite floats ≥ +0.0 (see `lt_nn`).
pub(crate) fn min_nn(a: f32, b: f32) -> f32 {
    if lt_nn(a, b) {
        a
    } else {
        b
    }
}

/// |x| by clearing the sign bit (no soft-float compare).
// speed: left to LLVM (with rings' `seg_cycles` and `SlotSink`), ping-pong took 5.754 s, not 5.739
#[inline(always)]
fn abs_f32(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & 0x7FFF_FFFF)
}

/// 2·x for a finite x ≥ +0.0, exactly, by adding one to the exponent (a
/// ~145-cycle soft-float multiply on the AVR otherwise). Zero, subnormals
/// and values near the top of the range take the multiply.
fn times2(x: f32) -> f32 {
    let b = x.to_bits();
    if (0x0080_0000..0x7F00_0000).contains(&b) {
        f32::from_bits(b + 0x0080_0000)
    } else {
        2.0 * x
    }
}

/// x / 2 for a finite x ≥ +0.0, exactly while x/2 is a normal number (by
/// subtracting one from the exponent); smaller values take the multiply.
// speed: LLVM makes it a call from the inlined `junction_sqr` otherwise
#[inline(always)]
fn half(x: f32) -> f32 {
    let b = x.to_bits();
    if b >= 0x0100_0000 {
        f32::from_bits(b - 0x0080_0000)
    } else {
        0.5 * x
    }
}

/// The junction speed² between a block along `prev_unit` and the next along
/// `unit` (grbl's junction deviation rule), (mm/s)²: `accel` is (this
/// block's, the previous block's) acceleration, `cap` the smaller nominal
/// speed² of the two: a junction at least as fast as that is
/// [`JUNCTION_SPEED_SQR_STRAIGHT`] without the square root (`cap_cache`
/// holds (bits of cap, cap²)). Used when a block is queued and when the
/// overrides re-plan the ring.
#[allow(clippy::too_many_arguments)]
// correctness: as a call, `cap` goes on the stack, and LLVM-AVR reads stack
// arguments one byte low on the ATmega2560 (it counts a 2-byte return address;
// the PC is 3 bytes): `cap_sqr_cache` then held garbage and tools/bench's corner
// job measured 2499 mm/s², not 1033. Speed too: ping-pong 5.794 s, not 5.739.
#[inline(always)]
fn junction_sqr(
    same_dir: bool,
    prev_unit: &[f32; N_AXES],
    unit: &[f32; N_AXES],
    moving: u8,
    accel: (f32, f32),
    cap: f32,
    cap_cache: &mut (u32, f32),
    s: &Settings,
) -> f32 {
    if same_dir {
        return JUNCTION_SPEED_SQR_STRAIGHT;
    }
    let mut cos_theta = 0.0f32;
    for i in 0..N_AXES {
        if moving & (1 << i) != 0 && prev_unit[i].to_bits() != 0 {
            cos_theta -= prev_unit[i] * unit[i];
        }
    }
    // |cos θ| beyond the limit, on the bit pattern (a soft-float
    // compare costs ~50 cycles).
    let cos_bits = cos_theta.to_bits();
    let beyond = cos_bits & 0x7FFF_FFFF > JUNCTION_COS_LIMIT.to_bits();
    if beyond && cos_bits & 0x8000_0000 == 0 {
        0.0 // full reversal
    } else if beyond {
        JUNCTION_SPEED_SQR_STRAIGHT
    } else {
        let a = min_nn(accel.0, accel.1);
        let ad = a * s.junction_deviation_mm;
        let h = half(1.0 - cos_theta); // sin²(θ/2)
        let mut reversing = 0u8;
        for i in 0..N_AXES {
            let (p, u) = (prev_unit[i].to_bits(), unit[i].to_bits());
            if (p ^ u) & 0x8000_0000 != 0 && p & 0x7FFF_FFFF != 0 && u & 0x7FFF_FFFF != 0 {
                reversing |= 1 << i;
            }
        }
        // The deviation rule gives v² = a·δ·s / (1 − s), s = sin(θ/2).
        // It reaches the cap L = min(nominal²) when s ≥ L / (a·δ + L),
        // i.e. h·(a·δ + L)² ≥ L²: then skip the square root and the
        // division (most junctions of a smooth curve).
        if cap_cache.0 != cap.to_bits() {
            *cap_cache = (cap.to_bits(), cap * cap);
        }
        let k = ad + cap;
        if reversing == 0 && !lt_nn(h * (k * k), cap_cache.1) {
            JUNCTION_SPEED_SQR_STRAIGHT
        } else {
            let sin_theta_d2 = sqrtf(h);
            let mut v_sqr = ad * sin_theta_d2 / (1.0 - sin_theta_d2);
            // An axis that reverses here jumps from +v·u_prev to −v·u
            // in one step, between a deceleration and an acceleration of
            // the same sign: limit that jump to what the axis'
            // acceleration gives in REVERSAL_STEP_S (see there).
            for i in 0..N_AXES {
                if reversing & (1 << i) != 0 {
                    let dv = REVERSAL_STEP_S * s.accel_mm_per_s2[i] / (abs_f32(prev_unit[i]) + abs_f32(unit[i]));
                    v_sqr = min_nn(v_sqr, dv * dv);
                }
            }
            v_sqr
        }
    }
}

impl Planner {
    /// An empty planner at position 0.
    pub const fn new() -> Self {
        Planner {
            blocks: [Block::EMPTY; BLOCK_BUFFER_LEN],
            line_tag: 0,
            feed_pct: 100,
            rapid_pct: 100,
            tail: 0,
            head: 0,
            len: 0,
            planned: 0,
            exec_replanned: false,
            stale: false,
            dir_known: 0,
            last_dir: 0,
            position: [0; N_AXES],
            backlash_offset: [0; 3],
            previous_unit_vec: [0.0; N_AXES],
            previous_nominal_speed_sqr: 0.0,
            previous_acceleration: 0.0,
            previous_t_axes: 0.0,
            previous_limits_valid: false,
            feed_cache: (0, 0.0),
            nominal_cache: (0, 0.0),
            rate_cache: (0, 0.0, 0.0),
            cap_sqr_cache: (0, 0.0),
            roots: [(0, 0.0, 0.0); ROOTS_LEN],
            axis: AxisCache::EMPTY,
            pending: None,
            axis_fresh: false,
        }
    }

    /// Queue a straight move to `target` (absolute steps, X Y Z E) at
    /// `feed_mm_per_min` (mm/min along the path, ignored when `rapid`: then each
    /// axis may run at its max feed). Zero-length moves queue nothing.
    pub fn push_line(&mut self, target: [i32; N_AXES], feed_mm_per_min: f32, rapid: bool, s: &Settings) -> Result<Push, PlanError> {
        self.push(target, if rapid { Speed::Rapid } else { Speed::Feed(feed_mm_per_min) }, s, false)
    }

    /// [`Planner::push_line`] at `speed`.
    pub fn push_move(&mut self, target: [i32; N_AXES], speed: Speed, s: &Settings) -> Result<Push, PlanError> {
        self.push(target, speed, s, false)
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
    pub fn accept_line(&mut self, target: [i32; N_AXES], speed: Speed, s: &Settings) -> Result<Push, PlanError> {
        self.push(target, speed, s, true)
    }

    /// [`Planner::push_move`] (`may_defer` false) or [`Planner::accept_line`].
    fn push(&mut self, target: [i32; N_AXES], speed: Speed, s: &Settings, may_defer: bool) -> Result<Push, PlanError> {
        let rapid = speed == Speed::Rapid;
        let (feed_mm_per_min, pct, programmed) = match speed {
            Speed::Rapid => (0.0, 100, 0),
            Speed::Feed(f) => (f, self.feed_pct, ((f + 0.5) as u16).max(1)),
            Speed::Fixed(f) => (f, 100, 0),
        };
        let inv_feed = if rapid {
            0.0
        } else {
            if !(feed_mm_per_min > 0.0 && feed_mm_per_min.is_finite()) {
                return Err(PlanError::BadFeed);
            }
            // s/mm at the feed times the override: 6000 / (feed · percent).
            // The key: the feed's bits (a feed is > 0: the sign bit is free)
            // and whether the override applies; `set_overrides` clears it.
            let bits = feed_mm_per_min.to_bits() | ((pct != 100) as u32) << 31;
            if self.feed_cache.0 != bits {
                self.feed_cache = (bits, crate::math::div_cold(6000.0, feed_mm_per_min * pct as f32));
            }
            self.feed_cache.1
        };

        let mut delta = [0i32; N_AXES];
        let mut moving = 0u8;
        let mut dir = 0u8;
        for i in 0..N_AXES {
            let d = target[i].wrapping_sub(self.position[i]);
            delta[i] = d;
            if d != 0 {
                moving |= 1 << i;
            }
            if d < 0 {
                dir |= 1 << i;
            }
        }
        if moving == 0 {
            return Ok(Push::default());
        }

        // Backlash: axes that reverse with a known previous direction.
        let mut take_up = [0i32; N_AXES];
        let mut take_up_any = false;
        let reversing = moving & self.dir_known & (dir ^ self.last_dir);
        if reversing != 0 {
            for i in 0..3 {
                if reversing & (1 << i) != 0 && s.backlash_mm[i] > 0.0 {
                    let n = round_i32(s.backlash_mm[i] * s.steps_per_mm[i]);
                    if n > 0 {
                        take_up[i] = if dir & (1 << i) != 0 { -n } else { n };
                        take_up_any = true;
                    }
                }
            }
        }
        // The move accepted before this one is planned first.
        self.flush(s);
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
                // Limits changed: the same direction no longer means the same limits.
                self.previous_limits_valid = false;
            }
            self.axis_fresh = may_defer;
        }
        let mut push = Push::default();
        if may_defer && !take_up_any && !rapid && moving & 0b1000 == 0 && lt_nn(self.axis.defer_min_inv_feed, inv_feed) {
            // Never capped (see `AxisCache::defer_min_inv_feed`); floored or
            // not, which is not reported, prep runs it the same.
            self.pending = Some((delta, inv_feed, programmed));
            push.queued = 1;
        } else {
            if take_up_any {
                let (capped, floored) = self.queue_block(&take_up, 0.0, Block::TAKE_UP, 0, s);
                for i in 0..3 {
                    self.backlash_offset[i] += take_up[i];
                }
                push.queued += 1;
                push.rate_capped |= capped;
                push.rate_floored |= floored;
            }
            let flags = if rapid { Block::RAPID } else { 0 };
            let (capped, floored) = self.queue_block(&delta, inv_feed, flags, programmed, s);
            push.queued += 1;
            push.rate_capped |= capped;
            push.rate_floored |= floored;
        }
        self.position = target;
        self.last_dir = (self.last_dir & !moving) | (dir & moving);
        self.dir_known |= moving;
        if !may_defer {
            self.recalculate();
        }
        Ok(push)
    }

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
        self.feed_cache = (0, 0.0);
        let ax = &self.axis;
        let mut prev: Option<([f32; N_AXES], f32, f32)> = None;
        let mut i = self.tail;
        for _ in 0..self.len {
            let b = &mut self.blocks[i as usize];
            // The unit vector and the length, from the steps.
            let mut unit = [0f32; N_AXES];
            let mut moving = 0u8;
            let mut xyz_sqr = 0.0f32;
            for a in 0..N_AXES {
                if b.steps[a] != 0 {
                    moving |= 1 << a;
                    let v = b.steps[a] as f32 * ax.mm_per_step[a];
                    unit[a] = if b.direction_bits & (1 << a) != 0 { -v } else { v };
                    if a < 3 {
                        xyz_sqr += v * v;
                    }
                }
            }
            let mm = if xyz_sqr.to_bits() != 0 { sqrtf(xyz_sqr) } else { abs_f32(unit[3]) };
            let inv_mm = 1.0 / mm;
            for u in unit.iter_mut() {
                *u *= inv_mm;
            }
            if b.flags & Block::RAPID != 0 || b.feed != 0 {
                let mut t_axes = 0.0f32;
                for a in 0..N_AXES {
                    if moving & (1 << a) != 0 {
                        t_axes = max_nn(t_axes, abs_f32(unit[a]) * ax.inv_max_speed[a]);
                    }
                }
                let mut t = if b.flags & Block::RAPID != 0 {
                    t_axes * (100.0 / rapid_pct as f32)
                } else {
                    max_nn(t_axes, 6000.0 / (b.feed as f32 * feed_pct as f32))
                };
                let steps_per_mm = b.step_event_count as f32 * inv_mm;
                if lt_nn(t * MAX_STEP_RATE_HZ, steps_per_mm) {
                    t = steps_per_mm * INV_MAX_STEP_RATE;
                } else if lt_nn(steps_per_mm, t * MIN_STEP_RATE_HZ) {
                    t = steps_per_mm * INV_MIN_STEP_RATE;
                }
                let v = 1.0 / t;
                b.nominal_speed_sqr = v * v;
            }
            let nominal = b.nominal_speed_sqr;
            if let (Some((pu, pa, pn)), true) = (prev, i != self.tail) {
                let mut same_dir = true;
                for a in 0..N_AXES {
                    same_dir &= unit[a].to_bits() == pu[a].to_bits();
                }
                let cap = min_nn(nominal, pn);
                let j = junction_sqr(same_dir, &pu, &unit, moving, (b.acceleration, pa), cap, &mut self.cap_sqr_cache, s);
                b.max_entry_speed_sqr = min_nn(j, cap);
            }
            prev = Some((unit, b.acceleration, nominal));
            i = next_index(i);
        }
        if let Some((_, _, n)) = prev {
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

    /// The settings changed: the next [`Planner::accept_line`] compares them
    /// with what the per-axis cache was made from ([`Planner::push_line`]
    /// always does).
    pub fn settings_changed(&mut self) {
        self.axis_fresh = false;
    }

    /// Plan the move [`Planner::accept_line`] left pending, if any (with the
    /// settings it was accepted under: the per-axis cache is as it was then).
    pub fn flush(&mut self, s: &Settings) {
        if let Some((delta, inv_feed, programmed)) = self.pending.take() {
            self.queue_block(&delta, inv_feed, 0, programmed, s);
        }
    }

    /// Build a block for `delta` (steps, not all zero) at `inv_feed` s/mm (0 =
    /// rapid), link it to the previous one and re-plan. Returns (rate capped,
    /// rate floored). The caller has checked there is room.
    ///
    /// AVR cost (simavr, 16 MHz, see the module doc): ~9–13 k cycles including
    /// the re-plan; every f32 multiply is ~170 cycles, a divide or sqrt ~500.
    fn queue_block(&mut self, delta: &[i32; N_AXES], inv_feed: f32, flags: u8, feed: u16, s: &Settings) -> (bool, bool) {
        let prev_unit = self.previous_unit_vec;
        let prev_nominal_sqr = self.previous_nominal_speed_sqr;
        let prev_accel = self.previous_acceleration;
        let prev_t_axes = self.previous_t_axes;
        let prev_valid = self.previous_limits_valid;
        let first = self.len == 0;
        let ax = &self.axis;
        // Built in place in its slot.
        let b = &mut self.blocks[self.head as usize];
        b.flags = flags;
        b.feed = feed;
        b.step_event_count = 0;
        b.direction_bits = 0;
        b.entry_speed_sqr = 0.0;
        let mut unit = [0f32; N_AXES];
        let mut moving = 0u8;
        for i in 0..N_AXES {
            let d = delta[i];
            let n = d.unsigned_abs();
            b.steps[i] = n;
            if n > b.step_event_count {
                b.step_event_count = n;
            }
            if d != 0 {
                moving |= 1 << i;
                if d < 0 {
                    b.direction_bits |= 1 << i;
                }
            }
        }
        // Path length and unit vector.
        let (mm, inv_mm);
        if moving & 0b1000 == 0 && ax.xyz_same_steps && b.step_event_count < 0x8000 {
            // X/Y/Z at one steps/mm: the length is √(Σd²) steps, and a stream
            // of short moves repeats a few dozen values of the integer Σd²,
            // whose root and inverse root are cached: no square root and no
            // division (~1 k cycles on the AVR) on a hit.
            let mut sum_sqr = 0u32;
            for i in 0..3 {
                let n = b.steps[i] as u16;
                sum_sqr += crate::math::mul_u16(n, n);
            }
            let e = &mut self.roots[(sum_sqr & (ROOTS_LEN as u32 - 1)) as usize];
            if e.0 != sum_sqr {
                *e = root_entry(sum_sqr);
            }
            let (root, inv_root) = (e.1, e.2);
            mm = root * ax.mm_per_step[0];
            inv_mm = inv_root * s.steps_per_mm[0];
            for i in 0..3 {
                if moving & (1 << i) != 0 {
                    unit[i] = delta[i] as f32 * inv_root;
                }
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
            mm = if xyz_sqr.to_bits() != 0 { sqrtf(xyz_sqr) } else { abs_f32(unit[3]) };
            inv_mm = 1.0 / mm;
            for i in 0..N_AXES {
                if moving & (1 << i) != 0 {
                    unit[i] *= inv_mm;
                }
            }
        }
        let mut same_dir = prev_valid;
        for i in 0..N_AXES {
            same_dir &= unit[i].to_bits() == prev_unit[i].to_bits();
        }

        // Per-axis limits: the path may go at most as fast (and accelerate at most
        // as hard) as the slowest axis allows, scaled by its share of the motion.
        // They depend on the direction only: a block in the same direction as the
        // last one (a stream of collinear moves) reuses them.
        let (acceleration, t_axes) = if same_dir {
            (prev_accel, prev_t_axes)
        } else if moving & !ax.uniform == 0 {
            // Every moving axis has axis 0's limits: the largest |u| decides
            // (exactly: rounding keeps the order of the products).
            let mut u_max = 0.0f32;
            for i in 0..N_AXES {
                if moving & (1 << i) != 0 {
                    u_max = max_nn(u_max, abs_f32(unit[i]));
                }
            }
            (1.0 / (u_max * ax.inv_accel[0]), u_max * ax.inv_max_speed[0])
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
            (1.0 / inv_accel, t_axes)
        };
        let mut t = if lt_nn(t_axes, inv_feed) { inv_feed } else { t_axes };
        if flags & Block::RAPID != 0 && self.rapid_pct != 100 {
            t *= 100.0 / self.rapid_pct as f32;
        }
        // Step-rate limits: the dominant axis makes step_event_count steps
        // over mm. At time per mm t the rate stays within them while the
        // steps per mm of path lie within t·MIN_STEP_RATE_HZ and
        // t·MAX_STEP_RATE_HZ (cached: t is usually the last block's).
        let steps_per_mm = b.step_event_count as f32 * inv_mm;
        if self.rate_cache.0 != t.to_bits() {
            self.rate_cache = (t.to_bits(), t * MAX_STEP_RATE_HZ, t * MIN_STEP_RATE_HZ);
        }
        let (max_steps_per_mm, min_steps_per_mm) = (self.rate_cache.1, self.rate_cache.2);
        let mut capped = false;
        let mut floored = false;
        if lt_nn(max_steps_per_mm, steps_per_mm) {
            t = steps_per_mm * INV_MAX_STEP_RATE;
            capped = true;
        } else if lt_nn(steps_per_mm, min_steps_per_mm) {
            t = steps_per_mm * INV_MIN_STEP_RATE;
            floored = true;
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
            let junction_sqr =
                junction_sqr(same_dir, &prev_unit, &unit, moving, (acceleration, prev_accel), cap, &mut self.cap_sqr_cache, s);
            min_nn(junction_sqr, min_nn(nominal_speed_sqr, prev_nominal_sqr))
        };
        b.millimeters = mm;
        b.acceleration = acceleration;
        b.nominal_speed_sqr = nominal_speed_sqr;
        b.max_delta_speed_sqr = times2(acceleration * mm);

        self.previous_unit_vec = unit;
        self.previous_nominal_speed_sqr = nominal_speed_sqr;
        self.previous_acceleration = acceleration;
        self.previous_t_axes = t_axes;
        self.previous_limits_valid = true;

        self.head = next_index(self.head);
        self.len += 1;
        self.stale = true;
        (capped, floored)
    }

    /// Run the look-ahead if blocks were queued since the last pass and it
    /// could change the executing block's exit speed (`planned` is the
    /// executing block). Otherwise the blocks up to `planned`, the next one
    /// included, are final, and the newer ones wait: their entry speeds are
    /// those of a stop at the end of the ring as it was, never too fast, and
    /// one pass later covers every block queued meanwhile. Prep calls this
    /// before every segment; with a stream of short moves it saves most
    /// passes (each visits every block of the final deceleration ramp).
    pub fn settle(&mut self) {
        if self.stale && self.planned == self.tail {
            self.recalculate();
        }
    }

    /// grbl's `planner_recalculate`: backward pass from the newest block to
    /// `planned`, then forward pass from `planned` to the newest block.
    fn recalculate(&mut self) {
        self.stale = false;
        let mut idx = prev_index(self.head);
        if idx == self.planned {
            return;
        }
        // The newest block always ends at zero speed.
        let mut cur = idx;
        {
            let b = &mut self.blocks[cur as usize];
            b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, b.max_delta_speed_sqr);
        }
        idx = prev_index(idx);
        if idx == self.planned {
            if idx == self.tail {
                self.exec_replanned = true;
            }
        } else {
            while idx != self.planned {
                let next_entry = self.blocks[cur as usize].entry_speed_sqr;
                cur = idx;
                idx = prev_index(idx);
                if idx == self.tail {
                    // The block after the executing one is about to change.
                    self.exec_replanned = true;
                }
                let b = &mut self.blocks[cur as usize];
                if b.entry_speed_sqr.to_bits() != b.max_entry_speed_sqr.to_bits() {
                    b.entry_speed_sqr = min_nn(b.max_entry_speed_sqr, next_entry + b.max_delta_speed_sqr);
                }
            }
        }
        // Forward pass.
        let mut cur = self.planned;
        let mut idx = next_index(cur);
        while idx != self.head {
            let (cur_entry, cur_delta) = {
                let c = &self.blocks[cur as usize];
                (c.entry_speed_sqr, c.max_delta_speed_sqr)
            };
            let n = &mut self.blocks[idx as usize];
            if lt_nn(cur_entry, n.entry_speed_sqr) {
                let e = cur_entry + cur_delta;
                if lt_nn(e, n.entry_speed_sqr) {
                    // Acceleration-limited: optimal, nothing before it can change.
                    n.entry_speed_sqr = e;
                    self.planned = idx;
                }
            }
            if n.entry_speed_sqr.to_bits() == n.max_entry_speed_sqr.to_bits() {
                self.planned = idx;
            }
            cur = idx;
            idx = next_index(idx);
        }
    }

    /// The executing (oldest) block, if any.
    pub fn current_block(&self) -> Option<&Block> {
        if self.len == 0 {
            None
        } else {
            Some(&self.blocks[self.tail as usize])
        }
    }

    /// The executing block, for prep to record progress in.
    pub fn current_block_mut(&mut self) -> Option<&mut Block> {
        if self.len == 0 {
            None
        } else {
            Some(&mut self.blocks[self.tail as usize])
        }
    }

    /// The i-th queued block, 0 = executing.
    pub fn block(&self, i: usize) -> Option<&Block> {
        if i >= self.len as usize {
            None
        } else {
            Some(&self.blocks[(self.tail as usize + i) % BLOCK_BUFFER_LEN])
        }
    }

    /// Drop the executing block (prep has prepared all its steps).
    pub fn discard_current_block(&mut self) {
        if self.len == 0 {
            return;
        }
        if self.planned == self.tail {
            self.planned = next_index(self.tail);
        }
        self.tail = next_index(self.tail);
        self.len -= 1;
    }

    /// Exit speed² of the executing block, (mm/s)²: the next block's entry speed,
    /// or 0 when it is the last one.
    pub fn exec_exit_speed_sqr(&self) -> f32 {
        if self.len <= 1 {
            0.0
        } else {
            self.blocks[next_index(self.tail) as usize].entry_speed_sqr
        }
    }

    /// True once (then cleared) when a re-plan may have changed the executing
    /// block's exit speed, so prep must recompute its profile.
    pub fn take_exec_replanned(&mut self) -> bool {
        core::mem::replace(&mut self.exec_replanned, false)
    }

    /// grbl's `plan_cycle_reinitialize`, for the end of a feed hold: the machine
    /// is stopped, so the executing block restarts from zero speed with the
    /// distance it has left, and the whole ring is re-planned from it.
    pub fn cycle_reinitialize(&mut self) {
        if self.len == 0 {
            return;
        }
        self.blocks[self.tail as usize].entry_speed_sqr = 0.0;
        self.replan();
    }

    /// Re-plan the whole ring from the executing block's current state.
    pub fn replan(&mut self) {
        if self.len == 0 {
            return;
        }
        self.planned = self.tail;
        self.exec_replanned = true;
        self.recalculate();
    }

    /// Commanded position after the last queued block, steps (X Y Z E). Backlash
    /// take-ups are not included.
    pub fn position(&self) -> [i32; N_AXES] {
        self.position
    }

    /// Set the commanded position (after homing, G92-free resync after an
    /// abort). Call with the queue empty. Resets the backlash offset to 0: the
    /// motors are where the new position says; the slack state (last direction)
    /// is kept.
    pub fn set_position(&mut self, p: [i32; N_AXES]) {
        self.position = p;
        self.backlash_offset = [0; 3];
    }

    /// Motor steps minus commanded steps after the last queued block, X Y Z: the
    /// sum of the queued backlash take-ups since the last `set_position`. When the
    /// queue is idle, reported position = motor step count − this.
    pub fn backlash_offset_steps(&self) -> [i32; 3] {
        self.backlash_offset
    }

    /// Blocks queued (including the executing one and a pending move).
    pub fn len(&self) -> usize {
        self.len as usize + self.pending.is_some() as usize
    }

    /// No block queued (and none pending).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// No free slot (a move with a backlash take-up needs 2).
    pub fn is_full(&self) -> bool {
        self.len() == BLOCK_BUFFER_LEN
    }

    /// Free slots.
    pub fn free(&self) -> usize {
        BLOCK_BUFFER_LEN - self.len()
    }

    /// Drop every block (e-stop, limit, abort). The position is kept as the end
    /// of the dropped moves: the caller must `set_position` to the true motor
    /// position. Backlash directions become unknown.
    pub fn clear(&mut self) {
        self.pending = None;
        self.stale = false;
        self.tail = 0;
        self.head = 0;
        self.len = 0;
        self.planned = 0;
        self.exec_replanned = false;
        self.dir_known = 0;
        self.previous_unit_vec = [0.0; N_AXES];
        self.previous_nominal_speed_sqr = 0.0;
        self.previous_acceleration = 0.0;
        self.previous_limits_valid = false;
    }
}

impl Default for Planner {
    fn default() -> Self {
        Self::new()
    }
}
