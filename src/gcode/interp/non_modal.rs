//! The non-modal codes that end their line: G4 (dwell), G10, G92/G92.1,
//! G28 (home), G37 (measure a tool) and the carousel codes G201–G205.

use super::command::Command;
use super::error::{grbl, Error};
use super::modal::ModalCopy;
use super::units::word_mm;
use super::{Ctx, Interp, AXIS_WORDS};
use crate::config::Settings;
use crate::gcode::{Line, NonModal, Word};
use crate::math::round_i32;

impl Interp {
    /// Non-modal codes that end the line (G4, G10, G92, G28, G37,
    /// G201–G205); `None` for the others (G53), which go on to the motion.
    // stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
    #[inline(never)]
    pub(super) fn non_modal(&mut self, cx: &Ctx, g: &ModalCopy, l: &Line) -> Option<Result<Option<Command>, Error>> {
        Some(match l.non_modal {
            // Checked here; run in its own phase, after the spindle and the
            // coolant of its line and before its motion.
            Some(NonModal::Dwell) => match dwell(cx.settings, l) {
                Ok(_) => return None,
                Err(e) => Err(e),
            },
            Some(NonModal::SetOffsets) => self.set_offsets(cx, g, l),
            Some(NonModal::SetPosition) => {
                let mut off = self.g92_mm;
                for (a, &w) in AXIS_WORDS.iter().enumerate() {
                    if let Some(v) = l.word(w) {
                        let v = word_mm(g.inches, a, v);
                        // work = machine - wcs - g92 - tlo  =>  g92 = machine - wcs - tlo - v
                        let tlo = if a == 2 { g.tlo } else { 0.0 };
                        off[a] = self.pos_mm[a] - self.wcs_mm[g.wcs as usize][a] - tlo - v;
                    }
                }
                g.commit(self);
                self.g92_mm = off;
                Ok(None)
            }
            Some(NonModal::ClearG92) => {
                g.commit(self);
                self.g92_mm = [0.0; 3];
                Ok(None)
            }
            Some(NonModal::Home) => {
                g.commit(self);
                let mut mask = 0u8;
                for (a, &w) in AXIS_WORDS.iter().enumerate() {
                    if l.word(w).is_some() {
                        mask |= 1 << a;
                    }
                }
                if mask == 0 {
                    mask = 0b111;
                }
                Ok(Some(Command::Home { mask }))
            }
            Some(NonModal::MeasureTool) => {
                g.commit(self);
                measure_mode(self.inches, l).map(|(mode, x_mm, y_mm)| Some(Command::Measure { mode, x_mm, y_mm }))
            }
            Some(nm @ (NonModal::AuxMove | NonModal::AuxSetPosition | NonModal::AuxEnable | NonModal::AuxHome)) => {
                g.commit(self);
                carousel_command(l, nm).map(Some)
            }
            _ => return None,
        })
    }
}

/// G4's time, in ms: P in seconds (RS274/NGC, grbl, LinuxCNC and every CAM
/// file of the corpus) or, with `$153=1`, in milliseconds (Mach3 and UCCNC
/// posts, Marlin: docs/gcode.md "G4"); without P, S in seconds (grbl, Marlin).
/// With P, an S on the line is the spindle speed.
pub(super) fn dwell(s: &Settings, l: &Line) -> Result<f32, Error> {
    let ms = match (l.word(Word::P), l.word(Word::S)) {
        (Some(p), _) if s.dwell_p_ms => p,
        (Some(secs), _) | (None, Some(secs)) => secs * 1000.0,
        (None, None) => return Err(Error::Coded(grbl::VALUE_MISSING, F!("G4 needs P (or S in seconds)"))),
    };
    if !(ms >= 0.0) {
        return Err(Error::Coded(grbl::NEGATIVE, F!("G4: the dwell must not be negative")));
    }
    Ok(ms)
}

/// G37's words as a measurement mode, with the setter position (mm) for a
/// calibration.
// stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
#[inline(never)]
fn measure_mode(inches: bool, l: &Line) -> Result<(crate::toolsetter::Mode, Option<f32>, Option<f32>), Error> {
    use crate::toolsetter::{Fault, Mode};
    let bad = Error::Setter(Fault::Words);
    let k = if inches { 25.4 } else { 1.0 };
    let um = |v: f32| round_i32(v * k * 1000.0);
    let (d, b, len, r) = (l.word(Word::D), l.word(Word::B), l.word(Word::L), l.word(Word::R));
    let (x, y) = (l.word(Word::X).map(|v| v * k), l.word(Word::Y).map(|v| v * k));
    let mode = match (d, b, len, r) {
        (None, None, None, None) => Mode::Length,
        (Some(1.0), None, None, None) => Mode::Diameter,
        (None, Some(t), None, None) if t >= 0.0 => Mode::Check { tol_um: um(t) },
        (None, None, Some(len), Some(r)) if len > 0.0 && r >= 0.0 => Mode::Calibrate { length_um: um(len), diameter_um: 2 * um(r) },
        _ => return Err(bad),
    };
    if (x.is_some() || y.is_some()) && !matches!(mode, Mode::Calibrate { .. }) {
        return Err(bad);
    }
    Ok((mode, x, y))
}

/// Largest |X| accepted by G201/G202, pitches (20 revolutions).
const CAROUSEL_MAX_X: f32 = 360.0;

/// G201, G202, G204, G205 (motor P0, the carousel): the words checked.
// stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
#[inline(never)]
fn carousel_command(l: &Line, nm: NonModal) -> Result<Command, Error> {
    use crate::atc::Fault;
    if l.word(Word::P) != Some(0.0) {
        return Err(Error::Atc(Fault::Motor));
    }
    let bit = |w: Word| match l.word(w) {
        None => Ok(None),
        Some(v) if v == 0.0 || v == 1.0 => Ok(Some(v == 1.0)),
        Some(_) => Err(Error::Atc(Fault::OnOff)),
    };
    let x = match l.word(Word::X) {
        Some(x) if x.abs() <= CAROUSEL_MAX_X => Some(x),
        Some(_) => return Err(Error::Atc(Fault::CarouselX)),
        None => None,
    };
    Ok(match nm {
        NonModal::AuxMove => Command::CarouselTurn { x: x.ok_or(Error::Atc(Fault::CarouselX))? },
        NonModal::AuxSetPosition => Command::CarouselSetPosition { x: x.ok_or(Error::Atc(Fault::CarouselX))? },
        NonModal::AuxEnable => Command::CarouselEnable { on: bit(Word::S)?.ok_or(Error::Atc(Fault::OnOff))? },
        _ => Command::CarouselHome { back: bit(Word::S)?.unwrap_or(false), only_if_unhomed: bit(Word::E)?.unwrap_or(false) },
    })
}
