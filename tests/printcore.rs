//! A real G-code sender on the simulated board: Printrun's `printcore` (the
//! engine of Pronterface, installed by `tools/setup-hosts` into `target/pyenv`)
//! streams a job through the pty bridge (`sim::pty`) with line numbers and
//! checksums. The bridge corrupts one line's checksum in transit; the firmware
//! must ask for it again and printcore must recover. The recorded steps must
//! end exactly at the job's final point. Opening the port resets the board
//! (auto-reset, as on a Mega2560), also when printcore reconnects mid-job;
//! the board runs the stock bootloader, as one bought does.

mod common;
use common::*;
use sim::pty::PtyBridge;
use sim::Axis;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// printcore opens the port, closes it and opens it again when it
/// connects (Printrun 2.2's workaround for a parity bug), and each open
/// resets the board.
const OPENS_PER_CONNECT: u64 = 2;

fn printcore_python() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let py = std::env::var_os("MILL_PRINTCORE_PYTHON").map(PathBuf::from).unwrap_or_else(|| root.join("target/pyenv/bin/python"));
    assert!(py.exists(), "{} missing: run tools/setup-hosts (tools/test does)", py.display());
    py
}

#[test]
fn printcore_streams_a_job_with_checksums_and_recovers_a_corrupted_line() {
    let mut vm = boot_with(board_as_sold());
    // A square with a rounded corner and a diagonal back, in mm from the
    // power-on position (the firmware's 0 until homed).
    let job = "\
M999 ; unlock: the job does not home (the homing lock refuses motion until then)
G21 G90 ; mm, absolute
G1 X10 F1500
G1 Y8
G2 X14 Y12 I4 J0
G1 X4 Y12
G1 X0 Y0
G1 X3.33 Y1.25
G91
G1 X1 Y1
G90
M400
";
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/tmp");
    std::fs::create_dir_all(&dir).unwrap();
    let job_path = dir.join("printcore-job.gcode");
    std::fs::write(&job_path, job).unwrap();

    // printcore numbers the job from N0 (after its own `N-1 M110`): corrupt N3.
    let mut bridge = PtyBridge::open(&vm, None).expect("pty").realtime(true).corrupt_checksum_of_line(3);
    let run = printcore_run(&mut bridge, &mut vm, &job_path, |_| false);
    // Let the last bytes reach the machine and the motion finish: pump until
    // no step has been recorded for 0.5 s of simulated time (at most 20 s).
    let mut quiet = 0;
    for _ in 0..4000 {
        let before = vm.recorder().trace().len();
        bridge.pump(&mut vm, 0.005).unwrap();
        quiet = if vm.recorder().trace().len() == before { quiet + 1 } else { 0 };
        if quiet >= 100 {
            break;
        }
    }
    let log = run.log;
    assert!(run.status.success(), "printcore failed:\n{log}");

    // The fault was injected and recovered from.
    assert_eq!(bridge.corrupted.len(), 1, "no line was corrupted: {log}");
    assert!(bridge.corrupted[0].starts_with("N3 "), "{:?}", bridge.corrupted);
    let fw: Vec<String> = vm.line_log().iter().map(|(_, l)| l.clone()).collect();
    assert!(fw.iter().any(|l| l == "Resend:3"), "no Resend:3 in {fw:?}");
    let sent: Vec<&str> = log.lines().filter_map(|l| l.strip_prefix("SENT: ")).collect();
    assert!(sent.iter().filter(|l| l.starts_with("N3 ")).count() >= 2, "N3 not resent: {sent:?}");

    // Every job line reached the machine and was acknowledged: one `ok` per
    // line the firmware received (printcore waits for each before the next).
    let job_lines = job.lines().filter(|l| !l.split(';').next().unwrap().trim().is_empty()).count();
    let last_n = format!("N{} ", job_lines - 1);
    assert!(sent.iter().any(|l| l.starts_with(&last_n)), "the last line {last_n} was never sent: {sent:?}");
    let oks = fw.iter().filter(|l| *l == "ok").count();
    let received = fw.iter().filter(|l| l.starts_with("Error:") || *l == "ok").count();
    assert!(oks > job_lines, "{oks} oks for {job_lines} lines: {fw:?}");
    assert!(received >= oks);

    // The final position is exact: (3.33 + 1, 1.25 + 1) mm at 100 steps/mm
    // from the power-on position, and nothing broke the timing rules.
    let start = vm.config().machine.initial_position;
    assert_eq!(vm.position(Axis::X), start[0] + 433);
    assert_eq!(vm.position(Axis::Y), start[1] + 225);
    assert_eq!(vm.position(Axis::Z), start[2]);
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
    // printcore opens the port twice to connect (open, close, open: its
    // parity workaround); each open resets the board (two opens between two
    // looks of the bridge are one reset), all before the job.
    assert!((1..=OPENS_PER_CONNECT).contains(&run.resets), "{} resets", run.resets);
    let external = vm.resets().iter().filter(|r| r.kind == sim::ResetKind::External).count() as u64;
    assert_eq!(external, bridge.auto_resets);
}

/// What one printcore run did: its exit, its output and the board resets
/// its connection caused.
struct Run {
    status: std::process::ExitStatus,
    log: String,
    resets: u64,
}

/// Runs printcore on `job` through `bridge` until it exits or `stop` says
/// so (then it is killed, as a sender closed mid-job).
///
/// printcore connects, sleeps 2 s of wall-clock time and starts the job
/// only if the board has answered by then; if not, it exits without
/// sending a line. A real board boots in ~1.1 s (its bootloader's wait
/// included). The virtual machine may not: on a loaded machine simulated
/// time falls behind the wall clock. Only then is printcore run again (at
/// most three times): a run that sent nothing while the board kept up
/// with the wall clock fails the test.
fn printcore_run(bridge: &mut PtyBridge, vm: &mut sim::Vm, job: &std::path::Path, mut stop: impl FnMut(&sim::Vm) -> bool) -> Run {
    let printcore = printcore_python().with_file_name("printcore.py");
    for attempt in 1..=3 {
        let resets0 = bridge.auto_resets;
        let cycles0 = vm.cycles();
        let mut child = Command::new(printcore_python())
            .arg(&printcore)
            .args(["-v", "-b", "250000"])
            .arg(bridge.port())
            .arg(job)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start printcore");
        let started = Instant::now();
        loop {
            bridge.pump(vm, 0.002).expect("virtual machine");
            if child.try_wait().unwrap().is_some() {
                break;
            }
            if stop(vm) {
                child.kill().unwrap();
                break;
            }
            assert!(started.elapsed() < Duration::from_secs(90), "printcore did not finish");
        }
        let wall_s = started.elapsed().as_secs_f64();
        let sim_s = (vm.cycles() - cycles0) as f64 / 16e6;
        let out = child.wait_with_output().unwrap();
        let log = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        let sent_nothing = !log.lines().any(|l| l.starts_with("SENT: "));
        if sent_nothing && sim_s < 0.9 * wall_s && attempt < 3 {
            eprintln!("printcore sent nothing: the board ran {sim_s:.2} s in {wall_s:.2} s of wall-clock time (a loaded machine); again");
            continue;
        }
        return Run { status: out.status, log, resets: bridge.auto_resets - resets0 };
    }
    unreachable!()
}

/// A sender that reconnects in the middle of a job, as on a real board with
/// auto-reset: the new connection resets the board, so the job stops where
/// it was, the firmware's position starts again from 0 and motion is
/// refused until the machine is homed or unlocked.
#[test]
fn a_sender_that_reconnects_mid_job_resets_the_board_and_the_job_is_gone() {
    let mut vm = boot_with(board_as_sold());
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/tmp");
    std::fs::create_dir_all(&dir).unwrap();
    let long = dir.join("printcore-long.gcode");
    std::fs::write(&long, "M999\nG21 G90\nG1 X40 F600\nG1 Y40\nG1 X0\nM400\n").unwrap();
    let again = dir.join("printcore-again.gcode");
    std::fs::write(&again, "M114\nG1 X1 F600\nM114\n").unwrap();
    let start = vm.config().machine.initial_position;
    let mut bridge = PtyBridge::open(&vm, None).expect("pty").realtime(true);
    // The first connection: the job runs until X has gone 5 mm.
    let first = printcore_run(&mut bridge, &mut vm, &long, |vm| vm.position(Axis::X) >= start[0] + 500).resets;
    assert!((1..=OPENS_PER_CONNECT).contains(&first), "{first} resets");
    // The second: opening the port resets the board mid-move.
    let second = printcore_run(&mut bridge, &mut vm, &again, |_| false);
    assert!(second.resets > 0, "{}", second.log);
    let reset = *vm.resets().last().unwrap();
    assert_eq!(reset.kind, sim::ResetKind::External);
    for _ in 0..250 {
        bridge.pump(&mut vm, 0.002).unwrap();
    }
    // Stopped at the reset: no step after it.
    let after = vm.recorder().trace().iter().filter(|t| t.cycle > reset.cycle).count();
    assert_eq!(after, 0, "{after} steps after the reset");
    let x = vm.position(Axis::X);
    assert!(x > start[0] + 500 && x < start[0] + 4000, "X at {x}");
    let fw: Vec<String> = vm.line_log().iter().filter(|(c, _)| *c > reset.cycle).map(|(_, l)| l.clone()).collect();
    assert!(fw.iter().any(|l| l == "echo:reset cause: external"), "{fw:?}");
    // The position is gone (0 where the machine stands), the queue too, and
    // the G1 is refused: the machine must be homed first.
    assert!(fw.iter().any(|l| l.starts_with("X:0.000 Y:0.000")), "{fw:?}");
    assert!(fw.iter().any(|l| l.starts_with("Error:not homed")), "{fw:?}");
}
