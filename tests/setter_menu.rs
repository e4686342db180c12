//! Calibrating the tool setter from the menu (Tools › Calibrate setter), on
//! the real ELF: the reference tool's length and diameter set with the
//! encoder, the calibration run as `G37 L R`, the result on the screen and
//! in EEPROM the same as the same calibration over serial.

mod common;
#[path = "common/panel.rs"]
mod panel;
use common::*;
use panel::{golden, press, redraw, screen, turn};
use sim::{Vm, VmConfig};

/// Where the setter record sits in EEPROM, and its length (version, six
/// i32, checksum).
const SETTER_ADDR: usize = 352;
const SETTER_LEN: usize = 26;

/// Homed, T1 (19.5 mm long, 3 mm thick: the reference) in the spindle, an
/// optical setter whose beam is not where the firmware's defaults say.
fn with_reference_tool() -> Vm {
    let mut vm = boot_with(tools_and_setter());
    ok(&mut vm, "G28");
    ok(&mut vm, "T1 M6");
    vm.take_lines();
    vm
}

fn setter_record(vm: &Vm) -> Vec<u8> {
    vm.eeprom()[SETTER_ADDR..SETTER_ADDR + SETTER_LEN].to_vec()
}

/// The value of `key` (`Z:`, `W:`, `L:`) in a `[SETTER …]`/`[TOOL …]` line.
fn field(line: &str, key: &str) -> f64 {
    line.split(' ').find_map(|w| w.strip_prefix(key)).unwrap().trim_end_matches(']').parse().unwrap()
}

#[test]
fn the_setter_is_calibrated_from_the_menu_as_g37_l_r_calibrates_it_over_serial() {
    // The same calibration over serial, for the reference.
    let mut by_line = with_reference_tool();
    let want = ok(&mut by_line, "G37 L19.5 R1.5").into_iter().find(|l| l.starts_with("[SETTER")).unwrap();
    let want_record = setter_record(&by_line);

    let mut vm = with_reference_tool();
    let blank = setter_record(&vm);
    // Menu › Tools › Calibrate setter (the last entry).
    press(&mut vm);
    turn(&mut vm, 5);
    press(&mut vm);
    turn(&mut vm, 8);
    assert_eq!(screen(&vm)[7], "[ Calibrate setter]", "{:?}", screen(&vm));
    press(&mut vm);
    redraw(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[0], "[ Calibrate setter]");
    assert_eq!(s[1..4].join(" ").split_whitespace().collect::<Vec<_>>().join(" "), "Reference tool in the spindle: its length, mm");
    assert_eq!(s[4..8], [" < Back", "[ Value          0.000]", " Step           1.000", " Save"], "{s:?}");
    // 19.5: 19 detents of 1 mm, the step 0.1 (six presses round: 10, 100,
    // 1000, 0.001, 0.01, 0.1), 5 more.
    press(&mut vm);
    turn(&mut vm, 19);
    press(&mut vm);
    turn(&mut vm, 1);
    for _ in 0..6 {
        press(&mut vm);
    }
    turn(&mut vm, -1);
    press(&mut vm);
    turn(&mut vm, 5);
    press(&mut vm);
    redraw(&mut vm);
    assert_eq!(screen(&vm)[5], "[ Value         19.500]", "{:?}", screen(&vm));
    golden(&vm, "setter_reference_length");
    turn(&mut vm, 2);
    press(&mut vm); // Save: the length goes into the setter record
    redraw(&mut vm);
    assert_eq!(screen(&vm)[2], " Ref length    19.500", "{:?}", screen(&vm));
    assert_ne!(setter_record(&vm), blank, "the reference length is stored");
    press(&mut vm);
    redraw(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[1..4].join(" ").split_whitespace().collect::<Vec<_>>().join(" "), "Its diameter, mm. Save: measure it in the beam");
    // 3 mm, then Save: the calibration runs.
    press(&mut vm);
    turn(&mut vm, 3);
    press(&mut vm);
    turn(&mut vm, 2);
    press(&mut vm);
    let line = vm.wait_line(|l| l.starts_with("[SETTER"), 90.0).unwrap();
    assert_eq!(line, want, "the menu's calibration is the serial line's");
    assert_eq!(setter_record(&vm), want_record, "the same setter record in EEPROM");
    redraw(&mut vm);
    let s = screen(&vm);
    assert_eq!(s[0], "[ Calibrate setter]");
    assert_eq!(s[2], format!(" Beam Z{:>14.3}", field(&line, "Z:")), "{s:?}");
    assert_eq!(s[3], format!(" Beam width{:>10.3}", field(&line, "W:")), "{s:?}");
    golden(&vm, "setter_calibrated");
    press(&mut vm);
    assert_eq!(screen(&vm)[7], "[ Calibrate setter]");
    // Measured with it: T2's length as the machine has it.
    ok(&mut vm, "T2 M6");
    let r = ok(&mut vm, "G37").into_iter().find(|l| l.starts_with("[TOOL:2")).unwrap();
    assert!((field(&r, "L:") - 21.3371).abs() < 0.02, "{r}");
}

#[test]
fn a_calibration_the_machine_refuses_says_why_and_stores_no_beam() {
    let mut cfg = VmConfig::default();
    cfg.command_timeout_s = 30.0;
    let mut vm = boot_with(cfg);
    // Not homed: G37 is refused.
    press(&mut vm);
    turn(&mut vm, 5);
    press(&mut vm);
    turn(&mut vm, 8);
    press(&mut vm);
    press(&mut vm);
    turn(&mut vm, 20);
    press(&mut vm);
    turn(&mut vm, 2);
    press(&mut vm);
    redraw(&mut vm);
    press(&mut vm);
    press(&mut vm);
    turn(&mut vm, 3);
    press(&mut vm);
    turn(&mut vm, 2);
    let before = vm.positions();
    press(&mut vm);
    vm.run_for(2.0).unwrap();
    redraw(&mut vm);
    let s = screen(&vm);
    assert!(s[2..7].join(" ").contains("home X Y Z"), "{s:?}");
    assert_eq!(vm.positions(), before, "nothing moved");
    let rec = setter_record(&vm);
    // The reference tool is kept (20 mm, 3 mm); the beam stays uncalibrated
    // (i32::MIN at bytes 9..13).
    assert_eq!(rec[9..13], i32::MIN.to_le_bytes(), "{rec:?}");
    assert_eq!(rec[17..21], 20_000i32.to_le_bytes(), "{rec:?}");
    assert_eq!(rec[21..25], 3_000i32.to_le_bytes(), "{rec:?}");
}
