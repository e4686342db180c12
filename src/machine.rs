//! The machine controller: everything between the serial bytes and the
//! segment ring, as plain logic over the [`Io`] trait.
//!
//! ```text
//!  bytes ─► protocol::LineAssembler ─► protocol::LineChecker ─► gcode::parse
//!        ─► Interp::next (gcode::interp: modal state, returns a Command)
//!        ─► Machine::dispatch ─► Machine::queue_line ─► Planner ─► Prep ─► Stepper::push_segment
//! ```
//!
//! This file owns the [`Machine`] itself (its state, construction and
//! boot); the work is in its children, one job each:
//!
//! | child | what it owns |
//! |---|---|
//! | [`io`] | the [`Io`] trait: the hardware as the controller sees it |
//! | [`line`](mod@line) | bytes into lines, the resend protocol, replies, running a line |
//! | [`dispatch`] | carrying out each `Command` of the interpreter |
//! | [`motion`] | the one way into the planner, jogs, G38, every wait |
//! | [`realtime`] | the main loop's turn: realtime requests, overrides, M0 |
//! | [`alarm`] | alarms, hard limits, aborts, the soft reset |
//! | [`status`] | `?`'s status line |
//! | [`settings`] | settings put in force, stored and loaded |
//! | [`homing`] | G28 / `$H` and the one switch seek |
//! | [`toolchange`] | T/M6, M61, G10 L1, the EEPROM journal |
//! | [`carousel`] | G201–G205 and carousel homing |
//! | [`setter`] | G37 |
//! | [`report`] | M114, M119, M503 |
//! | [`startup`] | grbl's startup blocks and `$I` text |
//! | [`rebuild`] | run from line: the scan's notes and the approach |
//!
//! `Machine::run_line` asks the interpreter for a line's commands one at a
//! time and carries each out. Every move, whoever makes it, enters the
//! planner through [`Machine::queue_line`]: the interpreter's (via
//! `Machine::dispatch`'s `Command::Move`), homing's and the carousel's
//! switch seeks (`Machine::seek_switch`, the one homing seek), and the
//! runners, which express their sequences over it ([`Machine::move_mm`]).
//! Nothing here calls back into the interpreter.
//!
//! The firmware implements [`Io`] over `board` (AVR); host tests implement it
//! with a fake stepper, so the whole controller (alarms, homing, hold, the
//! protocol replies) is tested without a simulator.
//!
//! Nothing here blocks without serving realtime requests: every wait goes
//! through [`Machine::wait_step`], which tops up the segment ring and handles
//! `?`, `!`, `~`, M112 and switch trips.

use crate::config::Settings;
use crate::fixed::Micros;
use crate::flash::FStr;
use crate::gcode::interp::{self, Interp};
use crate::planner::Planner;
use crate::protocol::LineChecker;
use crate::stepper::Prep;
use crate::N_AXES;
use ufmt::{uwrite, uwriteln};

pub mod alarm;
pub mod carousel;
pub mod dispatch;
pub mod homing;
pub mod io;
pub mod line;
pub mod motion;
pub mod realtime;
pub mod rebuild;
pub mod report;
pub mod setter;
pub mod settings;
pub mod startup;
pub mod status;
pub mod toolchange;

pub use alarm::Alarm;
pub use homing::home;
pub use io::{Host, Inputs, Io, Outputs, Realtime, SdJobFlags, Stepper, StepperStatus, Storage, Switches};

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

/// Interpreter-level error shown to the host as `Error:<text>`.
pub type CmdResult = Result<(), interp::Error>;

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

/// Where the line being run came from. One at a time: serial lines, SD
/// job lines and menu lines all run from the main loop's top level, never
/// inside another line's wait (the menu's commands wait for the top level,
/// the SD job's next line for the main loop's job turn).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum LineSource {
    /// No line is running.
    None,
    /// A serial line: its host waits for the `ok` (keepalive), and its
    /// block number tags its moves.
    Serial,
    /// A serial line during which a soft reset (0x18) happened: it ends
    /// without an `ok` or an error (grbl drops it).
    SerialReset,
    /// A serial line whose `ok` already went out: its last command, a
    /// move that passed every check, is only waiting for its planner slot
    /// (see `Machine::ack_early`). Nothing more is printed for it.
    SerialAcked,
    /// A line of the SD job: the only lines that may move while a job runs.
    Job,
    /// A line the menu runs, or a startup block: no host waits for it.
    Menu,
}

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
    /// Where the line being run came from (serial, SD job, menu, none).
    source: LineSource,

    /// The last poll reported a homing or probe trip (the ISR's latch holds
    /// it until the stop is cleared): all that is kept of a poll (the whole
    /// `Realtime`, 14 B, was copied on every main-loop turn).
    tripped: bool,
    /// The host numbers its lines (so dropped lines get `Resend:`): a
    /// property of the serial host's last line, kept after it ended (a
    /// line dropped after an overrun is answered as the one before it) and
    /// while other sources run, so not part of [`LineSource`].
    numbered: bool,
    /// An SD job is under way: serial lines may only ask for status. Not
    /// part of [`LineSource`]: the job goes on across its lines, and serial
    /// lines run between them.
    pub sd_job: bool,
    /// `io.millis()` when the running SD job started (M31).
    pub job_start_ms: u32,
    /// An abort is decelerating; the queue is dropped once stopped.
    aborting: bool,
    /// The abort decelerating leaves the spindle on (see
    /// [`Realtime::abort_keep_spindle`]).
    abort_keeps_spindle: bool,
    /// Aborts completed so far (wraps); waits fail while it differs from
    /// `line_aborts`, the count when the current line started.
    pub aborts: u8,
    line_aborts: u8,
    /// A soft reset flushed the input: the line being assembled (in the
    /// caller's assembler, see [`Machine::push_bytes`]) is dropped before
    /// the next byte.
    input_flushed: bool,
    /// Run from line: what the scan keeps (4 bytes).
    pub rebuild: rebuild::Rebuild,
}

impl Default for Machine {
    fn default() -> Self {
        Machine::new()
    }
}

impl Machine {
    /// A machine with default settings (the EEPROM is read in [`Machine::boot`]).
    pub const fn new() -> Machine {
        let mut m = Machine::with_settings(Settings::DEFAULT);
        m.setter = crate::toolsetter::Setter::DEFAULT;
        m
    }

    /// Build the machine in `slot` with the factory settings read from flash.
    /// The firmware's machine is a zeroed static built by this at boot: a
    /// `static` initialised with [`Machine::new`] would carry a 1.5 KB image
    /// in flash (`.data`) of which 71 bytes are not zero. Not inlined, so no
    /// machine-sized temporary stays in the caller's (never-returning) frame.
    // stack: out of the never-returning main frame (this file's two inlined: stack high-water 1734 -> 2668 B)
    #[inline(never)]
    pub fn init(slot: &mut core::mem::MaybeUninit<Machine>) -> &mut Machine {
        // Built with zeroed settings, which LLVM writes in place, then the
        // defaults copied in from flash: with the defaults' call in the
        // initialiser the whole machine was built in a 1.5 KB temporary,
        // the deepest stack of a run.
        // The tool setter's record stays zero: `boot` loads it (or its
        // default, from flash). As a value its default was a 24-byte
        // template in RAM (`.data`), and read here a 24-byte temporary in
        // this frame, the deepest of the boot.
        let m = slot.write(Machine::with_settings(Settings::ZEROED));
        m.settings.reset_to_defaults();
        m
    }

    /// A machine with `settings`, the tool setter's record all zero (the
    /// callers set it).
    pub const fn with_settings(settings: Settings) -> Machine {
        Machine {
            settings,
            planner: Planner::new(),
            prep: Prep::new(),
            interp: Interp::new(),
            atc: crate::atc::Atc::new(),
            setter: crate::toolsetter::Setter { x_um: 0, y_um: 0, beam_z_um: 0, beam_width_um: 0, ref_length_um: 0, ref_diameter_um: 0 },
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
            source: LineSource::None,
            tripped: false,
            spindle_pct: 100,
            spindle_duty: 0,
            spindle_stopped: false,
            numbered: false,
            sd_job: false,
            job_start_ms: 0,
            aborting: false,
            abort_keeps_spindle: false,
            aborts: 0,
            line_aborts: 0,
            input_flushed: false,
            rebuild: rebuild::Rebuild::OFF,
        }
    }

    /// Start-up: load settings, print the banner and the reset reason.
    // stack: out of the never-returning main frame (this file's two inlined: stack high-water 1734 -> 2668 B)
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
    pub fn firmware_line(&self, io: &mut impl ufmt::uWrite) {
        uwriteln!(
            io,
            "{}{}{}",
            F!("FIRMWARE_NAME:MillFW "),
            crate::FIRMWARE_VERSION,
            F!(" FIRMWARE_URL:none PROTOCOL_VERSION:1.0 MACHINE_TYPE:Mill EXTRUDER_COUNT:1 AXIS_COUNT:3 TOOLS:12")
        )
        .ok();
    }

    /// A feed hold is in force (`!`, M25, the menu) and not yet resumed.
    pub fn is_holding(&self) -> bool {
        self.holding
    }

    /// An abort is decelerating.
    pub fn is_aborting(&self) -> bool {
        self.aborting
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
    pub fn write_xyz(&self, io: &mut impl ufmt::uWrite, v: [f32; N_AXES]) {
        uwrite!(io, "{},{},{}", Micros::from_mm(v[0]), Micros::from_mm(v[1]), Micros::from_mm(v[2])).ok();
    }
}

#[cfg(test)]
mod tests;
