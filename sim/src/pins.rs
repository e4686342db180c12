//! The RAMPS 1.4 pin map as the virtual machine sees it (docs/SPEC.md §2).
//!
//! This is the sim's copy of the firmware's `board` pin table: the only place
//! in `sim/` that knows which AVR port bit is which machine signal. The
//! recorder (outputs) and the physics model (inputs) refer to pins only
//! through [`Axis`], [`SignalKind`] and [`Input`].

use serde::Serialize;

/// One AVR port pin, e.g. `PF0` is `Pin { port: b'F', bit: 0 }`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Pin {
    /// Port letter, upper case (`b'A'`..=`b'L'`).
    pub port: u8,
    /// Bit 0..=7.
    pub bit: u8,
}

impl Pin {
    /// `Pin::new(b'F', 0)` is PF0.
    pub const fn new(port: u8, bit: u8) -> Pin {
        Pin { port, bit }
    }

    /// Data-space address of the PINx register of this port on the ATmega2560.
    pub const fn pin_reg(self) -> u16 {
        port_regs(self.port).0
    }

    /// Data-space address of the DDRx register.
    pub const fn ddr_reg(self) -> u16 {
        port_regs(self.port).1
    }

    /// Data-space address of the PORTx register.
    pub const fn port_reg(self) -> u16 {
        port_regs(self.port).2
    }
}

impl std::fmt::Display for Pin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "P{}{}", self.port as char, self.bit)
    }
}

/// (PINx, DDRx, PORTx) data-space addresses on the ATmega2560 (datasheet §33,
/// register summary). Ports A–G sit in the low I/O space, H–L in extended I/O.
pub const fn port_regs(port: u8) -> (u16, u16, u16) {
    match port {
        b'A' => (0x20, 0x21, 0x22),
        b'B' => (0x23, 0x24, 0x25),
        b'C' => (0x26, 0x27, 0x28),
        b'D' => (0x29, 0x2A, 0x2B),
        b'E' => (0x2C, 0x2D, 0x2E),
        b'F' => (0x2F, 0x30, 0x31),
        b'G' => (0x32, 0x33, 0x34),
        b'H' => (0x100, 0x101, 0x102),
        b'J' => (0x103, 0x104, 0x105),
        b'K' => (0x106, 0x107, 0x108),
        b'L' => (0x109, 0x10A, 0x10B),
        _ => (0, 0, 0),
    }
}

/// A stepper axis. `E` is the E0 driver, which turns the tool carousel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Axis {
    X = 0,
    Y = 1,
    Z = 2,
    E = 3,
}

impl Axis {
    /// All four axes in index order.
    pub const ALL: [Axis; 4] = [Axis::X, Axis::Y, Axis::Z, Axis::E];

    /// 0..=3.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Inverse of [`Axis::index`].
    pub const fn from_index(i: usize) -> Axis {
        match i {
            0 => Axis::X,
            1 => Axis::Y,
            2 => Axis::Z,
            _ => Axis::E,
        }
    }

    /// "X", "Y", "Z" or "E".
    pub const fn name(self) -> &'static str {
        match self {
            Axis::X => "X",
            Axis::Y => "Y",
            Axis::Z => "Z",
            Axis::E => "E",
        }
    }

    /// The step/dir/enable pins of this axis' driver.
    pub const fn pins(self) -> DriverPins {
        DRIVERS[self as usize]
    }
}

impl std::fmt::Display for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which of a driver's three inputs a pin is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum SignalKind {
    /// Rising edge = one microstep.
    Step,
    /// High = positive direction (unless inverted in the machine config).
    Dir,
    /// Active low: high = driver disabled.
    Enable,
}

/// The three control pins of one DRV8825.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriverPins {
    pub step: Pin,
    pub dir: Pin,
    pub enable: Pin,
}

/// Which pin is which signal: the drivers' step/dir/enable, and each input
/// (`None`: not wired). [`PinMap::RAMPS`] is the mill's board; the
/// [`PinMap::GRBL_MEGA`] preset runs the real grbl-Mega for side-by-side
/// tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PinMap {
    pub drivers: [DriverPins; 4],
    pub inputs: [Option<Pin>; Input::COUNT],
}

impl PinMap {
    /// RAMPS 1.4 (docs/SPEC.md §2): [`DRIVERS`] and [`Input::pin`].
    pub const RAMPS: PinMap = PinMap {
        drivers: DRIVERS,
        inputs: [
            Some(Input::HomeX.pin()),
            Some(Input::HomeY.pin()),
            Some(Input::HomeZ.pin()),
            Some(Input::CarouselHome.pin()),
            Some(Input::ToolSetter.pin()),
            Some(Input::EncoderA.pin()),
            Some(Input::EncoderB.pin()),
            Some(Input::EncoderButton.pin()),
            Some(Input::SdDetect.pin()),
        ],
    };

    /// grbl-Mega 1.1g's `CPU_MAP_2560_INITIAL` (its `cpu_map.h`): steps on
    /// PA2/PA3/PA4 (D24–D26), directions on PC7/PC6/PC5 (D30–D32, high =
    /// toward negative: `MachineConfig::invert_dir_mask`), one disable pin
    /// for all drivers on PB7 (D13), limits on PB4/PB5/PB6 (D10–D12), the
    /// probe on PK7 (A15, as the tool setter's input). No carousel (its
    /// driver on PG3/PG4, which grbl never drives), no encoder, no card.
    pub const GRBL_MEGA: PinMap = PinMap {
        drivers: [
            DriverPins { step: Pin::new(b'A', 2), dir: Pin::new(b'C', 7), enable: Pin::new(b'B', 7) },
            DriverPins { step: Pin::new(b'A', 3), dir: Pin::new(b'C', 6), enable: Pin::new(b'B', 7) },
            DriverPins { step: Pin::new(b'A', 4), dir: Pin::new(b'C', 5), enable: Pin::new(b'B', 7) },
            DriverPins { step: Pin::new(b'G', 3), dir: Pin::new(b'G', 4), enable: Pin::new(b'B', 7) },
        ],
        inputs: [
            Some(Pin::new(b'B', 4)),
            Some(Pin::new(b'B', 5)),
            Some(Pin::new(b'B', 6)),
            None,
            Some(Pin::new(b'K', 7)),
            None,
            None,
            None,
            None,
        ],
    };

    /// The pin of `input`, if it is wired.
    pub const fn input(&self, input: Input) -> Option<Pin> {
        self.inputs[input.index()]
    }
}

impl Default for PinMap {
    fn default() -> Self {
        PinMap::RAMPS
    }
}

/// RAMPS 1.4 driver pins, indexed by [`Axis::index`] (docs/SPEC.md §2, thesis Table 7).
pub const DRIVERS: [DriverPins; 4] = [
    DriverPins { step: Pin::new(b'F', 0), dir: Pin::new(b'F', 1), enable: Pin::new(b'D', 7) },
    DriverPins { step: Pin::new(b'F', 6), dir: Pin::new(b'F', 7), enable: Pin::new(b'F', 2) },
    DriverPins { step: Pin::new(b'L', 3), dir: Pin::new(b'L', 1), enable: Pin::new(b'K', 0) },
    DriverPins { step: Pin::new(b'A', 4), dir: Pin::new(b'A', 6), enable: Pin::new(b'A', 2) },
];

/// Spindle PWM output: D10 = PB4 = OC2A.
pub const SPINDLE_PWM: Pin = Pin::new(b'B', 4);

/// Coolant output (M7/M8 on, M9 off): D9 = PH6, the RAMPS D9 MOSFET; high = on.
pub const COOLANT: Pin = Pin::new(b'H', 6);

/// A machine input the firmware reads.
///
/// "Active" means: switch closed, beam interrupted, button pressed, encoder
/// contact closed. The electrical level that corresponds to "active" is given
/// by [`Input::active_level`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Input {
    HomeX,
    HomeY,
    HomeZ,
    CarouselHome,
    ToolSetter,
    EncoderA,
    EncoderB,
    EncoderButton,
    /// SD card detect switch (D49, PL0): closed to ground while a card is in.
    SdDetect,
}

impl Input {
    /// Number of inputs.
    pub const COUNT: usize = 9;

    /// Every input, in a fixed order (also the index order).
    pub const ALL: [Input; Input::COUNT] = [
        Input::HomeX,
        Input::HomeY,
        Input::HomeZ,
        Input::CarouselHome,
        Input::ToolSetter,
        Input::EncoderA,
        Input::EncoderB,
        Input::EncoderButton,
        Input::SdDetect,
    ];

    /// Position in [`Input::ALL`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The AVR pin this input is wired to (docs/SPEC.md §2).
    pub const fn pin(self) -> Pin {
        match self {
            Input::HomeX => Pin::new(b'E', 5),
            Input::HomeY => Pin::new(b'J', 1),
            Input::HomeZ => Pin::new(b'D', 3),
            Input::CarouselHome => Pin::new(b'E', 4),
            Input::ToolSetter => Pin::new(b'D', 2),
            Input::EncoderA => Pin::new(b'C', 6),
            Input::EncoderB => Pin::new(b'C', 4),
            Input::EncoderButton => Pin::new(b'C', 2),
            Input::SdDetect => Pin::new(b'L', 0),
        }
    }

    /// Electrical level when the input is active.
    ///
    /// Switches, button and encoder contacts close to ground against the
    /// firmware's pull-ups (active = LOW); the optical tool setter drives HIGH
    /// when its beam is interrupted.
    pub const fn active_level(self) -> bool {
        matches!(self, Input::ToolSetter)
    }

    /// Electrical level for a logical state.
    pub const fn level(self, active: bool) -> bool {
        active == self.active_level()
    }

    /// The home switch of an axis, if it has one.
    pub const fn home_of(axis: Axis) -> Option<Input> {
        match axis {
            Axis::X => Some(Input::HomeX),
            Axis::Y => Some(Input::HomeY),
            Axis::Z => Some(Input::HomeZ),
            Axis::E => Some(Input::CarouselHome),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn driver_table_matches_spec() {
        assert_eq!(Axis::X.pins().step.to_string(), "PF0");
        assert_eq!(Axis::Y.pins().enable.to_string(), "PF2");
        assert_eq!(Axis::Z.pins().dir.to_string(), "PL1");
        assert_eq!(Axis::E.pins().step.to_string(), "PA4");
        for i in Input::ALL {
            assert_eq!(PinMap::RAMPS.input(i), Some(i.pin()));
        }
        // The preset's outputs and inputs never share a pin.
        let g = PinMap::GRBL_MEGA;
        for d in g.drivers {
            for p in [d.step, d.dir] {
                assert!(!g.inputs.contains(&Some(p)), "{p}");
            }
        }
        assert_eq!(Pin::new(b'L', 3).port_reg(), 0x10B);
        assert_eq!(Pin::new(b'F', 0).pin_reg(), 0x2F);
    }

    #[test]
    fn switch_polarity_is_active_low_except_tool_setter() {
        assert!(!Input::HomeX.level(true));
        assert!(Input::HomeX.level(false));
        assert!(Input::ToolSetter.level(true));
        assert!(!Input::ToolSetter.level(false));
    }
}
