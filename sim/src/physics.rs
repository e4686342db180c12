//! The physical machine around the chip: where the axes really are, and what
//! the switches, the carousel sensor and the tool-setter beam therefore read.
//!
//! Positions come from the [`crate::recorder::Recorder`] (one update per
//! recorded step); this module turns them into *logical* input states
//! ("switch closed", "beam broken"). The VM glue turns those into pin levels
//! ([`crate::pins::Input::level`]) and drives them into simavr.
//!
//! Model (docs/SPEC.md §12, machine defaults §3):
//! - Home switches X/Y/Z close when the axis' physical position is ≤ 0 steps,
//!   so homing trips exactly at machine 0. Z grows downward; its home is Z min.
//! - Every switch is a *real* switch by default ([`SwitchConfig`]): once
//!   closed it opens again only when the axis is the hysteresis past its
//!   closing point, and each change of state is followed by a few ms of
//!   contact bounce (random toggles from a seeded RNG, so a run repeats; the
//!   first contact is exact, at the modelled step). The VM drives the bounce
//!   with a cycle timer ([`Physics::next_toggle`], [`Physics::fire_toggles`]).
//!   [`SwitchConfig::ideal`] gives the old perfect switches.
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
    /// Hysteresis and bounce of every switch.
    pub switches: SwitchConfig,
    /// Inputs wired the other way, bit per [`crate::Input::index`] (bit 0
    /// X home … bit 3 carousel home, bit 4 tool setter): a normally-closed
    /// switch holds its pin low until triggered (and a broken wire reads
    /// as triggered); a setter whose output is low when the beam is broken.
    pub inverted_inputs: u8,
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
            switches: SwitchConfig::default(),
            inverted_inputs: 0,
        }
    }
}

/// The imperfections of one switch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchModel {
    /// Once closed, the switch opens again only when the axis has moved this
    /// far past its closing point: mm (X, Y, Z; the tool setter on each of
    /// them), degrees for the carousel. Rounded down to whole steps.
    pub hysteresis: f64,
    /// After each change of state the contact bounces (toggles at random)
    /// for up to this long, seconds. 0: a clean edge.
    pub bounce_s: f64,
}

impl SwitchModel {
    /// A perfect switch: no hysteresis, no bounce.
    pub const IDEAL: SwitchModel = SwitchModel { hysteresis: 0.0, bounce_s: 0.0 };
}

/// Hysteresis and bounce of the machine's switches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchConfig {
    /// Home switches X, Y, Z (default: 0.05 mm, 3 ms of bounce).
    pub home: [SwitchModel; 3],
    /// Carousel home switch (default: 0.5°, 3 ms).
    pub carousel: SwitchModel,
    /// Optical tool setter (default: 0.01 mm, no bounce: an optical beam
    /// switches cleanly through its comparator).
    pub tool_setter: SwitchModel,
    /// Seed of the bounce RNG.
    pub seed: u64,
}

impl SwitchConfig {
    /// Default home-switch hysteresis, mm.
    pub const HOME_HYSTERESIS_MM: f64 = 0.05;
    /// Default bounce of the mechanical switches, s.
    pub const BOUNCE_S: f64 = 0.003;

    /// Perfect switches everywhere.
    pub fn ideal() -> SwitchConfig {
        SwitchConfig { home: [SwitchModel::IDEAL; 3], carousel: SwitchModel::IDEAL, tool_setter: SwitchModel::IDEAL, seed: 1 }
    }

    /// The default machine with every home switch set to `hysteresis_mm`
    /// and `bounce_s`.
    pub fn home_switches(hysteresis_mm: f64, bounce_s: f64) -> SwitchConfig {
        let m = SwitchModel { hysteresis: hysteresis_mm, bounce_s };
        SwitchConfig { home: [m; 3], ..SwitchConfig::default() }
    }

    /// The model of `input`, if it is a modelled switch.
    pub fn of(&self, input: Input) -> Option<SwitchModel> {
        match input {
            Input::HomeX => Some(self.home[0]),
            Input::HomeY => Some(self.home[1]),
            Input::HomeZ => Some(self.home[2]),
            Input::CarouselHome => Some(self.carousel),
            Input::ToolSetter => Some(self.tool_setter),
            _ => None,
        }
    }
}

impl Default for SwitchConfig {
    fn default() -> Self {
        let home = SwitchModel { hysteresis: Self::HOME_HYSTERESIS_MM, bounce_s: Self::BOUNCE_S };
        SwitchConfig {
            home: [home; 3],
            carousel: SwitchModel { hysteresis: 0.5, bounce_s: Self::BOUNCE_S },
            tool_setter: SwitchModel { hysteresis: 0.01, bounce_s: 0.0 },
            seed: 0x5eed_0001,
        }
    }
}

/// The state of one switch's contact.
#[derive(Clone, Debug, Default)]
struct Contact {
    /// The state after hysteresis (None until first sensed).
    settled: Option<bool>,
    /// What the contact shows now (differs from `settled` while bouncing).
    shown: bool,
    /// Cycles at which the contact toggles next (ascending).
    toggles: std::collections::VecDeque<u64>,
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
    Beam { z_trip_steps: i64, x_window: Option<(i64, i64)>, y_window: Option<(i64, i64)> },
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
    /// The demo machine's beam (`sim` CLI, `--pty`, the OctoPrint test): at
    /// the firmware's default setter position, X 3–7, Y 10, tip height 48 mm
    /// below the top switch, 0.52 mm wide, at 100 steps/mm.
    pub fn demo() -> OpticalBeam {
        OpticalBeam { x_mm: (3.0, 7.0), y_mm: 10.0, z_mm: 48.0, width_mm: 0.52, steps_per_mm: 100.0 }
    }

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
                let inside = |w: &Option<(i64, i64)>, v: i64| w.is_none_or(|(lo, hi)| v >= lo && v <= hi);
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
    contacts: [Contact; Input::COUNT],
    rng: fastrand::Rng,
    /// Clock for converting bounce times to cycles.
    clock_hz: f64,
    /// Transitions seen per input (closing and opening, bounce excluded).
    transitions: [u64; Input::COUNT],
}

impl Physics {
    /// A machine with the given configuration and no overrides.
    pub fn new(config: MachineConfig) -> Physics {
        let atc = AtcModel::new(config.atc.clone(), &config.initial_position);
        let rng = fastrand::Rng::with_seed(config.switches.seed);
        Physics {
            config,
            overrides: [None; Input::COUNT],
            atc,
            contacts: Default::default(),
            rng,
            clock_hz: 16e6,
            transitions: [0; Input::COUNT],
        }
    }

    /// The clock the bounce times are counted in (the VM's CPU clock).
    pub fn set_clock_hz(&mut self, hz: f64) {
        self.clock_hz = hz;
    }

    /// Change the switch models (hysteresis and bounce) from now on.
    pub fn set_switches(&mut self, switches: SwitchConfig) {
        self.config.switches = switches;
    }

    /// How many times `input` changed state (after hysteresis, bounce not
    /// counted) since power-on.
    pub fn transitions(&self, input: Input) -> u64 {
        self.transitions[input.index()]
    }

    /// The hysteresis of `input` in steps per axis (0 on axes it ignores).
    fn hysteresis_steps(&self, input: Input) -> [i64; 4] {
        let Some(m) = self.config.switches.of(input) else { return [0; 4] };
        let steps = |a: usize| (m.hysteresis * self.config.steps_per_mm[a] + 1e-9).floor().max(0.0) as i64;
        match input {
            Input::HomeX => [steps(0), 0, 0, 0],
            Input::HomeY => [0, steps(1), 0, 0],
            Input::HomeZ => [0, 0, steps(2), 0],
            Input::CarouselHome => [0, 0, 0, steps(3)],
            _ => [steps(0), steps(1), steps(2), 0],
        }
    }

    /// Is a closed switch held closed at `pos`: is the closing region within
    /// the hysteresis of `pos` along one of its axes?
    fn held(&self, input: Input, pos: &[i64; 4]) -> bool {
        if self.model_active(input, pos) {
            return true;
        }
        let h = self.hysteresis_steps(input);
        (0..4).filter(|&a| h[a] > 0).any(|a| {
            [-h[a], h[a]].iter().any(|&d| {
                let mut p = *pos;
                p[a] += d;
                self.model_active(input, &p)
            })
        })
    }

    /// Follow the switch on `input` to the machine at `pos` at cycle `now`:
    /// hysteresis decides the state, and a change starts a bounce. Returns
    /// the logical state the pin shows (the override if any).
    pub fn sense(&mut self, input: Input, pos: &[i64; 4], now: u64) -> bool {
        if let Some(model) = self.config.switches.of(input) {
            let settled = self.contacts[input.index()].settled;
            let new = match settled {
                None => Some(self.model_active(input, pos)),
                Some(false) if self.model_active(input, pos) => Some(true),
                Some(true) if !self.held(input, pos) => Some(false),
                _ => None,
            };
            if let Some(state) = new {
                let bounce = (model.bounce_s * self.clock_hz) as u64;
                let toggles = if settled.is_some() && bounce >= 8 {
                    self.transitions[input.index()] += 1;
                    // An even number of toggles spread over the bounce time,
                    // so the contact ends in the new state.
                    let n = 2 * self.rng.u64(1..=4);
                    let mut t = now;
                    (0..n)
                        .map(|_| {
                            t += self.rng.u64(1..=bounce / n);
                            t
                        })
                        .collect()
                } else {
                    if settled.is_some() {
                        self.transitions[input.index()] += 1;
                    }
                    Default::default()
                };
                self.contacts[input.index()] = Contact { settled: Some(state), shown: state, toggles };
            }
        }
        self.active(input, pos)
    }

    /// The earliest pending bounce toggle of any switch, in cycles.
    pub fn next_toggle(&self) -> Option<u64> {
        self.contacts.iter().filter_map(|c| c.toggles.front().copied()).min()
    }

    /// Apply every bounce toggle due at `now`; the inputs whose contact
    /// changed.
    pub fn fire_toggles(&mut self, now: u64) -> Vec<Input> {
        let mut changed = Vec::new();
        for input in Input::ALL {
            let c = &mut self.contacts[input.index()];
            let mut flipped = false;
            while c.toggles.front().is_some_and(|&t| t <= now) {
                c.toggles.pop_front();
                c.shown = !c.shown;
                flipped = !flipped;
            }
            if flipped {
                changed.push(input);
            }
        }
        changed
    }

    /// End every bounce at once (the chip was reset: its timers are gone).
    pub fn settle(&mut self) {
        for c in &mut self.contacts {
            c.toggles.clear();
            if let Some(s) = c.settled {
                c.shown = s;
            }
        }
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
        // Plugged or unplugged: the wire changes at once, no contact bounces.
        self.contacts[Input::CarouselHome.index()] = Contact::default();
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

    /// Logical state of `input` at `pos`: the override if any, else what its
    /// contact shows (hysteresis and bounce, once [`Physics::sense`] has
    /// followed it), else the model.
    pub fn active(&self, input: Input, pos: &[i64; 4]) -> bool {
        self.overrides[input.index()].unwrap_or_else(|| {
            let c = &self.contacts[input.index()];
            if c.settled.is_some() {
                c.shown
            } else {
                self.model_active(input, pos)
            }
        })
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
    fn home_switch_opens_only_past_its_hysteresis() {
        let mut c = MachineConfig::default();
        c.switches = SwitchConfig::home_switches(0.05, 0.0);
        let mut p = Physics::new(c);
        let at = |x: i64| [x, 5, 5, 0];
        assert!(!p.sense(Input::HomeX, &at(3), 0));
        assert!(!p.sense(Input::HomeX, &at(1), 0));
        assert!(p.sense(Input::HomeX, &at(0), 0), "closes exactly at 0");
        // 0.05 mm = 5 steps: still closed up to 5, open at 6.
        assert!(p.sense(Input::HomeX, &at(3), 0));
        assert!(p.sense(Input::HomeX, &at(5), 0));
        assert!(!p.sense(Input::HomeX, &at(6), 0));
        assert!(!p.sense(Input::HomeX, &at(1), 0));
        assert!(p.sense(Input::HomeX, &at(0), 0));
        assert_eq!(p.transitions(Input::HomeX), 3);
    }

    #[test]
    fn bounce_toggles_an_even_number_of_times_within_its_time_and_repeats_with_the_seed() {
        let run = |seed: u64| {
            let mut c = MachineConfig::default();
            c.switches = SwitchConfig { seed, ..SwitchConfig::home_switches(0.0, 0.003) };
            let mut p = Physics::new(c);
            p.sense(Input::HomeY, &[5, 5, 5, 0], 0);
            assert!(p.sense(Input::HomeY, &[5, 0, 5, 0], 1000), "first contact is exact");
            let mut times = Vec::new();
            while let Some(t) = p.next_toggle() {
                assert!(t > 1000 && t <= 1000 + 48_000, "within 3 ms at 16 MHz: {t}");
                assert_eq!(p.fire_toggles(t), vec![Input::HomeY]);
                times.push((t, p.active(Input::HomeY, &[5, 0, 5, 0])));
            }
            assert!(times.len() >= 2 && times.len() % 2 == 0);
            assert!(p.active(Input::HomeY, &[5, 0, 5, 0]), "ends closed");
            times
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }

    #[test]
    fn carousel_window_has_hysteresis_on_both_edges() {
        let mut c = MachineConfig::default();
        c.switches = SwitchConfig { carousel: SwitchModel { hysteresis: 0.5, bounce_s: 0.0 }, ..SwitchConfig::ideal() };
        let mut p = Physics::new(c);
        let e = |e: i64| [0, 0, 0, e];
        assert!(!p.sense(Input::CarouselHome, &e(-1), 0));
        assert!(p.sense(Input::CarouselHome, &e(0), 0));
        // 0.5° at 3200/360 steps per degree = 4 steps past the window's edges.
        assert!(p.sense(Input::CarouselHome, &e(-4), 0));
        assert!(!p.sense(Input::CarouselHome, &e(-5), 0));
        assert!(p.sense(Input::CarouselHome, &e(19), 0));
        assert!(p.sense(Input::CarouselHome, &e(23), 0));
        assert!(!p.sense(Input::CarouselHome, &e(24), 0));
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
