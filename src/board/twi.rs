//! TWI (I²C) master for the OLED: SDA on PD1 (D20), SCL on PD0 (D21), docs/SPEC.md §2.
//!
//! Owns the TWI peripheral (ATmega2560 datasheet §24, "2-wire Serial
//! Interface"). It is a blocking, polled master: every wait on TWINT or TWSTO
//! is bounded and ends in [`Error::Timeout`] instead of hanging the main loop.
//! It implements the embedded-hal 1.0 [`I2c`] trait so that the `sh1106` driver
//! can talk to the SH1106 at 0x3C at 400 kHz.
//!
//! One write may also run in the background ([`Twi::write_async`]): the
//! `TWI` interrupt sends it byte by byte (Master Transmitter mode, §24.7.1),
//! ~60 cycles a byte instead of the ~360 a polled byte waits at 400 kHz. The
//! OLED's 33-byte slices go that way.
//!
//! The TWI takes over PD0/PD1 by itself once TWEN is set (§24 "Overview"/TWCR: TWEN), so no DDR
//! setup is needed. PORTD is shared with other pins, so the optional internal
//! pull-ups are set through [`enable_internal_pullups`], which borrows PORTD.

use avr_device::atmega2560::{PORTD, TWI};
use core::ptr::addr_of_mut;
use embedded_hal::i2c::{self, ErrorKind, I2c, NoAcknowledgeSource, Operation, SevenBitAddress};
use portable_atomic::{AtomicU8, Ordering};

/// CPU clock of the Mega2560 in Hz.
const F_CPU_HZ: u32 = 16_000_000;

/// Cycles one status poll costs at least (load TWCR, test, count, branch).
/// Used to turn a time budget into a poll count that is never too short.
const MIN_CYCLES_PER_POLL: u32 = 4;

/// Shortest time budget for one bus event, in CPU cycles (1 ms).
const MIN_TIMEOUT_CYCLES: u32 = F_CPU_HZ / 1000;

/// TWI status codes (TWSR & 0xF8) for master mode, datasheet §24 "Transmission Modes"
/// (Master Transmitter and Master Receiver status tables).
mod status {
    /// Bus error: an illegal START or STOP (§24 "Miscellaneous States").
    pub const BUS_ERROR: u8 = 0x00;
    /// A START condition has been transmitted.
    pub const START: u8 = 0x08;
    /// A repeated START condition has been transmitted.
    pub const REP_START: u8 = 0x10;
    /// SLA+W has been transmitted; ACK has been received.
    pub const MT_SLA_ACK: u8 = 0x18;
    /// SLA+W has been transmitted; NOT ACK has been received.
    pub const MT_SLA_NACK: u8 = 0x20;
    /// Data byte has been transmitted; ACK has been received.
    pub const MT_DATA_ACK: u8 = 0x28;
    /// Data byte has been transmitted; NOT ACK has been received.
    pub const MT_DATA_NACK: u8 = 0x30;
    /// Arbitration lost in SLA+R/W or data bytes.
    pub const ARB_LOST: u8 = 0x38;
    /// SLA+R has been transmitted; ACK has been received.
    pub const MR_SLA_ACK: u8 = 0x40;
    /// SLA+R has been transmitted; NOT ACK has been received.
    pub const MR_SLA_NACK: u8 = 0x48;
    /// Data byte has been received; ACK has been returned.
    pub const MR_DATA_ACK: u8 = 0x50;
    /// Data byte has been received; NOT ACK has been returned.
    pub const MR_DATA_NACK: u8 = 0x58;
}

/// Longest background write, bytes (an OLED slice: control byte + 32).
pub const ASYNC_MAX: usize = 33;

/// The background write: filled by [`Twi::write_async`] while
/// [`ASYNC_STATE`] is not `RUNNING`, then read only by the `TWI` interrupt
/// until it leaves `RUNNING`. RAM: 36 bytes.
struct AsyncTx {
    buf: [u8; ASYNC_MAX],
    len: u8,
    /// Next byte of `buf` to send.
    pos: u8,
    /// SLA+W.
    sla: u8,
}

static mut ASYNC: AsyncTx = AsyncTx { buf: [0; ASYNC_MAX], len: 0, pos: 0, sla: 0 };
/// `IDLE`, `RUNNING` or `FAILED`.
static ASYNC_STATE: AtomicU8 = AtomicU8::new(IDLE);
const IDLE: u8 = 0;
const RUNNING: u8 = 1;
const FAILED: u8 = 2;

/// What went wrong on the bus. Small and `Copy`, like every board error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The addressed device (or a data byte) was not acknowledged.
    NoAcknowledge(NoAcknowledgeSource),
    /// Another master won arbitration; the bus was released.
    ArbitrationLoss,
    /// Illegal START/STOP seen on the bus, or an unexpected TWI status.
    Bus,
    /// TWINT or TWSTO did not change within the time budget (stuck bus,
    /// missing pull-ups, or a device holding SCL low). The TWI was reset.
    Timeout,
}

impl i2c::Error for Error {
    fn kind(&self) -> ErrorKind {
        match *self {
            Error::NoAcknowledge(source) => ErrorKind::NoAcknowledge(source),
            Error::ArbitrationLoss => ErrorKind::ArbitrationLoss,
            Error::Bus => ErrorKind::Bus,
            Error::Timeout => ErrorKind::Other,
        }
    }
}

/// Polled TWI master that owns the TWI peripheral.
pub struct Twi {
    /// The TWI register block.
    twi: TWI,
    /// Status polls allowed per bus event before [`Error::Timeout`].
    timeout_polls: u16,
}

impl Twi {
    /// Take the TWI, set SCL to `freq_hz` (rounded down to the nearest
    /// reachable rate; 400 kHz gives TWBR = 12, prescaler 1) and enable it.
    ///
    /// SCL = F_CPU / (16 + 2·TWBR·4^TWPS), datasheet §24 "Bit Rate Generator Unit".
    pub fn new(twi: TWI, freq_hz: u32) -> Twi {
        let (twbr, twps) = bit_rate(freq_hz);
        twi.twsr().write(|w| w.twps().set(twps));
        twi.twbr().write(|w| w.set(twbr));
        twi.twcr().write(|w| w.twen().set_bit());

        // One byte is 9 SCL periods; allow ten bytes or 1 ms, whichever is longer.
        let scl_cycles = 16 + 2 * u32::from(twbr) * (1u32 << (2 * twps));
        let budget = (scl_cycles * 9 * 10).max(MIN_TIMEOUT_CYCLES);
        let polls = (budget / MIN_CYCLES_PER_POLL).min(u32::from(u16::MAX));
        Twi { twi, timeout_polls: polls as u16 }
    }

    /// Start sending `bytes` (at most [`ASYNC_MAX`]) to `address` as one
    /// write transaction in the background; [`Twi::async_busy`] must be
    /// false. The `TWI` interrupt does the rest and ends with a STOP.
    pub fn write_async(&mut self, address: u8, bytes: &[u8]) -> Result<(), Error> {
        if self.async_busy() || address > 0x7F {
            return Err(Error::Bus);
        }
        let n = bytes.len().min(ASYNC_MAX);
        // SAFETY: not RUNNING, so the interrupt is off (TWIE clear) and
        // nothing else touches ASYNC until the state store below.
        unsafe {
            let a = &mut *addr_of_mut!(ASYNC);
            a.buf[..n].copy_from_slice(&bytes[..n]);
            a.len = n as u8;
            a.pos = 0;
            a.sla = address << 1;
        }
        ASYNC_STATE.store(RUNNING, Ordering::Release);
        self.twi.twcr().write(|w| w.twint().set_bit().twsta().set_bit().twen().set_bit().twie().set_bit());
        Ok(())
    }

    /// A background write, or the STOP that ends it, is still on the bus.
    pub fn async_busy(&self) -> bool {
        ASYNC_STATE.load(Ordering::Acquire) == RUNNING || self.twi.twcr().read().twsto().bit_is_set()
    }

    /// True once (then forgotten) when the last background write failed.
    pub fn take_async_failed(&mut self) -> bool {
        if ASYNC_STATE.load(Ordering::Acquire) == FAILED {
            ASYNC_STATE.store(IDLE, Ordering::Release);
            return true;
        }
        false
    }

    /// Give up a background write that takes too long (a stuck bus): the TWI
    /// is switched off and on, and the write counts as failed.
    pub fn abort_async(&mut self) {
        self.reset();
        ASYNC_STATE.store(FAILED, Ordering::Release);
    }

    /// Give the TWI peripheral back, disabled.
    pub fn release(self) -> TWI {
        self.twi.twcr().write(|w| w);
        self.twi
    }

    /// Wait until TWINT is set, then return the status (TWSR & 0xF8).
    fn wait_int(&mut self) -> Result<u8, Error> {
        let mut polls = self.timeout_polls;
        while self.twi.twcr().read().twint().bit_is_clear() {
            polls -= 1;
            if polls == 0 {
                self.reset();
                return Err(Error::Timeout);
            }
        }
        Ok(self.twi.twsr().read().bits() & 0xF8)
    }

    /// Send a START (or a repeated START, when the bus is ours already).
    fn start(&mut self) -> Result<(), Error> {
        self.twi.twcr().write(|w| w.twint().set_bit().twsta().set_bit().twen().set_bit());
        match self.wait_int()? {
            status::START | status::REP_START => Ok(()),
            other => Err(self.fail(other)),
        }
    }

    /// Send SLA+R or SLA+W and check that the device answered.
    fn address(&mut self, address: u8, read: bool) -> Result<(), Error> {
        let sla = (address << 1) | u8::from(read);
        self.twi.twdr().write(|w| w.set(sla));
        self.twi.twcr().write(|w| w.twint().set_bit().twen().set_bit());
        match (self.wait_int()?, read) {
            (status::MT_SLA_ACK, false) | (status::MR_SLA_ACK, true) => Ok(()),
            // Old simavr releases (Debian's 1.6) report an address NACK as
            // 0x30; the hardware never gives 0x30 here, so reading it as an
            // address NACK costs nothing.
            (status::MT_SLA_NACK | status::MT_DATA_NACK, false) | (status::MR_SLA_NACK, true) => {
                Err(self.fail_nack(NoAcknowledgeSource::Address))
            }
            (other, _) => Err(self.fail(other)),
        }
    }

    /// Transmit one data byte and check for ACK.
    fn write_byte(&mut self, byte: u8) -> Result<(), Error> {
        self.twi.twdr().write(|w| w.set(byte));
        self.twi.twcr().write(|w| w.twint().set_bit().twen().set_bit());
        match self.wait_int()? {
            status::MT_DATA_ACK => Ok(()),
            status::MT_DATA_NACK => Err(self.fail_nack(NoAcknowledgeSource::Data)),
            other => Err(self.fail(other)),
        }
    }

    /// Receive one data byte, answering ACK (more to come) or NACK (last byte).
    fn read_byte(&mut self, ack: bool) -> Result<u8, Error> {
        self.twi.twcr().write(|w| w.twint().set_bit().twea().bit(ack).twen().set_bit());
        match (self.wait_int()?, ack) {
            (status::MR_DATA_ACK, true) | (status::MR_DATA_NACK, false) => Ok(self.twi.twdr().read().bits()),
            (other, _) => Err(self.fail(other)),
        }
    }

    /// Send a STOP and wait (bounded) until the hardware has sent it.
    /// TWINT is not set after a STOP; TWSTO clears itself (§24 TWCR: TWSTO).
    fn stop(&mut self) -> Result<(), Error> {
        self.twi.twcr().write(|w| w.twint().set_bit().twsto().set_bit().twen().set_bit());
        let mut polls = self.timeout_polls;
        while self.twi.twcr().read().twsto().bit_is_set() {
            polls -= 1;
            if polls == 0 {
                self.reset();
                return Err(Error::Timeout);
            }
        }
        Ok(())
    }

    /// Release the bus after a NACK with a STOP, and report the NACK.
    fn fail_nack(&mut self, source: NoAcknowledgeSource) -> Error {
        match self.stop() {
            Ok(()) => Error::NoAcknowledge(source),
            Err(e) => e,
        }
    }

    /// Map an unexpected status to an error and leave the TWI usable.
    fn fail(&mut self, status: u8) -> Error {
        match status {
            status::ARB_LOST => {
                // Clearing TWINT without STA/STO releases the bus and enters
                // not-addressed slave mode (§24 Master Transmitter status table, 0x38).
                self.twi.twcr().write(|w| w.twint().set_bit().twen().set_bit());
                Error::ArbitrationLoss
            }
            status::BUS_ERROR => {
                // Recovery from a bus error: set TWSTO and clear TWINT; no STOP
                // is sent on the bus and TWSTO clears itself (§24 "Miscellaneous States").
                let _ = self.stop();
                Error::Bus
            }
            _ => {
                self.reset();
                Error::Bus
            }
        }
    }

    /// Switch the TWI off and on again: this ends any transmission and frees
    /// PD0/PD1 (§24 TWCR: TWEN). Used after a timeout or an unknown status.
    fn reset(&mut self) {
        self.twi.twcr().write(|w| w);
        self.twi.twcr().write(|w| w.twen().set_bit());
    }

    /// Run one group of adjacent operations of the same kind, after its
    /// (repeated) START and address. Reads ACK every byte except the group's
    /// last, as embedded-hal requires.
    fn run_group(&mut self, address: u8, group: &mut [Operation<'_>]) -> Result<(), Error> {
        let read = matches!(group.first(), Some(Operation::Read(_)));
        self.start()?;
        self.address(address, read)?;
        if !read {
            for op in group.iter() {
                if let Operation::Write(bytes) = op {
                    for &byte in bytes.iter() {
                        self.write_byte(byte)?;
                    }
                }
            }
            return Ok(());
        }
        let mut remaining: usize = group
            .iter()
            .map(|op| match op {
                Operation::Read(buf) => buf.len(),
                Operation::Write(_) => 0,
            })
            .sum();
        if remaining == 0 {
            // After SLA+R ACK the device drives the bus: read one byte, NACK it
            // and drop it so the device lets go (a zero-length read).
            self.read_byte(false)?;
            return Ok(());
        }
        for op in group.iter_mut() {
            if let Operation::Read(buf) = op {
                for byte in buf.iter_mut() {
                    remaining -= 1;
                    *byte = self.read_byte(remaining > 0)?;
                }
            }
        }
        Ok(())
    }
}

/// TWBR and TWPS for an SCL of at most `freq_hz`: the smallest prescaler whose
/// TWBR fits in a byte. Frequencies above 1 MHz give TWBR = 0 (F_CPU / 16).
fn bit_rate(freq_hz: u32) -> (u8, u8) {
    let freq_hz = freq_hz.max(1);
    // ceil so that the rate never exceeds freq_hz.
    let ratio = F_CPU_HZ.div_ceil(freq_hz).saturating_sub(16);
    for twps in 0..4u8 {
        let step = 2u32 << (2 * twps); // 2·4^TWPS
        let twbr = ratio.div_ceil(step);
        if twbr <= 255 {
            return (twbr as u8, twps);
        }
    }
    (255, 3)
}

/// Turn on the internal pull-ups on PD0 (SCL) and PD1 (SDA), touching only
/// those two PORTD bits, inside a critical section (PORTD is shared). Optional:
/// the Mega2560 and most SH1106 modules carry external pull-ups.
pub fn enable_internal_pullups(portd: &PORTD) {
    avr_device::interrupt::free(|_| {
        portd.portd().modify(|_, w| w.pd0().set_bit().pd1().set_bit());
    });
}

impl i2c::ErrorType for Twi {
    type Error = Error;
}

impl I2c<SevenBitAddress> for Twi {
    /// Run `operations` as one bus transaction (embedded-hal 1.0 contract):
    /// START, then a repeated START and address only where the direction
    /// changes, ACK on every read byte except the last of a read run, STOP.
    /// On any error the bus is released before returning.
    fn transaction(&mut self, address: SevenBitAddress, operations: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        if address > 0x7F {
            // No device can answer a 7-bit address above 0x7F.
            return Err(Error::NoAcknowledge(NoAcknowledgeSource::Address));
        }
        if operations.is_empty() {
            return Ok(());
        }
        // A background write must end first (bounded, like every wait here).
        let mut polls = self.timeout_polls;
        while self.async_busy() {
            polls -= 1;
            if polls == 0 {
                self.abort_async();
                break;
            }
        }
        let mut rest = operations;
        while !rest.is_empty() {
            let read = matches!(rest[0], Operation::Read(_));
            let len = rest.iter().position(|op| matches!(op, Operation::Read(_)) != read).unwrap_or(rest.len());
            let (group, tail) = rest.split_at_mut(len);
            self.run_group(address, group)?;
            rest = tail;
        }
        self.stop()
    }
}

// The background write's byte engine (§24.7.1, Master Transmitter status
// table): address after the START, then each byte on an ACK, then STOP.
// Anything else ends the write as failed. Each run is ~60 cycles; 35 per
// OLED slice (START, SLA+W, 33 bytes).
#[avr_device::interrupt(atmega2560)]
fn TWI() {
    // SAFETY: this interrupt runs only while a background write is RUNNING
    // (TWIE is set by `write_async` alone and cleared here at its end), and
    // the main loop leaves the TWI and ASYNC alone meanwhile.
    let (twi, a) = unsafe { (&*TWI::ptr(), &mut *addr_of_mut!(ASYNC)) };
    let st = twi.twsr().read().bits() & 0xF8;
    let next = match st {
        status::START => Some(a.sla),
        status::MT_SLA_ACK | status::MT_DATA_ACK if a.pos < a.len => {
            let b = a.buf.get(a.pos as usize).copied().unwrap_or(0);
            a.pos += 1;
            Some(b)
        }
        status::MT_SLA_ACK | status::MT_DATA_ACK => {
            twi.twcr().write(|w| w.twint().set_bit().twsto().set_bit().twen().set_bit());
            ASYNC_STATE.store(IDLE, Ordering::Release);
            None
        }
        status::ARB_LOST => {
            // Release the bus without a STOP (as in `Twi::fail`).
            twi.twcr().write(|w| w.twint().set_bit().twen().set_bit());
            ASYNC_STATE.store(FAILED, Ordering::Release);
            None
        }
        _ => {
            twi.twcr().write(|w| w.twint().set_bit().twsto().set_bit().twen().set_bit());
            ASYNC_STATE.store(FAILED, Ordering::Release);
            None
        }
    };
    if let Some(b) = next {
        twi.twdr().write(|w| w.set(b));
        twi.twcr().write(|w| w.twint().set_bit().twen().set_bit().twie().set_bit());
    }
}
