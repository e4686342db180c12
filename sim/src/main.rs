//! `sim`: run a G-code job on the firmware in the virtual machine.
//!
//! ```text
//! cargo run -p sim --release -- [--elf PATH] [--json out/report.json] [--csv out/trace.csv] [--png out/toolpath.png] [--oled out/oled.png]
//!                               [--checksums] [--flow pingpong|count:N] [--timeout SECONDS] [JOB.gcode]
//! cargo run -p sim --release -- --pty [LINK] [--idle-exit SECONDS] [--elf PATH] [--json FILE] [--csv FILE]
//!                               [--blank] [--no-auto-reset]
//! either with [--switches ideal|HYSTERESIS_MM,BOUNCE_MS] [--bootloader [HEX]]
//! ```
//!
//! With `--pty`, no job is streamed: UART0 becomes a pseudo-terminal (its path
//! is printed; with LINK, e.g. `/tmp/millsim`, a symlink to it too) and a real
//! sender connects to it at any baud rate. The machine runs in real time until
//! Ctrl-C, or until nothing happened for `--idle-exit` seconds (no byte either
//! way, no firmware output, no step); then the report is printed as for a job.
//! Opening the port resets the board, as the Mega2560's DTR auto-reset
//! does (`--no-auto-reset`: a board whose RESET-EN jumper is cut).
//! `--bootloader` runs the stock Mega2560 bootloader (`sim::boot`: Debian's
//! `arduino-core-avr` hex, or HEX) in front of the firmware, as on a board
//! as sold: avrdude (`tools/flash PORT`) can then flash the virtual board
//! through the port; `--blank` starts with only the bootloader in flash.
//!
//! `--switches` sets the home switches: `ideal`, or hysteresis (mm) and
//! contact bounce (ms), e.g. `0.1,5`. Default: `sim::SwitchConfig::default()`
//! (0.05 mm, 3 ms).
//!
//! Boots the ELF, waits for `start`, streams the job (default
//! `sim/jobs/demo.gcode`), sends `M400` and waits for its `ok`, settles
//! 100 ms, prints the report and writes the JSON/CSV. Exit code 1 if there
//! were violations, a crash or a timeout; 2 on bad usage or a load error.

use sim::host::prepare_gcode;
use sim::{Flow, StreamOptions, Vm, VmConfig};
use std::path::PathBuf;
use std::process::ExitCode;

struct Args {
    elf: Option<PathBuf>,
    json: Option<PathBuf>,
    csv: Option<PathBuf>,
    png: Option<PathBuf>,
    /// `--oled FILE`: the OLED at the end of the job, as a PNG.
    oled: Option<PathBuf>,
    checksums: bool,
    flow: Flow,
    timeout_s: f64,
    job: PathBuf,
    /// `--pty [LINK]`: Some(None) for a pty without a link.
    pty: Option<Option<PathBuf>>,
    idle_exit_s: Option<f64>,
    switches: sim::SwitchConfig,
    /// `--bootloader [HEX]`: Some(None) for the default hex.
    bootloader: Option<Option<PathBuf>>,
    /// `--blank`: only the bootloader in flash.
    blank: bool,
    /// `--no-auto-reset`: opening the port does not reset the board.
    no_auto_reset: bool,
}

const USAGE: &str = "usage: sim [--elf PATH] [--json FILE] [--csv FILE] [--png FILE] [--oled FILE] [--checksums] \
[--flow pingpong|count:N] [--timeout SECONDS] [JOB.gcode]\n       \
sim --pty [LINK] [--idle-exit SECONDS] [--elf PATH] [--json FILE] [--csv FILE]\n       \
    [--blank] [--no-auto-reset]\n       \
either with [--switches ideal|HYSTERESIS_MM,BOUNCE_MS] [--bootloader [HEX]]";

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        elf: None,
        json: None,
        csv: None,
        png: None,
        oled: None,
        checksums: false,
        flow: Flow::PingPong,
        timeout_s: 600.0,
        job: PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("jobs/demo.gcode"),
        pty: None,
        idle_exit_s: None,
        switches: sim::SwitchConfig::default(),
        bootloader: None,
        blank: false,
        no_auto_reset: false,
    };
    let mut it = std::env::args().skip(1).peekable();
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match arg.as_str() {
            "--elf" => a.elf = Some(value("--elf")?.into()),
            "--json" => a.json = Some(value("--json")?.into()),
            "--csv" => a.csv = Some(value("--csv")?.into()),
            "--png" => a.png = Some(value("--png")?.into()),
            "--oled" => a.oled = Some(value("--oled")?.into()),
            "--checksums" => a.checksums = true,
            "--flow" => a.flow = value("--flow")?.parse()?,
            "--timeout" => {
                a.timeout_s = value("--timeout")?.parse().map_err(|e| format!("--timeout: {e}"))?;
            }
            "--pty" => {
                let link = it.next_if(|v| !v.starts_with("--")).map(PathBuf::from);
                a.pty = Some(link);
            }
            "--idle-exit" => {
                a.idle_exit_s = Some(value("--idle-exit")?.parse().map_err(|e| format!("--idle-exit: {e}"))?);
            }
            "--switches" => a.switches = parse_switches(&value("--switches")?)?,
            "--bootloader" => a.bootloader = Some(it.next_if(|v| v.ends_with(".hex")).map(PathBuf::from)),
            "--blank" => a.blank = true,
            "--no-auto-reset" => a.no_auto_reset = true,
            "-h" | "--help" => return Err(USAGE.to_string()),
            s if s.starts_with("--") => return Err(format!("unknown option {s}\n{USAGE}")),
            s => a.job = PathBuf::from(s),
        }
    }
    Ok(a)
}

/// `ideal` or `HYSTERESIS_MM,BOUNCE_MS`.
fn parse_switches(v: &str) -> Result<sim::SwitchConfig, String> {
    if v == "ideal" {
        return Ok(sim::SwitchConfig::ideal());
    }
    let bad = || format!("--switches: `ideal` or HYSTERESIS_MM,BOUNCE_MS, not {v}");
    let (h, b) = v.split_once(',').ok_or_else(bad)?;
    let h: f64 = h.trim().parse().map_err(|_| bad())?;
    let b: f64 = b.trim().parse().map_err(|_| bad())?;
    if !(0.0..=5.0).contains(&h) || !(0.0..=100.0).contains(&b) {
        return Err(bad());
    }
    Ok(sim::SwitchConfig::home_switches(h, b / 1000.0))
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    if let Some(link) = args.pty.clone() {
        return run_pty(&args, link);
    }
    let text = match std::fs::read_to_string(&args.job) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("cannot read {}: {e}", args.job.display());
            return ExitCode::from(2);
        }
    };
    let lines = prepare_gcode(&text);
    let mut config = demo_machine();
    config.machine.switches = args.switches;
    if let Some(elf) = args.elf {
        config.elf = elf;
    }
    if let Some(hex) = &args.bootloader {
        config.bootloader = Some(hex.clone().unwrap_or_else(sim::boot::default_hex_path));
    }
    let mut vm = match Vm::new(config) {
        Ok(vm) => vm,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };

    println!(
        "job: {} ({} lines), flow {:?}{}",
        args.job.display(),
        lines.len(),
        args.flow,
        if args.checksums { ", checksums" } else { "" }
    );
    let mut failure: Option<String> = None;
    let mut job = None;
    match vm.wait_for_start(5.0) {
        Err(e) => failure = Some(format!("no `start` from the firmware: {e}")),
        Ok(_) => {
            let opts = StreamOptions::new(args.flow).with_checksums(args.checksums).timeout(args.timeout_s);
            match vm.stream(&lines, opts) {
                Err(e) => failure = Some(e.to_string()),
                Ok(mut r) => {
                    if !r.timed_out {
                        // Wait for the motion queue to drain, then settle.
                        let left = (args.timeout_s - r.duration_s).max(1.0);
                        match vm.command_timeout("M400", left) {
                            Ok(_) => {
                                r.end_s = vm.seconds();
                                r.duration_s = r.end_s - r.start_s;
                                if let Err(e) = vm.run_for(0.1) {
                                    failure = Some(e.to_string());
                                }
                            }
                            Err(e) => failure = Some(format!("M400: {e}")),
                        }
                    }
                    job = Some(r);
                }
            }
        }
    }

    let mut report = vm.report(job.as_ref());
    if let Some(f) = &failure {
        if !report.errors.contains(f) {
            report.errors.push(f.clone());
        }
    }
    print!("{}", report.human());
    if let Some(j) = &job {
        for e in j.errors.iter().take(10) {
            println!("{:<22}{e}", "firmware error");
        }
    }
    print_job_summary(&vm);
    if let Some(p) = &args.json {
        if let Err(e) = report.write_json(p) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
        println!("{:<22}{}", "json", p.display());
    }
    if let Some(p) = &args.oled {
        // Let the display catch up with the end of the job (frames are 200 ms apart).
        let _ = vm.run_for(0.3);
        if let Err(e) = vm.screenshot(p, 2) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
        println!("{:<22}{}", "oled", p.display());
    }
    if let Some(p) = &args.csv {
        if let Err(e) = vm.write_trace_csv(p) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
        println!("{:<22}{}", "csv", p.display());
    }
    if let Some(p) = &args.png {
        let commanded = sim::plot::commanded_path(&lines);
        let recorded = sim::plot::recorded_path(&vm);
        if let Err(e) = sim::plot::write_toolpath_png(p, &commanded, &recorded) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
        println!("{:<22}{}", "toolpath", p.display());
    }
    if report.clean() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

/// `--pty`: bridge UART0 to a pseudo-terminal until idle or Ctrl-C.
fn run_pty(args: &Args, link: Option<PathBuf>) -> ExitCode {
    let mut config = demo_machine();
    config.machine.switches = args.switches;
    if let Some(elf) = &args.elf {
        config.elf = elf.clone();
    }
    if let Some(hex) = &args.bootloader {
        config.bootloader = Some(hex.clone().unwrap_or_else(sim::boot::default_hex_path));
    }
    config.blank_application = args.blank;
    let mut vm = match Vm::new(config) {
        Ok(vm) => vm,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    let bridge = match sim::pty::PtyBridge::open(&vm, link.as_deref()) {
        Ok(b) => b.realtime(true).fast_while_busy(true).auto_reset(!args.no_auto_reset),
        Err(e) => {
            eprintln!("cannot open a pty: {e}");
            return ExitCode::from(2);
        }
    };
    let mut bridge = bridge;
    println!("pty: {} (connect a sender at any baud; Ctrl-C to stop)", bridge.port().display());
    let mut last_traffic = std::time::Instant::now();
    let mut failure = None;
    loop {
        // Activity: bytes either way, any firmware output (a `busy:` line
        // during a long drain) or steps (a silent drain still moving).
        match bridge.pump_activity(&mut vm, 0.002) {
            Ok(a) if a.any() => last_traffic = std::time::Instant::now(),
            Ok(_) => {}
            Err(e) => {
                failure = Some(e.to_string());
                break;
            }
        }
        if args.idle_exit_s.is_some_and(|s| last_traffic.elapsed().as_secs_f64() > s) {
            break;
        }
    }
    let mut report = vm.report(None);
    if let Some(f) = failure {
        report.errors.push(f);
    }
    print!("{}", report.human());
    println!("{:<22}{} bytes from the sender, {} to it", "pty", bridge.bytes_in, bridge.bytes_out);
    if let Some(p) = &args.json {
        if let Err(e) = report.write_json(p) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
    }
    if let Some(p) = &args.csv {
        if let Err(e) = vm.write_trace_csv(p) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
    }
    if report.clean() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

/// The machine the CLI simulates: the default RAMPS machine, the 12-pocket
/// changer loaded with its default tools (tool n: 18 + 1.5 n mm long,
/// 1 + 0.5 n mm across) and an optical tool setter beam at the firmware's
/// default setter position (X 3–7, Y 10, tip height 48 mm, 0.52 mm wide).
fn demo_machine() -> VmConfig {
    let mut config = VmConfig::default();
    config.command_timeout_s = 300.0;
    config.machine.tool_setter = sim::ToolSetter::Optical(sim::OpticalBeam::demo());
    config
}

/// Tool changes, measurements and warnings, from what the firmware printed.
fn print_job_summary(vm: &Vm) {
    let log = vm.line_log();
    let changes: Vec<&str> = log.iter().filter_map(|(_, l)| l.strip_prefix("NowSelectedTool:")).collect();
    println!("{:<22}{} ({})", "tool changes", changes.len(), changes.iter().map(|t| format!("T{t}")).collect::<Vec<_>>().join(" -> "));
    for (_, l) in log.iter().filter(|(_, l)| l.starts_with("[TOOL:") || l.starts_with("[SETTER")) {
        println!("{:<22}{l}", "measured");
    }
    let warnings: Vec<&String> = log.iter().map(|(_, l)| l).filter(|l| l.starts_with("echo:warning") || l.starts_with("ALARM")).collect();
    println!("{:<22}{}", "warnings", warnings.len());
    for w in warnings.iter().take(10) {
        println!("{:<22}{w}", "");
    }
    let atc = vm.atc();
    println!(
        "{:<22}spindle {}, pockets {:?}, {} collisions",
        "tool changer",
        atc.spindle.map_or("empty".to_string(), |t| format!("T{}", t.id)),
        atc.pocket_ids(),
        atc.collisions.len()
    );
}
