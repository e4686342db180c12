//! The f32 multiply every `*` on the AVR calls, in assembly: a fast path
//! for what a streamed line multiplies (two normal numbers whose product is
//! normal), avr-libc's routine for everything else.
//!
//! avr-libc's `__mulsf3` (`libm.a`, hand-written) unpacks both operands in
//! `__fp_split3` (zeros, subnormals, infinities, NaN), multiplies, and
//! rounds in `__fp_round`, three calls deep: 152 cycles a call on average
//! on a streamed line (`profile --trace`), 16 calls a line. Here, after two
//! exponent tests, the same 24 × 24-bit product (avr-libc's `mul` order),
//! one normalizing shift, round to nearest even and the packing are done in
//! line: ~100 cycles. A zero times a finite number is a signed zero in
//! ~30 cycles. Where the operands or the product's exponent are out of
//! the fast path's range (a subnormal, an infinity or a NaN operand, or an
//! exponent sum that could overflow or underflow), it jumps to avr-libc's
//! `__mulsf3x` and `__fp_round`, which is what avr-libc's `__mulsf3` does.
//!
//! The linker's `--wrap=__mulsf3` (`avr-atmega2560.json`) sends every call
//! of `__mulsf3` here (`__wrap___mulsf3`), libm's own calls included.
//!
//! Tested against avr-libc's routine, bit for bit, in the virtual machine:
//! `tests/soft_float.rs` calls both in the real ELF on random and edge
//! operands, and checks the fast path against the host's IEEE product.

core::arch::global_asm!(
    ".pushsection .text.__wrap___mulsf3,\"ax\",@progbits",
    ".global __wrap___mulsf3",
    ".type __wrap___mulsf3, @function",
    // Off the fast path, first (the branches to it must reach): a zero
    // times a finite number is a signed zero, as avr-libc makes it (a
    // streamed line multiplies ~3 zeros); the rest is avr-libc's __mulsf3.
    ".global __mill_mulsf3_off_path",
    ".type __mill_mulsf3_off_path, @function",
    "__mill_mulsf3_off_path:",
    ".Lmul_slow:",
    "    mov  r26, r25",
    "    andi r26, 0x7f",
    "    or   r26, r24",
    "    or   r26, r23",
    "    or   r26, r22",
    "    breq 5f", // a = ±0: is b finite?
    "    mov  r26, r21",
    "    andi r26, 0x7f",
    "    or   r26, r20",
    "    or   r26, r19",
    "    or   r26, r18",
    "    brne 6f",       // no zero
    "    mov  r26, r24", // b = ±0: is a finite?
    "    lsl  r26",
    "    mov  r26, r25",
    "    rjmp 7f",
    "5:  mov  r26, r20",
    "    lsl  r26",
    "    mov  r26, r21",
    "7:  rol  r26", // the other's exponent
    "    cpi  r26, 0xff",
    "    breq 6f", // 0 × ∞, 0 × NaN: avr-libc's NaN
    "    eor  r25, r21",
    "    andi r25, 0x80",
    "    ldi  r24, 0",
    "    ldi  r23, 0",
    "    ldi  r22, 0",
    "    ret",
    "6:  call __mulsf3x",
    "    jmp  __fp_round",
    ".size __mill_mulsf3_off_path, . - __mill_mulsf3_off_path",
    // a: r25:r22, b: r21:r18 (sign, 8-bit exponent, 23-bit fraction).
    "__wrap___mulsf3:",
    // Each biased exponent must be 1..254 (normal): e − 1 < 254.
    "    mov  r26, r24",
    "    lsl  r26",
    "    mov  r26, r25",
    "    rol  r26",
    "    subi r26, 1",
    "    cpi  r26, 254",
    "    brsh .Lmul_slow",
    "    mov  r27, r20",
    "    lsl  r27",
    "    mov  r27, r21",
    "    rol  r27",
    "    subi r27, 1",
    "    cpi  r27, 254",
    "    brsh .Lmul_slow",
    // t = ea + eb − 128, 16 bits: the product's exponent is t + 1 (its
    // significand in [1, 2)) or t + 2 (in [2, 4), or rounded up to 2; no
    // product of two significands below 2 rounds up to 4). 0 ≤ t ≤ 252
    // keeps it in 1..254: no overflow, no subnormal.
    "    add  r26, r27",
    "    ldi  r31, 0",
    "    adc  r31, r31",
    "    subi r26, 126",
    "    sbci r31, 0",
    "    cpi  r26, 253",
    "    cpc  r31, r1",
    "    brsh .Lmul_slow",
    // Nothing above changed an operand: the slow path gets them whole.
    "    eor  r25, r21",
    "    bst  r25, 7",    // T: the product's sign
    "    mov  r21, r26",  // t
    "    ori  r24, 0x80", // the hidden bits
    "    ori  r20, 0x80",
    // 24 × 24 → 48 bits, avr-libc's __mulsf3_pse order; bytes 5..0 end
    // in r18, r22, r26, r27, r31, r30 (a2 a1 a0 = r24 r23 r22, b2 b1 b0 =
    // r20 r19 r18; a0 and b0 are reused once their products are summed).
    "    mul  r22, r18",
    "    movw r30, r0",
    "    mul  r23, r18",
    "    eor  r27, r27",
    "    add  r31, r0",
    "    adc  r27, r1",
    "    mul  r22, r19",
    "    eor  r26, r26",
    "    add  r31, r0",
    "    adc  r27, r1",
    "    adc  r26, r26",
    "    mul  r22, r20",
    "    eor  r22, r22",
    "    add  r27, r0",
    "    adc  r26, r1",
    "    adc  r22, r22",
    "    mul  r24, r18",
    "    eor  r18, r18",
    "    add  r27, r0",
    "    adc  r26, r1",
    "    adc  r22, r18",
    "    mul  r23, r19",
    "    add  r27, r0",
    "    adc  r26, r1",
    "    adc  r22, r18",
    "    mul  r24, r19",
    "    add  r26, r0",
    "    adc  r22, r1",
    "    adc  r18, r18",
    "    mul  r23, r20",
    "    eor  r19, r19",
    "    add  r26, r0",
    "    adc  r22, r1",
    "    adc  r18, r19",
    "    mul  r24, r20",
    "    add  r22, r0",
    "    adc  r18, r1",
    "    eor  r1, r1",
    "    or   r30, r31", // bytes 1 and 0: sticky bits only
    "    mov  r24, r18",
    "    mov  r23, r22",
    "    mov  r22, r26", // significand r24:r23:r22, r27 the byte below
    "    sbrc r24, 7",
    "    rjmp 1f",
    "    lsl  r27", // in [1, 2): one bit up
    "    rol  r22",
    "    rol  r23",
    "    rol  r24",
    "    rjmp 2f",
    "1:  inc  r21", // in [2, 4)
    "2:  inc  r21", // the exponent
    // Round to nearest, ties to even: bit 7 of r27 is the round bit, the
    // rest of r27 and r30 the sticky bits.
    "    sbrs r27, 7",
    "    rjmp 4f",
    "    andi r27, 0x7f",
    "    or   r27, r30",
    "    brne 3f",
    "    sbrs r22, 0", // a tie: up only from an odd significand
    "    rjmp 4f",
    "3:  subi r22, 0xff", // + 1
    "    sbci r23, 0xff",
    "    sbci r24, 0xff",
    "    brne 4f",
    "    inc  r21", // 0xFFFFFF + 1: 1.0 (the hidden bit goes), one exponent up
    "4:  lsl  r24", // pack: drop the hidden bit, exponent, sign
    "    lsr  r21",
    "    ror  r24",
    "    bld  r21, 7",
    "    mov  r25, r21",
    "    ret",
    ".size __wrap___mulsf3, . - __wrap___mulsf3",
    ".popsection",
);
