//! The reports a line can ask for (M114, M119, M503): the controller
//! prints them, from the stepper's counters, the switches and the settings.

use super::{Inputs, Machine, Stepper};
use crate::fixed::Micros;
use crate::flash::FStr;
use crate::frame;
use crate::N_AXES;
use ufmt::{uwrite, uwriteln};

/// M114: work position (user frame) and the step counters.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn position(m: &Machine, io: &mut (impl Stepper + ufmt::uWrite)) {
    let internal = io.stepper().position;
    let w = m.interp.work_user(m.steps_to_mm(internal));
    // Count: the step counters in the user's sense (Z counts up), so that
    // Count = position × steps/mm as in Marlin.
    let st = frame::steps_user_from_internal(internal);
    // The field names through F!: as format text they were RAM strings.
    let (y, z, e) = (F!(" Y:"), F!(" Z:"), F!(" E:"));
    uwrite!(
        io,
        "{}{}{}{}{}{}{}{}",
        F!("X:"),
        Micros::from_mm(w[0]),
        y,
        Micros::from_mm(w[1]),
        z,
        Micros::from_mm(w[2]),
        e,
        Micros::from_mm(w[3])
    )
    .ok();
    uwriteln!(io, "{}{}{}{}{}{}{}{}", F!(" Count X:"), st[0], y, st[1], z, st[2], e, st[3]).ok();
}

/// M119: the switches.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn switches(_m: &Machine, io: &mut (impl Inputs + ufmt::uWrite)) {
    let s = io.switches();
    uwriteln!(io, "{}", F!("Reporting endstop status")).ok();
    let lines = [
        (F!("x_min: "), s.home & 1 != 0),
        (F!("y_min: "), s.home & 2 != 0),
        (F!("z_min: "), s.home & 4 != 0),
        (F!("carousel: "), s.carousel_home),
        (F!("tool_setter: "), s.tool_setter),
    ];
    for (name, on) in lines {
        uwriteln!(io, "{}{}", name, if on { F!("TRIGGERED") } else { F!("open") }).ok();
    }
}

/// M503: the settings as the codes that set them.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn settings(m: &Machine, io: &mut impl ufmt::uWrite) {
    let s = &m.settings;
    let line = |io: &mut dyn DynOut, code: FStr, v: &[f32; N_AXES], scale: f32| {
        io.out(code);
        for a in 0..N_AXES {
            axis_name(io, a);
            io.num(v[a] * scale);
        }
        io.text("\n");
    };
    let mut d = Dyn(io);
    d.out(F!("echo:Steps per unit:\n"));
    line(&mut d, F!("M92"), &s.steps_per_mm, 1.0);
    d.out(F!("echo:Max feedrates (units/s):\n"));
    line(&mut d, F!("M203"), &s.max_feed_mm_per_min, 1.0 / 60.0);
    d.out(F!("echo:Max acceleration (units/s2):\n"));
    line(&mut d, F!("M201"), &s.accel_mm_per_s2, 1.0);
    d.out(F!("echo:Work offsets:\n"));
    for (i, o) in m.interp.wcs_mm.iter().enumerate() {
        d.out(F!("G10 L2 P"));
        d.int(i as i32 + 1);
        for a in 0..3 {
            axis_name(&mut d, a);
            d.num(frame::axis_user_from_internal(a, o[a]));
        }
        d.text("\n");
    }
    d.out(F!("echo:Travel (mm):"));
    for a in 0..3 {
        axis_name(&mut d, a);
        d.num(s.travel_mm[a]);
    }
    let on_off = |on: bool| if on { F!("on") } else { F!("off") };
    d.out(F!(" soft limits "));
    d.out(on_off(s.soft_limits));
    d.out(F!(", hard limits "));
    d.out(on_off(s.hard_limits));
    d.text("\n");
    d.out(F!("echo:Inputs read inverted (normally-closed), bits X Y Z carousel setter:\n$5="));
    d.int(s.invert_input_mask as i32);
    d.text("\n");
    d.out(F!("echo:Dialect: $153="));
    d.int(s.dwell_p_ms as i32);
    d.out(if s.dwell_p_ms { F!(" (G4 P in ms) $154=") } else { F!(" (G4 P in seconds) $154=") });
    d.int(s.g80_keeps_motion as i32);
    d.out(if s.g80_keeps_motion { F!(" (G80 keeps the motion mode)\n") } else { F!(" (G80 ends the motion mode)\n") });
    d.out(F!("echo:Card pulled mid-job, Z retract (mm below its home switch):\n$160="));
    d.num(s.card_out_retract_mm);
    d.text("\n");
    d.out(F!("echo:Tool change station X1 YA YB, Z1 Z2 travel (mm below Z home), feeds, pocket offset:\n"));
    // `$170`…`$180`: the first eleven of the station's fields.
    for (i, v) in s.station_fields().into_iter().take(11).enumerate() {
        d.out(F!("$"));
        d.int(170 + i as i32);
        d.out(F!("="));
        d.num(v);
        d.text("\n");
    }
    d.out(F!("echo:Tool numbers by pocket (G10 L1 P<tool> Q<pocket>):\n"));
    for p in 1..=crate::atc::N_POCKETS as u8 {
        let n = m.atc.table.number_of(p);
        if n != 0 {
            d.out(F!("G10 L1 P"));
            d.int(n as i32);
            d.out(F!(" Q"));
            d.int(p as i32);
            d.text("\n");
        }
    }
}

/// M31, as Marlin answers it: `echo:Print time: 1h 2m 3s` (leading zero
/// units left out), the time since the running SD job started; `0s` when
/// no job runs (a streamed job has no start this firmware knows of).
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn print_time(m: &Machine, io: &mut (impl Inputs + ufmt::uWrite)) {
    let s = if m.sd_job { (io.millis().wrapping_sub(m.job_start_ms) / 1000) as i32 } else { 0 };
    let parts = [(s / 86_400, F!("d ")), (s / 3600 % 24, F!("h ")), (s / 60 % 60, F!("m ")), (s % 60, F!("s"))];
    let mut d = Dyn(io);
    d.out(F!("echo:Print time: "));
    let mut started = false;
    for (i, (v, unit)) in parts.into_iter().enumerate() {
        started |= v != 0 || i == 3;
        if started {
            d.int(v);
            d.out(unit);
        }
    }
    d.text("\n");
}

/// Write ` X`, ` Y`, ` Z` or ` E` for axis `a` (0…3), computed: a table of
/// the four names was 24 bytes of RAM (`.data`) on AVR.
fn axis_name(d: &mut dyn DynOut, a: usize) {
    let letter = if a == 3 { b'E' } else { b'X' + a as u8 };
    let mut buf = [0u8; 4];
    d.text(" ");
    d.text(char::from(letter).encode_utf8(&mut buf));
}

/// Small object-safe writer used by the settings report.
trait DynOut {
    fn out(&mut self, s: FStr);
    fn text(&mut self, s: &str);
    fn num(&mut self, v: f32);
    fn int(&mut self, v: i32);
}

struct Dyn<'a, W: ufmt::uWrite>(&'a mut W);

impl<W: ufmt::uWrite> DynOut for Dyn<'_, W> {
    fn out(&mut self, s: FStr) {
        s.write_to(self.0).ok();
    }
    fn text(&mut self, s: &str) {
        self.0.write_str(s).ok();
    }
    fn num(&mut self, v: f32) {
        uwrite!(self.0, "{}", Micros::from_mm(v)).ok();
    }
    fn int(&mut self, v: i32) {
        uwrite!(self.0, "{}", v).ok();
    }
}
