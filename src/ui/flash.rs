//! Constant data kept in flash, read with `lpm` (AVR) or directly (host).
//!
//! On the AVR every `static` or string literal lives in RAM (`.data`, copied
//! from flash at boot). Tables placed in `.progmem.data` stay in flash only,
//! and must be read with the `lpm` instruction, never through a normal
//! pointer dereference. avr-gcc's linker script puts `.progmem*` at the start
//! of `.text`, inside the first 64 KiB, where `lpm` (Z pointer) reaches.
//!
//! The bytes are read with `avr-progmem`'s `read_byte`, like
//! [`crate::flash`]'s `F!` messages; this module adds what the UI needs on
//! top: indexed tables and an enum of strings, so menu entries can be stored
//! as one byte each. On the host the statics are ordinary memory.
//!
//! [`flash_texts!`] builds the UI's strings as one flash blob plus an offset
//! table and an enum naming each string.

/// Read one byte of a flash-resident static (`lpm` through avr-progmem on
/// AVR, as `crate::flash` does; a plain load on the host).
///
/// `b` is an element of a static declared with
/// `#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]`
/// (anything else reads the flash byte at that address: wrong, not unsafe).
pub fn read_byte(b: &u8) -> u8 {
    // SAFETY: `b` is a valid reference, to program memory on the AVR (see
    // above), which `lpm` reads; a plain load on the host.
    unsafe { avr_progmem::raw::read_byte(b) }
}

/// Read element `i` of a flash-resident `[u16]` (see [`read_byte`]).
// flash: 4 B less inlined (the call costs more than the two `lpm`s)
#[inline(always)]
pub fn read_u16(table: &[u16], i: usize) -> u16 {
    let p: *const u8 = (&table[i] as *const u16).cast();
    // SAFETY: p and p + 1 are the two bytes of table[i], in program memory
    // like the table.
    unsafe { u16::from_le_bytes([avr_progmem::raw::read_byte(p), avr_progmem::raw::read_byte(p.add(1))]) }
}

/// Declare the UI's flash strings: `flash_texts! { Name = "text", ... }`
/// gives `enum Text { Name, ... }` with [`Text::len`], [`Text::byte`] and
/// [`Text::for_each`], backed by one flash blob and one offset table
/// (RAM cost: nothing).
#[macro_export]
macro_rules! flash_texts {
    ($($name:ident = $s:literal,)*) => {
        /// A string kept in flash (see `ui::flash`).
        #[derive(Clone, Copy, PartialEq, Eq, Debug)]
        #[repr(u8)]
        pub enum Text { $($name,)* }

        const TEXT_PARTS: &[&[u8]] = &[$($s.as_bytes(),)*];
        const TEXT_COUNT: usize = TEXT_PARTS.len();
        const TEXT_TOTAL: usize = {
            let mut t = 0;
            let mut i = 0;
            while i < TEXT_COUNT {
                t += TEXT_PARTS[i].len();
                i += 1;
            }
            t
        };
        #[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
        static TEXT_BLOB: [u8; TEXT_TOTAL] = {
            let mut b = [0u8; TEXT_TOTAL];
            let mut at = 0;
            let mut i = 0;
            while i < TEXT_COUNT {
                let p = TEXT_PARTS[i];
                let mut j = 0;
                while j < p.len() {
                    b[at] = p[j];
                    at += 1;
                    j += 1;
                }
                i += 1;
            }
            b
        };
        #[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
        static TEXT_OFFSETS: [u16; TEXT_COUNT + 1] = {
            let mut o = [0u16; TEXT_COUNT + 1];
            let mut i = 0;
            while i < TEXT_COUNT {
                o[i + 1] = o[i] + TEXT_PARTS[i].len() as u16;
                i += 1;
            }
            o
        };

        impl Text {
            /// The text whose discriminant is `b`, if there is one.
            pub fn from_u8(b: u8) -> Option<Text> {
                if (b as usize) < TEXT_COUNT {
                    // SAFETY: Text is repr(u8) with implicit discriminants,
                    // 0 to TEXT_COUNT - 1.
                    Some(unsafe { core::mem::transmute::<u8, Text>(b) })
                } else {
                    None
                }
            }

            fn range(self) -> (usize, usize) {
                let i = self as usize;
                let a = $crate::ui::flash::read_u16(&TEXT_OFFSETS, i) as usize;
                let b = $crate::ui::flash::read_u16(&TEXT_OFFSETS, i + 1) as usize;
                (a, b)
            }

            /// Length in bytes.
            pub fn len(self) -> usize {
                let (a, b) = self.range();
                b - a
            }

            /// True for the empty string.
            pub fn is_empty(self) -> bool {
                self.len() == 0
            }

            /// Byte `i` (must be < len).
            pub fn byte(self, i: usize) -> u8 {
                let (a, _) = self.range();
                $crate::ui::flash::read_byte(&TEXT_BLOB[a + i])
            }

            /// The text as an [`FStr`]($crate::flash::FStr) (both live in flash).
            pub fn as_fstr(self) -> $crate::flash::FStr {
                let (a, b) = self.range();
                // SAFETY: a..b is the text's range in TEXT_BLOB, valid UTF-8
                // (it came from a string literal), in program memory on AVR.
                unsafe { $crate::flash::FStr::from_raw(TEXT_BLOB.as_ptr().add(a), (b - a) as u16) }
            }

            /// Call `f` with every byte.
            pub fn for_each(self, mut f: impl FnMut(u8)) {
                let (a, b) = self.range();
                for k in a..b {
                    f($crate::ui::flash::read_byte(&TEXT_BLOB[k]));
                }
            }
        }

        impl ufmt::uDisplay for Text {
            fn fmt<W: ufmt::uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
                // Through FStr: one chunking loop for every writer type.
                ufmt::uDisplay::fmt(&self.as_fstr(), f)
            }
        }
    };
}
