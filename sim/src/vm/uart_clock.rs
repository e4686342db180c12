//! UART0's frame time as the hardware has it (module docs of `vm`):
//! simavr's `cycles_per_byte` recomputed after every write to the
//! registers that set it, so that the chip receives (and sends) one byte
//! per frame of the baud rate its registers give, whatever order the
//! firmware writes them in.
//!
//! simavr computes a UART's frame time only when UBRRnL is written, from
//! the U2Xn bit it finds at that moment, and always counts a parity bit
//! (11 bits for 8N1). A firmware that writes UBRR0 before setting U2X0 (as
//! this one does; grbl sets U2X0 first) then runs its serial link at half
//! the baud rate in simulation, both ways, though the hardware runs it at
//! the full rate (datasheet §22.3.1: the rate is fosc / (8 (UBRRn + 1))
//! with U2Xn set, fosc / (16 (UBRRn + 1)) without, whenever the bits are
//! set). Here the frame is start + data + parity (only if UPMn is set) +
//! stop bits (§22.4), recomputed from UBRR0H/L, U2X0, UCSZ0[2:0], UPM0 and
//! USBS0 after any of UCSR0A, UCSR0B, UCSR0C, UBRR0L or UBRR0H is written.
//! simavr's receiver pump, its transmitter pump and the host feeder all
//! read `cycles_per_byte`, so all three follow.

use simavr_ffi as ffi;
use std::ffi::c_void;

/// Data-space addresses of USART0's registers (ATmega2560 register summary).
const UCSR0A: u16 = 0xC0;
const UCSR0B: u16 = 0xC1;
const UCSR0C: u16 = 0xC2;
const UBRR0L: u16 = 0xC4;
const UBRR0H: u16 = 0xC5;

/// Param of a wrapped USART0 register write handler.
pub(super) struct UartWrap {
    /// Data-space address of the register.
    addr: u16,
    orig: ffi::avr_io_write_t,
    orig_param: *mut c_void,
    uart: *mut ffi::avr_uart_t,
}

/// Cycles per frame for the USART register values `a`..`ubrrh` (UCSRnA,
/// UCSRnB, UCSRnC, UBRRnL, UBRRnH), datasheet §22.3.1 and §22.4.
pub(super) fn frame_cycles(a: u8, b: u8, c: u8, ubrrl: u8, ubrrh: u8) -> u64 {
    let ubrr = (((ubrrh & 0x0F) as u64) << 8) | ubrrl as u64;
    let per_bit = (ubrr + 1) * if a & 0x02 != 0 { 8 } else { 16 };
    // UCSZn2 (UCSRnB bit 2) : UCSZn1:0 (UCSRnC bits 2:1); reserved sizes as 8.
    let ucsz = ((b >> 2) & 1) << 2 | ((c >> 1) & 3);
    let data = [5, 6, 7, 8, 8, 8, 8, 9][ucsz as usize];
    let parity = u64::from((c >> 4) & 3 != 0);
    let stop = 1 + ((c >> 3) & 1) as u64;
    per_bit * (1 + data + parity + stop)
}

/// Runs simavr's handler for the register (or stores the byte when it has
/// none), then recomputes UART0's frame time from the registers.
// SAFETY (contract): installed as `avr->io[addr].w` with a UartWrap param
// that lives in Vm::uart_wraps; simavr calls it for CPU writes to `addr`.
unsafe extern "C" fn usart_write(avr: *mut ffi::avr_t, addr: ffi::avr_io_addr_t, v: u8, param: *mut c_void) {
    // SAFETY: param is a UartWrap alive as long as the instance; avr is live;
    // the UART struct is the instance's own; the addresses are below RAMEND.
    unsafe {
        let w = &*(param as *const UartWrap);
        match w.orig {
            Some(orig) => orig(avr, addr, v, w.orig_param),
            None => *(*avr).data.add(w.addr as usize) = v,
        }
        let d = |r: u16| *(*avr).data.add(r as usize);
        (*w.uart).cycles_per_byte = frame_cycles(d(UCSR0A), d(UCSR0B), d(UCSR0C), d(UBRR0L), d(UBRR0H));
    }
}

/// Wraps the write handlers of USART0's rate and frame registers. The
/// returned wraps are the handlers' params: keep them as long as the
/// instance.
///
/// SAFETY: `avr` must be a live, initialised instance that is not running
/// and `uart` its UART0.
pub(super) unsafe fn wrap(avr: *mut ffi::avr_t, uart: *mut ffi::avr_uart_t) -> Box<[UartWrap]> {
    let mut wraps: Box<[UartWrap]> = [UCSR0A, UCSR0B, UCSR0C, UBRR0L, UBRR0H]
        .iter()
        .map(|&addr| {
            // SAFETY: avr is live; reading the register's I/O table entry.
            let w = unsafe { (*avr).io[(addr - 32) as usize].w };
            UartWrap { addr, orig: w.c, orig_param: w.param, uart }
        })
        .collect();
    for w in wraps.iter_mut() {
        // SAFETY: avr is live and not running; the wrap outlives the instance (dropped after it in Vm::drop).
        unsafe {
            let slot = &mut (*avr).io[(w.addr - 32) as usize].w;
            slot.c = Some(usart_write);
            slot.param = w as *mut UartWrap as *mut c_void;
        }
    }
    wraps
}

#[cfg(test)]
mod tests {
    use super::frame_cycles;

    #[test]
    fn frames_are_counted_as_the_datasheet_counts_them() {
        // 8N1 with U2X: 10 bits of 8 (UBRR + 1) cycles.
        assert_eq!(frame_cycles(0x02, 0, 0x06, 7, 0), 640); // 250000 baud
        assert_eq!(frame_cycles(0x02, 0, 0x06, 16, 0), 1360); // 117647 baud
                                                              // Without U2X each bit takes twice as long.
        assert_eq!(frame_cycles(0, 0, 0x06, 7, 0), 1280);
        // Even parity and two stop bits: 12 bits; 9 data bits: 12 bits.
        assert_eq!(frame_cycles(0x02, 0, 0x26 | 0x08, 7, 0), 768);
        assert_eq!(frame_cycles(0x02, 0x04, 0x06 | 0x08, 7, 0), 768);
        // UBRRH's low nibble counts.
        assert_eq!(frame_cycles(0x02, 0, 0x06, 0, 1), 257 * 8 * 10);
    }
}
