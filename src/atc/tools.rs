//! What the firmware remembers about the tools (docs/SPEC.md §7 "Persistence"): the
//! tool table, which tool is in the spindle and which pockets are full, and
//! the "change in progress" journal, each with its EEPROM image.
//!
//! Three separate records after the settings image, so that a power loss
//! while one is written can corrupt only that one (each has a version byte
//! and a checksum seeded so that a blank, all-0xFF EEPROM fails):
//!
//! | address | record | bytes |
//! |---|---|---|
//! | [`EEPROM_STATE_ADDR`] | [`ToolState`]: spindle tool, pocket bits | 5 |
//! | [`EEPROM_JOURNAL_ADDR`] | [`Journal`]: change in progress (from, to) | 5 |
//! | [`EEPROM_TABLE_ADDR`] | [`ToolTable`]: 12 × (length, diameter) | 74 |
//!
//! The tool setter's calibration follows at [`EEPROM_SETTER_ADDR`] (see
//! `toolsetter`). The EEPROM layer programs only bytes that differ, and the
//! callers write a record only when its value changed, so a tool change
//! programs about a dozen bytes (journal on, state after each transfer,
//! journal off) and a plain move never writes anything.
//!
//! Tool `n` (1..=12) lives in pocket `n`; a set pocket bit means "tool `n`
//! is in pocket `n`". Tool 0 is "no tool".

/// Number of carousel pockets (= tools 1..=12).
pub const N_POCKETS: usize = 12;
/// Every pocket bit.
pub const ALL_POCKETS: u16 = (1 << N_POCKETS) - 1;

/// EEPROM address of the [`ToolState`] record (after the settings image).
pub const EEPROM_STATE_ADDR: u16 = 256;
/// EEPROM address of the [`Journal`] record.
pub const EEPROM_JOURNAL_ADDR: u16 = 264;
/// EEPROM address of the [`ToolTable`] record.
pub const EEPROM_TABLE_ADDR: u16 = 272;
/// EEPROM address of the tool setter's calibration record.
pub const EEPROM_SETTER_ADDR: u16 = 352;
/// EEPROM address of the tool numbers' record (`ToolTable::numbers`).
pub const EEPROM_NUMBERS_ADDR: u16 = 384;

const _: () = assert!(crate::config::Settings::IMAGE_LEN <= EEPROM_STATE_ADDR as usize);
const _: () = assert!(EEPROM_STATE_ADDR as usize + ToolState::IMAGE_LEN <= EEPROM_JOURNAL_ADDR as usize);
const _: () = assert!(EEPROM_JOURNAL_ADDR as usize + Journal::IMAGE_LEN <= EEPROM_TABLE_ADDR as usize);
const _: () = assert!(EEPROM_TABLE_ADDR as usize + ToolTable::IMAGE_LEN <= EEPROM_SETTER_ADDR as usize);

/// Layout version of the records. Bump when a layout changes.
const VERSION: u8 = 1;

/// [`ToolTable::numbers`]: the pocket's own number (tool `p` in pocket
/// `p`, the factory numbering). Zero, so a fresh table is all zeros and
/// costs no `.data`.
pub const OWN_NUMBER: u8 = 0;
/// [`ToolTable::numbers`]: the pocket has no tool number.
pub const NO_NUMBER: u8 = 255;

/// Checksum of a record, seeded so an all-0xFF or all-0x00 image fails.
pub(crate) fn checksum(b: &[u8]) -> u8 {
    b.iter().fold(0xA7u8, |s, &x| s.rotate_left(1) ^ x)
}

/// True when `img` is `VERSION`, payload, checksum.
pub(crate) fn valid(img: &[u8]) -> bool {
    let n = img.len();
    n >= 2 && img[0] == VERSION && checksum(&img[..n - 1]) == img[n - 1]
}

/// Put the version first and the checksum last.
pub(crate) fn seal(img: &mut [u8]) {
    let n = img.len();
    img[0] = VERSION;
    img[n - 1] = checksum(&img[..n - 1]);
}

/// Bit of pocket `p` (1..=12) in [`ToolState::occupied`]; 0 for 0 or out of range.
pub const fn pocket_bit(p: u8) -> u16 {
    if p == 0 || p as usize > N_POCKETS {
        0
    } else {
        1 << (p - 1)
    }
}

/// Where the tools are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ToolState {
    /// Tool in the spindle, 0 = empty.
    pub spindle: u8,
    /// Bit `p - 1` set: pocket `p` holds tool `p`.
    pub occupied: u16,
}

impl ToolState {
    /// Blank EEPROM: empty spindle, every pocket full (a carousel loaded with tools 1–12).
    pub const FACTORY: ToolState = ToolState { spindle: 0, occupied: ALL_POCKETS };
    /// Image size: version, spindle, pockets (2), checksum.
    pub const IMAGE_LEN: usize = 5;

    /// Does pocket `p` hold its tool?
    pub fn pocket_full(&self, p: u8) -> bool {
        self.occupied & pocket_bit(p) != 0
    }

    /// A state the machine can be in: tool 0–12, and the spindle tool's pocket empty.
    pub fn is_consistent(&self) -> bool {
        self.spindle as usize <= N_POCKETS && self.occupied & !ALL_POCKETS == 0 && !self.pocket_full(self.spindle)
    }

    /// The EEPROM image.
    pub fn to_bytes(&self) -> [u8; Self::IMAGE_LEN] {
        let o = self.occupied.to_le_bytes();
        let mut img = [0, self.spindle, o[0], o[1], 0];
        seal(&mut img);
        img
    }

    /// Parse an image; `None` when blank, corrupt or inconsistent.
    pub fn from_bytes(img: &[u8; Self::IMAGE_LEN]) -> Option<ToolState> {
        let s = ToolState { spindle: img[1], occupied: u16::from_le_bytes([img[2], img[3]]) };
        (valid(img) && s.is_consistent()).then_some(s)
    }

    /// After the old tool went into its pocket.
    pub fn released(self) -> ToolState {
        ToolState { spindle: 0, occupied: self.occupied | pocket_bit(self.spindle) }
    }

    /// After tool `t` was taken from its pocket.
    pub fn clamped(self, t: u8) -> ToolState {
        ToolState { spindle: t, occupied: self.occupied & !pocket_bit(t) }
    }

    /// The state after the operator confirmed (M61 Q`t`) that the spindle
    /// holds tool `t`. After an interrupted change `j`, the two tools of the
    /// change are where the confirmation puts them: the one in the spindle is
    /// out of its pocket, the other one is in its pocket. Other pockets keep
    /// their bits. `t` must be 0..=12.
    pub fn confirmed(self, t: u8, j: Option<Journal>) -> ToolState {
        let mut occ = self.occupied;
        if let Some(j) = j {
            for p in [j.from, j.to] {
                if p != 0 && p != t {
                    occ |= pocket_bit(p);
                }
            }
        }
        occ &= !pocket_bit(t);
        ToolState { spindle: t, occupied: occ }
    }
}

/// The "change in progress" record: written before the first motion of a
/// change, cleared after its last.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Journal {
    /// Tool in the spindle when the change started.
    pub from: u8,
    /// Tool asked for.
    pub to: u8,
}

/// Marker byte of an active journal.
const JOURNAL_ACTIVE: u8 = 0xC3;

impl Journal {
    /// Image size: version, active marker, from, to, checksum.
    pub const IMAGE_LEN: usize = 5;

    /// The image of `Some(journal)` (a change in progress) or `None` (no change).
    pub fn to_bytes(j: Option<Journal>) -> [u8; Self::IMAGE_LEN] {
        let mut img = match j {
            Some(j) => [0, JOURNAL_ACTIVE, j.from, j.to, 0],
            // Keep from/to of the last change: clearing writes only the marker and checksum.
            None => [0, 0, 0, 0, 0],
        };
        seal(&mut img);
        img
    }

    /// Clear an existing image in place (marker and checksum only).
    pub fn cleared(mut img: [u8; Self::IMAGE_LEN]) -> [u8; Self::IMAGE_LEN] {
        img[1] = 0;
        seal(&mut img);
        img
    }

    /// Parse: `Some` only for a valid, active record (blank or corrupt = no change in progress).
    pub fn from_bytes(img: &[u8; Self::IMAGE_LEN]) -> Option<Journal> {
        (valid(img) && img[1] == JOURNAL_ACTIVE).then_some(Journal { from: img[2], to: img[3] })
    }
}

/// Length and diameter of tools 1..=12. RAM: 72 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ToolTable {
    /// Tool length (gauge line to tip), µm; index `t - 1`.
    pub length_um: [i32; N_POCKETS],
    /// Tool diameter, µm; index `t - 1`.
    pub diameter_um: [u16; N_POCKETS],
    /// The tool number of the tool kept in each pocket (CAM and the shop's
    /// tool library number tools freely: T20, T101), as stored:
    /// [`OWN_NUMBER`] for the pocket's own number, [`NO_NUMBER`] for none;
    /// read it with [`ToolTable::number_of`]. `T<n>` finds its pocket here
    /// (`G10 L1 P<n> Q<pocket>` assigns it).
    pub numbers: [u8; N_POCKETS],
}

const _: () = assert!(core::mem::size_of::<ToolTable>() == 84);

impl ToolTable {
    /// Every entry zero.
    pub const EMPTY: ToolTable = ToolTable { length_um: [0; N_POCKETS], diameter_um: [0; N_POCKETS], numbers: [OWN_NUMBER; N_POCKETS] };
    /// Image size: version, 12 × (4 + 2), checksum.
    pub const IMAGE_LEN: usize = 1 + 6 * N_POCKETS + 1;
    /// Size of the tool numbers' record (at [`EEPROM_NUMBERS_ADDR`]).
    pub const NUMBERS_LEN: usize = 1 + N_POCKETS + 1;

    /// The pocket of tool `t`; `Some(0)` for T0 (the empty spindle), `None`
    /// for a tool number no pocket has.
    pub fn pocket_of(&self, t: u8) -> Option<u8> {
        if t == 0 {
            return Some(0);
        }
        (1..=N_POCKETS as u8).find(|&p| self.number_of(p) == t)
    }

    /// The tool number of pocket `p`'s tool (0 for pocket 0, the empty
    /// spindle, and for a pocket without a number).
    pub fn number_of(&self, p: u8) -> u8 {
        if pocket_bit(p) == 0 {
            return 0;
        }
        match self.numbers[p as usize - 1] {
            OWN_NUMBER => p,
            NO_NUMBER => 0,
            n => n,
        }
    }

    /// Give pocket `p` (1..=12) tool number `t` (0: none).
    pub fn set_number(&mut self, p: u8, t: u8) {
        self.numbers[p as usize - 1] = match t {
            0 => NO_NUMBER,
            t if t == p => OWN_NUMBER,
            t => t,
        };
    }

    /// Length of tool `t`, µm (0 for T0 and out of range).
    pub fn length_um(&self, t: u8) -> i32 {
        if pocket_bit(t) == 0 {
            0
        } else {
            self.length_um[t as usize - 1]
        }
    }

    /// Diameter of tool `t`, µm (0 for T0 and out of range).
    pub fn diameter_um(&self, t: u8) -> u16 {
        if pocket_bit(t) == 0 {
            0
        } else {
            self.diameter_um[t as usize - 1]
        }
    }

    /// The EEPROM image.
    pub fn to_bytes(&self) -> [u8; Self::IMAGE_LEN] {
        let mut img = [0u8; Self::IMAGE_LEN];
        for i in 0..N_POCKETS {
            img[1 + 4 * i..5 + 4 * i].copy_from_slice(&self.length_um[i].to_le_bytes());
            let d = 1 + 4 * N_POCKETS + 2 * i;
            img[d..d + 2].copy_from_slice(&self.diameter_um[i].to_le_bytes());
        }
        seal(&mut img);
        img
    }

    /// The tool numbers' EEPROM record: version, a number per pocket,
    /// checksum. A blank record (a table written before the numbers) reads
    /// as tool `p` in pocket `p`.
    pub fn numbers_to_bytes(&self) -> [u8; Self::NUMBERS_LEN] {
        let mut img = [0u8; Self::NUMBERS_LEN];
        img[1..1 + N_POCKETS].copy_from_slice(&self.numbers);
        seal(&mut img);
        img
    }

    /// Parse the numbers' record; `None` when blank, corrupt, or one
    /// number in two pockets (a table no T word could use).
    pub fn numbers_from_bytes(img: &[u8; Self::NUMBERS_LEN]) -> Option<[u8; N_POCKETS]> {
        if !valid(img) {
            return None;
        }
        let mut t = ToolTable::EMPTY;
        t.numbers.copy_from_slice(&img[1..1 + N_POCKETS]);
        let num = |i: usize| t.number_of(i as u8 + 1);
        let twice = (1..N_POCKETS).any(|i| num(i) != 0 && (0..i).any(|j| num(j) == num(i)));
        (!twice).then_some(t.numbers)
    }

    /// Parse an image; `None` when blank or corrupt.
    pub fn from_bytes(img: &[u8; Self::IMAGE_LEN]) -> Option<ToolTable> {
        if !valid(img) {
            return None;
        }
        let mut t = ToolTable { length_um: [0; N_POCKETS], diameter_um: [0; N_POCKETS], numbers: [OWN_NUMBER; N_POCKETS] };
        for i in 0..N_POCKETS {
            let b = &img[1 + 4 * i..5 + 4 * i];
            t.length_um[i] = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            let d = 1 + 4 * N_POCKETS + 2 * i;
            t.diameter_um[i] = u16::from_le_bytes([img[d], img[d + 1]]);
        }
        Some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tool_numbers_round_trip_blank_is_the_factory_numbering_and_a_duplicate_is_refused() {
        let mut t = ToolTable::EMPTY;
        assert_eq!((t.pocket_of(5), t.number_of(5), t.pocket_of(13)), (Some(5), 5, None));
        t.set_number(5, 0);
        t.set_number(5, 20);
        t.set_number(7, 0);
        t.set_number(11, 7);
        assert_eq!((t.pocket_of(20), t.pocket_of(7), t.number_of(7), t.pocket_of(5)), (Some(5), Some(11), 0, None));
        let img = t.numbers_to_bytes();
        assert_eq!(ToolTable::numbers_from_bytes(&img), Some(t.numbers));
        assert_eq!(ToolTable::numbers_from_bytes(&[0xFF; ToolTable::NUMBERS_LEN]), None);
        // Two pockets numbered 3 (pocket 3's own number, and 3 given to 4).
        let mut d = ToolTable::EMPTY;
        d.numbers[3] = 3;
        assert_eq!(ToolTable::numbers_from_bytes(&d.numbers_to_bytes()), None);
    }

    #[test]
    fn tool_state_round_trips_and_blank_is_refused() {
        let s = ToolState { spindle: 3, occupied: ALL_POCKETS & !pocket_bit(3) & !pocket_bit(7) };
        assert_eq!(ToolState::from_bytes(&s.to_bytes()), Some(s));
        assert_eq!(ToolState::from_bytes(&[0xFF; 5]), None);
        assert_eq!(ToolState::from_bytes(&[0; 5]), None);
        let mut img = s.to_bytes();
        img[3] ^= 1;
        assert_eq!(ToolState::from_bytes(&img), None);
    }

    #[test]
    fn a_spindle_tool_whose_pocket_is_full_is_inconsistent() {
        let s = ToolState { spindle: 2, occupied: ALL_POCKETS };
        assert!(!s.is_consistent());
        assert_eq!(ToolState::from_bytes(&s.to_bytes()), None);
        assert!(!ToolState { spindle: 13, occupied: 0 }.is_consistent());
        assert!(ToolState::FACTORY.is_consistent());
    }

    #[test]
    fn release_and_clamp_move_the_pocket_bits() {
        let s = ToolState { spindle: 4, occupied: ALL_POCKETS & !pocket_bit(4) };
        let r = s.released();
        assert_eq!(r, ToolState { spindle: 0, occupied: ALL_POCKETS });
        let c = r.clamped(9);
        assert_eq!(c, ToolState { spindle: 9, occupied: ALL_POCKETS & !pocket_bit(9) });
        assert!(c.is_consistent());
    }

    #[test]
    fn confirming_after_an_interrupted_change_puts_both_tools_in_place() {
        // Change T4 -> T9 interrupted somewhere; the record said T4 in the spindle.
        let j = Some(Journal { from: 4, to: 9 });
        let s = ToolState { spindle: 4, occupied: ALL_POCKETS & !pocket_bit(4) };
        // The operator finds T9 in the spindle: T4 went back, T9 left its pocket.
        assert_eq!(s.confirmed(9, j), ToolState { spindle: 9, occupied: ALL_POCKETS & !pocket_bit(9) });
        // The operator finds it empty: both tools are in their pockets.
        assert_eq!(s.confirmed(0, j), ToolState { spindle: 0, occupied: ALL_POCKETS });
        // Still T4: T9 never left.
        assert_eq!(s.confirmed(4, j), s);
        // Without a journal only the confirmed tool's pocket changes.
        let e = ToolState { spindle: 0, occupied: ALL_POCKETS & !pocket_bit(5) };
        assert_eq!(e.confirmed(2, None), ToolState { spindle: 2, occupied: ALL_POCKETS & !pocket_bit(5) & !pocket_bit(2) });
    }

    #[test]
    fn journal_is_active_only_when_written_active() {
        let j = Journal { from: 0, to: 5 };
        let img = Journal::to_bytes(Some(j));
        assert_eq!(Journal::from_bytes(&img), Some(j));
        let cleared = Journal::cleared(img);
        assert_eq!(Journal::from_bytes(&cleared), None);
        // Clearing changes only the marker and the checksum.
        assert_eq!(cleared[2..4], img[2..4]);
        assert_eq!(Journal::from_bytes(&[0xFF; 5]), None);
        assert_eq!(Journal::from_bytes(&Journal::to_bytes(None)), None);
    }

    #[test]
    fn tool_table_round_trips() {
        let mut t = ToolTable::EMPTY;
        t.length_um[0] = 25_400;
        t.length_um[11] = -3;
        t.diameter_um[5] = 6_350;
        assert_eq!(ToolTable::from_bytes(&t.to_bytes()), Some(t));
        assert_eq!(t.length_um(1), 25_400);
        assert_eq!(t.length_um(0), 0);
        assert_eq!(t.length_um(13), 0);
        assert_eq!(t.diameter_um(6), 6_350);
        assert_eq!(ToolTable::from_bytes(&[0xFF; ToolTable::IMAGE_LEN]), None);
    }
}
