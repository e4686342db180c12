/* Test firmware: a known step train on the RAMPS pins.
 *
 * Phase 1: 1000 steps +X, one per Timer1 compare at 100 us (OCR1A = 1599),
 *          each pulse high for exactly 62 cycles (sbi, 60 cycles, cbi).
 * Phase 2: 500 steps -Y at 50 us (OCR1A = 799), same pulse.
 * Phase 3 (interrupts off, hand-timed):
 *   - one +X pulse only 8 cycles high            -> StepHighTooShort (8)
 *   - X dir flipped 2 cycles before a rising edge -> DirSetupTooShort (2)
 *   - one Z pulse with Z disabled                -> StepWhileDisabled
 * Then prints "done" on UART0 and idles.
 */
#include <avr/io.h>
#include <avr/interrupt.h>

static volatile uint16_t remaining;
static volatile uint8_t phase;
static volatile uint8_t finished; /* 8-bit: read atomically by main */

ISR(TIMER1_COMPA_vect)
{
    if (!remaining)
        return;
    if (phase == 1) {
        PORTF |= _BV(0);            /* sbi: rise */
        __builtin_avr_delay_cycles(60);
        PORTF &= ~_BV(0);           /* cbi: fall, 62 cycles after the rise */
    } else {
        PORTF |= _BV(6);
        __builtin_avr_delay_cycles(60);
        PORTF &= ~_BV(6);
    }
    if (!--remaining)
        finished = 1;
}

static void uart_puts(const char *s)
{
    while (*s) {
        while (!(UCSR0A & _BV(UDRE0)))
            ;
        UDR0 = *s++;
    }
}

static void run_phase(uint8_t p, uint16_t n, uint16_t ocr)
{
    TCCR1B = 0;
    TCNT1 = 0;
    OCR1A = ocr;
    phase = p;
    remaining = n;
    finished = 0;
    TIFR1 = _BV(OCF1A);
    TIMSK1 = _BV(OCIE1A);
    TCCR1B = _BV(WGM12) | _BV(CS10); /* CTC, clk/1 */
    while (!finished)
        ;
    TCCR1B = 0;
    TIMSK1 = 0;
}

int main(void)
{
    UCSR0A = _BV(U2X0);
    UBRR0 = 7;
    UCSR0B = _BV(TXEN0) | _BV(RXEN0);

    /* X: PF0 step, PF1 dir, PD7 enable. Y: PF6, PF7, PF2. Z: PL3, PL1, PK0. */
    DDRF |= _BV(0) | _BV(1) | _BV(6) | _BV(7) | _BV(2);
    DDRD |= _BV(7);
    DDRL |= _BV(3) | _BV(1);
    DDRK |= _BV(0);
    PORTD &= ~_BV(7);       /* X enabled */
    PORTF &= ~_BV(2);       /* Y enabled */
    PORTK |= _BV(0);        /* Z disabled */
    PORTF |= _BV(1);        /* X dir + */
    PORTF &= ~_BV(7);       /* Y dir - */
    __builtin_avr_delay_cycles(1000);
    sei();

    run_phase(1, 1000, 1599);
    run_phase(2, 500, 799);

    cli();
    __builtin_avr_delay_cycles(1000);
    /* 8 cycles high: sbi (2) + 6 nops. */
    __asm__ volatile(
        "sbi %0, 0\n\t"
        "nop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop\n\t"
        "cbi %0, 0\n\t" ::"I"(_SFR_IO_ADDR(PORTF)));
    __builtin_avr_delay_cycles(1000);
    /* dir X -> negative, step 2 cycles later (cbi takes 2). */
    __asm__ volatile(
        "cbi %0, 1\n\t"
        "sbi %0, 0\n\t" ::"I"(_SFR_IO_ADDR(PORTF)));
    __builtin_avr_delay_cycles(100);
    PORTF &= ~_BV(0);
    __builtin_avr_delay_cycles(1000);
    /* Z step while disabled. */
    PORTL |= _BV(3);
    __builtin_avr_delay_cycles(100);
    PORTL &= ~_BV(3);
    __builtin_avr_delay_cycles(1000);

    uart_puts("done\n");
    for (;;)
        ;
}
