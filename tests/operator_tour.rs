//! The operator's tour on the real ELF: the screens of the menu that the
//! other walks (`tests/ui.rs`, `tests/setter_menu.rs`, `tests/builder.rs`)
//! pass without a picture, reached with the encoder and the button alone
//! and a card built by `fatfs`. Each screen is checked by its text, by what
//! the machine did, and against its reviewed golden PNG
//! (`tests/golden/tour_*.png`).

mod common;
#[path = "common/panel.rs"]
mod panel;
use common::*;
use panel::{golden, press, redraw, screen, turn};
use sim::{Axis, CardKind, FatKind, SdCard, SdImage, Vm};

/// Back and forth along X with the spindle on, long enough to open menus
/// while it runs.
fn job() -> String {
    let mut s = String::from("G21 G90\nM3 S8000\nG1 Z-1 F300\n");
    for i in 0..30 {
        s += &format!("G1 X{} F600\n", if i % 2 == 0 { 20 } else { 2 });
    }
    s + "G0 Z5\nM5\nM2\n"
}

/// T1 and T2 in the carousel, an optical setter, a card with one job.
fn machine() -> Vm {
    let mut vm = boot_with(tools_and_setter());
    let img = SdImage::new(FatKind::Fat16).file("FACE_MILL.NC", job().as_bytes());
    vm.insert_sd(SdCard::new(img.build(), CardKind::Sdhc));
    redraw(&mut vm);
    vm
}

/// The screen's rows from `from` on, then its golden picture `tour_<name>`.
fn shot(vm: &Vm, name: &str, from: usize, rows: &[&str]) {
    let s = screen(vm);
    assert_eq!(s[from..from + rows.len()], *rows, "{name}: {s:?}");
    golden(vm, &format!("tour_{name}"));
}

#[test]
fn every_menu_screen_reached_with_the_encoder_alone() {
    let mut vm = machine();
    // The main menu.
    press(&mut vm);
    shot(&vm, "main_menu", 0, &["[ Menu]", "[ Status]", " Run from SD", " Job", " Jog", " Home", " Tools", " Settings"]);
    // Home › Home all.
    turn(&mut vm, 4);
    press(&mut vm);
    shot(&vm, "home_menu", 0, &["[ Home]", "[ < Back]", " Home all", " Home Z", " Home Y", " Home X"]);
    turn(&mut vm, 1);
    press(&mut vm);
    // Homing ends 1 mm (100 steps) off each switch.
    vm.run_until(|v| v.positions()[..3] == [100, 100, 100], 60.0).unwrap();
    vm.run_for(1.0).unwrap();
    redraw(&mut vm);
    // Jog now: one detent is one step (1 mm) of X.
    press(&mut vm);
    turn(&mut vm, 3);
    press(&mut vm);
    turn(&mut vm, 3);
    press(&mut vm);
    let x0 = vm.position(Axis::X);
    turn(&mut vm, 2);
    vm.run_for(0.5).unwrap();
    redraw(&mut vm);
    assert_eq!(vm.position(Axis::X) - x0, 200, "2 mm of X");
    shot(&vm, "jogging", 0, &["[ Jog]", "", " X     3.000 mm", " Step   1.000 mm"]);
    press(&mut vm);
    turn(&mut vm, -10);
    press(&mut vm);
    // Spindle › Speed, then Override.
    turn(&mut vm, 10);
    press(&mut vm);
    turn(&mut vm, 2);
    press(&mut vm);
    turn(&mut vm, 30);
    redraw(&mut vm);
    shot(&vm, "spindle_speed", 0, &["[ Speed]", "", "        3000 rpm"]);
    press(&mut vm);
    turn(&mut vm, 1);
    press(&mut vm);
    turn(&mut vm, -3);
    redraw(&mut vm);
    shot(&vm, "spindle_override", 0, &["[ Spindle override]", "", "          70%"]);
    press(&mut vm);
    assert_eq!(ov(&mut vm, 30), "100,100,70", "the spindle override");
    turn(&mut vm, -10);
    press(&mut vm);
    // Tools › Change tool: the list, "Change to T2?", the change.
    turn(&mut vm, -3);
    press(&mut vm);
    turn(&mut vm, 1);
    press(&mut vm);
    shot(&vm, "pick_tool", 0, &["[ Change tool]", " < Back"]);
    turn(&mut vm, 2);
    press(&mut vm);
    shot(&vm, "ask_tool", 0, &["[ Change to T2?]", "[ No]", " Yes"]);
    turn(&mut vm, 1);
    press(&mut vm);
    vm.run_until(|v| v.atc().spindle.map(|t| t.id) == Some(2), 120.0).unwrap();
    // The change ends with the spindle back at travel height.
    for _ in 0..60 {
        if screen(&vm)[2] != " Tool change" {
            break;
        }
        vm.run_for(0.5).unwrap();
    }
    shot(&vm, "tool_changed", 0, &["[ Change tool]", "", " T2 in spindle"]);
    // The tool table.
    press(&mut vm);
    turn(&mut vm, 3);
    press(&mut vm);
    shot(&vm, "tool_table", 0, &["[ T      L mm     D mm]"]);
    press(&mut vm);
    // Changer › X1: "Teach X1?", No.
    turn(&mut vm, 2);
    press(&mut vm);
    turn(&mut vm, 1);
    press(&mut vm);
    shot(&vm, "teach_point", 0, &["[ Teach X1?]", "[ No]", " Yes"]);
    let before = vm.eeprom();
    press(&mut vm);
    assert_eq!(vm.eeprom(), before, "No stores nothing");
    turn(&mut vm, -10);
    press(&mut vm);
    turn(&mut vm, -10);
    press(&mut vm);
    // Run from SD › the file: "Run FACE_MILL.NC?", Yes.
    turn(&mut vm, -4);
    press(&mut vm);
    turn(&mut vm, 1);
    press(&mut vm);
    shot(&vm, "confirm_run", 0, &["[ Run FACE_MILL.NC?]", "[ No]", " Yes"]);
    turn(&mut vm, 1);
    press(&mut vm);
    vm.run_until(|v| v.spindle_on(), 10.0).unwrap();
    vm.run_for(1.0).unwrap();
    // Job › Feed override, then Abort with its question.
    press(&mut vm);
    turn(&mut vm, 2);
    press(&mut vm);
    shot(&vm, "job_menu", 0, &["[ Job]", "[ < Back]", " Pause", " Abort", " Feed override   100%", " Opt. stop M1     off"]);
    turn(&mut vm, 3);
    press(&mut vm);
    turn(&mut vm, -4);
    redraw(&mut vm);
    shot(&vm, "feed_override", 0, &["[ Feed override]", "", "          80%"]);
    press(&mut vm);
    assert_eq!(ov(&mut vm, 30), "80,100,70", "the feed override");
    turn(&mut vm, -1);
    press(&mut vm);
    shot(&vm, "confirm_abort", 0, &["[ Abort the job?]", "[ No]", " Yes"]);
    turn(&mut vm, 1);
    press(&mut vm);
    vm.run_for(2.0).unwrap();
    redraw(&mut vm);
    assert!(!vm.spindle_on(), "aborted: the spindle is off");
    let s = screen(&vm);
    assert_eq!(s[6], "Aborted", "{s:?}");
    assert!(vm.violations().is_empty(), "{:?}", vm.violations());
}
