//! The RAMPS 1.4 pin table (docs/SPEC.md §2): the only place that knows ports.
//!
//! Each pin is named after its function and mapped to an AVR port and bit,
//! with its Arduino pin number beside it (ATmega2560 datasheet §13, "I/O
//! ports"; Arduino Mega2560 pin map). Data-space addresses of the port
//! registers are used directly in the stepper ISR, where one `out`/`sts`
//! to a PINx register toggles several step pins at once, atomically.
//!
//! Step pins sit on three ports (PF, PL, PA), so the ISR maps the Bresenham
//! step bits (bit 0 = X … bit 3 = E0) with [`port_bits`].

/// One of the AVR's I/O ports, by its register addresses in data space.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Port {
    /// PINx: reads the pins; writing 1s toggles PORTx bits.
    pub pin: *mut u8,
    /// DDRx: 1 = output.
    pub ddr: *mut u8,
    /// PORTx: output level, or pull-up for inputs.
    pub port: *mut u8,
}

// SAFETY: the addresses are fixed hardware registers; sharing them between
// contexts is coordinated by the functions that access them.
unsafe impl Sync for Port {}

/// A port pin: its port's PINx address and the bit mask. Three bytes, so
/// that a `Pin` passes in registers: a 7-byte one (the [`Port`] itself) went
/// by reference to a copy in RAM (`.data`), one for each pin and pin table used.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Pin {
    pin_addr: u16,
    pub mask: u8,
}

const fn port(pin_addr: u16) -> Port {
    let a = pin_addr as usize;
    Port { pin: a as *mut u8, ddr: (a + 1) as *mut u8, port: (a + 2) as *mut u8 }
}

/// The PINx address of each port in data space (DDRx and PORTx follow it).
mod addr {
    pub const A: u16 = 0x20;
    pub const B: u16 = 0x23;
    pub const C: u16 = 0x26;
    pub const D: u16 = 0x29;
    pub const E: u16 = 0x2C;
    pub const F: u16 = 0x2F;
    pub const H: u16 = 0x100;
    pub const J: u16 = 0x103;
    pub const K: u16 = 0x106;
    pub const L: u16 = 0x109;
}

pub const PA: Port = port(addr::A);
pub const PF: Port = port(addr::F);
pub const PL: Port = port(addr::L);
/// The step ports' PINx addresses, for the step interrupt's assembly.
pub const PA_PIN: u16 = addr::A;
pub const PF_PIN: u16 = addr::F;
pub const PL_PIN: u16 = addr::L;

const fn pin(pin_addr: u16, bit: u8) -> Pin {
    Pin { pin_addr, mask: 1 << bit }
}

// ---- Steppers (thesis Table 7) -------------------------------------------
/// D54, PF0
pub const X_STEP: Pin = pin(addr::F, 0);
/// D55, PF1
pub const X_DIR: Pin = pin(addr::F, 1);
/// D38, PD7, active low
pub const X_ENABLE: Pin = pin(addr::D, 7);
/// D60, PF6
pub const Y_STEP: Pin = pin(addr::F, 6);
/// D61, PF7
pub const Y_DIR: Pin = pin(addr::F, 7);
/// D56, PF2, active low
pub const Y_ENABLE: Pin = pin(addr::F, 2);
/// D46, PL3
pub const Z_STEP: Pin = pin(addr::L, 3);
/// D48, PL1
pub const Z_DIR: Pin = pin(addr::L, 1);
/// D62, PK0, active low
pub const Z_ENABLE: Pin = pin(addr::K, 0);
/// D26, PA4 (E0, the carousel)
pub const E_STEP: Pin = pin(addr::A, 4);
/// D28, PA6
pub const E_DIR: Pin = pin(addr::A, 6);
/// D24, PA2, active low
pub const E_ENABLE: Pin = pin(addr::A, 2);

// The pins are written out where they are used, not walked as tables
// (`[X_ENABLE, Y_ENABLE, …]`): a table of pins is a copy in RAM on AVR.

// ---- Switches and sensors ------------------------------------------------
/// D3, PE5: X min. Closed switch pulls low.
pub const X_HOME: Pin = pin(addr::E, 5);
/// D14, PJ1: Y min.
pub const Y_HOME: Pin = pin(addr::J, 1);
/// D18, PD3: Z min (top; Z grows downward).
pub const Z_HOME: Pin = pin(addr::D, 3);
/// D2, PE4: carousel home (X_MAX header), closed at 0°.
pub const CAROUSEL_HOME: Pin = pin(addr::E, 4);
/// D19, PD2: optical tool setter (Z_MAX header); high = beam interrupted.
pub const TOOL_SETTER: Pin = pin(addr::D, 2);

// ---- Spindle, UI, buses --------------------------------------------------
/// D10, PB4 = OC2A: spindle PWM (thesis: DC spindle on D10).
pub const SPINDLE_PWM: Pin = pin(addr::B, 4);
/// D9, PH6: coolant (M7/M8 on, M9 off), the RAMPS D9 MOSFET output
/// (the fan/second-extruder-heater output); high = on.
pub const COOLANT: Pin = pin(addr::H, 6);
/// D31, PC6: encoder A (AUX-4).
pub const ENC_A: Pin = pin(addr::C, 6);
/// D33, PC4: encoder B.
pub const ENC_B: Pin = pin(addr::C, 4);
/// D35, PC2: encoder button.
pub const ENC_BUTTON: Pin = pin(addr::C, 2);
/// D53, PB0: SD card chip select (SPI SS).
pub const SD_SS: Pin = pin(addr::B, 0);
/// D49, PL0: SD card detect.
pub const SD_DETECT: Pin = pin(addr::L, 0);
// SDA D20 = PD1, SCL D21 = PD0 (TWI), SCK D52 = PB1, MOSI D51 = PB2,
// MISO D50 = PB3 (SPI): owned by the TWI and SPI drivers.
// Host serial: USART0 on D0 = PE0 (RX), D1 = PE1 (TX).

/// The stepper ISR's view of the step and direction pins (docs/SPEC.md §2): the step
/// pins of X and Y sit on PF, Z on PL, E0 on PA, at bits that do not overlap,
/// so one byte holds the step outputs of all four axes and `byte & STEP_PF`
/// (…`STEP_PL`, `STEP_PA`) is what to write to each port's PINx register.
/// Direction pins: port 0 = PF, 1 = PL, 2 = PA.
pub const STEP_MAP: mill::stepper::queue::StepMap = mill::stepper::queue::StepMap {
    step: [X_STEP.mask, Y_STEP.mask, Z_STEP.mask, E_STEP.mask],
    dir: [(0, X_DIR.mask), (0, Y_DIR.mask), (1, Z_DIR.mask), (2, E_DIR.mask)],
};
/// Step pins on PF (X, Y).
pub const STEP_PF: u8 = X_STEP.mask | Y_STEP.mask;
/// Step pin on PL (Z).
pub const STEP_PL: u8 = Z_STEP.mask;
/// Step pin on PA (E0).
pub const STEP_PA: u8 = E_STEP.mask;
/// Direction pins on PF, PL, PA.
pub const DIR_PF: u8 = X_DIR.mask | Y_DIR.mask;
pub const DIR_PL: u8 = Z_DIR.mask;
pub const DIR_PA: u8 = E_DIR.mask;

const _: () = {
    assert!(X_STEP.mask & Y_STEP.mask == 0);
    assert!(STEP_PF & STEP_PL == 0 && STEP_PF & STEP_PA == 0 && STEP_PL & STEP_PA == 0);
};

/// Home switches closed now, as axis bits (bit 0 = X … bit 2 = Z). A closed
/// switch pulls its pin low.
// speed: the step ISR reads it; out of line it became a call there
#[inline(always)]
pub fn home_closed() -> u8 {
    let mut b = 0;
    if !X_HOME.is_high() {
        b |= 1;
    }
    if !Y_HOME.is_high() {
        b |= 2;
    }
    if !Z_HOME.is_high() {
        b |= 4;
    }
    b
}

impl Pin {
    /// The pin's port registers.
    pub const fn port(self) -> Port {
        port(self.pin_addr)
    }

    /// Data-space address of the pin's PINx register.
    pub const fn pin_addr(self) -> u16 {
        self.pin_addr
    }

    /// Read the pin level.
    pub fn is_high(self) -> bool {
        // SAFETY: reading a PINx register has no side effects.
        unsafe { core::ptr::read_volatile(self.port().pin) & self.mask != 0 }
    }

    /// Make the pin an output at `high`. Read-modify-write: call with
    /// interrupts disabled if an ISR writes the same port (see [`Pin::set`]).
    pub fn make_output(self, high: bool) {
        self.set(high);
        avr_device::interrupt::free(|_| {
            // SAFETY: RMW of DDRx inside a critical section.
            unsafe {
                let v = core::ptr::read_volatile(self.port().ddr);
                core::ptr::write_volatile(self.port().ddr, v | self.mask);
            }
        });
    }

    /// Make the pin an input with the pull-up on.
    pub fn make_input_pullup(self) {
        avr_device::interrupt::free(|_| {
            // SAFETY: RMW of DDRx/PORTx inside a critical section.
            unsafe {
                let d = core::ptr::read_volatile(self.port().ddr);
                core::ptr::write_volatile(self.port().ddr, d & !self.mask);
                let p = core::ptr::read_volatile(self.port().port);
                core::ptr::write_volatile(self.port().port, p | self.mask);
            }
        });
    }

    /// Drive an output pin. The read-modify-write of PORTx happens in a
    /// critical section, because the stepper ISR toggles pins on PF, PL, PA.
    // speed: left to LLVM, tools/bench's ping-pong stream took 5.756 s, not 5.739
    #[inline(always)]
    pub fn set(self, high: bool) {
        avr_device::interrupt::free(|_| {
            // SAFETY: RMW of PORTx inside a critical section.
            unsafe {
                let v = core::ptr::read_volatile(self.port().port);
                let v = if high { v | self.mask } else { v & !self.mask };
                core::ptr::write_volatile(self.port().port, v);
            }
        });
    }
}
