//! SH1106 128x64 OLED over I2C (0x3C, 400 kHz; docs/SPEC.md §2, §9): its command
//! set and page writes, on the [`super::twi::Twi`] master through the
//! embedded-hal 1.0 `I2c` trait.
//!
//! A driver of our own rather than the `sh1106` crate: that crate is on
//! embedded-hal 0.2 (it would need an adapter) and its graphics mode keeps a
//! 1 KiB frame buffer, an eighth of the chip's RAM. The UI renders text a
//! 32-column slice at a time (`mill::ui::render`), so all this driver needs
//! is "write these bytes at page p, column x" plus the power-up sequence
//! (SH1106 datasheet V2.3, "Commands" 1–23).
//!
//! [`Sh1106::write`] is blocking (about 0.8 ms for a 32-byte slice at
//! 400 kHz); [`Sh1106::write_async`] sends the same bytes with the data in
//! the background. Errors (no display on the bus) are returned, never
//! retried: the machine runs the same without a display.

use embedded_hal::i2c::I2c;

/// 7-bit I2C address (SA0 low).
pub const ADDRESS: u8 = 0x3C;
/// SCL frequency, Hz.
pub const I2C_HZ: u32 = 400_000;
/// The 128 visible columns start at RAM column 2 of the SH1106's 132.
const COLUMN_OFFSET: u8 = 2;

/// Control byte: the rest of the transfer is commands.
const CONTROL_COMMANDS: u8 = 0x00;
/// Control byte: the rest of the transfer is display data.
const CONTROL_DATA: u8 = 0x40;

/// Power-up sequence (each command with its argument, if it has one), in flash.
#[link_section = ".progmem.data"]
static INIT: [u8; 24] = [
    CONTROL_COMMANDS,
    0xAE, // display off
    0xD5,
    0x80, // clock divide / oscillator
    0xA8,
    0x3F, // multiplex ratio 64
    0xD3,
    0x00, // display offset 0
    0x40, // start line 0
    0xAD,
    0x8B, // DC-DC (charge pump) on
    0xA1, // segment remap: column 131 is SEG0 (module mounted upright)
    0xC8, // COM scan from COM63 to COM0
    0xDA,
    0x12, // COM pins: alternative
    0x81,
    0x80, // contrast
    0xD9,
    0x22, // pre-charge / dis-charge
    0xDB,
    0x35, // VCOM deselect level
    0xA4, // show RAM contents
    0xA6, // normal (not inverted)
    0xAF, // display on
];

/// The display on an I2C bus.
pub struct Sh1106<I> {
    i2c: I,
}

impl<I: I2c> Sh1106<I> {
    /// Take the bus; call [`Sh1106::init`] before writing.
    pub fn new(i2c: I) -> Self {
        Sh1106 { i2c }
    }

    /// Send the power-up sequence. The RAM keeps whatever it held until
    /// the first frame is drawn.
    pub fn init(&mut self) -> Result<(), I::Error> {
        let mut buf = [0u8; 24];
        for (b, init) in buf.iter_mut().zip(INIT.iter()) {
            *b = mill::ui::flash::read_byte(init);
        }
        self.i2c.write(ADDRESS, &buf)
    }

    /// Write `data` to `page` (0..8) from visible column `x` on.
    /// At most 32 bytes per call (one UI slice).
    pub fn write(&mut self, page: u8, x: u8, data: &[u8]) -> Result<(), I::Error> {
        self.set_position(page, x)?;
        let (buf, n) = data_frame(data);
        self.i2c.write(ADDRESS, &buf[..=n])
    }

    /// Point the controller at `page` (0..8), visible column `x`.
    fn set_position(&mut self, page: u8, x: u8) -> Result<(), I::Error> {
        let col = x + COLUMN_OFFSET;
        let cmds = [CONTROL_COMMANDS, 0xB0 | (page & 7), col & 0x0F, 0x10 | (col >> 4)];
        self.i2c.write(ADDRESS, &cmds)
    }
}

/// The data transfer of one slice: the data control byte and up to 32
/// bytes; returns the frame and its data length.
fn data_frame(data: &[u8]) -> ([u8; 33], usize) {
    let mut buf = [0u8; 33];
    let n = data.len().min(32);
    buf[0] = CONTROL_DATA;
    buf[1..=n].copy_from_slice(&data[..n]);
    (buf, n)
}

impl Sh1106<super::twi::Twi> {
    /// [`Sh1106::write`], with the data (33 bytes, ~0.75 ms at 400 kHz)
    /// sent in the background by the TWI interrupt; only the position
    /// commands (~0.1 ms) block. Call when [`Sh1106::busy`] is false; a
    /// failure of the background part shows in [`Sh1106::take_failed`].
    pub fn write_async(&mut self, page: u8, x: u8, data: &[u8]) -> Result<(), super::twi::Error> {
        self.set_position(page, x)?;
        let (buf, n) = data_frame(data);
        self.i2c.write_async(ADDRESS, &buf[..=n])
    }

    /// [`Sh1106::write_async`] of the slice that follows the last one on
    /// its page: no position commands, as the controller's column address
    /// has moved past the last byte written. Only when that write went out
    /// whole (nothing failed or was aborted since).
    pub fn write_next_async(&mut self, data: &[u8]) -> Result<(), super::twi::Error> {
        let (buf, n) = data_frame(data);
        self.i2c.write_async(ADDRESS, &buf[..=n])
    }

    /// A background write is still on the bus.
    pub fn busy(&self) -> bool {
        self.i2c.async_busy()
    }

    /// True once when the last background write failed.
    pub fn take_failed(&mut self) -> bool {
        self.i2c.take_async_failed()
    }

    /// Give up a background write that is taking too long.
    pub fn abort(&mut self) {
        self.i2c.abort_async()
    }
}
