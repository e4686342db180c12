//! G-code interpreter (SPEC §5): modal state and the meaning of each code.
//!
//! Sits between [`super::parse`] and the planner. It owns the modal state
//! (units, distance mode, plane, work offsets, tool length offset, feed) and
//! the commanded position in machine millimetres, turns each parsed [`Line`]
//! into planner moves (absolute integer step targets, rounded from absolute
//! mm so rounding never accumulates) and runs the M-codes.
//!
//! Everything it keeps is in the internal frame (Z counts down from the top
//! switch); G-code words come in, and reports go out, in the user's frame
//! (+Z up) through [`crate::frame`]: [`word_mm`] for every axis word,
//! [`Interp::work_user`] and `frame::user_from_internal` for every report.
//!
//! A line is validated completely before anything on it runs: a bad word,
//! a missing feed or a target outside travel returns an [`Error`] and leaves
//! the machine exactly as it was.

use crate::flash::FStr;
use super::cycles::{self, Retract};
use super::{Coolant, Distance, Line, Motion, NonModal, Plane, Spindle, Stopping, ToolLength, Units, Word};
use crate::config::{Settings, N_WCS};
use crate::fixed::Micros;
use crate::frame;
use crate::machine::{Alarm, Io, Machine, State};
use crate::math::round_i32;
use crate::planner::arc::{self, ArcError};
use crate::N_AXES;
use ufmt::{uwrite, uwriteln};

/// Millimetres per inch.
const MM_PER_INCH: f32 = 25.4;
/// `v` in mm: × 25.4 under G20. The multiply is a call only made under
/// G20: LLVM-AVR turned `if inches { v * 25.4 } else { v }` into a select
/// that multiplied every axis word (~145 cycles each) in millimetres too.
#[inline]
fn to_mm(inches: bool, v: f32) -> f32 {
    if inches {
        inch_to_mm(v)
    } else {
        v
    }
}

/// An axis word's value (`axis` 0 X, 1 Y, 2 Z) in internal mm: inches
/// converted, Z mirrored from the user's +Z up into the internal frame
/// (see [`crate::frame`]). Offsets, G92, G53 and increments all follow.
#[inline]
fn word_mm(inches: bool, axis: usize, v: f32) -> f32 {
    frame::axis_internal_from_user(axis, to_mm(inches, v))
}

/// `v` × 25.4, as a call (see [`to_mm`]).
#[inline(never)]
fn inch_to_mm(v: f32) -> f32 {
    v * MM_PER_INCH
}

/// Number of tool table entries, T0..T12.
pub const N_TOOLS: usize = 13;

/// Interpreter errors, printed as `Error:<message>`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Error {
    /// The line did not parse.
    Parse(super::ParseError),
    /// The machine is in alarm; motion refused.
    Alarm,
    /// Feed rate missing, zero or negative.
    BadFeed,
    /// A target outside the travel (soft limits).
    SoftLimit,
    /// M4: the DC spindle turns one way only.
    SpindleCcw,
    /// Arc with no solution or inconsistent centre.
    Arc(ArcError),
    /// A word needed by the code is missing or out of range.
    BadWord(FStr),
    /// A code this build does not provide yet.
    NotAvailable(FStr),
    /// Homing failed (alarm raised).
    HomingFailed,
    /// Motion before homing or unlocking (homing lock, `$22`).
    NotHomed,
    /// G38.2 did not trip.
    ProbeFailed,
    /// The probe input was already triggered at the start.
    ProbeAlreadyTriggered,
    /// Tool changer or carousel (T, M6, M61, G201–G205).
    Atc(crate::atc::Fault),
    /// Tool setter (G37).
    Setter(crate::toolsetter::Fault),
    /// The line was cut short by an abort (SD job, menu).
    Aborted,
    /// An SD job is running: serial lines may only ask for status.
    JobRunning,
    /// An SD card error (message in flash).
    Sd(crate::ui::text::Text),
}

impl Error {
    /// Text printed after `Error:`.
    pub fn message(&self) -> FStr {
        match self {
            Error::Parse(p) => p.kind.message(),
            Error::Alarm => F!("alarm"),
            Error::BadFeed => F!("feed rate missing or not positive (F)"),
            Error::SoftLimit => F!("target outside travel (soft limit), nothing moved"),
            Error::SpindleCcw => F!("M4 not supported: the spindle turns one way only"),
            Error::Arc(e) => e.message(),
            Error::BadWord(m) => *m,
            Error::NotAvailable(m) => *m,
            Error::NotHomed => F!("not homed: home (G28) or unlock (M999) first, nothing moved"),
            Error::HomingFailed => F!("homing failed: switch not found"),
            Error::ProbeFailed => F!("probe failed: input did not trip"),
            Error::ProbeAlreadyTriggered => F!("probe input already triggered, nothing moved"),
            Error::Atc(f) => f.message(),
            Error::Setter(f) => f.message(),
            Error::Aborted => F!("aborted"),
            Error::JobRunning => F!("SD job running: command refused (status only: ?, M27, M114)"),
            Error::Sd(_) => F!("SD card error"),
        }
    }
}

/// Modal state and commanded position.
pub struct Interp {
    /// G20 active.
    pub inches: bool,
    /// G91 active.
    pub incremental: bool,
    /// Arc plane.
    pub plane: Plane,
    /// G90.1 active: I/J/K are absolute centre coordinates (G91.1, the
    /// default: offsets from the start).
    pub arc_absolute: bool,
    /// Modal motion (G0/G1/G2/G3/G80, a canned cycle).
    pub motion: Motion,
    /// Canned cycle return level (G98/G99, NGC group 10).
    pub retract: Retract,
    /// The canned cycle words kept from line to line (R, Z, Q, P, the
    /// initial level); meaningful while `motion` is a cycle.
    pub cycle: cycles::Sticky,
    /// Programmed feed, mm/min (0 = none yet).
    pub feed_mm_per_min: f32,
    /// Feed override, percent (M220).
    pub feed_override_pct: u16,
    /// Spindle speed, rpm (S), and whether it is on.
    pub spindle_rpm: f32,
    pub spindle_on: bool,
    /// Coolant as its M code: 7 (mist) or 8 (flood) on, 9 off (one output).
    pub coolant_m: u8,
    /// Active work coordinate system, 0 = G54.
    pub wcs: u8,
    /// Work offsets G54..G59, machine mm (internal frame: the user's
    /// `G10 L2 P1 Z-5` is stored as Z 5; see [`crate::frame`]).
    pub wcs_mm: [[f32; 3]; N_WCS],
    /// G92 offset, mm (internal frame).
    pub g92_mm: [f32; 3],
    /// Tool length offset applied to Z, mm, internal frame: −length (the
    /// user sees +length, LinuxCNC's G43; the tool table and the tool in
    /// the spindle live in `atc`).
    pub tlo_mm: f32,
    /// Commanded position, internal machine mm (E in carousel units).
    pub pos_mm: [f32; N_AXES],
    /// Per axis, the last mm → steps conversion: (bits of the mm value,
    /// steps). Valid while `conv_fresh`. See [`Interp::steps_of`].
    steps_cache: [(u32, i32); N_AXES],
    /// The travel of X, Y, Z in steps, rounded. Valid while `conv_fresh`.
    travel_steps: [i32; 3],
    /// The two caches above match the settings; cleared by
    /// [`Interp::settings_changed`].
    conv_fresh: bool,
    /// (bits of the programmed feed, override %, the feed with the override,
    /// mm/min). See [`Interp::feed_with_override`].
    feed_cache: (u32, u16, f32),
}

impl Interp {
    /// Power-up modal state: G21 G90 G17 G54 G49 G0 (grbl's G0: a bare
    /// axis word before any motion code is a rapid; LinuxCNC starts in G80
    /// and refuses it) G98, feed unset.
    pub const fn new() -> Interp {
        Interp {
            inches: false,
            incremental: false,
            plane: Plane::Xy,
            arc_absolute: false,
            motion: Motion::Rapid,
            retract: Retract::Initial,
            cycle: cycles::Sticky::NONE,
            feed_mm_per_min: 0.0,
            feed_override_pct: 100,
            spindle_rpm: 0.0,
            spindle_on: false,
            coolant_m: 9,
            wcs: 0,
            wcs_mm: [[0.0; 3]; N_WCS],
            g92_mm: [0.0; 3],
            tlo_mm: 0.0,
            pos_mm: [0.0; N_AXES],
            steps_cache: [(0, 0); N_AXES],
            travel_steps: [0; 3],
            conv_fresh: false,
            feed_cache: (0, 0, 0.0),
        }
    }

    /// Absolute mm → absolute steps, rounded per axis (no accumulated
    /// error). An axis whose mm value is that of its last conversion reuses
    /// the result (a float multiply and a rounding, ~330 cycles on the AVR;
    /// a streamed XY move leaves Z and E where they were).
    pub fn steps_of(&mut self, s: &Settings, mm: &[f32; N_AXES]) -> [i32; N_AXES] {
        if !self.conv_fresh {
            self.refresh_conv(s);
        }
        let mut st = [0i32; N_AXES];
        for a in 0..N_AXES {
            let c = &mut self.steps_cache[a];
            if c.0 != mm[a].to_bits() {
                *c = (mm[a].to_bits(), to_steps(mm[a], s.steps_per_mm[a]));
            }
            st[a] = c.1;
        }
        st
    }

    /// The settings changed: the step conversions are made afresh.
    pub fn settings_changed(&mut self) {
        self.conv_fresh = false;
    }

    /// Empty the steps cache (an all-ones pattern is a NaN, never a
    /// position) and convert the travel.
    #[inline(never)]
    fn refresh_conv(&mut self, s: &Settings) {
        for c in self.steps_cache.iter_mut() {
            c.0 = u32::MAX;
        }
        for a in 0..3 {
            self.travel_steps[a] = to_steps(s.travel_mm[a], s.steps_per_mm[a]);
        }
        self.conv_fresh = true;
    }

    /// The programmed feed with the override applied, mm/min (cached: both
    /// rarely change between lines).
    fn feed_with_override(&mut self) -> f32 {
        let key = (self.feed_mm_per_min.to_bits(), self.feed_override_pct);
        if (self.feed_cache.0, self.feed_cache.1) != key {
            let f = self.feed_mm_per_min * self.feed_override_pct as f32 * 0.01;
            self.feed_cache = (key.0, key.1, f);
        }
        self.feed_cache.2
    }

    /// Take the persistent parts (work offsets) from the settings.
    pub fn load_settings(&mut self, s: &Settings) {
        self.wcs_mm = s.wcs_mm;
    }

    /// Put the persistent parts back into the settings (before M500).
    pub fn store_settings(&self, s: &mut Settings) {
        s.wcs_mm = self.wcs_mm;
    }

    /// Reset the commanded position to where the steppers are.
    pub fn sync_position(&mut self, s: &Settings, steps: [i32; N_AXES]) {
        for a in 0..N_AXES {
            self.pos_mm[a] = steps[a] as f32 / s.steps_per_mm[a];
        }
    }

    /// Sum of the offsets between machine and work coordinates, per axis.
    fn offset(&self, axis: usize) -> f32 {
        let tlo = if axis == 2 { self.tlo_mm } else { 0.0 };
        self.wcs_mm[self.wcs as usize][axis] + self.g92_mm[axis] + tlo
    }

    /// Machine mm → work mm (X, Y, Z; E unchanged), both internal.
    pub fn machine_to_work(&self, m: [f32; N_AXES]) -> [f32; N_AXES] {
        let mut w = m;
        for a in 0..3 {
            w[a] = m[a] - self.offset(a);
        }
        w
    }

    /// Internal machine mm → the user's work coordinates (+Z up), for
    /// reports (M114, `?`, `[PRB:…]`, the OLED).
    pub fn work_user(&self, m: [f32; N_AXES]) -> [f32; N_AXES] {
        frame::user_from_internal(self.machine_to_work(m))
    }

    /// Programmed feed with override, and spindle rpm (0 when off).
    pub fn feed_and_speed(&self) -> (f32, f32) {
        let rpm = if self.spindle_on { self.spindle_rpm } else { 0.0 };
        (self.feed_mm_per_min * self.feed_override_pct as f32 / 100.0, rpm)
    }
}

impl Default for Interp {
    fn default() -> Self {
        Interp::new()
    }
}

const AXIS_WORDS: [Word; 3] = [Word::X, Word::Y, Word::Z];

/// True when a line carries any of X, Y, Z.
fn has_axis_words(l: &Line) -> bool {
    l.words.has_xyz()
}

/// True when the line's X, Y, Z words are the arguments of its M code
/// (M92, M201, M203: per-axis settings), not a move.
fn axis_words_are_settings(l: &Line) -> bool {
    matches!(l.other_m, Some(92 | 201 | 203))
}

/// Execute one parsed line (RS274/NGC order of execution).
///
/// The work is split over small non-inlined steps on purpose: AVR loads and
/// stores reach only 63 bytes into a stack frame, and in one function with
/// all of this inlined (a 445-byte frame) every access beyond that cost
/// 10 extra bytes of code (about 6 KB in all).
///
/// Not for flash alone: with the 248 KiB budget (issue 11) they were measured
/// again, in simavr on the real ELF (a G1 line sent to its `ok`, 60 lines;
/// the stack high-water of the demo job). Inlining all eleven steps here
/// (`execute` … `finish_line`, the arc helpers) cost +4 176 B of flash,
/// +117 B of stack and +716 cycles per G1 line (55 613 against 54 897);
/// the four arc helpers alone +1 760 B for no arc speed-up; `parse_into`
/// inlined +123 B of stack and +280 cycles per line. All are kept.
#[inline(never)]
pub fn execute(m: &mut Machine, l: &Line, text: &[u8], io: &mut impl Io) -> Result<(), Error> {
    if let Some(done) = execute_early(m, l, io) {
        return done;
    }
    // Work on a copy of the modal state; commit only when the line is valid.
    let mut g = ModalCopy::from(&m.interp);
    modal_words(m, l, &mut g)?;
    if l.non_modal.is_some() {
        if let Some(done) = non_modal(m, &g, l, io) {
            return done;
        }
    }
    motion_line(m, &g, l, text, io)
}

/// The checks and commands before the modal state: the SD-job filter, the
/// codes that work in any state, the alarm and interrupted-change locks and
/// the validation of words that need no modal state. `Some` ends the line.
#[inline(never)]
fn execute_early(m: &mut Machine, l: &Line, io: &mut impl Io) -> Option<Result<(), Error>> {
    // During an SD job the serial line may only ask for status (SPEC §9).
    if m.sd_job && !m.in_job_line() {
        let status_only = l.motion.is_none()
            && !has_axis_words(l)
            && l.non_modal.is_none()
            && l.spindle.is_none()
            && l.coolant.is_none()
            && !l.tool_change
            && l.stopping.is_none()
            && matches!(l.other_m, Some(114 | 115 | 119 | 220 | 503));
        if !status_only {
            return Some(Err(Error::JobRunning));
        }
    }
    // Commands that work in any state first.
    if let Some(code) = l.other_m {
        match code {
            115 => {
                m.firmware_line(io);
                return Some(Ok(()));
            }
            114 => {
                report_position(m, io);
                return Some(Ok(()));
            }
            105 => {
                // Senders (printcore, Pronterface, OctoPrint) poll M105 for
                // temperatures; a mill has no heaters, so it reports none
                // rather than an error every few seconds.
                uwriteln!(io, "T:0.0 /0.0").ok();
                return Some(Ok(()));
            }
            119 => {
                report_switches(m, io);
                return Some(Ok(()));
            }
            503 => {
                report_settings(m, io);
                return Some(Ok(()));
            }
            61 => return Some(crate::atc::run::m61(m, io, l)),
            999 => {
                m.clear_alarm(io);
                uwriteln!(io, "{}", F!("echo:alarm cleared; position unknown until homed (G28)")).ok();
                return Some(Ok(()));
            }
            110 => return Some(Ok(())), // handled by the line checker
            112 => {
                // The RX interrupt's scanner has usually raised it already.
                if m.alarm != Some(Alarm::EmergencyStop) {
                    m.raise(io, Alarm::EmergencyStop);
                }
                return Some(Ok(()));
            }
            _ => {}
        }
    }
    let moves = l.motion.is_some()
        || has_axis_words(l)
        || l.words.contains(Word::E)
        || l.non_modal.is_some()
        || l.spindle == Some(Spindle::Cw)
        || matches!(l.coolant, Some(Coolant::Mist | Coolant::Flood))
        || l.tool_change
        || l.words.contains(Word::T)
        || l.other_m.is_some()
        || l.stopping.is_some();
    if l.non_modal == Some(NonModal::AuxReport) {
        crate::atc::carousel::report(m, io);
        return Some(Ok(()));
    }
    let harmless = matches!(l.other_m, Some(500..=502) | Some(17) | Some(18) | Some(84)) || l.spindle == Some(Spindle::Off);
    if m.alarm.is_some() && moves {
        let homing_allowed = l.non_modal == Some(NonModal::Home) && m.alarm != Some(Alarm::EmergencyStop);
        if !homing_allowed && !harmless {
            return Some(Err(Error::Alarm));
        }
    }
    // After an interrupted tool change nothing moves until M61 confirms the spindle.
    if m.atc.interrupted.is_some() && moves && !harmless {
        return Some(Err(Error::Atc(crate::atc::Fault::Interrupted)));
    }

    // ---- Validate everything before changing anything -----------------
    if l.spindle == Some(Spindle::Ccw) {
        return Some(Err(Error::SpindleCcw));
    }
    if l.tool().is_some_and(|t| t as usize >= N_TOOLS) {
        return Some(Err(Error::Atc(crate::atc::Fault::ToolRange)));
    }
    if is_tool_change(m, l) && (l.motion.is_some() || has_axis_words(l) || l.non_modal.is_some()) {
        return Some(Err(Error::Atc(crate::atc::Fault::WithMotion)));
    }
    if let Some(code) = l.other_m {
        if (20..=29).contains(&code) {
            return Some(Err(Error::NotAvailable(F!("SD card not available in this build"))));
        }
    }
    if let Some(f) = l.word(Word::F) {
        if !(f > 0.0) {
            return Some(Err(Error::BadFeed));
        }
    }
    if let Some(s) = l.word(Word::S) {
        if s < 0.0 && l.non_modal != Some(NonModal::Dwell) {
            return Some(Err(Error::BadWord(F!("S must not be negative"))));
        }
    }
    None
}

/// True when the line changes tools: M6 (with or without a T word), or,
/// with the Repetier setting `$151=1`, a T word alone. By default (NGC) a T
/// word alone only selects the tool the next M6 changes to.
fn is_tool_change(m: &Machine, l: &Line) -> bool {
    l.tool_change || (m.settings.immediate_tool_change && l.words.contains(Word::T))
}

/// The line's modal words into the copy `g` (nothing is committed yet).
#[inline(never)]
fn modal_words(m: &Machine, l: &Line, g: &mut ModalCopy) -> Result<(), Error> {
    if let Some(u) = l.units {
        g.inches = u == Units::Inch;
    }
    if let Some(d) = l.distance {
        g.incremental = d == Distance::Incremental;
    }
    if let Some(p) = l.plane {
        g.plane = p;
    }
    if let Some(a) = l.arc_absolute {
        g.arc_absolute = a;
    }
    if let Some(w) = l.wcs {
        g.wcs = w;
    }
    if let Some(f) = l.word(Word::F) {
        g.feed = to_mm(g.inches, f);
    }
    if let Some(mo) = l.motion {
        g.motion = mo;
    }
    if let Some(r) = l.retract {
        g.retract = r;
    }
    if let Some(tl) = l.tool_length {
        g.tlo = match tl {
            ToolLength::Cancel => 0.0,
            ToolLength::Apply => {
                let t = match l.word(Word::H) {
                    Some(h) => tool_index(h).ok_or(Error::BadWord(F!("H must be a tool number 0-12")))?,
                    None => m.atc.spindle() as usize,
                };
                crate::atc::tool_length_offset_mm(m.atc.length_mm(t as u8))
            }
        };
    }
    Ok(())
}

/// Non-modal codes that end the line (G4, G10, G92, G28, G37, G201–G205);
/// `None` for the others (G53), which go on to the motion.
#[inline(never)]
fn non_modal(m: &mut Machine, g: &ModalCopy, l: &Line, io: &mut impl Io) -> Option<Result<(), Error>> {
    Some(match l.non_modal {
        Some(NonModal::Dwell) => dwell(m, g, l, io),
        Some(NonModal::SetOffsets) => set_offsets(m, g, l, io).map(|_| g.commit(&mut m.interp)),
        Some(NonModal::SetPosition) => {
            let mut off = m.interp.g92_mm;
            for (a, &w) in AXIS_WORDS.iter().enumerate() {
                if let Some(v) = l.word(w) {
                    let v = word_mm(g.inches, a, v);
                    // work = machine - wcs - g92 - tlo  =>  g92 = machine - wcs - tlo - v
                    let tlo = if a == 2 { g.tlo } else { 0.0 };
                    off[a] = m.interp.pos_mm[a] - m.interp.wcs_mm[g.wcs as usize][a] - tlo - v;
                }
            }
            g.commit(&mut m.interp);
            m.interp.g92_mm = off;
            Ok(())
        }
        Some(NonModal::ClearG92) => {
            g.commit(&mut m.interp);
            m.interp.g92_mm = [0.0; 3];
            Ok(())
        }
        Some(NonModal::Home) => {
            g.commit(&mut m.interp);
            let mut mask = 0u8;
            for (a, &w) in AXIS_WORDS.iter().enumerate() {
                if l.word(w).is_some() {
                    mask |= 1 << a;
                }
            }
            if mask == 0 {
                mask = 0b111;
            }
            crate::machine::home(m, io, mask)
        }
        Some(NonModal::MeasureTool) => {
            g.commit(&mut m.interp);
            crate::toolsetter::run::g37(m, io, l)
        }
        Some(nm @ (NonModal::AuxMove | NonModal::AuxSetPosition | NonModal::AuxEnable | NonModal::AuxHome)) => {
            g.commit(&mut m.interp);
            crate::atc::carousel::command(m, io, l, nm)
        }
        _ => return None,
    })
}

/// G4: wait for the queue to drain, then dwell P or S seconds (P in
/// seconds as in RS274/NGC, grbl and LinuxCNC, and every CAM file of the
/// corpus; Marlin's P is ms: README "G4"). `busy:processing` keeps the host
/// waiting (`Machine::wait_step`).
fn dwell(m: &mut Machine, g: &ModalCopy, l: &Line, io: &mut impl Io) -> Result<(), Error> {
    let ms = match (l.word(Word::P), l.word(Word::S)) {
        (Some(s), None) | (None, Some(s)) if s >= 0.0 => s * 1000.0,
        _ => return Err(Error::BadWord(F!("G4 needs one of P<s> or S<s> (seconds), not negative"))),
    };
    g.commit(&mut m.interp);
    wait_ms(m, io, ms)
}

/// Let the queue drain, then wait `ms` milliseconds, serving realtime
/// requests and sending the keepalive (G4, the canned cycles' P).
fn wait_ms(m: &mut Machine, io: &mut impl Io, ms: f32) -> Result<(), Error> {
    m.wait_idle(io)?;
    let start = io.millis();
    while (io.millis().wrapping_sub(start) as f32) < ms {
        m.wait_step(io)?;
    }
    Ok(())
}

/// The motion part of a line: target, checks, then (through [`arc_line`]
/// for arcs) [`finish_line`].
#[inline(never)]
fn motion_line(m: &mut Machine, g: &ModalCopy, l: &Line, text: &[u8], io: &mut impl Io) -> Result<(), Error> {
    let machine_coords = l.non_modal == Some(NonModal::MachineCoords);
    let mut target = m.interp.pos_mm;
    let any_axis = has_axis_words(l) && !axis_words_are_settings(l);
    for (a, &w) in AXIS_WORDS.iter().enumerate() {
        if let Some(v) = l.word(w) {
            let v = word_mm(g.inches, a, v);
            target[a] = if machine_coords {
                v
            } else if g.incremental {
                m.interp.pos_mm[a] + v
            } else {
                work_to_machine(m, g, a, v)
            };
        }
    }
    if machine_coords && matches!(g.motion, Motion::Cycle(_)) {
        return Err(Error::BadWord(F!("G53 not allowed with a canned cycle (G80 first)")));
    }
    let motion = if machine_coords && !matches!(g.motion, Motion::Rapid | Motion::Linear) { Motion::Linear } else { g.motion };
    // E0 (the carousel) moves with G0/G1 `E`, in its own units and without
    // offsets (Repetier's E0 motor), so all four motors can move at once.
    let e_word = if axis_words_are_settings(l) { None } else { l.word(Word::E) };
    if let Some(v) = e_word {
        if !matches!(motion, Motion::Rapid | Motion::Linear) {
            return Err(Error::BadWord(F!("E only with G0/G1")));
        }
        target[3] = if g.incremental { m.interp.pos_mm[3] + v } else { v };
    }
    if let Motion::Cycle(kind) = g.motion {
        if any_axis || l.motion.is_some() {
            return cycle_line(m, g, l, text, io, kind);
        }
    }
    let mut do_motion = None;
    if any_axis || e_word.is_some() || matches!(l.motion, Some(Motion::ArcCw | Motion::ArcCcw)) {
        match motion {
            Motion::Cancel => return Err(Error::BadWord(F!("axis words without a motion mode (G80 active)"))),
            Motion::Rapid => {}
            _ => {
                if !(g.feed > 0.0) {
                    return Err(Error::BadFeed);
                }
            }
        }
        check_soft_limits(m, &target)?;
        do_motion = Some(motion);
    }
    match do_motion {
        Some(mo @ (Motion::ArcCw | Motion::ArcCcw)) => arc_line(m, g, l, text, io, &target, mo),
        _ => finish_line(m, g, l, text, io, &target, do_motion, None, None),
    }
}

/// A canned cycle resolved and checked, ready to run once the line commits.
struct CycleRun {
    cycle: cycles::Cycle,
    /// The sticky words to keep after this line.
    sticky: cycles::Sticky,
    /// Machine − work offset per axis (work offset, G92, tool length),
    /// internal frame.
    off: [f32; 3],
}

/// A line that runs a canned cycle (G73, G81–G89, or bare X/Y/Z while one
/// is modal): resolve the words against the sticky ones, check every point
/// the cycle can reach against the soft limits, then finish the line with it.
/// A bad cycle line changes nothing and moves nothing.
#[inline(never)]
fn cycle_line(m: &mut Machine, g: &ModalCopy, l: &Line, text: &[u8], io: &mut impl Io, kind: cycles::Kind) -> Result<(), Error> {
    match g.plane {
        Plane::Xy => {}
        Plane::Zx => return Err(Error::BadWord(F!("canned cycles only in the XY plane (G17); G18 (ZX) is active, nothing moved"))),
        Plane::Yz => return Err(Error::BadWord(F!("canned cycles only in the XY plane (G17); G19 (YZ) is active, nothing moved"))),
    }
    if !(g.feed > 0.0) {
        return Err(Error::BadFeed);
    }
    let mm = |w: Word| l.word(w).map(|v| to_mm(g.inches, v));
    let words = cycles::LineWords { x: mm(Word::X), y: mm(Word::Y), z: mm(Word::Z), r: mm(Word::R), q: mm(Word::Q), p: l.word(Word::P), l: l.word(Word::L) };
    let mut off = [0.0f32; 3];
    let mut pos = [0.0f32; 3];
    for a in 0..3 {
        let tlo = if a == 2 { g.tlo } else { 0.0 };
        off[a] = m.interp.wcs_mm[g.wcs as usize][a] + g.g92[a] + tlo;
        pos[a] = frame::axis_user_from_internal(a, m.interp.pos_mm[a] - off[a]);
    }
    let prev = match m.interp.motion {
        Motion::Cycle(k) => Some(k),
        _ => None,
    };
    let bad = |e: cycles::Error| Error::BadWord(e.message());
    let (params, sticky) = cycles::resolve(kind, g.retract, g.incremental, prev, &m.interp.cycle, &words, pos).map_err(bad)?;
    let cycle = cycles::Cycle::new(params, pos).map_err(bad)?;
    let run = CycleRun { cycle, sticky, off };
    let (lo, hi) = run.cycle.bounds();
    check_soft_limits(m, &cycle_target(m, &run, lo))?;
    check_soft_limits(m, &cycle_target(m, &run, hi))?;
    let target = m.interp.pos_mm;
    finish_line(m, g, l, text, io, &target, Some(g.motion), None, Some(run))
}

/// A cycle's point `t` (user frame, work coordinates; NaN: the axis stays)
/// → internal machine mm, the other axes where the tool is.
fn cycle_target(m: &Machine, run: &CycleRun, t: [f32; 3]) -> [f32; N_AXES] {
    let mut target = m.interp.pos_mm;
    for a in 0..3 {
        if !t[a].is_nan() {
            target[a] = add_nz(frame::axis_internal_from_user(a, t[a]), run.off[a]);
        }
    }
    target
}

/// Queue the cycle's moves (each through [`move_to`], as G0/G1) and wait
/// out its dwells (as G4), sending the keepalive: a cycle of many holes is
/// one long line.
#[inline(never)]
fn run_cycle(m: &mut Machine, io: &mut impl Io, run: &mut CycleRun) -> Result<(), Error> {
    while let Some(step) = run.cycle.next_step() {
        m.keepalive(io);
        let (t, rapid) = match step {
            cycles::Step::Dwell(s) => {
                wait_ms(m, io, s * 1000.0)?;
                continue;
            }
            cycles::Step::Rapid(t) => (t, true),
            cycles::Step::Feed(t) => (t, false),
        };
        // Wait for room here (two slots: a backlash take-up may come
        // first), so the keepalive goes out while the queue is full.
        while m.planner.free() < 2 {
            m.keepalive(io);
            m.wait_step(io)?;
        }
        let feed = m.interp.feed_with_override();
        move_to(m, io, cycle_target(m, run, t), feed, rapid)?;
    }
    Ok(())
}

/// Absolute work coordinate `v` (mm) of axis `a` → machine mm, with the
/// line's modal offsets (axis words under G90, I/J/K under G90.1).
fn work_to_machine(m: &Machine, g: &ModalCopy, a: usize, v: f32) -> f32 {
    let tlo = if a == 2 { g.tlo } else { 0.0 };
    add_nz(add_nz(add_nz(v, m.interp.wcs_mm[g.wcs as usize][a]), g.g92[a]), tlo)
}

/// Arcs: compute the chord plan before committing anything, then finish the
/// line with it.
#[inline(never)]
fn arc_line(m: &mut Machine, g: &ModalCopy, l: &Line, text: &[u8], io: &mut impl Io, target: &[f32; N_AXES], mo: Motion) -> Result<(), Error> {
    let (a0, a1, a2) = match g.plane {
        Plane::Xy => (0, 1, 2),
        Plane::Zx => (2, 0, 1),
        Plane::Yz => (1, 2, 0),
    };
    let off_words = [Word::I, Word::J, Word::K];
    let r = l.word(Word::R).map(|r| to_mm(g.inches, r));
    let start = [m.interp.pos_mm[0], m.interp.pos_mm[1], m.interp.pos_mm[2]];
    let mut centre_off = [0.0f32; 3];
    let mut any_off = false;
    for (a, &w) in off_words.iter().enumerate() {
        if let Some(v) = l.word(w) {
            let v = word_mm(g.inches, a, v);
            // G90.1: the word is the centre's work coordinate.
            centre_off[a] = if g.arc_absolute { work_to_machine(m, g, a, v) - start[a] } else { v };
            any_off = true;
        }
    }
    if g.arc_absolute && any_off && (l.word(off_words[a0]).is_none() || l.word(off_words[a1]).is_none()) {
        return Err(Error::BadWord(F!("arc under G90.1: give both centre coordinates of the plane")));
    }
    // An end that rounds to the start's steps in the plane is the start: a
    // full circle (arc.rs), never a sliver of an arc from float round-off.
    let mut target = *target;
    let spm = m.settings.steps_per_mm;
    if to_steps(start[a0], spm[a0]) == to_steps(target[a0], spm[a0]) && to_steps(start[a1], spm[a1]) == to_steps(target[a1], spm[a1]) {
        target[a0] = start[a0];
        target[a1] = start[a1];
    }
    let end = [target[0], target[1], target[2]];
    let spec = match (r, any_off) {
        (Some(r), false) => arc::Centre::Radius(r),
        (None, true) => arc::Centre::Offset(centre_off),
        (Some(_), true) => return Err(Error::BadWord(F!("arc: give R or I/J/K, not both"))),
        (None, false) => return Err(Error::BadWord(F!("arc needs R or I/J/K"))),
    };
    // G18 and G19 contain Z: mirrored into the internal frame, they turn the other way.
    let cw = frame::internal_clockwise(mo == Motion::ArcCw, g.plane != Plane::Xy);
    let mut plan = new_arc(start, end, spec, (a0, a1, a2), cw, m.settings.arc_tolerance_mm)?;
    check_arc_limits(m, &plan)?;
    finish_line(m, g, l, text, io, &target, Some(mo), Some(&mut plan), None)
}

/// Every chord end stays inside the arc's bounding box; check it.
#[inline(never)]
fn check_arc_limits(m: &mut Machine, plan: &arc::Arc) -> Result<(), Error> {
    let (lo, hi) = plan.bounds();
    let mut lo4 = m.interp.pos_mm;
    let mut hi4 = m.interp.pos_mm;
    lo4[..3].copy_from_slice(&lo);
    hi4[..3].copy_from_slice(&hi);
    check_soft_limits(m, &lo4)?;
    check_soft_limits(m, &hi4)
}

/// Queue the chords of `plan`, then the programmed end `target`.
#[inline(never)]
fn arc_chords(m: &mut Machine, io: &mut impl Io, plan: &mut arc::Arc, target: [f32; N_AXES], feed: f32) -> Result<(), Error> {
    while let Some(p) = next_chord(plan) {
        let mut t = target;
        t[..3].copy_from_slice(&p);
        move_to(m, io, t, feed, false)?;
    }
    move_to(m, io, target, feed, false)
}

/// The next chord end of `plan`, in a frame of its own (see [`new_arc`]).
#[inline(never)]
fn next_chord(plan: &mut arc::Arc) -> Option<[f32; 3]> {
    plan.next()
}

/// [`arc::Arc::new`] in a frame of its own (its many f32 temporaries
/// would otherwise push [`arc_line`]'s locals out of `ldd` reach).
#[inline(never)]
fn new_arc(
    start: [f32; 3],
    end: [f32; 3],
    spec: arc::Centre,
    axes: (usize, usize, usize),
    clockwise: bool,
    tolerance_mm: f32,
) -> Result<arc::Arc, Error> {
    arc::Arc::new(start, end, spec, axes, clockwise, tolerance_mm).map_err(Error::Arc)
}

/// Commit the modal state, then act: tool change, spindle, the motion (the
/// arc's chords when `arc` is given), other M codes, program stops.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn finish_line(
    m: &mut Machine,
    g: &ModalCopy,
    l: &Line,
    text: &[u8],
    io: &mut impl Io,
    target: &[f32; N_AXES],
    do_motion: Option<Motion>,
    arc: Option<&mut arc::Arc>,
    cycle: Option<CycleRun>,
) -> Result<(), Error> {
    let target = *target;
    g.commit(&mut m.interp);
    if let Some(run) = &cycle {
        m.interp.cycle = run.sticky;
    }
    if is_tool_change(m, l) {
        crate::atc::run::select(m, io, l.tool().map(u16::from))?;
    } else if let Some(t) = l.tool() {
        // NGC: T selects (pre-stages) the tool; the next M6 changes to it.
        m.atc.last_t = t;
    }
    if let Some(s) = l.word(Word::S) {
        m.interp.spindle_rpm = s;
    }
    match l.spindle {
        Some(Spindle::Cw) => {
            m.wait_idle(io)?;
            m.interp.spindle_on = true;
            io.spindle(spindle_duty(&m.settings, m.interp.spindle_rpm));
        }
        Some(Spindle::Off) => {
            m.wait_idle(io)?;
            m.interp.spindle_on = false;
            io.spindle(0);
        }
        _ => {
            if l.word(Word::S).is_some() && m.interp.spindle_on {
                m.wait_idle(io)?;
                io.spindle(spindle_duty(&m.settings, m.interp.spindle_rpm));
            }
        }
    }
    // One output for both M7 (mist) and M8 (flood), switched in step with
    // the motion like the spindle (M9 in an alarm: at once, nothing moves).
    if let Some(c) = l.coolant {
        if m.alarm.is_none() {
            m.wait_idle(io)?;
        }
        io.coolant(c != Coolant::Off);
        m.interp.coolant_m = match c {
            Coolant::Mist => 7,
            Coolant::Flood => 8,
            Coolant::Off => 9,
        };
    }

    if let Some(mo) = do_motion {
        let rapid = mo == Motion::Rapid;
        let feed = m.interp.feed_with_override();
        match mo {
            Motion::ArcCw | Motion::ArcCcw => match arc {
                Some(plan) => arc_chords(m, io, plan, target, feed)?,
                None => move_to(m, io, target, feed, false)?,
            },
            Motion::ProbeToward | Motion::ProbeTowardNoError => {
                probe(m, io, target, feed, mo == Motion::ProbeToward)?;
            }
            Motion::Cycle(_) => {
                if let Some(mut run) = cycle {
                    run_cycle(m, io, &mut run)?;
                }
            }
            _ => move_to(m, io, target, feed, rapid)?,
        }
    }

    // ---- Other M codes and program stops ----------------------------------
    if let Some(code) = l.other_m {
        other_m(m, l, code, text, io)?;
    }
    match l.stopping {
        Some(Stopping::End | Stopping::EndRewind) => {
            m.wait_idle(io)?;
            m.spindle_off(io);
            uwriteln!(io, "{}", F!("echo:program end")).ok();
        }
        // M1 pauses only with optional stop on (`$152`, Job menu).
        Some(Stopping::OptionalPause) if !m.settings.optional_stop => {}
        Some(Stopping::Pause | Stopping::OptionalPause) => {
            m.wait_idle(io)?;
            uwriteln!(io, "{}", F!("echo:paused, send ~ to resume")).ok();
            m.pause_until_resume(io)?;
        }
        None => {}
    }
    Ok(())
}

/// Jog `axis` (0..3) by `delta_mm` (user frame: +Z up) at `feed` mm/min
/// from the commanded position (the menu's jog): soft limits apply, the modal state is untouched.
#[inline(never)]
pub fn jog(m: &mut Machine, io: &mut impl Io, axis: usize, delta_mm: f32, feed: f32) -> Result<(), Error> {
    if m.alarm.is_some() {
        return Err(Error::Alarm);
    }
    let mut target = m.interp.pos_mm;
    target[axis] += frame::axis_internal_from_user(axis, delta_mm);
    check_soft_limits(m, &target)?;
    move_to(m, io, target, feed, false)
}

/// Queue a move to `target` machine mm; updates the commanded position.
#[inline(never)]
pub fn move_to(m: &mut Machine, io: &mut impl Io, target: [f32; N_AXES], feed: f32, rapid: bool) -> Result<(), Error> {
    if m.alarm.is_some() {
        return Err(Error::Alarm);
    }
    // The homing lock guards X/Y/Z; the carousel alone (G201) has its own
    // homing (G205), and an interrupted tool change is locked separately.
    let xyz_moves = (0..3).any(|a| !same_f32(target[a], m.interp.pos_mm[a]));
    if xyz_moves && !m.motion_allowed() {
        return Err(Error::NotHomed);
    }
    let steps = m.interp.steps_of(&m.settings, &target);
    m.queue_line(io, steps, feed, rapid)?;
    m.interp.pos_mm = target;
    Ok(())
}

/// `a == b` for finite floats (+0.0 equals −0.0), on the bit patterns: a
/// soft-float compare costs ~50 cycles on the AVR.
#[inline]
fn same_f32(a: f32, b: f32) -> bool {
    let (a, b) = (a.to_bits(), b.to_bits());
    a == b || (a | b) & 0x7FFF_FFFF == 0
}

/// `a + b`, without the ~90-cycle soft-float addition when `b` is +0.0 (no
/// offset): `a + 0.0 == a` for every `a` but −0.0, which the parser never
/// gives.
#[inline]
fn add_nz(a: f32, b: f32) -> f32 {
    if b.to_bits() == 0 {
        a
    } else {
        add_cold(a, b)
    }
}

/// `a + b`, as a call: LLVM-AVR would otherwise turn [`add_nz`]'s branch
/// into a select that always adds (see `math::div_cold`).
#[inline(never)]
fn add_cold(a: f32, b: f32) -> f32 {
    a + b
}

/// `round(mm · steps_per_mm)`.
#[inline(never)]
fn to_steps(mm: f32, steps_per_mm: f32) -> i32 {
    round_i32(mm * steps_per_mm)
}

/// Soft limits: the target, rounded to steps as it will be queued, must lie
/// within 0..=travel (rounded to steps) on X, Y and Z. Integer compares on
/// the steps [`Interp::steps_of`] caches for the move itself.
fn check_soft_limits(m: &mut Machine, t: &[f32; N_AXES]) -> Result<(), Error> {
    if !m.settings.soft_limits {
        return Ok(());
    }
    let st = m.interp.steps_of(&m.settings, t);
    for a in 0..3 {
        if st[a] < 0 || st[a] > m.interp.travel_steps[a] {
            return Err(Error::SoftLimit);
        }
    }
    Ok(())
}

fn spindle_duty(s: &Settings, rpm: f32) -> u8 {
    let d = rpm / s.spindle_max_rpm * 255.0;
    if d <= 0.0 {
        0
    } else if d >= 255.0 {
        255
    } else {
        let v = round_i32(d) as u8;
        v.max(1)
    }
}

fn tool_index(v: f32) -> Option<usize> {
    let t = round_i32(v);
    if (t as f32 - v) != 0.0 || !(0..N_TOOLS as i32).contains(&t) {
        None
    } else {
        Some(t as usize)
    }
}

/// G10 L1 / L2 / L20.
#[inline(never)]
fn set_offsets(m: &mut Machine, g: &ModalCopy, l: &Line, io: &mut impl Io) -> Result<(), Error> {
    let lv = l.word(Word::L).ok_or(Error::BadWord(F!("G10 needs L1, L2 or L20")))?;
    let p = l.word(Word::P).ok_or(Error::BadWord(F!("G10 needs P")))?;
    let conv = |v: f32| to_mm(g.inches, v);
    match round_i32(lv) {
        1 if lv == 1.0 => {
            let t = tool_index(p).ok_or(Error::BadWord(F!("G10 L1: P must be a tool number 0-12")))?;
            if t == 0 {
                return Err(Error::BadWord(F!("G10 L1: P must be a tool number 1-12")));
            }
            let r = l.word(Word::R);
            if r.is_some_and(|r| r < 0.0) {
                return Err(Error::BadWord(F!("G10 L1: R must not be negative")));
            }
            crate::atc::run::set_tool(m, io, t as u8, l.word(Word::Z).map(conv), r.map(conv));
            Ok(())
        }
        n @ (2 | 20) if lv == n as f32 => {
            let idx = round_i32(p);
            if idx as f32 != p || !(0..=N_WCS as i32).contains(&idx) {
                return Err(Error::BadWord(F!("G10 L2/L20: P must be 0-6")));
            }
            let w = if idx == 0 { g.wcs as usize } else { (idx - 1) as usize };
            let mut off = m.interp.wcs_mm[w];
            for (a, &word) in AXIS_WORDS.iter().enumerate() {
                if let Some(v) = l.word(word) {
                    let v = word_mm(g.inches, a, v);
                    off[a] = if n == 2 {
                        v
                    } else {
                        let tlo = if a == 2 { g.tlo } else { 0.0 };
                        m.interp.pos_mm[a] - g.g92[a] - tlo - v
                    };
                }
            }
            m.interp.wcs_mm[w] = off;
            // Work offsets are persistent (SPEC §5): write them now; the
            // EEPROM layer programs only the bytes that changed.
            m.save_settings(io);
            Ok(())
        }
        _ => Err(Error::BadWord(F!("G10: L must be 1, 2 or 20"))),
    }
}

/// M codes of the "other" group.
#[inline(never)]
fn other_m(m: &mut Machine, l: &Line, code: u16, _text: &[u8], io: &mut impl Io) -> Result<(), Error> {
    match code {
        17 => {
            io.drivers(true);
        }
        18 | 84 => {
            // Wait for the moves, then spindle off (a mill with its drivers
            // off cannot cut: OctoPrint's cancel script has M84 but no M5),
            // drivers off; the position and the homing are kept (Marlin's
            // default, HOME_AFTER_DEACTIVATE off). README "Cancel".
            m.wait_idle(io)?;
            m.spindle_off(io);
            io.drivers(false);
            m.apply_watch(io, 0, false);
            if m.homed != 0 {
                uwriteln!(io, "{}", F!("echo:steppers off, position kept: home again (G28) if an axis was turned by hand")).ok();
            }
        }
        92 | 201 | 203 => {
            m.wait_idle(io)?;
            let mut s = m.settings;
            let words = [Word::X, Word::Y, Word::Z, Word::E];
            for (a, &w) in words.iter().enumerate() {
                if let Some(v) = l.word(w) {
                    if !(v > 0.0) {
                        return Err(Error::BadWord(F!("value must be positive")));
                    }
                    match code {
                        92 => s.steps_per_mm[a] = v,
                        201 => s.accel_mm_per_s2[a] = v,
                        _ => s.max_feed_mm_per_min[a] = v * 60.0, // M203 is mm/s (Marlin)
                    }
                }
            }
            if !s.is_sane() {
                return Err(Error::BadWord(F!("value out of range")));
            }
            m.replace_settings(s, io)?;
        }
        220 => {
            let s = l.word(Word::S).ok_or(Error::BadWord(F!("M220 needs S<percent>")))?;
            if !(10.0..=500.0).contains(&s) {
                return Err(Error::BadWord(F!("M220 S must be 10-500")));
            }
            m.interp.feed_override_pct = round_i32(s) as u16;
        }
        400 => m.wait_idle(io)?,
        500 => {
            m.save_settings(io);
            uwriteln!(io, "{}", F!("echo:settings stored")).ok();
        }
        501 => {
            m.wait_idle(io)?;
            if m.load_settings(io) {
                uwriteln!(io, "{}", F!("echo:settings loaded")).ok();
            } else {
                return Err(Error::BadWord(F!("EEPROM settings invalid; kept the current ones")));
            }
        }
        502 => {
            m.wait_idle(io)?;
            m.set_settings(Settings::defaults());
            m.interp.load_settings(&m.settings);
            uwriteln!(io, "{}", F!("echo:factory settings restored (M500 to store)")).ok();
        }
        108 => {}
        _ => return Err(Error::NotAvailable(F!("M code not supported"))),
    }
    Ok(())
}

/// G38.2/G38.3: move toward `target` until the tool-setter input trips.
#[inline(never)]
fn probe(m: &mut Machine, io: &mut impl Io, target: [f32; N_AXES], feed: f32, must_trip: bool) -> Result<(), Error> {
    if m.alarm.is_some() {
        return Err(Error::Alarm);
    }
    if !m.motion_allowed() {
        return Err(Error::NotHomed);
    }
    m.wait_idle(io)?;
    if io.switches().tool_setter {
        return Err(Error::ProbeAlreadyTriggered);
    }
    let prev = m.state;
    m.state = State::Probe;
    m.apply_watch(io, 0, true);
    let steps = m.interp.steps_of(&m.settings, &target);
    let r = m.queue_line(io, steps, feed, false).and_then(|_| m.wait_motion_or_trip(io));
    m.apply_watch(io, 0, false);
    m.state = prev;
    let tripped = r?;
    let pos = if tripped { io.stepper().trip_position } else { io.stepper().position };
    m.resync_after_stop(io);
    let mm = m.steps_to_mm(pos);
    uwrite!(io, "[PRB:").ok();
    m.write_xyz(io, m.interp.work_user(mm));
    uwriteln!(io, ":{}]", if tripped { 1u8 } else { 0u8 }).ok();
    if !tripped && must_trip {
        return Err(Error::ProbeFailed);
    }
    Ok(())
}

#[inline(never)]
fn report_position(m: &Machine, io: &mut impl Io) {
    let internal = io.stepper().position;
    let w = m.interp.work_user(m.steps_to_mm(internal));
    // Count: the step counters in the user's sense (Z counts up), so that
    // Count = position × steps/mm as in Marlin.
    let st = frame::steps_user_from_internal(internal);
    uwriteln!(
        io,
        "X:{} Y:{} Z:{} E:{}{}{} Y:{} Z:{} E:{}",
        Micros::from_mm(w[0]),
        Micros::from_mm(w[1]),
        Micros::from_mm(w[2]),
        Micros::from_mm(w[3]),
        F!(" Count X:"),
        st[0],
        st[1],
        st[2],
        st[3]
    )
    .ok();
}

#[inline(never)]
fn report_switches(_m: &Machine, io: &mut impl Io) {
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

#[inline(never)]
fn report_settings(m: &Machine, io: &mut impl Io) {
    let s = &m.settings;
    let line = |io: &mut dyn DynOut, code: FStr, v: &[f32; N_AXES], scale: f32| {
        io.out(code);
        for (a, &n) in AXIS_NAMES.iter().enumerate() {
            io.text(n);
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
        for (a, &n) in AXIS_NAMES[..3].iter().enumerate() {
            d.text(n);
            d.num(frame::axis_user_from_internal(a, o[a]));
        }
        d.text("\n");
    }
    d.out(F!("echo:Travel (mm):"));
    for (a, &n) in AXIS_NAMES[..3].iter().enumerate() {
        d.text(n);
        d.num(s.travel_mm[a]);
    }
    let on_off = |on: bool| if on { F!("on") } else { F!("off") };
    d.out(F!(" soft limits "));
    d.out(on_off(s.soft_limits));
    d.out(F!(", hard limits "));
    d.out(on_off(s.hard_limits));
    d.text("\n");
}

/// ` X` … ` E`: short, so plain RAM strings.
const AXIS_NAMES: [&str; N_AXES] = [" X", " Y", " Z", " E"];

/// Small object-safe writer used by the settings report.
trait DynOut {
    fn out(&mut self, s: FStr);
    fn text(&mut self, s: &str);
    fn num(&mut self, v: f32);
    fn int(&mut self, v: i32);
}

struct Dyn<'a, W: Io>(&'a mut W);

impl<W: Io> DynOut for Dyn<'_, W> {
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

/// The modal fields a line may change, copied so an invalid line changes nothing.
struct ModalCopy {
    inches: bool,
    incremental: bool,
    plane: Plane,
    arc_absolute: bool,
    motion: Motion,
    retract: Retract,
    feed: f32,
    wcs: u8,
    tlo: f32,
    g92: [f32; 3],
}

impl ModalCopy {
    fn from(i: &Interp) -> ModalCopy {
        ModalCopy {
            inches: i.inches,
            incremental: i.incremental,
            plane: i.plane,
            arc_absolute: i.arc_absolute,
            motion: i.motion,
            retract: i.retract,
            feed: i.feed_mm_per_min,
            wcs: i.wcs,
            tlo: i.tlo_mm,
            g92: i.g92_mm,
        }
    }

    fn commit(&self, i: &mut Interp) {
        i.inches = self.inches;
        i.incremental = self.incremental;
        i.plane = self.plane;
        i.arc_absolute = self.arc_absolute;
        i.motion = self.motion;
        i.retract = self.retract;
        i.feed_mm_per_min = self.feed;
        i.wcs = self.wcs;
        i.tlo_mm = self.tlo;
    }
}

#[cfg(test)]
#[path = "interp_tests.rs"]
pub(crate) mod tests;
