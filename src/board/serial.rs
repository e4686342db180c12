//! USART0, the host serial port (docs/SPEC.md §4), interrupt driven (datasheet §22).
//!
//! RX: the `USART0_RX` interrupt takes every byte as it arrives. Realtime
//! bytes (`?` `!` `~` outside comments and numbered lines, and 0x18 anywhere:
//! `protocol::RxText` decides) become bits in [`super::REALTIME`] and never
//! reach the ring; `M112` is spotted by `protocol::MCodeScanner` and stops the machine
//! from inside the ISR, and `M108` (continue after M0) sets the resume bit;
//! both lines also reach the ring and run as usual. Other bytes go into a
//! 256-byte single-producer ring (indexed by a `u8`, see [`rx_store`]) whose
//! consumer is the main loop. If the ring is full the byte is dropped, and a
//! gap marker (`protocol::RX_GAP`) is stored before the next byte that fits,
//! so the line assembler drops exactly the damaged line instead of running
//! it: the ring itself can never overflow. A dropped line end is counted and
//! stored later as a marker and a `\n` ([`store_lost_ends`]), so every line
//! the host sent still gets its one reply.
//!
//! The interrupt has two halves: a fast path in assembly (`__vector_25`)
//! stores the usual byte (a digit, a letter other than M, a blank, ...) in
//! 72 cycles, and hands every other byte to the slow path in Rust
//! (`usart0_rx_slow`), which does all of the above.
//!
//! TX: [`write`] queues bytes in a 128-byte ring drained by `USART0_UDRE`.
//! While the ring is full the writer runs a wait hook (the firmware's feeds
//! the watchdog); the segment ring holds enough motion to cover a full TX
//! ring draining (128 bytes = 5 ms at 250000 baud).

use super::{raise_in_isr, realtime};
use avr_device::atmega2560::USART0;
use core::ptr::addr_of_mut;
use mill::protocol::{rx_fast_mode, MCodeScanner, RxBytes, RxStore, RxText, Urgent, RX_ALL_SLOW, RX_FAST, RX_LINE_START, SOFT_RESET};
use portable_atomic::{AtomicU8, Ordering};

/// RX ring slots; one stays free, so 255 bytes are usable. A
/// character-counting host may keep this many bytes in flight. RAM: 256 + 2 B.
pub const RX_LEN: usize = 256;
/// TX ring slots (capacity + 1). RAM: 128 + 3 B.
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
fn rx_store(b: u8) -> bool {
    // Volatile accesses instead of the atomics' loads and stores: those
    // bracket each access with `cli`/`out SREG` on AVR, and interrupts are
    // off in the ISR anyway. A `u8` access is a single instruction, and
    // volatile accesses stay in program order (slot, then head).
    let head = RX_HEAD.as_ptr();
    let tail = RX_TAIL.as_ptr();
    // SAFETY: the ISR is the only writer of RX_HEAD and of the slot it
    // points at, which is outside the readable range `RX_TAIL..RX_HEAD`
    // until the head store below publishes it; RX_TAIL is only read.
    unsafe {
        let h = head.read_volatile();
        let next = h.wrapping_add(1);
        if next == tail.read_volatile() {
            return false;
        }
        addr_of_mut!(RX_BUF).cast::<u8>().add(h as usize).write_volatile(b);
        head.write_volatile(next);
    }
    true
}

/// The TX ring, like the RX one but indexed modulo [`TX_LEN`]: the main
/// loop writes slot `TX_HEAD` and then advances it, the UDRE ISR sends slot
/// `TX_TAIL` and then advances that; one slot stays free (127 bytes usable,
/// as with the `heapless` queue it replaces, whose atomics took a critical
/// section per index access: ~66 cycles a byte queued and ~90 a byte sent,
/// now about a third of that).
static mut TX_BUF: [u8; TX_LEN] = [0; TX_LEN];
/// Next TX slot to write (main loop only).
static TX_HEAD: AtomicU8 = AtomicU8::new(0);
/// Next TX slot to send (UDRE ISR only).
static TX_TAIL: AtomicU8 = AtomicU8::new(0);
/// Non-zero once [`init`] ran: bytes written before are dropped.
static TX_READY: AtomicU8 = AtomicU8::new(0);
const _: () = assert!(TX_LEN.is_power_of_two() && TX_LEN <= 128);
/// `i + 1` modulo [`TX_LEN`].
fn tx_next(i: u8) -> u8 {
    i.wrapping_add(1) & (TX_LEN as u8 - 1)
}
/// The RX ISR's watch for M112 and M108 (one byte).
static mut MCODE_SCAN: MCodeScanner = MCodeScanner::new();
/// The last byte fed to `MCODE_SCAN` (written by both RX paths).
static mut RX_PREV: u8 = 0;
/// The RX ISR's gap-marking store (one byte).
static mut RX_STORE: RxStore = RxStore::new();
/// The RX ISR's view of the line (comment, numbered line), which decides
/// whether `?` `!` `~` are realtime commands or text (one byte).
static mut RX_TEXT: RxText = RxText::new();
/// What the fast path may do with the next byte (`protocol::rx_fast_mode`):
/// `RX_ALL_SLOW` while a match is in progress in `MCODE_SCAN` or a gap
/// marker is pending in `RX_STORE`, else `RX_LINE_START` at the start of a
/// line in `RX_TEXT`, else `RX_FAST` (written by both paths).
static mut RX_SLOW: u8 = RX_LINE_START; // `RX_TEXT` starts at a line start
/// The byte the fast path hands to the slow path.
static mut RX_IN: u8 = 0;
/// Non-zero when bytes were lost before `RX_IN` (UCSR0A, with DOR0 set).
static mut RX_IN_LOST: u8 = 0;
/// Run while waiting for TX space (set by main).
static mut TX_WAIT_HOOK: fn() = || {};

/// Baud rates the firmware offers. 250000 is the default (Repetier's);
/// [`BUILD_BAUD`] picks one at build time.
#[derive(Clone, Copy)]
pub enum Baud {
    B250000,
    B115200,
}

/// The host baud rate of this build: `MILL_BAUD` at build time
/// (`MILL_BAUD=115200 tools/build-firmware`), 250000 if unset; any other
/// value fails the build.
pub const BUILD_BAUD: Baud = match option_env!("MILL_BAUD") {
    None => Baud::B250000,
    Some(v) if same(v, "250000") => Baud::B250000,
    Some(v) if same(v, "115200") => Baud::B115200,
    Some(_) => panic!("MILL_BAUD must be 250000 or 115200"),
};

/// `a == b` for the const above.
const fn same(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Set up USART0 (8N1, U2X) and the rings. Call once, interrupts off.
pub fn init(usart: &USART0, baud: Baud) {
    // SAFETY: a `u8` store; the TX ring is empty at boot.
    unsafe { TX_READY.as_ptr().write_volatile(1) };
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

/// Next received byte, if any (main loop only). Always inlined into the
/// line assembler's loop: as a call (LLVM's choice once `push_bytes` grew)
/// it cost ~47 cycles a byte, ~840 a streamed line (`profile --trace`).
// speed: ~47 cycles a byte as a call (see above); LLVM makes it one
#[inline(always)]
pub fn read() -> Option<u8> {
    // Volatile accesses instead of the atomics' loads and stores, as in
    // `rx_store`: those bracket each access with `cli`/`out SREG` on AVR
    // (~12 cycles a byte). A `u8` access is a single instruction, and
    // volatile accesses stay in program order (head, slot, then tail).
    let (head, tail) = (RX_HEAD.as_ptr(), RX_TAIL.as_ptr());
    // SAFETY: the main loop is the only writer of RX_TAIL; slot `t` was
    // published by the ISR (it is before RX_HEAD, read before the slot),
    // and the ISR does not write it again until RX_TAIL moves past it below.
    unsafe {
        let t = tail.read_volatile();
        if t == head.read_volatile() {
            return None;
        }
        let b = addr_of_mut!(RX_BUF).cast::<u8>().add(t as usize).read_volatile();
        tail.write_volatile(t.wrapping_add(1));
        Some(b)
    }
}

/// The RX ring as the line assembler's source ([`RxBytes`]): [`read`]
/// for a byte, and the run of usual bytes copied into the line in one call
/// (`mill_rx_take_usual`, below).
pub struct Rx;

impl RxBytes for Rx {
    // speed: in the assembler's per-byte loop (see `read`)
    #[inline(always)]
    fn next_byte(&mut self) -> Option<u8> {
        read()
    }

    // speed: once per run of usual bytes; the call is the assembly's
    #[inline(always)]
    fn take_usual(&mut self, dst: &mut [u8], started: bool) -> usize {
        extern "C" {
            fn mill_rx_take_usual(dst: *mut u8, room: u16, started: u8) -> u16;
        }
        // SAFETY: writes at most `room` bytes at `dst` (the slice's), reads
        // the ring's published slots and moves RX_TAIL past what it took,
        // as `read` does, from the main loop only; avr-gcc's calling
        // convention (only call-clobbered registers changed, r1 zero).
        (unsafe { mill_rx_take_usual(dst.as_mut_ptr(), dst.len() as u16, started as u8) }) as usize
    }
}

// `protocol::take_usual_plain` over the RX ring, in assembly: from
// RX_TAIL to the RX_HEAD read once (bytes that arrive meanwhile wait for
// the next call), at most `room` (r23:r22) of them, each byte that
// `protocol::usual` takes (`started` in r20, set by the first) stored at
// X from `dst` (r25:r24); RX_TAIL written after each byte, as `read`
// does, so that the interrupt sees the slot free at once. Z walks the ring
// and wraps with the tail. Returns the count in r25:r24. ~17 cycles a
// digit, ~21 a letter (26.6 a byte on the test's random rings, the calls
// included), against ~30 in the assembler's Rust loop: `profile
// --count 254 --feed 12000 --accel 5000 --trace 300:1500` 18 061 -> 17 888
// cycles a line. `tests/soft_float.rs` runs it in the ELF against the twin.
//
// SAFETY: reads the ring's published slots and the indices, writes at most
// `room` bytes at `dst` and RX_TAIL (the main loop's index); changes only
// call-clobbered registers (r18–r27, r30, r31); r1 stays zero.
core::arch::global_asm!(
    ".pushsection .text.mill_rx_take_usual,\"ax\",@progbits",
    ".global mill_rx_take_usual",
    ".type mill_rx_take_usual, @function",
    "mill_rx_take_usual:",
    "    lds  r21, {tail}",         // t
    "    lds  r19, {head}",         // h
    "    mov  r18, r21",            // t at the start
    "    movw r26, r24",            // X: dst
    "    tst  r23",                 // room ≥ 256: everything waiting fits
    "    brne .Ltu_start",
    "    mov  r25, r19",
    "    sub  r25, r21",            // bytes waiting
    "    cp   r22, r25",
    "    brsh .Ltu_start",
    "    mov  r19, r21",            // only room of them: h = t + room
    "    add  r19, r22",
    ".Ltu_start:",
    "    ldi  r30, lo8({buf})",
    "    ldi  r31, hi8({buf})",
    "    add  r30, r21",
    "    adc  r31, r1",
    ".Ltu_loop:",
    "    cp   r21, r19",
    "    breq .Ltu_done",
    "    ld   r24, Z+",
    "    mov  r25, r24",            // '+' to ':' (digits, '.', '-')
    "    subi r25, 0x2b",
    "    cpi  r25, 0x10",
    "    brlo .Ltu_take",
    "    mov  r25, r24",            // '<' to '~' (the letters)
    "    subi r25, 0x3c",
    "    cpi  r25, 0x43",
    "    brlo .Ltu_take",
    "    mov  r25, r24",            // '!' to '\''
    "    subi r25, 0x21",
    "    cpi  r25, 0x07",
    "    brlo .Ltu_take",
    "    cpi  r24, 0x20",           // a blank, once the line holds a byte
    "    breq .Ltu_blank",
    "    cpi  r24, 0x09",
    "    brne .Ltu_done",
    ".Ltu_blank:",
    "    tst  r20",
    "    breq .Ltu_done",
    ".Ltu_take:",
    "    st   X+, r24",
    "    ldi  r20, 1",
    "    inc  r21",
    "    sts  {tail}, r21",
    "    brne .Ltu_loop",
    "    ldi  r30, lo8({buf})",     // the tail wrapped: so does Z
    "    ldi  r31, hi8({buf})",
    "    rjmp .Ltu_loop",
    ".Ltu_done:",
    "    mov  r24, r21",
    "    sub  r24, r18",
    "    clr  r25",
    "    ret",
    ".size mill_rx_take_usual, . - mill_rx_take_usual",
    ".popsection",
    tail = sym RX_TAIL,
    head = sym RX_HEAD,
    buf = sym RX_BUF,
);

/// Store the line ends the RX ISR had to drop with a full ring
/// (`RxStore::store_lost_ends`), as soon as there is room (main loop, once
/// a turn: the ISR stores them before the next byte, but a host waiting
/// for the reply to the line they ended sends none). `forget`: drop them
/// instead, after a soft reset flushed the ring.
pub fn store_lost_ends(forget: bool) {
    // SAFETY: a `u8` volatile load; `RX_SLOW` is `RX_ALL_SLOW` while
    // anything is pending in `RX_STORE`.
    if unsafe { addr_of_mut!(RX_SLOW).read_volatile() } != RX_ALL_SLOW {
        return;
    }
    avr_device::interrupt::free(|_| {
        // SAFETY: interrupts are off, so the RX ISR, the only other user of
        // these statics and of `rx_store`, cannot run.
        let (scan, store, text) = unsafe { (&*addr_of_mut!(MCODE_SCAN), &mut *addr_of_mut!(RX_STORE), &*addr_of_mut!(RX_TEXT)) };
        if forget {
            store.forget_lost_ends();
        } else {
            store.store_lost_ends(&mut rx_store);
        }
        // SAFETY: as above.
        unsafe { addr_of_mut!(RX_SLOW).write_volatile(rx_fast_mode(scan, store, text)) };
    });
}

/// Bytes waiting in the RX ring.
pub fn rx_len() -> usize {
    RX_HEAD.load(Ordering::Acquire).wrapping_sub(RX_TAIL.load(Ordering::Relaxed)) as usize
}

/// Queue bytes for sending; waits (running the wait hook) while the ring is full.
///
/// A byte that finds the ring empty and the data register free goes
/// straight into UDR0, as the hardware allows at any time: no ring slot
/// and no interrupt for it. On the chip, whose transmitter is
/// double-buffered, an `ok` is then one interrupt (its newline), not four;
/// in the VM, whose transmitter is not, two (−104 cycles a streamed line,
/// `profile --trace`). Bytes keep their order: UDR0 is written only when
/// everything queued before has left the ring, and the interrupt sends
/// from the ring alone.
pub fn write(bytes: &[u8]) {
    let (head, tail) = (TX_HEAD.as_ptr(), TX_TAIL.as_ptr());
    // SAFETY: `u8` volatile accesses (single instructions, kept in program
    // order). The main loop is the only writer of TX_HEAD and of the slot
    // it points at, which is outside the range `TX_TAIL..TX_HEAD` the ISR
    // sends from until the head store below publishes it; TX_TAIL is only
    // read here. UDR0 is written only while the ring is empty, when the
    // ISR (which writes it only from the ring) has nothing to send.
    unsafe {
        if TX_READY.as_ptr().read_volatile() == 0 {
            return;
        }
        let usart = &*USART0::ptr();
        let mut queued = false;
        for &b in bytes {
            if !queued && head.read_volatile() == tail.read_volatile() && usart.ucsr0a().read().udre0().bit_is_set() {
                usart.udr0().write(|w| w.bits(b));
                continue;
            }
            queued = true;
            loop {
                let h = head.read_volatile();
                let next = tx_next(h);
                if next != tail.read_volatile() {
                    addr_of_mut!(TX_BUF).cast::<u8>().add(h as usize).write_volatile(b);
                    head.write_volatile(next);
                    break;
                }
                kick_tx();
                (*addr_of_mut!(TX_WAIT_HOOK))();
            }
        }
        if queued {
            kick_tx();
        }
    }
}

/// True when every queued byte has left the TX ring.
pub fn tx_empty() -> bool {
    // SAFETY: `u8` volatile loads.
    unsafe { TX_HEAD.as_ptr().read_volatile() == TX_TAIL.as_ptr().read_volatile() }
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

/// USART0 status register A and data register, data-space addresses, and
/// the data overrun bit of UCSR0A (datasheet §22.10).
const UCSR0A: u16 = 0xC0;
const UDR0: u16 = 0xC6;
const DOR0: u8 = 3;

// RX complete (`__vector_25`), fast path. A byte from 0x20 to 0x7D other
// than `!` `?` `(` `)` `;` `M` `m`, with no loss, no M-code match in
// progress, no gap marker pending and not at the start of a line, goes
// straight into the ring and `RX_PREV`: that is what the slow path does for
// it (`MCodeScanner::ignores` it, `RxText::classify` leaves its state alone,
// `protocol::tests::the_fast_path_bytes_change_nothing`, and
// `RxStore::store` with no gap pending is a plain enqueue), written out
// with 2 registers pushed and r24 and SREG kept in GPIOR1/2
// (`board::ISR_R24_IO`) instead of the 9 the Rust handler saves (a Rust
// ISR saves every register any of its paths uses). The two bytes of every
// line that change `RX_TEXT` are also taken here when nothing else is
// pending (`RX_SLOW` is `RX_FAST` or `RX_LINE_START`): a line end (`\n`,
// `\r`) is stored and sets `RX_TEXT` to a line start, and at a line start
// the first byte (one of the usual bytes, not a blank, `N` or `n`) is
// stored and sets it to mid-line, as `classify` would
// (`protocol::tests::the_fast_path_line_ends_and_line_starts`; the twin
// `the_fast_path_twin_matches_the_slow_path` runs this code's steps, in
// Rust, against the slow path over random streams). Any other byte, and a
// full ring, goes to `usart0_rx_slow`: the registers and SREG are
// restored, the byte and the loss are left in `RX_IN` / `RX_IN_LOST`, and
// a jump enters the slow path as if the hardware had, so that its `reti`
// ends the interrupt.
//
// Budget: 68 cycles per ordinary byte, entry to `reti` (72 with r24 and
// SREG pushed, 64 before the comment/numbered-line tracking of `RxText`;
// 164 in Rust alone), 56 for a digit, `.` or `-` (tested first: most of a
// G-code line), ~76 for a line end or a line's first byte (~200 through
// the slow path). Per
// streamed G1 line (`cargo run -p sim --release --bin profile -- --trace
// 500:300`, `__vector_25` inclusive): see docs/ARCHITECTURE.md "Benchmark". A byte
// for the slow path costs ~34 cycles here plus ~165 in `usart0_rx_slow`.
//
// SAFETY: the fast path writes only what the RX interrupt owns (the ring
// slot at RX_HEAD, then RX_HEAD, and RX_PREV / RX_TEXT / RX_SLOW / RX_IN /
// RX_IN_LOST) and GPIOR1/2 (the interrupts' scratch, `board::ISR_R24_IO`),
// keeps interrupts off, and leaves every register and SREG as it found
// them. `RxText` is `repr(transparent)` over its state byte.
core::arch::global_asm!(
    // Store r24 in the ring and RX_PREV (r25, r30, r31 free; r30 and r31
    // pushed); a full ring jumps to .Lrx_full.
    ".macro rx_put",
    "    lds  r30, {head}",
    "    mov  r25, r30",
    "    inc  r25",
    "    lds  r31, {tail}",
    "    cp   r25, r31",           // head + 1 == tail: full
    "    breq .Lrx_full",
    "    ldi  r31, 0",
    "    subi r30, lo8(-({buf}))",
    "    sbci r31, hi8(-({buf}))",
    "    st   Z, r24",             // the slot, then the head that publishes it
    "    sts  {head}, r25",
    "    sts  {prev}, r24",
    ".endm",
    ".pushsection .text.__vector_25,\"ax\",@progbits",
    ".global __vector_25",
    ".type __vector_25, @function",
    "__vector_25:",
    "    out  {r24_io}, r24",      // r24 and SREG kept in GPIOR1/2 (board::ISR_R24_IO)
    "    in   r24, 0x3f",          // SREG
    "    out  {sreg_io}, r24",
    "    push r25",
    "    lds  r25, {ucsr0a}",
    "    lds  r24, {udr0}",
    "    sbrc r25, {dor0}",        // bytes lost before this one
    "    rjmp .Lrx_lost",
    "    mov  r25, r24",           // '*' to ':' (digits, '.', '-'): usual,
    "    subi r25, 0x2a",          // most of a G-code line, one test
    "    cpi  r25, 0x11",
    "    brlo .Lrx_usual",
    "    cpi  r24, 0x7e",          // '~', DEL, non-ASCII (0xFF is stored as 0xFE)
    "    brsh .Lrx_slow",
    "    cpi  r24, 0x20",          // control bytes: line ends, tab, Ctrl-X
    "    brlo .Lrx_ctl",
    "    cpi  r24, 0x21",          // '!'
    "    breq .Lrx_slow",
    "    cpi  r24, 0x3f",          // '?'
    "    breq .Lrx_slow",
    "    cpi  r24, 0x3b",          // ';' starts a comment
    "    breq .Lrx_slow",
    "    mov  r25, r24",
    "    andi r25, 0xfe",
    "    cpi  r25, 0x28",          // '(' or ')'
    "    breq .Lrx_slow",
    "    mov  r25, r24",
    "    ori  r25, 0x20",
    "    cpi  r25, 0x6d",          // 'M' or 'm'
    "    breq .Lrx_slow",
    ".Lrx_usual:",
    "    lds  r25, {slow}",
    "    tst  r25",                // RX_FAST
    "    brne .Lrx_start",
    ".Lrx_plain:",
    "    push r30",
    "    push r31",
    "    rx_put",
    "    pop  r31",
    "    pop  r30",
    ".Lrx_done:",
    "    pop  r25",
    "    in   r24, {sreg_io}",
    "    out  0x3f, r24",
    "    in   r24, {r24_io}",
    "    reti",
    ".Lrx_full:",
    "    pop  r31",
    "    pop  r30",
    ".Lrx_slow:",
    "    clr  r25",
    ".Lrx_lost:",
    "    sts  {lost}, r25",
    "    sts  {byte}, r24",
    "    pop  r25",
    "    in   r24, {sreg_io}",
    "    out  0x3f, r24",
    "    in   r24, {r24_io}",
    "    jmp  {slow_path}",
    // A control byte: a line end is taken here unless all goes slow. (The
    // blocks sit here, after the usual byte's path, within the branches'
    // reach of ±64 words.)
    ".Lrx_ctl:",
    "    cpi  r24, 0x0a",          // '\n'
    "    breq .Lrx_eol",
    "    cpi  r24, 0x0d",          // '\r'
    "    brne .Lrx_slow",
    ".Lrx_eol:",
    "    lds  r25, {slow}",
    "    cpi  r25, {all_slow}",
    "    brne .Lrx_mark",
    "    rjmp .Lrx_slow",
    // A usual byte while RX_SLOW is not RX_FAST.
    ".Lrx_start:",
    "    cpi  r25, {line_start}",
    "    brne .Lrx_slow",          // RX_ALL_SLOW
    "    cpi  r24, 0x20",          // a blank keeps the line start
    "    breq .Lrx_plain",
    "    mov  r25, r24",
    "    ori  r25, 0x20",
    "    cpi  r25, 0x6e",          // 'N' or 'n' may number the line
    "    breq .Lrx_slow",
    // Store, then a line end starts a line and another byte begins one.
    ".Lrx_mark:",
    "    push r30",
    "    push r31",
    "    rx_put",
    "    cpi  r24, 0x20",
    "    brlo .Lrx_marked_end",
    "    ldi  r25, {mid_line}",
    "    sts  {text}, r25",
    "    ldi  r25, {fast}",
    "    sts  {slow}, r25",
    "    pop  r31",
    "    pop  r30",
    "    rjmp .Lrx_done",
    ".Lrx_marked_end:",
    "    ldi  r25, {start_state}",
    "    sts  {text}, r25",
    "    ldi  r25, {line_start}",
    "    sts  {slow}, r25",
    "    pop  r31",
    "    pop  r30",
    "    rjmp .Lrx_done",
    ".size __vector_25, . - __vector_25",
    ".popsection",
    ".purgem rx_put",
    ucsr0a = const UCSR0A,
    udr0 = const UDR0,
    dor0 = const DOR0,
    slow = sym RX_SLOW,
    head = sym RX_HEAD,
    tail = sym RX_TAIL,
    buf = sym RX_BUF,
    prev = sym RX_PREV,
    text = sym RX_TEXT,
    lost = sym RX_IN_LOST,
    byte = sym RX_IN,
    slow_path = sym usart0_rx_slow,
    r24_io = const super::ISR_R24_IO,
    sreg_io = const super::ISR_SREG_IO,
    fast = const RX_FAST,
    all_slow = const RX_ALL_SLOW,
    line_start = const RX_LINE_START,
    start_state = const RxText::LINE_START,
    mid_line = const RxText::MID_LINE,
);

/// RX complete, slow path: realtime bytes, the M-code scanner, losses and
/// a full ring. Entered from the fast path by a jump, with the registers
/// and SREG as the interrupt found them; returns from the interrupt.
extern "avr-interrupt" fn usart0_rx_slow() {
    // Volatile: the fast path's assembly writes these, out of the
    // compiler's sight.
    // SAFETY: the RX statics are only used by the RX interrupt, and ISRs
    // do not nest.
    let (b, lost, prev) = unsafe {
        (addr_of_mut!(RX_IN).read_volatile(), addr_of_mut!(RX_IN_LOST).read_volatile() != 0, addr_of_mut!(RX_PREV).read_volatile())
    };
    // SAFETY: as above.
    let (scan, store, text) = unsafe { (&mut *addr_of_mut!(MCODE_SCAN), &mut *addr_of_mut!(RX_STORE), &mut *addr_of_mut!(RX_TEXT)) };
    if lost {
        store.note_loss();
        text.note_loss();
    }
    if text.classify(b) {
        raise_in_isr(match b {
            b'?' => realtime::STATUS,
            b'!' => realtime::HOLD,
            b'~' => realtime::RESUME,
            0x85 => realtime::JOG_CANCEL,
            // grbl's override commands (a bit each, for the main loop) and
            // any other byte from 0x80 up: out of the stream.
            0x80..=0xFF => {
                or_in_isr(&super::MOTION_OVR, mill::overrides::motion_bit(b));
                or_in_isr(&super::ACCESSORY_OVR, mill::overrides::accessory_bit(b));
                0
            }
            _ => {
                // Ctrl-X: stop stepping now (grbl's mc_reset); the main loop
                // flushes the queues and reports. Whether steps were still
                // being produced decides if the position is kept.
                debug_assert!(b == SOFT_RESET);
                let moving = super::stepper::busy();
                super::stepper::halt_from_isr();
                realtime::RESET | if moving { realtime::RESET_MOVING } else { 0 }
            }
        });
    } else {
        match scan.feed(prev, b) {
            Urgent::Nothing => {}
            Urgent::Estop => super::emergency_stop_in_isr(),
            // M108 continues after M0/M1 even though the line waits in the
            // ring behind the pause (Marlin's emergency parser).
            Urgent::Continue => raise_in_isr(realtime::RESUME),
        }
        // SAFETY: as above.
        unsafe { addr_of_mut!(RX_PREV).write_volatile(b) };
        store.store(b, prev, rx_store);
    }
    let mode = rx_fast_mode(scan, store, text);
    // SAFETY: as above; volatile since only the assembly reads it.
    unsafe { addr_of_mut!(RX_SLOW).write_volatile(mode) };
}

/// Set `bits` in `a` from inside an ISR (see `raise_in_isr`).
fn or_in_isr(a: &AtomicU8, bits: u8) {
    let p = a.as_ptr();
    // SAFETY: interrupts are off inside an ISR and ISRs do not nest; the
    // main loop takes the byte with an atomic swap.
    unsafe { p.write_volatile(p.read_volatile() | bits) };
}

// TX data register empty: send the next byte or switch the interrupt off.
#[avr_device::interrupt(atmega2560)]
fn USART0_UDRE() {
    // SAFETY: this ISR is the only writer of TX_TAIL; the slot at TX_TAIL
    // was published by the main loop's head store (it is before TX_HEAD) and
    // is not written again until TX_TAIL moves past it. UCSR0B is modified
    // here with interrupts already disabled (ISRs do not nest).
    unsafe {
        let u = &*USART0::ptr();
        let (head, tail) = (TX_HEAD.as_ptr(), TX_TAIL.as_ptr());
        let t = tail.read_volatile();
        if t != head.read_volatile() {
            let b = addr_of_mut!(TX_BUF).cast::<u8>().add(t as usize).read_volatile();
            u.udr0().write(|w| w.bits(b));
            tail.write_volatile(tx_next(t));
        }
        // The ring emptied: off now, not one more interrupt later (a byte
        // queued after this load kicks the interrupt on again).
        if tail.read_volatile() == head.read_volatile() {
            u.ucsr0b().modify(|_, w| w.udrie0().clear_bit());
        }
    }
}
