//! `?`: grbl 1.1's status line (state, position, buffer, line number,
//! feed and speed, inputs, work offset and overrides in turn, accessories,
//! tool).

use super::{Io, Machine, State};
use crate::dollar;
use crate::flash::FStr;
use ufmt::{uwrite, uwriteln};

/// A status-report field of letters (`|Pn:XZ`, `|A:SF`), left out when
/// no letter is set.
struct Letters {
    buf: [u8; 12],
    len: u8,
    head: u8,
}

impl Letters {
    fn new(head: FStr) -> Letters {
        let mut buf = [0; 12];
        let n = head.len().min(6);
        for (i, b) in buf[..n].iter_mut().enumerate() {
            *b = head.get(i).unwrap_or(b' ');
        }
        Letters { buf, len: n as u8, head: n as u8 }
    }

    fn push(&mut self, on: bool, c: u8) {
        if on && (self.len as usize) < self.buf.len() {
            self.buf[self.len as usize] = c;
            self.len += 1;
        }
    }

    fn write(&self, io: &mut impl ufmt::uWrite) {
        if self.len > self.head {
            io.write_str(crate::protocol::ascii_str(&self.buf[..self.len as usize])).ok();
        }
    }
}

impl Machine {
    /// `?`: one grbl 1.1 status line.
    // speed: not inlined into idle (realtime/alarm/status attributes removed: ping-pong 5.756 -> 5.793 s)
    #[inline(never)]
    pub fn status_report(&mut self, io: &mut impl Io) {
        let st = io.stepper();
        // Steps are being produced: never `Idle`, whatever else is going on.
        let state = if self.state == State::Idle && st.busy { State::Run } else { self.state };
        // `$10` bit 0: the machine position, else the work position;
        // bit 1: the buffer field (grbl's).
        let mask = self.settings.status_mask;
        let mpos = self.steps_to_mm(st.position);
        let wpos = self.interp.work_user(mpos);
        let inches = self.settings.report_inches;
        if mask & 1 != 0 {
            uwrite!(io, "{}{}{}", F!("<"), state.name(), F!("|MPos:")).ok();
            dollar::coords(io, &crate::frame::user_from_internal(mpos), inches);
        } else {
            uwrite!(io, "{}{}{}", F!("<"), state.name(), F!("|WPos:")).ok();
            dollar::coords(io, &wpos, inches);
        }
        if mask & 2 != 0 {
            let rx_free = (255 - io.rx_pending().min(255)) as u16;
            uwrite!(io, "{}{}{}{}", F!("|Bf:"), self.planner.free() as u16, F!(","), rx_free).ok();
        }
        let (feed, rpm) = self.feed_and_speed();
        // Ln: the block number of the move being prepared (grbl with line
        // numbers on); none for unnumbered lines.
        if let Some(b) = self.planner.current_block().filter(|b| b.line != 0) {
            uwrite!(io, "{}{}", F!("|Ln:"), b.line).ok();
        }
        uwrite!(io, "{}", F!("|FS:")).ok();
        if inches {
            uwrite!(io, "{}", crate::fixed::Tenths(crate::math::round_i32(feed * (10.0 / 25.4)))).ok();
        } else {
            uwrite!(io, "{}", feed as i32).ok();
        }
        uwrite!(io, "{}{}", F!(","), rpm as i32).ok();
        // Pn: the inputs that read triggered (grbl's letters; C is the
        // carousel's home switch, P the tool setter, G38's probe input).
        // Letters are built as bytes: a `&str` per letter would sit in RAM.
        let sw = io.switches();
        let mut pn = Letters::new(F!("|Pn:"));
        pn.push(sw.home & 1 != 0, b'X');
        pn.push(sw.home & 2 != 0, b'Y');
        pn.push(sw.home & 4 != 0, b'Z');
        pn.push(sw.tool_setter, b'P');
        pn.push(sw.carousel_home, b'C');
        pn.write(io);
        // WCO and Ov in turn, every few reports (grbl sends them on a
        // refresh count too; both change rarely).
        self.report_count = self.report_count.wrapping_add(1);
        match self.report_count % 10 {
            0 => {
                uwrite!(io, "{}", F!("|WCO:")).ok();
                let m = crate::frame::user_from_internal(mpos);
                let mut wco = m;
                for a in 0..3 {
                    wco[a] = m[a] - wpos[a];
                }
                dollar::coords(io, &wco, inches);
            }
            1 => {
                let o = self.overrides();
                // (No literal text in the format: ufmt keeps it in RAM.)
                uwrite!(io, "{}{}", F!("|Ov:"), o.feed).ok();
                uwrite!(io, "{}{}", F!(","), o.rapid).ok();
                uwrite!(io, "{}{}", F!(","), o.spindle).ok();
            }
            _ => {}
        }
        let mut acc = Letters::new(F!("|A:"));
        acc.push(self.interp.spindle_on, b'S');
        acc.push(self.interp.coolant_m == 8, b'F');
        acc.push(self.interp.coolant_m == 7, b'M');
        acc.write(io);
        uwriteln!(io, "{}{}{}", F!("|T:"), self.atc.spindle_tool(), F!(">")).ok();
    }
}
