//! The virtual machine: the firmware ELF running in simavr (ATmega2560 at
//! 16 MHz) inside a modelled RAMPS machine.
//!
//! Owns one simavr instance and the Rust state its callbacks feed:
//! [`Recorder`] (step/dir/enable pins), [`Physics`] (switch inputs),
//! [`IsrTracker`] (per-vector service times), the host link on UART0 and the
//! spindle output. All hooks are simavr IRQ notifications or cycle timers;
//! nothing runs per instruction.
//!
//! simavr quirks this module works around (docs/SPEC.md §14, simavr-ffi 1.2.7):
//! - **Host habits.** UART0's stdout echo and its `usleep` on UCSRnA polling
//!   are switched off (`AVR_IOCTL_UART_SET_FLAGS` with neither STDIO nor
//!   POLL_SLEEP), and `avr->sleep` (which `usleep`s to keep wall-clock pace on
//!   SLEEP) is replaced with a no-op.
//! - **One instruction per `avr_run`.** simavr resets `run_cycle_limit` to 1
//!   on every reset, so each `avr_run` call executes a single instruction.
//!   The VM raises it to `batch_cycles` after every reset; simavr still stops
//!   at every due cycle timer and pending interrupt, so behaviour is unchanged.
//! - **Watchdog reset zeroes `avr->cycle`**, clears PINx and drops all cycle
//!   timers. The VM wraps `avr->reset` to add the old count to its own base
//!   ([`Vm::cycles`] is monotonic across resets), then re-applies every input
//!   level, re-arms its timers and tells the recorder that the pins floated.
//! - **Pulled-up inputs are re-raised on every PORTx/DDRx write.** Inputs are
//!   driven as the port's external state (`AVR_IOCTL_IOPORT_SET_EXTERNAL`) and
//!   additionally raised on the pin IRQ, so the firmware sees the level at
//!   once and keeps seeing it. After a reset the PINx bit and the pin IRQ's
//!   cached value are written directly (a raise of an unchanged value would be
//!   filtered and PINx would stay 0).
//! - **Interrupt nesting.** simavr tracks at most 64 nested interrupts. The VM
//!   watches each vector's "running" IRQ and stops with
//!   [`VmError::InterruptNesting`] beyond `max_interrupt_nesting` (60).
//! - **Crashes.** `cpu_Crashed` (PC past flash), `cpu_Done` (SLEEP with
//!   interrupts off) and invalid opcodes (simavr only logs and skips them) stop
//!   the VM with an error carrying the PC.
//! - **UART timing.** simavr counts 11 bits per byte (it always adds a parity
//!   bit): serial in simulation is ~10 % slower than at the real baud rate. The
//!   host link paces bytes with simavr's own `cycles_per_byte` for UART0, so it
//!   follows the firmware's UBRR setting.
//! - **UART receiver buffer.** simavr buffers 64 received bytes where the
//!   hardware holds 2, and drops bytes while RXEN is 0. [`Vm::send`] is a host
//!   with ideal flow control: it holds bytes while RXEN is 0 or simavr's FIFO
//!   is full (its XOFF IRQ). [`Vm::send_unpaced_flood`] is a host without any:
//!   one byte per byte-time regardless, and a byte that arrives while 2 unread
//!   bytes are waiting (or while RXEN is 0) is lost and DOR set, as on the
//!   hardware's 2-byte FIFO. The decision is taken when the byte is handed to
//!   simavr, one byte-time before the hardware would take it, so the model
//!   loses bytes slightly more eagerly than the chip.
//! - **Interrupt entry is free in simavr** (the 5-cycle response is not
//!   charged), so simulated firmware has 5 cycles per interrupt to spare; ISR
//!   statistics add them back ([`crate::isr::HW_OVERHEAD_CYCLES`]).
//! - **TCNTn is lost while a timer is stopped.** simavr restarts a timer from
//!   0 when its clock is switched on, so "preload TCNT, then start the clock"
//!   (grbl's step-pulse timer) comes out far too long. With
//!   `fix_tcnt_on_clock_start` (default on) the VM wraps every TCCRnB write
//!   handler: when the clock stops it freezes the current count into TCNTn (as
//!   the hardware keeps it), and when the clock starts it writes TCNTn back
//!   through simavr's own TCNT handler, so counting resumes from the frozen or
//!   preloaded value.
//! - Not worked around (the firmware must not depend on them): setting an
//!   interrupt-enable bit while its flag is already set does not fire at once
//!   (simavr waits for the next event); a low level on an INTn pin sets its
//!   flag even while that interrupt is disabled (clear EIFR before enabling).

use crate::boot;
use crate::elf::ElfSymbols;
use crate::host::{is_reply_end, StreamOptions, StreamReport, Streamer};
use crate::isr::{IsrStats, IsrTracker, STEPPER_VECTOR};
use crate::oled::Sh1106;
use crate::physics::{MachineConfig, Physics, ToolSetter};
use crate::pins::{Axis, Input, Pin, PinMap, SignalKind, COOLANT, SPINDLE_PWM};
use crate::recorder::{Recorder, RecorderConfig, Violation};
use crate::report::{AxisReport, Report, ResetKind, ResetRecord, UartReport};
use crate::sdcard::SdCard;
use crate::spindle;
use serde::Serialize;
use simavr_ffi as ffi;
use std::collections::VecDeque;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once};

/// simavr's `AVR_IOCTL_DEF(a, b, c, d)`.
const fn ioctl_def(a: u8, b: u8, c: u8, d: u8) -> u32 {
    ((a as u32) << 24) | ((b as u32) << 16) | ((c as u32) << 8) | (d as u32)
}
const fn ioctl_ioport_getirq(port: u8) -> u32 {
    ioctl_def(b'i', b'o', b'g', port)
}
const fn ioctl_ioport_set_external(port: u8) -> u32 {
    ioctl_def(b'i', b'o', b'p', port)
}
const fn ioctl_uart_getirq(name: u8) -> u32 {
    ioctl_def(b'u', b'a', b'r', name)
}
const fn ioctl_uart_set_flags(name: u8) -> u32 {
    ioctl_def(b'u', b'a', b's', name)
}
/// simavr's `AVR_IOCTL_TWI_GETIRQ(0)` / `AVR_IOCTL_SPI_GETIRQ(0)`: the
/// ATmega2560 declares its TWI and SPI without a name (name 0).
const IOCTL_TWI_GETIRQ: u32 = ioctl_def(b't', b'w', b'i', 0);
const IOCTL_SPI_GETIRQ: u32 = ioctl_def(b's', b'p', b'i', 0);
/// SD card chip select: PB0 (D53).
const SD_CS: Pin = Pin::new(b'B', 0);
const IOCTL_EEPROM_GET: u32 = ioctl_def(b'e', b'e', b'g', b'p');
const IOCTL_EEPROM_SET: u32 = ioctl_def(b'e', b'e', b's', b'p');

/// MCUSR: reset flags (PORF bit 0, EXTRF bit 1, BORF bit 2, WDRF bit 3).
const MCUSR: usize = 0x54;
/// OCR1AL's data-space address (ATmega2560 register summary).
const OCR1AL: u16 = 0x88;
/// EEPROM size of the ATmega2560, bytes.
pub const EEPROM_SIZE: usize = 4096;
/// Last SRAM address of the ATmega2560.
pub const RAMEND: u16 = 0x21FF;
/// Byte the firmware paints free RAM with at boot.
pub const STACK_PAINT: u8 = 0xC5;

extern "C" {
    fn vsnprintf(buf: *mut c_char, n: usize, fmt: *const c_char, ap: *mut ffi::__va_list_tag) -> c_int;
    fn free(p: *mut c_void);
}

/// Why the VM stopped or could not start.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum VmError {
    /// The ELF could not be loaded.
    Load(String),
    /// simavr declared the core crashed (e.g. PC ran past flash).
    Crashed { pc: u32, cycle: u64 },
    /// SLEEP with interrupts disabled: the chip can never wake (`cpu_Done`).
    Halted { pc: u32, cycle: u64 },
    /// More nested interrupts than `max_interrupt_nesting`.
    InterruptNesting { depth: u32, vector: u8, pc: u32, cycle: u64 },
    /// An instruction simavr does not know (flash garbage, a bad jump).
    BadOpcode { pc: u32, opcode: u16, cycle: u64 },
    /// A wait did not finish in time.
    Timeout { what: String, waited_s: f64 },
}

impl std::fmt::Display for VmError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            VmError::Load(s) => write!(f, "cannot load firmware: {s}"),
            VmError::Crashed { pc, cycle } => write!(f, "firmware crashed at PC 0x{pc:05x} (cycle {cycle})"),
            VmError::Halted { pc, cycle } => {
                write!(f, "firmware halted (SLEEP with interrupts off) at PC 0x{pc:05x} (cycle {cycle})")
            }
            VmError::InterruptNesting { depth, vector, pc, cycle } => {
                write!(f, "interrupt nesting overflow: depth {depth} entering vector {vector} at PC 0x{pc:05x} (cycle {cycle})")
            }
            VmError::BadOpcode { pc, opcode, cycle } => {
                write!(f, "invalid opcode 0x{opcode:04x} at PC 0x{pc:05x} (cycle {cycle})")
            }
            VmError::Timeout { what, waited_s } => write!(f, "timeout after {waited_s:.3} s waiting for {what}"),
        }
    }
}

impl std::error::Error for VmError {}

/// Everything a [`Vm`] needs to start.
#[derive(Clone, Debug)]
pub struct VmConfig {
    /// Firmware ELF.
    pub elf: PathBuf,
    /// CPU clock, Hz.
    pub frequency_hz: u32,
    /// The machine around the chip.
    pub machine: MachineConfig,
    /// Recorder limits and analysis parameters (`frequency_hz` is overwritten).
    pub recorder: RecorderConfig,
    /// `run_until` conditions are checked at least this often, cycles (and
    /// also whenever a line arrives on the UART). Default 1600 (100 µs).
    pub check_interval_cycles: u64,
    /// Cycles simavr may run per `avr_run` call between timers. Default 1024.
    pub batch_cycles: u64,
    /// Stop with an error beyond this interrupt nesting depth. Default 60.
    pub max_interrupt_nesting: u32,
    /// Treat an invalid opcode as a crash. Default true.
    pub stop_on_bad_opcode: bool,
    /// Default timeout of [`Vm::command`], simulated seconds. Default 60.
    pub command_timeout_s: f64,
    /// Keep TCNTn across clock stop/start like the hardware (module docs). Default true.
    pub fix_tcnt_on_clock_start: bool,
    /// The stock bootloader (Intel hex), loaded at the boot section with
    /// BOOTRST and the fuses of a board as sold ([`crate::boot`]): every
    /// reset starts it, and it starts the application. Default None: the
    /// chip starts at the application's reset vector.
    pub bootloader: Option<PathBuf>,
    /// Leave the application space erased (0xFF) instead of loading the
    /// ELF's image: a board with only the bootloader, to flash through it.
    /// The ELF is still read for its symbols. Default false.
    pub blank_application: bool,
    /// Which pin is which driver signal and input. Default: RAMPS 1.4.
    pub pins: PinMap,
    /// Data-space bytes written after every reset, before the firmware
    /// runs (a simavr workaround a peer firmware needs; see
    /// [`VmConfig::grbl_mega`]). Default none.
    pub poke_after_reset: Vec<(u16, u8)>,
}

impl VmConfig {
    /// Default configuration for a given ELF.
    pub fn new(elf: impl Into<PathBuf>) -> VmConfig {
        VmConfig { elf: elf.into(), ..VmConfig::default() }
    }

    /// The real grbl-Mega 1.1g (`../shared/peers/grbl-mega/`, its ELF
    /// `elf`) on its own pins ([`PinMap::GRBL_MEGA`], directions high =
    /// negative), with the two simavr workarounds its ORIGIN.txt measured:
    /// OCR1A set to 0xFF after every reset (simavr's Timer1 CTC never fires
    /// with OCR1A = 0, which grbl leaves there when it enables the
    /// interrupt), and TCNTn kept across a clock start (on by default).
    /// No switches are wired but the limits and the probe; grbl's limits
    /// and homing are off by default.
    pub fn grbl_mega(elf: impl Into<PathBuf>) -> VmConfig {
        let mut c = VmConfig::new(elf);
        c.pins = PinMap::GRBL_MEGA;
        c.machine.invert_dir_mask = 0b0111;
        // grbl's probe input reads low when it touches (pull-up, `$6=0`).
        c.machine.inverted_inputs |= 1 << Input::ToolSetter.index();
        c.poke_after_reset = vec![(OCR1AL, 0xFF)];
        c.fix_tcnt_on_clock_start = true;
        c
    }

    /// `$MILL_ELF` if set, else `<repo>/target/avr-atmega2560/release/mill.elf`
    /// (what `cargo fw` builds).
    pub fn default_elf_path() -> PathBuf {
        if let Some(p) = std::env::var_os("MILL_ELF") {
            return PathBuf::from(p);
        }
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/avr-atmega2560/release/mill.elf")
    }
}

impl Default for VmConfig {
    fn default() -> Self {
        VmConfig {
            elf: VmConfig::default_elf_path(),
            frequency_hz: 16_000_000,
            machine: MachineConfig::default(),
            recorder: RecorderConfig::default(),
            check_interval_cycles: 1600,
            batch_cycles: 1024,
            max_interrupt_nesting: 60,
            stop_on_bad_opcode: true,
            command_timeout_s: 60.0,
            fix_tcnt_on_clock_start: true,
            bootloader: None,
            blank_application: false,
            pins: PinMap::RAMPS,
            poke_after_reset: Vec::new(),
        }
    }
}

/// Host side of UART0.
#[derive(Default)]
struct UartHost {
    /// Bytes for the chip, paced with flow control.
    paced: VecDeque<u8>,
    /// Bytes for the chip, pushed at the line rate regardless.
    flood: VecDeque<u8>,
    /// The feeder cycle timer is armed.
    feeding: bool,
    /// simavr's XOFF: its input FIFO is full.
    xoff: bool,
    out: Vec<u8>,
    out_text: String,
    partial: String,
    pending: VecDeque<String>,
    log: Vec<(u64, String)>,
    bytes_to_chip: u64,
    rx_dropped: u64,
    rx_deep: u64,
}

/// State shared with the C callbacks. Lives in a `Box` whose raw pointer is
/// handed to simavr; only ever accessed through that pointer.
struct Inner {
    avr: *mut ffi::avr_t,
    uart: *mut ffi::avr_uart_t,
    /// Cycles before the last simavr reset (simavr zeroes `avr->cycle`).
    cycle_base: u64,
    batch_cycles: u64,
    max_nesting: u32,
    stop_on_bad_opcode: bool,
    recorder: Recorder,
    physics: Physics,
    isr: IsrTracker,
    host: UartHost,
    /// The board's pins ([`VmConfig::pins`]) and the bytes written after
    /// every reset ([`VmConfig::poke_after_reset`]).
    pins: PinMap,
    pokes: Vec<(u16, u8)>,
    /// Levels last driven per input.
    levels: [Option<bool>; Input::COUNT],
    input_irqs: [*mut ffi::avr_irq_t; Input::COUNT],
    output_irqs: Vec<*mut ffi::avr_irq_t>,
    orig_reset: Option<unsafe extern "C" fn(*mut ffi::avr_t)>,
    reset_seen: bool,
    resets: Vec<ResetRecord>,
    /// Something a waiter may care about happened (a line arrived).
    event: bool,
    fatal: Option<VmError>,
    stop_armed_at: Option<u64>,
    log: Vec<String>,
    spindle_duty: f64,
    spindle_history: Vec<(u64, f64)>,
    /// Coolant output level (PH6), and every change: (VM cycle, on).
    coolant: bool,
    coolant_history: Vec<(u64, bool)>,
    /// The SH1106 on the TWI bus, and whether the current transfer is for it.
    oled: Sh1106,
    oled_selected: bool,
    twi_input: *mut ffi::avr_irq_t,
    /// The SD card in the socket (None: empty socket).
    sd: Option<SdCard>,
    sd_selected: bool,
    spi_input: *mut ffi::avr_irq_t,
    /// The switch-bounce timer is armed for this VM cycle.
    switch_timer_at: Option<u64>,
    /// Inside the switch-bounce timer (it re-arms itself by its return value).
    in_switch_timer: bool,
}

impl Inner {
    /// VM clock: monotonic across resets.
    fn now(&self) -> u64 {
        // SAFETY: `avr` is valid for the life of Inner (freed only in Vm::drop, after Inner is no longer used).
        self.cycle_base + unsafe { (*self.avr).cycle }
    }

    fn set_fatal(&mut self, e: VmError) {
        if self.fatal.is_none() {
            self.fatal = Some(e);
        }
        // SAFETY: see `now`; stopping the core makes avr_run return without executing more.
        unsafe { (*self.avr).state = ffi::cpu_Stopped as c_int };
    }

    fn data(&self) -> *mut u8 {
        // SAFETY: see `now`; `data` is allocated by avr_init for ramend+1 bytes.
        unsafe { (*self.avr).data }
    }

    fn read(&self, addr: u16) -> u8 {
        // SAFETY: callers pass addresses ≤ RAMEND (the data array has ramend+1 bytes).
        unsafe { *self.data().add(addr as usize) }
    }
}

/// Param of a driver-pin notification.
struct PinHook {
    inner: *mut Inner,
    axis: Axis,
    kind: SignalKind,
}

/// Param of a wrapped TCCRnB write handler.
struct TimerWrap {
    /// Data-space address of TCCRnB and of TCNTn (low byte).
    tccrb: u16,
    tcnt: u16,
    orig: ffi::avr_io_write_t,
    orig_param: *mut c_void,
}

/// The 6 timers of the ATmega2560: (TCCRnB, TCNTn or TCNTnL).
const TIMERS: [(u16, u16); 6] = [(0x45, 0x46), (0x81, 0x84), (0xB1, 0xB2), (0x91, 0x94), (0xA1, 0xA4), (0x121, 0x124)];

static LOGGER: Once = Once::new();
static LOAD_LOCK: Mutex<()> = Mutex::new(());

/// The virtual machine. See the module docs.
pub struct Vm {
    avr: *mut ffi::avr_t,
    inner: *mut Inner,
    hooks: Box<[PinHook]>,
    timer_wraps: Box<[TimerWrap]>,
    config: VmConfig,
    symbols: ElfSymbols,
    wall_start: std::time::Instant,
}

// SAFETY: the simavr instance and Inner are owned exclusively by this Vm and
// touched only from the thread that currently owns it; simavr keeps no
// per-thread state (its only global, the logger, reads per-instance data).
unsafe impl Send for Vm {}

// ---------------------------------------------------------------- callbacks

/// simavr's logger: keep warnings and errors per VM, drop traces.
// SAFETY (contract): simavr calls this with a live instance (or null) and a matching format/va_list.
unsafe extern "C" fn logger(avr: *mut ffi::avr_t, level: c_int, fmt: *const c_char, ap: *mut ffi::__va_list_tag) {
    if level > ffi::LOG_WARNING as c_int || fmt.is_null() {
        return;
    }
    let mut buf = [0 as c_char; 512];
    // SAFETY: buf is 512 bytes; fmt/ap come from simavr's AVR_LOG and match.
    unsafe { vsnprintf(buf.as_mut_ptr(), buf.len(), fmt, ap) };
    // SAFETY: vsnprintf NUL-terminates within the buffer.
    let msg = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_string_lossy().trim_end().to_string();
    // SAFETY: avr is null or a live instance; custom.data is null or our Inner.
    let inner = if avr.is_null() { std::ptr::null_mut() } else { unsafe { (*avr).custom.data as *mut Inner } };
    if inner.is_null() {
        if level <= ffi::LOG_ERROR as c_int {
            eprintln!("simavr: {msg}");
        }
        return;
    }
    // SAFETY: Inner outlives the avr instance's use; simavr is single-threaded per instance.
    let inner = unsafe { &mut *inner };
    if inner.log.len() < 10_000 {
        inner.log.push(msg);
    }
}

/// Replaces simavr's `avr->sleep`, which `usleep`s to keep wall-clock pace.
// SAFETY (contract): does nothing with its arguments.
unsafe extern "C" fn no_sleep(_avr: *mut ffi::avr_t, _how_long: ffi::avr_cycle_count_t) {}

/// Wraps the core's reset callback: remember the cycle count simavr is about
/// to zero. Called by `avr_reset` (watchdog or ours) before the I/O modules reset.
// SAFETY (contract): installed as `avr->reset` after `custom.data` points to our Inner.
unsafe extern "C" fn reset_hook(avr: *mut ffi::avr_t) {
    // SAFETY: installed only after custom.data was set to our Inner.
    let inner = unsafe { &mut *((*avr).custom.data as *mut Inner) };
    // SAFETY: avr is live.
    inner.cycle_base += unsafe { (*avr).cycle };
    inner.reset_seen = true;
    if let Some(orig) = inner.orig_reset {
        // SAFETY: the core's own reset callback, called as simavr would.
        unsafe { orig(avr) };
    }
}

/// A driver pin changed level.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn pin_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is a PinHook in Vm::hooks, alive while the avr is.
    let hook = unsafe { &*(param as *const PinHook) };
    // SAFETY: hook.inner is our Inner; no other reference to it is live during avr_run.
    let inner = unsafe { &mut *hook.inner };
    let cycle = inner.now();
    if let Some(ev) = inner.recorder.on_pin(cycle, hook.axis, hook.kind, value & 1 != 0) {
        let pos = inner.recorder.positions();
        inner.physics.on_step(&pos, ev.axis);
        for &input in Physics::inputs_moved_by(ev.axis) {
            drive_input(inner, input, false);
        }
    }
}

/// An interrupt vector was entered (value 1) or left by RETI (value 0).
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn isr_notify(irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner (see pin_notify); irq is the vector's RUNNING IRQ.
    let inner = unsafe { &mut *(param as *mut Inner) };
    // SAFETY: irq is valid; vector IRQs are numbered vector * 256 + index.
    let vector = (unsafe { (*irq).irq } >> 8) as u8;
    let cycle = inner.now();
    if value != 0 {
        // SAFETY: avr is live; running_ptr is the depth before this entry.
        let (depth, pc) = unsafe { ((*inner.avr).interrupts.running_ptr as u32 + 1, (*inner.avr).pc) };
        inner.isr.enter(vector, cycle, depth);
        if depth > inner.max_nesting {
            inner.set_fatal(VmError::InterruptNesting { depth, vector, pc, cycle });
        }
    } else {
        inner.isr.exit(vector, cycle);
    }
}

/// simavr met an opcode it does not know.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn bad_opcode_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    if inner.stop_on_bad_opcode {
        let cycle = inner.now();
        // SAFETY: avr is live.
        let pc = unsafe { (*inner.avr).pc };
        inner.set_fatal(VmError::BadOpcode { pc, opcode: value as u16, cycle });
    }
}

/// UART0 transmitted a byte.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_out_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    let b = value as u8;
    let cycle = inner.now();
    let h = &mut inner.host;
    h.out.push(b);
    let c = if b.is_ascii() { b as char } else { char::REPLACEMENT_CHARACTER };
    h.out_text.push(c);
    if b == b'\n' {
        let line = std::mem::take(&mut h.partial);
        let line = line.strip_suffix('\r').unwrap_or(&line).to_string();
        h.log.push((cycle, line.clone()));
        h.pending.push_back(line);
        inner.event = true;
    } else {
        h.partial.push(c);
    }
}

// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_xoff_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.host.xoff = value != 0;
}

// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_xon_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    if value != 0 {
        inner.host.xoff = false;
    }
}

/// One byte-time of the host's transmitter: hand the next byte to simavr.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_feed_timer(_avr: *mut ffi::avr_t, when: ffi::avr_cycle_count_t, param: *mut c_void) -> u64 {
    let inner_p = param as *mut Inner;
    // Decide with short-lived borrows: raising the input IRQ below may call
    // uart_xoff_notify, which borrows Inner itself.
    let (raise, input_irq) = {
        // SAFETY: param is our Inner; no other borrow of it is live here.
        let inner = unsafe { &mut *inner_p };
        // SAFETY: inner.uart points into the live mcu struct; read by value.
        let (rxen_rb, dor_rb, read, write, irqs) = unsafe {
            let u = &*inner.uart;
            (u.rxen, u.dor, u.input.read, u.input.write, u.io.irq)
        };
        let rxen = regbit_get(inner, rxen_rb) != 0;
        let unread = (write.wrapping_sub(read) & 63) as usize;
        // SAFETY: the UART's IRQ array has UART_IRQ_COUNT entries.
        let input_irq = unsafe { irqs.add(ffi::UART_IRQ_INPUT as usize) };
        let h = &mut inner.host;
        let mut raise = None;
        if let Some(b) = h.flood.pop_front() {
            h.bytes_to_chip += 1;
            if !rxen || unread >= 2 {
                h.rx_dropped += 1;
                regbit_set(inner, dor_rb);
            } else {
                raise = Some(b);
            }
        } else if !h.paced.is_empty() && rxen && !h.xoff && unread < 62 {
            if unread >= 2 {
                h.rx_deep += 1;
            }
            h.bytes_to_chip += 1;
            raise = h.paced.pop_front();
        }
        (raise, input_irq)
    };
    if let Some(b) = raise {
        // SAFETY: raising the UART input IRQ is how simavr receives a byte; no Rust borrow is live.
        unsafe { ffi::avr_raise_irq(input_irq, b as u32) };
    }
    // SAFETY: as above; the raise has returned.
    let inner = unsafe { &mut *inner_p };
    if inner.host.flood.is_empty() && inner.host.paced.is_empty() {
        inner.host.feeding = false;
        return 0;
    }
    // SAFETY: reading a field of the live UART struct.
    let per_byte = unsafe { (*inner.uart).cycles_per_byte };
    when + per_byte.max(16)
}

/// Wraps simavr's TCCRnB write: freeze TCNTn when the clock stops, write it
/// back through simavr's TCNT handler when the clock starts.
// SAFETY (contract): installed as `avr->io[TCCRnB].w` with a TimerWrap param
// that lives in Vm::timer_wraps; simavr calls it for CPU writes to TCCRnB.
unsafe extern "C" fn tccrb_write(avr: *mut ffi::avr_t, addr: ffi::avr_io_addr_t, v: u8, param: *mut c_void) {
    // SAFETY: param is a TimerWrap alive as long as the instance; avr is live;
    // the I/O table entries belong to simavr's timer module.
    unsafe {
        let w = &*(param as *const TimerWrap);
        let data = (*avr).data;
        let tcnt_io = &(*avr).io[(w.tcnt - 32) as usize];
        let was_running = *data.add(w.tccrb as usize) & 7 != 0;
        let will_run = v & 7 != 0;
        if was_running && !will_run {
            if let Some(read) = tcnt_io.r.c {
                read(avr, w.tcnt, tcnt_io.r.param); // updates TCNTn (and TCNTnH) in data
            }
        }
        if let Some(orig) = w.orig {
            orig(avr, addr, v, w.orig_param);
        }
        if !was_running && will_run {
            if let Some(write) = tcnt_io.w.c {
                write(avr, w.tcnt, *data.add(w.tcnt as usize), tcnt_io.w.param);
            }
        }
    }
}

/// Bounds an `avr_run` batch at a VM-chosen cycle.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn stop_timer(_avr: *mut ffi::avr_t, _when: ffi::avr_cycle_count_t, param: *mut c_void) -> u64 {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.stop_armed_at = None;
    0
}

/// The start-up delay after a reset is over: the core runs (see
/// `Vm::hold_in_reset`).
// SAFETY (contract): only simavr calls this, from inside `avr_run`.
unsafe extern "C" fn startup_done(avr: *mut ffi::avr_t, _when: ffi::avr_cycle_count_t, _param: *mut c_void) -> u64 {
    // SAFETY: avr is the live instance that runs this timer.
    unsafe {
        (*avr).sreg[7] = 0; // I flag
        (*avr).state = ffi::cpu_Running as c_int;
    }
    0
}

/// Timer2 or PB4 changed: recompute the spindle duty.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn spindle_notify(_irq: *mut ffi::avr_irq_t, _value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    update_spindle(inner);
}

/// PH6 changed: the coolant output's new level.
// SAFETY (contract): only simavr calls this, from inside `avr_run` on the VM's
// thread, with the `param` registered in `Vm::new` (our `Inner`).
unsafe extern "C" fn coolant_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    set_coolant(inner, value != 0);
}

fn set_coolant(inner: &mut Inner, on: bool) {
    if on != inner.coolant {
        inner.coolant = on;
        let now = inner.now();
        inner.coolant_history.push((now, on));
    }
}

fn update_spindle(inner: &mut Inner) {
    let d = spindle::duty(
        inner.read(spindle::TCCR2A),
        inner.read(spindle::TCCR2B),
        inner.read(spindle::OCR2A),
        inner.read(spindle::DDRB),
        inner.read(spindle::PORTB),
    );
    if d != inner.spindle_duty {
        inner.spindle_duty = d;
        let now = inner.now();
        inner.spindle_history.push((now, d));
    }
}

/// The TWI master put a condition or byte on the bus: the SH1106 at 0x3C
/// acknowledges its address and every byte written to it.
// SAFETY (contract): only simavr calls this, from inside `avr_run` on the VM's
// thread, with our `Inner` as `param` (registered in `Vm::new`).
unsafe extern "C" fn twi_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    let inner_p = param as *mut Inner;
    let msg = (value >> 8) as u8;
    let addr = (value >> 16) as u8;
    let data = (value >> 24) as u8;
    let (ack, input) = {
        // SAFETY: param is our Inner; no other borrow of it is live here.
        let inner = unsafe { &mut *inner_p };
        let now = inner.now();
        let mut ack = false;
        if msg & ffi::TWI_COND_STOP as u8 != 0 {
            if inner.oled_selected {
                inner.oled.stop();
            }
            inner.oled_selected = false;
        }
        if msg & ffi::TWI_COND_START as u8 != 0 {
            inner.oled_selected = addr >> 1 == crate::oled::I2C_ADDRESS && addr & 1 == 0;
            if inner.oled_selected {
                inner.oled.start();
                ack = true;
            }
        } else if msg & ffi::TWI_COND_WRITE as u8 != 0 && inner.oled_selected {
            inner.oled.write(data, now);
            ack = true;
        }
        (ack, inner.twi_input)
    };
    if ack && !input.is_null() {
        // SAFETY: the TWI's input IRQ; simavr's handler does not call back into Inner.
        unsafe { ffi::avr_raise_irq(input, ffi::avr_twi_irq_msg(ffi::TWI_COND_ACK as u8, addr, 1)) };
    }
}

/// The SPI master finished a byte: the SD card (if selected) answers with
/// the byte it drove on MISO during that transfer.
// SAFETY (contract): as `twi_notify`.
unsafe extern "C" fn spi_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    let inner_p = param as *mut Inner;
    let (miso, input) = {
        // SAFETY: param is our Inner; no other borrow of it is live here.
        let inner = unsafe { &mut *inner_p };
        let selected = inner.sd_selected;
        let miso = match inner.sd.as_mut() {
            Some(card) if selected => card.exchange(value as u8),
            _ => 0xFF, // MISO pulled up
        };
        (miso, inner.spi_input)
    };
    if !input.is_null() {
        // SAFETY: the SPI's input IRQ sets SPDR; in master mode it does not call back.
        unsafe { ffi::avr_raise_irq(input, miso as u32) };
    }
}

/// PB0 (SD chip select) changed.
// SAFETY (contract): as `twi_notify`.
unsafe extern "C" fn sd_cs_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.sd_selected = value & 1 == 0;
    let sel = inner.sd_selected;
    if let Some(card) = inner.sd.as_mut() {
        card.select(sel);
    }
}

fn regbit_get(inner: &Inner, rb: ffi::avr_regbit_t) -> u8 {
    let reg = rb.reg() as u16;
    if reg == 0 {
        return 0;
    }
    (inner.read(reg) >> rb.bit()) & rb.mask() as u8
}

fn regbit_set(inner: &mut Inner, rb: ffi::avr_regbit_t) {
    let reg = rb.reg() as usize;
    if reg != 0 {
        // SAFETY: simavr regbits address registers inside the data array.
        unsafe { *inner.data().add(reg) |= (rb.mask() as u8) << rb.bit() };
    }
}

/// Drive one input to what the model/override says. With `direct`, write
/// PINx and the IRQ's cached value without notifying anyone (after a reset);
/// otherwise raise the pin IRQ (edges reach INTn/PCINT) if the level changed.
fn drive_input(inner: &mut Inner, input: Input, direct: bool) {
    let pos = inner.recorder.positions();
    let now = inner.now();
    let inverted = u32::from(inner.physics.config().inverted_inputs) >> input.index() & 1 != 0;
    let level = input.level(inner.physics.sense(input, &pos, now)) != inverted;
    if !direct {
        arm_switch_timer(inner);
    }
    let i = input.index();
    if !direct && inner.levels[i] == Some(level) {
        return;
    }
    inner.levels[i] = Some(level);
    let Some(pin) = inner.pins.input(input) else { return };
    // The port's external state covers every input on that port.
    let (mut mask, mut value) = (0u8, 0u8);
    for other in Input::ALL {
        let Some(p) = inner.pins.input(other) else { continue };
        if p.port == pin.port {
            if let Some(l) = inner.levels[other.index()] {
                mask |= 1 << p.bit;
                if l {
                    value |= 1 << p.bit;
                }
            }
        }
    }
    let mut ext: ffi::avr_ioport_external_t = zeroed_pod();
    ext.set_name(pin.port as _);
    ext.set_mask(mask as _);
    ext.set_value(value as _);
    // SAFETY: avr is live; the ioctl copies the struct's fields.
    unsafe { ffi::avr_ioctl(inner.avr, ioctl_ioport_set_external(pin.port), &mut ext as *mut _ as *mut c_void) };
    let irq = inner.input_irqs[i];
    if irq.is_null() {
        return;
    }
    if direct {
        // SAFETY: irq is a live port pin IRQ; PINx is inside the data array.
        unsafe {
            (*irq).value = level as u32;
            let p = inner.data().add(pin.pin_reg() as usize);
            if level {
                *p |= 1 << pin.bit;
            } else {
                *p &= !(1 << pin.bit);
            }
        }
    } else {
        // SAFETY: irq is a live port pin IRQ; raising it is simavr's input path.
        // No hook of ours sits on input pins, so this does not re-enter Inner.
        unsafe { ffi::avr_raise_irq(irq, level as u32) };
    }
}

/// Arm the switch-bounce timer for the earliest pending toggle (outside the
/// timer itself, which re-arms by its return value).
fn arm_switch_timer(inner: &mut Inner) {
    if inner.in_switch_timer {
        return;
    }
    let Some(t) = inner.physics.next_toggle() else { return };
    if inner.switch_timer_at.is_some_and(|at| at <= t) {
        return;
    }
    let now = inner.now();
    inner.switch_timer_at = Some(t);
    // SAFETY: avr is live; registering replaces this (timer, param) pair if
    // already queued; the param is our Inner, as for every other timer.
    unsafe {
        ffi::avr_cycle_timer_register(inner.avr, t.saturating_sub(now).max(1), Some(switch_timer), inner as *mut Inner as *mut c_void)
    };
}

/// A switch contact bounces: apply the toggles due now, drive their pins and
/// re-arm for the next one.
// SAFETY (contract): only simavr calls this, from inside `avr_run` on the VM's thread,
// with our `Inner` as param (registered by `arm_switch_timer`).
unsafe extern "C" fn switch_timer(_avr: *mut ffi::avr_t, _when: ffi::avr_cycle_count_t, param: *mut c_void) -> u64 {
    // SAFETY: param is our Inner; no other borrow of it is live during avr_run.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.in_switch_timer = true;
    let now = inner.now();
    for input in inner.physics.fire_toggles(now) {
        drive_input(inner, input, false);
    }
    inner.in_switch_timer = false;
    inner.switch_timer_at = inner.physics.next_toggle();
    match inner.switch_timer_at {
        // simavr's clock restarts at a reset: its cycles are ours less the base.
        Some(t) => t.max(now + 1) - inner.cycle_base,
        None => 0,
    }
}

fn zeroed_pod<T: Copy>() -> T {
    // SAFETY: only used for plain-old-data simavr structs, for which all-zero is valid.
    unsafe { std::mem::zeroed() }
}

// ----------------------------------------------------------------- the Vm

impl Vm {
    /// Loads the ELF into a fresh ATmega2560 and wires the machine around it.
    pub fn new(mut config: VmConfig) -> Result<Vm, VmError> {
        config.recorder.frequency_hz = config.frequency_hz;
        let path = config.elf.clone();
        if !path.exists() {
            return Err(VmError::Load(format!("{} does not exist (build it with `cargo fw`)", path.display())));
        }
        let symbols = ElfSymbols::load(&path).map_err(VmError::Load)?;
        LOGGER.call_once(|| {
            // SAFETY: installs a function pointer; simavr calls it with its own arguments.
            unsafe { ffi::avr_global_logger_set(Some(logger)) };
        });
        let cpath = CString::new(path.to_string_lossy().as_bytes()).map_err(|e| VmError::Load(e.to_string()))?;
        let _guard = LOAD_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: the name is a valid C string; returns null or a malloc'd mcu.
        let avr = unsafe { ffi::avr_make_mcu_by_name(c"atmega2560".as_ptr()) };
        if avr.is_null() {
            return Err(VmError::Load("simavr does not know atmega2560".into()));
        }
        // SAFETY: avr was just made; avr_init allocates flash/data and resets.
        unsafe { ffi::avr_init(avr) };
        let mut fw: Box<ffi::elf_firmware_t> = Box::new(zeroed_pod());
        // SAFETY: fw is zero-initialised as elf_read_firmware requires.
        let rc = unsafe { ffi::elf_read_firmware(cpath.as_ptr(), &mut *fw) };
        if rc != 0 {
            // SAFETY: avr is ours and not yet shared.
            unsafe {
                ffi::avr_terminate(avr);
                free(avr as *mut c_void);
            }
            return Err(VmError::Load(format!("simavr cannot read {}", path.display())));
        }
        fw.frequency = config.frequency_hz;
        // SAFETY: fw was filled by elf_read_firmware; load copies the chunks and frees them.
        unsafe {
            ffi::avr_load_firmware(avr, &mut *fw);
            for i in 0..fw.symbolcount as usize {
                free(*fw.symbol.add(i) as *mut c_void);
            }
            if !fw.symbol.is_null() {
                free(fw.symbol as *mut c_void);
            }
        }
        drop(_guard);
        // SAFETY: avr is ours, initialised and not running.
        if let Err(e) = unsafe { load_boot_section(avr, &config) } {
            // SAFETY: avr is ours and not yet shared.
            unsafe {
                ffi::avr_terminate(avr);
                free(avr as *mut c_void);
            }
            return Err(VmError::Load(e));
        }

        let recorder = Recorder::new(config.recorder.clone(), &config.machine);
        let mut physics = Physics::new(config.machine.clone());
        physics.set_clock_hz(config.frequency_hz as f64);
        let inner = Box::into_raw(Box::new(Inner {
            avr,
            uart: std::ptr::null_mut(),
            cycle_base: 0,
            batch_cycles: config.batch_cycles.max(1),
            max_nesting: config.max_interrupt_nesting,
            stop_on_bad_opcode: config.stop_on_bad_opcode,
            recorder,
            physics,
            isr: IsrTracker::default(),
            host: UartHost::default(),
            pins: config.pins,
            pokes: config.poke_after_reset.clone(),
            levels: [None; Input::COUNT],
            input_irqs: [std::ptr::null_mut(); Input::COUNT],
            output_irqs: Vec::new(),
            orig_reset: None,
            reset_seen: false,
            resets: vec![ResetRecord { cycle: 0, kind: ResetKind::PowerOn }],
            event: false,
            fatal: None,
            stop_armed_at: None,
            log: Vec::new(),
            spindle_duty: 0.0,
            spindle_history: Vec::new(),
            coolant: false,
            coolant_history: Vec::new(),
            oled: Sh1106::new(),
            oled_selected: false,
            twi_input: std::ptr::null_mut(),
            sd: None,
            sd_selected: false,
            spi_input: std::ptr::null_mut(),
            switch_timer_at: None,
            in_switch_timer: false,
        }));
        let param = inner as *mut c_void;

        // SAFETY: avr is a live, initialised instance owned by this
        // function (the whole block); every IRQ pointer comes from simavr's
        // own lookup and is checked for null; `param`/hook pointers stay
        // valid until Vm::drop terminates the instance.
        let hooks = unsafe {
            (*avr).custom.data = param;
            (*avr).sleep = Some(no_sleep);
            (*avr).run_cycle_limit = config.batch_cycles.max(1);
            (*inner).orig_reset = (*avr).reset;
            (*avr).reset = Some(reset_hook);

            // UART0: no stdout echo, no usleep on polling.
            let mut flags: u32 = 0;
            ffi::avr_ioctl(avr, ioctl_uart_set_flags(b'0'), &mut flags as *mut u32 as *mut c_void);
            (*inner).uart = find_uart0(avr);
            let out = ffi::avr_io_getirq(avr, ioctl_uart_getirq(b'0'), ffi::UART_IRQ_OUTPUT as c_int);
            let xon = ffi::avr_io_getirq(avr, ioctl_uart_getirq(b'0'), ffi::UART_IRQ_OUT_XON as c_int);
            let xoff = ffi::avr_io_getirq(avr, ioctl_uart_getirq(b'0'), ffi::UART_IRQ_OUT_XOFF as c_int);
            if out.is_null() || (*inner).uart.is_null() {
                drop(Box::from_raw(inner));
                ffi::avr_terminate(avr);
                free(avr as *mut c_void);
                return Err(VmError::Load("simavr has no UART0".into()));
            }
            ffi::avr_irq_register_notify(out, Some(uart_out_notify), param);
            ffi::avr_irq_register_notify(xon, Some(uart_xon_notify), param);
            ffi::avr_irq_register_notify(xoff, Some(uart_xoff_notify), param);

            // Driver pins.
            let mut hooks = Vec::new();
            for axis in Axis::ALL {
                let p = (*inner).pins.drivers[axis.index()];
                for (kind, pin) in [(SignalKind::Step, p.step), (SignalKind::Dir, p.dir), (SignalKind::Enable, p.enable)] {
                    hooks.push((PinHook { inner, axis, kind }, pin));
                }
            }
            let (hooks, pins): (Vec<PinHook>, Vec<Pin>) = hooks.into_iter().unzip();
            let hooks: Box<[PinHook]> = hooks.into_boxed_slice();
            for (hook, pin) in hooks.iter().zip(pins) {
                let irq = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(pin.port), pin.bit as c_int);
                if !irq.is_null() {
                    ffi::avr_irq_register_notify(irq, Some(pin_notify), hook as *const PinHook as *mut c_void);
                    (*inner).output_irqs.push(irq);
                }
            }

            // Inputs.
            for input in Input::ALL {
                if let Some(pin) = (*inner).pins.input(input) {
                    (*inner).input_irqs[input.index()] = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(pin.port), pin.bit as c_int);
                }
            }
            for &(addr, v) in &(*inner).pokes {
                *(*avr).data.add(addr as usize) = v;
            }
            for input in Input::ALL {
                drive_input(&mut *inner, input, true);
            }

            // Interrupt vectors.
            for v in 1..64u8 {
                let irq = ffi::avr_get_interrupt_irq(avr, v);
                if !irq.is_null() {
                    ffi::avr_irq_register_notify(irq.add(ffi::AVR_INT_IRQ_RUNNING as usize), Some(isr_notify), param);
                }
            }
            let bad = ffi::avr_get_core_irq(avr, ffi::AVR_CORE_BAD_OPCODE as c_int);
            if !bad.is_null() {
                ffi::avr_irq_register_notify(bad, Some(bad_opcode_notify), param);
            }

            // Spindle: Timer2 registers and PB4.
            for addr in [spindle::TCCR2A, spindle::TCCR2B, spindle::OCR2A] {
                let irq = ffi::avr_iomem_getirq(avr, addr, std::ptr::null(), ffi::AVR_IOMEM_IRQ_ALL as c_int);
                if !irq.is_null() {
                    ffi::avr_irq_register_notify(irq, Some(spindle_notify), param);
                }
            }
            let pb4 = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(SPINDLE_PWM.port), SPINDLE_PWM.bit as c_int);
            if !pb4.is_null() {
                ffi::avr_irq_register_notify(pb4, Some(spindle_notify), param);
            }
            // Coolant: the PH6 pin level.
            let ph6 = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(COOLANT.port), COOLANT.bit as c_int);
            if !ph6.is_null() {
                ffi::avr_irq_register_notify(ph6, Some(coolant_notify), param);
            }

            // OLED on the TWI bus.
            let twi_out = ffi::avr_io_getirq(avr, IOCTL_TWI_GETIRQ, ffi::TWI_IRQ_OUTPUT as c_int);
            (*inner).twi_input = ffi::avr_io_getirq(avr, IOCTL_TWI_GETIRQ, ffi::TWI_IRQ_INPUT as c_int);
            if !twi_out.is_null() {
                ffi::avr_irq_register_notify(twi_out, Some(twi_notify), param);
            }
            // SD card on the SPI bus, selected by PB0.
            let spi_out = ffi::avr_io_getirq(avr, IOCTL_SPI_GETIRQ, ffi::SPI_IRQ_OUTPUT as c_int);
            (*inner).spi_input = ffi::avr_io_getirq(avr, IOCTL_SPI_GETIRQ, ffi::SPI_IRQ_INPUT as c_int);
            if !spi_out.is_null() {
                ffi::avr_irq_register_notify(spi_out, Some(spi_notify), param);
            }
            let cs = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(SD_CS.port), SD_CS.bit as c_int);
            if !cs.is_null() {
                ffi::avr_irq_register_notify(cs, Some(sd_cs_notify), param);
            }
            hooks
        };

        let mut timer_wraps: Box<[TimerWrap]> = if config.fix_tcnt_on_clock_start {
            TIMERS
                .iter()
                .map(|&(tccrb, tcnt)| {
                    // SAFETY: avr is live; reading the I/O table entry of TCCRnB.
                    let w = unsafe { (*avr).io[(tccrb - 32) as usize].w };
                    TimerWrap { tccrb, tcnt, orig: w.c, orig_param: w.param }
                })
                .collect()
        } else {
            Box::new([])
        };
        for w in timer_wraps.iter_mut() {
            // SAFETY: avr is live and not running; the wrap outlives the instance (dropped after it in Vm::drop).
            unsafe {
                let slot = &mut (*avr).io[(w.tccrb - 32) as usize].w;
                slot.c = Some(tccrb_write);
                slot.param = w as *mut TimerWrap as *mut c_void;
            }
        }

        Ok(Vm { avr, inner, hooks, timer_wraps, config, symbols, wall_start: std::time::Instant::now() })
    }

    /// A VM for `elf` with the default machine.
    pub fn with_elf(elf: impl Into<PathBuf>) -> Result<Vm, VmError> {
        Vm::new(VmConfig::new(elf))
    }

    /// The configuration it was started with.
    pub fn config(&self) -> &VmConfig {
        &self.config
    }

    fn inner(&self) -> &Inner {
        // SAFETY: inner is valid until drop; no &mut to it is live outside avr_run.
        unsafe { &*self.inner }
    }

    fn inner_mut(&mut self) -> &mut Inner {
        // SAFETY: as `inner`; &mut self guarantees exclusivity on the Rust side.
        unsafe { &mut *self.inner }
    }

    // ------------------------------------------------------------ time

    /// VM clock in CPU cycles since power-on; monotonic across resets.
    pub fn cycles(&self) -> u64 {
        self.inner().now()
    }

    /// [`Vm::cycles`] in seconds.
    pub fn seconds(&self) -> f64 {
        self.cycles() as f64 / self.config.frequency_hz as f64
    }

    /// CPU clock, Hz.
    pub fn frequency(&self) -> u32 {
        self.config.frequency_hz
    }

    fn to_cycles(&self, seconds: f64) -> u64 {
        (seconds.max(0.0) * self.config.frequency_hz as f64).round() as u64
    }

    /// Current program counter (byte address).
    pub fn pc(&self) -> u32 {
        // SAFETY: avr is live.
        unsafe { (*self.avr).pc }
    }

    /// The error that stopped the VM, if any (sticky until a reset).
    pub fn fatal_error(&self) -> Option<&VmError> {
        self.inner().fatal.as_ref()
    }

    /// Wall-clock time since the VM was created.
    pub fn wall_seconds(&self) -> f64 {
        self.wall_start.elapsed().as_secs_f64()
    }

    // --------------------------------------------------------- running

    fn arm_stop(&mut self, at: u64) {
        let now = self.cycles();
        if self.inner().stop_armed_at == Some(at) || at <= now {
            return;
        }
        self.inner_mut().stop_armed_at = Some(at);
        // SAFETY: avr is live and not running; the timer's param is our Inner.
        unsafe { ffi::avr_cycle_timer_register(self.avr, at - now, Some(stop_timer), self.inner as *mut c_void) };
    }

    /// Runs until `deadline` (VM cycles) or until `cond` holds. Conditions
    /// are checked every `check_interval` cycles and whenever a UART line
    /// arrives. Returns whether `cond` held.
    fn run_inner(&mut self, deadline: u64, check_interval: u64, cond: &mut dyn FnMut(&Vm) -> bool) -> Result<bool, VmError> {
        let mut next_check = self.cycles();
        loop {
            if let Some(e) = &self.inner().fatal {
                return Err(e.clone());
            }
            let now = self.cycles();
            if self.inner().event || now >= next_check {
                self.inner_mut().event = false;
                if cond(self) {
                    return Ok(true);
                }
                next_check = now.saturating_add(check_interval);
            }
            if now >= deadline {
                return Ok(false);
            }
            self.arm_stop(next_check.min(deadline));
            // SAFETY: avr is live; no Rust reference into Inner is held across this call.
            let state = unsafe { ffi::avr_run(self.avr) };
            self.after_run(state);
        }
    }

    fn after_run(&mut self, state: c_int) {
        if self.inner().reset_seen {
            self.post_reset(None);
        }
        if state == ffi::cpu_Running as c_int || state == ffi::cpu_Sleeping as c_int {
            return;
        }
        let pc = self.pc();
        let cycle = self.cycles();
        let inner = self.inner_mut();
        if inner.fatal.is_none() {
            inner.fatal =
                Some(if state == ffi::cpu_Done as c_int { VmError::Halted { pc, cycle } } else { VmError::Crashed { pc, cycle } });
        }
    }

    /// Bring the VM's side back in line after simavr reset the chip.
    fn post_reset(&mut self, kind: Option<ResetKind>) {
        let avr = self.avr;
        let now = self.cycles();
        let inner = self.inner_mut();
        inner.reset_seen = false;
        inner.stop_armed_at = None;
        // SAFETY: avr is live and not running.
        let mcusr = unsafe {
            (*avr).run_cycle_limit = inner.batch_cycles;
            (*avr).sleep = Some(no_sleep);
            *(*avr).data.add(MCUSR)
        };
        let kind = kind.unwrap_or(if mcusr & 0x08 != 0 { ResetKind::Watchdog } else { ResetKind::External });
        inner.resets.push(ResetRecord { cycle: now, kind });
        for &(addr, v) in &inner.pokes {
            // SAFETY: avr is live and not running; the address is in its data space.
            unsafe { *(*avr).data.add(addr as usize) = v };
        }
        // Pins float: the drivers read step/dir/enable low.
        inner.recorder.on_reset(now);
        for &irq in &inner.output_irqs {
            // SAFETY: live port pin IRQs; keep simavr's cached level in line with the float.
            unsafe { (*irq).value = 0 };
        }
        inner.isr.on_reset();
        // simavr dropped its cycle timers: bouncing contacts settle now.
        inner.physics.settle();
        inner.switch_timer_at = None;
        for input in Input::ALL {
            drive_input(inner, input, true);
        }
        update_spindle(inner);
        // The pin floats after a reset: the MOSFET's gate pull-down turns it off.
        set_coolant(inner, false);
        inner.host.feeding = false;
        self.kick_feeder();
        if self.config.bootloader.is_some() {
            self.hold_in_reset();
        }
    }

    /// A board as sold waits [`boot::STOCK_STARTUP_S`] after a reset
    /// before the core runs: the core sleeps (with the I flag set, so that
    /// simavr lets time pass; nothing can interrupt, every source is off
    /// after a reset) until a cycle timer wakes it.
    fn hold_in_reset(&mut self) {
        let cycles = (boot::STOCK_STARTUP_S * self.config.frequency_hz as f64) as u64;
        // SAFETY: avr is live and not running; the timer has no param.
        unsafe {
            (*self.avr).sreg[7] = 1; // I flag
            (*self.avr).state = ffi::cpu_Sleeping as c_int;
            ffi::avr_cycle_timer_register(self.avr, cycles, Some(startup_done), std::ptr::null_mut());
        }
    }

    /// Cycles from a reset until the core runs: the stock fuses' start-up
    /// delay with a bootloader, else 0.
    pub fn startup_cycles(&self) -> u64 {
        if self.config.bootloader.is_some() {
            (boot::STOCK_STARTUP_S * self.config.frequency_hz as f64) as u64
        } else {
            0
        }
    }

    /// Runs `n` cycles.
    pub fn run_cycles(&mut self, n: u64) -> Result<(), VmError> {
        let deadline = self.cycles() + n;
        self.run_inner(deadline, u64::MAX / 4, &mut |_| false).map(|_| ())
    }

    /// Runs for `seconds` of simulated time.
    pub fn run_for(&mut self, seconds: f64) -> Result<(), VmError> {
        let n = self.to_cycles(seconds);
        self.run_cycles(n)
    }

    /// Runs until `cond(vm)` holds; error after `timeout_s` simulated seconds.
    /// Returns the simulated seconds it took. `cond` is evaluated every
    /// `check_interval_cycles` and whenever a UART line arrives.
    pub fn run_until(&mut self, mut cond: impl FnMut(&Vm) -> bool, timeout_s: f64) -> Result<f64, VmError> {
        let start = self.cycles();
        let deadline = start + self.to_cycles(timeout_s);
        let interval = self.config.check_interval_cycles.max(1);
        if self.run_inner(deadline, interval, &mut cond)? {
            Ok((self.cycles() - start) as f64 / self.config.frequency_hz as f64)
        } else {
            Err(VmError::Timeout { what: "condition".into(), waited_s: timeout_s })
        }
    }

    /// External reset (RESET pin: the reset button, or the USB port's DTR
    /// on a board with auto-reset): SRAM and EEPROM kept (datasheet §12:
    /// only a power loss loses SRAM), I/O registers reset, EXTRF set,
    /// inputs re-applied. Clears a fatal error, so a stopped VM can go on.
    pub fn reset(&mut self) {
        self.hard_reset(ResetKind::External);
    }

    /// Power cycle: like [`Vm::reset`] but MCUSR = PORF only, and SRAM
    /// comes up holding noise (a fixed pseudo-random pattern, different on
    /// each power cycle). The machine (positions) and the EEPROM are
    /// unchanged.
    pub fn power_cycle(&mut self) {
        self.hard_reset(ResetKind::PowerOn);
    }

    fn hard_reset(&mut self, kind: ResetKind) {
        let avr = self.avr;
        let seed = self.resets().len() as u64;
        // SAFETY: avr is live and not running; indices are within the data array.
        unsafe {
            let data = (*avr).data;
            if kind == ResetKind::PowerOn {
                let ioend = (*avr).ioend as usize;
                let ramend = (*avr).ramend as usize;
                power_on_noise(std::slice::from_raw_parts_mut(data.add(ioend + 1), ramend - ioend), seed);
            }
            match kind {
                ResetKind::PowerOn => *data.add(MCUSR) = 0x01,
                _ => *data.add(MCUSR) |= 0x02,
            }
            ffi::avr_reset(avr);
        }
        self.inner_mut().fatal = None;
        self.post_reset(Some(kind));
    }

    /// Every reset so far (the first is power-on at cycle 0).
    pub fn resets(&self) -> &[ResetRecord] {
        &self.inner().resets
    }

    /// Hangs the firmware as a main loop stuck with interrupts off would:
    /// global interrupts cleared and the program counter on the ELF's
    /// `__stop_program` (avr-libc's endless `rjmp` after `exit`). Nothing
    /// feeds the watchdog from then on, so an enabled watchdog resets the
    /// chip when it expires (simavr's own watchdog timer). False if the ELF
    /// has no `__stop_program`.
    pub fn hang(&mut self) -> bool {
        let Some(pc) = self.symbol_addr("__stop_program") else { return false };
        // SAFETY: avr is live and not running; SREG's I bit is sreg[7].
        unsafe {
            (*self.avr).sreg[7] = 0;
            (*self.avr).pc = pc;
        }
        true
    }

    /// Program memory: `len` bytes from byte address `addr` (clipped to
    /// the chip's 256 KiB).
    pub fn read_flash(&self, addr: u32, len: usize) -> Vec<u8> {
        // SAFETY: avr is live; flash has flashend + 1 bytes.
        unsafe {
            let end = ((*self.avr).flashend as usize + 1).min(addr as usize + len);
            let start = (addr as usize).min(end);
            std::slice::from_raw_parts((*self.avr).flash.add(start), end - start).to_vec()
        }
    }

    // ---------------------------------------------------------- memory

    /// Reads `len` bytes of data space (registers, I/O, SRAM) from `addr`.
    pub fn read_ram(&self, addr: u16, len: usize) -> Vec<u8> {
        let end = (addr as usize + len).min(RAMEND as usize + 1);
        (addr as usize..end).map(|a| self.inner().read(a as u16)).collect()
    }

    /// One byte of data space.
    pub fn read_u8(&self, addr: u16) -> u8 {
        self.inner().read(addr)
    }

    /// Little-endian u16 of data space.
    pub fn read_u16(&self, addr: u16) -> u16 {
        u16::from_le_bytes([self.read_u8(addr), self.read_u8(addr + 1)])
    }

    /// Little-endian u32 of data space.
    pub fn read_u32(&self, addr: u16) -> u32 {
        let b = self.read_ram(addr, 4);
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// Little-endian i32 of data space.
    pub fn read_i32(&self, addr: u16) -> i32 {
        self.read_u32(addr) as i32
    }

    /// Writes bytes into data space (no I/O side effects are triggered).
    pub fn write_ram(&mut self, addr: u16, bytes: &[u8]) {
        let data = self.inner().data();
        for (i, b) in bytes.iter().enumerate() {
            let a = addr as usize + i;
            if a <= RAMEND as usize {
                // SAFETY: a is within the data array.
                unsafe { *data.add(a) = *b };
            }
        }
    }

    /// Bytes of a RAM symbol (its ELF size), if it exists.
    pub fn read_symbol(&self, name: &str) -> Option<Vec<u8>> {
        let s = self.symbols.get(name)?;
        Some(self.read_ram(s.addr as u16, s.size as usize))
    }

    /// The whole EEPROM (4096 bytes).
    pub fn eeprom(&self) -> Vec<u8> {
        let mut buf = vec![0u8; EEPROM_SIZE];
        let mut d = ffi::avr_eeprom_desc_t { ee: buf.as_mut_ptr(), offset: 0, size: EEPROM_SIZE as u32 };
        // SAFETY: buf has `size` bytes; the ioctl copies into it.
        unsafe { ffi::avr_ioctl(self.avr, IOCTL_EEPROM_GET, &mut d as *mut _ as *mut c_void) };
        buf
    }

    /// Overwrites the EEPROM from offset 0 (at most 4096 bytes).
    pub fn set_eeprom(&mut self, bytes: &[u8]) {
        self.set_eeprom_at(0, bytes);
    }

    /// Overwrites part of the EEPROM.
    pub fn set_eeprom_at(&mut self, offset: u16, bytes: &[u8]) {
        let n = bytes.len().min(EEPROM_SIZE.saturating_sub(offset as usize));
        if n == 0 {
            return;
        }
        let mut copy = bytes[..n].to_vec();
        let mut d = ffi::avr_eeprom_desc_t { ee: copy.as_mut_ptr(), offset, size: n as u32 };
        // SAFETY: `copy` has `size` bytes; the ioctl copies out of it.
        unsafe { ffi::avr_ioctl(self.avr, IOCTL_EEPROM_SET, &mut d as *mut _ as *mut c_void) };
    }

    /// The ELF's symbols.
    pub fn symbols(&self) -> &ElfSymbols {
        &self.symbols
    }

    /// Address of a symbol: data-space address for RAM symbols, flash byte
    /// address for code (e.g. `symbol_addr("__heap_start")`).
    pub fn symbol_addr(&self, name: &str) -> Option<u32> {
        self.symbols.addr(name)
    }

    /// Stack high-water mark, bytes: from RAMEND down to the lowest byte above
    /// `__heap_start` (or `__bss_end`) that no longer holds the boot paint
    /// 0xC5. `None` without the symbol or if RAM was not painted.
    pub fn stack_high_water_bytes(&self) -> Option<u32> {
        let start = self.symbol_addr("__heap_start").or_else(|| self.symbol_addr("__bss_end"))? as u16;
        if start > RAMEND || self.read_u8(start) != STACK_PAINT {
            return None;
        }
        let mut a = start;
        while a <= RAMEND && self.read_u8(a) == STACK_PAINT {
            a += 1;
        }
        Some((RAMEND as u32 + 1) - a as u32)
    }

    // -------------------------------------------------------- host link

    fn kick_feeder(&mut self) {
        let inner = self.inner_mut();
        if inner.host.feeding || (inner.host.paced.is_empty() && inner.host.flood.is_empty()) {
            return;
        }
        inner.host.feeding = true;
        // SAFETY: avr is live and not running; the timer's param is our Inner.
        unsafe { ffi::avr_cycle_timer_register(self.avr, 1, Some(uart_feed_timer), self.inner as *mut c_void) };
    }

    /// Queues bytes for the chip, sent at the line rate with ideal flow
    /// control (held while simavr's RX FIFO is full or RXEN is off).
    pub fn send(&mut self, bytes: impl AsRef<[u8]>) {
        self.inner_mut().host.paced.extend(bytes.as_ref());
        self.kick_feeder();
    }

    /// Queues bytes for the chip ahead of everything still queued (a
    /// realtime command passing waiting lines), paced as [`Vm::send`].
    pub fn send_first(&mut self, bytes: impl AsRef<[u8]>) {
        let paced = &mut self.inner_mut().host.paced;
        for &b in bytes.as_ref().iter().rev() {
            paced.push_front(b);
        }
        self.kick_feeder();
    }

    /// Queues `line` + `\n`.
    pub fn send_line(&mut self, line: &str) {
        self.send(line.as_bytes());
        self.send(b"\n");
    }

    /// Pushes bytes at the line rate regardless of the chip: bytes arriving
    /// while 2 are unread (or RXEN is off) are lost and DOR is set, as with
    /// the hardware's 2-byte receive FIFO. See [`Vm::uart_rx_dropped`].
    pub fn send_unpaced_flood(&mut self, bytes: impl AsRef<[u8]>) {
        self.inner_mut().host.flood.extend(bytes.as_ref());
        self.kick_feeder();
    }

    /// Bytes queued but not yet handed to the chip.
    pub fn tx_pending(&self) -> usize {
        self.inner().host.paced.len() + self.inner().host.flood.len()
    }

    /// Drops every queued byte.
    pub fn clear_tx(&mut self) {
        let h = &mut self.inner_mut().host;
        h.paced.clear();
        h.flood.clear();
    }

    /// Flood bytes lost because the chip did not read them in time.
    pub fn uart_rx_dropped(&self) -> u64 {
        self.inner().host.rx_dropped
    }

    /// Paced bytes that found 2 or more unread bytes in the RX FIFO: on
    /// hardware without flow control each of these would have been an overrun.
    pub fn uart_rx_would_overrun(&self) -> u64 {
        self.inner().host.rx_deep
    }

    /// Everything the firmware printed, as text (non-ASCII bytes as U+FFFD).
    pub fn output(&self) -> &str {
        &self.inner().host.out_text
    }

    /// Everything the firmware printed, raw.
    pub fn output_bytes(&self) -> &[u8] {
        &self.inner().host.out
    }

    /// Every complete line received so far with its VM cycle.
    pub fn line_log(&self) -> &[(u64, String)] {
        &self.inner().host.log
    }

    /// Complete lines received and not yet taken (without `\r\n`).
    pub fn take_lines(&mut self) -> Vec<String> {
        self.inner_mut().host.pending.drain(..).collect()
    }

    /// Lines received and not yet taken, without taking them.
    pub fn pending_lines(&self) -> Vec<String> {
        self.inner().host.pending.iter().cloned().collect()
    }

    /// Runs until a line matching `pred` arrives (or is already pending),
    /// removes it from the pending lines and returns it. Non-matching lines
    /// stay pending.
    pub fn wait_line(&mut self, mut pred: impl FnMut(&str) -> bool, timeout_s: f64) -> Result<String, VmError> {
        let deadline = self.cycles() + self.to_cycles(timeout_s);
        let mut scanned = 0usize;
        let mut found: Option<usize> = None;
        let interval = u64::MAX / 4; // lines raise the event flag
        let met = self.run_inner(deadline, interval, &mut |vm: &Vm| {
            let pending = &vm.inner().host.pending;
            while scanned < pending.len() {
                if pred(&pending[scanned]) {
                    found = Some(scanned);
                    return true;
                }
                scanned += 1;
            }
            false
        })?;
        match (met, found) {
            (true, Some(i)) => Ok(self.inner_mut().host.pending.remove(i).unwrap_or_default()),
            _ => Err(VmError::Timeout { what: "a matching line".into(), waited_s: timeout_s }),
        }
    }

    /// Waits for the boot banner line `start`; returns the lines before it.
    pub fn wait_for_start(&mut self, timeout_s: f64) -> Result<Vec<String>, VmError> {
        self.wait_line(|l| l == "start", timeout_s)?;
        Ok(self.take_lines())
    }

    /// Wait for the whole boot banner (`start`, the reset cause and what
    /// follows within 50 ms: settings and tool-record messages) and return
    /// it from the reset cause on; the firmware then takes commands.
    pub fn wait_banner(&mut self) -> Result<Vec<String>, VmError> {
        self.wait_for_start(3.0)?;
        let cause = self.wait_line(|l| l.starts_with("echo:reset cause"), 1.0)?;
        self.run_for(0.05)?;
        let mut banner = vec![cause];
        banner.extend(self.take_lines());
        Ok(banner)
    }

    /// Sends `line\n` and collects lines up to and including the next `ok`
    /// (lines already pending come first). Timeout: `command_timeout_s`.
    pub fn command(&mut self, line: &str) -> Result<Vec<String>, VmError> {
        let t = self.config.command_timeout_s;
        self.command_timeout(line, t)
    }

    /// [`Vm::command`] with an explicit timeout, simulated seconds.
    pub fn command_timeout(&mut self, line: &str, timeout_s: f64) -> Result<Vec<String>, VmError> {
        self.send_line(line);
        let deadline = self.seconds() + timeout_s;
        let mut got = Vec::new();
        loop {
            let left = deadline - self.seconds();
            let l = self.wait_line(|_| true, left.max(0.0)).map_err(|e| match e {
                VmError::Timeout { .. } => VmError::Timeout { what: format!("ok for '{line}'"), waited_s: timeout_s },
                e => e,
            })?;
            let ok = is_reply_end(&l);
            got.push(l);
            if ok {
                return Ok(got);
            }
        }
    }

    /// Streams lines under a flow policy; see [`crate::host`]. A timeout ends
    /// the stream with `timed_out` set; a VM error is returned as such.
    pub fn stream<S: AsRef<str>>(&mut self, lines: &[S], opts: impl Into<StreamOptions>) -> Result<StreamReport, VmError> {
        let opts = opts.into();
        let mut s = Streamer::new(lines, &opts);
        let start = self.seconds();
        let deadline = start + opts.timeout_s;
        let mut last_ok = start;
        let mut timed_out = false;
        while !s.done() {
            while let Some(l) = s.next_to_send() {
                self.send(l.as_bytes());
            }
            if s.done() {
                break;
            }
            let left = deadline - self.seconds();
            match self.wait_line(|_| true, left.max(0.0)) {
                Ok(line) => {
                    if s.on_line(&line) {
                        last_ok = self.seconds();
                    }
                }
                Err(VmError::Timeout { .. }) => {
                    timed_out = true;
                    break;
                }
                Err(e) => return Err(e),
            }
        }
        let mut r = s.into_report();
        r.start_s = start;
        r.end_s = if timed_out { self.seconds() } else { last_ok };
        r.duration_s = r.end_s - start;
        r.timed_out = timed_out;
        Ok(r)
    }

    // --------------------------------------------------------- machine

    /// Physical position of an axis, steps.
    pub fn position(&self, axis: Axis) -> i64 {
        self.inner().recorder.position(axis)
    }

    /// Physical positions X, Y, Z, E, steps.
    pub fn positions(&self) -> [i64; 4] {
        self.inner().recorder.positions()
    }

    /// Physical position in mm (E: in the unit of `steps_per_mm[3]`).
    pub fn position_mm(&self, axis: Axis) -> f64 {
        self.position(axis) as f64 / self.config.machine.steps_per_mm[axis.index()]
    }

    /// Is the axis' driver enabled (ENABLE low)?
    pub fn driver_enabled(&self, axis: Axis) -> bool {
        self.inner().recorder.driver_enabled(axis)
    }

    /// The step recorder.
    pub fn recorder(&self) -> &Recorder {
        &self.inner().recorder
    }

    /// The step recorder, mutable (to clear its trace or violations).
    pub fn recorder_mut(&mut self) -> &mut Recorder {
        &mut self.inner_mut().recorder
    }

    /// Stored violations.
    pub fn violations(&self) -> &[Violation] {
        self.inner().recorder.violations()
    }

    /// The machine model.
    pub fn physics(&self) -> &Physics {
        &self.inner().physics
    }

    /// The tool changer's physical state: spindle tool, pocket contents,
    /// transfers and collisions.
    pub fn atc(&self) -> &crate::atc::AtcModel {
        self.inner().physics.atc()
    }

    /// Change the tool changer's physical state (swap, break or remove a
    /// tool); the tool-setter input follows at once.
    pub fn with_atc(&mut self, f: impl FnOnce(&mut crate::atc::AtcModel)) {
        let inner = self.inner_mut();
        f(inner.physics.atc_mut());
        drive_input(inner, Input::ToolSetter, false);
    }

    /// Force an input active/inactive (`Some`) or give it back to the model
    /// (`None`). Takes effect at once (edges reach INTn/PCINT).
    pub fn set_input(&mut self, input: Input, active: Option<bool>) {
        let inner = self.inner_mut();
        inner.physics.set_override(input, active);
        drive_input(inner, input, false);
    }

    /// The logical state the firmware currently sees on an input.
    pub fn input_active(&self, input: Input) -> bool {
        let inner = self.inner();
        inner.physics.active(input, &inner.recorder.positions())
    }

    /// The electrical level of an input's pin as the chip reads it (PINx bit).
    pub fn input_level(&self, input: Input) -> bool {
        let Some(pin) = self.inner().pins.input(input) else { return false };
        self.read_u8(pin.pin_reg()) & (1 << pin.bit) != 0
    }

    /// Replace the tool-setter model (takes effect at once).
    pub fn set_tool_setter(&mut self, model: ToolSetter) {
        let inner = self.inner_mut();
        inner.physics.set_tool_setter(model);
        drive_input(inner, Input::ToolSetter, false);
    }

    /// Change the switch models (hysteresis and bounce) from now on; the
    /// usual way is [`crate::physics::MachineConfig::switches`] before start.
    pub fn set_switches(&mut self, switches: crate::physics::SwitchConfig) {
        self.inner_mut().physics.set_switches(switches);
    }

    /// Connect or disconnect the carousel home sensor.
    pub fn set_carousel_connected(&mut self, connected: bool) {
        let inner = self.inner_mut();
        inner.physics.set_carousel_connected(connected);
        drive_input(inner, Input::CarouselHome, false);
    }

    /// Turns the encoder by `detents` (positive = clockwise: A leads B), one
    /// full quadrature cycle per detent, `seconds_per_detent` each. Runs the VM.
    pub fn turn_encoder(&mut self, detents: i32, seconds_per_detent: f64) -> Result<(), VmError> {
        let quarter = seconds_per_detent / 4.0;
        let seq: [(bool, bool); 4] = [(true, false), (true, true), (false, true), (false, false)];
        for _ in 0..detents.unsigned_abs() {
            for k in 0..4 {
                let (a, b) = seq[k];
                let (a, b) = if detents > 0 { (a, b) } else { (b, a) };
                self.set_input(Input::EncoderA, Some(a));
                self.set_input(Input::EncoderB, Some(b));
                self.run_for(quarter)?;
            }
        }
        self.set_input(Input::EncoderA, None);
        self.set_input(Input::EncoderB, None);
        Ok(())
    }

    /// Presses the encoder button for `hold_s`, then releases it. Runs the VM.
    pub fn press_button(&mut self, hold_s: f64) -> Result<(), VmError> {
        self.set_input(Input::EncoderButton, Some(true));
        self.run_for(hold_s)?;
        self.set_input(Input::EncoderButton, None);
        Ok(())
    }

    // ----------------------------------------------------- OLED, SD card

    /// The SH1106 model (display RAM, what the panel shows, write counters).
    pub fn oled(&self) -> &Sh1106 {
        &self.inner().oled
    }

    /// The SH1106 model, mutable (e.g. to turn its write log on).
    pub fn oled_mut(&mut self) -> &mut Sh1106 {
        &mut self.inner_mut().oled
    }

    /// Writes what the OLED shows as a PNG (`scale` pixels per pixel).
    pub fn screenshot(&self, path: impl AsRef<Path>, scale: usize) -> std::io::Result<()> {
        self.oled().write_png(path, scale)
    }

    /// Puts a card into the socket: the detect switch closes.
    pub fn insert_sd(&mut self, card: SdCard) {
        let inner = self.inner_mut();
        let mut card = card;
        card.set_present(true);
        card.select(inner.sd_selected);
        inner.sd = Some(card);
        self.set_input(Input::SdDetect, Some(true));
    }

    /// Pulls the card out: it stops answering at once and the detect switch
    /// opens. The card (with what was written to it) is returned.
    pub fn pull_sd(&mut self) -> Option<SdCard> {
        self.set_input(Input::SdDetect, Some(false));
        let mut card = self.inner_mut().sd.take();
        if let Some(c) = card.as_mut() {
            c.set_present(false);
        }
        card
    }

    /// The card in the socket.
    pub fn sd(&self) -> Option<&SdCard> {
        self.inner().sd.as_ref()
    }

    /// The card in the socket, mutable (to corrupt its image mid-test).
    pub fn sd_mut(&mut self) -> Option<&mut SdCard> {
        self.inner_mut().sd.as_mut()
    }

    // ------------------------------------------------------- ISR, spindle

    /// Service-time statistics of one interrupt vector.
    pub fn isr_stats(&self, vector: u8) -> Option<IsrStats> {
        self.inner().isr.stats(vector)
    }

    /// Statistics of the stepper ISR (TIMER1_COMPA, vector 17).
    pub fn stepper_isr_stats(&self) -> Option<IsrStats> {
        self.isr_stats(STEPPER_VECTOR)
    }

    /// Statistics of every vector that ran.
    pub fn all_isr_stats(&self) -> Vec<IsrStats> {
        self.inner().isr.all()
    }

    /// Deepest interrupt nesting seen.
    pub fn max_interrupt_depth(&self) -> u32 {
        self.inner().isr.max_depth()
    }

    /// Forget ISR statistics (e.g. after boot, before a measurement).
    pub fn clear_isr_stats(&mut self) {
        self.inner_mut().isr.clear();
    }

    /// Spindle PWM duty 0..=1 from OC2A's configuration (see [`crate::spindle`]).
    pub fn spindle_duty(&self) -> f64 {
        self.inner().spindle_duty
    }

    /// Is the spindle turning (duty > 0)?
    pub fn spindle_on(&self) -> bool {
        self.spindle_duty() > 0.0
    }

    /// Is the coolant output (D9, PH6) on?
    pub fn coolant_on(&self) -> bool {
        self.inner().coolant
    }

    /// Every coolant output change: (VM cycle, on).
    pub fn coolant_history(&self) -> &[(u64, bool)] {
        &self.inner().coolant_history
    }

    /// Every spindle duty change: (VM cycle, duty).
    pub fn spindle_history(&self) -> &[(u64, f64)] {
        &self.inner().spindle_history
    }

    /// simavr's warnings and errors for this instance (e.g. RX overruns).
    pub fn simavr_log(&self) -> &[String] {
        &self.inner().log
    }

    // --------------------------------------------------------- outputs

    /// Summary of the run so far. `job` is the stream report, if any.
    pub fn report(&self, job: Option<&StreamReport>) -> Report {
        let inner = self.inner();
        let rec = &inner.recorder;
        let axes = Axis::ALL
            .iter()
            .map(|&a| {
                let s = rec.axis_stats(a);
                AxisReport {
                    axis: a,
                    steps_pos: s.steps_pos,
                    steps_neg: s.steps_neg,
                    steps_while_disabled: s.steps_while_disabled,
                    final_position_steps: s.position,
                    // Physical Z steps count down from the top switch; the
                    // firmware's machine Z (and this figure) has +Z up.
                    final_position_mm: s.position as f64 / self.config.machine.steps_per_mm[a.index()]
                        * if a == Axis::Z { -1.0 } else { 1.0 },
                    peak_rate_hz: s.peak_rate_hz,
                    peak_rate_windowed_hz: s.peak_rate_windowed_hz,
                    max_accel_steps_per_s2: s.max_accel_steps_per_s2,
                    max_accel_mm_per_s2: s.max_accel_steps_per_s2.map(|x| x / self.config.machine.steps_per_mm[a.index()]),
                }
            })
            .collect();
        let mut errors: Vec<String> = inner.fatal.iter().map(|e| e.to_string()).collect();
        if let Some(j) = job {
            if j.timed_out {
                errors.push(format!("stream timed out after {:.3} s", j.duration_s.max(0.0)));
            }
        }
        let sim_time_s = self.seconds();
        let wall = self.wall_seconds();
        Report {
            elf: self.config.elf.display().to_string(),
            job_time_s: job.map_or(sim_time_s, |j| j.duration_s),
            sim_time_s,
            wall_time_s: wall,
            sim_speed: if wall > 0.0 { sim_time_s / wall } else { 0.0 },
            axes,
            stepper_isr: self.stepper_isr_stats(),
            isr: self.all_isr_stats(),
            max_interrupt_depth: inner.isr.max_depth(),
            stack_high_water_bytes: self.stack_high_water_bytes(),
            violation_count: rec.violation_count(),
            violations: rec.violations().to_vec(),
            uart: UartReport {
                bytes_to_chip: inner.host.bytes_to_chip,
                bytes_from_chip: inner.host.out.len() as u64,
                rx_dropped: inner.host.rx_dropped,
                rx_would_overrun: inner.host.rx_deep,
                simavr_messages: inner.log.iter().filter(|m| m.contains("UART")).cloned().collect(),
            },
            resets: inner.resets.clone(),
            spindle_on_at_end: self.spindle_on(),
            errors,
            stream: job.map(|j| StreamReport { received: Vec::new(), ..j.clone() }),
        }
    }

    /// Writes [`Vm::report`] as pretty JSON.
    pub fn write_json(&self, path: impl AsRef<Path>, job: Option<&StreamReport>) -> std::io::Result<()> {
        self.report(job).write_json(path)
    }

    /// Writes the step trace as CSV: `cycle,time_s,axis,position`.
    pub fn write_trace_csv(&self, path: impl AsRef<Path>) -> std::io::Result<()> {
        crate::report::write_trace_csv(path, self.recorder().trace(), self.config.frequency_hz)
    }
}

/// SRAM at power-on: noise, from a fixed seed per power cycle.
fn power_on_noise(sram: &mut [u8], seed: u64) {
    let mut rng = fastrand::Rng::with_seed(0x5EED_0000 + seed);
    rng.fill(sram);
}

/// Erases the application space if asked, then loads the bootloader with
/// the fuses and lock byte of a board as sold and points the reset vector
/// (BOOTRST) at it.
///
/// SAFETY: `avr` must be a live, initialised instance that is not running.
unsafe fn load_boot_section(avr: *mut ffi::avr_t, config: &VmConfig) -> Result<(), String> {
    // SAFETY: flash has flashend + 1 bytes; the caller owns the instance.
    unsafe {
        let flash = std::slice::from_raw_parts_mut((*avr).flash, (*avr).flashend as usize + 1);
        if config.blank_application {
            flash[..boot::BOOT_START as usize].fill(0xFF);
        }
        let Some(hex) = &config.bootloader else { return Ok(()) };
        for chunk in boot::read_ihex(hex)? {
            let (a, n) = (chunk.addr as usize, chunk.bytes.len());
            if a < boot::BOOT_START as usize || a + n > flash.len() {
                return Err(format!("{}: bytes at 0x{a:05x} outside the boot section", hex.display()));
            }
            flash[a..a + n].copy_from_slice(&chunk.bytes);
        }
        (*avr).codeend = (*avr).flashend;
        (*avr).reset_pc = boot::BOOT_START;
        (*avr).pc = boot::BOOT_START;
        for (i, &f) in boot::STOCK_FUSES.iter().enumerate() {
            (*avr).fuse[i] = f;
        }
        (*avr).lockbits = boot::STOCK_LOCK;
    }
    Ok(())
}

/// Finds UART0's `avr_uart_t` in the instance's I/O module list.
///
/// SAFETY: `avr` must be a live, initialised instance.
unsafe fn find_uart0(avr: *mut ffi::avr_t) -> *mut ffi::avr_uart_t {
    // SAFETY: walking simavr's own singly linked list of I/O modules.
    unsafe {
        let mut io = (*avr).io_port;
        while !io.is_null() {
            let kind = (*io).kind;
            if !kind.is_null() && CStr::from_ptr(kind).to_bytes() == b"uart" {
                // avr_uart_t starts with its avr_io_t.
                let u = io as *mut ffi::avr_uart_t;
                if (*u).name as u8 == b'0' {
                    return u;
                }
            }
            io = (*io).next;
        }
    }
    std::ptr::null_mut()
}

impl Drop for Vm {
    fn drop(&mut self) {
        // SAFETY: the instance and Inner were created in Vm::new and are freed
        // exactly once here; simavr is not running.
        unsafe {
            ffi::avr_terminate(self.avr);
            free(self.avr as *mut c_void);
            drop(Box::from_raw(self.inner));
        }
        let _ = (&self.hooks, &self.timer_wraps);
    }
}
