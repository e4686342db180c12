//! The on-chip EEPROM (4 KiB), where the settings image (`config`) and the
//! carousel's tool table (`atc`) are kept.
//!
//! Owns the EEPROM registers (ATmega2560 datasheet, rev. 2549Q: §8.3 "EEPROM Data
//! Memory" and the §8.6 register description of EEAR, EEDR and EECR). Byte access,
//! bounds-checked: an address past [`SIZE`] is an error, never a wrap-around.
//!
//! Writes spare the cells (about 100 000 erase/write cycles each): a byte is
//! only programmed when its value changes. Each programming waits for the
//! previous one (EEPE clear, typically 3.3 ms), and interrupts are disabled only
//! for the two-store EEMPE → EEPE sequence, which must complete within four
//! cycles (§8.6, EECR: EEPE). The waits are bounded and end in [`Error::Timeout`].

use avr_device::atmega2560::EEPROM;

/// Size of the EEPROM in bytes.
pub const SIZE: u16 = 4096;

/// Status polls allowed while waiting for EEPE to clear. One poll costs at
/// least 4 cycles, so this is at least 10 ms at 16 MHz, about three times the
/// datasheet's typical 3.3 ms erase + write time.
const EEPE_TIMEOUT_POLLS: u32 = 16_000_000 / 100 / 4;

/// What can go wrong with an EEPROM access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// `addr .. addr + len` does not lie inside `0 .. SIZE`.
    OutOfRange {
        /// First address asked for.
        addr: u16,
        /// Number of bytes asked for.
        len: u16,
    },
    /// A previous write did not finish (EEPE stayed set) within 10 ms.
    Timeout,
}

/// Byte-wise EEPROM access. Owns the EEPROM registers.
pub struct Eeprom {
    /// The EEPROM register block.
    eeprom: EEPROM,
}

impl Eeprom {
    /// Size of the EEPROM in bytes (same as [`SIZE`]).
    pub const SIZE: u16 = SIZE;

    /// Take the EEPROM registers.
    pub fn new(eeprom: EEPROM) -> Eeprom {
        Eeprom { eeprom }
    }

    /// Give the EEPROM registers back.
    pub fn release(self) -> EEPROM {
        self.eeprom
    }

    /// Read the byte at `addr`.
    pub fn read_byte(&mut self, addr: u16) -> Result<u8, Error> {
        check_range(addr, 1)?;
        self.wait_ready()?;
        Ok(self.read_cell(addr))
    }

    /// Fill `buf` from the bytes starting at `addr`.
    pub fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), Error> {
        check_range(addr, buf.len())?;
        self.wait_ready()?;
        for (cell, byte) in (addr..).zip(buf.iter_mut()) {
            *byte = self.read_cell(cell);
        }
        Ok(())
    }

    /// Store `data` at `addr`, programming only the bytes whose value differs.
    /// Returns how many bytes were actually programmed (0 when nothing changed).
    /// Blocks about 3.3 ms per programmed byte. On `Timeout` the bytes before
    /// the failing one are already stored.
    pub fn write(&mut self, addr: u16, data: &[u8]) -> Result<u16, Error> {
        check_range(addr, data.len())?;
        let mut written: u16 = 0;
        for (cell, &byte) in (addr..).zip(data.iter()) {
            // EEAR and EEDR must not change while a write is in progress.
            self.wait_ready()?;
            if self.read_cell(cell) == byte {
                continue;
            }
            self.program_cell(cell, byte);
            written += 1;
        }
        Ok(written)
    }

    /// Wait (bounded) until no write is in progress (EEPE clear).
    fn wait_ready(&mut self) -> Result<(), Error> {
        let mut polls = EEPE_TIMEOUT_POLLS;
        while self.eeprom.eecr().read().eepe().bit_is_set() {
            polls -= 1;
            if polls == 0 {
                return Err(Error::Timeout);
            }
        }
        Ok(())
    }

    /// Read one cell. EEPE must be clear. The CPU halts 4 cycles on EERE.
    fn read_cell(&mut self, addr: u16) -> u8 {
        self.eeprom.eear().write(|w| w.set(addr));
        self.eeprom.eecr().write(|w| w.eere().set_bit());
        self.eeprom.eedr().read().bits()
    }

    /// Start erase + write of one cell (§8.6, EECR: EEPE, steps 1 and 3–6; step 2,
    /// SPMEN, only matters to code that writes flash, which this firmware never does). EEPE must be clear.
    fn program_cell(&mut self, addr: u16, byte: u8) {
        self.eeprom.eear().write(|w| w.set(addr));
        self.eeprom.eedr().write(|w| w.set(byte));
        let eecr = self.eeprom.eecr();
        // An interrupt between the two stores would break the 4-cycle window,
        // so only these two stores run with interrupts off.
        avr_device::interrupt::free(|_| {
            // EEMPE alone, then EEMPE|EEPE, both with EEPM = 00 (atomic erase
            // and write) and EERIE = 0: what `sbi EECR,EEMPE; sbi EECR,EEPE`
            // leaves in EECR. Two constant stores, a few cycles apart.
            eecr.write(|w| w.eempe().set_bit());
            eecr.write(|w| w.eempe().set_bit().eepe().set_bit());
        });
    }
}

/// `Ok` if `addr .. addr + len` lies inside the EEPROM.
fn check_range(addr: u16, len: usize) -> Result<(), Error> {
    let end = u32::from(addr) + len as u32;
    if end > u32::from(SIZE) {
        Err(Error::OutOfRange { addr, len: len.min(usize::from(u16::MAX)) as u16 })
    } else {
        Ok(())
    }
}
