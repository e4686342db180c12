#![cfg_attr(target_arch = "avr", no_std, no_main, feature(abi_avr_interrupt))]

#[cfg(not(target_arch = "avr"))]
fn main() {
    eprintln!("the mill firmware runs on the ATmega2560: build it with `cargo fw`");
}

#[cfg(target_arch = "avr")]
#[avr_device::entry]
fn main() -> ! {
    let dp = avr_device::atmega2560::Peripherals::take().unwrap();
    let u = &dp.USART0;
    u.ubrr0().write(|w| unsafe { w.bits(3) });
    u.ucsr0a().write(|w| w.u2x0().set_bit());
    u.ucsr0b().write(|w| w.txen0().set_bit().rxen0().set_bit());
    for &b in b"start\n" {
        while u.ucsr0a().read().udre0().bit_is_clear() {}
        u.udr0().write(|w| unsafe { w.bits(b) });
    }
    loop {}
}

#[cfg(target_arch = "avr")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}
