//! UART0 as a pseudo-terminal, so that a real G-code sender (printcore,
//! Pronterface, OctoPrint, cncjs) can connect to the simulated board.
//!
//! ```text
//!  sender ─► /dev/pts/N (slave) ─► master fd ─► PtyBridge ─► Vm::send ─► UART0 RX
//!  sender ◄─ /dev/pts/N (slave) ◄─ master fd ◄─ PtyBridge ◄─ Vm::output_bytes ◄─ UART0 TX
//! ```
//!
//! The bridge keeps its own handle on the slave, set to raw mode, so that the
//! firmware's output is never echoed back as input before a sender opens the
//! port, and the master never sees a hang-up between two senders. Baud-rate
//! settings on the slave are ignored: the virtual machine's UART runs at the
//! firmware's rate. With `realtime`, simulated time is kept from running ahead
//! of the wall clock, so the sender sees a board that answers like real
//! hardware. A fault can be injected: the checksum of one numbered line is
//! corrupted once in transit, to prove the firmware asks for a resend and the
//! sender recovers.
//!
//! Pacing: the sender's bytes wait in the bridge and go to the UART in
//! order, a few at a time (the VM's own queue is kept under
//! [`UART_QUEUE`] bytes, about half a millisecond of line time). What a
//! realtime command is passes ahead of whatever still waits, at once:
//! `?`, `!`, `~` at the start of a line (inside a line they are text: a
//! comment, or a checksummed line the checksum covers), Ctrl-X (0x18)
//! wherever it is, and a whole `M112` line (the RX interrupt's emergency
//! scanner then sees it at once). While the chip runs its bootloader
//! (the program counter in the boot section, see [`crate::boot`]) every
//! byte goes in order: avrdude's messages are binary.
//!
//! Auto-reset: on a Mega2560 the USB chip's DTR line drives RESET through
//! a capacitor, and Linux raises DTR whenever a program opens the port, so
//! every open resets the board (Arduino Mega2560 schematic, "RESET-EN"
//! jumper). The bridge sees every open of the slave (inotify `IN_OPEN` on
//! it, which is what avrdude, pyserial and node-serialport all do) and
//! resets the virtual machine with [`Vm::reset`], as the pulse would:
//! bytes still waiting for the UART and output not yet read are lost, the
//! firmware starts again (through the bootloader if the VM has one; a board
//! with the stock fuses is held in reset for its 66 ms start-up delay
//! first, and the sender's bytes in that time are lost too). With
//! [`PtyBridge::auto_reset`] off the port never resets the board, as on a
//! board whose RESET-EN jumper is cut.
//!
//! Reconnecting: a sender may close the port and open it again. Output
//! nobody reads (no sender, or a gone one) would wait in the pty and reach
//! the next sender as stale lines; the bridge drops it once it has sat
//! unread for [`STALE_OUTPUT`].

use crate::{Vm, VmError};
use std::collections::VecDeque;
use std::ffi::CStr;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Bytes the bridge lets wait in the VM's UART queue (the rest waits in the
/// bridge, where realtime commands can pass it).
pub const UART_QUEUE: usize = 16;
/// Output left unread this long in the pty is dropped (the sender is gone).
pub const STALE_OUTPUT: Duration = Duration::from_secs(3);

/// What one [`PtyBridge::pump`] saw.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Activity {
    /// Bytes from the sender.
    pub host_bytes: usize,
    /// Bytes the firmware wrote (whether or not a sender read them).
    pub output_bytes: usize,
    /// Steps the machine made.
    pub steps: u64,
}

impl Activity {
    /// Anything at all: traffic either way, or motion.
    pub fn any(&self) -> bool {
        self.host_bytes > 0 || self.output_bytes > 0 || self.steps > 0
    }
}

/// A pty whose master side is wired to the virtual machine's UART0.
pub struct PtyBridge {
    master: OwnedFd,
    _slave: OwnedFd,
    /// inotify instance watching the slave for opens (None: auto-reset off).
    opens: Option<OwnedFd>,
    /// Resets caused by a sender opening the port.
    pub auto_resets: u64,
    /// Until this VM cycle the chip is held in reset (its start-up delay):
    /// the sender's bytes are lost.
    deaf_until: u64,
    /// Sender bytes lost that way.
    pub lost_in_reset: u64,
    slave_path: PathBuf,
    link: Option<PathBuf>,
    /// Firmware output already passed to the master.
    out_sent: usize,
    /// Sender bytes waiting for the UART, in order.
    pending: VecDeque<u8>,
    /// Where the sender's current line starts in `pending` (None: part of
    /// it already went to the UART).
    line_start: Option<usize>,
    /// The sender's stream is at the start of a line.
    at_line_start: bool,
    /// Unread output in the pty, and since when it has not shrunk.
    unread: (usize, Instant),
    /// Realtime bytes and M112 lines passed ahead of waiting bytes.
    pub urgent: u64,
    /// Unread output dropped (bytes).
    pub stale_dropped: u64,
    /// Corrupt the checksum of the line numbered this (once).
    corrupt_line: Option<u32>,
    /// Lines whose checksum was corrupted.
    pub corrupted: Vec<String>,
    /// Bytes from the sender, and to it.
    pub bytes_in: u64,
    pub bytes_out: u64,
    realtime: bool,
    /// With `realtime`: run unpaced while bytes flow (see `fast_while_busy`).
    fast_while_busy: bool,
    /// Bytes moved either way in the last pump.
    was_busy: bool,
    started: Instant,
    sim_start_s: f64,
}

fn check(r: i32, what: &str) -> io::Result<i32> {
    if r < 0 {
        Err(io::Error::new(io::Error::last_os_error().kind(), format!("{what}: {}", io::Error::last_os_error())))
    } else {
        Ok(r)
    }
}

impl PtyBridge {
    /// Opens a pty; with `link`, also a symlink to its slave (e.g.
    /// `/tmp/millsim`), for senders that want a stable port name.
    pub fn open(vm: &Vm, link: Option<&Path>) -> io::Result<PtyBridge> {
        // SAFETY: plain libc calls on fds we own; ptsname's buffer is copied
        // before any other pty call.
        unsafe {
            let m = check(libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY), "posix_openpt")?;
            let master = OwnedFd::from_raw_fd(m);
            check(libc::grantpt(m), "grantpt")?;
            check(libc::unlockpt(m), "unlockpt")?;
            let name = libc::ptsname(m);
            if name.is_null() {
                return Err(io::Error::last_os_error());
            }
            let slave_path = PathBuf::from(CStr::from_ptr(name).to_string_lossy().into_owned());
            let cpath = std::ffi::CString::new(slave_path.as_os_str().as_encoded_bytes()).expect("pts path");
            let s = check(libc::open(cpath.as_ptr(), libc::O_RDWR | libc::O_NOCTTY), "open slave")?;
            let slave = OwnedFd::from_raw_fd(s);
            let mut t: libc::termios = std::mem::zeroed();
            check(libc::tcgetattr(s, &mut t), "tcgetattr")?;
            libc::cfmakeraw(&mut t);
            check(libc::tcsetattr(s, libc::TCSANOW, &t), "tcsetattr")?;
            let flags = check(libc::fcntl(m, libc::F_GETFL), "fcntl")?;
            check(libc::fcntl(m, libc::F_SETFL, flags | libc::O_NONBLOCK), "fcntl")?;
            if let Some(l) = link {
                let _ = std::fs::remove_file(l);
                std::os::unix::fs::symlink(&slave_path, l)?;
            }
            let opens = watch_opens(&slave_path)?;
            Ok(PtyBridge {
                master,
                _slave: slave,
                opens: Some(opens),
                auto_resets: 0,
                deaf_until: 0,
                lost_in_reset: 0,
                slave_path,
                link: link.map(Path::to_path_buf),
                out_sent: vm.output_bytes().len(),
                pending: VecDeque::new(),
                line_start: Some(0),
                at_line_start: true,
                unread: (0, Instant::now()),
                urgent: 0,
                stale_dropped: 0,
                corrupt_line: None,
                corrupted: Vec::new(),
                bytes_in: 0,
                bytes_out: 0,
                realtime: false,
                fast_while_busy: false,
                was_busy: false,
                started: Instant::now(),
                sim_start_s: vm.seconds(),
            })
        }
    }

    /// The port a sender opens.
    pub fn port(&self) -> &Path {
        self.link.as_deref().unwrap_or(&self.slave_path)
    }

    /// Reset the board when a sender opens the port (default on; off: a
    /// board whose auto-reset jumper is cut).
    pub fn auto_reset(mut self, on: bool) -> Self {
        if !on {
            self.opens = None;
        } else if self.opens.is_none() {
            self.opens = watch_opens(&self.slave_path).ok();
        }
        self
    }

    /// Keep simulated time from running ahead of the wall clock.
    pub fn realtime(mut self, on: bool) -> Self {
        self.realtime = on;
        self.started = Instant::now();
        self
    }

    /// With [`PtyBridge::realtime`]: while the bootloader runs and bytes
    /// flow either way, let simulated time run as fast as it can; keep it
    /// in step with the wall clock while the line is quiet and whenever the
    /// firmware runs. Simulated timing is unchanged; only the wall-clock
    /// time of a transfer shrinks. Every wait avrdude or the bootloader
    /// times (a reply that does not come, the bootloader's timeout) happens
    /// on a quiet line, at the wall clock's pace. For avrdude.
    pub fn fast_while_busy(mut self, on: bool) -> Self {
        self.fast_while_busy = on;
        self
    }

    /// Corrupt the checksum of the line numbered `n`, once.
    pub fn corrupt_checksum_of_line(mut self, n: u32) -> Self {
        self.corrupt_line = Some(n);
        self
    }

    /// Moves bytes both ways, then runs the machine for `slice_s` simulated
    /// seconds. Returns whether any byte moved (either way).
    pub fn pump(&mut self, vm: &mut Vm, slice_s: f64) -> Result<bool, VmError> {
        let a = self.pump_activity(vm, slice_s)?;
        Ok(a.host_bytes > 0 || a.output_bytes > 0)
    }

    /// [`PtyBridge::pump`], saying what happened: bytes from the sender,
    /// firmware output and steps (what `--idle-exit` counts as activity).
    pub fn pump_activity(&mut self, vm: &mut Vm, slice_s: f64) -> Result<Activity, VmError> {
        let mut act = Activity::default();
        if self.port_opened() {
            self.reset_board(vm);
        }
        let mut buf = [0u8; 512];
        loop {
            // SAFETY: reading into our own buffer from a non-blocking fd.
            let n = unsafe { libc::read(self.master.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
            if n <= 0 {
                break;
            }
            act.host_bytes += n as usize;
            self.bytes_in += n as u64;
            if vm.cycles() < self.deaf_until {
                self.lost_in_reset += n as u64;
                continue;
            }
            for &b in &buf[..n as usize] {
                self.take_from_sender(vm, b);
            }
        }
        self.feed(vm);
        self.drop_stale_output();
        let out = &vm.output_bytes()[self.out_sent..];
        if !out.is_empty() {
            // SAFETY: writing our own bytes to a non-blocking fd.
            let n = unsafe { libc::write(self.master.as_raw_fd(), out.as_ptr().cast(), out.len()) };
            if n > 0 {
                self.out_sent += n as usize;
                self.bytes_out += n as u64;
            }
        }
        let busy =
            vm.pc() >= crate::boot::BOOT_START && (act.host_bytes > 0 || !self.pending.is_empty() || vm.tx_pending() > 0 || self.was_busy);
        if self.realtime && self.fast_while_busy && busy {
            // In step with the wall clock from here.
            self.started = Instant::now();
            self.sim_start_s = vm.seconds();
        } else if self.realtime {
            let ahead = (vm.seconds() - self.sim_start_s) - self.started.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(Duration::from_secs_f64(ahead.min(0.05)));
            }
        }
        let (steps, out_len) = (vm.recorder().total_steps(), vm.output_bytes().len());
        // Top the UART queue up every half millisecond (16 bytes per 0.5 ms
        // is more than the 25 000 B/s of 250 000 baud: the line stays full).
        let parts = (slice_s / 0.0005).ceil().max(1.0);
        for _ in 0..parts as usize {
            vm.run_for(slice_s / parts)?;
            self.feed(vm);
        }
        act.steps = vm.recorder().total_steps() - steps;
        act.output_bytes = vm.output_bytes().len() - out_len;
        self.was_busy = act.host_bytes > 0 || act.output_bytes > 0;
        Ok(act)
    }

    /// Has a sender opened the port since the last look? (Reads every
    /// pending inotify event.)
    fn port_opened(&mut self) -> bool {
        let Some(fd) = &self.opens else { return false };
        let mut buf = [0u8; 256];
        let mut opened = false;
        // SAFETY: reading events into our own buffer from a non-blocking fd.
        while unsafe { libc::read(fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) } > 0 {
            opened = true;
        }
        opened
    }

    /// The DTR pulse: the chip resets; what waited for it or for the old
    /// sender is gone.
    fn reset_board(&mut self, vm: &mut Vm) {
        self.auto_resets += 1;
        self.pending.clear();
        self.line_start = Some(0);
        self.at_line_start = true;
        vm.clear_tx();
        vm.reset();
        self.deaf_until = vm.cycles() + vm.startup_cycles();
        self.out_sent = vm.output_bytes().len();
    }

    /// Bytes still waiting in the bridge for the UART.
    pub fn waiting(&self) -> usize {
        self.pending.len()
    }

    /// Keep the VM's UART queue short: the rest waits here, where realtime
    /// commands can pass it.
    fn feed(&mut self, vm: &mut Vm) {
        let room = UART_QUEUE.saturating_sub(vm.tx_pending());
        let k = room.min(self.pending.len());
        if k == 0 {
            return;
        }
        let bytes: Vec<u8> = self.pending.drain(..k).collect();
        vm.send(&bytes);
        self.line_start = self.line_start.and_then(|s| s.checked_sub(k));
        if self.pending.is_empty() && self.at_line_start {
            self.line_start = Some(0);
        }
    }

    /// Send ahead of every waiting byte.
    fn urgent(&mut self, vm: &mut Vm, bytes: &[u8]) {
        self.urgent += 1;
        vm.send_first(bytes);
    }

    /// One byte from the sender (see the module doc for what passes ahead).
    fn take_from_sender(&mut self, vm: &mut Vm, b: u8) {
        if vm.pc() >= crate::boot::BOOT_START {
            // The bootloader runs (avrdude's binary STK500 messages): every
            // byte in order, none of them is a realtime command.
            self.pending.push_back(b);
            return;
        }
        if b == 0x18 || (self.at_line_start && matches!(b, b'?' | b'!' | b'~')) {
            self.urgent(vm, &[b]);
            return;
        }
        if self.at_line_start {
            self.line_start = Some(self.pending.len());
        }
        self.pending.push_back(b);
        // A line ends with `\n` or `\r` (some senders end lines with CR).
        self.at_line_start = matches!(b, b'\n' | b'\r');
        if !self.at_line_start {
            return;
        }
        let Some(start) = self.line_start else { return };
        let mut line: Vec<u8> = self.pending.range(start..).copied().collect();
        if is_m112(&line) {
            self.pending.truncate(start);
            self.urgent(vm, &line);
            return;
        }
        if let Some(n) = self.corrupt_line {
            if let Some(bad) = corrupt_checksum(&line, n) {
                self.corrupted.push(String::from_utf8_lossy(&line).trim_end().to_string());
                self.corrupt_line = None;
                line = bad;
                self.pending.truncate(start);
                self.pending.extend(line);
            }
        }
    }

    /// Drop output that has waited unread in the pty for [`STALE_OUTPUT`]:
    /// no sender is reading it, and the next one must not get it.
    fn drop_stale_output(&mut self) {
        let mut n: libc::c_int = 0;
        // SAFETY: FIONREAD on our own slave fd writes one int.
        if unsafe { libc::ioctl(self._slave.as_raw_fd(), libc::FIONREAD, &mut n) } < 0 {
            return;
        }
        let n = n.max(0) as usize;
        if n == 0 || n < self.unread.0 || (n > self.unread.0 && self.unread.0 == 0) {
            self.unread = (n, Instant::now());
        } else if self.unread.1.elapsed() >= STALE_OUTPUT {
            let mut sink = vec![0u8; n];
            // SAFETY: reading the `n` bytes FIONREAD reported from our own
            // slave fd (a read, not a flush: no sender is there to see it).
            unsafe { libc::read(self._slave.as_raw_fd(), sink.as_mut_ptr().cast(), n) };
            self.stale_dropped += n as u64;
            self.unread = (0, Instant::now());
        } else {
            self.unread.0 = n;
        }
    }
}

/// An inotify instance that reports every open of `path` (non-blocking).
fn watch_opens(path: &Path) -> io::Result<OwnedFd> {
    let cpath = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).expect("pts path");
    // SAFETY: plain libc calls; the fd is owned from here on.
    unsafe {
        let fd = check(libc::inotify_init1(libc::IN_NONBLOCK | libc::IN_CLOEXEC), "inotify_init1")?;
        let fd = OwnedFd::from_raw_fd(fd);
        check(libc::inotify_add_watch(fd.as_raw_fd(), cpath.as_ptr(), libc::IN_OPEN), "inotify_add_watch")?;
        Ok(fd)
    }
}

/// Is `line` an `M112` command (optionally numbered and checksummed)?
pub fn is_m112(line: &[u8]) -> bool {
    let text = String::from_utf8_lossy(line);
    let mut t = text.trim();
    if let Some(star) = t.rfind('*') {
        t = &t[..star];
    }
    if t.starts_with(['N', 'n']) {
        t = t[1..].trim_start_matches(|c: char| c.is_ascii_digit() || c == '-').trim_start();
    }
    let t = t.split([';', '(']).next().unwrap_or("").trim();
    t.eq_ignore_ascii_case("M112")
}

impl Drop for PtyBridge {
    fn drop(&mut self) {
        if let Some(l) = &self.link {
            let _ = std::fs::remove_file(l);
        }
    }
}

/// `N<n> … *<cs>\n` with a different checksum, if `line` is numbered `n`.
pub fn corrupt_checksum(line: &[u8], n: u32) -> Option<Vec<u8>> {
    let text = std::str::from_utf8(line).ok()?;
    let rest = text.strip_prefix('N')?;
    let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
    if digits.parse::<u32>().ok()? != n {
        return None;
    }
    let star = text.rfind('*')?;
    let cs: u8 = text[star + 1..].trim().parse().ok()?;
    Some(format!("{}*{}\n", &text[..star], cs ^ 0x55).into_bytes())
}

#[cfg(test)]
mod tests {
    use super::{corrupt_checksum, is_m112};

    #[test]
    fn m112_lines_are_recognised_numbered_or_not() {
        assert!(is_m112(b"M112\n"));
        assert!(is_m112(b"m112 ; stop\n"));
        assert!(is_m112(b"N12 M112*54\n"));
        assert!(!is_m112(b"M1120\n"));
        assert!(!is_m112(b"G1 X1 ; M112\n"));
        assert!(!is_m112(b"M11\n"));
    }

    #[test]
    fn only_the_named_line_gets_a_different_checksum() {
        assert_eq!(corrupt_checksum(b"N7 G1 X1*45\n", 7), Some(b"N7 G1 X1*120\n".to_vec()));
        assert_eq!(corrupt_checksum(b"N7 G1 X1*45\n", 8), None);
        assert_eq!(corrupt_checksum(b"N17 G1 X1*45\n", 1), None);
        assert_eq!(corrupt_checksum(b"G1 X1\n", 7), None);
    }
}
