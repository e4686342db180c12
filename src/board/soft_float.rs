//! The f32 multiply, sum and difference every `*`, `+` and `-` on the AVR
//! calls, in assembly: a fast path for what a streamed line computes
//! (normal numbers, a normal result), avr-libc's routines for everything
//! else.
//!
//! avr-libc's routines (`libm.a`, hand-written) unpack both operands in
//! `__fp_split3` (zeros, subnormals, infinities, NaN), compute, and round
//! in `__fp_round`, three calls deep: 152 cycles a multiply and ~123 a sum
//! on average on a streamed line (`profile --trace`), 16 and 17 calls a
//! line. Here the fast path does it in line after two exponent tests:
//! ~95 cycles a multiply, ~85 a sum; a zero times a finite number, or a
//! zero plus a normal number, ~30.
//!
//! The multiply: the same 24 × 24-bit product as avr-libc's (its `mul`
//! order), one normalizing shift, round to nearest even, the packing. A
//! zero times a finite number is a signed zero in ~30 cycles. Off the fast
//! path (a subnormal, an infinity or a NaN operand, or an exponent sum that
//! could overflow or underflow) it jumps to avr-libc's `__mulsf3x` and
//! `__fp_round`, which is what avr-libc's `__mulsf3` does.
//!
//! The linker's `--wrap` (`avr-atmega2560.json`) sends every call of
//! `__mulsf3`, `__addsf3` and `__subsf3` here (`__wrap___mulsf3`, …),
//! libm's own calls included.
//!
//! Tested against avr-libc's routines, bit for bit, in the virtual
//! machine: `tests/soft_float.rs` calls both in the real ELF on random and
//! edge operands, and checks the fast paths against the host's IEEE
//! results.

core::arch::global_asm!(
    // \dst = the biased exponent of the float whose top bytes are \hi:\mid.
    ".macro f32_exp dst, hi, mid",
    "    mov  \\dst, \\mid",
    "    lsl  \\dst",
    "    mov  \\dst, \\hi",
    "    rol  \\dst",
    ".endm",
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
    // rcall and rjmp, not call and jmp: avr-ld's relaxation of those
    // leaves the symbols after them the wrong size (or address).
    "6:  rcall __mulsf3x",
    "    rjmp __fp_round",
    ".size __mill_mulsf3_off_path, . - __mill_mulsf3_off_path",
    // a: r25:r22, b: r21:r18 (sign, 8-bit exponent, 23-bit fraction).
    "__wrap___mulsf3:",
    // Each biased exponent must be 1..254 (normal): e − 1 < 254.
    "    f32_exp r26, r25, r24",
    "    subi r26, 1",
    "    cpi  r26, 254",
    "    brsh .Lmul_slow",
    "    f32_exp r27, r21, r20",
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
    // The f32 sum (`__addsf3`) and difference (`__subsf3`, which flips b's
    // sign and adds): a fast path for two normal numbers of exponents 26..252
    // (|x| from 6.7e-32 to 1.7e38), avr-libc's `__addsf3x` and `__fp_round`
    // for the rest, as avr-libc's `__addsf3` runs them. The larger-exponent
    // operand x keeps its place; y's significand is shifted right by the
    // exponent difference into three bytes and a guard byte, whose last bit
    // is set when anything nonzero was shifted out (the sticky bit: round to
    // nearest even needs no more); then added or subtracted, normalized,
    // rounded and packed. An exponent difference above 25 leaves x as it is
    // (y is below a quarter of x's last place).
    ".pushsection .text.__wrap___addsf3,\"ax\",@progbits",
    ".global __mill_addsf3_off_path",
    ".type __mill_addsf3_off_path, @function",
    "__mill_addsf3_off_path:",
    // A zero and a normal number: the number (a streamed line adds ~1.4
    // zeros); the rest is avr-libc's __addsf3.
    ".Ladd_slow:",
    "    mov  r26, r21",
    "    andi r26, 0x7f",
    "    or   r26, r20",
    "    or   r26, r19",
    "    or   r26, r18",
    "    brne 1f", // b is not ±0
    "    f32_exp r27, r25, r24",
    "    subi r27, 1",
    "    cpi  r27, 254",
    "    brsh 2f",
    "    ret", // normal a + ±0 = a
    "1:  mov  r26, r25",
    "    andi r26, 0x7f",
    "    or   r26, r24",
    "    or   r26, r23",
    "    or   r26, r22",
    "    brne 2f", // a is not ±0
    "    f32_exp r27, r21, r20",
    "    subi r27, 1",
    "    cpi  r27, 254",
    "    brsh 2f",
    "    movw r22, r18", // ±0 + normal b = b
    "    movw r24, r20",
    "    ret",
    // rcall and rjmp, as in the multiply's (avr-ld's relaxation of call
    // and jmp put the second of two symbols that follow at the first one's
    // address).
    "2:  ldi  r26, 0", // what avr-libc's __addsf3 clears first
    "    ldi  r27, 0",
    "    rcall __addsf3x",
    "    rjmp __fp_round",
    ".size __mill_addsf3_off_path, . - __mill_addsf3_off_path",
    ".global __wrap___subsf3",
    ".type __wrap___subsf3, @function",
    "__wrap___subsf3:",
    "    subi r21, 0x80",
    ".size __wrap___subsf3, 2",
    ".global __wrap___addsf3",
    ".type __wrap___addsf3, @function",
    // a: r25:r22, b: r21:r18.
    "__wrap___addsf3:",
    "    f32_exp r26, r25, r24", // ea
    "    cpi  r26, 26",
    "    brlo .Ladd_slow",
    "    cpi  r26, 253",
    "    brsh .Ladd_slow",
    "    f32_exp r27, r21, r20", // eb
    "    cpi  r27, 26",
    "    brlo .Ladd_slow",
    "    cpi  r27, 253",
    "    brsh .Ladd_slow",
    "    bst  r25, 7",    // T: the sign of x (a, unless swapped)
    "    eor  r25, r21",  // bit 7: the signs differ
    "    ori  r24, 0x80", // the hidden bits
    "    ori  r20, 0x80",
    "    cp   r26, r27",
    "    brsh 1f",
    "    bst  r21, 7", // eb > ea: x is b
    "    movw r30, r22",
    "    movw r22, r18",
    "    movw r18, r30",
    "    mov  r30, r24",
    "    mov  r24, r20",
    "    mov  r20, r30",
    "    mov  r30, r26",
    "    mov  r26, r27",
    "    mov  r27, r30",
    // x: r24:r23:r22, exponent r26; y: r20:r19:r18, guard r30; r27 the
    // exponent difference, r21 the bits shifted out.
    "1:  neg  r27",
    "    add  r27, r26",
    "    ldi  r30, 0",
    "    ldi  r21, 0",
    "    cpi  r27, 26",
    "    brlo 2f",
    "    rjmp .Ladd_round", // x alone (guard 0: no rounding)
    "2:  cpi  r27, 8",      // whole bytes
    "    brlo 3f",
    "    or   r21, r30",
    "    mov  r30, r18",
    "    mov  r18, r19",
    "    mov  r19, r20",
    "    ldi  r20, 0",
    "    subi r27, 8",
    "    rjmp 2b",
    "3:  cpse r21, r1", // 0 or 1: the bit loop's rol keeps it
    "    ldi  r21, 1",
    "    rjmp 5f",
    "4:  lsr  r20", // then bits
    "    ror  r19",
    "    ror  r18",
    "    ror  r30",
    "    rol  r21",
    "5:  subi r27, 1",
    "    brcc 4b",
    "    cpse r21, r1",
    "    ori  r30, 1", // the sticky bit
    "    sbrc r25, 7",
    "    rjmp 6f",
    "    add  r22, r18", // same signs: x + y
    "    adc  r23, r19",
    "    adc  r24, r20",
    "    brcc .Ladd_round",
    "    ror  r24", // in [2, 4): one bit down
    "    ror  r23",
    "    ror  r22",
    "    ror  r30",
    "    brcc 7f",
    "    ori  r30, 1",
    "7:  inc  r26",
    "    rjmp .Ladd_round",
    "6:  neg  r30", // signs differ: x − y (x's guard is 0)
    "    sbc  r22, r18",
    "    sbc  r23, r19",
    "    sbc  r24, r20",
    "    brcc 8f",
    "    com  r24", // |y| > |x| (equal exponents, guard 0):
    "    com  r23", // negate, y's sign
    "    neg  r22",
    "    sbci r23, 0xff",
    "    sbci r24, 0xff",
    "    brts 7f",
    "    set",
    "    rjmp 8f",
    "7:  clt",
    "8:  mov  r27, r24",
    "    or   r27, r23",
    "    or   r27, r22",
    "    or   r27, r30",
    "    breq 9f",  // x − x: +0
    "1:  tst  r24", // normalize: whole bytes (exponent
    "    brne 2f",  // difference 0 or 1 only), then bits
    "    mov  r24, r23",
    "    mov  r23, r22",
    "    mov  r22, r30",
    "    ldi  r30, 0",
    "    subi r26, 8",
    "    rjmp 1b",
    "2:  sbrc r24, 7",
    "    rjmp .Ladd_round",
    "    lsl  r30",
    "    rol  r22",
    "    rol  r23",
    "    rol  r24",
    "    dec  r26",
    "    rjmp 2b",
    "9:  ldi  r22, 0",
    "    ldi  r23, 0",
    "    movw r24, r22",
    "    ret",
    // Round to nearest, ties to even (bit 7 of the guard is the round bit,
    // the rest sticky), then pack.
    ".Ladd_round:",
    "    sbrs r30, 7",
    "    rjmp 4f",
    "    andi r30, 0x7f",
    "    brne 3f",
    "    sbrs r22, 0",
    "    rjmp 4f",
    "3:  subi r22, 0xff",
    "    sbci r23, 0xff",
    "    sbci r24, 0xff",
    "    brne 4f",
    "    inc  r26",
    "4:  lsl  r24",
    "    lsr  r26",
    "    ror  r24",
    "    bld  r26, 7",
    "    mov  r25, r26",
    "    ret",
    ".size __wrap___addsf3, . - __wrap___addsf3",
    ".popsection",
);
