//! Machine settings (docs/SPEC.md §3): defaults, limits and their EEPROM image.
//!
//! Everything a machine builder can change over serial (M92, M201, M203, …) and
//! save with M500 lives in [`Settings`]. The firmware keeps one copy in RAM; the
//! planner, interpreter, homing and ATC read it. [`Settings::to_bytes`] /
//! [`Settings::from_bytes`] give the EEPROM image (versioned, with a checksum),
//! so a blank or corrupt EEPROM falls back to the defaults instead of running
//! on garbage.

use crate::N_AXES;

/// Settings layout version stored in EEPROM. Bump when the layout changes.
/// Versions 3 (before the dwell and G80 flags), 4 (before the card-out
/// retract height) and 5 (before the input invert mask) still load, the
/// fields they lack at their defaults.
pub const SETTINGS_VERSION: u8 = 6;

/// Number of work coordinate systems, G54..G59.
pub const N_WCS: usize = 6;

/// Machine settings. All lengths in mm, except the E axis, whose unit is one
/// carousel pocket pitch (docs/SPEC.md §7).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Steps per mm (E: steps per pocket pitch).
    pub steps_per_mm: [f32; N_AXES],
    /// Max feed per axis, mm/min (E: pitches/min).
    pub max_feed_mm_per_min: [f32; N_AXES],
    /// Max acceleration per axis, mm/s² (E: pitches/s²).
    pub accel_mm_per_s2: [f32; N_AXES],
    /// Travel of X, Y, Z: machine coordinates run 0..travel, mm.
    pub travel_mm: [f32; 3],
    /// Bit per axis: invert the direction pin.
    pub invert_dir_mask: u8,
    /// Inputs read inverted (`$5`): bits 0–2 the X, Y, Z home switches,
    /// bit 3 the carousel home switch, bit 4 the tool setter / probe. Set for
    /// a normally-closed switch (a broken wire then reads as triggered) or
    /// a sensor of the other polarity.
    pub invert_input_mask: u8,
    /// Junction deviation for cornering speed, mm (grbl's $11).
    pub junction_deviation_mm: f32,
    /// Max chord error of arcs, mm.
    pub arc_tolerance_mm: f32,
    /// Backlash take-up on direction reversal, per axis X, Y, Z, mm. 0 = off.
    pub backlash_mm: [f32; 3],
    /// Homing fast seek feed, mm/min.
    pub homing_seek_mm_per_min: f32,
    /// Homing slow (locate) feed, mm/min.
    pub homing_feed_mm_per_min: f32,
    /// Homing back-off distance after each switch hit, mm.
    pub homing_pulloff_mm: f32,
    /// Check targets against travel before queueing.
    pub soft_limits: bool,
    /// Raise an alarm when a home switch trips outside homing.
    pub hard_limits: bool,
    /// Spindle speed at 100 % PWM, rpm.
    pub spindle_max_rpm: f32,
    /// Apply the new tool's length offset automatically after a change.
    pub auto_tool_offset: bool,
    /// Refuse motion after power-on or an alarm until homed or unlocked
    /// (grbl's `$22` homing lock).
    pub homing_lock: bool,
    /// A T word alone changes the tool at once (Repetier, the thesis
    /// macros); off: T selects and M6 changes (RS274/NGC, the default).
    pub immediate_tool_change: bool,
    /// M1 pauses (optional stop on); off: M1 is skipped.
    pub optional_stop: bool,
    /// Card pulled mid-job: Z retracts to this far below its home switch
    /// (machine Z −this), mm, before the spindle stops (`$160`).
    pub card_out_retract_mm: f32,
    /// Work coordinate offsets G54..G59, X/Y/Z, mm.
    pub wcs_mm: [[f32; 3]; N_WCS],
    /// `G4 P` is milliseconds (Mach3 and UCCNC posts, Marlin); off: seconds
    /// (RS274/NGC, LinuxCNC, grbl).
    pub dwell_p_ms: bool,
    /// G80 cancels only the canned cycle and the motion mode from before
    /// the cycle stays (Fanuc, Haas, Mach3: Fusion 360's Mach3 post moves
    /// with bare axis words after G80); off: G80 leaves no motion mode and
    /// bare axis words are refused (LinuxCNC, grbl).
    pub g80_keeps_motion: bool,
}

/// Highest step rate the stepper ISR is allowed to be asked for, Hz.
/// The planner caps each block's nominal rate so its dominant axis never
/// exceeds this, and warns (docs/SPEC.md §11 overload row; `tests/overload.rs`).
/// Measured in simavr (`tools/bench`): a tick costs 149 cycles with no
/// partial axis and 241 with three (four axes at once); at 60 kHz (267
/// cycles) the four-axis ISR takes ~90 % of the CPU and prep still keeps the
/// ring filled through 300 mm/s² ramps; at 70 kHz four axes fell to 67 kHz.
pub const MAX_STEP_RATE_HZ: f32 = 60_000.0;

/// Slowest step event rate the step timer can produce (clk/8, OCR1A = 65535),
/// Hz. The planner raises slower nominal rates to this (`Push::rate_floored`),
/// and prep clamps slower segments (only the first/last few steps of a ramp at
/// very low accelerations) to it.
pub const MIN_STEP_RATE_HZ: f32 = crate::F_CPU_HZ as f32 / (8.0 * 65535.0);

impl Settings {
    /// Factory defaults (docs/SPEC.md §3; thesis §5.2.2 for acceleration).
    pub const DEFAULT: Settings = Settings {
        steps_per_mm: [100.0, 100.0, 100.0, 200.0 * 16.0 / 18.0],
        max_feed_mm_per_min: [3000.0, 3000.0, 3000.0, 600.0],
        accel_mm_per_s2: [1000.0, 1000.0, 1000.0, 50.0],
        travel_mm: [45.0, 45.0, 45.0],
        invert_dir_mask: 0,
        invert_input_mask: 0,
        junction_deviation_mm: 0.01,
        arc_tolerance_mm: 0.002,
        backlash_mm: [0.0; 3],
        homing_seek_mm_per_min: 1200.0,
        homing_feed_mm_per_min: 100.0,
        homing_pulloff_mm: 1.0,
        soft_limits: true,
        hard_limits: true,
        spindle_max_rpm: 10300.0,
        auto_tool_offset: true,
        homing_lock: true,
        immediate_tool_change: false,
        optional_stop: false,
        card_out_retract_mm: 2.0,
        wcs_mm: [[0.0; 3]; N_WCS],
        dwell_p_ms: false,
        g80_keeps_motion: true,
    };

    /// Size of the EEPROM image in bytes: version, fields, checksum.
    pub const IMAGE_LEN: usize = Self::IMAGE_LEN_V5 + 1;
    /// Size of a version 5 image: no input invert mask.
    const IMAGE_LEN_V5: usize = Self::IMAGE_LEN_V4 + 4;
    /// Size of a version 4 image: no card-out retract height.
    const IMAGE_LEN_V4: usize = Self::IMAGE_LEN_V3 + 2;
    /// Size of a version 3 image: no dwell or G80 flag.
    const IMAGE_LEN_V3: usize = 1 + 4 * (4 * 3 + 3 + 1 + 1 + 3 + 3 + 1 + 3 * N_WCS) + 1 + 6 + 1;

    /// The f32 fields in EEPROM image order.
    fn f32_fields(&self) -> [&[f32]; 12] {
        use core::slice::from_ref;
        [
            &self.steps_per_mm,
            &self.max_feed_mm_per_min,
            &self.accel_mm_per_s2,
            &self.travel_mm,
            from_ref(&self.junction_deviation_mm),
            from_ref(&self.arc_tolerance_mm),
            &self.backlash_mm,
            from_ref(&self.homing_seek_mm_per_min),
            from_ref(&self.homing_feed_mm_per_min),
            from_ref(&self.homing_pulloff_mm),
            from_ref(&self.spindle_max_rpm),
            self.wcs_mm.as_flattened(),
        ]
    }

    /// [`Settings::f32_fields`], writable.
    fn f32_fields_mut(&mut self) -> [&mut [f32]; 12] {
        use core::slice::from_mut;
        [
            &mut self.steps_per_mm,
            &mut self.max_feed_mm_per_min,
            &mut self.accel_mm_per_s2,
            &mut self.travel_mm,
            from_mut(&mut self.junction_deviation_mm),
            from_mut(&mut self.arc_tolerance_mm),
            &mut self.backlash_mm,
            from_mut(&mut self.homing_seek_mm_per_min),
            from_mut(&mut self.homing_feed_mm_per_min),
            from_mut(&mut self.homing_pulloff_mm),
            from_mut(&mut self.spindle_max_rpm),
            self.wcs_mm.as_flattened_mut(),
        ]
    }

    /// Serialise to the EEPROM image: version, the f32 fields (little
    /// endian, in [`Settings::f32_fields`] order), the flags, checksum.
    pub fn to_bytes(&self) -> [u8; Self::IMAGE_LEN] {
        let mut w = Writer { buf: [0; Self::IMAGE_LEN], at: 0 };
        w.u8(SETTINGS_VERSION);
        for part in self.f32_fields() {
            for &v in part {
                w.f32(v);
            }
        }
        w.u8(self.invert_dir_mask);
        w.u8(self.soft_limits as u8);
        w.u8(self.hard_limits as u8);
        w.u8(self.auto_tool_offset as u8);
        w.u8(self.homing_lock as u8);
        w.u8(self.immediate_tool_change as u8);
        w.u8(self.optional_stop as u8);
        w.u8(self.dwell_p_ms as u8);
        w.u8(self.g80_keeps_motion as u8);
        w.f32(self.card_out_retract_mm);
        w.u8(self.invert_input_mask);
        let sum = checksum(&w.buf[..w.at]);
        w.u8(sum);
        debug_assert_eq!(w.at, Self::IMAGE_LEN);
        w.buf
    }

    /// Parse an EEPROM image. `None` if blank, of another version, corrupt,
    /// or holding values no machine could use (NaN, zero steps/mm, …). A
    /// version 3 image (shorter by the two last flags) loads with those
    /// flags at their defaults.
    pub fn from_bytes(b: &[u8]) -> Option<Settings> {
        let mut s = Settings::defaults();
        s.read_image(b).then_some(s)
    }

    /// [`Settings::from_bytes`] into `self`; false (and `self` partly
    /// overwritten) when the image is not valid. Not inlined: it works on
    /// the settings through a pointer, within AVR's `ldd` reach.
    #[inline(never)]
    fn read_image(&mut self, b: &[u8]) -> bool {
        let len = match b.first() {
            Some(&SETTINGS_VERSION) => Self::IMAGE_LEN,
            Some(5) => Self::IMAGE_LEN_V5,
            Some(4) => Self::IMAGE_LEN_V4,
            Some(3) => Self::IMAGE_LEN_V3,
            _ => return false,
        };
        if b.len() < len || checksum(&b[..len - 1]) != b[len - 1] {
            return false;
        }
        let mut r = Reader { buf: b, at: 1 };
        for part in self.f32_fields_mut() {
            for v in part.iter_mut() {
                *v = r.f32();
            }
        }
        self.invert_dir_mask = r.u8();
        self.soft_limits = r.u8() != 0;
        self.hard_limits = r.u8() != 0;
        self.auto_tool_offset = r.u8() != 0;
        self.homing_lock = r.u8() != 0;
        self.immediate_tool_change = r.u8() != 0;
        self.optional_stop = r.u8() != 0;
        if len >= Self::IMAGE_LEN_V4 {
            self.dwell_p_ms = r.u8() != 0;
            self.g80_keeps_motion = r.u8() != 0;
        }
        if len >= Self::IMAGE_LEN_V5 {
            self.card_out_retract_mm = r.f32();
        }
        if len == Self::IMAGE_LEN {
            self.invert_input_mask = r.u8();
        }
        self.is_sane()
    }

    /// True when every value is one the planner can work with.
    pub fn is_sane(&self) -> bool {
        const MAX: f32 = f32::MAX;
        let singles_pos = [
            self.junction_deviation_mm,
            self.arc_tolerance_mm,
            self.homing_seek_mm_per_min,
            self.homing_feed_mm_per_min,
            self.spindle_max_rpm,
        ];
        // One table, one (non-inlined) check: each f32 range check inlined
        // costs about 60 bytes of AVR code.
        all_within(&self.steps_per_mm, 0.0, false, 10_000.0)
            && all_within(&self.max_feed_mm_per_min, 0.0, false, MAX)
            && all_within(&self.accel_mm_per_s2, 0.0, false, MAX)
            && all_within(&self.travel_mm, 0.0, false, MAX)
            && all_within(&singles_pos, 0.0, false, MAX)
            && all_within(&self.backlash_mm, 0.0, true, 5.0)
            && all_within(&[self.homing_pulloff_mm], 0.0, true, MAX)
            && all_within(&[self.card_out_retract_mm], 0.0, true, MAX)
            && all_within(self.wcs_mm.as_flattened(), f32::NEG_INFINITY, true, MAX)
    }

    /// Travel of an axis in steps (X, Y, Z).
    pub fn travel_steps(&self, axis: usize) -> i32 {
        crate::math::round_i32(self.travel_mm[axis] * self.steps_per_mm[axis])
    }
}

in_flash! {
    /// The factory settings, kept in flash: a `Settings::DEFAULT` used at run
    /// time would be a 172-byte constant copied into RAM at boot on AVR.
    static DEFAULTS_IN_FLASH: Settings = Settings::DEFAULT;
}

impl Settings {
    /// The factory settings (M502), read from flash.
    pub fn defaults() -> Settings {
        DEFAULTS_IN_FLASH.get()
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings::defaults()
    }
}

/// True when every value of `v` is finite, above `lo` (or equal to it when
/// `lo_incl`) and at most `hi`.
#[inline(never)]
fn all_within(v: &[f32], lo: f32, lo_incl: bool, hi: f32) -> bool {
    v.iter().all(|&x| x.is_finite() && (x > lo || (lo_incl && x == lo)) && x <= hi)
}

/// Additive checksum of the EEPROM image, seeded so an all-0xFF blank fails.
fn checksum(b: &[u8]) -> u8 {
    b.iter().fold(0x5Au8, |s, &x| s.rotate_left(1) ^ x)
}

struct Writer<const N: usize> {
    buf: [u8; N],
    at: usize,
}

impl<const N: usize> Writer<N> {
    fn u8(&mut self, v: u8) {
        self.buf[self.at] = v;
        self.at += 1;
    }
    fn f32(&mut self, v: f32) {
        for b in v.to_le_bytes() {
            self.u8(b);
        }
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn u8(&mut self) -> u8 {
        let v = self.buf[self.at];
        self.at += 1;
        v
    }
    fn f32(&mut self) -> f32 {
        let b = [self.u8(), self.u8(), self.u8(), self.u8()];
        f32::from_le_bytes(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_through_the_eeprom_image() {
        let mut s = Settings::DEFAULT;
        s.steps_per_mm[0] = 80.0;
        s.wcs_mm[1] = [1.0, -2.5, 3.25];
        s.hard_limits = false;
        let img = s.to_bytes();
        assert_eq!(Settings::from_bytes(&img), Some(s));
    }

    #[test]
    fn a_version_3_image_loads_with_the_new_flags_at_their_defaults() {
        // The image the firmware wrote before the dwell and G80 flags:
        // version 3, the same fields, its checksum right after M1's flag.
        let mut s = Settings::DEFAULT;
        s.steps_per_mm[2] = 400.0;
        s.optional_stop = true;
        s.dwell_p_ms = true;
        s.g80_keeps_motion = false;
        let new = s.to_bytes();
        let mut old = [0xFFu8; Settings::IMAGE_LEN];
        old[0] = 3;
        old[1..Settings::IMAGE_LEN_V3 - 1].copy_from_slice(&new[1..Settings::IMAGE_LEN_V3 - 1]);
        old[Settings::IMAGE_LEN_V3 - 1] = checksum(&old[..Settings::IMAGE_LEN_V3 - 1]);
        let loaded = Settings::from_bytes(&old).unwrap();
        assert_eq!(loaded.steps_per_mm[2], 400.0);
        assert!(loaded.optional_stop);
        assert_eq!((loaded.dwell_p_ms, loaded.g80_keeps_motion), (false, true));
        // A version 3 image with a bad checksum is still refused.
        old[5] ^= 1;
        assert_eq!(Settings::from_bytes(&old), None);
        assert_eq!(Settings::from_bytes(&new), Some(s));
    }

    #[test]
    fn a_version_4_image_loads_with_the_retract_height_at_its_default() {
        let mut s = Settings::DEFAULT;
        s.dwell_p_ms = true;
        s.card_out_retract_mm = 7.5;
        let new = s.to_bytes();
        let n = Settings::IMAGE_LEN_V4;
        let mut old = [0xFFu8; Settings::IMAGE_LEN];
        old[0] = 4;
        old[1..n - 1].copy_from_slice(&new[1..n - 1]);
        old[n - 1] = checksum(&old[..n - 1]);
        let loaded = Settings::from_bytes(&old).unwrap();
        assert!(loaded.dwell_p_ms);
        assert_eq!(loaded.card_out_retract_mm, Settings::DEFAULT.card_out_retract_mm);
    }

    #[test]
    fn a_version_5_image_loads_with_every_input_read_as_wired_before() {
        let mut s = Settings::DEFAULT;
        s.card_out_retract_mm = 7.5;
        s.invert_input_mask = 0b11111;
        let new = s.to_bytes();
        let n = Settings::IMAGE_LEN_V5;
        let mut old = [0xFFu8; Settings::IMAGE_LEN];
        old[0] = 5;
        old[1..n - 1].copy_from_slice(&new[1..n - 1]);
        old[n - 1] = checksum(&old[..n - 1]);
        let loaded = Settings::from_bytes(&old).unwrap();
        assert_eq!(loaded.card_out_retract_mm, 7.5);
        assert_eq!(loaded.invert_input_mask, 0);
        assert_eq!(Settings::from_bytes(&new).unwrap().invert_input_mask, 0b11111);
    }

    #[test]
    fn blank_eeprom_gives_none() {
        assert_eq!(Settings::from_bytes(&[0xFF; Settings::IMAGE_LEN]), None);
        assert_eq!(Settings::from_bytes(&[0x00; Settings::IMAGE_LEN]), None);
    }

    #[test]
    fn a_flipped_bit_is_detected() {
        let mut img = Settings::DEFAULT.to_bytes();
        img[7] ^= 0x10;
        assert_eq!(Settings::from_bytes(&img), None);
    }

    #[test]
    fn insane_values_are_refused_even_with_a_good_checksum() {
        let mut s = Settings::DEFAULT;
        s.steps_per_mm[1] = 0.0;
        assert_eq!(Settings::from_bytes(&s.to_bytes()), None);
        s.steps_per_mm[1] = f32::NAN;
        assert_eq!(Settings::from_bytes(&s.to_bytes()), None);
    }

    #[test]
    fn defaults_are_sane_and_match_the_spec() {
        let s = Settings::DEFAULT;
        assert!(s.is_sane());
        assert_eq!(s.travel_steps(0), 4500);
        assert_eq!(s.max_feed_mm_per_min[0], 50.0 * 60.0);
        assert_eq!(s.accel_mm_per_s2[2], 1000.0);
    }
}
