//! The SH1106 OLED on the TWI bus: the bus conditions and bytes the
//! firmware's TWI master puts out, acknowledged and fed to the
//! [`Sh1106`] model at 0x3C; screenshots of what it shows.

use super::simavr::ioctl_def;
use super::{Inner, Vm};
use crate::oled::Sh1106;
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};
use std::path::Path;

/// simavr's `AVR_IOCTL_TWI_GETIRQ(0)`: the ATmega2560 declares its TWI
/// without a name (name 0).
const IOCTL_TWI_GETIRQ: u32 = ioctl_def(b't', b'w', b'i', 0);

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

/// Hooks the TWI's output and finds its input (for the acknowledges).
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` the
/// Inner it calls back with, alive as long as the instance.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) {
    let param = inner as *mut c_void;
    // SAFETY: avr is live; each IRQ comes from simavr's own lookup and is checked for null.
    unsafe {
        // OLED on the TWI bus.
        let twi_out = ffi::avr_io_getirq(avr, IOCTL_TWI_GETIRQ, ffi::TWI_IRQ_OUTPUT as c_int);
        (*inner).twi_input = ffi::avr_io_getirq(avr, IOCTL_TWI_GETIRQ, ffi::TWI_IRQ_INPUT as c_int);
        if !twi_out.is_null() {
            ffi::avr_irq_register_notify(twi_out, Some(twi_notify), param);
        }
    }
}

impl Vm {
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
}
