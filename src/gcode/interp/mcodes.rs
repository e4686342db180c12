//! M codes and S: the spindle (S, M3, M5, and its PWM duty) and the
//! "other" M group (M220 here, M17…M503 handed to the controller).

use super::command::Command;
use super::error::Error;
use super::{Ctx, Interp};
use crate::config::Settings;
use crate::gcode::{Line, NonModal, Spindle, Word};
use crate::math::round_i32;
use crate::N_AXES;

impl Interp {
    /// S, M3, M5: the spindle command, if any.
    pub(super) fn spindle(&mut self, cx: &Ctx, l: &Line) -> Option<Command> {
        let s = spindle_speed(l);
        if let Some(s) = s {
            self.spindle_rpm = s;
        }
        match l.spindle {
            Some(Spindle::Cw) => Some(Command::Spindle { on: true, duty: spindle_duty(cx.settings, self.spindle_rpm) }),
            Some(Spindle::Off) => Some(Command::Spindle { on: false, duty: 0 }),
            _ if s.is_some() && self.spindle_on => Some(Command::Spindle { on: true, duty: spindle_duty(cx.settings, self.spindle_rpm) }),
            _ => None,
        }
    }

    /// M codes of the "other" group: M220 here, the rest for the controller.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn other_m(&mut self, l: &Line, code: u16) -> Result<Option<Command>, Error> {
        Ok(Some(match code {
            17 | 18 | 84 | 400 | 500 | 501 | 502 => Command::M(code),
            92 | 201 | 203 => {
                let mut values = [f32::NAN; N_AXES];
                for (a, &w) in [Word::X, Word::Y, Word::Z, Word::E].iter().enumerate() {
                    if let Some(v) = l.word(w) {
                        values[a] = v;
                    }
                }
                Command::AxisSettings { code, values }
            }
            220 => {
                let s = l.word(Word::S).ok_or(Error::BadWord(F!("M220 needs S<percent>")))?;
                if !(10.0..=500.0).contains(&s) {
                    return Err(Error::BadWord(F!("M220 S must be 10-500")));
                }
                Command::FeedOverride { pct: round_i32(s) as u16 }
            }
            108 => return Ok(None),
            _ => return Err(Error::NotAvailable(F!("M code not supported"))),
        }))
    }
}

/// The line's S word as a spindle speed: on a G4 line without P, S is the
/// dwell in seconds (grbl, Marlin), otherwise the speed (RS274/NGC:
/// `G4 P.5 G0 X10 S1000 M3` dwells, then starts the spindle at 1000).
#[inline]
pub(super) fn spindle_speed(l: &Line) -> Option<f32> {
    // The usual line has no S: one mask test.
    let s = l.word(Word::S)?;
    if l.non_modal == Some(NonModal::Dwell) && !l.words.contains(Word::P) {
        return None;
    }
    // M220's S is its percentage, not a speed.
    if l.other_m == Some(220) {
        return None;
    }
    Some(s)
}

fn spindle_duty(s: &Settings, rpm: f32) -> u8 {
    let rpm = if rpm > 0.0 && rpm < s.spindle_min_rpm { s.spindle_min_rpm } else { rpm };
    let d = rpm / s.spindle_max_rpm * 255.0;
    if d <= 0.0 {
        0
    } else if d >= 255.0 {
        255
    } else {
        let v = round_i32(d) as u8;
        v.max(1)
    }
}
