//! RS274/NGC as CAM posts write it (issue 13), on the real firmware in the
//! virtual machine: full circles from any start, the preamble codes, line
//! numbers without checksums, coolant on D9, M1 optional stop. Tool
//! selection (`T` then `M6`) is in `tests/atc.rs`. Each check reads the
//! recorded steps or the output pin, not only the replies.

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;

const TWO_PI: f64 = 2.0 * std::f64::consts::PI;
/// Chord tolerance + 1 step, per axis (see `check_arc`).
const ARC_DEV: f64 = ARC_TOL_MM * SPMM + 1.0;

/// Issue 13 item 1: arcs whose end is their start are full circles, in
/// every plane, both ways, from off-grid starts (36 centre angles, one per
/// arc), radii 0.05 mm to 20 mm, some helical, some ends within half a step
/// of the start; the reported 0.8 mm circle first. Every step must lie on the
/// circle (tolerance + 1 step), the sweep must be a whole turn, the farthest
/// point 2r from the start. 37 arcs in one boot, 6 of them 20 mm ones.
#[test]
fn full_circles_in_every_plane_and_direction_from_off_grid_starts() {
    let mut vm = boot_homed();
    // The reported case (5 mm below the top).
    run(&mut vm, "G17 G0 X18.087536 Y33.329412 Z-5");
    mark(&mut vm);
    run(&mut vm, "G3 X18.087536 Y33.329412 I-0.4 J-0.69282 F600");
    let start = mm_to_steps(user_to_physical_mm([18.087536, 33.329412, -5.0]));
    let c = [(18.087536 - 0.4) * SPMM, (33.329412 - 0.69282) * SPMM];
    let got = check_arc(&vm, (0, 1, 2), c, 80.0, start, start, ARC_DEV);
    assert!((got.swept - TWO_PI).abs() < 0.05, "reported case swept {} rad", got.swept);

    let radii = [0.05f64, 0.1, 0.3, 0.8, 2.0, 20.0];
    let letters = ["X", "Y", "Z"];
    let offsets = ["I", "J", "K"];
    // Centre (user frame, +Z up) and the physical sign of each axis (Z steps
    // count downward from the top switch).
    let cu = [22.5f64, 22.5, -22.5];
    let flip = |a: usize| if a == 2 { -1.0 } else { 1.0 };
    for k in 0..36usize {
        let (code, plane) = [("G17", (0usize, 1usize, 2usize)), ("G18", (2, 0, 1)), ("G19", (1, 2, 0))][k % 3];
        let cw = (k / 3) % 2 == 0;
        let r = radii[(k / 6) % 6];
        let (a0, a1, al) = plane;
        let t = ((k * 10 + 3) as f64).to_radians();
        let mut s = cu;
        s[a0] = cu[a0] + r * t.cos();
        s[a1] = cu[a1] + r * t.sin();
        s[al] = 10.0 * flip(al);
        let mut e = s;
        if k % 4 == 1 {
            e[al] += 0.5; // helical
        }
        let steps = |v: f64| (v * SPMM).round();
        if k % 5 == 2 && steps(s[a0] + 0.002) == steps(s[a0]) {
            e[a0] += 0.002; // within the start's step
        }
        run(&mut vm, &format!("{code} G0 X{:.6} Y{:.6} Z{:.6}", s[0], s[1], s[2]));
        mark(&mut vm);
        let mut line = (if cw { "G2" } else { "G3" }).to_string();
        for a in 0..3 {
            line += &format!(" {}{:.6}", letters[a], e[a]);
        }
        line += &format!(" {}{:.6} {}{:.6} F3000", offsets[a0], cu[a0] - s[a0], offsets[a1], cu[a1] - s[a1]);
        run(&mut vm, &line);
        let start = mm_to_steps(user_to_physical_mm(s));
        let end = mm_to_steps(user_to_physical_mm(e));
        let c = [cu[a0] * SPMM * flip(a0), cu[a1] * SPMM * flip(a1)];
        let got = check_arc(&vm, plane, c, r * SPMM, start, end, ARC_DEV);
        // G2 is clockwise seen from the plane's +normal, in the user's frame.
        let swept = got.swept * flip(a0) * flip(a1);
        let want = if cw { -TWO_PI } else { TWO_PI };
        // Small circles are a few steps across: the step path's sweep is coarse.
        let slack = if r < 0.2 { 0.8 } else { 0.05 };
        assert!((swept - want).abs() < slack, "{line}: swept {swept} rad");
        let far = events(&vm)
            .iter()
            .map(|p| {
                let q = xyz(p);
                ((q[a0] - start[a0] as f64).powi(2) + (q[a1] - start[a1] as f64).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        assert!(
            (far - 2.0 * r * SPMM).abs() <= 1.5 + ARC_TOL_MM * SPMM,
            "{line}: farthest point {far} steps from the start, want {}",
            2.0 * r * SPMM
        );
    }
    assert_no_violations(&vm);
    eprintln!("simulated {:.1} s", vm.cycles() as f64 / 16e6);
}

/// Issue 13 item 2: the preamble lines of the corpus run; the rest of each
/// line stays in force (`g20 g64` sets inches, `G40 G1 X25 Y10` moves).
#[test]
fn preamble_codes_are_accepted_and_their_lines_run() {
    let mut vm = boot_homed();
    for l in [
        "G17 G20 G40 G90",
        "G64 P0.00040 ( set maximum deviation from commanded toolpath )",
        "G61 (exact path mode)",
        "G61.1",
        "G91.1     (Incremental arc distance mode.)",
        "G80 (cancel modal motion)",
        "G92.1",
        "O1001",
        "O0000(3 HEATSINK PROFILE)",
        "G21",
    ] {
        ok(&mut vm, l);
    }
    ok(&mut vm, "g20 g64");
    run(&mut vm, "G1 X0.5 Y0.5 F20");
    assert_eq!(xyz_now(&vm), [1270, 1270, 100], "inches");
    run(&mut vm, "G21 G40 G1 X25 Y10 F600");
    assert_eq!(xyz_now(&vm), [2500, 1000, 100]);
    // Blanks inside a number, a block number without a checksum.
    run(&mut vm, "N0070 G1 X1 6.5 Y 1 2");
    assert_eq!(xyz_now(&vm), [1650, 1200, 100]);
    // G90.1: absolute centre, a quarter circle about (20, 12).
    mark(&mut vm);
    run(&mut vm, "G90.1 G3 X20 Y8.5 I20 J12");
    let got = check_arc(&vm, (0, 1, 2), [2000.0, 1200.0], 350.0, [1650, 1200, 100], [2000, 850, 100], ARC_DEV);
    assert!((got.swept - TWO_PI / 4.0).abs() < 0.05, "{got:?}");
    ok(&mut vm, "G91.1");
    // Refused, each by name, and nothing moves (`$154=0`: G80 as LinuxCNC
    // has it, so that `G80 X1` is refused for its G80).
    ok(&mut vm, "$154=0");
    let n = vm.recorder().trace().len();
    for (l, what) in [
        ("G18 G41 D1", "only in the XY plane"),
        ("#100=10.0 (outside feed)", "# parameters"),
        ("G1 X#1", "# parameters"),
        ("o100 sub", "O-word"),
        ("G0 X3. A0.", "X Y Z only"),
        ("G80 X1", "G80"),
    ] {
        let e = refused(&mut vm, l);
        assert!(e.contains(what), "{l}: {e}");
    }
    ok(&mut vm, "M400");
    assert_eq!(vm.recorder().trace().len(), n, "a refused line moved");
    assert_no_violations(&vm);
}

/// Issue 13 item 3: M7/M8 switch D9 (PH6) on after the moves before them,
/// M9 off; M2, M30, M112 and alarms switch it off.
#[test]
fn coolant_on_d9_follows_m7_m8_m9_and_goes_off_at_end_and_alarms() {
    let mut vm = boot_homed();
    assert!(!vm.coolant_on());
    ok(&mut vm, "G1 X20 F600");
    ok(&mut vm, "M8");
    assert!(vm.coolant_on());
    // Switched on only once the move before it had finished.
    let on_at = vm.coolant_history().last().unwrap().0;
    let last_step = vm.recorder().trace().last().unwrap().cycle;
    assert!(on_at > last_step, "coolant on at {on_at}, the move ended at {last_step}");
    ok(&mut vm, "M9");
    assert!(!vm.coolant_on());
    ok(&mut vm, "M7");
    assert!(vm.coolant_on());
    ok(&mut vm, "M2");
    assert!(!vm.coolant_on(), "M2");
    ok(&mut vm, "S1000 M3 M8");
    assert!(vm.coolant_on() && vm.spindle_on());
    ok(&mut vm, "M30");
    assert!(!vm.coolant_on() && !vm.spindle_on(), "M30");
    ok(&mut vm, "M8");
    let r = vm.command("M112").unwrap();
    assert!(r.iter().any(|l| l.contains("ALARM:emergency stop")), "{r:?}");
    assert!(!vm.coolant_on(), "M112");
    assert!(refused(&mut vm, "M8").contains("alarm"));
    assert!(!vm.coolant_on());
    ok(&mut vm, "M9");
    ok(&mut vm, "M999");
    ok(&mut vm, "G28");
    ok(&mut vm, "M8");
    assert!(vm.coolant_on());
    // A hard limit: drive X into its switch with soft limits off.
    ok(&mut vm, "$20=0");
    vm.command("G53 G1 X-2 F600").unwrap();
    vm.command("M400").unwrap();
    assert!(vm.output().contains("ALARM:hard limit"), "{}", vm.output());
    assert!(!vm.coolant_on(), "alarm");
    assert_eq!(vm.coolant_history().iter().filter(|h| h.1).count(), 5);
}

/// Issue 13 item 5: M1 is skipped unless optional stop is on (`$152`, or the
/// Job menu); M0 always pauses.
#[test]
fn m1_is_an_optional_stop() {
    let mut vm = boot_homed();
    let r = ok(&mut vm, "M1");
    assert!(!r.iter().any(|l| l.contains("paused")), "{r:?}");
    ok(&mut vm, "$152=1");
    vm.send_line("M1");
    vm.wait_line(|l| l.contains("paused"), 1.0).expect("M1 pauses with optional stop on");
    vm.send(b"~");
    vm.wait_line(|l| l == "ok", 1.0).expect("resumed");
}
