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

/// How a line is drawn.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Style {
    /// Text in 6-pixel cells.
    Text,
    /// A title bar: text, with its bottom pixel row dark, so that a
    /// highlighted line under it stays apart from it.
    Title,
    /// The top or the bottom half of double-size text: 12-pixel cells, two
    /// pages tall, [`BIG_COLS`] characters (the status screen's large
    /// digits).
    BigTop,
    BigBottom,
}

/// Characters of a double-size line.
pub const BIG_COLS: usize = WIDTH / (2 * CELL_W);

/// One text line of a screen.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Line {
    pub chars: [u8; COLS],
    /// Drawn light-on-dark reversed (a highlight bar).
    pub invert: bool,
    pub style: Style,
}

impl Default for Line {
    fn default() -> Self {
        Line::blank()
    }
}

impl Line {
    /// All spaces, not inverted.
    pub const fn blank() -> Line {
        Line { chars: [b' '; COLS], invert: false, style: Style::Text }
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
        h ^= (self.style as u16) << 11;
        for &c in &self.chars {
            h = (h ^ c as u16).wrapping_mul(0x0101).rotate_left(5) ^ 0x5A;
        }
        h
    }

    /// Page bytes for display columns `x0 .. x0 + out.len()` (bit 0 = top).
    /// The cell and the column in it advance together (a division per
    /// column cost ~75 cycles on the AVR: most of a status refresh).
    pub fn render(&self, x0: usize, out: &mut [u8]) {
        let big = matches!(self.style, Style::BigTop | Style::BigBottom);
        let cell_w = if big { 2 * CELL_W } else { CELL_W };
        let (mut cell, mut col) = (x0 / cell_w, x0 % cell_w);
        let invert = if self.invert { 0xFF } else { 0 };
        // A title's bottom pixel row stays dark.
        let keep = if self.style == Style::Title { 0x7F } else { 0xFF };
        for o in out.iter_mut() {
            let c = self.chars.get(cell).copied().unwrap_or(b' ');
            let b = match self.style {
                Style::Text | Style::Title => font::column(c, col),
                // Each glyph column twice, each of its rows twice: the top
                // half holds rows 0-3, the bottom half rows 4-7.
                Style::BigTop => stretch(font::column(c, col / 2) & 0x0F),
                Style::BigBottom => stretch(font::column(c, col / 2) >> 4),
            };
            *o = (b ^ invert) & keep;
            col += 1;
            if col == cell_w {
                col = 0;
                cell += 1;
            }
        }
    }
}

/// The four low bits of `n`, each doubled: bit i to bits 2i and 2i + 1.
fn stretch(n: u8) -> u8 {
    let mut b = 0;
    for i in 0..4 {
        if n & (1 << i) != 0 {
            b |= 0b11 << (2 * i);
        }
    }
    b
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

    #[test]
    fn a_title_keeps_its_bottom_row_dark_and_big_text_doubles_each_pixel() {
        let mut l = Line::blank();
        l.put(0, b"1");
        l.invert = true;
        l.style = Style::Title;
        let mut out = [0u8; 6];
        l.render(0, &mut out);
        for (c, b) in out.iter().enumerate() {
            assert_eq!(*b, !font::column(b'1', c) & 0x7F, "column {c}");
        }
        // Double size: 12 columns a cell, each glyph column twice; the top
        // half carries rows 0-3 doubled, the bottom half rows 4-7.
        l.invert = false;
        let (mut top, mut bottom) = ([0u8; 12], [0u8; 12]);
        l.style = Style::BigTop;
        l.render(0, &mut top);
        l.style = Style::BigBottom;
        l.render(0, &mut bottom);
        for x in 0..12 {
            let g = font::column(b'1', x / 2);
            for row in 0..8 {
                let on = g & (1 << row) != 0;
                let (half, y) = if row < 4 { (top[x], 2 * row) } else { (bottom[x], 2 * (row - 4)) };
                assert_eq!(half & (0b11 << y) != 0, on, "x {x} row {row}");
                assert!(half & (0b11 << y) == 0b11 << y || half & (0b11 << y) == 0, "x {x} row {row}: both pixel rows alike");
            }
        }
        assert_ne!(Line { style: Style::BigTop, ..l }.hash(), Line { style: Style::BigBottom, ..l }.hash());
    }

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
        let mut rng = crate::test_util::XorShift(0x2468_ACE1);
        for _ in 0..5000 {
            let x = rng.next();
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
