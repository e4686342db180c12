//! The serial link runs at the wire rate the firmware's registers give, in
//! both directions, for this firmware and for the real grbl-Mega alike: a
//! byte a frame (start, 8 data bits, stop: 10 bits of 8 (UBRR0 + 1)
//! cycles with U2X0), whatever order the firmware writes UBRR0 and U2X0 in
//! (this firmware writes UBRR0 first, grbl U2X0 first; simavr alone took
//! the order into account and ran this firmware's link at half the rate).
//! The VM's UART clock is `sim/src/vm/uart_clock.rs`; the benchmark's
//! 115200 and 250000 rows depend on it.

mod common;
use common::*;
use sim::{Flow, StreamOptions, Vm, VmConfig};
use std::path::PathBuf;

/// `../shared/peers/grbl-mega/grbl-mega-<baud>.elf`.
fn grbl(baud: u32) -> Vm {
    let elf = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../shared/peers/grbl-mega/grbl-mega-{baud}.elf"));
    assert!(elf.exists(), "{} missing (the peer firmware, ../shared/peers/grbl-mega)", elf.display());
    let mut vm = Vm::new(VmConfig::grbl_mega(elf)).expect("load grbl-Mega");
    vm.wait_line(|l| l.starts_with("Grbl 1.1"), 3.0).expect("grbl's banner");
    vm.run_for(0.2).unwrap();
    vm.take_lines();
    vm
}

/// 8N1 with U2X: 10 bits of 8 (UBRR + 1) cycles (datasheet §22.3.1, §22.4).
fn frame_cycles(ubrr: u64) -> u64 {
    10 * 8 * (ubrr + 1)
}

/// Streams 400 comment-only lines of 18 bytes with 254 bytes in flight
/// (the firmware does almost nothing with them, so the wire sets the pace)
/// and returns the cycles per received byte between the 50th and the last
/// `ok`.
fn cycles_per_byte_streamed(vm: &mut Vm) -> f64 {
    const LINES: usize = 400;
    let lines: Vec<String> = (0..LINES).map(|k| format!("; pacing {k:08}")).collect();
    assert_eq!(lines[0].len() + 1, 18);
    let log0 = vm.line_log().len();
    let rep = vm.stream(&lines, StreamOptions::new(Flow::CharCount(254)).timeout(5.0)).unwrap();
    assert!(!rep.timed_out && rep.oks == LINES, "{rep:?}");
    let oks: Vec<u64> = vm.line_log()[log0..].iter().filter(|(_, l)| l == "ok").map(|(c, _)| *c).collect();
    assert_eq!(oks.len(), LINES);
    (oks[LINES - 1] - oks[49]) as f64 / ((LINES - 50) * 18) as f64
}

fn assert_wire_rate(name: &str, vm: &mut Vm, ubrr: u64) {
    let frame = frame_cycles(ubrr);
    assert_eq!(vm.uart_frame_cycles(), frame, "{name}: the VM's frame time");
    let per_byte = cycles_per_byte_streamed(vm);
    let ratio = per_byte / frame as f64;
    assert!((0.99..1.01).contains(&ratio), "{name}: {per_byte:.0} cycles a byte streamed, a frame is {frame} ({ratio:.3}x)");
}

#[test]
fn this_firmware_takes_bytes_at_the_wire_rate() {
    // The default build: 250000 baud, UBRR0 = 7.
    let mut vm = boot();
    assert_wire_rate("this firmware, 250000", &mut vm, 7);
}

#[test]
fn grbl_mega_takes_bytes_at_the_wire_rate() {
    assert_wire_rate("grbl-Mega, 250000", &mut grbl(250_000), 7);
    // 115200: UBRR0 = 16 (117647 baud).
    assert_wire_rate("grbl-Mega, 115200", &mut grbl(115_200), 16);
}
