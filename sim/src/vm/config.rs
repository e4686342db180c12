//! [`VmConfig`]: everything a [`Vm`](super::Vm) needs to start, its
//! defaults (the mill on RAMPS 1.4) and the preset for the real grbl-Mega.

use crate::physics::MachineConfig;
use crate::pins::{Input, PinMap};
use crate::recorder::RecorderConfig;
use std::path::{Path, PathBuf};

/// OCR1AL's data-space address (ATmega2560 register summary).
const OCR1AL: u16 = 0x88;

/// Everything a [`Vm`](super::Vm) needs to start.
#[derive(Clone, Debug)]
pub struct VmConfig {
    /// Firmware ELF.
    pub elf: PathBuf,
    /// CPU clock, Hz.
    pub frequency_hz: u32,
    /// The machine around the chip.
    pub machine: MachineConfig,
    /// Recorder limits and analysis parameters (`frequency_hz` is overwritten).
    pub recorder: RecorderConfig,
    /// `run_until` conditions are checked at least this often, cycles (and
    /// also whenever a line arrives on the UART). Default 1600 (100 µs).
    pub check_interval_cycles: u64,
    /// Cycles simavr may run per `avr_run` call between timers. Default 1024.
    pub batch_cycles: u64,
    /// Stop with an error beyond this interrupt nesting depth. Default 60.
    pub max_interrupt_nesting: u32,
    /// Treat an invalid opcode as a crash. Default true.
    pub stop_on_bad_opcode: bool,
    /// Default timeout of [`Vm::command`](super::Vm::command), simulated seconds. Default 60.
    pub command_timeout_s: f64,
    /// Keep TCNTn across clock stop/start like the hardware (module docs). Default true.
    pub fix_tcnt_on_clock_start: bool,
    /// The stock bootloader (Intel hex), loaded at the boot section with
    /// BOOTRST and the fuses of a board as sold ([`crate::boot`]): every
    /// reset starts it, and it starts the application. Default None: the
    /// chip starts at the application's reset vector.
    pub bootloader: Option<PathBuf>,
    /// Leave the application space erased (0xFF) instead of loading the
    /// ELF's image: a board with only the bootloader, to flash through it.
    /// The ELF is still read for its symbols. Default false.
    pub blank_application: bool,
    /// Which pin is which driver signal and input. Default: RAMPS 1.4.
    pub pins: PinMap,
    /// Data-space bytes written after every reset, before the firmware
    /// runs (a simavr workaround a peer firmware needs; see
    /// [`VmConfig::grbl_mega`]). Default none.
    pub poke_after_reset: Vec<(u16, u8)>,
}

impl VmConfig {
    /// Default configuration for a given ELF.
    pub fn new(elf: impl Into<PathBuf>) -> VmConfig {
        VmConfig { elf: elf.into(), ..VmConfig::default() }
    }

    /// The real grbl-Mega 1.1g (`../shared/peers/grbl-mega/`, its ELF
    /// `elf`) on its own pins ([`PinMap::GRBL_MEGA`], directions high =
    /// negative), with the two simavr workarounds its ORIGIN.txt measured:
    /// OCR1A set to 0xFF after every reset (simavr's Timer1 CTC never fires
    /// with OCR1A = 0, which grbl leaves there when it enables the
    /// interrupt), and TCNTn kept across a clock start (on by default).
    /// No switches are wired but the limits and the probe; grbl's limits
    /// and homing are off by default.
    pub fn grbl_mega(elf: impl Into<PathBuf>) -> VmConfig {
        let mut c = VmConfig::new(elf);
        c.pins = PinMap::GRBL_MEGA;
        c.machine.invert_dir_mask = 0b0111;
        // grbl's probe input reads low when it touches (pull-up, `$6=0`).
        c.machine.inverted_inputs |= 1 << Input::ToolSetter.index();
        c.poke_after_reset = vec![(OCR1AL, 0xFF)];
        c.fix_tcnt_on_clock_start = true;
        c
    }

    /// `$MILL_ELF` if set, else `<repo>/target/avr-atmega2560/release/mill.elf`
    /// (what `cargo fw` builds).
    pub fn default_elf_path() -> PathBuf {
        if let Some(p) = std::env::var_os("MILL_ELF") {
            return PathBuf::from(p);
        }
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/avr-atmega2560/release/mill.elf")
    }
}

impl Default for VmConfig {
    fn default() -> Self {
        VmConfig {
            elf: VmConfig::default_elf_path(),
            frequency_hz: 16_000_000,
            machine: MachineConfig::default(),
            recorder: RecorderConfig::default(),
            check_interval_cycles: 1600,
            batch_cycles: 1024,
            max_interrupt_nesting: 60,
            stop_on_bad_opcode: true,
            command_timeout_s: 60.0,
            fix_tcnt_on_clock_start: true,
            bootloader: None,
            blank_application: false,
            pins: PinMap::RAMPS,
            poke_after_reset: Vec::new(),
        }
    }
}
