//! Which modal group each G and M code goes in: a code recorded in its
//! slot of the [`Line`], or rejected (unsupported, or a second code of the
//! same group).

use super::codes::{
    is_other_m, Coolant, CutterComp, Distance, FeedMode, Motion, NonModal, PathMode, Plane, Spindle, Stopping, ToolLength, Units,
};
use super::error::{err, ParseError, ParseErrorKind};
use super::line::Line;
use crate::gcode::cycles::{Kind, Retract};

/// Put `v` in a modal group slot, or report the conflict at `col`.
fn set_group<T>(slot: &mut Option<T>, v: T, col: u8) -> Result<(), ParseError> {
    if slot.is_some() {
        return err(ParseErrorKind::ModalGroupConflict, col);
    }
    *slot = Some(v);
    Ok(())
}

/// Record G code `code_x10` (G38.2 → 382) in `line`.
pub(super) fn apply_g(line: &mut Line, code_x10: u16, col: u8) -> Result<(), ParseError> {
    match code_x10 {
        0 => set_group(&mut line.motion, Motion::Rapid, col),
        10 => set_group(&mut line.motion, Motion::Linear, col),
        20 => set_group(&mut line.motion, Motion::ArcCw, col),
        30 => set_group(&mut line.motion, Motion::ArcCcw, col),
        382 => set_group(&mut line.motion, Motion::ProbeToward, col),
        383 => set_group(&mut line.motion, Motion::ProbeTowardNoError, col),
        800 => set_group(&mut line.motion, Motion::Cancel, col),
        730 => set_group(&mut line.motion, Motion::Cycle(Kind::ChipBreak), col),
        810 => set_group(&mut line.motion, Motion::Cycle(Kind::Drill), col),
        820 => set_group(&mut line.motion, Motion::Cycle(Kind::DrillDwell), col),
        830 => set_group(&mut line.motion, Motion::Cycle(Kind::Peck), col),
        850 => set_group(&mut line.motion, Motion::Cycle(Kind::Bore), col),
        890 => set_group(&mut line.motion, Motion::Cycle(Kind::BoreDwell), col),
        760 | 840 | 860 | 870 | 880 => err(ParseErrorKind::UnsupportedCycle, col),
        980 => set_group(&mut line.retract, Retract::Initial, col),
        990 => set_group(&mut line.retract, Retract::RPlane, col),
        170 => set_group(&mut line.plane, Plane::Xy, col),
        180 => set_group(&mut line.plane, Plane::Zx, col),
        190 => set_group(&mut line.plane, Plane::Yz, col),
        200 => set_group(&mut line.units, Units::Inch, col),
        210 => set_group(&mut line.units, Units::Mm, col),
        900 => set_group(&mut line.distance, Distance::Absolute, col),
        910 => set_group(&mut line.distance, Distance::Incremental, col),
        940 => set_group(&mut line.feed_mode, FeedMode::UnitsPerMinute, col),
        540 | 550 | 560 | 570 | 580 | 590 => set_group(&mut line.wcs, ((code_x10 - 540) / 10) as u8, col),
        430 => set_group(&mut line.tool_length, ToolLength::Apply, col),
        490 => set_group(&mut line.tool_length, ToolLength::Cancel, col),
        40 => set_group(&mut line.non_modal, NonModal::Dwell, col),
        400 => set_group(&mut line.cutter_comp, CutterComp::Off, col),
        410 => set_group(&mut line.cutter_comp, CutterComp::Left, col),
        420 => set_group(&mut line.cutter_comp, CutterComp::Right, col),
        411 => set_group(&mut line.cutter_comp, CutterComp::LeftDiameter, col),
        421 => set_group(&mut line.cutter_comp, CutterComp::RightDiameter, col),
        610 => set_group(&mut line.path_mode, PathMode::ExactPath, col),
        611 => set_group(&mut line.path_mode, PathMode::ExactStop, col),
        640 => set_group(&mut line.path_mode, PathMode::Blend, col),
        901 => set_group(&mut line.arc_absolute, true, col),
        911 => set_group(&mut line.arc_absolute, false, col),
        921 | 922 => set_group(&mut line.non_modal, NonModal::ClearG92, col),
        100 => set_group(&mut line.non_modal, NonModal::SetOffsets, col),
        280 => set_group(&mut line.non_modal, NonModal::Home, col),
        530 => set_group(&mut line.non_modal, NonModal::MachineCoords, col),
        920 => set_group(&mut line.non_modal, NonModal::SetPosition, col),
        370 => set_group(&mut line.non_modal, NonModal::MeasureTool, col),
        2010 => set_group(&mut line.non_modal, NonModal::AuxMove, col),
        2020 => set_group(&mut line.non_modal, NonModal::AuxSetPosition, col),
        2030 => set_group(&mut line.non_modal, NonModal::AuxReport, col),
        2040 => set_group(&mut line.non_modal, NonModal::AuxEnable, col),
        2050 => set_group(&mut line.non_modal, NonModal::AuxHome, col),
        _ => err(ParseErrorKind::UnsupportedCode, col),
    }
}

/// Record M code `code` in `line`.
pub(super) fn apply_m(line: &mut Line, code: u16, col: u8) -> Result<(), ParseError> {
    match code {
        0 => set_group(&mut line.stopping, Stopping::Pause, col),
        1 => set_group(&mut line.stopping, Stopping::OptionalPause, col),
        2 => set_group(&mut line.stopping, Stopping::End, col),
        30 => set_group(&mut line.stopping, Stopping::EndRewind, col),
        3 => set_group(&mut line.spindle, Spindle::Cw, col),
        4 => set_group(&mut line.spindle, Spindle::Ccw, col),
        5 => set_group(&mut line.spindle, Spindle::Off, col),
        // M7 and M8 may share a line (LinuxCNC): both switch the one output on.
        7 | 8 if matches!(line.coolant, Some(Coolant::Mist | Coolant::Flood)) && line.coolant != Some(coolant_of(code)) => {
            line.coolant = Some(Coolant::Flood);
            Ok(())
        }
        7..=9 => set_group(&mut line.coolant, coolant_of(code), col),
        6 if line.tool_change => err(ParseErrorKind::ModalGroupConflict, col),
        6 => {
            line.tool_change = true;
            Ok(())
        }
        _ if is_other_m(code) => set_group(&mut line.other_m, code, col),
        62..=65 => err(ParseErrorKind::NoOutputs, col),
        _ => err(ParseErrorKind::UnsupportedCode, col),
    }
}

/// The coolant code of M7, M8, M9.
fn coolant_of(code: u16) -> Coolant {
    match code {
        7 => Coolant::Mist,
        8 => Coolant::Flood,
        _ => Coolant::Off,
    }
}
