//! Canned drilling cycles on the real firmware (issue 13 item 4), in the
//! virtual machine: each cycle is checked against the PHYSICAL Z motion the
//! recorder saw, not only the firmware's replies.
//!
//! The recorder's Z steps count downward from the top switch (physical Z
//! step 500 is G-code machine Z −5 mm, 100 steps/mm); after `boot_homed` the
//! work offsets are zero, so G-code `Z-8` is physical step 800.

mod common;
#[path = "common/motion.rs"]
mod motion_util;

use common::*;
use motion_util::*;
use sim::{Axis, Vm};

/// Physical Z step of a G-code Z (work = machine here), mm.
fn zp(user_z: f64) -> i64 {
    mm_to_steps(user_to_physical_mm([0.0, 0.0, user_z]))[2]
}

/// The recorded Z steps since the last mark: (VM cycle, physical position).
fn z_steps(vm: &Vm) -> Vec<(u64, i64)> {
    vm.recorder().trace().iter().filter(|t| t.axis == Axis::Z).map(|t| (t.cycle, t.position)).collect()
}

/// Physical Z positions where Z turned around, and the last one: the
/// depths and heights of a cycle, in order.
fn z_turns(vm: &Vm) -> Vec<i64> {
    let z = z_steps(vm);
    let mut out = Vec::new();
    for w in z.windows(2).collect::<Vec<_>>().windows(2) {
        let (a, b, c) = (w[0][0].1, w[0][1].1, w[1][1].1);
        if (b - a) * (c - b) < 0 {
            out.push(b);
        }
    }
    if let Some(l) = z.last() {
        out.push(l.1);
    }
    out
}

/// X, Y (physical steps) at every deepest point of Z (a turn from down to up).
fn bottoms_xy(vm: &Vm) -> Vec<[i64; 3]> {
    let path = events(vm);
    let mut out = Vec::new();
    for w in path.windows(3) {
        let (a, b, c) = (w[0].position[2], w[1].position[2], w[2].position[2]);
        if b > a && c < b {
            out.push([w[1].position[0], w[1].position[1], b]);
        }
    }
    out
}

/// Z step rate (steps/s) over the middle half of the steps between the
/// physical positions `from` and `to` (exclusive, either direction), the
/// first such stretch after VM cycle `after`.
fn z_rate_between(vm: &Vm, from: i64, to: i64, after: u64) -> f64 {
    let z: Vec<(u64, i64)> = z_steps(vm).into_iter().filter(|s| s.0 > after).collect();
    let start = z.iter().position(|s| s.1 == from + (to - from).signum()).expect("start of the stretch");
    let end = start + z[start..].iter().position(|s| s.1 == to).expect("end of the stretch");
    let n = end - start;
    let (a, b) = (start + n / 4, start + 3 * n / 4);
    (b - a) as f64 / ((z[b].0 - z[a].0) as f64 / 16e6)
}

#[test]
fn g81_retracts_to_the_initial_z_under_g98_and_to_r_under_g99_and_bare_x_y_lines_drill_more_holes() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X5 Y10 Z-5");
    mark(&mut vm);
    ok(&mut vm, "G98 G81 X10 Y10 Z-15 R-8 F300");
    ok(&mut vm, "X15");
    ok(&mut vm, "Y20");
    run(&mut vm, "G99 X20");
    // G98: each hole from Z -5 (500) down to -15 (1500) and back to -5.
    // G99 from there: down to -15, back to R -8 (800) only.
    assert_eq!(z_turns(&vm), vec![1500, 500, 1500, 500, 1500, 500, 1500, 800]);
    assert_eq!(bottoms_xy(&vm), vec![[1000, 1000, 1500], [1500, 1000, 1500], [1500, 2000, 1500], [2000, 2000, 1500]]);
    // X/Y only ever move at the clearance plane (Z -5 here), never in the hole.
    let path = events(&vm);
    for w in path.windows(2) {
        if w[1].position[0] != w[0].position[0] || w[1].position[1] != w[0].position[1] {
            assert_eq!(w[1].position[2], 500, "X/Y moved at Z {}", w[1].position[2]);
        }
    }
    // G99: the next hole travels at R, drills and comes back to R.
    mark(&mut vm);
    run(&mut vm, "X25");
    assert_eq!(z_turns(&vm), vec![1500, 800]);
    for p in events(&vm) {
        assert!(p.position[2] >= 800, "above R at {:?}", p.position);
        if p.position[0] != 2000 && p.position[0] != 2500 {
            assert_eq!(p.position[2], 800, "X moved below R");
        }
    }
    // The plunge is at the feed (F300 = 500 steps/s), the retract a rapid.
    mark(&mut vm);
    let t0 = vm.cycles();
    run(&mut vm, "X30");
    let plunge = z_rate_between(&vm, 800, 1500, t0);
    assert!((plunge - 500.0).abs() < 500.0 * 0.03, "plunge at {plunge:.0} steps/s");
    let retract = z_rate_between(&vm, 1500, 800, t0);
    assert!(retract > 2000.0, "retract at {retract:.0} steps/s, not a rapid");
    // G80 ends it: with `$154=0` a bare X is refused and nothing moves.
    ok(&mut vm, "$154=0");
    ok(&mut vm, "G80");
    mark(&mut vm);
    assert!(refused(&mut vm, "X35").contains("G80"));
    ok(&mut vm, "M400");
    assert_eq!(steps_since_mark(&vm), 0);
    assert_eq!(xyz_now(&vm), [3000, 2000, 800]);
    assert_eq!(m114_work(&mut vm), [30.0, 20.0, -8.0]);
    assert_no_violations(&vm);
}

#[test]
fn g83_pecks_q_deep_with_full_retracts_and_g73_breaks_the_chip_with_short_back_offs() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-5");
    mark(&mut vm);
    // R -8, Z -14, Q 2.5: pecks to -10.5, -13, then -14; out to R between.
    run(&mut vm, "G99 G83 X20 Z-14 R-8 Q2.5 F300");
    let t = z_turns(&vm);
    assert_eq!(t, vec![1050, 800, 1300, 800, 1400, 800]);
    // Three reversals at the bottom of a peck, each at most Q deeper than the last.
    let downs: Vec<i64> = t.iter().copied().step_by(2).collect();
    assert_eq!(downs, vec![zp(-10.5), zp(-13.0), zp(-14.0)]);
    // Back in at rapid to 0.254 mm above the depth reached, then feed: the
    // descent after a retract slows to the feed at 1025 (−10.25) and 1275.
    let z = z_steps(&vm);
    for (above, depth) in [(1025i64, 1050i64), (1275, 1300)] {
        let i = z.iter().position(|s| s.1 == above + 1 && s.0 > 0).unwrap();
        let j = z.iter().skip(i).position(|s| s.1 == depth).unwrap() + i;
        // Steps 5 to 20 before the depth: past the junction, before the stop.
        let rate = 15.0 / ((z[j - 5].0 - z[j - 20].0) as f64 / 16e6);
        assert!((rate - 500.0).abs() < 15.0, "feed after the re-entry at {above}: {rate:.0} steps/s");
    }
    mark(&mut vm);
    run(&mut vm, "G73 X30 Z-14 R-8 Q2.5");
    // Chip break: back off 0.254 mm (rounded to 25 steps) at each peck.
    assert_eq!(z_turns(&vm), vec![1050, 1025, 1300, 1275, 1400, 800]);
    assert_eq!(bottoms_xy(&vm).iter().map(|b| b[0]).collect::<Vec<_>>(), vec![3000, 3000, 3000]);
    assert_no_violations(&vm);
}

#[test]
fn g82_and_g89_dwell_p_seconds_at_the_bottom_and_g85_g89_feed_out() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-5");
    mark(&mut vm);
    run(&mut vm, "G99 G82 X20 Z-15 R-8 P0.5 F300");
    // Z stands still at the bottom for P seconds (simulated), then rapids out.
    let still = |vm: &Vm, bottom: i64| {
        let z = z_steps(vm);
        let i = z.iter().position(|s| s.1 == bottom).unwrap();
        (z[i + 1].0 - z[i].0) as f64 / 16e6
    };
    let d = still(&vm, 1500);
    eprintln!("G82 P0.5: Z still {d:.4} s at the bottom");
    assert!((0.5..0.56).contains(&d), "G82 P0.5 stood {d:.3} s");
    assert_eq!(z_turns(&vm), vec![1500, 800]);
    // G85: feed in and feed out, both at F120 (200 steps/s).
    mark(&mut vm);
    let t0 = vm.cycles();
    run(&mut vm, "G85 X30 Z-15 R-8 F120");
    let down = z_rate_between(&vm, 800, 1500, t0);
    let up = z_rate_between(&vm, 1500, 800, t0);
    eprintln!("G85 F120: in {down:.1}, out {up:.1} steps/s (200 expected)");
    assert!((down - 200.0).abs() < 6.0 && (up - 200.0).abs() < 6.0, "G85 in {down:.0}, out {up:.0} steps/s");
    // G89 under G98 from Z -5: dwell, then feed all the way out to the initial level.
    run(&mut vm, "G0 Z-5");
    mark(&mut vm);
    let t0 = vm.cycles();
    run(&mut vm, "G98 G89 X40 Z-15 R-8 P0.25 F120");
    let d = still(&vm, 1500);
    eprintln!("G89 P0.25: Z still {d:.4} s at the bottom");
    assert!((0.25..0.31).contains(&d), "G89 P0.25 stood {d:.3} s");
    let up = z_rate_between(&vm, 1500, 500, t0);
    assert!((up - 200.0).abs() < 6.0, "G89 out at {up:.0} steps/s");
    assert_eq!(z_turns(&vm), vec![1500, 500]);
    assert_no_violations(&vm);
}

#[test]
fn g91_l_drills_a_row_and_inches_convert_every_word() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-5");
    mark(&mut vm);
    // R 3 mm below the start (-8), Z 7 mm below R (-15), 5 mm apart, 4 holes.
    run(&mut vm, "G91 G99 G81 X5 Y2 R-3 Z-7 L4 F300");
    assert_eq!(bottoms_xy(&vm), vec![[1500, 1200, 1500], [2000, 1400, 1500], [2500, 1600, 1500], [3000, 1800, 1500]]);
    assert_eq!(z_turns(&vm), vec![1500, 800, 1500, 800, 1500, 800, 1500, 800]);
    run(&mut vm, "G90 G80");
    // G20: X 1.5 in, R -0.3 in, Z -0.5 in, Q 0.1 in.
    run(&mut vm, "G20 G0 Z-0.2");
    mark(&mut vm);
    run(&mut vm, "G98 G83 X1.5 Y1 Z-0.5 R-0.3 Q0.1 F10");
    assert_eq!(z_turns(&vm), vec![1016, 762, 1270, 508]);
    assert_eq!(bottoms_xy(&vm).iter().map(|b| [b[0], b[1]]).collect::<Vec<_>>(), vec![[3810, 2540], [3810, 2540]]);
    run(&mut vm, "G21 G80");
    assert_no_violations(&vm);
}

#[test]
fn a_bad_cycle_line_is_refused_whole_and_nothing_moves() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-5");
    mark(&mut vm);
    for (line, why) in [
        ("G81 X20 Z-15 F300", "R missing"),
        ("G81 X20 R-8 F300", "Z missing"),
        ("G83 X20 Z-15 R-8 Q0 F300", "Q (peck depth) must be positive"),
        ("G81 X20 Z-6 R-8 F300", "Z is above R"),
        ("G18 G81 X20 Z-15 R-8 F300", "G18 (ZX)"),
        ("G81 X20 Z-60 R-8 F300", "soft limit"),
        ("G84 X20 Z-15 R-8 F300", "canned cycle not supported"),
    ] {
        let e = refused(&mut vm, line);
        assert!(e.contains(why), "{line}: {e}");
    }
    ok(&mut vm, "M400");
    assert_eq!(steps_since_mark(&vm), 0);
    // Nothing changed: a bare X is still a rapid (G0 modal), in G17, mm.
    run(&mut vm, "X12");
    assert_eq!(xyz_now(&vm), [1200, 1000, 500]);
}

#[test]
fn feed_hold_and_m112_work_in_the_middle_of_a_long_cycle_line() {
    let mut vm = boot_homed();
    run(&mut vm, "G0 X10 Y10 Z-5");
    mark(&mut vm);
    // 10 holes of 4 pecks each, one line: many more moves than the planner holds.
    vm.send_line("G91 G99 G83 X3 R-3 Z-7 Q2 L10 F600");
    vm.run_for(1.5).unwrap();
    vm.send(b"?");
    let st = vm.wait_line(|l| l.starts_with('<'), 0.5).expect("status during the cycle line");
    assert!(st.starts_with("<Run|"), "{st}");
    vm.send(b"!");
    vm.run_for(0.3).unwrap();
    let held = xyz_now(&vm);
    vm.run_for(0.5).unwrap();
    assert_eq!(xyz_now(&vm), held, "moved during the hold");
    vm.send(b"~");
    vm.wait_line(|l| l == "ok", 60.0).expect("ok after the cycle");
    ok(&mut vm, "M400");
    assert_eq!(xyz_now(&vm), [4000, 1000, 800]);
    assert_eq!(bottoms_xy(&vm).iter().filter(|b| b[2] == 1500).count(), 10);
    // Busy keepalives went out while the line ran.
    assert!(vm.output().contains("busy:processing"));
    eprintln!("stack high water after a 40-peck cycle line: {:?} B", vm.stack_high_water_bytes());
    // M112 in the middle of another long cycle line: the line ends with an
    // error and the alarm, no step after.
    run(&mut vm, "G90 G0 X10 Z-5");
    vm.send_line("G91 G99 G83 X2 R-3 Z-7 Q2 L10 F600");
    vm.run_for(1.0).unwrap();
    let sent = vm.cycles();
    vm.send(b"M112\n");
    vm.wait_line(|l| l == "ALARM:emergency stop", 0.2).expect("alarm");
    vm.wait_line(|l| l.starts_with("Error:alarm"), 0.5).expect("the cycle line fails");
    let last = vm.recorder().trace().last().unwrap().cycle;
    assert!(last < sent + 16_000 * 5, "steps {} ms after M112", (last - sent) / 16_000);
    let stopped = xyz_now(&vm);
    vm.run_for(0.5).unwrap();
    assert_eq!(xyz_now(&vm), stopped);
    assert_no_violations(&vm);
}
