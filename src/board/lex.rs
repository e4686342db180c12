//! [`mill::math::decimal::lex_plain`]'s assembly (`mill_lex_plain`): the
//! digits of a word's plain number, read once for every value word of a
//! line. The library calls it on the AVR; module-level assembly is
//! assembled here, in the firmware crate (see `board::sqrt`).

// `decimal::lex_plain_plain`'s steps over the `len` bytes at Z: the integer
// digits multiplied in (at most 9 digits in all), the mantissa below 10⁶,
// then after a point the fraction's digits, its zeros counted (`pending`)
// and multiplied in only once a non-zero digit follows, each digit
// multiplied in raising the scale; at least one digit; then no `e`, `E`,
// `.`, `+` or `-` right after, and after blanks no digit, nor a point when
// the number had none. The result: mantissa in r18–r21, scale in r22, the
// length (digits and point) in r23, r24 and r25 zero; all zero for a number
// that is not plain (the twin's `(0, 0, 0)`). m·10 + d is four byte
// products on the hardware multiplier (r17 = 10, r16 = 0), two while the
// mantissa fits 16 bits (its first four digits: ~12 cycles a digit fewer,
// ~90 a streamed line). The T flag is the point. `tests/soft_float.rs`
// calls it in the ELF against the twin on random and edge texts, bit for
// bit, and times it.
//
// SAFETY: reads only the `len` bytes at the pointer; changes only the
// call-clobbered registers of avr-gcc's convention (r18–r27, r30, r31, r0)
// and r16/r17, which it saves and restores; r1 is zero again at the return.
core::arch::global_asm!(
    // m = m·10 + \d (m in r21:r20:r19:r18, below 10⁸ before).
    ".macro lex_x10 d",
    "    mul  r21, r17",
    "    mov  r21, r0",
    "    mul  r20, r17",
    "    mov  r20, r0",
    "    add  r21, r1",
    "    mul  r19, r17",
    "    mov  r19, r0",
    "    add  r20, r1",
    "    adc  r21, r16",
    "    mul  r18, r17",
    "    mov  r18, r0",
    "    add  r19, r1",
    "    adc  r20, r16",
    "    adc  r21, r16",
    "    add  r18, \\d",
    "    adc  r19, r16",
    "    adc  r20, r16",
    "    adc  r21, r16",
    ".endm",
    // The same for a mantissa of at most 3 digits before (r23, the digits
    // read, at most 4 with this one): it fits 16 bits before and after
    // (r21:r20 stay zero; the high byte times 10 fits a byte), two
    // products instead of four.
    ".macro lex_x10_short d",
    "    cpi  r23, 5",
    "    brsh 1f",
    "    mul  r19, r17",
    "    mov  r19, r0",
    "    mul  r18, r17",
    "    mov  r18, r0",
    "    add  r19, r1",
    "    add  r18, \\d",
    "    adc  r19, r16",
    "    rjmp 2f",
    "1:  lex_x10 \\d",
    "2:",
    ".endm",
    ".pushsection .text.mill_lex_plain,\"ax\",@progbits",
    ".global mill_lex_plain",
    ".type mill_lex_plain, @function",
    "mill_lex_plain:",
    "    movw r30, r24",
    "    mov  r26, r22",           // bytes left
    "    push r16",
    "    push r17",
    "    clr  r16",
    "    ldi  r17, 10",
    "    clr  r18",
    "    clr  r19",
    "    movw r20, r18",
    "    clr  r23",                // digits read
    "    clr  r24",                // fraction zeros not multiplied in
    "    clr  r25",                // scale
    "    clt",                     // no point
    ".Llex_int:",
    "    tst  r26",
    "    breq .Llex_int_end",
    "    ld   r27, Z",
    "    subi r27, 0x30",
    "    cpi  r27, 10",
    "    brsh .Llex_int_end",
    "    cpi  r23, {max_digits}",
    "    brne .Llex_int_more",
    "    rjmp .Llex_not",
    ".Llex_int_more:",
    "    adiw r30, 1",
    "    dec  r26",
    "    inc  r23",
    "    lex_x10_short r27",
    "    rjmp .Llex_int",
    ".Llex_int_end:",
    "    cpi  r18, 0x40",          // 1 000 000 = 0x000F4240
    "    ldi  r27, 0x42",
    "    cpc  r19, r27",
    "    ldi  r27, 0x0F",
    "    cpc  r20, r27",
    "    cpc  r21, r16",
    "    brlo .Llex_small",
    "    rjmp .Llex_not",
    ".Llex_small:",
    "    tst  r26",
    "    breq .Llex_to_end",
    "    ld   r27, Z",
    "    cpi  r27, 0x2E",          // '.'
    "    breq .Llex_point",
    ".Llex_to_end:",
    "    rjmp .Llex_end",
    ".Llex_point:",
    "    set",
    "    adiw r30, 1",
    "    dec  r26",
    ".Llex_frac:",
    "    tst  r26",
    "    breq .Llex_to_end",
    "    ld   r27, Z",
    "    subi r27, 0x30",
    "    cpi  r27, 10",
    "    brsh .Llex_to_end",
    "    cpi  r23, {max_digits}",
    "    brne .Llex_frac_more",
    "    rjmp .Llex_not",
    ".Llex_frac_more:",
    "    adiw r30, 1",
    "    dec  r26",
    "    inc  r23",
    "    tst  r27",
    "    brne .Llex_mul",
    "    inc  r24",                // a zero: multiplied in if a digit follows
    "    rjmp .Llex_frac",
    // The zeros waiting (r22 = 0 for each), then the digit: each raises
    // the scale.
    ".Llex_mul:",
    "    clr  r22",
    "    tst  r24",
    "    brne .Llex_mul_one",
    "    mov  r22, r27",
    ".Llex_mul_one:",
    "    lex_x10_short r22",
    "    inc  r25",
    "    tst  r24",
    "    breq .Llex_frac",
    "    dec  r24",
    "    rjmp .Llex_mul",
    // What follows the number.
    ".Llex_end:",
    "    tst  r23",
    "    breq .Llex_not",          // no digit
    "    tst  r26",
    "    breq .Llex_ok",
    "    ld   r27, Z+",
    "    dec  r26",
    "    mov  r24, r27",
    "    ori  r24, 0x20",
    "    cpi  r24, 0x65",          // 'e' or 'E'
    "    breq .Llex_not",
    "    cpi  r27, 0x2E",          // '.'
    "    breq .Llex_not",
    "    cpi  r27, 0x2B",          // '+'
    "    breq .Llex_not",
    "    cpi  r27, 0x2D",          // '-'
    "    breq .Llex_not",
    "    cpi  r27, 0x20",
    "    breq .Llex_blanks",
    "    cpi  r27, 0x09",
    "    brne .Llex_ok",
    ".Llex_blanks:",               // blanks, then no more of the number
    "    tst  r26",
    "    breq .Llex_ok",
    "    ld   r27, Z+",
    "    dec  r26",
    "    cpi  r27, 0x20",
    "    breq .Llex_blanks",
    "    cpi  r27, 0x09",
    "    breq .Llex_blanks",
    "    subi r27, 0x30",
    "    cpi  r27, 10",
    "    brlo .Llex_not",          // a digit
    "    cpi  r27, 0xFE",          // '.' − '0'
    "    brne .Llex_ok",
    "    brts .Llex_ok",           // a second point is the parser's to refuse
    ".Llex_not:",
    "    clr  r18",
    "    clr  r19",
    "    movw r20, r18",
    "    movw r22, r18",
    "    movw r24, r18",
    "    rjmp .Llex_ret",
    ".Llex_ok:",
    "    brtc .Llex_scale",
    "    inc  r23",                // the point's byte
    ".Llex_scale:",
    "    mov  r22, r25",
    "    clr  r24",
    "    clr  r25",
    ".Llex_ret:",
    "    pop  r17",
    "    pop  r16",
    "    clr  r1",
    "    ret",
    ".size mill_lex_plain, . - mill_lex_plain",
    ".popsection",
    ".purgem lex_x10_short",
    ".purgem lex_x10",
    max_digits = const mill::math::decimal::MAX_SIG_DIGITS,
);
