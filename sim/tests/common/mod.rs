//! Builds the C test firmwares in `tests/firmware/` with avr-gcc.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;
use std::sync::Mutex;

static BUILD: Mutex<()> = Mutex::new(());

/// Compiles `tests/firmware/<name>.c` for the ATmega2560 (-O2) and returns the ELF.
pub fn firmware(name: &str) -> PathBuf {
    let _g = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/firmware").join(format!("{name}.c"));
    let out_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("sim-firmware");
    std::fs::create_dir_all(&out_dir).unwrap();
    let elf = out_dir.join(format!("{name}.elf"));
    let fresh = match (std::fs::metadata(&src), std::fs::metadata(&elf)) {
        (Ok(s), Ok(e)) => e.modified().unwrap() > s.modified().unwrap(),
        _ => false,
    };
    if !fresh {
        let tmp = out_dir.join(format!("{name}.{}.elf", std::process::id()));
        let st = Command::new("avr-gcc")
            .args(["-mmcu=atmega2560", "-DF_CPU=16000000UL", "-O2", "-Wall", "-o"])
            .arg(&tmp)
            .arg(&src)
            .status()
            .expect("avr-gcc must be installed (apt-get install gcc-avr avr-libc)");
        assert!(st.success(), "avr-gcc failed on {}", src.display());
        std::fs::rename(&tmp, &elf).unwrap();
    }
    elf
}
