//! The chip's memories as tests see them: data space (registers, I/O,
//! SRAM), flash, the EEPROM, the ELF's symbols and the stack's high-water
//! mark.

use super::simavr::ioctl_def;
use super::Vm;
use crate::elf::ElfSymbols;
use simavr_ffi as ffi;
use std::ffi::c_void;

const IOCTL_EEPROM_GET: u32 = ioctl_def(b'e', b'e', b'g', b'p');
const IOCTL_EEPROM_SET: u32 = ioctl_def(b'e', b'e', b's', b'p');
/// EEPROM size of the ATmega2560, bytes.
pub const EEPROM_SIZE: usize = 4096;
/// Last SRAM address of the ATmega2560.
pub const RAMEND: u16 = 0x21FF;
/// Byte the firmware paints free RAM with at boot.
pub const STACK_PAINT: u8 = 0xC5;

impl Vm {
    /// Program memory: `len` bytes from byte address `addr` (clipped to
    /// the chip's 256 KiB).
    pub fn read_flash(&self, addr: u32, len: usize) -> Vec<u8> {
        // SAFETY: avr is live; flash has flashend + 1 bytes.
        unsafe {
            let end = ((*self.avr).flashend as usize + 1).min(addr as usize + len);
            let start = (addr as usize).min(end);
            std::slice::from_raw_parts((*self.avr).flash.add(start), end - start).to_vec()
        }
    }

    /// Reads `len` bytes of data space (registers, I/O, SRAM) from `addr`.
    pub fn read_ram(&self, addr: u16, len: usize) -> Vec<u8> {
        let end = (addr as usize + len).min(RAMEND as usize + 1);
        (addr as usize..end).map(|a| self.inner().read(a as u16)).collect()
    }

    /// One byte of data space.
    pub fn read_u8(&self, addr: u16) -> u8 {
        self.inner().read(addr)
    }

    /// Little-endian u16 of data space.
    pub fn read_u16(&self, addr: u16) -> u16 {
        u16::from_le_bytes([self.read_u8(addr), self.read_u8(addr + 1)])
    }

    /// Little-endian u32 of data space.
    pub fn read_u32(&self, addr: u16) -> u32 {
        let b = self.read_ram(addr, 4);
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// Little-endian i32 of data space.
    pub fn read_i32(&self, addr: u16) -> i32 {
        self.read_u32(addr) as i32
    }

    /// Writes bytes into data space (no I/O side effects are triggered).
    pub fn write_ram(&mut self, addr: u16, bytes: &[u8]) {
        let data = self.inner().data();
        for (i, b) in bytes.iter().enumerate() {
            let a = addr as usize + i;
            if a <= RAMEND as usize {
                // SAFETY: a is within the data array.
                unsafe { *data.add(a) = *b };
            }
        }
    }

    /// Bytes of a RAM symbol (its ELF size), if it exists.
    pub fn read_symbol(&self, name: &str) -> Option<Vec<u8>> {
        let s = self.symbols.get(name)?;
        Some(self.read_ram(s.addr as u16, s.size as usize))
    }

    /// The whole EEPROM (4096 bytes).
    pub fn eeprom(&self) -> Vec<u8> {
        let mut buf = vec![0u8; EEPROM_SIZE];
        let mut d = ffi::avr_eeprom_desc_t { ee: buf.as_mut_ptr(), offset: 0, size: EEPROM_SIZE as u32 };
        // SAFETY: buf has `size` bytes; the ioctl copies into it.
        unsafe { ffi::avr_ioctl(self.avr, IOCTL_EEPROM_GET, &mut d as *mut _ as *mut c_void) };
        buf
    }

    /// Overwrites the EEPROM from offset 0 (at most 4096 bytes).
    pub fn set_eeprom(&mut self, bytes: &[u8]) {
        self.set_eeprom_at(0, bytes);
    }

    /// Overwrites part of the EEPROM.
    pub fn set_eeprom_at(&mut self, offset: u16, bytes: &[u8]) {
        let n = bytes.len().min(EEPROM_SIZE.saturating_sub(offset as usize));
        if n == 0 {
            return;
        }
        let mut copy = bytes[..n].to_vec();
        let mut d = ffi::avr_eeprom_desc_t { ee: copy.as_mut_ptr(), offset, size: n as u32 };
        // SAFETY: `copy` has `size` bytes; the ioctl copies out of it.
        unsafe { ffi::avr_ioctl(self.avr, IOCTL_EEPROM_SET, &mut d as *mut _ as *mut c_void) };
    }

    /// The ELF's symbols.
    pub fn symbols(&self) -> &ElfSymbols {
        &self.symbols
    }

    /// Address of a symbol: data-space address for RAM symbols, flash byte
    /// address for code (e.g. `symbol_addr("__heap_start")`).
    pub fn symbol_addr(&self, name: &str) -> Option<u32> {
        self.symbols.addr(name)
    }

    /// Stack high-water mark, bytes: from RAMEND down to the lowest byte above
    /// `__heap_start` (or `__bss_end`) that no longer holds the boot paint
    /// 0xC5. `None` without the symbol or if RAM was not painted.
    pub fn stack_high_water_bytes(&self) -> Option<u32> {
        let start = self.symbol_addr("__heap_start").or_else(|| self.symbol_addr("__bss_end"))? as u16;
        if start > RAMEND || self.read_u8(start) != STACK_PAINT {
            return None;
        }
        let mut a = start;
        while a <= RAMEND && self.read_u8(a) == STACK_PAINT {
            a += 1;
        }
        Some((RAMEND as u32 + 1) - a as u32)
    }
}
