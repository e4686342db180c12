//! Symbols of the firmware ELF (read with the `object` crate).
//!
//! avr-gcc/rustc place RAM in a fake address space at 0x800000 and EEPROM at
//! 0x810000 (sim_elf.h `AVR_SEGMENT_OFFSET_*`). [`ElfSymbols::addr`] strips
//! those offsets, so a RAM symbol comes back as its data-space address (what
//! [`crate::Vm::read_ram`] takes) and a code symbol as its flash byte address.

use object::{Object, ObjectSymbol};
use std::collections::HashMap;
use std::path::Path;

/// Start of the data (RAM) segment in AVR ELF files.
pub const DATA_OFFSET: u64 = 0x80_0000;
/// Start of the EEPROM segment in AVR ELF files.
pub const EEPROM_OFFSET: u64 = 0x81_0000;

/// Where a symbol lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    Flash,
    Ram,
    Eeprom,
}

/// One ELF symbol.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Symbol {
    pub name: String,
    /// Address within its space (offset stripped), bytes.
    pub addr: u32,
    /// Size, bytes (0 for labels like `__heap_start`).
    pub size: u32,
    pub space: Space,
}

/// Name → symbol table.
#[derive(Clone, Debug, Default)]
pub struct ElfSymbols {
    by_name: HashMap<String, Symbol>,
}

impl ElfSymbols {
    /// Reads the symbol table of an ELF file.
    pub fn load(path: &Path) -> Result<ElfSymbols, String> {
        let data = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let file = object::File::parse(&*data).map_err(|e| format!("{}: not an ELF: {e}", path.display()))?;
        let mut by_name = HashMap::new();
        for s in file.symbols() {
            let Ok(name) = s.name() else { continue };
            if name.is_empty() {
                continue;
            }
            let v = s.address();
            let (space, addr) = if (EEPROM_OFFSET..EEPROM_OFFSET + 0x1_0000).contains(&v) {
                (Space::Eeprom, v - EEPROM_OFFSET)
            } else if (DATA_OFFSET..EEPROM_OFFSET).contains(&v) {
                (Space::Ram, v - DATA_OFFSET)
            } else {
                (Space::Flash, v)
            };
            let sym = Symbol { name: name.to_string(), addr: addr as u32, size: s.size() as u32, space };
            // Prefer a sized definition over a label of the same name.
            by_name
                .entry(name.to_string())
                .and_modify(|old: &mut Symbol| {
                    if old.size == 0 && sym.size > 0 {
                        *old = sym.clone();
                    }
                })
                .or_insert(sym);
        }
        Ok(ElfSymbols { by_name })
    }

    /// A symbol by exact name.
    pub fn get(&self, name: &str) -> Option<&Symbol> {
        self.by_name.get(name)
    }

    /// Address of a symbol within its space (RAM symbols: data-space address).
    pub fn addr(&self, name: &str) -> Option<u32> {
        self.get(name).map(|s| s.addr)
    }

    /// Symbols whose name contains `part` (Rust names are mangled; this finds
    /// `_ZN4mill7stepper5STATE17h...E` from `"stepper5STATE"`).
    pub fn find(&self, part: &str) -> Vec<&Symbol> {
        let mut v: Vec<&Symbol> = self.by_name.values().filter(|s| s.name.contains(part)).collect();
        v.sort_by(|a, b| a.name.cmp(&b.name));
        v
    }

    /// Number of symbols.
    pub fn len(&self) -> usize {
        self.by_name.len()
    }

    /// No symbols at all.
    pub fn is_empty(&self) -> bool {
        self.by_name.is_empty()
    }
}
