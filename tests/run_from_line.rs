//! Run from line (docs/standalone.md "Run from line") on the real ELF in
//! the virtual machine, driven only through the encoder, the button and
//! the card (a FAT16 image built with `fatfs`, sim's `SdImage`): after an
//! abort, a power cut and a card pulled, the line proposed, the refusals,
//! the scan, and the approach (Z up, X/Y, the spindle up to speed, the
//! plunge at the job's feed at that line) checked on the recorded motion, the spindle
//! output, the OLED and the EEPROM record.
//!
//! Golden screenshots as in tests/ui.rs (`MILL_UPDATE_GOLDEN=1` rewrites).

mod common;
#[path = "common/motion.rs"]
mod motion_util;
#[path = "common/panel.rs"]
mod panel;
use common::*;
use panel::{golden, golden_masked, press, redraw, screen, turn};
use sim::{Axis, CardKind, FatKind, SdCard, SdImage, Vm};

/// The record's address and layout (src/ui/resume.rs).
const REC: usize = 512;
const SLOTS: usize = REC + 20;

/// A cutting job: spindle at 8000, flood, Z 5 mm into the work, then
/// `lines` cuts alternating X 2 / X 20 at F1200, each one Y mm further
/// (every line ends at its own point). Lines 1-5 are the head; cut k
/// (0-based) is line 6 + k.
fn job(lines: usize) -> String {
    let mut s = String::from("G21 G90\nM3 S8000\nM8\nG0 X20 Y5\nG1 Z-5 F600\n");
    for k in 0..lines {
        s += &format!("G1 X{} Y{} F1200\n", [2, 20][k % 2], 6 + k);
    }
    s + "G0 Z0\nM9\nM5\nM2\n"
}

fn card(text: &str) -> SdCard {
    SdCard::new(SdImage::new(FatKind::Fat16).file("CUT.NC", text.as_bytes()).build(), CardKind::Sdhc)
}

fn wait_for(vm: &mut Vm, pred: impl FnMut(&str) -> bool, s: f64) -> String {
    vm.wait_line(pred, s).unwrap_or_else(|e| panic!("{e}; output:\n{}", tail(vm)))
}

fn tail(vm: &Vm) -> String {
    let o = vm.output();
    o[o.len().saturating_sub(2000)..].to_string()
}

/// Every step as (axis, position) after `cycle`.
fn steps_after(vm: &Vm, cycle: u64) -> Vec<(Axis, i64)> {
    vm.recorder().trace().iter().filter(|t| t.cycle > cycle).map(|t| (t.axis, t.position)).collect()
}

/// The line executing at `cycle`: the head's 5 lines, plus one per X
/// reversal (each cut reverses X).
fn line_at(vm: &Vm, cycle: u64) -> u32 {
    let xs: Vec<i64> = vm.recorder().trace().iter().filter(|t| t.axis == Axis::X && t.cycle <= cycle).map(|t| t.position).collect();
    5 + xs.windows(3).filter(|w| (w[1] - w[0]) * (w[2] - w[1]) < 0).count() as u32
}

/// The line in the EEPROM record: the newest (largest) slot, with the
/// header's magic and the file's name and size checked.
fn recorded_line(vm: &Vm, size: usize) -> Option<u32> {
    let e = vm.eeprom();
    if e[REC] != 0x52 {
        return None;
    }
    assert_eq!(&e[REC + 1..REC + 7], b"CUT.NC");
    assert_eq!(u32::from_le_bytes(e[REC + 13..REC + 17].try_into().unwrap()) as usize, size);
    (0..8).map(|i| u32::from_le_bytes(e[SLOTS + 4 * i..SLOTS + 4 * i + 4].try_into().unwrap())).filter(|&v| v != u32::MAX).max()
}

/// From the status screen: Run from SD, the file, the Run screen.
fn open_run_screen(vm: &mut Vm) {
    press(vm);
    turn(vm, 1);
    press(vm);
    turn(vm, 1);
    press(vm);
    assert_eq!(screen(vm)[..4], ["[ Run CUT.NC?]", "[ No]", " Yes", " From line"], "{:?}", screen(vm));
}

/// From the Run screen: From line; returns the line proposed.
fn open_from_line(vm: &mut Vm) -> u32 {
    turn(vm, 2);
    press(vm);
    let s = screen(vm);
    assert_eq!(s[0], "[ From line]", "{s:?}");
    assert_eq!(s[4], " < Back");
    assert!(s[5].starts_with("[ Line") && s[7] == " Start", "{s:?}");
    s[5].trim_end_matches(']').rsplit(' ').next().unwrap().parse().unwrap()
}

/// The reference: the whole job run from the top, every step after the
/// start and the spindle's duty while cutting.
fn full_run(text: &str) -> (Vec<(Axis, i64)>, f64) {
    let mut vm = motion_util::boot_homed();
    vm.insert_sd(card(text));
    open_run_screen(&mut vm);
    turn(&mut vm, 1);
    let start = vm.cycles();
    press(&mut vm);
    wait_for(&mut vm, |l| l == "Done printing file", 60.0);
    let duty = vm.spindle_history().iter().find(|(c, d)| *c > start && *d > 0.0).unwrap().1;
    (steps_after(&vm, 0), duty)
}

/// After the Start press at `pressed`: Z up first (to $160, 2 mm below its
/// switch: 200 steps; a Z above that stays), then X/Y, the spindle on at
/// the job's duty before Z goes down, the plunge at its feed to the cut depth,
/// then the rest of the path exactly as the full run's end.
fn check_approach(vm: &Vm, pressed: u64, reference: &[(Axis, i64)], duty: f64, z_from: i64) {
    let trace: Vec<_> = vm.recorder().trace().iter().filter(|t| t.cycle > pressed).cloned().collect();
    let first_xy = trace.iter().position(|t| t.axis != Axis::Z).expect("X/Y moved");
    let z_top = z_from.min(200);
    assert!(trace[..first_xy].iter().all(|t| t.axis == Axis::Z), "Z alone first");
    assert_eq!(trace[..first_xy].len() as i64, z_from - z_top, "Z up from {z_from} to {z_top}");
    assert!(trace[..first_xy].windows(2).all(|w| w[1].position < w[0].position), "Z only up");
    // Then X/Y only, until Z goes down.
    let plunge = first_xy + trace[first_xy..].iter().position(|t| t.axis == Axis::Z).expect("plunge");
    let last_xy = trace[plunge - 1].cycle;
    let plunge_end = plunge + trace[plunge..].iter().position(|t| t.axis != Axis::Z).unwrap();
    assert_eq!((plunge_end - plunge) as i64, 500 - z_top, "plunge back to the cut depth");
    assert_eq!(trace[plunge_end - 1].position, 500);
    // The spindle: on at the job's speed after X/Y, before the plunge.
    let on: Vec<&(u64, f64)> = vm.spindle_history().iter().filter(|(c, d)| *c > pressed && *d > 0.0).collect();
    assert!(!on.is_empty(), "spindle on");
    let (on_at, on_duty) = *on[0];
    assert!((on_duty - duty).abs() < 1e-9, "spindle duty {on_duty} vs the job's {duty}");
    assert!(last_xy < on_at && on_at < trace[plunge].cycle, "spindle on after X/Y and before the plunge");
    // The plunge at the job's feed at that line, F1200 (20 mm/s): no
    // faster (a rapid would take a third of the time).
    let plunge_s = (trace[plunge_end - 1].cycle - trace[plunge].cycle) as f64 / 16e6;
    assert!(plunge_s >= (500 - z_top) as f64 / 2000.0 * 0.97, "plunge in {plunge_s} s: faster than F1200");
    // The rest: each axis exactly as at the end of the full run.
    let rest = &trace[plunge_end..];
    assert!(rest.len() > 1000, "the job went on: {} steps", rest.len());
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        let got: Vec<i64> = rest.iter().filter(|t| t.axis == axis).map(|t| t.position).collect();
        let all: Vec<i64> = reference.iter().filter(|t| t.0 == axis).map(|t| t.1).collect();
        assert_eq!(got[..], all[all.len() - got.len()..], "{axis:?}: the rest of the path differs from the full run's");
    }
}

#[test]
fn after_an_abort_run_from_line_proposes_the_line_and_finishes_the_job_as_the_full_run() {
    let text = job(10);
    let (reference, duty) = full_run(&text);
    let mut vm = motion_util::boot_homed();
    vm.insert_sd(card(&text));
    // Run it, abort in the cut: Job, Abort, Yes.
    open_run_screen(&mut vm);
    golden(&vm, "run_from_line_run_screen");
    turn(&mut vm, 1);
    press(&mut vm);
    vm.run_until(|v| v.spindle_on(), 5.0).unwrap();
    vm.run_for(3.5).unwrap();
    press(&mut vm);
    turn(&mut vm, 2);
    press(&mut vm);
    turn(&mut vm, 2);
    press(&mut vm);
    turn(&mut vm, 1);
    vm.press_button(0.01).unwrap();
    let aborted_at = vm.cycles();
    wait_for(&mut vm, |l| l.contains("SD job aborted"), 5.0);
    vm.run_for(0.5).unwrap();
    let n = line_at(&vm, aborted_at);
    assert!(n > 6, "aborted in a cut: line {n}");
    assert_eq!(vm.position(Axis::Z), 500, "still at the cut depth");
    assert!(!vm.spindle_on());
    // The record: this file, the line executing at the abort.
    eprintln!("EEPROM {:?}", &vm.eeprom()[REC..REC + 52]);
    assert_eq!(recorded_line(&vm, text.len()), Some(n));
    // Run from line: the line proposed is the one reached.
    redraw(&mut vm);
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), n);
    golden(&vm, "run_from_line_pick");
    let s = screen(&vm);
    assert_eq!(s[1..4], [" Proposed: the last", " line reached by its", " last run"], "{s:?}");
    // Start.
    turn(&mut vm, 2);
    let pressed = vm.cycles();
    press(&mut vm);
    wait_for(&mut vm, |l| l.starts_with("echo:run from line ") && l.ends_with(": scanning"), 1.0);
    wait_for(&mut vm, |l| l == "Done printing file", 60.0);
    check_approach(&vm, pressed, &reference, duty, 500);
    // Done: nothing left to resume.
    assert_eq!(recorded_line(&vm, text.len()), None);
    assert_eq!(vm.eeprom()[REC], 0);
    ram_within_budget(&vm, "run from line");
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}

#[test]
fn after_a_power_cut_run_from_line_is_refused_until_homed_then_goes_on_from_the_recorded_line() {
    let text = job(40);
    let (reference, duty) = full_run(&text);
    let mut vm = motion_util::boot_homed();
    vm.insert_sd(card(&text));
    open_run_screen(&mut vm);
    turn(&mut vm, 1);
    press(&mut vm);
    let started = vm.cycles();
    vm.run_for(33.0).unwrap();
    // Recorded every 30 s of cutting: the line reached then.
    let rec = recorded_line(&vm, text.len()).expect("recorded");
    let s = 16_000_000u64;
    assert!(rec >= line_at(&vm, started + 29 * s) && rec <= line_at(&vm, started + 31 * s), "recorded line {rec}");
    let z = vm.position(Axis::Z);
    vm.power_cycle();
    vm.wait_for_start(3.0).unwrap();
    vm.run_for(0.5).unwrap();
    let eeprom = vm.eeprom();
    let still = vm.positions();
    assert_eq!(still[2], z);
    // Not homed: the line is proposed, and Start refused; nothing moves.
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), rec);
    turn(&mut vm, 2);
    press(&mut vm);
    let r = screen(&vm);
    assert_eq!(r[0], "[ From line]", "{r:?}");
    assert_eq!(r[2..5], [" home first: the", " position is not", " known (power cut?),"], "{r:?}");
    golden(&vm, "run_from_line_not_homed");
    vm.run_for(1.0).unwrap();
    assert_eq!(vm.positions(), still, "nothing moved");
    assert_eq!(vm.eeprom(), eeprom, "EEPROM untouched");
    // Back to the pick (a press), < Back, No, < Back: the main menu; Home,
    // Home all.
    press(&mut vm);
    assert_eq!(screen(&vm)[0], "[ From line]", "{:?}", screen(&vm));
    turn(&mut vm, -1);
    press(&mut vm);
    turn(&mut vm, -2);
    press(&mut vm);
    turn(&mut vm, -1);
    press(&mut vm);
    assert_eq!(screen(&vm)[0], "[ Menu]", "{:?}", screen(&vm));
    turn(&mut vm, 3);
    press(&mut vm);
    turn(&mut vm, 1);
    press(&mut vm);
    vm.run_until(|v| v.positions()[..3] == [100, 100, 100], 60.0).unwrap();
    vm.run_for(1.0).unwrap();
    // Now it goes: from the recorded line, the same way as after an abort
    // (Z homed 1 mm below its switch: already above $160, it does not go up).
    redraw(&mut vm);
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), rec);
    turn(&mut vm, 2);
    let pressed = vm.cycles();
    press(&mut vm);
    wait_for(&mut vm, |l| l == "Done printing file", 60.0);
    check_approach(&vm, pressed, &reference, duty, 100);
    ram_within_budget(&vm, "run from line");
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}

/// A long job: the head of [`job`], then `lines` cuts alternating X 2 /
/// X 20 with Y cycling 6..15.
fn long_job(lines: usize) -> String {
    let mut s = String::from("G21 G90\nM3 S8000\nM8\nG0 X20 Y5\nG1 Z-5 F600\n");
    for k in 0..lines {
        s += &format!("G1 X{} Y{} F1200\n", [2, 20][k % 2], 6 + k % 10);
    }
    s + "G0 Z0\nM9\nM5\nM2\n"
}

/// On the pick screen: the step to 10^k lines (Step pressed k times from
/// 1), then `detents` on the line; the selection back on Start.
fn set_line(vm: &mut Vm, k: usize, detents: i32) {
    turn(vm, 1);
    for _ in 0..k {
        press(vm);
    }
    turn(vm, -1);
    press(vm);
    turn(vm, detents);
    press(vm);
    turn(vm, 2);
    assert_eq!(screen(vm)[7], "[ Start]", "{:?}", screen(vm));
}

#[test]
fn after_a_card_pull_the_line_named_is_proposed_a_scan_stops_cleanly_on_a_pull_or_past_the_end_and_an_edited_file_starts_at_1() {
    let text = long_job(3000);
    let mut vm = motion_util::boot_homed();
    vm.insert_sd(card(&text));
    // No earlier run: line 1, and the screen says why.
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), 1);
    assert_eq!(screen(&vm)[1..4], [" No stopped run of", " this file: line 1", ""], "{:?}", screen(&vm));
    golden(&vm, "run_from_line_no_record");
    // < Back, Yes: the job from the top; the card pulled in the cut.
    turn(&mut vm, -1);
    press(&mut vm);
    turn(&mut vm, -1);
    press(&mut vm);
    vm.run_until(|v| v.spindle_on(), 5.0).unwrap();
    vm.run_for(3.0).unwrap();
    vm.pull_sd();
    let msg = wait_for(&mut vm, |l| l.starts_with("echo:SD card removed: job stopped at line "), 1.0);
    let n: u32 = msg.rsplit(' ').next().unwrap().parse().unwrap();
    wait_for(&mut vm, |l| l.starts_with("echo:SD job ended (card removed)"), 10.0);
    vm.run_for(0.5).unwrap();
    assert_eq!(recorded_line(&vm, text.len()), Some(n), "the line named is recorded");
    // The card back: the line named is proposed.
    vm.insert_sd(card(&text));
    redraw(&mut vm);
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), n);
    // 2000 lines further (step 1000, two detents): the scan takes a while.
    set_line(&mut vm, 3, 2);
    let target = n + 2000;
    let still = vm.positions();
    let before = vm.eeprom();
    press(&mut vm);
    vm.run_for(0.2).unwrap();
    let s = screen(&vm);
    assert!(s[6].starts_with(&format!("Scan to {target}")) && s[6].ends_with('%'), "{s:?}");
    // The share scanned so far depends on the firmware's speed: not compared.
    golden_masked(&vm, "run_from_line_scanning", 6, 16..21);
    // The record holds the line chosen from the start of the scan.
    assert_eq!(recorded_line(&vm, text.len()), Some(target));
    assert_ne!(vm.eeprom(), before);
    // The card pulled during the scan: the job ends, nothing moves.
    vm.pull_sd();
    wait_for(&mut vm, |l| l == format!("echo:SD card removed: job stopped at line {target}, nothing moved"), 1.0);
    wait_for(&mut vm, |l| l == format!("echo:run from line not started: line {target}"), 1.0);
    redraw(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[6], format!("Not resumed: {target}"), "{s:?}");
    assert_eq!(s[7], "Card out during scan", "{s:?}");
    golden(&vm, "run_from_line_card_out_in_scan");
    vm.run_for(1.0).unwrap();
    assert_eq!(vm.positions(), still, "nothing moved");
    assert!(!vm.spindle_on() && !vm.coolant_on());
    assert!(status(&mut vm).starts_with("<Idle|"), "out of the scan's check mode");
    // Past the end of the file: refused after the scan, nothing moves.
    vm.insert_sd(card(&text));
    redraw(&mut vm);
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), target);
    set_line(&mut vm, 3, 5);
    press(&mut vm);
    let past = target + 5000;
    wait_for(&mut vm, |l| l == format!("echo:run from line not started: line {past}"), 30.0);
    assert!(vm.output().contains(&format!("echo:run from line: the file ends at line {}, nothing moved", 3009)), "{}", tail(&vm));
    redraw(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[6], format!("Not resumed: {past}"), "{s:?}");
    assert_eq!(s[7], "File ends before it", "{s:?}");
    golden(&vm, "run_from_line_past_the_end");
    assert_eq!(vm.positions(), still, "nothing moved");
    assert!(status(&mut vm).starts_with("<Idle|"));
    // The file edited since (same name, another size): line 1, and why.
    vm.pull_sd();
    vm.run_for(0.5).unwrap();
    vm.insert_sd(card(&long_job(2999)));
    redraw(&mut vm);
    open_run_screen(&mut vm);
    assert_eq!(open_from_line(&mut vm), 1);
    assert_eq!(screen(&vm)[1..3], [" File changed since", " its last run: line 1"], "{:?}", screen(&vm));
    golden(&vm, "run_from_line_file_changed");
    ram_within_budget(&vm, "run from line");
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}
