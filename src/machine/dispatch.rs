//! Dispatch: carries out each [`Command`] the interpreter returns, by
//! calling the runner that owns it (motion, homing, the tool change, the
//! carousel, G37, the reports, the settings), and the commands simple
//! enough to need none (spindle, coolant, dwell, M17/M18, M400, M500–M502,
//! `$C`, and grbl's `$` lines).

use super::{after_eq, carousel, homing, report, setter, startup, toolchange, Alarm, CmdResult, Io, Machine, State};
use crate::config::Settings;
use crate::dollar;
use crate::flash::FStr;
use crate::gcode::interp::{self, Command};
use crate::planner::Speed;
use ufmt::uwriteln;

impl Machine {
    /// Carry out one command of the interpreter.
    // stack: each command's frame only while it runs (this file's attributes removed: +219 B stack)
    #[inline(never)]
    pub(super) fn dispatch(&mut self, cmd: &Command, io: &mut impl Io) -> CmdResult {
        match *cmd {
            Command::Move { feed_mm_per_min, rapid } => self.move_interp(io, feed_mm_per_min, rapid),
            Command::CycleMove { feed_mm_per_min, rapid } => self.cycle_move(io, feed_mm_per_min, rapid),
            Command::Probe { feed_mm_per_min, must_trip } => self.probe(io, *self.interp.target(), Speed::Feed(feed_mm_per_min), must_trip),
            Command::Dwell { ms } => {
                self.keepalive(io);
                self.wait_ms(io, ms)
            }
            Command::Home { mask } => homing::home(self, io, mask),
            Command::Measure { mode, x_mm, y_mm } => setter::g37(self, io, mode, x_mm, y_mm),
            Command::SelectTool { to } => toolchange::select(self, io, to),
            Command::PreselectTool(t) => {
                // NGC: T selects (pre-stages) the tool; the next M6 changes to it.
                self.atc.last_t = t;
                Ok(())
            }
            Command::ConfirmTool { tool } => {
                toolchange::confirm_tool(self, io, tool);
                Ok(())
            }
            Command::SetPocket { pocket, full } => toolchange::set_pocket(self, io, pocket, full),
            Command::AssignTool { tool, pocket } => toolchange::assign(self, io, tool, pocket),
            Command::SetTool { tool, length_mm, radius_mm } => {
                toolchange::set_tool(self, io, tool, length_mm, radius_mm);
                Ok(())
            }
            Command::StoreOffsets => {
                self.save_settings(io);
                Ok(())
            }
            Command::CarouselTurn { x } => carousel::turn_to(self, io, x),
            Command::CarouselSetPosition { x } => carousel::set_position(self, io, x),
            Command::CarouselReport => {
                carousel::report(self, io);
                Ok(())
            }
            Command::CarouselEnable { on } => carousel::enable(self, io, on),
            Command::CarouselHome { back, only_if_unhomed } => carousel::home_command(self, io, back, only_if_unhomed),
            Command::Spindle { on, duty } => self.spindle(io, on, duty),
            Command::FeedOverride { pct } => {
                self.set_feed_override(pct);
                Ok(())
            }
            Command::Coolant { m } => {
                // One output for both M7 (mist) and M8 (flood), switched in
                // step with the motion like the spindle (M9 in an alarm: at
                // once, nothing moves).
                if self.alarm.is_none() {
                    self.wait_idle(io)?;
                }
                io.coolant(m != 9);
                self.interp.coolant_m = m;
                Ok(())
            }
            Command::AxisSettings { code, values } => self.axis_settings(io, code, values),
            Command::M(code) => self.m_code(io, code),
            Command::Report(r) => {
                match r {
                    interp::Report::Position => report::position(self, io),
                    interp::Report::Firmware => self.firmware_line(io),
                    interp::Report::Temperatures => {
                        uwriteln!(io, "{}", F!("T:0.0 /0.0")).ok();
                    }
                    interp::Report::Switches => report::switches(self, io),
                    interp::Report::Settings => report::settings(self, io),
                    interp::Report::PrintTime => report::print_time(self, io),
                }
                Ok(())
            }
            Command::ClearAlarm => {
                if self.alarm.is_none() {
                    // grbl: `$X` outside an alarm has no effect. Only the
                    // homing lock after power-on is lifted; the queue and
                    // the position are not touched (a move may be running).
                    if !self.motion_allowed() {
                        self.unlocked = true;
                        uwriteln!(io, "{}", F!("echo:unlocked; position unknown until homed (G28)")).ok();
                    }
                    return Ok(());
                }
                self.clear_alarm(io);
                uwriteln!(io, "{}", F!("echo:alarm cleared; position unknown until homed (G28)")).ok();
                Ok(())
            }
            Command::EmergencyStop => {
                // The RX interrupt's scanner has usually raised it already.
                if self.alarm != Some(Alarm::EmergencyStop) {
                    self.raise(io, Alarm::EmergencyStop);
                }
                Ok(())
            }
            Command::ProgramEnd => {
                self.wait_idle(io)?;
                self.spindle_off(io);
                uwriteln!(io, "{}", F!("echo:program end")).ok();
                Ok(())
            }
            Command::Pause => {
                self.wait_idle(io)?;
                uwriteln!(io, "{}", F!("echo:paused, send ~ to resume")).ok();
                self.pause_until_resume(io)
            }
        }
    }

    /// A canned cycle's move: wait for room first (two slots: a backlash
    /// take-up may come first), so the keepalive goes out while the queue
    /// is full.
    // stack: each command's frame only while it runs (this file's attributes removed: +219 B stack)
    #[inline(never)]
    pub(super) fn cycle_move(&mut self, io: &mut impl Io, feed: f32, rapid: bool) -> CmdResult {
        self.keepalive(io);
        while self.planner.free() < 2 {
            self.keepalive(io);
            self.wait_step(io)?;
        }
        self.move_interp(io, feed, rapid)
    }

    /// Switch the spindle in step with the motion; when it starts or stops,
    /// wait its spin-up (`$181`) or spin-down (`$182`) delay before the next
    /// move (a speed change while on waits nothing, as Marlin).
    pub fn spindle(&mut self, io: &mut impl Io, on: bool, duty: u8) -> CmdResult {
        self.wait_idle(io)?;
        let was = self.interp.spindle_on;
        self.interp.spindle_on = on;
        self.spindle_duty = duty;
        io.spindle(crate::overrides::spindle_duty(duty, self.spindle_pct));
        let delay_s = match (was, on) {
            (false, true) => self.settings.spin_up_s,
            (true, false) => self.settings.spin_down_s,
            _ => 0.0,
        };
        if delay_s > 0.0 {
            self.keepalive(io);
            self.wait_ms(io, delay_s * 1000.0)?;
        }
        Ok(())
    }

    /// Let the queue drain, then wait at least `ms` milliseconds, serving
    /// realtime requests and sending the keepalive (G4, the canned cycles'
    /// P, the spindle's delays). The clock's first tick may come right
    /// after the start, so one tick more is counted: the wait is `ms` to
    /// `ms` + 1 ms, never less (a G4 S0.3 took 299.97 ms with the reply).
    pub(super) fn wait_ms(&mut self, io: &mut impl Io, ms: f32) -> CmdResult {
        self.wait_idle(io)?;
        let start = io.millis();
        let ticks = ms + 1.0;
        while (io.millis().wrapping_sub(start) as f32) < ticks {
            self.wait_step(io)?;
        }
        Ok(())
    }

    /// M17, M18/M84, M400, M500, M501, M502.
    // stack: each command's frame only while it runs (this file's attributes removed: +219 B stack)
    #[inline(never)]
    pub(super) fn m_code(&mut self, io: &mut impl Io, code: u16) -> CmdResult {
        match code {
            17 => io.drivers(true),
            18 | 84 => {
                // Wait for the moves, then spindle off (a mill with its drivers
                // off cannot cut: OctoPrint's cancel script has M84 but no M5),
                // drivers off; the position and the homing are kept (Marlin's
                // default, HOME_AFTER_DEACTIVATE off). docs/hosts.md "Cancel".
                // In an alarm nothing moves: at once.
                if self.alarm.is_none() {
                    self.wait_idle(io)?;
                }
                self.spindle_off(io);
                io.drivers(false);
                self.apply_watch(io, 0, false);
                if self.homed != 0 {
                    uwriteln!(io, "{}", F!("echo:steppers off, position kept: home again (G28) if an axis was turned by hand")).ok();
                }
            }
            400 => self.wait_idle(io)?,
            500 => {
                self.save_settings(io);
                uwriteln!(io, "{}", F!("echo:settings stored")).ok();
            }
            501 => {
                self.wait_idle(io)?;
                if self.load_settings(io) {
                    uwriteln!(io, "{}", F!("echo:settings loaded")).ok();
                } else {
                    return Err(interp::Error::BadWord(F!("EEPROM settings invalid; kept the current ones")));
                }
            }
            _ => {
                self.wait_idle(io)?;
                self.set_settings(Settings::defaults());
                self.interp.load_settings(&self.settings);
                uwriteln!(io, "{}", F!("echo:factory settings restored (M500 to store)")).ok();
            }
        }
        Ok(())
    }

    /// A grbl-style `$` line (see `crate::dollar`).
    // stack: each command's frame only while it runs (this file's attributes removed: +219 B stack)
    #[inline(never)]
    pub(super) fn dollar(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        let bad = |e: dollar::DollarError| interp::Error::Coded(e.grbl_code(), e.message());
        match dollar::parse(text).map_err(bad)? {
            dollar::Command::List => dollar::list(&self.settings, io),
            dollar::Command::Modes => dollar::modes(&self.interp, self.atc.spindle_tool(), io),
            dollar::Command::Params => dollar::params(&self.interp, self.settings.report_inches, io),
            dollar::Command::Info => startup::info(io),
            dollar::Command::InfoSet => startup::set_info(io, after_eq(text))?,
            dollar::Command::StartupList => startup::list(io),
            dollar::Command::StartupSet(i) => startup::set(io, i, after_eq(text))?,
            dollar::Command::HomeAxis(mask) => return homing::home(self, io, mask),
            dollar::Command::Sleep => {
                // grbl's sleep: everything that drives the machine off; here
                // any command wakes it (the drivers come on with a move).
                self.spindle_off(io);
                if self.alarm.is_none() {
                    self.wait_idle(io)?;
                }
                io.drivers(false);
                uwriteln!(io, "{}", F!("[MSG:Sleeping]")).ok();
            }
            dollar::Command::Restore(what) => self.restore(io, what)?,
            dollar::Command::Check => self.toggle_check(io)?,
            dollar::Command::Home => return self.execute_flash(F!("G28"), io),
            dollar::Command::Unlock => return self.execute_flash(F!("M999"), io),
            dollar::Command::Jog => return self.jog_line(text, io),
            dollar::Command::Set(n, v) => self.set_setting(io, n, v)?,
        }
        Ok(())
    }

    /// Run a short line kept in flash (`$H`, `$X`): as a `b"…"` literal it
    /// was a RAM string on AVR.
    // stack: the copy's frame only while it runs, not in `dollar`'s
    #[inline(never)]
    fn execute_flash(&mut self, line: FStr, io: &mut impl Io) -> CmdResult {
        let mut buf = [0u8; 8];
        let n = line.len().min(buf.len());
        for (i, b) in buf[..n].iter_mut().enumerate() {
            *b = line.get(i).unwrap_or(b' ');
        }
        self.execute(&buf[..n], io)
    }

    /// `$C`: check mode on (from Idle) or off. Leaving it puts the commanded
    /// position back where the machine is and the work offsets back to the
    /// stored ones; the modal state stays as the checked lines left it
    /// (grbl resets it with a soft reset).
    pub(super) fn toggle_check(&mut self, io: &mut impl Io) -> CmdResult {
        // Not during an SD job: a run from line's scan is check mode, and
        // leaving it would run the rest of the scan for real.
        if self.sd_job {
            return Err(interp::Error::JobRunning);
        }
        if self.state == State::Check {
            let p = io.stepper().position;
            self.interp.sync_position(&self.settings, p);
            self.interp.load_settings(&self.settings);
            self.state = State::Idle;
            uwriteln!(io, "{}", F!("[MSG:Disabled]")).ok();
            return Ok(());
        }
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        self.wait_idle(io)?;
        self.state = State::Check;
        uwriteln!(io, "{}", F!("[MSG:Enabled]")).ok();
        Ok(())
    }
}
