//! TCNTn kept across a timer's clock stop/start, as on the hardware (module
//! docs of `vm`): simavr's TCCRnB write handlers wrapped when
//! [`VmConfig::fix_tcnt_on_clock_start`](super::VmConfig::fix_tcnt_on_clock_start) is set.

use simavr_ffi as ffi;
use std::ffi::c_void;

/// Param of a wrapped TCCRnB write handler.
pub(super) struct TimerWrap {
    /// Data-space address of TCCRnB and of TCNTn (low byte).
    tccrb: u16,
    tcnt: u16,
    orig: ffi::avr_io_write_t,
    orig_param: *mut c_void,
}

/// The 6 timers of the ATmega2560: (TCCRnB, TCNTn or TCNTnL).
const TIMERS: [(u16, u16); 6] = [(0x45, 0x46), (0x81, 0x84), (0xB1, 0xB2), (0x91, 0x94), (0xA1, 0xA4), (0x121, 0x124)];

/// Wraps simavr's TCCRnB write: freeze TCNTn when the clock stops, write it
/// back through simavr's TCNT handler when the clock starts.
// SAFETY (contract): installed as `avr->io[TCCRnB].w` with a TimerWrap param
// that lives in Vm::timer_wraps; simavr calls it for CPU writes to TCCRnB.
unsafe extern "C" fn tccrb_write(avr: *mut ffi::avr_t, addr: ffi::avr_io_addr_t, v: u8, param: *mut c_void) {
    // SAFETY: param is a TimerWrap alive as long as the instance; avr is live;
    // the I/O table entries belong to simavr's timer module.
    unsafe {
        let w = &*(param as *const TimerWrap);
        let data = (*avr).data;
        let tcnt_io = &(*avr).io[(w.tcnt - 32) as usize];
        let was_running = *data.add(w.tccrb as usize) & 7 != 0;
        let will_run = v & 7 != 0;
        if was_running && !will_run {
            if let Some(read) = tcnt_io.r.c {
                read(avr, w.tcnt, tcnt_io.r.param); // updates TCNTn (and TCNTnH) in data
            }
        }
        if let Some(orig) = w.orig {
            orig(avr, addr, v, w.orig_param);
        }
        if !was_running && will_run {
            if let Some(write) = tcnt_io.w.c {
                write(avr, w.tcnt, *data.add(w.tcnt as usize), tcnt_io.w.param);
            }
        }
    }
}

/// Wraps the TCCRnB write handler of every timer (none without `fix`).
/// The returned wraps are the handlers' params: keep them as long as the
/// instance.
///
/// SAFETY: `avr` must be a live, initialised instance that is not running.
pub(super) unsafe fn wrap(avr: *mut ffi::avr_t, fix: bool) -> Box<[TimerWrap]> {
    let mut timer_wraps: Box<[TimerWrap]> = if fix {
        TIMERS
            .iter()
            .map(|&(tccrb, tcnt)| {
                // SAFETY: avr is live; reading the I/O table entry of TCCRnB.
                let w = unsafe { (*avr).io[(tccrb - 32) as usize].w };
                TimerWrap { tccrb, tcnt, orig: w.c, orig_param: w.param }
            })
            .collect()
    } else {
        Box::new([])
    };
    for w in timer_wraps.iter_mut() {
        // SAFETY: avr is live and not running; the wrap outlives the instance (dropped after it in Vm::drop).
        unsafe {
            let slot = &mut (*avr).io[(w.tccrb - 32) as usize].w;
            slot.c = Some(tccrb_write);
            slot.param = w as *mut TimerWrap as *mut c_void;
        }
    }
    timer_wraps
}
