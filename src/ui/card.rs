//! The SD card as the UI and the SD job see it: 8.3 [`Name`]s, directory
//! [`Entry`]s with their long names, the [`Folder`] an operation works in,
//! [`SdError`], and the [`Card`] trait (the firmware's is `embedded-sdmmc`
//! over SPI; tests use a fake in `sd`'s tests).

use crate::ui::text::Text;
use ufmt::uWrite;

/// An 8.3 file name, upper case, as `NAME.EXT` (at most 12 bytes).
#[derive(Clone, Copy, PartialEq, Eq, Default, Debug)]
pub struct Name {
    bytes: [u8; 12],
    len: u8,
}

impl Name {
    /// The empty name.
    pub const EMPTY: Name = Name { bytes: [0; 12], len: 0 };

    /// Parse a user-given 8.3 name (case-insensitive; leading `/` allowed).
    pub fn parse(s: &[u8]) -> Option<Name> {
        let s = s.strip_prefix(b"/").unwrap_or(s);
        let (base, ext) = match s.iter().position(|&b| b == b'.') {
            Some(i) => (&s[..i], &s[i + 1..]),
            None => (s, &s[s.len()..]),
        };
        // A match, not a byte-string table: a table would sit in RAM on the AVR.
        let legal = |b: u8| {
            b.is_ascii_alphanumeric()
                || matches!(b, b'_' | b'-' | b'~' | b'!' | b'#' | b'$' | b'%' | b'&' | b'\'' | b'(' | b')' | b'@' | b'^' | b'{' | b'}')
        };
        let ok = |p: &[u8], max: usize| p.len() <= max && p.iter().all(|&b| legal(b));
        if base.is_empty() || !ok(base, 8) || !ok(ext, 3) {
            return None;
        }
        let mut n = Name::default();
        for &b in base {
            n.push(b.to_ascii_uppercase());
        }
        if !ext.is_empty() {
            n.push(b'.');
            for &b in ext {
                n.push(b.to_ascii_uppercase());
            }
        }
        Some(n)
    }

    /// From a directory entry's base name and extension (space padded or not).
    pub fn from_parts(base: &[u8], ext: &[u8]) -> Name {
        let mut n = Name::default();
        for &b in base.iter().take(8).filter(|&&b| b != b' ') {
            n.push(b);
        }
        let ext = ext.iter().take(3).filter(|&&b| b != b' ');
        let mut first = true;
        for &b in ext {
            if first {
                n.push(b'.');
                first = false;
            }
            n.push(b);
        }
        n
    }

    fn push(&mut self, b: u8) {
        // Only printable ASCII is kept, so `as_str` needs no UTF-8 check.
        let b = if (0x21..0x7F).contains(&b) { b } else { b'?' };
        if (self.len as usize) < self.bytes.len() {
            self.bytes[self.len as usize] = b;
            self.len += 1;
        }
    }

    /// The name as bytes.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..self.len as usize]
    }

    /// The name as text (always ASCII).
    pub fn as_str(&self) -> &str {
        // SAFETY: `push` stores printable ASCII only. (`from_utf8` would put
        // core's 256-byte UTF-8 width table in RAM on the AVR.)
        unsafe { core::str::from_utf8_unchecked(self.as_bytes()) }
    }

    /// True for the empty name.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl ufmt::uDisplay for Name {
    fn fmt<W: uWrite + ?Sized>(&self, f: &mut ufmt::Formatter<'_, W>) -> Result<(), W::Error> {
        f.write_str(self.as_str())
    }
}

/// What can go wrong with the card. Small and `Copy`.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum SdError {
    /// No card in the socket, or it does not answer.
    NoCard,
    /// No FAT16/FAT32 volume on the card.
    NoFilesystem,
    /// No such file.
    NotFound,
    /// Reading failed (card error or a broken FAT chain).
    ReadFailed,
    /// Writing failed (card error, full, or read-only).
    WriteFailed,
    /// Not an 8.3 file name.
    BadName,
}

impl SdError {
    /// Text for `Error:` lines and the display.
    pub fn text(self) -> Text {
        match self {
            SdError::NoCard => Text::ErrNoCard,
            SdError::NoFilesystem => Text::ErrNoFs,
            SdError::NotFound => Text::ErrNotFound,
            SdError::ReadFailed => Text::ErrRead,
            SdError::WriteFailed => Text::ErrWrite,
            SdError::BadName => Text::ErrBadName,
        }
    }
}

/// Which folder a listing or an open works in.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Folder {
    /// The root folder: the serial SD commands (M20, M23, M28, M30, M33)
    /// always work here, whatever the menu shows.
    Root,
    /// The folder the menu's file list has entered ([`Card::enter`]).
    Current,
}

/// One directory entry, as [`Card::list`] hands it out.
pub struct Entry<'a> {
    /// The 8.3 name: unique in its folder, and what opens the entry.
    pub name: Name,
    /// The long name, when the card has one (empty otherwise).
    pub long: &'a str,
    /// A folder (else a file).
    pub dir: bool,
    /// File size, bytes (0 for a folder).
    pub size: u32,
}

/// The card as the job sees it. One file is open at a time.
pub trait Card {
    /// The detect switch says a card is in.
    fn detected(&self) -> bool;
    /// Initialise the card and open its first FAT volume (no-op when done).
    fn mount(&mut self) -> Result<(), SdError>;
    /// Forget the card (it was pulled, or M22): handles are dropped, and the
    /// current folder is the root again.
    fn unmount(&mut self);
    /// Call `f` for every visible file and folder of `at`, in directory order
    /// (no `.`/`..`, no volume label, nothing hidden).
    fn list(&mut self, at: Folder, f: &mut dyn FnMut(&Entry<'_>)) -> Result<(), SdError>;
    /// Open a file of `at` for reading (returns its size) or, with `write`,
    /// create or truncate it for writing (returns 0). Closes any other open file.
    fn open(&mut self, at: Folder, name: &Name, write: bool) -> Result<u32, SdError>;
    /// Make the folder `name` of the current folder the current one.
    fn enter(&mut self, name: &Name) -> Result<(), SdError>;
    /// Make the current folder's parent the current one (no-op at the root).
    fn leave(&mut self) -> Result<(), SdError>;
    /// Folders below the root the current folder is (0: the root).
    fn depth(&self) -> u8;
    /// Read from the open file; 0 at the end.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, SdError>;
    /// Move the read position of the open file.
    fn seek(&mut self, pos: u32) -> Result<(), SdError>;
    /// Append to the open file.
    fn write(&mut self, data: &[u8]) -> Result<(), SdError>;
    /// Close the open file (flushing writes).
    fn close(&mut self) -> Result<(), SdError>;
}
