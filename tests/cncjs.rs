//! A real CNC host on the simulated board: cncjs (installed from npm by
//! `tools/setup-hosts` into `target/cncjs`, pinned) runs on 127.0.0.1 with a fresh
//! config and HOME, and `tests/hosts/cncjs_drive.js` drives it over its
//! Socket.IO API as its web page does, once with its Marlin controller and
//! once with its Grbl controller, both at 250000 baud through the pty bridge
//! (`sim::pty`, real time):
//!
//! ```text
//!  cncjs_drive.js ──Socket.IO──► cncjs ──/dev/pts/N──► PtyBridge ──► firmware in simavr
//!        ▲ stdin/stdout: MARK, WAIT_MOVED, WAIT_STILL                       │
//!        └──────────────────────── this test (owns the Vm and its recorder) ┘
//! ```
//!
//! Job A runs to the end; job B is paused and resumed (and in grbl mode feed
//! held and cycle-started, then sped up with the feed override button three
//! times and reset: cncjs must read `Ov:130` and `Ov:100`, and the job still
//! ends exactly); job C is stopped with cncjs's Stop button
//! (`gcode:stop {force: true}`: in grbl mode `!` then 0x18), after which the
//! machine must be still, stay still after Cycle start and a raw `~`, answer,
//! and run job D (relative moves) exactly. Every position is checked against
//! the recorded steps; the firmware must answer every query cncjs sends on
//! its own (status, parser state, position, temperature) without an error.

mod common;
use common::*;
use sim::pty::PtyBridge;
use sim::{Axis, ResetKind, Vm};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The two controllers run one after the other: each needs the simulated
/// board to keep up with the wall clock (cncjs's timers are wall-clock).
static SERIAL: Mutex<()> = Mutex::new(());

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `target/cncjs` (or `$MILL_CNCJS_DIR`), where `tools/setup-hosts` installs cncjs.
fn cncjs_dir() -> PathBuf {
    let dir = std::env::var_os("MILL_CNCJS_DIR").map(PathBuf::from).unwrap_or_else(|| root().join("target/cncjs"));
    let bin = dir.join("node_modules/cncjs/bin/cncjs");
    assert!(bin.exists(), "{} missing: run tools/setup-hosts (tools/test does)", bin.display());
    dir
}

/// A child process killed when the test ends, passed or not.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// The square of 1 mm segments around (0,0)–(10,10), `laps` times, at F600
/// (collinear segments: the planner keeps the feed through them).
fn square_segments(laps: usize) -> String {
    let mut s = String::new();
    for _ in 0..laps {
        for i in 1..=10 {
            writeln!(s, "G1 X{i} Y0").unwrap();
        }
        for i in 1..=10 {
            writeln!(s, "G1 X10 Y{i}").unwrap();
        }
        for i in (0..10).rev() {
            writeln!(s, "G1 X{i} Y10").unwrap();
        }
        for i in (0..10).rev() {
            writeln!(s, "G1 X0 Y{i}").unwrap();
        }
    }
    s
}

/// Job files and their ends, in steps from the power-on position (the
/// firmware's 0 until homed; 100 steps/mm).
struct Jobs {
    dir: PathBuf,
    a_end: (i64, i64),
    b_end: (i64, i64),
    c_end: (i64, i64),
    d_delta: (i64, i64),
}

fn write_jobs(dir: &Path) -> Jobs {
    std::fs::create_dir_all(dir).unwrap();
    // A: a line, an arc and a line back, 1.5 s.
    let a = "G21 G90\nG1 X5 Y3 F1200\nG2 X8 Y6 I3 J0\nG1 X2.5 Y4.25\n";
    // B: 4.9 s of motion in 43 lines, more than the firmware holds queued.
    let b = format!("G21 G90\nG1 X0 Y0 F600\n{}G1 X3.21 Y1.07\n", square_segments(1));
    // C: 8 s in 83 lines; stopped after 1.5 mm.
    let c = format!("G21 G90\nG1 X0 Y0 F600\n{}G1 X7.77 Y2.22\n", square_segments(2));
    // D: relative moves, so that anything left of C would shift its end.
    let d = "G21 G91\nG1 X2 Y1 F1200\nG1 X-0.5 Y0.25\nG90\n";
    // F: a line the firmware refuses (G93, inverse time) after 1 mm, then
    // 12 mm more in 60 lines (what cncjs had already streamed before the
    // error still runs, as with grbl; the rest waits).
    let f = format!("G21 G91\nG1 X1 F600\nG93 G1 X1 F10\n{}G90\n", "G1 X0.2 F600\n".repeat(60));
    for (name, text) in [("a.nc", a), ("b.nc", &b), ("c.nc", &c), ("d.nc", d), ("f.nc", &f)] {
        std::fs::write(dir.join(name), text).unwrap();
    }
    Jobs { dir: dir.to_path_buf(), a_end: (250, 425), b_end: (321, 107), c_end: (777, 222), d_delta: (150, 125) }
}

/// The machine at one instant the driver named.
#[derive(Clone, Copy, Debug)]
struct Mark {
    seconds: f64,
    pos: [i64; 4],
    steps: u64,
}

enum Pending {
    Moved { from: u64, n: u64, deadline: Instant },
    Still { still_s: f64, since: f64, deadline: Instant },
}

/// Seconds since the last recorded step (or since power-on).
fn quiet_for(vm: &Vm) -> f64 {
    let last = vm.recorder().trace().last().map_or(0, |t| t.cycle);
    (vm.cycles() - last) as f64 / vm.frequency() as f64
}

struct Session {
    marks: HashMap<String, Mark>,
    /// The driver's transcript and the firmware's lines, by simulated time.
    transcript: Vec<String>,
    failure: Option<String>,
    /// Checks the driver made itself (`CHECK_FAIL`).
    driver_checks: Vec<String>,
    fw_lines: Vec<(f64, String)>,
    cncjs_log: PathBuf,
}

impl Session {
    fn mark(&self, name: &str) -> Mark {
        *self.marks.get(name).unwrap_or_else(|| panic!("no mark {name}: the driver stopped early\n{}", self.tail()))
    }

    /// The last part of the exchange, for failure messages.
    fn tail(&self) -> String {
        let n = self.transcript.len().saturating_sub(120);
        format!(
            "driver failure: {:?}\n--- last {} transcript lines (sim s) ---\n{}\n(cncjs log: {})",
            self.failure,
            self.transcript.len() - n,
            self.transcript[n..].join("\n"),
            self.cncjs_log.display()
        )
    }

    /// Recorded steps between two marks (exclusive of the first instant).
    fn steps_between(&self, vm: &Vm, from: &str, to: &str) -> usize {
        let f = vm.frequency() as f64;
        let (a, b) = (self.mark(from).seconds, self.mark(to).seconds);
        vm.recorder().trace().iter().filter(|t| t.cycle as f64 / f > a && t.cycle as f64 / f <= b).count()
    }

    /// Firmware lines from `t_s` (simulated seconds) on.
    fn fw_lines_after(&self, t_s: f64) -> Vec<String> {
        self.fw_lines.iter().filter(|(t, _)| *t >= t_s).map(|(_, l)| l.clone()).collect()
    }

    /// Firmware lines that are errors (Marlin's `Error:`, grbl's `error:`).
    fn errors(&self) -> Vec<String> {
        self.fw_lines
            .iter()
            .filter(|(_, l)| l.starts_with("Error") || l.starts_with("error") || l.starts_with("!!"))
            .map(|(t, l)| format!("[{t:.3}] {l}"))
            .collect()
    }
}

fn spawn_reader(child: &mut Child) -> Receiver<String> {
    let (tx, rx) = channel();
    let out = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

fn reply(stdin: &mut ChildStdin, s: &str) {
    let _ = writeln!(stdin, "{s}");
    let _ = stdin.flush();
}

/// Runs cncjs and the driver with one controller against a fresh board.
fn run_session(controller: &str) -> (Vm, Session, Jobs) {
    let cncjs = cncjs_dir();
    let work = root().join(format!("target/tmp/cncjs-{}", controller.to_lowercase()));
    let _ = std::fs::remove_dir_all(&work);
    let home = work.join("home");
    std::fs::create_dir_all(&home).unwrap();
    let jobs = write_jobs(&work.join("jobs"));

    let mut vm = boot_with(board_as_sold());
    let mut bridge = PtyBridge::open(&vm, None).expect("pty");
    let port_path = bridge.port().to_string_lossy().into_owned();

    // cncjs's config as its first start writes it, plus what a user sets: the
    // port (SerialPort.list() needs udev, absent here) and the baud rate.
    let secret = "millfw-cncjs-test-secret";
    let cncrc = home.join(".cncrc");
    std::fs::write(
        &cncrc,
        format!(
            "{{\n  \"secret\": \"{secret}\",\n  \"accessTokenLifetime\": \"1h\",\n  \"ports\": [{{ \"path\": \"{port_path}\", \"manufacturer\": \"MillFW sim\" }}],\n  \"baudrates\": [250000]\n}}\n"
        ),
    )
    .unwrap();
    let http_port = free_tcp_port();
    let cncjs_log = work.join("cncjs.log");
    let log = std::fs::File::create(&cncjs_log).unwrap();
    let node = std::env::var("MILL_NODE").unwrap_or_else(|_| "node".into());
    let _server = Guard(
        Command::new(&node)
            .arg(cncjs.join("node_modules/cncjs/bin/cncjs"))
            .args(["-H", "127.0.0.1", "-p", &http_port.to_string(), "-c"])
            .arg(&cncrc)
            .arg("-vvv")
            .env("HOME", &home)
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .expect("start cncjs (node)"),
    );
    // Wait for its HTTP port; the board idles meanwhile.
    let started = Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", http_port)).is_err() {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "cncjs did not listen on {http_port}: {}",
            std::fs::read_to_string(&cncjs_log).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut bridge_rt = {
        bridge.pump(&mut vm, 0.001).unwrap();
        bridge.realtime(true)
    };

    let mut driver = Command::new(&node)
        .arg(root().join("tests/hosts/cncjs_drive.js"))
        .arg(format!("http://127.0.0.1:{http_port}"))
        .arg(secret)
        .arg(&port_path)
        .arg(controller)
        .arg(&jobs.dir)
        .env("NODE_PATH", cncjs.join("node_modules"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start the cncjs driver (node)");
    let lines = spawn_reader(&mut driver);
    let mut stdin = driver.stdin.take().unwrap();
    let _driver = Guard(driver);

    let mut s = Session {
        marks: HashMap::new(),
        transcript: Vec::new(),
        failure: None,
        driver_checks: Vec::new(),
        fw_lines: Vec::new(),
        cncjs_log,
    };
    let mut pending: Option<Pending> = None;
    let mut fw_seen = vm.line_log().len();
    let started = Instant::now();
    let mut done = false;
    while !done {
        bridge_rt.pump(&mut vm, 0.002).expect("virtual machine");
        let t = vm.seconds();
        for (_, l) in &vm.line_log()[fw_seen..] {
            s.fw_lines.push((t, l.clone()));
            s.transcript.push(format!("[{t:9.3}] fw  {l}"));
        }
        fw_seen = vm.line_log().len();
        while let Ok(line) = lines.try_recv() {
            s.transcript.push(format!("[{t:9.3}] drv {line}"));
            let mut w = line.split_whitespace();
            match w.next() {
                Some("MARK") => {
                    let name = w.next().unwrap().to_string();
                    s.marks.insert(name.clone(), Mark { seconds: t, pos: vm.positions(), steps: total_steps(&vm) });
                    reply(&mut stdin, &format!("MARKED {name}"));
                }
                Some("WAIT_MOVED") => {
                    let name = w.next().unwrap();
                    let n: u64 = w.next().unwrap().parse().unwrap();
                    let timeout: f64 = w.next().unwrap().parse().unwrap();
                    let from = s.marks.get(name).map_or(0, |m| m.steps);
                    pending = Some(Pending::Moved { from, n, deadline: Instant::now() + Duration::from_secs_f64(timeout) });
                }
                Some("WAIT_STILL") => {
                    let still_s: f64 = w.next().unwrap().parse().unwrap();
                    let timeout: f64 = w.next().unwrap().parse().unwrap();
                    pending = Some(Pending::Still { still_s, since: t, deadline: Instant::now() + Duration::from_secs_f64(timeout) });
                }
                Some("CHECK_FAIL") => s.driver_checks.push(line["CHECK_FAIL ".len()..].to_string()),
                Some("DONE") => done = true,
                Some("FAIL") => {
                    s.failure = Some(line.clone());
                    done = true;
                }
                _ => {}
            }
        }
        match &pending {
            Some(Pending::Moved { from, n, deadline }) => {
                let moved = total_steps(&vm) - from;
                if moved >= *n {
                    reply(&mut stdin, &format!("MOVED {moved}"));
                    pending = None;
                } else if Instant::now() > *deadline {
                    reply(&mut stdin, &format!("TIMEOUT moved {moved}"));
                    pending = None;
                }
            }
            Some(Pending::Still { still_s, since, deadline }) => {
                // Quiet since the request too: a line just answered may
                // not have started its steps yet.
                let quiet = quiet_for(&vm).min(vm.seconds() - since);
                if quiet >= *still_s {
                    reply(&mut stdin, &format!("STILL {:.3} s after the request, quiet for {quiet:.3} s", t - since - quiet));
                    pending = None;
                } else if Instant::now() > *deadline {
                    reply(&mut stdin, &format!("TIMEOUT still moving {:.3} s after the request", t - since));
                    pending = None;
                }
            }
            None => {}
        }
        if started.elapsed() > Duration::from_secs(240) {
            s.failure = Some("the driver did not finish within 240 s".into());
            break;
        }
    }
    // Let the last bytes through, then stop.
    for _ in 0..50 {
        bridge_rt.pump(&mut vm, 0.002).unwrap();
    }
    let t = vm.seconds();
    for (_, l) in &vm.line_log()[fw_seen..] {
        s.fw_lines.push((t, l.clone()));
        s.transcript.push(format!("[{t:9.3}] fw  {l}"));
    }
    let _ = std::fs::write(work.join("transcript.txt"), s.transcript.join("\n"));
    eprintln!(
        "cncjs {controller}: {:.1} s wall, {:.1} s simulated; transcript in {}",
        started.elapsed().as_secs_f64(),
        vm.seconds(),
        work.join("transcript.txt").display()
    );
    (vm, s, jobs)
}

/// The time of an [`Session::errors`] entry (`[t] line`).
fn e_time(e: &str) -> f64 {
    e.trim_start_matches('[').split(']').next().and_then(|t| t.trim().parse().ok()).unwrap_or(0.0)
}

/// The checks common to both controllers.
fn check_session(controller: &str, vm: &Vm, s: &Session, jobs: &Jobs) {
    let start = vm.config().machine.initial_position;
    let at = |m: &Mark| (m.pos[0] - start[0], m.pos[1] - start[1]);
    let mut failures: Vec<String> = Vec::new();
    let mut check = |ok: bool, what: String| {
        eprintln!("  [{}] {controller}: {what}", if ok { "pass" } else { "FAIL" });
        if !ok {
            failures.push(what);
        }
    };

    // A job to the end, exact.
    let a = s.marks.get("a_end");
    check(a.map(at) == Some(jobs.a_end), format!("job A ends at {:?} steps, expected {:?}", a.map(at), jobs.a_end));

    // Pause/resume: still while paused, exact end.
    for hold in ["b_pause", "b_feedhold"] {
        if hold == "b_feedhold" && controller == "Marlin" {
            continue; // cncjs's Marlin controller sends nothing for Feed hold / Cycle start.
        }
        let (h, e) = (format!("{hold}_held"), format!("{hold}_held_end"));
        if s.marks.contains_key(&h) && s.marks.contains_key(&e) {
            let n = s.steps_between(vm, &h, &e);
            check(n == 0, format!("{hold}: {n} steps during 1.5 s of hold"));
        } else {
            check(false, format!("{hold}: the machine never held still"));
        }
    }
    let b = s.marks.get("b_end");
    check(b.map(at) == Some(jobs.b_end), format!("job B (paused, resumed) ends at {:?} steps, expected {:?}", b.map(at), jobs.b_end));

    // Stop: still, stays still after Cycle start and `~`, answers.
    match (s.marks.get("c_stop"), s.marks.get("c_still"), s.marks.get("c_end")) {
        (Some(stop), Some(still), Some(_)) => {
            let n = s.steps_between(vm, "c_still", "c_end");
            check(n == 0, format!("after Stop: {n} steps of the old job after Cycle start and `~`"));
            check(at(still) != jobs.c_end, format!("after Stop: the machine stopped at {:?}, not at the job's end", at(still)));
            // The time from the Stop click to the last step before `c_still`.
            let f = vm.frequency() as f64;
            let last = vm.recorder().trace().iter().rev().map(|t| t.cycle as f64 / f).find(|&x| x <= still.seconds);
            let stop_s = last.map_or(0.0, |x| (x - stop.seconds).max(0.0));
            eprintln!("  [info] {controller}: the last step came {stop_s:.3} s after the Stop click");
            if controller == "Grbl" {
                // `!` goes out at once: only the deceleration may follow.
                check(stop_s < 0.5, format!("grbl Stop: motion went on for {stop_s:.3} s after the click"));
            }
        }
        _ => check(false, "Stop: the driver did not reach the end of the Stop phase".into()),
    }
    match (s.marks.get("c_end"), s.marks.get("d_end")) {
        (Some(c), Some(d)) => {
            let delta = (d.pos[0] - c.pos[0], d.pos[1] - c.pos[1]);
            check(delta == jobs.d_delta, format!("job D after the Stop moves {delta:?} steps, expected {:?}", jobs.d_delta));
        }
        _ => check(false, "job D after the Stop did not run".into()),
    }
    // E: reopening the port mid-job reset the board (auto-reset): nothing
    // moved after the reset, the job stopped short, the firmware restarted
    // with its position lost and refused a move before homing.
    match (s.marks.get("e_close"), s.marks.get("e_reopened"), s.marks.get("e_end")) {
        (Some(close), Some(reopened), Some(_)) => {
            let f = vm.frequency() as f64;
            let reset = vm.resets().iter().find(|r| r.cycle as f64 / f >= close.seconds).copied();
            check(reset.map(|r| r.kind) == Some(ResetKind::External), format!("reopening the port reset the board: {reset:?}"));
            if let Some(r) = reset {
                let after = vm.recorder().trace().iter().filter(|t| t.cycle > r.cycle).count();
                check(after == 0, format!("after the reset: {after} steps"));
            }
            check(at(reopened) != jobs.a_end, format!("job E stopped at {:?}, short of its end", at(reopened)));
            let lines = s.fw_lines_after(reopened.seconds - 2.0);
            check(lines.iter().any(|l| l == "echo:reset cause: external"), "the banner says reset cause: external".into());
            check(lines.iter().any(|l| l.starts_with("Error:not homed")), "a move is refused until homed".into());
        }
        _ => check(false, "job E: the driver did not reach the reconnect".into()),
    }
    // Grbl: a refused line pauses the job (nothing after it runs); a hard
    // limit is left with Unlock and a jog off the switch.
    let mut window = (f64::MAX, f64::MAX);
    if controller == "Grbl" {
        match (s.marks.get("f_start"), s.marks.get("f_paused"), s.marks.get("f_paused_end")) {
            (Some(f0), Some(fp), Some(fe)) => {
                // The refused line moved nothing (its 1 mm is missing from
                // every total: 100 + 20 k steps) and the job is held short
                // of its end (1300 steps).
                let delta = (fp.pos[0] - f0.pos[0], fp.pos[1] - f0.pos[1]);
                check(
                    delta.1 == 0 && delta.0 >= 100 && delta.0 < 1300 && (delta.0 - 100) % 20 == 0,
                    format!("job F held after the refused line: {delta:?} steps (the job: 100, the refused 100, then 1200)"),
                );
                let n = s.steps_between(vm, "f_paused", "f_paused_end");
                check(n == 0, format!("job F: {n} steps while cncjs held it on the error"));
                let lines = s.fw_lines_after(f0.seconds);
                check(lines.iter().any(|l| l == "error:20"), "job F: the firmware answered the G93 line with error:20".into());
                window = (f0.seconds, fe.seconds);
            }
            _ => check(false, "job F: cncjs did not pause on the error".into()),
        }
        match (s.marks.get("g_alarm"), s.marks.get("g_unlocked"), s.marks.get("g_end")) {
            (Some(ga), Some(_), Some(ge)) => {
                let n = s.steps_between(vm, "g_alarm", "g_unlocked");
                check(n == 0, format!("hard limit: {n} steps between the alarm and the unlock"));
                let delta = (ge.pos[0] - ga.pos[0], ge.pos[1] - ga.pos[1]);
                check(delta == (500, 0), format!("the jog off the switch after Unlock moved {delta:?} steps, expected (500, 0)"));
                check((-50..=0).contains(&ga.pos[0]), format!("X stopped at its switch (machine 0): {} steps", ga.pos[0]));
            }
            _ => check(false, "hard limit: the driver did not reach the jog off the switch".into()),
        }
    }
    for c in &s.driver_checks {
        check(false, c.clone());
    }
    check(s.failure.is_none(), format!("the driver finished: {:?}", s.failure));
    // (The refusal of job E's move is asked for.)
    let asked = s.marks.get("e_reopened").map_or(f64::MAX, |m| m.seconds);
    let errors: Vec<String> = s
        .errors()
        .into_iter()
        .filter(|e| !e.contains("Error:not homed") || e_time(e) < asked)
        .filter(|e| !(window.0..=window.1).contains(&e_time(e)))
        .collect();
    check(errors.is_empty(), format!("no error from the firmware to what cncjs sends: {errors:?}"));
    check(vm.position(Axis::Z) == start[2], "Z never moved".into());
    check(vm.violations().is_empty(), format!("no timing violation: {:?}", vm.violations()));

    assert!(failures.is_empty(), "cncjs {controller}: {} check(s) failed:\n- {}\n{}", failures.len(), failures.join("\n- "), s.tail());
}

#[test]
fn cncjs_marlin_controller_runs_pauses_and_stops_a_job() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (vm, s, jobs) = run_session("Marlin");
    check_session("Marlin", &vm, &s, &jobs);
}

#[test]
fn cncjs_grbl_controller_runs_holds_and_stops_a_job() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (vm, s, jobs) = run_session("Grbl");
    check_session("Grbl", &vm, &s, &jobs);
}
