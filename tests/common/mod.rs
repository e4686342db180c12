//! Shared set-up for the simavr regression tests: boot the real firmware ELF
//! in the virtual machine and talk to it like a host.
#![allow(dead_code)]

use sim::{Vm, VmConfig};

/// Boot the firmware (`$MILL_ELF`, built by `tools/test`) and wait for `start`.
pub fn boot() -> Vm {
    boot_with(VmConfig::default())
}

/// Boot with a custom virtual-machine configuration.
pub fn boot_with(cfg: VmConfig) -> Vm {
    let elf = cfg.elf.clone();
    assert!(elf.exists(), "firmware ELF {} missing: run tools/build-firmware (tools/test does)", elf.display());
    let mut vm = Vm::new(cfg).expect("load firmware");
    vm.wait_banner().expect("firmware prints its boot banner");
    vm
}

/// Static RAM plus the stack's high-water mark so far, printed with
/// `what`, asserted within the 7 KiB budget of SPEC §11. Returns the sum.
pub fn ram_within_budget(vm: &Vm, what: &str) -> u32 {
    let stack = vm.stack_high_water_bytes().unwrap();
    let statics = (vm.symbol_addr("__bss_end").unwrap() & 0xFFFF) - 0x200;
    println!("{what}: static RAM {statics} B + stack high-water {stack} B = {} B of 7168", statics + stack);
    assert!(statics + stack <= 7168, "{what}: static {statics} + stack {stack}");
    statics + stack
}

/// A board as sold: the stock Mega2560 bootloader in front of the firmware
/// (Debian's `arduino-core-avr`, installed by `tools/setup`), as the real
/// hosts meet it.
pub fn board_as_sold() -> VmConfig {
    let hex = sim::boot::default_hex_path();
    assert!(hex.exists(), "{} missing: tools/setup installs Debian's arduino-core-avr", hex.display());
    VmConfig { bootloader: Some(hex), ..VmConfig::default() }
}

/// The mill with T1 (19.5 mm long, 3 mm thick) and T2 (21.3371 mm,
/// 3.175 mm) in the carousel and an optical tool setter whose beam is not
/// where the firmware's defaults say; commands may take 120 s (a tool
/// change, a measurement).
pub fn tools_and_setter() -> VmConfig {
    use sim::{AtcConfig, OpticalBeam, Tool, ToolSetter};
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = 120.0;
    cfg.machine.tool_setter =
        ToolSetter::Optical(OpticalBeam { x_mm: (3.0, 7.0), y_mm: 10.013, z_mm: 48.0047, width_mm: 0.52, steps_per_mm: 100.0 });
    let mut atc = AtcConfig::default();
    atc.pockets[0] = Some(Tool { id: 1, length_mm: 19.5, diameter_mm: 3.0 });
    atc.pockets[1] = Some(Tool { id: 2, length_mm: 21.3371, diameter_mm: 3.175 });
    cfg.machine.atc = atc;
    cfg
}

/// Send a command and return its reply lines, asserting it ends with `ok`
/// and carries no error.
pub fn ok(vm: &mut Vm, line: &str) -> Vec<String> {
    let t = vm.config().command_timeout_s;
    ok_within(vm, line, t)
}

/// [`ok`] for a command that may take longer than the VM's command
/// timeout (an M400 behind a long queue): `timeout_s` simulated seconds.
pub fn ok_within(vm: &mut Vm, line: &str, timeout_s: f64) -> Vec<String> {
    let r = vm.command_timeout(line, timeout_s).unwrap_or_else(|e| panic!("{line}: {e}"));
    assert_eq!(r.last().map(String::as_str), Some("ok"), "{line}: {r:?}");
    assert!(!r.iter().any(|l| l.starts_with("Error")), "{line}: {r:?}");
    r
}

/// Send a command that must be refused: returns the error line. A grbl
/// reply (`[MSG:<text>]` and `error:<n>` instead of `ok`) is returned as
/// `Error:<text> (error:<n>)`.
pub fn refused(vm: &mut Vm, line: &str) -> String {
    let r = vm.command(line).unwrap_or_else(|e| panic!("{line}: {e}"));
    let last = r.last().map(String::as_str).unwrap_or("");
    if last.starts_with("error:") {
        let msg = r.iter().rev().find_map(|l| l.strip_prefix("[MSG:")).unwrap_or_else(|| panic!("{line}: no text in {r:?}"));
        return format!("Error:{} ({last})", msg.trim_end_matches(']'));
    }
    assert_eq!(last, "ok", "{line}: {r:?}");
    r.iter().find(|l| l.starts_with("Error")).cloned().unwrap_or_else(|| panic!("{line}: no error in {r:?}"))
}

/// Sends `?` and returns the next status line (`<...>`).
pub fn status(vm: &mut Vm) -> String {
    vm.send(b"?");
    vm.wait_line(|l| l.starts_with('<'), 0.5).expect("status line")
}

/// The names of a status line's fields, in order (`<Idle|MPos:…|FS:…>`:
/// Idle, MPos, FS).
pub fn fields(st: &str) -> Vec<String> {
    st.trim_matches(['<', '>']).split('|').map(|f| f.split(':').next().unwrap().to_string()).collect()
}

/// `Ov:` from the next of at most `reports` status reports that carries it
/// (20 ms of simulated time between them).
pub fn ov(vm: &mut Vm, reports: usize) -> String {
    for _ in 0..reports {
        let st = status(vm);
        if let Some(f) = st.trim_matches(['<', '>']).split('|').find_map(|f| f.strip_prefix("Ov:")) {
            return f.to_string();
        }
        vm.run_for(0.02).unwrap();
    }
    panic!("no Ov: in {reports} status reports");
}

/// X steps per second between cycles `t0` and `t1`, from the recorder.
pub fn x_rate(vm: &Vm, t0: u64, t1: u64) -> f64 {
    let n = vm.recorder().trace().iter().filter(|p| p.axis == sim::Axis::X && (t0..t1).contains(&p.cycle)).count();
    n as f64 * f64::from(vm.frequency()) / (t1 - t0) as f64
}

/// Wait until the machine has been still for `quiet_s` (no step recorded).
pub fn settle(vm: &mut Vm, quiet_s: f64) {
    loop {
        let before = vm.recorder().trace().len();
        vm.run_for(quiet_s).unwrap();
        if vm.recorder().trace().len() == before {
            return;
        }
    }
}

/// Positions of X, Y, Z, E in steps, from the recorder.
pub fn steps(vm: &Vm) -> [i64; 4] {
    vm.positions()
}

/// Total steps emitted on every axis (both directions).
pub fn total_steps(vm: &Vm) -> u64 {
    vm.recorder().total_steps()
}

/// Tiny deterministic PRNG (xorshift32) for fuzz-like inputs.
pub struct Rng(pub u32);

impl Rng {
    pub fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }
}

/// The XOR checksum of a host line (Marlin/Repetier).
pub fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}
