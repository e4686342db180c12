//! grbl-style `$` settings on the real firmware: list, set (stored in EEPROM
//! at once, as grbl does), refuse nonsense, and drive the motion after a
//! reboot.

mod common;
use common::*;
use sim::Axis;

fn setting(vm: &mut sim::Vm, n: u32) -> String {
    let lines = ok(vm, "$$");
    let prefix = format!("${n}=");
    lines
        .iter()
        .find_map(|l| l.strip_prefix(&prefix))
        .map(|v| v.split(' ').next().unwrap().to_string())
        .unwrap_or_else(|| panic!("${n} not listed: {lines:?}"))
}

#[test]
fn dollar_settings_list_set_persist_and_drive_the_motion() {
    let mut vm = boot();
    let lines = ok(&mut vm, "$$");
    assert_eq!(lines.iter().filter(|l| l.starts_with('$')).count(), 53, "{lines:?}");
    assert_eq!(setting(&mut vm, 100), "100.000");
    assert_eq!(setting(&mut vm, 130), "45.000");

    // Nonsense is refused and changes nothing, in RAM or in EEPROM.
    let eeprom = vm.eeprom();
    for bad in ["$100=-5", "$100=0", "$20=2", "$3=16", "$5=32", "$5=1.5", "$999=1", "$100=abc", "$100", "$"] {
        let e = refused(&mut vm, bad);
        assert!(e.starts_with("Error:$ command:"), "{bad}: {e}");
    }
    assert_eq!(vm.eeprom(), eeprom);
    assert_eq!(setting(&mut vm, 100), "100.000");

    // A change is stored at once and survives a power cycle.
    ok(&mut vm, "$100=80");
    ok(&mut vm, "$131=30");
    assert_ne!(vm.eeprom(), eeprom);
    vm.power_cycle();
    vm.wait_for_start(3.0).unwrap();
    vm.run_for(0.05).unwrap();
    vm.take_lines();
    assert_eq!(setting(&mut vm, 100), "80.000");
    assert_eq!(setting(&mut vm, 131), "30.000");
    // M503 agrees.
    let m503 = ok(&mut vm, "M503").join("\n");
    assert!(m503.contains("M92 X80.000"), "{m503}");

    // And the motion follows: 10 mm on X is now 800 steps; Y travel is 30 mm.
    let x0 = vm.position(Axis::X);
    ok(&mut vm, "M999");
    ok(&mut vm, "G21 G90 G1 X10 F1200");
    ok(&mut vm, "M400");
    assert_eq!(vm.position(Axis::X) - x0, 800);
    let e = refused(&mut vm, "G1 Y35");
    assert!(e.contains("soft limit"), "{e}");
}

/// The settings image's checksum (`config::checksum`, spelled out).
fn image_checksum(b: &[u8]) -> u8 {
    b.iter().fold(0x5Au8, |s, &x| s.rotate_left(1) ^ x)
}

#[test]
fn eeprom_settings_written_before_the_dialect_flags_still_load() {
    // The image as the firmware wrote it before `$153`/`$154` (version 3:
    // the same fields up to M1's flag, then the checksum), made here from
    // today's image with `$100=80`.
    const LEN_V3: usize = 177;
    let mut vm = boot();
    ok(&mut vm, "$100=80");
    ok(&mut vm, "$153=1");
    ok(&mut vm, "$154=0");
    let now = vm.eeprom();
    assert_eq!(now[0], 7, "version 7 now");
    let mut old = now[..LEN_V3].to_vec();
    old[0] = 3;
    old[LEN_V3 - 1] = image_checksum(&old[..LEN_V3 - 1]);
    old.extend_from_slice(&[0xFF, 0xFF]);
    vm.set_eeprom_at(0, &old);
    vm.power_cycle();
    let boot_lines = vm.wait_for_start(3.0).unwrap();
    vm.run_for(0.05).unwrap();
    let boot_lines = [boot_lines, vm.take_lines()].concat();
    assert!(!boot_lines.iter().any(|l| l.contains("EEPROM settings invalid")), "{boot_lines:?}");
    assert_eq!(setting(&mut vm, 100), "80.000", "the old image's values");
    assert_eq!((setting(&mut vm, 153), setting(&mut vm, 154)), ("0".to_string(), "1".to_string()), "the new flags at their defaults");
    let m503 = ok(&mut vm, "M503").join("\n");
    assert!(m503.contains("echo:Dialect: $153=0 (G4 P in seconds) $154=1 (G80 keeps the motion mode)"), "{m503}");

    // The image the firmware wrote before `$10`/`$13` (version 6: two
    // bytes shorter) loads with grbl's defaults for them.
    const LEN_V6: usize = 248;
    ok(&mut vm, "$10=3");
    ok(&mut vm, "$13=1");
    ok(&mut vm, "$182=1.5");
    let now = vm.eeprom();
    let mut old = now[..LEN_V6].to_vec();
    old[0] = 6;
    old[LEN_V6 - 1] = image_checksum(&old[..LEN_V6 - 1]);
    old.extend_from_slice(&[0xFF, 0xFF, 0xFF]);
    vm.set_eeprom_at(0, &old);
    vm.power_cycle();
    vm.wait_for_start(3.0).unwrap();
    vm.run_for(0.05).unwrap();
    assert_eq!(setting(&mut vm, 182), "1.500", "the old image's values");
    assert_eq!((setting(&mut vm, 10), setting(&mut vm, 13)), ("1".to_string(), "0".to_string()));
}
