//! The machine's inputs as the chip sees them: home switches, tool setter,
//! carousel sensor, SD detect and the encoder, driven from the [`Physics`]
//! model (or a test's override) onto their pins, with contact bounce
//! replayed by a cycle timer; and the VM's API to the model (overrides,
//! tool-setter and switch models, the tool changer, encoder turns).

use super::simavr::{ioctl_ioport_getirq, ioctl_ioport_set_external, zeroed_pod};
use super::{Inner, Vm, VmError};
use crate::physics::{Physics, ToolSetter};
use crate::pins::Input;
use simavr_ffi as ffi;
use std::ffi::{c_int, c_void};

/// Drive one input to what the model/override says. With `direct`, write
/// PINx and the IRQ's cached value without notifying anyone (after a reset);
/// otherwise raise the pin IRQ (edges reach INTn/PCINT) if the level changed.
pub(super) fn drive_input(inner: &mut Inner, input: Input, direct: bool) {
    let pos = inner.recorder.positions();
    let now = inner.now();
    let inverted = u32::from(inner.physics.config().inverted_inputs) >> input.index() & 1 != 0;
    let level = input.level(inner.physics.sense(input, &pos, now)) != inverted;
    if !direct {
        arm_switch_timer(inner);
    }
    let i = input.index();
    if !direct && inner.levels[i] == Some(level) {
        return;
    }
    inner.levels[i] = Some(level);
    let Some(pin) = inner.pins.input(input) else { return };
    // The port's external state covers every input on that port.
    let (mut mask, mut value) = (0u8, 0u8);
    for other in Input::ALL {
        let Some(p) = inner.pins.input(other) else { continue };
        if p.port == pin.port {
            if let Some(l) = inner.levels[other.index()] {
                mask |= 1 << p.bit;
                if l {
                    value |= 1 << p.bit;
                }
            }
        }
    }
    let mut ext: ffi::avr_ioport_external_t = zeroed_pod();
    ext.set_name(pin.port as _);
    ext.set_mask(mask as _);
    ext.set_value(value as _);
    // SAFETY: avr is live; the ioctl copies the struct's fields.
    unsafe { ffi::avr_ioctl(inner.avr, ioctl_ioport_set_external(pin.port), &mut ext as *mut _ as *mut c_void) };
    let irq = inner.input_irqs[i];
    if irq.is_null() {
        return;
    }
    if direct {
        // SAFETY: irq is a live port pin IRQ; PINx is inside the data array.
        unsafe {
            (*irq).value = level as u32;
            let p = inner.data().add(pin.pin_reg() as usize);
            if level {
                *p |= 1 << pin.bit;
            } else {
                *p &= !(1 << pin.bit);
            }
        }
    } else {
        // SAFETY: irq is a live port pin IRQ; raising it is simavr's input path.
        // No hook of ours sits on input pins, so this does not re-enter Inner.
        unsafe { ffi::avr_raise_irq(irq, level as u32) };
    }
}

/// Arm the switch-bounce timer for the earliest pending toggle (outside the
/// timer itself, which re-arms by its return value).
fn arm_switch_timer(inner: &mut Inner) {
    if inner.in_switch_timer {
        return;
    }
    let Some(t) = inner.physics.next_toggle() else { return };
    if inner.switch_timer_at.is_some_and(|at| at <= t) {
        return;
    }
    let now = inner.now();
    inner.switch_timer_at = Some(t);
    // SAFETY: avr is live; registering replaces this (timer, param) pair if
    // already queued; the param is our Inner, as for every other timer.
    unsafe {
        ffi::avr_cycle_timer_register(inner.avr, t.saturating_sub(now).max(1), Some(switch_timer), inner as *mut Inner as *mut c_void)
    };
}

/// A switch contact bounces: apply the toggles due now, drive their pins and
/// re-arm for the next one.
// SAFETY (contract): only simavr calls this, from inside `avr_run` on the VM's thread,
// with our `Inner` as param (registered by `arm_switch_timer`).
unsafe extern "C" fn switch_timer(_avr: *mut ffi::avr_t, _when: ffi::avr_cycle_count_t, param: *mut c_void) -> u64 {
    // SAFETY: param is our Inner; no other borrow of it is live during avr_run.
    let inner = unsafe { &mut *(param as *mut Inner) };
    inner.in_switch_timer = true;
    let now = inner.now();
    for input in inner.physics.fire_toggles(now) {
        drive_input(inner, input, false);
    }
    inner.in_switch_timer = false;
    inner.switch_timer_at = inner.physics.next_toggle();
    match inner.switch_timer_at {
        // simavr's clock restarts at a reset: its cycles are ours less the base.
        Some(t) => t.max(now + 1) - inner.cycle_base,
        None => 0,
    }
}

/// Looks up the pin IRQ of every input the board's pin map wires.
///
/// SAFETY: `avr` must be a live, initialised instance and `inner` its Inner.
pub(super) unsafe fn attach(avr: *mut ffi::avr_t, inner: *mut Inner) {
    // SAFETY: avr is live; inner is ours and not borrowed elsewhere.
    unsafe {
        for input in Input::ALL {
            if let Some(pin) = (*inner).pins.input(input) {
                (*inner).input_irqs[input.index()] = ffi::avr_io_getirq(avr, ioctl_ioport_getirq(pin.port), pin.bit as c_int);
            }
        }
    }
}

impl Vm {
    /// The machine model.
    pub fn physics(&self) -> &Physics {
        &self.inner().physics
    }

    /// The tool changer's physical state: spindle tool, pocket contents,
    /// transfers and collisions.
    pub fn atc(&self) -> &crate::atc::AtcModel {
        self.inner().physics.atc()
    }

    /// Change the tool changer's physical state (swap, break or remove a
    /// tool); the tool-setter input follows at once.
    pub fn with_atc(&mut self, f: impl FnOnce(&mut crate::atc::AtcModel)) {
        let inner = self.inner_mut();
        f(inner.physics.atc_mut());
        drive_input(inner, Input::ToolSetter, false);
    }

    /// Force an input active/inactive (`Some`) or give it back to the model
    /// (`None`). Takes effect at once (edges reach INTn/PCINT).
    pub fn set_input(&mut self, input: Input, active: Option<bool>) {
        let inner = self.inner_mut();
        inner.physics.set_override(input, active);
        drive_input(inner, input, false);
    }

    /// The logical state the firmware currently sees on an input.
    pub fn input_active(&self, input: Input) -> bool {
        let inner = self.inner();
        inner.physics.active(input, &inner.recorder.positions())
    }

    /// The electrical level of an input's pin as the chip reads it (PINx bit).
    pub fn input_level(&self, input: Input) -> bool {
        let Some(pin) = self.inner().pins.input(input) else { return false };
        self.read_u8(pin.pin_reg()) & (1 << pin.bit) != 0
    }

    /// Replace the tool-setter model (takes effect at once).
    pub fn set_tool_setter(&mut self, model: ToolSetter) {
        let inner = self.inner_mut();
        inner.physics.set_tool_setter(model);
        drive_input(inner, Input::ToolSetter, false);
    }

    /// Change the switch models (hysteresis and bounce) from now on; the
    /// usual way is [`crate::physics::MachineConfig::switches`] before start.
    pub fn set_switches(&mut self, switches: crate::physics::SwitchConfig) {
        self.inner_mut().physics.set_switches(switches);
    }

    /// Connect or disconnect the carousel home sensor.
    pub fn set_carousel_connected(&mut self, connected: bool) {
        let inner = self.inner_mut();
        inner.physics.set_carousel_connected(connected);
        drive_input(inner, Input::CarouselHome, false);
    }

    /// Turns the encoder by `detents` (positive = clockwise: A leads B), one
    /// full quadrature cycle per detent, `seconds_per_detent` each. Runs the VM.
    pub fn turn_encoder(&mut self, detents: i32, seconds_per_detent: f64) -> Result<(), VmError> {
        let quarter = seconds_per_detent / 4.0;
        let seq: [(bool, bool); 4] = [(true, false), (true, true), (false, true), (false, false)];
        for _ in 0..detents.unsigned_abs() {
            for k in 0..4 {
                let (a, b) = seq[k];
                let (a, b) = if detents > 0 { (a, b) } else { (b, a) };
                self.set_input(Input::EncoderA, Some(a));
                self.set_input(Input::EncoderB, Some(b));
                self.run_for(quarter)?;
            }
        }
        self.set_input(Input::EncoderA, None);
        self.set_input(Input::EncoderB, None);
        Ok(())
    }

    /// Presses the encoder button for `hold_s`, then releases it. Runs the VM.
    pub fn press_button(&mut self, hold_s: f64) -> Result<(), VmError> {
        self.set_input(Input::EncoderButton, Some(true));
        self.run_for(hold_s)?;
        self.set_input(Input::EncoderButton, None);
        Ok(())
    }
}
