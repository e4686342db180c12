//! Tool numbers on a line: whether it changes tools (M6, or T with
//! `$151=1`), a T/H/D/G10 L1 P/M61 Q word as a pocket of the tool table,
//! and M61's words (the operator's answer after an interrupted change).

use super::command::Command;
use super::error::Error;
use super::Ctx;
use crate::gcode::{Line, Word};
use crate::math::round_i32;

/// True when the line changes tools: M6 (with or without a T word), or,
/// with the Repetier setting `$151=1`, a T word alone. By default (NGC) a T
/// word alone only selects the tool the next M6 changes to.
pub(super) fn is_tool_change(cx: &Ctx, l: &Line) -> bool {
    l.tool_change || (cx.settings.immediate_tool_change && l.words.contains(Word::T))
}

/// The pocket of the tool numbered `v` (a T, H, D, G10 L1 P or M61 Q word):
/// a whole number the tool table has; 0 is the empty spindle.
pub(super) fn tool_pocket(cx: &Ctx, v: f32) -> Option<usize> {
    let t = whole_in(v, 0, 255)?;
    cx.atc.table.pocket_of(t).map(usize::from)
}

/// `v` as a whole number within `lo..=hi`.
pub(super) fn whole_in(v: f32, lo: i32, hi: i32) -> Option<u8> {
    let n = round_i32(v);
    (n as f32 == v && (lo..=hi).contains(&n)).then_some(n as u8)
}

/// M61's words: `Q<tool>` (a tool of the tool table, 0: empty), or
/// `P<1-12> S<0|1>`.
// stack: a frame of its own, off Interp::start's (ldd reach; see its doc)
#[inline(never)]
pub(super) fn m61(cx: &Ctx, l: &Line) -> Result<Command, Error> {
    let whole = |v: f32, lo: i32, hi: i32| {
        let n = round_i32(v);
        (n as f32 == v && (lo..=hi).contains(&n)).then_some(n as u8)
    };
    let bad = Error::Atc(crate::atc::Fault::M61Words);
    match (l.word(Word::Q), l.word(Word::P), l.word(Word::S)) {
        (Some(q), None, None) => Ok(Command::ConfirmTool { tool: tool_pocket(cx, q).ok_or(bad)? as u8 }),
        (None, Some(p), Some(s)) => {
            let pocket = whole(p, 1, 12).ok_or(bad)?;
            let full = whole(s, 0, 1).ok_or(bad)? == 1;
            Ok(Command::SetPocket { pocket, full })
        }
        _ => Err(bad),
    }
}
