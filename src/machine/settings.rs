//! Settings: putting new ones in force (M92, M201, M203, `$<n>=`, `$RST`,
//! the menu's teach), and storing and loading the settings image in EEPROM
//! (M500, M501, boot).

use super::{startup, CmdResult, Io, Machine, Storage, EEPROM_SETTINGS_ADDR};
use crate::config::Settings;
use crate::dollar;
use crate::gcode::interp;
use crate::N_AXES;
use ufmt::uwriteln;

impl Machine {
    /// M92 / M201 / M203 (`values`: X Y Z E, NaN where absent), once the
    /// machine is still.
    pub(super) fn axis_settings(&mut self, io: &mut impl Io, code: u16, values: [f32; N_AXES]) -> CmdResult {
        self.wait_idle(io)?;
        let mut s = self.settings;
        for (a, &v) in values.iter().enumerate() {
            if v.is_nan() {
                continue;
            }
            if !(v > 0.0) {
                return Err(interp::Error::BadWord(F!("value must be positive")));
            }
            match code {
                92 => s.steps_per_mm[a] = v,
                201 => s.accel_mm_per_s2[a] = v,
                _ => s.max_feed_mm_per_min[a] = v * 60.0, // M203 is mm/s (Marlin)
            }
        }
        if !s.is_sane() {
            return Err(interp::Error::BadWord(F!("value out of range")));
        }
        self.replace_settings(&s, io);
        Ok(())
    }

    /// `$<n>=<v>`: check the value (a bad one is refused at once, even
    /// while moving), wait until the machine is still, put it in force,
    /// then store all settings at once.
    pub fn set_setting(&mut self, io: &mut impl Io, n: u8, v: f32) -> CmdResult {
        self.put_setting(io, n, v, false)?;
        self.still_for_settings(io)?;
        self.put_setting(io, n, v, true)?;
        self.save_settings(io);
        Ok(())
    }

    /// `$<n>=<v>` on a copy of the settings, checked; with `apply`, the copy
    /// is then put in force. Not inlined: its frame, with the copy, is
    /// gone before the wait and before `save_settings` builds the EEPROM
    /// image.
    // stack: `$n=` was the deepest path (docs/ARCHITECTURE.md, RAM)
    #[inline(never)]
    fn put_setting(&mut self, io: &mut impl Io, n: u8, v: f32, apply: bool) -> CmdResult {
        let bad = |e: dollar::DollarError| interp::Error::BadWord(e.message());
        let mut s = self.settings;
        dollar::set(&mut s, n, v).map_err(bad)?;
        if !s.is_sane() {
            return Err(bad(dollar::DollarError::BadValue));
        }
        // A station point set outside its axis' travel: named, nothing
        // stored. (A travel made shorter under the station is taken: a
        // machine without a changer needs no station; a tool change then
        // refuses to start.)
        if let Some((setting, axis)) = s.station.outside(&s.travel_mm).filter(|_| (170..=175).contains(&n)) {
            return Err(interp::Error::StationOutside { setting, axis: axis as u8 });
        }
        if apply {
            self.replace_settings(&s, io);
        }
        Ok(())
    }

    /// The menu's "teach": station point `p` (`$170 + p`: X1, Y point A,
    /// Y point B, Z1, Z2, the travel height) becomes where the machine is,
    /// through the same checks as `$170=…`. Refused until homed (the
    /// position means nothing before).
    pub fn teach_station(&mut self, io: &mut impl Io, p: u8) -> CmdResult {
        if self.homed & 0b111 != 0b111 {
            return Err(interp::Error::NotHomed);
        }
        let Some(&(_, axis, n)) = self.settings.station.points().get(p as usize) else {
            return Err(interp::Error::BadWord(dollar::DollarError::Unknown.message()));
        };
        let v = self.interp.pos_mm[axis];
        self.set_setting(io, n, v)
    }

    /// `$RST=$` settings to defaults (the work offsets kept), `$RST=#` work
    /// offsets to 0, `$RST=*` both and the startup blocks and info text;
    /// stored at once, as grbl does. The tool table and the changer's
    /// state are kept: they describe the machine as it physically is.
    pub(super) fn restore(&mut self, io: &mut impl Io, what: u8) -> CmdResult {
        self.still_for_settings(io)?;
        let mut s = Settings::defaults();
        self.interp.store_settings(&mut self.settings);
        if what == b'#' {
            s = self.settings;
        }
        if what == b'$' {
            s.wcs_mm = self.settings.wcs_mm;
        } else {
            s.wcs_mm = [[0.0; 3]; crate::config::N_WCS];
        }
        if what == b'*' {
            startup::clear(io);
        }
        self.replace_settings(&s, io);
        self.interp.load_settings(&self.settings);
        self.save_settings(io);
        uwriteln!(io, "{}", F!("[MSG:Restoring defaults]")).ok();
        Ok(())
    }

    /// Wait until the machine is still, before a settings change. In an
    /// alarm nothing moves (it stopped the steps and dropped the queue):
    /// settings such as `$21=0` may change at once. The callers wait before
    /// they copy the settings: a copy (250 B) held across the wait lies
    /// under the main loop's frames (the display's, ~270 B), and `$n=` was
    /// the deepest stack path that way.
    fn still_for_settings(&mut self, io: &mut impl Io) -> CmdResult {
        if self.alarm.is_none() {
            self.wait_idle(io)?;
        }
        Ok(())
    }

    /// Put new settings in force, the machine still (M92, M201, M203,
    /// `$n=`, `$RST`; the caller waited: [`Machine::still_for_settings`]):
    /// the step counters are rescaled so that a steps/mm change keeps
    /// the physical position, and the ISR's watch list follows the limits and
    /// direction settings.
    pub fn replace_settings(&mut self, s: &Settings, io: &mut impl Io) {
        let mm = self.steps_to_mm(io.stepper().position);
        self.set_settings(*s);
        let new = self.interp.steps_of(&self.settings, &mm);
        io.set_stepper_position(new);
        self.planner.set_position(new);
        self.apply_watch(io, 0, false);
    }

    /// Put `s` in force as the settings (the planner and the interpreter's
    /// caches are told).
    pub fn set_settings(&mut self, s: Settings) {
        self.settings = s;
        self.settings_loaded();
    }

    /// The settings changed in place: the planner's and the interpreter's
    /// caches follow.
    pub(super) fn settings_loaded(&mut self) {
        self.planner.settings_changed();
        self.interp.settings_changed();
    }

    /// Save the settings image to EEPROM (M500).
    pub fn save_settings(&mut self, io: &mut impl Storage) {
        self.interp.store_settings(&mut self.settings);
        let mut img = [0; Settings::IMAGE_LEN];
        self.settings.write_image(&mut img);
        io.eeprom_write(EEPROM_SETTINGS_ADDR, &img);
    }

    /// Load the settings from EEPROM (M501). False if the image is invalid.
    pub fn load_settings(&mut self, io: &mut impl Storage) -> bool {
        let mut img = [0u8; Settings::IMAGE_LEN];
        io.eeprom_read(EEPROM_SETTINGS_ADDR, &mut img);
        let loaded = self.settings.load_image(&img);
        self.settings_loaded();
        if loaded {
            self.interp.load_settings(&self.settings);
        }
        loaded
    }
}
