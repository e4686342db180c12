//! The firmware with its code above 128 KiB (issue 11): proof that the
//! flash budget can be the ATmega2560's whole application space (253 952 B).
//!
//! Two things could break once code lies above 0x20000, and this file checks
//! both on a variant of the real firmware whose main, ISRs, parser,
//! controller and every address-taken function start above 0x20000
//! (`--features high-flash`: build.rs links it with avr-ld's own avr6 script
//! plus a gap after `.progmem`, the trampolines and the interpreter, planner,
//! changer, setter, menu and SD-job code, which no longer fit above it; `tools/build-variants`
//! builds it into `target/variants/high-flash.elf`, `$MILL_ELF_HIGH`):
//!
//! 1. A function address is a 16-bit *word* address, so it reaches 128 KiB.
//!    LLVM emits `R_AVR_*_GS` relocations for the addresses it takes and GNU
//!    ld answers with a `jmp` stub in `.trampolines` (low flash) for every
//!    target above 128 KiB; `icall` reaches the stub, EIND stays 0.
//!    [`the_code_sits_above_128_kib_and_function_addresses_go_through_trampolines`]
//!    reads that from the ELF.
//! 2. Everything else (calls, returns, the vector table, `.data`'s initial
//!    image read with `elpm`) must just work: the other tests run a
//!    representative set of the simavr regression checks on the variant
//!    (protocol, homing and exact lines and arcs, an SD job started from the
//!    menu, a tool change), with the same helpers as `tests/protocol.rs`,
//!    `tests/motion.rs`, `tests/ui.rs` and `tests/atc.rs`, and compare the
//!    recorded steps with the normal build's (`$MILL_ELF`) step for step.
//!
//! The negative control: `--features no-stubs` is the same variant linked
//! with `-Wl,--no-stubs`, i.e. function addresses without trampolines (the
//! link succeeds silently; every stored address is truncated to 16 bits).
//! [`without_trampolines_the_same_checks_fail`] runs the protocol check on it
//! and requires it to fail. Where a truncated address lands depends on the
//! build: until the menu code grew, the first one (the TX wait hook, the
//! banner filling the TX ring) ran into address 0; since then that one lands
//! in code that happens to return, and it is the SD card's directory walk
//! (`M20`: closures called by address) that fails. The check therefore
//! goes through several of the trampoline targets (the TX ring filled by
//! `$$`, `M20` on a card), and the control prints where it failed.
//! Reproduce by hand:
//!
//! ```text
//! tools/build-variants
//! MILL_ELF_NO_STUBS=target/variants/no-stubs.elf cargo test --test high_flash without -- --nocapture
//! without trampolines the checks fail, as they must: M20: firmware crashed at PC 0x00000 (cycle 6266766)
//! ```

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;
use object::{Object, ObjectSection, ObjectSymbol, SymbolKind};
use sim::{Axis, Vm, VmConfig};
use std::path::PathBuf;

/// 128 KiB: the reach of a 16-bit word address (icall, EIND = 0).
const HIGH: u64 = 0x2_0000;

/// An ELF from `$var`, else `target/variants/<name>.elf` (tools/build-variants).
fn variant(var: &str, name: &str) -> PathBuf {
    let p = std::env::var_os(var)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/variants").join(format!("{name}.elf")));
    assert!(p.exists(), "{} missing: run tools/build-variants (tools/test does)", p.display());
    p
}

fn high_elf() -> PathBuf {
    variant("MILL_ELF_HIGH", "high-flash")
}

fn boot_elf(elf: PathBuf) -> Vm {
    let mut cfg = VmConfig::new(elf);
    cfg.command_timeout_s = 120.0;
    boot_with(cfg)
}

/// Decodes a 4-byte AVR `jmp k` at `b`: the target's byte address.
fn jmp_target(b: &[u8]) -> Option<u64> {
    let w1 = u16::from_le_bytes([b[0], b[1]]);
    let w2 = u16::from_le_bytes([b[2], b[3]]);
    if w1 & 0xFE0E != 0x940C {
        return None;
    }
    let k = ((((w1 >> 4) & 0x1F) as u64) << 17) | (((w1 & 1) as u64) << 16) | w2 as u64;
    Some(k * 2)
}

#[test]
fn the_code_sits_above_128_kib_and_function_addresses_go_through_trampolines() {
    let path = high_elf();
    let data = std::fs::read(&path).unwrap();
    let elf = object::File::parse(&*data).unwrap();
    let text = elf.section_by_name(".text").expect(".text");
    let bytes = text.data().unwrap();
    let sym = |name: &str| elf.symbols().find(|s| s.name() == Ok(name)).unwrap_or_else(|| panic!("no symbol {name}")).address();

    // The firmware is larger than the 120 KiB above 0x20000, so build.rs
    // keeps some modules (interpreter, planner, tool changer, tool setter,
    // menu) below the gap; everything else starts above 128 KiB: main, the
    // parser, the ISRs, the controller, the SD code, avr-libc's C objects.
    let funcs: Vec<(String, u64)> = elf
        .symbols()
        .filter(|s| s.kind() == SymbolKind::Text && s.address() < 0x80_0000 && s.size() > 0)
        .map(|s| (s.name().unwrap_or("?").to_string(), s.address()))
        .collect();
    assert!(funcs.len() > 300, "only {} functions in {}", funcs.len(), path.display());
    let high = funcs.iter().filter(|(_, a)| *a >= HIGH).count();
    assert!(high * 2 > funcs.len(), "only {high} of {} functions above 0x20000", funcs.len());
    // The modules build.rs keeps below the gap (its HIGH_FLASH_LOW_MODULES).
    let build = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/build.rs")).unwrap();
    let list = build.split("HIGH_FLASH_LOW_MODULES: &[&str] = &[").nth(1).and_then(|r| r.split("];").next()).expect("the list in build.rs");
    let low_modules: Vec<&str> = list.split('"').skip(1).step_by(2).collect();
    assert!(low_modules.contains(&"4mill7planner"), "{low_modules:?}");
    let low: Vec<_> = funcs.iter().filter(|(n, a)| *a < HIGH && !low_modules.iter().any(|m| n.contains(m))).collect();
    assert!(low.is_empty(), "functions below 0x20000 outside the modules kept low: {low:x?}");
    assert!(sym("main") >= HIGH && sym("__init") >= HIGH);
    let parser: Vec<_> = funcs.iter().filter(|(n, _)| n.contains("5gcode5parse")).collect();
    assert!(!parser.is_empty(), "no mill::gcode::parse function found");
    assert!(parser.iter().all(|(_, a)| *a >= HIGH), "parser below 0x20000: {parser:x?}");
    // The interrupt handlers the firmware defines (stepper, USART0 RX and
    // UDRE, the ms clock, TWI) and the vector table's jumps to them.
    let vectors: Vec<_> = elf
        .symbols()
        .filter(|s| s.name().is_ok_and(|n| n.starts_with("__vector_")) && !s.is_weak())
        .map(|s| (s.name().unwrap().to_string(), s.address()))
        .collect();
    for v in ["__vector_17", "__vector_25", "__vector_26"] {
        assert!(vectors.iter().any(|(n, _)| n == v), "{v} not defined: {vectors:?}");
    }
    assert!(vectors.iter().all(|(_, a)| *a >= HIGH), "{vectors:x?}");
    for i in 0..57u64 {
        let t = jmp_target(&bytes[(i * 4) as usize..]).unwrap_or_else(|| panic!("vector {i} is not a jmp"));
        assert!(t >= HIGH, "vector {i} jumps to {t:#x}");
    }

    // The trampolines: low in flash, one `jmp` per function whose address is
    // taken, each to the start of a function above 128 KiB.
    let (t0, t1) = (sym("__trampolines_start"), sym("__trampolines_end"));
    assert!(t1 > t0 && t1 <= HIGH && (t1 - t0) % 4 == 0, "trampolines {t0:#x}..{t1:#x}");
    let mut targets = Vec::new();
    for a in (t0..t1).step_by(4) {
        let t = jmp_target(&bytes[a as usize..]).unwrap_or_else(|| panic!("trampoline at {a:#x} is not a jmp"));
        let f = funcs
            .iter()
            .find(|(_, fa)| *fa == t)
            .unwrap_or_else(|| panic!("trampoline at {a:#x} jumps to {t:#x}, no function starts there"));
        assert!(t >= HIGH);
        targets.push(f.0.clone());
    }
    // The serial TX-wait hook and the SD card's listing callbacks (`Card::list`
    // takes a `&mut dyn FnMut(&Entry)`) are among them.
    for want in ["8firmware7tx_wait", "4card5Entry"] {
        assert!(targets.iter().any(|n| n.contains(want)), "no trampoline to *{want}*: {targets:#?}");
    }
    // The data read with `lpm` stays below 64 KiB (memory.x asserts it at link time too).
    assert!(sym("__ctors_start") <= 0x1_0000);
    eprintln!(
        "{} functions, lowest at {:#x}; {} trampolines at {t0:#x}..{t1:#x}",
        funcs.len(),
        funcs.iter().map(|f| f.1).min().unwrap(),
        targets.len()
    );
}

/// Banner, M115 and a checksum resend (as tests/protocol.rs) on `elf`.
fn protocol_checks(elf: PathBuf) {
    let mut vm = boot_elf(elf);
    let out = vm.output().to_string();
    let start = out.find("start\n").expect("start line");
    assert!(out[start..].lines().nth(1).is_some_and(|l| l.starts_with("FIRMWARE_NAME:MillFW")), "{out}");
    let r = ok(&mut vm, "M115");
    assert!(r[0].starts_with("FIRMWARE_NAME:MillFW") && r[0].contains("TOOLS:12"), "{r:?}");
    let l1 = "N1 G21";
    ok(&mut vm, &format!("{l1}*{}", checksum(l1)));
    let l2 = "N2 G90";
    let r = vm.command(&format!("{l2}*{}", checksum(l2) ^ 0x55)).unwrap();
    assert_eq!(r[1..], ["Resend:2", "ok"], "{r:?}");
    ok(&mut vm, &format!("{l2}*{}", checksum(l2)));
    // `$$`: some 3 KB, more than the TX ring holds, so the firmware waits
    // for room through its TX wait hook, a function called by address.
    let list = ok(&mut vm, "$$");
    assert!(list.len() > 50 && list.iter().any(|l| l.starts_with("$184=")), "{list:?}");
    // The card's directory walk: closures called by address.
    let mut img = sim::SdImage::new(sim::FatKind::Fat16);
    for n in ["A.GCO", "B.GCO", "C.GCO"] {
        img = img.file(n, b"G0 X1\n");
    }
    vm.insert_sd(sim::SdCard::new(img.build(), sim::CardKind::Sdhc));
    let files = ok(&mut vm, "M20");
    assert!(["A.GCO", "B.GCO", "C.GCO"].iter().all(|n| files.iter().any(|l| l.starts_with(n))), "{files:?}");
    assert_eq!(total_steps(&vm), 0);
}

#[test]
fn protocol_banner_m115_and_a_checksum_resend() {
    protocol_checks(high_elf());
}

#[test]
fn without_trampolines_the_same_checks_fail() {
    let broken = variant("MILL_ELF_NO_STUBS", "no-stubs");
    let r = std::panic::catch_unwind(|| protocol_checks(broken));
    let Err(e) = r else {
        panic!("the firmware linked with --no-stubs passed the protocol checks: the high-flash test proves nothing");
    };
    let why = e.downcast_ref::<String>().map(String::as_str).or_else(|| e.downcast_ref::<&str>().copied()).unwrap_or("?");
    eprintln!("without trampolines the checks fail, as they must: {}", why.lines().next().unwrap_or(""));
}

/// G28, a square and a full G2 circle: exact end points, the ideal path, and
/// the very same steps as the normal build.
fn homing_lines_and_an_arc(elf: PathBuf) -> Vec<(Axis, i64)> {
    let mut cfg = VmConfig::new(elf);
    cfg.machine.initial_position = [600, 600, 600, 0];
    let mut vm = boot_with(cfg);
    ok(&mut vm, "G28");
    assert_eq!(steps(&vm), [100, 100, 100, 0], "G28 ends 1 mm off each switch");
    run(&mut vm, "G0 X10 Y10");
    mark(&mut vm);
    for l in ["G1 X30 F1500", "Y30", "X10", "Y10", "M400"] {
        ok(&mut vm, l);
    }
    let corners = [[1000, 1000, 100], [3000, 1000, 100], [3000, 3000, 100], [1000, 3000, 100], [1000, 1000, 100]];
    assert_eq!(check_polyline(&vm, &corners, 1.0), 0.0);
    assert_eq!(steps_pos_neg(&vm, Axis::X), (2000, 2000));
    assert_eq!(steps_pos_neg(&vm, Axis::Y), (2000, 2000));
    let mut all = vm.recorder().trace().iter().map(|t| (t.axis, t.position)).collect::<Vec<_>>();
    mark(&mut vm);
    ok(&mut vm, "G17 G2 X10 Y10 I7.5 J0 F1500");
    ok(&mut vm, "M400");
    let got = check_arc(&vm, (0, 1, 2), [1750.0, 1000.0], 750.0, [1000, 1000, 100], [1000, 1000, 100], ARC_TOL_MM * SPMM + 1.0);
    assert!((got.swept + 2.0 * std::f64::consts::PI).abs() < 0.01, "swept {}", got.swept);
    // M114 counts Z up (+Z is up in user frames): the recorder's 100 is -100 there.
    assert_eq!(m114_counts(&mut vm), [1000, 1000, -100]);
    assert_no_violations(&vm);
    all.extend(vm.recorder().trace().iter().map(|t| (t.axis, t.position)));
    all
}

#[test]
fn motion_homing_a_square_and_a_circle_step_for_step_like_the_normal_build() {
    let high = homing_lines_and_an_arc(high_elf());
    let normal = homing_lines_and_an_arc(VmConfig::default_elf_path());
    assert_eq!(high.len(), normal.len());
    assert!(high == normal, "the high-flash build stepped differently from the normal build");
}

/// Let the firmware react and draw, as tests/ui.rs does.
fn settle(vm: &mut Vm) {
    vm.run_for(0.35).unwrap();
}

#[test]
fn an_sd_job_started_from_the_menu_runs_like_the_same_lines_over_serial() {
    let job: String =
        (0..20).map(|i| format!("G1 X{:.2} Y{:.2} F3000\n", 3.0 + (i * 7 % 11) as f32 * 0.9, 4.0 + (i * 5 % 13) as f32 * 0.7)).collect();
    let mut img = sim::SdImage::new(sim::FatKind::Fat16);
    img = img.file("JOB.GCO", job.as_bytes());
    let mut vm = boot_elf(high_elf());
    ok(&mut vm, "M999");
    vm.insert_sd(sim::SdCard::new(img.build(), sim::CardKind::Sdhc));
    settle(&mut vm);
    // Status screen → menu → "Run from SD" (entry 1) → the file list
    // ("< Back", JOB.GCO) → JOB.GCO → "Run JOB.GCO?" No / Yes → Yes.
    for (detents, press) in [(0, true), (1, true), (1, true), (1, true)] {
        if detents != 0 {
            vm.turn_encoder(detents, 0.1).unwrap();
            settle(&mut vm);
        }
        if press {
            vm.press_button(0.05).unwrap();
            settle(&mut vm);
        }
    }
    vm.wait_line(|l| l == "Done printing file", 30.0).unwrap_or_else(|e| panic!("{e}: {}", vm.output()));
    let from_sd: Vec<_> = vm.recorder().trace().iter().map(|t| (t.axis, t.position)).collect();
    assert!(from_sd.len() > 500, "{} steps", from_sd.len());
    assert_no_violations(&vm);
    // The same file streamed over serial, on the same build.
    let mut b = boot_elf(high_elf());
    ok(&mut b, "M999");
    for l in job.lines() {
        ok(&mut b, l);
    }
    ok(&mut b, "M400");
    let streamed: Vec<_> = b.recorder().trace().iter().map(|t| (t.axis, t.position)).collect();
    assert!(from_sd == streamed, "the SD job stepped differently from the serial stream");
}

#[test]
fn a_tool_change_t3_m6_then_t0_m6_matches_the_physical_changer() {
    let mut vm = boot_elf(high_elf());
    ok(&mut vm, "G28");
    ok(&mut vm, "G0 X10 Y5 Z-3");
    ok(&mut vm, "M400");
    let before = steps(&vm);
    let r = ok(&mut vm, "T3 M6");
    assert!(r.iter().any(|l| l == "NowSelectedTool:3"), "{r:?}");
    assert_eq!(vm.atc().spindle.map(|t| t.id), Some(3));
    assert_eq!(vm.atc().pocket(3), None);
    let now = steps(&vm);
    assert_eq!((now[0], now[1]), (before[0], before[1]), "back at the pre-change X/Y");
    let r = ok(&mut vm, "T0 M6");
    assert!(r.iter().any(|l| l == "NowSelectedTool:0"), "{r:?}");
    assert_eq!(vm.atc().spindle, None);
    assert_eq!(vm.atc().pocket_ids(), [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    let t = &vm.atc().transfers;
    assert_eq!(t.len(), 2);
    assert!(t[0].to_spindle && t[0].tool == 3 && !t[1].to_spindle && t[1].tool == 3, "{t:?}");
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    assert_no_violations(&vm);
}
