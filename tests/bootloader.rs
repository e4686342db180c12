//! The board as users have it: the stock Mega2560 bootloader (Debian's
//! `arduino-core-avr`, `sim::boot`) in the virtual machine, flashed by
//! avrdude through `tools/flash` over the pty, reset by the port.
//!
//! - `tools/flash` writes the firmware, verifies it, and the board boots
//!   the flashed image, also after a watchdog reset; the same for an image
//!   of the whole 253,952-byte application space (tests run in parallel
//!   threads: the two avrdude sessions overlap).
//! - A watchdog reset goes through the bootloader, which starts the
//!   application at byte 0x20000 (EIND = 1): the landing pad there
//!   (src/board/bootloader.rs) brings it to the banner with `reset cause:
//!   watchdog` and the watchdog alarm. The same test on the same firmware
//!   without the pad (`mill-no-landing.elf`, `$MILL_ELF_NO_LANDING`, kept
//!   by tools/link-firmware) must fail: it runs into the middle of a
//!   function at 0x20000 (measured: it restarts through address 0 and
//!   reports `reset cause: external`, with no watchdog alarm).
//! - The bootloader clears MCUSR: the firmware still tells power-on,
//!   external (the port's DTR) and watchdog apart.
//! - Three `!` in the first bytes after a reset enter the bootloader's
//!   monitor instead of the firmware (docs/flashing.md).

mod common;
use sim::pty::PtyBridge;
use sim::{boot, ResetKind, Vm, VmConfig};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bootloader() -> PathBuf {
    let hex = boot::default_hex_path();
    assert!(hex.exists(), "{} missing: tools/setup installs Debian's arduino-core-avr", hex.display());
    hex
}

/// A board as sold: the bootloader, and `elf`'s image in flash (or nothing).
fn board(elf: &Path, blank: bool) -> Vm {
    let mut cfg = VmConfig::new(elf);
    cfg.bootloader = Some(bootloader());
    cfg.blank_application = blank;
    // Erased flash (0xFFFF) is no instruction simavr knows; the chip runs
    // through it up to the bootloader again, and so does the VM.
    cfg.stop_on_bad_opcode = !blank;
    Vm::new(cfg).expect("load the board")
}

/// A scratch directory for this test.
fn scratch(name: &str) -> PathBuf {
    let d = root().join("target/test-bootloader").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The application image of an ELF as Intel hex (what tools/build-firmware makes).
fn hex_of(elf: &Path, dir: &Path) -> PathBuf {
    let hex = dir.join("mill.hex");
    let st = Command::new("avr-objcopy").args(["-O", "ihex", "-R", ".eeprom"]).arg(elf).arg(&hex).status().unwrap();
    assert!(st.success());
    hex
}

/// Flat bytes of a hex image from address 0.
fn image(hex: &Path) -> Vec<u8> {
    let mut img = Vec::new();
    for c in boot::read_ihex(hex).unwrap() {
        let end = c.addr as usize + c.bytes.len();
        if img.len() < end {
            img.resize(end, 0xFF);
        }
        img[c.addr as usize..end].copy_from_slice(&c.bytes);
    }
    img
}

/// Runs `tools/flash PORT` with `MILL_HEX=hex` against the virtual board,
/// pumping the pty until avrdude exits. Returns avrdude's output and how
/// much the chip had printed when the bootloader last ran (what follows is
/// the application's); panics if avrdude failed.
fn flash(vm: &mut Vm, hex: &Path, dir: &Path) -> (String, usize) {
    let mut bridge = PtyBridge::open(vm, None).expect("pty").realtime(true).fast_while_busy(true);
    let log = dir.join("avrdude.log");
    let out = std::fs::File::create(&log).unwrap();
    let mut child = Command::new(root().join("tools/flash"))
        .arg(bridge.port())
        .env("MILL_HEX", hex)
        .stdin(Stdio::null())
        .stdout(out.try_clone().unwrap())
        .stderr(out)
        .spawn()
        .expect("tools/flash");
    let t = Instant::now();
    let mut boot_out = 0;
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if t.elapsed() > Duration::from_secs(900) {
            let _ = child.kill();
            panic!("avrdude still running after 900 s: {}", std::fs::read_to_string(&log).unwrap_or_default());
        }
        // After avrdude's last command the bootloader starts whatever is in
        // flash: a crash there (the full-space noise image) ends the pumping.
        if vm.fatal_error().is_none() {
            let _ = bridge.pump(vm, 0.001);
            if vm.pc() >= boot::BOOT_START {
                boot_out = vm.output_bytes().len();
            }
        } else {
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    let text = std::fs::read_to_string(&log).unwrap();
    eprintln!("tools/flash: {:.1} s wall, {} auto-reset(s)\n{}", t.elapsed().as_secs_f64(), bridge.auto_resets, tail(&text));
    assert!(status.success(), "tools/flash failed:\n{text}");
    assert!(bridge.auto_resets >= 1, "opening the port did not reset the board");
    (text, boot_out)
}

fn tail(s: &str) -> String {
    s.lines().filter(|l| !l.contains('#')).rev().take(12).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n")
}

/// `N bytes of flash written` / `verified` in avrdude's output.
fn avrdude_bytes(out: &str, what: &str) -> Option<usize> {
    let key = format!("bytes of flash {what}");
    out.lines().find(|l| l.contains(&key))?.split_whitespace().find_map(|w| w.parse().ok())
}

/// Complete lines the firmware printed after `from` bytes of output.
fn lines_after(vm: &Vm, from: usize) -> Vec<String> {
    let text = String::from_utf8_lossy(&vm.output_bytes()[from..]).to_string();
    let done = &text[..text.rfind('\n').map_or(0, |i| i + 1)];
    done.lines().map(|l| l.trim_end_matches('\r').to_string()).collect()
}

#[test]
fn tools_flash_writes_and_verifies_the_firmware_and_the_board_boots_it() {
    let dir = scratch("firmware");
    let elf = VmConfig::default_elf_path();
    let hex = hex_of(&elf, &dir);
    let want = image(&hex);
    let mut vm = board(&elf, true);
    // Only the bootloader: it waits, starts the erased application (0xFFFF
    // is a no-op that runs up to the bootloader again), and waits again.
    assert!(vm.read_flash(0, 4) == [0xFF; 4]);
    let (out, from) = flash(&mut vm, &hex, &dir);
    assert_eq!(avrdude_bytes(&out, "written"), Some(want.len()), "{out}");
    assert_eq!(avrdude_bytes(&out, "verified"), Some(want.len()), "{out}");
    assert!(vm.read_flash(0, want.len()) == want, "flash differs from the image");
    // avrdude leaves the bootloader, which starts the flashed firmware.
    if let Err(e) = vm.run_until(|vm| lines_after(vm, from).iter().any(|l| l.starts_with("echo:reset cause")), 5.0) {
        panic!("{e}: no banner from the flashed image: {:?}", lines_after(&vm, from));
    }
    let lines = lines_after(&vm, from);
    assert!(lines.iter().any(|l| l == "start"), "{lines:?}");
    // A first start after flashing: nothing of the firmware's was in SRAM.
    assert!(lines.iter().any(|l| l == "echo:reset cause: power-on"), "{lines:?}");
    // What avrdude's session left in the output (the bootloader's replies,
    // the flash read back for the verify) is not an answer to M115.
    vm.take_lines();
    assert!(common::ok(&mut vm, "M115").iter().any(|l| l.contains("FIRMWARE_NAME")));
    // The flashed image through a watchdog reset: the bootloader starts it
    // at 0x20000, the landing pad brings it to the banner.
    let from = vm.output_bytes().len();
    assert!(vm.hang());
    let _ = vm.run_until(|vm| lines_after(vm, from).iter().any(|l| l.starts_with("echo:reset cause")), 5.0);
    let lines = lines_after(&vm, from);
    assert!(lines.iter().any(|l| l == "echo:reset cause: watchdog"), "{lines:?}");
}

#[test]
fn tools_flash_writes_and_verifies_the_whole_application_space() {
    let dir = scratch("full");
    let n = boot::BOOT_START as usize;
    assert_eq!(n, 253_952);
    let mut rng = common::Rng(0x1234_5678);
    let noise: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
    let hex = dir.join("full.hex");
    boot::write_ihex(&hex, 0, &noise).unwrap();
    let mut vm = board(&VmConfig::default_elf_path(), true);
    let boot_section = vm.read_flash(boot::BOOT_START, 8192);
    let (out, _) = flash(&mut vm, &hex, &dir);
    assert_eq!(avrdude_bytes(&out, "written"), Some(n), "{out}");
    assert_eq!(avrdude_bytes(&out, "verified"), Some(n), "{out}");
    assert!(vm.read_flash(0, n) == noise, "flash differs from the image");
    assert!(vm.read_flash(boot::BOOT_START, 8192) == boot_section, "the bootloader was overwritten");
}

/// Boots the board with `elf` already flashed, hangs the firmware, and
/// returns what it printed after the watchdog reset (up to 5 s later).
fn after_a_watchdog_reset(elf: &Path) -> (Vm, Vec<String>) {
    let mut vm = board(elf, false);
    vm.wait_banner().expect("banner through the bootloader");
    assert!(vm.output().contains("echo:reset cause: power-on"), "{}", vm.output());
    let from = vm.output_bytes().len();
    assert!(vm.hang(), "no __stop_program in {}", elf.display());
    // The watchdog runs at 2 s; then the bootloader, then the firmware.
    let _ = vm.run_until(|vm| lines_after(vm, from).iter().any(|l| l.starts_with("echo:reset cause")), 5.0);
    let lines = lines_after(&vm, from);
    (vm, lines)
}

/// What a watchdog reset through the bootloader must end in: the banner
/// with `reset cause: watchdog`, the watchdog alarm and a board that
/// answers. Err says what happened instead.
fn watchdog_reset_ends_in_the_banner(elf: &Path) -> Result<(), String> {
    let (mut vm, lines) = after_a_watchdog_reset(elf);
    let seen = |vm: &Vm| format!("after the reset: {lines:?}, VM error {:?}", vm.fatal_error());
    if vm.resets().last().map(|r| r.kind) != Some(ResetKind::Watchdog) {
        return Err(format!("no watchdog reset; {}", seen(&vm)));
    }
    if !lines.iter().any(|l| l == "echo:reset cause: watchdog") {
        return Err(seen(&vm));
    }
    vm.run_for(0.1).map_err(|e| e.to_string())?;
    if !lines_after(&vm, 0).iter().any(|l| l.starts_with("ALARM") && l.contains("watchdog")) {
        return Err(format!("no watchdog alarm; {}", seen(&vm)));
    }
    vm.command("M115").map_err(|e| e.to_string())?;
    Ok(())
}

#[test]
fn a_watchdog_reset_through_the_bootloader_lands_on_the_pad_and_reports_watchdog() {
    if let Err(e) = watchdog_reset_ends_in_the_banner(&VmConfig::default_elf_path()) {
        panic!("{e}");
    }
}

#[test]
fn without_the_landing_pad_the_same_watchdog_reset_goes_wrong() {
    let Some(elf) = std::env::var_os("MILL_ELF_NO_LANDING").map(PathBuf::from) else {
        panic!("MILL_ELF_NO_LANDING unset: tools/test points it at mill-no-landing.elf (tools/link-firmware)");
    };
    match watchdog_reset_ends_in_the_banner(&elf) {
        Ok(()) => panic!("the firmware without the landing pad came through a watchdog reset unharmed"),
        Err(e) => eprintln!("without the landing pad: {e}"),
    }
}

#[test]
fn the_reset_cause_survives_the_bootloader_clearing_mcusr() {
    let mut vm = board(&VmConfig::default_elf_path(), false);
    vm.wait_banner().unwrap();
    assert!(vm.output().contains("echo:reset cause: power-on"));
    for (reset, cause) in [(Vm::reset as fn(&mut Vm), "external"), (Vm::power_cycle, "power-on"), (Vm::reset, "external")] {
        let from = vm.output_bytes().len();
        reset(&mut vm);
        vm.run_until(|vm| lines_after(vm, from).iter().any(|l| l.starts_with("echo:reset cause")), 3.0).unwrap();
        let lines = lines_after(&vm, from);
        assert!(lines.iter().any(|l| *l == format!("echo:reset cause: {cause}")), "{cause}: {lines:?}");
    }
}

#[test]
fn three_bangs_right_after_a_reset_enter_the_bootloader_monitor_not_the_firmware() {
    let mut vm = board(&VmConfig::default_elf_path(), false);
    vm.wait_banner().unwrap();
    let from = vm.output_bytes().len();
    vm.reset();
    // A host that sends feed hold three times right after opening the port.
    vm.run_for(0.05).unwrap();
    vm.send(b"!!!");
    vm.run_for(3.0).unwrap();
    let out = String::from_utf8_lossy(&vm.output_bytes()[from..]).to_string();
    assert!(!out.contains("start"), "the firmware started: {out:?}");
    // The monitor's greeting: five rows of 25 `!`.
    assert!(out.contains(&format!("{}\r\n", "!".repeat(25)).repeat(5)), "no monitor: {out:?}");
    // Its quit command starts the firmware.
    vm.send(b"Q");
    if let Err(e) = vm.run_until(|vm| lines_after(vm, from).iter().any(|l| l.starts_with("echo:reset cause")), 10.0) {
        panic!("{e}: {:?}", String::from_utf8_lossy(&vm.output_bytes()[from..]));
    }
}

/// Simulated seconds from `vm.seconds()` now until the firmware's banner
/// (at most `timeout_s`); None if it never came.
fn seconds_to_banner(vm: &mut Vm, timeout_s: f64) -> Option<f64> {
    let from = vm.output_bytes().len();
    let t0 = vm.seconds();
    vm.run_until(|vm| lines_after(vm, from).iter().any(|l| l.starts_with("echo:reset cause")), timeout_s).ok()?;
    Some(vm.seconds() - t0)
}

#[test]
fn the_bootloader_waits_a_second_and_a_byte_in_that_second_holds_it_until_the_line_is_quiet() {
    let mut vm = board(&VmConfig::default_elf_path(), false);
    vm.wait_banner().unwrap();
    // A reset with a quiet line: the bootloader's wait, then the firmware.
    vm.reset();
    let quiet = seconds_to_banner(&mut vm, 5.0).expect("banner");
    assert!((0.85..1.0).contains(&quiet), "{quiet:.2} s from reset to banner");
    // A host that writes right after opening the port: the bootloader
    // takes the bytes and waits for avrdude until 4.5 s of silence.
    vm.reset();
    vm.run_for(0.1).unwrap();
    vm.send(b"M105\n");
    let held = seconds_to_banner(&mut vm, 10.0).expect("banner");
    assert!((4.3..5.2).contains(&held), "{held:.2} s from the host's line to the banner");
    // A host that polls every 2 s keeps it there as long as it polls.
    vm.reset();
    let from = vm.output_bytes().len();
    for _ in 0..6 {
        vm.run_for(0.5).unwrap();
        vm.send(b"?");
        vm.run_for(1.5).unwrap();
    }
    assert!(!lines_after(&vm, from).iter().any(|l| l.starts_with("echo:reset cause")), "the firmware started while polled");
    let polled = seconds_to_banner(&mut vm, 10.0).expect("banner once the polling stops");
    assert!((3.0..4.0).contains(&polled), "{polled:.2} s after the last poll");
    eprintln!("boot wait {quiet:.2} s; a line in it: banner {held:.2} s later; polling every 2 s for 12 s: banner {polled:.2} s after the last poll (+1.5 already waited)");
}
