//! The G-code dialect as third-party files write it, on the real ELF in the
//! virtual machine: a byte-order mark and UTF-8 comment text, `*` inside a
//! comment, `$` lines with a comment, a tool number past the pockets, long
//! comments, and cutter radius compensation (G41/G42). Each file style runs
//! over serial and from the SD card where the two differ.

mod common;
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
    // Outside a comment it is still refused, and nothing moves.
    let r = command_bytes(&mut vm, "G1 X4 Ø".as_bytes());
    assert!(r.iter().any(|l| l.starts_with("Error")), "{r:?}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0)[0], 200);
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

// ------------------------------------------------ tool numbers past the pockets

#[test]
fn a_tool_past_the_pockets_is_refused_naming_the_tool_and_the_pockets() {
    let mut vm = unlocked();
    let p0 = steps(&vm);
    let e = refused(&mut vm, "T15 M6");
    assert!(e.contains("T15") && e.contains("T0-T12"), "{e}");
    ok(&mut vm, "M400");
    assert_eq!(moved(&vm, p0), [0; 4]);
    // From SD the job stops at that line, before any cut.
    let job = "G21 G90\nT15 M6\nM3 S5000\nG1 X5 F600\nM5\n";
    let mut vm = with_card(&[("T15.NC", job.as_bytes())]);
    let p0 = steps(&vm);
    let out = run_sd(&mut vm, "T15.NC", 10.0);
    assert!(out.iter().any(|l| l.contains("T15") && l.contains("T0-T12")), "{out:?}");
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
