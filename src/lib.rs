//! Mill firmware core: the pure logic of the pipeline, host-testable.
//!
//! ```text
//!  serial / SD bytes ─► protocol (line assembly, N/*, realtime bytes)
//!                    ─► gcode (parse; the interpreter turns a line into Commands)
//!                    ─► machine (the controller: carries the Commands out)
//!                    ─► planner (block ring, look-ahead, arcs → chords)
//!                    ─► stepper::prep (segments, in the main loop)
//!                    ─► stepper ISR (board, Bresenham tick over stepper::queue records)
//! ```
//!
//! Nothing in this crate touches a register: `src/board` (AVR only) does that,
//! and `src/main.rs` wires the pieces together. Everything here compiles and is
//! unit-tested on the host with plain `cargo test`.
//!
//! # Layers
//!
//! A module may name (`use crate::…`, `crate::…::`) only modules of its own
//! layer or of a lower one, and a layer has no cycle; below the top level,
//! the children of a module have no cycle either. `tools/layers` checks it,
//! and the sim crate's modules too (run by `tools/test`; the same table is in
//! that script):
//!
//! | layer | modules | what |
//! |---|---|---|
//! | 0 | `math`, `fixed`, `flash`, `config`, `protocol`, `overrides`, `axis` | arithmetic, settings, wire protocol |
//! | 1 | `planner`, `stepper`, `frame` | motion pipeline, the Z flip |
//! | 2 | `atc`, `toolsetter` | the tool changer's and the setter's pure logic |
//! | 3 | `gcode` | parser, interpreter (pure: returns `Command`s), canned cycles |
//! | 4 | `hostcodes`, `dollar` | codes taken before the parser |
//! | 5 | `machine` | the controller, and the runners that move the machine (homing, `machine::toolchange`, `machine::carousel`, `machine::setter`) |
//! | 6 | `ui` | menu, display, SD jobs (uses the machine) |
//! | 7 | `board`, `firmware` | the AVR binary (not in this library) |
//!
//! Unit tests may reach up (`gcode`'s tests drive `Machine::execute`).
#![cfg_attr(not(test), no_std)]
#![cfg_attr(target_arch = "avr", feature(asm_experimental_arch))]
// Every unsafe operation sits in an `unsafe {}` block with its `// SAFETY:`
// line, also inside an `unsafe fn`.
#![deny(unsafe_op_in_unsafe_fn)]

#[macro_use]
pub mod flash;
pub mod atc;
pub mod config;
pub mod dollar;
pub mod fixed;
pub mod frame;
pub mod gcode;
pub mod hostcodes;
pub mod machine;
pub mod math;
pub mod overrides;
pub mod planner;
pub mod protocol;
pub mod stepper;
pub mod toolsetter;
pub mod ui;

/// A fake board (time, stepper, switches, EEPROM) for host tests of the controller.
#[cfg(test)]
pub mod fake_board;

/// Helpers shared by the library's unit tests.
#[cfg(test)]
pub(crate) mod test_util {
    /// Tiny xorshift32 PRNG for random-input tests (no `rand` crate).
    pub struct XorShift(pub u32);

    impl XorShift {
        /// Next pseudo-random value.
        pub fn next(&mut self) -> u32 {
            let mut x = self.0;
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            self.0 = x;
            x
        }
    }
}

/// Number of stepper axes: X, Y, Z and E0 (the tool carousel).
pub const N_AXES: usize = 4;

/// Axis indices into every `[_; N_AXES]` array.
pub mod axis {
    pub const X: usize = 0;
    pub const Y: usize = 1;
    pub const Z: usize = 2;
    /// The E0 driver, which turns the tool carousel.
    pub const E: usize = 3;
    /// Axis letters in index order.
    pub const NAMES: [u8; super::N_AXES] = *b"XYZE";
}

/// Firmware name and version, as printed at boot and by M115.
pub const FIRMWARE_NAME: &str = "MillFW";
/// Firmware version (the crate version).
pub const FIRMWARE_VERSION: &str = env!("CARGO_PKG_VERSION");
/// CPU clock of the ATmega2560 on the Mega2560 board, in Hz.
pub const F_CPU_HZ: u32 = 16_000_000;
/// [`F_CPU_HZ`] as a float, for times in CPU cycles.
pub const F_CPU: f32 = F_CPU_HZ as f32;
