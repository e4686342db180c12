//! [`mill::math::decimal::quotient_f32`]'s assembly (`mill_quotient_f32`):
//! the parser's conversion of a word's digits to an f32. The library calls
//! it on the AVR; module-level assembly is assembled here, in the firmware
//! crate (see `board::sqrt`).

// `decimal::quotient_f32_plain`'s steps: m (1 ≤ m < 2²⁴) shifted left
// until its top bit is bit 31 (whole bytes first, then bits; a = a1:a0 in
// r27:r26:r25:r24, whose low byte is 0), the reciprocal R = R1:R0 of 5^s from the table
// (`QUOTIENT_TABLE`, five bytes a power), H = a1·R1 + ⌊a1·R0 / 2¹⁶⌋ +
// ⌊a0·R1 / 2¹⁶⌋ exact on the hardware multiplier, H doubled unless its top
// bit is set, the significand its top 24 bits and the byte below them the
// rounding (≤ 123 down, ≥ 129 up, between: no answer), and the biased
// exponent less one, x = 157 + top − e − z − s, kept in r21 from the start.
// The result's bits are (x << 23) + significand + round up, or 0 for no
// answer (m = 0, m ≥ 2²⁴, s outside 1..=9, an undecided rounding), as the
// twin's `None`. `tests/soft_float.rs` calls it in the ELF against the twin,
// bit for bit, and times it.
//
// SAFETY: reads only the table in flash (`lpm`, below 64 KiB: `.progmem.data`);
// changes only the call-clobbered registers of avr-gcc's convention
// (r18–r27, r30, r31, r0); r1 is zero again at the return.
core::arch::global_asm!(
    ".pushsection .text.mill_quotient_f32,\"ax\",@progbits",
    ".global mill_quotient_f32",
    ".type mill_quotient_f32, @function",
    "mill_quotient_f32:",
    "    tst  r25",                // m ≥ 2²⁴
    "    brne .Lq_none",
    "    mov  r18, r22",
    "    or   r18, r23",
    "    or   r18, r24",
    "    breq .Lq_none",           // m = 0
    "    mov  r18, r20",
    "    dec  r18",                // s − 1
    "    cpi  r18, 9",
    "    brlo .Lq_go",
    ".Lq_none:",
    "    clr  r22",
    "    clr  r23",
    "    movw r24, r22",
    "    ret",
    ".Lq_go:",
    "    ldi  r21, 157",
    "    sub  r21, r20",           // x = 157 − s
    // a = m shifted: by a byte when m ≥ 2¹⁶ (z = 8), else by two (z = 16).
    // Its lowest byte, r24, is 0 (z ≥ 8): the zero register from here on.
    "    tst  r24",
    "    breq .Lq_small",
    "    mov  r27, r24",
    "    mov  r26, r23",
    "    mov  r25, r22",
    "    clr  r24",
    "    subi r21, 8",
    "    rjmp .Lq_bits",
    ".Lq_small:",
    "    mov  r27, r23",           // r25 and r24 are zero
    "    mov  r26, r22",
    "    subi r21, 16",
    "    tst  r27",
    "    brne .Lq_bits",
    "    mov  r27, r26",           // m < 2⁸: one more byte
    "    clr  r26",
    "    subi r21, 8",
    ".Lq_bits:",
    "    sbrc r27, 7",
    "    rjmp .Lq_table",
    "    lsl  r25",
    "    rol  r26",
    "    rol  r27",
    "    dec  r21",
    "    rjmp .Lq_bits",
    // R0 in r19:r18, R1 in r23:r22, x −= e.
    ".Lq_table:",
    "    ldi  r30, lo8({table})",
    "    ldi  r31, hi8({table})",
    "    mov  r19, r18",
    "    lsl  r19",
    "    lsl  r19",
    "    add  r19, r18",           // 5 (s − 1)
    "    add  r30, r19",
    "    adc  r31, r24",
    "    lpm  r18, Z+",
    "    lpm  r19, Z+",
    "    lpm  r22, Z+",
    "    lpm  r23, Z+",
    "    lpm  r20, Z",
    "    sub  r21, r20",
    // ⌊a0·R1 / 2¹⁶⌋ = ⌊r25·R1 / 2⁸⌋ (a0's low byte is 0) in r31:r30.
    "    mul  r25, r22",
    "    mov  r30, r1",
    "    mul  r25, r23",
    "    add  r30, r0",
    "    mov  r31, r1",
    "    adc  r31, r24",
    // Plus ⌊a1·R0 / 2¹⁶⌋ (bytes 1–3 of the product: r20, then added to
    // r31:r30 with the carry in r25): T = r25:r31:r30.
    "    mul  r26, r18",
    "    mov  r20, r1",
    "    mul  r27, r19",
    "    add  r30, r0",
    "    adc  r31, r1",
    "    clr  r25",                // (eor: the carry stays)
    "    adc  r25, r24",
    "    mul  r26, r19",
    "    add  r20, r0",
    "    adc  r30, r1",
    "    adc  r31, r24",
    "    adc  r25, r24",
    "    mul  r27, r18",
    "    add  r20, r0",
    "    adc  r30, r1",
    "    adc  r31, r24",
    "    adc  r25, r24",
    // H = a1·R1 + T in r18:r25:r31:r30.
    "    clr  r18",
    "    mul  r26, r22",
    "    add  r30, r0",
    "    adc  r31, r1",
    "    adc  r25, r24",
    "    adc  r18, r24",
    "    mul  r27, r23",
    "    add  r25, r0",
    "    adc  r18, r1",
    "    mul  r26, r23",
    "    add  r31, r0",
    "    adc  r25, r1",
    "    adc  r18, r24",
    "    mul  r27, r22",
    "    add  r31, r0",
    "    adc  r25, r1",
    "    adc  r18, r24",
    // Top bit at 31: x + 1; else H doubled.
    "    sbrs r18, 7",
    "    rjmp .Lq_double",
    "    inc  r21",
    "    rjmp .Lq_round",
    ".Lq_double:",
    "    lsl  r30",
    "    rol  r31",
    "    rol  r25",
    "    rol  r18",
    // The byte below the significand (r18:r25:r31) decides: r20 = 0 or 1.
    ".Lq_round:",
    "    clr  r20",
    "    cpi  r30, 124",
    "    brlo .Lq_pack",
    "    cpi  r30, 129",
    "    brsh .Lq_up",
    "    clr  r1",
    "    rjmp .Lq_none",           // undecided
    ".Lq_up:",
    "    inc  r20",
    // (x << 23) + significand + r20 in r25:r24:r23:r22.
    ".Lq_pack:",
    "    mov  r22, r31",
    "    mov  r23, r25",
    "    mov  r24, r18",
    "    mov  r25, r21",
    "    lsr  r25",
    "    clr  r18",                // (eor: the carry stays)
    "    ror  r18",
    "    clr  r1",
    "    add  r24, r18",
    "    adc  r25, r1",
    "    add  r22, r20",
    "    adc  r23, r1",
    "    adc  r24, r1",
    "    adc  r25, r1",
    "    ret",
    ".size mill_quotient_f32, . - mill_quotient_f32",
    ".popsection",
    table = sym mill::math::decimal::QUOTIENT_TABLE,
);
