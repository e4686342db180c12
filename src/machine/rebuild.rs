//! Run from line, the machine's part: the scan that rebuilds a job's
//! modal state from its first lines without moving ([`Machine::begin_scan`],
//! the lines run in check mode and [`Machine::scan_note`] keeps what check
//! mode skips), then the safe way to where the job was
//! ([`Machine::approach`]: tool, Z up, XY, spindle up to speed, coolant,
//! plunge at the job's feed). The SD job reads the lines (`ui::sd`); the
//! operator's side is in docs/standalone.md, "Run from line".
//!
//! ```text
//!  begin_scan ─► lines 1..n-1 in check mode (moves only track the position;
//!                spindle, coolant, tool noted here) ─► approach ─► line n on
//! ```

use super::{toolchange, CmdResult, Io, Machine, State, RETRACT_FEED_MM_PER_MIN};
use crate::gcode::interp::{self, Command};
use crate::gcode::{Motion, Plane};
use crate::planner::Speed;

/// No tool change seen in the scan.
pub const NO_TOOL: u8 = 0xFF;

/// What the scan keeps that check mode skips. RAM: 4 bytes.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Rebuild {
    /// A scan is running: check mode notes the commands below.
    pub active: bool,
    /// The spindle the job had on (M3) at the line, at `Interp::spindle_rpm`.
    pub spindle: bool,
    /// The job's coolant M code at the line (7, 8; 9 off).
    pub coolant: u8,
    /// The pocket of the tool the job's last change asked for ([`NO_TOOL`]: none).
    pub tool: u8,
}

impl Rebuild {
    pub const OFF: Rebuild = Rebuild { active: false, spindle: false, coolant: 9, tool: NO_TOOL };
}

impl Machine {
    /// Start a scan: refused unless idle and homed (after a power cut the
    /// position is lost, and the approach needs it). The modes start as at
    /// power-up (G21 G90 G17 G54, no G92, G0, the spindle tool's length
    /// offset, no feed), the commanded position where the machine is; the
    /// lines then run in check mode.
    pub fn begin_scan(&mut self, io: &mut impl Io) -> CmdResult {
        if self.alarm.is_some() {
            return Err(interp::Error::Alarm);
        }
        if self.homed & 0b111 != 0b111 {
            return Err(interp::Error::BadWord(F!("home first: the position is not known (power cut?), nothing moved")));
        }
        if self.state != State::Idle || !self.motion_done(io) {
            return Err(interp::Error::BadWord(F!("machine busy")));
        }
        let i = &mut self.interp;
        i.inches = false;
        i.incremental = false;
        i.plane = Plane::Xy;
        i.arc_absolute = false;
        i.motion = Motion::Rapid;
        i.feed_mm_per_min = 0.0;
        i.spindle_rpm = 0.0;
        i.wcs = 0;
        i.g92_mm = [0.0; 3];
        i.tlo_mm = 0.0;
        self.interp.load_settings(&self.settings);
        toolchange::apply_offset(self);
        self.interp.sync_position(&self.settings, io.stepper().position);
        self.rebuild = Rebuild { active: true, ..Rebuild::OFF };
        self.state = State::Check;
        Ok(())
    }

    /// A command check mode skipped, during a scan: the spindle, the
    /// coolant and the tool the job would have, noted (a tool change also
    /// takes the new tool's length offset, as the change would).
    pub(super) fn scan_note(&mut self, cmd: &Command) {
        let r = &mut self.rebuild;
        match *cmd {
            Command::Spindle { on, .. } => r.spindle = on,
            Command::Coolant { m } => r.coolant = m,
            Command::PreselectTool(t) => self.atc.last_t = t,
            Command::SelectTool { to } => {
                let p = to.map_or(self.atc.last_t, |t| t as u8);
                if p != NO_TOOL {
                    r.tool = p;
                    self.atc.last_t = p;
                    if self.settings.auto_tool_offset {
                        self.interp.tlo_mm = crate::atc::tool_length_offset_mm(self.atc.length_mm(p));
                    }
                }
            }
            Command::ProgramEnd => {
                r.spindle = false;
                r.coolant = 9;
            }
            _ => {}
        }
    }

    /// End a scan (if one runs): out of check mode, the commanded position
    /// back where the machine is, the length offset of the tool really in
    /// the spindle (the approach puts the job's back); the other modes stay
    /// as the scanned lines left them, as `$C` leaves them. Returns where
    /// the job would have been (internal machine mm).
    pub fn end_scan(&mut self, io: &mut impl Io) -> [f32; crate::N_AXES] {
        let target = self.interp.pos_mm;
        if self.rebuild.active {
            self.rebuild.active = false;
            self.state = State::Idle;
            self.interp.sync_position(&self.settings, io.stepper().position);
            toolchange::apply_offset(self);
        }
        target
    }

    /// After the scan: go where the job was at the end of its last line
    /// scanned, the safe way. The job's tool first (a change, as the job
    /// would); Z up to `$160` below its switch (only up: a tool above it
    /// and above the target stays); X and Y at rapid; the spindle on at the
    /// job's speed, its spin-up delay (`$181`) waited; the coolant; then Z
    /// down to the target at the job's feed. The modes stay as the scan
    /// left them. Refused under cutter compensation (a contour cannot start
    /// mid-way), nothing moved.
    pub fn approach(&mut self, io: &mut impl Io) -> CmdResult {
        let comp = self.interp.comp.side.is_some();
        let (tlo, r) = (self.interp.tlo_mm, self.rebuild);
        let target = self.end_scan(io);
        if comp {
            return Err(interp::Error::BadWord(F!("cutter compensation (G41/G42) on at this line: pick one outside it, nothing moved")));
        }
        self.line_aborts = self.aborts;
        if r.tool != NO_TOOL && r.tool != self.atc.spindle() {
            toolchange::select(self, io, Some(r.tool as u16))?;
        }
        // The change sets its tool's offset; the job's G43/G49 since rule.
        self.interp.tlo_mm = tlo;
        let mut p = self.interp.pos_mm;
        let safe = self.settings.card_out_retract_mm;
        // Internal frame: Z counts down from the switch, the least is highest.
        p[2] = p[2].min(safe).min(target[2]);
        self.move_mm(io, &p, Speed::Fixed(RETRACT_FEED_MM_PER_MIN))?;
        p[0] = target[0];
        p[1] = target[1];
        self.move_mm(io, &p, Speed::Rapid)?;
        self.wait_idle(io)?;
        if r.spindle {
            // The job's M3 at its S (built on the stack: a constant would
            // sit in RAM).
            self.run_job_line(&core::hint::black_box(*b"M3"), io)?;
        }
        if r.coolant != 9 {
            io.coolant(true);
            self.interp.coolant_m = r.coolant;
        }
        p[2] = target[2];
        let feed = self.interp.feed_mm_per_min;
        self.move_mm(io, &p, if feed > 0.0 { Speed::Feed(feed) } else { Speed::Fixed(RETRACT_FEED_MM_PER_MIN) })
    }
}

#[cfg(test)]
mod tests {
    //! The scan and the approach on the fake board, with the SD job's own
    //! line reader over a card in RAM: what the scan rebuilds, that it
    //! moves nothing, and the approach's order.
    use super::*;
    use crate::fake_board::{FakeBoard, Output};
    use crate::protocol::MAX_LINE_LEN;
    use crate::ui::sd::tests::{FakeCard, Out};
    use crate::ui::sd::{Folder, Name, Phase, SdJob, Turn};

    /// A job: inches for a while, then metric in G55 (X offset 5 mm) with
    /// G92, T0 kept, spindle at 9000, flood, then relative moves.
    const JOB: &str =
        "G20 G90\nG0 X1\nG21\nG10 L2 P2 X5\n\nG55\nG92 Y-1\nM3 S9000\nM8\nG0 X10 Y20\nG1 Z-3 F300\nG91\nG1 X1\nG1 X1\nG1 X1\nM5\nM2\n";

    /// Homed at 1 mm off each switch; the card holds `text` as A.NC.
    fn rig(text: &str) -> (Box<Machine>, FakeBoard, SdJob, FakeCard) {
        let mut io = FakeBoard::new();
        let mut m = Box::new(Machine::new());
        m.boot(&mut io, F!("power-on"), false);
        m.execute(b"G28", &mut io).unwrap();
        m.wait_idle(&mut io).unwrap();
        let mut card = FakeCard::new(&[("A.NC", text)]);
        let mut job = SdJob::new();
        job.select(&mut card, Folder::Root, &Name::parse(b"A.NC").unwrap()).unwrap();
        (m, io, job, card)
    }

    /// Scan up to `line`: the line the job goes on with (after the
    /// approach), or `None` when the scan ended the job.
    fn scan(m: &mut Machine, io: &mut FakeBoard, job: &mut SdJob, card: &mut FakeCard, line: u32) -> Option<String> {
        m.begin_scan(io).unwrap();
        job.start_from(m, line).unwrap();
        let mut buf = [0u8; MAX_LINE_LEN];
        let mut out = Out::default();
        for _ in 0..100 {
            match job.poll(card, m, m.motion_done(io), &mut buf, &mut out) {
                Turn::Scan(n) => {
                    let r = m.run_job_line(&buf[..n], io);
                    job.line_done(r, m, &mut out);
                }
                Turn::Approach(n) => return Some(String::from_utf8(buf[..n].to_vec()).unwrap()),
                Turn::Idle if !job.active() => {
                    eprintln!("scan ended: {:?} {}", job.phase, out.0);
                    return None;
                }
                _ => {}
            }
            m.idle(io);
        }
        panic!("the scan did not end: {:?}", job.phase);
    }

    #[test]
    fn the_scan_rebuilds_the_modes_spindle_coolant_and_position_without_moving() {
        let (mut m, mut io, mut job, mut card) = rig(JOB);
        let steps = io.steps.len();
        // Line 15 is the third `G1 X1`: two of them are before it.
        assert_eq!(scan(&mut m, &mut io, &mut job, &mut card, 15).as_deref(), Some("G1 X1"));
        assert_eq!(io.steps.len(), steps, "nothing stepped");
        assert_eq!((io.spindle, io.coolant), (0, false), "spindle and coolant only noted");
        let i = &m.interp;
        assert!(!i.inches && i.incremental && i.wcs == 1);
        assert_eq!((i.spindle_rpm, i.feed_mm_per_min), (9000.0, 300.0));
        assert_eq!(m.rebuild, Rebuild { active: true, spindle: true, coolant: 8, tool: NO_TOOL });
        assert_eq!(m.state, State::Check);
        // Work X 12 in G55 (X +5) = machine X 17; G92 Y-1 at machine Y 1
        // (homed) puts work Y 20 at machine 22; work Z -3 = 3 mm below the
        // switch (internal +Z down).
        let t = m.interp.pos_mm;
        assert!((t[0] - 17.0).abs() < 1e-4 && (t[1] - 22.0).abs() < 1e-4 && (t[2] - 3.0).abs() < 1e-4, "{t:?}");
        assert_eq!(job.phase, Phase::Running);
        // `$C` cannot end the scan's check mode (the rest would run for real).
        assert_eq!(m.execute(b"$C", &mut io), Err(interp::Error::JobRunning));
        assert_eq!(m.state, State::Check);
    }

    #[test]
    fn the_approach_goes_up_then_across_then_starts_the_spindle_then_plunges_at_the_feed() {
        let (mut m, mut io, mut job, mut card) = rig(JOB);
        scan(&mut m, &mut io, &mut job, &mut card, 15).unwrap();
        let from = io.steps.len();
        m.approach(&mut io).unwrap();
        m.wait_idle(&mut io).unwrap();
        assert_eq!(m.state, State::Idle);
        assert!(!m.rebuild.active);
        // Machine steps (100/mm): X 17, Y 22, Z 3 mm down.
        assert_eq!(&io.pos[..3], &[1700, 2200, 300]);
        let steps = &io.steps[from..];
        let z_down = |s: &&crate::fake_board::Step| s.axes & 4 != 0;
        let xy = |s: &&crate::fake_board::Step| s.axes & 3 != 0;
        let first_xy = steps.iter().find(xy).unwrap().cycle;
        let last_xy = steps.iter().rev().find(xy).unwrap().cycle;
        // Homed 1 mm below the switch, $160 is 2 mm: already above it, Z
        // does not go down before X and Y; it only goes down after them.
        assert!(steps.iter().filter(z_down).all(|s| s.cycle > last_xy), "Z moved before X/Y ended");
        assert_eq!(steps.iter().filter(z_down).count(), 200, "plunge 1 -> 3 mm");
        let spindle_on = io.outputs.iter().find(|(_, o)| matches!(o, Output::Spindle(d) if *d > 0)).unwrap().0;
        let first_z = steps.iter().find(z_down).unwrap().cycle;
        assert!(first_xy < spindle_on && spindle_on < first_z, "spindle on after X/Y, before the plunge");
        assert!(io.coolant, "flood on");
        // The plunge at F300: 2 mm in at least 0.4 s (16 MHz cycles).
        let last_z = steps.iter().rev().find(z_down).unwrap().cycle;
        assert!((last_z - first_z) as f64 / 16e6 >= 0.39, "plunge too fast: {} cycles", last_z - first_z);
    }

    /// A job that changes to T2 (25 mm long: Z-30 is 5 mm below the Z
    /// switch with it): the scan notes the change
    /// and takes T2's length offset without moving; the approach changes
    /// the tool first and arrives where the job would be with T2.
    #[test]
    fn a_tool_change_in_the_scan_is_made_by_the_approach_with_the_new_tool_length() {
        let (mut m, mut io, mut job, mut card) = rig("G21 G90\nT2 M6\nM3 S6000\nG0 X10 Y10\nG1 Z-30 F200\nG1 X12\n");
        m.execute(b"G10 L1 P2 Z25", &mut io).unwrap();
        let steps = io.steps.len();
        assert_eq!(scan(&mut m, &mut io, &mut job, &mut card, 6).as_deref(), Some("G1 X12"));
        assert_eq!(io.steps.len(), steps, "nothing stepped");
        assert_eq!(m.atc.spindle(), 0, "not changed by the scan");
        assert_eq!(m.rebuild.tool, 2);
        let tlo = crate::atc::tool_length_offset_mm(25.0);
        assert_eq!(m.interp.tlo_mm, tlo);
        let target = m.interp.pos_mm;
        m.approach(&mut io).unwrap();
        m.wait_idle(&mut io).unwrap();
        assert_eq!(m.atc.spindle(), 2, "T2 in the spindle");
        assert_eq!(m.interp.tlo_mm, tlo);
        assert_eq!(m.interp.pos_mm[..3], target[..3]);
        assert!(io.spindle > 0);
    }

    #[test]
    fn a_line_past_the_end_ends_the_job_and_moves_nothing() {
        let (mut m, mut io, mut job, mut card) = rig(JOB);
        let steps = io.steps.len();
        assert_eq!(scan(&mut m, &mut io, &mut job, &mut card, 40), None);
        assert_eq!(job.phase, Phase::Ended(crate::ui::sd::Outcome::NotResumed(40)));
        m.end_scan(&mut io);
        assert_eq!(io.steps.len(), steps);
        assert_eq!(m.state, State::Idle);
    }

    #[test]
    fn a_scan_is_refused_unhomed_and_a_contour_under_compensation_is_not_approached() {
        let mut io = FakeBoard::new();
        let mut m = Box::new(Machine::new());
        m.boot(&mut io, F!("power-on"), false);
        assert!(m.begin_scan(&mut io).is_err(), "not homed");
        assert_eq!(m.state, State::Idle);
        let (mut m, mut io, mut job, mut card) = rig("G10 L1 P1 R1\nG0 X10 Y10\nG41 D1\nG1 X20 F300\nG1 Y20\nG40\n");
        scan(&mut m, &mut io, &mut job, &mut card, 5).unwrap();
        let steps = io.steps.len();
        assert!(m.approach(&mut io).is_err());
        assert_eq!(io.steps.len(), steps, "nothing moved");
        assert_eq!(m.state, State::Idle);
    }
}
