//! The machine controller: everything between the serial bytes and the
//! segment ring, as plain logic over the [`Io`] trait.
//!
//! ```text
//!  bytes ─► protocol::LineAssembler ─► protocol::LineChecker ─► gcode::parse
//!        ─► Interp::next (gcode::interp: modal state, returns a Command)
//!        ─► Machine::dispatch ─► Machine::queue_line ─► Planner ─► Prep ─► Io::push_segment
//! ```
//!
//! `Machine::run_line` asks the interpreter for a line's commands one at a
//! time and carries each out. Every move, whoever makes it, enters the
//! planner through [`Machine::queue_line`]: the interpreter's (via
//! `Machine::dispatch`'s `Command::Move`), homing's and the carousel's
//! switch seeks (`Machine::seek_switch`, the one homing seek), and the
//! runners in this module's children, which express their sequences over it
//! ([`Machine::move_mm`]): [`toolchange`] (T/M6, M61, G10 L1, the EEPROM
//! journal), [`carousel`] (G201–G205), [`setter`] (G37) and [`report`]
//! (M114, M119, M503). Nothing here calls back into the interpreter.
//!
//! The firmware implements [`Io`] over `board` (AVR); host tests implement it
//! with a fake stepper, so the whole controller (alarms, homing, hold, the
//! protocol replies) is tested without a simulator.
//!
//! Nothing here blocks without serving realtime requests: every wait goes
//! through [`Machine::wait_step`], which tops up the segment ring and handles
//! `?`, `!`, `~`, M112 and switch trips.

use crate::config::Settings;
use crate::dollar;
use crate::fixed::Micros;
use crate::flash::FStr;
use crate::gcode::interp::{self, Command, Interp};
use crate::planner::{PlanError, Planner, Speed};
use crate::protocol::{Assembled, LineAssembler, LineChecker};
use crate::stepper::rings::Watch;
use crate::stepper::{Prep, StepperCmd};
use crate::N_AXES;
use core::convert::Infallible;
use ufmt::{uwrite, uwriteln};

pub mod carousel;
pub mod report;
pub mod setter;
pub mod startup;
pub mod toolchange;

/// Realtime events collected by the hardware since the last poll.
#[derive(Clone, Copy, Default, Debug)]
pub struct Realtime {
    pub status: bool,
    pub hold: bool,
    pub resume: bool,
    pub estop: bool,
    pub limit: bool,
    pub home_tripped: bool,
    pub probe_tripped: bool,
    /// Abort requested (SD job or menu): decelerate, then drop the queue.
    pub abort: bool,
    /// With `abort`: leave the spindle running (the caller retracts the
    /// tool first: the SD card pulled mid-job).
    pub abort_keep_spindle: bool,
    /// 0x18 (Ctrl-X, grbl's soft reset) received; the stepper is halted.
    pub reset: bool,
    /// 0x85 (grbl's jog cancel) received.
    pub jog_cancel: bool,
    /// grbl's realtime override bytes received since the last poll, as
    /// request bits ([`crate::overrides::motion`], [`crate::overrides::accessory`]).
    pub motion_ovr: u8,
    pub accessory_ovr: u8,
    /// With `reset`: steps were still being produced when it arrived.
    pub reset_moving: bool,
}

/// What the stepper ISR reports.
#[derive(Clone, Copy, Default, Debug)]
pub struct StepperStatus {
    /// Machine position in steps, counted by the ISR.
    pub position: [i32; N_AXES],
    /// Steps still being produced or queued.
    pub busy: bool,
    /// Position latched at the last homing/probe trip.
    pub trip_position: [i32; N_AXES],
    /// A homing or probe trip stopped the ISR (and is not cleared yet).
    pub tripped: bool,
}

/// Switch levels, already as "triggered".
#[derive(Clone, Copy, Default, Debug)]
pub struct Switches {
    /// Home switches, bit i = axis i (X, Y, Z).
    pub home: u8,
    pub carousel_home: bool,
    pub tool_setter: bool,
}

/// The hardware as the controller sees it.
pub trait Io: ufmt::uWrite<Error = Infallible> {
    /// Feed the watchdog and collect realtime events.
    fn poll(&mut self) -> Realtime;
    /// Queue a command for the stepper ISR; false if the ring is full.
    fn push_segment(&mut self, cmd: StepperCmd) -> bool;
    /// Free slots in the segment ring.
    fn segment_space(&self) -> usize;
    /// Stepper position and activity.
    fn stepper(&self) -> StepperStatus;
    /// Overwrite the stepper's position counter (only while stopped).
    fn set_stepper_position(&mut self, p: [i32; N_AXES]);
    /// Stop stepping at once, dropping queued segments.
    fn stop_motion(&mut self);
    /// Accept segments again after a stop; clears trip flags.
    fn clear_stop(&mut self);
    /// The ISR is stopped (e-stop, hard limit, homing or probe trip) and
    /// drops every segment it is given until [`Io::clear_stop`].
    fn stepper_stopped(&self) -> bool {
        false
    }
    /// What the ISR watches: homing axes, probe input, hard-limit axes,
    /// homed axes, direction inversion mask.
    /// `release`: steps above 0 where a homed axis' switch may still be
    /// closed (the homing pull-off, per axis X Y Z).
    fn set_watch(&mut self, w: Watch);
    /// Enable or disable the stepper drivers.
    fn drivers(&mut self, on: bool);
    /// Enable or disable the carousel (E0) driver alone (G204).
    fn carousel_driver(&mut self, on: bool);
    /// Spindle PWM duty, 0 = off.
    fn spindle(&mut self, duty: u8);
    /// Coolant output (M7/M8 on, M9 off).
    fn coolant(&mut self, on: bool);
    /// Current switch levels.
    fn switches(&self) -> Switches;
    /// Milliseconds since boot.
    fn millis(&self) -> u32;
    /// Read EEPROM bytes.
    fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]);
    /// Write EEPROM bytes (only the ones that differ are programmed).
    fn eeprom_write(&mut self, addr: u16, data: &[u8]);
    /// RAM never touched by the stack since boot, bytes.
    fn free_ram(&self) -> u16;
    /// Bytes waiting in the serial RX ring.
    fn rx_pending(&self) -> usize;
    /// Throw away every byte waiting in the serial RX ring (soft reset).
    fn flush_rx(&mut self) {}
    /// An SD command (M20–M29, M524; `arg` is the text after the code),
    /// with the little of the machine it may touch (`job`: M24 starts a
    /// job). Without an SD card in the build it is refused.
    fn sd_command(&mut self, _job: SdJobFlags<'_>, _code: u16, _arg: &[u8]) -> CmdResult {
        Err(interp::Error::NotAvailable(F!("SD card not available in this build")))
    }
    /// While M28 writes a file, store the line there and return true.
    fn sd_capture(&mut self, _line: &[u8]) -> bool {
        false
    }
    /// End of every [`Machine::idle`]: the standalone UI's turn (encoder,
    /// one slice of the display). Must be short.
    fn background(&mut self, _m: &Machine) {}
}

/// What an SD command may change of the machine ([`Io::sd_command`]): M24
/// starts a job, which needs the abort count to watch and sets `sd_job`.
pub struct SdJobFlags<'a> {
    /// [`Machine::sd_job`]: set when a job starts.
    pub sd_job: &'a mut bool,
    /// [`Machine::aborts`] now.
    pub aborts: u8,
}

/// Machine state, as reported by `?` (grbl 1.1 names).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum State {
    Idle,
    Run,
    Hold,
    Alarm,
    Home,
    Tool,
    Probe,
    /// A `$J=` jog is running (grbl 1.1).
    Jog,
    /// `$C` check mode: lines are read and checked, nothing moves.
    Check,
}

impl State {
    /// The grbl 1.1 status word (in flash: a `&str` would sit in RAM).
    pub fn name(self) -> crate::flash::FStr {
        match self {
            State::Idle => F!("Idle"),
            State::Run => F!("Run"),
            State::Hold => F!("Hold"),
            State::Alarm => F!("Alarm"),
            State::Home => F!("Home"),
            State::Tool => F!("Tool"),
            State::Probe => F!("Probe"),
            State::Jog => F!("Jog"),
            State::Check => F!("Check"),
        }
    }
}

crate::flash_messages! {
    /// Why the machine is in alarm (docs/SPEC.md §10); `message`: the text after
    /// `Error:alarm ` / `ALARM:`.
    #[derive(Clone, Copy, PartialEq, Eq, Debug)]
    pub enum Alarm {
        /// M112 received.
        EmergencyStop => "emergency stop",
        /// A home switch closed outside homing.
        HardLimit => "hard limit",
        /// G28 did not find a switch within travel + 10 %.
        HomingFailed => "homing failed",
        /// The probe input did not trip (G38.2).
        ProbeFailed => "probe failed",
        /// Booted after a watchdog reset.
        WatchdogReset => "watchdog reset",
        /// G205 / a tool change did not find the carousel switch.
        CarouselHome => "carousel home switch not found",
        /// G37 B: the tool's length is off by more than the tolerance.
        BrokenTool => "broken tool",
        /// 0x18 (soft reset) while steps were being produced: the stop was
        /// abrupt, steps may be lost (grbl's ALARM:3).
        ResetWhileMoving => "reset while moving",
    }
}

impl Alarm {
    /// grbl 1.1's alarm number (grblHAL's 10 for the emergency stop), for
    /// grbl senders (`ALARM:<n>`).
    pub fn grbl_code(self) -> u8 {
        match self {
            Alarm::HardLimit => 1,
            Alarm::ResetWhileMoving | Alarm::WatchdogReset => 3,
            Alarm::ProbeFailed | Alarm::BrokenTool => 5,
            Alarm::HomingFailed | Alarm::CarouselHome => 9,
            Alarm::EmergencyStop => 10,
        }
    }
}

/// Interpreter-level error shown to the host as `Error:<text>`.
pub type CmdResult = Result<(), interp::Error>;

/// A status-report field of letters (`|Pn:XZ`, `|A:SF`), left out when
/// no letter is set.
struct Letters {
    buf: [u8; 12],
    len: u8,
    head: u8,
}

impl Letters {
    fn new(head: &[u8]) -> Letters {
        let mut buf = [0; 12];
        let n = head.len().min(6);
        buf[..n].copy_from_slice(&head[..n]);
        Letters { buf, len: n as u8, head: n as u8 }
    }

    fn push(&mut self, on: bool, c: u8) {
        if on && (self.len as usize) < self.buf.len() {
            self.buf[self.len as usize] = c;
            self.len += 1;
        }
    }

    fn write(&self, io: &mut impl Io) {
        if self.len > self.head {
            io.write_str(crate::protocol::ascii_str(&self.buf[..self.len as usize])).ok();
        }
    }
}

/// The text after the first `=` of a `$` line.
fn after_eq(text: &[u8]) -> &[u8] {
    text.iter().position(|&b| b == b'=').map_or(&[][..], |i| &text[i + 1..])
}

/// How long a held home switch must read open before its hard limit is
/// armed again (see `Machine::limits_held`), ms: longer than any contact
/// bounce.
pub const LIMIT_REARM_MS: u16 = 20;

/// EEPROM address of the settings image.
pub const EEPROM_SETTINGS_ADDR: u16 = 0;

/// Feed of the retract after the card is pulled mid-job
/// ([`Machine::retract_and_stop_spindle`]), mm/min: straight up, out of the
/// cut, at a cutting feed rather than a rapid.
pub const RETRACT_FEED_MM_PER_MIN: f32 = 600.0;

/// The controller.
pub struct Machine {
    /// The spindle override, percent (grbl's 0x99–0x9D), the duty the
    /// program set (M3 S…), and the spindle stopped by 0x9E in a hold.
    spindle_pct: u8,
    spindle_duty: u8,
    spindle_stopped: bool,
    pub settings: Settings,
    pub planner: Planner,
    pub prep: Prep,
    pub interp: Interp,
    /// Tool changer: where the tools are, the tool table, an interrupted change.
    pub atc: crate::atc::Atc,
    /// Tool setter position and calibration.
    pub setter: crate::toolsetter::Setter,
    asm: LineAssembler,
    chk: LineChecker,
    pub state: State,
    pub alarm: Option<Alarm>,
    /// Axes with a known position (bit i = axis i).
    pub homed: u8,
    /// M999 / `$X` since the last power-on or alarm: motion allowed unhomed.
    pub unlocked: bool,
    /// Reply the grbl way (`error:<n>` instead of `ok`, `ALARM:<n>`): set
    /// by a serial `$$`, `$I`, `$G` or `$#` (every grbl sender sends one of
    /// them on connecting; a terminal's `$<n>=<v>` does not), cleared by a
    /// numbered line, `M110` or `M115` (a Marlin host's first words) and
    /// at power-on.
    pub grbl_replies: bool,
    /// Status reports sent (`?`): WCO and Ov come on every tenth.
    report_count: u8,
    /// Home switches found closed when an alarm was cleared (bit i = axis
    /// i): their hard limit waits until the switch has read open for
    /// [`LIMIT_REARM_MS`], so the axis can be jogged off it (grbl's limits
    /// are edge-triggered to the same effect).
    limits_held: u8,
    /// Home switches closed when the last hard limit tripped (bit i = axis
    /// i): which switch it was, for the display.
    pub limit_axes: u8,
    /// Low 16 bits of the milliseconds when every held switch last read
    /// closed.
    held_since_ms: u16,
    /// Feed-hold requested and not yet resumed.
    holding: bool,
    /// Milliseconds of the last `busy:processing` (or of the start of the
    /// serial line being run).
    last_busy_ms: u32,
    /// M117 message, M73 progress, M113 keepalive interval.
    pub host: crate::hostcodes::HostState,
    /// A serial line is being run: its host waits for the `ok` (keepalive).
    serial_line: bool,
    /// A soft reset (0x18) happened while the current serial line ran: it
    /// ends without an `ok` or an error (grbl drops it).
    silenced: bool,

    /// Realtime events of the last poll (trip flags persist until cleared).
    last_rt: Realtime,
    /// The host numbers its lines (so dropped lines get `Resend:`).
    numbered: bool,
    /// An SD job is under way: serial lines may only ask for status.
    pub sd_job: bool,
    /// `io.millis()` when the running SD job started (M31).
    pub job_start_ms: u32,
    /// The line being executed comes from the SD job.
    job_line: bool,
    /// An abort is decelerating; the queue is dropped once stopped.
    aborting: bool,
    /// The abort decelerating leaves the spindle on (see
    /// [`Realtime::abort_keep_spindle`]).
    abort_keeps_spindle: bool,
    /// Aborts completed so far (wraps); waits fail while it differs from
    /// `line_aborts`, the count when the current line started.
    pub aborts: u8,
    line_aborts: u8,
}

impl Default for Machine {
    fn default() -> Self {
        Machine::new()
    }
}

impl Machine {
    /// A machine with default settings (the EEPROM is read in [`Machine::boot`]).
    pub const fn new() -> Machine {
        Machine::with_settings(Settings::DEFAULT)
    }

    /// Build the machine in `slot` with the factory settings read from flash.
    /// The firmware's machine is a zeroed static built by this at boot: a
    /// `static` initialised with [`Machine::new`] would carry a 1.5 KB image
    /// in flash (`.data`) of which 71 bytes are not zero. Not inlined, so no
    /// machine-sized temporary stays in the caller's (never-returning) frame.
    #[inline(never)]
    pub fn init(slot: &mut core::mem::MaybeUninit<Machine>) -> &mut Machine {
        // Built with zeroed settings, which LLVM writes in place, then the
        // defaults copied in from flash: with the defaults' call in the
        // initialiser the whole machine was built in a 1.5 KB temporary,
        // the deepest stack of a run.
        let m = slot.write(Machine::with_settings(Settings::ZEROED));
        m.settings.reset_to_defaults();
        m
    }

    /// A machine with `settings`.
    pub const fn with_settings(settings: Settings) -> Machine {
        Machine {
            settings,
            planner: Planner::new(),
            prep: Prep::new(),
            interp: Interp::new(),
            atc: crate::atc::Atc::new(),
            setter: crate::toolsetter::Setter::DEFAULT,
            asm: LineAssembler::new(),
            chk: LineChecker::new(),
            state: State::Idle,
            alarm: None,
            homed: 0,
            unlocked: false,
            limits_held: 0,
            report_count: 0xFF,
            limit_axes: 0,
            grbl_replies: false,
            held_since_ms: 0,
            holding: false,
            last_busy_ms: 0,
            host: crate::hostcodes::HostState::new(),
            serial_line: false,
            silenced: false,
            last_rt: Realtime {
                status: false,
                hold: false,
                resume: false,
                estop: false,
                limit: false,
                home_tripped: false,
                probe_tripped: false,
                abort: false,
                abort_keep_spindle: false,
                reset: false,
                reset_moving: false,
                jog_cancel: false,
                motion_ovr: 0,
                accessory_ovr: 0,
            },
            spindle_pct: 100,
            spindle_duty: 0,
            spindle_stopped: false,
            numbered: false,
            sd_job: false,
            job_start_ms: 0,
            job_line: false,
            aborting: false,
            abort_keeps_spindle: false,
            aborts: 0,
            line_aborts: 0,
        }
    }

    /// Start-up: load settings, print the banner and the reset reason.
    #[inline(never)]
    pub fn boot(&mut self, io: &mut impl Io, reset_cause: FStr, watchdog: bool) {
        let mut img = [0u8; Settings::IMAGE_LEN];
        io.eeprom_read(EEPROM_SETTINGS_ADDR, &mut img);
        let loaded = self.settings.load_image(&img);
        self.settings_loaded();
        self.interp.load_settings(&self.settings);
        self.apply_watch(io, 0, false);
        uwriteln!(io, "{}", F!("start")).ok();
        self.firmware_line(io);
        uwriteln!(io, "{}{}", F!("echo:reset cause: "), reset_cause).ok();
        if !loaded {
            uwriteln!(io, "{}", F!("echo:EEPROM settings invalid or blank, using defaults")).ok();
        }
        toolchange::boot(self, io);
        if watchdog {
            self.raise(io, Alarm::WatchdogReset);
        } else if self.settings.homing_lock {
            uwriteln!(io, "{}", F!("echo:home (G28) before moving, or M999 to unlock")).ok();
        }
        startup::run(self, io);
    }

    /// May motion commands run? Not after power-on or an alarm until the
    /// machine is homed or unlocked, while the homing lock (`$22`) is on.
    pub fn motion_allowed(&self) -> bool {
        !self.settings.homing_lock || self.homed & 0b111 == 0b111 || self.unlocked
    }

    /// The M115 / boot firmware line.
    pub fn firmware_line(&self, io: &mut impl Io) {
        uwriteln!(
            io,
            "{}{}{}",
            F!("FIRMWARE_NAME:MillFW "),
            crate::FIRMWARE_VERSION,
            F!(" FIRMWARE_URL:none PROTOCOL_VERSION:1.0 MACHINE_TYPE:Mill EXTRUDER_COUNT:1 AXIS_COUNT:3 TOOLS:12")
        )
        .ok();
    }

    /// Feed received bytes as long as `bytes` gives them; runs complete
    /// lines as they end. `scratch` holds the line while it runs (the
    /// firmware passes the SD job's line buffer: the two are never in use
    /// at once, and a copy on the stack cost 256 bytes of stack high-water).
    ///
    /// The per-byte path is only the assembler, in one loop (a call per
    /// byte cost ~20 cycles on the AVR); the end of a line goes through
    /// [`Machine::line_end`].
    #[inline(never)]
    pub fn push_bytes(&mut self, bytes: impl Iterator<Item = u8>, io: &mut impl Io, scratch: &mut [u8; crate::protocol::MAX_LINE_LEN]) {
        for b in bytes {
            if let Some(done) = self.asm.push(b) {
                self.line_end(done, io, scratch);
            }
        }
    }

    /// A line ended in the assembler: run it, or report why it was dropped.
    #[inline(never)]
    fn line_end(&mut self, done: Assembled, io: &mut impl Io, scratch: &mut [u8; crate::protocol::MAX_LINE_LEN]) {
        match done {
            Assembled::Line => {
                // The line is copied out of the assembler (running it needs
                // `&mut self`).
                let raw = self.asm.line();
                let n = raw.len().min(scratch.len());
                let line = match (scratch.get_mut(..n), raw.get(..n)) {
                    (Some(d), Some(r)) => {
                        d.copy_from_slice(r);
                        &*d
                    }
                    _ => &[][..],
                };
                self.run_raw_line(line, io);
            }
            other => {
                let msg = match other {
                    Assembled::TooLong => F!("line too long (max 256 characters), ignored"),
                    Assembled::Overrun => F!("serial receive overrun, line dropped before its checksum was checked"),
                    _ => F!("binary data in line, ignored"),
                };
                // Numbered if it began with N; after an overrun (its start may
                // be lost) as the line before it was.
                self.numbered |= self.asm.dropped_numbered();
                if self.grbl_replies && !self.numbered {
                    // grbl: error 11 (line overflow), or 1 for the rest.
                    let code = if other == Assembled::TooLong { 11u8 } else { 1 };
                    uwriteln!(io, "{}{}{}{}", F!("[MSG:"), msg, F!("]\nerror:"), code).ok();
                    return;
                }
                self.reject_line(io, msg);
                uwriteln!(io, "ok").ok();
            }
        }
    }

    /// A line failed a protocol check (checksum, too long, overrun, ...).
    /// A numbered line is asked for again (`Resend:`), until it has failed
    /// `protocol::MAX_TRIES` times in a row: then it is given up with an
    /// error and the line number moves past it (`LineChecker::failed`), so
    /// that no input keeps a host resending the same line forever.
    fn reject_line(&mut self, io: &mut impl Io, msg: crate::flash::FStr) {
        if !self.numbered {
            uwriteln!(io, "Error:{}", msg).ok();
            return;
        }
        match self.chk.failed() {
            crate::protocol::Retry::GiveUp(n) => {
                // No checksum or line-number words in this text: OctoPrint
                // must not take it for a resend request (it stops the job).
                uwriteln!(io, "Error:{}{}{}", F!("gave up on line "), n, F!(" after 3 failed tries; it is NOT run")).ok();
            }
            crate::protocol::Retry::Resend(n) => {
                uwriteln!(io, "{}{}{}{}", F!("Error:"), msg, F!(", Last Line: "), self.chk.last_line()).ok();
                uwriteln!(io, "{}{}", F!("Resend:"), n).ok();
            }
        }
    }

    /// Check N/* and run one line; always ends with exactly one `ok`.
    #[inline(never)]
    fn run_raw_line(&mut self, raw: &[u8], io: &mut impl Io) {
        // Numbered for the resend protocol: N and a checksum (an N alone is a
        // file's block number, which the protocol does not track).
        self.numbered = matches!(raw.first(), Some(b'N' | b'n')) && raw.contains(&b'*');
        self.silenced = false;
        match self.chk.check(raw) {
            Err(crate::protocol::ProtoError::LineNumber) => {
                // A line sent after one that failed (the host had several in
                // flight): not a new try of the failed line.
                let e = crate::protocol::ProtoError::LineNumber;
                uwriteln!(io, "{}{}{}{}", F!("Error:"), e.message(), F!(", Last Line: "), self.chk.last_line()).ok();
                uwriteln!(io, "{}{}", F!("Resend:"), self.chk.resend_line()).ok();
            }
            Err(e) => {
                self.numbered = true;
                self.reject_line(io, e.message());
            }
            Ok(cmd) => {
                self.note_host(cmd);
                self.serial_line = true;
                if self.numbered {
                    self.planner.line_tag = self.chk.last_line() as u16;
                }
                self.last_busy_ms = io.millis();
                self.line_aborts = self.aborts;
                let sd = crate::hostcodes::sd_code(cmd);
                let was_running = self.sd_job;
                let r = match sd {
                    // M28 is writing a file: every line but M29 goes there.
                    Some((29, _)) => io.sd_command(SdJobFlags { sd_job: &mut self.sd_job, aborts: self.aborts }, 29, &[]),
                    _ if io.sd_capture(cmd) => Ok(()),
                    Some((code, arg)) => io.sd_command(SdJobFlags { sd_job: &mut self.sd_job, aborts: self.aborts }, code, arg),
                    None => self.execute(cmd, io),
                };
                self.serial_line = false;
                if self.sd_job && !was_running {
                    self.job_start_ms = io.millis();
                }
                if self.silenced {
                    // A soft reset ended the line: grbl prints nothing more
                    // for it (the banner already went out).
                    return;
                }
                if let Err(e) = r {
                    if self.grbl_replies && matches!(e, interp::Error::ProbeFailed) {
                        // grbl: a probe that touched nothing is its alarm
                        // (`ALARM:5`, already out); the line itself is
                        // acknowledged.
                        uwriteln!(io, "ok").ok();
                        return;
                    }
                    if self.grbl_replies {
                        // grbl: the error instead of the `ok`, its text first.
                        uwrite!(io, "{}", F!("[MSG:")).ok();
                        self.write_error(io, e);
                        uwriteln!(io, "{}{}", F!("]\nerror:"), e.grbl_code()).ok();
                        return;
                    }
                    uwrite!(io, "Error:").ok();
                    self.write_error(io, e);
                    uwriteln!(io, "").ok();
                }
            }
        }
        uwriteln!(io, "ok").ok();
    }

    /// Which host is talking, from what it sends (see
    /// [`Machine::grbl_replies`]): a first-byte test for the usual line.
    #[inline(always)]
    fn note_host(&mut self, cmd: &[u8]) {
        match cmd.first() {
            Some(b'$') => {
                if matches!(cmd.get(1), Some(b'$' | b'I' | b'i' | b'G' | b'g' | b'#')) {
                    self.grbl_replies = true;
                }
            }
            Some(b'M' | b'm') if self.grbl_replies => {
                if matches!(cmd.get(1..4), Some(b"110" | b"115")) {
                    self.grbl_replies = false;
                }
            }
            _ => {}
        }
        if self.numbered {
            self.grbl_replies = false;
        }
    }

    /// Print `Error:<what>` for a failed line.
    pub fn report_error(&self, io: &mut impl ufmt::uWrite, e: interp::Error) {
        uwrite!(io, "Error:").ok();
        self.write_error(io, e);
        uwriteln!(io, "").ok();
    }

    /// The text of an error, without a line end.
    fn write_error(&self, io: &mut impl ufmt::uWrite, e: interp::Error) {
        match e {
            interp::Error::Alarm => {
                let why = self.alarm.map_or(F!("unknown"), |a| a.message());
                uwrite!(io, "alarm {}{}", why, F!("; home or M999")).ok();
            }
            interp::Error::Parse(p) => {
                uwrite!(io, "{}{}{}", p.kind.message(), F!(" at col "), p.col).ok();
            }
            interp::Error::Sd(t) => {
                // SD card errors print their own text.
                uwrite!(io, "{}", t).ok();
            }
            interp::Error::StationOutside { setting, axis } => {
                let name = b"XYZ"[axis as usize] as char;
                uwrite!(io, "${}{}{}", setting, F!(" (tool change station) outside the "), name).ok();
                uwrite!(io, "{}{}{}", F!(" travel 0..$13"), axis, F!(", nothing changed")).ok();
            }
            interp::Error::UnusedWord(w) => {
                uwrite!(io, "{}{}", w.letter() as char, F!(" word with no code that uses it")).ok();
            }
            interp::Error::NoPocket(t) => {
                uwrite!(io, "{}{}{}{}{}", F!("tool T"), t, F!(" not in the tool table: G10 L1 P"), t, F!(" Q<pocket> assigns it")).ok();
            }
            other => {
                uwrite!(io, "{}", other.message()).ok();
            }
        }
    }

    /// Run one line of an SD job (the same path as a serial line, without
    /// the `ok`; the job reports errors with the line number).
    #[inline(never)]
    pub fn run_job_line(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        self.line_aborts = self.aborts;
        if crate::hostcodes::sd_code(text).is_some() {
            return Err(interp::Error::BadWord(F!("SD commands are not allowed inside an SD job")));
        }
        self.job_line = true;
        let r = self.execute(text, io);
        self.job_line = false;
        r
    }

    /// Run one line for the menu (Tools: `T<n>`, `G37`, `M61 Q<t>`): the
    /// same path as a serial line, without the `ok`; the caller reports errors.
    #[inline(never)]
    pub fn run_menu_line(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        self.line_aborts = self.aborts;
        self.execute(text, io)
    }

    /// True while the line being run comes from the SD job.
    pub fn in_job_line(&self) -> bool {
        self.job_line
    }

    /// Parse and run one command line (without N and checksum).
    #[inline(never)]
    pub fn execute(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        if text.first() == Some(&b'$') {
            return self.dollar(text, io);
        }
        if let Some((code, arg)) = crate::hostcodes::code(text) {
            return crate::hostcodes::run(&mut self.host, io, code, arg);
        }
        let mut line = crate::gcode::Line::default();
        crate::gcode::parse_into(text, &mut line).map_err(interp::Error::Parse)?;
        // A serial line's block number (`N10 G1 …`, grbl senders): its moves
        // carry it for `?`'s `Ln:` (a Marlin host's N is the checker's, set
        // in `run_raw_line`; an SD job tags its own lines).
        if self.serial_line && !self.numbered {
            self.planner.line_tag = crate::protocol::block_number(text);
        }
        self.run_line(&line, io)
    }

    /// Run a parsed line: ask the interpreter for its commands, one at a
    /// time, and carry each out ([`Machine::dispatch`]) before asking for
    /// the next. The first error ends the line.
    #[inline(never)]
    fn run_line(&mut self, l: &crate::gcode::Line, io: &mut impl Io) -> CmdResult {
        self.interp.begin_line();
        // `line_done` spares the last call (a streamed G1 is one move).
        while !self.interp.line_done() {
            let cx = interp::Ctx {
                settings: &self.settings,
                atc: &self.atc,
                alarm: self.alarm.is_some(),
                estop: self.alarm == Some(Alarm::EmergencyStop),
                status_only: self.sd_job && !self.job_line,
            };
            // Matched by reference: the command is not copied again.
            let r = self.interp.next(&cx, l);
            match &r {
                Ok(Some(Command::Move { .. } | Command::CycleMove { .. })) if self.state == State::Check => {
                    self.interp.target_reached();
                }
                Ok(Some(Command::Move { feed_mm_per_min, rapid })) => self.move_interp(io, *feed_mm_per_min, *rapid)?,
                // `$C`: only reports run; spindle, tool, probe, dwell,
                // homing and EEPROM writes are checked and skipped.
                Ok(Some(cmd)) if self.state == State::Check && !matches!(cmd, Command::Report(_)) => {}
                Ok(Some(cmd)) => self.dispatch(cmd, io)?,
                Ok(None) => return Ok(()),
                Err(e) => return Err(*e),
            }
        }
        Ok(())
    }

    /// Carry out one command of the interpreter.
    #[inline(never)]
    fn dispatch(&mut self, cmd: &Command, io: &mut impl Io) -> CmdResult {
        match *cmd {
            Command::Move { feed_mm_per_min, rapid } => self.move_interp(io, feed_mm_per_min, rapid),
            Command::CycleMove { feed_mm_per_min, rapid } => self.cycle_move(io, feed_mm_per_min, rapid),
            Command::Probe { feed_mm_per_min, must_trip } => self.probe(io, *self.interp.target(), Speed::Feed(feed_mm_per_min), must_trip),
            Command::Dwell { ms } => {
                self.keepalive(io);
                self.wait_ms(io, ms)
            }
            Command::Home { mask } => home(self, io, mask),
            Command::Measure { mode, x_mm, y_mm } => setter::g37(self, io, mode, x_mm, y_mm),
            Command::SelectTool { to } => toolchange::select(self, io, to),
            Command::PreselectTool(t) => {
                // NGC: T selects (pre-stages) the tool; the next M6 changes to it.
                self.atc.last_t = t;
                Ok(())
            }
            Command::ConfirmTool { tool } => {
                toolchange::confirm_tool(self, io, tool);
                Ok(())
            }
            Command::SetPocket { pocket, full } => toolchange::set_pocket(self, io, pocket, full),
            Command::AssignTool { tool, pocket } => toolchange::assign(self, io, tool, pocket),
            Command::SetTool { tool, length_mm, radius_mm } => {
                toolchange::set_tool(self, io, tool, length_mm, radius_mm);
                Ok(())
            }
            Command::StoreOffsets => {
                self.save_settings(io);
                Ok(())
            }
            Command::CarouselTurn { x } => carousel::turn_to(self, io, x),
            Command::CarouselSetPosition { x } => carousel::set_position(self, io, x),
            Command::CarouselReport => {
                carousel::report(self, io);
                Ok(())
            }
            Command::CarouselEnable { on } => carousel::enable(self, io, on),
            Command::CarouselHome { back, only_if_unhomed } => carousel::home_command(self, io, back, only_if_unhomed),
            Command::Spindle { on, duty } => self.spindle(io, on, duty),
            Command::FeedOverride { pct } => {
                self.set_feed_override(pct);
                Ok(())
            }
            Command::Coolant { m } => {
                // One output for both M7 (mist) and M8 (flood), switched in
                // step with the motion like the spindle (M9 in an alarm: at
                // once, nothing moves).
                if self.alarm.is_none() {
                    self.wait_idle(io)?;
                }
                io.coolant(m != 9);
                self.interp.coolant_m = m;
                Ok(())
            }
            Command::AxisSettings { code, values } => self.axis_settings(io, code, values),
            Command::M(code) => self.m_code(io, code),
            Command::Report(r) => {
                match r {
                    interp::Report::Position => report::position(self, io),
                    interp::Report::Firmware => self.firmware_line(io),
                    interp::Report::Temperatures => {
                        uwriteln!(io, "{}", F!("T:0.0 /0.0")).ok();
                    }
                    interp::Report::Switches => report::switches(self, io),
                    interp::Report::Settings => report::settings(self, io),
                    interp::Report::PrintTime => report::print_time(self, io),
                }
                Ok(())
            }
            Command::ClearAlarm => {
                if self.alarm.is_none() {
                    // grbl: `$X` outside an alarm has no effect. Only the
                    // homing lock after power-on is lifted; the queue and
                    // the position are not touched (a move may be running).
                    if !self.motion_allowed() {
                        self.unlocked = true;
                        uwriteln!(io, "{}", F!("echo:unlocked; position unknown until homed (G28)")).ok();
                    }
                    return Ok(());
                }
                self.clear_alarm(io);
                uwriteln!(io, "{}", F!("echo:alarm cleared; position unknown until homed (G28)")).ok();
                Ok(())
            }
            Command::EmergencyStop => {
                // The RX interrupt's scanner has usually raised it already.
                if self.alarm != Some(Alarm::EmergencyStop) {
                    self.raise(io, Alarm::EmergencyStop);
                }
                Ok(())
            }
            Command::ProgramEnd => {
                self.wait_idle(io)?;
                self.spindle_off(io);
                uwriteln!(io, "{}", F!("echo:program end")).ok();
                Ok(())
            }
            Command::Pause => {
                self.wait_idle(io)?;
                uwriteln!(io, "{}", F!("echo:paused, send ~ to resume")).ok();
                self.pause_until_resume(io)
            }
        }
    }

    /// A canned cycle's move: wait for room first (two slots: a backlash
    /// take-up may come first), so the keepalive goes out while the queue
    /// is full.
    #[inline(never)]
    fn cycle_move(&mut self, io: &mut impl Io, feed: f32, rapid: bool) -> CmdResult {
        self.keepalive(io);
        while self.planner.free() < 2 {
            self.keepalive(io);
            self.wait_step(io)?;
        }
        self.move_interp(io, feed, rapid)
    }

    /// Let the queue drain, then wait `ms` milliseconds, serving realtime
    /// requests and sending the keepalive (G4, the canned cycles' P).
    /// Switch the spindle in step with the motion; when it starts or stops,
    /// wait its spin-up (`$181`) or spin-down (`$182`) delay before the next
    /// move (a speed change while on waits nothing, as Marlin).
    pub fn spindle(&mut self, io: &mut impl Io, on: bool, duty: u8) -> CmdResult {
        self.wait_idle(io)?;
        let was = self.interp.spindle_on;
        self.interp.spindle_on = on;
        self.spindle_duty = duty;
        io.spindle(crate::overrides::spindle_duty(duty, self.spindle_pct));
        let delay_s = match (was, on) {
            (false, true) => self.settings.spin_up_s,
            (true, false) => self.settings.spin_down_s,
            _ => 0.0,
        };
        if delay_s > 0.0 {
            self.keepalive(io);
            self.wait_ms(io, delay_s * 1000.0)?;
        }
        Ok(())
    }

    fn wait_ms(&mut self, io: &mut impl Io, ms: f32) -> CmdResult {
        self.wait_idle(io)?;
        let start = io.millis();
        while (io.millis().wrapping_sub(start) as f32) < ms {
            self.wait_step(io)?;
        }
        Ok(())
    }

    /// G38.2/G38.3: move toward `target` until the tool-setter input trips.
    #[inline(never)]
    fn probe(&mut self, io: &mut impl Io, target: [f32; N_AXES], speed: Speed, must_trip: bool) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        if !self.motion_allowed() {
            return Err(interp::Error::NotHomed);
        }
        self.wait_idle(io)?;
        if io.switches().tool_setter {
            return Err(interp::Error::ProbeAlreadyTriggered);
        }
        let prev = self.state;
        self.state = State::Probe;
        self.apply_watch(io, 0, true);
        let steps = self.interp.steps_of(&self.settings, &target);
        let r = self.queue_line(io, steps, speed).and_then(|_| self.wait_motion_or_trip(io));
        self.apply_watch(io, 0, false);
        self.state = prev;
        let tripped = r?;
        let pos = if tripped { io.stepper().trip_position } else { io.stepper().position };
        self.resync_after_stop(io);
        let mm = self.steps_to_mm(pos);
        uwrite!(io, "{}", F!("[PRB:")).ok();
        self.write_xyz(io, self.interp.work_user(mm));
        uwriteln!(io, ":{}]", if tripped { 1u8 } else { 0u8 }).ok();
        if !tripped && must_trip {
            // grbl's ALARM:5: the lines after a probe (G92, G10 L20) must
            // not set a zero where nothing was touched. G38.3 may miss.
            self.raise(io, Alarm::ProbeFailed);
            return Err(interp::Error::ProbeFailed);
        }
        Ok(())
    }

    /// M92 / M201 / M203 (`values`: X Y Z E, NaN where absent), once the
    /// machine is still.
    #[inline(never)]
    fn axis_settings(&mut self, io: &mut impl Io, code: u16, values: [f32; N_AXES]) -> CmdResult {
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
        self.replace_settings(s, io)
    }

    /// M17, M18/M84, M400, M500, M501, M502.
    #[inline(never)]
    fn m_code(&mut self, io: &mut impl Io, code: u16) -> CmdResult {
        match code {
            17 => io.drivers(true),
            18 | 84 => {
                // Wait for the moves, then spindle off (a mill with its drivers
                // off cannot cut: OctoPrint's cancel script has M84 but no M5),
                // drivers off; the position and the homing are kept (Marlin's
                // default, HOME_AFTER_DEACTIVATE off). docs/hosts.md "Cancel".
                // In an alarm nothing moves: at once.
                if self.alarm.is_none() {
                    self.wait_idle(io)?;
                }
                self.spindle_off(io);
                io.drivers(false);
                self.apply_watch(io, 0, false);
                if self.homed != 0 {
                    uwriteln!(io, "{}", F!("echo:steppers off, position kept: home again (G28) if an axis was turned by hand")).ok();
                }
            }
            400 => self.wait_idle(io)?,
            500 => {
                self.save_settings(io);
                uwriteln!(io, "{}", F!("echo:settings stored")).ok();
            }
            501 => {
                self.wait_idle(io)?;
                if self.load_settings(io) {
                    uwriteln!(io, "{}", F!("echo:settings loaded")).ok();
                } else {
                    return Err(interp::Error::BadWord(F!("EEPROM settings invalid; kept the current ones")));
                }
            }
            _ => {
                self.wait_idle(io)?;
                self.set_settings(Settings::defaults());
                self.interp.load_settings(&self.settings);
                uwriteln!(io, "{}", F!("echo:factory settings restored (M500 to store)")).ok();
            }
        }
        Ok(())
    }

    /// A grbl-style `$` line (see `crate::dollar`).
    #[inline(never)]
    fn dollar(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        let bad = |e: dollar::DollarError| interp::Error::Coded(e.grbl_code(), e.message());
        match dollar::parse(text).map_err(bad)? {
            dollar::Command::List => dollar::list(&self.settings, io),
            dollar::Command::Modes => dollar::modes(&self.interp, self.atc.spindle_tool(), io),
            dollar::Command::Params => dollar::params(&self.interp, self.settings.report_inches, io),
            dollar::Command::Info => startup::info(io),
            dollar::Command::InfoSet => startup::set_info(io, after_eq(text))?,
            dollar::Command::StartupList => startup::list(io),
            dollar::Command::StartupSet(i) => startup::set(io, i, after_eq(text))?,
            dollar::Command::HomeAxis(mask) => return home(self, io, mask),
            dollar::Command::Sleep => {
                // grbl's sleep: everything that drives the machine off; here
                // any command wakes it (the drivers come on with a move).
                self.spindle_off(io);
                if self.alarm.is_none() {
                    self.wait_idle(io)?;
                }
                io.drivers(false);
                uwriteln!(io, "{}", F!("[MSG:Sleeping]")).ok();
            }
            dollar::Command::Restore(what) => self.restore(io, what)?,
            dollar::Command::Check => self.toggle_check(io)?,
            dollar::Command::Home => return self.execute(b"G28", io),
            dollar::Command::Unlock => return self.execute(b"M999", io),
            dollar::Command::Jog => return self.jog_line(text, io),
            dollar::Command::Set(n, v) => self.set_setting(io, n, v)?,
        }
        Ok(())
    }

    /// `$<n>=<v>`: check the value, then store all settings at once.
    #[inline(never)]
    pub fn set_setting(&mut self, io: &mut impl Io, n: u8, v: f32) -> CmdResult {
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
        self.replace_settings(s, io)?;
        self.save_settings(io);
        Ok(())
    }

    /// The menu's Z probe: G38.2 straight down by `mm` (at most to the end
    /// of the Z travel) from where the machine is, at `feed` (the probe input; a miss raises the probe-fail
    /// alarm, as G38.2 does). Refused until homed.
    #[inline(never)]
    pub fn probe_z_down(&mut self, io: &mut impl Io, mm: f32, feed: f32) -> CmdResult {
        if !self.motion_allowed() {
            return Err(interp::Error::NotHomed);
        }
        // The internal frame counts Z down from the home switch: down by
        // `mm`, no deeper than the Z travel.
        let mut target = self.interp.pos_mm;
        let depth = target[2] + mm;
        let travel = self.settings.travel_mm[2];
        target[2] = if depth < travel { depth } else { travel };
        self.probe(io, target, Speed::Fixed(feed), true)
    }

    /// The menu's "teach": station point `p` (`$170 + p`: X1, Y point A,
    /// Y point B, Z1, Z2, the travel height) becomes where the machine is,
    /// through the same checks as `$170=…`. Refused until homed (the
    /// position means nothing before).
    #[inline(never)]
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

    /// `$C`: check mode on (from Idle) or off. Leaving it puts the commanded
    /// position back where the machine is and the work offsets back to the
    /// stored ones; the modal state stays as the checked lines left it
    /// (grbl resets it with a soft reset).
    fn toggle_check(&mut self, io: &mut impl Io) -> CmdResult {
        if self.state == State::Check {
            let p = io.stepper().position;
            self.interp.sync_position(&self.settings, p);
            self.interp.load_settings(&self.settings);
            self.state = State::Idle;
            uwriteln!(io, "{}", F!("[MSG:Disabled]")).ok();
            return Ok(());
        }
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        self.wait_idle(io)?;
        self.state = State::Check;
        uwriteln!(io, "{}", F!("[MSG:Enabled]")).ok();
        Ok(())
    }

    /// `$RST=$` settings to defaults (the work offsets kept), `$RST=#` work
    /// offsets to 0, `$RST=*` both and the startup blocks and info text;
    /// stored at once, as grbl does. The tool table and the changer's
    /// state are kept: they describe the machine as it physically is.
    fn restore(&mut self, io: &mut impl Io, what: u8) -> CmdResult {
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
        self.replace_settings(s, io)?;
        self.interp.load_settings(&self.settings);
        self.save_settings(io);
        uwriteln!(io, "{}", F!("[MSG:Restoring defaults]")).ok();
        Ok(())
    }

    /// Put new settings in force once the machine is still (M92, M201, M203,
    /// `$n=`): the step counters are rescaled so that a steps/mm change keeps
    /// the physical position, and the ISR's watch list follows the limits and
    /// direction settings.
    pub fn replace_settings(&mut self, s: Settings, io: &mut impl Io) -> CmdResult {
        // In an alarm nothing moves (it stopped the steps and dropped the
        // queue): settings such as `$21=0` may change at once.
        if self.alarm.is_none() {
            self.wait_idle(io)?;
        }
        let mm = self.steps_to_mm(io.stepper().position);
        self.set_settings(s);
        let new = self.interp.steps_of(&self.settings, &mm);
        io.set_stepper_position(new);
        self.planner.set_position(new);
        self.apply_watch(io, 0, false);
        Ok(())
    }

    // ---- Motion plumbing --------------------------------------------------

    /// Queue a straight move to `target` (absolute steps). Waits for planner
    /// space while serving realtime requests.
    #[inline(never)]
    pub fn queue_line(&mut self, io: &mut impl Io, target: [i32; N_AXES], speed: Speed) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        // Drivers switch on with the first move (Marlin, grbl); M18/M84 turn
        // them off again.
        io.drivers(true);
        loop {
            match self.planner.accept_line(target, speed, &self.settings) {
                Ok(p) => {
                    if p.rate_capped {
                        uwriteln!(io, "{}", F!("echo:warning: feed capped to the maximum step rate")).ok();
                    }
                    if self.state == State::Idle {
                        self.state = State::Run;
                    }
                    return Ok(());
                }
                Err(PlanError::Full) => self.wait_step(io)?,
                Err(_) => return Err(interp::Error::BadFeed),
            }
        }
    }

    /// Queue a straight move to `target` (internal machine mm, E in carousel
    /// units): the one entry point of every move in mm (the interpreter's
    /// moves, chords and cycle steps, the tool changer's and the tool
    /// setter's rapids, the carousel's turns, the menu's jog). The homing
    /// lock guards X/Y/Z (the carousel alone has its own homing, G205); the
    /// commanded position follows once the planner took the move.
    #[inline(never)]
    pub fn move_mm(&mut self, io: &mut impl Io, target: &[f32; N_AXES], speed: Speed) -> CmdResult {
        self.may_move_to(target)?;
        let steps = self.interp.steps_of(&self.settings, target);
        self.queue_line(io, steps, speed)?;
        self.interp.pos_mm = *target;
        Ok(())
    }

    /// [`Machine::move_mm`] to the interpreter's [`Interp::target`]
    /// (`Command::Move`), without copying it out.
    #[inline(never)]
    fn move_interp(&mut self, io: &mut impl Io, feed_mm_per_min: f32, rapid: bool) -> CmdResult {
        self.may_move_to(self.interp.target())?;
        let steps = self.interp.target_steps(&self.settings);
        let speed = if rapid { Speed::Rapid } else { Speed::Feed(feed_mm_per_min) };
        self.queue_line(io, steps, speed)?;
        self.interp.target_reached();
        Ok(())
    }

    /// Motion to `target` is allowed: no alarm, and the homing lock
    /// (`$22`) guards X/Y/Z (the carousel alone has its own homing, G205;
    /// an interrupted tool change is locked separately).
    #[inline(always)]
    fn may_move_to(&self, target: &[f32; N_AXES]) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        // The cheap test first: homed or unlocked, any target goes.
        if self.motion_allowed() {
            return Ok(());
        }
        let xyz_moves = (0..3).any(|a| !interp::same_f32(target[a], self.interp.pos_mm[a]));
        if xyz_moves {
            return Err(interp::Error::NotHomed);
        }
        Ok(())
    }

    /// The menu's jog: `axis` (0..3) by `delta_mm` (user frame: +Z up) at
    /// `feed` mm/min from the commanded position; soft limits apply, the
    /// modal state is untouched.
    #[inline(never)]
    pub fn jog(&mut self, io: &mut impl Io, axis: usize, delta_mm: f32, feed: f32) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        let mut target = self.interp.pos_mm;
        target[axis] += crate::frame::axis_internal_from_user(axis, delta_mm);
        self.interp.check_soft_limits(&self.settings, &target)?;
        let target = self.keep_out_clip(&target);
        self.move_mm(io, &target, Speed::Fixed(feed))
    }

    /// The SD card was pulled mid-job and the job's moves are dropped: lift
    /// Z to `$160` below its home switch at [`RETRACT_FEED_MM_PER_MIN`]
    /// (only up: a tool above that height stays), wait for it, then the
    /// spindle and coolant off. Without a known Z (not homed) nothing moves.
    #[inline(never)]
    pub fn retract_and_stop_spindle(&mut self, io: &mut impl Io) -> CmdResult {
        // The job's abort is over: this move's wait must not fail on it.
        self.line_aborts = self.aborts;
        let r = self.retract_z(io);
        self.spindle_off(io);
        r
    }

    fn retract_z(&mut self, io: &mut impl Io) -> CmdResult {
        if self.alarm.is_some() || self.homed & 0b100 == 0 {
            return Ok(());
        }
        let mut target = self.interp.pos_mm;
        // Internal frame: Z counts down from the switch.
        let safe = self.settings.card_out_retract_mm;
        if target[2] > safe {
            target[2] = safe;
            self.move_mm(io, &target, Speed::Fixed(RETRACT_FEED_MM_PER_MIN))?;
            self.wait_idle(io)?;
        }
        Ok(())
    }

    /// `$J=<words>`: a grbl 1.1 jog (see [`Interp::jog_target`]), only
    /// from Idle or Jog; the soft limits refuse a target beyond the travel
    /// before anything moves. Queued like any move, so a stream of short
    /// jogs runs without stopping between them; 0x85 or `!` ends it.
    #[inline(never)]
    fn jog_line(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        if !matches!(self.state, State::Idle | State::Jog) || self.holding {
            return Err(interp::Error::BadWord(F!("$J= only while idle or jogging")));
        }
        let mut line = crate::gcode::Line::default();
        crate::gcode::parse_into(after_eq(text), &mut line).map_err(interp::Error::Parse)?;
        let (target, feed) = self.interp.jog_target(&line)?;
        if !self.motion_allowed() {
            return Err(interp::Error::NotHomed);
        }
        self.interp.check_soft_limits(&self.settings, &target)?;
        let target = self.keep_out_clip(&target);
        self.move_mm(io, &target, Speed::Fixed(feed))?;
        self.state = State::Jog;
        Ok(())
    }

    /// A jog (`$J=`, the menu's) toward the tool magazine stops at the edge
    /// of its keep-out zone, a step's width short of it: the target moved
    /// back along the jog. One that starts at the edge going in moves nothing.
    #[inline(never)]
    fn keep_out_clip(&self, target: &[f32; N_AXES]) -> [f32; N_AXES] {
        let a = self.interp.pos_mm;
        let xyz = |p: &[f32; N_AXES]| [p[0], p[1], p[2]];
        let Some(t) = self.settings.station.keep_out_entry(xyz(&a), xyz(target)) else {
            return *target;
        };
        let d: [f32; 3] = core::array::from_fn(|i| target[i] - a[i]);
        let len = crate::math::sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        // 0.02 mm: two steps at the default 100 steps/mm, so the step grid
        // does not round the end point into the zone.
        let t = if len > 0.0 { t - 0.02 / len } else { 0.0 };
        let t = if t > 0.0 { t } else { 0.0 };
        let mut c = a;
        for i in 0..3 {
            c[i] = a[i] + d[i] * t;
        }
        c
    }

    /// One turn of every wait loop: top up segments, serve realtime.
    /// Fails when an alarm stops the machine meanwhile.
    pub fn wait_step(&mut self, io: &mut impl Io) -> CmdResult {
        self.keepalive(io);
        self.idle(io);
        if self.alarm.is_some() {
            Err(interp::Error::Alarm)
        } else if self.aborts != self.line_aborts {
            Err(interp::Error::Aborted)
        } else {
            Ok(())
        }
    }

    /// True when nothing is planned, prepared or stepping.
    pub fn motion_done(&self, io: &impl Io) -> bool {
        self.planner.is_empty() && !self.prep.is_busy() && !io.stepper().busy
    }

    /// Wait until every queued move has been stepped out.
    pub fn wait_idle(&mut self, io: &mut impl Io) -> CmdResult {
        loop {
            self.wait_step(io)?;
            if self.motion_done(io) {
                return Ok(());
            }
        }
    }

    /// While a serial line waits (M400, G4, G28, M0, a tool change, G37, a
    /// full planner ...): `busy:processing` every M113 interval (2 s by
    /// default, Marlin's), counted from the start of the line, so that no
    /// host times out (docs/SPEC.md §4). Every wait loop calls it through
    /// [`Machine::wait_step`]. Not for SD-job or menu lines: no host waits
    /// for those.
    pub fn keepalive(&mut self, io: &mut impl Io) {
        let every = self.host.busy_interval_s as u32 * 1000;
        if !self.serial_line || every == 0 {
            return;
        }
        let now = io.millis();
        if now.wrapping_sub(self.last_busy_ms) >= every {
            self.last_busy_ms = now;
            uwriteln!(io, "{}", F!("busy:processing")).ok();
        }
    }

    /// Top up the segment ring from the planner. Not while the ISR is
    /// stopped: it drops what it is given, so the whole queue would be
    /// prepared into it before the stop is served (an M112 sent behind a
    /// full queue was reported 0.75 s late).
    pub fn fill_segments(&mut self, io: &mut impl Io) {
        // A move the planner accepted without planning it yet (so that `ok`
        // went out sooner) is planned now, before prep looks at the ring.
        self.planner.flush(&self.settings);
        // At most one ring's worth per call, and none while the ISR is
        // stopped (after an emergency stop it throws segments away as fast
        // as they come: the whole planner queue was prepped before the next
        // poll, 0.7 s before the alarm was even reported). The space is asked
        // again for each segment: the board caps the queued motion time, not
        // only the slots.
        let mut room = io.segment_space();
        while room > 0 && io.segment_space() > 0 && !io.stepper_stopped() {
            room -= 1;
            match self.prep.next_segment(&mut self.planner) {
                Some(cmd) => {
                    if !io.push_segment(cmd) {
                        break;
                    }
                }
                None => break,
            }
        }
    }

    /// Main-loop housekeeping: segments, realtime requests, state.
    #[inline(never)]
    pub fn idle(&mut self, io: &mut impl Io) {
        self.fill_segments(io);
        let rt = io.poll();
        self.last_rt = rt;
        if rt.reset {
            self.soft_reset(io, rt.reset_moving);
        }
        if rt.estop && self.alarm != Some(Alarm::EmergencyStop) {
            self.raise(io, Alarm::EmergencyStop);
        }
        if rt.limit && self.alarm.is_none() {
            self.limit_axes = io.switches().home & 0b111;
            self.raise(io, Alarm::HardLimit);
        }
        if rt.hold && self.alarm.is_none() && !self.holding {
            self.holding = true;
            self.prep.hold();
            if self.state == State::Run || self.state == State::Idle {
                self.state = State::Hold;
            }
        }
        if rt.motion_ovr | rt.accessory_ovr != 0 {
            self.apply_overrides(io, rt.motion_ovr, rt.accessory_ovr);
        }
        if rt.resume && self.holding && !self.aborting {
            self.holding = false;
            if self.spindle_stopped {
                // 0x9E stopped it in the hold: back on before the motion.
                self.spindle_stopped = false;
                io.spindle(crate::overrides::spindle_duty(self.spindle_duty, self.spindle_pct));
            }
            if self.prep.is_held() || !io.stepper().busy {
                self.planner.cycle_reinitialize();
            }
            self.prep.resume();
            if self.state == State::Hold {
                self.state = State::Run;
            }
            self.fill_segments(io);
        }
        // grbl: a jog ends on 0x85 or on a feed hold, decelerating, with
        // every queued jog move dropped.
        if (rt.jog_cancel || rt.hold) && self.state == State::Jog && !self.aborting {
            self.aborting = true;
            if !self.holding {
                self.holding = true;
                self.prep.hold();
            }
        }
        if rt.abort && self.alarm.is_none() && !self.aborting {
            self.aborting = true;
            self.abort_keeps_spindle = rt.abort_keep_spindle;
            if !self.holding {
                self.holding = true;
                self.prep.hold();
            }
        }
        if self.aborting && (self.prep.is_held() || self.motion_done(io)) && !io.stepper().busy {
            self.finish_abort(io);
        }
        if self.limits_held != 0 {
            self.rearm_limits(io);
        }
        if rt.status {
            self.status_report(io);
        }
        if matches!(self.state, State::Run | State::Jog) && self.motion_done(io) {
            self.state = State::Idle;
        }
        io.background(self);
    }

    /// grbl's realtime overrides: the feed and rapid overrides re-plan the
    /// queued moves at once ([`Planner::set_overrides`]); the spindle
    /// override scales the spindle's duty now; 0x9E stops the spindle in a
    /// hold (again: on; `~` restores it); 0xA0/0xA1 toggle the coolant in
    /// Idle, Run or Hold (grbl's states for them).
    #[inline(never)]
    fn apply_overrides(&mut self, io: &mut impl Io, motion: u8, accessory: u8) {
        use crate::overrides::{accessory as acc, spindle_duty, Percent};
        let mut p = Percent { feed: self.planner.feed_override(), rapid: self.planner.rapid_override(), spindle: self.spindle_pct };
        p.apply_motion(motion);
        p.apply_spindle(accessory);
        if p != self.overrides() {
            // The next status report carries `Ov:` (grbl's refresh rule).
            self.report_count = 0;
        }
        self.planner.set_overrides(p.feed, p.rapid, &self.settings);
        let on = self.interp.spindle_on;
        if p.spindle != self.spindle_pct {
            self.spindle_pct = p.spindle;
            if on && !self.spindle_stopped {
                io.spindle(spindle_duty(self.spindle_duty, p.spindle));
            }
        }
        if accessory & acc::SPINDLE_STOP != 0 && self.holding && on {
            self.spindle_stopped = !self.spindle_stopped;
            io.spindle(if self.spindle_stopped { 0 } else { spindle_duty(self.spindle_duty, p.spindle) });
        }
        if accessory & (acc::FLOOD | acc::MIST) != 0 && matches!(self.state, State::Idle | State::Run | State::Hold) {
            let m = if self.interp.coolant_m != 9 {
                9
            } else if accessory & acc::FLOOD != 0 {
                8
            } else {
                7
            };
            self.interp.coolant_m = m;
            io.coolant(m != 9);
        }
    }

    /// The feed override (M220, the menu), for the queued moves too.
    pub fn set_feed_override(&mut self, pct: u16) {
        self.planner.set_overrides(pct, self.planner.rapid_override(), &self.settings);
    }

    /// The feed (programmed, times the feed override) and the spindle
    /// speed (times the spindle override; 0 when off), for `FS:` and the
    /// status screen.
    pub fn feed_and_speed(&self) -> (f32, f32) {
        let (f, s) = self.interp.feed_and_speed();
        (f * self.planner.feed_override() as f32 * 0.01, s * self.spindle_pct as f32 * 0.01)
    }

    /// The feed, rapid and spindle overrides in force, percent (`Ov:`).
    pub fn overrides(&self) -> crate::overrides::Percent {
        crate::overrides::Percent { feed: self.planner.feed_override(), rapid: self.planner.rapid_override(), spindle: self.spindle_pct }
    }

    /// The abort's deceleration has ended: drop the queue, keep the
    /// position, turn the spindle off. Waits in progress fail with
    /// `Error::Aborted`, so the line that was running stops too.
    fn finish_abort(&mut self, io: &mut impl Io) {
        self.aborting = false;
        self.holding = false;
        io.stop_motion();
        self.planner.clear();
        self.prep.reset();
        io.clear_stop();
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        // A cancelled jog leaves the spindle as it was (grbl); so does an
        // abort whose caller retracts the tool first.
        if self.state != State::Jog && !core::mem::take(&mut self.abort_keeps_spindle) {
            self.spindle_off(io);
        }
        if matches!(self.state, State::Hold | State::Run | State::Jog) {
            self.state = State::Idle;
        }
        self.aborts = self.aborts.wrapping_add(1);
    }

    /// 0x18 (Ctrl-X), grbl's soft reset. The RX interrupt has halted the
    /// stepper already; here every queue is dropped (planner, segments, the
    /// RX ring and the line being assembled), the spindle goes off, holds
    /// and aborts end, and the line being run (if any) stops without a
    /// reply. The position is kept, unless steps were still being produced
    /// (an abrupt stop may lose steps): then `ALARM:reset while moving`
    /// (grbl's ALARM:3), and homing or `$X` is needed. An alarm in force
    /// stays. Then grbl 1.1's banner, which grbl hosts (cncjs) wait for.
    #[inline(never)]
    pub fn soft_reset(&mut self, io: &mut impl Io, moving: bool) {
        io.stop_motion();
        self.planner.clear();
        self.prep.reset();
        if self.alarm.is_none() {
            io.clear_stop();
        }
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        self.spindle_off(io);
        // grbl's soft reset puts every override back to 100 %.
        self.planner.set_overrides(100, 100, &self.settings);
        self.spindle_pct = 100;
        self.holding = false;
        self.aborting = false;
        self.last_rt.home_tripped = false;
        self.last_rt.probe_tripped = false;
        self.apply_watch(io, 0, false);
        io.flush_rx();
        self.asm.reset();
        self.aborts = self.aborts.wrapping_add(1);
        self.silenced = self.serial_line;
        if self.alarm.is_none() {
            // Whatever ran (a move, homing, a tool change, a probe) is over.
            self.state = State::Idle;
        }
        if moving && self.alarm.is_none() {
            self.raise(io, Alarm::ResetWhileMoving);
        }
        uwrite!(io, "{}", F!("\r\nGrbl 1.1h ['$' for help]\r\n")).ok();
        if self.alarm.is_some() {
            uwriteln!(io, "{}", F!("[MSG:'$H'|'$X' to unlock]")).ok();
        }
    }

    /// Spindle and coolant off (and remembered as off): aborts, program end.
    pub fn spindle_off(&mut self, io: &mut impl Io) {
        self.interp.spindle_on = false;
        self.spindle_stopped = false;
        self.interp.coolant_m = 9;
        io.spindle(0);
        io.coolant(false);
    }

    /// A feed hold is in force (`!`, M25, the menu) and not yet resumed.
    pub fn is_holding(&self) -> bool {
        self.holding
    }

    /// An abort is decelerating.
    pub fn is_aborting(&self) -> bool {
        self.aborting
    }

    /// Enter the alarm state: stop steps, spindle off, forget the queue.
    #[inline(never)]
    pub fn raise(&mut self, io: &mut impl Io, alarm: Alarm) {
        io.stop_motion();
        io.spindle(0);
        io.coolant(false);
        // Off for the interpreter too: an S word alone must not restart it.
        self.interp.spindle_on = false;
        self.interp.coolant_m = 9;
        if alarm == Alarm::EmergencyStop {
            io.drivers(false);
        }
        self.alarm = Some(alarm);
        self.state = State::Alarm;
        // A probe that ended its move untouched stopped cleanly: the
        // position is still exact. Every other alarm may have lost steps.
        if alarm != Alarm::ProbeFailed {
            self.homed = 0;
        }
        self.limits_held = 0;
        self.unlocked = false;
        self.holding = false;
        self.aborting = false;
        self.planner.clear();
        self.prep.reset();
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        if self.grbl_replies {
            let (code, why) = (alarm.grbl_code(), alarm.message());
            uwriteln!(io, "{}{}{}{}{}", F!("ALARM:"), code, F!("\n[MSG:"), why, F!("; $H or $X to continue]")).ok();
        } else {
            uwriteln!(io, "ALARM:{}", alarm.message()).ok();
            uwriteln!(io, "{}", F!("echo:home (G28) or M999 to continue")).ok();
        }
    }

    /// M999: leave the alarm state. Position stays unknown until homed.
    pub fn clear_alarm(&mut self, io: &mut impl Io) {
        // A switch still closed (the axis stopped on it) is not armed until
        // it opens, or the alarm would come back at once.
        self.limits_held = io.switches().home & 0b111;
        self.held_since_ms = io.millis() as u16;
        io.clear_stop();
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
        self.alarm = None;
        self.unlocked = true;
        self.state = State::Idle;
        self.apply_watch(io, 0, false);
    }

    /// Arm the hard limit of each held axis (see [`Machine::limits_held`])
    /// whose switch has read open for [`LIMIT_REARM_MS`]: longer than a
    /// switch's bounce, so it is not re-armed on a bounce.
    fn rearm_limits(&mut self, io: &mut impl Io) {
        let now = io.millis() as u16;
        let open = self.limits_held & !io.switches().home;
        if open == 0 {
            self.held_since_ms = now;
        } else if now.wrapping_sub(self.held_since_ms) >= LIMIT_REARM_MS {
            self.limits_held &= !open;
            self.apply_watch(io, 0, false);
        }
    }

    /// Tell the ISR what to watch. Hard limits stay off through a whole
    /// homing cycle (`State::Home`), pull-offs included, as in grbl: an axis
    /// not yet homed may rest on its closed switch, and a real switch stays
    /// closed for its hysteresis and bounces after it opens.
    pub fn apply_watch(&mut self, io: &mut impl Io, homing: u8, probe: bool) {
        let arm = self.settings.hard_limits && homing == 0 && self.state != State::Home;
        let limits = if arm { 0b111 & !self.limits_held } else { 0 };
        // A real switch that closed at machine 0 may stay closed for its
        // hysteresis; homing checked that the pull-off clears it.
        let mut release = [0u16; 3];
        let pulloff = if self.settings.homing_pulloff_mm >= 0.1 { self.settings.homing_pulloff_mm } else { 0.1 };
        for (a, r) in release.iter_mut().enumerate() {
            let steps = crate::math::round_i32(pulloff * self.settings.steps_per_mm[a]);
            *r = steps.clamp(0, u16::MAX as i32) as u16;
        }
        io.set_watch(Watch {
            homing,
            probe,
            limits,
            homed: self.homed,
            invert_dir: self.settings.invert_dir_mask,
            invert_inputs: self.settings.invert_input_mask,
            release,
        });
    }

    /// `?`: one grbl 1.1 status line.
    #[inline(never)]
    pub fn status_report(&mut self, io: &mut impl Io) {
        let st = io.stepper();
        // Steps are being produced: never `Idle`, whatever else is going on.
        let state = if self.state == State::Idle && st.busy { State::Run } else { self.state };
        // `$10` bit 0: the machine position, else the work position;
        // bit 1: the buffer field (grbl's).
        let mask = self.settings.status_mask;
        let mpos = self.steps_to_mm(st.position);
        let wpos = self.interp.work_user(mpos);
        let inches = self.settings.report_inches;
        if mask & 1 != 0 {
            uwrite!(io, "<{}{}", state.name(), F!("|MPos:")).ok();
            dollar::coords(io, &crate::frame::user_from_internal(mpos), inches);
        } else {
            uwrite!(io, "<{}{}", state.name(), F!("|WPos:")).ok();
            dollar::coords(io, &wpos, inches);
        }
        if mask & 2 != 0 {
            uwrite!(io, "|Bf:{},{}", self.planner.free() as u16, (255 - io.rx_pending().min(255)) as u16).ok();
        }
        let (feed, rpm) = self.feed_and_speed();
        // Ln: the block number of the move being prepared (grbl with line
        // numbers on); none for unnumbered lines.
        if let Some(b) = self.planner.current_block().filter(|b| b.line != 0) {
            uwrite!(io, "{}{}", F!("|Ln:"), b.line).ok();
        }
        uwrite!(io, "{}", F!("|FS:")).ok();
        if inches {
            uwrite!(io, "{}", crate::fixed::Tenths(crate::math::round_i32(feed * (10.0 / 25.4)))).ok();
        } else {
            uwrite!(io, "{}", feed as i32).ok();
        }
        uwrite!(io, ",{}", rpm as i32).ok();
        // Pn: the inputs that read triggered (grbl's letters; C is the
        // carousel's home switch, P the tool setter, G38's probe input).
        // Letters are built as bytes: a `&str` per letter would sit in RAM.
        let sw = io.switches();
        let mut pn = Letters::new(b"|Pn:");
        pn.push(sw.home & 1 != 0, b'X');
        pn.push(sw.home & 2 != 0, b'Y');
        pn.push(sw.home & 4 != 0, b'Z');
        pn.push(sw.tool_setter, b'P');
        pn.push(sw.carousel_home, b'C');
        pn.write(io);
        // WCO and Ov in turn, every few reports (grbl sends them on a
        // refresh count too; both change rarely).
        self.report_count = self.report_count.wrapping_add(1);
        match self.report_count % 10 {
            0 => {
                uwrite!(io, "{}", F!("|WCO:")).ok();
                let m = crate::frame::user_from_internal(mpos);
                let mut wco = m;
                for a in 0..3 {
                    wco[a] = m[a] - wpos[a];
                }
                dollar::coords(io, &wco, inches);
            }
            1 => {
                let o = self.overrides();
                // (No literal text in the format: ufmt keeps it in RAM.)
                uwrite!(io, "{}{}", F!("|Ov:"), o.feed).ok();
                uwrite!(io, "{}{}", F!(","), o.rapid).ok();
                uwrite!(io, "{}{}", F!(","), o.spindle).ok();
            }
            _ => {}
        }
        let mut acc = Letters::new(b"|A:");
        acc.push(self.interp.spindle_on, b'S');
        acc.push(self.interp.coolant_m == 8, b'F');
        acc.push(self.interp.coolant_m == 7, b'M');
        acc.write(io);
        uwriteln!(io, "|T:{}>", self.atc.spindle_tool()).ok();
    }

    /// Steps → mm for X, Y, Z (E in carousel units).
    pub fn steps_to_mm(&self, steps: [i32; N_AXES]) -> [f32; N_AXES] {
        let mut mm = [0.0; N_AXES];
        for a in 0..N_AXES {
            mm[a] = steps[a] as f32 / self.settings.steps_per_mm[a];
        }
        mm
    }

    /// Print `x,y,z` with three decimals.
    pub fn write_xyz(&self, io: &mut impl Io, v: [f32; N_AXES]) {
        uwrite!(io, "{},{},{}", Micros::from_mm(v[0]), Micros::from_mm(v[1]), Micros::from_mm(v[2])).ok();
    }

    /// Put `s` in force as the settings (the planner and the interpreter's
    /// caches are told).
    pub fn set_settings(&mut self, s: Settings) {
        self.settings = s;
        self.settings_loaded();
    }

    /// The settings changed in place: the planner's and the interpreter's
    /// caches follow.
    fn settings_loaded(&mut self) {
        self.planner.settings_changed();
        self.interp.settings_changed();
    }

    /// Save the settings image to EEPROM (M500).
    pub fn save_settings(&mut self, io: &mut impl Io) {
        self.interp.store_settings(&mut self.settings);
        let img = self.settings.to_bytes();
        io.eeprom_write(EEPROM_SETTINGS_ADDR, &img);
    }

    /// Load the settings from EEPROM (M501). False if the image is invalid.
    pub fn load_settings(&mut self, io: &mut impl Io) -> bool {
        let mut img = [0u8; Settings::IMAGE_LEN];
        io.eeprom_read(EEPROM_SETTINGS_ADDR, &mut img);
        let loaded = self.settings.load_image(&img);
        self.settings_loaded();
        if loaded {
            self.interp.load_settings(&self.settings);
        }
        loaded
    }

    /// Wait until the queued motion ends or the ISR latched a trip
    /// (homing switch or probe). Returns true if it tripped.
    pub fn wait_motion_or_trip(&mut self, io: &mut impl Io) -> Result<bool, interp::Error> {
        loop {
            self.keepalive(io);
            self.wait_step(io)?;
            if self.last_rt.home_tripped || self.last_rt.probe_tripped {
                return Ok(true);
            }
            if self.motion_done(io) {
                // The trip may have stopped the ISR after this loop's poll:
                // ask the stepper itself, or a trip in the last queued
                // segments reads as "never tripped".
                return Ok(io.stepper().tripped);
            }
        }
    }

    /// After the ISR stopped on a trip (or a finished move): drop whatever is
    /// left of the queue and take the stepper's position as the truth.
    pub fn resync_after_stop(&mut self, io: &mut impl Io) {
        io.stop_motion();
        self.planner.clear();
        self.prep.reset();
        io.clear_stop();
        self.last_rt.home_tripped = false;
        self.last_rt.probe_tripped = false;
        let p = io.stepper().position;
        self.planner.set_position(p);
        self.interp.sync_position(&self.settings, p);
    }

    /// M0/M1: wait for `~` (resume).
    #[inline(never)]
    pub fn pause_until_resume(&mut self, io: &mut impl Io) -> CmdResult {
        let prev = self.state;
        self.state = State::Hold;
        loop {
            self.keepalive(io);
            self.fill_segments(io);
            let rt = io.poll();
            self.last_rt = rt;
            if rt.estop {
                self.raise(io, Alarm::EmergencyStop);
                return Err(interp::Error::Alarm);
            }
            if rt.status {
                self.status_report(io);
            }
            if rt.resume {
                self.state = prev;
                return Ok(());
            }
            if rt.abort {
                // Nothing is moving during M0/M1 (the queue drained first).
                self.finish_abort(io);
                return Err(interp::Error::Aborted);
            }
            io.background(self);
        }
    }

    /// One homing seek, the only one (G28's axes and the carousel's G205):
    /// move `axis` by up to `steps` (signed, toward its switch) with the ISR
    /// watching the switch (`set_watch`'s homing mask bit `axis`: X, Y, Z or
    /// the carousel on E). Returns true when the switch tripped; the axis
    /// position is then 0 at the trip step (docs/SPEC.md §6: Marlin's convention).
    pub(crate) fn seek_switch(&mut self, io: &mut impl Io, axis: usize, steps: i32, feed: f32) -> Result<bool, interp::Error> {
        self.apply_watch(io, 1 << axis, false);
        let mut target = io.stepper().position;
        target[axis] += steps;
        let r = self.queue_line(io, target, Speed::Fixed(feed)).and_then(|_| self.wait_motion_or_trip(io));
        self.apply_watch(io, 0, false);
        let tripped = r?;
        if tripped {
            let trip = io.stepper().trip_position;
            let mut now = io.stepper().position;
            now[axis] -= trip[axis];
            io.set_stepper_position(now);
        }
        self.resync_after_stop(io);
        Ok(tripped)
    }

    /// A linear axis' homing seek toward its switch (−) by up to `dist_mm`.
    fn home_seek(&mut self, io: &mut impl Io, axis: usize, dist_mm: f32, feed: f32) -> Result<bool, interp::Error> {
        let steps = crate::math::round_i32(dist_mm * self.settings.steps_per_mm[axis]);
        self.seek_switch(io, axis, -steps, feed)
    }

    /// Move `axis` away from its switch by `dist_mm` (no switch watching:
    /// the caller is in `State::Home`, so hard limits are off), then check
    /// the switch let go: a pull-off shorter than the switch's hysteresis
    /// fails here, not later as a hard limit on the first move (grbl's
    /// alarm 8). The switch opened hysteresis-worth of travel before the
    /// end of the pull-off, so its bounce is long over.
    fn home_pulloff(&mut self, io: &mut impl Io, axis: usize, dist_mm: f32, feed: f32) -> CmdResult {
        let mut target = io.stepper().position;
        target[axis] += crate::math::round_i32(dist_mm * self.settings.steps_per_mm[axis]);
        self.queue_line(io, target, Speed::Fixed(feed))?;
        self.wait_idle(io)?;
        if io.switches().home & (1 << axis) != 0 {
            return self.home_fail(io);
        }
        Ok(())
    }

    fn home_fail(&mut self, io: &mut impl Io) -> CmdResult {
        self.raise(io, Alarm::HomingFailed);
        Err(interp::Error::HomingFailed)
    }
}

/// G28: home the axes in `mask` in the order Z, Y, X: fast seek, back off,
/// slow seek, back off. Position 0 is where the switch trips on the slow
/// approach; the final back-off is counted (position = pull-off distance).
#[inline(never)]
pub fn home(m: &mut Machine, io: &mut impl Io, mask: u8) -> CmdResult {
    if m.alarm.is_some() {
        // Homing is the way out of an alarm (except M112, checked by the
        // caller). Clear it first: waiting for the (already stopped) motion
        // fails while an alarm is set.
        m.clear_alarm(io);
    }
    m.wait_idle(io)?;
    io.drivers(true);
    let prev = m.state;
    m.state = State::Home;
    // Hard limits off for the whole cycle (see `apply_watch`).
    m.apply_watch(io, 0, false);
    let r = home_axes(m, io, mask);
    if m.state == State::Home {
        m.state = if prev == State::Alarm || prev == State::Home { State::Idle } else { prev };
    }
    // Re-armed only now, with every homed axis pulled off its switch (or
    // after a failure, with the alarm raised).
    m.limits_held &= !m.homed;
    m.apply_watch(io, 0, false);
    r?;
    let p = io.stepper().position;
    // Also starts the hard-limit bookkeeping afresh: the homed axes left
    // their switches (`ChunkWatch::release`).
    io.set_stepper_position(p);
    m.planner.set_position(p);
    m.interp.sync_position(&m.settings, p);
    Ok(())
}

/// The per-axis part of [`home`], in `State::Home`.
fn home_axes(m: &mut Machine, io: &mut impl Io, mask: u8) -> CmdResult {
    let s = m.settings;
    for axis in [2usize, 1, 0] {
        if mask & (1 << axis) == 0 {
            continue;
        }
        m.homed &= !(1 << axis);
        // `max` without f32::max (compiler-builtins' fmaximum_numf, 142 bytes).
        let pulloff = if s.homing_pulloff_mm >= 0.1 { s.homing_pulloff_mm } else { 0.1 };
        if io.switches().home & (1 << axis) != 0 {
            // Starting on the switch: move off it first (fails if it stays closed).
            m.home_pulloff(io, axis, pulloff, s.homing_feed_mm_per_min)?;
        }
        let travel = s.travel_mm[axis] * 1.1;
        if !m.home_seek(io, axis, travel, s.homing_seek_mm_per_min)? {
            return m.home_fail(io);
        }
        m.home_pulloff(io, axis, pulloff, s.homing_seek_mm_per_min)?;
        if !m.home_seek(io, axis, pulloff * 2.0, s.homing_feed_mm_per_min)? {
            return m.home_fail(io);
        }
        m.home_pulloff(io, axis, pulloff, s.homing_feed_mm_per_min)?;
        m.homed |= 1 << axis;
    }
    Ok(())
}
