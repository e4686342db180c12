//! Text kept in flash instead of RAM.
//!
//! On AVR, rustc copies every `&str` literal into RAM at boot (`.data`),
//! because ordinary loads cannot read program memory. With 8 KiB of RAM the
//! firmware cannot afford that for its messages, so every message of more than
//! a few characters goes through [`F!`](crate::F): the text becomes a static
//! byte array in the `.progmem.data` section (linked into the low 64 KiB of
//! flash) and an [`FStr`] handle to it, which is read one byte at a time with
//! `lpm` through `avr-progmem`'s `read_byte`. On the host the same static is
//! ordinary memory and `read_byte` is a plain load, so tests see the text.
//!
//! `avr-progmem`'s own `PmString<N>` carries its length in its type, so
//! messages of different lengths could not share one `Error::message()`
//! return type; [`FStr`] is the unsized handle that it lacks (4 bytes).

use core::fmt;

/// A value kept in program memory: a state machine's transition table, the
/// factory settings. Read a copy with [`InFlash::get`] (an array's rows with
/// [`InFlash::row`]).
///
/// Declare it with [`in_flash!`](crate::in_flash), which places the
/// `static` in `.progmem.data` on the AVR.
#[repr(transparent)]
pub struct InFlash<T: Copy>(T);

impl<T: Copy> InFlash<T> {
    /// # Safety
    /// The value must be a `static` placed in `.progmem.data` on the AVR
    /// (`#[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]`):
    /// it is read with `lpm`, which reads program memory. [`in_flash!`](crate::in_flash)
    /// does both.
    #[doc(hidden)]
    pub const unsafe fn new(value: T) -> Self {
        InFlash(value)
    }

    /// A copy of the value, read from flash.
    pub fn get(&'static self) -> T {
        // SAFETY: `self` is a static in program memory (the promise of
        // `new`), plain memory on the host; T is Copy.
        unsafe { avr_progmem::raw::read_value(&self.0) }
    }
}

impl<T: Copy, const N: usize> InFlash<[T; N]> {
    /// Row `i` of a table in flash, `None` past its end.
    pub fn row(&'static self, i: usize) -> Option<T> {
        // SAFETY: as in `get`; `r` is an element of the static array.
        self.0.get(i).map(|r| unsafe { avr_progmem::raw::read_value(r) })
    }
}

impl<const K: usize> InFlash<[[u8; 256]; K]> {
    /// Byte `i` of column `k` of a table of byte columns: one `lpm` (a
    /// `u8` index cannot leave a 256-byte column; `k` is a constant where
    /// it is used, so its bounds check folds away).
    #[inline(always)]
    pub fn at(&'static self, k: usize, i: u8) -> u8 {
        // SAFETY: as in `get`; the byte is an element of the static array.
        unsafe { avr_progmem::raw::read_byte(&self.0[k][i as usize]) }
    }
}

/// A string in program memory: a pointer into flash and a length.
#[derive(Clone, Copy)]
pub struct FStr {
    ptr: *const u8,
    len: u16,
}

// SAFETY: an FStr only ever points at immutable statics.
unsafe impl Sync for FStr {}
// SAFETY: as above.
unsafe impl Send for FStr {}

impl FStr {
    /// # Safety
    /// `ptr..ptr + len` must be a UTF-8 static in program memory (AVR: the
    /// `.progmem.data` section, below 64 KiB). Use [`F!`](crate::F).
    #[doc(hidden)]
    pub const unsafe fn from_raw(ptr: *const u8, len: u16) -> Self {
        FStr { ptr, len }
    }

    /// Length in bytes.
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Byte `i`, or `None` past the end.
    pub fn get(&self, i: usize) -> Option<u8> {
        // SAFETY: in bounds of a program-memory static (see `from_raw`).
        (i < self.len()).then(|| unsafe { avr_progmem::raw::read_byte(self.ptr.add(i)) })
    }

    /// The bytes, read from flash one at a time.
    pub fn bytes(self) -> impl Iterator<Item = u8> {
        (0..self.len()).filter_map(move |i| self.get(i))
    }

    /// Same text as `s`?
    pub fn eq_str(&self, s: &str) -> bool {
        self.len() == s.len() && self.bytes().zip(s.bytes()).all(|(a, b)| a == b)
    }

    /// Does the text start with `s`?
    pub fn starts_with(&self, s: &str) -> bool {
        self.len() >= s.len() && self.bytes().zip(s.bytes()).all(|(a, b)| a == b)
    }

    /// Write the text through a `ufmt` writer, 16 bytes at a time.
    pub fn write_to<W: ufmt::uWrite + ?Sized>(&self, w: &mut W) -> Result<(), W::Error> {
        let mut chunk = [0u8; 16];
        let mut n = 0;
        for i in 0..self.len() {
            if let (Some(slot), Some(b)) = (chunk.get_mut(n), self.get(i)) {
                *slot = b;
                n += 1;
            }
            // Cut only between characters (at most 4 bytes each, so a cut
            // point comes before the chunk is full).
            let next_starts_char = self.get(i + 1).is_none_or(|b| b & 0xC0 != 0x80);
            if n >= chunk.len() - 4 && next_starts_char {
                w.write_str(as_str(&chunk[..n]))?;
                n = 0;
            }
        }
        w.write_str(as_str(&chunk[..n]))
    }
}

/// A chunk cut at character boundaries out of an `F!` string.
fn as_str(b: &[u8]) -> &str {
    // SAFETY: `F!` stores a `&str` (valid UTF-8) and `write_to` cuts it only
    // between characters. (`from_utf8` would add core's 256-byte UTF-8 width
    // table to RAM on AVR.)
    unsafe { core::str::from_utf8_unchecked(b) }
}

impl ufmt::uDisplay for FStr {
    fn fmt<W: ufmt::uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
        let mut w = FmtBridge(f);
        self.write_to(&mut w)
    }
}

/// Lets [`FStr::write_to`] write through a `ufmt::Formatter`.
struct FmtBridge<'a, 'b, W: ufmt::uWrite + ?Sized>(&'a mut ufmt::Formatter<'b, W>);

impl<W: ufmt::uWrite + ?Sized> ufmt::uWrite for FmtBridge<'_, '_, W> {
    type Error = W::Error;
    fn write_str(&mut self, s: &str) -> Result<(), W::Error> {
        self.0.write_str(s)
    }
}

impl fmt::Debug for FStr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use fmt::Write;
        f.write_char('"')?;
        for b in self.bytes() {
            f.write_char(b as char)?;
        }
        f.write_char('"')
    }
}

impl PartialEq for FStr {
    fn eq(&self, other: &FStr) -> bool {
        self.len == other.len && self.bytes().zip(other.bytes()).all(|(a, b)| a == b)
    }
}

impl PartialEq<&str> for FStr {
    fn eq(&self, other: &&str) -> bool {
        self.eq_str(other)
    }
}

/// `F!` helper: a `&str` as a fixed-size array, at compile time.
#[doc(hidden)]
pub const fn to_array<const N: usize>(s: &str) -> [u8; N] {
    let b = s.as_bytes();
    let mut out = [0u8; N];
    let mut i = 0;
    while i < N {
        out[i] = b[i];
        i += 1;
    }
    out
}

/// A string literal kept in flash: `F!("text")` is an [`FStr`](crate::flash::FStr).
/// Named after Arduino's `F()` macro, which does the same for C++.
#[macro_export]
macro_rules! F {
    ($s:expr) => {{
        const __S: &str = $s;
        #[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
        static __P: [u8; __S.len()] = $crate::flash::to_array(__S);
        // SAFETY: __P is an immutable UTF-8 static, in .progmem.data on AVR.
        unsafe { $crate::flash::FStr::from_raw(__P.as_ptr(), __S.len() as u16) }
    }};
}

/// Declare a `static` kept in program memory:
/// `in_flash! { static NAME: T = value; }` gives `static NAME: InFlash<T>`,
/// in `.progmem.data` on the AVR, read with [`InFlash::get`] and
/// [`InFlash::row`]. The one place where the link section and the promise
/// of [`InFlash::new`] are written.
///
/// ```
/// #[derive(Clone, Copy)]
/// struct Row(u8);
/// mill::in_flash! {
///     /// Two rows.
///     static ROWS: [Row; 2] = [Row(1), Row(2)];
/// }
/// assert_eq!(ROWS.get()[1].0, 2);
/// ```
#[macro_export]
macro_rules! in_flash {
    ($(#[$meta:meta])* $vis:vis static $name:ident: $ty:ty = $value:expr;) => {
        $(#[$meta])*
        #[cfg_attr(target_arch = "avr", link_section = ".progmem.data")]
        $vis static $name: $crate::flash::InFlash<$ty> = {
            let value: $ty = $value;
            // SAFETY: this static is in program memory on the AVR (the
            // attribute above).
            unsafe { $crate::flash::InFlash::new(value) }
        };
    };
}

/// A fieldless enum whose variants each carry a message: the messages are
/// one table of [`F!`] strings in flash, so `message()` is one indexed read
/// instead of a compare chain of some 16 bytes per variant (jump tables are
/// off on this target). The enum and its table come from the same list, so
/// they cannot get out of step.
///
/// ```
/// mill::flash_messages! {
///     /// Why it failed.
///     #[derive(Clone, Copy, Debug, PartialEq, Eq)]
///     pub enum Fault {
///         /// The doc of the variant.
///         Stopped => "stopped",
///         Jammed => "jammed",
///     }
/// }
/// assert!(Fault::Jammed.message().eq_str("jammed"));
/// ```
#[macro_export]
macro_rules! flash_messages {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $( $(#[$vmeta:meta])* $variant:ident => $text:literal, )+
        }
    ) => {
        $(#[$meta])*
        $vis enum $name {
            $( $(#[$vmeta])* $variant, )+
        }

        impl $name {
            /// The message of this variant, in flash.
            pub fn message(self) -> $crate::flash::FStr {
                $crate::in_flash! {
                    static TABLE: [$crate::flash::FStr; [$($text),+].len()] = [$( $crate::F!($text) ),+];
                }
                // Every variant has its row.
                TABLE.row(self as usize).unwrap_or($crate::F!(""))
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use crate::flash::FStr;

    struct S(String);
    impl ufmt::uWrite for S {
        type Error = ();
        fn write_str(&mut self, s: &str) -> Result<(), ()> {
            self.0.push_str(s);
            Ok(())
        }
    }

    #[test]
    fn a_flash_string_prints_whole_through_ufmt_whatever_its_length() {
        let long: FStr = F!("echo:factory settings restored (M500 to store), and a ü in the middle");
        for f in [F!(""), F!("ok"), F!("0123456789abcdef"), long] {
            let mut s = S(String::new());
            ufmt::uwrite!(s, "[{}]", f).unwrap();
            let text: String = f.bytes().map(char::from).collect::<String>();
            assert_eq!(s.0.len(), f.len() + 2);
            assert!(s.0.starts_with('[') && s.0.ends_with(']'));
            if f.bytes().all(|b| b < 0x80) {
                assert_eq!(s.0, format!("[{text}]"));
            }
        }
        let mut s = S(String::new());
        ufmt::uwrite!(s, "{}", long).unwrap();
        assert_eq!(s.0, "echo:factory settings restored (M500 to store), and a ü in the middle");
    }

    #[test]
    fn comparisons_see_the_text() {
        assert_eq!(F!("abc"), "abc");
        assert!(F!("abc") != "abd");
        assert!(!F!("abc").eq_str("ab"));
        assert_eq!(format!("{:?}", F!("x y")), "\"x y\"");
        assert_eq!(F!("ab").get(1), Some(b'b'));
        assert_eq!(F!("ab").get(2), None);
    }
}
