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
//! - **UART timing.** simavr computes a frame time only when UBRRnL is
//!   written, from the U2Xn bit of that moment, and counts 11 bits per byte
//!   (it always adds a parity bit): a firmware that writes UBRR0 before
//!   U2X0 (this one) ran its link at half the baud rate in simulation, and
//!   every link ~10 % slow. The VM recomputes UART0's frame time after every
//!   write to UCSR0A/B/C and UBRR0H/L as the hardware counts it (start,
//!   data, parity only if UPM0 is set, stop bits; `uart_clock`), and the
//!   host link paces bytes with that same frame time
//!   ([`Vm::uart_frame_cycles`]).
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
//!
//! This file owns the [`Vm`] type, the state its simavr callbacks share
//! (`Inner`), the errors that stop it, its clock and the run loop. The rest,
//! one job per file:
//! - `config`: [`VmConfig`], its defaults and the grbl-Mega preset.
//! - `setup`: [`Vm::new`]: the ELF (and bootloader) loaded into a fresh
//!   simavr instance and every hook below registered on it.
//! - `simavr`: glue over simavr's C API the other files share (ioctl
//!   codes, register bits, libc, the logger, the `sleep` replacement).
//! - `reset`: external, power-on and watchdog resets, the cycle base
//!   across them and the bootloader's start-up delay.
//! - `timers`: the TCCRnB wrap that keeps TCNTn across a clock stop/start.
//! - `interrupts`: vector entry/exit: ISR statistics and nesting.
//! - `uart_clock`: UART0's frame time recomputed as the hardware has it.
//! - `uart`: UART0's host side: paced and flood sending, the lines the
//!   firmware prints, commands and streamed jobs.
//! - `drivers`: step/dir/enable pins into the [`Recorder`]; positions.
//! - `inputs`: the machine model onto the input pins (switches, tool
//!   setter, carousel sensor, encoder), overrides, contact bounce.
//! - `outputs`: the spindle's PWM duty and the coolant output.
//! - `display`: the SH1106 OLED on the TWI bus.
//! - `sd_socket`: the SD card on the SPI bus and its socket.
//! - `memory`: data space, flash, EEPROM, ELF symbols, stack high water.
//! - `call`: one routine of the ELF called with chosen registers (the
//!   tests of the assembly float routines).
//! - `summary`: the run's [`Report`](crate::report::Report), its JSON, the
//!   step trace CSV and simavr's log.

mod call;
mod config;
mod display;
mod drivers;
mod inputs;
mod interrupts;
mod memory;
mod outputs;
mod reset;
mod sd_socket;
mod setup;
mod simavr;
mod summary;
mod timers;
mod uart;
mod uart_clock;

pub use config::VmConfig;
pub use memory::{EEPROM_SIZE, RAMEND, STACK_PAINT};

use crate::elf::ElfSymbols;
use crate::isr::IsrTracker;
use crate::oled::Sh1106;
use crate::physics::Physics;
use crate::pins::{Input, PinMap};
use crate::recorder::Recorder;
use crate::report::ResetRecord;
use crate::sdcard::SdCard;
use drivers::PinHook;
use serde::Serialize;
use simavr::free;
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};
use timers::TimerWrap;
use uart::UartHost;
use uart_clock::UartWrap;

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

/// The virtual machine. See the module docs.
pub struct Vm {
    avr: *mut ffi::avr_t,
    inner: *mut Inner,
    hooks: Box<[PinHook]>,
    timer_wraps: Box<[TimerWrap]>,
    uart_wraps: Box<[UartWrap]>,
    config: VmConfig,
    symbols: ElfSymbols,
    wall_start: std::time::Instant,
}

// SAFETY: the simavr instance and Inner are owned exclusively by this Vm and
// touched only from the thread that currently owns it; simavr keeps no
// per-thread state (its only global, the logger, reads per-instance data).
unsafe impl Send for Vm {}

// ---------------------------------------------------------------- callbacks

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

/// Bounds an `avr_run` batch at a VM-chosen cycle.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn stop_timer(_avr: *mut ffi::avr_t, _when: ffi::avr_cycle_count_t, param: *mut c_void) -> u64 {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.stop_armed_at = None;
    0
}

// ----------------------------------------------------------------- the Vm

impl Vm {
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
        let _ = (&self.hooks, &self.timer_wraps, &self.uart_wraps);
    }
}
