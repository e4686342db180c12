//! The spindle output: D10 = PB4 = OC2A, driving the DC spindle's MOSFET.
//!
//! The duty cycle is derived from Timer2's registers (ATmega2560 datasheet
//! §20, "8-bit Timer/Counter2 with PWM"): COM2A1:0 in TCCR2A, WGM22:0 across
//! TCCR2A/TCCR2B, the clock select CS22:0 and OCR2A. When OC2A is not
//! connected, the pin is a plain output and PORTB4 decides. A pin that is not
//! an output (DDRB4 = 0) leaves the MOSFET gate to its pull-down: off.

/// Timer2 control register A, data-space address.
pub const TCCR2A: u16 = 0xB0;
/// Timer2 control register B.
pub const TCCR2B: u16 = 0xB1;
/// Output compare A of timer 2.
pub const OCR2A: u16 = 0xB3;
/// DDRB.
pub const DDRB: u16 = 0x24;
/// PORTB.
pub const PORTB: u16 = 0x25;

/// Spindle duty 0.0..=1.0 from the register values.
///
/// Fast PWM non-inverting with OCR2A = 0 produces a one-tick spike per period
/// on real hardware; it is reported as 0 (off), which is what it does to a
/// DC motor.
pub fn duty(tccr2a: u8, tccr2b: u8, ocr2a: u8, ddrb: u8, portb: u8) -> f64 {
    const BIT: u8 = 1 << 4;
    if ddrb & BIT == 0 {
        return 0.0;
    }
    let pin_level = if portb & BIT != 0 { 1.0 } else { 0.0 };
    let com = (tccr2a >> 6) & 3;
    let wgm = (tccr2a & 3) | ((tccr2b >> 1) & 4);
    let clock_runs = tccr2b & 7 != 0;
    if com == 0 {
        return pin_level;
    }
    if !clock_runs {
        // Output compare unit connected but frozen: the OC2A latch holds its
        // last level, which the simulator does not expose; PORT is the best guess.
        return pin_level;
    }
    let ocr = ocr2a as f64;
    match (wgm, com) {
        // Fast PWM, TOP = 0xFF.
        (3, 2) => {
            if ocr2a == 0 {
                0.0
            } else {
                (ocr + 1.0) / 256.0
            }
        }
        (3, 3) => (255.0 - ocr) / 256.0,
        // Phase-correct PWM, TOP = 0xFF.
        (1, 2) => ocr / 255.0,
        (1, 3) => 1.0 - ocr / 255.0,
        // Toggle on compare (non-PWM modes, or WGM 5/7 with COM = 1): square wave.
        (_, 1) => 0.5,
        // Set/clear on compare in non-PWM modes: a static level after the
        // first match; PORT is the best guess.
        _ => pin_level,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_pwm_duty_and_off_cases() {
        // Fast PWM (WGM21:0 = 3), COM2A1 = 1, clk/8, pin output.
        assert_eq!(duty(0b1000_0011, 0b010, 127, 0x10, 0), 0.5);
        assert_eq!(duty(0b1000_0011, 0b010, 0, 0x10, 0), 0.0);
        assert_eq!(duty(0b1000_0011, 0b010, 255, 0x10, 0), 1.0);
        // Not an output: off.
        assert_eq!(duty(0b1000_0011, 0b010, 200, 0x00, 0x10), 0.0);
        // Disconnected from the timer: PORT decides.
        assert_eq!(duty(0b0000_0011, 0b010, 200, 0x10, 0x10), 1.0);
        assert_eq!(duty(0b0000_0011, 0b010, 200, 0x10, 0x00), 0.0);
    }
}
