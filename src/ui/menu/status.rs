//! The status screen: the machine state and tool, the work position (in
//! double-size digits on the big variant), feed, spindle, the job or the
//! host's message, the alarm, and what the button does now.

use super::view::View;
use crate::machine::{Alarm, State};
use crate::ui::render::{Line, Style, BIG_COLS, COLS};
use crate::ui::sd::{Outcome, Phase};
use crate::ui::text::Text;

/// The machine state's name on the display.
/// (`Not homed` for Idle before the axes are homed: the position means
/// nothing yet.)
pub fn state_text(s: State, homed: bool) -> Text {
    match s {
        State::Idle if !homed => Text::StNotHomed,
        State::Idle | State::Check => Text::StIdle,
        State::Run | State::Jog => Text::StRun,
        State::Hold => Text::StHold,
        State::Alarm => Text::StAlarm,
        State::Home => Text::StHoming,
        State::Tool => Text::StTool,
        State::Probe => Text::StProbe,
    }
}

/// The status screen to read from a step away: the state and the tool,
/// the work position in double-size digits, then the feed (or the alarm).
// layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
#[inline(never)]
pub(super) fn big_status_line(row: usize, v: &View, tool: u8, host: &crate::hostcodes::HostState, l: &mut Line) {
    match row {
        1..=6 => {
            let a = (row - 1) / 2;
            l.style = if row % 2 == 1 { Style::BigTop } else { Style::BigBottom };
            l.put(0, &[b"XYZ"[a]]);
            l.micros_right(BIG_COLS, v.wpos_um[a]);
        }
        7 if v.alarm.is_some() => alarm_line(v, l),
        7 => status_line(4, v, tool, host, l),
        _ => status_line(0, v, tool, host, l),
    }
}

pub(super) fn status_line(row: usize, v: &View, tool: u8, host: &crate::hostcodes::HostState, l: &mut Line) {
    match row {
        0 => {
            l.invert = true;
            l.style = Style::Title;
            l.text(1, state_text(v.state, v.homed));
            let c = l.put(COLS - 4, b"T");
            l.uint(c, tool as u32);
        }
        1..=3 => {
            l.put(0, &[b"XYZ"[row - 1]]);
            l.micros_right(12, v.wpos_um[row - 1]);
            l.text(12, Text::Mm);
        }
        4 => {
            l.put(0, b"F");
            l.uint_right(7, v.feed as u32);
            l.text(8, Text::MmMin);
            l.uint_right(COLS - 1, v.override_pct as u32);
            l.text(COLS - 1, Text::Pct);
        }
        // In an alarm the spindle is off: the line says which alarm.
        5 if v.alarm.is_some() => alarm_line(v, l),
        5 => {
            l.put(0, b"S");
            if v.rpm == 0 {
                l.text(2, Text::Off);
            } else {
                l.uint_right(7, v.rpm as u32);
                l.text(8, Text::Rpm);
            }
        }
        // An interrupted change outranks the job: nothing moves until confirmed.
        6 if v.interrupted.is_some() => {
            l.text(0, Text::ChangeCut);
        }
        // No SD job: what the host says (M117 message, M73 progress).
        6 if matches!(v.job, Phase::Idle | Phase::Writing) && (host.msg_len > 0 || host.percent().is_some()) => {
            l.put(0, host.message());
            if let Some(p) = host.percent() {
                l.put(COLS - 5, b"     ");
                l.uint_right(COLS - 1, p as u32);
                l.text(COLS - 1, Text::Pct);
            }
        }
        6 => job_status(v, l),
        7 => {
            l.text(
                0,
                if v.state == State::Alarm {
                    Text::HintRecover
                } else if v.interrupted.is_some() {
                    Text::HintConfirm
                } else if v.state == State::Hold && !matches!(v.job, Phase::Aborting(_)) {
                    Text::HintResume
                } else {
                    Text::HintMenu
                },
            );
        }
        _ => {}
    }
}

// layout: without it the landing pad cannot be linked (menu/mod.rs, Inlining)
#[inline(never)]
fn job_status(v: &View, l: &mut Line) {
    let pct = |l: &mut Line| {
        l.uint_right(COLS - 1, v.job_pct as u32);
        l.text(COLS - 1, Text::Pct);
    };
    match v.job {
        Phase::Idle | Phase::Writing => {
            l.text(0, Text::NoJob);
        }
        Phase::Selected => {
            l.put(0, v.job_name.as_bytes());
        }
        Phase::Running | Phase::Draining(_) => {
            l.put(0, v.job_name.as_bytes());
            pct(l);
        }
        Phase::Paused => {
            l.text(0, Text::JobPaused);
            pct(l);
        }
        Phase::Aborting(Outcome::CardRemoved(n)) => {
            let c = l.text(0, Text::JobCardOut);
            l.uint(c, n);
        }
        Phase::Aborting(_) => {
            l.text(0, Text::JobStopping);
        }
        Phase::Ended(o) => match o {
            Outcome::Done => {
                let c = l.text(0, Text::JobDone);
                l.put(c + 1, v.job_name.as_bytes());
            }
            Outcome::Aborted => {
                l.text(0, Text::JobAborted);
            }
            Outcome::BadLine(n) => {
                let c = l.text(0, Text::JobLine);
                l.uint(c, n);
            }
            Outcome::ReadError(_) => {
                l.text(0, Text::JobReadErr);
            }
            Outcome::CardRemoved(n) => {
                let c = l.text(0, Text::JobCardOut);
                l.uint(c, n);
            }
        },
    }
}

/// Which alarm, in the operator's words; a hard limit names its switch.
fn alarm_line(v: &View, l: &mut Line) {
    let t = match v.alarm {
        Some(Alarm::HardLimit) => Text::AlHardLimit,
        Some(Alarm::ProbeFailed) => Text::AlProbe,
        Some(Alarm::EmergencyStop) => Text::AlEstop,
        Some(Alarm::HomingFailed) => Text::AlHoming,
        Some(Alarm::WatchdogReset) => Text::AlWatchdog,
        Some(Alarm::CarouselHome) => Text::AlCarousel,
        Some(Alarm::BrokenTool) => Text::AlBrokenTool,
        Some(Alarm::ResetWhileMoving) => Text::AlResetMoving,
        None => return,
    };
    let mut c = l.text(0, t);
    if v.alarm == Some(Alarm::HardLimit) {
        for a in 0..3 {
            if v.limit_axes & (1 << a) != 0 {
                c = l.put(c + 1, &[b"XYZ"[a]]) - 1;
            }
        }
    }
}
