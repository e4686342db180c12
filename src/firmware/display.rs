//! The OLED status display, drawn page by page (docs/SPEC.md §9: no frame
//! buffer, refresh ≥ 4 Hz, never starving the planner: one 32-column slice
//! per idle call, pages whose text did not change skipped).

use super::Hw;
use crate::board;
use crate::board::oled::Sh1106;
use crate::board::stepper;
use crate::board::twi::Twi;
use mill::machine::Machine;
use mill::ui::menu::Screen;
use mill::ui::render::{Line, ROWS, SLICE, WIDTH};

/// Display frames start at most this often (5 Hz; docs/SPEC.md §9 asks ≥ 4 Hz).
const FRAME_MS: u32 = 200;

/// Page-by-page drawing state (docs/SPEC.md §9: no frame buffer, refresh ≥ 4 Hz,
/// never starving the planner: one 32-column slice per idle call).
pub(super) struct Display {
    oled: Option<Sh1106<Twi>>,
    /// A frame is being drawn: its page and slice.
    drawing: bool,
    page: u8,
    slice: u8,
    /// The line being sent and its hash.
    line: Line,
    hash: u16,
    /// Hash of what each page shows; `valid` bit i = page i is known.
    shown: [u16; ROWS],
    valid: u8,
    frame_start_ms: u32,
    /// Page and start time of the slice last sent in the background.
    sent_page: u8,
    sent_ms: u32,
    /// The controller's column address is where the next slice of the
    /// page starts: the last slice was started, and did not fail and was
    /// not aborted. The position commands then stay out (a blocking
    /// transfer of ~0.1 ms, 2 000 cycles with the bus wait).
    follows: bool,
}

impl Display {
    /// Nothing drawn yet, on `oled` (`None`: no display answered at boot).
    pub(super) fn new(oled: Option<Sh1106<Twi>>) -> Display {
        Display {
            oled,
            drawing: false,
            page: 0,
            slice: 0,
            line: Line::blank(),
            hash: 0,
            shown: [0; ROWS],
            valid: 0,
            frame_start_ms: 0,
            sent_page: 0,
            sent_ms: 0,
            follows: false,
        }
    }

    /// Start the next frame at once (the menu changed: show it now).
    pub(super) fn frame_now(&mut self) {
        self.frame_start_ms = board::millis().wrapping_sub(FRAME_MS);
    }
}

impl Hw {
    /// Snapshot of the machine for one frame.
    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    pub(super) fn capture(&mut self, m: &Machine) {
        let v = &mut self.view;
        let mm = m.steps_to_mm(stepper::position());
        let w = m.interp.work_user(mm);
        for a in 0..3 {
            v.wpos_um[a] = mill::math::round_i32(w[a] * 1000.0);
        }
        let (feed, rpm) = m.feed_and_speed();
        v.state = m.state;
        v.homed = m.homed & 0b111 == 0b111;
        v.tool = m.atc.spindle();
        v.feed = feed.clamp(0.0, 65535.0) as u16;
        v.override_pct = m.planner.feed_override();
        v.opt_stop = m.settings.optional_stop;
        v.wcs = m.interp.wcs;
        v.rpm = rpm.clamp(0.0, 65535.0) as u16;
        v.speed = m.interp.spindle_rpm.clamp(0.0, 65535.0) as u16;
        v.spindle_pct = m.overrides().spindle;
        v.job = self.job.phase;
        v.job_pct = (self.job.permille_cut(m) / 10) as u8;
        if self.job.active() {
            v.job_s = (board::millis().wrapping_sub(m.job_start_ms) / 1000).min(u16::MAX as u32) as u16;
        }
        v.job_why = self.job.why;
        v.job_name = self.job.name;
        v.card_in = board::sd_detected();
        v.files = self.files.count;
        v.in_folder = self.sd.depth > 0;
        v.folder_rows = if self.files.first == self.ui.visible_files().0 { self.files.dirs() } else { 0 };
        v.interrupted = m.atc.interrupted;
        v.alarm = m.alarm;
        v.limit_axes = m.limit_axes;
        if matches!(self.ui.screen, Screen::Info) {
            v.free_ram = board::free_ram();
        }
    }

    /// One step of drawing: start a frame when due, else send one slice of
    /// the current page (pages whose text did not change are skipped).
    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    pub(super) fn draw_step(&mut self, m: &Machine) {
        let d = &mut self.display;
        let Some(o) = d.oled.as_mut() else { return };
        // The last slice goes out in the background (~0.75 ms): come back
        // when the bus is free; a stuck bus is given up after 20 ms. A slice
        // that failed leaves its page to be drawn again.
        if o.busy() {
            if board::millis().wrapping_sub(d.sent_ms) < 20 {
                return;
            }
            o.abort();
            d.follows = false;
        }
        if o.take_failed() {
            d.valid &= !(1 << d.sent_page);
            d.follows = false;
        }
        if !self.display.drawing {
            let now = board::millis();
            if now.wrapping_sub(self.display.frame_start_ms) < FRAME_MS {
                return;
            }
            self.display.frame_start_ms = now;
            self.display.drawing = true;
            self.display.page = 0;
            self.display.slice = 0;
            self.capture(m);
            return;
        }
        let page = self.display.page;
        if self.display.slice == 0 {
            let line = self.ui.line(page as usize, &self.view, m, &self.files);
            let h = line.hash();
            let d = &mut self.display;
            if d.valid & (1 << page) != 0 && d.shown[page as usize] == h {
                d.page += 1;
                if d.page as usize == ROWS {
                    d.drawing = false;
                }
                return;
            }
            d.line = line;
            d.hash = h;
        }
        let d = &mut self.display;
        let x0 = d.slice as usize * SLICE;
        let mut buf = [0u8; SLICE];
        let n = SLICE.min(WIDTH - x0);
        d.line.render(x0, &mut buf[..n]);
        let ok = match d.oled.as_mut() {
            Some(o) if d.follows && d.slice != 0 => o.write_next_async(&buf[..n]).is_ok(),
            Some(o) => o.write_async(page, x0 as u8, &buf[..n]).is_ok(),
            None => false,
        };
        d.follows = ok;
        d.sent_page = page;
        d.sent_ms = board::millis();
        d.slice += 1;
        if !ok {
            d.valid &= !(1 << page);
        }
        if d.slice as usize * SLICE >= WIDTH {
            if ok {
                d.shown[page as usize] = d.hash;
                d.valid |= 1 << page;
            }
            d.slice = 0;
            d.page += 1;
            if d.page as usize == ROWS {
                d.drawing = false;
            }
        }
    }
}
