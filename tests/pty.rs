//! The pty bridge (`sim::pty`, `sim --pty`) as a real sender sees it
//! (issue 14, item 9): motion and firmware output count as activity for
//! `--idle-exit`; realtime commands pass bytes still waiting for the UART;
//! a sender that closes the port and opens it again finds it working, with
//! no stale output: the board resets on every open (auto-reset) unless
//! that is turned off, as on a board with its reset jumper cut.

mod common;
use common::*;
use sim::pty::PtyBridge;
use sim::Vm;
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::time::{Duration, Instant};

/// The last line of the boot banner (the homing lock is on by default).
const BANNER_END: &str = "echo:home (G28) before moving";

/// A sender on the pty's slave side (non-blocking reads).
struct Host {
    port: File,
    got: String,
}

impl Host {
    fn open(bridge: &PtyBridge) -> Host {
        let port = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
            .open(bridge.port())
            .expect("open the pty");
        Host { port, got: String::new() }
    }

    fn write(&mut self, bytes: &[u8]) {
        self.port.write_all(bytes).unwrap();
    }

    fn read(&mut self) {
        let mut buf = [0u8; 4096];
        while let Ok(n) = self.port.read(&mut buf) {
            if n == 0 {
                break;
            }
            self.got.push_str(&String::from_utf8_lossy(&buf[..n]));
        }
    }

    /// Opening the port reset the board (auto-reset): pump until the
    /// sender has read the fresh banner, then forget what it read.
    fn after_reset(&mut self, bridge: &mut PtyBridge, vm: &mut Vm) {
        self.until(bridge, vm, |l| l.starts_with(BANNER_END));
        self.got.clear();
    }

    /// Pump until the sender has read a line matching `pred` (up to 20 s of
    /// simulated time).
    fn until(&mut self, bridge: &mut PtyBridge, vm: &mut Vm, mut pred: impl FnMut(&str) -> bool) {
        for _ in 0..10_000 {
            bridge.pump(vm, 0.002).unwrap();
            self.read();
            // Complete lines only.
            let done = &self.got[..self.got.rfind('\n').map_or(0, |i| i + 1)];
            if done.lines().any(&mut pred) {
                return;
            }
        }
        panic!("no such line; the sender read {:?}", self.got);
    }
}

#[test]
fn motion_and_firmware_output_count_as_activity_without_host_bytes() {
    let mut vm = boot();
    let mut bridge = PtyBridge::open(&vm, None).unwrap();
    let mut host = Host::open(&bridge);
    // A 2 s move, then M400: after the `ok` of G1 the sender is silent and
    // so, for 2 s, is the firmware but for its keepalive: the steps are the
    // activity.
    host.write(b"M999\nG1 X20 F600\nM400\n");
    let (mut silent_slices, mut silent_but_moving) = (0, 0);
    let mut done = false;
    for _ in 0..2000 {
        let a = bridge.pump_activity(&mut vm, 0.002).unwrap();
        host.read();
        if a.host_bytes == 0 && a.output_bytes == 0 {
            silent_slices += 1;
            if a.steps > 0 {
                silent_but_moving += 1;
                assert!(a.any());
            }
        }
        if host.got.matches("ok").count() >= 3 {
            done = true;
            break;
        }
    }
    assert!(done, "{:?}", host.got);
    // Nearly every silent slice of the 2 s move made steps.
    assert!(silent_but_moving > 800, "{silent_but_moving} of {silent_slices} silent slices moved");
    let start = vm.config().machine.initial_position;
    assert_eq!(vm.position(sim::Axis::X), start[0] + 2000);
}

#[test]
fn realtime_bytes_pass_lines_still_waiting_for_the_uart() {
    let mut vm = boot();
    let mut bridge = PtyBridge::open(&vm, None).unwrap();
    let mut host = Host::open(&bridge);
    host.after_reset(&mut bridge, &mut vm);
    assert_eq!(bridge.auto_resets, 1);
    ok(&mut vm, "M999");
    // 120 short lines (480 bytes, ~19 ms of line time) then `?` at a line
    // start: the status report comes back while most lines still wait.
    let mut burst: Vec<u8> = (0..120).flat_map(|_| b"G90\n".to_vec()).collect();
    burst.extend(b"?");
    host.write(&burst);
    host.until(&mut bridge, &mut vm, |l| l.starts_with('<'));
    assert!(bridge.waiting() > 200, "{} bytes still waiting", bridge.waiting());
    assert_eq!(bridge.urgent, 1);
    // A `?` inside a comment is text: it stays in its line, in order.
    host.got.clear();
    host.write(b"G90 (right?)\n");
    host.until(&mut bridge, &mut vm, |l| l == "ok");
    assert_eq!(bridge.urgent, 1);
    // An M112 line passes waiting lines too: the machine stops at once.
    host.got.clear();
    let mut burst: Vec<u8> = (0..120).flat_map(|_| b"G90\n".to_vec()).collect();
    burst.extend(b"M112\n");
    host.write(&burst);
    host.until(&mut bridge, &mut vm, |l| l.starts_with("ALARM"));
    assert!(bridge.waiting() > 200, "{} bytes still waiting", bridge.waiting());
    assert_eq!(bridge.urgent, 2);
    // Ctrl-X passes from inside a half-written line.
    host.write(b"G90 X\x18");
    for _ in 0..10 {
        bridge.pump(&mut vm, 0.002).unwrap();
    }
    assert_eq!(bridge.urgent, 3);
}

#[test]
fn a_sender_that_reconnects_finds_the_port_working_without_stale_output() {
    let mut vm = boot();
    let mut bridge = PtyBridge::open(&vm, None).unwrap();
    let mut host = Host::open(&bridge);
    host.write(b"M115\n");
    host.until(&mut bridge, &mut vm, |l| l == "ok");
    assert!(host.got.contains("FIRMWARE_NAME"), "{:?}", host.got);
    // The sender leaves with a command running: its replies come with
    // nobody reading.
    host.write(b"M999\nG4 S0.2\nM115\n");
    for _ in 0..20 {
        bridge.pump(&mut vm, 0.002).unwrap();
    }
    drop(host);
    let t = Instant::now();
    while t.elapsed() < sim::pty::STALE_OUTPUT + Duration::from_millis(700) {
        bridge.pump(&mut vm, 0.002).unwrap();
    }
    assert!(bridge.stale_dropped > 0, "nothing was left unread");
    // A new sender: opening the port resets the board, and the first thing
    // it reads is the fresh banner, then the answer to its own command.
    let mut host = Host::open(&bridge);
    host.until(&mut bridge, &mut vm, |l| l.starts_with(BANNER_END));
    let first = host.got.lines().next().unwrap_or("");
    assert_eq!(first, "start", "stale output reached the new sender: {:?}", host.got);
    host.got.clear();
    host.write(b"M114\n");
    host.until(&mut bridge, &mut vm, |l| l == "ok");
    assert!(host.got.lines().next().unwrap_or("").starts_with("X:"), "{:?}", host.got);
    // And once more, closing and opening again at once.
    drop(host);
    let mut host = Host::open(&bridge);
    host.until(&mut bridge, &mut vm, |l| l.starts_with("echo:reset cause"));
    assert_eq!(host.got.lines().next().unwrap_or(""), "start", "{:?}", host.got);
    assert_eq!(bridge.auto_resets, 3);
}

#[test]
fn without_auto_reset_a_reconnecting_sender_finds_the_board_as_it_left_it() {
    let mut vm = boot();
    let mut bridge = PtyBridge::open(&vm, None).unwrap().auto_reset(false);
    let mut host = Host::open(&bridge);
    host.write(b"M999\nG1 X1 F600\nM400\nM114\n");
    host.until(&mut bridge, &mut vm, |l| l.starts_with("X:"));
    drop(host);
    // The first thing the next sender reads is the answer to its own
    // command: no banner, no stale output, the position kept.
    let t = Instant::now();
    while t.elapsed() < sim::pty::STALE_OUTPUT + Duration::from_millis(700) {
        bridge.pump(&mut vm, 0.002).unwrap();
    }
    let mut host = Host::open(&bridge);
    host.write(b"M114\n");
    host.until(&mut bridge, &mut vm, |l| l == "ok");
    let first = host.got.lines().next().unwrap_or("");
    assert!(first.starts_with("X:1.000"), "{:?}", host.got);
    assert_eq!(bridge.auto_resets, 0);
    assert_eq!(vm.resets().len(), 1);
}
