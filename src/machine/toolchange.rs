//! The ATC's executor: performs the actions of [`crate::atc::change::Change`]
//! through the planner, keeps the EEPROM records in step with where the
//! tools are, loads them at boot, and serves M61 and G10 L1.
//!
//! Wire protocol (docs/SPEC.md §4, thesis log lines):
//! - `SelectTool:<n>` when a change starts, `NowSelectedTool:<n>` when it is
//!   complete; `busy:processing` every 2 s in between.
//! - `T<n>` for the tool already in the spindle does nothing and prints nothing.
//! - A change stopped by a fault leaves the "change in progress" record in
//!   EEPROM and refuses motion until `M61 Q<tool in spindle>`:
//!   `echo:tool change T<a>->T<b> interrupted: motion refused until M61 Q<tool in spindle>`.
//!
//! M61 (LinuxCNC's "set current tool", extended):
//! - `M61 Q<t>`: the operator confirms the spindle holds tool `t` (0 = empty).
//!   After an interrupted change the two tools of that change are put where
//!   the confirmation implies (see `ToolState::confirmed`), the record is
//!   cleared and motion is allowed again.
//! - `M61 P<p> S1` / `S0`: pocket `p` holds its tool / is empty (the operator
//!   loaded or took out a tool by hand).

use super::{carousel, Io, Machine, State, Storage};
use crate::atc::change::{Action, Change, Event, Request};
use crate::atc::tools::{
    pocket_bit, Journal, ToolState, ToolTable, EEPROM_JOURNAL_ADDR, EEPROM_NUMBERS_ADDR, EEPROM_SETTER_ADDR, EEPROM_STATE_ADDR,
    EEPROM_TABLE_ADDR,
};
use crate::atc::{tool_length_offset_mm, Fault};
use crate::gcode::interp::Error;
use crate::math::round_i32;
use crate::planner::Speed;
use crate::toolsetter::Setter;
use ufmt::{uwrite, uwriteln};

// The setter's record (toolsetter) ends before the tool numbers' (atc).
const _: () = assert!(EEPROM_SETTER_ADDR as usize + Setter::IMAGE_LEN <= EEPROM_NUMBERS_ADDR as usize);

/// Load the tool records and the tool setter's calibration (defaults when
/// blank) at boot, and say what the operator must know.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn boot(m: &mut Machine, io: &mut (impl Storage + ufmt::uWrite)) {
    let mut st = [0u8; ToolState::IMAGE_LEN];
    io.eeprom_read(EEPROM_STATE_ADDR, &mut st);
    match ToolState::from_bytes(&st) {
        Some(s) => m.atc.tools = s,
        None => {
            m.atc.tools = ToolState::FACTORY;
            uwriteln!(io, "{}", F!("echo:no tool record: spindle empty, pockets full assumed (M61)")).ok();
        }
    }
    let mut tb = [0u8; ToolTable::IMAGE_LEN];
    io.eeprom_read(EEPROM_TABLE_ADDR, &mut tb);
    if let Some(t) = ToolTable::from_bytes(&tb) {
        m.atc.table = t;
    }
    let mut nb = [0u8; ToolTable::NUMBERS_LEN];
    io.eeprom_read(EEPROM_NUMBERS_ADDR, &mut nb);
    m.atc.table.numbers = ToolTable::numbers_from_bytes(&nb).unwrap_or([crate::atc::tools::OWN_NUMBER; crate::atc::N_POCKETS]);
    let mut jb = [0u8; Journal::IMAGE_LEN];
    io.eeprom_read(EEPROM_JOURNAL_ADDR, &mut jb);
    m.atc.interrupted = Journal::from_bytes(&jb);
    let mut sb = [0u8; Setter::IMAGE_LEN];
    io.eeprom_read(EEPROM_SETTER_ADDR, &mut sb);
    m.setter = Setter::from_bytes(&sb).unwrap_or_else(Setter::factory);
    apply_offset(m);
    uwriteln!(io, "{}{}", F!("echo:tool in spindle: T"), m.atc.spindle_tool()).ok();
    report_interrupted(m, io);
}

/// The interrupted-change line, if a change is interrupted.
pub fn report_interrupted(m: &Machine, io: &mut impl ufmt::uWrite) {
    if let Some(j) = m.atc.interrupted {
        let (from, to) = (m.atc.table.number_of(j.from), m.atc.table.number_of(j.to));
        uwrite!(io, "{}{}->T{}", F!("echo:tool change T"), from, to).ok();
        uwriteln!(io, "{}", F!(" interrupted: motion refused until M61 Q<tool in spindle>")).ok();
    }
}

/// With auto offset on (the default), make the spindle tool's length the
/// active G43 offset.
pub fn apply_offset(m: &mut Machine) {
    if m.settings.auto_tool_offset {
        m.interp.tlo_mm = tool_length_offset_mm(m.atc.length_mm(m.atc.spindle()));
    }
}

/// `T<n>`, `M6 T<n>` or `M6` (the last T word): change to tool `to`.
// flash: one copy (the runners' attributes removed: +1034 B flash)
#[inline(never)]
pub fn select(m: &mut Machine, io: &mut impl Io, to: Option<u16>) -> Result<(), Error> {
    let to = match to {
        Some(t) => t,
        None if m.atc.last_t != 0xFF => m.atc.last_t as u16,
        None => return Err(Error::Atc(Fault::NoTool)),
    };
    if m.atc.interrupted.is_some() {
        return Err(Error::Atc(Fault::Interrupted));
    }
    m.wait_idle(io)?;
    let req = Request {
        to,
        tools: m.atc.tools,
        xyz_homed: m.homed & 0b111 == 0b111,
        carousel_homed: m.homed & carousel::HOMED_BIT != 0,
        xy_mm: [m.interp.pos_mm[0], m.interp.pos_mm[1]],
        travel_mm: m.settings.travel_mm,
    };
    let change = Change::new(&req, &m.settings.station).map_err(Error::Atc)?;
    m.atc.last_t = to as u8;
    let Some(mut c) = change else {
        return Ok(());
    };
    uwriteln!(io, "{}{}", F!("SelectTool:"), m.atc.table.number_of(to as u8)).ok();
    m.state = State::Tool;
    let mut journal = false;
    let mut failure = None;
    let mut a = c.start(&m.settings.station);
    loop {
        let ev = match a {
            Action::Done => break,
            Action::Abort(_) => {
                if journal {
                    m.atc.interrupted = Some(Journal { from: c.from(), to: c.to() });
                    report_interrupted(m, io);
                }
                if m.state == State::Tool {
                    m.state = State::Idle;
                }
                return Err(failure.unwrap_or(Error::Atc(Fault::Stopped)));
            }
            Action::BeginJournal(j) => {
                // The tool record first (a no-op unless it was blank or
                // stale), so a fault leaves both records valid.
                io.eeprom_write(EEPROM_STATE_ADDR, &m.atc.tools.to_bytes());
                io.eeprom_write(EEPROM_JOURNAL_ADDR, &Journal::to_bytes(Some(j)));
                journal = true;
                Event::Done
            }
            other => match perform(m, io, other) {
                Ok(()) => Event::Done,
                Err(e) => {
                    failure = Some(e);
                    Event::Failed(match e {
                        Error::Atc(f) => f,
                        _ => Fault::Stopped,
                    })
                }
            },
        };
        a = c.step(ev, &m.settings.station);
    }
    m.state = State::Idle;
    apply_offset(m);
    uwriteln!(io, "{}{}", F!("NowSelectedTool:"), m.atc.spindle_tool()).ok();
    Ok(())
}

/// One action of a change.
fn perform(m: &mut Machine, io: &mut impl Io, a: Action) -> Result<(), Error> {
    match a {
        // Stopped, and its spin-down waited, before the tool is released.
        Action::SpindleOff => m.spindle(io, false, 0)?,
        Action::Move { xyz, feed_mm_per_min } => {
            let mut t = m.interp.pos_mm;
            for (i, v) in xyz.iter().enumerate() {
                if let Some(v) = v {
                    t[i] = *v;
                }
            }
            m.move_mm(io, &t, feed_mm_per_min.map_or(Speed::Rapid, Speed::Fixed))?;
            m.wait_motion_or_trip(io)?;
        }
        Action::HomeCarousel => carousel::home(m, io)?,
        Action::Turn { position } => carousel::turn_to(m, io, position)?,
        Action::Store(s) => store_state(m, io, s),
        Action::EndJournal => clear_journal(io),
        Action::BeginJournal(_) | Action::Done | Action::Abort(_) => {}
    }
    Ok(())
}

/// Keep `s` as where the tools are, in RAM and EEPROM.
fn store_state(m: &mut Machine, io: &mut impl Storage, s: ToolState) {
    m.atc.tools = s;
    io.eeprom_write(EEPROM_STATE_ADDR, &s.to_bytes());
}

/// Mark "no change in progress" (only the marker and checksum change).
fn clear_journal(io: &mut impl Storage) {
    let mut jb = [0u8; Journal::IMAGE_LEN];
    io.eeprom_read(EEPROM_JOURNAL_ADDR, &mut jb);
    if Journal::from_bytes(&jb).is_some() {
        io.eeprom_write(EEPROM_JOURNAL_ADDR, &Journal::cleared(jb));
    }
}

/// Store the tool table (lengths and diameters, and the numbers' record)
/// where it differs from `before`.
pub fn store_table(m: &Machine, io: &mut impl Storage, before: &ToolTable) {
    let t = &m.atc.table;
    if t.length_um != before.length_um || t.diameter_um != before.diameter_um {
        io.eeprom_write(EEPROM_TABLE_ADDR, &t.to_bytes());
    }
    if t.numbers != before.numbers {
        io.eeprom_write(EEPROM_NUMBERS_ADDR, &t.numbers_to_bytes());
    }
}

/// M61 Q<t>: the spindle holds tool `t` (0 = empty); see the module docs.
pub fn confirm_tool(m: &mut Machine, io: &mut (impl Storage + ufmt::uWrite), t: u8) {
    let s = m.atc.tools.confirmed(t, m.atc.interrupted);
    store_state(m, io, s);
    if m.atc.interrupted.take().is_some() {
        clear_journal(io);
    }
    apply_offset(m);
    uwriteln!(io, "{}{}", F!("echo:tool in spindle: T"), m.atc.spindle_tool()).ok();
}

/// M61 P<p> S<0|1>: pocket `p` holds its tool (`full`) or is empty.
pub fn set_pocket(m: &mut Machine, io: &mut impl Storage, p: u8, full: bool) -> Result<(), Error> {
    if full && p == m.atc.spindle() {
        return Err(Error::Atc(Fault::PocketOfSpindleTool));
    }
    let mut st = m.atc.tools;
    st.occupied = if full { st.occupied | pocket_bit(p) } else { st.occupied & !pocket_bit(p) };
    if st != m.atc.tools {
        store_state(m, io, st);
    }
    Ok(())
}

/// `G10 L1 P<tool> Q<pocket>`: tool number `tool` is kept in `pocket`;
/// `Q0` takes the tool out of the table. Refused, nothing stored: a pocket
/// that holds another tool number, a tool already in another pocket (take
/// it out first with `Q0`), and the pocket of the tool in the spindle.
pub fn assign(m: &mut Machine, io: &mut impl Storage, tool: u8, pocket: u8) -> Result<(), Error> {
    let before = m.atc.table;
    let now = before.pocket_of(tool);
    let holder = before.number_of(pocket);
    if pocket != 0 && holder != 0 && holder != tool {
        return Err(Error::Atc(Fault::PocketTaken));
    }
    if pocket != 0 && now.is_some_and(|p| p != pocket) {
        return Err(Error::Atc(Fault::ToolElsewhere));
    }
    let affected = if pocket != 0 { pocket } else { now.unwrap_or(0) };
    if affected != 0 && affected == m.atc.spindle() {
        return Err(Error::Atc(Fault::PocketOfSpindleTool));
    }
    if affected != 0 {
        m.atc.table.set_number(affected, if pocket == 0 { 0 } else { tool });
    }
    store_table(m, io, &before);
    Ok(())
}

/// G10 L1 P<t> [Z<length>] [R<radius>]: set a tool table entry by hand
/// (mm, already converted from inches). Stored in EEPROM when it changed.
pub fn set_tool(m: &mut Machine, io: &mut impl Storage, t: u8, length_mm: Option<f32>, radius_mm: Option<f32>) {
    let before = m.atc.table;
    let i = t as usize - 1;
    if let Some(z) = length_mm {
        m.atc.table.length_um[i] = round_i32(z * 1000.0);
    }
    if let Some(r) = radius_mm {
        m.atc.table.diameter_um[i] = round_i32(2000.0 * r).clamp(0, u16::MAX as i32) as u16;
    }
    store_table(m, io, &before);
    if t == m.atc.spindle() {
        apply_offset(m);
    }
}
