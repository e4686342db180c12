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

use crate::{Vm, VmError};
use std::ffi::CStr;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A pty whose master side is wired to the virtual machine's UART0.
pub struct PtyBridge {
    master: OwnedFd,
    _slave: OwnedFd,
    slave_path: PathBuf,
    link: Option<PathBuf>,
    /// Firmware output already passed to the master.
    out_sent: usize,
    /// Host bytes of the line being assembled (forwarded at its `\n`).
    line: Vec<u8>,
    /// Corrupt the checksum of the line numbered this (once).
    corrupt_line: Option<u32>,
    /// Lines whose checksum was corrupted.
    pub corrupted: Vec<String>,
    /// Bytes from the sender, and to it.
    pub bytes_in: u64,
    pub bytes_out: u64,
    realtime: bool,
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
            Ok(PtyBridge {
                master,
                _slave: slave,
                slave_path,
                link: link.map(Path::to_path_buf),
                out_sent: vm.output_bytes().len(),
                line: Vec::new(),
                corrupt_line: None,
                corrupted: Vec::new(),
                bytes_in: 0,
                bytes_out: 0,
                realtime: false,
                started: Instant::now(),
                sim_start_s: vm.seconds(),
            })
        }
    }

    /// The port a sender opens.
    pub fn port(&self) -> &Path {
        self.link.as_deref().unwrap_or(&self.slave_path)
    }

    /// Keep simulated time from running ahead of the wall clock.
    pub fn realtime(mut self, on: bool) -> Self {
        self.realtime = on;
        self.started = Instant::now();
        self
    }

    /// Corrupt the checksum of the line numbered `n`, once.
    pub fn corrupt_checksum_of_line(mut self, n: u32) -> Self {
        self.corrupt_line = Some(n);
        self
    }

    /// Moves bytes both ways, then runs the machine for `slice_s` simulated
    /// seconds. Returns whether any byte moved.
    pub fn pump(&mut self, vm: &mut Vm, slice_s: f64) -> Result<bool, VmError> {
        let mut moved = false;
        let mut buf = [0u8; 512];
        loop {
            // SAFETY: reading into our own buffer from a non-blocking fd.
            let n = unsafe { libc::read(self.master.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
            if n <= 0 {
                break;
            }
            moved = true;
            self.bytes_in += n as u64;
            for &b in &buf[..n as usize] {
                self.from_sender(vm, b);
            }
        }
        let out = &vm.output_bytes()[self.out_sent..];
        if !out.is_empty() {
            // SAFETY: writing our own bytes to a non-blocking fd.
            let n = unsafe { libc::write(self.master.as_raw_fd(), out.as_ptr().cast(), out.len()) };
            if n > 0 {
                self.out_sent += n as usize;
                self.bytes_out += n as u64;
                moved = true;
            }
        }
        if self.realtime {
            let ahead = (vm.seconds() - self.sim_start_s) - self.started.elapsed().as_secs_f64();
            if ahead > 0.0 {
                std::thread::sleep(Duration::from_secs_f64(ahead.min(0.05)));
            }
        }
        vm.run_for(slice_s)?;
        Ok(moved)
    }

    /// One byte from the sender: realtime bytes pass at once, lines at their end.
    fn from_sender(&mut self, vm: &mut Vm, b: u8) {
        if self.line.is_empty() && matches!(b, b'?' | b'!' | b'~') {
            vm.send([b]);
            return;
        }
        self.line.push(b);
        if b == b'\n' {
            let mut line = std::mem::take(&mut self.line);
            if let Some(n) = self.corrupt_line {
                if let Some(bad) = corrupt_checksum(&line, n) {
                    self.corrupted.push(String::from_utf8_lossy(&line).trim_end().to_string());
                    self.corrupt_line = None;
                    line = bad;
                }
            }
            vm.send(&line);
        }
    }
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
    use super::corrupt_checksum;

    #[test]
    fn only_the_named_line_gets_a_different_checksum() {
        assert_eq!(corrupt_checksum(b"N7 G1 X1*45\n", 7), Some(b"N7 G1 X1*120\n".to_vec()));
        assert_eq!(corrupt_checksum(b"N7 G1 X1*45\n", 8), None);
        assert_eq!(corrupt_checksum(b"N17 G1 X1*45\n", 1), None);
        assert_eq!(corrupt_checksum(b"G1 X1\n", 7), None);
    }
}
