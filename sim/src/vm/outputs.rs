//! The machine's outputs: the spindle's PWM duty (Timer2's OC2A on PB4,
//! [`crate::spindle`]) and the coolant output (PH6), each with its history.

use super::simavr::ioctl_ioport_getirq;
use super::{Inner, Vm};
use crate::pins::{COOLANT, SPINDLE_PWM};
use crate::spindle;
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};

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

pub(super) fn set_coolant(inner: &mut Inner, on: bool) {
    if on != inner.coolant {
        inner.coolant = on;
        let now = inner.now();
        inner.coolant_history.push((now, on));
    }
}

pub(super) fn update_spindle(inner: &mut Inner) {
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

/// Hooks Timer2's registers and PB4 (spindle) and PH6 (coolant).
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` the
/// Inner it calls back with, alive as long as the instance.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) {
    let param = inner as *mut c_void;
    // SAFETY: avr is live; each IRQ comes from simavr's own lookup and is checked for null.
    unsafe {
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
    }
}

impl Vm {
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
}
