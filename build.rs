//! Passes `memory.x` (the RAM/flash budget, SPEC §11) and `--relax` to the AVR link.
use std::env;

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    if env::var("CARGO_CFG_TARGET_ARCH").as_deref() == Ok("avr") {
        let dir = env::var("CARGO_MANIFEST_DIR").unwrap();
        // Keep the budget symbols even though nothing references them.
        println!("cargo:rustc-link-arg-bins=-Wl,--undefined=__mill_ram_budget");
        // Linker relaxation: call/jmp within ±4 KiB become rcall/rjmp (flash,
        // README "Flash"); LLVM's AVR objects carry the relocations for it.
        println!("cargo:rustc-link-arg-bins=-Wl,--relax");
        println!("cargo:rustc-link-arg-bins={dir}/memory.x");
    }
}
