//! The firmware's side of `mill::machine::Io`: the stepper ISR, the
//! switches, the outputs, the EEPROM, the serial port and the realtime
//! requests, over `board`; the SD commands go to the SD job and the idle
//! hook to the menu and the display.

use super::Hw;
use crate::board::{self, serial, stepper, wdt};
use core::convert::Infallible;
use mill::gcode::interp;
use mill::machine::{Host, Inputs, Machine, Outputs, Realtime, Stepper, StepperStatus, Storage};
use mill::stepper::StepperCmd;
use mill::ui::menu::{Cmd, Screen};
use mill::ui::sd::{self as sdjob, req, Card};

/// Stack the Files screen's rows take to read, below `file_rows`' test
/// (`FileList::refresh`, the card's directory walk: 509–534 B, measured in
/// tests/ui.rs' `the_file_list_follows_the_encoder_while_a_dwell_runs` by
/// raising this until the rows stayed blank), and a margin.
const FILE_LIST_STACK: u16 = 600;

/// The serial port as a `uWrite`, for code that holds parts of `Hw`.
pub(super) struct SerialOut;

impl ufmt::uWrite for SerialOut {
    type Error = Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        serial::write(s.as_bytes());
        Ok(())
    }
}

impl ufmt::uWrite for Hw {
    type Error = Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        serial::write(s.as_bytes());
        Ok(())
    }
}

impl Stepper for Hw {
    fn push_segment(&mut self, cmd: StepperCmd) -> bool {
        stepper::push(cmd)
    }

    fn segment_space(&self) -> usize {
        stepper::space()
    }

    fn push_fitting(&mut self, cmd: StepperCmd) -> usize {
        stepper::push_fitting(cmd)
    }

    fn queued_at_least(&self, cycles: u32) -> bool {
        stepper::queued_at_least(cycles)
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

    fn stepper_busy(&self) -> bool {
        stepper::busy()
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

    fn stepper_stopped(&self) -> bool {
        stepper::MOTION.load(portable_atomic::Ordering::Acquire) & stepper::motion::STOP != 0
    }

    fn set_watch(&mut self, w: mill::stepper::rings::Watch) {
        stepper::set_watch(w);
    }
}

impl Inputs for Hw {
    fn poll(&mut self) -> Realtime {
        wdt::feed();
        serial::store_lost_ends(false);
        let rt = board::take_realtime();
        if rt & board::realtime::RESET != 0 && self.job.active() {
            // A soft reset ends an SD job too (its abort finishes at once:
            // the reset leaves nothing moving).
            self.job.abort();
        }
        let ui = self.job.take_requests() | core::mem::take(&mut self.requests);
        let m = stepper::MOTION.load(portable_atomic::Ordering::Acquire);
        Realtime {
            status: rt & board::realtime::STATUS != 0,
            hold: rt & board::realtime::HOLD != 0 || ui & req::HOLD != 0,
            resume: rt & board::realtime::RESUME != 0 || ui & req::RESUME != 0,
            estop: rt & board::realtime::ESTOP != 0,
            limit: m & stepper::motion::LIMIT != 0,
            home_tripped: m & stepper::motion::HOME_TRIPPED != 0,
            probe_tripped: m & stepper::motion::PROBE_TRIPPED != 0,
            abort: ui & req::ABORT != 0,
            abort_keep_spindle: ui & req::KEEP_SPINDLE != 0,
            reset: rt & board::realtime::RESET != 0,
            jog_cancel: rt & board::realtime::JOG_CANCEL != 0,
            reset_moving: rt & board::realtime::RESET_MOVING != 0,
            motion_ovr: board::take_overrides(&board::MOTION_OVR),
            accessory_ovr: board::take_overrides(&board::ACCESSORY_OVR),
        }
    }

    fn switches(&self) -> mill::machine::Switches {
        let i = board::inputs();
        mill::machine::Switches { home: i.home, carousel_home: i.carousel_home, tool_setter: i.tool_setter }
    }

    fn millis(&self) -> u32 {
        board::millis()
    }
}

impl Outputs for Hw {
    fn drivers(&mut self, on: bool) {
        board::drivers_enable(on);
    }

    fn carousel_driver(&mut self, on: bool) {
        board::carousel_driver_enable(on);
    }

    fn spindle(&mut self, duty: u8) {
        board::spindle_set(duty);
    }

    fn coolant(&mut self, on: bool) {
        board::coolant_set(on);
    }
}

impl Storage for Hw {
    fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]) {
        let _ = self.eeprom.read(addr, buf);
    }

    fn eeprom_write(&mut self, addr: u16, data: &[u8]) {
        let _ = self.eeprom.write(addr, data);
    }
}

impl Host for Hw {
    fn flush_rx(&mut self) {
        while serial::read().is_some() {}
        serial::store_lost_ends(true);
    }

    fn rx_pending(&self) -> usize {
        serial::rx_len()
    }

    fn sd_command(&mut self, flags: mill::machine::SdJobFlags<'_>, code: u16, arg: &[u8]) -> mill::machine::CmdResult {
        self.files.valid = false;
        sdjob::command_with(&mut self.job, &mut self.sd, flags, &mut SerialOut, code, arg).map_err(|t| interp::Error::Sd(t.as_fstr()))
    }

    fn sd_capture(&mut self, line: &[u8]) -> bool {
        sdjob::capture(&mut self.job, &mut self.sd, line, &mut SerialOut)
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn background(&mut self, m: &Machine) {
        // The card pulled mid-job ends the job now, even while one of its
        // lines waits (a long arc, a full planner, M0): the status screen
        // says so.
        super::sd::keep_record(self, m);
        // (Without a job running it has nothing to end.)
        if self.job.active() && self.job.card_check(board::sd_detected(), m, &mut SerialOut) {
            self.sd.unmount();
            self.ui.screen = Screen::Status;
        }
        let (detents, presses) = board::take_encoder();
        if detents != 0 || presses != 0 {
            let cmd = self.ui.step(detents, presses != 0, &self.view);
            match cmd {
                // An edit screen opened: its value, here where the machine is.
                // (Run from line's proposal needs the card: the main loop's.)
                Cmd::Edit(e) if !matches!(e, mill::ui::menu::Edit::FromLine(_)) => self.ui.edit_um = e.current(m),
                other => self.command_now(other),
            }
            self.ui.fit_edit(m);
            // Show the change at once.
            self.display.frame_now();
        }
        // The Files screen's rows are read here, not in the menu's turn of
        // the main loop, so that they follow the list while the machine
        // waits too (M400, a dwell, the end of a job), as Marlin's menus do.
        // (The card is free here: `background` needs all of `Hw`.) In a
        // wait too deep to leave [`FILE_LIST_STACK`] within the RAM budget
        // they wait for a shallower turn.
        if matches!(self.ui.screen, Screen::Files) {
            self.file_rows();
        }
        self.draw_step(m);
    }
}

impl Hw {
    /// The Files screen's rows, read if they are not those on screen and
    /// the stack has room ([`FILE_LIST_STACK`]).
    // stack: out of background's frame, which every wait's turn takes (inlined: +33 B on the demo job's deepest path)
    #[inline(never)]
    fn file_rows(&mut self) {
        let first = self.ui.visible_files().0;
        if (!self.files.valid || first != self.files.first) && board::stack_room() >= FILE_LIST_STACK {
            self.files.refresh(&mut self.sd, first);
        }
    }
}
