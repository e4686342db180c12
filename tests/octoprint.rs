//! The real OctoPrint (1.11, from PyPI, installed by `tools/setup-hosts` into
//! `target/octoprint-venv`) drives the simulated board through the pty bridge
//! (`sim::pty`), in real time, as a user does from its web page.
//!
//! The test owns the virtual machine; `tests/hosts/octoprint_drive.py` owns
//! OctoPrint: it writes a fresh basedir with only what a user sets (the
//! first-run wizard, the connection dialog's port and baud, and the printer
//! profile's 13 tools that docs/hosts.md "OctoPrint" asks for), starts the server on
//! 127.0.0.1 and, through the REST API, connects, runs the demo job to its end,
//! pauses and resumes a second job that changes to T12, cancels a third with the
//! spindle on, and asks `M114` from the terminal; then, in the middle of a
//! fourth job, disconnects and connects again: opening the port resets the
//! board (auto-reset, as on a Mega2560), so the job is gone, `M114` says 0
//! and a move is refused until homed. At each `CHECK <name>` it
//! prints, this test reads the board's state (recorded steps, spindle, tool
//! changer, the firmware's output) and answers. Every failed check is collected
//! and listed at the end, with OctoPrint's logs kept in `target/tmp/octoprint/`.

mod common;
use common::*;
use sim::pty::PtyBridge;
use sim::Axis;
use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn octoprint_python() -> PathBuf {
    let py =
        std::env::var_os("MILL_OCTOPRINT_PYTHON").map(PathBuf::from).unwrap_or_else(|| root().join("target/octoprint-venv/bin/python"));
    assert!(py.exists(), "{} missing: OctoPrint is not installed; run tools/setup-hosts (tools/test does)", py.display());
    py
}

/// The driver and the OctoPrint server it starts run in their own process
/// group, killed whatever happens to the test.
struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait() {
            // The whole group: the driver and the server it started.
            let _ = Command::new("kill").arg("-KILL").arg(format!("-{}", self.0.id())).status();
            let _ = self.0.wait();
        }
    }
}

/// Job 2, paused half-way and resumed: a tool change from OctoPrint (T12, the
/// highest tool: OctoPrint sends it only with 13 tools in the profile), then
/// short moves on X/Y so the queue drains quickly once paused.
fn pause_job() -> (String, [i64; 2]) {
    let mut job = String::from("; paused and resumed by tests/octoprint.rs\nG21 G90\nT12 M6\nG0 X10 Y10\nG1 F900\n");
    let (mut x, mut y) = (10.0f64, 10.0f64);
    for i in 0..48 {
        match i % 4 {
            0 => x += 1.5,
            1 => y += 1.0,
            2 => x += 0.5,
            _ => y -= 0.5,
        }
        job.push_str(&format!("G1 X{x:.1} Y{y:.1}\n"));
    }
    job.push_str("M400\n");
    (job, [(x * 100.0).round() as i64, (y * 100.0).round() as i64])
}

/// Job 3, cancelled a third of the way: T3 pre-staged on its own line (NGC:
/// a bare T only selects) and changed by a bare `M6`, spindle on, then 2 mm
/// moves.
fn cancel_job() -> (String, [i64; 2]) {
    let mut job = String::from("; cancelled by tests/octoprint.rs\nG21 G90\nT3\nG0 X10 Y10\nM6\nM3 S8000\nG1 F600\n");
    let mut x = 10.0f64;
    for i in 0..60 {
        x += if i % 2 == 0 { 2.0 } else { -1.5 };
        job.push_str(&format!("G1 X{x:.1} Y{:.1}\n", 10.0 + (i % 3) as f64));
    }
    job.push_str("M5\nM400\n");
    (job, [(x * 100.0).round() as i64, 1000 + ((59 % 3) as i64) * 100])
}

#[test]
fn octoprint_connects_runs_the_demo_pauses_resumes_and_cancels() {
    let py = octoprint_python();
    // The machine `sim --pty` simulates: the changer loaded (tool n is
    // 18 + 1.5 n mm long, 1 + 0.5 n mm across) and the optical setter beam.
    // A board as sold: the stock bootloader in front of the firmware.
    let mut cfg = board_as_sold();
    cfg.machine.tool_setter = sim::ToolSetter::Optical(sim::OpticalBeam::demo());
    let mut vm = boot_with(cfg);

    let dir = root().join("target/tmp/octoprint");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("base")).unwrap();
    let demo = root().join("sim/jobs/demo.gcode");
    let (pause, pause_end) = pause_job();
    let (cancel, cancel_end) = cancel_job();
    std::fs::write(dir.join("pause.gcode"), &pause).unwrap();
    std::fs::write(dir.join("cancel.gcode"), &cancel).unwrap();
    // Long moves, so that the reconnect comes in the middle of one.
    let reconnect = "M999\nG90\nG1 X30 Y30 F300\nG1 X5 Y5 F300\nG1 X30 Y30 F300\nM400\n";
    std::fs::write(dir.join("reconnect.gcode"), reconnect).unwrap();

    let mut bridge = PtyBridge::open(&vm, Some(&dir.join("millsim"))).expect("pty").realtime(true);
    // The host runs niced: on a real machine the board has a CPU of its own,
    // here the simulated board shares two cores with OctoPrint, whose job
    // analysis at every job start slowed the board to 0.64x real time, and
    // OctoPrint's busy timeout (3 s of wall clock against a 2 s keepalive of
    // board time) then fired. Nothing OctoPrint sees or checks changes.
    let mut child = Command::new("nice");
    child
        .args(["-n", "10"])
        .arg(&py)
        .arg(root().join("tests/hosts/octoprint_drive.py"))
        .arg("--port")
        .arg(bridge.port())
        .arg("--basedir")
        .arg(dir.join("base"))
        .arg("--run")
        .arg(&demo)
        .arg("--pause")
        .arg(dir.join("pause.gcode"))
        .arg("--cancel")
        .arg(dir.join("cancel.gcode"))
        .arg("--reconnect")
        .arg(dir.join("reconnect.gcode"))
        // OctoPrint's ToolChange events: the demo's T1, T2, T0, then T12, T3.
        .args(["--expect-tools", "1,2,0,12,3"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(std::fs::File::create(dir.join("driver.err")).unwrap()))
        .process_group(0);
    // For investigations only: extra OctoPrint settings (YAML) to get past a
    // known failure and see the next one. The test can never pass with it.
    let extra = std::env::var("MILL_OCTOPRINT_EXTRA_CONFIG").ok();
    if let Some(e) = &extra {
        child.arg("--extra-config").arg(e);
    }
    let mut driver = Driver(child.spawn().expect("start the OctoPrint driver"));
    let mut to_driver = driver.0.stdin.take().unwrap();
    let from_driver = driver.0.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(from_driver).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });

    let mut problems: Vec<String> = Vec::new();
    if let Some(e) = &extra {
        problems.push(format!("MILL_OCTOPRINT_EXTRA_CONFIG={e}: not the settings docs/hosts.md tells a user to set"));
    }
    let mut transcript: Vec<String> = Vec::new();
    let mut result = None;
    let mut at_pause = None;
    let mut at_reconnect: Option<u64> = None;
    let mut at_reconnected = None;
    let started = Instant::now();
    let fw_lines = |vm: &sim::Vm| vm.line_log().iter().map(|(_, l)| l.clone()).collect::<Vec<_>>();
    loop {
        bridge.pump(&mut vm, 0.002).expect("virtual machine");
        while let Ok(line) = rx.try_recv() {
            println!("[driver] {line}");
            transcript.push(line.clone());
            if let Some(r) = line.strip_prefix("RESULT ") {
                result = Some(r.to_string());
            }
            let Some(name) = line.strip_prefix("CHECK ") else { continue };
            let mut bad: Vec<String> = Vec::new();
            if name.ends_with("-done") {
                // OctoPrint's PrintDone means every line was acknowledged;
                // the last moves may still run: the job ends when the
                // machine stops (no step for 1 s, at most 30 s).
                let mut quiet = 0.0;
                let mut waited = 0.0;
                while quiet < 1.0 && waited < 30.0 {
                    let before = vm.recorder().trace().len();
                    bridge.pump(&mut vm, 0.01).expect("virtual machine");
                    quiet = if vm.recorder().trace().len() == before { quiet + 0.01 } else { 0.0 };
                    waited += 0.01;
                }
                if quiet < 1.0 {
                    bad.push(format!("{name}: the machine still moves 30 s after OctoPrint's PrintDone"));
                }
            }
            let pos = vm.positions();
            let fw = fw_lines(&vm);
            match name {
                "connected" => {}
                "run-done" => {
                    // The demo ends at G0 X5 Y5 with the spindle empty (T0),
                    // Z at the changer's travel height (machine Z 1.0).
                    if pos[..3] != [500, 500, 100] {
                        bad.push(format!("demo end: steps {:?}, expected [500, 500, 100]", &pos[..3]));
                    }
                    let changes: Vec<&str> = fw.iter().filter_map(|l| l.strip_prefix("NowSelectedTool:")).collect();
                    if changes != ["1", "2", "0"] {
                        bad.push(format!("demo tool changes {changes:?}, expected T1, T2, T0"));
                    }
                    for want in ["[SETTER Z:-48.000 W:0.530]", "[TOOL:2 L:21.000 D:2.000]"] {
                        if !fw.iter().any(|l| l == want) {
                            bad.push(format!("demo: no {want} from the firmware"));
                        }
                    }
                    if vm.atc().spindle.is_some() {
                        bad.push(format!("demo: spindle holds {:?}, expected empty", vm.atc().spindle.map(|t| t.id)));
                    }
                }
                "paused-1" => at_pause = Some(pos),
                "paused-2" => {
                    if at_pause != Some(pos) {
                        bad.push(format!("paused: the machine moved from {at_pause:?} to {pos:?} while paused"));
                    }
                    if pos[..2] == pause_end {
                        bad.push("paused: already at the job's end; the pause came too late to test".into());
                    }
                }
                "pause-done" => {
                    if pos[..2] != pause_end {
                        bad.push(format!("pause job end: X/Y steps {:?}, expected {pause_end:?}", &pos[..2]));
                    }
                    if vm.atc().spindle.map(|t| t.id) != Some(12) {
                        bad.push(format!("pause job: spindle holds {:?}, expected T12", vm.atc().spindle.map(|t| t.id)));
                    }
                }
                "cancel-before" => {
                    if vm.atc().spindle.map(|t| t.id) != Some(3) {
                        bad.push(format!("cancel job: spindle holds {:?} after T3, M6", vm.atc().spindle.map(|t| t.id)));
                    }
                    if !vm.spindle_on() {
                        bad.push("cancel job: the spindle is not on before the cancel".into());
                    }
                }
                "cancelled" => {
                    if vm.spindle_on() {
                        bad.push(format!("cancelled: the spindle is still on (duty {:.2})", vm.spindle_duty()));
                    }
                    if pos[..2] == cancel_end {
                        bad.push("cancelled: the whole job ran (at its end point)".into());
                    }
                    // The cancel script's `M104 T0 S0` is a heater index, not
                    // a tool change: T3 stays in the spindle.
                    if vm.atc().spindle.map(|t| t.id) != Some(3) {
                        bad.push(format!("cancelled: spindle holds {:?}, expected T3", vm.atc().spindle.map(|t| t.id)));
                    }
                }
                "reconnect-before" => at_reconnect = Some(vm.cycles()),
                "reconnected" => {
                    // Opening the port again reset the board: nothing moved
                    // after the reset, the job stopped short of its end.
                    let reset = vm.resets().iter().find(|r| Some(r.cycle) > at_reconnect).copied();
                    match reset {
                        Some(r) if r.kind == sim::ResetKind::External => {
                            let after = vm.recorder().trace().iter().filter(|t| t.cycle > r.cycle).count();
                            if after > 0 {
                                bad.push(format!("reconnected: {after} steps after the reset"));
                            }
                        }
                        other => bad.push(format!("reconnected: no reset from reopening the port ({other:?})")),
                    }
                    if !fw.iter().any(|l| l == "echo:reset cause: external") {
                        bad.push("reconnected: no `reset cause: external` banner".into());
                    }
                    at_reconnected = Some(pos);
                }
                other => bad.push(format!("unknown checkpoint {other}")),
            }
            for l in &fw {
                if l.starts_with("ALARM") || l.starts_with("Error") || l.starts_with("!!") {
                    bad.push(format!("the firmware said {l:?}"));
                }
            }
            bad.dedup();
            let reply = if bad.is_empty() { "OK".to_string() } else { bad.join("; ") };
            for b in &bad {
                problems.push(format!("{name}: {b}"));
            }
            let _ = writeln!(to_driver, "{reply}");
            let _ = to_driver.flush();
        }
        if let Some(status) = driver.0.try_wait().unwrap() {
            while let Ok(line) = rx.recv_timeout(Duration::from_millis(200)) {
                println!("[driver] {line}");
                if let Some(r) = line.strip_prefix("RESULT ") {
                    result = Some(r.to_string());
                }
                transcript.push(line);
            }
            if !status.success() && result.is_none() {
                problems.push(format!("the driver exited with {status}"));
            }
            break;
        }
        if started.elapsed() > Duration::from_secs(600) {
            problems.push("the OctoPrint session did not finish within 600 s".into());
            break;
        }
    }
    // One more second: nothing moves after the reconnect (the move sent
    // then is refused) and the disconnect.
    for _ in 0..500 {
        bridge.pump(&mut vm, 0.002).unwrap();
    }
    if let Some(p) = at_reconnected {
        if vm.positions() != p {
            problems.push(format!("after the reconnect the machine moved from {p:?} to {:?}", vm.positions()));
        }
    }
    if vm.spindle_on() {
        problems.push("the spindle is on at the end".into());
    }
    if !vm.violations().is_empty() {
        problems.push(format!("timing violations: {:?}", vm.violations()));
    }
    if !vm.atc().collisions.is_empty() {
        problems.push(format!("tool changer collisions: {:?}", vm.atc().collisions));
    }
    // Power-on, then the resets of the two connects (auto-reset): nothing
    // else. On Debian OctoPrint opens the port twice per connect (its
    // parity workaround: open with odd parity, close, open), and a real
    // board resets on each DTR pulse; the two opens are milliseconds apart
    // and may fall into one pump or two, so a connect is a burst of
    // external resets within 0.1 s.
    let resets = vm.resets();
    let kinds_ok =
        resets.first().map(|r| r.kind) == Some(sim::ResetKind::PowerOn) && resets[1..].iter().all(|r| r.kind == sim::ResetKind::External);
    let burst = u64::from(vm.frequency() / 10);
    let connects = resets[1..].windows(2).filter(|w| w[1].cycle - w[0].cycle > burst).count() + usize::from(resets.len() > 1);
    if !kinds_ok || connects != 2 || bridge.auto_resets != (resets.len() - 1) as u64 {
        problems.push(format!(
            "resets {resets:?}, {} from opening the port: expected power-on, then the resets of 2 connects",
            bridge.auto_resets
        ));
    }
    for l in transcript.iter().filter(|l| l.starts_with("FAIL ")) {
        problems.push(format!("octoprint: {}", &l[5..]));
    }
    if result.as_deref() != Some("ok") && problems.is_empty() {
        problems.push(format!("the driver's result: {result:?}"));
    }
    let fw = fw_lines(&vm);
    let y = vm.position(Axis::Y);
    println!(
        "board: {} lines from the firmware, {} bytes in, {} out, final steps {:?} (Y {y}), {:.1} s simulated, {:.1} s wall",
        fw.len(),
        bridge.bytes_in,
        bridge.bytes_out,
        vm.positions(),
        vm.seconds(),
        started.elapsed().as_secs_f64()
    );
    problems.dedup();
    // OctoPrint's timeouts run on the wall clock: a board simulated slower
    // than real time (a loaded machine) stretches every silence.
    let pace = vm.seconds() / started.elapsed().as_secs_f64();
    if !problems.is_empty() && pace < 0.9 {
        problems.push(format!("note: the board ran at {pace:.2}x real time (machine load): a timeout may come from that"));
    }
    assert!(
        problems.is_empty(),
        "{} problem(s) with OctoPrint (its logs: {}):\n  {}\nlast firmware lines: {:?}",
        problems.len(),
        dir.join("base").display(),
        problems.join("\n  "),
        &fw[fw.len().saturating_sub(30)..]
    );
}
