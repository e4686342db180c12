//! [`mill::math::sqrt_1ulp`]'s assembly (`mill_sqrt_1ulp`): the library
//! calls it on the AVR; module-level assembly is assembled here, in the
//! firmware crate, for the ATmega2560 (in the library it was not).

// `sqrt::sqrt_1ulp_plain` for a positive normal x, in assembly: the
// interval byte i (bit 7 of the third byte flipped) picks a knot, its rise
// and its bow from the table's six byte columns, 256 bytes apart (Z, then
// one `inc r31` a column); t = the low 16 bits, tt = t·(2¹⁶ − t) >> 16,
// up = rise·t + bow·tt + 2¹⁵, and the root's bits are (e << 23) + knot +
// (up >> 16) with e = (E + 127) >> 1 for the biased exponent E. Each
// product exact on the hardware multiplier, as the twin's `u32`s. Any
// other x (±0, negative, subnormal, infinite, NaN) jumps to avr-libc's
// `sqrt`, as the twin calls `sqrtf`. 119 cycles from call to return,
// against ~215 for the twin compiled (its ten saved registers and a table
// address computed per column): `tests/soft_float.rs` calls it in the ELF
// against the twin, bit for bit, and times it.
//
// SAFETY: reads only the table in flash (`lpm`); changes only the
// call-clobbered registers of avr-gcc's convention (r18–r27, r30, r31, r0)
// and r16/r17, which it saves and restores; r1 is zero again at the return.
core::arch::global_asm!(
    ".pushsection .text.mill_sqrt_1ulp,\"ax\",@progbits",
    ".global mill_sqrt_1ulp",
    ".type mill_sqrt_1ulp, @function",
    "mill_sqrt_1ulp:",
    // Positive normal: (bits >> 16) − 0x80 below 0x7F00.
    "    movw r18, r24",
    "    subi r18, 0x80",
    "    sbci r19, 0x00",
    "    cpi  r19, 0x7F",
    "    brlo 1f",
    "    jmp  sqrt",
    "1:  push r16",
    "    push r17",
    // tt = t·(−t) >> 16 in r20:r19: the partial products' sum above the
    // lowest byte (r20:r19:r18), plus th·nth.
    "    movw r30, r22",
    "    neg  r31",
    "    neg  r30",
    "    sbc  r31, r1",
    "    clr  r21",                // zero from here on
    "    mul  r22, r30",
    "    mov  r18, r1",
    "    clr  r19",
    "    clr  r20",
    "    mul  r22, r31",
    "    add  r18, r0",
    "    adc  r19, r1",
    "    adc  r20, r21",
    "    mul  r23, r30",
    "    add  r18, r0",
    "    adc  r19, r1",
    "    adc  r20, r21",
    "    mul  r23, r31",
    "    add  r19, r0",
    "    adc  r20, r1",
    // Z = the table's first column at i; e = (E + 127) >> 1 in r18.
    "    mov  r30, r24",
    "    subi r30, 0x80",
    "    ldi  r31, 0",
    "    subi r30, lo8(-({table}))",
    "    sbci r31, hi8(-({table}))",
    "    lsl  r24",
    "    rol  r25",
    "    ldi  r24, 127",
    "    add  r25, r24",
    "    ror  r25",
    "    mov  r18, r25",
    // up = rise·t (r25:r24:r17:r16) ...
    "    subi r31, 0xFD",          // the rise's columns
    "    lpm  r26, Z",
    "    inc  r31",
    "    lpm  r27, Z",
    "    inc  r31",                // the bow's column
    "    mul  r26, r22",
    "    movw r16, r0",
    "    mul  r27, r23",
    "    movw r24, r0",
    "    mul  r26, r23",
    "    add  r17, r0",
    "    adc  r24, r1",
    "    adc  r25, r21",
    "    mul  r27, r22",
    "    add  r17, r0",
    "    adc  r24, r1",
    "    adc  r25, r21",
    // ... + bow·tt + 0x8000.
    "    lpm  r22, Z",
    "    mul  r22, r19",
    "    add  r16, r0",
    "    adc  r17, r1",
    "    adc  r24, r21",
    "    adc  r25, r21",
    "    mul  r22, r20",
    "    add  r17, r0",
    "    adc  r24, r1",
    "    adc  r25, r21",
    "    ldi  r22, 0x80",
    "    add  r17, r22",
    "    adc  r24, r21",
    "    adc  r25, r21",
    // The knot (r20:r23:r22) + (up >> 16) + (e << 23).
    "    subi r31, 5",             // the knot's columns
    "    lpm  r22, Z",
    "    inc  r31",
    "    lpm  r23, Z",
    "    inc  r31",
    "    lpm  r20, Z",
    "    clr  r19",
    "    lsr  r18",
    "    ror  r19",
    "    add  r22, r24",
    "    adc  r23, r25",
    "    adc  r20, r19",
    "    adc  r18, r21",
    "    mov  r24, r20",
    "    mov  r25, r18",
    "    pop  r17",
    "    pop  r16",
    "    clr  r1",
    "    ret",
    ".size mill_sqrt_1ulp, . - mill_sqrt_1ulp",
    ".popsection",
    table = sym mill::math::SQRT_TABLE,
);
