//! The VM against small C firmwares with known behaviour (tests/firmware/*.c).

mod common;

use sim::*;

fn host_vm() -> Vm {
    let mut vm = Vm::with_elf(common::firmware("host")).unwrap();
    vm.wait_for_start(1.0).unwrap();
    assert_eq!(vm.wait_line(|l| l.starts_with("reset"), 0.1).unwrap(), "reset 01");
    vm
}

fn steps_vm(config: impl FnOnce(&mut VmConfig)) -> Vm {
    let mut c = VmConfig::new(common::firmware("steps"));
    config(&mut c);
    let mut vm = Vm::new(c).unwrap();
    vm.wait_line(|l| l == "done", 1.0).unwrap();
    vm
}

#[test]
fn recorder_reports_exact_count_direction_and_timing_of_a_step_train() {
    let vm = steps_vm(|_| {});
    let x = vm.recorder().axis_stats(Axis::X);
    let y = vm.recorder().axis_stats(Axis::Y);
    // 1000 train steps + the short pulse forward, one step back after the dir flip.
    assert_eq!((x.steps_pos, x.steps_neg), (1001, 1));
    assert_eq!(vm.position(Axis::X), 2250 + 1000);
    assert_eq!((y.steps_pos, y.steps_neg), (0, 500));
    assert_eq!(vm.position(Axis::Y), 2250 - 500);
    // Z stepped once while disabled: flagged, did not move.
    assert_eq!(vm.position(Axis::Z), 2250);
    assert_eq!(vm.recorder().axis_stats(Axis::Z).steps_while_disabled, 1);

    // Timing of the trains: every 1600 cycles (100 µs) on X, 800 (50 µs) on Y.
    let xs: Vec<u64> = vm.recorder().trace().iter().filter(|t| t.axis == Axis::X).map(|t| t.cycle).collect();
    let ys: Vec<u64> = vm.recorder().trace().iter().filter(|t| t.axis == Axis::Y).map(|t| t.cycle).collect();
    // Interrupt latency depends on the instruction being executed when the
    // compare matches (as on hardware): ±1 cycle per pulse, exact on average.
    assert!(xs[..1000].windows(2).all(|w| (w[1] - w[0]).abs_diff(1600) <= 1));
    assert!(ys.windows(2).all(|w| (w[1] - w[0]).abs_diff(800) <= 1));
    assert!((xs[999] - xs[0]).abs_diff(999 * 1600) <= 1);
    assert!((ys[499] - ys[0]).abs_diff(499 * 800) <= 1);
    assert_eq!(y.min_step_interval_cycles, Some(799));
    assert_eq!(y.min_step_high_cycles, Some(62));
    assert_eq!(y.max_step_high_cycles, Some(62));
    assert_eq!(x.min_step_high_cycles, Some(8));

    // Exactly the three deliberate violations.
    let v: Vec<(Axis, ViolationKind, i64)> = vm.violations().iter().map(|v| (v.axis, v.kind, v.measured)).collect();
    assert_eq!(
        v,
        vec![
            (Axis::X, ViolationKind::StepHighTooShort, 8),
            (Axis::X, ViolationKind::DirSetupTooShort, 2),
            (Axis::Z, ViolationKind::StepWhileDisabled, -1), // dir low: a - step
        ]
    );

    // The stepper vector ran once per train step.
    let isr = vm.stepper_isr_stats().unwrap();
    assert_eq!(isr.count, 1500);
    assert!(isr.min_cycles > 62 && isr.max_cycles < 200, "{isr:?}");
}

#[test]
fn pulse_widths_are_measured_as_coded() {
    // Raise the limit above the coded 62-cycle pulse: every train pulse is flagged with its width.
    let vm = steps_vm(|c| c.recorder.min_step_high_cycles = 63);
    let widths: Vec<i64> = vm.violations().iter().filter(|v| v.kind == ViolationKind::StepHighTooShort).map(|v| v.measured).collect();
    assert_eq!(widths.len(), 1501);
    assert_eq!(widths.iter().filter(|&&w| w == 62).count(), 1500);
}

#[test]
fn inverted_dir_mask_flips_the_count() {
    let vm = steps_vm(|c| c.machine.invert_dir_mask = 0b0001);
    assert_eq!(vm.position(Axis::X), 2250 - 1000);
    assert_eq!(vm.position(Axis::Y), 2250 - 500);
}

#[test]
fn uart_round_trip_and_streaming() {
    let mut vm = host_vm();
    assert_eq!(vm.command("hello").unwrap(), vec!["echo:hello", "ok"]);
    let lines: Vec<String> = (0..40).map(|i| format!("G1 X{i}")).collect();
    for opts in [
        StreamOptions::new(Flow::PingPong),
        StreamOptions::new(Flow::CharCount(63)),
        StreamOptions::new(Flow::CharCount(127)).with_checksums(true),
    ] {
        let r = vm.stream(&lines, opts.clone()).unwrap();
        let extra = opts.checksums as usize;
        assert_eq!(r.oks, 40 + extra, "{opts:?}");
        assert_eq!(r.lines_sent, 40 + extra);
        assert!(r.errors.is_empty() && r.resends == 0 && !r.timed_out);
        assert!(r.duration_s > 0.0);
    }
    assert!(vm.output().contains("echo:G1 X39"));
    assert!(matches!(vm.wait_line(|l| l == "never", 0.01), Err(VmError::Timeout { .. })));
    assert!(matches!(vm.run_until(|_| false, 0.01), Err(VmError::Timeout { .. })));
    let t = vm.run_until(|vm| vm.seconds() > 0.5, 1.0).unwrap();
    assert!(t > 0.0 && vm.seconds() > 0.5);
    assert_eq!(vm.uart_rx_dropped(), 0);
}

#[test]
fn eeprom_persists_across_reset_sram_across_a_reset_but_not_a_power_cycle() {
    let mut vm = host_vm();
    vm.command("eew 10 42").unwrap();
    assert_eq!(vm.eeprom()[10], 42);
    assert_eq!(vm.eeprom().len(), 4096);
    vm.set_eeprom_at(100, &[7, 8, 9]);
    // SRAM survives the RESET pin (datasheet §12), not a power loss.
    let top = vm.read_ram(0x2000, 256);
    vm.reset();
    assert_eq!(vm.read_ram(0x2000, 256), top);
    vm.wait_for_start(1.0).unwrap();
    assert_eq!(vm.wait_line(|l| l.starts_with("reset"), 0.1).unwrap(), "reset 02"); // EXTRF
    assert_eq!(vm.command("eer 10").unwrap()[0], "ee 10=42");
    assert_eq!(vm.command("eer 101").unwrap()[0], "ee 101=8");
    vm.power_cycle();
    let noise = vm.read_ram(0x2000, 256);
    assert!(noise != top && noise.iter().filter(|&&b| b == noise[0]).count() < 64, "{noise:?}");
    vm.wait_for_start(1.0).unwrap();
    assert_eq!(vm.wait_line(|l| l.starts_with("reset"), 0.1).unwrap(), "reset 01"); // PORF
    assert_eq!(vm.command("eer 10").unwrap()[0], "ee 10=42");
}

#[test]
fn watchdog_reset_keeps_the_clock_monotonic_and_inputs_applied() {
    let mut vm = host_vm();
    vm.set_input(Input::HomeY, Some(true));
    let before = vm.command("pins").unwrap()[0].clone();
    let c0 = vm.cycles();
    vm.send_line("wdt");
    vm.wait_for_start(1.0).unwrap();
    assert_eq!(vm.wait_line(|l| l.starts_with("reset"), 0.1).unwrap(), "reset 08"); // WDRF
    let c1 = vm.cycles();
    assert!(c1 > c0 + 15 * 16_000, "clock went from {c0} to {c1}");
    assert_eq!(vm.resets().last().unwrap().kind, ResetKind::Watchdog);
    assert_eq!(vm.command("pins").unwrap()[0], before);
    assert!(vm.cycles() > c1);
}

#[test]
fn input_overrides_and_model_are_seen_by_the_firmware() {
    let mut vm = host_vm();
    // Model at power-on: X/Y/Z mid-travel (switches open = high), carousel at 0° (closed = low),
    // beam clear (low), encoder idle (high).
    assert_eq!(vm.command("pins").unwrap()[0], "pins E=20 J=02 D=08 C=54");
    vm.set_input(Input::HomeX, Some(true));
    vm.set_input(Input::CarouselHome, Some(false));
    vm.set_input(Input::ToolSetter, Some(true));
    vm.set_input(Input::EncoderButton, Some(true));
    assert_eq!(vm.command("pins").unwrap()[0], "pins E=10 J=02 D=0c C=50");
    assert!(!vm.input_level(Input::HomeX) && vm.input_level(Input::ToolSetter));
    for i in Input::ALL {
        vm.set_input(i, None);
    }
    vm.set_carousel_connected(false);
    assert_eq!(vm.command("pins").unwrap()[0], "pins E=30 J=02 D=08 C=54");
}

#[test]
fn home_switch_closes_within_the_step_that_reaches_zero() {
    let mut c = VmConfig::new(common::firmware("host"));
    c.machine.initial_position = [5, 100, 100, 0];
    let mut vm = Vm::new(c).unwrap();
    vm.wait_for_start(1.0).unwrap();
    let reply = vm.command("jogx 8").unwrap();
    assert!(reply.contains(&"trip=5".to_string()), "{reply:?}");
    assert_eq!(vm.position(Axis::X), -3);
    assert!(vm.input_active(Input::HomeX));
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}

#[test]
fn interrupt_nesting_overflow_is_an_error_not_a_host_crash() {
    let mut vm = host_vm();
    vm.send_line("nest");
    let e = vm.run_for(0.1).unwrap_err();
    match e {
        VmError::InterruptNesting { depth, vector, .. } => assert_eq!((depth, vector), (61, 32)),
        e => panic!("unexpected {e}"),
    }
    assert!(vm.run_for(0.01).is_err(), "the error is sticky");
    assert!(vm.report(None).errors[0].contains("nesting"));
    vm.reset();
    vm.wait_for_start(1.0).unwrap();
    assert_eq!(vm.command("hello").unwrap().last().unwrap(), "ok");
}

#[test]
fn sleep_with_interrupts_off_is_reported_with_the_pc() {
    let mut vm = host_vm();
    vm.send_line("sleep");
    match vm.run_for(0.05).unwrap_err() {
        VmError::Halted { pc, .. } => assert!(pc > 0),
        e => panic!("unexpected {e}"),
    }
}

#[test]
fn spindle_state_follows_oc2a() {
    let mut vm = host_vm();
    assert!(!vm.spindle_on());
    vm.command("spin 127").unwrap();
    assert!(vm.spindle_on());
    assert_eq!(vm.spindle_duty(), 0.5);
    vm.command("spin 0").unwrap();
    assert!(!vm.spindle_on());
    vm.command("spin 255").unwrap();
    assert_eq!(vm.spindle_duty(), 1.0);
    vm.command("spin off").unwrap();
    assert!(!vm.spindle_on());
    assert_eq!(vm.spindle_history().iter().map(|h| h.1).collect::<Vec<_>>(), vec![0.5, 0.0, 1.0, 0.0]);
}

#[test]
fn unpaced_flood_loses_bytes_only_when_the_chip_does_not_read() {
    let mut vm = host_vm();
    // The chip reads every byte: a 4 KiB random flood arrives whole.
    let mut x: u32 = 12345;
    let noise: Vec<u8> = (0..4096)
        .map(|_| {
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (x >> 16) as u8
        })
        .collect();
    vm.send_unpaced_flood(&noise);
    vm.run_until(|vm| vm.tx_pending() == 0, 1.0).unwrap();
    vm.run_for(0.01).unwrap();
    assert_eq!(vm.uart_rx_dropped(), 0);
    vm.send_line("");
    vm.run_for(0.01).unwrap();
    vm.take_lines();
    let stats = vm.command("stats").unwrap();
    let rx_line = stats.iter().find(|l| l.starts_with("rx=")).unwrap().clone();
    let rx: u32 = rx_line[3..].split(' ').next().unwrap().parse().unwrap();

    // The chip does not read for 50 ms: of 1000 bytes, the 2-byte FIFO keeps 2.
    vm.send_line("busy 50");
    vm.run_for(0.002).unwrap();
    vm.send_unpaced_flood(vec![b'x'; 1000]);
    vm.wait_line(|l| l == "ok", 1.0).unwrap();
    assert_eq!(vm.uart_rx_dropped(), 998);
    assert_eq!(vm.command("").unwrap(), vec!["echo:xx", "ok"]);
    let stats = vm.command("stats").unwrap();
    let after = stats.iter().find(|l| l.starts_with("rx=")).unwrap();
    let rx2: u32 = after[3..].split(' ').next().unwrap().parse().unwrap();
    // "stats\n" (6) + "\n" (1) + "busy 50\n" (8) + 2 kept + "\n" (1) + "stats\n" (6)
    assert_eq!(rx2 - rx, 2 + 1 + 8 + 6);
    assert!(after.contains("dor=1"), "{after}");
}

#[test]
fn stack_high_water_and_symbols() {
    let mut vm = host_vm();
    vm.command("pins").unwrap();
    let heap = vm.symbol_addr("__heap_start").unwrap();
    assert!((0x200..0x2200).contains(&heap));
    let hw = vm.stack_high_water_bytes().unwrap();
    assert!(hw > 8 && hw < 512, "{hw}");
}

#[test]
fn four_axes_stepping_at_40_khz_are_all_counted() {
    let mut vm = host_vm();
    vm.command("steps4 2000").unwrap();
    vm.run_for(0.06).unwrap();
    for axis in Axis::ALL {
        let s = vm.recorder().axis_stats(axis);
        assert_eq!((s.steps_pos, s.steps_neg), (2000, 0), "{axis}");
        assert!(s.min_step_interval_cycles.unwrap().abs_diff(400) <= 2, "{s:?}");
        assert!((s.peak_rate_windowed_hz - 40_000.0).abs() <= 1000.0, "{s:?}");
    }
    assert_eq!(vm.positions(), [4250, 4250, 4250, 2000]);
    assert!(vm.violations().is_empty(), "{:?}", &vm.violations()[..1]);
    // 2000 stepping services + the one that stops the timer.
    assert_eq!(vm.stepper_isr_stats().unwrap().count, 2001);
    // Every intermediate point of the diagonal is on the line x = y = z.
    vm.recorder().for_each_step(|p| {
        let [x, y, z, _] = p.position;
        assert!(x.abs_diff(y) <= 1 && y.abs_diff(z) <= 1, "{p:?}");
    });
}

#[test]
fn simulation_speed() {
    let mut vm = host_vm();
    let t = std::time::Instant::now();
    vm.run_for(2.0).unwrap();
    let idle = 2.0 / t.elapsed().as_secs_f64();

    let mut c = VmConfig::new(common::firmware("host"));
    c.machine.travel_steps = [None; 4];
    let mut vm = Vm::new(c).unwrap();
    vm.wait_for_start(1.0).unwrap();
    vm.command("steps4 40000").unwrap();
    let t = std::time::Instant::now();
    vm.run_for(1.0).unwrap();
    let stepping = 1.0 / t.elapsed().as_secs_f64();
    assert_eq!(vm.position(Axis::E), 40_000);
    println!("sim speed: idle UART loop {idle:.1} s/s; 4 axes at 40 kHz {stepping:.1} s/s");
    assert!(idle > 1.0 && stepping > 0.5);
}

#[test]
fn report_json_and_trace_csv_are_written() {
    let vm = steps_vm(|_| {});
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-test");
    let json = dir.join("report.json");
    let csv = dir.join("trace.csv");
    vm.write_json(&json, None).unwrap();
    vm.write_trace_csv(&csv).unwrap();
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(r["violation_count"], 3);
    assert_eq!(r["stepper_isr"]["vector"], 17);
    assert_eq!(r["axes"][0]["steps_pos"], 1001);
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("cycle,time_s,axis,position"));
    assert_eq!(lines.count(), vm.recorder().trace().len());
    assert!(text.contains(",X,2251\n") && text.contains(",Y,1750\n"));
    let report = vm.report(None);
    assert!(!report.clean());
    assert!(report.human().contains("StepHighTooShort"));
}

#[test]
fn cli_streams_a_job_and_exits_zero_when_clean() {
    let elf = common::firmware("host");
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli-test");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sim"))
        .arg("--elf")
        .arg(&elf)
        .arg("--json")
        .arg(dir.join("r.json"))
        .arg("--csv")
        .arg(dir.join("t.csv"))
        .args(["--checksums", "--flow", "count:64"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    // The demo job's lines + the M110 preamble, all acknowledged.
    let demo = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/demo.gcode")).unwrap();
    let n = sim::host::prepare_gcode(&demo).len();
    let want = format!("{n} lines, {} sent, {} ok, 0 errors", n + 1, n + 1);
    assert!(stdout.contains(&want), "{want} not in {stdout}");
    assert!(dir.join("r.json").exists() && dir.join("t.csv").exists());

    // The step-train firmware never answers: timeout -> non-zero exit.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sim"))
        .arg("--elf")
        .arg(common::firmware("steps"))
        .args(["--timeout", "0.2"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
}

#[test]
fn timer_preloaded_while_stopped_counts_from_the_preload() {
    // Hardware: 56 ticks from TCNT0 = 200 to overflow, plus ISR entry.
    let mut vm = Vm::with_elf(common::firmware("tcnt")).unwrap();
    vm.wait_line(|l| l == "done", 0.1).unwrap();
    let x = vm.recorder().axis_stats(Axis::X);
    assert_eq!(x.steps_pos, 3);
    let (lo, hi) = (x.min_step_high_cycles.unwrap(), x.max_step_high_cycles.unwrap());
    assert!(lo >= 56 && hi < 100, "pulse {lo}..{hi} cycles");

    // Without the fix simavr restarts the count from 0: 256 ticks.
    let mut c = VmConfig::new(common::firmware("tcnt"));
    c.fix_tcnt_on_clock_start = false;
    let mut vm = Vm::new(c).unwrap();
    vm.wait_line(|l| l == "done", 0.1).unwrap();
    assert!(vm.recorder().axis_stats(Axis::X).min_step_high_cycles.unwrap() > 256);
}
