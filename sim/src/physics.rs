//! The physical machine around the chip: where the axes really are, and what
//! the switches, the carousel sensor and the tool-setter beam therefore read.
//!
//! Positions come from the [`crate::recorder::Recorder`] (one update per
//! recorded step); this module turns them into *logical* input states
//! ("switch closed", "beam broken"). The VM glue turns those into pin levels
//! ([`crate::pins::Input::level`]) and drives them into simavr.
//!
//! Model (SPEC §12, machine defaults §3):
//! - Home switches X/Y/Z close when the axis' physical position is ≤ 0 steps,
//!   so homing trips exactly at machine 0. Z grows downward; its home is Z min.
//! - The carousel switch closes when `E mod steps_per_rev` is in
//!   `[0, switch_width)`; it can be configured as disconnected (never closes).
//! - The tool setter is a [`ToolSetter`] model: never, scripted, a beam at a Z
//!   height (optionally only inside an X/Y window), an [`OpticalBeam`] broken
//!   by the real geometry of the tool in the spindle, or any closure.
//! - The tool changer is a [`crate::atc::AtcModel`], stepped with every move.
//! - Encoder contacts and button have no model: they are idle (inactive)
//!   unless a test drives them.
//!
//! Every input can be overridden by a test; `None` hands it back to the model.

use crate::atc::{AtcConfig, AtcModel, Tool};
use crate::pins::{Axis, Input};
use std::sync::Arc;

/// Everything about the machine that is not the chip. Units are steps.
#[derive(Clone, Debug)]
pub struct MachineConfig {
    /// Steps per mm (X, Y, Z) and per carousel unit (E: steps per degree is
    /// `carousel.steps_per_rev / 360`; this entry is only used for display).
    pub steps_per_mm: [f64; 4],
    /// Travel per axis in steps (0..=travel); `None` = unlimited (E).
    pub travel_steps: [Option<i64>; 4],
    /// How far beyond 0 or beyond travel an axis may go before the recorder
    /// flags a crash, in steps (homing overshoots the switch a little).
    pub travel_margin_steps: [i64; 4],
    /// Physical position at power-on, in steps from each home switch.
    pub initial_position: [i64; 4],
    /// Bit per axis (bit 0 = X ... bit 3 = E): dir pin LOW means positive.
    pub invert_dir_mask: u8,
    /// The carousel and its home sensor.
    pub carousel: CarouselConfig,
    /// The optical tool setter.
    pub tool_setter: ToolSetter,
    /// The tool changer: pockets, spindle, station geometry.
    pub atc: AtcConfig,
}

impl Default for MachineConfig {
    fn default() -> Self {
        let mid = 2250; // 22.5 mm at 100 steps/mm
        MachineConfig {
            steps_per_mm: [100.0, 100.0, 100.0, 3200.0 / 360.0],
            travel_steps: [Some(4500), Some(4500), Some(4500), None],
            travel_margin_steps: [100, 100, 100, 0],
            initial_position: [mid, mid, mid, 0],
            invert_dir_mask: 0,
            carousel: CarouselConfig::default(),
            tool_setter: ToolSetter::Never,
            atc: AtcConfig::default(),
        }
    }
}

/// The carousel home sensor.
#[derive(Clone, Debug)]
pub struct CarouselConfig {
    /// E0 microsteps per carousel revolution (default 200 × 16).
    pub steps_per_rev: i64,
    /// The switch is closed for this many steps from 0° on (default 20).
    pub switch_width_steps: i64,
    /// `false` models a broken/unplugged sensor: it never closes.
    pub connected: bool,
}

impl Default for CarouselConfig {
    fn default() -> Self {
        CarouselConfig { steps_per_rev: 3200, switch_width_steps: 20, connected: true }
    }
}

/// A closure deciding the tool-setter state from the physical position.
pub type SetterFn = Arc<dyn Fn(&[i64; 4]) -> bool + Send + Sync>;

/// How the tool-setter beam state is decided.
#[derive(Clone, Default)]
pub enum ToolSetter {
    /// The beam is never interrupted.
    #[default]
    Never,
    /// A fixed state, set by the test.
    Scripted(bool),
    /// A beam at a Z height: interrupted while Z ≥ `z_trip_steps` (Z grows
    /// downward, so the tool tip reaches the beam from above), optionally only
    /// while X and Y are inside the given inclusive windows.
    Beam {
        z_trip_steps: i64,
        x_window: Option<(i64, i64)>,
        y_window: Option<(i64, i64)>,
    },
    /// An optical beam broken by the tool in the spindle (its length and
    /// diameter), see [`OpticalBeam`].
    Optical(OpticalBeam),
    /// Any model of the position.
    Custom(SetterFn),
}

/// A light beam along X at height `z_mm` (as a tool-tip Z: the spindle Z
/// plus the tool length; Z grows downward) and at `y_mm`, `width_mm` wide,
/// between the setter's arms `x_mm.0..=x_mm.1`. It breaks when the tool's tip
/// is at or below the beam and the tool's side reaches it:
/// |Y − y| ≤ (diameter + width)/2. With an empty spindle the bare nose is a
/// point at the gauge line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpticalBeam {
    pub x_mm: (f64, f64),
    pub y_mm: f64,
    pub z_mm: f64,
    pub width_mm: f64,
    /// Steps per mm of X, Y, Z.
    pub steps_per_mm: f64,
}

impl OpticalBeam {
    /// Is the beam broken with the spindle at `pos` (steps) holding `tool`?
    pub fn broken(&self, pos: &[i64; 4], tool: Option<&Tool>) -> bool {
        let k = self.steps_per_mm;
        let (len, d) = tool.map_or((0.0, 0.0), |t| (t.length_mm, t.diameter_mm));
        let x = pos[0] as f64 / k;
        let tip = pos[2] as f64 + len * k;
        let side = (pos[1] as f64 - self.y_mm * k).abs() <= (d + self.width_mm) / 2.0 * k;
        x >= self.x_mm.0 && x <= self.x_mm.1 && tip >= self.z_mm * k && side
    }
}

impl std::fmt::Debug for ToolSetter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ToolSetter::Never => write!(f, "Never"),
            ToolSetter::Scripted(b) => write!(f, "Scripted({b})"),
            ToolSetter::Beam { z_trip_steps, x_window, y_window } => {
                write!(f, "Beam {{ z_trip_steps: {z_trip_steps}, x_window: {x_window:?}, y_window: {y_window:?} }}")
            }
            ToolSetter::Optical(b) => write!(f, "{b:?}"),
            ToolSetter::Custom(_) => write!(f, "Custom(..)"),
        }
    }
}

impl ToolSetter {
    /// Is the beam interrupted with the machine at `pos`?
    pub fn triggered(&self, pos: &[i64; 4]) -> bool {
        match self {
            ToolSetter::Never => false,
            ToolSetter::Scripted(b) => *b,
            ToolSetter::Beam { z_trip_steps, x_window, y_window } => {
                let inside = |w: &Option<(i64, i64)>, v: i64| w.map_or(true, |(lo, hi)| v >= lo && v <= hi);
                pos[2] >= *z_trip_steps && inside(x_window, pos[0]) && inside(y_window, pos[1])
            }
            ToolSetter::Optical(b) => b.broken(pos, None),
            ToolSetter::Custom(f) => f(pos),
        }
    }
}

/// The machine model: logical input states from positions plus test overrides.
#[derive(Clone, Debug)]
pub struct Physics {
    config: MachineConfig,
    overrides: [Option<bool>; Input::COUNT],
    atc: AtcModel,
}

impl Physics {
    /// A machine with the given configuration and no overrides.
    pub fn new(config: MachineConfig) -> Physics {
        let atc = AtcModel::new(config.atc.clone(), &config.initial_position);
        Physics { config, overrides: [None; Input::COUNT], atc }
    }

    /// The configuration.
    pub fn config(&self) -> &MachineConfig {
        &self.config
    }

    /// The tool changer's physical state.
    pub fn atc(&self) -> &AtcModel {
        &self.atc
    }

    /// The tool changer, mutable (a test swaps or breaks a tool).
    pub fn atc_mut(&mut self) -> &mut AtcModel {
        &mut self.atc
    }

    /// The machine made one step on `axis` and is now at `pos`.
    pub fn on_step(&mut self, pos: &[i64; 4], axis: Axis) {
        self.atc.on_step(pos, axis.index());
    }

    /// Change the tool-setter model.
    pub fn set_tool_setter(&mut self, model: ToolSetter) {
        self.config.tool_setter = model;
    }

    /// Connect or disconnect the carousel sensor.
    pub fn set_carousel_connected(&mut self, connected: bool) {
        self.config.carousel.connected = connected;
    }

    /// Force an input active/inactive (`Some`) or hand it back to the model (`None`).
    pub fn set_override(&mut self, input: Input, active: Option<bool>) {
        self.overrides[input.index()] = active;
    }

    /// The current override of an input.
    pub fn override_of(&self, input: Input) -> Option<bool> {
        self.overrides[input.index()]
    }

    /// What the model alone says about `input` at `pos` (ignores overrides).
    pub fn model_active(&self, input: Input, pos: &[i64; 4]) -> bool {
        match input {
            Input::HomeX => pos[0] <= 0,
            Input::HomeY => pos[1] <= 0,
            Input::HomeZ => pos[2] <= 0,
            Input::CarouselHome => {
                let c = &self.config.carousel;
                c.connected && c.steps_per_rev > 0 && pos[3].rem_euclid(c.steps_per_rev) < c.switch_width_steps
            }
            Input::ToolSetter => match &self.config.tool_setter {
                ToolSetter::Optical(b) => b.broken(pos, self.atc.spindle.as_ref()),
                other => other.triggered(pos),
            },
            // No card unless the VM inserts one (it overrides SdDetect).
            Input::EncoderA | Input::EncoderB | Input::EncoderButton | Input::SdDetect => false,
        }
    }

    /// Logical state of `input` at `pos`: the override if any, else the model.
    pub fn active(&self, input: Input, pos: &[i64; 4]) -> bool {
        self.overrides[input.index()].unwrap_or_else(|| self.model_active(input, pos))
    }

    /// The inputs whose model depends on `axis`' position (checked after a step).
    pub fn inputs_moved_by(axis: Axis) -> &'static [Input] {
        match axis {
            Axis::X => &[Input::HomeX, Input::ToolSetter],
            Axis::Y => &[Input::HomeY, Input::ToolSetter],
            Axis::Z => &[Input::HomeZ, Input::ToolSetter],
            Axis::E => &[Input::CarouselHome, Input::ToolSetter],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn home_switch_closes_at_zero_and_below() {
        let p = Physics::new(MachineConfig::default());
        assert!(!p.active(Input::HomeX, &[1, 5, 5, 0]));
        assert!(p.active(Input::HomeX, &[0, 5, 5, 0]));
        assert!(p.active(Input::HomeX, &[-3, 5, 5, 0]));
        assert!(p.active(Input::HomeZ, &[5, 5, 0, 0]));
    }

    #[test]
    fn carousel_switch_is_a_window_per_revolution() {
        let mut p = Physics::new(MachineConfig::default());
        assert!(p.active(Input::CarouselHome, &[0, 0, 0, 0]));
        assert!(p.active(Input::CarouselHome, &[0, 0, 0, 19]));
        assert!(!p.active(Input::CarouselHome, &[0, 0, 0, 20]));
        assert!(p.active(Input::CarouselHome, &[0, 0, 0, 3205]));
        assert!(!p.active(Input::CarouselHome, &[0, 0, 0, -1]));
        assert!(p.active(Input::CarouselHome, &[0, 0, 0, -3200]));
        p.set_carousel_connected(false);
        assert!(!p.active(Input::CarouselHome, &[0, 0, 0, 0]));
    }

    #[test]
    fn override_wins_until_released() {
        let mut p = Physics::new(MachineConfig::default());
        p.set_override(Input::HomeY, Some(true));
        assert!(p.active(Input::HomeY, &[100, 100, 100, 0]));
        p.set_override(Input::HomeY, None);
        assert!(!p.active(Input::HomeY, &[100, 100, 100, 0]));
    }

    #[test]
    fn beam_trips_when_z_reaches_it_inside_window() {
        let mut p = Physics::new(MachineConfig::default());
        p.set_tool_setter(ToolSetter::Beam { z_trip_steps: 4000, x_window: Some((100, 200)), y_window: None });
        assert!(!p.active(Input::ToolSetter, &[150, 0, 3999, 0]));
        assert!(p.active(Input::ToolSetter, &[150, 0, 4000, 0]));
        assert!(!p.active(Input::ToolSetter, &[250, 0, 4000, 0]));
    }
}
