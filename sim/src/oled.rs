//! The SH1106 128x64 OLED controller as an I2C slave (SH1106 datasheet
//! V2.3: "Commands", "I2C-bus interface").
//!
//! The VM feeds it the TWI traffic addressed to it ([`Sh1106::start`],
//! [`Sh1106::write`], [`Sh1106::stop`]). It keeps the 132x64 display RAM
//! (8 pages of 132 column bytes, bit 0 = top row of a page), the column and
//! page address counters and the commands that change what is seen, and
//! renders what a 1.3" module (128 visible columns at RAM columns 2..129)
//! shows as a picture ([`Sh1106::pixels`], [`Sh1106::write_png`]).
//!
//! A control byte precedes commands or data: bit 7 (Co) = one more control
//! byte follows after the next byte, bit 6 (D/C#) = the next bytes are data.
//! Also counted for tests: data bytes written per page and the time of the
//! last write to each page (to measure refresh rates).

use std::path::Path;

/// Display RAM columns of the SH1106.
pub const RAM_COLUMNS: usize = 132;
/// Visible columns and rows of the panel.
pub const WIDTH: usize = 128;
pub const HEIGHT: usize = 64;
/// First RAM column shown on a 128-column panel.
pub const COLUMN_OFFSET: usize = 2;

/// The 7-bit I2C address (SA0 low).
pub const I2C_ADDRESS: u8 = 0x3C;

/// The controller model.
#[derive(Clone)]
pub struct Sh1106 {
    ram: [[u8; RAM_COLUMNS]; 8],
    column: usize,
    page: usize,
    /// After a control byte: true = data, false = command.
    data_mode: bool,
    /// A control byte with Co = 1 was seen: only one byte follows, then
    /// another control byte.
    single: bool,
    /// Expecting a control byte next.
    want_control: bool,
    /// A two-byte command waiting for its argument.
    pending: Option<u8>,
    pub display_on: bool,
    pub inverted: bool,
    pub segment_remap: bool,
    pub com_reverse: bool,
    pub start_line: u8,
    pub contrast: u8,
    pub charge_pump: bool,
    /// Data bytes written per page since power-on.
    pub page_writes: [u64; 8],
    /// VM cycle of the last data byte written into each page.
    pub page_written_at: [Option<u64>; 8],
    /// Every data write: (cycle, page, column).
    pub write_log: Vec<(u64, u8, u8)>,
    pub commands: u64,
    keep_log: bool,
}

impl Default for Sh1106 {
    fn default() -> Self {
        Sh1106::new()
    }
}

impl Sh1106 {
    /// Power-on state: display off, RAM contents zero.
    pub fn new() -> Sh1106 {
        Sh1106 {
            ram: [[0; RAM_COLUMNS]; 8],
            column: 0,
            page: 0,
            data_mode: false,
            single: false,
            want_control: true,
            pending: None,
            display_on: false,
            inverted: false,
            segment_remap: false,
            com_reverse: false,
            start_line: 0,
            contrast: 0x80,
            charge_pump: true,
            page_writes: [0; 8],
            page_written_at: [None; 8],
            write_log: Vec::new(),
            commands: 0,
            keep_log: false,
        }
    }

    /// Keep a log of every data write (off by default: a job writes many).
    pub fn set_write_log(&mut self, on: bool) {
        self.keep_log = on;
    }

    /// START addressed to us: a control byte comes first.
    pub fn start(&mut self) {
        self.want_control = true;
        self.single = false;
    }

    /// STOP.
    pub fn stop(&mut self) {
        self.want_control = true;
    }

    /// One byte written by the master, at VM cycle `cycle`.
    pub fn write(&mut self, byte: u8, cycle: u64) {
        if self.want_control {
            self.data_mode = byte & 0x40 != 0;
            self.single = byte & 0x80 != 0;
            self.want_control = false;
            return;
        }
        if self.data_mode {
            self.data(byte, cycle);
        } else {
            self.command(byte);
        }
        if self.single {
            self.want_control = true;
        }
    }

    fn data(&mut self, byte: u8, cycle: u64) {
        if self.column < RAM_COLUMNS {
            self.ram[self.page][self.column] = byte;
            self.page_writes[self.page] += 1;
            self.page_written_at[self.page] = Some(cycle);
            if self.keep_log {
                self.write_log.push((cycle, self.page as u8, self.column as u8));
            }
            self.column += 1; // stops at the last column (no wrap on the SH1106)
        }
    }

    fn command(&mut self, b: u8) {
        self.commands += 1;
        if let Some(cmd) = self.pending.take() {
            match cmd {
                0x81 => self.contrast = b,
                0xAD => self.charge_pump = b & 1 != 0,
                _ => {} // 0xA8 mux, 0xD3 offset, 0xD5 clock, 0xD9 precharge, 0xDA pins, 0xDB vcom
            }
            return;
        }
        match b {
            0x00..=0x0F => self.column = (self.column & 0xF0) | b as usize,
            0x10..=0x1F => self.column = (self.column & 0x0F) | ((b as usize & 0x0F) << 4),
            0x40..=0x7F => self.start_line = b - 0x40,
            0x81 | 0xA8 | 0xAD | 0xD3 | 0xD5 | 0xD9 | 0xDA | 0xDB => self.pending = Some(b),
            0xA0 => self.segment_remap = false,
            0xA1 => self.segment_remap = true,
            0xA6 => self.inverted = false,
            0xA7 => self.inverted = true,
            0xAE => self.display_on = false,
            0xAF => self.display_on = true,
            0xB0..=0xB7 => self.page = (b - 0xB0) as usize,
            0xC0..=0xC7 => self.com_reverse = false,
            0xC8..=0xCF => self.com_reverse = true,
            _ => {} // 0xA4/A5 entire display on, 0x30-0x33 pump voltage, 0xE0/EE/E3 ...
        }
    }

    /// The display RAM, page by page.
    pub fn ram(&self) -> &[[u8; RAM_COLUMNS]; 8] {
        &self.ram
    }

    /// What the panel shows, row-major, `true` = lit. A module is mounted so
    /// that the firmware's A1 (segment remap) and C8 (COM reverse) give an
    /// upright picture; other settings mirror it as the real panel would.
    /// A display that is off shows nothing.
    pub fn pixels(&self) -> Vec<bool> {
        let mut px = vec![false; WIDTH * HEIGHT];
        if !self.display_on {
            return px;
        }
        for y in 0..HEIGHT {
            let row = if self.com_reverse { y } else { HEIGHT - 1 - y };
            let line = (row + self.start_line as usize) % HEIGHT;
            for x in 0..WIDTH {
                let col = if self.segment_remap { x + COLUMN_OFFSET } else { RAM_COLUMNS - 1 - COLUMN_OFFSET - x };
                let on = self.ram[line / 8][col] >> (line % 8) & 1 != 0;
                px[y * WIDTH + x] = on != self.inverted;
            }
        }
        px
    }

    /// The panel as text: `#` lit, `.` dark, one line per row (for test output).
    pub fn ascii(&self) -> String {
        let px = self.pixels();
        let mut s = String::with_capacity((WIDTH + 1) * HEIGHT);
        for y in 0..HEIGHT {
            for x in 0..WIDTH {
                s.push(if px[y * WIDTH + x] { '#' } else { '.' });
            }
            s.push('\n');
        }
        s
    }

    /// Write what the panel shows as a grayscale PNG, each pixel `scale` x
    /// `scale` (lit = white on black, like the blue/white modules' glass).
    pub fn write_png(&self, path: impl AsRef<Path>, scale: usize) -> std::io::Result<()> {
        write_png(path, &self.pixels(), scale)
    }
}

/// Write a 128x64 picture (row-major, `true` = lit) as a grayscale PNG.
pub fn write_png(path: impl AsRef<Path>, px: &[bool], scale: usize) -> std::io::Result<()> {
    let scale = scale.max(1);
    let (w, h) = (WIDTH * scale, HEIGHT * scale);
    let mut data = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            if px[(y / scale) * WIDTH + x / scale] {
                data[y * w + x] = 0xFF;
            }
        }
    }
    if let Some(dir) = path.as_ref().parent() {
        std::fs::create_dir_all(dir)?;
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut enc = png::Encoder::new(file, w as u32, h as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(std::io::Error::other)?;
    writer.write_image_data(&data).map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)?;
    Ok(())
}

/// Read a PNG written by [`write_png`] back into 128x64 pixels (the top-left
/// pixel of each `scale` block; lit = brighter than mid-gray).
pub fn read_png(path: impl AsRef<Path>) -> std::io::Result<Vec<bool>> {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path)?));
    let mut reader = dec.read_info().map_err(std::io::Error::other)?;
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap_or(0)];
    let info = reader.next_frame(&mut buf).map_err(std::io::Error::other)?;
    let (w, h) = (info.width as usize, info.height as usize);
    if w % WIDTH != 0 || h % HEIGHT != 0 || w / WIDTH != h / HEIGHT {
        return Err(std::io::Error::other(format!("picture is {w}x{h}, not a multiple of 128x64")));
    }
    let scale = w / WIDTH;
    let bpp = info.line_size / w;
    let mut px = vec![false; WIDTH * HEIGHT];
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let at = (y * scale) * info.line_size + (x * scale) * bpp;
            px[y * WIDTH + x] = buf[at] >= 0x80;
        }
    }
    Ok(px)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn init(o: &mut Sh1106) {
        o.start();
        for b in [0x00, 0xAE, 0xA1, 0xC8, 0x81, 0x7F, 0x40, 0xAF] {
            o.write(b, 0);
        }
        o.stop();
    }

    #[test]
    fn data_lands_at_the_addressed_page_and_column() {
        let mut o = Sh1106::new();
        init(&mut o);
        assert!(o.display_on && o.segment_remap && o.com_reverse);
        assert_eq!(o.contrast, 0x7F);
        // Page 3, column 2 (the first visible one), then two data bytes.
        o.start();
        for b in [0x00, 0xB3, 0x02, 0x10] {
            o.write(b, 1);
        }
        o.stop();
        o.start();
        for b in [0x40, 0x01, 0x80] {
            o.write(b, 2);
        }
        o.stop();
        let px = o.pixels();
        assert!(px[24 * WIDTH]); // page 3 bit 0 = row 24, x 0
        assert!(px[31 * WIDTH + 1]); // bit 7 = row 31, x 1
        assert_eq!(px.iter().filter(|&&p| p).count(), 2);
        assert_eq!(o.page_writes[3], 2);
        assert_eq!(o.page_written_at[3], Some(2));
    }

    #[test]
    fn co_bit_alternates_control_and_command_bytes() {
        let mut o = Sh1106::new();
        o.start();
        for b in [0x80, 0xAF, 0x80, 0xB5, 0x40, 0xFF] {
            o.write(b, 0);
        }
        assert!(o.display_on);
        assert_eq!(o.ram()[5][0], 0xFF);
    }

    #[test]
    fn png_round_trip() {
        let mut o = Sh1106::new();
        init(&mut o);
        o.start();
        for b in [0x00, 0xB0, 0x02, 0x10] {
            o.write(b, 0);
        }
        o.start();
        o.write(0x40, 0);
        for i in 0..128u32 {
            o.write((i * 37) as u8, 0);
        }
        let dir = std::env::temp_dir().join(format!("sh1106-{}", std::process::id()));
        let path = dir.join("t.png");
        o.write_png(&path, 2).unwrap();
        assert_eq!(read_png(&path).unwrap(), o.pixels());
        let _ = std::fs::remove_dir_all(dir);
    }
}
