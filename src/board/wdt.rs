//! Watchdog and reset cause: the last line of defence against a hung main loop
//! (docs/SPEC.md §10), and the boot-time report of why the board restarted.
//!
//! Owns the use of WDTCSR and MCUSR (ATmega2560 datasheet §12 "System Control
//! and Reset": §12.5 Watchdog Timer and the MCUSR/WDTCSR register
//! descriptions). The watchdog runs in System Reset mode (WDE = 1, WDIE = 0)
//! with a 2 s timeout; the main loop calls [`feed`].
//!
//! Boot order, first thing in `main`: [`disable_at_boot`] and [`reset_cause`]
//! (either order: MCUSR is latched once), then the rest of the set-up, then
//! [`enable_2s`]. WDTCSR and MCUSR are reached through the PAC's fixed
//! addresses, used by no other module, so these functions take no arguments.
//! After a watchdog reset the WDT stays enabled at its shortest timeout
//! (16 ms) with WDRF set, and WDE cannot be cleared while WDRF is set.
//!
//! Changing WDE or the prescaler takes the timed sequence: write WDCE|WDE,
//! then the new value within four cycles. Both writes are constant stores
//! inside `interrupt::free`, so nothing can come between them.

use core::cell::Cell;

use avr_device::atmega2560::wdt::RegisterBlock;
use avr_device::atmega2560::{CPU, WDT};
use avr_device::interrupt::{CriticalSection, Mutex};

/// Why the MCU last came out of reset, decoded from MCUSR.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// Power was applied (PORF).
    PowerOn,
    /// The RESET pin was pulled low: reset button or the USB-serial DTR (EXTRF).
    External,
    /// VCC fell below the brown-out level (BORF).
    BrownOut,
    /// The watchdog expired: the main loop stopped feeding it (WDRF).
    Watchdog,
    /// A JTAG reset (JTRF).
    Jtag,
    /// No flag set. Not reported at boot: when the bootloader cleared
    /// MCUSR, [`super::bootloader`] recovers watchdog, external or power-on.
    Unknown,
}

/// MCUSR bit: power-on reset.
const PORF: u8 = 1 << 0;
/// MCUSR bit: external reset.
const EXTRF: u8 = 1 << 1;
/// MCUSR bit: brown-out reset.
const BORF: u8 = 1 << 2;
/// MCUSR bit: watchdog reset.
const WDRF: u8 = 1 << 3;
/// MCUSR bit: JTAG reset.
const JTRF: u8 = 1 << 4;

impl ResetCause {
    /// Decode MCUSR. When several flags are set, the most telling one wins:
    /// watchdog, then JTAG, then power-on (a power-up often also sets BORF),
    /// then brown-out, then external.
    pub const fn from_mcusr(mcusr: u8) -> ResetCause {
        if mcusr & WDRF != 0 {
            ResetCause::Watchdog
        } else if mcusr & JTRF != 0 {
            ResetCause::Jtag
        } else if mcusr & PORF != 0 {
            ResetCause::PowerOn
        } else if mcusr & BORF != 0 {
            ResetCause::BrownOut
        } else if mcusr & EXTRF != 0 {
            ResetCause::External
        } else {
            ResetCause::Unknown
        }
    }

    /// Short lowercase name for the boot banner, e.g. `"watchdog"` (in
    /// flash: as `&str` the names sat in RAM).
    pub fn name(&self) -> mill::flash::FStr {
        use mill::F;
        match self {
            ResetCause::PowerOn => F!("power-on"),
            ResetCause::External => F!("external"),
            ResetCause::BrownOut => F!("brown-out"),
            ResetCause::Watchdog => F!("watchdog"),
            ResetCause::Jtag => F!("jtag"),
            ResetCause::Unknown => F!("unknown"),
        }
    }
}

/// MCUSR as it was at boot, latched by the first [`reset_cause`] or
/// [`disable_at_boot`] call (`None` until then).
static BOOT_MCUSR: Mutex<Cell<Option<u8>>> = Mutex::new(Cell::new(None));

/// The WDT registers. Only this module uses WDTCSR.
fn wdt() -> &'static RegisterBlock {
    // SAFETY: WDTCSR is used by this module only, and only inside
    // `interrupt::free`; the register block lives at a fixed address.
    unsafe { &*WDT::ptr() }
}

/// MCUSR at boot: read and cleared on the first call, latched for later calls
/// (when the bootloader left it 0, the flags [`super::bootloader`] recovers).
/// Clearing WDRF is also what lets WDE be cleared afterwards.
fn boot_mcusr(cs: CriticalSection<'_>) -> u8 {
    let latched = BOOT_MCUSR.borrow(cs);
    if let Some(flags) = latched.get() {
        return flags;
    }
    // SAFETY: MCUSR is read and written by this module only, inside a critical
    // section; the other CPU registers (SMCR, PRR, ...) are not touched.
    let cpu = unsafe { &*CPU::ptr() };
    let flags = cpu.mcusr().read().bits();
    cpu.mcusr().write(|w| {
        w.porf().clear_bit().extrf().clear_bit().borf().clear_bit();
        w.wdrf().clear_bit().jtrf().clear_bit()
    });
    // The stock bootloader clears MCUSR before starting the application:
    // rebuild what can be known (super::bootloader).
    let flags = if flags == 0 {
        super::bootloader::recovered_mcusr()
    } else {
        super::bootloader::set_ram_mark();
        flags
    };
    latched.set(Some(flags));
    flags
}

/// Why the MCU was last reset. The first call (or [`disable_at_boot`]) reads
/// MCUSR and clears it; every call returns the same boot-time answer, so the
/// two may be called in either order.
pub fn reset_cause() -> ResetCause {
    ResetCause::from_mcusr(avr_device::interrupt::free(boot_mcusr))
}

/// First thing in `main`: switch the watchdog off, which after a watchdog
/// reset is still running at 16 ms. Clears WDRF first (WDE cannot be cleared
/// while WDRF is set); the reset cause stays available from [`reset_cause`].
pub fn disable_at_boot() {
    avr_device::interrupt::free(|cs| {
        boot_mcusr(cs);
        let wdt = wdt();
        avr_device::asm::wdr();
        // Timed sequence: WDCE|WDE, then WDE = 0 within four cycles.
        wdt.wdtcsr().write(|w| w.wdce().set_bit().wde().set_bit());
        wdt.wdtcsr().write(|w| w);
    });
}

/// Start the watchdog in System Reset mode with a 2 s timeout
/// (WDP3:0 = 0111, 256K cycles of the 128 kHz watchdog oscillator).
/// Call [`feed`] at least every 2 s from then on.
pub fn enable_2s() {
    avr_device::interrupt::free(|_| {
        let wdt = wdt();
        // Restart the count first so the old, possibly short, timeout cannot
        // expire during the change.
        avr_device::asm::wdr();
        // Timed sequence: WDCE|WDE, then WDE|WDP2|WDP1|WDP0 (WDCE = 0, WDIE = 0)
        // within four cycles.
        wdt.wdtcsr().write(|w| w.wdce().set_bit().wde().set_bit());
        wdt.wdtcsr().write(|w| w.wde().set_bit().wdph().clear_bit().wdpl().cycles_256k());
    });
}

/// Restart the watchdog count (the `wdr` instruction). Cheap; call it once
/// per main-loop pass, never from an ISR (that would hide a hung main loop).
pub fn feed() {
    avr_device::asm::wdr();
}
