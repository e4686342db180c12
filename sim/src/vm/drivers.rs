//! The stepper drivers: every step/dir/enable pin change into the
//! [`Recorder`] (positions, DRV8825 timing, travel), with the inputs that
//! the move may have reached re-driven; and the VM's view of the result
//! (positions, driver enables, violations).

use super::inputs::drive_input;
use super::simavr::ioctl_ioport_getirq;
use super::{Inner, Vm};
use crate::physics::Physics;
use crate::pins::{Axis, Pin, SignalKind};
use crate::recorder::{Recorder, Violation};
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};

/// Param of a driver-pin notification.
pub(super) struct PinHook {
    inner: *mut Inner,
    axis: Axis,
    kind: SignalKind,
}

/// A driver pin changed level.
// SAFETY (contract): only simavr calls this, from inside `avr_run`/`avr_raise_irq` on the VM's thread,
// with the `param` registered in `Vm::new` (our `Inner`, or a `PinHook` for pin_notify).
unsafe extern "C" fn pin_notify(_irq: *mut ffi::avr_irq_t, value: u32, param: *mut c_void) {
    // SAFETY: param is a PinHook in Vm::hooks, alive while the avr is.
    let hook = unsafe { &*(param as *const PinHook) };
    // SAFETY: hook.inner is our Inner; no other reference to it is live during avr_run.
    let inner = unsafe { &mut *hook.inner };
    let cycle = inner.now();
    if let Some(ev) = inner.recorder.on_pin(cycle, hook.axis, hook.kind, value & 1 != 0) {
        let pos = inner.recorder.positions();
        inner.physics.on_step(&pos, ev.axis);
        for &input in Physics::inputs_moved_by(ev.axis) {
            drive_input(inner, input, false);
        }
    }
}

/// Hooks every driver pin of the board's pin map; the returned hooks are
/// the notifications' params: keep them as long as the instance.
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` the
/// Inner the hooks point to, alive as long as the instance.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) -> Box<[PinHook]> {
    // SAFETY: avr is live; every IRQ pointer comes from simavr's own lookup
    // and is checked for null; the hooks' heap slice does not move.
    unsafe {
        let mut hooks = Vec::new();
        for axis in Axis::ALL {
            let p = (*inner).pins.drivers[axis.index()];
            for (kind, pin) in [(SignalKind::Step, p.step), (SignalKind::Dir, p.dir), (SignalKind::Enable, p.enable)] {
                hooks.push((PinHook { inner, axis, kind }, pin));
            }
        }
        let (hooks, pins): (Vec<PinHook>, Vec<Pin>) = hooks.into_iter().unzip();
        let hooks: Box<[PinHook]> = hooks.into_boxed_slice();
        for (hook, pin) in hooks.iter().zip(pins) {
            let irq = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(pin.port), pin.bit as c_int);
            if !irq.is_null() {
                ffi::avr_irq_register_notify(irq, Some(pin_notify), hook as *const PinHook as *mut c_void);
                (*inner).output_irqs.push(irq);
            }
        }
        hooks
    }
}

impl Vm {
    /// Physical position of an axis, steps.
    pub fn position(&self, axis: Axis) -> i64 {
        self.inner().recorder.position(axis)
    }

    /// Physical positions X, Y, Z, E, steps.
    pub fn positions(&self) -> [i64; 4] {
        self.inner().recorder.positions()
    }

    /// Physical position in mm (E: in the unit of `steps_per_mm[3]`).
    pub fn position_mm(&self, axis: Axis) -> f64 {
        self.position(axis) as f64 / self.config.machine.steps_per_mm[axis.index()]
    }

    /// Is the axis' driver enabled (ENABLE low)?
    pub fn driver_enabled(&self, axis: Axis) -> bool {
        self.inner().recorder.driver_enabled(axis)
    }

    /// The step recorder.
    pub fn recorder(&self) -> &Recorder {
        &self.inner().recorder
    }

    /// The step recorder, mutable (to clear its trace or violations).
    pub fn recorder_mut(&mut self) -> &mut Recorder {
        &mut self.inner_mut().recorder
    }

    /// Stored violations.
    pub fn violations(&self) -> &[Violation] {
        self.inner().recorder.violations()
    }
}
