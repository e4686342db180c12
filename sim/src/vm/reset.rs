//! Resets: the external RESET pin, power cycles and the watchdog (with
//! [`Vm::hang`], which lets it fire). simavr zeroes its cycle count, drops
//! its timers and floats the pins on every reset; this file keeps the VM
//! clock monotonic, re-applies inputs, pokes and timers, and with the stock
//! bootloader holds the core for the fuses' start-up delay.

use super::inputs::drive_input;
use super::outputs::{set_coolant, update_spindle};
use super::simavr::no_sleep;
use super::{Inner, Vm};
use crate::boot;
use crate::pins::Input;
use crate::report::{ResetKind, ResetRecord};
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};

/// The ATmega2560's first SRAM address (after the reserved extended IO).
const RAM_START: usize = 0x200;

/// MCUSR: reset flags (PORF bit 0, EXTRF bit 1, BORF bit 2, WDRF bit 3).
const MCUSR: usize = 0x54;

/// Wraps the core's reset callback: remember the cycle count simavr is about
/// to zero. Called by `avr_reset` (watchdog or ours) before the I/O modules reset.
// SAFETY (contract): installed as `avr->reset` after `custom.data` points to our Inner.
pub(super) unsafe extern "C" fn reset_hook(avr: *mut ffi::avr_t) {
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

impl Vm {
    /// Bring the VM's side back in line after simavr reset the chip.
    pub(super) fn post_reset(&mut self, kind: Option<ResetKind>) {
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
                let ramend = (*avr).ramend as usize;
                power_on_noise(std::slice::from_raw_parts_mut(data.add(RAM_START), ramend + 1 - RAM_START), seed);
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
}

/// SRAM at power-on: noise, from a fixed seed per power cycle.
fn power_on_noise(sram: &mut [u8], seed: u64) {
    let mut rng = fastrand::Rng::with_seed(0x5EED_0000 + seed);
    rng.fill(sram);
}
