//! The stock Arduino Mega2560 bootloader in the virtual machine: where the
//! board as sold keeps it, the fuses it is sold with, and the Intel hex
//! reader that loads it (and that reads back images for `tools/flash`).
//!
//! The bootloader is the STK500v2 one (`stk500boot_v2_mega2560.hex`) that
//! every Mega2560 ships with. It is GPL-2 and not part of this repository:
//! it is read from where Debian's `arduino-core-avr` package installs it
//! (`tools/setup` installs the package), or from `$MILL_BOOTLOADER`.
//!
//! A stock board (ATmega2560 datasheet §28 "Boot Loader Support", fuse
//! tables §29.2): high fuse 0xD8, so BOOTSZ = 00 (a 4096-word boot
//! section at byte 0x3E000) and BOOTRST programmed (the chip starts there
//! after every reset); low fuse 0xFF (external crystal), extended 0xFD
//! (brown-out at 2.7 V); lock byte 0xCF (the boot section cannot be written
//! by SPM, the application section can).

use std::path::{Path, PathBuf};

/// Where Debian's `arduino-core-avr` installs the Mega2560 bootloader.
pub const DEBIAN_HEX: &str = "/usr/share/arduino/hardware/arduino/avr/bootloaders/stk500v2/stk500boot_v2_mega2560.hex";
/// First byte of the boot section (BOOTSZ = 00): the application gets the
/// 253,952 bytes below it.
pub const BOOT_START: u32 = 0x3E000;
/// Fuses of a board as sold: low, high, extended.
pub const STOCK_FUSES: [u8; 3] = [0xFF, 0xD8, 0xFD];
/// Lock byte of a board as sold.
pub const STOCK_LOCK: u8 = 0xCF;
/// Start-up delay after every reset with the stock fuses (low fuse 0xFF:
/// full-swing crystal, SUT = 11): 16K clock cycles plus 65 ms (datasheet
/// §10.4, "Start-up Times"). The chip is held in reset meanwhile: bytes on
/// its RX pin are lost.
pub const STOCK_STARTUP_S: f64 = 0.065 + 16_384.0 / 16_000_000.0;
/// Where the stock bootloader starts the application after a watchdog reset
/// (it calls address 0 with `eicall` and EIND = 1: byte 0x20000).
pub const WATCHDOG_ENTRY: u32 = 0x20000;

/// The bootloader hex: `$MILL_BOOTLOADER` if set, else Debian's.
pub fn default_hex_path() -> PathBuf {
    std::env::var_os("MILL_BOOTLOADER").map(PathBuf::from).unwrap_or_else(|| PathBuf::from(DEBIAN_HEX))
}

/// One contiguous run of bytes of an Intel hex file at a flash byte address.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chunk {
    pub addr: u32,
    pub bytes: Vec<u8>,
}

/// Reads an Intel hex file (record types 00 data, 01 end, 02 segment and 04
/// linear address; 03 and 05 start addresses are ignored) into chunks, each
/// data record merged with the one before when they are contiguous.
pub fn read_ihex(path: &Path) -> Result<Vec<Chunk>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse_ihex(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// [`read_ihex`] on the text of the file.
pub fn parse_ihex(text: &str) -> Result<Vec<Chunk>, String> {
    let mut chunks: Vec<Chunk> = Vec::new();
    let mut base = 0u32;
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let bad = |what: &str| format!("line {}: {what}", n + 1);
        let hex = line.strip_prefix(':').ok_or_else(|| bad("no ':'"))?;
        if hex.len() < 10 || hex.len() % 2 != 0 {
            return Err(bad("bad length"));
        }
        let bytes: Vec<u8> = (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16))
            .collect::<Result<_, _>>()
            .map_err(|_| bad("not hex"))?;
        if bytes.iter().fold(0u8, |s, &b| s.wrapping_add(b)) != 0 {
            return Err(bad("checksum"));
        }
        let len = bytes[0] as usize;
        if bytes.len() != len + 5 {
            return Err(bad("count does not match"));
        }
        let offset = u16::from_be_bytes([bytes[1], bytes[2]]) as u32;
        let data = &bytes[4..4 + len];
        match bytes[3] {
            0x00 => {
                let addr = base + offset;
                match chunks.last_mut() {
                    Some(c) if c.addr + c.bytes.len() as u32 == addr => c.bytes.extend_from_slice(data),
                    _ => chunks.push(Chunk { addr, bytes: data.to_vec() }),
                }
            }
            0x01 => break,
            0x02 if len == 2 => base = (u16::from_be_bytes([data[0], data[1]]) as u32) << 4,
            0x04 if len == 2 => base = (u16::from_be_bytes([data[0], data[1]]) as u32) << 16,
            0x03 | 0x05 => {}
            t => return Err(bad(&format!("record type {t:02x}"))),
        }
    }
    Ok(chunks)
}

/// Writes `bytes` at byte address `addr` as an Intel hex file (16 bytes per
/// record, an extended linear address record at each 64 KiB boundary).
pub fn write_ihex(path: &Path, addr: u32, bytes: &[u8]) -> std::io::Result<()> {
    use std::fmt::Write;
    let mut out = String::new();
    let mut record = |kind: u8, offset: u16, data: &[u8]| {
        let mut sum = (data.len() as u8).wrapping_add((offset >> 8) as u8).wrapping_add(offset as u8).wrapping_add(kind);
        let _ = write!(out, ":{:02X}{:04X}{:02X}", data.len(), offset, kind);
        for &b in data {
            sum = sum.wrapping_add(b);
            let _ = write!(out, "{b:02X}");
        }
        let _ = writeln!(out, "{:02X}", sum.wrapping_neg());
    };
    let mut upper = None;
    for (i, chunk) in bytes.chunks(16).enumerate() {
        let a = addr + (i * 16) as u32;
        if upper != Some(a >> 16) {
            upper = Some(a >> 16);
            record(0x04, 0, &((a >> 16) as u16).to_be_bytes());
        }
        record(0x00, a as u16, chunk);
    }
    record(0x01, 0, &[]);
    std::fs::write(path, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extended_linear_records_place_the_bootloader_at_0x3e000() {
        let text = ":020000023000CC\n:10E000000D9489F10D94B2F10D94B2F10D94B2F129\n:00000001FF\n";
        let c = parse_ihex(text).unwrap();
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].addr, 0x3E000);
        assert_eq!(&c[0].bytes[..4], &[0x0D, 0x94, 0x89, 0xF1]);
    }

    #[test]
    fn a_written_image_reads_back_the_same() {
        let dir = std::env::temp_dir().join(format!("ihex-{}", std::process::id()));
        let bytes: Vec<u8> = (0..70_000u32).map(|i| (i * 7 + i / 256) as u8).collect();
        write_ihex(&dir, 0xFFF0, &bytes).unwrap();
        let c = read_ihex(&dir).unwrap();
        let _ = std::fs::remove_file(&dir);
        assert_eq!(c, vec![Chunk { addr: 0xFFF0, bytes }]);
    }

    #[test]
    fn a_bad_checksum_is_refused() {
        assert!(parse_ihex(":10E000000D9489F10D94B2F10D94B2F10D94B2F128\n").is_err());
    }
}
