//! A machine builder's setup, on the real firmware: what differs from one
//! mill to the next is set over serial (`$` settings) and stored, with no
//! recompile.
//!
//! Normally-closed switches: every input of the virtual machine wired the
//! other way (`MachineConfig::inverted_inputs`), then `$5` tells the
//! firmware. Homing, hard limits, `M119`, `?`'s `Pn:`, the carousel's home
//! switch (a tool change) and the tool setter (`G37`) all read them right,
//! checked on the recorded steps.

mod common;
use common::*;
use sim::{Axis, Input, OpticalBeam, ToolSetter, Vm, VmConfig};

/// Every switch normally-closed and the setter's output inverted: the
/// electrical level of each input is the opposite of the stock machine's.
fn inverted_machine() -> VmConfig {
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = 120.0;
    cfg.machine.inverted_inputs = 0b1_1111;
    cfg.machine.tool_setter = ToolSetter::Optical(OpticalBeam::demo());
    cfg
}

/// The inputs in M119's order.
const INPUTS: [Input; 5] = [Input::HomeX, Input::HomeY, Input::HomeZ, Input::CarouselHome, Input::ToolSetter];

/// M119's five lines as (name, triggered).
fn m119(vm: &mut Vm) -> Vec<(String, bool)> {
    ok(vm, "M119")
        .iter()
        .filter_map(|l| l.split_once(": ").map(|(n, v)| (n.to_string(), v == "TRIGGERED")))
        .collect()
}

#[test]
fn normally_closed_inputs_work_everywhere_once_dollar_5_says_so() {
    let mut vm = boot_with(inverted_machine());
    // As wired, with the stock setting, every input reads the opposite of
    // what it is: the switches untouched read triggered, the carousel's,
    // closed at home, reads open. The builder sees it in M119 and sets $5.
    let physical = |vm: &Vm| INPUTS.map(|i| vm.input_active(i)).to_vec();
    let before = m119(&mut vm);
    assert_eq!(before.len(), 5, "{before:?}");
    let truth = physical(&vm);
    assert_eq!(truth, [false, false, false, true, false], "the machine at power-on: only the carousel at home");
    assert_eq!(before.iter().map(|(_, t)| !*t).collect::<Vec<_>>(), truth, "with $5=0 every input reads inverted: {before:?}");

    ok(&mut vm, "$5=31");
    let after = m119(&mut vm);
    assert_eq!(after.iter().map(|(_, t)| *t).collect::<Vec<_>>(), truth, "with $5=31 each input reads as it is: {after:?}");
    assert!(!status(&mut vm).contains("Pn:X"), "{}", status(&mut vm));
    // Stored: M503 shows it, and it survives a power cycle.
    assert!(ok(&mut vm, "M503").iter().any(|l| l == "$5=31"));

    // Homing through the inverted switches ends 1 mm off each, as on the
    // stock machine.
    ok(&mut vm, "G28");
    assert_eq!(steps(&vm)[..3], [100, 100, 100]);

    // The carousel's home switch: a tool change homes the carousel, takes
    // T3 from its pocket, and the changer model sees no collision.
    ok(&mut vm, "T3 M6");
    assert_eq!(vm.atc().spindle.map(|t| t.id), Some(3));
    assert!(vm.atc().collisions.is_empty(), "{:?}", vm.atc().collisions);

    // The tool setter: G37 measures T3 (the demo changer's tool n is
    // 18 + 1.5 n mm long, 1 + 0.5 n across) against the beam.
    let r = ok(&mut vm, "G37 L22.5 R1.25");
    assert!(r.iter().any(|l| l.starts_with("[SETTER Z:-48.0")), "{r:?}");

    // A hard limit: soft limits off, X driven into its switch. The switch
    // opens (an NC switch triggers by opening): the alarm stops X there.
    ok(&mut vm, "G53 G0 Z-1");
    ok(&mut vm, "G53 G0 X5 Y5");
    ok(&mut vm, "$20=0");
    vm.command("G53 G1 X-3 F600").unwrap();
    settle(&mut vm, 0.5);
    let s = status(&mut vm);
    assert!(s.starts_with("<Alarm"), "{s}");
    assert!(s.contains("Pn:X"), "the closed switch in Pn: {s}");
    let x = vm.position(Axis::X);
    assert!((-30..=5).contains(&x), "X stopped at the switch, not at the target: {x}");

    // After a power cycle the setting is still there.
    vm.power_cycle();
    settle(&mut vm, 0.5);
    ok(&mut vm, "M999");
    assert!(!vm.input_level(Input::HomeY), "the NC switch holds its pin low while untouched");
    let m = m119(&mut vm);
    let triggered: Vec<bool> = m.iter().map(|(_, t)| *t).collect();
    assert_eq!(triggered, physical(&vm), "after the power cycle each input still reads as it is: {m:?}");
}

#[test]
fn a_broken_wire_on_a_normally_closed_switch_reads_triggered() {
    // The X switch's wire cut: its pin floats high on the pull-up, as an
    // NC switch that opened. With $5 set for NC switches that reads
    // "triggered", and homing X finds its switch at once instead of
    // driving into the frame.
    let mut vm = boot_with(inverted_machine());
    ok(&mut vm, "$5=31");
    vm.set_input(Input::HomeX, Some(true));
    assert!(vm.input_level(Input::HomeX), "a cut wire: the pull-up holds the pin high");
    let m = m119(&mut vm);
    assert_eq!(m[0], ("x_min".to_string(), true), "{m:?}");
    let before = vm.position(Axis::X);
    let _ = vm.command("$HX");
    settle(&mut vm, 0.5);
    assert!(vm.position(Axis::X) >= before - 10, "X drove {} steps toward a switch that reads closed", before - vm.position(Axis::X));
}
