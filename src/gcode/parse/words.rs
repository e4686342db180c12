//! The value words of a line: [`Word`] (the letters, their bits) and
//! [`Words`], the set of words present with their values, tested by mask.

use core::mem::MaybeUninit;

/// Value words, in the bit order of [`Words`].
///
/// `B` is the G37 broken-tool tolerance (docs/SPEC.md §5); `A`, `C` (rotary axes),
/// `U`, `V`, `W` are axes this machine does not have, and `O` is a program
/// number or an O-word (see [`parse`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Word {
    B,
    D,
    E,
    F,
    H,
    I,
    J,
    K,
    L,
    N,
    P,
    Q,
    R,
    S,
    T,
    X,
    Y,
    Z,
    /// `@`: polar radius (LinuxCNC), mm or inches.
    At,
    /// `^`: polar angle (LinuxCNC), degrees counter-clockwise from +X.
    Caret,
}

impl Word {
    /// Number of value words.
    pub const COUNT: usize = 20;
    /// Every word, in bit order.
    pub const ALL: [Word; Word::COUNT] = [
        Word::B,
        Word::D,
        Word::E,
        Word::F,
        Word::H,
        Word::I,
        Word::J,
        Word::K,
        Word::L,
        Word::N,
        Word::P,
        Word::Q,
        Word::R,
        Word::S,
        Word::T,
        Word::X,
        Word::Y,
        Word::Z,
        Word::At,
        Word::Caret,
    ];

    /// The word for a letter, any case (and `@`, `^`); `None` for letters
    /// outside the dialect and for `G` and `M`, which are codes.
    ///
    /// One read of [`LETTER_WORDS`], a table in flash, instead of a chain
    /// of compares (~76 cycles a call on the AVR, twice a streamed line);
    /// the same answer as the match it replaces for every byte
    /// (`the_letter_table_matches_the_match`).
    // speed: the parser's per-word lookup (doc above)
    #[inline(always)]
    pub fn from_letter(c: u8) -> Option<Word> {
        LETTER_WORDS.row(c.to_ascii_uppercase().wrapping_sub(b'@') as usize).flatten()
    }

    /// [`Word::from_letter`] by a match (the reference of the table).
    #[cfg(test)]
    pub(super) fn from_letter_by_match(c: u8) -> Option<Word> {
        Some(match c.to_ascii_uppercase() {
            b'B' => Word::B,
            b'D' => Word::D,
            b'E' => Word::E,
            b'F' => Word::F,
            b'H' => Word::H,
            b'I' => Word::I,
            b'J' => Word::J,
            b'K' => Word::K,
            b'L' => Word::L,
            b'N' => Word::N,
            b'P' => Word::P,
            b'Q' => Word::Q,
            b'R' => Word::R,
            b'S' => Word::S,
            b'T' => Word::T,
            b'X' => Word::X,
            b'Y' => Word::Y,
            b'Z' => Word::Z,
            b'@' => Word::At,
            b'^' => Word::Caret,
            _ => return None,
        })
    }

    /// The upper-case letter of the word (`@`, `^` for the polar words). A
    /// match, not a table: on AVR a table would be copied into RAM.
    pub const fn letter(self) -> u8 {
        match self {
            Word::B => b'B',
            Word::D => b'D',
            Word::E => b'E',
            Word::F => b'F',
            Word::H => b'H',
            Word::I => b'I',
            Word::J => b'J',
            Word::K => b'K',
            Word::L => b'L',
            Word::N => b'N',
            Word::P => b'P',
            Word::Q => b'Q',
            Word::R => b'R',
            Word::S => b'S',
            Word::T => b'T',
            Word::X => b'X',
            Word::Y => b'Y',
            Word::Z => b'Z',
            Word::At => b'@',
            Word::Caret => b'^',
        }
    }

    /// The word of bit `i` ([`Word::ALL`]`[i]`, by a match).
    pub(super) fn from_index(i: u8) -> Option<Word> {
        let letter = match i {
            0 => b'B',
            1 => b'D',
            2 => b'E',
            3 => b'F',
            4 => b'H',
            5 => b'I',
            6 => b'J',
            7 => b'K',
            8 => b'L',
            9 => b'N',
            10 => b'P',
            11 => b'Q',
            12 => b'R',
            13 => b'S',
            14 => b'T',
            15 => b'X',
            16 => b'Y',
            17 => b'Z',
            18 => b'@',
            19 => b'^',
            _ => return None,
        };
        Word::from_letter(letter)
    }

    /// The presence mask of `words` (for [`Words::first_outside`]).
    pub const fn mask(words: &[Word]) -> u32 {
        let mut m = 0;
        let mut i = 0;
        while i < words.len() {
            m |= words[i].bit();
            i += 1;
        }
        m
    }

    /// Bit of this word in a presence mask.
    ///
    /// A variable 32-bit shift is a loop on the AVR (up to 17 turns of four
    /// shifts, ~100 cycles); a byte is shifted and placed instead. Always
    /// inlined: the callers name the word or hold it in a register (as a
    /// call, ~48 cycles, five times a streamed line).
    // speed: ~48 cycles a call, five calls a streamed line (doc above)
    #[inline(always)]
    const fn bit(self) -> u32 {
        let i = self as u8;
        let b = (1u8 << (i & 7)) as u32;
        match i >> 3 {
            0 => b,
            1 => b << 8,
            _ => b << 16,
        }
    }
}

/// `1 << n` for `n` in 0..=7, by compares: a variable shift is a loop on
/// the AVR (~5 cycles a place, 7 places for X).
// speed: inlined into Words::insert (doc above)
#[inline(always)]
fn bit_in_byte(n: u8) -> u8 {
    match n {
        0 => 1,
        1 => 2,
        2 => 4,
        3 => 8,
        4 => 16,
        5 => 32,
        6 => 64,
        _ => 128,
    }
}

crate::in_flash! {
    /// [`Word::from_letter`] for the bytes `@` (0x40) to `_` (0x5F): the
    /// upper-case letters, `@` and `^`.
    static LETTER_WORDS: [Option<Word>; 32] = {
        let mut t = [None; 32];
        let mut i = 0;
        while i < Word::COUNT {
            let w = Word::ALL[i];
            t[(w.letter() - b'@') as usize] = Some(w);
            i += 1;
        }
        t
    };
}

/// The value words of one line: a presence mask and one f32 per word.
///
/// Values are in the units written on the line (the interpreter applies
/// G20/G21 and G90/G91); every value is finite and within ±1e6.
///
/// Only the values of present words are written: an empty set is its mask
/// alone, so the `Line` made for every line is not 80 bytes of zeros more
/// (a `memset` of ~260 cycles a streamed line on the AVR, `profile
/// --trace`). Equality and `Debug` look at the present words only
/// (`words_behave_as_a_map_of_the_present_words`).
#[derive(Clone, Copy)]
pub struct Words {
    /// Bit `w as u32` set when word `w` is present, in little-endian
    /// bytes: [`Words::insert`] reads and writes the word's byte alone.
    present: [u8; 3],
    /// Value per word, written when the word is inserted; not read while
    /// its bit is clear.
    values: [MaybeUninit<f32>; Word::COUNT],
}

impl Default for Words {
    fn default() -> Self {
        Self::new()
    }
}

impl PartialEq for Words {
    /// The same words with the same values.
    fn eq(&self, other: &Self) -> bool {
        if self.present != other.present {
            return false;
        }
        // `Word::ALL` is a table (RAM on AVR): the bits' match instead.
        let mut i = 0u8;
        while i < Word::COUNT as u8 {
            if let Some(w) = Word::from_index(i) {
                if self.get(w) != other.get(w) {
                    return false;
                }
            }
            i += 1;
        }
        true
    }
}

impl core::fmt::Debug for Words {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_map().entries(self.iter().map(|(w, v)| (w.letter() as char, v))).finish()
    }
}

impl Words {
    /// No words.
    pub const fn new() -> Self {
        Words { present: [0; 3], values: [MaybeUninit::uninit(); Word::COUNT] }
    }

    /// The presence mask (bit `w as u32` for word `w`).
    // speed: a constant word's test folds to one byte test (see Words::get)
    #[inline(always)]
    fn mask(&self) -> u32 {
        let [b0, b1, b2] = self.present;
        u32::from_le_bytes([b0, b1, b2, 0])
    }

    /// The value of word `w`, if present. Always inlined: the callers name
    /// the word, so the mask test folds to one byte test (as a call, ~110
    /// cycles with the variable shift building the mask).
    // speed: the mask test folds to one byte test (~110 cycles as a call)
    #[inline(always)]
    pub fn get(&self, w: Word) -> Option<f32> {
        if self.contains(w) {
            // SAFETY: a word's bit is set only by `insert`, after it wrote
            // the word's value.
            self.values.get(w as usize).map(|v| unsafe { v.assume_init() })
        } else {
            None
        }
    }

    /// True if word `w` is present. Always inlined: the callers name the
    /// word, so the test folds to one byte test (as a call, ~63 cycles).
    // speed: the mask test folds to one byte test (~63 cycles as a call)
    #[inline(always)]
    pub fn contains(&self, w: Word) -> bool {
        self.mask() & w.bit() != 0
    }

    /// Set word `w`. Returns false (and changes nothing) if it was already
    /// present. Always inlined into the parser (two calls there): as a
    /// call, with its 16 registers saved and restored, ~218 cycles a word.
    // speed: ~218 cycles a word as a call (doc above)
    #[inline(always)]
    pub fn insert(&mut self, w: Word, value: f32) -> bool {
        // The word's byte alone: the parser's `w` is a variable, and its
        // 32-bit mask (a variable shift, a loop on the AVR) with the 32-bit
        // test and update cost ~50 cycles a streamed line more (`profile
        // --trace`: 21 293 → 21 239).
        let i = w as u8;
        let bit = bit_in_byte(i & 7);
        let (Some(byte), Some(slot)) = (self.present.get_mut((i >> 3) as usize), self.values.get_mut(i as usize)) else {
            return true;
        };
        if *byte & bit != 0 {
            return false;
        }
        *slot = MaybeUninit::new(value);
        *byte |= bit;
        true
    }

    /// Take word `w` out, returning its value. An interpreter can take the
    /// words each code uses and then reject whatever is left over.
    pub fn remove(&mut self, w: Word) -> Option<f32> {
        let v = self.get(w);
        let [b0, b1, b2, _] = (self.mask() & !w.bit()).to_le_bytes();
        self.present = [b0, b1, b2];
        v
    }

    /// True when any of X, Y, Z is present (one mask test).
    #[inline]
    pub fn has_xyz(&self) -> bool {
        const XYZ: u32 = Word::X.bit() | Word::Y.bit() | Word::Z.bit();
        self.mask() & XYZ != 0
    }

    /// True when no word is present.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.mask() == 0
    }

    /// True when any of X, Y, Z or the polar words `@`, `^` is present: the
    /// line names a point.
    #[inline]
    pub fn has_position(&self) -> bool {
        const POINT: u32 = Word::mask(&[Word::X, Word::Y, Word::Z, Word::At, Word::Caret]);
        self.mask() & POINT != 0
    }

    /// True when every present word is in `mask` (a [`Word::mask`]): one
    /// test.
    // speed: with the mask a constant, three byte tests (as a call ~44 cycles, twice a streamed line)
    #[inline(always)]
    pub fn within(&self, mask: u32) -> bool {
        self.mask() & !mask == 0
    }

    /// True when `@` or `^` is present.
    #[inline]
    pub fn has_polar(&self) -> bool {
        const POLAR: u32 = Word::mask(&[Word::At, Word::Caret]);
        self.mask() & POLAR != 0
    }

    /// The first present word, in bit order, that is not in `allowed` (a
    /// [`Word::mask`]): a word no code on the line uses.
    pub fn first_outside(&self, allowed: u32) -> Option<Word> {
        let extra = self.mask() & !allowed;
        // `Word::ALL` is a table (RAM on AVR): the letters' match instead.
        let mut i = 0u8;
        while i < Word::COUNT as u8 {
            if extra & (1 << i) != 0 {
                return Word::from_index(i);
            }
            i += 1;
        }
        None
    }

    /// The first present word in bit order (e.g. to name a left-over word).
    pub fn first(&self) -> Option<Word> {
        Word::ALL.iter().copied().find(|&w| self.contains(w))
    }

    /// The present words and their values, in bit order.
    pub fn iter(&self) -> impl Iterator<Item = (Word, f32)> + '_ {
        Word::ALL.iter().filter_map(move |&w| self.get(w).map(|v| (w, v)))
    }
}
