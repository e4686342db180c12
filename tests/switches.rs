//! Real switches: homing through hysteresis and contact bounce (issue 14).
//!
//! The virtual machine's switches have hysteresis and bounce by default
//! (`sim::SwitchConfig`); these tests sweep the hysteresis over 0.005–0.2 mm,
//! the bounce, the homing order, a switch already closed at power-on and a
//! switch that is never found, and check machine zero to the step and that
//! no alarm is raised.

mod common;

use common::*;
use sim::{Axis, Input, SwitchConfig, SwitchModel, VmConfig};

fn cfg(start: [i64; 3], switches: SwitchConfig) -> VmConfig {
    let mut cfg = VmConfig::default();
    cfg.machine.initial_position = [start[0], start[1], start[2], 0];
    cfg.machine.switches = switches;
    cfg
}

/// Home `cmd` and check: `ok`, no alarm, no error, every homed axis at its
/// pull-off (1 mm = 100 steps) from where its switch closes, and M114 saying
/// the same.
fn homes_exactly(vm: &mut sim::Vm, cmd: &str, axes: &[Axis]) {
    let r = ok(vm, cmd);
    assert!(!r.iter().any(|l| l.contains("ALARM") || l.contains("larm")), "{cmd}: {r:?}");
    for &a in axes {
        assert_eq!(vm.position(a), 100, "{cmd}: {a} is not 1 mm from its switch's closing point");
    }
    vm.send("?");
    let st = vm.wait_line(|l| l.starts_with('<'), 5.0).unwrap();
    assert!(st.starts_with("<Idle"), "{cmd}: {st}");
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}

#[test]
fn default_switches_have_hysteresis_and_bounce() {
    let s = SwitchConfig::default();
    for m in s.home {
        assert!(m.hysteresis >= 0.005 && m.hysteresis <= 0.2 && m.bounce_s > 0.0, "{m:?}");
    }
    assert!(s.carousel.hysteresis > 0.0 && s.carousel.bounce_s > 0.0);
    assert_eq!(VmConfig::default().machine.switches, s);
}

#[test]
fn g28_homes_through_hysteresis_from_0_005_to_0_2_mm_with_bounce() {
    for (i, h) in [0.005, 0.02, 0.05, 0.1, 0.2].into_iter().enumerate() {
        let sw = SwitchConfig { seed: 100 + i as u64, ..SwitchConfig::home_switches(h, 0.004) };
        let mut vm = boot_with(cfg([1500, 1200, 900], sw));
        homes_exactly(&mut vm, "G28", &[Axis::X, Axis::Y, Axis::Z]);
        // The switch really bounced and really has the hysteresis: it
        // closed twice (seek, locate) and opened twice per axis.
        for inp in [Input::HomeX, Input::HomeY, Input::HomeZ] {
            assert_eq!(vm.physics().transitions(inp), 4, "h {h}: {inp:?}");
        }
        // A move after homing raises no hard limit.
        ok(&mut vm, "G0 X10 Y10 Z-10");
        ok(&mut vm, "M400");
        assert_eq!(vm.positions()[..3], [1000, 1000, 1000], "h {h}");
    }
}

#[test]
fn homing_every_order_and_single_axes_through_real_switches() {
    let sw = SwitchConfig::home_switches(0.2, 0.005);
    let mut vm = boot_with(cfg([700, 800, 900], sw));
    homes_exactly(&mut vm, "G28 X", &[Axis::X]);
    homes_exactly(&mut vm, "G28 Y", &[Axis::Y]);
    homes_exactly(&mut vm, "G28 Z", &[Axis::Z]);
    homes_exactly(&mut vm, "G28 X Y", &[Axis::X, Axis::Y]);
    homes_exactly(&mut vm, "$H", &[Axis::X, Axis::Y, Axis::Z]);
    ok(&mut vm, "G0 X20 Y30 Z-5");
    homes_exactly(&mut vm, "G28", &[Axis::X, Axis::Y, Axis::Z]);
}

#[test]
fn homing_starts_on_a_closed_switch() {
    // X at its switch, Y 0.1 mm past it (inside any hysteresis), Z far.
    for start in [[0, -10, 900], [-10, 0, 0], [0, 0, 0]] {
        let mut vm = boot_with(cfg(start, SwitchConfig::home_switches(0.1, 0.003)));
        homes_exactly(&mut vm, "G28", &[Axis::X, Axis::Y, Axis::Z]);
    }
    // Homing Z alone while X and Y rest on their closed switches: no hard
    // limit from the others during the cycle.
    let mut vm = boot_with(cfg([0, 0, 900], SwitchConfig::home_switches(0.1, 0.003)));
    homes_exactly(&mut vm, "G28 Z", &[Axis::Z]);
}

#[test]
fn a_switch_never_found_fails_homing_with_its_alarm_not_a_hard_limit() {
    let mut vm = boot_with(cfg([1500, 1200, 900], SwitchConfig::default()));
    vm.set_input(Input::HomeY, Some(false));
    let r = vm.command("G28").unwrap();
    assert!(r.iter().any(|l| l.contains("homing failed")), "{r:?}");
    assert!(!r.iter().any(|l| l.contains("hard limit")), "{r:?}");
    // Z homed before Y failed; Y ran its whole search past the switch.
    assert_eq!(vm.position(Axis::Z), 100);
    assert!(vm.position(Axis::Y) < 0);
}

#[test]
fn machine_zero_repeats_to_the_step_over_ten_homings() {
    let sw = SwitchConfig::home_switches(0.05, 0.003);
    let mut vm = boot_with(cfg([1500, 1200, 900], sw));
    ok(&mut vm, "G28");
    let mut zeros = Vec::new();
    for i in 0..10 {
        ok(&mut vm, &format!("G0 X{} Y{} Z-{}", 5 + i, 7 + 2 * i, 3 + i));
        homes_exactly(&mut vm, "G28", &[Axis::X, Axis::Y, Axis::Z]);
        // The firmware's machine 0 is the step where the switch closed on
        // the locate seek: the recorder's physical position, less 1 mm.
        zeros.push(vm.positions());
    }
    assert!(zeros.iter().all(|z| z[..3] == [100, 100, 100]), "{zeros:?}");
}

#[test]
fn ideal_switches_are_still_available() {
    let mut vm = boot_with(cfg([1500, 1200, 900], SwitchConfig::ideal()));
    homes_exactly(&mut vm, "G28", &[Axis::X, Axis::Y, Axis::Z]);
    let _ = SwitchModel::IDEAL;
}

#[test]
fn a_pull_off_shorter_than_the_hysteresis_fails_homing_instead_of_a_later_hard_limit() {
    let mut vm = boot_with(cfg([1500, 1200, 900], SwitchConfig::home_switches(0.2, 0.003)));
    ok(&mut vm, "$27=0.1");
    let r = vm.command("G28 Z").unwrap();
    assert!(r.iter().any(|l| l == "ALARM:homing failed"), "{r:?}");
    assert!(!r.iter().any(|l| l.contains("hard limit")), "{r:?}");
    // 0.1 mm is enough for 0.05 mm of hysteresis.
    vm.set_switches(SwitchConfig::home_switches(0.05, 0.003));
    let r = ok(&mut vm, "G28 Z");
    assert!(!r.iter().any(|l| l.contains("ALARM")), "{r:?}");
    assert_eq!(vm.position(Axis::Z), 10);
}

#[test]
fn a_hard_limit_still_trips_after_homing_through_real_switches() {
    let mut vm = boot_with(cfg([1500, 1200, 900], SwitchConfig::default()));
    ok(&mut vm, "G28");
    // The switch closes outside homing (an obstacle, a lost step).
    vm.set_input(Input::HomeX, Some(true));
    vm.send_line("G1 X20 F600");
    let l = vm.wait_line(|l| l.starts_with("ALARM"), 10.0).unwrap();
    assert_eq!(l, "ALARM:hard limit");
}

#[test]
fn the_carousel_homes_through_hysteresis_and_bounce_to_the_exact_step() {
    for (start, h) in [(1000, 0.5), (3190, 2.0), (5, 2.0)] {
        let mut c = VmConfig::default();
        c.machine.initial_position = [1500, 1200, 900, start];
        c.machine.switches.carousel = SwitchModel { hysteresis: h, bounce_s: 0.005 };
        let mut vm = boot_with(c);
        let r = ok(&mut vm, "G205 P0");
        assert!(!r.iter().any(|l| l.contains("ALARM")), "{r:?}");
        // Carousel 0 is the step where the switch closes on the slow seek:
        // a whole number of revolutions (3200 steps) from the model's 0°.
        let e = vm.position(Axis::E);
        assert_eq!(e.rem_euclid(3200), 0, "start {start}, h {h}°: E at {e}");
        let r = ok(&mut vm, "G203 P0");
        assert!(r.iter().any(|l| l.starts_with("Motor0 Pos:0.000")), "{r:?}");
        assert!(vm.physics().transitions(Input::CarouselHome) >= 3, "start {start}");
    }
}
