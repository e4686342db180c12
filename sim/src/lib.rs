//! `sim`: the mill's virtual machine (docs/SPEC.md §12).
//!
//! The real firmware ELF runs in simavr as an ATmega2560 at 16 MHz; around it
//! sits a model of the RAMPS 1.4 machine:
//!
//! - [`vm`]: the simavr instance, its clock, reset handling and every hook
//!   (and the simavr quirks of docs/SPEC.md §14 it works around; see that module).
//! - [`recorder`]: step/dir/enable pins → positions, DRV8825 timing and travel
//!   violations, step rates, acceleration. Pure, unit-tested on synthetic events.
//! - [`physics`]: positions → home switches, carousel sensor, tool-setter beam,
//!   with per-input test overrides.
//! - [`atc`]: the physical tool changer (pockets, spindle clamp, collisions).
//! - [`host`]: the scripted G-code host on UART0 (ok / character-counting flow,
//!   line numbers and checksums, resends).
//! - [`isr`]: per-vector interrupt service times.
//! - [`spindle`]: PWM duty of OC2A.
//! - [`oled`]: the SH1106 OLED on the TWI bus (display RAM, PNG screenshots).
//! - [`sdcard`], [`sdimage`]: an SPI-mode SD card and the FAT images it holds.
//! - [`elf`]: ELF symbols (RAM addresses, `__heap_start`).
//! - [`report`]: JSON report and CSV step trace.
//! - [`pins`]: the RAMPS pin map, the only place `sim/` knows pins.
//! - [`pty`]: UART0 as a pseudo-terminal for real G-code senders and avrdude.
//! - [`boot`]: the stock Mega2560 bootloader (where it is installed, the
//!   fuses of a board as sold) and Intel hex files.
//! - [`plot`]: the toolpath PNG, commanded against recorded.
//!
//! ```no_run
//! use sim::{Axis, Flow, Input, StreamOptions, Vm, VmConfig};
//! let mut config = VmConfig::default();                // $MILL_ELF or target/avr-atmega2560/release/mill.elf
//! config.machine.initial_position = [1000, 1000, 500, 0]; // physical steps from each home switch
//! let mut vm = Vm::new(config)?;
//! vm.wait_for_start(2.0)?;                              // boot banner
//! vm.command("G28")?;                                   // lines up to and including "ok"
//! vm.command("G1 X10 F1200")?;
//! vm.command("M400")?;
//! assert_eq!(vm.position(Axis::X), 1000);               // physical position, steps
//! assert!(vm.violations().is_empty());
//! vm.set_input(Input::HomeX, Some(true));               // force the X switch closed
//! vm.set_input(Input::HomeX, None);                     // back to the model
//! let job = vm.stream(&["G0 X1", "G0 X2"], StreamOptions::new(Flow::CharCount(127)).with_checksums(true))?;
//! let isr = vm.stepper_isr_stats();                     // TIMER1_COMPA cycles
//! println!("{}", vm.report(Some(&job)).human());
//! # Ok::<(), sim::VmError>(())
//! ```

pub mod atc;
pub mod boot;
pub mod ceiling;
pub mod circle;
pub mod contour;
pub mod elf;
pub mod host;
pub mod isr;
pub mod oled;
pub mod physics;
pub mod pins;
pub mod plot;
pub mod pty;
pub mod recorder;
pub mod report;
pub mod sdcard;
pub mod sdimage;
pub mod spindle;
pub mod vm;

pub use atc::{AtcConfig, AtcModel, Collision, CollisionKind, Tool, Transfer};
pub use host::{Flow, StreamOptions, StreamReport};
pub use isr::{IsrStats, STEPPER_VECTOR};
pub use oled::Sh1106;
pub use physics::{CarouselConfig, MachineConfig, OpticalBeam, Physics, SwitchConfig, SwitchModel, ToolSetter};
pub use pins::{Axis, Input, Pin, PinMap, SignalKind};
pub use recorder::{PathPoint, Recorder, RecorderConfig, TracePoint, Violation, ViolationKind};
pub use report::{Report, ResetKind, ResetRecord};
pub use sdcard::{CardKind, SdCard};
pub use sdimage::{FatKind, SdImage};
pub use vm::{Vm, VmConfig, VmError};
