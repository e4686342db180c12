//! The firmware's main loop and its hardware side of `mill::machine::Io`.
//!
//! `board` provides registers; `mill::machine::Machine` provides all the
//! logic. This file only connects the two: it boots the board, loads the
//! settings from EEPROM, prints the banner and then pumps serial bytes into
//! the machine forever.

use crate::board::{self, eeprom::Eeprom, serial, stepper, wdt};
use core::convert::Infallible;
use mill::machine::{Io, Machine, Realtime, StepperStatus};
use mill::stepper::StepperCmd;

/// The hardware behind `Io`.
struct Hw {
    eeprom: Eeprom,
}

impl ufmt::uWrite for Hw {
    type Error = Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        serial::write(s.as_bytes());
        Ok(())
    }
}

impl Io for Hw {
    fn poll(&mut self) -> Realtime {
        wdt::feed();
        let rt = board::take_realtime();
        let m = stepper::MOTION.load(portable_atomic::Ordering::Acquire);
        Realtime {
            status: rt & board::realtime::STATUS != 0,
            hold: rt & board::realtime::HOLD != 0,
            resume: rt & board::realtime::RESUME != 0,
            estop: rt & board::realtime::ESTOP != 0,
            limit: m & stepper::motion::LIMIT != 0,
            home_tripped: m & stepper::motion::HOME_TRIPPED != 0,
            probe_tripped: m & stepper::motion::PROBE_TRIPPED != 0,
        }
    }

    fn push_segment(&mut self, cmd: StepperCmd) -> bool {
        stepper::push(cmd)
    }

    fn segment_space(&self) -> usize {
        stepper::space()
    }

    fn stepper(&self) -> StepperStatus {
        let m = stepper::MOTION.load(portable_atomic::Ordering::Acquire);
        StepperStatus {
            position: stepper::position(),
            busy: stepper::busy(),
            trip_position: stepper::trip_position(),
            tripped: m & (stepper::motion::HOME_TRIPPED | stepper::motion::PROBE_TRIPPED) != 0,
        }
    }

    fn set_stepper_position(&mut self, p: [i32; 4]) {
        stepper::set_position(p);
    }

    fn stop_motion(&mut self) {
        stepper::halt_from_isr();
    }

    fn clear_stop(&mut self) {
        stepper::MOTION.fetch_and(
            !(stepper::motion::LIMIT | stepper::motion::HOME_TRIPPED | stepper::motion::PROBE_TRIPPED),
            portable_atomic::Ordering::AcqRel,
        );
        stepper::clear_stop();
    }

    fn set_watch(&mut self, homing: u8, probe: bool, limits: u8, homed: u8, invert_dir: u8) {
        stepper::set_watch(stepper::Watch { homing, probe, limits, homed, invert_dir });
    }

    fn drivers(&mut self, on: bool) {
        board::drivers_enable(on);
    }

    fn carousel_driver(&mut self, on: bool) {
        board::carousel_driver_enable(on);
    }

    fn spindle(&mut self, duty: u8) {
        board::spindle_set(duty);
    }

    fn switches(&self) -> mill::machine::Switches {
        let i = board::inputs();
        mill::machine::Switches { home: i.home, carousel_home: i.carousel_home, tool_setter: i.tool_setter }
    }

    fn millis(&self) -> u32 {
        board::millis()
    }

    fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]) {
        let _ = self.eeprom.read(addr, buf);
    }

    fn eeprom_write(&mut self, addr: u16, data: &[u8]) {
        let _ = self.eeprom.write(addr, data);
    }

    fn free_ram(&self) -> u16 {
        board::free_ram()
    }

    fn rx_pending(&self) -> usize {
        serial::rx_len()
    }
}

static mut MACHINE: Machine = Machine::new();

/// Run the firmware. Never returns.
pub fn run() -> ! {
    let cause = wdt::reset_cause();
    wdt::disable_at_boot();
    board::paint_stack();
    // SAFETY: taken once, at boot.
    let dp = unsafe { avr_device::atmega2560::Peripherals::steal() };
    board::init(&dp);
    let mut hw = Hw { eeprom: Eeprom::new(dp.EEPROM) };
    // SAFETY: MACHINE is used only from this (main) context.
    let m = unsafe { &mut *core::ptr::addr_of_mut!(MACHINE) };
    serial::set_tx_wait_hook(tx_wait);
    // SAFETY: all shared state is initialised; ISRs may run from here on.
    unsafe { avr_device::interrupt::enable() };
    wdt::enable_2s();
    m.boot(&mut hw, cause.as_str());
    loop {
        while let Some(b) = serial::read() {
            m.push_byte(b, &mut hw);
        }
        m.idle(&mut hw);
    }
}

/// While the TX ring is full: keep the watchdog fed.
fn tx_wait() {
    wdt::feed();
}
