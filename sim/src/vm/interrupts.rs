//! Interrupt vectors: every vector's entry and RETI timed into the
//! [`IsrTracker`](crate::isr::IsrTracker) (per-vector service times) and the
//! nesting depth checked against `max_interrupt_nesting`.

use super::{Inner, Vm, VmError};
use crate::isr::{IsrStats, STEPPER_VECTOR};
use simavr_ffi as ffi;
use std::ffi::c_void;

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

/// Watches every vector's "running" IRQ.
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` the
/// Inner it calls back with, alive as long as the instance.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) {
    let param = inner as *mut c_void;
    // SAFETY: avr is live; each IRQ comes from simavr's own lookup and is checked for null.
    unsafe {
        for v in 1..64u8 {
            let irq = ffi::avr_get_interrupt_irq(avr, v);
            if !irq.is_null() {
                ffi::avr_irq_register_notify(irq.add(ffi::AVR_INT_IRQ_RUNNING as usize), Some(isr_notify), param);
            }
        }
    }
}

impl Vm {
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
}
