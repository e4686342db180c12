//! The G-code dialect as third-party files write it, on the real ELF in the
//! virtual machine: a byte-order mark and UTF-8 comment text, `*` inside a
//! comment, `$` lines with a comment, a tool number past the pockets, long
//! comments, and cutter radius compensation (G41/G42). Each file style runs
//! over serial and from the SD card where the two differ.

mod common;
#[path = "common/motion.rs"]
mod motion_util;
use common::*;
use sim::{Axis, CardKind, FatKind, SdCard, SdImage, Vm};

/// Boot and lift the homing lock (M999), output cleared.
fn unlocked() -> Vm {
    let mut vm = boot();
    ok(&mut vm, "M999");
    vm.take_lines();
    vm
}

/// Boot unlocked with a FAT16 card holding `files`.
fn with_card(files: &[(&str, &[u8])]) -> Vm {
    let mut vm = unlocked();
    let mut img = SdImage::new(FatKind::Fat16);
    for (n, d) in files {
        img = img.file(n, d);
    }
    vm.insert_sd(SdCard::new(img.build(), CardKind::Sdhc));
    vm
}

/// Steps moved since `p0`.
fn moved(vm: &Vm, p0: [i64; 4]) -> [i64; 4] {
    let p = steps(vm);
    [p[0] - p0[0], p[1] - p0[1], p[2] - p0[2], p[3] - p0[3]]
}

/// Send raw bytes and a newline; the reply lines up to and with `ok`.
fn command_bytes(vm: &mut Vm, bytes: &[u8]) -> Vec<String> {
    vm.take_lines();
    vm.send(bytes);
    vm.send(b"\n");
    vm.run_until(|vm| vm.pending_lines().iter().any(|l| l == "ok"), 5.0).unwrap();
    vm.take_lines()
}

/// Run an SD file to its end; every line the firmware printed meanwhile.
fn run_sd(vm: &mut Vm, name: &str, timeout_s: f64) -> Vec<String> {
    ok(vm, &format!("M23 {name}"));
    ok(vm, "M24");
    vm.wait_line(|l| l == "Done printing file" || l.contains("SD job ended"), timeout_s)
        .unwrap_or_else(|e| panic!("{e}; output:\n{}", vm.output()));
    vm.run_for(0.5).unwrap();
    vm.take_lines();
    ok(vm, "M400");
    vm.output().lines().map(str::to_string).collect()
}

/// `N<n> <cmd>*<xor>`.
fn numbered(n: i32, cmd: &str) -> String {
    let body = format!("N{n} {cmd}");
    format!("{body}*{}", checksum(&body))
}

// ------------------------------------------------ byte-order mark, UTF-8

#[test]
fn a_file_saved_on_windows_with_a_byte_order_mark_runs_from_sd() {
    let job = "\u{feff}G21 G90\n(Ø3 end mill)\nG1 X5 F600 ; Ø3 fräsen\nG1 X0\n";
    let mut vm = with_card(&[("BOM.NC", job.as_bytes())]);
    let p0 = steps(&vm);
    let out = run_sd(&mut vm, "BOM.NC", 20.0);
    assert!(out.iter().any(|l| l == "Done printing file"), "{out:?}");
    assert!(!out.iter().any(|l| l.starts_with("Error")), "{out:?}");
    let s = vm.recorder().axis_stats(Axis::X);
    assert_eq!((s.steps_pos, s.steps_neg), (500, 500));
    assert_eq!(moved(&vm, p0), [0; 4]);
}

#[test]
fn a_byte_order_mark_and_utf8_comment_text_over_serial_are_text() {
    let mut vm = unlocked();
    let p0 = steps(&vm);
    let r = command_bytes(&mut vm, b"\xEF\xBB\xBFG21 G90 G1 X5 F600");
    assert_eq!(r, ["ok"], "the mark is text, not data");
    let r = command_bytes(&mut vm, "G1 X2 (Ø3 end mill) ; Größe".as_bytes());
    assert_eq!(r, ["ok"], "UTF-8 inside comments is text");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 200);
    // Outside a comment, on a line without a number (a grbl sender, a
    // terminal), the receive interrupt takes every byte from 0x80 up out
    // of the stream as grbl does (realtime commands, cncjs's UTF-8 `C2 91`):
    // the line runs without it.
    let r = command_bytes(&mut vm, "G1 X4 Ø".as_bytes());
    assert_eq!(r, ["ok"], "{r:?}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 400);
    // A numbered line (a Marlin host) reaches the line assembler whole:
    // there it is refused, and nothing moves.
    ok(&mut vm, &numbered(0, "M110 N0"));
    let line = numbered(1, "G1 X6 Ø");
    vm.take_lines();
    vm.send(line.as_bytes());
    vm.send(b"\n");
    vm.run_until(|vm| vm.pending_lines().iter().any(|l| l.starts_with("ok")), 5.0).unwrap();
    let r = vm.take_lines();
    assert!(r.iter().any(|l| l.starts_with("Error")), "{r:?}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 400);
}

// ------------------------------------------------ `*` inside a comment

#[test]
fn a_star_inside_a_comment_is_text_not_a_checksum() {
    let mut vm = unlocked();
    let p0 = steps(&vm);
    let r = ok(&mut vm, "G0 X5 ( *** move *** )");
    assert!(!r.iter().any(|l| l.starts_with("Resend")), "{r:?}");
    ok(&mut vm, "G0 X3 ; ** done **");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 300);
    // Numbered and checksummed, the same line still checks.
    ok(&mut vm, &numbered(0, "M110 N0"));
    let r = ok(&mut vm, &numbered(1, "G0 X1 ( *** move *** )"));
    assert!(!r.iter().any(|l| l.starts_with("Resend")), "{r:?}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 100);
    // A bad checksum after such a comment is still caught.
    let bad = format!("N2 G0 X9 (a*b)*{}", checksum("N2 G0 X9 (a*b)") ^ 1);
    let r = vm.command(&bad).unwrap();
    assert!(r.iter().any(|l| l.starts_with("Resend:2")), "{r:?}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 100);
}

// ------------------------------------------------ `$` lines with a comment

#[test]
fn dollar_lines_with_a_comment_run_as_gcodetools_writes_them() {
    let mut vm = unlocked();
    let r = ok(&mut vm, "$I ; build info");
    assert!(r.iter().any(|l| l.starts_with("[VER:")), "{r:?}");
    let r = ok(&mut vm, "$$ ; settings");
    assert!(r.iter().any(|l| l.starts_with("$100=")), "{r:?}");
    let r = ok(&mut vm, "$G (modal state)");
    assert!(r.iter().any(|l| l.starts_with("[GC:")), "{r:?}");
    // A setting with a comment is set; a bad one is still refused.
    ok(&mut vm, "$110=4000 ; X max rate");
    assert!(ok(&mut vm, "$$").iter().any(|l| l.starts_with("$110=4000")));
    let e = refused(&mut vm, "$110=abc ; nonsense");
    assert!(e.starts_with("Error:"), "{e}");
}

// ------------------------------------------------ tool numbers the table lacks

#[test]
fn a_tool_the_tool_table_lacks_is_refused_naming_the_tool_and_how_to_add_it() {
    let mut vm = unlocked();
    let p0 = steps(&vm);
    let e = refused(&mut vm, "T15 M6");
    assert!(e.contains("tool T15 not in the tool table: G10 L1 P15 Q<pocket> assigns it"), "{e}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0), [0; 4]);
    // From SD the job stops at that line, before any cut.
    let job = "G21 G90\nT15 M6\nM3 S5000\nG1 X5 F600\nM5\n";
    let mut vm = with_card(&[("T15.NC", job.as_bytes())]);
    let p0 = steps(&vm);
    let out = run_sd(&mut vm, "T15.NC", 10.0);
    assert!(out.iter().any(|l| l.contains("tool T15 not in the tool table")), "{out:?}");
    assert!(!out.iter().any(|l| l == "Done printing file"), "{out:?}");
    assert_eq!(moved(&vm, p0), [0; 4]);
    assert!(!vm.spindle_on());
}

// ------------------------------------------------ long comments

/// A Fusion 360 style header line: `; ` and a part description, `len` long.
fn long_comment_line(code: &str, len: usize) -> String {
    let mut l = format!("{code} ; ");
    while l.len() < len {
        l.push_str("Part 4711 rev C ");
    }
    l.truncate(len);
    l
}

#[test]
fn a_300_character_line_that_is_mostly_comment_runs_over_serial_and_from_sd() {
    let mut vm = unlocked();
    let p0 = steps(&vm);
    ok(&mut vm, &long_comment_line("G21 G90 G1 X4 F600", 300));
    let paren = format!("G1 X2 ({}) Y1", "d".repeat(290));
    ok(&mut vm, &paren);
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[..2], [200, 100]);
    // The code part keeps its limit: 257 characters of code are refused.
    let code = format!("G1 X1 ({}) Y1{}", "d".repeat(290), "0".repeat(256));
    let e = refused(&mut vm, &code);
    assert!(e.contains("too long"), "{e}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[..2], [200, 100]);

    let job = format!("{}\nG1 X4 F600\n{paren}\nG1 X0 Y0\n", long_comment_line("G21 G90", 300));
    let mut vm = with_card(&[("LONG.NC", job.as_bytes())]);
    let p0 = steps(&vm);
    let out = run_sd(&mut vm, "LONG.NC", 20.0);
    assert!(out.iter().any(|l| l == "Done printing file"), "{out:?}");
    let s = vm.recorder().axis_stats(Axis::X);
    assert_eq!((s.steps_pos, s.steps_neg), (400, 400));
    assert_eq!(moved(&vm, p0), [0; 4]);
}

// ------------------------------------------------ cutter radius compensation

mod comp {
    use super::*;
    use crate::motion_util::{boot_homed, dist_to_segment, events, mark, xyz, xyz_now, SPMM};
    use std::io::Write;
    use std::process::{Command, Stdio};

    /// The issue's reproduction: a G41 entry, a G3 on the inside, an outside
    /// corner into a line, and a G40 exit.
    pub const EXAMPLE: &str = "G21 G90 G17\nG0 X10 Y10 Z-10\nG1 Z-12 F100\nG41 X12 Y10 D1\nG3 X14 Y12 I0 J2\nG1 X20\nG40 X25\n";

    /// The tool-centre path of `job` from `start` (work mm, +Z up) by the
    /// independent reference (tests/comp_reference.py), in physical steps.
    pub fn reference(job: &str, radii: &str, start: [f64; 3]) -> Vec<[f64; 3]> {
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/comp_reference.py");
        let mut child = Command::new("python3")
            .arg(script)
            .arg(radii)
            .args(start.map(|v| v.to_string()))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("python3 runs");
        child.stdin.take().unwrap().write_all(job.as_bytes()).unwrap();
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "reference failed: {}", String::from_utf8_lossy(&out.stderr));
        let pts: Vec<[f64; 3]> = serde_json::from_slice(&out.stdout).unwrap();
        pts.iter().map(|p| [p[0] * SPMM, p[1] * SPMM, -p[2] * SPMM]).collect()
    }

    /// Every step event since the last mark within `max_dev` steps of the
    /// reference polyline, followed in order to its end, ending exactly on
    /// its last point. Returns the largest deviation, steps.
    pub fn check_against(vm: &Vm, reference: &[[f64; 3]], max_dev: f64) -> f64 {
        let path = events(vm);
        assert!(!path.is_empty(), "no steps recorded");
        let last = reference.len() - 2;
        let mut k = 0usize;
        let mut worst = 0.0f64;
        for (i, p) in path.iter().enumerate() {
            let q = xyz(p);
            // The first segment near enough from the match on: a path that
            // crosses itself (an exit over the entry) is followed in order.
            let window = || (k.saturating_sub(4)..=(k + 400).min(last)).map(|j| (j, dist_to_segment(q, reference[j], reference[j + 1])));
            let (near, d) = window().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
            assert!(d <= max_dev, "step event {i} at {:?} is {d:.2} steps off the reference near {:?}", p.position, reference[near]);
            let (j, _) = window().find(|&(_, d)| d <= max_dev).unwrap();
            worst = worst.max(d);
            k = k.max(j);
        }
        assert!(k + 3 >= last, "the path stopped at reference segment {k} of {last}");
        let end = reference.last().unwrap().map(|v| v.round() as i64);
        assert_eq!(xyz_now(vm), end, "final position");
        worst
    }

    #[test]
    fn the_issue_example_follows_the_reference_tool_path() {
        let mut vm = boot_homed();
        ok(&mut vm, "G10 L1 P1 R0.5");
        mark(&mut vm);
        for l in EXAMPLE.lines() {
            ok(&mut vm, l);
        }
        ok(&mut vm, "M400");
        let r = reference(EXAMPLE, r#"{"1": 0.5}"#, [1.0, 1.0, -1.0]);
        let worst = check_against(&vm, &r, 1.5);
        println!("issue example: worst deviation {worst:.2} steps");
        assert!(vm.violations().is_empty(), "{:?}", vm.violations());
    }

    #[test]
    fn outside_and_inside_corners_of_lines_and_arcs_follow_the_reference() {
        // A contour with every corner kind (`sim::contour`).
        for (side, d) in [("G41", "D1"), ("G42", "D2"), ("G41.1", "D1.6")] {
            let job = sim::contour::job(&format!("{side} {d}"));
            let mut vm = boot_homed();
            ok(&mut vm, "G10 L1 P1 R0.5");
            ok(&mut vm, "G10 L1 P2 R1.25");
            mark(&mut vm);
            for l in job.lines() {
                ok(&mut vm, l);
            }
            ok(&mut vm, "M400");
            let r = reference(&job, r#"{"1": 0.5, "2": 1.25}"#, [1.0, 1.0, -1.0]);
            let worst = check_against(&vm, &r, 1.5);
            println!("{side} {d}: worst deviation {worst:.2} steps");
            assert!(vm.violations().is_empty(), "{:?}", vm.violations());
            // Compensated arcs and their corners are the deepest stack
            // path of a job (`Interp::comp_move`'s frame, the arc's limit
            // checks).
            ram_within_budget(&vm, &format!("{side} {d} corners"));
        }
    }

    #[test]
    fn an_sd_job_that_ends_under_compensation_runs_its_last_move() {
        // No G40, no M2: the move held back for look-ahead still runs.
        let job = "G21 G90 G17\nG10 L1 P1 R0.5\nG0 X10 Y10 Z-5\nG41 D1 G1 X20 F600\nG1 X30\n";
        let mut vm = with_card(&[("OPEN.NC", job.as_bytes())]);
        let p0 = steps(&vm);
        ok(&mut vm, "M23 OPEN.NC");
        ok(&mut vm, "M24");
        vm.wait_line(|l| l == "Done printing file", 20.0).unwrap();
        // Nothing sent after the job (any line would send the held move).
        vm.run_for(1.0).unwrap();
        assert_eq!(moved(&vm, p0)[..2], [3000, 1050]);
    }

    #[test]
    fn refusals_move_nothing_and_name_the_reason() {
        let mut vm = boot_homed();
        ok(&mut vm, "G10 L1 P1 R0.5");
        ok(&mut vm, "G21 G90 G0 X10 Y10 Z-5");
        ok(&mut vm, "M400");
        let p0 = steps(&vm);
        for (line, what) in [("G18 G41 D1 G1 X20 F600", "XY plane"), ("G41 D1 G1 X10.4 F600", "entry move")] {
            let e = refused(&mut vm, line);
            assert!(e.contains(what), "{line}: {e}");
        }
        ok(&mut vm, "G17");
        ok(&mut vm, "G41 D1 G1 X20 F600");
        for (line, what) in [
            ("G3 X20.6 Y10 I0.3 J0", "arc radius"),
            ("G18", "XY plane"),
            ("T2 M6", "tool change"),
            ("G40 G2 X30 Y10 R5", "exit move"),
            ("G41 D1", "already on"),
        ] {
            let e = refused(&mut vm, line);
            assert!(e.contains(what), "{line}: {e}");
        }
        vm.run_for(1.0).unwrap();
        assert_eq!(steps(&vm), p0, "the entry move is still held, nothing moved");
        ok(&mut vm, "G1 X30");
        ok(&mut vm, "G1 X30.3");
        let e = refused(&mut vm, "G1 Y20");
        assert!(e.contains("too short"), "{e}");
        ok(&mut vm, "G40 G1 X35");
        ok(&mut vm, "M400");
        assert!(vm.violations().is_empty(), "{:?}", vm.violations());
    }
}
