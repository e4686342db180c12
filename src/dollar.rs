//! grbl-style `$` commands: every machine setting by number, for builders and
//! senders (cncjs, UGS) that know grbl.
//!
//! ```text
//!  $$            list every setting as `$<n>=<value>` (grbl's format)
//!  $<n>=<value>  set one, check it, and store all settings in EEPROM at once
//!                (grbl's behaviour; M92/M201/M203 change RAM until M500)
//!  $H            home all axes (G28)
//!  $X            unlock an alarm (M999)
//!  $G            modal state, grbl 1.1's `[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]`
//!  $#            offsets: `[G54:x,y,z]` … `[G59:…]`, `[G28:…]`, `[G30:…]`,
//!                `[G92:…]`, `[TLO:z]`, `[PRB:x,y,z:0]` (G28/G30 hold no
//!                stored positions here, G28 homes; the probe result is not
//!                kept, G38.x prints it: all three always read 0)
//!  $I            `[VER:1.1h.MillFW:<version>]`, `[OPT:VNH,15,255]`
//! ```
//!
//! The numbers follow grbl where grbl has the setting ($3, $5, $10, $11, $12, $13, $31, $20,
//! $21, $22, $24, $25, $27, $30, $100–$132) and continue in grbl's style for the
//! rest ($103/$113/$123 for the carousel on E0, $140–$142 backlash, $150
//! automatic tool offset, $151 Repetier's immediate T, $152 optional stop,
//! $153 `G4 P` in milliseconds, $154 G80 keeping the motion mode, $160 the
//! retract height when the card is pulled mid-job, $170–$180 the tool
//! change station and the carousel's pocket offset, $181/$182 the spindle's
//! spin-up and spin-down delays). The table is a `match`, so it lives in flash.
//!
//! Called from `Machine::run_raw_line` for lines starting with `$`; pure
//! parsing and formatting here, host-tested.

use crate::config::Settings;
use crate::fixed::Micros;
use crate::flash::FStr;
use ufmt::{uWrite, uwrite, uwriteln};

/// One setting, borrowed out of [`Settings`].
pub enum Field<'a> {
    Num(&'a mut f32),
    Flag(&'a mut bool),
    /// A bit mask, and the highest value it may take.
    Mask(&'a mut u8, u8),
}

/// One setting's value, read out of [`Settings`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Num(f32),
    Flag(bool),
    /// A bit mask, and the highest value it may take.
    Mask(u8, u8),
}

impl Value {
    /// The value in thousandths (the unit the menu edits in; a flag or a
    /// mask is a whole number).
    pub fn micros(self) -> i32 {
        match self {
            Value::Num(x) => Micros::from_mm(x).0,
            Value::Flag(b) => b as i32 * 1000,
            Value::Mask(m, _) => m as i32 * 1000,
        }
    }
}

/// The settings table, written once: `field` (to set one), `value` (to read
/// one and what it means), and the list of numbers in flash (`count`,
/// `nth`), all from the same lines. `$s` and `$n` are the functions' parameters, named at the
/// call so the places can use them.
macro_rules! settings_table {
    ($s:ident, $n:ident; $($num:pat => $kind:ident($place:expr $(, $max:expr)?), $what:literal;)*) => {
        /// The setting numbered `n`, to set it.
        // flash: one copy of the table (inlined into `set_setting`: 168 B more)
        #[inline(never)]
        pub fn field($s: &mut Settings, $n: u8) -> Option<Field<'_>> {
            Some(match $n {
                $($num => Field::$kind(&mut $place $(, $max)?),)*
                _ => return None,
            })
        }

        /// The value of setting `n`, and what it means.
        pub fn value($s: &Settings, $n: u8) -> Option<(Value, FStr)> {
            Some(match $n {
                $($num => (Value::$kind($place $(, $max)?), F!($what)),)*
                _ => return None,
            })
        }

        /// True if setting `n` exists.
        const fn exists($n: u8) -> bool {
            matches!($n, $($num)|*)
        }
    };
}

settings_table! { s, n;
    3 => Mask(s.invert_dir_mask, 0b1111), "direction invert mask, bit 0 X .. bit 3 E";
    5 => Mask(s.invert_input_mask, 0b11111), "input invert mask (normally-closed): bit 0-2 X Y Z home, 3 carousel home, 4 tool setter";
    10 => Mask(s.status_mask, 0b11), "status report: bit 0 MPos (else WPos), bit 1 Bf";
    11 => Num(s.junction_deviation_mm), "junction deviation, mm";
    12 => Num(s.arc_tolerance_mm), "arc tolerance, mm";
    13 => Flag(s.report_inches), "report positions and feeds in inches (? and $#), 0/1";
    20 => Flag(s.soft_limits), "soft limits, 0/1";
    21 => Flag(s.hard_limits), "hard limits, 0/1";
    22 => Flag(s.homing_lock), "homing lock: no motion until homed or unlocked, 0/1";
    24 => Num(s.homing_feed_mm_per_min), "homing locate feed, mm/min";
    25 => Num(s.homing_seek_mm_per_min), "homing seek feed, mm/min";
    27 => Num(s.homing_pulloff_mm), "homing pull-off, mm";
    30 => Num(s.spindle_max_rpm), "spindle rpm at 100 % PWM";
    31 => Num(s.spindle_min_rpm), "spindle minimum rpm when on";
    100..=103 => Num(s.steps_per_mm[(n - 100) as usize]), "steps/mm (E: steps/pocket)";
    110..=113 => Num(s.max_feed_mm_per_min[(n - 110) as usize]), "max rate, mm/min";
    120..=123 => Num(s.accel_mm_per_s2[(n - 120) as usize]), "acceleration, mm/s^2";
    130..=132 => Num(s.travel_mm[(n - 130) as usize]), "max travel, mm";
    140..=142 => Num(s.backlash_mm[(n - 140) as usize]), "backlash, mm";
    150 => Flag(s.auto_tool_offset), "apply tool length offset after a change, 0/1";
    151 => Flag(s.immediate_tool_change), "T alone changes the tool at once (Repetier), 0/1";
    152 => Flag(s.optional_stop), "optional stop: M1 pauses, 0/1";
    153 => Flag(s.dwell_p_ms), "G4 P in milliseconds (Mach3, UCCNC, Marlin), 0/1";
    154 => Flag(s.g80_keeps_motion), "G80 keeps the motion mode from before the cycle (Fanuc, Mach3), 0/1";
    160 => Num(s.card_out_retract_mm), "card pulled mid-job: retract Z to this far below its home switch, mm";
    170 => Num(s.station.x1), "tool change X1 (in front of the magazine), mm";
    171 => Num(s.station.y_a), "tool change Y point A (outside the magazine), mm";
    172 => Num(s.station.y_b), "tool change Y point B (in the pocket), mm";
    173 => Num(s.station.z1), "tool change Z1 (above the tool in its pocket), mm below Z home";
    174 => Num(s.station.z2), "tool change Z2 (clamp / release), mm below Z home";
    175 => Num(s.station.z_safe), "tool change travel height, mm below Z home";
    176 => Num(s.station.feed_y_in), "tool change feed Y in, mm/min";
    177 => Num(s.station.feed_z_clamp), "tool change feed Z down to clamp, mm/min";
    178 => Num(s.station.feed_z_release), "tool change feed Z release and up, mm/min";
    179 => Num(s.station.feed_y_out), "tool change feed Y out, mm/min";
    180 => Num(s.station.pocket_offset), "carousel: pocket 1 at this + 1 pitches from home, 0-17";
    181 => Num(s.spin_up_s), "spindle spin-up delay after M3, s";
    182 => Num(s.spin_down_s), "spindle spin-down delay after M5 and before a tool change, s";
    183 => Num(s.station.keep_out_half_width), "tool magazine keep-out zone: half width in X around X1, mm (0: none)";
    184 => Num(s.station.keep_out_top), "tool magazine keep-out zone: top, mm below Z home";
}

/// How many settings there are.
const COUNT: usize = {
    let mut c = 0;
    let mut n = 0;
    while n < 256 {
        if exists(n as u8) {
            c += 1;
        }
        n += 1;
    }
    c
};

crate::in_flash! {
    /// Every setting's number, ascending.
    static NUMBERS: [u8; COUNT] = {
        let mut t = [0u8; COUNT];
        let (mut i, mut n) = (0, 0);
        while n < 256 {
            if exists(n as u8) {
                t[i] = n as u8;
                i += 1;
            }
            n += 1;
        }
        t
    };
}

/// How many settings there are (the menu's Settings list).
pub fn count() -> u8 {
    COUNT as u8
}

/// The number of the `i`-th setting in ascending order (`i` < [`count`]).
pub fn nth(i: u8) -> u8 {
    NUMBERS.row(i as usize).unwrap_or(0)
}

/// A parsed `$` command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    List,
    /// `$G`: the modal state.
    Modes,
    /// `$#`: the offsets.
    Params,
    /// `$I`: build info.
    Info,
    Set(u8, f32),
    Home,
    Unlock,
    /// `$J=<words>`: a jog (the words are read by the caller).
    Jog,
    /// `$HX`, `$HY`, `$HZ`: home one axis (bit 0 X, 1 Y, 2 Z).
    HomeAxis(u8),
    /// `$N`: list the startup blocks.
    StartupList,
    /// `$N0=<line>`, `$N1=<line>` (the line is read by the caller).
    StartupSet(u8),
    /// `$I=<text>` (the text is read by the caller).
    InfoSet,
    /// `$RST=$` (settings), `$RST=#` (work offsets), `$RST=*` (both, and
    /// the startup blocks and info text).
    Restore(u8),
    /// `$SLP`: spindle, coolant and drivers off.
    Sleep,
    /// `$C`: check mode on or off.
    Check,
}

/// Why a `$` line was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DollarError {
    Syntax,
    Unknown,
    BadValue,
}

impl DollarError {
    /// grbl's code (as the real grbl-Mega answers): 2 ("bad number
    /// format") for a `$` line it cannot read, 3 ("invalid statement") for
    /// a setting it does not have, 20 for a bad value.
    pub fn grbl_code(self) -> u8 {
        match self {
            DollarError::Syntax => 2,
            DollarError::Unknown => crate::gcode::interp::grbl::BAD_STATEMENT,
            DollarError::BadValue => 20,
        }
    }

    pub fn message(self) -> FStr {
        match self {
            DollarError::Syntax => F!("$ command: use $$, $<n>=<value>, $H[XYZ], $X, $G, $#, $I[=], $J=, $N[0|1=], $C, $RST=$|#|*, $SLP"),
            DollarError::Unknown => F!("$ command: no such setting (see $$)"),
            DollarError::BadValue => F!("$ command: value out of range, nothing changed"),
        }
    }
}

/// Parse a line that starts with `$`. A comment after the command (`$I ;
/// build info`, `$$ (settings)`, as Inkscape's gcodetools writes for grbl)
/// is ignored.
pub fn parse(line: &[u8]) -> Result<Command, DollarError> {
    let rest = line.strip_prefix(b"$").ok_or(DollarError::Syntax)?;
    let code = rest.iter().position(|&b| b == b';' || b == b'(').map_or(rest, |i| &rest[..i]);
    let trimmed = trim(code);
    match trimmed {
        b"$" => return Ok(Command::List),
        b"H" | b"h" => return Ok(Command::Home),
        b"X" | b"x" => return Ok(Command::Unlock),
        b"G" | b"g" => return Ok(Command::Modes),
        b"#" => return Ok(Command::Params),
        [b'J' | b'j', b'=', ..] => return Ok(Command::Jog),
        [b'I' | b'i', b'=', ..] => return Ok(Command::InfoSet),
        [b'N' | b'n'] => return Ok(Command::StartupList),
        [b'N' | b'n', d @ b'0'..=b'9', b'=', ..] => return Ok(Command::StartupSet(d - b'0')),
        [b'H' | b'h', a] => {
            return match a | 0x20 {
                b'x' => Ok(Command::HomeAxis(1)),
                b'y' => Ok(Command::HomeAxis(2)),
                b'z' => Ok(Command::HomeAxis(4)),
                _ => Err(DollarError::Syntax),
            }
        }
        [b'S' | b's', b'L' | b'l', b'P' | b'p'] => return Ok(Command::Sleep),
        [b'C' | b'c'] => return Ok(Command::Check),
        [b'R' | b'r', b'S' | b's', b'T' | b't', b'=', w] if matches!(w, b'$' | b'#' | b'*') => return Ok(Command::Restore(*w)),
        b"I" | b"i" => return Ok(Command::Info),
        _ => {}
    }
    let eq = trimmed.iter().position(|&b| b == b'=').ok_or(DollarError::Syntax)?;
    let (num, val) = (trim(&trimmed[..eq]), trim(&trimmed[eq + 1..]));
    if num.is_empty() || num.len() > 3 || !num.iter().all(u8::is_ascii_digit) {
        return Err(DollarError::Syntax);
    }
    let n = num.iter().fold(0u16, |a, &d| a * 10 + (d - b'0') as u16);
    let n = u8::try_from(n).map_err(|_| DollarError::Unknown)?;
    let v = parse_value(val).ok_or(DollarError::BadValue)?;
    Ok(Command::Set(n, v))
}

fn trim(b: &[u8]) -> &[u8] {
    let start = b.iter().position(|c| !c.is_ascii_whitespace()).unwrap_or(b.len());
    let end = b.iter().rposition(|c| !c.is_ascii_whitespace()).map_or(start, |e| e + 1);
    &b[start..end]
}

/// A plain decimal (sign, digits, one point, at most 7 significant digits).
fn parse_value(b: &[u8]) -> Option<f32> {
    let (neg, digits) = match b.first()? {
        b'-' => (true, &b[1..]),
        b'+' => (false, &b[1..]),
        _ => (false, b),
    };
    let (mut int, mut frac, mut scale, mut seen_point, mut n) = (0u32, 0u32, 1u32, false, 0);
    for &c in digits {
        match c {
            b'.' if !seen_point => seen_point = true,
            b'0'..=b'9' => {
                n += 1;
                if n > 9 {
                    return None;
                }
                let d = (c - b'0') as u32;
                if seen_point {
                    frac = frac * 10 + d;
                    scale *= 10;
                } else {
                    int = int * 10 + d;
                }
            }
            _ => return None,
        }
    }
    if n == 0 {
        return None;
    }
    let v = int as f32 + frac as f32 / scale as f32;
    Some(if neg { -v } else { v })
}

/// Set setting `n` of `s` to `v`. The caller checks `s.is_sane()` after.
pub fn set(s: &mut Settings, n: u8, v: f32) -> Result<(), DollarError> {
    let f = field(s, n).ok_or(DollarError::Unknown)?;
    match f {
        Field::Num(x) => *x = v,
        Field::Flag(x) => {
            *x = match v {
                0.0 => false,
                1.0 => true,
                _ => return Err(DollarError::BadValue),
            }
        }
        Field::Mask(x, max) => {
            if !(0.0..=max as f32).contains(&v) || v != (v as u8) as f32 {
                return Err(DollarError::BadValue);
            }
            *x = v as u8;
        }
    }
    Ok(())
}

/// `$$`: every setting, one `$<n>=<value> (<meaning>)` line each.
pub fn list(s: &Settings, w: &mut impl uWrite) {
    for i in 0..count() {
        let n = nth(i);
        if let Some((v, what)) = value(s, n) {
            uwrite!(w, "${}=", n).ok();
            match v {
                Value::Num(x) => uwrite!(w, "{}", Micros::from_mm(x)),
                Value::Flag(x) => uwrite!(w, "{}", x as u8),
                Value::Mask(x, _) => uwrite!(w, "{}", x),
            }
            .ok();
            uwriteln!(w, " ({})", what).ok();
        }
    }
}

/// `$G`: grbl 1.1's modal-state line.
pub fn modes(i: &crate::gcode::interp::Interp, tool: u8, w: &mut impl uWrite) {
    use crate::gcode::parse::{Motion, Plane};
    // Every text through F!: a plain `&str` from a match is a RAM copy on AVR.
    let motion = match i.motion {
        Motion::Rapid => F!("G0"),
        Motion::Linear => F!("G1"),
        Motion::ArcCw => F!("G2"),
        Motion::ArcCcw => F!("G3"),
        Motion::ProbeToward => F!("G38.2"),
        Motion::ProbeTowardNoError => F!("G38.3"),
        Motion::Cancel => F!("G80"),
        Motion::Cycle(k) => {
            use crate::gcode::cycles::Kind;
            match k {
                Kind::Drill => F!("G81"),
                Kind::DrillDwell => F!("G82"),
                Kind::Peck => F!("G83"),
                Kind::ChipBreak => F!("G73"),
                Kind::Bore => F!("G85"),
                Kind::BoreDwell => F!("G89"),
            }
        }
    };
    let plane = match i.plane {
        Plane::Xy => 17u8,
        Plane::Zx => 18,
        Plane::Yz => 19,
    };
    let units = if i.inches { 20u8 } else { 21 };
    let dist = if i.incremental { 91u8 } else { 90 };
    let spindle = if i.spindle_on { 3u8 } else { 5 };
    // F in the current units per minute, S in rpm, whole numbers.
    let feed = if i.inches { i.feed_mm_per_min / 25.4 } else { i.feed_mm_per_min };
    uwrite!(w, "{}{} G{} G{} G{} G{}", F!("[GC:"), motion, 54 + i.wcs, plane, units, dist).ok();
    uwriteln!(
        w,
        "{}{}{}{}{}{}{}{}{}{}]",
        F!(" G94 M"),
        spindle,
        F!(" M"),
        i.coolant_m,
        F!(" T"),
        tool,
        F!(" F"),
        crate::math::round_i32(feed),
        F!(" S"),
        crate::math::round_i32(i.spindle_rpm)
    )
    .ok();
}

/// `$#`: grbl 1.1's offset lines (work offsets in machine mm), in the
/// user frame (+Z up, `crate::frame`).
/// With `inches` (`$13=1`) every value in inches, as grbl.
pub fn params(i: &crate::gcode::interp::Interp, inches: bool, w: &mut impl uWrite) {
    use crate::frame::{axis_user_from_internal, user_from_internal, Z};
    for (n, v) in i.wcs_mm.iter().enumerate() {
        uwrite!(w, "{}{}:", F!("[G5"), 4 + n as u8).ok();
        xyz(w, user_from_internal(*v), inches);
    }
    uwrite!(w, "{}", F!("[G28:")).ok();
    xyz(w, [0.0; 3], inches);
    uwrite!(w, "{}", F!("[G30:")).ok();
    xyz(w, [0.0; 3], inches);
    uwrite!(w, "{}", F!("[G92:")).ok();
    xyz(w, user_from_internal(i.g92_mm), inches);
    uwrite!(w, "{}", F!("[TLO:")).ok();
    coord(w, axis_user_from_internal(Z, i.tlo_mm), inches);
    uwriteln!(w, "]").ok();
    uwrite!(w, "{}", F!("[PRB:")).ok();
    coords(w, &[0.0; 3], inches);
    uwriteln!(w, ":0]").ok();
}

/// `x,y,z]` and the line end.
fn xyz(w: &mut impl uWrite, v: [f32; 3], inches: bool) {
    coords(w, &v, inches);
    uwriteln!(w, "]").ok();
}

/// `x,y,z` as grbl reports coordinates: mm with three decimals, or with
/// `inches` (`$13=1`) inches with four.
pub fn coords(w: &mut impl uWrite, v: &[f32], inches: bool) {
    for (a, &x) in v.iter().take(3).enumerate() {
        if a > 0 {
            uwrite!(w, ",").ok();
        }
        coord(w, x, inches);
    }
}

/// One coordinate of [`coords`].
fn coord(w: &mut impl uWrite, mm: f32, inches: bool) {
    if inches {
        // Ten-thousandths of an inch, printed as thousandths with one more
        // digit: the value ×10 000 is an integer, so Micros of it / 10.
        let t = crate::math::round_i32(mm * (10_000.0 / 25.4));
        let m = Micros(t / 10);
        let d = t.unsigned_abs() % 10;
        if t < 0 && t / 10 == 0 {
            uwrite!(w, "-").ok();
        }
        uwrite!(w, "{}{}", m, d as u8).ok();
    } else {
        uwrite!(w, "{}", Micros::from_mm(mm)).ok();
    }
}

/// `$I`: grbl 1.1's build info lines (options: V variable spindle, N line
/// numbers, H single-axis homing; 16-block planner, 255-byte RX ring).
/// `user`: the text stored with `$I=`.
pub fn info(w: &mut impl uWrite, user: &str) {
    uwriteln!(w, "{}{}:{}]", F!("[VER:1.1h.MillFW:"), crate::FIRMWARE_VERSION, user).ok();
    uwriteln!(w, "{}", F!("[OPT:VNH,15,255]")).ok();
}

#[cfg(test)]
mod tests {
    use super::*;

    struct S(String);
    impl uWrite for S {
        type Error = ();
        fn write_str(&mut self, s: &str) -> Result<(), ()> {
            self.0.push_str(s);
            Ok(())
        }
    }

    #[test]
    fn dollar_dollar_prints_grbl_lines_with_the_values() {
        let mut out = S(String::new());
        let mut s = Settings::DEFAULT;
        s.steps_per_mm[0] = 80.0;
        s.hard_limits = false;
        list(&s, &mut out);
        let lines: Vec<&str> = out.0.lines().collect();
        assert_eq!(lines.len(), 53);
        assert!(lines.contains(&"$10=1 (status report: bit 0 MPos (else WPos), bit 1 Bf)"), "{lines:?}");
        assert!(lines.contains(&"$13=0 (report positions and feeds in inches (? and $#), 0/1)"), "{lines:?}");
        assert!(lines.contains(&"$153=0 (G4 P in milliseconds (Mach3, UCCNC, Marlin), 0/1)"), "{lines:?}");
        assert!(lines.contains(&"$154=1 (G80 keeps the motion mode from before the cycle (Fanuc, Mach3), 0/1)"), "{lines:?}");
        assert!(lines.contains(&"$151=0 (T alone changes the tool at once (Repetier), 0/1)"), "{lines:?}");
        assert!(lines.contains(&"$152=0 (optional stop: M1 pauses, 0/1)"), "{lines:?}");
        assert!(lines.contains(&"$160=2.000 (card pulled mid-job: retract Z to this far below its home switch, mm)"), "{lines:?}");
        assert!(lines.contains(&"$100=80.000 (steps/mm (E: steps/pocket))"), "{lines:?}");
        assert!(lines.contains(&"$21=0 (hard limits, 0/1)"));
        assert!(lines.contains(&"$130=45.000 (max travel, mm)"));
    }

    #[test]
    fn commands_parse_and_nonsense_is_refused() {
        assert_eq!(parse(b"$$"), Ok(Command::List));
        assert_eq!(parse(b"$H"), Ok(Command::Home));
        assert_eq!(parse(b"$x"), Ok(Command::Unlock));
        assert_eq!(parse(b"$J=G91 X1 F100"), Ok(Command::Jog));
        assert_eq!(parse(b"$RST=*"), Ok(Command::Restore(b'*')));
        assert_eq!(parse(b"$RST=$"), Ok(Command::Restore(b'$')));
        assert_eq!(parse(b"$RST=#"), Ok(Command::Restore(b'#')));
        assert_eq!(parse(b"$RST=x"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$N"), Ok(Command::StartupList));
        assert_eq!(parse(b"$N1=G21 G90"), Ok(Command::StartupSet(1)));
        assert_eq!(parse(b"$I=shop"), Ok(Command::InfoSet));
        assert_eq!(parse(b"$hy"), Ok(Command::HomeAxis(2)));
        assert_eq!(parse(b"$HQ"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$SLP"), Ok(Command::Sleep));
        assert_eq!(parse(b"$c"), Ok(Command::Check));
        assert_eq!(parse(b"$G"), Ok(Command::Modes));
        assert_eq!(parse(b"$#"), Ok(Command::Params));
        assert_eq!(parse(b"$I"), Ok(Command::Info));
        assert_eq!(parse(b"$100=80"), Ok(Command::Set(100, 80.0)));
        assert_eq!(parse(b"$ 11 = 0.02 "), Ok(Command::Set(11, 0.02)));
        assert_eq!(parse(b"$140=-1.5"), Ok(Command::Set(140, -1.5)));
        assert_eq!(parse(b"$"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$100"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$A=1"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$1000=1"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$300=1"), Err(DollarError::Unknown));
        assert_eq!(parse(b"$100="), Err(DollarError::BadValue));
        assert_eq!(parse(b"$100=1e99"), Err(DollarError::BadValue));
        assert_eq!(parse(b"$100=1.2.3"), Err(DollarError::BadValue));
        assert_eq!(parse(b"$100=1234567890"), Err(DollarError::BadValue));
    }

    #[test]
    fn a_comment_after_a_dollar_command_is_ignored() {
        assert_eq!(parse(b"$I ; build info"), Ok(Command::Info));
        assert_eq!(parse(b"$$ ; settings"), Ok(Command::List));
        assert_eq!(parse(b"$G(modal state)"), Ok(Command::Modes));
        assert_eq!(parse(b"$110=4000 ; X max rate"), Ok(Command::Set(110, 4000.0)));
        assert_eq!(parse(b"$ ; nothing"), Err(DollarError::Syntax));
        assert_eq!(parse(b"$110=abc ; nonsense"), Err(DollarError::BadValue));
    }

    #[test]
    fn dollar_g_hash_and_i_answer_in_grbl_1_1_formats() {
        let mut i = crate::gcode::interp::Interp::new();
        let mut out = S(String::new());
        modes(&i, 0, &mut out);
        assert_eq!(out.0, "[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\n");
        i.motion = crate::gcode::parse::Motion::Linear;
        i.wcs = 1;
        i.incremental = true;
        i.spindle_on = true;
        i.spindle_rpm = 8000.0;
        i.feed_mm_per_min = 600.0;
        let mut out = S(String::new());
        modes(&i, 3, &mut out);
        assert_eq!(out.0, "[GC:G1 G55 G17 G21 G91 G94 M3 M9 T3 F600 S8000]\n");
        i.coolant_m = 8;
        let mut out = S(String::new());
        modes(&i, 3, &mut out);
        assert_eq!(out.0, "[GC:G1 G55 G17 G21 G91 G94 M3 M8 T3 F600 S8000]\n");
        i.coolant_m = 9;
        i.wcs_mm[0] = [1.5, -2.0, 0.25];
        i.g92_mm = [0.0, 1.0, 0.0];
        i.tlo_mm = -19.5;
        let mut out = S(String::new());
        params(&i, false, &mut out);
        let l: Vec<&str> = out.0.lines().collect();
        assert_eq!(l.len(), 11);
        // Internal Z grows downward; reports are +Z up (crate::frame).
        assert_eq!(l[0], "[G54:1.500,-2.000,-0.250]");
        assert_eq!(l[5], "[G59:0.000,0.000,0.000]");
        assert_eq!(l[6], "[G28:0.000,0.000,0.000]");
        assert_eq!(l[7], "[G30:0.000,0.000,0.000]");
        assert_eq!(l[8], "[G92:0.000,1.000,0.000]");
        assert_eq!(l[9], "[TLO:19.500]");
        assert_eq!(l[10], "[PRB:0.000,0.000,0.000:0]");
        // `$13=1`: inches with four decimals (grbl's).
        let mut out = S(String::new());
        params(&i, true, &mut out);
        let l: Vec<&str> = out.0.lines().collect();
        assert_eq!(l[0], "[G54:0.0591,-0.0787,-0.0098]");
        assert_eq!(l[9], "[TLO:0.7677]");
        assert_eq!(l[10], "[PRB:0.0000,0.0000,0.0000:0]");
        let mut out = S(String::new());
        info(&mut out, "shop mill 2");
        let l: Vec<&str> = out.0.lines().collect();
        assert!(l[0].starts_with("[VER:1.1h.MillFW:") && l[0].ends_with(":shop mill 2]"), "{l:?}");
        assert_eq!(l[1], "[OPT:VNH,15,255]");
    }

    #[test]
    fn set_checks_the_kind_of_each_setting() {
        let mut s = Settings::DEFAULT;
        set(&mut s, 101, 400.0).unwrap();
        assert_eq!(s.steps_per_mm[1], 400.0);
        set(&mut s, 20, 0.0).unwrap();
        assert!(!s.soft_limits);
        assert_eq!(set(&mut s, 20, 2.0), Err(DollarError::BadValue));
        set(&mut s, 3, 5.0).unwrap();
        assert_eq!(s.invert_dir_mask, 5);
        assert_eq!(set(&mut s, 3, 16.0), Err(DollarError::BadValue));
        assert_eq!(set(&mut s, 3, 1.5), Err(DollarError::BadValue));
        assert_eq!(set(&mut s, 99, 1.0), Err(DollarError::Unknown));
        // A value of the right kind but insane is caught by is_sane.
        set(&mut s, 100, -5.0).unwrap();
        assert!(!s.is_sane());
    }
}
