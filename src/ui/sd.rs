//! SD card jobs and the SD commands M20–M29 (docs/SPEC.md §5, §9), as plain logic
//! over a [`Card`] (the firmware's is `embedded-sdmmc` over SPI; tests use a
//! fake).
//!
//! ```text
//!  Card ─► SdJob::next_line (64-byte read-ahead, line splitting) ─► Machine::run_job_line
//!                                                                   (the same parser/planner
//!                                                                    path as serial lines)
//! ```
//!
//! A job reads one line per main-loop turn while the planner has room, so a
//! job from SD runs through exactly the same pipeline as a streamed one.
//! What it asks of the machine (hold, resume, abort) goes out as
//! [`Requests`] bits, which the firmware hands to the machine as realtime
//! events, like `!`, `~` from the serial line.
//!
//! Faults and what they do:
//! - the card is pulled while a job runs: feed hold, message, the job waits
//!   for an abort (it cannot go on without its file);
//! - a read error (or binary garbage, or a line over 256 characters): the job
//!   stops at once (decelerated abort), spindle off, message;
//! - a G-code error on line n: nothing after line n is read; the moves
//!   before it finish, then the spindle is turned off and line n is reported.

use crate::machine::{CmdResult, Machine, SdJobFlags};
use crate::protocol::{code_run, folded_len, Keep, LineCut, BOM, MAX_LINE_LEN};
use crate::ui::text::Text;
use ufmt::{uWrite, uwriteln};

mod card_out;

pub use super::card::{Card, Entry, Folder, Name, SdError};

/// Requests to the machine, as realtime bits (see the module docs).
pub mod req {
    /// Feed hold.
    pub const HOLD: u8 = 1 << 0;
    /// Resume from hold.
    pub const RESUME: u8 = 1 << 1;
    /// Decelerate, then drop the queue (abort).
    pub const ABORT: u8 = 1 << 2;
    /// With ABORT: leave the spindle on (the job retracts the tool first).
    pub const KEEP_SPINDLE: u8 = 1 << 3;
}

/// How a job ended, for the display and M27.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Outcome {
    /// Ran to its end.
    Done,
    /// Aborted by the operator.
    Aborted,
    /// A G-code error on this line; nothing after it ran.
    BadLine(u32),
    /// The file could not be read (at this byte); the job stopped.
    ReadError(u32),
    /// The card was pulled mid-job: the job stopped in this line (the one
    /// whose move was executing, or the last one read when none was).
    CardRemoved(u32),
    /// Run from this line did not start ([`SdJob::why`] says why: the file
    /// ends before it, the card was pulled during the scan); nothing moved.
    NotResumed(u32),
}

/// Where the job is.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Phase {
    /// No file selected.
    Idle,
    /// A file is selected (M23 or the menu) and not started.
    Selected,
    /// Lines are being read and run.
    Running,
    /// Paused (M25 or the menu): held, nothing read.
    Paused,
    /// No more lines will be read; waiting for the queued moves to finish.
    Draining(Outcome),
    /// Waiting for the machine to finish an abort (decelerate and flush).
    Aborting(Outcome),
    /// Finished (the outcome stays for the display).
    Ended(Outcome),
    /// M28: serial lines are written to the open file until M29.
    Writing,
    /// Run from line: the lines before this one are read without moving
    /// (the modal state rebuilt, `machine::rebuild`).
    Scanning(u32),
}

/// What the main loop should do after [`SdJob::poll`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Turn {
    /// Nothing this turn.
    Idle,
    /// Run the line now in the caller's buffer (this many bytes).
    Run(usize),
    /// The job is over: turn the spindle off.
    SpindleOff,
    /// The card was pulled and the job's moves are dropped: retract Z to
    /// the safe height, then turn the spindle off.
    RetractThenSpindleOff,
    /// Run from line: scan the line in the caller's buffer (this many
    /// bytes) in check mode.
    Scan(usize),
    /// Run from line: the scan reached the line; go to where the job was
    /// (`Machine::approach`), then run the line in the caller's buffer.
    Approach(usize),
}

/// Bytes of read-ahead.
const CHUNK: usize = 64;

/// An SD job: the selected file, its read position and the line splitter.
/// RAM: about 110 bytes (7 of them for run from line's record).
pub struct SdJob {
    pub phase: Phase,
    /// Selected file.
    pub name: Name,
    /// Its size, bytes.
    pub size: u32,
    /// Bytes consumed (start of the next unread line), for M27 and the %.
    pub pos: u32,
    /// Line number of the last line handed out (1-based).
    pub line: u32,
    /// Why the job stopped on a bad line: the refusal's message.
    pub why: Option<crate::flash::FStr>,
    chunk: [u8; CHUNK],
    head: u8,
    fill: u8,
    eof: bool,
    /// [`req`] bits for the machine, taken by the firmware's poll.
    requests: u8,
    /// `Machine::aborts` when the job last looked.
    seen_aborts: u8,
    /// The last line reached (run from line's record), when it was last
    /// recorded (seconds, wrapping), and a record due now (a start, a
    /// pause, the end).
    reached: u32,
    saved_ms: u16,
    record_now: u8,
}

/// `SdJob::record_now`: nothing, the line reached, a job's start.
const NO_RECORD: u8 = 0;
const RECORD_LINE: u8 = 1;
const RECORD_START: u8 = 2;

/// A record of run from line's EEPROM record due ([`SdJob::record_due`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Due {
    /// A job starts on the selected file at this line: the whole record.
    Start(u32),
    /// The job reached this line (0: it ran to its end).
    Reached(u32),
}

impl Default for SdJob {
    fn default() -> Self {
        SdJob::new()
    }
}

impl SdJob {
    pub const fn new() -> SdJob {
        SdJob {
            phase: Phase::Idle,
            name: Name::EMPTY,
            size: 0,
            pos: 0,
            line: 0,
            why: None,
            chunk: [0; CHUNK],
            head: 0,
            fill: 0,
            eof: false,
            requests: 0,
            seen_aborts: 0,
            reached: 1,
            saved_ms: 0,
            record_now: NO_RECORD,
        }
    }

    /// A job is under way (serial motion is refused meanwhile).
    pub fn active(&self) -> bool {
        matches!(self.phase, Phase::Running | Phase::Paused | Phase::Draining(_) | Phase::Aborting(_) | Phase::Scanning(_))
    }

    /// Progress in percent of the file's bytes read.
    pub fn percent(&self) -> u8 {
        scaled(self.pos.min(self.size), self.size, 100) as u8
    }

    /// Progress by the cut: the share of the file up to the line whose move
    /// is executing (not the lines read ahead into the planner), estimated
    /// from the bytes read as `pos × cut line / lines read`, so lines of any
    /// length count in proportion. Per mille.
    pub fn permille_cut(&self, m: &Machine) -> u16 {
        let read = scaled(self.pos.min(self.size), self.size, 1000);
        if let Phase::Scanning(to) = self.phase {
            // The scan's progress toward its line.
            return scaled(self.line, to, 1000) as u16;
        }
        if !self.active() || self.line == 0 {
            return read as u16;
        }
        scaled(self.cut_line(m), self.line, read) as u16
    }

    /// The line whose move is executing: the planner's current block's tag is
    /// the low 16 bits of a line read at most a planner's worth of blocks
    /// ago; with nothing planned, the last line read.
    pub fn cut_line(&self, m: &Machine) -> u32 {
        match m.planner.current_block() {
            Some(b) => self.line.wrapping_sub((self.line as u16).wrapping_sub(b.line) as u32),
            None => self.line,
        }
    }

    /// Take the pending [`req`] bits.
    pub fn take_requests(&mut self) -> u8 {
        core::mem::take(&mut self.requests)
    }

    /// Ask the machine for something (hold, resume, abort).
    pub fn request(&mut self, bits: u8) {
        self.requests |= bits;
    }

    /// Select the file `name` of folder `at` for a job (M23: the root; the
    /// menu: the folder its list shows).
    pub fn select(&mut self, card: &mut impl Card, at: Folder, name: &Name) -> Result<(), SdError> {
        if self.active() || self.phase == Phase::Writing {
            card.close().ok();
        }
        self.phase = Phase::Idle;
        card.mount()?;
        let size = card.open(at, name, false)?;
        self.name = *name;
        self.size = size;
        self.rewind();
        self.phase = Phase::Selected;
        Ok(())
    }

    fn rewind(&mut self) {
        self.why = None;
        self.pos = 0;
        self.line = 0;
        self.head = 0;
        self.fill = 0;
        self.eof = false;
    }

    /// Start the selected file, or resume a paused job (M24, the menu).
    pub fn start(&mut self, m: &mut Machine) -> Result<(), Text> {
        self.start_with(SdJobFlags { sd_job: &mut m.sd_job, aborts: m.aborts })
    }

    /// [`SdJob::start`] over the machine's job flags only.
    pub fn start_with(&mut self, f: SdJobFlags<'_>) -> Result<(), Text> {
        match self.phase {
            Phase::Selected => {
                self.seen_aborts = f.aborts;
                self.phase = Phase::Running;
                self.reached = 1;
                // Recorded at once: the records' clock starts with the job.
                self.record_now = RECORD_START;
                *f.sd_job = true;
                Ok(())
            }
            Phase::Paused => {
                self.resume();
                Ok(())
            }
            Phase::Running => Ok(()),
            _ => Err(Text::ErrNoFileSelected),
        }
    }

    /// Run from line `line` of the selected file: its lines before `line`
    /// are scanned first ([`Turn::Scan`]), then the machine goes there
    /// ([`Turn::Approach`]). The caller started the scan
    /// (`Machine::begin_scan`).
    pub fn start_from(&mut self, m: &mut Machine, line: u32) -> Result<(), Text> {
        if !matches!(self.phase, Phase::Selected) {
            return Err(Text::ErrNoFileSelected);
        }
        self.seen_aborts = m.aborts;
        self.phase = Phase::Scanning(line);
        self.reached = line;
        self.record_now = RECORD_START;
        m.sd_job = true;
        Ok(())
    }

    /// Resume a paused job (M24, the menu).
    pub fn resume(&mut self) {
        if self.phase == Phase::Paused {
            self.request(req::RESUME);
            self.phase = Phase::Running;
        }
    }

    /// Pause a running job (M25, the menu): feed hold, nothing more is read.
    pub fn pause(&mut self) {
        if self.phase == Phase::Running {
            self.request(req::HOLD);
            self.phase = Phase::Paused;
            self.record_now = self.record_now.max(RECORD_LINE);
        }
    }

    /// Abort the job: decelerate, drop the queue, spindle off.
    pub fn abort(&mut self) {
        if matches!(self.phase, Phase::Running | Phase::Paused | Phase::Draining(_) | Phase::Scanning(_)) {
            self.request(req::ABORT);
            self.phase = Phase::Aborting(Outcome::Aborted);
        }
    }

    /// Set the read position (M26 S), only before start or while paused.
    pub fn seek(&mut self, card: &mut impl Card, pos: u32) -> Result<(), Text> {
        if !matches!(self.phase, Phase::Selected | Phase::Paused) {
            return Err(Text::ErrNoFileSelected);
        }
        if pos > self.size {
            return Err(Text::ErrSeek);
        }
        card.seek(pos).map_err(SdError::text)?;
        self.head = 0;
        self.fill = 0;
        self.eof = false;
        self.pos = pos;
        Ok(())
    }

    /// [`SdJob::poll`] has nothing to do: no job, no abort unseen.
    pub fn quiet(&self, m: &Machine) -> bool {
        !self.active() && m.aborts == self.seen_aborts
    }

    /// One main-loop turn. `motion_done`: nothing planned or stepping.
    /// May fill `line` with the next line to run (see [`Turn`]).
    pub fn poll(
        &mut self,
        card: &mut impl Card,
        m: &mut Machine,
        motion_done: bool,
        line: &mut [u8; MAX_LINE_LEN],
        out: &mut impl uWrite,
    ) -> Turn {
        // An abort finished by the machine (from here, the menu or M112-less
        // serial) ends the job.
        if m.aborts != self.seen_aborts {
            self.seen_aborts = m.aborts;
            if self.active() {
                let outcome = match self.phase {
                    Phase::Aborting(o) => o,
                    _ => Outcome::Aborted,
                };
                return self.end(card, m, outcome, out);
            }
        }
        if self.active() && m.alarm.is_some() {
            // An alarm (M112, limit) dropped everything already.
            return self.end(card, m, Outcome::Aborted, out);
        }
        if self.card_check(card.detected(), m, out) {
            card.unmount();
            return Turn::Idle;
        }
        match self.phase {
            Phase::Running => {
                if m.planner.free() == 0 {
                    return Turn::Idle;
                }
                match self.next_line(card, line) {
                    Ok(Some(n)) => {
                        m.planner.line_tag = self.line as u16;
                        Turn::Run(n)
                    }
                    Ok(None) if m.interp.comp.held.is_some_and(|h| !h.sent) => {
                        // A file that ends under cutter compensation: its
                        // last move, held back for look-ahead, runs (G40).
                        line[..3].copy_from_slice(b"G40");
                        Turn::Run(3)
                    }
                    Ok(None) => {
                        self.phase = Phase::Draining(Outcome::Done);
                        Turn::Idle
                    }
                    Err(_) if !card.detected() => self.card_gone(card, m, out),
                    Err(e) => {
                        uwriteln!(out, "{}{}{}{}{}{}", Text::Error, e, Text::AtSdByte, self.pos, Text::JobStopped, self.line + 1).ok();
                        self.request(req::ABORT);
                        self.phase = Phase::Aborting(Outcome::ReadError(self.pos));
                        Turn::Idle
                    }
                }
            }
            Phase::Scanning(to) => self.scan(card, m, to, line, out),
            Phase::Draining(o) if motion_done => self.end(card, m, o, out),
            _ => Turn::Idle,
        }
    }

    /// The scan's next line: lines before `to` are scanned; the first one
    /// from `to` on (blank lines skipped) is the one to go on with.
    fn scan(&mut self, card: &mut impl Card, m: &mut Machine, to: u32, line: &mut [u8; MAX_LINE_LEN], out: &mut impl uWrite) -> Turn {
        match self.next_line(card, line) {
            Ok(Some(n)) if self.line >= to => {
                self.phase = Phase::Running;
                m.planner.line_tag = self.line as u16;
                Turn::Approach(n)
            }
            Ok(Some(n)) => Turn::Scan(n),
            Ok(None) => {
                uwriteln!(out, "{}{}{}{}", Text::Echo, Text::MsgPastEnd, self.line, Text::MsgNothingMoved).ok();
                self.not_resumed(to, Text::WhyPastEnd);
                Turn::Idle
            }
            Err(_) if !card.detected() => self.card_gone(card, m, out),
            Err(e) => {
                uwriteln!(out, "{}{}{}{}{}{}", Text::Error, e, Text::AtSdByte, self.pos, Text::JobStopped, self.line + 1).ok();
                self.not_resumed(to, e);
                Turn::Idle
            }
        }
    }

    /// Run from line `to` will not start: the job ends with `why`, nothing
    /// moved (the scan is ended by the firmware, `Machine::end_scan`).
    fn not_resumed(&mut self, to: u32, why: Text) {
        self.why = Some(why.as_fstr());
        self.reached = to;
        self.phase = Phase::Draining(Outcome::NotResumed(to));
    }

    /// [`SdJob::record_due`] may find one due: a job, or a record waiting.
    pub fn record_maybe_due(&self) -> bool {
        self.active() || self.record_now != NO_RECORD
    }

    /// A record of the line reached is due (run from line, `ui::resume`):
    /// when the job pauses or ends, and every [`RECORD_EVERY_S`] seconds
    /// while it cuts; when a job starts (from the menu or M24), the whole
    /// record. `now_ms`: a clock in milliseconds, its low 16 bits (wrapping:
    /// the 30 s fit, and no division by 1000 on every call). Called from every
    /// wait (the main loop sits in a line's wait for the last part of a
    /// job: M5 waits for the moves queued before it), it follows the line
    /// reached while the job cuts; not while a scan reads lines (they are
    /// not reached), nor after it.
    ///
    /// [`RECORD_EVERY_S`]: crate::ui::resume::RECORD_EVERY_S
    pub fn record_due(&mut self, m: &Machine, now_ms: u16) -> Option<Due> {
        if matches!(self.phase, Phase::Running | Phase::Draining(Outcome::Done)) && self.line > 0 {
            self.reached = self.cut_line(m).max(1);
            if now_ms.wrapping_sub(self.saved_ms) >= crate::ui::resume::RECORD_EVERY_S * 1000 {
                self.record_now = self.record_now.max(RECORD_LINE);
            }
        }
        let due = core::mem::replace(&mut self.record_now, NO_RECORD);
        if due == NO_RECORD {
            return None;
        }
        self.saved_ms = now_ms;
        Some(if due == RECORD_START {
            Due::Start(self.reached)
        } else if matches!(self.phase, Phase::Ended(Outcome::Done)) {
            Due::Reached(0)
        } else {
            Due::Reached(self.reached)
        })
    }

    /// After a line ran: on an error, stop reading (the moves before it finish).
    pub fn line_done(&mut self, r: CmdResult, m: &mut Machine, out: &mut impl uWrite) {
        if let Err(e) = r {
            if matches!(self.phase, Phase::Running | Phase::Paused | Phase::Scanning(_)) {
                if e == crate::gcode::interp::Error::Aborted {
                    return; // the abort path ends the job
                }
                m.report_error(out, e);
                self.why = Some(e.message());
                uwriteln!(out, "{}{}{}", Text::Echo, Text::MsgStoppedAtLine, self.line).ok();
                self.phase = Phase::Draining(Outcome::BadLine(self.line));
            }
        }
    }
    fn end(&mut self, card: &mut impl Card, m: &mut Machine, o: Outcome, out: &mut impl uWrite) -> Turn {
        card.close().ok();
        m.sd_job = false;
        self.phase = Phase::Ended(o);
        self.record_now = self.record_now.max(RECORD_LINE);
        match o {
            Outcome::Done => uwriteln!(out, "{}", Text::MsgDonePrinting).ok(),
            Outcome::Aborted => uwriteln!(out, "{}{}", Text::Echo, Text::MsgAborted).ok(),
            Outcome::BadLine(n) => uwriteln!(out, "{}{}{}", Text::Echo, Text::MsgEndedAtLine, n).ok(),
            Outcome::ReadError(p) => uwriteln!(out, "{}{}{}", Text::Echo, Text::MsgReadErrorAt, p).ok(),
            Outcome::NotResumed(n) => uwriteln!(out, "{}{}{}", Text::Echo, Text::MsgNotResumed, n).ok(),
            Outcome::CardRemoved(n) => {
                uwriteln!(out, "{}{}{}", Text::Echo, Text::MsgCardEnded, n).ok();
                return Turn::RetractThenSpindleOff;
            }
        };
        Turn::SpindleOff
    }

    /// Next line of the file into `line`: `Ok(None)` at the end. Blank lines
    /// are skipped, and so is a byte-order mark at the start of the file.
    /// Errors: the card failed, a control byte (binary data), or code past
    /// `MAX_LINE_LEN` (comment text past it is dropped: [`LineCut`]). Bytes
    /// from 0x80 up (UTF-8 or Latin-1 text, as in a comment `(fräsen)`) pass
    /// to the parser, which ignores them in a comment and refuses them
    /// anywhere else.
    fn next_line(&mut self, card: &mut impl Card, line: &mut [u8; MAX_LINE_LEN]) -> Result<Option<usize>, Text> {
        loop {
            let mut n = 0usize;
            let mut consumed = 0u32;
            let mut ended = false;
            let mut cut = LineCut::new();
            loop {
                if self.head == self.fill {
                    if self.eof {
                        break;
                    }
                    let got = card.read(&mut self.chunk).map_err(SdError::text)?;
                    self.head = 0;
                    self.fill = got as u8;
                    if got == 0 {
                        self.eof = true;
                        break;
                    }
                }
                if cut == LineCut::new() {
                    // The common case, code outside comments: a run of it
                    // is stored without classifying each byte.
                    let run = self.chunk.get(self.head as usize..self.fill as usize).unwrap_or(&[]);
                    let k = code_run(run, line.get_mut(n..).unwrap_or(&mut []));
                    n += k;
                    self.head += k as u8;
                    consumed += k as u32;
                    if self.head == self.fill {
                        continue;
                    }
                }
                let b = self.chunk[self.head as usize];
                self.head += 1;
                consumed += 1;
                match b {
                    b'\n' => {
                        ended = true;
                        break;
                    }
                    b'\r' => {}
                    b'\t' | 0x20..=0x7E | 0x80..=0xFF => match cut.keep(b, n) {
                        Keep::Store => {
                            line[n] = b;
                            n += 1;
                            if self.pos == 0 && n == BOM.len() && line[..n] == BOM {
                                n = 0;
                            }
                        }
                        Keep::Drop => {}
                        Keep::Fold => n = folded_len(&line[..n]),
                        Keep::Full => return Err(Text::ErrLineTooLong),
                    },
                    _ => return Err(Text::ErrBinary),
                }
            }
            if consumed == 0 {
                return Ok(None);
            }
            self.pos += consumed;
            self.line += 1;
            let blank = line[..n].iter().all(|&b| b == b' ' || b == b'\t');
            if !blank {
                return Ok(Some(n));
            }
            if !ended && self.eof {
                return Ok(None);
            }
        }
    }

    /// M27: progress report.
    pub fn report(&self, out: &mut impl uWrite) {
        if self.active() {
            uwriteln!(out, "{}{}/{}", Text::SdPrintingByte, self.pos, self.size).ok();
        } else {
            uwriteln!(out, "{}", Text::NotSdPrinting).ok();
        }
    }
}

/// `part × of / whole`, in u32 only (a u64 division costs 2.8 KB of flash on
/// the AVR): both are scaled down until the product cannot overflow; `of`
/// is at most 1000. 0 for an empty whole.
fn scaled(part: u32, whole: u32, of: u32) -> u32 {
    let (mut p, mut w) = (part.min(whole), whole);
    while w > u32::MAX / 1024 {
        p >>= 8;
        w >>= 8;
    }
    if w == 0 {
        return 0;
    }
    p * of / w
}

/// Run one SD command (M20–M29, M524) from the serial line. `arg` is the
/// text after the code (file name, or `S<pos>` for M26).
pub fn command(job: &mut SdJob, card: &mut impl Card, m: &mut Machine, out: &mut impl uWrite, code: u16, arg: &[u8]) -> Result<(), Text> {
    command_with(job, card, SdJobFlags { sd_job: &mut m.sd_job, aborts: m.aborts }, out, code, arg)
}

/// [`command`] over the machine's job flags only (what `Io::sd_command`
/// is given).
pub fn command_with(
    job: &mut SdJob,
    card: &mut impl Card,
    flags: SdJobFlags<'_>,
    out: &mut impl uWrite,
    code: u16,
    arg: &[u8],
) -> Result<(), Text> {
    let busy = job.active();
    match code {
        20 => {
            match card.mount() {
                // Marlin: `echo:No media`, not an error (OctoPrint stops at
                // an `Error:` it does not know).
                Err(SdError::NoCard) => {
                    uwriteln!(out, "{}{}", Text::Echo, Text::MsgNoMedia).ok();
                    return Ok(());
                }
                r => r.map_err(SdError::text)?,
            }
            uwriteln!(out, "{}", Text::BeginFileList).ok();
            // The root's files, as Marlin lists them without `L`: 8.3 name
            // and size (folders are for the menu).
            let r = card.list(Folder::Root, &mut |e| {
                if !e.dir {
                    uwriteln!(out, "{} {}", e.name, e.size).ok();
                }
            });
            uwriteln!(out, "{}", Text::EndFileList).ok();
            r.map_err(SdError::text)?;
        }
        21 => {
            if !busy {
                card.unmount();
            }
            match card.mount() {
                // Marlin's answer for a missing card: an echo, not an error
                // (OctoPrint sends M21 at connect and goes offline on an
                // `Error:` it does not know).
                Err(SdError::NoCard) => {
                    uwriteln!(out, "{}{}", Text::Echo, Text::MsgSdInitFail).ok();
                }
                r => {
                    r.map_err(SdError::text)?;
                    uwriteln!(out, "{}{}", Text::Echo, Text::MsgCardOk).ok();
                }
            }
        }
        33 => {
            // Marlin's long name of a root file: `/<long name>` (its 8.3
            // name when it has none), `/???` when there is no such file.
            let name = Name::parse(arg).ok_or(Text::ErrBadName)?;
            card.mount().map_err(SdError::text)?;
            let mut found = false;
            card.list(Folder::Root, &mut |e| {
                if e.name == name && !e.dir {
                    found = true;
                    if e.long.is_empty() {
                        uwriteln!(out, "{}{}", F!("/"), name).ok();
                    } else {
                        uwriteln!(out, "{}{}", F!("/"), e.long).ok();
                    }
                }
            })
            .map_err(SdError::text)?;
            if !found {
                uwriteln!(out, "{}", F!("/???")).ok();
            }
        }
        22 => {
            if busy {
                return Err(Text::ErrJobRunning);
            }
            job.phase = Phase::Idle;
            card.unmount();
            uwriteln!(out, "{}{}", Text::Echo, Text::MsgCardReleased).ok();
        }
        23 => {
            if busy {
                return Err(Text::ErrJobRunning);
            }
            let name = Name::parse(arg).ok_or(Text::ErrBadName)?;
            if let Err(e) = job.select(card, Folder::Root, &name) {
                uwriteln!(out, "{}{}.", Text::OpenFailed, name).ok();
                return Err(e.text());
            }
            uwriteln!(out, "{}{}{}{}", Text::FileOpened, name, Text::SizeWord, job.size).ok();
            uwriteln!(out, "{}", Text::FileSelected).ok();
        }
        24 => job.start_with(flags)?,
        25 => job.pause(),
        26 => {
            let pos = parse_s(arg).ok_or(Text::ErrSeek)?;
            job.seek(card, pos)?;
        }
        27 => job.report(out),
        28 => {
            if busy {
                return Err(Text::ErrJobRunning);
            }
            let name = Name::parse(arg).ok_or(Text::ErrBadName)?;
            job.phase = Phase::Idle;
            card.mount().map_err(SdError::text)?;
            card.open(Folder::Root, &name, true).map_err(SdError::text)?;
            job.name = name;
            job.phase = Phase::Writing;
            uwriteln!(out, "{}{}", Text::WritingToFile, name).ok();
        }
        29 => {
            if job.phase == Phase::Writing {
                job.phase = Phase::Idle;
                card.close().map_err(SdError::text)?;
                uwriteln!(out, "{}", Text::DoneSaving).ok();
            }
        }
        524 => job.abort(),
        _ => return Err(Text::ErrNoFileSelected),
    }
    Ok(())
}

/// While M28 writes a file: store `line` (+ newline). False when not writing.
pub fn capture(job: &mut SdJob, card: &mut impl Card, line: &[u8], out: &mut impl uWrite) -> bool {
    if !matches!(job.phase, Phase::Writing) {
        return false;
    }
    if card.write(line).and_then(|_| card.write(b"\n")).is_err() {
        uwriteln!(out, "{}{}", Text::Error, Text::ErrWrite).ok();
        card.close().ok();
        job.phase = Phase::Idle;
    }
    true
}

/// `S<digits>` → the number.
fn parse_s(arg: &[u8]) -> Option<u32> {
    let t = arg.strip_prefix(b"S").or_else(|| arg.strip_prefix(b"s"))?;
    let t = t.strip_prefix(b" ").unwrap_or(t);
    if t.is_empty() || t.len() > 9 {
        return None;
    }
    let mut v = 0u32;
    for &b in t {
        if !b.is_ascii_digit() {
            return None;
        }
        v = v * 10 + (b - b'0') as u32;
    }
    Some(v)
}

/// The SD command recogniser lives with the other codes taken before the
/// parser (the machine, below this module, needs it).
pub use crate::hostcodes::sd_code;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A card in RAM: files as (folder path, 8.3 name, long name, bytes),
    /// folders as entries with no bytes and `dir` set.
    pub struct FakeCard {
        pub present: bool,
        pub mounted: bool,
        pub files: Vec<FakeEntry>,
        /// The current folder, as a path of 8.3 names joined by `/` ("" is the root).
        pub cwd: String,
        open: Option<(usize, usize, bool)>,
        /// Reads fail from this byte offset on.
        pub fail_at: Option<usize>,
        /// The card is pulled by the read that reaches this byte offset.
        pub pull_at: Option<usize>,
    }

    /// One entry of a [`FakeCard`].
    pub struct FakeEntry {
        pub folder: String,
        pub name: Name,
        pub long: String,
        pub dir: bool,
        pub data: Vec<u8>,
    }

    impl FakeCard {
        /// Root files with 8.3 names.
        pub fn new(files: &[(&str, &str)]) -> FakeCard {
            let mut c =
                FakeCard { present: true, mounted: false, files: Vec::new(), cwd: String::new(), open: None, fail_at: None, pull_at: None };
            for (n, d) in files {
                c.add("", n, "", false, d);
            }
            c
        }

        /// Add an entry in `folder` (a path of 8.3 names, "" for the root).
        pub fn add(&mut self, folder: &str, name: &str, long: &str, dir: bool, data: &str) -> &mut FakeCard {
            let name = Name::parse(name.as_bytes()).unwrap();
            self.files.push(FakeEntry { folder: folder.into(), name, long: long.into(), dir, data: data.as_bytes().to_vec() });
            self
        }

        fn folder(&self, at: Folder) -> String {
            match at {
                Folder::Root => String::new(),
                Folder::Current => self.cwd.clone(),
            }
        }
    }

    impl Card for FakeCard {
        fn detected(&self) -> bool {
            self.present
        }
        fn mount(&mut self) -> Result<(), SdError> {
            if !self.present {
                return Err(SdError::NoCard);
            }
            self.mounted = true;
            Ok(())
        }
        fn unmount(&mut self) {
            self.mounted = false;
            self.open = None;
            self.cwd.clear();
        }
        fn list(&mut self, at: Folder, f: &mut dyn FnMut(&Entry<'_>)) -> Result<(), SdError> {
            let folder = self.folder(at);
            for e in self.files.iter().filter(|e| e.folder == folder) {
                f(&Entry { name: e.name, long: &e.long, dir: e.dir, size: e.data.len() as u32 });
            }
            Ok(())
        }
        fn open(&mut self, at: Folder, name: &Name, write: bool) -> Result<u32, SdError> {
            let folder = self.folder(at);
            let i = match self.files.iter().position(|e| e.folder == folder && e.name == *name && !e.dir) {
                Some(i) => i,
                None if write => {
                    self.files.push(FakeEntry { folder, name: *name, long: String::new(), dir: false, data: Vec::new() });
                    self.files.len() - 1
                }
                None => return Err(SdError::NotFound),
            };
            if write {
                self.files[i].data.clear();
            }
            self.open = Some((i, 0, write));
            Ok(self.files[i].data.len() as u32)
        }
        fn enter(&mut self, name: &Name) -> Result<(), SdError> {
            if !self.files.iter().any(|e| e.folder == self.cwd && e.name == *name && e.dir) {
                return Err(SdError::NotFound);
            }
            if !self.cwd.is_empty() {
                self.cwd.push('/');
            }
            self.cwd.push_str(name.as_str());
            Ok(())
        }
        fn leave(&mut self) -> Result<(), SdError> {
            let cut = self.cwd.rfind('/').unwrap_or(0);
            self.cwd.truncate(cut);
            Ok(())
        }
        fn depth(&self) -> u8 {
            if self.cwd.is_empty() {
                0
            } else {
                self.cwd.matches('/').count() as u8 + 1
            }
        }
        fn read(&mut self, buf: &mut [u8]) -> Result<usize, SdError> {
            if !self.present || !self.mounted {
                return Err(SdError::NoCard);
            }
            let (i, pos, _) = self.open.as_mut().ok_or(SdError::NotFound)?;
            if self.pull_at.is_some_and(|p| *pos >= p) {
                self.present = false;
                return Err(SdError::NoCard);
            }
            if let Some(f) = self.fail_at {
                if *pos >= f {
                    return Err(SdError::ReadFailed);
                }
            }
            let d = &self.files[*i].data;
            let n = buf.len().min(d.len() - *pos).min(17); // odd chunks
            buf[..n].copy_from_slice(&d[*pos..*pos + n]);
            *pos += n;
            Ok(n)
        }
        fn seek(&mut self, p: u32) -> Result<(), SdError> {
            let (_, pos, _) = self.open.as_mut().ok_or(SdError::NotFound)?;
            *pos = p as usize;
            Ok(())
        }
        fn write(&mut self, data: &[u8]) -> Result<(), SdError> {
            let (i, _, w) = self.open.ok_or(SdError::NotFound)?;
            if !w {
                return Err(SdError::WriteFailed);
            }
            self.files[i].data.extend_from_slice(data);
            Ok(())
        }
        fn close(&mut self) -> Result<(), SdError> {
            self.open = None;
            Ok(())
        }
    }

    /// Serial output collected as a String.
    #[derive(Default)]
    pub struct Out(pub String);
    impl uWrite for Out {
        type Error = core::convert::Infallible;
        fn write_str(&mut self, s: &str) -> Result<(), Self::Error> {
            self.0.push_str(s);
            Ok(())
        }
    }

    /// The main loop's quick tests ([`SdJob::quiet`], [`SdJob::record_maybe_due`],
    /// and `active()` before `card_check`) against the calls they spare: in
    /// every phase, with a record waiting or not, an abort seen or not, a
    /// card in or out, a test that says "nothing to do" is never wrong
    /// (the call returns nothing and changes nothing), and says it for
    /// every phase without a job.
    #[test]
    fn the_main_loops_quick_tests_skip_only_calls_that_do_nothing() {
        let outcomes = [Outcome::Done, Outcome::Aborted, Outcome::NotResumed(3), Outcome::CardRemoved(2)];
        let mut phases = vec![Phase::Idle, Phase::Selected, Phase::Running, Phase::Paused, Phase::Writing, Phase::Scanning(5)];
        for o in outcomes {
            phases.extend([Phase::Draining(o), Phase::Aborting(o), Phase::Ended(o)]);
        }
        let snap = |j: &SdJob| (j.phase, j.pos, j.line, j.requests, j.seen_aborts, j.reached, j.saved_ms, j.record_now);
        let mut quiet_phases = 0;
        for &phase in &phases {
            for record_now in [NO_RECORD, RECORD_LINE, RECORD_START] {
                for seen in [0u8, 1] {
                    for present in [true, false] {
                        let mut m = Machine::new();
                        m.aborts = 1;
                        let mut card = FakeCard::new(&[("A.NC", "G1 X1\nG1 X2\n")]);
                        card.present = present;
                        let mut job = SdJob::new();
                        if present {
                            card.mount().unwrap();
                            job.select(&mut card, Folder::Root, &Name::parse(b"A.NC").unwrap()).unwrap();
                        }
                        job.phase = phase;
                        job.line = 1;
                        job.record_now = record_now;
                        job.seen_aborts = seen;
                        let before = snap(&job);
                        let what = format!("{phase:?} record {record_now} seen {seen} card {present}");
                        if !job.record_maybe_due() {
                            assert_eq!(job.record_due(&m, 40_000), None, "{what}");
                            assert_eq!(snap(&job), before, "{what}");
                        }
                        if !job.active() {
                            assert!(!job.card_check(present, &m, &mut Out::default()), "{what}");
                            assert_eq!(snap(&job), before, "{what}");
                        }
                        if job.quiet(&m) {
                            let mut line = [0u8; MAX_LINE_LEN];
                            let mut out = Out::default();
                            assert_eq!(job.poll(&mut card, &mut m, true, &mut line, &mut out), Turn::Idle, "{what}");
                            assert_eq!(snap(&job), before, "{what}");
                            assert_eq!(out.0, "", "{what}");
                            quiet_phases += 1;
                        }
                    }
                }
            }
        }
        // Quiet: each of the 7 phases without a job (Idle, Selected,
        // Writing, the 4 Ended) × 3 records × 2 cards, with the abort seen.
        assert_eq!(quiet_phases, 7 * 3 * 2);
    }

    /// The 30-second record of a running job on the clock's low 16 bits of
    /// milliseconds against the plain rule it replaces (seconds, `ms / 1000`,
    /// on the whole clock): over a run whose clock passes several 16-bit
    /// wraps, with irregular main-loop passes, both make as many records,
    /// 30 s apart (the plain rule: 29 to 30, whole seconds).
    #[test]
    fn running_job_records_every_30_s_on_the_wrapping_ms_clock_as_the_plain_seconds_rule() {
        let m = Machine::new();
        let mut job = SdJob::new();
        job.phase = Phase::Running;
        job.line = 7;
        let (mut fast, mut plain) = (Vec::new(), Vec::new());
        // The job's start writes the whole record: both clocks start there.
        let mut ms: u32 = 1_000_000 - 12_345;
        job.record_now = RECORD_START;
        assert_eq!(job.record_due(&m, ms as u16), Some(Due::Start(7)));
        let mut saved_s = (ms / 1000) as u16;
        let mut seed = 12_345u32;
        while ms < 1_000_000 + 400_000 {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ms += 1 + (seed >> 24) % 150;
            if let Some(d) = job.record_due(&m, ms as u16) {
                assert_eq!(d, Due::Reached(7));
                fast.push(ms);
            }
            let now_s = (ms / 1000) as u16;
            if now_s.wrapping_sub(saved_s) >= crate::ui::resume::RECORD_EVERY_S {
                saved_s = now_s;
                plain.push(ms);
            }
        }
        assert!(fast.len() >= 12, "{fast:?}");
        assert!(fast.len().abs_diff(plain.len()) <= 1, "{fast:?} {plain:?}");
        // The plain rule: 29 to 30 s apart (whole seconds), plus at most one
        // main-loop pass; the wrapping one: 30 s, plus at most one pass.
        for w in plain.windows(2) {
            assert!((29_000..30_150).contains(&(w[1] - w[0])), "{plain:?}");
        }
        for w in fast.windows(2) {
            assert!((30_000..30_150).contains(&(w[1] - w[0])), "{fast:?}");
        }
    }

    #[test]
    fn names_are_8_3_upper_case() {
        assert_eq!(Name::parse(b"job.gco").unwrap().as_str(), "JOB.GCO");
        assert_eq!(Name::parse(b"/PART1").unwrap().as_str(), "PART1");
        assert!(Name::parse(b"TOOLONGNAME.G").is_none());
        assert!(Name::parse(b"A.GCODE").is_none());
        assert!(Name::parse(b"").is_none());
        assert_eq!(Name::from_parts(b"JOB     ", b"NC ").as_str(), "JOB.NC");
        assert_eq!(Name::from_parts(b"README", b"").as_str(), "README");
    }

    #[test]
    fn sd_codes_are_recognised_with_their_argument() {
        assert_eq!(sd_code(b"M23 job.gco"), Some((23, &b"job.gco"[..])));
        assert_eq!(sd_code(b" m20 ; list"), Some((20, &b""[..])));
        assert_eq!(sd_code(b"M26 S100"), Some((26, &b"S100"[..])));
        assert_eq!(sd_code(b"M524"), Some((524, &b""[..])));
        assert_eq!(sd_code(b"M2"), None);
        assert_eq!(sd_code(b"M30"), None);
        assert_eq!(sd_code(b"G1 X1"), None);
        assert_eq!(parse_s(b"S1234"), Some(1234));
        assert_eq!(parse_s(b"S"), None);
    }

    fn lines_of(text: &str) -> Result<Vec<String>, Text> {
        let mut card = FakeCard::new(&[("A.G", text)]);
        let mut job = SdJob::new();
        job.select(&mut card, Folder::Root, &Name::parse(b"A.G").unwrap()).unwrap();
        let mut v = Vec::new();
        let mut buf = [0u8; MAX_LINE_LEN];
        while let Some(n) = job.next_line(&mut card, &mut buf)? {
            v.push(String::from_utf8(buf[..n].to_vec()).unwrap());
        }
        assert_eq!(job.pos, text.len() as u32);
        Ok(v)
    }

    /// The line splitter without `code_run`: every byte through
    /// [`LineCut::keep`], as `next_line` reads a line.
    fn lines_plain(data: &[u8]) -> Result<Vec<Vec<u8>>, Text> {
        let mut v = Vec::new();
        let mut it = data.iter().copied().peekable();
        let mut first = true;
        while it.peek().is_some() {
            let (mut line, mut cut) = (Vec::new(), LineCut::new());
            for b in it.by_ref() {
                match b {
                    b'\n' => break,
                    b'\r' => {}
                    b'\t' | 0x20..=0x7E | 0x80..=0xFF => match cut.keep(b, line.len()) {
                        Keep::Store => {
                            line.push(b);
                            if first && line == BOM {
                                line.clear();
                            }
                        }
                        Keep::Drop => {}
                        Keep::Fold => line.truncate(folded_len(&line)),
                        Keep::Full => return Err(Text::ErrLineTooLong),
                    },
                    _ => return Err(Text::ErrBinary),
                }
            }
            first = false;
            if !line.iter().all(|&b| b == b' ' || b == b'\t') {
                v.push(line);
            }
        }
        Ok(v)
    }

    #[test]
    fn the_code_run_fast_path_splits_lines_as_the_byte_by_byte_splitter() {
        let max = crate::protocol::MAX_LINE_LEN;
        let pieces: [&[u8]; 14] =
            [b"G1 X1.5 Y-2", b" ", b"\t", b"(", b")", b";", b"\r", b"\n", "ä".as_bytes(), &BOM, b"*", b"\x01", b"N7", b"%"];
        let mut rng = crate::test_util::XorShift(0x2545_f491);
        let mut next = move || rng.next();
        for case in 0..3000 {
            let mut data = Vec::new();
            while data.len() < 40 + case % 700 {
                let r = next();
                match r % 23 {
                    // Long runs of code or comment text, to reach the line's limit.
                    0 => data.extend(core::iter::repeat_n(b'7', (r >> 8) as usize % (max + 20))),
                    1 => data.extend(core::iter::repeat_n(b'c', (r >> 8) as usize % (max + 20))),
                    // A control byte (binary) only now and then, so most files run to their end.
                    k if k as usize >= pieces.len() || pieces[k as usize] == b"\x01" && r & 0x700 != 0 => {
                        data.extend_from_slice(b"G0 Z1\n")
                    }
                    k => data.extend_from_slice(pieces[k as usize]),
                }
            }
            let text = String::from_utf8_lossy(&data);
            let mut card = FakeCard::new(&[]);
            card.files.push(FakeEntry {
                folder: String::new(),
                name: Name::parse(b"A.G").unwrap(),
                long: String::new(),
                dir: false,
                data: data.clone(),
            });
            let mut job = SdJob::new();
            job.select(&mut card, Folder::Root, &Name::parse(b"A.G").unwrap()).unwrap();
            let mut got = Vec::new();
            let mut buf = [0u8; MAX_LINE_LEN];
            let got = loop {
                match job.next_line(&mut card, &mut buf) {
                    Ok(Some(n)) => got.push(buf[..n].to_vec()),
                    Ok(None) => break Ok(got),
                    Err(e) => break Err(e),
                }
            };
            assert_eq!(got, lines_plain(&data), "case {case}: {text:?}");
        }
    }

    #[test]
    fn lines_split_across_chunks_and_crlf_and_blanks_are_handled() {
        let long: String = (0..30).map(|i| format!("G1 X{i}.5 Y{i}\r\n\r\n")).collect();
        let v = lines_of(&long).unwrap();
        assert_eq!(v.len(), 30);
        assert_eq!(v[29], "G1 X29.5 Y29");
        assert_eq!(lines_of("G0 X1\nG0 X2").unwrap(), ["G0 X1", "G0 X2"]);
        assert_eq!(lines_of("").unwrap(), Vec::<String>::new());
    }

    #[test]
    fn a_binary_byte_or_an_overlong_line_is_an_error() {
        assert_eq!(lines_of("G0 X1\nG0\u{1} X2\n"), Err(Text::ErrBinary));
        assert_eq!(lines_of("G0 X1\nG0\u{7f} X2\n"), Err(Text::ErrBinary));
        // Text in another encoding is not binary: it reaches the parser.
        assert_eq!(lines_of("(fräsen)\nG0 X1 ; Größe\n").unwrap(), ["(fräsen)", "G0 X1 ; Größe"]);
        let long = format!("G1 X{}\n", "1".repeat(crate::protocol::MAX_LINE_LEN));
        assert_eq!(lines_of(&long), Err(Text::ErrLineTooLong));
    }

    #[test]
    fn a_byte_order_mark_starting_the_file_is_skipped_and_nowhere_else() {
        assert_eq!(lines_of("\u{feff}G0 X1\n(Ø3 end mill)\n").unwrap(), ["G0 X1", "(Ø3 end mill)"]);
        assert_eq!(lines_of("\u{feff}\nG0 X1\n").unwrap(), ["G0 X1"]);
        // Later in the file the parser sees it (and refuses it as code).
        assert_eq!(lines_of("G0 X1\n\u{feff}G0 X2\n").unwrap(), ["G0 X1", "\u{feff}G0 X2"]);
    }

    #[test]
    fn comment_text_past_the_limit_is_dropped_and_code_past_it_is_too_long() {
        let max = crate::protocol::MAX_LINE_LEN;
        let semi = format!("G0 X1 ; {}\n", "d".repeat(300));
        let v = lines_of(&semi).unwrap();
        assert_eq!(v[0].len(), max);
        assert!(v[0].starts_with("G0 X1 ; ddd"));
        let paren = format!("G0 X1 ({}) Y2\n", "d".repeat(300));
        let v = lines_of(&paren).unwrap();
        assert_eq!(v[0], "G0 X1 () Y2");
        let code = format!("G0 X1 ({}) Y{}\n", "d".repeat(300), "2".repeat(max));
        assert_eq!(lines_of(&code), Err(Text::ErrLineTooLong));
    }

    #[test]
    fn m20_lists_and_m23_m27_report_like_marlin() {
        let mut card = FakeCard::new(&[("A.GCO", "G0 X1\n"), ("B.NC", "G0 X2\nG0 X3\n")]);
        let mut job = SdJob::new();
        let mut m = Machine::new();
        let mut out = Out::default();
        command(&mut job, &mut card, &mut m, &mut out, 20, b"").unwrap();
        assert_eq!(out.0, "Begin file list\nA.GCO 6\nB.NC 12\nEnd file list\n");
        out.0.clear();
        command(&mut job, &mut card, &mut m, &mut out, 23, b"b.nc").unwrap();
        assert_eq!(out.0, "File opened: B.NC Size: 12\nFile selected\n");
        out.0.clear();
        command(&mut job, &mut card, &mut m, &mut out, 27, b"").unwrap();
        assert_eq!(out.0, "Not SD printing\n");
        assert_eq!(command(&mut job, &mut card, &mut m, &mut out, 23, b"nope.g"), Err(Text::ErrNotFound));
    }

    #[test]
    fn m33_answers_the_long_name_as_marlin_and_leaves_the_selected_file() {
        let mut card = FakeCard::new(&[("A.GCO", "G0 X1\n"), ("B.NC", "G0 X2\nG0 X3\n")]);
        let mut job = SdJob::new();
        let mut m = Machine::new();
        let mut out = Out::default();
        assert_eq!(sd_code(b"M33 b.nc"), Some((33, &b"b.nc"[..])));
        command(&mut job, &mut card, &mut m, &mut out, 23, b"a.gco").unwrap();
        out.0.clear();
        command(&mut job, &mut card, &mut m, &mut out, 33, b"b.nc").unwrap();
        command(&mut job, &mut card, &mut m, &mut out, 33, b"c.nc").unwrap();
        assert_eq!(out.0, "/B.NC\n/???\n");
        assert_eq!(job.name, Name::parse(b"A.GCO").unwrap(), "the selected job is unchanged");
    }

    #[test]
    fn m28_writes_lines_until_m29() {
        let mut card = FakeCard::new(&[]);
        let mut job = SdJob::new();
        let mut m = Machine::new();
        let mut out = Out::default();
        command(&mut job, &mut card, &mut m, &mut out, 28, b"new.gco").unwrap();
        assert!(capture(&mut job, &mut card, b"G1 X1 F600", &mut out));
        assert!(capture(&mut job, &mut card, b"M2", &mut out));
        command(&mut job, &mut card, &mut m, &mut out, 29, b"").unwrap();
        assert!(!capture(&mut job, &mut card, b"G0 X0", &mut out));
        assert_eq!(card.files[0].data, b"G1 X1 F600\nM2\n");
        assert!(out.0.contains("Writing to file: NEW.GCO") && out.0.ends_with("Done saving file.\n"));
    }

    #[test]
    fn a_card_pulled_mid_job_aborts_keeping_the_spindle_then_retracts_and_names_the_executing_line() {
        let mut card = FakeCard::new(&[("A.NC", "G0 X1\n")]);
        let mut job = SdJob::new();
        let mut m = Machine::new();
        let mut out = Out::default();
        job.phase = Phase::Running;
        job.line = 70_010;
        // Lines 70,007 and 70,008 are queued; the first one is executing.
        for (tag, x) in [(70_007u32, 100), (70_008, 200)] {
            m.planner.line_tag = tag as u16;
            m.planner.push_line([x, 0, 0, 0], 600.0, false, &m.settings).unwrap();
        }
        assert!(!job.card_check(true, &m, &mut out), "card still in");
        assert!(job.card_check(false, &m, &mut out));
        assert_eq!(job.phase, Phase::Aborting(Outcome::CardRemoved(70_007)));
        assert_eq!(job.take_requests(), req::ABORT | req::KEEP_SPINDLE);
        assert_eq!(out.0, "echo:SD card removed: job stopped at line 70007\n");
        assert!(!job.card_check(false, &m, &mut out), "once");
        // The machine finished the abort: the job ends, the tool retracts.
        m.aborts = m.aborts.wrapping_add(1);
        let mut line = [0u8; MAX_LINE_LEN];
        assert_eq!(job.poll(&mut card, &mut m, true, &mut line, &mut out), Turn::RetractThenSpindleOff);
        assert_eq!(job.phase, Phase::Ended(Outcome::CardRemoved(70_007)));
        assert!(!job.active());
    }

    #[test]
    fn progress_follows_the_executing_line_not_the_lines_read_ahead() {
        let mut job = SdJob::new();
        let mut m = Machine::new();
        job.phase = Phase::Running;
        job.size = 10_000;
        job.pos = 8_000; // 80 % read
        job.line = 400;
        assert_eq!(job.percent(), 80);
        // Nothing planned: the cut is at the last line read.
        assert_eq!(job.permille_cut(&m), 800);
        // Line 100 is executing, 300 more are read ahead: a quarter of the
        // lines read, so a quarter of the 80 % read.
        m.planner.line_tag = 100;
        m.planner.push_line([100, 0, 0, 0], 600.0, false, &m.settings).unwrap();
        assert_eq!(job.cut_line(&m), 100);
        assert_eq!(job.permille_cut(&m), 200);
        // Large files: no overflow (a 3 GB file half read, all of it cut).
        let mut big = SdJob::new();
        (big.phase, big.size, big.pos, big.line) = (Phase::Running, 3_000_000_000, 1_500_000_000, 9);
        assert_eq!(big.permille_cut(&Machine::new()), 500);
        assert_eq!(scaled(7, 0, 1000), 0, "an empty file");
    }

    /// The card pulled while a line is read (after the turn's check saw it
    /// in): a removal, as when the check sees it, in a job and in run from
    /// line's scan, never a read error.
    #[test]
    fn a_card_pulled_during_a_read_is_a_removal_not_a_read_error() {
        for scan in [false, true] {
            let text: String = (0..300).map(|k| format!("G1 X{k}\n")).collect();
            let mut card = FakeCard::new(&[("A.NC", &text)]);
            card.mount().unwrap();
            let mut m = Machine::new();
            let mut job = SdJob::new();
            job.select(&mut card, Folder::Root, &Name::parse(b"A.NC").unwrap()).unwrap();
            if scan {
                job.start_from(&mut m, 250).unwrap();
            } else {
                job.phase = Phase::Running;
            }
            card.pull_at = Some(700);
            let (mut out, mut line) = (Out::default(), [0u8; MAX_LINE_LEN]);
            let mut turns = 0;
            while matches!(job.phase, Phase::Running | Phase::Scanning(_)) && turns < 1000 {
                job.poll(&mut card, &mut m, true, &mut line, &mut out);
                turns += 1;
            }
            assert!(!card.present, "the card was pulled by a read");
            assert!(!out.0.contains("rror"), "scan {scan}: {}", out.0);
            assert!(out.0.contains("removed"), "scan {scan}: {}", out.0);
            if scan {
                assert_eq!(job.phase, Phase::Draining(Outcome::NotResumed(250)));
            } else {
                assert!(matches!(job.phase, Phase::Aborting(Outcome::CardRemoved(_))), "{:?}", job.phase);
            }
        }
    }

    #[test]
    fn a_card_pulled_with_nothing_queued_names_the_last_line_read() {
        let mut job = SdJob::new();
        let m = Machine::new();
        let mut out = Out::default();
        job.phase = Phase::Paused;
        job.line = 12;
        assert!(job.card_check(false, &m, &mut out));
        assert_eq!(job.phase, Phase::Aborting(Outcome::CardRemoved(12)));
        let mut idle = SdJob::new();
        idle.phase = Phase::Ended(Outcome::Done);
        assert!(!idle.card_check(false, &m, &mut out), "no job: nothing to end");
    }
}
