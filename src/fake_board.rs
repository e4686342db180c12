//! A fake board for host tests of the controller: the
//! [`Io`] the firmware implements over `board`, with time, a stepper that
//! steps, switches that follow the axes, EEPROM in memory and outputs that
//! are recorded.
//!
//! Where it sits: it replaces `src/firmware.rs` + `src/board` under
//! [`Machine`](crate::machine::Machine) in `cargo test`, so that homing, a
//! tool change, G37, alarms and feed holds run on the host (see
//! `machine/tests.rs`) with no simulator. It is the one host fake: the
//! gcode tests (`gcode/interp/tests.rs`, `gcode/tests.rs`) run their
//! lines on it too and read the path of block end points it records
//! ([`FakeBoard::path`]).
//!
//! ```text
//!  Machine ─ Stepper::push_segment ─► stepper::rings::Rings (the board's own
//!                                 bookkeeping) ─► Chunk / Seg ring arrays
//!        ◄─ Inputs::poll ─ clock += poll_cycles ─► timer ISR twin (one event per period):
//!                      output `pending`, check armed switches, load a segment,
//!                      Chunk::tick_out ─► physical and counted positions, step log
//! ```
//!
//! What is the same as the firmware: the main-loop side of the rings is the
//! board's own code, [`Rings`] (the splitter with the board's watch list,
//! heads and free slots, the 40 ms cap of queued motion, retiring, the
//! position from the chunks, `set_position`, the trip latch, `clear`), over
//! ring arrays of the board's sizes; the ISR's arithmetic (`Chunk::tick_out`,
//! the twin of its assembly), the order of the ISR's work (`board::stepper`'s
//! `TIMER1_COMPA`: output the step computed last time, check the switches if
//! armed, load a segment, compute the next step), its period (OCR1A ×
//! prescaler CPU cycles, 1 kHz idle), what `clear_stop` resets, and the realtime requests
//! (`firmware.rs`'s `poll`; M112 and Ctrl-X halt the stepper at once, as the
//! RX interrupt does).
//!
//! What is a model: time passes only in [`Inputs::poll`] ([`FakeBoard::poll_cycles`]
//! CPU cycles each, 250 µs by default: one main-loop turn), the switches
//! (home switches close at or below a settable physical position, with
//! optional hysteresis; the carousel switch is a window per revolution; the
//! tool-setter beam is broken by the tip of the tool the test says is in the
//! spindle), and scripted events (`!`, `~`, `?`, M112, Ctrl-X, a switch
//! forced) at a time or at a step count.
//!
//! Positions: `phys` is where the motors really are (steps from where each
//! home switch closes), `pos` is the firmware's counted position (moved by
//! [`Stepper::set_stepper_position`]). The board counts no steps: [`Rings`]
//! rebuilds the position from the splitter's plan, the queued chunks and
//! `Chunk::steps_done` of the running one
//! ([`FakeBoard::reconstructed_position`]); the fake counts them as well,
//! and after every timer event that steps, and on every
//! [`Stepper::stepper`], it asserts that the two agree (and that the
//! latched trip position is where the ISR stopped), so every controller
//! test also checks the board's bookkeeping.

use crate::machine::{Host, Inputs, Outputs, Realtime, Stepper, StepperStatus, Storage, Switches};
use crate::stepper::queue::{Seg, StepMap};
use crate::stepper::rings::host::Statics;
use crate::stepper::rings::Rings;
pub use crate::stepper::rings::Watch;
use crate::stepper::StepperCmd;
use crate::N_AXES;
use core::cell::RefCell;
use core::convert::Infallible;
/// Timer period while idle, CPU cycles (1 kHz, as the board).
const IDLE_PERIOD: u64 = 16_000;
/// CPU cycles per millisecond.
const CYCLES_PER_MS: u64 = crate::F_CPU_HZ as u64 / 1000;

/// Step-output bits = axis bits here (the board maps them to pins).
const MAP: StepMap = StepMap { step: [1, 2, 4, 8], dir: [(0, 1), (0, 2), (0, 4), (0, 8)] };

/// An input a test can force.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// Home switch of axis 0..=2 (X, Y, Z).
    Home(usize),
    CarouselHome,
    ToolSetter,
}

/// What happens at a scripted moment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// `?` received.
    Status,
    /// `!` received (feed hold).
    Hold,
    /// `~` received (resume).
    Resume,
    /// M112 seen by the RX interrupt: stepper halted, drivers, spindle and coolant off at once.
    Estop,
    /// Ctrl-X: the stepper halts at once; the main loop resets.
    Reset,
    /// An abort from the menu / SD job.
    Abort,
    /// Force an input closed/open (`Some`) or give it back to the model (`None`).
    Force(Input, Option<bool>),
    /// A grbl realtime override byte (0x90–0xA1) received.
    Override(u8),
}

/// When a scripted event happens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum At {
    /// At this clock time, ms since boot (checked at every timer event and poll).
    Ms(u32),
    /// Right after the `n`-th output step (all axes counted; 1-based).
    Step(u64),
}

/// One output step event of the ISR twin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Step {
    /// CPU cycle of the timer interrupt that output it.
    pub cycle: u64,
    /// Axes that stepped (bit i = axis i).
    pub axes: u8,
    /// Axes of `axes` that moved negative.
    pub neg: u8,
    /// Physical position after the step.
    pub phys: [i64; N_AXES],
}

/// A tool in the spindle, as the tool-setter beam sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    pub length_mm: f64,
    pub diameter_mm: f64,
}

/// A light beam along X (sim's `OpticalBeam`): broken when the tool tip
/// (spindle Z + length, Z grows downward) is at or below `z_mm`, X within
/// `x_mm` and the tool's side within the beam: |Y − y| ≤ (d + width)/2.
/// Physical mm from the home switches, at `steps_per_mm` (X, Y, Z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beam {
    pub x_mm: (f64, f64),
    pub y_mm: f64,
    pub z_mm: f64,
    pub width_mm: f64,
    pub steps_per_mm: f64,
}

impl Beam {
    /// Broken with the spindle at `phys` holding `tool` (`None`: the bare nose, a point).
    pub fn broken(&self, phys: &[i64; N_AXES], tool: Option<Tool>) -> bool {
        let k = self.steps_per_mm;
        let (len, d) = tool.map_or((0.0, 0.0), |t| (t.length_mm, t.diameter_mm));
        let x = phys[0] as f64 / k;
        let tip = phys[2] as f64 + len * k;
        let side = (phys[1] as f64 - self.y_mm * k).abs() <= (d + self.width_mm) / 2.0 * k;
        x >= self.x_mm.0 && x <= self.x_mm.1 && tip >= self.z_mm * k && side
    }
}

/// An output change, with the CPU cycle it happened at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    Spindle(u8),
    Coolant(bool),
    Drivers(bool),
    CarouselDriver(bool),
}

/// The fake board. Fields are public: tests read and set them directly.
pub struct FakeBoard {
    /// Everything the firmware printed.
    pub out: String,
    /// CPU cycles since boot (16 MHz).
    pub cycles: u64,
    /// Cycles each [`Inputs::poll`] lets pass (one main-loop turn).
    pub poll_cycles: u64,
    /// Polls so far.
    pub polls: u64,
    /// More polls than this panic: a controller stuck in a wait loop fails
    /// its test instead of hanging it (default 2 000 000: 500 s of machine time).
    pub poll_limit: u64,
    /// Next timer interrupt, and the timer period now (CPU cycles).
    next_isr: u64,
    period: u64,

    /// The rings and the ISR's state.
    st: Statics,
    /// The board's main-loop bookkeeping (`board::stepper::MAIN`); in a
    /// cell because `Stepper::stepper` and `Stepper::segment_space` take `&self`.
    rings: RefCell<Rings>,
    /// A segment was loaded since the ring was last found empty.
    running: bool,
    /// Hard-limit axes of the running chunk.
    limit: u8,
    /// The ISR's copy of the watch (`homing`, `probe`).
    pub watch: Watch,
    /// The ISR is stopped (`motion::STOP`), and why.
    stopped: bool,
    home_tripped: bool,
    probe_tripped: bool,
    limit_hit: bool,
    /// Counted position where the ISR stopped at the last trip.
    trip: [i32; N_AXES],
    /// Times the ISR ran out of segments after running one (`MILL_STEP_UNDERRUNS`).
    pub underruns: u32,

    /// Counted position (the firmware's), steps.
    pub pos: [i32; N_AXES],
    /// Physical position: steps from where each home switch closes (E: from 0°).
    pub phys: [i64; N_AXES],
    /// Every output step, in order.
    pub steps: Vec<Step>,
    /// The counted position at the end of each planner block, in the order
    /// the blocks were handed to the board (one per chord of an arc), and
    /// the millisecond each was handed over: the path the gcode tests check.
    pub path: Vec<[i32; N_AXES]>,
    pub path_ms: Vec<u32>,
    /// Where the last block handed over ends (counted steps).
    block_end: [i32; N_AXES],

    /// Physical position at which each home switch closes (closed at or below it).
    pub home_at: [i64; 3],
    /// Home-switch hysteresis, steps: once closed it opens only above `home_at + hysteresis`.
    pub hysteresis: [i64; 3],
    /// Home switch contacts now (after hysteresis).
    home_closed: [bool; 3],
    /// Closing and opening count per home switch.
    pub transitions: [u32; 3],
    /// Carousel: E steps per revolution and the width of the switch window from 0°.
    pub carousel_steps_per_rev: i64,
    pub carousel_width_steps: i64,
    /// False: the carousel sensor is unplugged (never closes).
    pub carousel_connected: bool,
    /// The tool-setter beam (`None`: never broken).
    pub beam: Option<Beam>,
    /// The tool in the spindle as the beam sees it.
    pub tool: Option<Tool>,
    /// Forced inputs: home X Y Z, carousel, tool setter.
    forced: [Option<bool>; 5],

    /// 4 KiB of EEPROM, blank (0xFF).
    pub eeprom: Vec<u8>,
    /// Every `eeprom_write` that changed a byte (the board programs only
    /// those): the output steps made before it, its address and data, in order.
    pub eeprom_log: Vec<(u64, u16, Vec<u8>)>,

    pub spindle: u8,
    pub coolant: bool,
    pub drivers: bool,
    pub carousel_driver: bool,
    /// Every output change, with its cycle.
    pub outputs: Vec<(u64, Output)>,

    /// Every poll reports `~` (resume): M0/M1 pauses end at once.
    pub auto_resume: bool,
    /// Scripted events not yet fired.
    script: Vec<(At, Event)>,
    /// Realtime requests collected since the last poll.
    rt: Realtime,
}

/// CPU cycles between the step events of `s`.
fn seg_period(s: &Seg) -> u64 {
    let div = if s.tccr & 0x07 == 1 { 1 } else { 8 };
    s.period as u64 * div
}

impl Default for FakeBoard {
    fn default() -> Self {
        Self::new()
    }
}

impl FakeBoard {
    /// Ideal switches at physical 0, the motors at 22.5 mm from every switch
    /// (the sim's default machine), carousel at 0°, blank EEPROM.
    pub fn new() -> FakeBoard {
        let mut b = FakeBoard {
            out: String::new(),
            cycles: 0,
            poll_cycles: 4_000,
            polls: 0,
            poll_limit: 2_000_000,
            next_isr: IDLE_PERIOD,
            period: IDLE_PERIOD,
            st: Statics::new(),
            rings: RefCell::new(Rings::new()),
            running: false,
            limit: 0,
            watch: Watch::default(),
            stopped: false,
            home_tripped: false,
            probe_tripped: false,
            limit_hit: false,
            trip: [0; N_AXES],
            underruns: 0,
            pos: [0; N_AXES],
            phys: [2250, 2250, 2250, 0],
            steps: Vec::new(),
            path: Vec::new(),
            path_ms: Vec::new(),
            block_end: [0; N_AXES],
            home_at: [0; 3],
            hysteresis: [0; 3],
            home_closed: [false; 3],
            transitions: [0; 3],
            carousel_steps_per_rev: 3200,
            carousel_width_steps: 20,
            carousel_connected: true,
            beam: None,
            tool: None,
            forced: [None; 5],
            eeprom: vec![0xFF; 4096],
            eeprom_log: Vec::new(),
            spindle: 0,
            coolant: false,
            drivers: false,
            carousel_driver: false,
            outputs: Vec::new(),
            auto_resume: false,
            script: Vec::new(),
            rt: Realtime::default(),
        };
        b.settle_switches();
        b
    }

    /// Put the motors at `phys` (power-on position; the counted position is not touched).
    pub fn place(&mut self, phys: [i64; N_AXES]) {
        self.phys = phys;
        self.settle_switches();
    }

    /// Re-read the home switches from the position, forgetting their
    /// hysteresis state (after the test changed `phys`, `home_at` or `hysteresis`).
    pub fn settle_switches(&mut self) {
        for a in 0..3 {
            self.home_closed[a] = self.phys[a] <= self.home_at[a];
        }
    }

    /// Script `ev` to happen at `at`.
    pub fn at(&mut self, at: At, ev: Event) {
        self.script.push((at, ev));
    }

    /// Make `ev` happen now (before the next poll).
    pub fn now(&mut self, ev: Event) {
        self.fire(ev);
    }

    /// Output steps so far.
    pub fn step_count(&self) -> u64 {
        self.steps.len() as u64
    }

    /// Steps made by `axis` (both directions) in `steps[from..]`.
    pub fn axis_steps_since(&self, axis: usize, from: usize) -> u64 {
        self.steps[from..].iter().filter(|s| s.axes & (1 << axis) != 0).count() as u64
    }

    /// Milliseconds since boot.
    pub fn ms(&self) -> u32 {
        (self.cycles / CYCLES_PER_MS) as u32
    }

    /// Take what was printed so far.
    pub fn take_out(&mut self) -> String {
        core::mem::take(&mut self.out)
    }

    /// Home switch `a` as the firmware reads it.
    fn home_switch(&self, a: usize) -> bool {
        self.forced[a].unwrap_or(self.home_closed[a])
    }

    /// The carousel switch as the firmware reads it.
    fn carousel_switch(&self) -> bool {
        self.forced[3]
            .unwrap_or_else(|| self.carousel_connected && self.phys[3].rem_euclid(self.carousel_steps_per_rev) < self.carousel_width_steps)
    }

    /// The tool-setter (probe) input as the firmware reads it.
    fn setter_switch(&self) -> bool {
        self.forced[4].unwrap_or_else(|| self.beam.is_some_and(|b| b.broken(&self.phys, self.tool)))
    }

    /// Follow home switch `a` to the position (hysteresis).
    fn follow_switch(&mut self, a: usize) {
        let p = self.phys[a];
        let closed = if self.home_closed[a] { p <= self.home_at[a] + self.hysteresis[a] } else { p <= self.home_at[a] };
        if closed != self.home_closed[a] {
            self.home_closed[a] = closed;
            self.transitions[a] += 1;
        }
    }

    fn output(&mut self, o: Output) {
        self.outputs.push((self.cycles, o));
    }

    /// Something the RX interrupt (or the UI) would have raised.
    fn fire(&mut self, ev: Event) {
        match ev {
            Event::Status => self.rt.status = true,
            Event::Hold => self.rt.hold = true,
            Event::Resume => self.rt.resume = true,
            Event::Abort => self.rt.abort = true,
            Event::Estop => {
                // `board::emergency_stop_in_isr`.
                self.stopped = true;
                self.drivers = false;
                self.spindle = 0;
                self.coolant = false;
                self.output(Output::Drivers(false));
                self.output(Output::Spindle(0));
                self.output(Output::Coolant(false));
                self.rt.estop = true;
            }
            Event::Reset => {
                let moving = self.busy();
                self.stopped = true;
                self.rt.reset = true;
                self.rt.reset_moving = moving;
            }
            Event::Force(i, v) => {
                let k = match i {
                    Input::Home(a) => a,
                    Input::CarouselHome => 3,
                    Input::ToolSetter => 4,
                };
                self.forced[k] = v;
            }
            Event::Override(b) => {
                self.rt.motion_ovr |= crate::overrides::motion_bit(b);
                self.rt.accessory_ovr |= crate::overrides::accessory_bit(b);
            }
        }
    }

    /// Fire the scripted events whose time or step count has come.
    fn fire_due(&mut self) {
        if self.script.is_empty() {
            return;
        }
        let (ms, n) = (self.ms(), self.step_count());
        let mut i = 0;
        while i < self.script.len() {
            let due = match self.script[i].0 {
                At::Ms(t) => ms >= t,
                At::Step(k) => n >= k,
            };
            if due {
                let (_, ev) = self.script.remove(i);
                self.fire(ev);
            } else {
                i += 1;
            }
        }
    }

    /// Let `cycles` CPU cycles pass: run the timer interrupts that fall in them.
    pub fn advance(&mut self, cycles: u64) {
        let end = self.cycles + cycles;
        while self.next_isr <= end {
            self.cycles = self.next_isr;
            self.fire_due();
            self.isr();
            self.next_isr += self.period;
        }
        self.cycles = end;
        self.fire_due();
    }

    /// `board::stepper::busy`.
    fn busy(&self) -> bool {
        !self.stopped && self.st.busy()
    }

    /// `board::stepper::space`.
    fn space(&self) -> usize {
        self.rings.borrow_mut().space(&self.st)
    }

    /// A homing or probe trip stopped the ISR (`board::stepper::tripped`).
    fn tripped(&self) -> bool {
        self.home_tripped || self.probe_tripped
    }

    /// The timer interrupt, in `board::stepper::TIMER1_COMPA`'s order.
    fn isr(&mut self) {
        if self.stopped {
            // `pending` is never output.
            self.period = IDLE_PERIOD;
            return;
        }
        let p = self.st.pending;
        if p != 0 {
            self.output_steps(p);
        }
        let armed = self.watch.homing | self.watch.probe as u8 | self.limit;
        if armed != 0 && self.switches_trip() {
            self.st.pending = 0;
            self.period = IDLE_PERIOD;
            return;
        }
        if self.st.ticks_left == 0 {
            self.load_segment();
        }
        self.st.next_event(&MAP);
        if p != 0 || self.st.pending != 0 {
            // Between any two interrupts the main loop may ask for the position.
            assert_eq!(self.reconstructed_position(), self.pos, "board position reconstruction");
        }
    }

    /// The step pins pulse for the axes in `bits` (of the running chunk).
    fn output_steps(&mut self, bits: u8) {
        let mut neg = 0;
        for a in 0..N_AXES {
            if bits & (1 << a) == 0 {
                continue;
            }
            let d = if self.st.cur().axis_dir & (1 << a) != 0 {
                neg |= 1 << a;
                -1
            } else {
                1
            };
            self.phys[a] += d as i64;
            if !self.st.cur().take_up {
                self.pos[a] += d;
            }
            if a < 3 {
                self.follow_switch(a);
            }
        }
        self.steps.push(Step { cycle: self.cycles, axes: bits, neg, phys: self.phys });
        self.fire_due();
    }

    /// The position as `board::stepper::position` reconstructs it (it
    /// counts no steps; [`Rings::position`]): the finished chunks, the
    /// running chunk's `Chunk::steps_done` from its error counters, minus
    /// the step computed but not output yet.
    pub fn reconstructed_position(&self) -> [i32; N_AXES] {
        self.rings.borrow_mut().position(&MAP, &self.st)
    }

    /// `switches_trip`: hard limit first (spindle off in the ISR), then homing, then probe.
    fn switches_trip(&mut self) -> bool {
        let mut closed = 0u8;
        for a in 0..3 {
            if self.home_switch(a) {
                closed |= 1 << a;
            }
        }
        if closed & self.limit != 0 {
            self.spindle = 0;
            self.output(Output::Spindle(0));
            self.limit_hit = true;
            self.stopped = true;
            return true;
        }
        if self.watch.homing != 0 {
            let mut c = closed;
            if self.watch.homing & (1 << 3) != 0 && self.carousel_switch() {
                c |= 1 << 3;
            }
            if c & self.watch.homing != 0 {
                self.trip_now();
                self.home_tripped = true;
                return true;
            }
        }
        if self.watch.probe && self.setter_switch() {
            self.trip_now();
            self.probe_tripped = true;
            return true;
        }
        false
    }

    /// Stop on a homing/probe trip; the position is frozen, so the latch
    /// (`Rings::trip_position`, first asked after the trip) must say this.
    fn trip_now(&mut self) {
        self.stopped = true;
        self.trip = self.pos;
    }

    /// `load_segment`: the next segment's period and hard-limit axes, or
    /// the idle timer (an underrun if steps were running).
    fn load_segment(&mut self) {
        match self.st.load_segment() {
            Some(s) => {
                self.running = true;
                self.period = seg_period(&s);
                if s.new_chunk != 0 {
                    self.limit = self.st.cur().limit;
                }
            }
            None => {
                if self.running {
                    self.running = false;
                    self.underruns += 1;
                    self.limit = 0;
                }
                self.period = IDLE_PERIOD;
            }
        }
    }
}

impl ufmt::uWrite for FakeBoard {
    type Error = Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Infallible> {
        self.out.push_str(s);
        Ok(())
    }
}

impl Stepper for FakeBoard {
    fn push_segment(&mut self, cmd: StepperCmd) -> bool {
        let taken = self.rings.get_mut().push(&cmd, &MAP, &mut self.st);
        if let (true, StepperCmd::Block(b)) = (taken, cmd) {
            if !b.take_up {
                for a in 0..N_AXES {
                    let s = b.steps[a] as i32;
                    self.block_end[a] += if b.direction_bits & (1 << a) != 0 { -s } else { s };
                }
            }
            self.path.push(self.block_end);
            self.path_ms.push(self.ms());
        }
        taken
    }

    fn segment_space(&self) -> usize {
        self.space()
    }

    fn stepper(&self) -> StepperStatus {
        // The firmware's position is reconstructed, this one counted: they agree.
        assert_eq!(self.reconstructed_position(), self.pos, "board position reconstruction");
        let tripped = self.tripped();
        let trip_position = self.rings.borrow_mut().trip_position(tripped, &MAP, &self.st);
        if tripped {
            assert_eq!(trip_position, self.trip, "latched trip position");
        }
        StepperStatus { position: self.pos, busy: self.busy(), trip_position, tripped }
    }

    fn set_stepper_position(&mut self, p: [i32; N_AXES]) {
        let tripped = self.tripped();
        self.rings.get_mut().set_position(p, tripped, &MAP, &self.st);
        self.pos = p;
        self.block_end = p;
    }

    fn stop_motion(&mut self) {
        self.stopped = true;
    }

    fn clear_stop(&mut self) {
        self.limit_hit = false;
        self.home_tripped = false;
        self.probe_tripped = false;
        // As the board: the position first (it subtracts the pending step),
        // then the ISR's state, then the rings.
        let q = self.reconstructed_position();
        assert_eq!(q, self.pos, "board position reconstruction");
        self.st.clear_isr();
        self.running = false;
        let cur = self.st.cur;
        self.rings.get_mut().clear(cur, q, &mut self.st);
        self.stopped = false;
        self.block_end = q;
    }

    fn stepper_stopped(&self) -> bool {
        self.stopped
    }

    fn set_watch(&mut self, w: Watch) {
        // The fake's switches are logical (triggered or not): the input
        // inversion of `$5` is an electrical matter it has no part in.
        let w = Watch { homing: w.homing & 0x0F, ..w };
        self.rings.get_mut().set_watch(w);
        self.watch = w;
    }
}

impl Inputs for FakeBoard {
    fn poll(&mut self) -> Realtime {
        self.polls += 1;
        assert!(self.polls <= self.poll_limit, "{} polls ({} ms): the controller is stuck waiting", self.polls, self.ms());
        self.advance(self.poll_cycles);
        let rt = core::mem::take(&mut self.rt);
        let resume = rt.resume || self.auto_resume;
        Realtime { limit: self.limit_hit, home_tripped: self.home_tripped, probe_tripped: self.probe_tripped, resume, ..rt }
    }

    fn switches(&self) -> Switches {
        let mut home = 0;
        for a in 0..3 {
            if self.home_switch(a) {
                home |= 1 << a;
            }
        }
        Switches { home, carousel_home: self.carousel_switch(), tool_setter: self.setter_switch() }
    }

    fn millis(&self) -> u32 {
        self.ms()
    }
}

impl Outputs for FakeBoard {
    fn drivers(&mut self, on: bool) {
        if self.drivers != on {
            self.drivers = on;
            self.output(Output::Drivers(on));
        }
    }

    fn carousel_driver(&mut self, on: bool) {
        if self.carousel_driver != on {
            self.carousel_driver = on;
            self.output(Output::CarouselDriver(on));
        }
    }

    fn spindle(&mut self, duty: u8) {
        if self.spindle != duty {
            self.spindle = duty;
            self.output(Output::Spindle(duty));
        }
    }

    fn coolant(&mut self, on: bool) {
        if self.coolant != on {
            self.coolant = on;
            self.output(Output::Coolant(on));
        }
    }
}

impl Storage for FakeBoard {
    fn eeprom_read(&mut self, addr: u16, buf: &mut [u8]) {
        let a = addr as usize;
        buf.copy_from_slice(&self.eeprom[a..a + buf.len()]);
    }

    fn eeprom_write(&mut self, addr: u16, data: &[u8]) {
        let a = addr as usize;
        let differ: Vec<u8> = data.iter().zip(&self.eeprom[a..]).filter(|(n, o)| n != o).map(|(n, _)| *n).collect();
        if !differ.is_empty() {
            self.eeprom_log.push((self.step_count(), addr, data.to_vec()));
        }
        self.eeprom[a..a + data.len()].copy_from_slice(data);
    }
}

impl Host for FakeBoard {
    fn rx_pending(&self) -> usize {
        0
    }
}
