//! Run from line, the record that survives a power cut: which file the
//! last SD job ran (its 8.3 name and size) and the last line it reached,
//! in EEPROM ([`Record`]), and the line the menu proposes from it
//! ([`propose`]). The job's side (when to write) is `SdJob::record_due`;
//! the scan and the approach are `sd` and `machine::rebuild`'s.
//!
//! Layout at [`EEPROM_RESUME_ADDR`] (52 bytes):
//!
//! | offset | bytes | what |
//! |---|---|---|
//! | 0 | 1 | [`MAGIC`] (0: no job to resume) |
//! | 1 | 12 | the name, NUL padded |
//! | 13 | 4 | the file's size, bytes, little-endian |
//! | 17 | 1 | check byte over 0..17 |
//! | 20 | 8 × 4 | the line reached, one slot per record, round robin |
//!
//! Wear. The EEPROM programs only the bytes that change, and a cell lasts
//! 100 000 writes (ATmega2560 datasheet §32.5). The line is written when
//! the job pauses or stops and every [`RECORD_EVERY_S`] s while it cuts,
//! each time into the slot after the newest (the newest is the largest:
//! within a job the line only grows), so a slot's cells take one write in
//! [`SLOTS`] records: 100 000 × 8 × 30 s = 6 667 hours of cutting. A job's
//! start writes the header (a new file only) and resets the slots: one
//! write per cell and job, 100 000 job starts.

use crate::machine::Storage;
use crate::ui::card::Name;
use crate::ui::text::Text;

/// EEPROM address of the record (after the tool numbers, before the
/// startup blocks).
pub const EEPROM_RESUME_ADDR: u16 = 512;
/// The record's first byte when it holds a job.
pub const MAGIC: u8 = 0x52;
/// Line slots, written round robin.
pub const SLOTS: usize = 8;
/// Seconds of cutting between two records of the line reached.
pub const RECORD_EVERY_S: u16 = 30;
const HEAD_LEN: usize = 18;
const SLOT_ADDR: u16 = EEPROM_RESUME_ADDR + 20;
/// The whole record, bytes.
pub const RECORD_LEN: usize = 20 + 4 * SLOTS;
const _: () = assert!(crate::atc::tools::EEPROM_NUMBERS_ADDR as usize + 16 <= EEPROM_RESUME_ADDR as usize);
const _: () = assert!(EEPROM_RESUME_ADDR as usize + RECORD_LEN <= crate::machine::startup::EEPROM_STARTUP_ADDR as usize);

/// The last SD job: its file and the last line it reached.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Record {
    pub name: Name,
    /// The file's size, bytes: a file changed since is told apart.
    pub size: u32,
    /// The last line reached (1-based).
    pub line: u32,
}

fn check(b: &[u8]) -> u8 {
    b.iter().fold(0xA5u8, |c, &x| c.rotate_left(1) ^ x)
}

/// The record in EEPROM, if one holds a job.
pub fn load(io: &mut impl Storage) -> Option<Record> {
    let mut h = [0u8; HEAD_LEN];
    io.eeprom_read(EEPROM_RESUME_ADDR, &mut h);
    if h[0] != MAGIC || check(&h[..17]) != h[17] {
        return None;
    }
    let len = h[1..13].iter().position(|&b| b == 0).unwrap_or(12);
    let name = Name::parse(&h[1..1 + len])?;
    let size = u32::from_le_bytes([h[13], h[14], h[15], h[16]]);
    let (_, line) = newest(io);
    (line != u32::MAX).then_some(Record { name, size, line })
}

/// The newest slot and its line (`u32::MAX` when every slot is empty).
fn newest(io: &mut impl Storage) -> (usize, u32) {
    let mut best = (0, u32::MAX);
    for i in 0..SLOTS {
        let mut b = [0u8; 4];
        io.eeprom_read(SLOT_ADDR + 4 * i as u16, &mut b);
        let v = u32::from_le_bytes(b);
        if v != u32::MAX && (best.1 == u32::MAX || v > best.1) {
            best = (i, v);
        }
    }
    best
}

/// A job starts on `name` (`size` bytes) at `line`: the header, and the
/// slots reset to that line.
pub fn start(io: &mut impl Storage, name: &Name, size: u32, line: u32) {
    let mut h = [0u8; HEAD_LEN];
    h[0] = MAGIC;
    let n = name.as_bytes();
    h[1..1 + n.len()].copy_from_slice(n);
    h[13..17].copy_from_slice(&size.to_le_bytes());
    h[17] = check(&h[..17]);
    io.eeprom_write(EEPROM_RESUME_ADDR, &h);
    for i in 0..SLOTS {
        let v = if i == 0 { line } else { u32::MAX };
        io.eeprom_write(SLOT_ADDR + 4 * i as u16, &v.to_le_bytes());
    }
}

/// The job reached `line` (0: it ran to its end, nothing to resume).
pub fn reached(io: &mut impl Storage, line: u32) {
    if line == 0 {
        // Built on the stack: a constant would sit in RAM.
        io.eeprom_write(EEPROM_RESUME_ADDR, &core::hint::black_box([0u8]));
        return;
    }
    let (i, v) = newest(io);
    if v == line {
        return;
    }
    let next = if v == u32::MAX { 0 } else { (i + 1) % SLOTS };
    io.eeprom_write(SLOT_ADDR + 4 * next as u16, &line.to_le_bytes());
}

/// The line the menu proposes for file `name` of `size` bytes, and a note
/// when it is not the stored one: the last line reached when the record
/// is this file's, else line 1.
pub fn propose(rec: Option<Record>, name: &Name, size: u32) -> (u32, Option<Text>) {
    match rec {
        Some(r) if r.name == *name && r.size == size => (r.line.max(1), None),
        Some(r) if r.name == *name => (1, Some(Text::NoteFileChanged)),
        _ => (1, Some(Text::NoteNoRun)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 4 KB of EEPROM that counts the writes of each cell.
    struct Eeprom {
        cells: Vec<u8>,
        writes: Vec<u32>,
    }

    impl Storage for Eeprom {
        fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]) {
            let a = addr as usize;
            buf.copy_from_slice(&self.cells[a..a + buf.len()]);
        }
        fn eeprom_write(&mut self, addr: u16, data: &[u8]) {
            for (i, &b) in data.iter().enumerate() {
                let a = addr as usize + i;
                if self.cells[a] != b {
                    self.cells[a] = b;
                    self.writes[a] += 1;
                }
            }
        }
    }

    fn blank() -> Eeprom {
        Eeprom { cells: vec![0xFF; 4096], writes: vec![0; 4096] }
    }

    fn name(s: &str) -> Name {
        Name::parse(s.as_bytes()).unwrap()
    }

    #[test]
    fn a_blank_eeprom_holds_no_job_and_line_1_is_proposed() {
        let mut e = blank();
        assert_eq!(load(&mut e), None);
        assert_eq!(propose(load(&mut e), &name("CUT.NC"), 100), (1, Some(Text::NoteNoRun)));
    }

    #[test]
    fn the_last_line_reached_is_proposed_for_the_same_file_only() {
        let mut e = blank();
        start(&mut e, &name("CUT.NC"), 1234, 1);
        for l in [40, 90, 130] {
            reached(&mut e, l);
        }
        let r = load(&mut e).unwrap();
        assert_eq!(r, Record { name: name("CUT.NC"), size: 1234, line: 130 });
        assert_eq!(propose(Some(r), &name("CUT.NC"), 1234), (130, None));
        assert_eq!(propose(Some(r), &name("CUT.NC"), 1235), (1, Some(Text::NoteFileChanged)));
        assert_eq!(propose(Some(r), &name("OTHER.NC"), 1234), (1, Some(Text::NoteNoRun)));
        // A job that ran to its end leaves nothing to resume.
        reached(&mut e, 0);
        assert_eq!(load(&mut e), None);
        // A run from line 20 starts the slots again at 20.
        start(&mut e, &name("CUT.NC"), 1234, 20);
        assert_eq!(load(&mut e).unwrap().line, 20);
        reached(&mut e, 25);
        assert_eq!(load(&mut e).unwrap().line, 25);
    }

    #[test]
    fn a_corrupt_header_holds_no_job() {
        let mut e = blank();
        start(&mut e, &name("CUT.NC"), 1234, 7);
        e.cells[EEPROM_RESUME_ADDR as usize + 14] ^= 1;
        assert_eq!(load(&mut e), None);
    }

    /// The wear the module doc states: 8 000 records of a long job (66
    /// hours at one every 30 s) program no cell more than 1 001 times (1 000
    /// round-robin turns and the job's start).
    #[test]
    fn records_go_round_the_slots_so_each_cell_takes_one_write_in_eight() {
        let mut e = blank();
        start(&mut e, &name("LONG.NC"), 9_999_999, 1);
        for k in 1..=8000u32 {
            reached(&mut e, 1 + k * 37);
        }
        assert_eq!(load(&mut e).unwrap().line, 1 + 8000 * 37);
        let most = *e.writes.iter().max().unwrap();
        assert!(most <= 1001, "a cell was programmed {most} times");
        // Writing the same line again programs nothing.
        let before = e.writes.clone();
        reached(&mut e, 1 + 8000 * 37);
        assert_eq!(e.writes, before);
    }
}
