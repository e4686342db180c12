//! The menu's commands carried out: the realtime ones at once (from the
//! idle hook: pause, resume, abort, jog detents added up), the rest at the
//! top of the main loop, never nested in a wait (start a file, home, jog,
//! the Tools lines and the edits stored through the same lines as over
//! serial), and the file list of the Files screen.

use super::Hw;
use crate::board;
use mill::gcode::interp;
use mill::machine::{Inputs, Machine};
use mill::ui::menu::{Cmd, Edit, Reply, Screen};
use mill::ui::render::Line;
use mill::ui::resume;
use mill::ui::sd::{req, Card, Folder, SdError};
use ufmt::uwriteln;

/// Jog feed from the menu, mm/min.
const JOG_FEED_MM_PER_MIN: f32 = 1200.0;

impl Hw {
    /// Menu commands: realtime ones now, the rest for the main loop.
    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    pub(super) fn command_now(&mut self, cmd: Cmd) {
        match cmd {
            Cmd::None => {}
            Cmd::Pause => {
                if self.job.active() {
                    self.job.pause();
                } else {
                    self.requests |= req::HOLD;
                }
            }
            Cmd::Resume => {
                if self.job.phase == mill::ui::sd::Phase::Paused {
                    self.job.resume();
                } else {
                    // Feed hold, or M0/M1 inside a job or a stream.
                    self.requests |= req::RESUME;
                }
            }
            Cmd::Abort => {
                if self.job.active() {
                    self.job.abort();
                } else {
                    self.requests |= req::ABORT;
                }
            }
            Cmd::Jog { axis, delta_um } => {
                // Detents add up while a jog is still being queued.
                self.pending = match self.pending {
                    Cmd::Jog { axis: a, delta_um: d } if a == axis => Cmd::Jog { axis, delta_um: d + delta_um },
                    _ => cmd,
                };
            }
            other => self.pending = other,
        }
    }
}

/// The Spindle menu's commands, through the serial lines where there is
/// one (`M3 S<rpm>`, `M5`, `S<rpm>`: the same checks and clamps as a
/// host's), the override as 0x9A/0x9B set it. A frame of its own, as
/// [`files_cmd`].
#[inline(never)]
fn spindle_cmd(m: &mut Machine, hw: &mut Hw, cmd: Cmd) -> mill::machine::CmdResult {
    let (on, rpm, set) = match cmd {
        Cmd::Spindle { on, rpm, set } => (on, rpm, set),
        Cmd::SpindleOverride(pct) => {
            m.set_spindle_override(hw, pct);
            return Ok(());
        }
        _ => return Ok(()),
    };
    // The words byte by byte: `b"M3 S"` and `b"M5"` were RAM strings on AVR.
    let mut l = Line::blank();
    let ch = &mut l.chars;
    let c = match (on, set) {
        (false, false) => {
            (ch[0], ch[1]) = (b'M', b'5');
            2
        }
        (false, true) => {
            ch[0] = b'S';
            1
        }
        (true, _) => {
            (ch[0], ch[1], ch[2], ch[3]) = (b'M', b'3', b' ', b'S');
            4
        }
    };
    let c = if on || set { l.uint(c, rpm as u32) } else { c };
    m.run_menu_line(&l.chars[..c], hw)
}

/// The Files screen's commands (a frame of their own: `ui_turn` is on the
/// deepest stack path, the alarm menu's jog).
#[inline(never)]
fn files_cmd(m: &mut Machine, hw: &mut Hw, cmd: Cmd) -> mill::machine::CmdResult {
    let sd_err = |e: SdError| interp::Error::Sd(e.text().as_fstr());
    match cmd {
        Cmd::ListFiles => {
            hw.files.valid = false;
            Ok(())
        }
        Cmd::OpenFolder(i) => {
            let r = match hw.files.entry(&mut hw.sd, i) {
                Some((name, true)) => hw.sd.enter(&name).map_err(sd_err),
                _ => Err(sd_err(SdError::NotFound)),
            };
            hw.files.valid = false;
            r
        }
        Cmd::FolderUp => {
            hw.files.valid = false;
            hw.sd.leave().map_err(sd_err)
        }
        Cmd::RunFile(i) => match hw.files.entry(&mut hw.sd, i) {
            Some((name, false)) => match hw.job.select(&mut hw.sd, Folder::Current, &name) {
                Ok(()) => {
                    m.job_start_ms = hw.millis();
                    hw.job.start(m).map_err(|t| interp::Error::Sd(t.as_fstr()))
                }
                Err(e) => Err(sd_err(e)),
            },
            _ => Err(sd_err(SdError::NotFound)),
        },
        Cmd::Edit(Edit::FromLine(i)) => {
            // The line proposed: the last one reached, when the record is
            // this file's (same name and size); else line 1 and why.
            let (line, note) = match hw.files.entry(&mut hw.sd, i) {
                Some((name, false)) => match hw.job.select(&mut hw.sd, Folder::Current, &name) {
                    Ok(()) => resume::propose(resume::load(hw), &name, hw.job.size),
                    Err(e) => (1, Some(e.text())),
                },
                _ => (1, Some(SdError::NotFound.text())),
            };
            hw.ui.edit_um = line.min(2_000_000) as i32 * 1000;
            hw.ui.reply = note.map_or(Reply::Ok, |t| Reply::Err(t.as_fstr()));
            Ok(())
        }
        _ => Ok(()),
    }
}

/// Run from line `line` of file `i` of the list: refused unless homed and
/// idle (nothing moves then); the scan starts, the job runs it
/// (`SdJob::start_from`), the status screen shows its progress.
#[inline(never)]
fn run_from_line(m: &mut Machine, hw: &mut Hw, i: u8, line: u32) -> mill::machine::CmdResult {
    let sd_err = |e: SdError| interp::Error::Sd(e.text().as_fstr());
    let Some((name, false)) = hw.files.entry(&mut hw.sd, i) else {
        return Err(sd_err(SdError::NotFound));
    };
    m.begin_scan(hw)?;
    if let Err(e) = hw.job.select(&mut hw.sd, Folder::Current, &name) {
        m.end_scan(hw);
        return Err(sd_err(e));
    }
    hw.job.start_from(m, line).map_err(|t| interp::Error::Sd(t.as_fstr()))?;
    m.job_start_ms = hw.millis();
    uwriteln!(hw, "{}{}{}{}", mill::F!("echo:"), mill::ui::text::Text::MsgResumeAt, line, mill::F!(": scanning")).ok();
    hw.ui.screen = Screen::Status;
    Ok(())
}

/// The menu's turn: nothing while no command waits and no idle card was
/// pulled, else [`ui_work`].
// speed: the test is all of a turn with the menu quiet (as a call: +200 cycles a turn)
#[inline(always)]
pub(super) fn ui_turn(m: &mut Machine, hw: &mut Hw) {
    if matches!(hw.pending, Cmd::None) && (hw.sd.vol.is_none() || board::sd_detected()) {
        return;
    }
    ui_work(m, hw);
}

/// The menu's commands that run at the top level.
// stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
#[inline(never)]
fn ui_work(m: &mut Machine, hw: &mut Hw) {
    if !board::sd_detected() && hw.sd.vol.is_some() && !hw.job.active() {
        // Pulled while idle: forget it, so the next card is mounted afresh.
        hw.sd.unmount();
        hw.files.valid = false;
    }
    let cmd = core::mem::replace(&mut hw.pending, Cmd::None);
    let r = match cmd {
        Cmd::ListFiles | Cmd::OpenFolder(_) | Cmd::FolderUp | Cmd::RunFile(_) | Cmd::Edit(_) => files_cmd(m, hw, cmd),
        Cmd::Override(pct) => {
            m.set_feed_override(pct);
            Ok(())
        }
        Cmd::OptionalStop(on) => {
            // The same setting as `$152`, stored like it.
            m.settings.optional_stop = on;
            m.save_settings(hw);
            Ok(())
        }
        Cmd::Jog { axis, delta_um } => m.jog(hw, axis as usize, delta_um as f32 / 1000.0, JOG_FEED_MM_PER_MIN),
        Cmd::Home(mask) => mill::machine::home(m, hw, mask),
        Cmd::Unlock => {
            if m.alarm.is_some() {
                m.clear_alarm(hw);
            }
            Ok(())
        }
        Cmd::Teach(p) => m.teach_station(hw, p),
        Cmd::Spindle { .. } | Cmd::SpindleOverride(_) => spindle_cmd(m, hw, cmd),
        Cmd::Store(e, um) => {
            let r = store_edit(m, hw, e, um);
            hw.ui.reply = match r {
                Ok(()) => Reply::Ok,
                Err(e) => Reply::Err(e.message()),
            };
            r
        }
        Cmd::Tool(op) => {
            if matches!(op, mill::ui::menu::ToolOp::Confirm(_)) && m.alarm.is_some() {
                // Confirming the spindle is a way out of the alarm.
                m.clear_alarm(hw);
            }
            // The same line as over serial (T<n>, G37 [D1], M61 Q<t>), so
            // the same checks and errors; the reply screen shows the outcome.
            // The menu picks pockets; the line names the pocket's tool
            // number, and a pocket without one is refused.
            use mill::ui::menu::ToolOp;
            let (op, pocket) = match op {
                ToolOp::Change(p) => (ToolOp::Change(m.atc.table.number_of(p)), p),
                ToolOp::Confirm(p) => (ToolOp::Confirm(m.atc.table.number_of(p)), p),
                other => (other, 0),
            };
            let unnumbered = pocket != 0 && matches!(op, ToolOp::Change(0) | ToolOp::Confirm(0));
            let mut l = Line::blank();
            let n = op.gcode(&mut l);
            let r = if unnumbered {
                Err(interp::Error::Atc(mill::atc::Fault::NoNumber))
            } else if op == ToolOp::ProbeZ {
                // Down at most PROBE_Z_MM on the probe input (a miss is the
                // probe-fail alarm, as G38.2), then the zero line.
                m.probe_z_down(hw, mill::ui::menu::PROBE_Z_MM, mill::ui::menu::PROBE_Z_FEED)
                    .and_then(|()| m.run_menu_line(&l.chars[..n], hw))
            } else {
                m.run_menu_line(&l.chars[..n], hw)
            };
            hw.ui.reply = match r {
                Ok(()) => Reply::Ok,
                Err(e) => Reply::Err(match (e, m.alarm) {
                    (interp::Error::Alarm, Some(a)) => a.message(),
                    _ => e.message(),
                }),
            };
            r
        }
        _ => Ok(()),
    };
    if let Err(e) = r {
        uwriteln!(hw, "{}", mill::F!("echo:menu:")).ok();
        m.report_error(hw, e);
    }
}

/// The menu's edit stored through the serial lines: `$n=<value>`, or for
/// a pocket's tool number `G10 L1 P<old> Q0` then `G10 L1 P<new> Q<p>`
/// (the old number put back if the new one is refused); the setter's
/// reference tool into its record, then `G37 L R`.
// stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
#[inline(never)]
fn store_edit(m: &mut Machine, hw: &mut Hw, e: mill::ui::menu::Edit, um: i32) -> mill::machine::CmdResult {
    let mut l = Line::blank();
    if let Edit::FromLine(i) = e {
        return run_from_line(m, hw, i, (um / 1000) as u32);
    }
    if let Edit::RefLength | Edit::RefDia = e {
        // The reference tool goes into the setter record; its diameter
        // stored, the calibration runs with both (`G37 L R`).
        let mut s = m.setter;
        if e == Edit::RefLength {
            s.ref_length_um = um;
        } else {
            s.ref_diameter_um = um;
        }
        mill::machine::setter::store_setter(m, hw, s);
        if e == Edit::RefLength {
            return Ok(());
        }
        let n = mill::ui::menu::calibrate_line(s.ref_length_um, um, &mut l);
        return m.run_menu_line(&l.chars[..n], hw);
    }
    let Edit::Pocket(p) = e else {
        let n = e.gcode(um, None, &mut l);
        return m.run_menu_line(&l.chars[..n], hw);
    };
    let (old, new) = (m.atc.table.number_of(p), (um / 1000) as u8);
    if old == new {
        return Ok(());
    }
    if old != 0 {
        let n = e.gcode(um, Some(old), &mut l);
        m.run_menu_line(&l.chars[..n], hw)?;
    }
    if new == 0 {
        return Ok(());
    }
    let mut l = Line::blank();
    let n = e.gcode(um, None, &mut l);
    let r = m.run_menu_line(&l.chars[..n], hw);
    if r.is_err() && old != 0 {
        let mut l = Line::blank();
        let n = e.gcode(old as i32 * 1000, None, &mut l);
        m.run_menu_line(&l.chars[..n], hw).ok();
    }
    r
}
