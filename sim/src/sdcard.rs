//! An SD card in SPI mode, byte by byte (SD Physical Layer Simplified
//! Specification, chapter 7 "SPI Mode").
//!
//! The VM hands every byte the AVR's SPI master clocks out while the card's
//! chip select (PB0) is low to [`SdCard::exchange`] and clocks the returned
//! byte back in. The card is backed by a whole-card image (MBR + partition,
//! see [`crate::sdimage`]).
//!
//! Modelled: CMD0, CMD8, CMD9 (CSD v2), CMD12, CMD13, CMD16, CMD17, CMD18,
//! CMD24, CMD25, CMD55/ACMD41, ACMD23, CMD58 (OCR with CCS), CMD59 (CRC on/off);
//! CRC7 on every command frame (CMD0 and CMD8 always, the others once CMD59
//! turned CRC on) and CRC16 on data blocks both ways; SDHC block addressing or
//! SDSC byte addressing; a data error token for reads past the end; the card
//! pulled out (MISO floats high, everything is forgotten); a wrong data CRC
//! on a chosen read, for tests ([`SdCard::corrupt_next_read_crc`]).
//!
//! Not modelled: timing (the card answers after one byte, NCR = 1, and sends
//! a read token after one more), erase, CSD v1 cards, write protection.

use std::collections::VecDeque;

/// Block size, bytes.
pub const BLOCK: usize = 512;

/// Card capacity class, which decides how CMD17/18/24/25 address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CardKind {
    /// SDHC/SDXC: block addresses, OCR CCS = 1.
    Sdhc,
    /// SDSC (v2): byte addresses, OCR CCS = 0.
    Sdsc,
}

/// Counters, for tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SdStats {
    pub commands: u64,
    pub blocks_read: u64,
    pub blocks_written: u64,
    pub crc_errors: u64,
    pub bytes: u64,
    /// Data blocks sent with a wrong CRC16 ([`SdCard::corrupt_next_read_crc`]).
    pub corrupted_crcs: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Rx {
    /// Waiting for / collecting a command frame.
    Command,
    /// After CMD24/CMD25: waiting for a start token (multi: true).
    WriteToken { block: u32, multi: bool },
    /// Collecting a data block + CRC.
    WriteData { block: u32, multi: bool },
}

/// The card model. See the module docs.
pub struct SdCard {
    image: Vec<u8>,
    kind: CardKind,
    present: bool,
    selected: bool,
    /// Card has left the idle state (ACMD41 done).
    ready: bool,
    acmd41_polls: u8,
    app_cmd: bool,
    crc_on: bool,
    frame: Vec<u8>,
    out: VecDeque<u8>,
    rx: Rx,
    data: Vec<u8>,
    /// CMD18 in progress: next block to stream.
    read_multi: Option<u32>,
    /// The next read of this block sends a wrong CRC16.
    corrupt_crc_of: Option<u32>,
    stats: SdStats,
    /// Log of the commands received: (cmd, arg).
    pub log: Vec<(u8, u32)>,
}

impl SdCard {
    /// A card holding `image` (its length is rounded up to whole blocks).
    pub fn new(mut image: Vec<u8>, kind: CardKind) -> SdCard {
        let n = image.len().div_ceil(BLOCK).max(1) * BLOCK;
        image.resize(n, 0);
        SdCard {
            image,
            kind,
            present: true,
            selected: false,
            ready: false,
            acmd41_polls: 0,
            app_cmd: false,
            crc_on: false,
            frame: Vec::with_capacity(6),
            out: VecDeque::new(),
            rx: Rx::Command,
            data: Vec::with_capacity(BLOCK + 3),
            read_multi: None,
            corrupt_crc_of: None,
            stats: SdStats::default(),
            log: Vec::new(),
        }
    }

    /// The card's contents (writes included).
    pub fn image(&self) -> &[u8] {
        &self.image
    }

    /// The card's contents, mutable (to corrupt it in a test).
    pub fn image_mut(&mut self) -> &mut Vec<u8> {
        &mut self.image
    }

    /// The next time block `block` is read (CMD17/CMD18), send its data
    /// with the CRC16 off by one bit, once: a transfer error the host must
    /// catch by its CRC check (the data itself arrives intact).
    pub fn corrupt_next_read_crc(&mut self, block: u32) {
        self.corrupt_crc_of = Some(block);
    }

    /// Counters.
    pub fn stats(&self) -> SdStats {
        self.stats
    }

    /// Is the card in the socket?
    pub fn present(&self) -> bool {
        self.present
    }

    /// Pull the card out (`false`) or push it back in (`true`). A pulled card
    /// loses its state: it must be initialised again (CMD0...).
    pub fn set_present(&mut self, present: bool) {
        self.present = present;
        if !present {
            self.ready = false;
            self.crc_on = false;
            self.app_cmd = false;
            self.frame.clear();
            self.out.clear();
            self.rx = Rx::Command;
            self.read_multi = None;
        }
    }

    /// Chip select level changed (`true` = selected, CS low).
    pub fn select(&mut self, selected: bool) {
        self.selected = selected;
        if !selected {
            // A half-received command frame is dropped.
            self.frame.clear();
        }
    }

    /// One SPI byte: the master sent `mosi`; returns what the card drives on MISO.
    pub fn exchange(&mut self, mosi: u8) -> u8 {
        if !self.present || !self.selected {
            return 0xFF;
        }
        self.stats.bytes += 1;
        if self.out.is_empty() {
            if let Some(b) = self.read_multi {
                self.queue_block(b, 1);
                self.read_multi = Some(b + 1);
            }
        }
        let miso = self.out.pop_front().unwrap_or(0xFF);
        self.receive(mosi);
        miso
    }

    fn receive(&mut self, b: u8) {
        match self.rx {
            Rx::Command => {
                if self.frame.is_empty() && b & 0xC0 != 0x40 {
                    return; // idle clocks (0xFF) or junk between frames
                }
                self.frame.push(b);
                if self.frame.len() == 6 {
                    let f = std::mem::take(&mut self.frame);
                    self.command(&f);
                }
            }
            Rx::WriteToken { block, multi } => {
                if !multi && b == 0xFE || multi && b == 0xFC {
                    self.data.clear();
                    self.rx = Rx::WriteData { block, multi };
                } else if multi && b == 0xFD {
                    // Stop tran: the card is busy for a moment.
                    self.out.extend([0xFF, 0x00, 0x00]);
                    self.rx = Rx::Command;
                }
            }
            Rx::WriteData { block, multi } => {
                self.data.push(b);
                if self.data.len() == BLOCK + 2 {
                    let crc = u16::from_be_bytes([self.data[BLOCK], self.data[BLOCK + 1]]);
                    let ok_crc = !self.crc_on || crc == crc16(&self.data[..BLOCK]);
                    let in_range = ((block as usize) + 1) * BLOCK <= self.image.len();
                    if !ok_crc {
                        self.stats.crc_errors += 1;
                        self.out.extend([0x0B]); // data rejected: CRC error
                    } else if !in_range {
                        self.out.extend([0x0D]); // data rejected: write error
                    } else {
                        let at = block as usize * BLOCK;
                        let (img, data) = (&mut self.image, &self.data);
                        img[at..at + BLOCK].copy_from_slice(&data[..BLOCK]);
                        self.stats.blocks_written += 1;
                        self.out.extend([0x05, 0x00, 0x00, 0x00]); // accepted, busy
                    }
                    self.rx = if multi { Rx::WriteToken { block: block + 1, multi } } else { Rx::Command };
                }
            }
        }
    }

    fn r1(&self) -> u8 {
        if self.ready {
            0x00
        } else {
            0x01
        }
    }

    fn command(&mut self, f: &[u8]) {
        let cmd = f[0] & 0x3F;
        let arg = u32::from_be_bytes([f[1], f[2], f[3], f[4]]);
        self.stats.commands += 1;
        self.log.push((cmd, arg));
        let app = std::mem::take(&mut self.app_cmd);
        // NCR: one byte of 0xFF before the response.
        self.out.clear();
        if cmd == 12 {
            // Stop transmission: the stuff byte, then R1.
            self.read_multi = None;
            self.out.extend([0xFF, 0x00]);
            return;
        }
        self.out.push_back(0xFF);
        let crc_ok = crc7(&f[..5]) << 1 | 1 == f[5];
        if (self.crc_on || cmd == 0 || cmd == 8) && !crc_ok {
            self.stats.crc_errors += 1;
            self.out.push_back(self.r1() | 0x08);
            return;
        }
        match (app, cmd) {
            (_, 0) => {
                self.ready = false;
                self.crc_on = false;
                self.acmd41_polls = 0;
                self.read_multi = None;
                self.rx = Rx::Command;
                self.out.push_back(0x01);
            }
            (_, 8) => {
                let r = self.r1();
                self.out.extend([r, 0x00, 0x00, (arg >> 8) as u8 & 0x0F, arg as u8]);
            }
            (_, 55) => {
                self.app_cmd = true;
                let r = self.r1();
                self.out.push_back(r);
            }
            (true, 41) => {
                // Two polls before the card is ready, as real cards take a while.
                self.acmd41_polls += 1;
                if self.acmd41_polls >= 2 {
                    self.ready = true;
                }
                let r = self.r1();
                self.out.push_back(r);
            }
            (true, 23) => {
                let r = self.r1();
                self.out.push_back(r);
            }
            (_, 58) => {
                let ccs = if self.kind == CardKind::Sdhc { 0x40 } else { 0 };
                let r = self.r1();
                self.out.extend([r, 0x80 | ccs, 0xFF, 0x80, 0x00]);
            }
            (_, 59) => {
                self.crc_on = arg & 1 != 0;
                let r = self.r1();
                self.out.push_back(r);
            }
            (_, 9) if self.ready => {
                let csd = self.csd();
                self.out.extend([0x00, 0xFF, 0xFE]);
                self.out.extend(csd);
                self.out.extend(crc16(&csd).to_be_bytes());
            }
            (_, 13) if self.ready => self.out.extend([0x00, 0x00]),
            (_, 16) if self.ready => self.out.push_back(0x00),
            (_, 17) | (_, 18) if self.ready => match self.block_of(arg) {
                Some(b) => {
                    self.out.push_back(0x00);
                    self.queue_block(b, 1);
                    if cmd == 18 {
                        self.read_multi = Some(b + 1);
                    }
                }
                None => self.out.push_back(0x40), // parameter (address) error
            },
            (_, 24) | (_, 25) if self.ready => match self.block_of(arg) {
                Some(b) => {
                    self.out.push_back(0x00);
                    self.rx = Rx::WriteToken { block: b, multi: cmd == 25 };
                }
                None => self.out.push_back(0x40),
            },
            _ => {
                let r = self.r1();
                self.out.push_back(r | 0x04); // illegal command
            }
        }
    }

    /// Block number of a data address, or None if misaligned (SDSC).
    fn block_of(&self, arg: u32) -> Option<u32> {
        match self.kind {
            CardKind::Sdhc => Some(arg),
            CardKind::Sdsc if (arg as usize).is_multiple_of(BLOCK) => Some(arg / BLOCK as u32),
            CardKind::Sdsc => None,
        }
    }

    /// Queue a read of block `b`: one byte of NAC, then the data token, the
    /// data and its CRC16; past the end of the card: a data error token
    /// (out of range).
    fn queue_block(&mut self, b: u32, nac: usize) {
        for _ in 0..nac {
            self.out.push_back(0xFF);
        }
        let at = b as usize * BLOCK;
        if at + BLOCK > self.image.len() {
            self.read_multi = None;
            self.out.push_back(0x08);
            return;
        }
        self.stats.blocks_read += 1;
        self.out.push_back(0xFE);
        let data = &self.image[at..at + BLOCK];
        self.out.extend(data.iter().copied());
        let mut crc = crc16(data);
        if self.corrupt_crc_of == Some(b) {
            self.corrupt_crc_of = None;
            self.stats.corrupted_crcs += 1;
            crc ^= 1;
        }
        self.out.extend(crc.to_be_bytes());
    }

    /// CSD version 2.0 (SDHC): C_SIZE = blocks / 1024 - 1.
    fn csd(&self) -> [u8; 16] {
        let blocks = (self.image.len() / BLOCK) as u32;
        let c_size = (blocks / 1024).max(1) - 1;
        let mut c = [0u8; 16];
        c[0] = 0x40; // CSD_STRUCTURE = 1
        c[1] = 0x0E; // TAAC
        c[2] = 0x00; // NSAC
        c[3] = 0x32; // TRAN_SPEED 25 MHz
        c[4] = 0x5B; // CCC high
        c[5] = 0x59; // CCC low | READ_BL_LEN = 9
        c[6] = 0x00;
        c[7] = ((c_size >> 16) & 0x3F) as u8;
        c[8] = (c_size >> 8) as u8;
        c[9] = c_size as u8;
        c[10] = 0x7F; // ERASE_BLK_EN, SECTOR_SIZE
        c[11] = 0x80;
        c[12] = 0x0A; // WRITE_BL_LEN = 9
        c[13] = 0x40;
        c[14] = 0x00;
        c[15] = (crc7(&c[..15]) << 1) | 1;
        c
    }
}

/// CRC7 of a command frame (polynomial x^7 + x^3 + 1).
pub fn crc7(data: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &byte in data {
        let mut d = byte;
        for _ in 0..8 {
            crc <<= 1;
            if (d ^ crc) & 0x80 != 0 {
                crc ^= 0x09;
            }
            d <<= 1;
        }
    }
    crc & 0x7F
}

/// CRC16-CCITT (XModem) of a data block, as SD cards use.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc = 0u16;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ 0x1021 } else { crc << 1 };
        }
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(cmd: u8, arg: u32) -> Vec<u8> {
        let mut f = vec![0x40 | cmd, (arg >> 24) as u8, (arg >> 16) as u8, (arg >> 8) as u8, arg as u8];
        f.push(crc7(&f) << 1 | 1);
        f
    }

    /// Send a command and return R1 (first non-0xFF byte).
    fn cmd(c: &mut SdCard, cmd: u8, arg: u32) -> u8 {
        for b in frame(cmd, arg) {
            c.exchange(b);
        }
        for _ in 0..8 {
            let r = c.exchange(0xFF);
            if r & 0x80 == 0 {
                return r;
            }
        }
        0xFF
    }

    fn init(c: &mut SdCard) {
        c.select(true);
        assert_eq!(cmd(c, 0, 0), 0x01);
        assert_eq!(cmd(c, 8, 0x1AA), 0x01);
        let echo: Vec<u8> = (0..4).map(|_| c.exchange(0xFF)).collect();
        assert_eq!(echo, [0, 0, 1, 0xAA]);
        assert_eq!(cmd(c, 59, 1), 0x01);
        loop {
            assert_eq!(cmd(c, 55, 0) & !1, 0);
            if cmd(c, 41, 0x4000_0000) == 0 {
                break;
            }
        }
    }

    #[test]
    fn crc7_of_cmd0_is_the_well_known_0x95() {
        assert_eq!(crc7(&[0x40, 0, 0, 0, 0]) << 1 | 1, 0x95);
        assert_eq!(crc7(&[0x48, 0, 0, 1, 0xAA]) << 1 | 1, 0x87);
    }

    #[test]
    fn crc16_of_a_block_of_ff_matches_the_spec_example() {
        // SD spec 4.5: 512 bytes of 0xFF have CRC16 0x7FA1.
        assert_eq!(crc16(&[0xFF; 512]), 0x7FA1);
    }

    #[test]
    fn init_then_read_a_block_with_its_crc() {
        let mut img = vec![0u8; 4 * BLOCK];
        img[BLOCK..2 * BLOCK].iter_mut().enumerate().for_each(|(i, b)| *b = i as u8);
        let mut c = SdCard::new(img, CardKind::Sdhc);
        init(&mut c);
        assert_eq!(cmd(&mut c, 17, 1), 0x00);
        let mut tok = c.exchange(0xFF);
        while tok == 0xFF {
            tok = c.exchange(0xFF);
        }
        assert_eq!(tok, 0xFE);
        let data: Vec<u8> = (0..BLOCK).map(|_| c.exchange(0xFF)).collect();
        assert_eq!(data[3], 3);
        let crc = u16::from_be_bytes([c.exchange(0xFF), c.exchange(0xFF)]);
        assert_eq!(crc, crc16(&data));
        // Past the end: data error token.
        assert_eq!(cmd(&mut c, 17, 100), 0x00);
        let mut tok = c.exchange(0xFF);
        while tok == 0xFF {
            tok = c.exchange(0xFF);
        }
        assert_eq!(tok, 0x08);
    }

    #[test]
    fn a_corrupted_read_crc_is_wrong_once_and_the_data_intact() {
        let mut img = vec![0u8; 4 * BLOCK];
        img[2 * BLOCK..3 * BLOCK].iter_mut().enumerate().for_each(|(i, b)| *b = (i * 7) as u8);
        let mut c = SdCard::new(img, CardKind::Sdhc);
        init(&mut c);
        c.corrupt_next_read_crc(2);
        let read = |c: &mut SdCard| {
            assert_eq!(cmd(c, 17, 2), 0x00);
            while c.exchange(0xFF) == 0xFF {}
            let data: Vec<u8> = (0..BLOCK).map(|_| c.exchange(0xFF)).collect();
            let crc = u16::from_be_bytes([c.exchange(0xFF), c.exchange(0xFF)]);
            (data, crc)
        };
        let (data, crc) = read(&mut c);
        assert_eq!(data[5], 35);
        assert_ne!(crc, crc16(&data));
        let (data, crc) = read(&mut c);
        assert_eq!(crc, crc16(&data), "only the next read");
        assert_eq!(c.stats().corrupted_crcs, 1);
    }

    #[test]
    fn a_written_block_lands_in_the_image() {
        let mut c = SdCard::new(vec![0u8; 4 * BLOCK], CardKind::Sdhc);
        init(&mut c);
        assert_eq!(cmd(&mut c, 24, 2), 0x00);
        c.exchange(0xFF);
        c.exchange(0xFE);
        let data = [0x5Au8; BLOCK];
        for b in data {
            c.exchange(b);
        }
        for b in crc16(&data).to_be_bytes() {
            c.exchange(b);
        }
        assert_eq!(c.exchange(0xFF) & 0x1F, 0x05);
        assert_eq!(&c.image()[2 * BLOCK..2 * BLOCK + 4], &[0x5A; 4]);
    }

    #[test]
    fn a_pulled_card_answers_nothing() {
        let mut c = SdCard::new(vec![0u8; 4 * BLOCK], CardKind::Sdhc);
        init(&mut c);
        c.set_present(false);
        assert_eq!(cmd(&mut c, 17, 1), 0xFF);
        c.set_present(true);
        // It must be initialised again.
        assert_eq!(cmd(&mut c, 17, 1) & 0x01, 0x01);
    }

    #[test]
    fn a_bad_command_crc_is_reported() {
        let mut c = SdCard::new(vec![0u8; 4 * BLOCK], CardKind::Sdhc);
        c.select(true);
        for b in [0x40, 0, 0, 0, 0, 0x01] {
            c.exchange(b);
        }
        c.exchange(0xFF);
        assert_eq!(c.exchange(0xFF) & 0x08, 0x08);
    }
}
