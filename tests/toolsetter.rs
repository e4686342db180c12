//! Optical tool setter (docs/SPEC.md §8) on the real firmware: the virtual machine's
//! beam is broken by the real geometry of the tool in the spindle.

mod common;
use common::*;
use mill::atc::tools::{ToolTable, EEPROM_TABLE_ADDR};
use sim::{AtcConfig, Axis, Input, OpticalBeam, Tool, ToolSetter, Vm, VmConfig};

/// The beam: along X between X 3 and 7, at Y 10.013, 48.0047 mm below the
/// Z home switch (the VM's physical frame counts Z down; the firmware reports
/// it as machine Z −48.0047, +Z up), 0.52 mm wide.
fn beam() -> OpticalBeam {
    OpticalBeam { x_mm: (3.0, 7.0), y_mm: 10.013, z_mm: 48.0047, width_mm: 0.52, steps_per_mm: 100.0 }
}

/// Tools with lengths and diameters between steps; T1 is the reference.
fn tools() -> [Tool; 4] {
    [
        Tool { id: 1, length_mm: 19.5, diameter_mm: 3.0 },
        Tool { id: 2, length_mm: 21.3371, diameter_mm: 3.175 },
        Tool { id: 3, length_mm: 27.9032, diameter_mm: 6.35 },
        Tool { id: 4, length_mm: 24.5113, diameter_mm: 1.5875 },
    ]
}

fn setter_vm() -> Vm {
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = 120.0;
    cfg.machine.tool_setter = ToolSetter::Optical(beam());
    let mut atc = AtcConfig::default();
    for t in tools() {
        atc.pockets[t.id as usize - 1] = Some(t);
    }
    cfg.machine.atc = atc;
    let mut vm = boot_with(cfg);
    ok(&mut vm, "G28");
    vm
}

/// Calibrate with T1 (length 19.5, radius 1.5).
fn calibrate(vm: &mut Vm) -> String {
    ok(vm, "T1 M6");
    let r = ok(vm, "G37 L19.5 R1.5");
    r.iter().find(|l| l.starts_with("[SETTER")).cloned().expect("calibration line")
}

/// `[TOOL:n L:x D:y]` → (L, D) in mm.
fn parse_tool_line(l: &str) -> (f64, Option<f64>) {
    let field = |k: &str| l.split(' ').find_map(|w| w.strip_prefix(k)).map(|v| v.trim_end_matches(']').parse().unwrap());
    (field("L:").unwrap(), field("D:"))
}

fn table(vm: &Vm) -> ToolTable {
    let e = vm.eeprom();
    let a = EEPROM_TABLE_ADDR as usize;
    ToolTable::from_bytes(&e[a..a + ToolTable::IMAGE_LEN].try_into().unwrap()).expect("tool table record")
}

#[test]
fn calibrate_then_three_tools_measured_within_a_step() {
    let mut vm = setter_vm();
    let cal = calibrate(&mut vm);
    // Beam tip height 48.005 below home (the reference trips on the step at
    // or past it): machine Z −48.005 with +Z up; width 0.52.
    assert!(cal.starts_with("[SETTER Z:-48.0"), "{cal}");
    for t in &tools()[1..] {
        ok(&mut vm, &format!("T{} M6", t.id));
        let r = ok(&mut vm, "G37 D1");
        let line = r.iter().find(|l| l.starts_with(&format!("[TOOL:{} ", t.id))).expect("result line");
        let (len, dia) = parse_tool_line(line);
        let dia = dia.unwrap();
        let (el, ed) = ((len - t.length_mm) * 100.0, (dia - t.diameter_mm) * 100.0);
        eprintln!("T{}: L {len} (true {}, {el:+.2} steps)  D {dia} (true {}, {ed:+.2} steps)", t.id, t.length_mm, t.diameter_mm);
        assert!(el.abs() <= 1.0, "T{} length off by {el} steps", t.id);
        assert!(ed.abs() <= 1.0, "T{} diameter off by {ed} steps", t.id);
        // Stored in the table, in EEPROM.
        let tb = table(&vm);
        assert_eq!(tb.length_um(t.id) as f64, (len * 1000.0).round());
        assert_eq!(tb.diameter_um(t.id) as f64, (dia * 1000.0).round());
    }
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
    assert!(vm.atc().collisions.is_empty());
}

#[test]
fn broken_tool_check_alarms_on_a_tool_half_a_millimetre_shorter() {
    let mut vm = setter_vm();
    calibrate(&mut vm);
    ok(&mut vm, "T2 M6");
    ok(&mut vm, "G37");
    // Unchanged tool: within tolerance, no alarm.
    let r = ok(&mut vm, "G37 B0.2");
    assert!(r.iter().any(|l| l.starts_with("[TOOL:2 ") && l.contains("dL:0.0")), "{r:?}");
    let before = table(&vm);
    // The tip breaks off: 0.5 mm shorter.
    vm.with_atc(|a| a.spindle.as_mut().unwrap().length_mm -= 0.5);
    let r = vm.command("G37 B0.2").unwrap();
    assert!(r.iter().any(|l| l.starts_with("[TOOL:2 ") && l.contains("dL:-0.5")), "{r:?}");
    assert!(r.iter().any(|l| l == "ALARM:broken tool"), "{r:?}");
    assert!(!vm.spindle_on());
    assert_eq!(table(&vm), before, "a check stores nothing");
    assert!(refused(&mut vm, "G0 X1").contains("alarm"));
}

#[test]
fn a_beam_blocked_at_the_start_is_refused_with_no_motion() {
    let mut vm = setter_vm();
    calibrate(&mut vm);
    ok(&mut vm, "T2 M6");
    vm.set_input(Input::ToolSetter, Some(true));
    let n = total_steps(&vm);
    assert!(refused(&mut vm, "G37").contains("blocked at start"));
    assert_eq!(total_steps(&vm), n);
}

#[test]
fn a_beam_that_never_breaks_retracts_the_tool_and_stores_nothing() {
    let mut vm = setter_vm();
    calibrate(&mut vm);
    ok(&mut vm, "T3 M6");
    let before = table(&vm);
    vm.set_input(Input::ToolSetter, Some(false)); // the setter's cable is cut
    let r = vm.command("G37 D1").unwrap();
    assert!(r.iter().any(|l| l.starts_with("Error:") && l.contains("never broke")), "{r:?}");
    // As a G38.2 that touches nothing: an alarm, so that nothing after it
    // runs on a tool that was never measured.
    assert!(r.iter().any(|l| l == "ALARM:probe failed"), "{r:?}");
    assert!(refused(&mut vm, "G0 X1").contains("alarm"));
    ok(&mut vm, "M999");
    ok(&mut vm, "M400");
    assert_eq!(vm.position(Axis::Z), 100, "retracted to the travel height");
    assert_eq!(table(&vm), before);
    // It went all the way down looking for the beam.
    assert!(vm.recorder().axis_stats(Axis::Z).steps_pos > 4000);
}

#[test]
fn g38_probes_on_the_tool_setter_input_and_g10_l1_sets_the_table() {
    let mut vm = setter_vm();
    ok(&mut vm, "T2 M6");
    ok(&mut vm, "G0 X5 Y10.013");
    let r = ok(&mut vm, "G38.2 Z-45 F300");
    // Tip 21.3371 below the spindle reaches 48.0047 below home at spindle Z
    // 26.6676 below home: the trip step is 2667, reported as Z −26.67.
    // T2's table length is still 0 (never measured): work Z = machine Z.
    assert!(r.iter().any(|l| l == "[PRB:5.000,10.010,-26.670:1]"), "{r:?}");
    assert_eq!(vm.position(Axis::Z), 2667);
    ok(&mut vm, "G0 Z-1");
    ok(&mut vm, "G0 X30");
    let r = ok(&mut vm, "G38.3 Z-20 F300");
    assert!(r.iter().any(|l| l.ends_with(":0]")), "{r:?}");
    assert!(refused(&mut vm, "G38.2 Z-21 F300").contains("did not trip"));
    ok(&mut vm, "M999");
    // G10 L1 writes the table (and EEPROM) by hand.
    ok(&mut vm, "G10 L1 P7 Z33.25 R2");
    let tb = table(&vm);
    assert_eq!((tb.length_um(7), tb.diameter_um(7)), (33_250, 4_000));
}

/// docs/SPEC.md §8 in a job: T1, cut, T2, G37, the same cut, T0. The recorded Z of
/// the second cut is higher by exactly the length difference.
#[test]
fn a_job_with_a_change_and_a_measurement_shifts_z_by_the_length_difference() {
    let mut vm = setter_vm();
    calibrate(&mut vm); // T1 is in the spindle, offset applied (work Z = tip Z)
    let cut = |vm: &mut Vm| -> i64 {
        ok(vm, "G0 X30 Y20");
        ok(vm, "G1 Z-40 F300");
        ok(vm, "M400");
        let z = vm.position(Axis::Z);
        ok(vm, "G1 X35 F600");
        ok(vm, "G0 Z-30");
        ok(vm, "M400");
        z
    };
    ok(&mut vm, "M3 S8000");
    let z1 = cut(&mut vm);
    ok(&mut vm, "M5");
    ok(&mut vm, "T2 M6");
    ok(&mut vm, "G37");
    ok(&mut vm, "M3 S8000");
    let z2 = cut(&mut vm);
    ok(&mut vm, "M5");
    ok(&mut vm, "T0 M6");
    let t = tools();
    let true_shift = (t[1].length_mm - t[0].length_mm) * 100.0;
    eprintln!("cut Z with T1 {z1}, with T2 {z2}: shift {} steps, length difference {true_shift:.2} steps", z1 - z2);
    assert!(((z1 - z2) as f64 - true_shift).abs() <= 1.0);
    // Tip at work Z −40 in both cuts (40 mm below home: physical step 4000), within a step.
    assert!(((z1 as f64 + t[0].length_mm * 100.0) - 4000.0).abs() <= 1.0);
    assert!(((z2 as f64 + t[1].length_mm * 100.0) - 4000.0).abs() <= 1.0);
    assert_eq!(vm.atc().spindle, None);
    assert_eq!(vm.atc().pocket_ids()[..4], [1, 2, 3, 4]);
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}
