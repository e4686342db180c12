/* Test firmware: a tiny line-oriented host link on UART0 (250000 baud, U2X,
 * UBRR = 7), RX by interrupt into a 256-byte ring.
 *
 * Boot: disables the watchdog, paints free RAM with 0xC5, prints "start", then "reset <MCUSR>", clears MCUSR.
 * Every line gets "echo:<line>" (for unknown lines) or a reply, then "ok".
 *   pins          -> "pins E=xx J=xx D=xx C=xx" (PINE, PINJ, PIND, PINC)
 *   eew A V       -> writes EEPROM byte A = V
 *   eer A         -> "ee A=V"
 *   wdt           -> enables the watchdog (15 ms) and hangs: watchdog reset
 *   nest          -> Timer3 compare ISR that re-enables interrupts and outlasts
 *                    its period: unbounded interrupt nesting
 *   spin N        -> Timer2 fast PWM on OC2A (PB4) with OCR2A = N; "spin off"
 *                    disconnects OC2A and drives PB4 low
 *   jogx N        -> N steps of -X (dir low), 200 us apart; after each rising
 *                    edge reads PINE5; prints "trip=K" (K = first step after
 *                    which the switch read closed, 0 = never)
 *   stats         -> "rx=<bytes received> lost=<ring overflows> dor=<DOR seen>"
 *   steps4 N      -> background: N steps on all four axes (+), 25 us apart
 *                    (Timer1 compare ISR, 40 kHz), "ok" at once
 *   busy N        -> interrupts off for N ms (the UART is not read meanwhile)
 *   sleep         -> cli; sleep (halts the core for good)
 */
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/eeprom.h>
#include <avr/wdt.h>
#include <avr/sleep.h>
#include <stdlib.h>
#include <string.h>

static volatile uint8_t ring[256];
static volatile uint8_t head, tail;
static volatile uint32_t rx_count;
static volatile uint16_t lost, dor_seen;

ISR(USART0_RX_vect)
{
    uint8_t st = UCSR0A;
    uint8_t b = UDR0;
    if (st & _BV(DOR0))
        dor_seen++;
    rx_count++;
    uint8_t next = head + 1;
    if (next == tail) {
        lost++;
        return;
    }
    ring[head] = b;
    head = next;
}

static volatile uint16_t steps_left;

ISR(TIMER1_COMPA_vect)
{
    if (!steps_left) {
        TCCR1B = 0;
        return;
    }
    PORTF |= _BV(0) | _BV(6);
    PORTL |= _BV(3);
    PORTA |= _BV(4);
    __builtin_avr_delay_cycles(40);
    PORTF &= ~(_BV(0) | _BV(6));
    PORTL &= ~_BV(3);
    PORTA &= ~_BV(4);
    steps_left--;
}

ISR(TIMER3_COMPA_vect)
{
    sei();
    __builtin_avr_delay_cycles(2000);
}

static void putc0(char c)
{
    while (!(UCSR0A & _BV(UDRE0)))
        ;
    UDR0 = c;
}

static void puts0(const char *s)
{
    while (*s)
        putc0(*s++);
}

static void puthex(uint8_t v)
{
    const char *h = "0123456789abcdef";
    putc0(h[v >> 4]);
    putc0(h[v & 15]);
}

static void putdec(uint32_t v)
{
    char buf[12];
    ultoa(v, buf, 10);
    puts0(buf);
}

static char line[100];
static uint8_t len;

static void handle(void)
{
    if (!strcmp(line, "pins")) {
        puts0("pins E=");
        puthex(PINE);
        puts0(" J=");
        puthex(PINJ);
        puts0(" D=");
        puthex(PIND);
        puts0(" C=");
        puthex(PINC);
        putc0('\n');
    } else if (!strncmp(line, "eew ", 4)) {
        char *end;
        uint16_t a = strtoul(line + 4, &end, 10);
        uint8_t v = strtoul(end, 0, 10);
        eeprom_write_byte((uint8_t *)a, v);
    } else if (!strncmp(line, "eer ", 4)) {
        uint16_t a = strtoul(line + 4, 0, 10);
        puts0("ee ");
        putdec(a);
        putc0('=');
        putdec(eeprom_read_byte((uint8_t *)a));
        putc0('\n');
    } else if (!strcmp(line, "wdt")) {
        wdt_enable(WDTO_15MS);
        for (;;)
            ;
    } else if (!strcmp(line, "nest")) {
        OCR3A = 400;
        TCNT3 = 0;
        TIMSK3 = _BV(OCIE3A);
        TCCR3B = _BV(WGM32) | _BV(CS30);
        for (;;)
            ;
    } else if (!strcmp(line, "spin off")) {
        TCCR2A = 0;
        PORTB &= ~_BV(4);
        DDRB |= _BV(4);
    } else if (!strncmp(line, "spin ", 5)) {
        OCR2A = strtoul(line + 5, 0, 10);
        DDRB |= _BV(4);
        TCCR2A = _BV(COM2A1) | _BV(WGM21) | _BV(WGM20);
        TCCR2B = _BV(CS21);
    } else if (!strncmp(line, "jogx ", 5)) {
        uint16_t n = strtoul(line + 5, 0, 10), trip = 0;
        DDRF |= _BV(0) | _BV(1);
        DDRD |= _BV(7);
        PORTD &= ~_BV(7);
        PORTF &= ~_BV(1);
        __builtin_avr_delay_cycles(100);
        for (uint16_t k = 1; k <= n; k++) {
            PORTF |= _BV(0);
            if (!trip && !(PINE & _BV(5)))
                trip = k;
            __builtin_avr_delay_cycles(60);
            PORTF &= ~_BV(0);
            __builtin_avr_delay_cycles(3000);
        }
        puts0("trip=");
        putdec(trip);
        putc0('\n');
    } else if (!strcmp(line, "stats")) {
        puts0("rx=");
        putdec(rx_count);
        puts0(" lost=");
        putdec(lost);
        puts0(" dor=");
        putdec(dor_seen);
        putc0('\n');
    } else if (!strncmp(line, "steps4 ", 7)) {
        /* step/dir/enable of X, Y, Z, E as outputs, enabled, dir + */
        DDRF |= _BV(0) | _BV(1) | _BV(6) | _BV(7) | _BV(2);
        DDRD |= _BV(7);
        DDRL |= _BV(3) | _BV(1);
        DDRK |= _BV(0);
        DDRA |= _BV(4) | _BV(6) | _BV(2);
        PORTD &= ~_BV(7);
        PORTF &= ~_BV(2);
        PORTK &= ~_BV(0);
        PORTA &= ~_BV(2);
        PORTF |= _BV(1) | _BV(7);
        PORTL |= _BV(1);
        PORTA |= _BV(6);
        cli();
        steps_left = strtoul(line + 7, 0, 10);
        sei();
        OCR1A = 399;
        TCNT1 = 0;
        TIMSK1 = _BV(OCIE1A);
        TCCR1B = _BV(WGM12) | _BV(CS10);
    } else if (!strncmp(line, "busy ", 5)) {
        uint16_t ms = strtoul(line + 5, 0, 10);
        cli();
        while (ms--)
            __builtin_avr_delay_cycles(16000);
        sei();
    } else if (!strcmp(line, "sleep")) {
        cli();
        set_sleep_mode(SLEEP_MODE_PWR_DOWN);
        sleep_enable();
        sleep_cpu();
    } else {
        puts0("echo:");
        puts0(line);
        putc0('\n');
    }
    puts0("ok\n");
}

extern uint8_t __heap_start;

int main(void)
{
    uint8_t flags = MCUSR;
    MCUSR = 0;
    wdt_disable();

    /* Paint free RAM for the stack high-water measurement. */
    for (uint8_t *p = &__heap_start; p < (uint8_t *)SP - 32; p++)
        *p = 0xC5;

    /* Pull-ups on the switch and encoder inputs, as the real firmware does. */
    PORTE |= _BV(5) | _BV(4);
    PORTJ |= _BV(1);
    PORTD |= _BV(3);
    PORTC |= _BV(6) | _BV(4) | _BV(2);

    UCSR0A = _BV(U2X0);
    UBRR0 = 7;
    UCSR0B = _BV(TXEN0) | _BV(RXEN0) | _BV(RXCIE0);
    sei();
    puts0("start\nreset ");
    puthex(flags);
    putc0('\n');

    for (;;) {
        if (head == tail)
            continue;
        uint8_t c = ring[tail];
        tail = tail + 1;
        if (c == '\n') {
            line[len] = 0;
            handle();
            len = 0;
        } else if (c != '\r' && len < sizeof(line) - 1) {
            line[len++] = c;
        }
    }
}
