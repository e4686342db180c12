//! The firmware's main loop and its hardware side of `mill::machine::Io`.
//!
//! `board` provides registers; `mill::machine::Machine` and `mill::ui`
//! provide all the logic. This file only connects them: it boots the board,
//! loads the settings from EEPROM, prints the banner, then forever
//!
//! ```text
//!  serial bytes ─► Machine::push_bytes
//!  SD job       ─► one line per turn while the planner has room ─► Machine::run_job_line
//!  menu command ─► jog / home / start a file / Tools line (at the top level, never nested in a wait)
//!  Machine::idle ─► segment prep, realtime ─► Io::background: encoder, one display slice
//! ```
//!
//! The SD card sits behind `embedded-sdmmc` (`VolumeManager` with one
//! volume, one directory and one file open at most: its 512-byte block
//! cache is the biggest RAM item here).

use crate::board::oled::Sh1106;
use crate::board::spi::{BusyDelay, ClockDiv, SdDevice, SpiBus};
use crate::board::twi::Twi;
use crate::board::{self, eeprom::Eeprom, serial, stepper, wdt};
use core::convert::Infallible;
use core::ops::ControlFlow;
use embedded_sdmmc::{Mode, RawFile, RawVolume, SdCard, TimeSource, Timestamp, VolumeIdx, VolumeManager};
use mill::gcode::interp;
use mill::machine::{Io, Machine, Realtime, StepperStatus};
use mill::protocol::MAX_LINE_LEN;
use mill::stepper::StepperCmd;
use mill::ui::menu::{Cmd, Reply, Screen, Ui, View};
use mill::ui::render::{Line, ROWS, SLICE, WIDTH};
use mill::ui::sd::{self as sdjob, req, Card, Name, SdError, SdJob, Turn};
use ufmt::uwriteln;

/// Display frames start at most this often (5 Hz; docs/SPEC.md §9 asks ≥ 4 Hz).
const FRAME_MS: u32 = 200;
/// Jog feed from the menu, mm/min.
const JOG_FEED_MM_PER_MIN: f32 = 1200.0;

/// The serial port as a `uWrite`, for code that holds parts of `Hw`.
struct SerialOut;

impl ufmt::uWrite for SerialOut {
    type Error = Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        serial::write(s.as_bytes());
        Ok(())
    }
}

/// Files get this date (there is no real-time clock).
struct FixedClock;

impl TimeSource for FixedClock {
    fn get_timestamp(&self) -> Timestamp {
        Timestamp { year_since_1970: 56, zero_indexed_month: 0, zero_indexed_day: 0, hours: 0, minutes: 0, seconds: 0 }
    }
}

/// The SD driver's retry delay: a busy wait that also feeds the watchdog,
/// because a card that never answers keeps `embedded-sdmmc` retrying for
/// seconds (10 000 polls per command, 50 CMD0 attempts).
#[derive(Clone, Copy)]
struct SdDelay;

impl embedded_hal::delay::DelayNs for SdDelay {
    fn delay_ns(&mut self, ns: u32) {
        wdt::feed();
        BusyDelay.delay_ns(ns);
    }
}

type SdDev = SdCard<SdDevice, SdDelay>;
/// One volume, one directory, one file open at a time.
type Volumes = VolumeManager<SdDev, FixedClock, 1, 1, 1>;

/// The SD card behind `mill::ui::sd::Card`.
struct Storage {
    vm: Volumes,
    vol: Option<RawVolume>,
    file: Option<RawFile>,
}

fn map_err<E: core::fmt::Debug + core::error::Error>(e: embedded_sdmmc::Error<E>) -> SdError {
    use embedded_sdmmc::Error as E2;
    match e {
        E2::DeviceError(_) => SdError::NoCard,
        E2::FormatError(_) | E2::NoSuchVolume => SdError::NoFilesystem,
        E2::NotFound => SdError::NotFound,
        E2::FilenameError(_) => SdError::BadName,
        _ => SdError::ReadFailed,
    }
}

impl Storage {
    fn set_clock(&mut self, div: ClockDiv) {
        self.vm.device(|d| d.spi(|s| s.bus.set_clock(div)));
    }

    fn close_file(&mut self) -> Result<(), SdError> {
        match self.file.take() {
            Some(f) => self.vm.close_file(f).map_err(|_| SdError::WriteFailed),
            None => Ok(()),
        }
    }
}

impl Card for Storage {
    fn detected(&self) -> bool {
        board::sd_detected()
    }

    #[inline(never)]
    fn mount(&mut self) -> Result<(), SdError> {
        if !board::sd_detected() {
            self.unmount();
            return Err(SdError::NoCard);
        }
        if self.vol.is_some() {
            return Ok(());
        }
        // A fresh card: slow clock, 80 idle clocks, then let the driver
        // initialise it on the first block read (the MBR).
        self.set_clock(ClockDiv::SD_INIT);
        self.vm.device(|d| {
            d.mark_card_uninit();
            d.spi(|s| s.wake_card().ok());
        });
        let v = self.vm.open_raw_volume(VolumeIdx(0)).map_err(map_err)?;
        self.vol = Some(v);
        self.set_clock(ClockDiv::FAST);
        Ok(())
    }

    #[inline(never)]
    fn unmount(&mut self) {
        // Handles are dropped whatever the card says (it may be gone).
        if let Some(f) = self.file.take() {
            let _ = self.vm.close_file(f);
        }
        if let Some(v) = self.vol.take() {
            let _ = self.vm.close_volume(v);
        }
        self.vm.device(|d| d.mark_card_uninit());
    }

    #[inline(never)]
    fn list(&mut self, f: &mut dyn FnMut(&Name, u32)) -> Result<(), SdError> {
        let vol = self.vol.ok_or(SdError::NoCard)?;
        let dir = self.vm.open_root_dir(vol).map_err(map_err)?;
        let r = self.vm.iterate_dir(dir, |e| {
            if !e.attributes.is_directory() && !e.attributes.is_volume() && !e.attributes.is_hidden() {
                f(&Name::from_parts(e.name.base_name(), e.name.extension()), e.size);
            }
            ControlFlow::Continue(())
        });
        let _ = self.vm.close_dir(dir);
        r.map_err(map_err)
    }

    #[inline(never)]
    fn open(&mut self, name: &Name, write: bool) -> Result<u32, SdError> {
        self.close_file()?;
        let vol = self.vol.ok_or(SdError::NoCard)?;
        let dir = self.vm.open_root_dir(vol).map_err(map_err)?;
        let mode = if write { Mode::ReadWriteCreateOrTruncate } else { Mode::ReadOnly };
        // The name goes in as a ShortFileName: passed as a `&str`, the AVR
        // build of open_file_in_dir did not find files that
        // find_directory_entry found (measured in simavr; not chased further).
        let r = embedded_sdmmc::ShortFileName::create_from_str(name.as_str())
            .map_err(embedded_sdmmc::Error::FilenameError)
            .and_then(|sfn| self.vm.open_file_in_dir(dir, sfn, mode));
        let _ = self.vm.close_dir(dir);
        let f = r.map_err(map_err)?;
        self.file = Some(f);
        self.vm.file_length(f).map_err(map_err)
    }

    #[inline(never)]
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, SdError> {
        let f = self.file.ok_or(SdError::NotFound)?;
        if self.vm.file_eof(f).map_err(|_| SdError::ReadFailed)? {
            return Ok(0);
        }
        self.vm.read(f, buf).map_err(|_| SdError::ReadFailed)
    }

    #[inline(never)]
    fn seek(&mut self, pos: u32) -> Result<(), SdError> {
        let f = self.file.ok_or(SdError::NotFound)?;
        self.vm.file_seek_from_start(f, pos).map_err(|_| SdError::ReadFailed)
    }

    #[inline(never)]
    fn write(&mut self, data: &[u8]) -> Result<(), SdError> {
        let f = self.file.ok_or(SdError::NotFound)?;
        self.vm.write(f, data).map_err(|_| SdError::WriteFailed)
    }

    #[inline(never)]
    fn close(&mut self) -> Result<(), SdError> {
        self.close_file()
    }
}

/// Page-by-page drawing state (docs/SPEC.md §9: no frame buffer, refresh ≥ 4 Hz,
/// never starving the planner: one 32-column slice per idle call).
struct Display {
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
}

/// The hardware behind `Io`, plus the UI and the SD job.
struct Hw {
    eeprom: Eeprom,
    sd: Storage,
    job: SdJob,
    ui: Ui,
    view: View,
    display: Display,
    /// Names of the file rows on the Files screen, from `names_first` on.
    names: [Name; 7],
    names_first: u8,
    names_valid: bool,
    files: u8,
    /// A menu command for the main loop (jog, home, start a file ...).
    pending: Cmd,
    /// Realtime requests from the menu ([`req`] bits).
    requests: u8,
}

impl ufmt::uWrite for Hw {
    type Error = Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        serial::write(s.as_bytes());
        Ok(())
    }
}

impl Io for Hw {
    fn poll(&mut self) -> Realtime {
        wdt::feed();
        let rt = board::take_realtime();
        if rt & board::realtime::RESET != 0 && self.job.active() {
            // A soft reset ends an SD job too (its abort finishes at once:
            // the reset leaves nothing moving).
            self.job.abort();
        }
        let ui = self.job.take_requests() | core::mem::take(&mut self.requests);
        let m = stepper::MOTION.load(portable_atomic::Ordering::Acquire);
        Realtime {
            status: rt & board::realtime::STATUS != 0,
            hold: rt & board::realtime::HOLD != 0 || ui & req::HOLD != 0,
            resume: rt & board::realtime::RESUME != 0 || ui & req::RESUME != 0,
            estop: rt & board::realtime::ESTOP != 0,
            limit: m & stepper::motion::LIMIT != 0,
            home_tripped: m & stepper::motion::HOME_TRIPPED != 0,
            probe_tripped: m & stepper::motion::PROBE_TRIPPED != 0,
            abort: ui & req::ABORT != 0,
            abort_keep_spindle: ui & req::KEEP_SPINDLE != 0,
            reset: rt & board::realtime::RESET != 0,
            jog_cancel: rt & board::realtime::JOG_CANCEL != 0,
            reset_moving: rt & board::realtime::RESET_MOVING != 0,
            motion_ovr: board::take_overrides(&board::MOTION_OVR),
            accessory_ovr: board::take_overrides(&board::ACCESSORY_OVR),
        }
    }

    fn flush_rx(&mut self) {
        while serial::read().is_some() {}
    }

    fn push_segment(&mut self, cmd: StepperCmd) -> bool {
        stepper::push(cmd)
    }

    fn segment_space(&self) -> usize {
        stepper::space()
    }

    fn stepper(&self) -> StepperStatus {
        let m = stepper::MOTION.load(portable_atomic::Ordering::Acquire);
        StepperStatus {
            position: stepper::position(),
            busy: stepper::busy(),
            trip_position: stepper::trip_position(),
            tripped: m & (stepper::motion::HOME_TRIPPED | stepper::motion::PROBE_TRIPPED) != 0,
        }
    }

    fn set_stepper_position(&mut self, p: [i32; 4]) {
        stepper::set_position(p);
    }

    fn stop_motion(&mut self) {
        stepper::halt_from_isr();
    }

    fn clear_stop(&mut self) {
        stepper::MOTION.fetch_and(
            !(stepper::motion::LIMIT | stepper::motion::HOME_TRIPPED | stepper::motion::PROBE_TRIPPED),
            portable_atomic::Ordering::AcqRel,
        );
        stepper::clear_stop();
    }

    fn stepper_stopped(&self) -> bool {
        stepper::MOTION.load(portable_atomic::Ordering::Acquire) & stepper::motion::STOP != 0
    }

    fn set_watch(&mut self, w: mill::stepper::rings::Watch) {
        stepper::set_watch(w);
    }

    fn drivers(&mut self, on: bool) {
        board::drivers_enable(on);
    }

    fn carousel_driver(&mut self, on: bool) {
        board::carousel_driver_enable(on);
    }

    fn spindle(&mut self, duty: u8) {
        board::spindle_set(duty);
    }

    fn coolant(&mut self, on: bool) {
        board::coolant_set(on);
    }

    fn switches(&self) -> mill::machine::Switches {
        let i = board::inputs();
        mill::machine::Switches { home: i.home, carousel_home: i.carousel_home, tool_setter: i.tool_setter }
    }

    fn millis(&self) -> u32 {
        board::millis()
    }

    fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]) {
        let _ = self.eeprom.read(addr, buf);
    }

    fn eeprom_write(&mut self, addr: u16, data: &[u8]) {
        let _ = self.eeprom.write(addr, data);
    }

    fn free_ram(&self) -> u16 {
        board::free_ram()
    }

    fn rx_pending(&self) -> usize {
        serial::rx_len()
    }

    fn sd_command(&mut self, flags: mill::machine::SdJobFlags<'_>, code: u16, arg: &[u8]) -> mill::machine::CmdResult {
        self.names_valid = false;
        sdjob::command_with(&mut self.job, &mut self.sd, flags, &mut SerialOut, code, arg).map_err(|t| interp::Error::Sd(t.as_fstr()))
    }

    fn sd_capture(&mut self, line: &[u8]) -> bool {
        sdjob::capture(&mut self.job, &mut self.sd, line, &mut SerialOut)
    }

    #[inline(never)]
    fn background(&mut self, m: &Machine) {
        // The card pulled mid-job ends the job now, even while one of its
        // lines waits (a long arc, a full planner, M0): the status screen
        // says so.
        if self.job.card_check(board::sd_detected(), m, &mut SerialOut) {
            self.sd.unmount();
            self.ui.screen = Screen::Status;
        }
        let (detents, presses) = board::take_encoder();
        if detents != 0 || presses != 0 {
            let cmd = self.ui.step(detents, presses != 0, &self.view);
            match cmd {
                // An edit screen opened: its value, here where the machine is.
                Cmd::Edit(e) => self.ui.edit_um = e.current(m),
                other => self.command_now(other),
            }
            self.ui.fit_edit(m);
            // Show the change at once.
            self.display.frame_start_ms = board::millis().wrapping_sub(FRAME_MS);
        }
        self.draw_step(m);
    }
}

impl Hw {
    /// Menu commands: realtime ones now, the rest for the main loop.
    #[inline(never)]
    fn command_now(&mut self, cmd: Cmd) {
        match cmd {
            Cmd::None => {}
            Cmd::Pause => {
                if self.job.active() {
                    self.job.pause();
                } else {
                    self.requests |= req::HOLD;
                }
            }
            Cmd::Resume => {
                if self.job.phase == mill::ui::sd::Phase::Paused {
                    self.job.resume();
                } else {
                    // Feed hold, or M0/M1 inside a job or a stream.
                    self.requests |= req::RESUME;
                }
            }
            Cmd::Abort => {
                if self.job.active() {
                    self.job.abort();
                } else {
                    self.requests |= req::ABORT;
                }
            }
            Cmd::Jog { axis, delta_um } => {
                // Detents add up while a jog is still being queued.
                self.pending = match self.pending {
                    Cmd::Jog { axis: a, delta_um: d } if a == axis => Cmd::Jog { axis, delta_um: d + delta_um },
                    _ => cmd,
                };
            }
            other => self.pending = other,
        }
    }

    /// Snapshot of the machine for one frame.
    #[inline(never)]
    fn capture(&mut self, m: &Machine) {
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
        v.job = self.job.phase;
        v.job_pct = self.job.percent();
        v.job_name = self.job.name;
        v.card_in = board::sd_detected();
        v.files = self.files;
        v.interrupted = m.atc.interrupted;
        v.alarm = m.alarm;
        v.limit_axes = m.limit_axes;
        if matches!(self.ui.screen, Screen::Info) {
            v.free_ram = board::free_ram();
        }
    }

    /// One step of drawing: start a frame when due, else send one slice of
    /// the current page (pages whose text did not change are skipped).
    #[inline(never)]
    fn draw_step(&mut self, m: &Machine) {
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
        }
        if o.take_failed() {
            d.valid &= !(1 << d.sent_page);
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
            let names = &self.names;
            let first = self.names_first;
            let valid = self.names_valid;
            let file = |i: u8| -> Option<Name> {
                if valid && i >= first && ((i - first) as usize) < names.len() {
                    Some(names[(i - first) as usize])
                } else {
                    None
                }
            };
            let line = self.ui.line(page as usize, &self.view, m, &file);
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
            Some(o) => o.write_async(page, x0 as u8, &buf[..n]).is_ok(),
            None => false,
        };
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

    /// Read the file names for the Files screen (count, and the visible ones).
    #[inline(never)]
    fn refresh_names(&mut self) {
        let (first, _) = self.ui.visible_files();
        let mut count: u8 = 0;
        let names = &mut self.names;
        let r = self.sd.mount().and_then(|_| {
            self.sd.list(&mut |n, _| {
                if count >= first && ((count - first) as usize) < names.len() {
                    names[(count - first) as usize] = *n;
                }
                count = count.saturating_add(1);
            })
        });
        self.files = if r.is_ok() { count } else { 0 };
        self.names_first = first;
        self.names_valid = true;
    }

    /// The name of file `i` in directory order.
    #[inline(never)]
    fn file_name(&mut self, i: u8) -> Option<Name> {
        let mut k: u8 = 0;
        let mut found = None;
        self.sd
            .list(&mut |n, _| {
                if k == i {
                    found = Some(*n);
                }
                k = k.saturating_add(1);
            })
            .ok()?;
        found
    }
}

/// Zero-initialised (in .bss, no flash image); built by `Machine::init` in `run`.
static mut MACHINE: core::mem::MaybeUninit<Machine> = core::mem::MaybeUninit::uninit();
/// Zero-initialised (in .bss, no flash image); written once in `run`.
static mut HW: core::mem::MaybeUninit<Hw> = core::mem::MaybeUninit::uninit();

/// Run the firmware. Never returns.
pub fn run() -> ! {
    let cause = wdt::reset_cause();
    wdt::disable_at_boot();
    board::paint_stack();
    // SAFETY: taken once, at boot.
    let dp = unsafe { avr_device::atmega2560::Peripherals::steal() };
    board::init(&dp);
    let (bus, cs) = SpiBus::new(dp.SPI, &dp.PORTB, ClockDiv::SD_INIT);
    let mut oled = Sh1106::new(Twi::new(dp.TWI, crate::board::oled::I2C_HZ));
    let oled = if oled.init().is_ok() { Some(oled) } else { None };
    let sd = Storage {
        vm: VolumeManager::new_with_limits(
            SdCard::new_with_options(
                SdDevice { bus, cs },
                SdDelay,
                embedded_sdmmc::sdcard::spi::AcquireOpts { use_crc: true, acquire_retries: 5 },
            ),
            FixedClock,
            0,
        ),
        vol: None,
        file: None,
    };
    // SAFETY: HW and MACHINE are used only from this (main) context.
    let hw = unsafe {
        let slot = &mut *core::ptr::addr_of_mut!(HW);
        slot.write(Hw {
            eeprom: Eeprom::new(dp.EEPROM),
            sd,
            job: SdJob::new(),
            ui: Ui::new(),
            view: View::new(),
            display: Display {
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
            },
            names: [Name::EMPTY; 7],
            names_first: 0,
            names_valid: false,
            files: 0,
            pending: Cmd::None,
            requests: 0,
        })
    };
    // SAFETY: as above.
    let m = Machine::init(unsafe { &mut *core::ptr::addr_of_mut!(MACHINE) });
    serial::set_tx_wait_hook(tx_wait);
    // SAFETY: all shared state is initialised; ISRs may run from here on.
    unsafe { avr_device::interrupt::enable() };
    wdt::enable_2s();
    m.boot(hw, cause.name(), cause == wdt::ResetCause::Watchdog);
    // The SD job's line buffer lives here, not in `job_turn`'s frame: zeroing
    // it on every turn of the loop cost ~1.4k cycles per streamed line. The
    // serial line runs from it too (`push_bytes`): never both at once.
    let mut job_line = [0u8; MAX_LINE_LEN];
    #[cfg(feature = "panic-test")]
    let mut last = 0u64;
    loop {
        #[cfg(not(feature = "panic-test"))]
        m.push_bytes(core::iter::from_fn(serial::read), hw, &mut job_line);
        #[cfg(feature = "panic-test")]
        m.push_bytes(core::iter::from_fn(|| serial::read().inspect(|&b| panic_test(&mut last, b))), hw, &mut job_line);
        job_turn(m, hw, &mut job_line);
        ui_turn(m, hw);
        m.idle(hw);
    }
}

/// Test builds only (`--features panic-test`, tests/panic.rs): the line
/// `M9999` panics and `M9998` aborts (the `llvm.trap` that
/// `panic = "immediate-abort"` makes of every panic) as its newline arrives,
/// from inside the serial → parser path.
#[cfg(feature = "panic-test")]
fn panic_test(last: &mut u64, b: u8) {
    *last = (*last << 8 | b as u64) & 0xFFFF_FFFF_FFFF;
    if *last == u64::from_be_bytes(*b"\0\0M9999\n") {
        panic!("M9999");
    }
    if *last == u64::from_be_bytes(*b"\0\0M9998\n") {
        core::intrinsics::abort();
    }
}

/// The SD job's turn: at most one line.
#[inline(never)]
fn job_turn(m: &mut Machine, hw: &mut Hw, line: &mut [u8; MAX_LINE_LEN]) {
    // Up to four lines per turn while the planner has room, as a serial host
    // keeps lines coming back to back (one line per turn of the main loop
    // left the ring emptier than a serial stream's: 10 % slower). Serial
    // bytes waiting (M27, a status query) end the batch: they go first, as
    // they did with one line per turn.
    for _ in 0..4 {
        let done = m.motion_done(hw);
        let turn = hw.job.poll(&mut hw.sd, m, done, line, &mut SerialOut);
        match turn {
            Turn::Run(n) => {
                let r = m.run_job_line(&line[..n], hw);
                hw.job.line_done(r, m, &mut SerialOut);
                if serial::rx_len() != 0 {
                    return;
                }
                // The ISR must not run dry during a batch (a card block read
                // takes ~5 ms; it did, and the restart showed as a 12 % jump
                // in the measured acceleration): top its segments up when
                // less than 5 ms are left. Not after every line: each top-up
                // runs the look-ahead over the few blocks queued (10 % slower).
                if !stepper::queued_at_least(mill::F_CPU_HZ / 200) {
                    m.fill_segments(hw);
                }
            }
            Turn::SpindleOff => {
                m.spindle_off(hw);
                return;
            }
            Turn::RetractThenSpindleOff => {
                if let Err(e) = m.retract_and_stop_spindle(hw) {
                    m.report_error(hw, e);
                }
                return;
            }
            Turn::Idle => return,
        }
    }
}

/// The menu's commands that run at the top level.
#[inline(never)]
fn ui_turn(m: &mut Machine, hw: &mut Hw) {
    if !board::sd_detected() && hw.sd.vol.is_some() && !hw.job.active() {
        // Pulled while idle: forget it, so the next card is mounted afresh.
        hw.sd.unmount();
        hw.names_valid = false;
    }
    if matches!(hw.ui.screen, Screen::Files) && (!hw.names_valid || hw.ui.visible_files().0 != hw.names_first) {
        hw.refresh_names();
    }
    let cmd = core::mem::replace(&mut hw.pending, Cmd::None);
    let r = match cmd {
        Cmd::ListFiles => {
            hw.names_valid = false;
            Ok(())
        }
        Cmd::RunFile(i) => match hw.file_name(i) {
            Some(name) => match hw.job.select(&mut hw.sd, &name) {
                Ok(()) => {
                    m.job_start_ms = hw.millis();
                    hw.job.start(m).map_err(|t| interp::Error::Sd(t.as_fstr()))
                }
                Err(e) => Err(interp::Error::Sd(e.text().as_fstr())),
            },
            None => Err(interp::Error::Sd(SdError::NotFound.text().as_fstr())),
        },
        Cmd::Override(pct) => {
            m.set_feed_override(pct);
            Ok(())
        }
        Cmd::OptionalStop(on) => {
            // The same setting as `$152`, stored like it.
            m.settings.optional_stop = on;
            m.save_settings(hw);
            Ok(())
        }
        Cmd::Jog { axis, delta_um } => m.jog(hw, axis as usize, delta_um as f32 / 1000.0, JOG_FEED_MM_PER_MIN),
        Cmd::Home(mask) => mill::machine::home(m, hw, mask),
        Cmd::Unlock => {
            if m.alarm.is_some() {
                m.clear_alarm(hw);
            }
            Ok(())
        }
        Cmd::Teach(p) => m.teach_station(hw, p),
        Cmd::Store(e, um) => {
            let r = store_edit(m, hw, e, um);
            hw.ui.reply = match r {
                Ok(()) => Reply::Ok,
                Err(e) => Reply::Err(e.message()),
            };
            r
        }
        Cmd::Tool(op) => {
            if matches!(op, mill::ui::menu::ToolOp::Confirm(_)) && m.alarm.is_some() {
                // Confirming the spindle is a way out of the alarm.
                m.clear_alarm(hw);
            }
            // The same line as over serial (T<n>, G37 [D1], M61 Q<t>), so
            // the same checks and errors; the reply screen shows the outcome.
            // The menu picks pockets; the line names the pocket's tool
            // number, and a pocket without one is refused.
            use mill::ui::menu::ToolOp;
            let (op, pocket) = match op {
                ToolOp::Change(p) => (ToolOp::Change(m.atc.table.number_of(p)), p),
                ToolOp::Confirm(p) => (ToolOp::Confirm(m.atc.table.number_of(p)), p),
                other => (other, 0),
            };
            let unnumbered = pocket != 0 && matches!(op, ToolOp::Change(0) | ToolOp::Confirm(0));
            let mut l = Line::blank();
            let n = op.gcode(&mut l);
            let r = if unnumbered {
                Err(interp::Error::Atc(mill::atc::Fault::NoNumber))
            } else if op == ToolOp::ProbeZ {
                // Down at most PROBE_Z_MM on the probe input (a miss is the
                // probe-fail alarm, as G38.2), then the zero line.
                m.probe_z_down(hw, mill::ui::menu::PROBE_Z_MM, mill::ui::menu::PROBE_Z_FEED)
                    .and_then(|()| m.run_menu_line(&l.chars[..n], hw))
            } else {
                m.run_menu_line(&l.chars[..n], hw)
            };
            hw.ui.reply = match r {
                Ok(()) => Reply::Ok,
                Err(e) => Reply::Err(match (e, m.alarm) {
                    (interp::Error::Alarm, Some(a)) => a.message(),
                    _ => e.message(),
                }),
            };
            r
        }
        _ => Ok(()),
    };
    if let Err(e) = r {
        uwriteln!(hw, "{}", mill::F!("echo:menu:")).ok();
        m.report_error(hw, e);
    }
}

/// The menu's edit stored through the serial lines: `$n=<value>`, or for
/// a pocket's tool number `G10 L1 P<old> Q0` then `G10 L1 P<new> Q<p>`
/// (the old number put back if the new one is refused).
#[inline(never)]
fn store_edit(m: &mut Machine, hw: &mut Hw, e: mill::ui::menu::Edit, um: i32) -> mill::machine::CmdResult {
    use mill::ui::menu::Edit;
    let mut l = Line::blank();
    let Edit::Pocket(p) = e else {
        let n = e.gcode(um, None, &mut l);
        return m.run_menu_line(&l.chars[..n], hw);
    };
    let (old, new) = (m.atc.table.number_of(p), (um / 1000) as u8);
    if old == new {
        return Ok(());
    }
    if old != 0 {
        let n = e.gcode(um, Some(old), &mut l);
        m.run_menu_line(&l.chars[..n], hw)?;
    }
    if new == 0 {
        return Ok(());
    }
    let mut l = Line::blank();
    let n = e.gcode(um, None, &mut l);
    let r = m.run_menu_line(&l.chars[..n], hw);
    if r.is_err() && old != 0 {
        let mut l = Line::blank();
        let n = e.gcode(old as i32 * 1000, None, &mut l);
        m.run_menu_line(&l.chars[..n], hw).ok();
    }
    r
}

/// While the TX ring is full: keep the watchdog fed.
fn tx_wait() {
    wdt::feed();
}
