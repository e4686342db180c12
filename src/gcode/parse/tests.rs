//! Host tests of the parser: every code and word, the number lexer against
//! its reference, the errors and their columns.

use super::number::{blank_then, lex_number, lex_plain, lex_spaced, Number, MAX_INT_DIGITS, MAX_SIG_DIGITS};
use super::*;
use crate::gcode::cycles::{Kind, Retract};

fn ok(s: &str) -> Line {
    match parse(s.as_bytes()) {
        Ok(l) => l,
        Err(e) => panic!("{:?} rejected: {:?}", s, e),
    }
}

fn fails(s: &str) -> (ParseErrorKind, u8) {
    match parse(s.as_bytes()) {
        Ok(l) => panic!("{:?} accepted: {:?}", s, l),
        Err(e) => (e.kind, e.col),
    }
}

fn x(s: &str) -> f32 {
    ok(s).word(Word::X).unwrap()
}

/// The number lexer spelled out on decimal text, the reference the
/// one-pass lexer must match: the digits are gathered as characters
/// (blanks inside the number skipped as RS274/NGC says), then cut to
/// [`MAX_SIG_DIGITS`] significant digits with half-up rounding on the
/// digit text, and only then turned into a mantissa and a scale.
fn reference_lex_number(s: &[u8], pos: usize, col: u8) -> Result<(Number, usize), ParseError> {
    let mut pos = skip_blanks(s, pos);
    let mut negative = false;
    match s.get(pos) {
        Some(b'-') => {
            negative = true;
            pos += 1;
        }
        Some(b'+') => pos += 1,
        _ => {}
    }
    pos = skip_blanks(s, pos);
    if matches!(s.get(pos), Some(b'#' | b'[')) {
        return err(ParseErrorKind::Parameter, col);
    }
    let mut int = String::new();
    let mut frac = String::new();
    loop {
        match s.get(pos) {
            Some(c @ b'0'..=b'9') => {
                int.push(*c as char);
                pos += 1;
            }
            _ => match blank_then(s, pos, true) {
                Some(next) => pos = next,
                None => break,
            },
        }
    }
    let point = s.get(pos) == Some(&b'.');
    if point {
        pos += 1;
        loop {
            match s.get(pos) {
                Some(c @ b'0'..=b'9') => {
                    frac.push(*c as char);
                    pos += 1;
                }
                _ => match blank_then(s, pos, false) {
                    Some(next) => pos = next,
                    None => break,
                },
            }
        }
    }
    if int.is_empty() && frac.is_empty() {
        return err(ParseErrorKind::BadNumber, col);
    }
    match s.get(pos) {
        Some(b'e' | b'E') => return err(ParseErrorKind::Exponent, col),
        Some(b'.' | b'+' | b'-') => return err(ParseErrorKind::BadNumber, col),
        _ => {}
    }
    let int = int.trim_start_matches('0');
    if int.len() > MAX_INT_DIGITS as usize {
        return err(ParseErrorKind::NumberOutOfRange, col);
    }
    let frac = frac.trim_end_matches('0');
    // All the digits, and how many of them are fraction digits.
    let all = format!("{int}{frac}");
    let mut scale = frac.len();
    let lead = all.len() - all.trim_start_matches('0').len();
    let mut kept: Vec<u8> = all.bytes().skip(lead).collect();
    let mut up = false;
    if kept.len() > MAX_SIG_DIGITS as usize {
        let cut = kept.len() - MAX_SIG_DIGITS as usize;
        up = kept[MAX_SIG_DIGITS as usize] >= b'5';
        kept.truncate(MAX_SIG_DIGITS as usize);
        scale -= cut;
    }
    let mut mantissa: u64 = kept.iter().fold(0, |m, &d| m * 10 + (d - b'0') as u64) + up as u64;
    while scale > 0 && mantissa.is_multiple_of(10) && mantissa != 0 {
        mantissa /= 10;
        scale -= 1;
    }
    if mantissa == 0 {
        scale = 0;
    }
    Ok((Number { negative, mantissa: mantissa as u32, scale: scale as u16 }, pos))
}

/// Random number-ish texts: digits, points, signs, blanks, exponents,
/// letters, `#`.
fn number_texts() -> Vec<Vec<u8>> {
    const ALPHABET: &[u8] = b"0000123456789....  \t--+eEX#[Y;";
    let mut seed = 0x9E37_79B9_u32;
    let mut out = Vec::new();
    for len in 0..24 {
        for _ in 0..3000 {
            let mut t = Vec::new();
            for _ in 0..len {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                t.push(ALPHABET[(seed >> 8) as usize % ALPHABET.len()]);
            }
            out.push(t);
        }
    }
    for t in [
        &b"19.950"[..],
        b"-1.257",
        b"0.000",
        b"1.0000000000",
        b"0.0000000001",
        b"999999.999",
        b"1000000",
        b"123456789",
        b"1234567890",
        b"12345.6789",
        b"00000000000001.5",
        b"1.50000000000000",
        b"1 6.5",
        b"1 .5",
        b"1. 5",
        b"- 1",
        b"+.5",
        b".",
        b"-",
        b"",
        b"1e5",
        b"1.2.3",
        b"1-2",
        b"  7  ",
        b"007.0700",
    ] {
        out.push(t.to_vec());
    }
    out
}

fn same(a: Result<(Number, usize), ParseError>, b: Result<(Number, usize), ParseError>) -> bool {
    match (a, b) {
        (Ok((x, i)), Ok((y, j))) => (x.negative, x.mantissa, x.scale, i) == (y.negative, y.mantissa, y.scale, j),
        (Err(e), Err(f)) => e == f,
        _ => false,
    }
}

#[test]
fn number_lexer_matches_its_reference() {
    let mut plain = 0;
    for t in number_texts() {
        for pos in 0..=t.len() {
            let new = lex_number(&t, pos, 7);
            let old = reference_lex_number(&t, pos, 7);
            assert!(
                same(new, old),
                "{:?} at {pos}: {:?} vs {:?}",
                String::from_utf8_lossy(&t),
                new.map(|(n, i)| (n.mantissa, n.scale, i)),
                old.map(|(n, i)| (n.mantissa, n.scale, i))
            );
            if lex_plain(t.get(pos..).unwrap_or(&[])).2 != 0 {
                plain += 1;
            }
        }
    }
    assert!(plain > 100_000, "{plain}");
}

/// The division-free conversion against the division it replaces, bit
/// for bit: every mantissa below 10^6 at scales 1..=9 (every number the
/// benchmark's lines hold), random mantissas up to 2^24, and the edges.
/// It must also answer nearly always (else it saves nothing).
#[test]
fn the_division_free_conversion_matches_the_division() {
    let mut answered = 0u64;
    let mut asked = 0u64;
    let mut check = |m: u32, s: u16| {
        let reference = Number { negative: false, mantissa: m, scale: s }.to_f32_by_division();
        // Where it is meant to answer.
        asked += ((1..=9).contains(&s) && m > 0 && m < 1 << 24) as u64;
        if let Some(v) = crate::math::decimal::quotient_f32(m, s) {
            answered += 1;
            assert_eq!(v.to_bits(), reference.to_bits(), "{m} / 10^{s}: {v:e} vs {reference:e}");
        }
        let n = Number { negative: true, mantissa: m, scale: s };
        assert_eq!(n.to_f32().to_bits(), n.to_f32_by_division().to_bits(), "-{m} / 10^{s}");
    };
    for s in 0..=12 {
        for m in 0..1_000_000 {
            check(m, s);
        }
        for m in (1u32 << 24) - 1000..(1 << 24) + 1000 {
            check(m, s);
        }
        for k in 0..=30 {
            for d in 0..64 {
                check((1u32 << k).wrapping_sub(d), s);
                check((1u32 << k) + d, s);
            }
        }
    }
    let mut rng = crate::test_util::XorShift(0x9E37_79B9);
    for _ in 0..3_000_000 {
        let x = rng.next();
        check(x & 0xFF_FFFF, (x >> 24) as u16 % 10);
        check(x % 1_000_000_000, (x >> 27) as u16 + 1);
    }
    assert!(answered * 100 > asked * 95, "answered {answered} of {asked}");
}

#[test]
fn plain_and_spaced_lexers_agree() {
    for t in number_texts() {
        for first in 0..=t.len() {
            let (mantissa, scale, len) = lex_plain(&t[first..]);
            if len == 0 {
                continue;
            }
            let (n, end) = lex_spaced(&t, first, false, 1).unwrap();
            assert_eq!(
                (n.mantissa, n.scale, end),
                (mantissa, scale as u16, first + len as usize),
                "{:?}",
                String::from_utf8_lossy(&t[first..])
            );
        }
    }
}

#[test]
fn line_fits_the_ram_budget() {
    let size = core::mem::size_of::<Line>();
    println!("size_of::<Line>() = {size} bytes (host)");
    assert!(size <= 120);
}

#[test]
fn canned_cycles_are_motion_codes_and_g98_g99_their_own_group() {
    assert_eq!(ok("G81").motion, Some(Motion::Cycle(Kind::Drill)));
    assert_eq!(ok("G82").motion, Some(Motion::Cycle(Kind::DrillDwell)));
    assert_eq!(ok("G83").motion, Some(Motion::Cycle(Kind::Peck)));
    assert_eq!(ok("G73").motion, Some(Motion::Cycle(Kind::ChipBreak)));
    assert_eq!(ok("G85").motion, Some(Motion::Cycle(Kind::Bore)));
    assert_eq!(ok("g89").motion, Some(Motion::Cycle(Kind::BoreDwell)));
    let l = ok("G98 G83 X1 Y2 Z-3 R1 Q0.5 F100 L2");
    assert_eq!((l.retract, l.motion), (Some(Retract::Initial), Some(Motion::Cycle(Kind::Peck))));
    assert_eq!((l.word(Word::R), l.word(Word::Q), l.word(Word::L)), (Some(1.0), Some(0.5), Some(2.0)));
    assert_eq!(ok("G99").retract, Some(Retract::RPlane));
    assert_eq!(ok("G99").motion, None);
    // One motion group: a cycle and G0 (or two cycles) conflict; so do G98 and G99.
    assert_eq!(fails("G81 G0 X1"), (ParseErrorKind::ModalGroupConflict, 5));
    assert_eq!(fails("G81 G83"), (ParseErrorKind::ModalGroupConflict, 5));
    assert_eq!(fails("G98 G99"), (ParseErrorKind::ModalGroupConflict, 5));
    for c in ["G76", "G84", "G86", "G87", "G88"] {
        assert_eq!(fails(c), (ParseErrorKind::UnsupportedCycle, 1));
    }
}

#[test]
fn every_supported_g_code_is_accepted_in_its_group() {
    assert_eq!(ok("G0").motion, Some(Motion::Rapid));
    assert_eq!(ok("G1").motion, Some(Motion::Linear));
    assert_eq!(ok("G2").motion, Some(Motion::ArcCw));
    assert_eq!(ok("G3").motion, Some(Motion::ArcCcw));
    assert_eq!(ok("G38.2").motion, Some(Motion::ProbeToward));
    assert_eq!(ok("G38.3").motion, Some(Motion::ProbeTowardNoError));
    assert_eq!(ok("G80").motion, Some(Motion::Cancel));
    assert_eq!(ok("G17").plane, Some(Plane::Xy));
    assert_eq!(ok("G18").plane, Some(Plane::Zx));
    assert_eq!(ok("G19").plane, Some(Plane::Yz));
    assert_eq!(ok("G20").units, Some(Units::Inch));
    assert_eq!(ok("G21").units, Some(Units::Mm));
    assert_eq!(ok("G90").distance, Some(Distance::Absolute));
    assert_eq!(ok("G91").distance, Some(Distance::Incremental));
    assert_eq!(ok("G94").feed_mode, Some(FeedMode::UnitsPerMinute));
    for (i, g) in ["G54", "G55", "G56", "G57", "G58", "G59"].iter().enumerate() {
        assert_eq!(ok(g).wcs, Some(i as u8));
    }
    assert_eq!(ok("G43 H3").tool_length, Some(ToolLength::Apply));
    assert_eq!(ok("G49").tool_length, Some(ToolLength::Cancel));
    let non_modal = [
        ("G4", NonModal::Dwell),
        ("G10", NonModal::SetOffsets),
        ("G28", NonModal::Home),
        ("G53", NonModal::MachineCoords),
        ("G92", NonModal::SetPosition),
        ("G37", NonModal::MeasureTool),
        ("G201", NonModal::AuxMove),
        ("G202", NonModal::AuxSetPosition),
        ("G203", NonModal::AuxReport),
        ("G204", NonModal::AuxEnable),
        ("G205", NonModal::AuxHome),
    ];
    for (g, want) in non_modal {
        assert_eq!(ok(g).non_modal, Some(want), "{g}");
    }
}

#[test]
fn leading_zeros_and_zero_decimals_in_codes_are_the_same_code() {
    assert_eq!(ok("G00").motion, Some(Motion::Rapid));
    assert_eq!(ok("G01").motion, Some(Motion::Linear));
    assert_eq!(ok("G1.0").motion, Some(Motion::Linear));
    assert_eq!(ok("G038.20").motion, Some(Motion::ProbeToward));
    assert_eq!(ok("M03").spindle, Some(Spindle::Cw));
    assert_eq!(ok("M3.0").spindle, Some(Spindle::Cw));
}

#[test]
fn every_supported_m_code_is_accepted_in_its_group() {
    assert_eq!(ok("M0").stopping, Some(Stopping::Pause));
    assert_eq!(ok("M1").stopping, Some(Stopping::OptionalPause));
    assert_eq!(ok("M2").stopping, Some(Stopping::End));
    assert_eq!(ok("M30").stopping, Some(Stopping::EndRewind));
    assert_eq!(ok("M3 S1000").spindle, Some(Spindle::Cw));
    assert_eq!(ok("M4").spindle, Some(Spindle::Ccw));
    assert_eq!(ok("M5").spindle, Some(Spindle::Off));
    assert!(ok("M6").tool_change);
    assert!(!ok("G0").tool_change);
    for m in OTHER_M_CODES.get() {
        let text = if TEXT_ARG_M_CODES.contains(&m) { format!("M{m} A.GCO") } else { format!("M{m}") };
        assert_eq!(ok(&text).other_m, Some(m), "{text}");
    }
}

#[test]
fn g_codes_with_a_decimal_other_than_g38_2_and_g38_3_are_unsupported() {
    assert_eq!(fails("G1.5"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G38.1"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G38.25"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G38"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("M3.5"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G-1"), (ParseErrorKind::UnsupportedCode, 1));
}

#[test]
fn unknown_g_and_m_codes_point_at_the_word() {
    assert_eq!(fails("G93"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G1 X1 G33.1"), (ParseErrorKind::UnsupportedCode, 7));
    assert_eq!(fails("M11"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G0 M104"), (ParseErrorKind::UnsupportedCode, 4));
    assert_eq!(fails("M65535"), (ParseErrorKind::UnsupportedCode, 1));
    assert_eq!(fails("G7000"), (ParseErrorKind::UnsupportedCode, 1));
}

#[test]
fn two_codes_of_one_group_conflict_at_the_second() {
    assert_eq!(fails("G0 G1"), (ParseErrorKind::ModalGroupConflict, 4));
    assert_eq!(fails("G1 G1"), (ParseErrorKind::ModalGroupConflict, 4));
    assert_eq!(fails("G54 G55"), (ParseErrorKind::ModalGroupConflict, 5));
    assert_eq!(fails("G4 P1 G53"), (ParseErrorKind::ModalGroupConflict, 7));
    assert_eq!(fails("M3 M5"), (ParseErrorKind::ModalGroupConflict, 4));
    assert_eq!(fails("M6 M6"), (ParseErrorKind::ModalGroupConflict, 4));
    assert_eq!(fails("M114 M115"), (ParseErrorKind::ModalGroupConflict, 6));
    assert_eq!(fails("M0 M30"), (ParseErrorKind::ModalGroupConflict, 4));
}

#[test]
fn codes_of_different_groups_share_a_line() {
    let l = ok("G90 G21 G17 G54 G94 G49 G53 G0 X1 M5 M6 T2 M400");
    assert_eq!(l.distance, Some(Distance::Absolute));
    assert_eq!(l.units, Some(Units::Mm));
    assert_eq!(l.plane, Some(Plane::Xy));
    assert_eq!(l.wcs, Some(0));
    assert_eq!(l.feed_mode, Some(FeedMode::UnitsPerMinute));
    assert_eq!(l.tool_length, Some(ToolLength::Cancel));
    assert_eq!(l.non_modal, Some(NonModal::MachineCoords));
    assert_eq!(l.motion, Some(Motion::Rapid));
    assert_eq!(l.spindle, Some(Spindle::Off));
    assert!(l.tool_change);
    assert_eq!(l.tool(), Some(2));
    assert_eq!(l.other_m, Some(400));
}

#[test]
fn every_value_word_is_read() {
    let l = ok("B1 D2 E3 F4 H5 I6 J7 K8 L9 N10 P11 Q12 R13 S14 T15 X16 Y17 Z18 @19 ^20");
    for (i, w) in Word::ALL.iter().enumerate() {
        assert_eq!(l.word(*w), Some((i + 1) as f32), "{}", w.letter() as char);
    }
    assert_eq!(l.words.iter().count(), Word::COUNT);
}

#[test]
fn axis_letters_of_axes_this_machine_lacks_are_refused_by_name() {
    // LinuxCNC refuses an axis its configuration lacks ("Cannot use A
    // word"); a 3-axis mill cannot honour A0 either (corpus 21).
    assert_eq!(fails("G1 A5"), (ParseErrorKind::NoSuchAxis, 4));
    assert_eq!(fails("C1"), (ParseErrorKind::NoSuchAxis, 1));
    assert_eq!(fails("G0 x1 u2"), (ParseErrorKind::NoSuchAxis, 7));
    assert_eq!(fails("N4 G0 G90 G54 X3. Y82.494 A0. S3183 M3 F300"), (ParseErrorKind::NoSuchAxis, 27));
    for c in b"VW" {
        assert_eq!(fails(&format!("G1 {}1", *c as char)).0, ParseErrorKind::NoSuchAxis);
    }
    assert!(ParseErrorKind::NoSuchAxis.message().bytes().map(char::from).collect::<String>().contains("X Y Z only"));
}

#[test]
fn a_program_number_alone_is_accepted_and_o_word_control_flow_is_refused() {
    // Fanuc/HAAS-style posts (corpus 06, 21, 24).
    assert!(ok("O1001").is_empty());
    assert!(ok("O01023").is_empty());
    assert!(ok("O00001 ").is_empty());
    assert!(ok("O0000(3 HEATSINK PROFILE)").is_empty());
    assert!(ok("N10 O1001 (PART) ; end").is_empty());
    assert!(ok("o1001").is_empty());
    // LinuxCNC O-words: subroutines, loops, conditionals (corpus 01, 18).
    for l in ["o100 sub", "o100 endsub", "O100 call [1] [2]", "o10 while [#1 GT 0]", "o7 if [1]", "o<name> call", "O", "O-1", "O1.5"] {
        assert_eq!(fails(l), (ParseErrorKind::OWord, 1), "{l}");
    }
    assert_eq!(fails("G0 X1 O100"), (ParseErrorKind::OWord, 7));
    assert_eq!(fails("O100 G0 X1"), (ParseErrorKind::OWord, 1));
    assert!(ParseErrorKind::OWord.message().bytes().map(char::from).collect::<String>().contains("O-word"));
}

#[test]
fn parameters_and_expressions_are_refused_by_name() {
    for (l, col) in [
        ("#1=5", 1),
        ("#<_feed> = 5", 1),
        ("G1 F#100", 4),
        ("g0 z#<_safe_Z>", 4),
        ("G1 X[#1+2]", 4),
        ("G1 X-#1", 4),
        ("X [1]", 1),
        ("[1]", 1),
    ] {
        assert_eq!(fails(l), (ParseErrorKind::Parameter, col), "{l}");
    }
    assert!(ParseErrorKind::Parameter.message().bytes().map(char::from).collect::<String>().contains("# parameters"));
}

#[test]
fn cutter_compensation_codes_are_one_modal_group() {
    assert_eq!(ok("G41").cutter_comp, Some(CutterComp::Left));
    assert_eq!(ok("G42 D1").cutter_comp, Some(CutterComp::Right));
    assert_eq!(ok("G42 D1").word(Word::D), Some(1.0));
    assert_eq!(ok("G41.1 D2").cutter_comp, Some(CutterComp::LeftDiameter));
    assert_eq!(ok("g42.1").cutter_comp, Some(CutterComp::RightDiameter));
    assert_eq!(ok("G40").cutter_comp, Some(CutterComp::Off));
    let l = ok("G40 G1 X25 Y10");
    assert_eq!(l.cutter_comp, Some(CutterComp::Off));
    assert_eq!(l.motion, Some(Motion::Linear));
    assert_eq!(l.word(Word::X), Some(25.0));
    assert_eq!(fails("G40 G40"), (ParseErrorKind::ModalGroupConflict, 5));
    assert_eq!(fails("G41 G42"), (ParseErrorKind::ModalGroupConflict, 5));
    assert_eq!(ok("G17 G20 G40 G90").cutter_comp, Some(CutterComp::Off));
}

#[test]
fn preamble_codes_path_mode_arc_distance_and_g92_1_are_accepted() {
    assert_eq!(ok("G64").path_mode, Some(PathMode::Blend));
    let l = ok("G64 P0.01");
    assert_eq!((l.path_mode, l.word(Word::P)), (Some(PathMode::Blend), Some(0.01)));
    assert_eq!(ok("G64 P0.01 Q0.005").path_mode, Some(PathMode::Blend));
    assert_eq!(ok("G61").path_mode, Some(PathMode::ExactPath));
    assert_eq!(ok("G61.1").path_mode, Some(PathMode::ExactStop));
    assert_eq!(fails("G61 G64"), (ParseErrorKind::ModalGroupConflict, 5));
    let l = ok("g20 g64");
    assert_eq!((l.units, l.path_mode), (Some(Units::Inch), Some(PathMode::Blend)));
    assert_eq!(ok("G90.1").arc_absolute, Some(true));
    assert_eq!(ok("G91.1").arc_absolute, Some(false));
    assert_eq!(ok("G91.1").distance, None, "G91.1 is not G91");
    assert_eq!(fails("G90.1 G91.1"), (ParseErrorKind::ModalGroupConflict, 7));
    let l = ok("G90 G90.1");
    assert_eq!((l.distance, l.arc_absolute), (Some(Distance::Absolute), Some(true)));
    assert_eq!(ok("G92.1").non_modal, Some(NonModal::ClearG92));
    assert_eq!(ok("G92.2").non_modal, Some(NonModal::ClearG92));
    assert_eq!(ok("G80").motion, Some(Motion::Cancel));
    assert_eq!(fails("G17.1").0, ParseErrorKind::UnsupportedCode);
    assert_eq!(fails("G33.1 Z-1 K0.05").0, ParseErrorKind::UnsupportedCode);
}

#[test]
fn coolant_codes_m7_m8_m9() {
    assert_eq!(ok("M7").coolant, Some(Coolant::Mist));
    assert_eq!(ok("M8").coolant, Some(Coolant::Flood));
    assert_eq!(ok("M9").coolant, Some(Coolant::Off));
    assert_eq!(ok("S764 M3 M8").coolant, Some(Coolant::Flood));
    assert_eq!(ok("M5 M9").coolant, Some(Coolant::Off));
    // LinuxCNC allows M7 and M8 together: one output, on.
    assert_eq!(ok("M7 M8").coolant, Some(Coolant::Flood));
    assert_eq!(fails("M8 M9"), (ParseErrorKind::ModalGroupConflict, 4));
    assert_eq!(fails("M9 M9"), (ParseErrorKind::ModalGroupConflict, 4));
    assert_eq!(fails("M8 M8"), (ParseErrorKind::ModalGroupConflict, 4));
}

#[test]
fn line_numbers_without_checksums_are_skipped() {
    // grbl-style senders stream N on every line (corpus 04, 06, 21).
    assert_eq!(ok("N5 G00 G90 G54 X3. Y82.494 S3183 M3"), ok("G00 G90 G54 X3. Y82.494 S3183 M3"));
    assert_eq!(ok("N0010 G17 G21 G90"), ok("G17 G21 G90"));
}

#[test]
fn a_repeated_word_is_an_error_at_the_second() {
    assert_eq!(fails("G1 X1 X2"), (ParseErrorKind::RepeatedWord, 7));
    assert_eq!(fails("G1X1Y2x3"), (ParseErrorKind::RepeatedWord, 7));
    assert_eq!(fails("M110 N1 N2"), (ParseErrorKind::RepeatedWord, 9));
}

#[test]
fn case_does_not_matter() {
    assert_eq!(ok("g1 x10 y-2.5 f300"), ok("G1 X10 Y-2.5 F300"));
    assert_eq!(ok("g38.2 z-5").motion, Some(Motion::ProbeToward));
}

#[test]
fn blanks_are_optional_between_words_and_allowed_after_a_letter() {
    let l = ok("G1X10Y-2.5");
    assert_eq!(l.motion, Some(Motion::Linear));
    assert_eq!(l.word(Word::X), Some(10.0));
    assert_eq!(l.word(Word::Y), Some(-2.5));
    assert_eq!(ok("G1 X 10\tY -2.5"), l);
    assert_eq!(ok("  G 1   X10 Y-2.5  "), l);
}

#[test]
fn non_ascii_text_is_ignored_in_comments_and_refused_outside_them() {
    assert_eq!(x("G0 X1 (Fräsen, Größe 3)"), 1.0);
    assert_eq!(x("G0 X2 ; Kühlung"), 2.0);
    assert_eq!(fails("G0 Xä1").0, ParseErrorKind::BadNumber);
    assert_eq!(fails("G0 ä X1"), (ParseErrorKind::Unexpected, 4));
}

#[test]
fn blanks_inside_a_number_are_ignored_as_in_rs274ngc() {
    assert_eq!(x("X1 6.5"), 16.5);
    assert_eq!(x("X1 0"), 10.0);
    assert_eq!(x("X- 1"), -1.0);
    assert_eq!(x("X 1 . 5"), 1.5);
    assert_eq!(x("X1.2 5"), 1.25);
    assert_eq!(x("X - 0 . 0 0 1"), -0.001);
    let l = ok("G 0 1 X1 6.5 Y 2");
    assert_eq!((l.motion, l.word(Word::X), l.word(Word::Y)), (Some(Motion::Linear), Some(16.5), Some(2.0)));
    // A blank still ends a number before a letter: `X1 E5` is two words.
    let l = ok("G1 X1 E5");
    assert_eq!((l.word(Word::X), l.word(Word::E)), (Some(1.0), Some(5.0)));
    assert_eq!(ok("T1 2").tool(), Some(12));
    assert_eq!(fails("X1 .2 .3"), (ParseErrorKind::Unexpected, 7));
}

#[test]
fn comments_are_ignored() {
    let l = ok("G1 (move) X1 ; to the end (not a comment");
    assert_eq!(l.motion, Some(Motion::Linear));
    assert_eq!(l.word(Word::X), Some(1.0));
    assert_eq!(ok("G1(no blanks)X2").word(Word::X), Some(2.0));
    assert_eq!(ok("(a (b) G0"), ok("G0"), "no nesting: the first ) closes");
    assert!(ok("(only a comment)").is_empty());
    assert!(ok("; only a comment").is_empty());
    assert!(ok("").is_empty());
    assert!(ok("   \t ").is_empty());
}

#[test]
fn an_unclosed_comment_is_an_error_at_its_paren() {
    assert_eq!(fails("G1 X1 (oops"), (ParseErrorKind::UnclosedComment, 7));
    assert_eq!(fails("("), (ParseErrorKind::UnclosedComment, 1));
}

#[test]
fn stray_characters_are_unexpected() {
    assert_eq!(fails("G1 )"), (ParseErrorKind::Unexpected, 4));
    assert_eq!(fails("&"), (ParseErrorKind::Unexpected, 1));
    assert_eq!(fails("G1 X1*12"), (ParseErrorKind::Unexpected, 6));
    assert_eq!(fails("$H"), (ParseErrorKind::Unexpected, 1));
}

#[test]
fn a_line_starting_with_percent_is_a_program_marker_and_the_rest_is_not_read() {
    assert!(ok("%").is_empty());
    assert!(ok(" % (start)").is_empty());
    // A Fusion 360 post for the MPCNC writes text after it.
    assert!(ok("% vfd enable").is_empty());
    assert!(ok("% G1 X5").is_empty());
    assert!(ok("%%").is_empty());
    assert!(ok("%(unclosed").is_empty());
    // Anywhere else it is still a stray character.
    assert_eq!(fails("G1 %"), (ParseErrorKind::Unexpected, 4));
    assert_eq!(fails("N10 %"), (ParseErrorKind::Unexpected, 5));
}

#[test]
fn word_bits_letters_and_indexes_agree() {
    for (i, &w) in Word::ALL.iter().enumerate() {
        assert_eq!(Word::from_index(i as u8), Some(w));
        assert_eq!(Word::from_letter(w.letter()), Some(w));
        assert_eq!(Word::mask(&[w]), 1 << i);
        let mut words = Words::new();
        words.insert(w, 1.0);
        assert_eq!(words.first_outside(0), Some(w));
        assert_eq!(words.first_outside(Word::mask(&[w])), None);
    }
    assert_eq!(Word::from_index(Word::COUNT as u8), None);
}

#[test]
fn polar_words_at_and_caret_are_read_as_numbers() {
    let l = ok("G1 @.5 ^90");
    assert_eq!((l.word(Word::At), l.word(Word::Caret)), (Some(0.5), Some(90.0)));
    assert!(l.words.has_position() && l.words.has_polar() && !l.words.has_xyz());
    let l = ok("G81 R.1 Z-.1 ^60 L6");
    assert_eq!(l.word(Word::Caret), Some(60.0));
    assert!(!l.words.has_polar() || l.word(Word::At).is_none());
    assert_eq!(fails("G1 @1 @2"), (ParseErrorKind::RepeatedWord, 7));
    assert_eq!(fails("G1 ^"), (ParseErrorKind::BadNumber, 4));
    assert_eq!(fails("G1 @#1"), (ParseErrorKind::Parameter, 4));
}

#[test]
fn outputs_m62_to_m65_are_refused_by_name_and_m31_is_a_code() {
    for m in ["M62 P1", "M63 P1", "M64 P0", "M65 P0"] {
        assert_eq!(fails(m), (ParseErrorKind::NoOutputs, 1), "{m}");
    }
    assert_eq!(ok("M31").other_m, Some(31));
    assert_eq!(fails("M66"), (ParseErrorKind::UnsupportedCode, 1));
}

#[test]
fn a_leading_line_number_is_skipped() {
    assert_eq!(ok("N10 G1 X1"), ok("G1 X1"));
    assert_eq!(ok("n123456789012 G0"), ok("G0"));
    assert_eq!(ok("N-1 M110"), ok("M110"));
    assert_eq!(ok("M110 N100").word(Word::N), Some(100.0));
    assert_eq!(fails("N G1"), (ParseErrorKind::BadNumber, 1));
    // A fraction is accepted, as LinuxCNC does.
    assert_eq!(ok("N4567.789 S1200"), ok("S1200"));
    assert_eq!(ok("N1. G1"), ok("G1"));
    assert_eq!(fails("N.5 G1"), (ParseErrorKind::BadNumber, 1));
    assert_eq!(fails("N1.5.2 G1"), (ParseErrorKind::BadNumber, 1));
    assert_eq!(fails("N1e5 G1"), (ParseErrorKind::BadNumber, 1));
}

#[test]
fn numbers_with_signs_points_and_leading_zeros() {
    assert_eq!(x("X-0.5"), -0.5);
    assert_eq!(x("X+1"), 1.0);
    assert_eq!(x("X.5"), 0.5);
    assert_eq!(x("X5."), 5.0);
    assert_eq!(x("X007"), 7.0);
    assert_eq!(x("X-.25"), -0.25);
    assert_eq!(x("X0"), 0.0);
    assert_eq!(x("X-0").to_bits(), 0.0f32.to_bits(), "no negative zero");
    assert_eq!(x("X000000000000.5"), 0.5, "leading zeros are not significant");
    assert_eq!(x("X1.50000000000"), 1.5, "trailing zeros are not significant");
    assert_eq!(x("X0.000000001"), 1e-9);
}

#[test]
fn decimals_parse_to_the_nearest_f32() {
    assert_eq!(x("X0.1"), 0.1f32);
    assert_eq!(x("X-0.1"), -0.1f32);
    assert_eq!(x("X0.3"), 0.3f32);
    assert_eq!(x("X123.456"), 123.456f32);
    assert_eq!(x("X2.675"), 2.675f32);
    assert_eq!(x("X999999.9"), 999999.9f32);
    assert_eq!(x("X0.001"), 0.001f32);
    assert_eq!(x("X45.0005"), 45.0005f32);
    // Exhaustive over three decimals up to 100 mm.
    for i in 0..100_000u32 {
        let s = format!("X{}.{:03}", i / 1000, i % 1000);
        let want: f32 = s[1..].parse().unwrap();
        assert_eq!(x(&s), want, "{s}");
    }
}

#[test]
fn malformed_numbers_are_bad_numbers_at_the_word() {
    for s in ["X", "X-", "X.", "X+.", "X-.", "X+", "X1.2.3", "X1-2", "X1+", "X--1", "X+-1"] {
        assert_eq!(fails(s), (ParseErrorKind::BadNumber, 1), "{s}");
    }
    assert_eq!(fails("G1 Y2 X"), (ParseErrorKind::BadNumber, 7));
    assert_eq!(fails("G1 Xa"), (ParseErrorKind::BadNumber, 4));
    assert_eq!(fails("G"), (ParseErrorKind::BadNumber, 1));
    assert_eq!(fails("M"), (ParseErrorKind::BadNumber, 1));
    assert_eq!(fails("G1 X10 F"), (ParseErrorKind::BadNumber, 8));
}

#[test]
fn g28_may_name_axes_without_numbers_and_no_other_line_may() {
    let l = ok("G28 X Z");
    assert_eq!(l.non_modal, Some(NonModal::Home));
    assert_eq!((l.word(Word::X), l.word(Word::Y), l.word(Word::Z)), (Some(0.0), None, Some(0.0)));
    assert_eq!(ok("g28y"), ok("G28 Y0"));
    assert_eq!(ok("Y G28 (home Y)").word(Word::Y), Some(0.0));
    assert_eq!(ok("G28 X;all").word(Word::X), Some(0.0));
    assert_eq!(fails("G28 X X"), (ParseErrorKind::RepeatedWord, 7));
    assert_eq!(fails("G0 X"), (ParseErrorKind::BadNumber, 4));
    assert_eq!(fails("X Y1 G1"), (ParseErrorKind::BadNumber, 1));
    assert_eq!(fails("G28 X-"), (ParseErrorKind::BadNumber, 5));
    assert_eq!(fails("G28 X."), (ParseErrorKind::BadNumber, 5));
    assert_eq!(fails("G28 F"), (ParseErrorKind::BadNumber, 5));
}

#[test]
fn an_exponent_is_rejected_but_an_e_word_after_a_blank_is_fine() {
    assert_eq!(fails("X1e99"), (ParseErrorKind::Exponent, 1));
    assert_eq!(fails("G1 X1E5"), (ParseErrorKind::Exponent, 4));
    assert_eq!(fails("X1.5e-3"), (ParseErrorKind::Exponent, 1));
    let l = ok("M92 X100 E3200");
    assert_eq!(l.word(Word::E), Some(3200.0));
}

#[test]
fn numbers_too_big_are_out_of_range_and_long_ones_are_rounded() {
    assert_eq!(fails("X1000000"), (ParseErrorKind::NumberOutOfRange, 1));
    assert_eq!(fails("X-1000000.0"), (ParseErrorKind::NumberOutOfRange, 1));
    assert_eq!(fails("G1 F99999999999999999999999"), (ParseErrorKind::NumberOutOfRange, 4));
    // Any number of digits: the nearest f32 of the number as written.
    for t in [
        "24.985715729",
        "1.23456789012",
        "1.234567891",
        "-0.33333333333333333333",
        "7.99999999999",
        "0.0000000001234567891",
        "123456.78901234",
    ] {
        let v = x(&format!("X{t}"));
        let nearest: f32 = t.parse().unwrap();
        assert!((v - nearest).abs() <= nearest.abs() * 2.4e-7, "{t}: {v} vs {nearest}");
    }
    assert_eq!(x("X1.9999999999"), 2.0);
    assert_eq!(x("X1.00000000001"), 1.0);
    assert_eq!(x("X999999.99999"), 1_000_000.0);
    assert_eq!(ok("G1.00000000001").motion, Some(Motion::Linear));
    assert_eq!(ok("T2.0000000000").tool(), Some(2));
    assert_eq!(x("X999999.999"), 1_000_000.0, "9 digits round to the nearest f32");
    // Beyond 7 digits the mantissa itself rounds: within one ulp.
    let v = x("X-123.456789");
    let nearest: f32 = "-123.456789".parse().unwrap();
    assert!((v - nearest).abs() <= 8e-6, "{v} vs {nearest}");
    assert_eq!(fails("G1234567"), (ParseErrorKind::NumberOutOfRange, 1));
}

#[test]
fn tiny_numbers_stay_finite() {
    let v = x("X0.000000000000000000000000000000000000000000000000001");
    assert!(v.is_finite() && v.abs() < 1e-30);
}

#[test]
fn t_must_be_a_whole_number_up_to_255() {
    assert_eq!(ok("T0").tool(), Some(0));
    assert_eq!(ok("T12").tool(), Some(12));
    assert_eq!(ok("T255").tool(), Some(255));
    assert_eq!(ok("T5.0").tool(), Some(5));
    assert_eq!(ok("T5 M6").tool(), Some(5));
    assert_eq!(fails("T1.5"), (ParseErrorKind::BadToolNumber, 1));
    assert_eq!(fails("M6 T-1"), (ParseErrorKind::BadToolNumber, 4));
    assert_eq!(fails("T256"), (ParseErrorKind::BadToolNumber, 1));
}

#[test]
fn m23_and_m28_take_the_rest_of_the_line_as_a_file_name() {
    let src = b"M23 Part-1 X5.GCO ; select";
    let l = parse(src).unwrap();
    assert_eq!(l.other_m, Some(23));
    assert_eq!(l.text(src), Some(&b"Part-1 X5.GCO"[..]));
    assert!(l.words.is_empty());
    let src = b"m28\tjob.nc  ";
    let l = parse(src).unwrap();
    assert_eq!(l.other_m, Some(28));
    assert_eq!(l.text(src), Some(&b"job.nc"[..]));
    assert_eq!(ok("M30").text_arg, None);
    assert_eq!(fails("M23"), (ParseErrorKind::MissingFileName, 1));
    assert_eq!(fails("G4 P1 M28   ; nothing"), (ParseErrorKind::MissingFileName, 7));
}

#[test]
fn words_can_be_taken_out_one_by_one() {
    let mut w = ok("G1 X1 Y2").words;
    assert_eq!(w.first(), Some(Word::X));
    assert_eq!(w.remove(Word::X), Some(1.0));
    assert_eq!(w.remove(Word::X), None);
    assert_eq!(w.first(), Some(Word::Y));
    assert_eq!(w.remove(Word::Y), Some(2.0));
    assert!(w.is_empty());
    assert!(w.insert(Word::Z, 3.0));
    assert!(!w.insert(Word::Z, 4.0));
    assert_eq!(w.get(Word::Z), Some(3.0));
}

#[test]
fn a_full_length_line_of_many_words_parses() {
    let mut s = String::from("G1M3");
    for w in Word::ALL {
        if w == Word::T {
            s.push_str("T12");
        } else if w == Word::E {
            // A blank before E, or `-1.5E` would read as an exponent.
            s.push_str(" E-1.5");
        } else {
            s.push(w.letter() as char);
            s.push_str("-1.5");
        }
    }
    s.push_str("G54");
    while s.len() < crate::protocol::MAX_LINE_LEN {
        s.push(' ');
    }
    assert_eq!(s.len(), crate::protocol::MAX_LINE_LEN);
    let l = ok(&s);
    assert_eq!(l.words.iter().count(), Word::COUNT);
    assert_eq!(l.word(Word::Z), Some(-1.5));
    assert_eq!(l.wcs, Some(0));
}

#[test]
fn an_over_long_line_is_rejected() {
    let s = vec![b' '; MAX_PARSE_LEN + 1];
    assert_eq!(parse(&s).unwrap_err().kind, ParseErrorKind::LineTooLong);
    let s = vec![b' '; MAX_PARSE_LEN];
    assert!(parse(&s).unwrap().is_empty());
}

#[test]
fn every_error_kind_has_a_message_and_prints_with_its_column() {
    let kinds = [
        ParseErrorKind::BadNumber,
        ParseErrorKind::Exponent,
        ParseErrorKind::NumberOutOfRange,
        ParseErrorKind::Unexpected,
        ParseErrorKind::UnsupportedCode,
        ParseErrorKind::RepeatedWord,
        ParseErrorKind::ModalGroupConflict,
        ParseErrorKind::UnclosedComment,
        ParseErrorKind::BadToolNumber,
        ParseErrorKind::MissingFileName,
        ParseErrorKind::LineTooLong,
        ParseErrorKind::Parameter,
        ParseErrorKind::OWord,
        ParseErrorKind::NoSuchAxis,
        ParseErrorKind::UnsupportedCycle,
        ParseErrorKind::NoOutputs,
    ];
    for k in kinds {
        assert!(!k.message().is_empty());
    }
    let e = parse(b"G1 X1 X2").unwrap_err();
    let mut out = String::new();
    ufmt::uwrite!(out, "Error:{}", e).unwrap();
    assert_eq!(out, "Error:word repeated at col 7");
}

#[test]
fn every_error_kind_comes_from_some_line_with_the_column_of_its_cause() {
    let long = " ".repeat(MAX_PARSE_LEN + 1);
    let cases: [(&str, ParseErrorKind, u8); 16] = [
        ("G1 X1..2", ParseErrorKind::BadNumber, 4),
        ("G1 Y1e5", ParseErrorKind::Exponent, 4),
        ("G1 Z-1000000", ParseErrorKind::NumberOutOfRange, 4),
        ("G1 U3", ParseErrorKind::NoSuchAxis, 4),
        ("G1 X1 &", ParseErrorKind::Unexpected, 7),
        ("G1 M10", ParseErrorKind::UnsupportedCode, 4),
        ("G1 F1 F2", ParseErrorKind::RepeatedWord, 7),
        ("G17 G18", ParseErrorKind::ModalGroupConflict, 5),
        ("G1 (x", ParseErrorKind::UnclosedComment, 4),
        ("T2.5", ParseErrorKind::BadToolNumber, 1),
        ("M28 ;", ParseErrorKind::MissingFileName, 1),
        (long.as_str(), ParseErrorKind::LineTooLong, 255),
        ("G0 X#1", ParseErrorKind::Parameter, 4),
        ("o100 sub", ParseErrorKind::OWord, 1),
        ("G0 G84", ParseErrorKind::UnsupportedCycle, 4),
        ("G4 P1 M64 P2", ParseErrorKind::NoOutputs, 7),
    ];
    let mut seen = [false; 16];
    for (text, kind, col) in cases {
        assert_eq!(fails(text), (kind, col), "{text:?}");
        // Exhaustive: a new kind must be added to the table above.
        let i = match kind {
            ParseErrorKind::BadNumber => 0,
            ParseErrorKind::Exponent => 1,
            ParseErrorKind::NumberOutOfRange => 2,
            ParseErrorKind::NoSuchAxis => 3,
            ParseErrorKind::Unexpected => 4,
            ParseErrorKind::UnsupportedCode => 5,
            ParseErrorKind::RepeatedWord => 6,
            ParseErrorKind::ModalGroupConflict => 7,
            ParseErrorKind::UnclosedComment => 8,
            ParseErrorKind::BadToolNumber => 9,
            ParseErrorKind::MissingFileName => 10,
            ParseErrorKind::LineTooLong => 11,
            ParseErrorKind::Parameter => 12,
            ParseErrorKind::OWord => 13,
            ParseErrorKind::UnsupportedCycle => 14,
            ParseErrorKind::NoOutputs => 15,
        };
        seen[i] = true;
    }
    assert!(seen.iter().all(|&s| s), "{seen:?}");
}

use crate::test_util::XorShift;

#[test]
fn random_g_code_like_text_never_panics_and_values_stay_in_range() {
    let alphabet = b"GMXYZFNTSPE0123456789.-+ ();%eabc*\t";
    let mut rng = XorShift(0xdead_beef);
    for _ in 0..50_000 {
        let len = (rng.next() % 40) as usize;
        let s: Vec<u8> = (0..len).map(|_| alphabet[rng.next() as usize % alphabet.len()]).collect();
        match parse(&s) {
            Ok(l) => {
                for (_, v) in l.words.iter() {
                    assert!(v.is_finite() && v.abs() <= 1e6, "{:?}", String::from_utf8_lossy(&s));
                }
            }
            Err(e) => assert!(e.col >= 1 && e.col as usize <= s.len().max(1)),
        }
    }
}

#[test]
fn the_letter_table_matches_the_match() {
    for c in 0..=255u8 {
        assert_eq!(Word::from_letter(c), Word::from_letter_by_match(c), "{c:#x}");
    }
}

/// `letter` and `len` random bytes after it: any ASCII byte when `any`,
/// else bytes of `alphabet` (the twin tests' inputs).
fn random_word(rng: &mut XorShift, letter: u8, len: usize, alphabet: &[u8], any: bool) -> Vec<u8> {
    let mut s = vec![letter];
    s.extend((0..len).map(|_| if any { (rng.next() & 0x7F) as u8 } else { alphabet[(rng.next() as usize) % alphabet.len()] }));
    s
}

#[test]
fn plain_words_read_as_the_general_route_reads_them() {
    // Where `plain_value` answers, the general route (the bare-axis test,
    // then `lex_number`) gives the same number and end.
    let alphabet = b"0123456789000.-+ \tXYEe#[;(";
    let mut rng = XorShift(0x91A1);
    let mut answered = 0;
    for k in 0..400_000u32 {
        let len = 1 + (rng.next() % 14) as usize;
        let s = random_word(&mut rng, b'X', len, alphabet, k.is_multiple_of(4));
        let Some((n, used)) = super::plain_value(&s, 1) else {
            continue;
        };
        answered += 1;
        assert!(!super::no_number_follows(&s, 1), "{:?}", String::from_utf8_lossy(&s));
        let (m, end) = lex_number(&s, 1, 1).unwrap_or_else(|e| panic!("{:?}: {e:?}", String::from_utf8_lossy(&s)));
        assert_eq!(
            (n.negative, n.mantissa, n.scale, 1 + used),
            (m.negative, m.mantissa, m.scale, end),
            "{:?}",
            String::from_utf8_lossy(&s)
        );
    }
    assert!(answered > 50_000, "{answered}");
}

#[test]
fn plain_g_reads_as_the_general_route_reads_it() {
    // Where `plain_g` answers, `g_word` (the plain number or `lex_number`,
    // then `code_x10`) gives the same line, result and end.
    let alphabet = b"0123456789.-+ \tXYEeG#;(";
    let mut rng = XorShift(0x6A11);
    let mut answered = 0;
    for k in 0..400_000u32 {
        let len = (rng.next() % 6) as usize;
        let s = random_word(&mut rng, b'G', len, alphabet, k.is_multiple_of(4));
        let Some((code, used)) = super::plain_g(&s, 1) else {
            continue;
        };
        answered += 1;
        let (mut fast, mut general) = (Line::default(), Line::default());
        let fast_end = groups::apply_g(&mut fast, code, 1).map(|()| 1 + used);
        let general_end = super::g_word(&s, 1, 1, &mut general);
        assert_eq!((fast_end, fast), (general_end, general), "{:?}", String::from_utf8_lossy(&s));
    }
    assert!(answered > 50_000, "{answered}");
}

#[test]
fn words_behave_as_a_map_of_the_present_words() {
    // Random inserts and removes against a plain map: the values, the
    // set's equality (a set rebuilt from the map), emptiness.
    let mut rng = XorShift(0x3030);
    for _ in 0..2000 {
        let mut words = Words::new();
        let mut map: std::collections::BTreeMap<u8, f32> = Default::default();
        for _ in 0..30 {
            let w = Word::ALL[(rng.next() as usize) % Word::COUNT];
            let v = (rng.next() % 2001) as f32 - 1000.0;
            if rng.next().is_multiple_of(3) {
                assert_eq!(words.remove(w), map.remove(&(w as u8)));
            } else {
                let fresh = !map.contains_key(&(w as u8));
                assert_eq!(words.insert(w, v), fresh);
                map.entry(w as u8).or_insert(v);
            }
            let mut rebuilt = Words::new();
            for (&i, &v) in &map {
                assert!(rebuilt.insert(Word::ALL[i as usize], v));
            }
            for w in Word::ALL {
                assert_eq!(words.get(w), map.get(&(w as u8)).copied(), "{w:?}");
                assert_eq!(words.contains(w), map.contains_key(&(w as u8)), "{w:?}");
            }
            // The bytes `insert` sets against the 32-bit mask of the words
            // present.
            let present: Vec<Word> = map.keys().map(|&i| Word::ALL[i as usize]).collect();
            assert!(words.within(Word::mask(&present)));
            assert_eq!(words.first_outside(0), present.first().copied());
            assert_eq!(words, rebuilt);
            if let Some((&i, &v)) = map.iter().next() {
                let w = Word::ALL[i as usize];
                let mut changed = words;
                changed.remove(w);
                changed.insert(w, v + 0.5);
                assert_ne!(changed, words);
            }
            assert_eq!(words.is_empty(), map.is_empty());
            assert_eq!(words == Words::new(), map.is_empty());
        }
    }
}
