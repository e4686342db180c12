//! The first checks of a line, before its modal words: the SD-job filter,
//! the codes that work in any state (reports, M61, M999, M112), the alarm
//! and interrupted-change locks, the words that need no modal state, and
//! LinuxCNC's rule against words no code on the line uses.

use super::command::{Command, Report};
use super::error::{grbl, Error};
use super::mcodes::spindle_speed;
use super::modal::ModalCopy;
use super::tool_words::{is_tool_change, m61};
use super::{has_axis_words, Ctx};
use crate::gcode::{Coolant, CutterComp, Line, Motion, NonModal, PathMode, Spindle, ToolLength, Word};

/// The checks and commands before the modal state: the SD-job filter, the
/// codes that work in any state, the alarm and interrupted-change locks and
/// the validation of words that need no modal state. `Some` ends the line.
///
/// A line that is only a move, outside an SD job's status filter
/// (`move_only`, from [`move_only`]), is checked here, in the caller's
/// frame; the rest in [`early_other`].
// speed: inlined into Interp::start, a streamed move spares early_other's
// call and its 18-register frame (profile --trace 20 441 → 20 289 cycles a line)
#[inline(always)]
pub(super) fn early(cx: &Ctx, l: &Line, move_only: bool, extras: &mut bool) -> Option<Result<Option<Command>, Error>> {
    if move_only {
        return move_checks(cx, l, extras);
    }
    early_other(cx, l, extras)
}

/// True when [`early`] takes its short path: the line is only a move
/// ([`only_a_move`]: no non-modal code, only words of [`ALWAYS_USED`]) and
/// no SD job filters it.
#[inline(always)]
pub(super) fn move_only(cx: &Ctx, l: &Line) -> bool {
    !cx.status_only && only_a_move(l)
}

/// [`early`] for the lines its fast path leaves: the SD-job filter first.
// stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
#[inline(never)]
fn early_other(cx: &Ctx, l: &Line, extras: &mut bool) -> Option<Result<Option<Command>, Error>> {
    // During an SD job the serial line may only ask for status (docs/SPEC.md §9).
    if cx.status_only {
        let status_only = l.motion.is_none()
            && !has_axis_words(l)
            && l.non_modal.is_none()
            && l.spindle.is_none()
            && l.coolant.is_none()
            && !l.tool_change
            && l.stopping.is_none()
            && matches!(l.other_m, Some(31 | 114 | 115 | 119 | 220 | 503));
        if !status_only {
            return Some(Err(Error::JobRunning));
        }
    }
    // A line that is only a move took `early`'s path (under the status
    // filter it has no M code: refused above).
    // Commands that work in any state first.
    if let Some(code) = l.other_m {
        let c = match code {
            115 => Some(Command::Report(Report::Firmware)),
            114 => Some(Command::Report(Report::Position)),
            // Senders (printcore, Pronterface, OctoPrint) poll M105 for
            // temperatures; a mill has no heaters, so it reports none
            // rather than an error every few seconds.
            105 => Some(Command::Report(Report::Temperatures)),
            119 => Some(Command::Report(Report::Switches)),
            503 => Some(Command::Report(Report::Settings)),
            31 => Some(Command::Report(Report::PrintTime)),
            61 => return Some(m61(cx, l).map(Some)),
            999 => Some(Command::ClearAlarm),
            110 => return Some(Ok(None)), // handled by the line checker
            // The RX interrupt's scanner has usually raised it already.
            112 => Some(Command::EmergencyStop),
            _ => None,
        };
        if c.is_some() {
            return Some(Ok(c));
        }
    }
    early_checks(cx, l, extras)
}

/// The words of a line that is only a move: a point (X, Y, Z, `@`, `^`),
/// E, F.
const MOVE_WORDS: u32 = Word::mask(&[Word::X, Word::Y, Word::Z, Word::At, Word::Caret, Word::E, Word::F]);

// `Interp::start` skips the unused-word test for a line that is only a
// move: its words must all be among those any line may carry.
const _: () = assert!(MOVE_WORDS & !ALWAYS_USED == 0);

/// True when `l` has nothing but a move: no M code, no non-modal code, no
/// spindle, coolant, tool change or stop, and only [`MOVE_WORDS`] (a
/// streamed `G1 X.. Y..`).
#[inline(always)]
fn only_a_move(l: &Line) -> bool {
    l.other_m.is_none()
        && l.non_modal.is_none()
        && l.spindle.is_none()
        && l.coolant.is_none()
        && !l.tool_change
        && l.stopping.is_none()
        && l.words.within(MOVE_WORDS)
}

/// [`early_checks`] for a line that is [`only_a_move`], with the tests that
/// cannot refuse it left out (no M code, no spindle, no T or S: ~250
/// cycles a streamed line on the AVR). The reference, every line through
/// `early_checks`: `early_on_a_move_matches_the_full_checks`.
#[inline(always)]
fn move_checks(cx: &Ctx, l: &Line, extras: &mut bool) -> Option<Result<Option<Command>, Error>> {
    let moves = l.motion.is_some() || has_axis_words(l) || l.words.contains(Word::E);
    if moves && cx.alarm {
        return Some(Err(Error::Alarm));
    }
    if moves && cx.atc.interrupted.is_some() {
        return Some(Err(Error::Atc(crate::atc::Fault::Interrupted)));
    }
    if let Some(f) = l.word(Word::F) {
        if let Some(e) = feed_error(f) {
            return Some(Err(e));
        }
    }
    *extras = false;
    None
}

/// The F word's check: not negative, not zero.
// flash: one copy for both paths of `early`
#[inline(never)]
fn feed_error(f: f32) -> Option<Error> {
    if f < 0.0 {
        return Some(Error::Coded(grbl::NEGATIVE, F!("F must not be negative")));
    }
    if !(f > 0.0) {
        return Some(Error::BadFeed);
    }
    None
}

/// The locks and the validation of [`early`]; `extras`: the line has more
/// than its motion (T, M6, S, M3/M5, M7–M9), from the lookups made here.
pub(super) fn early_checks(cx: &Ctx, l: &Line, extras: &mut bool) -> Option<Result<Option<Command>, Error>> {
    let moves = l.motion.is_some()
        || has_axis_words(l)
        || l.words.contains(Word::E)
        || l.non_modal.is_some()
        || l.spindle == Some(Spindle::Cw)
        || matches!(l.coolant, Some(Coolant::Mist | Coolant::Flood))
        || l.tool_change
        || l.words.contains(Word::T)
        || l.other_m.is_some()
        || l.stopping.is_some();
    if l.non_modal == Some(NonModal::AuxReport) {
        return Some(Ok(Some(Command::CarouselReport)));
    }
    let harmless = matches!(l.other_m, Some(500..=502) | Some(17) | Some(18) | Some(84)) || l.spindle == Some(Spindle::Off);
    if cx.alarm && moves {
        let homing_allowed = l.non_modal == Some(NonModal::Home) && !cx.estop;
        if !homing_allowed && !harmless {
            return Some(Err(Error::Alarm));
        }
    }
    // After an interrupted tool change nothing moves until M61 confirms the spindle.
    if cx.atc.interrupted.is_some() && moves && !harmless {
        return Some(Err(Error::Atc(crate::atc::Fault::Interrupted)));
    }

    // ---- Validate everything before changing anything -----------------
    if l.spindle == Some(Spindle::Ccw) {
        return Some(Err(Error::SpindleCcw));
    }
    let tool = l.tool();
    if let Some(t) = tool.filter(|&t| cx.atc.table.pocket_of(t).is_none()) {
        return Some(Err(Error::NoPocket(t)));
    }
    if is_tool_change(cx, l) && (l.motion.is_some() || has_axis_words(l) || l.non_modal.is_some()) {
        return Some(Err(Error::Atc(crate::atc::Fault::WithMotion)));
    }
    if let Some(code) = l.other_m {
        if (20..=29).contains(&code) {
            return Some(Err(Error::NotAvailable(F!("SD card not available in this build"))));
        }
    }
    if let Some(f) = l.word(Word::F) {
        if let Some(e) = feed_error(f) {
            return Some(Err(e));
        }
    }
    let s_word = spindle_speed(l);
    if let Some(s) = s_word {
        if s < 0.0 {
            return Some(Err(Error::Coded(grbl::NEGATIVE, F!("S must not be negative"))));
        }
    }
    *extras = l.tool_change
        || l.spindle.is_some()
        || l.coolant.is_some()
        || tool.is_some()
        || s_word.is_some()
        || l.non_modal == Some(NonModal::Dwell);
    None
}

/// The words any line may carry: F, S, T, and the words of a point (X, Y,
/// Z, `@`, `^`, E), which the motion checks itself (no motion mode, E only
/// with G0/G1). A streamed line has only these: one mask test.
pub(super) const ALWAYS_USED: u32 = Word::mask(&[Word::F, Word::S, Word::T, Word::X, Word::Y, Word::Z, Word::At, Word::Caret, Word::E]);

/// LinuxCNC's rule, which grbl shares (error 20/36): a word that no code on
/// the line uses is an error ("R word with no g code that uses it"), not
/// silently dropped (`G61 R0.5`, `G0 X1 I2`). `g` holds the line's modal
/// state: I, J, K, R belong to an arc, R, L, P (G82, G89) and Q (G73, G83)
/// to a canned cycle, when the line moves.
// stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
#[inline(never)]
pub(super) fn unused_word(l: &Line, g: &ModalCopy) -> Result<(), Error> {
    use Word::*;
    // Consts: a mask built at run time would keep its word list in RAM.
    const ARC: u32 = Word::mask(&[I, J, K, R]);
    const CYCLE: u32 = Word::mask(&[R, L]);
    const P_: u32 = Word::mask(&[P]);
    const Q_: u32 = Word::mask(&[Q]);
    const PQ: u32 = Word::mask(&[P, Q]);
    const G10: u32 = Word::mask(&[L, P, R]);
    const G37: u32 = Word::mask(&[B, D, L, R]);
    const H_: u32 = Word::mask(&[H]);
    const N_: u32 = Word::mask(&[N]);
    const D_: u32 = Word::mask(&[D]);
    let mut used = ALWAYS_USED;
    let moves = has_axis_words(l) || l.motion.is_some();
    match g.motion {
        Motion::ArcCw | Motion::ArcCcw if moves => used |= ARC,
        Motion::Cycle(kind) if moves => {
            used |= CYCLE;
            if kind.dwells() {
                used |= P_;
            }
            if kind.pecks() {
                used |= Q_;
            }
        }
        _ => {}
    }
    used |= match l.non_modal {
        Some(NonModal::Dwell) => P_,
        // G10 L1 P<tool> Q<pocket>: the tool numbers.
        Some(NonModal::SetOffsets) if l.word(L) == Some(1.0) => G10 | Q_,
        Some(NonModal::SetOffsets) => G10,
        Some(NonModal::MeasureTool) => G37,
        Some(NonModal::AuxMove | NonModal::AuxSetPosition | NonModal::AuxReport | NonModal::AuxEnable | NonModal::AuxHome) => P_,
        _ => 0,
    };
    if l.path_mode == Some(PathMode::Blend) {
        used |= PQ;
    }
    if l.tool_length == Some(ToolLength::Apply) {
        used |= H_;
    }
    // G41/G42 D<tool>, G41.1/G42.1 D<diameter>.
    if l.cutter_comp.is_some_and(|c| c != CutterComp::Off) {
        used |= D_;
    }
    match l.other_m {
        Some(61) => used |= PQ,
        Some(110) => used |= N_,
        _ => {}
    }
    match l.words.first_outside(used) {
        Some(w) => Err(Error::UnusedWord(w)),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Settings;

    #[test]
    fn early_on_a_move_matches_the_full_checks() {
        // Lines of words drawn from moves and from everything else a line
        // may carry, in every lock state: a move takes the short path, and
        // it and the full checks give the same answer and the same `extras`
        // (and none takes it under the SD job's status filter).
        const WORDS: [&str; 24] = [
            "G0", "G1", "G2", "G38.2", "X1", "Y-2", "Z.5", "@3", "^45", "E2", "F100", "F0", "F-5", "S1000", "S-1", "T2", "T99", "M3", "M4",
            "M5", "M6", "M8", "G4 P1", "M114",
        ];
        let mut rng = crate::test_util::XorShift(0x2545_F491);
        let mut atc = crate::atc::Atc::new();
        let mut settings = Settings::DEFAULT;
        let (mut short, mut total) = (0, 0);
        for i in 0..40_000 {
            let x = rng.next();
            let mut text = String::new();
            for (k, w) in WORDS.iter().enumerate() {
                // Move words often, the others seldom.
                let p = if k < 13 { 3 } else { 14 };
                if (x >> (k % 24)).wrapping_mul(2_654_435_761).is_multiple_of(p) {
                    text.push_str(w);
                    text.push(' ');
                }
            }
            let Ok(l) = crate::gcode::parse(text.as_bytes()) else { continue };
            atc.interrupted = (i % 5 == 1).then_some(crate::atc::Journal { from: 1, to: 2 });
            settings.immediate_tool_change = i % 7 == 3;
            let cx = Ctx { settings: &settings, atc: &atc, alarm: i % 3 == 2, estop: i % 6 == 5, status_only: false };
            let (mut e1, mut e2) = (true, true);
            let fast = early(&cx, &l, move_only(&cx, &l), &mut e1);
            let plain = early_checks(&cx, &l, &mut e2);
            total += 1;
            if only_a_move(&l) {
                // What `Interp::start` then leaves untested.
                assert!(l.words.within(ALWAYS_USED) && l.non_modal.is_none(), "{text}");
                short += 1;
                assert_eq!(fast, plain, "{text}");
                assert_eq!(e1, e2, "{text}");
            }
            // Under an SD job's status filter every line takes the full
            // path: the same answer as `early_other` on its own.
            let cx = Ctx { status_only: true, ..cx };
            let (mut e1, mut e2) = (true, true);
            assert_eq!(early(&cx, &l, move_only(&cx, &l), &mut e1), early_other(&cx, &l, &mut e2), "{text}");
            assert_eq!(e1, e2, "{text}");
        }
        assert!(short > 5_000 && total - short > 5_000, "{short} of {total}");
    }
}
