//! grbl 1.1's realtime overrides: the bytes 0x90–0xA1 a grbl sender writes
//! at any instant (UGS, cncjs, bCNC, gSender, Candle), and what each does to
//! the feed, rapid and spindle percentages.
//!
//! The serial interrupt turns each byte into a bit ([`motion_bit`],
//! [`accessory_bit`]) of one of two request bytes, as grbl's
//! `sys_rt_exec_motion_override` and `sys_rt_exec_accessory_override` do; the
//! main loop takes both and applies them here ([`Percent::apply_motion`],
//! [`Percent::apply_spindle`]), then re-plans the queued moves
//! (`Planner::set_overrides`) and sets the spindle output. Pure logic,
//! host-tested.
//!
//! | byte | grbl's name | here |
//! |---|---|---|
//! | 0x90 | feed 100 % | feed override 100 % |
//! | 0x91 / 0x92 | feed +10 % / −10 % | within 10–200 % |
//! | 0x93 / 0x94 | feed +1 % / −1 % | within 10–200 % |
//! | 0x95 / 0x96 / 0x97 | rapid 100 / 50 / 25 % | G0 and the tool changer's travels |
//! | 0x99 | spindle 100 % | spindle override 100 % |
//! | 0x9A / 0x9B | spindle +10 % / −10 % | within 10–200 % |
//! | 0x9C / 0x9D | spindle +1 % / −1 % | within 10–200 % |
//! | 0x9E | spindle stop | in a feed hold only: off, again on; `~` restores it |
//! | 0xA0 | flood coolant toggle | the coolant output (D9) on/off |
//! | 0xA1 | mist coolant toggle | the same output (one pin for M7 and M8) |

/// The lowest and highest feed and spindle override, percent (grbl's).
pub const MIN_PCT: u16 = 10;
pub const MAX_PCT: u16 = 200;

/// Motion request bits (from 0x90–0x97): bit n is byte 0x90 + n.
pub mod motion {
    pub const FEED_RESET: u8 = 1 << 0;
    pub const FEED_PLUS_10: u8 = 1 << 1;
    pub const FEED_MINUS_10: u8 = 1 << 2;
    pub const FEED_PLUS_1: u8 = 1 << 3;
    pub const FEED_MINUS_1: u8 = 1 << 4;
    pub const RAPID_RESET: u8 = 1 << 5;
    pub const RAPID_MEDIUM: u8 = 1 << 6;
    pub const RAPID_LOW: u8 = 1 << 7;
}

/// Accessory request bits (from 0x99–0x9E, 0xA0, 0xA1).
pub mod accessory {
    pub const SPINDLE_RESET: u8 = 1 << 0;
    pub const SPINDLE_PLUS_10: u8 = 1 << 1;
    pub const SPINDLE_MINUS_10: u8 = 1 << 2;
    pub const SPINDLE_PLUS_1: u8 = 1 << 3;
    pub const SPINDLE_MINUS_1: u8 = 1 << 4;
    pub const SPINDLE_STOP: u8 = 1 << 5;
    pub const FLOOD: u8 = 1 << 6;
    pub const MIST: u8 = 1 << 7;
}

/// The motion request bit of byte `b`, or 0.
pub const fn motion_bit(b: u8) -> u8 {
    if b >= 0x90 && b <= 0x97 {
        1 << (b - 0x90)
    } else {
        0
    }
}

/// The accessory request bit of byte `b`, or 0.
pub const fn accessory_bit(b: u8) -> u8 {
    match b {
        0x99..=0x9E => 1 << (b - 0x99),
        0xA0 => accessory::FLOOD,
        0xA1 => accessory::MIST,
        _ => 0,
    }
}

/// The overrides in force, percent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Percent {
    pub feed: u16,
    /// 100, 50 or 25.
    pub rapid: u8,
    pub spindle: u8,
}

impl Percent {
    pub const NONE: Percent = Percent { feed: 100, rapid: 100, spindle: 100 };

    /// Apply the motion request `bits` as grbl does: every request of the
    /// byte in turn (reset, ±10, ±1), clamped to 10–200 %; a feed above
    /// 200 % from `M220` is taken down to 200 by any step.
    pub fn apply_motion(&mut self, bits: u8) {
        self.feed = step(self.feed, bits);
        if bits & motion::RAPID_RESET != 0 {
            self.rapid = 100;
        }
        if bits & motion::RAPID_MEDIUM != 0 {
            self.rapid = 50;
        }
        if bits & motion::RAPID_LOW != 0 {
            self.rapid = 25;
        }
    }

    /// Apply the spindle part of the accessory request `bits`.
    pub fn apply_spindle(&mut self, bits: u8) {
        self.spindle = step(self.spindle as u16, bits & 0b1_1111) as u8;
    }
}

/// A percentage after the reset/±10/±1 requests of `bits` (the same bit
/// order for the feed and the spindle).
fn step(pct: u16, bits: u8) -> u16 {
    if bits & 0b1_1111 == 0 {
        return pct;
    }
    let mut p = pct as i16;
    if bits & motion::FEED_RESET != 0 {
        p = 100;
    }
    if bits & motion::FEED_PLUS_10 != 0 {
        p += 10;
    }
    if bits & motion::FEED_MINUS_10 != 0 {
        p -= 10;
    }
    if bits & motion::FEED_PLUS_1 != 0 {
        p += 1;
    }
    if bits & motion::FEED_MINUS_1 != 0 {
        p -= 1;
    }
    p.clamp(MIN_PCT as i16, MAX_PCT as i16) as u16
}

/// The spindle PWM duty `duty` (0–255, as the program set it) under the
/// spindle override `pct`: scaled, at most full on, never off while on.
pub fn spindle_duty(duty: u8, pct: u8) -> u8 {
    if duty == 0 {
        return 0;
    }
    let d = duty as u16 * pct as u16 / 100;
    d.clamp(1, 255) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_byte_has_its_own_bit_and_others_none() {
        let mut seen = 0u16;
        for b in 0x90..=0x97u8 {
            let m = motion_bit(b);
            assert_eq!(m.count_ones(), 1, "{b:#x}");
            assert_eq!(seen & m as u16, 0);
            seen |= m as u16;
        }
        let mut seen = 0u8;
        for b in [0x99, 0x9A, 0x9B, 0x9C, 0x9D, 0x9E, 0xA0, 0xA1] {
            let a = accessory_bit(b);
            assert_eq!(a.count_ones(), 1, "{b:#x}");
            assert_eq!(seen & a, 0);
            seen |= a;
        }
        for b in [0x80, 0x85, 0x98, 0x9F, 0xA2, 0xC2, 0xFF, b'?', b'!'] {
            assert_eq!((motion_bit(b), accessory_bit(b)), (0, 0), "{b:#x}");
        }
    }

    #[test]
    fn feed_steps_clamp_to_grbls_range_and_rapid_takes_three_values() {
        let mut p = Percent::NONE;
        for _ in 0..3 {
            p.apply_motion(motion_bit(0x91));
        }
        assert_eq!(p.feed, 130);
        p.apply_motion(motion_bit(0x94));
        assert_eq!(p.feed, 129);
        for _ in 0..20 {
            p.apply_motion(motion_bit(0x91));
        }
        assert_eq!(p.feed, 200);
        p.apply_motion(motion_bit(0x90));
        assert_eq!(p.feed, 100);
        for _ in 0..20 {
            p.apply_motion(motion_bit(0x92));
        }
        assert_eq!(p.feed, 10);
        // Several requests in one byte: reset first, then the steps.
        p.apply_motion(motion::FEED_RESET | motion::FEED_PLUS_10 | motion::FEED_PLUS_1);
        assert_eq!(p.feed, 111);
        // M220 S300, then a step: into grbl's range.
        p.feed = 300;
        p.apply_motion(motion::FEED_PLUS_1);
        assert_eq!(p.feed, 200);
        p.apply_motion(motion_bit(0x97));
        assert_eq!((p.feed, p.rapid), (200, 25));
        p.apply_motion(motion_bit(0x96));
        assert_eq!(p.rapid, 50);
        p.apply_motion(motion_bit(0x95));
        assert_eq!(p.rapid, 100);
    }

    #[test]
    fn spindle_steps_and_the_scaled_duty() {
        let mut p = Percent::NONE;
        p.apply_spindle(accessory_bit(0x9B) | accessory::FLOOD);
        assert_eq!(p.spindle, 90);
        p.apply_spindle(accessory_bit(0x9E));
        assert_eq!(p.spindle, 90, "spindle stop is not a step");
        p.apply_spindle(accessory_bit(0x99));
        assert_eq!(p.spindle, 100);
        assert_eq!(spindle_duty(200, 150), 255);
        assert_eq!(spindle_duty(200, 50), 100);
        assert_eq!(spindle_duty(1, 10), 1);
        assert_eq!(spindle_duty(0, 150), 0);
    }
}
