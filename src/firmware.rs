//! The firmware's main loop and its hardware side of `mill::machine::Io`.
//!
//! `board` provides registers; `mill::machine::Machine` and `mill::ui`
//! provide all the logic. This file only connects them: it boots the board,
//! loads the settings from EEPROM, prints the banner, then forever
//!
//! ```text
//!  serial bytes ─► Machine::push_bytes
//!  SD job       ─► one line per turn while the planner has room ─► Machine::run_job_line
//!  menu command ─► jog / home / start a file / Tools line (at the top level, never nested in a wait)
//!  Machine::idle ─► segment prep, realtime ─► Host::background: encoder, one display slice
//! ```
//!
//! The SD card sits behind `embedded-sdmmc` (`VolumeManager` with one
//! volume, one directory and one file open at most: its 512-byte block
//! cache is the biggest RAM item here).
//!
//! The parts, one job each: [`io`] (the `Io` implementation over `board`),
//! [`sd`] (the SD card behind `mill::ui::sd::Card`), [`display`] (the OLED,
//! a slice per idle call) and [`menu`] (the menu's commands carried out).

mod display;
mod io;
mod menu;
mod sd;

use crate::board::oled::Sh1106;
use crate::board::spi::{ClockDiv, SdDevice, SpiBus};
use crate::board::twi::Twi;
use crate::board::{self, eeprom::Eeprom, serial, stepper, wdt};
use display::Display;
use embedded_sdmmc::{SdCard, VolumeManager};
use io::SerialOut;
use mill::machine::Machine;
use mill::protocol::{LineAssembler, MAX_LINE_LEN};
use mill::ui::files::FileList;
use mill::ui::menu::{Cmd, Ui, View};
use mill::ui::sd::{SdJob, Turn};
use sd::{FixedClock, SdDelay, SdFiles};

/// The hardware behind `Io`, plus the UI and the SD job.
struct Hw {
    eeprom: Eeprom,
    sd: SdFiles,
    job: SdJob,
    ui: Ui,
    view: View,
    display: Display,
    /// The Files screen's rows.
    files: FileList,
    /// A menu command for the main loop (jog, home, start a file ...).
    pending: Cmd,
    /// Realtime requests from the menu ([`req`] bits).
    requests: u8,
}

/// Zero-initialised (in .bss, no flash image); built by `Machine::init` in `run`.
static mut MACHINE: core::mem::MaybeUninit<Machine> = core::mem::MaybeUninit::uninit();
/// Zero-initialised (in .bss, no flash image); written once in `run`.
static mut HW: core::mem::MaybeUninit<Hw> = core::mem::MaybeUninit::uninit();
/// The serial line being assembled (`Machine::push_bytes`).
static mut ASM: LineAssembler = LineAssembler::new();

/// Start the machine: the hardware side built, then the settings, the
/// banner and the tool changer's journal (`Machine::boot`). A frame of its
/// own, so that nothing of it stays under the main loop, whose frame is on
/// every stack path (the alarm menu's jog path went from 1 980 to 1 846 B
/// of stack).
#[inline(never)]
fn boot() -> (&'static mut Machine, &'static mut Hw) {
    let cause = wdt::reset_cause();
    wdt::disable_at_boot();
    board::paint_stack();
    let hw = init_hw();
    // SAFETY: MACHINE is used only from this (main) context.
    let m = Machine::init(unsafe { &mut *core::ptr::addr_of_mut!(MACHINE) });
    serial::set_tx_wait_hook(tx_wait);
    // SAFETY: all shared state is initialised; ISRs may run from here on.
    unsafe { avr_device::interrupt::enable() };
    wdt::enable_2s();
    m.boot(hw, cause.name(), cause == wdt::ResetCause::Watchdog);
    (m, hw)
}

/// The board's registers set up and the hardware side written into `HW`:
/// a frame of its own (its temporaries, 270 B, are gone before
/// `Machine::boot` runs).
#[inline(never)]
fn init_hw() -> &'static mut Hw {
    // SAFETY: taken once, at boot.
    let dp = unsafe { avr_device::atmega2560::Peripherals::steal() };
    board::init(&dp);
    let (bus, cs) = SpiBus::new(dp.SPI, &dp.PORTB, ClockDiv::SD_INIT);
    let mut oled = Sh1106::new(Twi::new(dp.TWI, crate::board::oled::I2C_HZ));
    let oled = if oled.init().is_ok() { Some(oled) } else { None };
    let sd = SdFiles {
        vm: VolumeManager::new_with_limits(
            SdCard::new_with_options(
                SdDevice { bus, cs },
                SdDelay,
                embedded_sdmmc::sdcard::spi::AcquireOpts { use_crc: true, acquire_retries: 5 },
            ),
            FixedClock,
            0,
        ),
        vol: None,
        file: None,
        cwd: 0,
        depth: 0,
    };
    // SAFETY: HW is used only from this (main) context.
    unsafe {
        let slot = &mut *core::ptr::addr_of_mut!(HW);
        slot.write(Hw {
            eeprom: Eeprom::new(dp.EEPROM),
            sd,
            job: SdJob::new(),
            ui: Ui::new(),
            view: View::new(),
            display: Display::new(oled),
            files: FileList::new(),
            pending: Cmd::None,
            requests: 0,
        })
    }
}

/// Run the firmware. Never returns.
pub fn run() -> ! {
    let (m, hw) = boot();
    // SAFETY: ASM is used only here, from the main context.
    let asm = unsafe { &mut *core::ptr::addr_of_mut!(ASM) };
    // The SD job's line buffer lives here, not in `job_turn`'s frame: zeroing
    // it on every turn of the loop cost ~1.4k cycles per streamed line.
    let mut job_line = [0u8; MAX_LINE_LEN];
    #[cfg(feature = "panic-test")]
    let mut last = 0u64;
    loop {
        #[cfg(not(feature = "panic-test"))]
        m.push_bytes(asm, serial::Rx, hw);
        #[cfg(feature = "panic-test")]
        m.push_bytes(asm, core::iter::from_fn(|| serial::read().inspect(|&b| panic_test(&mut last, b))), hw);
        job_turn(m, hw, &mut job_line);
        menu::ui_turn(m, hw);
        m.idle(hw);
    }
}

/// Test builds only (`--features panic-test`, tests/panic.rs): the line
/// `M9999` panics and `M9998` aborts (the `llvm.trap` that
/// `panic = "immediate-abort"` makes of every panic) as its newline arrives,
/// from inside the serial → parser path.
#[cfg(feature = "panic-test")]
fn panic_test(last: &mut u64, b: u8) {
    *last = (*last << 8 | b as u64) & 0xFFFF_FFFF_FFFF;
    if *last == u64::from_be_bytes(*b"\0\0M9999\n") {
        panic!("M9999");
    }
    if *last == u64::from_be_bytes(*b"\0\0M9998\n") {
        core::intrinsics::abort();
    }
}

/// The SD job's turn: nothing without a job ([`SdJob::quiet`]), else
/// [`job_lines`].
// speed: the test is all of a turn without a job (as a call: +250 cycles a turn)
#[inline(always)]
fn job_turn(m: &mut Machine, hw: &mut Hw, line: &mut [u8; MAX_LINE_LEN]) {
    if hw.job.quiet(m) && !m.rebuild.active {
        return;
    }
    job_lines(m, hw, line);
}

/// The SD job's turn: at most four lines.
// stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
#[inline(never)]
fn job_lines(m: &mut Machine, hw: &mut Hw, line: &mut [u8; MAX_LINE_LEN]) {
    // Up to four lines per turn while the planner has room, as a serial host
    // keeps lines coming back to back (one line per turn of the main loop
    // left the ring emptier than a serial stream's: 10 % slower). Serial
    // bytes waiting (M27, a status query) end the batch: they go first, as
    // they did with one line per turn.
    sd::end_left_scan(m, hw);
    for _ in 0..4 {
        let done = m.motion_done(hw);
        let turn = hw.job.poll(&mut hw.sd, m, done, line, &mut SerialOut);
        match turn {
            // A line scanned for run from line runs the same way, in check mode.
            Turn::Run(n) | Turn::Scan(n) => {
                let r = m.run_job_line(&line[..n], hw);
                hw.job.line_done(r, m, &mut SerialOut);
                if serial::rx_len() != 0 {
                    return;
                }
                // The ISR must not run dry during a batch (a card block read
                // takes ~5 ms; it did, and the restart showed as a 12 % jump
                // in the measured acceleration): top its segments up when
                // less than 5 ms are left. Not after every line: each top-up
                // runs the look-ahead over the few blocks queued (10 % slower).
                if !stepper::queued_at_least(mill::F_CPU_HZ / 200) {
                    m.fill_segments(hw);
                }
            }
            Turn::Approach(n) => {
                let r = m.approach(hw).and_then(|()| m.run_job_line(&line[..n], hw));
                hw.job.line_done(r, m, &mut SerialOut);
                return;
            }
            Turn::SpindleOff => {
                m.spindle_off(hw);
                return;
            }
            Turn::RetractThenSpindleOff => {
                if let Err(e) = m.retract_and_stop_spindle(hw) {
                    m.report_error(hw, e);
                }
                return;
            }
            Turn::Idle => return,
        }
    }
}

/// While the TX ring is full: keep the watchdog fed.
fn tx_wait() {
    wdt::feed();
}
