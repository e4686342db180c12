//! Board layer: the only code that touches ATmega2560 registers.
//!
//! `arduino-hal` is not on crates.io (and GitHub cannot be reached here), so
//! this small layer sits directly on the `avr-device` PAC. It owns:
//! - [`pins`]: the RAMPS 1.4 pin table (docs/SPEC.md §2);
//! - [`serial`]: USART0 with interrupt-driven RX/TX rings and realtime bytes;
//! - [`stepper`]: Timer1, the step ISR (Bresenham over X, Y, Z, E0);
//! - the millisecond clock (Timer0) and spindle PWM (Timer2) in this file;
//! - [`twi`] and [`spi`]: bus masters implementing the `embedded-hal` 1.0 traits;
//! - [`oled`]: the SH1106 display on the TWI (its command set, page writes);
//! - [`eeprom`] and [`wdt`];
//! - [`bootloader`]: the stock bootloader's watchdog entry (the landing
//!   pad at 0x20000) and the reset cause it clears;
//! - [`halt`]: where every panic and `abort` ends (the M112 state, then halt);
//! - `mem`: faster `memcpy` and `memset` than avr-libc's, and
//!   `soft_float`: faster f32 `*`, `+` and `-` (not registers, but
//!   AVR-only assembly like the rest).
//!
//! Everything above this layer (the `mill` library) sees values, never pins.

pub mod bootloader;
mod decimal;
pub mod eeprom;
pub mod halt;
mod lex;
mod mem;
pub mod oled;
pub mod pins;
pub mod serial;
mod soft_float;
pub mod spi;
mod sqrt;
pub mod stepper;
pub mod twi;
pub mod wdt;

/// GPIOR1 and GPIOR2 (I/O 0x2A and 0x2B, datasheet §10.4): where the
/// assembly fast paths of the step, RX and millisecond interrupts keep r24
/// and SREG while they run (`out` and `in`, a cycle each, instead of a
/// push and a pop, two each: 4 cycles an interrupt). Interrupts never
/// nest (no handler sets I), each fast path takes its values back before
/// its `reti` or its jump to a Rust handler, and nothing else uses the two
/// registers (GPIOR0 is the bootloader landing pad's mark).
const ISR_R24_IO: u8 = 0x2A;
const ISR_SREG_IO: u8 = 0x2B;

use avr_device::atmega2560::{Peripherals, TC0, TC2};
use avr_device::interrupt::Mutex;
use core::cell::Cell;
use core::ptr::addr_of_mut;
use portable_atomic::{AtomicU8, Ordering};

/// Realtime request bits set from ISRs, consumed by the main loop.
pub mod realtime {
    /// `?` received: print one status line.
    pub const STATUS: u8 = 1 << 0;
    /// `!` received: feed hold.
    pub const HOLD: u8 = 1 << 1;
    /// `~` received: resume.
    pub const RESUME: u8 = 1 << 2;
    /// `M112` seen on the wire: the machine is already stopped.
    pub const ESTOP: u8 = 1 << 3;
    /// 0x18 (Ctrl-X, grbl's soft reset): the stepper is already halted.
    pub const RESET: u8 = 1 << 4;
    /// With [`RESET`]: steps were still being produced when it arrived.
    pub const RESET_MOVING: u8 = 1 << 5;
    /// 0x85 (grbl's jog cancel).
    pub const JOG_CANCEL: u8 = 1 << 6;
}

/// Pending realtime requests (bits of [`realtime`]).
pub static REALTIME: AtomicU8 = AtomicU8::new(0);

/// Set [`realtime`] request bits from inside an ISR: a plain read-modify-write,
/// since interrupts are already off there (`fetch_or` would bracket it with
/// `cli` and a restore of SREG).
pub(crate) fn raise_in_isr(bits: u8) {
    let p = REALTIME.as_ptr();
    // SAFETY: interrupts are off inside an ISR and ISRs do not nest, so
    // nothing can run between the load and the store.
    unsafe { p.write_volatile(p.read_volatile() | bits) };
}

/// grbl's realtime override bytes received (request bits of
/// `mill::overrides::motion` and `::accessory`), set by the RX interrupt.
pub static MOTION_OVR: AtomicU8 = AtomicU8::new(0);
pub static ACCESSORY_OVR: AtomicU8 = AtomicU8::new(0);

/// Take and clear the pending requests of an override byte.
pub fn take_overrides(o: &AtomicU8) -> u8 {
    o.swap(0, Ordering::AcqRel)
}

/// Take and clear all pending realtime requests.
pub fn take_realtime() -> u8 {
    REALTIME.swap(0, Ordering::AcqRel)
}

/// Stop everything now: drivers off, spindle off, stepper halted.
/// Safe to call from any context, including ISRs.
pub fn emergency_stop() {
    avr_device::interrupt::free(|_| {
        stepper::halt_from_isr();
        drivers_enable_raw(false);
        spindle_off_raw();
        // SAFETY: RMW of PORTH inside the critical section; coolant off.
        unsafe {
            let p = pins::COOLANT;
            core::ptr::write_volatile(p.port().port, core::ptr::read_volatile(p.port().port) & !p.mask);
        }
    });
    REALTIME.fetch_or(realtime::ESTOP, Ordering::AcqRel);
}

/// [`emergency_stop`] from inside an ISR (interrupts are off already),
/// written out to a few register writes with no call: a call in the RX ISR
/// made it save 14 more registers for every byte received.
// speed: LLVM makes it a call otherwise (14 more registers saved a byte, see above)
#[inline(always)]
pub(crate) fn emergency_stop_in_isr() {
    stepper::halt_from_isr();
    /// Drive pin `p` high (enable is active low: driver off).
    fn set_high(p: pins::Pin) {
        // SAFETY: RMW of PORTx with interrupts off (inside an ISR).
        unsafe { core::ptr::write_volatile(p.port().port, core::ptr::read_volatile(p.port().port) | p.mask) }
    }
    set_high(pins::X_ENABLE);
    set_high(pins::Y_ENABLE);
    set_high(pins::Z_ENABLE);
    set_high(pins::E_ENABLE);
    // SAFETY: RMWs of Timer2 and PORTB with interrupts off (inside an ISR).
    unsafe {
        (*TC2::ptr()).tccr2a().modify(|_, w| w.com2a().disconnected());
        let p = pins::SPINDLE_PWM;
        core::ptr::write_volatile(p.port().port, core::ptr::read_volatile(p.port().port) & !p.mask);
    }
    // SAFETY: RMW of PORTH with interrupts off (inside an ISR).
    unsafe {
        let p = pins::COOLANT;
        core::ptr::write_volatile(p.port().port, core::ptr::read_volatile(p.port().port) & !p.mask);
    }
    raise_in_isr(realtime::ESTOP);
}

// ---- Steppers enable -----------------------------------------------------

/// Enable (`true`) or disable all four stepper drivers (enable is active low).
pub fn drivers_enable(on: bool) {
    // Every queued move asks for the drivers on: when all four already are,
    // skip the critical section and the read-modify-writes.
    // SAFETY: reading PORTx has no side effects.
    let on_now = |p: pins::Pin| unsafe { core::ptr::read_volatile(p.port().port) } & p.mask == 0;
    let all_on = on_now(pins::X_ENABLE) && on_now(pins::Y_ENABLE) && on_now(pins::Z_ENABLE) && on_now(pins::E_ENABLE);
    if on && all_on {
        return;
    }
    avr_device::interrupt::free(|_| drivers_enable_raw(on));
}

/// Out of line for speed: inlined into [`drivers_enable`] (its only caller
/// since panics stopped using [`emergency_stop`]) it gave that function a
/// 32-byte frame, set up on every call, even on the all-on fast path that
/// every queued move takes: the 0.1 mm ping-pong stream went from 5.593 to
/// 5.632 s (`tools/bench`).
// speed: see above (LLVM inlines it otherwise)
#[inline(never)]
fn drivers_enable_raw(on: bool) {
    let set = |p: pins::Pin| {
        // SAFETY: RMW of PORTx; callers hold a critical section.
        unsafe {
            let v = core::ptr::read_volatile(p.port().port);
            core::ptr::write_volatile(p.port().port, if on { v & !p.mask } else { v | p.mask });
        }
    };
    set(pins::X_ENABLE);
    set(pins::Y_ENABLE);
    set(pins::Z_ENABLE);
    set(pins::E_ENABLE);
}

/// Enable (`true`) or disable the carousel (E0) driver alone (G204).
pub fn carousel_driver_enable(on: bool) {
    let p = pins::E_ENABLE;
    // SAFETY: RMW of PORTA inside a critical section (the step ISR writes
    // PORTA only through PINA toggles, which cannot interleave here).
    avr_device::interrupt::free(|_| unsafe {
        let v = core::ptr::read_volatile(p.port().port);
        core::ptr::write_volatile(p.port().port, if on { v & !p.mask } else { v | p.mask });
    });
}

/// True when the drivers are enabled (X's enable pin is low).
pub fn drivers_enabled() -> bool {
    // SAFETY: reading PORTD has no side effects.
    unsafe { core::ptr::read_volatile(pins::X_ENABLE.port().port) & pins::X_ENABLE.mask == 0 }
}

// ---- Millisecond clock (Timer0, CTC at 1 kHz) ---------------------------

/// Milliseconds since boot: written by the 1 kHz tick, read with
/// interrupts off ([`millis`]).
static mut MILLIS: u32 = 0;

fn clock_init(tc0: &TC0) {
    // CTC, clk/64, OCR0A = 249: 16 MHz / 64 / 250 = 1 kHz.
    tc0.tccr0a().write(|w| w.wgm0().ctc());
    // SAFETY: any OCR value is valid.
    tc0.ocr0a().write(|w| unsafe { w.bits(249) });
    tc0.tccr0b().write(|w| w.cs0().prescale_64());
    tc0.timsk0().write(|w| w.ocie0a().set_bit());
}

/// Milliseconds since boot (wraps after 49 days).
pub fn millis() -> u32 {
    // SAFETY: the tick, the only writer, cannot run inside the critical
    // section.
    avr_device::interrupt::free(|_| unsafe { addr_of_mut!(MILLIS).read_volatile() })
}

/// The encoder decoder, sampled by the 1 kHz tick (see `mill::ui::encoder`).
static ENCODER: Mutex<Cell<mill::ui::encoder::Decoder>> = Mutex::new(Cell::new(mill::ui::encoder::Decoder::new()));

/// The encoder's and its button's pins (all on port C).
const ENC_MASK: u8 = pins::ENC_A.mask | pins::ENC_B.mask | pins::ENC_BUTTON.mask;
const _: () = assert!(pins::ENC_A.pin_addr() == pins::ENC_B.pin_addr() && pins::ENC_A.pin_addr() == pins::ENC_BUTTON.pin_addr());
/// PINC in I/O space (`in`).
const ENC_PIN_IO: u16 = pins::ENC_A.pin_addr() - 0x20;

/// The encoder pins (masked) of the last sample when it left the decoder
/// settled, so that the same levels again change nothing
/// (`Decoder::settled`); 0xFF (never a masked level) otherwise.
static mut ENC_LAST: u8 = 0xFF;

// 1 kHz tick (`__vector_21`, TIMER0_COMPA), fast path: the millisecond
// clock, and when the encoder's pins read as in the last sample and that
// sample left the decoder settled, nothing else (a sample would change
// nothing: `settled_levels_again_change_nothing`). Written out with r24
// and SREG kept in GPIOR1/2 (`ISR_R24_IO`) and r25 pushed: ~41 cycles
// entry to `reti`, against ~157 for the Rust handler (which saved 13
// registers and sampled every tick). Otherwise the
// registers and SREG are restored and a jump enters `timer0_sample` as if
// the hardware had, so that its `reti` ends the interrupt.
//
// SAFETY: writes only MILLIS (read elsewhere with interrupts off) and
// GPIOR1/2 (the interrupts' scratch, `ISR_R24_IO`), keeps interrupts off,
// and leaves every register and SREG as it found them.
core::arch::global_asm!(
    ".pushsection .text.__vector_21,\"ax\",@progbits",
    ".global __vector_21",
    ".type __vector_21, @function",
    "__vector_21:",
    "    out  {r24_io}, r24",      // r24 and SREG kept in GPIOR1/2 (board::ISR_R24_IO)
    "    in   r24, 0x3f",          // SREG
    "    out  {sreg_io}, r24",
    "    lds  r24, {ms}",          // MILLIS += 1, a byte at a time
    "    subi r24, 0xff",
    "    sts  {ms}, r24",
    "    lds  r24, {ms}+1",
    "    sbci r24, 0xff",
    "    sts  {ms}+1, r24",
    "    lds  r24, {ms}+2",
    "    sbci r24, 0xff",
    "    sts  {ms}+2, r24",
    "    lds  r24, {ms}+3",
    "    sbci r24, 0xff",
    "    sts  {ms}+3, r24",
    "    push r25",
    "    in   r24, {pin}",
    "    andi r24, {mask}",
    "    lds  r25, {last}",
    "    cp   r24, r25",
    "    pop  r25",
    "    brne .Ltick_sample",
    "    in   r24, {sreg_io}",
    "    out  0x3f, r24",
    "    in   r24, {r24_io}",
    "    reti",
    ".Ltick_sample:",
    "    in   r24, {sreg_io}",
    "    out  0x3f, r24",
    "    in   r24, {r24_io}",
    "    jmp  {sample}",
    ".size __vector_21, . - __vector_21",
    ".popsection",
    ms = sym MILLIS,
    pin = const ENC_PIN_IO,
    mask = const ENC_MASK,
    last = sym ENC_LAST,
    sample = sym timer0_sample,
    r24_io = const ISR_R24_IO,
    sreg_io = const ISR_SREG_IO,
);

/// The 1 kHz tick's slow path: one sample of the encoder and its button
/// (PC6 A, PC4 B, PC2 button; closed contact = low). Entered from the fast
/// path by a jump, with the registers and SREG as the interrupt found
/// them; returns from the interrupt.
extern "avr-interrupt" fn timer0_sample() {
    // SAFETY: reading PINC has no side effects.
    let pinc = unsafe { core::ptr::read_volatile(pins::ENC_A.port().pin) };
    avr_device::interrupt::free(|cs| {
        let e = ENCODER.borrow(cs);
        let mut d = e.get();
        d.sample(pinc & pins::ENC_A.mask == 0, pinc & pins::ENC_B.mask == 0, pinc & pins::ENC_BUTTON.mask == 0);
        e.set(d);
        // SAFETY: only the tick writes ENC_LAST, and ISRs do not nest.
        unsafe { addr_of_mut!(ENC_LAST).write_volatile(if d.settled() { pinc & ENC_MASK } else { 0xFF }) };
    });
}

/// Encoder detents (+ = clockwise) and button presses since the last call.
pub fn take_encoder() -> (i8, u8) {
    avr_device::interrupt::free(|cs| {
        let e = ENCODER.borrow(cs);
        let mut d = e.get();
        let r = d.take();
        e.set(d);
        r
    })
}

/// The SD socket's detect switch is closed (a card is in; D49 low).
pub fn sd_detected() -> bool {
    !pins::SD_DETECT.is_high()
}

// ---- Spindle PWM (Timer2, OC2A on PB4 = D10) -----------------------------

fn spindle_init(tc2: &TC2) {
    // Fast PWM, TOP = 0xFF, clk/8: 16 MHz / 8 / 256 = 7.8 kHz. Output off.
    tc2.tccr2a().write(|w| w.wgm2().pwm_fast());
    tc2.tccr2b().write(|w| w.cs2().prescale_8());
    pins::SPINDLE_PWM.make_output(false);
    pins::COOLANT.make_output(false);
}

/// Coolant output (D9, PH6) on or off.
pub fn coolant_set(on: bool) {
    pins::COOLANT.set(on);
}

/// Set spindle PWM duty (0 = off, 255 = full).
pub fn spindle_set(duty: u8) {
    avr_device::interrupt::free(|_| {
        if duty == 0 {
            spindle_off_raw();
        } else {
            // SAFETY: Timer2 is owned by the spindle; inside a critical section.
            let tc2 = unsafe { &*TC2::ptr() };
            // SAFETY: every 8-bit value is a valid compare value.
            tc2.ocr2a().write(|w| unsafe { w.bits(duty) });
            tc2.tccr2a().modify(|_, w| w.com2a().match_clear());
        }
    });
}

/// Spindle off; callers hold a critical section (or run in an ISR).
pub(crate) fn spindle_off_raw() {
    // SAFETY: Timer2 is owned by the spindle; callers hold a critical section.
    let tc2 = unsafe { &*TC2::ptr() };
    tc2.tccr2a().modify(|_, w| w.com2a().disconnected());
    // SAFETY: RMW of PORTB in a critical section; pin forced low.
    unsafe {
        let p = pins::SPINDLE_PWM;
        let v = core::ptr::read_volatile(p.port().port);
        core::ptr::write_volatile(p.port().port, v & !p.mask);
    }
}

// ---- Inputs ----------------------------------------------------------------

/// Switch and sensor levels, already converted to "triggered".
#[derive(Clone, Copy, Default)]
pub struct Inputs {
    /// Home switches closed, bit i = axis i (X, Y, Z).
    pub home: u8,
    /// Carousel home switch closed.
    pub carousel_home: bool,
    /// Tool-setter beam interrupted.
    pub tool_setter: bool,
}

/// Read all switches (closed switch pulls low; tool setter high = blocked),
/// each inverted where `$5` says so (as the stepper ISR reads them).
pub fn inputs() -> Inputs {
    let invert = stepper::input_invert();
    Inputs {
        home: (pins::home_closed() ^ invert) & 0b111,
        carousel_home: !pins::CAROUSEL_HOME.is_high() != (invert & (1 << 3) != 0),
        tool_setter: pins::TOOL_SETTER.is_high() != (invert & (1 << 4) != 0),
    }
}

// ---- Stack painting (for the RAM report) --------------------------------

/// Byte painted over free RAM at boot; the simulator reads back how much of
/// it the stack overwrote (stack high-water mark, docs/SPEC.md §11).
pub const STACK_PAINT: u8 = 0xC5;

/// Paint the RAM between the end of .bss and the current stack with
/// [`STACK_PAINT`]. Call first thing in `main`.
pub fn paint_stack() {
    extern "C" {
        static mut __heap_start: u8;
    }
    // SAFETY: the memory between __heap_start (end of .bss, no heap is used)
    // and the current stack pointer minus a margin is unused at this point.
    unsafe {
        let start = core::ptr::addr_of_mut!(__heap_start) as usize;
        let sp = core::ptr::read_volatile(0x5D as *const u16) as usize; // SPL/SPH
        let mut p = start;
        while p + 16 < sp {
            core::ptr::write_volatile(p as *mut u8, STACK_PAINT);
            p += 1;
        }
    }
}

/// Bytes of RAM never touched by the stack since boot (0xC5 still in place).
pub fn free_ram() -> u16 {
    extern "C" {
        static mut __heap_start: u8;
    }
    // SAFETY: read-only scan of RAM above .bss.
    unsafe {
        let start = core::ptr::addr_of_mut!(__heap_start) as usize;
        let mut p = start;
        while p < 0x2200 && core::ptr::read_volatile(p as *const u8) == STACK_PAINT {
            p += 1;
        }
        (p - start) as u16
    }
}

/// Stack bytes left before static RAM plus the stack would pass the RAM
/// budget (memory.x's `__mill_ram_budget`, docs/SPEC.md §11): how deep a
/// call made from here may still go.
pub fn stack_room() -> u16 {
    extern "C" {
        static mut __heap_start: u8;
        static __mill_ram_budget: u8;
    }
    // SAFETY: only the symbols' addresses are taken (`__mill_ram_budget` is
    // an absolute symbol: its address is the budget), and SPL/SPH are read.
    unsafe {
        let statics = core::ptr::addr_of_mut!(__heap_start) as usize - 0x200;
        let budget = core::ptr::addr_of!(__mill_ram_budget) as usize;
        let stack = 0x21FF - core::ptr::read_volatile(0x5D as *const u16) as usize; // SPL/SPH
        budget.saturating_sub(statics + stack) as u16
    }
}

/// Bring up every peripheral the firmware uses. Interrupts stay disabled.
pub fn init(dp: &Peripherals) {
    // One call per pin, not a loop over a table of pins (a RAM copy on AVR).
    use pins::*;
    let (low, off) = (|p: Pin| p.make_output(false), |p: Pin| p.make_output(true));
    low(X_STEP);
    low(Y_STEP);
    low(Z_STEP);
    low(E_STEP);
    low(X_DIR);
    low(Y_DIR);
    low(Z_DIR);
    low(E_DIR);
    // Drivers disabled (enable is active low).
    off(X_ENABLE);
    off(Y_ENABLE);
    off(Z_ENABLE);
    off(E_ENABLE);
    X_HOME.make_input_pullup();
    Y_HOME.make_input_pullup();
    Z_HOME.make_input_pullup();
    CAROUSEL_HOME.make_input_pullup();
    TOOL_SETTER.make_input_pullup();
    ENC_A.make_input_pullup();
    ENC_B.make_input_pullup();
    ENC_BUTTON.make_input_pullup();
    SD_DETECT.make_input_pullup();
    serial::init(&dp.USART0, serial::BUILD_BAUD);
    clock_init(&dp.TC0);
    spindle_init(&dp.TC2);
    stepper::init(&dp.TC1);
}
