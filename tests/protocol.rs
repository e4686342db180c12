//! Host protocol on the real firmware (docs/SPEC.md §4), in the virtual machine.

mod common;
use common::*;
use sim::ViolationKind;

#[test]
fn boot_prints_start_and_the_firmware_line() {
    let vm = boot();
    let out = vm.line_log().iter().map(|(_, l)| l.clone()).collect::<Vec<_>>().join("\n");
    let lines: Vec<&str> = out.lines().collect();
    let start = lines.iter().position(|l| *l == "start").expect("start line");
    let fw = lines[start + 1];
    assert!(fw.starts_with("FIRMWARE_NAME:MillFW"), "{fw}");
    assert!(fw.contains("MACHINE_TYPE:Mill") && fw.contains("TOOLS:12"), "{fw}");
    assert!(out.contains("reset cause:"), "{out}");
    // Nothing moved and no driver is enabled at boot.
    assert_eq!(total_steps(&vm), 0);
}

#[test]
fn m115_answers_with_the_firmware_line_then_ok() {
    let mut vm = boot();
    let r = ok(&mut vm, "M115");
    assert_eq!(r.len(), 2, "{r:?}");
    assert!(r[0].starts_with("FIRMWARE_NAME:MillFW") && r[0].contains("AXIS_COUNT:3"), "{r:?}");
}

#[test]
fn numbered_lines_are_acknowledged_and_a_bad_checksum_asks_for_a_resend() {
    let mut vm = boot();
    let l1 = "N1 G21";
    ok(&mut vm, &format!("{l1}*{}", checksum(l1)));
    let l2 = "N2 G90";
    let bad = checksum(l2) ^ 0x55;
    let r = vm.command(&format!("{l2}*{bad}")).unwrap();
    assert_eq!(r.len(), 3, "{r:?}");
    assert!(r[0].starts_with("Error:checksum mismatch") && r[0].ends_with("Last Line: 1"), "{r:?}");
    assert_eq!(r[1], "Resend:2");
    assert_eq!(r[2], "ok");
    // The resent line is accepted.
    ok(&mut vm, &format!("{l2}*{}", checksum(l2)));
    // A skipped number is refused with a resend of the expected one.
    let l4 = "N4 G90";
    let r = vm.command(&format!("{l4}*{}", checksum(l4))).unwrap();
    assert!(r.iter().any(|l| l == "Resend:3"), "{r:?}");
}

#[test]
fn m110_sets_the_line_number_as_printcore_does() {
    let mut vm = boot();
    let l = "N-1 M110";
    ok(&mut vm, &format!("{l}*{}", checksum(l)));
    let l = "N0 G21";
    ok(&mut vm, &format!("{l}*{}", checksum(l)));
    let l = "N100 M110 N100";
    ok(&mut vm, &format!("{l}*{}", checksum(l)));
    let l = "N101 G90";
    ok(&mut vm, &format!("{l}*{}", checksum(l)));
}

#[test]
fn a_300_character_line_is_an_error_and_nothing_moves() {
    // Lines up to 256 characters of code run (LinuxCNC's limit); comment
    // text past it is dropped (tests/dialect.rs), code past it is refused.
    let mut vm = boot();
    let mut long = String::from("G0 X10 Y10");
    while long.len() < 300 {
        long.push_str(" G90");
    }
    long.truncate(300);
    let before = steps(&vm);
    let e = refused(&mut vm, &long);
    assert!(e.contains("line too long"), "{e}");
    ok(&mut vm, "M400");
    vm.run_for(0.2).unwrap();
    assert_eq!(steps(&vm), before);
    assert_eq!(total_steps(&vm), 0);
}

#[test]
fn four_kib_of_random_bytes_without_flow_control_do_not_crash_or_reset() {
    let mut vm = boot();
    let before = steps(&vm);
    let mut rng = Rng(0x1234_5678);
    let junk: Vec<u8> = (0..4096).map(|_| rng.next() as u8).collect();
    vm.send_unpaced_flood(&junk);
    vm.run_for(0.5).unwrap();
    vm.send(b"\n");
    vm.run_for(0.1).unwrap();
    vm.take_lines();
    // Clear whatever the junk left (an alarm if the junk spelled M112 is fine;
    // a crash or reset is not).
    let r = vm.command("M115").expect("firmware still answers");
    assert!(r.iter().any(|l| l.starts_with("FIRMWARE_NAME:MillFW")), "{r:?}");
    assert!(vm.fatal_error().is_none());
    assert_eq!(vm.resets().iter().filter(|r| r.kind != sim::ResetKind::PowerOn).count(), 0, "{:?}", vm.resets());
    assert_eq!(steps(&vm), before, "random bytes moved the machine");
}

#[test]
fn a_flood_that_overruns_the_rx_ring_drops_only_the_damaged_lines() {
    // M114 answers with ~50 bytes for 5 received, so a host that ignores `ok`
    // soon fills the 255-byte RX ring and bytes are lost. Any M114 that loses
    // a byte becomes a different line ("M14", "114", "M114M114"...), so the
    // only acceptable errors are the overrun ones: a damaged line must never
    // run, and an intact one must answer normally.
    let mut vm = boot();
    let n = 400;
    vm.send_unpaced_flood("M114\n".repeat(n).as_bytes());
    vm.run_until(|vm| vm.tx_pending() == 0 && vm.output().matches("ok").count() > 10, 20.0).unwrap();
    // The drops' replies (~90 bytes each) take a while.
    let _ = vm.run_until(|vm| vm.output().matches("ok").count() >= n, 5.0);
    vm.run_for(0.5).unwrap();
    let lines = vm.take_lines();
    let overruns = lines.iter().filter(|l| l.starts_with("Error:serial receive overrun")).count();
    let other_errors: Vec<_> = lines.iter().filter(|l| l.starts_with("Error") && !l.contains("overrun")).collect();
    let reports = lines.iter().filter(|l| l.starts_with("X:")).count();
    let oks = lines.iter().filter(|l| *l == "ok").count();
    assert!(vm.uart_rx_dropped() > 0 || overruns > 0, "the flood never overran the ring; the test proves nothing");
    assert!(overruns > 0, "bytes were lost but no line was dropped");
    assert!(other_errors.is_empty(), "a damaged line ran: {other_errors:?}");
    assert_eq!(oks, reports + overruns, "one ok per line, for {reports} reports and {overruns} drops");
    // Even a line whose end was lost gets its reply: a host counting
    // replies is never left waiting.
    assert_eq!(reports + overruns, n, "{reports} reports and {overruns} drops for {n} lines");
    eprintln!("{n} sent: {reports} answered, {overruns} dropped, {} bytes lost by the UART model", vm.uart_rx_dropped());
    assert!(reports > 0 && reports < n);
    // If the flood's last bytes were lost, the next line is marked damaged
    // (the loss may have cut it): end that line before asking M115.
    vm.send(b"\n");
    vm.run_for(0.1).unwrap();
    vm.take_lines();
    let r = vm.command("M115").expect("firmware still answers");
    assert!(r.iter().any(|l| l.starts_with("FIRMWARE_NAME:MillFW")), "{r:?}");
    assert_eq!(vm.resets().iter().filter(|r| r.kind != sim::ResetKind::PowerOn).count(), 0);
}

#[test]
fn m112_from_a_full_queue_stops_everything() {
    let mut vm = boot();
    ok(&mut vm, "M999");
    ok(&mut vm, "G21 G90 G1 F600");
    // Far more moves than the planner holds, sent without waiting for ok.
    let mut job = String::new();
    for i in 0..60 {
        let x = if i % 2 == 0 { 30 } else { 10 };
        job.push_str(&format!("G1 X{x} Y{}\n", 5 + i % 7));
    }
    vm.send(job.as_bytes());
    vm.run_for(0.3).unwrap();
    assert!(total_steps(&vm) > 0, "motion started");
    vm.send(b"M112\n");
    // The RX ISR acts on the bytes: within a few ms everything has stopped.
    vm.run_for(0.01).unwrap();
    let stopped_at = steps(&vm);
    vm.run_for(0.5).unwrap();
    assert_eq!(steps(&vm), stopped_at, "steps after M112");
    for a in [sim::Axis::X, sim::Axis::Y, sim::Axis::Z, sim::Axis::E] {
        assert!(!vm.driver_enabled(a), "{a:?} driver still enabled");
    }
    assert!(!vm.spindle_on());
    assert!(vm.output().contains("ALARM:emergency stop"), "{}", vm.output());
    // Let the rest of the queued job drain (each line is refused), end any
    // partial line, then check the refusal on a clean line.
    vm.run_until(|vm| vm.tx_pending() == 0, 5.0).unwrap();
    vm.send(b"\n");
    vm.run_for(0.2).unwrap();
    vm.take_lines();
    // Motion is refused until M999.
    let e = refused(&mut vm, "G1 X20");
    assert!(e.starts_with("Error:alarm emergency stop"), "{e}");
    assert!(vm.recorder().violations_of(ViolationKind::StepWhileDisabled).is_empty());
}

#[test]
fn m108_continues_after_m0_although_it_waits_behind_the_pause() {
    let mut vm = boot();
    ok(&mut vm, "M999");
    ok(&mut vm, "G21 G90");
    let x0 = steps(&vm)[0];
    vm.send_line("M0");
    vm.wait_line(|l| l.starts_with("echo:paused"), 1.0).expect("paused");
    // Queued behind M0: nothing runs while paused.
    vm.send_line("G1 X5 F1200");
    vm.run_for(0.3).unwrap();
    assert_eq!(steps(&vm)[0], x0, "moved while paused");
    assert!(!vm.pending_lines().iter().any(|l| l == "ok"), "M0 acknowledged before it was continued");
    vm.send_line("M108");
    vm.run_for(1.0).unwrap();
    let oks = vm.take_lines().iter().filter(|l| *l == "ok").count();
    assert_eq!(oks, 3, "M0, G1 and M108 each get one ok");
    assert_eq!(steps(&vm)[0] - x0, 500);
}
