//! `memcpy` and `memset` for the AVR, four bytes per loop turn.
//!
//! Rust moves and clears structs through these two (a parsed line, a
//! planner block, a step chunk: ~20 calls of 10–70 bytes per streamed
//! G-code line). avr-libc's versions move one byte per turn: 8 cycles a byte
//! for `memcpy`, 6 for `memset`. These do the `n mod 4` odd bytes first, then
//! four per turn: 5 and 3 cycles a byte (measured with the profiler, docs/ARCHITECTURE.md
//! "Benchmark"). Being defined here, the linker takes them instead of
//! avr-libc's (an archive member is only pulled in for a symbol still
//! undefined).
//!
//! Calling convention (avr-gcc ABI, as avr-libc's): destination in r25:r24
//! (returned unchanged), source or fill byte in r23:r22, count in r21:r20;
//! r0, r18–r27, r30, r31 may be clobbered, r1 is zero on entry and exit.

core::arch::global_asm!(
    ".section .text.memcpy,\"ax\",@progbits",
    ".global memcpy",
    ".type memcpy, @function",
    "memcpy:",
    "movw r30, r22",
    "movw r26, r24",
    // One odd byte, then two.
    "sbrs r20, 0",
    "rjmp 1f",
    "ld r0, Z+",
    "st X+, r0",
    "1:",
    "sbrs r20, 1",
    "rjmp 2f",
    "ld r0, Z+",
    "st X+, r0",
    "ld r0, Z+",
    "st X+, r0",
    "2:",
    // The rest in turns of four.
    "lsr r21",
    "ror r20",
    "lsr r21",
    "ror r20",
    "rjmp 4f",
    "3:",
    "ld r0, Z+",
    "st X+, r0",
    "ld r0, Z+",
    "st X+, r0",
    "ld r0, Z+",
    "st X+, r0",
    "ld r0, Z+",
    "st X+, r0",
    "4:",
    "subi r20, 1",
    "sbci r21, 0",
    "brcc 3b",
    "ret",
    ".size memcpy, . - memcpy",
    "",
    ".section .text.memset,\"ax\",@progbits",
    ".global memset",
    ".type memset, @function",
    "memset:",
    "movw r26, r24",
    // One odd byte, then two (a skipped `st` is one word).
    "sbrc r20, 0",
    "st X+, r22",
    "sbrc r20, 1",
    "st X+, r22",
    "sbrc r20, 1",
    "st X+, r22",
    "lsr r21",
    "ror r20",
    "lsr r21",
    "ror r20",
    "rjmp 2f",
    "1:",
    "st X+, r22",
    "st X+, r22",
    "st X+, r22",
    "st X+, r22",
    "2:",
    "subi r20, 1",
    "sbci r21, 0",
    "brcc 1b",
    "ret",
    ".size memset, . - memset",
);
