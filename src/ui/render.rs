//! Text screens for the 128x64 SH1106: 8 lines (one display page each) of
//! 21 characters in 6-pixel cells, rendered a slice at a time.
//!
//! No frame buffer: a screen is a function from a row number to a [`Line`]
//! (21 bytes of text + an "inverted" flag); [`Line::render`] turns any
//! column range of it into page bytes (bit 0 = top pixel), ready to send.
//! [`Line::hash`] lets the firmware skip pages that did not change.

use super::font::{self, CELL_W};
use super::text::Text;

/// Characters per line.
pub const COLS: usize = 21;
/// Lines per screen (= display pages).
pub const ROWS: usize = 8;
/// Display width, pixels.
pub const WIDTH: usize = 128;
/// Columns sent per I2C transfer (4 slices per page).
pub const SLICE: usize = 32;

/// One text line of a screen.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Line {
    pub chars: [u8; COLS],
    /// Drawn light-on-dark reversed (a highlight bar).
    pub invert: bool,
}

impl Default for Line {
    fn default() -> Self {
        Line::blank()
    }
}

impl Line {
    /// All spaces, not inverted.
    pub const fn blank() -> Line {
        Line { chars: [b' '; COLS], invert: false }
    }

    /// Put bytes at column `at` (clipped); returns the column after them.
    pub fn put(&mut self, at: usize, b: &[u8]) -> usize {
        let mut c = at;
        for &x in b {
            if c < COLS {
                self.chars[c] = x;
            }
            c += 1;
        }
        c
    }

    /// Put a flash text at `at`; returns the column after it.
    pub fn text(&mut self, at: usize, t: Text) -> usize {
        let mut c = at;
        t.for_each(|b| {
            if c < COLS {
                self.chars[c] = b;
            }
            c += 1;
        });
        c
    }

    /// Put an unsigned number at `at`; returns the column after it.
    pub fn uint(&mut self, at: usize, v: u32) -> usize {
        let mut d = [0u8; 10];
        let n = digits(v, &mut d);
        self.put(at, &d[10 - n..])
    }

    /// Put an unsigned number right-aligned so it ends just before `end`.
    pub fn uint_right(&mut self, end: usize, v: u32) {
        let mut d = [0u8; 10];
        let n = digits(v, &mut d);
        self.put(end.saturating_sub(n), &d[10 - n..]);
    }

    /// Put `um` micrometres as `-12.345` right-aligned, ending before `end`.
    pub fn micros_right(&mut self, end: usize, um: i32) {
        let mut buf = [b' '; 14];
        let i = micros_text(um, &mut buf);
        self.put(end.saturating_sub(buf.len() - i), &buf[i..]);
    }

    /// Put `um` micrometres as `-12.345` at `at`; returns the column after it.
    pub fn micros(&mut self, at: usize, um: i32) -> usize {
        let mut buf = [b' '; 14];
        let i = micros_text(um, &mut buf);
        self.put(at, &buf[i..])
    }

    /// 16-bit hash of the line (text and inversion), to skip unchanged pages.
    pub fn hash(&self) -> u16 {
        let mut h: u16 = if self.invert { 0x9E37 } else { 0x1234 };
        for &c in &self.chars {
            h = (h ^ c as u16).wrapping_mul(0x0101).rotate_left(5) ^ 0x5A;
        }
        h
    }

    /// Page bytes for display columns `x0 .. x0 + out.len()` (bit 0 = top).
    /// The cell and the column in it advance together (a division per
    /// column cost ~75 cycles on the AVR: most of a status refresh).
    pub fn render(&self, x0: usize, out: &mut [u8]) {
        let (mut cell, mut col) = (x0 / CELL_W, x0 % CELL_W);
        let invert = if self.invert { 0xFF } else { 0 };
        for o in out.iter_mut() {
            let b = match self.chars.get(cell) {
                Some(&c) => font::column(c, col),
                None => 0,
            };
            *o = b ^ invert;
            col += 1;
            if col == CELL_W {
                col = 0;
                cell += 1;
            }
        }
    }
}

/// Decimal digits of `v` at the end of `d`; returns how many. (No `u32`
/// `%`/`/` by 10: on the AVR each digit was a ~600-cycle `__udivmodsi4`.)
fn digits(mut v: u32, d: &mut [u8; 10]) -> usize {
    let mut n = 0;
    loop {
        let (q, r) = crate::math::div10(v);
        d[9 - n] = b'0' + r;
        n += 1;
        v = q;
        if v == 0 {
            return n;
        }
    }
}

/// `um` micrometres as `-12.345` at the end of `buf`; returns where it starts.
fn micros_text(um: i32, buf: &mut [u8; 14]) -> usize {
    let mut a = um.unsigned_abs();
    let mut i = buf.len();
    // Three decimals, the point, then at least one digit.
    for k in 0.. {
        let (q, r) = crate::math::div10(a);
        i -= 1;
        buf[i] = b'0' + r;
        a = q;
        if k == 2 {
            i -= 1;
            buf[i] = b'.';
        } else if k > 2 && a == 0 {
            break;
        }
    }
    if um < 0 {
        i -= 1;
        buf[i] = b'-';
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(l: &Line) -> String {
        String::from_utf8(l.chars.to_vec()).unwrap()
    }

    #[test]
    fn numbers_are_placed_and_aligned() {
        let mut l = Line::blank();
        l.put(0, b"X");
        l.micros_right(11, -12345);
        assert_eq!(s(&l), "X   -12.345          ");
        let mut l = Line::blank();
        l.micros_right(11, 5);
        l.uint_right(21, 100);
        assert_eq!(s(&l), "      0.005       100");
        let mut l = Line::blank();
        let c = l.text(0, Text::Yes);
        l.uint(c + 1, 0);
        assert_eq!(&s(&l)[..5], "Yes 0");
    }

    #[test]
    fn micrometres_and_integers_print_as_with_format() {
        let mut vals = vec![0, 1, -1, 5, 999, 1000, -1000, 1001, 12345, -12345, 99_999, i32::MAX, i32::MIN, i32::MIN + 1];
        let mut x = 0x2468_ACE1_u32;
        for _ in 0..5000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            vals.push(x as i32 >> (x % 28));
        }
        for um in vals {
            let mut l = Line::blank();
            l.micros_right(COLS, um);
            let a = um.unsigned_abs();
            let want = format!("{}{}.{:03}", if um < 0 { "-" } else { "" }, a / 1000, a % 1000);
            assert_eq!(s(&l).trim_start(), want);
            let mut l = Line::blank();
            l.uint_right(COLS, a);
            assert_eq!(s(&l).trim_start(), format!("{a}"));
        }
    }

    #[test]
    fn rendering_uses_the_font_and_inversion() {
        let mut l = Line::blank();
        l.put(0, b"A");
        let mut out = [0u8; 8];
        l.render(0, &mut out);
        assert_eq!(out, [0x3E, 0x09, 0x09, 0x3E, 0, 0, 0, 0]);
        l.invert = true;
        l.render(0, &mut out);
        assert_eq!(out[0], !0x3E);
        // Past the last cell (126, 127): blank, or solid when inverted.
        let mut tail = [1u8; 2];
        l.render(126, &mut tail);
        assert_eq!(tail, [0xFF, 0xFF]);
        assert_ne!(l.hash(), Line::blank().hash());
    }
}
