//! The scripted host's protocol logic (docs/SPEC.md §4), without the simulator.
//!
//! [`Streamer`] is the state machine of a G-code sender: which line to send
//! next under a [`Flow`] policy, what an `ok`, an `Error:` or a `Resend:`
//! means. [`crate::Vm::stream`] drives it with the bytes the firmware prints.
//!
//! - `Flow::PingPong`: one line in flight; the next goes after its `ok`
//!   (Repetier-Host, Pronterface, OctoPrint by default).
//! - `Flow::CharCount(n)`: grbl's character-counting: keep at most `n` bytes of
//!   unacknowledged lines in flight (a line longer than `n` goes alone).
//! - Checksums (OctoPrint's habit): the stream starts with `N0 M110 N0*cs`, then
//!   line k of the job is sent as `N<k> <line>*<xor>`, k from 1. `Resend:<n>`
//!   (also `rs <n>`) rewinds to line n. With several lines in flight, the
//!   firmware answers every line that arrived after the bad one with its own
//!   `Resend`; those come in while the lines sent *before* the rewind are still
//!   at the front of the in-flight queue, and are ignored (each answered line
//!   still gets exactly one `ok`, which pops the queue).

use serde::Serialize;
use std::collections::VecDeque;

/// Flow control of a stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Flow {
    /// Send the next line only after the previous line's `ok`.
    PingPong,
    /// Keep at most this many bytes (including newlines) unacknowledged.
    CharCount(usize),
}

impl std::str::FromStr for Flow {
    type Err = String;
    /// `pingpong` or `count:N`.
    fn from_str(s: &str) -> Result<Flow, String> {
        if s == "pingpong" {
            return Ok(Flow::PingPong);
        }
        if let Some(n) = s.strip_prefix("count:") {
            return n.parse().map(Flow::CharCount).map_err(|e| format!("bad count '{n}': {e}"));
        }
        Err(format!("unknown flow '{s}' (pingpong | count:N)"))
    }
}

/// How to stream.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamOptions {
    pub flow: Flow,
    /// Number lines and append `*checksum`.
    pub checksums: bool,
    /// Give up after this many simulated seconds without finishing.
    pub timeout_s: f64,
}

impl StreamOptions {
    /// Given flow, no checksums, 600 s timeout.
    pub fn new(flow: Flow) -> StreamOptions {
        StreamOptions { flow, checksums: false, timeout_s: 600.0 }
    }

    /// With or without line numbers and checksums.
    pub fn with_checksums(mut self, on: bool) -> StreamOptions {
        self.checksums = on;
        self
    }

    /// With another timeout, simulated seconds.
    pub fn timeout(mut self, seconds: f64) -> StreamOptions {
        self.timeout_s = seconds;
        self
    }
}

impl From<Flow> for StreamOptions {
    fn from(flow: Flow) -> StreamOptions {
        StreamOptions::new(flow)
    }
}

/// What happened during a stream.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StreamReport {
    /// Job lines (not counting the `M110` preamble).
    pub lines_total: usize,
    /// Transmissions, including resends and the preamble.
    pub lines_sent: usize,
    /// `ok` lines received.
    pub oks: usize,
    /// Every `Error:`/`error:` line, verbatim.
    pub errors: Vec<String>,
    /// Rewinds performed on `Resend`.
    pub resends: usize,
    /// Bytes sent.
    pub bytes_sent: usize,
    /// Every line received during the stream.
    pub received: Vec<String>,
    /// VM time of the first byte, s.
    pub start_s: f64,
    /// VM time of the last `ok`, s.
    pub end_s: f64,
    /// `end_s - start_s`.
    pub duration_s: f64,
    /// The stream did not finish within the timeout.
    pub timed_out: bool,
}

/// XOR of all bytes, as Marlin/Repetier compute it over `N<n> <cmd>`.
pub fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}

/// `N<n> <line>*<checksum>`.
pub fn numbered_line(n: u32, line: &str) -> String {
    let body = format!("N{n} {line}");
    let cs = checksum(&body);
    format!("{body}*{cs}")
}

/// `ok`, or `ok` followed by a space and more (`ok N12`, `ok T:20`).
pub fn is_ok_line(line: &str) -> bool {
    line == "ok" || line.starts_with("ok ")
}

/// The end of the reply to one line: `ok`, or grbl's `error:<n>`, which
/// grbl sends instead of the `ok`.
pub fn is_reply_end(line: &str) -> bool {
    is_ok_line(line) || line.starts_with("error:")
}

/// An error report (`Error:...` Marlin/Repetier, `error:...` grbl).
pub fn is_error_line(line: &str) -> bool {
    line.starts_with("Error") || line.starts_with("error:") || line.starts_with("!!")
}

/// The line number of `Resend:12`, `Resend: 12`, `rs 12` or `rs N12`.
pub fn parse_resend(line: &str) -> Option<u32> {
    let rest = line.strip_prefix("Resend:").or_else(|| line.strip_prefix("rs ")).or_else(|| line.strip_prefix("resend:"))?;
    let rest = rest.trim().trim_start_matches('N');
    let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
    digits.parse().ok()
}

/// The lines of a G-code file as a host sends them: `;` comments and
/// surrounding blanks removed, empty lines dropped. Parenthesised comments are
/// left for the firmware.
pub fn prepare_gcode(text: &str) -> Vec<String> {
    text.lines().map(|l| l.split(';').next().unwrap_or("").trim().to_string()).filter(|l| !l.is_empty()).collect()
}

#[derive(Clone, Debug)]
struct InFlight {
    len: usize,
    epoch: u32,
}

/// The sender state machine. See the module docs.
#[derive(Clone, Debug)]
pub struct Streamer {
    flow: Flow,
    /// What goes on the wire (with `\n`), index = line number when numbered.
    wire: Vec<String>,
    checksums: bool,
    next: usize,
    in_flight: VecDeque<InFlight>,
    epoch: u32,
    report: StreamReport,
}

impl Streamer {
    /// A stream of `lines` (no newlines) with the given options.
    pub fn new<S: AsRef<str>>(lines: &[S], opts: &StreamOptions) -> Streamer {
        let mut wire = Vec::with_capacity(lines.len() + 1);
        if opts.checksums {
            wire.push(format!("{}\n", numbered_line(0, "M110 N0")));
            for (k, l) in lines.iter().enumerate() {
                wire.push(format!("{}\n", numbered_line(k as u32 + 1, l.as_ref())));
            }
        } else {
            wire.extend(lines.iter().map(|l| format!("{}\n", l.as_ref())));
        }
        Streamer {
            flow: opts.flow,
            wire,
            checksums: opts.checksums,
            next: 0,
            in_flight: VecDeque::new(),
            epoch: 0,
            report: StreamReport { lines_total: lines.len(), ..Default::default() },
        }
    }

    fn bytes_in_flight(&self) -> usize {
        self.in_flight.iter().map(|f| f.len).sum()
    }

    /// The next line to transmit now, if flow control allows one.
    pub fn next_to_send(&mut self) -> Option<String> {
        let line = self.wire.get(self.next)?;
        let allowed = match self.flow {
            Flow::PingPong => self.in_flight.is_empty(),
            Flow::CharCount(n) => self.in_flight.is_empty() || self.bytes_in_flight() + line.len() <= n,
        };
        if !allowed {
            return None;
        }
        let line = line.clone();
        self.in_flight.push_back(InFlight { len: line.len(), epoch: self.epoch });
        self.next += 1;
        self.report.lines_sent += 1;
        self.report.bytes_sent += line.len();
        Some(line)
    }

    /// Feed one received line. Returns true if it was an `ok`.
    pub fn on_line(&mut self, line: &str) -> bool {
        self.report.received.push(line.to_string());
        if is_ok_line(line) {
            self.report.oks += 1;
            self.in_flight.pop_front();
            return true;
        }
        if let Some(n) = parse_resend(line) {
            let fresh = self.in_flight.front().is_none_or(|f| f.epoch == self.epoch);
            if self.checksums && fresh && (n as usize) < self.wire.len() {
                self.next = n as usize;
                self.epoch += 1;
                self.report.resends += 1;
            }
            return false;
        }
        if is_error_line(line) {
            self.report.errors.push(line.to_string());
        }
        if line.starts_with("error:") {
            // grbl's error replaces the line's `ok`: it acknowledges it.
            self.in_flight.pop_front();
            return true;
        }
        false
    }

    /// Every line sent and acknowledged.
    pub fn done(&self) -> bool {
        self.next >= self.wire.len() && self.in_flight.is_empty()
    }

    /// Unacknowledged lines.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// The report so far.
    pub fn report(&self) -> &StreamReport {
        &self.report
    }

    /// The report, consuming the streamer.
    pub fn into_report(self) -> StreamReport {
        self.report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_matches_marlin_example() {
        // Marlin docs: "N3 T0*57"
        assert_eq!(checksum("N3 T0"), 57);
        assert_eq!(numbered_line(3, "T0"), "N3 T0*57");
    }

    #[test]
    fn resend_formats() {
        assert_eq!(parse_resend("Resend:12"), Some(12));
        assert_eq!(parse_resend("Resend: 7"), Some(7));
        assert_eq!(parse_resend("rs N5"), Some(5));
        assert_eq!(parse_resend("ok"), None);
        assert!(is_ok_line("ok N12") && is_ok_line("ok") && !is_ok_line("okay"));
    }

    #[test]
    fn prepare_strips_semicolon_comments_and_blanks() {
        let l = prepare_gcode("G21 ; mm\n\n  ; only comment\nG1 X1 (keep)\n");
        assert_eq!(l, vec!["G21", "G1 X1 (keep)"]);
    }

    #[test]
    fn ping_pong_waits_for_ok() {
        let mut s = Streamer::new(&["G0 X1", "G0 X2"], &StreamOptions::new(Flow::PingPong));
        assert_eq!(s.next_to_send().as_deref(), Some("G0 X1\n"));
        assert_eq!(s.next_to_send(), None);
        assert!(s.on_line("ok"));
        assert_eq!(s.next_to_send().as_deref(), Some("G0 X2\n"));
        s.on_line("ok");
        assert!(s.done());
        assert_eq!(s.report().oks, 2);
    }

    #[test]
    fn char_count_keeps_bytes_in_flight_under_limit() {
        let mut s = Streamer::new(&["AAAA", "BBBB", "CCCC"], &StreamOptions::new(Flow::CharCount(10)));
        assert!(s.next_to_send().is_some()); // 5
        assert!(s.next_to_send().is_some()); // 10
        assert!(s.next_to_send().is_none()); // would be 15
        s.on_line("ok");
        assert!(s.next_to_send().is_some());
    }

    #[test]
    fn resend_rewinds_once_while_old_lines_drain() {
        let opts = StreamOptions::new(Flow::CharCount(1000)).with_checksums(true);
        let mut s = Streamer::new(&["G1 X1", "G1 X2", "G1 X3"], &opts);
        let mut sent = Vec::new();
        while let Some(l) = s.next_to_send() {
            sent.push(l);
        }
        assert_eq!(sent[0], "N0 M110 N0*125\n");
        assert!(sent[1].starts_with("N1 G1 X1*"));
        // N0 ok, N1 corrupted: the firmware asks for 1, then for 1 again for N2, N3.
        s.on_line("ok");
        s.on_line("Error:checksum mismatch");
        s.on_line("Resend:1");
        s.on_line("ok");
        for _ in 0..2 {
            s.on_line("Error:Line Number is not Last Line Number+1");
            s.on_line("Resend:1");
            s.on_line("ok");
        }
        assert_eq!(s.report().resends, 1);
        let again: Vec<String> = std::iter::from_fn(|| s.next_to_send()).collect();
        assert_eq!(again.len(), 3);
        assert!(again[0].starts_with("N1 "));
        for _ in 0..3 {
            s.on_line("ok");
        }
        assert!(s.done());
        assert_eq!(s.report().errors.len(), 3);
        assert_eq!(s.report().lines_sent, 7);
    }
}
