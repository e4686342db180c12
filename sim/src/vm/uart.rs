//! UART0's host side: bytes for the chip (paced with ideal flow control,
//! or flooded at the line rate as a host without any), what the firmware
//! prints (bytes, text, lines), and the conversation on top: waiting for a
//! line, a command up to its `ok`, a streamed job ([`crate::host`]). The
//! simavr UART quirks this works around are in the module docs of `vm`.

use super::simavr::{ioctl_uart_getirq, ioctl_uart_set_flags, regbit_get, regbit_set};
use super::{Inner, Vm, VmError};
use crate::host::{is_reply_end, StreamOptions, StreamReport, Streamer};
use simavr_ffi as ffi;
use std::collections::VecDeque;
use std::ffi::{c_int, c_void, CStr};

/// Host side of UART0.
#[derive(Default)]
pub(super) struct UartHost {
    /// Bytes for the chip, paced with flow control.
    pub(super) paced: VecDeque<u8>,
    /// Bytes for the chip, pushed at the line rate regardless.
    pub(super) flood: VecDeque<u8>,
    /// The feeder cycle timer is armed.
    pub(super) feeding: bool,
    /// simavr's XOFF: its input FIFO is full.
    pub(super) xoff: bool,
    pub(super) out: Vec<u8>,
    pub(super) out_text: String,
    pub(super) partial: String,
    pub(super) pending: VecDeque<String>,
    pub(super) log: Vec<(u64, String)>,
    pub(super) bytes_to_chip: u64,
    pub(super) rx_dropped: u64,
    pub(super) rx_deep: u64,
}

/// UART0 transmitted a byte.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_out_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    let b = value as u8;
    let cycle = inner.now();
    let h = &mut inner.host;
    h.out.push(b);
    let c = if b.is_ascii() { b as char } else { char::REPLACEMENT_CHARACTER };
    h.out_text.push(c);
    if b == b'\n' {
        let line = std::mem::take(&mut h.partial);
        let line = line.strip_suffix('\r').unwrap_or(&line).to_string();
        h.log.push((cycle, line.clone()));
        h.pending.push_back(line);
        inner.event = true;
    } else {
        h.partial.push(c);
    }
}

// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_xoff_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.host.xoff = value != 0;
}

// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_xon_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is our Inner.
    let inner = unsafe { &mut *(param as *mut Inner) };
    if value != 0 {
        inner.host.xoff = false;
    }
}

/// One byte-time of the host's transmitter: hand the next byte to simavr.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn uart_feed_timer(_avr: *mut ffi::avr_t, when: ffi::avr_cycle_count_t, param: *mut c_void) -> u64 {
    let inner_p = param as *mut Inner;
    // Decide with short-lived borrows: raising the input IRQ below may call
    // uart_xoff_notify, which borrows Inner itself.
    let (raise, input_irq) = {
        // SAFETY: param is our Inner; no other borrow of it is live here.
        let inner = unsafe { &mut *inner_p };
        // SAFETY: inner.uart points into the live mcu struct; read by value.
        let (rxen_rb, dor_rb, read, write, irqs) = unsafe {
            let u = &*inner.uart;
            (u.rxen, u.dor, u.input.read, u.input.write, u.io.irq)
        };
        let rxen = regbit_get(inner, rxen_rb) != 0;
        let unread = (write.wrapping_sub(read) & 63) as usize;
        // SAFETY: the UART's IRQ array has UART_IRQ_COUNT entries.
        let input_irq = unsafe { irqs.add(ffi::UART_IRQ_INPUT as usize) };
        let h = &mut inner.host;
        let mut raise = None;
        if let Some(b) = h.flood.pop_front() {
            h.bytes_to_chip += 1;
            if !rxen || unread >= 2 {
                h.rx_dropped += 1;
                regbit_set(inner, dor_rb);
            } else {
                raise = Some(b);
            }
        } else if !h.paced.is_empty() && rxen && !h.xoff && unread < 62 {
            if unread >= 2 {
                h.rx_deep += 1;
            }
            h.bytes_to_chip += 1;
            raise = h.paced.pop_front();
        }
        (raise, input_irq)
    };
    if let Some(b) = raise {
        // SAFETY: raising the UART input IRQ is how simavr receives a byte; no Rust borrow is live.
        unsafe { ffi::avr_raise_irq(input_irq, b as u32) };
    }
    // SAFETY: as above; the raise has returned.
    let inner = unsafe { &mut *inner_p };
    if inner.host.flood.is_empty() && inner.host.paced.is_empty() {
        inner.host.feeding = false;
        return 0;
    }
    // SAFETY: reading a field of the live UART struct.
    let per_byte = unsafe { (*inner.uart).cycles_per_byte };
    when + per_byte.max(16)
}

/// Switches off UART0's stdout echo and its `usleep` on polling, finds its
/// `avr_uart_t` and hooks its output and flow-control IRQs. False if the
/// instance has no UART0 (nothing is hooked then).
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` the
/// Inner it calls back with, alive as long as the instance.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) -> bool {
    let param = inner as *mut c_void;
    // SAFETY: avr is live; every IRQ pointer comes from simavr's own lookup
    // and is checked for null before use.
    unsafe {
        // UART0: no stdout echo, no usleep on polling.
        let mut flags: u32 = 0;
        ffi::avr_ioctl(avr, ioctl_uart_set_flags(b'0'), &mut flags as *mut u32 as *mut c_void);
        (*inner).uart = find_uart0(avr);
        let out = ffi::avr_io_getirq(avr, ioctl_uart_getirq(b'0'), ffi::UART_IRQ_OUTPUT as c_int);
        let xon = ffi::avr_io_getirq(avr, ioctl_uart_getirq(b'0'), ffi::UART_IRQ_OUT_XON as c_int);
        let xoff = ffi::avr_io_getirq(avr, ioctl_uart_getirq(b'0'), ffi::UART_IRQ_OUT_XOFF as c_int);
        if out.is_null() || (*inner).uart.is_null() {
            return false;
        }
        ffi::avr_irq_register_notify(out, Some(uart_out_notify), param);
        ffi::avr_irq_register_notify(xon, Some(uart_xon_notify), param);
        ffi::avr_irq_register_notify(xoff, Some(uart_xoff_notify), param);
    }
    true
}

/// Finds UART0's `avr_uart_t` in the instance's I/O module list.
///
/// SAFETY: `avr` must be a live, initialised instance.
unsafe fn find_uart0(avr: *mut ffi::avr_t) -> *mut ffi::avr_uart_t {
    // SAFETY: walking simavr's own singly linked list of I/O modules.
    unsafe {
        let mut io = (*avr).io_port;
        while !io.is_null() {
            let kind = (*io).kind;
            if !kind.is_null() && CStr::from_ptr(kind).to_bytes() == b"uart" {
                // avr_uart_t starts with its avr_io_t.
                let u = io as *mut ffi::avr_uart_t;
                if (*u).name as u8 == b'0' {
                    return u;
                }
            }
            io = (*io).next;
        }
    }
    std::ptr::null_mut()
}

impl Vm {
    pub(super) fn kick_feeder(&mut self) {
        let inner = self.inner_mut();
        if inner.host.feeding || (inner.host.paced.is_empty() && inner.host.flood.is_empty()) {
            return;
        }
        inner.host.feeding = true;
        // SAFETY: avr is live and not running; the timer's param is our Inner.
        unsafe { ffi::avr_cycle_timer_register(self.avr, 1, Some(uart_feed_timer), self.inner as *mut c_void) };
    }

    /// Queues bytes for the chip, sent at the line rate with ideal flow
    /// control (held while simavr's RX FIFO is full or RXEN is off).
    pub fn send(&mut self, bytes: impl AsRef<[u8]>) {
        self.inner_mut().host.paced.extend(bytes.as_ref());
        self.kick_feeder();
    }

    /// Queues bytes for the chip ahead of everything still queued (a
    /// realtime command passing waiting lines), paced as [`Vm::send`].
    pub fn send_first(&mut self, bytes: impl AsRef<[u8]>) {
        let paced = &mut self.inner_mut().host.paced;
        for &b in bytes.as_ref().iter().rev() {
            paced.push_front(b);
        }
        self.kick_feeder();
    }

    /// Queues `line` + `\n`.
    pub fn send_line(&mut self, line: &str) {
        self.send(line.as_bytes());
        self.send(b"\n");
    }

    /// Pushes bytes at the line rate regardless of the chip: bytes arriving
    /// while 2 are unread (or RXEN is off) are lost and DOR is set, as with
    /// the hardware's 2-byte receive FIFO. See [`Vm::uart_rx_dropped`].
    pub fn send_unpaced_flood(&mut self, bytes: impl AsRef<[u8]>) {
        self.inner_mut().host.flood.extend(bytes.as_ref());
        self.kick_feeder();
    }

    /// Bytes queued but not yet handed to the chip.
    pub fn tx_pending(&self) -> usize {
        self.inner().host.paced.len() + self.inner().host.flood.len()
    }

    /// Drops every queued byte.
    pub fn clear_tx(&mut self) {
        let h = &mut self.inner_mut().host;
        h.paced.clear();
        h.flood.clear();
    }

    /// UART0's frame time, cycles: one byte on the wire at the rate and
    /// frame format the firmware set (`uart_clock`).
    pub fn uart_frame_cycles(&self) -> u64 {
        // SAFETY: `uart` points into the live instance (found at start).
        unsafe { (*self.inner().uart).cycles_per_byte }
    }

    /// Flood bytes lost because the chip did not read them in time.
    pub fn uart_rx_dropped(&self) -> u64 {
        self.inner().host.rx_dropped
    }

    /// Paced bytes that found 2 or more unread bytes in the RX FIFO: on
    /// hardware without flow control each of these would have been an overrun.
    pub fn uart_rx_would_overrun(&self) -> u64 {
        self.inner().host.rx_deep
    }

    /// Everything the firmware printed, as text (non-ASCII bytes as U+FFFD).
    pub fn output(&self) -> &str {
        &self.inner().host.out_text
    }

    /// Everything the firmware printed, raw.
    pub fn output_bytes(&self) -> &[u8] {
        &self.inner().host.out
    }

    /// Every complete line received so far with its VM cycle.
    pub fn line_log(&self) -> &[(u64, String)] {
        &self.inner().host.log
    }

    /// Complete lines received and not yet taken (without `\r\n`).
    pub fn take_lines(&mut self) -> Vec<String> {
        self.inner_mut().host.pending.drain(..).collect()
    }

    /// Lines received and not yet taken, without taking them.
    pub fn pending_lines(&self) -> Vec<String> {
        self.inner().host.pending.iter().cloned().collect()
    }

    /// Runs until a line matching `pred` arrives (or is already pending),
    /// removes it from the pending lines and returns it. Non-matching lines
    /// stay pending.
    pub fn wait_line(&mut self, mut pred: impl FnMut(&str) -> bool, timeout_s: f64) -> Result<String, VmError> {
        let deadline = self.cycles() + self.to_cycles(timeout_s);
        let mut scanned = 0usize;
        let mut found: Option<usize> = None;
        let interval = u64::MAX / 4; // lines raise the event flag
        let met = self.run_inner(deadline, interval, &mut |vm: &Vm| {
            let pending = &vm.inner().host.pending;
            while scanned < pending.len() {
                if pred(&pending[scanned]) {
                    found = Some(scanned);
                    return true;
                }
                scanned += 1;
            }
            false
        })?;
        match (met, found) {
            (true, Some(i)) => Ok(self.inner_mut().host.pending.remove(i).unwrap_or_default()),
            _ => Err(VmError::Timeout { what: "a matching line".into(), waited_s: timeout_s }),
        }
    }

    /// Waits for the boot banner line `start`; returns the lines before it.
    pub fn wait_for_start(&mut self, timeout_s: f64) -> Result<Vec<String>, VmError> {
        self.wait_line(|l| l == "start", timeout_s)?;
        Ok(self.take_lines())
    }

    /// Wait for the whole boot banner (`start`, the reset cause and what
    /// follows within 50 ms: settings and tool-record messages) and return
    /// it from the reset cause on; the firmware then takes commands.
    pub fn wait_banner(&mut self) -> Result<Vec<String>, VmError> {
        self.wait_for_start(3.0)?;
        let cause = self.wait_line(|l| l.starts_with("echo:reset cause"), 1.0)?;
        self.run_for(0.05)?;
        let mut banner = vec![cause];
        banner.extend(self.take_lines());
        Ok(banner)
    }

    /// Sends `line\n` and collects lines up to and including the next `ok`
    /// (lines already pending come first). Timeout: `command_timeout_s`.
    pub fn command(&mut self, line: &str) -> Result<Vec<String>, VmError> {
        let t = self.config.command_timeout_s;
        self.command_timeout(line, t)
    }

    /// [`Vm::command`] with an explicit timeout, simulated seconds.
    pub fn command_timeout(&mut self, line: &str, timeout_s: f64) -> Result<Vec<String>, VmError> {
        self.send_line(line);
        let deadline = self.seconds() + timeout_s;
        let mut got = Vec::new();
        loop {
            let left = deadline - self.seconds();
            let l = self.wait_line(|_| true, left.max(0.0)).map_err(|e| match e {
                VmError::Timeout { .. } => VmError::Timeout { what: format!("ok for '{line}'"), waited_s: timeout_s },
                e => e,
            })?;
            let ok = is_reply_end(&l);
            got.push(l);
            if ok {
                return Ok(got);
            }
        }
    }

    /// Streams lines under a flow policy; see [`crate::host`]. A timeout ends
    /// the stream with `timed_out` set; a VM error is returned as such.
    pub fn stream<S: AsRef<str>>(&mut self, lines: &[S], opts: impl Into<StreamOptions>) -> Result<StreamReport, VmError> {
        let opts = opts.into();
        let mut s = Streamer::new(lines, &opts);
        let start = self.seconds();
        let deadline = start + opts.timeout_s;
        let mut last_ok = start;
        let mut timed_out = false;
        while !s.done() {
            while let Some(l) = s.next_to_send() {
                self.send(l.as_bytes());
            }
            if s.done() {
                break;
            }
            let left = deadline - self.seconds();
            match self.wait_line(|_| true, left.max(0.0)) {
                Ok(line) => {
                    if s.on_line(&line) {
                        last_ok = self.seconds();
                    }
                }
                Err(VmError::Timeout { .. }) => {
                    timed_out = true;
                    break;
                }
                Err(e) => return Err(e),
            }
        }
        let mut r = s.into_report();
        r.start_s = start;
        r.end_s = if timed_out { self.seconds() } else { last_ok };
        r.duration_s = r.end_s - start;
        r.timed_out = timed_out;
        Ok(r)
    }
}
