//! Passes `memory.x` (the RAM/flash budget, docs/SPEC.md §11) and `--relax` to the AVR
//! link, and, for the test-only variants (Cargo features), the linker script
//! of the above-128-KiB build, the no-trampolines build (docs/ARCHITECTURE.md,
//! "Flash") and the panic build's link without the landing pad.
use std::env;
use std::path::PathBuf;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    // The linker (.cargo/config.toml): a change must relink.
    println!("cargo:rerun-if-changed=tools/link-firmware");
    if env::var("CARGO_CFG_TARGET_ARCH").as_deref() != Ok("avr") {
        return;
    }
    let dir = env::var("CARGO_MANIFEST_DIR").unwrap();
    // Keep the budget symbols even though nothing references them.
    println!("cargo:rustc-link-arg-bins=-Wl,--undefined=__mill_ram_budget");
    // Linker relaxation: call/jmp within ±4 KiB become rcall/rjmp (flash,
    // docs/ARCHITECTURE.md "Flash"); LLVM's AVR objects carry the relocations for it.
    println!("cargo:rustc-link-arg-bins=-Wl,--relax");
    if env::var_os("CARGO_FEATURE_HIGH_FLASH").is_some() {
        let script = high_flash_script();
        println!("cargo:rustc-link-arg-bins=-Wl,-T,{}", script.display());
    }
    if env::var_os("CARGO_FEATURE_PANIC_TEST").is_some() {
        // tests/panic.rs needs no bootloader landing pad: tools/link-firmware
        // links once, as avr-gcc would, without the gap below the pad
        // (whose size is the one function that crosses 0x20000, so it
        // changes with the layout; the variant's extra panic code must
        // not fail the flash budget on that).
        println!("cargo:rustc-link-arg-bins=-Wl,--defsym=__mill_no_landing_pad=1");
    }
    if env::var_os("CARGO_FEATURE_NO_STUBS").is_some() {
        // The deliberately broken variant: no `jmp` trampolines for function
        // addresses above 128 KiB (tests/high_flash.rs shows it never boots).
        println!("cargo:rustc-link-arg-bins=-Wl,--no-stubs");
    }
    println!("cargo:rustc-link-arg-bins={dir}/memory.x");
}

/// Modules (v0-mangled path pieces) linked below the gap in the high-flash
/// variant: the interpreter with its canned cycles and cutter
/// compensation, the planner, the tool changer (its logic and its runner,
/// the carousel's runner), the tool setter (likewise), homing, the `$`
/// settings, the menu and screens, and the SD job (about 108 KB of
/// ~173 KB).
const HIGH_FLASH_LOW_MODULES: &[&str] = &[
    "4mill5gcode6interp",
    "4mill5gcode6cycles",
    "4mill5gcode4comp",
    "4mill7planner",
    "4mill3atc",
    "4mill10toolsetter",
    "4mill7machine10toolchange",
    "4mill7machine6setter",
    "4mill7machine8carousel",
    "4mill7machine6homing",
    "4mill6dollar",
    "4mill2ui4menu",
    "4mill2ui4text",
    "4mill2ui6render",
    "4mill2ui2sd",
];

/// avr-ld's own atmega2560 (avr6) script with a gap before the code: after
/// the vectors, `.progmem` and the trampolines (all below 64 KiB, read with
/// `lpm` or reached through 16-bit word addresses), the location counter
/// jumps to 0x20000, so `.init*`, `main`, every ISR, the parser and every
/// function whose address is taken link above 128 KiB (the modules of
/// [`HIGH_FLASH_LOW_MODULES`] stay below it: the whole firmware no longer
/// fits above 128 KiB). The gap's two ends are symbols that
/// `memory.x` subtracts in its flash budget check and `tests/high_flash.rs`
/// reads back.
fn high_flash_script() -> PathBuf {
    let out = Command::new("avr-ld").args(["--verbose", "-mavr6"]).output().expect("avr-ld --verbose -mavr6");
    let text = String::from_utf8(out.stdout).expect("avr-ld prints text");
    // The script is printed between two lines of '='.
    let mut parts = text.split("==================================================");
    let script = parts.nth(1).expect("avr-ld --verbose prints its default script");
    let anchor = "    *(.init0)  /* Start here after reset.  */";
    assert!(script.contains(anchor), "avr-ld's avr6 script changed: no `{anchor}` to put the gap before");
    // The firmware is bigger than the 120 KiB above 0x20000, so a first
    // share of its code stays below the gap: modules that are neither
    // asked to be high (main, the ISRs, the parser) nor take part in a
    // function address (the test checks every trampoline's target is high,
    // so a wrong pattern here fails it). A section goes to the first
    // pattern that matches it, so these win over the `*(.text.*)` below.
    let low: String = HIGH_FLASH_LOW_MODULES.iter().map(|m| format!("    *(.text.*{m}*)\n")).collect();
    let gap = format!("{low}    __mill_high_gap_start = . ;\n    . = MAX(., 0x20000);\n    __mill_high_gap_end = . ;\n");
    let script = script.replacen(anchor, &format!("{gap}{anchor}"), 1);
    let path = PathBuf::from(env::var("OUT_DIR").unwrap()).join("avr6-high-flash.x");
    std::fs::write(&path, script).unwrap();
    path
}
