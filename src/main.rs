//! Firmware entry point for the ATmega2560 (Arduino Mega2560 + RAMPS 1.4).
//!
//! Wires the pipeline together:
//! serial bytes → `protocol` (line assembly, N/*) → `machine::Machine`
//! (parser, interpreter, planner, segment prep) → `board::stepper` ISR.
//!
//! The main loop never blocks for long: every wait (TX space, planner space,
//! dwell, homing) runs [`idle`], which feeds the watchdog, tops up the segment
//! ring and serves realtime requests (`?`, `!`, `~`, M112).
//!
//! On the host this file compiles to a stub so `cargo test` can build the
//! package; the firmware is built with `cargo fw`.
#![cfg_attr(target_arch = "avr", no_std, no_main, feature(abi_avr_interrupt, asm_experimental_arch))]
// tests/panic.rs's M9998 calls the abort intrinsic (src/firmware.rs).
#![cfg_attr(all(target_arch = "avr", feature = "panic-test"), allow(internal_features), feature(core_intrinsics))]
// Every unsafe operation sits in an `unsafe {}` block with its `// SAFETY:`
// line, also inside an `unsafe fn`.
#![deny(unsafe_op_in_unsafe_fn)]

#[cfg(not(target_arch = "avr"))]
fn main() {
    eprintln!("the mill firmware runs on the ATmega2560: build it with `cargo fw`");
}

#[cfg(target_arch = "avr")]
// Parts of the board layer (release functions, spare pins) are not called yet.
#[allow(dead_code)]
mod board;
#[cfg(target_arch = "avr")]
mod firmware;

#[cfg(target_arch = "avr")]
#[avr_device::entry]
fn main() -> ! {
    firmware::run()
}

/// Panic: the machine stops as on M112, reports `ALARM:firmware panic`,
/// and halts until reset (`board::halt`; docs/ARCHITECTURE.md, "Panics").
#[cfg(target_arch = "avr")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    board::halt::halt(mill::F!("firmware panic"))
}

/// `abort` (avr-libc's would only `cli` and spin, leaving the drivers on and
/// the spindle turning): the same end as a panic. Defining it here keeps
/// avr-libc's out of the link.
#[cfg(target_arch = "avr")]
#[no_mangle]
pub extern "C" fn abort() -> ! {
    board::halt::halt(mill::F!("firmware abort"))
}
