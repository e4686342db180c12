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
        // A running job: its time so far and the time left, estimated from
        // the progress by the cut.
        7 if matches!(v.job, Phase::Running | Phase::Draining(_))
            && !matches!(v.state, State::Alarm | State::Hold)
            && v.interrupted.is_none() =>
        {
            job_time(v, l)
        }
        // A job stopped on a bad line: why (the refusal's first words).
        7 if matches!(v.job, Phase::Ended(Outcome::BadLine(_) | Outcome::NotResumed(_)))
            && v.job_why.is_some()
            && v.state != State::Alarm =>
        {
            if let Some(why) = v.job_why {
                let mut w = LineWriter { l, at: 0, mid_word: false };
                ufmt::uwrite!(w, "{}", why).ok();
                if w.mid_word {
                    // Cut at the last whole word.
                    let keep = l.chars.iter().rposition(|&c| c == b' ').unwrap_or(COLS);
                    l.chars[keep..].fill(b' ');
                }
            }
        }
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
        // Run from line: the scan's progress toward the line.
        Phase::Scanning(n) => {
            let c = l.text(0, Text::JobScanning);
            l.uint(c, n);
            pct(l);
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
            Outcome::NotResumed(n) => {
                let c = l.text(0, Text::JobNotResumed);
                l.uint(c, n);
            }
        },
    }
}

/// `Time m:ss Left m:ss` (h:mm:ss past an hour, without the `Time ` label
/// when that does not fit); the time left is `elapsed × (1000 − ‰) / ‰` of
/// the progress by the cut, shown from 1 % on.
fn job_time(v: &View, l: &mut Line) {
    let s = v.job_s as u32;
    let pm = v.job_pct as u32 * 10;
    let left = (pm >= 10).then(|| s * (1000 - pm.min(1000)) / pm);
    let long = s >= 3600 || left.is_some_and(|t| t >= 3600);
    let c = if long { 0 } else { l.text(0, Text::TimeLabel) };
    let c = clock(l, c, s);
    let c = l.text(c, Text::LeftLabel);
    match left {
        Some(t) => clock(l, c, t),
        None => l.put(c, b"-:--"),
    };
}

/// `m:ss`, or `h:mm:ss` from an hour on; returns the column after it.
fn clock(l: &mut Line, at: usize, s: u32) -> usize {
    let two = |l: &mut Line, at: usize, v: u32| l.put(at, &[b'0' + (v / 10) as u8, b'0' + (v % 10) as u8]);
    let c = if s >= 3600 {
        let c = l.uint(at, s / 3600);
        let c = l.put(c, b":");
        two(l, c, s / 60 % 60)
    } else {
        l.uint(at, s / 60)
    };
    let c = l.put(c, b":");
    two(l, c, s % 60)
}

/// Text written into a [`Line`] from a column on (cut at its end).
struct LineWriter<'a> {
    l: &'a mut Line,
    at: usize,
    /// The cut fell inside a word.
    mid_word: bool,
}

impl ufmt::uWrite for LineWriter<'_> {
    type Error = core::convert::Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Self::Error> {
        let next = COLS.checked_sub(self.at).and_then(|i| s.as_bytes().get(i).copied());
        self.at = self.l.put(self.at, s.as_bytes());
        if let Some(c) = next {
            self.mid_word = c != b' ' && self.l.chars[COLS - 1] != b' ';
        }
        Ok(())
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
