//! The SD card behind `mill::ui::sd::Card`: `embedded-sdmmc`'s
//! `VolumeManager` with one volume, one directory and one file open at
//! most (its 512-byte block cache is the biggest RAM item of the
//! firmware), on the SPI bus with a watchdog-feeding retry delay and a
//! fixed file date.

use crate::board::spi::{BusyDelay, ClockDiv, SdDevice};
use crate::board::{self, wdt};
use core::ops::ControlFlow;
use embedded_sdmmc::{LfnBuffer, Mode, RawDirectory, RawFile, RawVolume, SdCard, TimeSource, Timestamp, VolumeIdx, VolumeManager};
use mill::machine::Machine;
use mill::ui::resume;
use mill::ui::sd::{Card, Due, Entry, Folder, Name, Phase, SdError};

/// Run from line: a scan the job left (aborted, the card pulled, the
/// file too short) is ended. Once per main-loop turn.
// stack: out of job_turn's frame
#[inline(never)]
pub(super) fn end_left_scan(m: &mut Machine, hw: &mut super::Hw) {
    if m.rebuild.active && !matches!(hw.job.phase, Phase::Scanning(_)) {
        m.end_scan(hw);
    }
}

/// Run from line's record: the line reached, in EEPROM when it is due
/// (`SdJob::record_due`), and the file with it when a job starts (from
/// the menu or M24). From the idle hook, so also during a line's
/// wait, right after `Machine::idle` topped the segment ring up (a
/// programmed byte takes 3.3 ms; a record programs one or two).
// speed: the test is all of it without a job (as a call: ~150 cycles a turn)
#[inline(always)]
pub(super) fn keep_record(hw: &mut super::Hw, m: &Machine) {
    if hw.job.record_maybe_due() {
        record(hw, m);
    }
}

/// [`keep_record`]'s work.
// stack: out of the idle hook's frame
#[inline(never)]
fn record(hw: &mut super::Hw, m: &Machine) {
    // The clock's low 16 bits: a u32 division by 1000 here cost 266 cycles
    // a streamed line (this runs on every main-loop pass).
    match hw.job.record_due(m, board::millis() as u16) {
        Some(Due::Start(line)) => {
            let (name, size) = (hw.job.name, hw.job.size);
            resume::start(hw, &name, size, line);
        }
        Some(Due::Reached(line)) => resume::reached(hw, line),
        None => {}
    }
}

/// Files get this date (there is no real-time clock).
pub(super) struct FixedClock;

impl TimeSource for FixedClock {
    fn get_timestamp(&self) -> Timestamp {
        Timestamp { year_since_1970: 56, zero_indexed_month: 0, zero_indexed_day: 0, hours: 0, minutes: 0, seconds: 0 }
    }
}

/// The SD driver's retry delay: a busy wait that also feeds the watchdog,
/// because a card that never answers keeps `embedded-sdmmc` retrying for
/// seconds (10 000 polls per command, 50 CMD0 attempts).
#[derive(Clone, Copy)]
pub(super) struct SdDelay;

impl embedded_hal::delay::DelayNs for SdDelay {
    fn delay_ns(&mut self, ns: u32) {
        wdt::feed();
        BusyDelay.delay_ns(ns);
    }
}

pub(super) type SdDev = SdCard<SdDevice, SdDelay>;
/// One volume, one directory, one file open at a time.
type Volumes = VolumeManager<SdDev, FixedClock, 1, 1, 1>;

/// The SD card behind `mill::ui::sd::Card`.
pub(super) struct SdFiles {
    pub(super) vm: Volumes,
    pub(super) vol: Option<RawVolume>,
    pub(super) file: Option<RawFile>,
    /// The menu's current folder: its first cluster (0: the root), and how
    /// deep it is. No directory handle stays open: each use opens the root
    /// and points it there (`set_dir_cluster`).
    pub(super) cwd: u32,
    pub(super) depth: u8,
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

impl SdFiles {
    fn set_clock(&mut self, div: ClockDiv) {
        self.vm.device(|d| d.spi(|s| s.bus.set_clock(div)));
    }

    /// Open folder `at` (the one directory handle): the root, pointed at
    /// the current folder when that is asked for.
    fn open_folder(&mut self, at: Folder) -> Result<RawDirectory, SdError> {
        let vol = self.vol.ok_or(SdError::NoCard)?;
        let dir = self.vm.open_root_dir(vol).map_err(map_err)?;
        if at == Folder::Current && self.cwd != 0 {
            if let Err(e) = self.vm.set_dir_cluster(dir, self.cwd) {
                let _ = self.vm.close_dir(dir);
                return Err(map_err(e));
            }
        }
        Ok(dir)
    }

    /// Move the current folder to its entry `name` (a folder, or `..`).
    fn change_folder(&mut self, name: embedded_sdmmc::ShortFileName) -> Result<(), SdError> {
        let dir = self.open_folder(Folder::Current)?;
        let r = self.vm.enter_dir_in_place(dir, name);
        let _ = self.vm.close_dir(dir);
        self.cwd = r.map_err(map_err)?;
        Ok(())
    }

    fn close_file(&mut self) -> Result<(), SdError> {
        match self.file.take() {
            Some(f) => self.vm.close_file(f).map_err(|_| SdError::WriteFailed),
            None => Ok(()),
        }
    }
}

impl Card for SdFiles {
    fn detected(&self) -> bool {
        board::sd_detected()
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
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

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn unmount(&mut self) {
        // Handles are dropped whatever the card says (it may be gone).
        if let Some(f) = self.file.take() {
            let _ = self.vm.close_file(f);
        }
        if let Some(v) = self.vol.take() {
            let _ = self.vm.close_volume(v);
        }
        self.cwd = 0;
        self.depth = 0;
        self.vm.device(|d| d.mark_card_uninit());
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn list(&mut self, at: Folder, f: &mut dyn FnMut(&Entry<'_>)) -> Result<(), SdError> {
        let dir = self.open_folder(at)?;
        // Long names up to 64 bytes of UTF-8; a longer one lists as its 8.3 name.
        let mut lfn = [0u8; 64];
        let mut lfn = LfnBuffer::new(&mut lfn);
        let r = self.vm.iterate_dir_lfn(dir, &mut lfn, |e, long| {
            let dot = e.name.base_name() == b"." || e.name.base_name() == b"..";
            if !dot && !e.attributes.is_volume() && !e.attributes.is_hidden() {
                let name = Name::from_parts(e.name.base_name(), e.name.extension());
                let long = long.unwrap_or("");
                f(&Entry { name, long, dir: e.attributes.is_directory(), size: e.size });
            }
            ControlFlow::Continue(())
        });
        let _ = self.vm.close_dir(dir);
        r.map_err(map_err)
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn open(&mut self, at: Folder, name: &Name, write: bool) -> Result<u32, SdError> {
        self.close_file()?;
        let dir = self.open_folder(at)?;
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

    fn enter(&mut self, name: &Name) -> Result<(), SdError> {
        let sfn = embedded_sdmmc::ShortFileName::create_from_str(name.as_str()).map_err(|_| SdError::BadName)?;
        self.change_folder(sfn)?;
        self.depth = self.depth.saturating_add(1);
        Ok(())
    }

    fn leave(&mut self) -> Result<(), SdError> {
        if self.depth == 0 {
            return Ok(());
        }
        self.change_folder(embedded_sdmmc::ShortFileName::parent_dir())?;
        self.depth -= 1;
        Ok(())
    }

    fn depth(&self) -> u8 {
        self.depth
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, SdError> {
        let f = self.file.ok_or(SdError::NotFound)?;
        if self.vm.file_eof(f).map_err(|_| SdError::ReadFailed)? {
            return Ok(0);
        }
        self.vm.read(f, buf).map_err(|_| SdError::ReadFailed)
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn seek(&mut self, pos: u32) -> Result<(), SdError> {
        let f = self.file.ok_or(SdError::NotFound)?;
        self.vm.file_seek_from_start(f, pos).map_err(|_| SdError::ReadFailed)
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn write(&mut self, data: &[u8]) -> Result<(), SdError> {
        let f = self.file.ok_or(SdError::NotFound)?;
        self.vm.write(f, data).map_err(|_| SdError::WriteFailed)
    }

    // stack: out of run's frame (the firmware's attributes removed: +88 B stack, +242 B flash)
    #[inline(never)]
    fn close(&mut self) -> Result<(), SdError> {
        self.close_file()
    }
}
