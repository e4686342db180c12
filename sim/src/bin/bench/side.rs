//! The benchmark's side-by-side section: this firmware and the real
//! grbl-Mega 1.1g (`../shared/peers/grbl-mega/`, booted with
//! [`VmConfig::grbl_mega`]: its own pins and the two simavr workarounds its
//! ORIGIN.txt lists) in the same virtual machine, on the same job: the
//! 2,000 chords of 0.1 mm around a circle of radius 20 mm ([`circle`],
//! 18.5 bytes a line), at 100 steps/mm and 1000 mm/s² on both, the X/Y
//! rate limit raised to the feed on both. Each row is run on a freshly
//! booted VM of each firmware; rates are segments per second over the
//! middle half of the job (by time), from the tool's angle on the circle.
//!
//! Rows: send-response (one line in flight) and 254 bytes in flight, at
//! 250000 and at 115200 baud, F6000; CPU cycles per streamed line; the same
//! job from the SD card (this firmware only). *CPU cycles per streamed
//! line* = 16 MHz / the mid-job rate of the 254-byte stream at 250000 baud
//! with the feed and the X/Y acceleration raised ([`CPU_FEED`],
//! [`CPU_ACCEL`]) so that neither the feed nor the planner's stopping
//! distance holds the tool back: every cycle a line takes counts, busy or
//! waiting for the next byte, and the rate is the CPU's (down to the
//! wire's floor, shown as the row's wire limit). Each row carries its wire limit:
//! the lines per second the serial link itself allows, from the frame time
//! the VM's UART runs at ([`Vm::uart_frame_cycles`]: 10 bits a byte, as the
//! hardware sends 8N1) and the bytes a line needs on the wire (the line,
//! and for send-response also the reply it waits for). And its motion
//! limit ([`sim::ceiling`]): the fastest the job runs under grbl's planner
//! rules with unbounded look-ahead and CPU, which no firmware that plans
//! as grbl does can pass.

use super::{segment_rate, F_CPU};
use serde::Serialize;
use sim::ceiling::{self, Path as Joints};
use sim::host::prepare_gcode;
use sim::{circle, CardKind, FatKind, Flow, SdCard, SdImage, StreamOptions, Vm, VmConfig};
use std::path::{Path, PathBuf};

/// The feed of the side-by-side streams, mm/min.
pub const FEED: f64 = 6000.0;
/// Feed and acceleration of the CPU row: beyond what either firmware's
/// CPU allows on 0.1 mm lines. F12000 is 2,000 lines/s; at 5000 mm/s² the
/// 2.0 mm of 0.1 mm lines the 21-block planner holds ahead stop the tool
/// from 141 mm/s (1,414 lines/s, 11.3k cycles a line), grbl-Mega's 36
/// blocks from 187 mm/s. Not more: grbl-Mega stalls in simavr at 10000
/// mm/s² and above (it goes idle with blocks left; not investigated), and
/// crashes above ~44 kHz of steps (the move to the circle's start runs at
/// this feed).
pub const CPU_FEED: f64 = 12000.0;
pub const CPU_ACCEL: f64 = 5000.0;
/// The goal of the in-flight row at 250000 baud and of the SD job, lines/s.
const FAST_GOAL: f64 = 900.0;
/// The bytes kept in flight by the character-counting rows (grbl-Mega's RX
/// ring is 255 bytes).
const IN_FLIGHT: usize = 254;

/// Which firmware a run boots.
#[derive(Clone, Copy, PartialEq)]
pub enum Kind {
    Mill,
    Grbl,
}

/// One firmware build: what it is and where its ELF is.
#[derive(Clone)]
pub struct Fw {
    pub kind: Kind,
    pub elf: PathBuf,
}

/// How the job reaches the firmware.
#[derive(Clone, Copy, PartialEq)]
enum Feed {
    SendResponse,
    InFlight,
    Sd,
}

/// One measured run.
#[derive(Clone, Copy, Default, Serialize)]
pub struct Run {
    /// Segments per second over the middle half of the job.
    pub per_s: f64,
    /// Lines per second the serial link allows (0 from SD).
    pub wire_per_s: f64,
    /// Errors the firmware answered during the job.
    pub errors: usize,
}

/// One row of the section, for the table and the JSON.
#[derive(Serialize)]
pub struct Row {
    pub what: String,
    pub grbl: Option<f64>,
    pub ours: f64,
    /// ours / grbl.
    pub ratio: Option<f64>,
    pub wire_limit: Option<f64>,
    /// The job's motion limit under grbl's planner rules ([`ceiling`]).
    pub motion_limit: Option<f64>,
    pub goal: String,
    pub pass: bool,
}

/// `../shared/peers/grbl-mega/` next to the repository.
pub fn default_grbl_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/peers/grbl-mega")
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Sends a line and waits for its reply; `error` or `Error` fails.
fn cmd(vm: &mut Vm, line: &str) -> Result<(), String> {
    let r = vm.command_timeout(line, 120.0).map_err(|e| format!("{line}: {e}"))?;
    match r.iter().find(|l| l.starts_with("Error") || l.starts_with("error")) {
        Some(e) => Err(format!("{line}: {e}")),
        None => Ok(()),
    }
}

/// Boots `fw`, sets 100 steps/mm, `accel` mm/s² and an X/Y rate limit of
/// at least `feed` (mm/min), and brings the tool to the circle's start at
/// `feed`, waiting there.
fn boot(fw: &Fw, feed: f64, accel: f64) -> Result<Vm, String> {
    match fw.kind {
        Kind::Mill => {
            let mut cfg = VmConfig::new(&fw.elf);
            cfg.machine.travel_steps = [None; 4];
            cfg.machine.initial_position = [100, 100, 100, 0];
            let mut vm = Vm::new(cfg).map_err(err)?;
            vm.wait_banner().map_err(err)?;
            cmd(&mut vm, "M999")?;
            if accel != 1000.0 {
                cmd(&mut vm, &format!("M201 X{accel} Y{accel}"))?;
            }
            for l in circle::setup(feed) {
                cmd(&mut vm, &l)?;
            }
            Ok(vm)
        }
        Kind::Grbl => {
            let mut cfg = VmConfig::grbl_mega(&fw.elf);
            cfg.machine.travel_steps = [None; 4];
            let mut vm = Vm::new(cfg).map_err(err)?;
            vm.wait_line(|l| l.starts_with("Grbl 1.1"), 3.0).map_err(err)?;
            vm.run_for(0.2).map_err(err)?;
            vm.take_lines();
            let rate = feed.max(5000.0);
            for s in [
                "$100=100".to_string(),
                "$101=100".into(),
                "$102=100".into(),
                format!("$110={rate}"),
                format!("$111={rate}"),
                "$112=5000".into(),
                format!("$120={accel}"),
                format!("$121={accel}"),
                "$122=1000".into(),
            ] {
                cmd(&mut vm, &s)?;
            }
            let (x0, y0) = circle::point(0);
            cmd(&mut vm, &format!("G1 X{x0:.3} Y{y0:.3} F{feed}"))?;
            // G4 waits for the motion in grbl (M400 is not a grbl code).
            cmd(&mut vm, "G4 P0.01")?;
            Ok(vm)
        }
    }
}

/// Runs the job on `fw` and measures it.
fn run(fw: &Fw, how: Feed, feed: f64, accel: f64) -> Result<Run, String> {
    let mut vm = boot(fw, feed, accel)?;
    vm.recorder_mut().clear_trace();
    let (x0, y0) = circle::point(0);
    let p0 = vm.positions();
    let centre = (p0[0] as f64 - (x0 - circle::CENTRE.0) * 100.0, p0[1] as f64 - (y0 - circle::CENTRE.1) * 100.0);
    let lines = prepare_gcode(&circle::moves().join("\n"));
    let line_bytes = lines.iter().map(|l| l.len() + 1).sum::<usize>() as f64 / lines.len() as f64;
    let out0 = vm.output_bytes().len();
    let errors = match how {
        Feed::Sd => {
            let text = lines.join("\n") + "\n";
            vm.insert_sd(SdCard::new(SdImage::new(FatKind::Fat16).file("BENCH.NC", text.as_bytes()).build(), CardKind::Sdhc));
            cmd(&mut vm, "M23 BENCH.NC")?;
            vm.send_line("M24");
            vm.wait_line(|l| l == "Done printing file", 120.0).map_err(|e| format!("SD job: {e}"))?;
            vm.take_lines().iter().filter(|l| l.starts_with("Error")).count()
        }
        _ => {
            let flow = if how == Feed::SendResponse { Flow::PingPong } else { Flow::CharCount(IN_FLIGHT) };
            let rep = vm.stream(&lines, StreamOptions::new(flow).timeout(120.0)).map_err(err)?;
            if rep.timed_out {
                return Err("stream timed out".into());
            }
            rep.errors.len()
        }
    };
    let reply_bytes = (vm.output_bytes().len() - out0) as f64 / lines.len() as f64;
    cmd(&mut vm, if fw.kind == Kind::Mill { "M400" } else { "G4 P0.01" })?;
    vm.run_for(0.01).map_err(err)?;
    // The whole path ran: the tool is at the last target (to a step).
    let (x1, y1) = circle::point(circle::MOVES);
    let want = [p0[0] as f64 + (x1 - x0) * 100.0, p0[1] as f64 + (y1 - y0) * 100.0];
    let at = vm.positions();
    if (at[0] as f64 - want[0]).abs() > 1.0 || (at[1] as f64 - want[1]).abs() > 1.0 {
        return Err(format!("the tool stopped at steps {:?}, not at the job's end {want:?}", &at[..2]));
    }
    let wire_bytes = match how {
        Feed::SendResponse => line_bytes + reply_bytes,
        Feed::InFlight => line_bytes,
        Feed::Sd => 0.0,
    };
    let wire_per_s = if wire_bytes > 0.0 { F_CPU / (vm.uart_frame_cycles() as f64 * wire_bytes) } else { 0.0 };
    let per_s = segment_rate(&vm, p0, centre, circle::chord_angle(), 0.25, 0.75);
    Ok(Run { per_s, wire_per_s, errors })
}

/// The builds the section runs.
pub struct Builds {
    pub mill_250000: PathBuf,
    pub mill_115200: PathBuf,
    pub grbl_dir: PathBuf,
    /// Feed (mm/min) and X/Y acceleration (mm/s²) of the CPU row.
    pub cpu_feed: f64,
    pub cpu_accel: f64,
}

/// Runs every row for both firmwares (the SD row for this one only).
/// A run that fails is reported in `failures` and its row shows 0.
pub fn measure(b: &Builds, failures: &mut Vec<String>) -> Vec<Row> {
    let mill = |elf: &PathBuf| Fw { kind: Kind::Mill, elf: elf.clone() };
    let grbl = |baud: u32| Fw { kind: Kind::Grbl, elf: b.grbl_dir.join(format!("grbl-mega-{baud}.elf")) };
    let mut one = |name: &str, fw: &Fw, how: Feed, feed: f64, accel: f64| -> Run {
        let who = if fw.kind == Kind::Mill { "this firmware" } else { "grbl-Mega" };
        eprintln!("bench: side by side, {name}, {who} ...");
        match run(fw, how, feed, accel) {
            Ok(r) if r.errors == 0 => r,
            Ok(r) => {
                failures.push(format!("{name}, {who}: {} errors", r.errors));
                r
            }
            Err(e) => {
                failures.push(format!("{name}, {who}: {e}"));
                Run::default()
            }
        }
    };
    let mut rows = Vec::new();
    let streams = [
        ("send-response, 250000 baud, F6000", 250_000, Feed::SendResponse, 600.0),
        ("254 B in flight, 250000 baud, F6000", 250_000, Feed::InFlight, FAST_GOAL),
        ("send-response, 115200 baud, F6000", 115_200, Feed::SendResponse, 320.0),
        ("254 B in flight, 115200 baud, F6000", 115_200, Feed::InFlight, 520.0),
    ];
    for (name, baud, how, goal) in streams {
        let ours_elf = if baud == 250_000 { &b.mill_250000 } else { &b.mill_115200 };
        let g = one(name, &grbl(baud), how, FEED, 1000.0);
        let m = one(name, &mill(ours_elf), how, FEED, 1000.0);
        let ratio = if g.per_s > 0.0 { Some(m.per_s / g.per_s) } else { None };
        rows.push(Row {
            what: name.into(),
            grbl: Some(g.per_s),
            ours: m.per_s,
            ratio,
            wire_limit: Some(m.wire_per_s),
            motion_limit: Some(ceiling::lines_per_s(FEED, 1000.0, Joints::Steps)),
            goal: format!(">= {goal:.0}/s, ahead"),
            pass: m.per_s >= goal && m.per_s > g.per_s,
        });
    }
    // CPU: the 254-byte stream at 250000 with the feed and acceleration out
    // of the way; 16 MHz / lines per second.
    let name = &format!("CPU cycles per line (F{:.0}, {:.0} mm/s²)", b.cpu_feed, b.cpu_accel);
    let g = one(name, &grbl(250_000), Feed::InFlight, b.cpu_feed, b.cpu_accel);
    let m = one(name, &mill(&b.mill_250000), Feed::InFlight, b.cpu_feed, b.cpu_accel);
    let cycles = |r: &Run| if r.per_s > 0.0 { F_CPU / r.per_s } else { 0.0 };
    let (gc, mc) = (cycles(&g), cycles(&m));
    rows.push(Row {
        what: name.into(),
        grbl: Some(gc),
        ours: mc,
        ratio: if gc > 0.0 { Some(mc / gc) } else { None },
        // The fewest cycles a line this stream can show: the wire's.
        wire_limit: Some(if m.wire_per_s > 0.0 { F_CPU / m.wire_per_s } else { 0.0 }),
        // And the motion's: the fewest cycles a line this feed allows.
        motion_limit: Some(F_CPU / ceiling::lines_per_s(b.cpu_feed, b.cpu_accel, Joints::Steps)),
        goal: "<= 16000, ahead".into(),
        pass: mc > 0.0 && mc <= 16_000.0 && mc < gc,
    });
    let name = "SD job, F6000";
    let m = one(name, &mill(&b.mill_250000), Feed::Sd, FEED, 1000.0);
    rows.push(Row {
        what: name.into(),
        grbl: None,
        ours: m.per_s,
        ratio: None,
        wire_limit: None,
        motion_limit: Some(ceiling::lines_per_s(FEED, 1000.0, Joints::Steps)),
        goal: format!(">= {FAST_GOAL:.0}/s"),
        pass: m.per_s >= FAST_GOAL,
    });
    rows
}

/// Prints the section's table.
pub fn print(rows: &[Row]) {
    println!();
    println!("Side by side with grbl-Mega 1.1g (same VM, same job: 2,000 chords of 0.1 mm, R20 circle, 18.5 B a line; mid-job rates)");
    println!();
    println!(
        "| {:<40} | {:>9} | {:>13} | {:>9} | {:>10} | {:>12} | {:<16} | {:<4} |",
        "row", "grbl-Mega", "this firmware", "ours/grbl", "wire limit", "motion limit", "goal", ""
    );
    println!(
        "|{}|{}|{}|{}|{}|{}|{}|{}|",
        "-".repeat(42),
        "-".repeat(11),
        "-".repeat(15),
        "-".repeat(11),
        "-".repeat(12),
        "-".repeat(14),
        "-".repeat(18),
        "-".repeat(6)
    );
    for r in rows {
        let cpu = r.what.starts_with("CPU");
        let fmt = |v: f64| if cpu { format!("{:.1}k", v / 1000.0) } else { format!("{v:.0}/s") };
        let grbl = r.grbl.map_or("—".to_string(), fmt);
        let ratio = r.ratio.map_or("—".to_string(), |v| format!("{v:.2}"));
        let limit = |l: Option<f64>| match l {
            None => "—".to_string(),
            Some(v) if cpu => format!(">= {:.1}k", v / 1000.0),
            Some(v) => format!("{v:.0}/s"),
        };
        let (wire, motion) = (limit(r.wire_limit), limit(r.motion_limit));
        let v = if r.pass { "ok" } else { "MISS" };
        println!(
            "| {:<40} | {:>9} | {:>13} | {:>9} | {:>10} | {:>12} | {:<16} | {:<4} |",
            r.what,
            grbl,
            fmt(r.ours),
            ratio,
            wire,
            motion,
            r.goal,
            v
        );
    }
    println!();
    println!(
        "Motion limit: the job's fastest under grbl's planner rules with unbounded look-ahead and CPU, joints from the chords' step deltas (grbl, Marlin, this firmware): {:.0}/s at F6000; with joints from the commanded chords (LinuxCNC): {:.0}/s.",
        ceiling::lines_per_s(FEED, 1000.0, Joints::Steps),
        ceiling::lines_per_s(FEED, 1000.0, Joints::Commanded)
    );
    let ahead = ceiling::RING_AHEAD;
    let need = |j| ceiling::ahead_for(FEED, 1000.0, j, FAST_GOAL).map_or(format!("none up to {}", ceiling::MAX_AHEAD), |a| a.to_string());
    println!(
        "With this firmware's look-ahead ({ahead} chords ahead of the running one): {:.1}/s with the step joints, {:.1}/s with the commanded ones. Chords ahead for {:.0}/s: {} with the step joints, {} with the commanded ones.",
        ceiling::lines_per_s_ahead(FEED, 1000.0, Joints::Steps, ahead),
        ceiling::lines_per_s_ahead(FEED, 1000.0, Joints::Commanded, ahead),
        FAST_GOAL,
        need(Joints::Steps),
        need(Joints::Commanded)
    );
}
