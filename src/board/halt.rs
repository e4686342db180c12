//! The end of every panic and `abort` path: the machine stops in
//! the same safe state as `M112`, says so, and stays stopped.
//!
//! [`halt`] runs with interrupts off and trusts nothing the failed code may
//! have left half-done: it makes the same register writes as the RX
//! interrupt's M112 (stepper timer stopped, the four drivers' enable pins
//! high, spindle PWM disconnected and its pin low), writes one `ALARM:` line
//! to USART0 by polling (the TX ring and its interrupt are not used), then
//! loops feeding the watchdog until the board is reset.
//!
//! Why no watchdog reset: a restart would print a fresh banner a host can
//! take for a healthy board, and lose the alarm. A reset by hand (the reset
//! button, or a host reopening the port, which pulses DTR) boots as usual:
//! unhomed, with the homing lock (`$22`) refusing motion, and no SD job
//! running, so nothing resumes by itself.

use avr_device::atmega2560::USART0;
use mill::flash::FStr;
use mill::F;

/// Stop the machine, report `ALARM:<what>, halted: reset the board`, halt.
pub fn halt(what: FStr) -> ! {
    avr_device::interrupt::disable();
    super::emergency_stop_in_isr();
    // SAFETY: interrupts are off for good: nothing else touches USART0 now.
    let u = unsafe { &*USART0::ptr() };
    // Only when the port was set up (TXEN0): before `serial::init` there is
    // nobody listening at a known baud rate.
    if u.ucsr0b().read().txen0().bit_is_set() {
        u.ucsr0b().modify(|_, w| w.udrie0().clear_bit().rxcie0().clear_bit());
        let put = |b: u8| {
            // UDRE0 is set within one character time (40 µs at 250000 baud);
            // the bound only guards against a transmitter that never frees up.
            for _ in 0..u16::MAX {
                if u.ucsr0a().read().udre0().bit_is_set() {
                    // SAFETY: UDR0 takes any byte.
                    u.udr0().write(|w| unsafe { w.bits(b) });
                    return;
                }
            }
        };
        // A fresh line: a reply may have been cut mid-line.
        // The text in flash (`F!`): a `&str` would cost its RAM copy.
        for b in F!("\nALARM:").bytes().chain(what.bytes()).chain(F!(", halted: reset the board\n").bytes()) {
            put(b);
        }
    }
    loop {
        super::wdt::feed();
    }
}
