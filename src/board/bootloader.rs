//! What the stock Mega2560 bootloader (STK500v2, `stk500boot.c`) does to
//! the application, and how the firmware copes: the landing pad it jumps to
//! after a watchdog reset, and the reset cause it clears.
//!
//! After every reset the chip starts in the bootloader (BOOTRST), which
//! reads MCUSR and clears it before starting the application, so MCUSR reads
//! 0 in `main` (ATmega2560 datasheet §12.5, "MCUSR"). It then starts the
//! application in one of two ways:
//! - after a watchdog reset (WDRF), at once, with `eicall` through a null
//!   function pointer while EIND = 1: the call lands on word 0x10000, byte
//!   **0x20000**, not on the reset vector. `tools/link-firmware` puts the
//!   landing pad there ([`LANDING`]; `tools/size` checks it): it marks the
//!   entry in GPIOR0 and jumps to the reset vector;
//! - otherwise (power-on, the reset button, the USB port's DTR, brown-out),
//!   after its own wait for avrdude, with `ijmp` to 0.
//!
//! [`recovered_mcusr`] rebuilds what can be known when MCUSR reads 0:
//! watchdog from the landing pad's mark (GPIOR0 is 0 after every reset, and
//! only the pad writes it), then whether SRAM kept the firmware's mark
//! (`__mill_ram_mark`, 2 bytes of `.noinit`) through the reset (it does through every reset but a power loss: external, reset
//! button, DTR, and usually brown-out) or came up as power-on noise.
//! External and brown-out cannot be told apart this way, nor JTAG.

/// GPIOR0 (I/O 0x1E): 0 after every reset; written only by the landing pad.
const GPIOR0_IO: u8 = 0x1E;
/// The landing pad's mark in GPIOR0.
const LANDED: u8 = 0xA5;
/// What the firmware leaves in `__mill_ram_mark` once it runs: still there
/// after a reset that kept SRAM, noise after a power loss (which matches it
/// 1 time in 65,536: that power-on then reads as external).
const RUNNING: u16 = 0x4D31;

/// Byte address where the stock bootloader starts the application after a
/// watchdog reset (word 0x10000 with EIND = 1).
pub const LANDING: u32 = 0x2_0000;

// The landing pad: a section of its own that tools/link-firmware keeps at
// LANDING. Interrupts go off (the bootloader left them on) until `main`
// enables them; EIND stays 1 until avr-libc's start-up code (`__init`)
// sets it to 0, before any indirect call.
core::arch::global_asm!(
    ".section .mill_landing,\"ax\",@progbits",
    ".global __mill_landing",
    "__mill_landing:",
    "cli",
    "ldi r24, 0xA5",
    "out 0x1E, r24",
    "jmp 0",
    // Two bytes of SRAM that no start-up code touches (.noinit, after .bss).
    ".section .noinit,\"aw\",@nobits",
    ".global __mill_ram_mark",
    "__mill_ram_mark:",
    ".skip 2",
);
const _: () = assert!(LANDED == 0xA5 && GPIOR0_IO == 0x1E, "the landing pad's asm writes 0xA5 to I/O 0x1E");

extern "C" {
    /// [`RUNNING`] while the firmware runs (2 bytes of `.noinit` SRAM).
    static mut __mill_ram_mark: u16;
}

/// Reset flags (MCUSR bits) for a boot that found MCUSR cleared: WDRF if
/// the landing pad ran, EXTRF if SRAM kept the firmware's mark, PORF if it
/// did not. Reads and clears the pad's mark, and sets the SRAM mark for the
/// next reset. Call once, at boot, with interrupts off.
pub fn recovered_mcusr() -> u8 {
    const PORF: u8 = 1 << 0;
    const EXTRF: u8 = 1 << 1;
    const WDRF: u8 = 1 << 3;
    let gpior0 = (GPIOR0_IO + 0x20) as usize as *mut u8;
    // SAFETY: GPIOR0 is a plain I/O register used by this module only; the
    // mark is 2 bytes of .noinit SRAM that only this function touches.
    unsafe {
        let landed = core::ptr::read_volatile(gpior0) == LANDED;
        core::ptr::write_volatile(gpior0, 0);
        let mark = core::ptr::addr_of_mut!(__mill_ram_mark);
        let kept = core::ptr::read_volatile(mark) == RUNNING;
        core::ptr::write_volatile(mark, RUNNING);
        if landed {
            WDRF
        } else if kept {
            EXTRF
        } else {
            PORF
        }
    }
}

/// Sets the SRAM mark when MCUSR told the cause itself (no bootloader, or
/// one that keeps MCUSR), so that the next reset through the bootloader is
/// told apart from a power loss.
pub fn set_ram_mark() {
    // SAFETY: as in `recovered_mcusr`.
    unsafe { core::ptr::write_volatile(core::ptr::addr_of_mut!(__mill_ram_mark), RUNNING) };
}
