mod common;
#[path = "common/motion.rs"]
mod motion_util;
use common::*;
use motion_util::*;
#[test]
fn line_cost() {
    let mut vm = boot_homed();
    let mut tot = 0u64;
    let mut arc = 0u64;
    for i in 0..60 {
        let l = format!("G1 X{:.3} Y{:.3} F3000", 10.0 + i as f64 * 0.05, 10.0 + (i % 7) as f64 * 0.03);
        let t0 = vm.cycles();
        ok(&mut vm, &l);
        tot += vm.cycles() - t0;
        ok(&mut vm, "M400");
    }
    ok(&mut vm, "G0 X10 Y10"); ok(&mut vm, "M400");
    for i in 0..10 {
        let t0 = vm.cycles();
        let _ = i; ok(&mut vm, "G2 X10.5 Y9.5 I0.5 J0 F3000");
        arc += vm.cycles() - t0;
        ok(&mut vm, "M400");
        ok(&mut vm, "G0 X10 Y10");
        ok(&mut vm, "M400");
    }
    eprintln!("LINECOST G1 {} cycles/line, G2 {} cycles/arc", tot / 60, arc / 10);
}
