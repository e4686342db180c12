//! Glue over simavr's C API that the other files share: ioctl codes,
//! register bits, zeroed plain-old-data structs, libc's `free` and
//! `vsnprintf`, and the two callbacks that replace simavr's host habits:
//! its global logger (messages kept per VM) and `avr->sleep`.

use super::Inner;
use simavr_ffi as ffi;
use std::ffi::{c_char, c_int, c_void, CStr};

/// simavr's `AVR_IOCTL_DEF(a, b, c, d)`.
pub(super) const fn ioctl_def(a: u8, b: u8, c: u8, d: u8) -> u32 {
    ((a as u32) << 24) | ((b as u32) << 16) | ((c as u32) << 8) | (d as u32)
}
pub(super) const fn ioctl_ioport_getirq(port: u8) -> u32 {
    ioctl_def(b'i', b'o', b'g', port)
}
pub(super) const fn ioctl_ioport_set_external(port: u8) -> u32 {
    ioctl_def(b'i', b'o', b'p', port)
}
pub(super) const fn ioctl_uart_getirq(name: u8) -> u32 {
    ioctl_def(b'u', b'a', b'r', name)
}
pub(super) const fn ioctl_uart_set_flags(name: u8) -> u32 {
    ioctl_def(b'u', b'a', b's', name)
}

extern "C" {
    fn vsnprintf(buf: *mut c_char, n: usize, fmt: *const c_char, ap: *mut ffi::__va_list_tag) -> c_int;
    pub(super) fn free(p: *mut c_void);
}

/// simavr's logger: keep warnings and errors per VM, drop traces.
// SAFETY (contract): simavr calls this with a live instance (or null) and a matching format/va_list.
pub(super) unsafe extern "C" fn logger(avr: *mut ffi::avr_t, level: c_int, fmt: *const c_char, ap: *mut ffi::__va_list_tag) {
    if level > ffi::LOG_WARNING as c_int || fmt.is_null() {
        return;
    }
    let mut buf = [0 as c_char; 512];
    // SAFETY: buf is 512 bytes; fmt/ap come from simavr's AVR_LOG and match.
    unsafe { vsnprintf(buf.as_mut_ptr(), buf.len(), fmt, ap) };
    // SAFETY: vsnprintf NUL-terminates within the buffer.
    let msg = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_string_lossy().trim_end().to_string();
    // SAFETY: avr is null or a live instance; custom.data is null or our Inner.
    let inner = if avr.is_null() { std::ptr::null_mut() } else { unsafe { (*avr).custom.data as *mut Inner } };
    if inner.is_null() {
        if level <= ffi::LOG_ERROR as c_int {
            eprintln!("simavr: {msg}");
        }
        return;
    }
    // SAFETY: Inner outlives the avr instance's use; simavr is single-threaded per instance.
    let inner = unsafe { &mut *inner };
    if inner.log.len() < 10_000 {
        inner.log.push(msg);
    }
}

/// Replaces simavr's `avr->sleep`, which `usleep`s to keep wall-clock pace.
// SAFETY (contract): does nothing with its arguments.
pub(super) unsafe extern "C" fn no_sleep(_avr: *mut ffi::avr_t, _how_long: ffi::avr_cycle_count_t) {}

pub(super) fn regbit_get(inner: &Inner, rb: ffi::avr_regbit_t) -> u8 {
    let reg = rb.reg() as u16;
    if reg == 0 {
        return 0;
    }
    (inner.read(reg) >> rb.bit()) & rb.mask() as u8
}

pub(super) fn regbit_set(inner: &mut Inner, rb: ffi::avr_regbit_t) {
    let reg = rb.reg() as usize;
    if reg != 0 {
        // SAFETY: simavr regbits address registers inside the data array.
        unsafe { *inner.data().add(reg) |= (rb.mask() as u8) << rb.bit() };
    }
}

pub(super) fn zeroed_pod<T: Copy>() -> T {
    // SAFETY: only used for plain-old-data simavr structs, for which all-zero is valid.
    unsafe { std::mem::zeroed() }
}
