//! Line handling: bytes into lines (`protocol::LineAssembler`), the
//! resend protocol (`protocol::LineChecker`), the one reply a serial line
//! gets (`ok`, `Error:…`, or grbl's `error:<n>`), which host is talking, and
//! running a line from any source (serial, SD job, menu) through the parser
//! and the interpreter, one [`Command`] at a time into
//! [`Machine::dispatch`](super::Machine).

use super::{Alarm, CmdResult, Io, LineSource, Machine, SdJobFlags, State};
use crate::gcode::interp::{self, Command};
use crate::protocol::{Assembled, LineAssembler, RxBytes};
use ufmt::{uwrite, uwriteln};

impl Machine {
    /// Feed received bytes as long as `bytes` gives them (the firmware's RX
    /// ring, or any byte iterator) into `asm`; runs complete lines as they
    /// end. The assembler is the caller's, not the machine's, so that a
    /// line runs from its buffer while the machine is borrowed mutably (a
    /// copy into a buffer of its own cost ~110 cycles a streamed line on
    /// the AVR); a soft reset drops its line in progress here, before the
    /// next byte (`input_flushed`).
    ///
    /// The per-byte path is only the assembler's loop
    /// (`LineAssembler::push_from`; a call per byte cost ~20 cycles on the
    /// AVR); the end of a line goes through [`Machine::line_end`].
    // stack: the line path's frames stay apart (this file's attributes removed: +24 B stack, +110 B flash)
    #[inline(never)]
    pub fn push_bytes(&mut self, asm: &mut LineAssembler, mut bytes: impl RxBytes, io: &mut impl Io) {
        self.sync_input(asm);
        while let Some(done) = asm.push_from(&mut bytes) {
            self.line_end(asm, done, io);
            self.sync_input(asm);
            // Lines back to back (a host with many bytes in flight): the
            // ISR must not run dry meanwhile (as in an SD job's batch), so
            // the main loop takes its turn (the top-up, realtime requests,
            // the watchdog) when less than 5 ms of motion are left.
            if !io.queued_at_least(crate::F_CPU_HZ / 200) {
                return;
            }
        }
    }

    /// A line ended in the assembler: run it, or report why it was dropped.
    // speed: inlined into its one caller, push_bytes: no call and no register
    // save at a line's end (profile --trace 20 165 → 20 123 cycles a line,
    // stack peak 1 542 → 1 536 B)
    #[inline(always)]
    pub(super) fn line_end(&mut self, asm: &LineAssembler, done: Assembled, io: &mut impl Io) {
        match done {
            Assembled::Line => self.run_raw_line(asm.line(), asm.has_marks(), io),
            other => {
                let msg = match other {
                    Assembled::TooLong => F!("line too long (max 256 characters), ignored"),
                    Assembled::Overrun => F!("serial receive overrun, line dropped before its checksum was checked"),
                    _ => F!("binary data in line, ignored"),
                };
                // Numbered if it began with N; after an overrun (its start may
                // be lost) as the line before it was.
                self.numbered |= asm.dropped_numbered();
                if self.grbl_replies && !self.numbered {
                    // grbl: error 11 (line overflow), or 1 for the rest.
                    let code = if other == Assembled::TooLong { 11u8 } else { 1 };
                    uwriteln!(io, "{}{}{}{}", F!("[MSG:"), msg, F!("]\nerror:"), code).ok();
                    return;
                }
                self.reject_line(io, msg);
                uwriteln!(io, "ok").ok();
            }
        }
    }

    /// Drop the line `asm` is assembling if a soft reset flushed the input
    /// since the last call.
    // speed: a test per line of push_bytes' loop
    #[inline(always)]
    fn sync_input(&mut self, asm: &mut LineAssembler) {
        if core::mem::take(&mut self.input_flushed) {
            asm.reset();
        }
    }

    /// A line failed a protocol check (checksum, too long, overrun, ...).
    /// A numbered line is asked for again (`Resend:`), until it has failed
    /// `protocol::MAX_TRIES` times in a row: then it is given up with an
    /// error and the line number moves past it (`LineChecker::failed`), so
    /// that no input keeps a host resending the same line forever.
    pub(super) fn reject_line(&mut self, io: &mut impl Io, msg: crate::flash::FStr) {
        if !self.numbered {
            uwriteln!(io, "Error:{}", msg).ok();
            return;
        }
        match self.chk.failed() {
            crate::protocol::Retry::GiveUp(n) => {
                // No checksum or line-number words in this text: OctoPrint
                // must not take it for a resend request (it stops the job).
                uwriteln!(io, "Error:{}{}{}", F!("gave up on line "), n, F!(" after 3 failed tries; it is NOT run")).ok();
            }
            crate::protocol::Retry::Resend(n) => {
                uwriteln!(io, "{}{}{}{}", F!("Error:"), msg, F!(", Last Line: "), self.chk.last_line()).ok();
                uwriteln!(io, "{}{}", F!("Resend:"), n).ok();
            }
        }
    }

    /// Check N/* and run one line; always ends with exactly one `ok`.
    /// `marks`: the line may hold a `(`, `)`, `*` or `;`
    /// (`LineAssembler::has_marks`).
    // speed: inlined into its one caller, line_end: no call and no 14-register
    // save (profile --trace 20 211 → 20 165 cycles a line, stack peak
    // 1 547 → 1 542 B)
    #[inline(always)]
    pub(super) fn run_raw_line(&mut self, raw: &[u8], marks: bool, io: &mut impl Io) {
        // Numbered for the resend protocol: N and a checksum (an N alone is a
        // file's block number, which the protocol does not track).
        self.numbered = matches!(raw.first(), Some(b'N' | b'n')) && raw.contains(&b'*');
        match self.chk.check_marked(raw, marks) {
            Err(crate::protocol::ProtoError::LineNumber) => {
                // A line sent after one that failed (the host had several in
                // flight): not a new try of the failed line.
                let e = crate::protocol::ProtoError::LineNumber;
                uwriteln!(io, "{}{}{}{}", F!("Error:"), e.message(), F!(", Last Line: "), self.chk.last_line()).ok();
                uwriteln!(io, "{}{}", F!("Resend:"), self.chk.resend_line()).ok();
            }
            Err(e) => {
                self.numbered = true;
                self.reject_line(io, e.message());
            }
            Ok(cmd) => {
                self.note_host(cmd);
                self.source = LineSource::Serial;
                if self.numbered {
                    self.planner.line_tag = self.chk.last_line() as u16;
                }
                self.last_busy_ms = io.millis();
                self.line_aborts = self.aborts;
                let sd = crate::hostcodes::sd_code(cmd);
                let was_running = self.sd_job;
                let r = match sd {
                    // M28 is writing a file: every line but M29 goes there.
                    Some((29, _)) => io.sd_command(SdJobFlags { sd_job: &mut self.sd_job, aborts: self.aborts }, 29, &[]),
                    _ if io.sd_capture(cmd) => Ok(()),
                    Some((code, arg)) => io.sd_command(SdJobFlags { sd_job: &mut self.sd_job, aborts: self.aborts }, code, arg),
                    None => self.execute(cmd, io),
                };
                let source = core::mem::replace(&mut self.source, LineSource::None);
                if self.sd_job && !was_running {
                    self.job_start_ms = io.millis();
                }
                if matches!(source, LineSource::SerialReset | LineSource::SerialAcked) {
                    // A soft reset ended the line: grbl prints nothing more
                    // for it (the banner already went out). Or its `ok`
                    // went out before its move was queued (`ack_early`).
                    return;
                }
                if let Err(e) = r {
                    if self.grbl_replies && matches!(e, interp::Error::ProbeFailed) {
                        // grbl: a probe that touched nothing is its alarm
                        // (`ALARM:5`, already out); the line itself is
                        // acknowledged.
                        uwriteln!(io, "ok").ok();
                        return;
                    }
                    if self.grbl_replies {
                        // grbl: the error instead of the `ok`, its text first.
                        uwrite!(io, "{}", F!("[MSG:")).ok();
                        self.write_error(io, e);
                        uwriteln!(io, "{}{}", F!("]\nerror:"), e.grbl_code()).ok();
                        return;
                    }
                    uwrite!(io, "Error:").ok();
                    self.write_error(io, e);
                    uwriteln!(io, "").ok();
                }
            }
        }
        uwriteln!(io, "ok").ok();
    }

    /// A serial line's `ok`, sent before its last command, a move, is
    /// queued: a host that waits for each `ok` (send-response streaming)
    /// sends its next line while this one is planned. Only once every
    /// check that depends on the line has passed (the interpreter's, which
    /// ran already: syntax, modal state, feed, soft limits, keep-out zone;
    /// and here the alarm and the homing lock), and only for a feed move
    /// that cannot print the step-rate warning while it is queued,
    /// so that a line's error still comes in place of its `ok`, and only
    /// when the planner has room for the move: queuing it then only takes
    /// CPU time, and the main loop is back at the RX ring soon. What can
    /// still end the line after its `ok` is not about the line (an alarm,
    /// an e-stop, a soft reset), each reported on its own (`ALARM:`, the
    /// banner), as grbl and Marlin report them. The move is queued before
    /// any later line is read.
    // speed: on every streamed move (inlined into run_line)
    #[inline(always)]
    fn ack_early(&mut self, io: &mut impl Io, feed_mm_per_min: f32, rapid: bool) -> CmdResult {
        if self.source != LineSource::Serial || !self.interp.line_done() {
            return Ok(());
        }
        self.may_move_to(self.interp.target())?;
        // Not when queuing may print a warning (a rapid, a feed near the
        // step-rate cap, the feed override on): that goes before the `ok`.
        // (A feed the planner refuses, not > 0, never gets here: the
        // interpreter refused it.)
        // Nor when the move would wait for planner room: the firmware would
        // stop reading the RX ring while the host sends its next line, and
        // a line longer than the ring (up to 256 characters) would be lost.
        // (2 slots: a backlash take-up needs one more.)
        let f = feed_mm_per_min.to_bits();
        if rapid
            || f as i32 <= 0
            || self.planner.free() < 2
            || !self.interp.never_rate_capped(feed_mm_per_min)
            || self.planner.feed_override() != 100
        {
            return Ok(());
        }
        uwriteln!(io, "ok").ok();
        self.source = LineSource::SerialAcked;
        Ok(())
    }

    /// Which host is talking, from what it sends (see
    /// [`Machine::grbl_replies`]): a first-byte test for the usual line.
    // speed: a first-byte test, inline in run_raw_line (this file's attributes removed: +24 B stack, +110 B flash)
    #[inline(always)]
    pub(super) fn note_host(&mut self, cmd: &[u8]) {
        match cmd.first() {
            Some(b'$') => {
                if matches!(cmd.get(1), Some(b'$' | b'I' | b'i' | b'G' | b'g' | b'#')) {
                    self.grbl_replies = true;
                }
            }
            Some(b'M' | b'm') if self.grbl_replies => {
                if matches!(cmd.get(1..4), Some(b"110" | b"115")) {
                    self.grbl_replies = false;
                }
            }
            _ => {}
        }
        if self.numbered {
            self.grbl_replies = false;
        }
    }

    /// Print `Error:<what>` for a failed line.
    pub fn report_error(&self, io: &mut impl ufmt::uWrite, e: interp::Error) {
        uwrite!(io, "Error:").ok();
        self.write_error(io, e);
        uwriteln!(io, "").ok();
    }

    /// The text of an error, without a line end.
    pub(super) fn write_error(&self, io: &mut impl ufmt::uWrite, e: interp::Error) {
        match e {
            interp::Error::Alarm => {
                let why = self.alarm.map_or(F!("unknown"), |a| a.message());
                uwrite!(io, "alarm {}{}", why, F!("; home or M999")).ok();
            }
            interp::Error::Parse(p) => {
                uwrite!(io, "{}{}{}", p.kind.message(), F!(" at col "), p.col).ok();
            }
            interp::Error::Sd(t) => {
                // SD card errors print their own text.
                uwrite!(io, "{}", t).ok();
            }
            interp::Error::StationOutside { setting, axis } => {
                let name = b"XYZ"[axis as usize] as char;
                uwrite!(io, "${}{}{}", setting, F!(" (tool change station) outside the "), name).ok();
                uwrite!(io, "{}{}{}", F!(" travel 0..$13"), axis, F!(", nothing changed")).ok();
            }
            interp::Error::UnusedWord(w) => {
                uwrite!(io, "{}{}", w.letter() as char, F!(" word with no code that uses it")).ok();
            }
            interp::Error::NoPocket(t) => {
                uwrite!(io, "{}{}{}{}{}", F!("tool T"), t, F!(" not in the tool table: G10 L1 P"), t, F!(" Q<pocket> assigns it")).ok();
            }
            other => {
                uwrite!(io, "{}", other.message()).ok();
            }
        }
    }

    /// Run one line of an SD job (the same path as a serial line, without
    /// the `ok`; the job reports errors with the line number).
    // stack: the line path's frames stay apart (this file's attributes removed: +24 B stack, +110 B flash)
    #[inline(never)]
    pub fn run_job_line(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        self.line_aborts = self.aborts;
        if crate::hostcodes::sd_code(text).is_some() {
            return Err(interp::Error::BadWord(F!("SD commands are not allowed inside an SD job")));
        }
        self.source = LineSource::Job;
        let r = self.execute(text, io);
        self.source = LineSource::None;
        r
    }

    /// Run one line for the menu (Tools: `T<n>`, `G37`, `M61 Q<t>`): the
    /// same path as a serial line, without the `ok`; the caller reports errors.
    // stack: the line path's frames stay apart (this file's attributes removed: +24 B stack, +110 B flash)
    #[inline(never)]
    pub fn run_menu_line(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        self.line_aborts = self.aborts;
        self.source = LineSource::Menu;
        let r = self.execute(text, io);
        self.source = LineSource::None;
        r
    }

    /// True while the line being run comes from the SD job.
    pub fn in_job_line(&self) -> bool {
        self.source == LineSource::Job
    }

    /// A serial line is running (its host waits for the `ok`, or, once
    /// the `ok` went out early, for the next line's, which waits in the
    /// ring behind this one).
    pub(super) fn in_serial_line(&self) -> bool {
        matches!(self.source, LineSource::Serial | LineSource::SerialReset | LineSource::SerialAcked)
    }

    /// Parse and run one command line (without N and checksum).
    // stack: the line path's frames stay apart (this file's attributes removed: +24 B stack, +110 B flash)
    #[inline(never)]
    pub fn execute(&mut self, text: &[u8], io: &mut impl Io) -> CmdResult {
        if text.first() == Some(&b'$') {
            return self.dollar(text, io);
        }
        if let Some((code, arg)) = crate::hostcodes::code(text) {
            return crate::hostcodes::run(&mut self.host, io, code, arg);
        }
        let mut line = crate::gcode::Line::default();
        crate::gcode::parse_into(text, &mut line).map_err(interp::Error::Parse)?;
        // A serial line's block number (`N10 G1 …`, grbl senders): its moves
        // carry it for `?`'s `Ln:` (a Marlin host's N is the checker's, set
        // in `run_raw_line`; an SD job tags its own lines).
        if self.in_serial_line() && !self.numbered {
            self.planner.line_tag = crate::protocol::block_number(text);
        }
        self.run_line(&line, io)
    }

    /// Run a parsed line: ask the interpreter for its commands, one at a
    /// time, and carry each out ([`Machine::dispatch`]) before asking for
    /// the next. The first error ends the line.
    // stack: the line path's frames stay apart (this file's attributes removed: +24 B stack, +110 B flash;
    // this one alone, inlined into execute, measured no faster: 20 211 → 20 209 cycles a line)
    #[inline(never)]
    pub(super) fn run_line(&mut self, l: &crate::gcode::Line, io: &mut impl Io) -> CmdResult {
        self.interp.begin_line();
        // `line_done` spares the last call (a streamed G1 is one move).
        while !self.interp.line_done() {
            let cx = interp::Ctx {
                settings: &self.settings,
                atc: &self.atc,
                alarm: self.alarm.is_some(),
                estop: self.alarm == Some(Alarm::EmergencyStop),
                status_only: self.sd_job && self.source != LineSource::Job,
            };
            // Matched by reference: the command is not copied again.
            let r = self.interp.next(&cx, l);
            match &r {
                Ok(Some(Command::Move { .. } | Command::CycleMove { .. })) if self.state == State::Check => {
                    self.interp.target_reached();
                }
                Ok(Some(Command::Move { feed_mm_per_min, rapid })) => {
                    self.ack_early(io, *feed_mm_per_min, *rapid)?;
                    self.move_interp(io, *feed_mm_per_min, *rapid)?
                }
                // `$C`: only reports run; spindle, tool, probe, dwell,
                // homing and EEPROM writes are checked and skipped.
                Ok(Some(cmd)) if self.state == State::Check && !matches!(cmd, Command::Report(_)) => {
                    if self.rebuild.active {
                        self.scan_note(cmd);
                    }
                }
                Ok(Some(cmd)) => self.dispatch(cmd, io)?,
                Ok(None) => return Ok(()),
                Err(e) => return Err(*e),
            }
        }
        Ok(())
    }
}
