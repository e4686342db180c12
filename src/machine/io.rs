//! The hardware as the controller sees it: narrow traits split as
//! embedded-hal splits its own ([`Stepper`], [`Inputs`], [`Outputs`],
//! [`Storage`], [`Host`]), [`Io`] their sum, and the values they report
//! ([`Realtime`] requests, [`StepperStatus`], [`Switches`]). The firmware
//! implements them over `board` (`src/firmware/io.rs`), the host tests over
//! `crate::fake_board`.

use super::{CmdResult, Machine};
use crate::gcode::interp;
use crate::stepper::rings::Watch;
use crate::stepper::StepperCmd;
use crate::N_AXES;
use core::convert::Infallible;

/// Realtime events collected by the hardware since the last poll.
#[derive(Clone, Copy, Default, Debug)]
pub struct Realtime {
    pub status: bool,
    pub hold: bool,
    pub resume: bool,
    pub estop: bool,
    pub limit: bool,
    pub home_tripped: bool,
    pub probe_tripped: bool,
    /// Abort requested (SD job or menu): decelerate, then drop the queue.
    pub abort: bool,
    /// With `abort`: leave the spindle running (the caller retracts the
    /// tool first: the SD card pulled mid-job).
    pub abort_keep_spindle: bool,
    /// 0x18 (Ctrl-X, grbl's soft reset) received; the stepper is halted.
    pub reset: bool,
    /// 0x85 (grbl's jog cancel) received.
    pub jog_cancel: bool,
    /// grbl's realtime override bytes received since the last poll, as
    /// request bits ([`crate::overrides::motion`], [`crate::overrides::accessory`]).
    pub motion_ovr: u8,
    pub accessory_ovr: u8,
    /// With `reset`: steps were still being produced when it arrived.
    pub reset_moving: bool,
}

/// What the stepper ISR reports.
#[derive(Clone, Copy, Default, Debug)]
pub struct StepperStatus {
    /// Machine position in steps, counted by the ISR.
    pub position: [i32; N_AXES],
    /// Steps still being produced or queued.
    pub busy: bool,
    /// Position latched at the last homing/probe trip.
    pub trip_position: [i32; N_AXES],
    /// A homing or probe trip stopped the ISR (and is not cleared yet).
    pub tripped: bool,
}

/// Switch levels, already as "triggered".
#[derive(Clone, Copy, Default, Debug)]
pub struct Switches {
    /// Home switches, bit i = axis i (X, Y, Z).
    pub home: u8,
    pub carousel_home: bool,
    pub tool_setter: bool,
}

/// The stepper ISR and its rings (`board::stepper`): segments in, the
/// position and the trip latch out, and what the ISR watches.
pub trait Stepper {
    /// Queue a command for the stepper ISR; false if the ring is full.
    fn push_segment(&mut self, cmd: StepperCmd) -> bool;
    /// Free slots in the segment ring.
    fn segment_space(&self) -> usize;
    /// Queue a command that fits (`segment_space() > 0`, nothing queued
    /// since); returns `segment_space()` after it.
    fn push_fitting(&mut self, cmd: StepperCmd) -> usize {
        if self.push_segment(cmd) {
            self.segment_space()
        } else {
            0
        }
    }
    /// At least `cycles` CPU cycles of motion wait in the segment ring
    /// (a board that does not count them says yes).
    fn queued_at_least(&self, _cycles: u32) -> bool {
        true
    }
    /// Stepper position and activity.
    fn stepper(&self) -> StepperStatus;
    /// [`StepperStatus::busy`] alone (the position costs a pass over the
    /// queued chunks on the board).
    fn stepper_busy(&self) -> bool {
        self.stepper().busy
    }
    /// Overwrite the stepper's position counter (only while stopped).
    fn set_stepper_position(&mut self, p: [i32; N_AXES]);
    /// Stop stepping at once, dropping queued segments.
    fn stop_motion(&mut self);
    /// Accept segments again after a stop; clears trip flags.
    fn clear_stop(&mut self);
    /// The ISR is stopped (e-stop, hard limit, homing or probe trip) and
    /// drops every segment it is given until [`Stepper::clear_stop`].
    fn stepper_stopped(&self) -> bool {
        false
    }
    /// What the ISR watches: homing axes, probe input, hard-limit axes,
    /// homed axes, direction inversion mask.
    /// `release`: steps above 0 where a homed axis' switch may still be
    /// closed (the homing pull-off, per axis X Y Z).
    fn set_watch(&mut self, w: Watch);
}

/// What the controller reads of the world: the realtime requests collected
/// since the last poll, the switches and the clock.
pub trait Inputs {
    /// Feed the watchdog and collect realtime events.
    fn poll(&mut self) -> Realtime;
    /// Current switch levels.
    fn switches(&self) -> Switches;
    /// Milliseconds since boot.
    fn millis(&self) -> u32;
}

/// What the controller switches: the stepper drivers, the spindle, the
/// coolant.
pub trait Outputs {
    /// Enable or disable the stepper drivers.
    fn drivers(&mut self, on: bool);
    /// Enable or disable the carousel (E0) driver alone (G204).
    fn carousel_driver(&mut self, on: bool);
    /// Spindle PWM duty, 0 = off.
    fn spindle(&mut self, duty: u8);
    /// Coolant output (M7/M8 on, M9 off).
    fn coolant(&mut self, on: bool);
}

/// Non-volatile storage: the EEPROM (settings, tool records, the change
/// journal, the setter's calibration, grbl's stored texts).
pub trait Storage {
    /// Read EEPROM bytes.
    fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]);
    /// Write EEPROM bytes (only the ones that differ are programmed).
    fn eeprom_write(&mut self, addr: u16, data: &[u8]);
}

/// The host's side: the serial link (replies go out through `uWrite`), the
/// SD card commands that arrive on it, and the standalone UI's turn.
pub trait Host: ufmt::uWrite<Error = Infallible> {
    /// Bytes waiting in the serial RX ring.
    fn rx_pending(&self) -> usize;
    /// Throw away every byte waiting in the serial RX ring (soft reset).
    fn flush_rx(&mut self) {}
    /// An SD command (M20–M29, M524; `arg` is the text after the code),
    /// with the little of the machine it may touch (`job`: M24 starts a
    /// job). Without an SD card in the build it is refused.
    fn sd_command(&mut self, _job: SdJobFlags<'_>, _code: u16, _arg: &[u8]) -> CmdResult {
        Err(interp::Error::NotAvailable(F!("SD card not available in this build")))
    }
    /// While M28 writes a file, store the line there and return true.
    fn sd_capture(&mut self, _line: &[u8]) -> bool {
        false
    }
    /// End of every [`Machine::idle`]: the standalone UI's turn (encoder,
    /// one slice of the display). Must be short.
    fn background(&mut self, _m: &Machine) {}
}

/// The hardware as the controller sees it: every narrow trait at once.
/// Implemented for anything that implements them all; code that needs
/// less asks for less (`impl Storage`, `impl Stepper`, …).
pub trait Io: Stepper + Inputs + Outputs + Storage + Host {}

impl<T: Stepper + Inputs + Outputs + Storage + Host + ?Sized> Io for T {}

/// What an SD command may change of the machine ([`Host::sd_command`]): M24
/// starts a job, which needs the abort count to watch and sets `sd_job`.
pub struct SdJobFlags<'a> {
    /// [`Machine::sd_job`]: set when a job starts.
    pub sd_job: &'a mut bool,
    /// [`Machine::aborts`] now.
    pub aborts: u8,
}
