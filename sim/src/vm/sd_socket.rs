//! The SD socket: the [`SdCard`] on the SPI bus, selected by PB0, answering
//! each byte the firmware's SPI master clocks out; inserting and pulling
//! the card (with its detect switch).

use super::simavr::{ioctl_def, ioctl_ioport_getirq};
use super::{Inner, Vm};
use crate::pins::{Input, Pin};
use crate::sdcard::SdCard;
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};

/// simavr's `AVR_IOCTL_SPI_GETIRQ(0)`: the ATmega2560 declares its SPI
/// without a name (name 0).
const IOCTL_SPI_GETIRQ: u32 = ioctl_def(b's', b'p', b'i', 0);
/// SD card chip select: PB0 (D53).
const SD_CS: Pin = Pin::new(b'B', 0);

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

/// Hooks the SPI's output and PB0, and finds the SPI's input (for MISO).
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` the
/// Inner it calls back with, alive as long as the instance.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) {
    let param = inner as *mut c_void;
    // SAFETY: avr is live; each IRQ comes from simavr's own lookup and is checked for null.
    unsafe {
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
    }
}

impl Vm {
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
}
