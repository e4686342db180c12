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
pub const SETTINGS_VERSION: u8 = 7;

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
    /// The tool-change station (`$170`–`$180`).
    pub station: Station,
    /// Lowest spindle speed when on, rpm (grbl's `$31`): an `S` below it
    /// runs at it; `S0` is off.
    pub spindle_min_rpm: f32,
    /// Seconds to wait after the spindle starts before anything moves
    /// (`$181`; Marlin's `SPINDLE_LASER_POWERUP_DELAY`).
    pub spin_up_s: f32,
    /// Seconds to wait after the spindle stops (`M5`, and before a tool
    /// change releases the tool) (`$182`; Marlin's `…POWERDOWN_DELAY`).
    pub spin_down_s: f32,
    /// `$10`, grbl's status report mask: bit 0 machine position (`MPos`,
    /// else `WPos`), bit 1 the buffer field (`Bf`).
    pub status_mask: u8,
    /// `$13`: `?` and `$#` report inches (grbl).
    pub report_inches: bool,
    /// G80 cancels only the canned cycle and the motion mode from before
    /// the cycle stays (Fanuc, Haas, Mach3: Fusion 360's Mach3 post moves
    /// with bare axis words after G80); off: G80 leaves no motion mode and
    /// bare axis words are refused (LinuxCNC, grbl).
    pub g80_keeps_motion: bool,
}

/// The tool-change station (thesis Table 8), the travel height and the
/// carousel's pocket offset, with the feeds of the sequence (`$170`–`$180`).
/// X and Y in machine mm; the heights as depths below the Z home switch, mm
/// (the internal frame of [`crate::frame`]: Z grows downward, as the thesis
/// measures it; the user's machine Z is the negative: Z1 −40.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Station {
    /// X1: in front of the magazine.
    pub x1: f32,
    /// Y point A: outside the magazine.
    pub y_a: f32,
    /// Y point B: in the pocket.
    pub y_b: f32,
    /// Z1: safe, above the tool in the pocket.
    pub z1: f32,
    /// Z2: clamp / release.
    pub z2: f32,
    /// Travel height to and from the station (near the Z home at the top).
    pub z_safe: f32,
    /// Y in, mm/min.
    pub feed_y_in: f32,
    /// Z down to clamp, mm/min.
    pub feed_z_clamp: f32,
    /// Z down to release and back up, mm/min.
    pub feed_z_release: f32,
    /// Y out, mm/min.
    pub feed_y_out: f32,
    /// Pocket 1 sits this many pitches past pocket "0" from the carousel's
    /// home switch: pocket `p` at `p + pocket_offset` pitches.
    pub pocket_offset: f32,
    /// Half the width in X of the magazine's keep-out zone around X1, mm
    /// (`$183`; 0, the default: no zone, as before it existed).
    pub keep_out_half_width: f32,
    /// Top of the keep-out zone, mm below the Z home switch (`$184`): above
    /// it the spindle and its tool clear the magazine.
    pub keep_out_top: f32,
}

impl Station {
    /// Thesis Table 8 (docs/SPEC.md §3).
    pub const THESIS: Station = Station {
        x1: 23.0,
        y_a: 28.0,
        y_b: 44.0,
        z1: 40.5,
        z2: 45.0,
        z_safe: 1.0,
        feed_y_in: 800.0,
        feed_z_clamp: 200.0,
        feed_z_release: 1000.0,
        feed_y_out: 1000.0,
        pocket_offset: 3.0,
        keep_out_half_width: 0.0,
        keep_out_top: 1.0,
    };

    /// Does the straight move from `a` to `b` (machine mm, internal frame: Z
    /// as depth below the home switch) enter the magazine's keep-out zone?
    /// The zone: X within `keep_out_half_width` of X1, Y past point A
    /// (toward the magazine), Z deeper than `keep_out_top`; open on those
    /// sides, so its faces themselves (Y at point A, the travel height) are
    /// outside. Only the tool change goes in.
    pub fn enters_keep_out(&self, a: [f32; 3], b: [f32; 3]) -> bool {
        self.keep_out_entry(a, b).is_some()
    }

    /// Where the straight move from `a` to `b` enters the keep-out zone, as
    /// the fraction of the move done there (0: it starts inside); `None`
    /// when it stays out. See [`Station::enters_keep_out`].
    ///
    /// Every move is checked, and most machines have no zone (`$183=0`):
    /// that case is one integer test of the width's bit pattern, before
    /// the call that works out the crossing (a soft-float compare and that
    /// call's frame cost ~200 cycles a streamed line on the AVR). The
    /// reference: `keep_out_entry_matches_its_plain_reference`.
    // speed: inlined, the test is a few instructions and no arrays are built
    #[inline(always)]
    pub fn keep_out_entry(&self, a: [f32; 3], b: [f32; 3]) -> Option<f32> {
        if !self.keep_out_on() {
            return None;
        }
        self.keep_out_crossing(a, b)
    }

    /// The zone is on: `keep_out_half_width > 0.0`, on the bit pattern
    /// (positive, not ±0, not a NaN). Callers test it before they build
    /// the points for [`Station::keep_out_entry`].
    #[inline(always)]
    pub fn keep_out_on(&self) -> bool {
        let w = self.keep_out_half_width.to_bits();
        w as i32 > 0 && w <= 0x7F80_0000
    }

    /// [`Station::keep_out_entry`] with the zone on. The slabs are taken Z
    /// first: a move in XY above the zone's top (most moves near a
    /// magazine) is out after one compare, without X's two divisions. The
    /// order changes nothing: `t0` only grows and `t1` only shrinks.
    // speed: the frame is paid only with the zone on (see keep_out_entry)
    #[inline(never)]
    fn keep_out_crossing(&self, a: [f32; 3], b: [f32; 3]) -> Option<f32> {
        let w = self.keep_out_half_width;
        let lo = [self.x1 - w, self.y_a, self.keep_out_top];
        let hi = [self.x1 + w, f32::INFINITY, f32::INFINITY];
        // The segment a + t (b - a), t in [0, 1], against each slab (open
        // intervals): what is left of t after all three is inside the box.
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for i in [2, 0, 1] {
            let d = b[i] - a[i];
            if d == 0.0 {
                if !(a[i] > lo[i] && a[i] < hi[i]) {
                    return None;
                }
                continue;
            }
            let (mut u, mut v) = ((lo[i] - a[i]) / d, (hi[i] - a[i]) / d);
            if u > v {
                core::mem::swap(&mut u, &mut v);
            }
            t0 = if u > t0 { u } else { t0 };
            t1 = if v < t1 { v } else { t1 };
            if t0 >= t1 {
                return None;
            }
        }
        Some(t0)
    }

    /// Does the box `lo..=hi` (machine mm, internal frame) overlap the
    /// keep-out zone? For arcs and canned cycles, by their bounding box.
    pub fn box_enters_keep_out(&self, lo: [f32; 3], hi: [f32; 3]) -> bool {
        let w = self.keep_out_half_width;
        w > 0.0 && lo[0] < self.x1 + w && hi[0] > self.x1 - w && hi[1] > self.y_a && hi[2] > self.keep_out_top
    }

    /// The station's points with the axis each lies on and its `$` number.
    pub fn points(&self) -> [(f32, usize, u8); 6] {
        [(self.x1, 0, 170), (self.y_a, 1, 171), (self.y_b, 1, 172), (self.z1, 2, 173), (self.z2, 2, 174), (self.z_safe, 2, 175)]
    }

    /// The first point outside `0..=travel` of its axis: its `$` number and
    /// the axis. `None`: every point inside.
    pub fn outside(&self, travel_mm: &[f32; 3]) -> Option<(u8, usize)> {
        self.points().into_iter().find(|&(v, a, _)| !(v >= 0.0 && v <= travel_mm[a])).map(|(_, a, n)| (n, a))
    }
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
        station: Station::THESIS,
        spindle_min_rpm: 0.0,
        spin_up_s: 0.0,
        spin_down_s: 0.0,
        status_mask: 1,
        report_inches: false,
    };

    /// Every value zero: only a placeholder for building a `Machine` in
    /// place (`Machine::init`), never used.
    // SAFETY: every field is an f32, a bool or a u8 (arrays and `Station`
    // of them): all-zero bytes are a valid value of each (0.0, false, 0).
    pub const ZEROED: Settings = unsafe { core::mem::zeroed() };

    /// Size of the EEPROM image in bytes: version, fields, checksum.
    pub const IMAGE_LEN: usize = Self::IMAGE_LEN_V6 + 2;
    /// Size of a version 6 image: no status report mask or inch flag.
    const IMAGE_LEN_V6: usize = Self::IMAGE_LEN_V5 + 1 + 4 * 16;
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
        let mut img = [0; Self::IMAGE_LEN];
        self.write_image(&mut img);
        img
    }

    /// [`Settings::to_bytes`] into `img`: the firmware's one copy of the
    /// image (returned by value it was two on the AVR, 250 B more stack on
    /// the deepest path, `$n=`).
    pub fn write_image(&self, img: &mut [u8; Self::IMAGE_LEN]) {
        let mut w = Writer { buf: img, at: 0 };
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
        for v in self.station_fields() {
            w.f32(v);
        }
        w.f32(self.spindle_min_rpm);
        w.f32(self.spin_up_s);
        w.f32(self.spin_down_s);
        w.u8(self.status_mask);
        w.u8(self.report_inches as u8);
        let sum = checksum(&w.buf[..w.at]);
        w.u8(sum);
        debug_assert_eq!(w.at, Self::IMAGE_LEN);
    }

    /// Parse an EEPROM image. `None` if blank, of another version, corrupt,
    /// or holding values no machine could use (NaN, zero steps/mm, …). A
    /// version 3 image (shorter by the two last flags) loads with those
    /// flags at their defaults.
    pub fn from_bytes(b: &[u8]) -> Option<Settings> {
        let mut s = Settings::defaults();
        s.read_image(b).then_some(s)
    }

    /// [`Settings::from_bytes`] in place, for the boot and M501 (the
    /// settings are some 250 bytes: no copy of them on the stack). A blank
    /// or corrupt image leaves `self` as it was; one with a good checksum
    /// but values no machine could use leaves the defaults.
    pub fn load_image(&mut self, b: &[u8]) -> bool {
        if Self::image_len(b).is_none() {
            return false;
        }
        if self.read_image(b) {
            return true;
        }
        self.reset_to_defaults();
        false
    }

    /// The factory settings, in place (read from flash).
    #[cold]
    // flash: inlined (LLVM's choice, with `read_image`), 4 B more
    #[inline(never)]
    pub fn reset_to_defaults(&mut self) {
        *self = Settings::defaults();
    }

    /// The length of a valid image of a version this firmware reads
    /// (version and checksum right), or `None`.
    fn image_len(b: &[u8]) -> Option<usize> {
        let len = match b.first() {
            Some(&SETTINGS_VERSION) => Self::IMAGE_LEN,
            Some(6) => Self::IMAGE_LEN_V6,
            Some(5) => Self::IMAGE_LEN_V5,
            Some(4) => Self::IMAGE_LEN_V4,
            Some(3) => Self::IMAGE_LEN_V3,
            _ => return None,
        };
        (b.len() >= len && checksum(&b[..len - 1]) == b[len - 1]).then_some(len)
    }

    /// [`Settings::from_bytes`] into `self`; false (and `self` partly
    /// overwritten) when the image is not valid. Not inlined: it works on
    /// the settings through a pointer, within AVR's `ldd` reach.
    // flash: see `reset_to_defaults`
    #[inline(never)]
    fn read_image(&mut self, b: &[u8]) -> bool {
        let Some(len) = Self::image_len(b) else {
            return false;
        };
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
        if len >= Self::IMAGE_LEN_V6 {
            self.invert_input_mask = r.u8();
            let mut v = [0.0; 13];
            for x in v.iter_mut() {
                *x = r.f32();
            }
            self.set_station_fields(v);
            self.spindle_min_rpm = r.f32();
            self.spin_up_s = r.f32();
            self.spin_down_s = r.f32();
        }
        if len == Self::IMAGE_LEN {
            self.status_mask = r.u8();
            self.report_inches = r.u8() != 0;
        }
        self.is_sane()
    }

    /// The station's values in EEPROM image order, which is `$170`…`$180`,
    /// then `$183`, `$184`.
    pub fn station_fields(&self) -> [f32; 13] {
        let s = &self.station;
        [
            s.x1,
            s.y_a,
            s.y_b,
            s.z1,
            s.z2,
            s.z_safe,
            s.feed_y_in,
            s.feed_z_clamp,
            s.feed_z_release,
            s.feed_y_out,
            s.pocket_offset,
            s.keep_out_half_width,
            s.keep_out_top,
        ]
    }

    /// Inverse of [`Settings::station_fields`].
    fn set_station_fields(&mut self, v: [f32; 13]) {
        let [x1, y_a, y_b, z1, z2, z_safe, feed_y_in, feed_z_clamp, feed_z_release, feed_y_out, pocket_offset, keep_out_half_width, keep_out_top] =
            v;
        self.station = Station {
            x1,
            y_a,
            y_b,
            z1,
            z2,
            z_safe,
            feed_y_in,
            feed_z_clamp,
            feed_z_release,
            feed_y_out,
            pocket_offset,
            keep_out_half_width,
            keep_out_top,
        };
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
        // One table, one check (LLVM keeps `all_within` out of line): each
        // f32 range check inlined costs about 60 bytes of AVR code.
        all_within(&self.steps_per_mm, 0.0, false, 10_000.0)
            && all_within(&self.max_feed_mm_per_min, 0.0, false, MAX)
            && all_within(&self.accel_mm_per_s2, 0.0, false, MAX)
            && all_within(&self.travel_mm, 0.0, false, MAX)
            && all_within(&singles_pos, 0.0, false, MAX)
            && all_within(&self.backlash_mm, 0.0, true, 5.0)
            && all_within(&[self.homing_pulloff_mm], 0.0, true, MAX)
            && all_within(&[self.card_out_retract_mm], 0.0, true, MAX)
            && all_within(&self.station_fields()[..6], 0.0, true, MAX)
            && all_within(&self.station_fields()[6..10], 0.0, false, MAX)
            && all_within(&[self.station.pocket_offset], 0.0, true, 17.0)
            && all_within(&[self.station.keep_out_half_width, self.station.keep_out_top], 0.0, true, MAX)
            && all_within(&[self.spindle_min_rpm], 0.0, true, self.spindle_max_rpm)
            && all_within(&[self.spin_up_s, self.spin_down_s], 0.0, true, 60.0)
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
fn all_within(v: &[f32], lo: f32, lo_incl: bool, hi: f32) -> bool {
    v.iter().all(|&x| x.is_finite() && (x > lo || (lo_incl && x == lo)) && x <= hi)
}

/// Additive checksum of the EEPROM image, seeded so an all-0xFF blank fails.
fn checksum(b: &[u8]) -> u8 {
    b.iter().fold(0x5Au8, |s, &x| s.rotate_left(1) ^ x)
}

struct Writer<'a, const N: usize> {
    buf: &'a mut [u8; N],
    at: usize,
}

impl<const N: usize> Writer<'_, N> {
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

    /// The image an older firmware wrote: `version`, the first `len - 2`
    /// bytes of today's image `new` after the version, its own checksum
    /// (the rest blank).
    fn old_image(new: &[u8], version: u8, len: usize) -> [u8; Settings::IMAGE_LEN] {
        let mut old = [0xFFu8; Settings::IMAGE_LEN];
        old[0] = version;
        old[1..len - 1].copy_from_slice(&new[1..len - 1]);
        old[len - 1] = checksum(&old[..len - 1]);
        old
    }

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
        let mut old = old_image(&new, 3, Settings::IMAGE_LEN_V3);
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
        let old = old_image(&s.to_bytes(), 4, Settings::IMAGE_LEN_V4);
        let loaded = Settings::from_bytes(&old).unwrap();
        assert!(loaded.dwell_p_ms);
        assert_eq!(loaded.card_out_retract_mm, Settings::DEFAULT.card_out_retract_mm);
    }

    #[test]
    fn a_version_6_image_loads_with_grbls_status_report_defaults() {
        let mut s = Settings::DEFAULT;
        s.spin_down_s = 2.5;
        s.status_mask = 2;
        s.report_inches = true;
        let new = s.to_bytes();
        let old = old_image(&new, 6, Settings::IMAGE_LEN_V6);
        let loaded = Settings::from_bytes(&old).unwrap();
        assert_eq!(loaded.spin_down_s, 2.5);
        assert_eq!((loaded.status_mask, loaded.report_inches), (1, false));
        let back = Settings::from_bytes(&new).unwrap();
        assert_eq!((back.status_mask, back.report_inches), (2, true));
    }

    #[test]
    fn a_version_5_image_loads_with_every_input_read_as_wired_before() {
        let mut s = Settings::DEFAULT;
        s.card_out_retract_mm = 7.5;
        s.invert_input_mask = 0b11111;
        let new = s.to_bytes();
        let old = old_image(&new, 5, Settings::IMAGE_LEN_V5);
        let loaded = Settings::from_bytes(&old).unwrap();
        assert_eq!(loaded.card_out_retract_mm, 7.5);
        assert_eq!(loaded.invert_input_mask, 0);
        assert_eq!(Settings::from_bytes(&new).unwrap().invert_input_mask, 0b11111);
    }

    #[test]
    fn the_keep_out_zone_takes_moves_into_the_magazine_and_nothing_else() {
        let s = Station { keep_out_half_width: 10.0, ..Station::THESIS }; // X 13..33, Y past 28, deeper than 1 mm
        let k = |a: [f32; 3], b: [f32; 3]| s.enters_keep_out(a, b);
        // The example: over the magazine at the top, then down.
        assert!(!k([0.0, 0.0, 0.0], [23.0, 42.0, 0.0]));
        assert!(k([23.0, 42.0, 0.0], [23.0, 42.0, 44.0]));
        // A diagonal from the work area that cuts through the zone.
        assert!(k([5.0, 40.0, 10.0], [40.0, 40.0, 10.0]));
        // Beside it, below the travel height, and on its faces: outside.
        assert!(!k([5.0, 40.0, 10.0], [12.9, 44.0, 30.0]));
        assert!(!k([23.0, 28.0, 40.5], [23.0, 0.0, 40.5]));
        assert!(!k([0.0, 44.0, 1.0], [45.0, 44.0, 1.0]));
        assert!(!k([10.0, 10.0, 20.0], [40.0, 27.9, 20.0]));
        // Inside to outside counts (a move must not start in it either).
        assert!(k([23.0, 30.0, 5.0], [23.0, 20.0, 5.0]));
        // Zone off.
        let off = Station { keep_out_half_width: 0.0, ..s };
        assert!(!off.enters_keep_out([23.0, 42.0, 0.0], [23.0, 42.0, 44.0]));
    }

    /// [`Station::keep_out_entry`] as it was written plainly: `w > 0.0`,
    /// the slabs in X, Y, Z order.
    fn keep_out_entry_plain(st: &Station, a: [f32; 3], b: [f32; 3]) -> Option<f32> {
        let w = st.keep_out_half_width;
        if !(w > 0.0) {
            return None;
        }
        let lo = [st.x1 - w, st.y_a, st.keep_out_top];
        let hi = [st.x1 + w, f32::INFINITY, f32::INFINITY];
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for i in 0..3 {
            let d = b[i] - a[i];
            if d == 0.0 {
                if !(a[i] > lo[i] && a[i] < hi[i]) {
                    return None;
                }
                continue;
            }
            let (mut u, mut v) = ((lo[i] - a[i]) / d, (hi[i] - a[i]) / d);
            if u > v {
                core::mem::swap(&mut u, &mut v);
            }
            t0 = if u > t0 { u } else { t0 };
            t1 = if v < t1 { v } else { t1 };
            if t0 >= t1 {
                return None;
            }
        }
        Some(t0)
    }

    #[test]
    fn keep_out_entry_matches_its_plain_reference() {
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        let mut next = || rng.next();
        // Widths: off (0, −0, negative, NaN), on, and the edge cases of the bit test.
        let widths = [0.0, -0.0, -5.0, f32::NAN, -f32::NAN, f32::INFINITY, f32::MIN_POSITIVE, 1e-45, 10.0, 3.5];
        let mut hits = 0;
        for i in 0..200_000 {
            let w = widths[i % widths.len()];
            let st = Station { keep_out_half_width: w, ..Station::THESIS };
            // Points around the zone (X 13..33, Y past 28, deeper than 1),
            // on a 0.5 mm grid so that moves often run along a face.
            let mut p = || core::array::from_fn(|_| (next() % 120) as f32 * 0.5 - 10.0);
            let (a, mut b): ([f32; 3], [f32; 3]) = (p(), p());
            // Often one or two axes still (an XY move, a Z move).
            match next() % 4 {
                0 => b[2] = a[2],
                1 => (b[0], b[1]) = (a[0], a[1]),
                _ => {}
            }
            let (f, r) = (st.keep_out_entry(a, b), keep_out_entry_plain(&st, a, b));
            assert_eq!(f.map(f32::to_bits), r.map(f32::to_bits), "w {w} {a:?} → {b:?}");
            hits += f.is_some() as u32;
        }
        assert!(hits > 1000, "{hits}");
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
