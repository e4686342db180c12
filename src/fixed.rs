//! Fixed-point numbers for what a person reads (serial replies, OLED).
//!
//! Positions are shown in mm with three decimals. They are formatted from
//! integer micrometres with `ufmt`, so no float formatting code is linked.

use ufmt::{uWrite, uwrite};

/// A length in micrometres, printed as mm with three decimals (`-12.345`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Micros(pub i32);

impl Micros {
    /// Convert a float mm value, rounding to the nearest micrometre.
    pub fn from_mm(mm: f32) -> Micros {
        Micros(crate::math::round_i32(mm * 1000.0))
    }
}

impl ufmt::uDisplay for Micros {
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
        let v = self.0 as i64;
        let (sign, a) = if v < 0 { ("-", -v) } else { ("", v) };
        let int = (a / 1000) as u32;
        let frac = (a % 1000) as u16;
        let pad = if frac < 10 {
            "00"
        } else if frac < 100 {
            "0"
        } else {
            ""
        };
        uwrite!(f, "{}{}.{}{}", sign, int, pad, frac)
    }
}

/// A value with one decimal (tenths), printed like `12.5`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tenths(pub i32);

impl ufmt::uDisplay for Tenths {
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
        let v = self.0 as i64;
        let (sign, a) = if v < 0 { ("-", -v) } else { ("", v) };
        uwrite!(f, "{}{}.{}", sign, (a / 10) as u32, (a % 10) as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn show<T: ufmt::uDisplay>(v: T) -> String {
        let mut s = String::new();
        ufmt::uwrite!(s, "{}", v).unwrap();
        s
    }

    #[test]
    fn micrometres_print_as_millimetres_with_three_decimals() {
        assert_eq!(show(Micros(12345)), "12.345");
        assert_eq!(show(Micros(-5)), "-0.005");
        assert_eq!(show(Micros(40)), "0.040");
        assert_eq!(show(Micros(0)), "0.000");
        assert_eq!(show(Micros(i32::MIN)), "-2147483.648");
        assert_eq!(show(Micros::from_mm(-1.0006)), "-1.001");
    }

    #[test]
    fn tenths_print_with_one_decimal() {
        assert_eq!(show(Tenths(125)), "12.5");
        assert_eq!(show(Tenths(-3)), "-0.3");
    }
}
