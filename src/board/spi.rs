//! SPI master for the SD card: SCK PB1 (D52), MOSI PB2 (D51), MISO PB3 (D50),
//! chip select PB0 (D53, the hardware SS pin used as a GPIO), docs/SPEC.md §2.
//!
//! Owns the SPI peripheral (ATmega2560 datasheet §21, "SPI – Serial Peripheral
//! Interface") and the PB0..PB3 bits of DDRB/PORTB. PB4 is the spindle PWM pin
//! and belongs to someone else, so every DDRB/PORTB change here is a masked
//! read-modify-write inside `interrupt::free`.
//!
//! It provides the three embedded-hal 1.0 pieces that `embedded-sdmmc` needs to
//! build an `SdCard` over an `ExclusiveDevice`: [`SpiBus`] (mode 0, MSB first,
//! blocking), [`ChipSelect`] (PB0 as an `OutputPin`) and [`BusyDelay`]
//! (a cycle-counted `DelayNs` for 16 MHz), and [`SdDevice`], the bus with its
//! chip select, which also reads data blocks with their CRC16 computed during
//! the transfer (the vendored crate's `ReadCrc16`).
//!
//! PB0 must stay an output: if SS were an input and went low, the SPI would
//! drop out of master mode (§21 "SS Pin Functionality", master mode). [`SpiBus::new`] makes it an output, high.

use core::convert::Infallible;

use avr_device::atmega2560::{PORTB, SPI};
use embedded_hal::{delay::DelayNs, digital, spi};

/// CPU clock of the Mega2560 in Hz.
const F_CPU_HZ: u32 = 16_000_000;

/// Status polls allowed for one byte before [`Error::Timeout`]. A byte takes at
/// most 8 × 128 = 1024 CPU cycles and one poll at least 4 cycles, so this
/// allows several times the slowest byte.
const BYTE_TIMEOUT_POLLS: u16 = 2048;

/// The word clocked out while only reading: MOSI held high, as SD cards expect.
const FILL_BYTE: u8 = 0xFF;

/// SPDR and SPSR in the I/O space (`in`/`out`), datasheet "Register Summary":
/// memory addresses 0x4E and 0x4D minus 0x20.
const SPDR_IO: u8 = 0x2E;
const SPSR_IO: u8 = 0x2D;

/// SCK = F_CPU / divider. Every divider the SPI offers (§21 SPCR/SPSR, "Relationship between SCK and the Oscillator Frequency").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockDiv {
    /// F_CPU / 2 = 8 MHz: the fast mode after SD initialisation.
    Div2,
    /// F_CPU / 4 = 4 MHz.
    Div4,
    /// F_CPU / 8 = 2 MHz.
    Div8,
    /// F_CPU / 16 = 1 MHz.
    Div16,
    /// F_CPU / 32 = 500 kHz.
    Div32,
    /// F_CPU / 64 = 250 kHz.
    Div64,
    /// F_CPU / 128 = 125 kHz: SD card initialisation (must be ≤ 400 kHz).
    Div128,
}

impl ClockDiv {
    /// The clock for SD card initialisation (125 kHz, ≤ 400 kHz required).
    pub const SD_INIT: ClockDiv = ClockDiv::Div128;
    /// The clock after SD initialisation (8 MHz).
    pub const FAST: ClockDiv = ClockDiv::Div2;

    /// SCK frequency in Hz for this divider at 16 MHz.
    pub const fn sck_hz(self) -> u32 {
        F_CPU_HZ / self.divider()
    }

    /// The divider as a number (2..=128).
    pub const fn divider(self) -> u32 {
        match self {
            ClockDiv::Div2 => 2,
            ClockDiv::Div4 => 4,
            ClockDiv::Div8 => 8,
            ClockDiv::Div16 => 16,
            ClockDiv::Div32 => 32,
            ClockDiv::Div64 => 64,
            ClockDiv::Div128 => 128,
        }
    }

    /// (SPR1:0, SPI2X) for this divider, Table 21-5.
    const fn bits(self) -> (u8, bool) {
        match self {
            ClockDiv::Div2 => (0, true),
            ClockDiv::Div4 => (0, false),
            ClockDiv::Div8 => (1, true),
            ClockDiv::Div16 => (1, false),
            ClockDiv::Div32 => (2, true),
            ClockDiv::Div64 => (2, false),
            ClockDiv::Div128 => (3, false),
        }
    }
}

/// What can go wrong on the SPI bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The SPI left master mode (MSTR cleared): SS/PB0 was made an input and
    /// pulled low by someone else. [`SpiBus::set_clock`] restores master mode.
    ModeFault,
    /// SPIF did not come within the time budget for one byte.
    Timeout,
}

impl spi::Error for Error {
    fn kind(&self) -> spi::ErrorKind {
        match *self {
            Error::ModeFault => spi::ErrorKind::ModeFault,
            Error::Timeout => spi::ErrorKind::Other,
        }
    }
}

/// Blocking SPI master, mode 0 (CPOL = 0, CPHA = 0), MSB first.
pub struct SpiBus {
    /// The SPI register block.
    spi: SPI,
}

impl SpiBus {
    /// Take the SPI, set up PB0..PB3 (CS output high, SCK and MOSI outputs low,
    /// MISO input with pull-up) and enable the SPI as master at `div`.
    /// Returns the bus and the chip select for PB0.
    pub fn new(spi: SPI, portb: &PORTB, div: ClockDiv) -> (SpiBus, ChipSelect) {
        avr_device::interrupt::free(|_| {
            // CS high before it becomes an output, so the card never sees a
            // select glitch; SCK/MOSI idle low in mode 0; MISO pulled up
            // (an SD card tri-states DO while deselected).
            portb.portb().modify(|_, w| w.pb0().set_bit().pb1().clear_bit().pb2().clear_bit().pb3().set_bit());
            portb.ddrb().modify(|_, w| w.pb0().set_bit().pb1().set_bit().pb2().set_bit().pb3().clear_bit());
        });
        let mut bus = SpiBus { spi };
        bus.set_clock(div);
        // Clear a stale SPIF: read SPSR, then SPDR (§21 SPSR: SPIF).
        let _ = bus.spi.spsr().read();
        let _ = bus.spi.spdr().read();
        (bus, ChipSelect { _private: () })
    }

    /// Set SCK to F_CPU / `div` (mode 0, MSB first, master, enabled).
    /// Use [`ClockDiv::SD_INIT`] before SD initialisation, [`ClockDiv::FAST`] after.
    pub fn set_clock(&mut self, div: ClockDiv) {
        let (spr, spi2x) = div.bits();
        self.spi.spcr().write(|w| {
            w.spe().set_bit().mstr().set_bit();
            w.cpol().clear_bit().cpha().clear_bit().dord().clear_bit();
            match spr {
                0 => w.spr().fosc_4_2(),
                1 => w.spr().fosc_16_8(),
                2 => w.spr().fosc_64_32(),
                _ => w.spr().fosc_128_64(),
            }
        });
        self.spi.spsr().write(|w| w.spi2x().bit(spi2x));
    }

    /// Give the SPI back, disabled. PB0..PB3 keep their last setting.
    pub fn release(self) -> SPI {
        self.spi.spcr().write(|w| w);
        self.spi
    }

    /// Clock one byte out and return the byte clocked in. Always inlined:
    /// as a call it cost ~45 cycles a byte against the 16 the SPI takes at
    /// F_CPU / 2 (an SD block is 512 bytes).
    // speed: ~45 cycles a byte as a call (see above); LLVM makes it one
    #[inline(always)]
    fn exchange(&mut self, out: u8) -> Result<u8, Error> {
        self.spi.spdr().write(|w| w.set(out));
        for _ in 0..BYTE_TIMEOUT_POLLS {
            if self.spi.spsr().read().spif().bit_is_set() {
                return Ok(self.spi.spdr().read().bits());
            }
        }
        Err(self.fault_or(Error::Timeout))
    }

    /// Read `words`, clocking out 0xFF for each, and return their
    /// CRC-16/XMODEM (the SD data CRC).
    ///
    /// This is the SD card's data path (512-byte blocks), so the loop is
    /// assembly, and it computes the CRC of the byte before while the SPI
    /// shifts the next one: 31 cycles a byte, where reading (25) and then
    /// the CRC (27, `crc16_fast` in the vendored `embedded-sdmmc`) took 52.
    /// The CRC step is that of `crc16_fast`, 19 single-cycle instructions;
    /// the first turn steps a 0 byte, which leaves the CRC at 0, and the
    /// last byte is stepped after the loop (the T flag marks that turn).
    ///
    /// The wait for each byte needs no counter: in master mode SPIF comes
    /// 16 cycles after the write at F_CPU / 2 (2 × 8 bits; the CRC step
    /// takes longer, and slower clocks only wait longer), and a mode fault
    /// sets SPIF as well (§21 "SS Pin Functionality", SPSR), which the check
    /// after the loop reports. SPDR is read before the next byte is written
    /// (no reliance on the receive buffer).
    pub fn read_crc16(&mut self, words: &mut [u8]) -> Result<u16, Error> {
        self.check_master()?;
        if words.is_empty() {
            return Ok(0);
        }
        let mut crc = 0u16;
        // SAFETY: writes `words.len()` bytes from `words.as_mut_ptr()` on,
        // inside `words`; touches SPDR and SPSR, which this SpiBus owns. The
        // count is non-zero (checked above), so the loop ends.
        unsafe {
            core::arch::asm!(
                "clt",
                "1:",
                "out {spdr}, {ff}",
                // CRC step for the byte before (x): with x = (crc >> 8) ^ x,
                // x ^= x >> 4: hi = lo ^ (x << 4) ^ (x >> 3), lo = (x << 5) ^ x.
                "2:",
                "eor {x}, {crc:h}",
                "mov {t}, {x}",
                "swap {t}",
                "andi {t}, 0x0F",
                "eor {x}, {t}",
                "mov {s}, {x}",
                "swap {s}",
                "mov {crc:h}, {s}",
                "andi {crc:h}, 0xF0",
                "eor {crc:h}, {crc:l}",
                "mov {t}, {x}",
                "lsr {t}",
                "lsr {t}",
                "lsr {t}",
                "eor {crc:h}, {t}",
                "lsl {s}",
                "andi {s}, 0xE0",
                "eor {s}, {x}",
                "mov {crc:l}, {s}",
                "brts 4f",
                "3:",
                "in {t}, {spsr}",
                "sbrs {t}, 7",
                "rjmp 3b",
                "in {x}, {spdr}",
                "st X+, {x}",
                "sbiw {n}, 1",
                "brne 1b",
                "set",
                "rjmp 2b",
                "4:",
                inout("X") words.as_mut_ptr() => _,
                n = inout(reg_iw) words.len() as u16 => _,
                ff = in(reg) FILL_BYTE,
                x = inout(reg) 0u8 => _,
                crc = inout(reg_iw) crc,
                t = out(reg_upper) _,
                s = out(reg_upper) _,
                spdr = const SPDR_IO,
                spsr = const SPSR_IO,
                options(nostack),
            );
        }
        self.check_master()?;
        Ok(crc)
    }

    /// `ModeFault` if the SPI has left master mode, else `other`.
    fn fault_or(&self, other: Error) -> Error {
        if self.spi.spcr().read().mstr().bit_is_clear() {
            Error::ModeFault
        } else {
            other
        }
    }

    /// Fail early if a mode fault has dropped the SPI out of master mode.
    fn check_master(&self) -> Result<(), Error> {
        if self.spi.spcr().read().mstr().bit_is_clear() {
            Err(Error::ModeFault)
        } else {
            Ok(())
        }
    }
}

impl spi::ErrorType for SpiBus {
    type Error = Error;
}

impl spi::SpiBus<u8> for SpiBus {
    /// Read `words`, clocking out 0xFF for each: [`SpiBus::read_crc16`]
    /// without the CRC (one read loop in flash).
    fn read(&mut self, words: &mut [u8]) -> Result<(), Self::Error> {
        self.read_crc16(words).map(|_| ())
    }

    /// Write `words`, dropping what comes back.
    fn write(&mut self, words: &[u8]) -> Result<(), Self::Error> {
        self.check_master()?;
        for &word in words {
            self.exchange(word)?;
        }
        Ok(())
    }

    /// Run for `max(read.len(), write.len())` bytes: 0xFF is sent past the end
    /// of `write`, and bytes received past the end of `read` are dropped.
    fn transfer(&mut self, read: &mut [u8], write: &[u8]) -> Result<(), Self::Error> {
        self.check_master()?;
        let len = read.len().max(write.len());
        for i in 0..len {
            let out = write.get(i).copied().unwrap_or(FILL_BYTE);
            let got = self.exchange(out)?;
            if let Some(slot) = read.get_mut(i) {
                *slot = got;
            }
        }
        Ok(())
    }

    /// Send `words` and replace each with the byte received for it.
    fn transfer_in_place(&mut self, words: &mut [u8]) -> Result<(), Self::Error> {
        self.check_master()?;
        for word in words.iter_mut() {
            *word = self.exchange(*word)?;
        }
        Ok(())
    }

    /// Nothing is ever left in flight: each byte completes before the call returns.
    fn flush(&mut self) -> Result<(), Self::Error> {
        self.check_master()
    }
}

/// The SD card chip select on PB0 (active low). Only [`SpiBus::new`] makes one,
/// so PB0 has a single owner.
pub struct ChipSelect {
    /// Not constructible outside this module.
    _private: (),
}

impl ChipSelect {
    /// Set or clear PORTB0 only, inside a critical section (PORTB is shared).
    fn drive(&mut self, high: bool) {
        avr_device::interrupt::free(|_| {
            // SAFETY: PORTB is only read and written here, inside a critical
            // section, changing bit 0 only; bit 0 is owned by this ChipSelect,
            // the only one there is, so no other code's bits are disturbed.
            let portb = unsafe { &*PORTB::ptr() };
            portb.portb().modify(|_, w| w.pb0().bit(high));
        });
    }
}

impl digital::ErrorType for ChipSelect {
    type Error = Infallible;
}

impl digital::OutputPin for ChipSelect {
    /// Select the card (PB0 low).
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.drive(false);
        Ok(())
    }

    /// Deselect the card (PB0 high).
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.drive(true);
        Ok(())
    }
}

/// Busy-wait delay counted in CPU cycles at 16 MHz. Waits at least as long as
/// asked; interrupts taken meanwhile only make it longer.
#[derive(Clone, Copy, Debug, Default)]
pub struct BusyDelay;

impl BusyDelay {
    /// CPU cycles per microsecond.
    const CYCLES_PER_US: u32 = F_CPU_HZ / 1_000_000;
    /// Largest microsecond count whose cycle count fits in a u32.
    const MAX_US_PER_CALL: u32 = u32::MAX / Self::CYCLES_PER_US;
}

impl DelayNs for BusyDelay {
    /// Wait at least `ns` nanoseconds (one cycle is 62.5 ns).
    fn delay_ns(&mut self, ns: u32) {
        // ns / 62.5 = ns · 1.024 / 64; ns/64 + ns/2048 = ns · 1.03125 / 64 is
        // never less, and needs only shifts (no 32-bit division on the AVR).
        let cycles = (ns >> 6) + (ns >> 11) + 1;
        avr_device::asm::delay_cycles(cycles);
    }

    /// Wait at least `us` microseconds.
    fn delay_us(&mut self, mut us: u32) {
        while us > Self::MAX_US_PER_CALL {
            avr_device::asm::delay_cycles(Self::MAX_US_PER_CALL * Self::CYCLES_PER_US);
            us -= Self::MAX_US_PER_CALL;
        }
        avr_device::asm::delay_cycles(us * Self::CYCLES_PER_US);
    }

    /// Wait at least `ms` milliseconds.
    fn delay_ms(&mut self, ms: u32) {
        for _ in 0..ms {
            avr_device::asm::delay_cycles(1000 * Self::CYCLES_PER_US);
        }
    }
}

/// The SD card as an embedded-hal 1.0 [`spi::SpiDevice`]: the bus plus its
/// chip select, asserted for the length of each transaction (what
/// `embedded-sdmmc`'s `SdCard` needs; a few lines instead of the
/// `embedded-hal-bus` crate).
pub struct SdDevice {
    pub bus: SpiBus,
    pub cs: ChipSelect,
}

impl SdDevice {
    /// The card's power-up: at least 74 clocks with CS high (SD Physical
    /// Layer spec 6.4.1), here 80, at the current (slow) clock.
    pub fn wake_card(&mut self) -> Result<(), Error> {
        use digital::OutputPin;
        let _ = self.cs.set_high();
        // Ten bytes of fill clocked out one by one: `&[FILL_BYTE; 10]` was a
        // 10-byte array in RAM (`.data`) on AVR.
        self.bus.check_master()?;
        for _ in 0..10 {
            self.bus.exchange(FILL_BYTE)?;
        }
        Ok(())
    }
}

impl spi::ErrorType for SdDevice {
    type Error = Error;
}

/// The SD driver reads data blocks through [`SpiBus::read_crc16`], which
/// computes their CRC during the transfer (vendor/README.md).
impl embedded_sdmmc::sdcard::spi::ReadCrc16 for SdDevice {
    fn read_crc16(&mut self, buffer: &mut [u8]) -> Result<u16, Error> {
        use digital::OutputPin;
        let _ = self.cs.set_low();
        let r = self.bus.read_crc16(buffer);
        let _ = self.cs.set_high();
        r
    }
}

impl spi::SpiDevice<u8> for SdDevice {
    fn transaction(&mut self, operations: &mut [spi::Operation<'_, u8>]) -> Result<(), Error> {
        use digital::OutputPin;
        use spi::{Operation, SpiBus as _};
        let _ = self.cs.set_low();
        let mut r = Ok(());
        for op in operations.iter_mut() {
            r = match op {
                Operation::Read(buf) => self.bus.read(buf),
                Operation::Write(buf) => self.bus.write(buf),
                Operation::Transfer(rd, wr) => self.bus.transfer(rd, wr),
                Operation::TransferInPlace(buf) => self.bus.transfer_in_place(buf),
                Operation::DelayNs(ns) => {
                    BusyDelay.delay_ns(*ns);
                    Ok(())
                }
            };
            if r.is_err() {
                break;
            }
        }
        let _ = self.cs.set_high();
        r
    }
}
