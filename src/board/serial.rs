//! USART0, the host serial port (SPEC §4), interrupt driven (datasheet §22).
//!
//! RX: the `USART0_RX` ISR takes every byte as it arrives. Realtime bytes
//! (`?` `!` `~`) become bits in [`super::REALTIME`] and never reach the ring;
//! `M112` is spotted by `protocol::EstopScanner` and stops the machine from
//! inside the ISR, and `M108` (continue after M0) sets the resume bit; both
//! lines also reach the ring and run as usual. Other bytes go into a 256-byte
//! single-producer ring (indexed by a `u8`, see [`rx_store`]) whose consumer
//! is the main loop. If the ring is full the byte is dropped, and a
//! gap marker (`protocol::RX_GAP`) is stored before the next byte that fits,
//! so the line assembler drops exactly the damaged line instead of running
//! it: the ring itself can never overflow.
//!
//! TX: [`write`] queues bytes in a 128-byte ring drained by `USART0_UDRE`.
//! While the ring is full the writer runs a wait hook (the firmware's feeds
//! the watchdog); the segment ring holds enough motion to cover a full TX
//! ring draining (128 bytes = 5 ms at 250000 baud).

use super::{realtime, REALTIME};
use avr_device::atmega2560::USART0;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicU8, Ordering};
use heapless::spsc::{Consumer, Producer, Queue};
use mill::protocol::{ContinueScanner, EstopScanner, RxStore};

/// RX ring slots; one stays free, so 255 bytes are usable. A
/// character-counting host may keep this many bytes in flight. RAM: 256 + 2 B.
pub const RX_LEN: usize = 256;
/// TX ring capacity + 1.
pub const TX_LEN: usize = 128;

/// The RX ring. Indexed by a `u8`, so 256 slots wrap for free; the ISR
/// writes slot `RX_HEAD` and then advances it, the main loop reads slot
/// `RX_TAIL` and then advances that. Each index has one writer and a `u8`
/// load or store is a single instruction, so neither side needs a critical
/// section (heapless' `spsc` took ~100 cycles per byte in the ISR here).
static mut RX_BUF: [u8; RX_LEN] = [0; RX_LEN];
/// Next RX slot to write (ISR only).
static RX_HEAD: AtomicU8 = AtomicU8::new(0);
/// Next RX slot to read (main loop only).
static RX_TAIL: AtomicU8 = AtomicU8::new(0);
const _: () = assert!(RX_LEN == u8::MAX as usize + 1);

/// Store `b` in the RX ring; false when it is full (RX ISR only).
#[inline(always)]
fn rx_store(b: u8) -> bool {
    let head = RX_HEAD.load(Ordering::Relaxed);
    let next = head.wrapping_add(1);
    if next == RX_TAIL.load(Ordering::Acquire) {
        return false;
    }
    // SAFETY: only this ISR writes the ring, and slot `head` is outside the
    // readable range `RX_TAIL..RX_HEAD` until the store below publishes it.
    unsafe { (*addr_of_mut!(RX_BUF))[head as usize] = b };
    RX_HEAD.store(next, Ordering::Release);
    true
}

static mut TX: Queue<u8, TX_LEN> = Queue::new();
// Ends of the TX ring: the producer is the main loop's, the consumer the
// UDRE ISR's.
static mut TX_PROD: Option<Producer<'static, u8, TX_LEN>> = None;
static mut TX_CONS: Option<Consumer<'static, u8, TX_LEN>> = None;
static mut ESTOP_SCAN: EstopScanner = EstopScanner::new();
static mut CONTINUE_SCAN: ContinueScanner = ContinueScanner::new();
/// The RX ISR's gap-marking store (one byte).
static mut RX_STORE: RxStore = RxStore::new();
/// Run while waiting for TX space (set by main).
static mut TX_WAIT_HOOK: fn() = || {};

/// Baud rates the firmware offers. 250000 is the default (Repetier's).
#[derive(Clone, Copy)]
pub enum Baud {
    B250000,
    B115200,
}

/// Set up USART0 (8N1, U2X) and the rings. Call once, interrupts off.
pub fn init(usart: &USART0, baud: Baud) {
    // SAFETY: called once at boot with interrupts disabled; nothing else
    // holds references into the queues yet.
    unsafe {
        let (p, c) = (*addr_of_mut!(TX)).split();
        *addr_of_mut!(TX_PROD) = Some(p);
        *addr_of_mut!(TX_CONS) = Some(c);
    }
    // U2X: baud = 16 MHz / (8 (UBRR + 1)). 7 -> 250000 exactly; 16 -> 117647 (+2.1 %).
    let ubrr = match baud {
        Baud::B250000 => 7,
        Baud::B115200 => 16,
    };
    // SAFETY: any UBRR value is valid.
    usart.ubrr0().write(|w| unsafe { w.bits(ubrr) });
    usart.ucsr0a().write(|w| w.u2x0().set_bit());
    usart.ucsr0c().write(|w| w.ucsz0().chr8());
    usart.ucsr0b().write(|w| w.rxen0().set_bit().txen0().set_bit().rxcie0().set_bit());
}

/// Set the function run while waiting for TX space.
pub fn set_tx_wait_hook(f: fn()) {
    // SAFETY: written by the main loop only, read by the main loop only.
    unsafe { *addr_of_mut!(TX_WAIT_HOOK) = f };
}

/// Next received byte, if any (main loop only).
#[inline]
pub fn read() -> Option<u8> {
    let tail = RX_TAIL.load(Ordering::Relaxed);
    if tail == RX_HEAD.load(Ordering::Acquire) {
        return None;
    }
    // SAFETY: slot `tail` was published by the ISR (it is before RX_HEAD),
    // and the ISR does not write it again until RX_TAIL moves past it below.
    let b = unsafe { (*addr_of_mut!(RX_BUF))[tail as usize] };
    RX_TAIL.store(tail.wrapping_add(1), Ordering::Release);
    Some(b)
}

/// Bytes waiting in the RX ring.
pub fn rx_len() -> usize {
    RX_HEAD.load(Ordering::Acquire).wrapping_sub(RX_TAIL.load(Ordering::Relaxed)) as usize
}

/// Queue bytes for sending; waits (running the wait hook) while the ring is full.
pub fn write(bytes: &[u8]) {
    for &b in bytes {
        loop {
            // SAFETY: the TX producer is only used from the main loop.
            let ok = unsafe { (*addr_of_mut!(TX_PROD)).as_mut().map_or(true, |p| p.enqueue(b).is_ok()) };
            if ok {
                break;
            }
            kick_tx();
            // SAFETY: the hook is a plain fn set by the main loop.
            unsafe { (*addr_of_mut!(TX_WAIT_HOOK))() };
        }
    }
    kick_tx();
}

/// True when every queued byte has left the TX ring.
pub fn tx_empty() -> bool {
    // SAFETY: main loop only.
    unsafe { (*addr_of_mut!(TX_PROD)).as_ref().map_or(true, |p| p.len() == 0) }
}

/// Enable the data-register-empty interrupt so the ISR drains the ring.
fn kick_tx() {
    avr_device::interrupt::free(|_| {
        // SAFETY: UCSR0B RMW inside a critical section; the UDRE ISR also
        // writes it, but never while interrupts are off.
        let u = unsafe { &*USART0::ptr() };
        u.ucsr0b().modify(|_, w| w.udrie0().set_bit());
    });
}

/// A `ufmt` writer onto the serial port.
pub struct Writer;

impl ufmt::uWrite for Writer {
    type Error = core::convert::Infallible;
    fn write_str(&mut self, s: &str) -> Result<(), Self::Error> {
        write(s.as_bytes());
        Ok(())
    }
}

// RX complete. Measured with the realtime scan: see README "ISR budgets".
#[avr_device::interrupt(atmega2560)]
fn USART0_RX() {
    // SAFETY: the ISR is the only user of USART0's data register for reading.
    let u = unsafe { &*USART0::ptr() };
    let lost = u.ucsr0a().read().dor0().bit_is_set();
    let b = u.udr0().read().bits();
    if lost {
        // SAFETY: RX_STORE is only used by this ISR.
        unsafe { (*addr_of_mut!(RX_STORE)).note_loss() };
    }
    match b {
        b'?' => REALTIME.fetch_or(realtime::STATUS, portable_atomic::Ordering::AcqRel),
        b'!' => REALTIME.fetch_or(realtime::HOLD, portable_atomic::Ordering::AcqRel),
        b'~' => REALTIME.fetch_or(realtime::RESUME, portable_atomic::Ordering::AcqRel),
        _ => {
            // SAFETY: the scanner and RX producer are only used by this ISR.
            unsafe {
                if (*addr_of_mut!(ESTOP_SCAN)).feed(b) {
                    super::emergency_stop_in_isr();
                }
                // M108 continues after M0/M1 even though the line waits in
                // the ring behind the pause (Marlin's emergency parser).
                if (*addr_of_mut!(CONTINUE_SCAN)).feed(b) {
                    REALTIME.fetch_or(realtime::RESUME, portable_atomic::Ordering::AcqRel);
                }
                (*addr_of_mut!(RX_STORE)).store(b, rx_store);
            }
            0
        }
    };
}

// TX data register empty: send the next byte or switch the interrupt off.
#[avr_device::interrupt(atmega2560)]
fn USART0_UDRE() {
    // SAFETY: the TX consumer is only used by this ISR; UCSR0B is modified
    // here with interrupts already disabled (ISRs do not nest).
    unsafe {
        let u = &*USART0::ptr();
        match (*addr_of_mut!(TX_CONS)).as_mut().and_then(|c| c.dequeue()) {
            Some(b) => {
                u.udr0().write(|w| w.bits(b));
            }
            None => {
                u.ucsr0b().modify(|_, w| w.udrie0().clear_bit());
            }
        }
    }
}
