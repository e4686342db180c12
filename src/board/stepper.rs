//! The stepper ISR: Timer1 compare A in CTC mode (datasheet §17).
//!
//! Pipeline position: the main loop's `stepper::prep` pushes `StepperCmd`s
//! into a `heapless::spsc` ring ([`producer`]); this ISR is its consumer.
//! Each interrupt is one Bresenham step event:
//!
//! 1. toggle the step pins of the event computed last time **high**
//!    (one write to PINF, PINL, PINA each: atomic, no read-modify-write);
//! 2. count those steps into [`position`] and check switches (homing latch,
//!    probe latch, hard limits);
//! 3. compute the next event (`Bresenham::tick`), loading the next segment
//!    or block from the ring when the current one is done;
//! 4. toggle the same step pins **low**: the work in 2–3 keeps the pulse high
//!    for well over the DRV8825's 1.9 µs (31 cycles), checked by the virtual
//!    machine's recorder on every pulse;
//! 5. set the direction pins for the next event, so they settle for a whole
//!    period (≥ 266 cycles) before its rising edge (DRV8825: 650 ns).
//!
//! The timer never stops: with nothing to do it ticks at 1 kHz and polls the
//! ring, so there is no start/stop race with the main loop. OCR1A never goes
//! below `prep::MIN_PERIOD_CYCLES`, and is loaded before the interrupt is
//! enabled (simavr never fires CTC with OCR1A = 0, SPEC §14). No TCNT preload
//! is used (simavr loses those).
//!
//! Cycle budget: measured by `tools/bench` (min / mean / max in the README).

use super::pins;
use avr_device::atmega2560::TC1;
use core::ptr::{addr_of_mut, write_volatile};
use heapless::spsc::{Consumer, Producer, Queue};
use mill::stepper::{Bresenham, Prescale, StepperCmd};
use portable_atomic::{AtomicU8, Ordering};

/// Segment ring length (+1 slot heapless keeps free).
pub const SEGMENT_RING_LEN: usize = 16;
/// Timer period while idle: 1 kHz at clk/1.
const IDLE_PERIOD: u16 = 16_000;

/// Motion status bits shared between the ISR and the main loop.
pub mod motion {
    /// The ISR drops all queued commands and stops stepping (set by main or
    /// by a latch/limit/e-stop; cleared by main once planner and prep are reset).
    pub const STOP: u8 = 1 << 0;
    /// A homing switch tripped (position latched in `trip_position`).
    pub const HOME_TRIPPED: u8 = 1 << 1;
    /// The probe input tripped (position latched in `trip_position`).
    pub const PROBE_TRIPPED: u8 = 1 << 2;
    /// A home switch closed outside homing: hard-limit alarm.
    pub const LIMIT: u8 = 1 << 3;
    /// The ISR is executing a segment (or has one queued up next).
    pub const BUSY: u8 = 1 << 4;
}

/// Bits of [`motion`].
pub static MOTION: AtomicU8 = AtomicU8::new(0);

/// What the ISR watches on each step (written by main in a critical section).
#[derive(Clone, Copy, Default)]
pub struct Watch {
    /// Axes being homed: a closed home switch on one of them latches and
    /// stops (bit 3, E0: the carousel home switch).
    pub homing: u8,
    /// Probe active: the tool-setter input latches and stops.
    pub probe: bool,
    /// Axes whose home switch raises a hard-limit alarm while moving toward it.
    pub limits: u8,
    /// Axes homed (their switch closing at position 0 is expected).
    pub homed: u8,
    /// Direction-pin inversion mask (setting).
    pub invert_dir: u8,
}

struct State {
    cons: Option<Consumer<'static, StepperCmd, SEGMENT_RING_LEN>>,
    bres: Bresenham,
    /// Step events left in the running segment.
    ticks_left: u16,
    /// Step bits computed last time, output at the start of the next ISR.
    pending: u8,
    /// Direction bits of the running block (bit i = axis i negative).
    block_dir: u8,
    /// Count steps into `position` (false for backlash take-up blocks).
    counting: bool,
    /// Direction pin levels currently driven (bit i = axis i pin high).
    dir_pins: u8,
    /// Machine position in steps.
    position: [i32; 4],
    /// Position latched by a homing or probe trip.
    trip_position: [i32; 4],
    watch: Watch,
    prescale: Prescale,
}

static mut SEGMENTS: Queue<StepperCmd, SEGMENT_RING_LEN> = Queue::new();
static mut PRODUCER: Option<Producer<'static, StepperCmd, SEGMENT_RING_LEN>> = None;
static mut ST: State = State {
    cons: None,
    bres: Bresenham::new(),
    ticks_left: 0,
    pending: 0,
    block_dir: 0,
    counting: true,
    dir_pins: 0,
    position: [0; 4],
    trip_position: [0; 4],
    watch: Watch { homing: 0, probe: false, limits: 0, homed: 0, invert_dir: 0 },
    prescale: Prescale::Div1,
};

/// Set up Timer1 in CTC mode at the idle rate and split the segment ring.
pub fn init(tc1: &TC1) {
    // SAFETY: called once at boot with interrupts disabled.
    unsafe {
        let (p, c) = (*addr_of_mut!(SEGMENTS)).split();
        *addr_of_mut!(PRODUCER) = Some(p);
        (*addr_of_mut!(ST)).cons = Some(c);
    }
    // SAFETY: a non-zero compare value is loaded before the clock starts.
    tc1.ocr1a().write(|w| unsafe { w.bits(IDLE_PERIOD) });
    tc1.tccr1a().write(|w| unsafe { w.bits(0) });
    tc1.tccr1b().write(|w| w.wgm1().set(0b01).cs1().direct());
    tc1.timsk1().write(|w| w.ocie1a().set_bit());
}

/// The main loop's end of the segment ring.
pub fn producer() -> &'static mut Producer<'static, StepperCmd, SEGMENT_RING_LEN> {
    // SAFETY: only the main loop calls this; the producer was set in init.
    unsafe { (*addr_of_mut!(PRODUCER)).as_mut().unwrap_unchecked() }
}

/// Machine position in steps (read atomically).
pub fn position() -> [i32; 4] {
    // SAFETY: read inside a critical section, so the ISR cannot be mid-update.
    avr_device::interrupt::free(|_| unsafe { (*addr_of_mut!(ST)).position })
}

/// Set the machine position (only while the ISR is idle or stopped).
pub fn set_position(p: [i32; 4]) {
    // SAFETY: written inside a critical section.
    avr_device::interrupt::free(|_| unsafe { (*addr_of_mut!(ST)).position = p });
}

/// Position latched at the last homing or probe trip.
pub fn trip_position() -> [i32; 4] {
    // SAFETY: read inside a critical section.
    avr_device::interrupt::free(|_| unsafe { (*addr_of_mut!(ST)).trip_position })
}

/// Replace what the ISR watches (homing, probe, limits).
pub fn set_watch(w: Watch) {
    // SAFETY: written inside a critical section.
    avr_device::interrupt::free(|_| unsafe { (*addr_of_mut!(ST)).watch = w });
}

/// What the ISR watches now.
pub fn watch() -> Watch {
    // SAFETY: read inside a critical section.
    avr_device::interrupt::free(|_| unsafe { (*addr_of_mut!(ST)).watch })
}

/// True while steps are being produced or segments wait in the ring.
pub fn busy() -> bool {
    MOTION.load(Ordering::Acquire) & motion::BUSY != 0 || producer().len() != 0
}

/// Stop stepping at once and drop everything queued. ISR-safe.
pub fn halt_from_isr() {
    MOTION.fetch_or(motion::STOP, Ordering::AcqRel);
}

/// Resume accepting segments after a stop, once main has reset the planner
/// and prep. Drops whatever is still in the ring.
pub fn clear_stop() {
    avr_device::interrupt::free(|_| {
        // SAFETY: inside a critical section the ISR cannot run; main is the
        // only other user of the state.
        unsafe {
            let st = &mut *addr_of_mut!(ST);
            if let Some(c) = st.cons.as_mut() {
                while c.dequeue().is_some() {}
            }
            st.ticks_left = 0;
            st.pending = 0;
        }
        MOTION.fetch_and(!(motion::STOP | motion::BUSY), Ordering::AcqRel);
    });
}

#[inline(always)]
fn toggle(f: u8, l: u8, a: u8) {
    // SAFETY: writing 1s to PINx toggles those PORTx bits atomically
    // (datasheet §13.2.2); only step/dir bits are ever written here.
    unsafe {
        write_volatile(pins::PF.pin, f);
        write_volatile(pins::PL.pin, l);
        write_volatile(pins::PA.pin, a);
    }
}

#[inline(always)]
fn set_period(period: u16, prescale: Prescale, st: &mut State) {
    // SAFETY: Timer1 is owned by this ISR after init.
    let tc1 = unsafe { &*TC1::ptr() };
    tc1.ocr1a().write(|w| unsafe { w.bits(period) });
    if prescale != st.prescale {
        st.prescale = prescale;
        match prescale {
            Prescale::Div1 => {
                tc1.tccr1b().write(|w| w.wgm1().set(0b01).cs1().direct());
            }
            Prescale::Div8 => {
                tc1.tccr1b().write(|w| w.wgm1().set(0b01).cs1().prescale_8());
            }
        }
    }
}

/// Check switches after the steps in `bits` were output. Returns true to stop.
#[inline(always)]
fn check_switches(st: &mut State, bits: u8) -> bool {
    let w = st.watch;
    let mut home = 0u8;
    if w.homing | w.limits != 0 {
        for (i, p) in pins::HOME.iter().enumerate() {
            if !p.is_high() {
                home |= 1 << i;
            }
        }
    }
    if w.homing != 0 {
        // Bit 3 (E0): the carousel switch, closed at 0° (pulls low).
        if w.homing & (1 << 3) != 0 && !pins::CAROUSEL_HOME.is_high() {
            home |= 1 << 3;
        }
        if home & w.homing != 0 {
            st.trip_position = st.position;
            MOTION.fetch_or(motion::HOME_TRIPPED | motion::STOP, Ordering::AcqRel);
            return true;
        }
        return false;
    }
    if w.probe && pins::TOOL_SETTER.is_high() {
        st.trip_position = st.position;
        MOTION.fetch_or(motion::PROBE_TRIPPED | motion::STOP, Ordering::AcqRel);
        return true;
    }
    // Hard limits: a switch closed on an axis stepping toward it, unless the
    // axis is homed and exactly at its switch point (position 0).
    let toward = bits & st.block_dir & w.limits & home;
    if toward != 0 {
        let mut fault = false;
        for i in 0..3 {
            if toward & (1 << i) != 0 && !(w.homed & (1 << i) != 0 && st.position[i] == 0) {
                fault = true;
            }
        }
        if fault {
            MOTION.fetch_or(motion::LIMIT | motion::STOP, Ordering::AcqRel);
            super::spindle_off_raw();
            return true;
        }
    }
    false
}

// One step event. See the module doc for the order of operations.
#[avr_device::interrupt(atmega2560)]
fn TIMER1_COMPA() {
    // SAFETY: the ISR has exclusive use of ST while it runs (no nesting);
    // the main loop only touches ST inside critical sections.
    let st = unsafe { &mut *addr_of_mut!(ST) };

    // 1. Rising edges of the event computed last time (none once stopped:
    //    an e-stop may have disabled the drivers since it was computed).
    let mut stop = MOTION.load(Ordering::Acquire) & motion::STOP != 0;
    let out = if stop { 0 } else { st.pending };
    let (f, l, a) = pins::port_bits(out);
    toggle(f, l, a);

    // 2. Count the steps, then check switches.
    if out != 0 && st.counting {
        let dir = st.block_dir;
        for i in 0..4 {
            if out & (1 << i) != 0 {
                if dir & (1 << i) != 0 {
                    st.position[i] -= 1;
                } else {
                    st.position[i] += 1;
                }
            }
        }
        if !stop {
            stop = check_switches(st, out);
        }
    }

    // 3. Compute the next event.
    let mut next = 0u8;
    if stop {
        st.ticks_left = 0;
        if let Some(c) = st.cons.as_mut() {
            while c.dequeue().is_some() {}
        }
        MOTION.fetch_and(!motion::BUSY, Ordering::AcqRel);
        set_period(IDLE_PERIOD, Prescale::Div1, st);
    } else {
        if st.ticks_left == 0 {
            loop {
                match st.cons.as_mut().and_then(|c| c.dequeue()) {
                    Some(StepperCmd::Block(b)) => {
                        st.bres.load(&b);
                        st.block_dir = b.direction_bits;
                        st.counting = !b.take_up;
                    }
                    Some(StepperCmd::Run(s)) => {
                        st.ticks_left = s.ticks;
                        set_period(s.period, s.prescale, st);
                        MOTION.fetch_or(motion::BUSY, Ordering::AcqRel);
                        break;
                    }
                    None => {
                        MOTION.fetch_and(!motion::BUSY, Ordering::AcqRel);
                        set_period(IDLE_PERIOD, Prescale::Div1, st);
                        break;
                    }
                }
            }
        }
        if st.ticks_left != 0 {
            next = st.bres.tick();
            st.ticks_left -= 1;
        }
    }

    // 4. Falling edges.
    toggle(f, l, a);

    // 5. Direction for the next event (pins high = positive, unless inverted).
    if next != 0 {
        let want = !st.block_dir ^ st.watch.invert_dir;
        let diff = (want ^ st.dir_pins) & 0x0F;
        if diff != 0 {
            let (df, dl, da) = pins::dir_port_bits(diff);
            toggle(df, dl, da);
            st.dir_pins ^= diff;
        }
    }
    st.pending = next;
}
