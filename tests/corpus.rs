//! Real jobs (issue 13, "A corpus test in CI"): every third-party G-code file
//! of `../shared/corpus` (read in place, never copied here), scaled into the
//! machine by `tools/corpus_scale.py`, run on the real ELF in the virtual
//! machine over serial (one line in flight, comments stripped, as grbl-style
//! senders send) and from the SD card
//! (M23/M24), and checked against the manifest `tests/corpus/manifest.json`:
//!
//! - the outcome (`runs`, or the first refused line and its error text) is
//!   exactly the manifest's, over serial and from SD, in either direction;
//! - zero timing/travel violations, zero resets or crashes, no alarm, no
//!   collision in the tool changer;
//! - every recorded step event lies within 1 step + `$12` (0.002 mm) per axis
//!   of the path computed by the independent reference interpreter
//!   (`tools/corpus_scale.py path`, Python, no code shared with the
//!   firmware), in order, covering the whole path; the tool changer's own
//!   moves (between `SelectTool:` and `NowSelectedTool:`) are not compared,
//!   the changer must come back to the X/Y it left;
//! - the final position is exactly the reference's last point (rounded to
//!   steps).
//!
//! The test prints a table (outcome, steps, worst deviation, simulated and
//! wall time per run) and writes it to `target/corpus/results.md` (the
//! table in docs/ARCHITECTURE.md is copied from it). `MILL_CORPUS=<text>` runs only the
//! folders whose name contains the text (for development; CI runs all).

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::events;
use sim::{CardKind, FatKind, SdCard, SdImage, Vm, VmConfig};
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

/// Is +Z up in the firmware's G-code frames (RS274/NGC, grbl, LinuxCNC)?
///
/// `false` on main today: Z grows downward (docs/SPEC.md §3), machine Z runs 0 (top
/// switch) to +45. The scaler then puts each job's Z numbers in 4..38 (the
/// job's lowest point 4 mm below the top), the firmware runs it upside down
/// (a retract goes down), and the recorded Z steps are read as +Z down, so
/// the comparison checks what the firmware does with the numbers.
/// Set it to `true` when +Z up lands (issue 13 item 0): the scaler then puts
/// Z in −38..−4 (the job's highest point 4 mm below the top), the reference
/// homes to Z −1, and recorded Z steps are read as machine Z = −steps. That
/// is the only change the harness needs.
const FIRMWARE_Z_UP: bool = true;

/// Steps per mm on X, Y, Z (factory settings).
const SPMM: f64 = 100.0;
/// Allowed per-axis distance from the reference path, steps: 1 step (the
/// rounding of each end point to steps and the Bresenham's half step) + the
/// arc tolerance `$12` (0.002 mm = 0.2 step) + the reference's own chords
/// (0.0002 mm = 0.02 step) + float noise.
const TOL_STEPS: f64 = 1.0 + 0.2 + 0.02 + 1e-6;
/// How far along the reference path (steps) one step event may move the
/// match point: a step event moves at most one step per axis.
const BUDGET_STEPS: f64 = 4.0;
/// How far back along the path (steps) a match may step, and how much
/// nearer (steps) another candidate must be to keep the match from going to
/// the furthest one (see [`check_events`]).
const BACK_STEPS: f64 = 4.0;
const SLACK_STEPS: f64 = 0.5;
/// Simulated time allowed for one job line (a long move queued behind a
/// full queue, a tool change, a homing), s.
const LINE_TIMEOUT_S: f64 = 120.0;
/// Simulated time allowed for a whole SD job, s.
const JOB_TIMEOUT_S: f64 = 1800.0;
/// Where the machine stands at power-on, physical steps (near the switches:
/// the G28 in front of every job then takes ~2 s instead of ~8).
const START_STEPS: [i64; 3] = [600, 600, 600];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn corpus_dir() -> PathBuf {
    // ../shared/corpus next to the checkout (main), or two levels up (a
    // worktree under wt/); MILL_CORPUS_DIR overrides.
    if let Some(d) = std::env::var_os("MILL_CORPUS_DIR") {
        return PathBuf::from(d);
    }
    let near = repo().join("../shared/corpus");
    if near.is_dir() {
        near
    } else {
        repo().join("../../shared/corpus")
    }
}

/// One manifest entry.
struct Entry {
    folder: String,
    file: String,
    scale: f64,
    expect: String,
    /// The SD run's outcome where it differs from the serial one (the card
    /// reader sees bytes a sender strips, e.g. comments).
    expect_sd: Option<String>,
    /// Tool radii (tool number -> mm) put in the tool table before the job
    /// (`G10 L1 P<n> R<r>`) and given to the reference, for files that use
    /// cutter compensation (G41/G42 take the spindle tool's diameter).
    tool_radii: Vec<(u8, f64)>,
}

fn manifest() -> Vec<Entry> {
    let text = std::fs::read_to_string(repo().join("tests/corpus/manifest.json")).expect("manifest");
    let v: serde_json::Value = serde_json::from_str(&text).expect("manifest is JSON");
    v["jobs"]
        .as_array()
        .expect("jobs")
        .iter()
        .map(|j| Entry {
            folder: j["folder"].as_str().unwrap().to_string(),
            file: j["file"].as_str().unwrap().to_string(),
            scale: j["scale"].as_f64().unwrap(),
            expect: j["expect"].as_str().unwrap().to_string(),
            expect_sd: j.get("expect_sd").and_then(|v| v.as_str()).map(str::to_string),
            tool_radii: j
                .get("tool_radii")
                .and_then(|v| v.as_object())
                .map(|o| o.iter().map(|(t, r)| (t.parse().unwrap(), r.as_f64().unwrap())).collect())
                .unwrap_or_default(),
        })
        .collect()
}

/// The reference path in physical steps (what the recorder counts).
#[derive(Clone, Debug, Default)]
struct RefPath {
    pts: Vec<[f64; 3]>,
    /// Scaled-file line of each point (0 for the start point).
    line: Vec<usize>,
    /// A tool change may happen at this point.
    jump: Vec<bool>,
    /// No Z word since the last possible tool change: after a real one, Z is
    /// the changer's travel height.
    z_stale: Vec<bool>,
    /// The model stops here (line, why).
    unsupported: Option<(usize, String)>,
}

impl RefPath {
    /// Only the points of lines before `line` (the refused one).
    fn before(&self, line: usize) -> RefPath {
        let n = self.line.iter().take_while(|&&l| l < line).count();
        RefPath {
            pts: self.pts[..n].to_vec(),
            line: self.line[..n].to_vec(),
            jump: self.jump[..n].to_vec(),
            z_stale: self.z_stale[..n].to_vec(),
            unsupported: None,
        }
    }
}

fn to_physical(mm: [f64; 3]) -> [f64; 3] {
    let zs = if FIRMWARE_Z_UP { -1.0 } else { 1.0 };
    [mm[0] * SPMM, mm[1] * SPMM, zs * mm[2] * SPMM]
}

fn python(args: &[&str]) -> String {
    let out =
        Command::new("python3").arg(repo().join("tools/corpus_scale.py")).args(args).output().expect("python3 runs tools/corpus_scale.py");
    assert!(out.status.success(), "corpus_scale.py {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// A job made ready: scaled text and its reference path.
struct Prepared {
    name: String,
    /// `G10 L1 P<n> R<r>` lines sent before the job (see `Entry::tool_radii`).
    tool_table: Vec<String>,
    scaled: String,
    scale: f64,
    reference: RefPath,
}

fn prepare(e: &Entry) -> Prepared {
    let src = corpus_dir().join(&e.folder).join(&e.file);
    assert!(src.exists(), "{} missing (the corpus lives in ../shared/corpus)", src.display());
    let dir = repo().join("target/corpus").join(&e.folder);
    std::fs::create_dir_all(&dir).unwrap();
    let job = dir.join("job.gcode");
    let path = dir.join("reference.path");
    let zflag = if FIRMWARE_Z_UP { "--z-up" } else { "--z-down" };
    let params = python(&["scale", src.to_str().unwrap(), job.to_str().unwrap(), zflag]);
    let params: serde_json::Value = serde_json::from_str(params.trim()).expect("scale parameters");
    let radii = format!("{{{}}}", e.tool_radii.iter().map(|(t, r)| format!("\"{t}\": {r}")).collect::<Vec<_>>().join(", "));
    python(&["path", job.to_str().unwrap(), path.to_str().unwrap(), "--start", &start_arg(), zflag, "--radii", &radii]);
    Prepared {
        name: e.folder.clone(),
        tool_table: e.tool_radii.iter().map(|(t, r)| format!("G10 L1 P{t} R{r}")).collect(),
        scaled: std::fs::read_to_string(&job).unwrap(),
        scale: params["scale"].as_f64().unwrap(),
        reference: read_reference(&path),
    }
}

/// The reference start point, machine mm, as `--start` takes it.
fn start_arg() -> String {
    let zs = if FIRMWARE_Z_UP { -1.0 } else { 1.0 };
    format!("{},{},{}", START_STEPS[0] as f64 / SPMM, START_STEPS[1] as f64 / SPMM, zs * START_STEPS[2] as f64 / SPMM)
}

/// A path file of `corpus_scale.py path`, in physical steps.
fn read_reference(path: &std::path::Path) -> RefPath {
    let mut r = RefPath::default();
    r.pts.push(START_STEPS.map(|v| v as f64));
    r.line.push(0);
    r.jump.push(false);
    r.z_stale.push(false);
    let mut cur = 0usize;
    for l in std::fs::read_to_string(path).unwrap().lines() {
        let mut w = l.split_whitespace();
        match w.next() {
            Some("L") => cur = w.next().unwrap().parse().unwrap(),
            Some("P") => {
                let v: Vec<f64> = w.map(|x| x.parse().unwrap()).collect();
                r.pts.push(to_physical([v[0], v[1], v[2]]));
                r.line.push(cur);
                r.jump.push(false);
                r.z_stale.push(v[3] != 0.0);
            }
            Some("J") => *r.jump.last_mut().unwrap() = true,
            Some("U") => {
                let n = w.next().unwrap().parse().unwrap();
                r.unsupported = Some((n, w.collect::<Vec<_>>().join(" ")));
            }
            _ => {}
        }
    }
    r
}

/// What one run did.
#[derive(Debug, Default)]
struct RunResult {
    /// `runs` or `refused: line <original line>: <error>`.
    outcome: String,
    steps: usize,
    worst_dev: f64,
    sim_s: f64,
    wall_s: f64,
    tool_changes: usize,
    /// Everything wrong besides the outcome.
    problems: Vec<String>,
}

fn vm_for_corpus(p: &Prepared) -> Vm {
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = LINE_TIMEOUT_S;
    cfg.machine.initial_position = [START_STEPS[0], START_STEPS[1], START_STEPS[2], 0];
    let mut vm = boot_with(cfg);
    for l in &p.tool_table {
        ok(&mut vm, l);
    }
    vm
}

/// The line as a grbl-style sender (UGS, cncjs, bCNC) sends it: comments
/// `( )` and `;` removed, blanks around trimmed. Senders strip comments
/// because `!`, `~` and `?` are realtime bytes wherever they appear on the
/// wire (grbl's rule, kept here): 15_grbl-hsm-test's first comment,
/// `(DO NOT USE WHEN CONNECTED TO A MACHINE!!)`, sent as it is, puts the
/// machine in feed hold. An unclosed `(` is sent as it is, for the firmware
/// to refuse.
fn host_line(raw: &str) -> String {
    let mut out = String::new();
    let mut rest = raw;
    loop {
        match rest.find(['(', ';']) {
            None => {
                out.push_str(rest);
                break;
            }
            Some(i) if rest.as_bytes()[i] == b';' => {
                out.push_str(&rest[..i]);
                break;
            }
            Some(i) => match rest[i..].find(')') {
                Some(j) => {
                    out.push_str(&rest[..i]);
                    out.push(' ');
                    rest = &rest[i + j + 1..];
                }
                None => {
                    out.push_str(rest);
                    break;
                }
            },
        }
    }
    out.trim().to_string()
}

/// `MILL_CORPUS_DEBUG=1` prints every line the firmware sends.
fn debug(how: &str, line: &str) {
    if std::env::var_os("MILL_CORPUS_DEBUG").is_some() {
        eprintln!("{how}< {line}");
    }
}

fn outcome_of(refused: &Option<(usize, String)>) -> String {
    match refused {
        None => "runs".to_string(),
        // The scaled file has one line (G28) in front of the original's.
        Some((n, e)) => format!("refused: line {}: {}", n - 1, e),
    }
}

/// Serial: ping-pong, stop sending at the first refused line (as a sender
/// that aborts on error does), `~` after each M0/M1 pause.
fn run_serial(p: &Prepared) -> RunResult {
    let wall = Instant::now();
    let mut vm = vm_for_corpus(p);
    let t0 = vm.seconds();
    let mut refused: Option<(usize, String)> = None;
    let mut problems = Vec::new();
    'lines: for (i, raw) in p.scaled.lines().enumerate() {
        let line = host_line(raw);
        if line.is_empty() {
            continue;
        }
        vm.send_line(&line);
        loop {
            let r = match vm.wait_line(|_| true, LINE_TIMEOUT_S) {
                Ok(r) => r,
                Err(e) => {
                    problems.push(format!("serial line {}: {e}", i + 1));
                    break 'lines;
                }
            };
            debug("serial", &r);
            if r.starts_with("echo:paused") {
                vm.send("~");
            }
            if r.starts_with("Error") && refused.is_none() {
                refused = Some((i + 1, r.clone()));
            }
            if r.starts_with("ALARM") || r.starts_with("!!") {
                problems.push(format!("serial line {}: {r}", i + 1));
            }
            if r == "ok" || r.starts_with("ok ") {
                break;
            }
        }
        if refused.is_some() {
            break;
        }
    }
    finish(p, vm, refused, problems, t0, wall, "serial")
}

/// From SD: M23/M24, `~` after each pause, until `Done printing file` or the
/// job stops at a refused line.
fn run_sd(p: &Prepared) -> RunResult {
    let wall = Instant::now();
    let mut vm = vm_for_corpus(p);
    let img = SdImage::new(FatKind::Fat16).file("JOB.NC", p.scaled.as_bytes()).build();
    vm.insert_sd(SdCard::new(img, CardKind::Sdhc));
    let t0 = vm.seconds();
    let mut problems = Vec::new();
    let mut refused: Option<(usize, String)> = None;
    let mut error: Option<String> = None;
    ok(&mut vm, "M23 JOB.NC");
    ok(&mut vm, "M24");
    loop {
        // A job prints nothing while it runs: wait for the whole job.
        let r = match vm.wait_line(|_| true, JOB_TIMEOUT_S) {
            Ok(r) => r,
            Err(e) => {
                problems.push(format!("SD: {e}"));
                break;
            }
        };
        debug("SD", &r);
        if r == "Done printing file" {
            break;
        }
        if r.starts_with("echo:paused") {
            vm.send("~");
        }
        if r.starts_with("Error") && error.is_none() {
            error = Some(r.clone());
        }
        if r.starts_with("ALARM") || r.starts_with("!!") {
            problems.push(format!("SD: {r}"));
        }
        // A refused line: `echo:SD job stopped at line N` after its error; a
        // line the reader refuses: `Error:<what> at SD byte B; job stopped
        // at line N`. Then the job drains and ends.
        if let Some(n) = r.strip_prefix("echo:SD job stopped at line ") {
            let n: usize = n.trim().parse().unwrap_or(0);
            refused = Some((n, error.clone().unwrap_or_else(|| "(no error line)".into())));
        }
        if let (Some(i), Some(j)) = (r.find(" at SD byte "), r.find("; job stopped at line ")) {
            let n: usize = r[j + "; job stopped at line ".len()..].trim().parse().unwrap_or(0);
            refused = Some((n, r[..i].to_string()));
        }
        if r.starts_with("echo:SD job ended") || r == "echo:SD job aborted" {
            break;
        }
    }
    finish(p, vm, refused, problems, t0, wall, "SD")
}

fn finish(
    p: &Prepared,
    mut vm: Vm,
    refused: Option<(usize, String)>,
    mut problems: Vec<String>,
    t0: f64,
    wall: Instant,
    how: &str,
) -> RunResult {
    // Let queued motion finish; after a refusal nothing else may move.
    if let Err(e) = vm.command_timeout("M400", LINE_TIMEOUT_S) {
        problems.push(format!("{how}: M400 after the job: {e}"));
    }
    let steps_then = vm.recorder().trace().len();
    let _ = vm.run_for(0.3);
    if vm.recorder().trace().len() != steps_then {
        problems.push(format!("{how}: the machine moved after the job ended"));
    }
    let sim_s = vm.seconds() - t0;
    if !vm.violations().is_empty() {
        let v = vm.violations();
        problems.push(format!("{how}: {} violations, first {:?}", v.len(), &v[..v.len().min(3)]));
    }
    if vm.resets().len() != 1 {
        problems.push(format!("{how}: resets {:?}", vm.resets()));
    }
    if let Some(e) = vm.fatal_error() {
        problems.push(format!("{how}: VM stopped: {e}"));
    }
    if !vm.atc().collisions.is_empty() {
        problems.push(format!("{how}: changer collisions {:?}", vm.atc().collisions));
    }
    // The reference up to the refused line (every line if none).
    let upto = refused.as_ref().map_or(usize::MAX, |r| r.0);
    if let Some((u, why)) = &p.reference.unsupported {
        if *u < upto {
            problems.push(format!(
                "{how}: the firmware accepted scaled line {u}, where the reference model stops ({why}): the path after it is unchecked"
            ));
        }
    }
    let reference = p.reference.before(upto.min(p.reference.unsupported.as_ref().map_or(usize::MAX, |u| u.0)));
    let windows = change_windows(&vm);
    let (worst, steps) = match check_path(&vm, &reference, &windows) {
        Ok(x) => x,
        Err(e) => {
            problems.push(format!("{how}: path: {e}"));
            (f64::NAN, events(&vm).len())
        }
    };
    RunResult {
        outcome: outcome_of(&refused),
        steps,
        worst_dev: worst,
        sim_s,
        wall_s: wall.elapsed().as_secs_f64(),
        tool_changes: windows.len(),
        problems,
    }
}

/// Cycle windows of the tool changes: from a little before `SelectTool:`
/// arrived (the line takes ~1 ms on the wire; the change waits for the
/// queue to drain before it prints it) to `NowSelectedTool:`.
fn change_windows(vm: &Vm) -> Vec<(u64, u64)> {
    let margin = (0.004 * vm.frequency() as f64) as u64;
    let mut out = Vec::new();
    let mut start = None;
    for (c, l) in vm.line_log() {
        if l.starts_with("SelectTool:") {
            start = Some(c.saturating_sub(margin));
        } else if l.starts_with("NowSelectedTool:") {
            if let Some(s) = start.take() {
                out.push((s, *c));
            }
        }
    }
    if let Some(s) = start {
        out.push((s, u64::MAX));
    }
    out
}

fn seg_len(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

/// (Euclidean distance, projection parameter 0..1) of `p` to segment a-b.
fn project(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> (f64, f64) {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let t = if l2 == 0.0 { 0.0 } else { (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1] + (p[2] - a[2]) * d[2]) / l2).clamp(0.0, 1.0) };
    let q = [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]];
    (seg_len(p, q), t)
}

/// Per-axis (Chebyshev) distance of `p` to segment a-b: min over the segment
/// of the largest per-axis difference (convex in t: ternary search).
fn cheb(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let f = |t: f64| (0..3).map(|i| (p[i] - a[i] - t * (b[i] - a[i])).abs()).fold(0.0, f64::max);
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let m1 = lo + (hi - lo) / 3.0;
        let m2 = hi - (hi - lo) / 3.0;
        if f(m1) <= f(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    f(0.5 * (lo + hi)).min(f(0.0)).min(f(1.0))
}

/// The distance used for the check: per-axis, computed exactly only where
/// it matters (the Euclidean distance bounds it from above).
fn dist(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> (f64, f64) {
    let (e, t) = project(p, a, b);
    if e <= 0.5 {
        (e, t)
    } else {
        (cheb(p, a, b), t)
    }
}

/// Follows the recorded step events along the reference polyline: each
/// event must lie within [`TOL_STEPS`] (per axis) of a segment at most
/// [`BUDGET_STEPS`] ahead of the previous match; events inside a tool
/// change window are skipped and the path resumes from where the changer
/// left the machine (which must be the X/Y it came from). The path must
/// reach the last reference point, and the machine end exactly on it.
/// Returns (worst per-axis deviation, events checked).
fn check_path(vm: &Vm, r: &RefPath, windows: &[(u64, u64)]) -> Result<(f64, usize), String> {
    let evs: Vec<(u64, [f64; 3])> =
        events(vm).iter().map(|e| (e.cycle, [e.position[0] as f64, e.position[1] as f64, e.position[2] as f64])).collect();
    let now = vm.positions();
    check_events(&evs, [now[0], now[1], now[2]], r, windows)
}

/// [`check_path`] on step events (cycle, position) and the final position.
fn check_events(evs: &[(u64, [f64; 3])], now: [i64; 3], r: &RefPath, windows: &[(u64, u64)]) -> Result<(f64, usize), String> {
    let mut pts = r.pts.clone();
    let n = pts.len();
    let mut k = 0usize; // current segment pts[k] -> pts[k+1] (or the last point)
    let mut along = 0.0f64; // match point, steps from pts[k]
    let mut worst = 0.0f64;
    let mut win = 0usize;
    let mut in_window = false;
    let mut checked = 0usize;
    let mut last_pos: [f64; 3] = START_STEPS.map(|v| v as f64);
    let resume = |k: &mut usize, along: &mut f64, pts: &mut Vec<[f64; 3]>, at: [f64; 3]| -> Result<(), String> {
        let j = (*k..n).find(|&j| r.jump[j]).ok_or_else(|| format!("a tool change at {at:?} where the job has no T/M6 ahead"))?;
        let before = pts[j];
        if (before[0] - at[0]).abs() > 0.5 || (before[1] - at[1]).abs() > 0.5 {
            return Err(format!("the tool change left X/Y at {at:?}, it started at {before:?}"));
        }
        pts[j] = at;
        // Until the job states Z again, it stays where the changer left it.
        for i in j + 1..n {
            if !r.z_stale[i] {
                break;
            }
            pts[i][2] = at[2];
        }
        *k = j;
        *along = 0.0;
        Ok(())
    };
    for &(cycle, q) in evs {
        while win < windows.len() && cycle > windows[win].1 {
            // A window closed before this event.
            if in_window {
                resume(&mut k, &mut along, &mut pts, last_pos)?;
                in_window = false;
            }
            win += 1;
        }
        if win < windows.len() && cycle >= windows[win].0 {
            in_window = true;
            last_pos = q;
            continue;
        }
        if in_window {
            resume(&mut k, &mut along, &mut pts, last_pos)?;
            in_window = false;
        }
        last_pos = q;
        checked += 1;
        // Candidates: the segments within BUDGET_STEPS of path ahead of the
        // match point and BACK_STEPS behind it. Among those holding the
        // event, the furthest of the nearly nearest (within SLACK_STEPS of
        // the best distance): the furthest follows a path that runs back
        // over itself (homing, pecks, a retract and plunge 0.01 step apart),
        // the nearest keeps a tight spiral from running ahead, and the small
        // step back absorbs a match that ran ahead anyway.
        let mut cands: Vec<(usize, f64, f64)> = Vec::new();
        let consider = |j: usize, cands: &mut Vec<(usize, f64, f64)>| {
            let (a, b) = (pts[j], if j + 1 < n { pts[j + 1] } else { pts[j] });
            let (d, t) = dist(q, a, b);
            if d <= TOL_STEPS {
                cands.push((j, d, t * seg_len(a, b)));
            }
        };
        let mut back = along;
        let mut j = k;
        while j > 0 && back <= BACK_STEPS {
            j -= 1;
            consider(j, &mut cands);
            back += seg_len(pts[j], pts[j + 1]);
        }
        let mut reach = 0.0f64;
        let mut j = k;
        loop {
            if j > k {
                reach += if j == k + 1 { seg_len(pts[k], pts[(k + 1).min(n - 1)]) - along } else { seg_len(pts[j - 1], pts[j]) };
                if reach > BUDGET_STEPS {
                    break;
                }
            }
            consider(j, &mut cands);
            j += 1;
            if j + 1 > n {
                break;
            }
        }
        let dmin = cands.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
        let best = cands.iter().filter(|c| c.1 <= dmin + SLACK_STEPS).max_by_key(|c| c.0).copied();
        match best {
            Some((j, d, a)) => {
                if j != k || a >= along {
                    along = a;
                }
                k = j;
                worst = worst.max(d);
            }
            None => {
                let (a, b) = (pts[k], pts[(k + 1).min(n - 1)]);
                return Err(format!(
                    "step event {checked} at {q:?} (cycle {cycle}) is {:.2} steps (per axis) off the reference segment {:?} -> {:?} of scaled line {}",
                    cheb(q, a, b),
                    a.map(|v| (v * 100.0).round() / 100.0),
                    b.map(|v| (v * 100.0).round() / 100.0),
                    r.line[(k + 1).min(n - 1)]
                ));
            }
        }
    }
    if in_window {
        resume(&mut k, &mut along, &mut pts, last_pos)?;
    }
    // Covered the whole path: the match reached the last segment.
    if k + 2 < n {
        return Err(format!(
            "the steps ended on reference segment {k} of {} (scaled line {}): the rest of the path never ran",
            n - 1,
            r.line[k + 1]
        ));
    }
    let end = pts[n - 1].map(|v| v.round() as i64);
    if now != end {
        return Err(format!("final position {now:?}, the reference ends at {end:?}"));
    }
    Ok((worst, checked))
}

#[test]
fn corpus_jobs_run_over_serial_and_from_sd_as_the_manifest_says_on_the_reference_path() {
    let filter = std::env::var("MILL_CORPUS").unwrap_or_default();
    let entries = manifest();
    let folders: Vec<String> = std::fs::read_dir(corpus_dir())
        .expect("../shared/corpus")
        .filter_map(|d| d.ok())
        .filter(|d| d.path().is_dir())
        .map(|d| d.file_name().to_string_lossy().to_string())
        .collect();
    // The manifest lists every folder of the corpus, and nothing else.
    let mut listed: Vec<&str> = entries.iter().map(|e| e.folder.as_str()).collect();
    listed.sort();
    let mut present: Vec<&str> = folders.iter().map(String::as_str).collect();
    present.sort();
    assert_eq!(listed, present, "manifest vs corpus folders");
    assert!(entries.len() >= 20, "at least 20 files");

    let mut failures = Vec::new();
    let mut rows = Vec::new();
    let wall = Instant::now();
    for e in entries.iter().filter(|e| e.folder.contains(&filter)) {
        let p = prepare(e);
        if (p.scale - e.scale).abs() > 1e-9 {
            failures.push(format!("{}: scale {} but the manifest says {}", e.folder, p.scale, e.scale));
        }
        // Serial and SD in parallel (two VMs, two cores).
        let (ser, sd) = std::thread::scope(|s| {
            let a = s.spawn(|| run_serial(&p));
            let b = s.spawn(|| run_sd(&p));
            (a.join().expect("serial run"), b.join().expect("SD run"))
        });
        for (how, r, expect) in [("serial", &ser, &e.expect), ("SD", &sd, e.expect_sd.as_ref().unwrap_or(&e.expect))] {
            if &r.outcome != expect {
                failures.push(format!("{} ({how}): outcome `{}`, the manifest expects `{expect}`", e.folder, r.outcome));
            }
            for pr in &r.problems {
                failures.push(format!("{}: {pr}", e.folder));
            }
        }

        let row = format!(
            "| {} | {} | {} | {} / {} | {:.3} / {:.3} | {} | {:.1} / {:.1} | {:.1} / {:.1} |",
            p.name,
            p.scale,
            if ser.outcome == sd.outcome { ser.outcome.clone() } else { format!("serial {}; SD {}", ser.outcome, sd.outcome) }
                .replace('|', "\\|"),
            ser.steps,
            sd.steps,
            ser.worst_dev / SPMM,
            sd.worst_dev / SPMM,
            ser.tool_changes,
            ser.sim_s,
            sd.sim_s,
            ser.wall_s,
            sd.wall_s
        );
        println!("{row}");
        rows.push(row);
    }
    let header = "| folder | scale | outcome (serial and SD) | step events checked serial / SD | worst deviation mm serial / SD | tool changes | simulated s serial / SD | wall s serial / SD |\n|---|---|---|---|---|---|---|---|";
    let table = format!("{header}\n{}\n\nTotal wall time {:.0} s.\n", rows.join("\n"), wall.elapsed().as_secs_f64());
    println!("{table}");
    let out = repo().join("target/corpus");
    std::fs::create_dir_all(&out).unwrap();
    if filter.is_empty() {
        std::fs::write(out.join("results.md"), &table).unwrap();
    }
    assert!(failures.is_empty(), "{} problems:\n{}", failures.len(), failures.join("\n"));
}

/// A Bresenham walk from `a` to `b` (whole steps), one event per step.
fn walk(evs: &mut Vec<(u64, [f64; 3])>, a: [i64; 3], b: [i64; 3]) {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let n = d.iter().map(|v| v.abs()).max().unwrap();
    for s in 1..=n {
        let p = [0, 1, 2].map(|i| (a[i] as f64 + d[i] as f64 * s as f64 / n as f64).round());
        let c = evs.last().map_or(0, |e| e.0) + 1000;
        evs.push((c, p));
    }
}

fn synthetic_ref(pts: &[[f64; 3]]) -> RefPath {
    RefPath {
        pts: pts.to_vec(),
        line: (0..pts.len()).collect(),
        jump: vec![false; pts.len()],
        z_stale: vec![false; pts.len()],
        unsupported: None,
    }
}

#[test]
fn the_path_check_fails_on_a_skipped_circle_an_off_path_step_and_a_wrong_end() {
    // Reference: a line, a full circle of radius 80 steps, a line.
    let mut pts = vec![[0.0, 0.0, 0.0], [200.0, 200.0, 0.0]];
    for k in 1..=400 {
        let t = k as f64 / 400.0 * std::f64::consts::TAU;
        pts.push([120.0 + 80.0 * t.cos(), 200.0 + 80.0 * t.sin(), 0.0]);
    }
    pts.push([200.0, 300.0, 50.0]);
    let r = synthetic_ref(&pts);
    // A faithful trace: the lines walked, the circle in whole steps.
    let mut good = Vec::new();
    walk(&mut good, [0, 0, 0], [200, 200, 0]);
    let mut prev = [200i64, 200, 0];
    for p in &pts[2..pts.len() - 1] {
        let q = p.map(|v| v.round() as i64);
        walk(&mut good, prev, q);
        prev = q;
    }
    walk(&mut good, prev, [200, 300, 50]);
    let (worst, n) = check_events(&good, [200, 300, 50], &r, &[]).expect("the faithful trace passes");
    assert!(worst <= TOL_STEPS && n == good.len(), "{worst} {n}");
    // The circle skipped (issue 13 item 1): the trace goes straight on.
    let mut skipped = Vec::new();
    walk(&mut skipped, [0, 0, 0], [200, 200, 0]);
    walk(&mut skipped, [200, 200, 0], [200, 300, 50]);
    let e = check_events(&skipped, [200, 300, 50], &r, &[]).unwrap_err();
    assert!(e.contains("off the reference"), "{e}");
    // One step 2 steps off the line.
    let mut off = good.clone();
    off[50].1[2] += 2.0;
    assert!(check_events(&off, [200, 300, 50], &r, &[]).unwrap_err().contains("2.00 steps"));
    // Stopping early, and a final position one step off.
    let short = good[..good.len() - 30].to_vec();
    let stopped = short.last().unwrap().1.map(|v| v as i64);
    assert!(check_events(&short, stopped, &r, &[]).unwrap_err().contains("final position"));
    let shorter = good[..good.len() / 2].to_vec();
    let stopped = shorter.last().unwrap().1.map(|v| v as i64);
    assert!(check_events(&shorter, stopped, &r, &[]).unwrap_err().contains("never ran"));
    assert!(check_events(&good, [200, 301, 50], &r, &[]).unwrap_err().contains("final position"));
}

#[test]
fn the_reference_interpreter_passes_its_own_checks() {
    // Full circles in G17/G18/G19 both ways, R arcs short and long, G90.1 vs
    // G91.1, helix, G20, G91, G92, G28 (this firmware's homing), G81 with
    // G98/G99 and modal holes, G83 pecks, G91 canned cycles with L, and the
    // scaler touching only coordinate numbers (tools/corpus_scale.py).
    let out = python(&["selftest"]);
    assert!(out.contains("self-test: ok"), "{out}");
}

// ---- Dialect reproductions -------------------------------------------------
//
// Short jobs written the way some generators and controllers write them,
// run on the real ELF over serial like the corpus files (a G28 in front),
// every line's answer checked, and the recorded steps checked against the
// reference model's path of the same text.

/// What one line of a reproduction answered: its `Error:` line, if any, and
/// every other line before its `ok`.
struct Answer {
    line: String,
    error: Option<String>,
    other: Vec<String>,
    /// Simulated seconds from sending the line to its `ok`.
    secs: f64,
}

/// Run `text` (a G28 goes in front) over serial, one line in flight, every
/// line sent even after an error. The lines of `refused` must be answered
/// with an `Error:` and every other line without one. Then the path check of
/// [`finish`] against `corpus_scale.py path` (`model_args`: its options) of
/// the same text without the refused lines: a refused line must change
/// nothing, so the path is the one of the others. `check` looks at each
/// line's answer and the VM first; then any problem [`finish`] finds
/// (violations, moves after the end, a path off the reference) fails the
/// test.
fn run_reproduction(name: &str, text: &str, model_args: &[&str], refused: &[&str], check: impl FnOnce(&[Answer], &mut Vm)) {
    let dir = repo().join("target/dialect").join(name);
    std::fs::create_dir_all(&dir).unwrap();
    let job = dir.join("job.gcode");
    let path = dir.join("reference.path");
    let text = format!("G28\n{text}");
    let model: String = text.lines().filter(|l| !refused.contains(&host_line(l).as_str())).map(|l| format!("{l}\n")).collect();
    std::fs::write(&job, &model).unwrap();
    let zflag = if FIRMWARE_Z_UP { "--z-up" } else { "--z-down" };
    let mut args = vec!["path", job.to_str().unwrap(), path.to_str().unwrap(), "--start"];
    let start = start_arg();
    args.push(&start);
    args.push(zflag);
    args.extend_from_slice(model_args);
    python(&args);
    let mut p = Prepared { name: name.to_string(), tool_table: Vec::new(), scaled: model, scale: 1.0, reference: read_reference(&path) };
    p.scaled = text.clone();
    let wall = Instant::now();
    let mut vm = vm_for_corpus(&p);
    let t0 = vm.seconds();
    let mut answers = Vec::new();
    for raw in p.scaled.lines() {
        let line = host_line(raw);
        if line.is_empty() {
            continue;
        }
        let sent = vm.seconds();
        vm.send_line(&line);
        let mut a = Answer { line: line.clone(), error: None, other: Vec::new(), secs: 0.0 };
        loop {
            let r = vm.wait_line(|_| true, LINE_TIMEOUT_S).unwrap_or_else(|e| panic!("{name}: `{line}`: {e}"));
            if r == "ok" || r.starts_with("ok ") {
                break;
            }
            if r.starts_with("Error") {
                a.error = Some(r);
            } else {
                a.other.push(r);
            }
        }
        a.secs = vm.seconds() - sent;
        answers.push(a);
    }
    only_refused(&answers, refused);
    check(&answers, &mut vm);
    let r = finish(&p, vm, None, Vec::new(), t0, wall, name);
    assert!(r.problems.is_empty(), "{name}: {:#?}", r.problems);
}

/// The answer to the line `text` (the first one sent as it).
fn answer<'a>(answers: &'a [Answer], text: &str) -> &'a Answer {
    answers.iter().find(|a| a.line == text).unwrap_or_else(|| panic!("`{text}` was not sent"))
}

/// Every line was answered `ok` without an error but those of `refused`.
fn only_refused(answers: &[Answer], refused: &[&str]) {
    for a in answers {
        let expected = refused.contains(&a.line.as_str());
        assert_eq!(a.error.is_some(), expected, "`{}` answered {:?}", a.line, a.error);
    }
}

#[test]
fn fusion_mach3_post_moves_with_bare_axis_words_after_g80_as_the_motion_before_the_cycle() {
    // Fusion 360's Mach3 post ends a cycle with G80 and moves on with bare
    // axis words: the G0 in force before the cycle (`$154=1`, the default).
    let job = "G0 X5 Y5 Z-2\nG98 G73 X10 Y10 Z-11 R-5 Q0.25 F250\nG80\nZ-4\nX12 Y12 Z-4\nM400\n";
    run_reproduction("g80_mach3", job, &[], &[], |_, _| {});
    // `$154=0`: LinuxCNC's and grbl's refusal, and nothing moves after it.
    let job = "$154=0\nG0 X5 Y5 Z-2\nG98 G81 X10 Y10 Z-11 R-5 F250\nG80\nZ-4\n";
    run_reproduction("g80_strict", job, &["--g80-cancels"], &["Z-4"], |a, _| {
        assert!(answer(a, "Z-4").error.as_ref().unwrap().contains("G80 active"));
    });
}

#[test]
fn linuxcnc_polar_coordinates_drill_six_holes_on_a_circle_and_move_by_radius_and_angle() {
    // The work origin at the circle's centre (G92), then LinuxCNC's
    // `G81 R.1 Z-.1 ^60 L6` under G91 (six holes 60° apart), and polar
    // moves under G90 and G91.
    let job =
        "G0 X20 Y20 Z-2\nG92 X0 Y0\nG0 @10 ^0\nG91 G98 G81 R-1 Z-3 ^60 L6 F300\nG90 G80\nG1 @5 ^90 F600\nG91 ^-90\n@2\nG90 G92.1\nM400\n";
    run_reproduction("polar", job, &[], &[], |_, _| {});
    // What LinuxCNC refuses is refused, and nothing moves.
    let job = "G0 X20 Y20 Z-2\nG1 @5 X3 F600\nG18 G1 @5 ^10\nG17 G53 G0 @5 ^10\nM400\n";
    run_reproduction("polar_refused", job, &[], &["G1 @5 X3 F600", "G18 G1 @5 ^10", "G17 G53 G0 @5 ^10"], |a, _| {
        for l in ["G1 @5 X3 F600", "G18 G1 @5 ^10", "G17 G53 G0 @5 ^10"] {
            assert!(answer(a, l).error.as_ref().unwrap().contains("polar"), "{l}");
        }
    });
}

#[test]
fn g4_with_p_dwells_then_runs_the_spindle_and_the_move_of_its_line() {
    // LinuxCNC's program skeleton: with P on the line, S is the spindle speed.
    let job = "G0 X5 Y5\nG04 P.5 G0 X10 Y10 S1000 M3\nM400\n";
    run_reproduction("g4_skeleton", job, &[], &[], |a, vm| {
        assert!(vm.spindle_on(), "M3 on the G4 line");
        let duty = vm.spindle_duty();
        assert!((duty - 1000.0 / 10300.0).abs() < 0.01, "S1000 of 10300 rpm: duty {duty}");
        let t = answer(a, "G04 P.5 G0 X10 Y10 S1000 M3").secs;
        assert!(t >= 0.5, "the dwell before the move: {t} s");
    });
}

#[test]
fn g4_p_is_seconds_by_default_and_milliseconds_with_setting_153() {
    let job = "G4 P0.25\n$153=1\nG04 P400\nG4 S0.3\n$153=0\nM400\n";
    run_reproduction("g4_units", job, &[], &[], |a, _| {
        let t = answer(a, "G4 P0.25").secs;
        assert!((0.25..0.4).contains(&t), "P0.25 s: {t}");
        let t = answer(a, "G04 P400").secs;
        assert!((0.4..0.55).contains(&t), "P400 ms under $153=1: {t}");
        let t = answer(a, "G4 S0.3").secs;
        assert!((0.3..0.45).contains(&t), "S stays seconds: {t}");
    });
}

#[test]
fn percent_lines_with_text_report_only_codes_and_long_numbers_are_accepted() {
    let job = "% vfd enable\nG0 X5 Y5\nM31\nM62 P1\nG1 X24.985715729 Y1.23456789012 F600\nX1.234567\n%\nM400\n";
    run_reproduction("marker_codes_numbers", job, &[], &["M62 P1"], |a, _| {
        assert!(answer(a, "M31").other.iter().any(|l| l == "echo:Print time: 0s"), "{:?}", answer(a, "M31").other);
        let e = answer(a, "M62 P1").error.clone().unwrap();
        assert!(e.contains("M62-M65"), "{e}");
    });
}

#[test]
fn fractional_line_numbers_pass_and_words_no_code_uses_are_refused_as_linuxcnc_does() {
    let job = "G0 X5 Y5\nN4567.789 S1200\nG61 R0.5\nG38.2 F1\nG0 X6 I2\nG1 X7 Y6 F300\nG1 X8 P2\nG0 X9 H1\nM400\n";
    run_reproduction("unused_words", job, &[], &["G61 R0.5", "G38.2 F1", "G0 X6 I2", "G1 X8 P2", "G0 X9 H1"], |a, _| {
        assert_eq!(answer(a, "G61 R0.5").error.as_deref(), Some("Error:R word with no code that uses it"));
        assert_eq!(answer(a, "G0 X6 I2").error.as_deref(), Some("Error:I word with no code that uses it"));
        assert!(answer(a, "G38.2 F1").error.as_ref().unwrap().contains("all axes missing"));
    });
}
