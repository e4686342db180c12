/* Test firmware: grbl-style step pulse timed by Timer0 overflow.
 * Three times: stop Timer0, preload TCNT0 = 200, raise X step, start Timer0
 * at clk/1; the overflow ISR (56 timer ticks later on hardware) drops the
 * pulse and stops the timer. Then prints "done".
 */
#include <avr/io.h>
#include <avr/interrupt.h>

static volatile uint8_t pulse_done;

ISR(TIMER0_OVF_vect)
{
    PORTF &= ~_BV(0);
    TCCR0B = 0;
    pulse_done = 1;
}

int main(void)
{
    UCSR0A = _BV(U2X0);
    UBRR0 = 7;
    UCSR0B = _BV(TXEN0);
    DDRF |= _BV(0) | _BV(1);
    DDRD |= _BV(7);
    PORTD &= ~_BV(7);
    PORTF |= _BV(1);
    TIMSK0 = _BV(TOIE0);
    sei();
    for (uint8_t i = 0; i < 3; i++) {
        __builtin_avr_delay_cycles(2000);
        pulse_done = 0;
        TCCR0B = 0;
        TCNT0 = 200;
        PORTF |= _BV(0);
        TCCR0B = _BV(CS00);
        while (!pulse_done)
            ;
    }
    const char *s = "done\n";
    while (*s) {
        while (!(UCSR0A & _BV(UDRE0)))
            ;
        UDR0 = *s++;
    }
    for (;;)
        ;
}
