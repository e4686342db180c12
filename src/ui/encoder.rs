//! Rotary encoder (A D31, B D33, button D35; docs/SPEC.md §2) decoding, sampled by
//! the 1 kHz Timer0 tick (`board`): PORTC has no pin-change interrupt on the
//! ATmega2560, and 1 kHz is 25 samples per quadrature step at 10 detents/s.
//!
//! Quadrature: with A and B as "contact closed", the Gray position
//! `p = B·2 + (A xor B)` counts 1, 2, 3, 0 clockwise (A leads B). Every
//! change of ±1 is a quarter step; a jump of 2 (a missed sample) is ignored.
//! A detent is counted when the contacts are back at rest (both open) with
//! at least two quarter steps in one direction, so contact bounce inside a
//! detent never counts twice.
//!
//! Button: a level must hold for [`DEBOUNCE_MS`] samples to count; each
//! debounced press counts once.

/// Samples (ms) a button level must hold to count.
pub const DEBOUNCE_MS: u8 = 8;

/// Decoder state (6 bytes, lives in the ISR's static).
#[derive(Clone, Copy, Default, Debug, PartialEq, Eq)]
pub struct Decoder {
    pos: u8,
    quarter: i8,
    /// Detents since the main loop last took them (+ = clockwise).
    pub detents: i8,
    /// Debounced button state and the samples the raw level has disagreed.
    pressed: bool,
    bounce: u8,
    /// Presses since the main loop last took them.
    pub presses: u8,
}

impl Decoder {
    pub const fn new() -> Decoder {
        Decoder { pos: 0, quarter: 0, detents: 0, pressed: false, bounce: 0, presses: 0 }
    }

    /// One 1 kHz sample; arguments are "contact closed".
    #[inline]
    pub fn sample(&mut self, a: bool, b: bool, button: bool) {
        let p = ((b as u8) << 1) | ((a ^ b) as u8);
        match p.wrapping_sub(self.pos) & 3 {
            1 => self.quarter = self.quarter.saturating_add(1),
            3 => self.quarter = self.quarter.saturating_sub(1),
            _ => {}
        }
        self.pos = p;
        if p == 0 {
            if self.quarter >= 2 {
                self.detents = self.detents.saturating_add(1);
            } else if self.quarter <= -2 {
                self.detents = self.detents.saturating_sub(1);
            }
            self.quarter = 0;
        }
        if button != self.pressed {
            self.bounce += 1;
            if self.bounce >= DEBOUNCE_MS {
                self.pressed = button;
                self.bounce = 0;
                if button {
                    self.presses = self.presses.saturating_add(1);
                }
            }
        } else {
            self.bounce = 0;
        }
    }

    /// The last sample left nothing in progress (the button's level agrees
    /// with its debounced state): a sample of the same levels again changes
    /// nothing, so the tick may skip it (`settled_levels_again_change_nothing`).
    pub fn settled(&self) -> bool {
        self.bounce == 0
    }

    /// Take the detents and presses counted so far.
    pub fn take(&mut self) -> (i8, u8) {
        let r = (self.detents, self.presses);
        self.detents = 0;
        self.presses = 0;
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The VM's quadrature cycle for one clockwise detent (A leads B).
    const CW: [(bool, bool); 4] = [(true, false), (true, true), (false, true), (false, false)];

    fn turn(d: &mut Decoder, detents: i32, samples_per_quarter: usize) {
        for _ in 0..detents.unsigned_abs() {
            for &(a, b) in &CW {
                let (a, b) = if detents > 0 { (a, b) } else { (b, a) };
                for _ in 0..samples_per_quarter {
                    d.sample(a, b, false);
                }
            }
        }
    }

    #[test]
    fn each_quadrature_cycle_is_one_detent_either_way() {
        let mut d = Decoder::new();
        turn(&mut d, 7, 25);
        assert_eq!(d.take(), (7, 0));
        turn(&mut d, -3, 1);
        assert_eq!(d.take(), (-3, 0));
    }

    #[test]
    fn bounce_inside_a_detent_does_not_count() {
        let mut d = Decoder::new();
        // Wobble between rest and the first quarter, then a real detent.
        for _ in 0..5 {
            d.sample(true, false, false);
            d.sample(false, false, false);
        }
        assert_eq!(d.take().0, 0);
        turn(&mut d, 1, 3);
        assert_eq!(d.take().0, 1);
    }

    #[test]
    fn a_button_press_counts_once_after_debouncing() {
        let mut d = Decoder::new();
        for i in 0..40 {
            d.sample(false, false, i % 3 == 0 && i < 6); // bounce
        }
        assert_eq!(d.take().1, 0);
        for _ in 0..50 {
            d.sample(false, false, true);
        }
        for _ in 0..50 {
            d.sample(false, false, false);
        }
        assert_eq!(d.take().1, 1);
    }

    /// The tick's fast path skips a sample when the levels are those of
    /// the last sample and it left the decoder settled: then that sample
    /// must change nothing, from every state a random walk reaches.
    #[test]
    fn settled_levels_again_change_nothing() {
        let mut rng = crate::test_util::XorShift(0xE4C0);
        let mut d = Decoder::new();
        let (mut skipped, mut walked) = (0, 0);
        for _ in 0..200_000 {
            let r = rng.next();
            // Mostly hold the levels (as the tick sees them between edges).
            let (a, b, button) = (r & 1 != 0, r & 2 != 0, r & 4 != 0);
            for _ in 0..(r >> 8) % 40 {
                d.sample(a, b, button);
                walked += 1;
                if d.settled() {
                    let before = d;
                    d.sample(a, b, button);
                    assert_eq!(d, before, "levels {a} {b} {button}");
                    skipped += 1;
                }
            }
            if r & 0x80 != 0 {
                d.take();
            }
        }
        assert!(skipped > walked / 4, "{skipped} of {walked}");
    }
}
