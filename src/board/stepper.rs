//! The stepper ISR: Timer1 compare A in CTC mode (datasheet §17).
//!
//! Pipeline position: the main loop's `stepper::prep` makes `StepperCmd`s;
//! [`push`] hands them to `mill::stepper::rings::Rings` (host-tested: the
//! splitter, heads, free slots, position, trips), which writes
//! [`Chunk`]s (the Bresenham of a block, ≤ 32767 events, 16-bit) and
//! [`Seg`]s (`ticks` events at one timer period) into the two rings here.
//! This file keeps only the statics, the registers, the ISR and one-line
//! wrappers. The ISR reads both rings **in place, by index**: nothing is
//! copied per segment, and a chunk's error counters are updated in its ring
//! slot.
//!
//! Each interrupt is one step event:
//!
//! 1. toggle the step pins of the event computed last time (`pending`)
//!    **high**: one write to PINF, PINL, PINA each (atomic, no RMW);
//! 2. if armed (homing, probe, or a hard limit on an axis moving toward its
//!    switch in this chunk): read the switches, and stop on a trip;
//! 3. when the segment is used up, load the next one (OCR1A, prescaler, and
//!    on a new chunk: its pointer and the direction pins);
//! 4. compute the next event (16-bit Bresenham over the chunk's partial axes);
//! 5. toggle the same step pins **low**. Steps 2–4 keep the pulse high for at
//!    least 39 cycles (the shortest path, measured by `tools/bench`; DRV8825:
//!    1.9 µs = 31 cycles); the low time is the rest of the period. The direction pins
//!    change in step 3, ≥ 11 cycles after the rising edge and a whole period
//!    before the next one (DRV8825: 650 ns setup and hold).
//!
//! The ISR does not count position. The main loop knows every chunk it
//! queued: [`position`] (`Rings::position`) takes the queued ones from the
//! position at their end and adds, for the chunk in progress, what its
//! error counters say ([`Chunk::steps_done`]), minus the
//! computed-but-not-yet-output `pending` step.
//!
//! The timer never stops: with nothing to do it ticks at 1 kHz and polls the
//! ring, so there is no start/stop race with the main loop. OCR1A never goes
//! below `MIN_PERIOD_CYCLES` and is loaded before the interrupt is enabled
//! (simavr never fires CTC with OCR1A = 0, docs/SPEC.md §14). No TCNT preload is used
//! (simavr loses those).
//!
//! The usual event (not stopped, nothing homed or probed, no segment to
//! load) runs in assembly, `__vector_17` below; every other one jumps from
//! it to the Rust path (`step_slow`), which does the same steps.
//!
//! Cycle budget (simavr, 16 MHz, interrupt response and RETI included,
//! measured by `tools/bench` over all its runs): min 139, mean 166, max 361
//! (docs/SPEC.md §11: 400). The longest is a segment load with a new chunk
//! on the Rust path, ~22 cycles after the assembly's tests and jump. On a
//! streamed 0.1 mm G1 line the interrupt averages 177 cycles (it was 204
//! in Rust alone: `profile --count 254 --feed 12000 --accel 5000 --trace
//! 500:300`, `__vector_17`). Idle polling at 1 kHz takes the Rust path.

use super::pins;
use core::ptr::{addr_of, addr_of_mut, read_volatile, write_volatile};
use mill::stepper::queue::{tccr1b, Chunk, Seg};
pub use mill::stepper::rings::Watch;
use mill::stepper::rings::{IsrSnapshot, RingMem, Rings, CHUNK_MASK, CHUNK_RING_LEN, SEG_MASK, SEG_RING_LEN};
use mill::stepper::{Prescale, StepperCmd};
use mill::N_AXES;
use portable_atomic::{compiler_fence, AtomicU8, Ordering};

mod fast;

/// Timer period while idle: 1 kHz at clk/1.
const IDLE_PERIOD: u16 = 16_000;
/// TCCR1B at clk/1 (CTC).
const TCCR_DIV1: u8 = tccr1b(Prescale::Div1);
/// `armed` bit: the probe input is watched.
const PROBE_BIT: u8 = 1 << 3;

// Timer1 registers (data-space addresses, ATmega2560 datasheet §17.11).
const TCCR1B: *mut u8 = 0x81 as *mut u8;
const TCNT1L: *mut u8 = 0x84 as *mut u8;
const OCR1AL: *mut u8 = 0x88 as *mut u8;
const OCR1AH: *mut u8 = 0x89 as *mut u8;
const TIMSK1: *mut u8 = 0x6F as *mut u8;

/// Motion status bits shared between the ISR and the main loop.
pub mod motion {
    /// The ISR stops stepping (set by main or by a latch/limit/e-stop;
    /// cleared by [`super::clear_stop`] once planner and prep are reset).
    pub const STOP: u8 = 1 << 0;
    /// A homing switch tripped (the position is frozen at the trip).
    pub const HOME_TRIPPED: u8 = 1 << 1;
    /// The probe input tripped (the position is frozen at the trip).
    pub const PROBE_TRIPPED: u8 = 1 << 2;
    /// A home switch closed outside homing: hard-limit alarm.
    pub const LIMIT: u8 = 1 << 3;
}

/// Bits of [`motion`].
pub static MOTION: AtomicU8 = AtomicU8::new(0);

/// The ISR's state: one static, addressed directly (`lds`/`sts`; the
/// assembly in `fast` by these fields' offsets, and `tests/motion.rs`
/// pokes `armed`, `probe` and `invert` by theirs to run a job on the Rust
/// path alone).
#[repr(C)]
struct Isr {
    /// Step-output bits of the event computed last time, output next time.
    pending: u8,
    /// Events left in the running segment.
    ticks_left: u16,
    /// `k_end` of the running segment (main: events done in the chunk).
    k_end: u16,
    /// The running chunk (a slot of `CHUNKS`).
    chunk: *mut Chunk,
    /// Its ring index.
    cur: u8,
    /// Next segment slot to read.
    seg_tail: u8,
    /// TCCR1B now.
    tccr: u8,
    /// Check switches on every tick when non-zero: homing | limit | PROBE_BIT.
    armed: u8,
    /// Axes being homed (bit 3: the carousel switch).
    homing: u8,
    /// PROBE_BIT when the probe is watched, else 0.
    probe: u8,
    /// Hard-limit axes of the running chunk.
    limit: u8,
    /// A segment was loaded since the ring was last found empty.
    running: u8,
    /// Inputs read inverted ([`Watch::invert_inputs`]).
    invert: u8,
}

static mut SEGS: [Seg; SEG_RING_LEN] = [Seg { ticks: 0, period: 0, tccr: 0, new_chunk: 0, k_end: 0 }; SEG_RING_LEN];
/// Next free segment slot (written by main only, read by the ISR).
static mut SEG_HEAD: u8 = 0;
static mut CHUNKS: [Chunk; CHUNK_RING_LEN] = [Chunk::EMPTY; CHUNK_RING_LEN];
static mut ST: Isr = Isr {
    pending: 0,
    ticks_left: 0,
    k_end: 0,
    chunk: core::ptr::null_mut(),
    cur: 0,
    seg_tail: 0,
    tccr: TCCR_DIV1,
    armed: 0,
    homing: 0,
    probe: 0,
    limit: 0,
    running: 0,
    invert: 0,
};

/// Times the ISR found the segment ring empty after running a segment: one
/// per finished job, more when prep did not keep up (the machine stalled for
/// up to a millisecond). Read by the benchmark (`tools/bench`) by name.
#[no_mangle]
pub static mut MILL_STEP_UNDERRUNS: u16 = 0;
/// Main-loop bookkeeping of the rings (`mill::stepper::rings`, host-tested).
static mut MAIN: Rings = Rings::new();

/// Set up Timer1 in CTC mode at the idle rate.
pub fn init(_tc1: &avr_device::atmega2560::TC1) {
    // SAFETY: called once at boot with interrupts disabled; a non-zero
    // compare value is loaded before the clock starts.
    unsafe {
        (*addr_of_mut!(ST)).chunk = addr_of_mut!(CHUNKS[0]);
        write_volatile(OCR1AH, (IDLE_PERIOD >> 8) as u8);
        write_volatile(OCR1AL, IDLE_PERIOD as u8);
        write_volatile(0x80 as *mut u8, 0); // TCCR1A: normal ports, WGM11:10 = 0
        write_volatile(TCCR1B, TCCR_DIV1);
        write_volatile(TIMSK1, 1 << 1); // OCIE1A
    }
    let _ = TCNT1L;
}

// ---- Main-loop side: thin wrappers over `mill::stepper::rings` -----------------

/// The board's statics as the rings' memory.
struct Mem;

impl RingMem for Mem {
    fn seg_tail(&self) -> u8 {
        // SAFETY: a single-byte read of an index the ISR writes.
        unsafe { read_volatile(addr_of!(ST.seg_tail)) }
    }

    fn seg_head(&self) -> u8 {
        // SAFETY: SEG_HEAD is written by main only.
        unsafe { *addr_of!(SEG_HEAD) }
    }

    fn chunk_cur(&self) -> u8 {
        // SAFETY: a single-byte read of an index the ISR writes.
        unsafe { read_volatile(addr_of!(ST.cur)) }
    }

    // speed: LLVM makes it a call (one per queued chunk the position passes) otherwise
    #[inline(always)]
    fn chunk(&self, i: u8) -> &Chunk {
        // SAFETY: the rings ask only for slots the ISR has finished (before
        // its current one) or not yet reached, or with the ISR unable to run;
        // the ISR writes only the error counters of its running chunk.
        unsafe { &*addr_of!(CHUNKS[i as usize]) }
    }

    // speed: LLVM makes it a call (one per chunk queued) otherwise
    #[inline(always)]
    fn set_chunk(&mut self, i: u8, c: &Chunk) {
        // SAFETY: as above: a free slot, or the ISR cannot run.
        unsafe { *addr_of_mut!(CHUNKS[i as usize]) = *c };
    }

    // speed: LLVM makes it a call (one per chunk queued) otherwise
    #[inline(always)]
    fn chunk_mut(&mut self, i: u8) -> &mut Chunk {
        // SAFETY: as above: a free slot, or the ISR cannot run; the caller
        // keeps the reference only while it writes the slot.
        unsafe { &mut *addr_of_mut!(CHUNKS[i as usize]) }
    }

    fn set_seg(&mut self, i: u8, s: &Seg) {
        // SAFETY: slot i is free (between head and tail), unseen by the ISR
        // until the head is published.
        unsafe { *addr_of_mut!(SEGS[i as usize]) = *s };
    }

    fn publish_seg_head(&mut self, head: u8) {
        // SAFETY: main is the only writer; the fence keeps the slot writes
        // before the head that publishes them.
        unsafe {
            compiler_fence(Ordering::SeqCst);
            write_volatile(addr_of_mut!(SEG_HEAD), head);
        }
    }

    fn snapshot(&self) -> IsrSnapshot {
        // A consistent snapshot of the ISR's progress (the ISR cannot run here).
        avr_device::interrupt::free(|_| {
            // SAFETY: inside a critical section.
            unsafe {
                let st = &*addr_of!(ST);
                IsrSnapshot { cur: st.cur, k: st.k_end.wrapping_sub(st.ticks_left), pending: st.pending, chunk: *st.chunk }
            }
        })
    }
}

/// The rings' bookkeeping (main loop only).
fn rings() -> &'static mut Rings {
    // SAFETY: MAIN is used by the main loop only, and no caller keeps the
    // reference across another call to this function.
    unsafe { &mut *addr_of_mut!(MAIN) }
}

/// A homing or probe trip has stopped the ISR.
fn tripped() -> bool {
    MOTION.load(Ordering::Acquire) & (motion::HOME_TRIPPED | motion::PROBE_TRIPPED) != 0
}

/// At least `cycles` CPU cycles of motion wait in the segment ring.
pub fn queued_at_least(cycles: u32) -> bool {
    rings().queued_cycles(&Mem) >= cycles
}

/// Commands that surely fit now (a `Run` may take 2 segments and a chunk).
pub fn space() -> usize {
    rings().space(&Mem)
}

/// Queue one command from prep. False (nothing queued) without room.
pub fn push(cmd: StepperCmd) -> bool {
    rings().push(&cmd, &pins::STEP_MAP, &mut Mem)
}

/// Queue one command that fits ([`space`] > 0 and nothing queued since);
/// returns [`space`] after it.
pub fn push_fitting(cmd: StepperCmd) -> usize {
    rings().push_fitting(&cmd, &pins::STEP_MAP, &mut Mem)
}

/// Machine position in steps: what has been output on the pins.
pub fn position() -> [i32; N_AXES] {
    rings().position(&pins::STEP_MAP, &Mem)
}

/// Set the machine position (only while the ISR is idle or stopped).
pub fn set_position(p: [i32; N_AXES]) {
    rings().set_position(p, tripped(), &pins::STEP_MAP, &Mem);
}

/// Position latched at the last homing or probe trip.
pub fn trip_position() -> [i32; N_AXES] {
    rings().trip_position(tripped(), &pins::STEP_MAP, &Mem)
}

/// Replace what the ISR watches (homing, probe, limits).
pub fn set_watch(w: Watch) {
    rings().set_watch(w);
    // SAFETY: ST is written inside a critical section.
    avr_device::interrupt::free(|_| unsafe {
        let st = &mut *addr_of_mut!(ST);
        st.homing = w.homing & 0x0F;
        st.probe = if w.probe { PROBE_BIT } else { 0 };
        st.invert = w.invert_inputs;
        st.armed = st.homing | st.probe | st.limit;
    });
}

/// Inputs read inverted (`$5`), as the ISR applies them.
pub fn input_invert() -> u8 {
    // SAFETY: a single byte written by main only (`set_watch`).
    unsafe { read_volatile(addr_of!(ST.invert)) }
}

/// What the ISR watches now.
pub fn watch() -> Watch {
    rings().watch()
}

/// True while steps are being produced or segments wait in the ring.
pub fn busy() -> bool {
    if MOTION.load(Ordering::Acquire) & motion::STOP != 0 {
        return false;
    }
    avr_device::interrupt::free(|_| {
        // SAFETY: inside a critical section.
        unsafe {
            let st = &*addr_of!(ST);
            st.ticks_left != 0 || st.pending != 0 || st.seg_tail != *addr_of!(SEG_HEAD)
        }
    })
}

/// Stop stepping at once. ISR-safe.
pub fn halt_from_isr() {
    MOTION.fetch_or(motion::STOP, Ordering::AcqRel);
}

/// Resume accepting segments after a stop, once main has reset the planner
/// and prep. Drops whatever is still in the rings; the position stays what
/// was output.
pub fn clear_stop() {
    avr_device::interrupt::free(|_| {
        let q = position();
        // SAFETY: inside a critical section the ISR cannot run; main is the
        // only other user of the state.
        unsafe {
            let st = &mut *addr_of_mut!(ST);
            st.ticks_left = 0;
            st.k_end = 0;
            st.pending = 0;
            st.running = 0;
            // The stopped chunk's hard limits go with it: an axis left
            // resting on its switch must not trip again (see `load_segment`).
            st.limit = 0;
            st.armed = st.homing | st.probe;
            st.seg_tail = *addr_of!(SEG_HEAD);
            rings().clear(st.cur, q, &mut Mem);
        }
        MOTION.fetch_and(!motion::STOP, Ordering::AcqRel);
    });
}

// ---- The ISR -------------------------------------------------------------------

unsafe fn set_idle_timer(st: &mut Isr) {
    // SAFETY: called from the stepper ISR only, which owns timer 1's compare
    // and clock-select registers while the stepper runs.
    unsafe {
        write_volatile(OCR1AH, (IDLE_PERIOD >> 8) as u8);
        write_volatile(OCR1AL, IDLE_PERIOD as u8);
        if st.tccr != TCCR_DIV1 {
            st.tccr = TCCR_DIV1;
            write_volatile(TCCR1B, TCCR_DIV1);
        }
    }
}

/// Switch checks after the rising edges. Returns true to stop (flags set).
/// A hard limit is checked first and turns the spindle off before anything
/// else, a few cycles after the switch pins are read.
// speed: in the interrupt's Rust paths, not a call from them (each call
// cost the worst case ~40 cycles, over SPEC §11's 400)
#[inline(always)]
unsafe fn switches_trip(st: &mut Isr) -> bool {
    // SAFETY: called from the stepper ISR only: MOTION is read and written
    // with plain volatile accesses, as main changes it only with interrupts
    // off; reading the switch pins has no side effects.
    unsafe {
        let closed = pins::home_closed() ^ st.invert;
        let m = MOTION.as_ptr();
        if closed & st.limit != 0 {
            limit_trip();
            return true;
        }
        if st.homing != 0 {
            // Bit 3 (E0): the carousel switch, closed at 0° (pulls low);
            // `closed` holds its inversion bit until this.
            let mut c = closed & 0b111 | st.invert & (1 << 3);
            if st.homing & (1 << 3) != 0 && !pins::CAROUSEL_HOME.is_high() {
                c ^= 1 << 3;
            }
            if c & st.homing != 0 {
                write_volatile(m, read_volatile(m) | motion::HOME_TRIPPED | motion::STOP);
                return true;
            }
        }
        if st.probe != 0 && pins::TOOL_SETTER.is_high() != (st.invert & (1 << 4) != 0) {
            write_volatile(m, read_volatile(m) | motion::PROBE_TRIPPED | motion::STOP);
            return true;
        }
        false
    }
}

/// The next segment, if any; on a new chunk also its pointer, the direction
/// pins and the limit mask.
// speed: as `switches_trip`
#[inline(always)]
unsafe fn load_segment(st: &mut Isr) {
    // SAFETY: called from the stepper ISR only, which owns `st`, timer 1 and
    // the direction pins; main writes the segment and chunk slots before it
    // publishes them (SEG_HEAD), and `st.chunk` stays inside CHUNKS.
    unsafe {
        let tail = st.seg_tail;
        if tail == read_volatile(addr_of!(SEG_HEAD)) {
            if st.running != 0 {
                st.running = 0;
                let u = addr_of_mut!(MILL_STEP_UNDERRUNS);
                *u = (*u).wrapping_add(1);
                // Nothing moves now: hard limits are for axes moving toward
                // their switch (an axis may rest on its switch).
                st.limit = 0;
                st.armed = st.homing | st.probe;
            }
            set_idle_timer(st);
            return;
        }
        st.running = 1;
        let s = &*addr_of!(SEGS[(tail & SEG_MASK) as usize]);
        st.ticks_left = s.ticks;
        st.k_end = s.k_end;
        write_volatile(OCR1AH, (s.period >> 8) as u8);
        write_volatile(OCR1AL, s.period as u8);
        let tccr = s.tccr;
        if tccr != st.tccr {
            st.tccr = tccr;
            write_volatile(TCCR1B, tccr);
        }
        if s.new_chunk != 0 {
            st.cur = (st.cur + 1) & CHUNK_MASK;
            // The next slot (a pointer step, not an index multiply).
            let mut c = st.chunk.add(1);
            if c == addr_of_mut!(CHUNKS).cast::<Chunk>().add(CHUNK_RING_LEN) {
                c = addr_of_mut!(CHUNKS).cast::<Chunk>();
            }
            st.chunk = c;
            let c = &*c;
            let pf = pins::PF.port;
            write_volatile(pf, (read_volatile(pf) & !pins::DIR_PF) | c.dir_out[0]);
            let pl = pins::PL.port;
            write_volatile(pl, (read_volatile(pl) & !pins::DIR_PL) | c.dir_out[1]);
            let pa = pins::PA.port;
            write_volatile(pa, (read_volatile(pa) & !pins::DIR_PA) | c.dir_out[2]);
            st.limit = c.limit;
            st.armed = st.homing | st.probe | c.limit;
        }
        compiler_fence(Ordering::SeqCst);
        write_volatile(addr_of_mut!(st.seg_tail), (tail + 1) & SEG_MASK);
    }
}

/// One Bresenham event of the chunk: step-output bits. Hand-written
/// assembly of `mill::stepper::bresenham::Chunk::tick_out`, its plain host
/// twin, which the host tests check against the model `Chunk::tick` on
/// every kind of chunk the splitter makes
/// (`the_isr_twin_steps_exactly_like_the_reference_on_every_chunk_the_splitter_makes`).
/// LLVM's AVR code for the twin spends ~30 cycles per partial axis
/// (`mov`/`andi`/`cpi` per mask test, the pointer re-copied per field);
/// here an axis costs 18–20 cycles, an axis that is not partial 3.
/// Measured gain: with the twin in its place the whole interrupt costs 341
/// cycles on average instead of 199 in the 0.1 mm G1 stream (`profile
/// --count 254 --trace 500:300 --feed 3300`, `__vector_17`, 2026-11-26),
/// and 36 015 instead of 34 851 cycles a streamed line.
unsafe fn tick(c: *mut Chunk) -> u8 {
    let bits: u8;
    // SAFETY: `c` points to the running chunk slot, which only the ISR uses
    // while it runs; the offsets are checked against the layout below.
    unsafe {
        core::arch::asm!(
            "ldd {bits}, Z+{every}",
            "ldd {p}, Z+{partial}",
            "tst {p}",
            "breq 9f",
            "ldd {nl}, Z+{events}",
            "ldd {nh}, Z+{events}+1",
            // Axis i: e += s; if e >= 0 { e -= n; step }.
            "sbrs {p}, 0",
            "rjmp 3f",
            "ldd {el}, Z+0", "ldd {eh}, Z+1", "ldd {sl}, Z+8", "ldd {sh}, Z+9",
            "add {el}, {sl}", "adc {eh}, {sh}",
            "brmi 2f",
            "sub {el}, {nl}", "sbc {eh}, {nh}",
            "ori {bits}, {x}",
            "2:", "std Z+0, {el}", "std Z+1, {eh}",
            "3:",
            "sbrs {p}, 1",
            "rjmp 5f",
            "ldd {el}, Z+2", "ldd {eh}, Z+3", "ldd {sl}, Z+10", "ldd {sh}, Z+11",
            "add {el}, {sl}", "adc {eh}, {sh}",
            "brmi 4f",
            "sub {el}, {nl}", "sbc {eh}, {nh}",
            "ori {bits}, {y}",
            "4:", "std Z+2, {el}", "std Z+3, {eh}",
            "5:",
            "sbrs {p}, 2",
            "rjmp 7f",
            "ldd {el}, Z+4", "ldd {eh}, Z+5", "ldd {sl}, Z+12", "ldd {sh}, Z+13",
            "add {el}, {sl}", "adc {eh}, {sh}",
            "brmi 6f",
            "sub {el}, {nl}", "sbc {eh}, {nh}",
            "ori {bits}, {z}",
            "6:", "std Z+4, {el}", "std Z+5, {eh}",
            "7:",
            "sbrs {p}, 3",
            "rjmp 9f",
            "ldd {el}, Z+6", "ldd {eh}, Z+7", "ldd {sl}, Z+14", "ldd {sh}, Z+15",
            "add {el}, {sl}", "adc {eh}, {sh}",
            "brmi 8f",
            "sub {el}, {nl}", "sbc {eh}, {nh}",
            "ori {bits}, {e}",
            "8:", "std Z+6, {el}", "std Z+7, {eh}",
            "9:",
            in("Z") c,
            bits = out(reg_upper) bits,
            p = out(reg) _,
            nl = out(reg) _,
            nh = out(reg) _,
            el = out(reg) _,
            eh = out(reg) _,
            sl = out(reg) _,
            sh = out(reg) _,
            every = const core::mem::offset_of!(Chunk, every),
            partial = const core::mem::offset_of!(Chunk, partial),
            events = const core::mem::offset_of!(Chunk, events),
            x = const pins::X_STEP.mask,
            y = const pins::Y_STEP.mask,
            z = const pins::Z_STEP.mask,
            e = const pins::E_STEP.mask,
            options(nostack),
        );
    }
    bits
}

// The assembly above addresses the chunk by these offsets.
const _: () = {
    assert!(core::mem::offset_of!(Chunk, error) == 0);
    assert!(core::mem::offset_of!(Chunk, steps) == 8);
    assert!(core::mem::offset_of!(Chunk, events) == 16);
    assert!(core::mem::offset_of!(Chunk, every) == 18);
    assert!(core::mem::offset_of!(Chunk, partial) == 19);
};

unsafe fn toggle_steps(p: u8) {
    // SAFETY: called from the stepper ISR only; writing 1s to PINx toggles
    // only those bits, and the masks keep the step pins.
    unsafe {
        // Writing 1s to PINx toggles those PORTx bits atomically (datasheet §13.2.2).
        write_volatile(pins::PF.pin, p & pins::STEP_PF);
        write_volatile(pins::PL.pin, p & pins::STEP_PL);
        write_volatile(pins::PA.pin, p & pins::STEP_PA);
    }
}

/// The step interrupt's other cases (stopped, homing or probing, a segment
/// to load), entered from `__vector_17` by a jump with the registers as
/// the interrupt found them. See the module doc for the order of
/// operations.
extern "avr-interrupt" fn step_slow() {
    // SAFETY: the ISR has exclusive use of ST while it runs (no nesting); the
    // main loop touches ST only inside critical sections or through
    // single-byte indices, and writes ring slots before publishing them.
    unsafe {
        let st = &mut *addr_of_mut!(ST);
        if read_volatile(MOTION.as_ptr()) & motion::STOP != 0 {
            // Stopped: `pending` is never output (main subtracts it).
            set_idle_timer(st);
            return;
        }
        let p = st.pending;
        toggle_steps(p);
        after_rise(st, p);
    }
}

/// The fast path raised the step pins and read a hard-limit switch of the
/// running chunk closed: the trip, as `switches_trip` and `after_rise` make
/// it (the spindle goes off ~30 cycles after the switches were read).
extern "avr-interrupt" fn step_tripped() {
    // SAFETY: as `step_slow`.
    unsafe {
        let st = &mut *addr_of_mut!(ST);
        limit_trip();
        stop_event(st);
    }
}

/// A hard limit: the spindle off first, then the stop and the alarm flag.
#[inline(always)]
unsafe fn limit_trip() {
    // SAFETY: called from the step interrupt only: MOTION is read and
    // written with plain volatile accesses, as main changes it only with
    // interrupts off.
    unsafe {
        super::spindle_off_raw();
        let m = MOTION.as_ptr();
        write_volatile(m, read_volatile(m) | motion::LIMIT | motion::STOP);
    }
}

/// A trip ends the event: the pending step is never output (main
/// subtracts it), the timer idles, the pulse ends.
#[inline(always)]
unsafe fn stop_event(st: &mut Isr) {
    let p = st.pending;
    st.pending = 0;
    // SAFETY: called from the step interrupt only.
    unsafe {
        set_idle_timer(st);
        toggle_steps(p);
    }
}

/// The event after its rising edges: switches, the next segment, the next
/// event, the falling edges.
// speed: in the interrupt's Rust path, not a call from it
#[inline(always)]
unsafe fn after_rise(st: &mut Isr, p: u8) {
    // SAFETY: called from the step interrupt only (see `step_slow`).
    unsafe {
        if st.armed != 0 && switches_trip(st) {
            stop_event(st);
            return;
        }
        if st.ticks_left == 0 {
            load_segment(st);
        }
        let mut next = 0;
        if st.ticks_left != 0 {
            st.ticks_left -= 1;
            next = tick(st.chunk);
        }
        // The work above keeps the step high ≥ 31 cycles (DRV8825; measured
        // minimum: 39 cycles, `tools/bench`); keep it before the falling edge.
        compiler_fence(Ordering::SeqCst);
        toggle_steps(p);
        st.pending = next;
    }
}
