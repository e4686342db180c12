//! grbl's stored texts: the two startup blocks (`$N0=`, `$N1=`), run at
//! boot and after a soft reset, and the build-info text (`$I=`), each in
//! EEPROM as a length byte, the text and an XOR check byte.
//!
//! Startup blocks run as grbl runs them: each line is echoed as
//! `><line>:ok` or `><line>:error:<n>` (Marlin replies: `:Error:<text>`),
//! and not at all while an alarm is in force (no stored move may run into
//! an unknown position).

use super::{Io, Machine, Storage};
use crate::gcode::interp::Error;
use ufmt::{uwrite, uwriteln};

/// EEPROM address of startup block 0; block 1 follows at +[`SLOT`].
pub const EEPROM_STARTUP_ADDR: u16 = 1024;
/// EEPROM address of the `$I=` text.
pub const EEPROM_INFO_ADDR: u16 = EEPROM_STARTUP_ADDR + 2 * SLOT as u16;
/// Longest startup block, characters (grbl's line buffer holds 80 with its
/// end).
pub const STARTUP_LEN: usize = 78;
/// Longest `$I=` text, characters.
pub const INFO_LEN: usize = 40;
/// Bytes of one stored text: length, text, check byte.
const SLOT: usize = STARTUP_LEN + 2;
const _: () = assert!(EEPROM_STARTUP_ADDR >= crate::atc::tools::EEPROM_SETTER_ADDR + 64);
const _: () = assert!(EEPROM_INFO_ADDR as usize + INFO_LEN + 2 <= 4096);

fn check(text: &[u8]) -> u8 {
    text.iter().fold(0x5A, |a, &b| a ^ b)
}

/// Read the text stored at `addr` (at most `max` characters) into `buf`;
/// its length, 0 for an empty, erased or damaged slot.
fn load(io: &mut impl Storage, addr: u16, max: usize, buf: &mut [u8; SLOT]) -> usize {
    io.eeprom_read(addr, &mut buf[..max + 2]);
    let n = buf[0] as usize;
    if n == 0 || n > max || check(&buf[1..1 + n]) != buf[1 + n] {
        return 0;
    }
    buf.copy_within(1..1 + n, 0);
    n
}

/// Store `text` at `addr` (the caller checked its length).
fn store(io: &mut impl Storage, addr: u16, text: &[u8]) {
    let mut buf = [0u8; SLOT];
    let n = text.len().min(SLOT - 2);
    buf[0] = n as u8;
    buf[1..1 + n].copy_from_slice(&text[..n]);
    buf[1 + n] = check(&text[..n]);
    io.eeprom_write(addr, &buf[..n + 2]);
}

/// `text` is printable ASCII (a stored text is printed back verbatim).
fn printable(text: &[u8]) -> bool {
    text.iter().all(|b| (0x20..0x7F).contains(b))
}

/// `$N`: both startup blocks, as grbl prints them.
pub fn list(io: &mut (impl Storage + ufmt::uWrite)) {
    let mut buf = [0u8; SLOT];
    for i in 0..2u8 {
        let n = load(io, EEPROM_STARTUP_ADDR + i as u16 * SLOT as u16, STARTUP_LEN, &mut buf);
        let text = crate::protocol::ascii_str(&buf[..n]);
        uwriteln!(io, "$N{}={}", i, text).ok();
    }
}

/// `$N<i>=<line>`: check the line (it must parse, and may not be a `$`
/// line) and store it; an empty line clears the block.
pub fn set(io: &mut impl Storage, i: u8, line: &[u8]) -> Result<(), Error> {
    if i > 1 {
        return Err(Error::BadWord(F!("$N: blocks are $N0 and $N1")));
    }
    if line.len() > STARTUP_LEN || !printable(line) || line.first() == Some(&b'$') {
        return Err(Error::BadWord(F!("$N: a G-code line of at most 78 characters")));
    }
    if !line.is_empty() {
        let mut l = crate::gcode::Line::default();
        crate::gcode::parse_into(line, &mut l).map_err(Error::Parse)?;
    }
    store(io, EEPROM_STARTUP_ADDR + i as u16 * SLOT as u16, line);
    Ok(())
}

/// Clear both startup blocks and the info text (`$RST=*`).
pub fn clear(io: &mut impl Storage) {
    for i in 0..2u16 {
        store(io, EEPROM_STARTUP_ADDR + i * SLOT as u16, b"");
    }
    store(io, EEPROM_INFO_ADDR, b"");
}

/// Run the stored startup blocks (boot, soft reset); none in an alarm.
pub fn run(m: &mut Machine, io: &mut impl Io) {
    if m.alarm.is_some() {
        return;
    }
    let mut buf = [0u8; SLOT];
    for i in 0..2u16 {
        let n = load(io, EEPROM_STARTUP_ADDR + i * SLOT as u16, STARTUP_LEN, &mut buf);
        if n == 0 {
            continue;
        }
        let line = &buf[..n];
        uwrite!(io, ">{}:", crate::protocol::ascii_str(line)).ok();
        match m.run_menu_line(line, io) {
            Ok(()) => {
                uwriteln!(io, "ok").ok();
            }
            Err(e) if m.grbl_replies => {
                uwriteln!(io, "{}{}", F!("error:"), e.grbl_code()).ok();
            }
            Err(e) => m.report_error(io, e),
        }
    }
}

/// `$I=<text>`: store the build-info text.
pub fn set_info(io: &mut impl Storage, text: &[u8]) -> Result<(), Error> {
    if text.len() > INFO_LEN || !printable(text) {
        return Err(Error::BadWord(F!("$I=: at most 40 printable characters")));
    }
    store(io, EEPROM_INFO_ADDR, text);
    Ok(())
}

/// `$I`: grbl's build-info lines, with the stored text.
pub fn info(io: &mut (impl Storage + ufmt::uWrite)) {
    let mut buf = [0u8; SLOT];
    let n = load(io, EEPROM_INFO_ADDR, INFO_LEN, &mut buf);
    crate::dollar::info(io, crate::protocol::ascii_str(&buf[..n]));
}
