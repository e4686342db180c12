//! A real grbl sender on the simulated board: bCNC 0.9.16 (PyPI, pinned,
//! installed by `tools/setup-hosts` into `target/bcnc-venv`), its own
//! `Sender` class and GRBL1 controller, driven without its window by
//! `tests/hosts/bcnc_drive.py` (what the window's buttons do: Unlock, a jog
//! button, a job streamed by bCNC's own serial thread with the feed slider
//! at 130 % and back, Feed hold/Resume, Stop, Unlock after a hard limit),
//! at 250000 baud through the pty bridge in real time, on a board with the
//! stock bootloader and auto-reset. Every check is on the recorded steps.

mod common;
use common::*;
use sim::pty::PtyBridge;
use sim::Vm;
use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::channel;
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A child process killed when the test ends, passed or not.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The X position (steps) and the simulated time at each MARK.
struct Marks(HashMap<String, (i64, f64)>);

impl Marks {
    fn x(&self, name: &str) -> i64 {
        self.0.get(name).unwrap_or_else(|| panic!("no mark {name}: {:?}", self.0.keys().collect::<Vec<_>>())).0
    }
    fn t(&self, name: &str) -> f64 {
        self.0[name].1
    }
}

/// X steps recorded between two marks.
fn steps_between(vm: &Vm, m: &Marks, a: &str, b: &str) -> usize {
    let f = f64::from(vm.frequency());
    let (ta, tb) = (m.t(a), m.t(b));
    vm.recorder().trace().iter().filter(|p| (ta..tb).contains(&(p.cycle as f64 / f))).count()
}

#[test]
fn bcnc_jogs_streams_a_job_with_the_feed_slider_holds_stops_and_unlocks_after_a_hard_limit() {
    let py = std::env::var_os("MILL_BCNC_PYTHON").map(PathBuf::from).unwrap_or_else(|| root().join("target/bcnc-venv/bin/python"));
    assert!(py.exists(), "{} missing: run tools/setup-hosts (tools/test does)", py.display());
    // X starts 5 mm from its switch: the session's moves (+10, +20, then
    // back) stay inside the travel, soft limits on, until the hard limit.
    let mut cfg = board_as_sold();
    cfg.machine.initial_position = [500, 2250, 2250, 0];
    let mut vm = boot_with(cfg);
    let mut bridge = PtyBridge::open(&vm, None).expect("pty");
    let port = bridge.port().to_string_lossy().into_owned();
    bridge.pump(&mut vm, 0.001).unwrap();
    let mut rt = bridge.realtime(true);
    let work = root().join("target/tmp/bcnc");
    std::fs::create_dir_all(work.join("home")).unwrap();
    let mut child = Command::new(&py)
        .arg(root().join("tests/hosts/bcnc_drive.py"))
        .arg(&port)
        .env("HOME", work.join("home"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start the bCNC driver");
    let out = child.stdout.take().unwrap();
    let _g = Guard(child);
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut marks = Marks(HashMap::new());
    let mut transcript = Vec::new();
    let started = Instant::now();
    let mut end = None;
    while end.is_none() {
        rt.pump(&mut vm, 0.002).expect("virtual machine");
        while let Ok(l) = rx.try_recv() {
            transcript.push(format!("[{:8.3}] {l}", vm.seconds()));
            if let Some(name) = l.strip_prefix("MARK ") {
                marks.0.insert(name.to_string(), (vm.positions()[0], vm.seconds()));
            } else if l == "DONE" || l.starts_with("FAIL") {
                end = Some(l);
            }
        }
        if started.elapsed() > Duration::from_secs(180) {
            end = Some("FAIL: the driver did not finish within 180 s".into());
        }
    }
    let _ = std::fs::write(work.join("transcript.txt"), transcript.join("\n"));
    let fw: Vec<String> = vm.line_log().iter().map(|(_, l)| l.clone()).collect();
    let tail = || format!("driver:\n{}\nfirmware (last 30):\n{}", transcript.join("\n"), fw[fw.len().saturating_sub(30)..].join("\n"));
    assert_eq!(end.as_deref(), Some("DONE"), "{}", tail());
    // The jog button: 10 mm.
    assert_eq!(marks.x("jog_end") - marks.x("ready"), 1000, "{}", tail());
    // The job: every line ran (80 × 0.25 mm), slider and hold or not.
    assert_eq!(marks.x("job_end") - marks.x("job_start"), 2000, "{}", tail());
    assert_eq!(steps_between(&vm, &marks, "held", "held_end"), 0, "moved while held");
    assert!(fw.iter().any(|l| l.contains("|Ov:130,")), "the firmware reported the slider's 130 %");
    // Stop: short of the job's end, and still after it.
    let stopped = marks.x("job_end") - marks.x("stopped");
    assert!(stopped > 0 && stopped < 1500, "the stopped job moved {stopped} steps of 1500");
    assert_eq!(steps_between(&vm, &marks, "stopped", "stopped_end"), 0, "moved after Stop");
    // The hard limit: X at its switch; Unlock and a jog of 5 mm off it.
    assert!((-50..=0).contains(&marks.x("alarm")), "X at its switch: {}", marks.x("alarm"));
    assert_eq!(steps_between(&vm, &marks, "alarm", "unlocked"), 0);
    assert_eq!(marks.x("off_switch") - marks.x("unlocked"), 500, "{}", tail());
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}
