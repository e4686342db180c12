//! Host tests of the line protocol: realtime bytes, the RX fast path
//! against the slow one, line assembly, checksums and resends, the M112
//! scanner, losses.

use super::checker::trim;
use super::mcode_scanner::S_M108;
use super::*;

#[test]
fn the_block_number_a_line_starts_with() {
    assert_eq!(block_number(b"N10 G1 X5"), 10);
    assert_eq!(block_number(b"  n7G0"), 7);
    assert_eq!(block_number(b"N70000 G0"), (70000u32 & 0xFFFF) as u16);
    assert_eq!(block_number(b"G1 N10"), 0);
    assert_eq!(block_number(b"N-5 G0"), 0);
    assert_eq!(block_number(b"N G0"), 0);
}

/// Feed `bytes`, collecting each result with its line text.
fn assemble(a: &mut LineAssembler, bytes: &[u8]) -> Vec<(Assembled, Vec<u8>)> {
    let mut out = Vec::new();
    for &b in bytes {
        if let Some(r) = a.push(b) {
            out.push((r, a.line().to_vec()));
        }
    }
    out
}

fn xor(s: &[u8]) -> u8 {
    s.iter().fold(0, |a, &b| a ^ b)
}

/// `N<n> <cmd>` with its correct checksum.
fn numbered(n: i32, cmd: &str) -> Vec<u8> {
    let body = format!("N{} {}", n, cmd);
    format!("{}*{}", body, xor(body.as_bytes())).into_bytes()
}

#[test]
fn realtime_bytes_are_question_bang_tilde_and_ctrl_x() {
    assert!(is_realtime(b'?') && is_realtime(b'!') && is_realtime(b'~') && is_realtime(0x18));
    assert!(!is_realtime(b'G') && !is_realtime(b'\n') && !is_realtime(b'*'));
}

/// The bytes of `stream` that `RxText` takes out as realtime commands,
/// and the text that is left.
fn split_realtime(stream: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let mut t = RxText::new();
    let (mut rt, mut text) = (Vec::new(), Vec::new());
    for &b in stream {
        if t.classify(b) {
            rt.push(b);
        } else {
            text.push(b);
        }
    }
    (rt, text)
}

#[test]
fn realtime_bytes_in_comments_and_numbered_lines_are_text() {
    assert_eq!(split_realtime(b"G0 X5 Y5 (is this right?)\n"), (vec![], b"G0 X5 Y5 (is this right?)\n".to_vec()));
    assert_eq!(split_realtime(b"(Warning! check the clamp)\n").0, vec![]);
    assert_eq!(split_realtime(b"G1 X1 ; ok? ~!\n").0, vec![]);
    assert_eq!(split_realtime(b"  N12 G1 X1 ?!~*99\n").0, vec![]);
    assert_eq!(split_realtime(b"n3 M117 Hi!*1\n").0, vec![]);
    // Outside those: realtime, wherever in the line.
    assert_eq!(split_realtime(b"G1 X?1 (a) !\n~G1 Y1 N2\n"), (b"?!~".to_vec(), b"G1 X1 (a) \nG1 Y1 N2\n".to_vec()));
    // The comment and the numbered line end with the line.
    assert_eq!(split_realtime(b"(open\n?N1*3\n!;x\n~").0, b"?!~".to_vec());
    // Ctrl-X always acts, and the line after it starts afresh.
    assert_eq!(split_realtime(b"N1 (\x18)\x18\n").0, vec![0x18, 0x18]);
    assert_eq!(split_realtime(b"N1 (a\x18?").0, vec![0x18, b'?']);
}

#[test]
fn after_a_loss_realtime_bytes_act() {
    let mut t = RxText::new();
    for &b in b"N1 G1 (" {
        assert!(!t.classify(b));
    }
    t.note_loss();
    assert!(t.classify(b'!'));
    assert!(!t.at_line_start());
}

/// The rule, spelled out on the text of the line so far.
fn rx_text_reference(line: &[u8], b: u8) -> bool {
    if b == 0x18 {
        return true;
    }
    let trimmed: Vec<u8> = line.iter().copied().skip_while(|c| *c == b' ' || *c == b'\t').collect();
    let numbered = matches!(trimmed.first(), Some(b'N' | b'n'));
    // Bytes from 0x80 up leave every line but a numbered one, comments
    // included.
    if b >= 0x80 {
        return !numbered;
    }
    if !matches!(b, b'?' | b'!' | b'~') || numbered {
        return false;
    }
    let mut in_paren = false;
    for &c in line {
        match c {
            b'(' if !in_paren => in_paren = true,
            b')' if in_paren => in_paren = false,
            b';' if !in_paren => return false,
            _ => {}
        }
    }
    !in_paren
}

#[test]
fn rx_text_matches_the_rule_on_random_streams() {
    const PIECES: &[&[u8]] = &[
        b"N",
        b"n",
        b" ",
        b"\t",
        b"(",
        b")",
        b";",
        b"?",
        b"!",
        b"~",
        b"\n",
        b"\r",
        b"G1",
        b"X5",
        b"*",
        b"\x18",
        b"M112",
        b"\xfe",
        b"\x00",
        b"\xc2\x91",
        b"\x85",
    ];
    let mut rng = XorShift(0x5EED);
    let mut t = RxText::new();
    let mut line: Vec<u8> = Vec::new();
    let (mut acted, mut kept) = (0, 0);
    for _ in 0..200_000 {
        for &b in PIECES[rng.next() as usize % PIECES.len()] {
            let want = rx_text_reference(&line, b);
            assert_eq!(t.classify(b), want, "{:?} then {:?}", String::from_utf8_lossy(&line), b as char);
            if want {
                acted += 1;
                if b == 0x18 {
                    line.clear();
                }
            } else {
                if matches!(b, b'?' | b'!' | b'~') {
                    kept += 1;
                }
                if b == b'\n' || b == b'\r' {
                    line.clear();
                } else {
                    line.push(b);
                }
            }
        }
    }
    assert!(acted > 5000 && kept > 5000, "{acted} acted, {kept} kept as text");
}

/// What the RX ISR's assembly fast path stores without calling the slow
/// path: 0x20..=0x7D except `!` `?` `(` `)` `;` `M` `m`.
fn fast_path_byte(b: u8) -> bool {
    (0x20..0x7e).contains(&b) && !matches!(b, b'!' | b'?' | b'(' | b')' | b';' | b'M' | b'm')
}

/// Every `RxText` state reachable from a line start, over any bytes and
/// losses.
fn reachable_text_states() -> Vec<u8> {
    let mut seen = vec![RxText::new().state];
    let mut i = 0;
    while i < seen.len() {
        let t0 = RxText { state: seen[i] };
        let mut next = vec![RxText::MID_LINE];
        for b in 0..=255u8 {
            let mut t = t0;
            t.classify(b);
            next.push(t.state);
        }
        for s in next {
            if !seen.contains(&s) {
                seen.push(s);
            }
        }
        i += 1;
    }
    seen
}

/// The RX ISR's assembly fast path (`__vector_25` in `board/serial.rs`),
/// step for step: stores `b` and updates `mode` and `text` when it
/// takes the byte (true), or leaves everything to the slow path (false).
fn asm_fast_path(mode: &mut u8, text: &mut RxText, prev: &mut u8, ring: &mut Vec<u8>, b: u8) -> bool {
    if b >= 0x7e {
        return false;
    }
    if b < 0x20 {
        if !(b == b'\n' || b == b'\r') || *mode == RX_ALL_SLOW {
            return false;
        }
        ring.push(b);
        *prev = b;
        text.state = RxText::LINE_START;
        *mode = RX_LINE_START;
        return true;
    }
    if matches!(b, b'!' | b'?' | b';' | b'(' | b')' | b'M' | b'm') {
        return false;
    }
    match *mode {
        RX_FAST => {}
        RX_LINE_START if b | 0x20 == b'n' => return false,
        RX_LINE_START if b == b' ' => {}
        RX_LINE_START => {
            text.state = RxText::MID_LINE;
            *mode = RX_FAST;
        }
        _ => return false,
    }
    ring.push(b);
    *prev = b;
    true
}

/// The RX ISR's slow path (`usart0_rx_slow`) on an unbounded ring,
/// without losses; true when `b` was a realtime byte.
fn slow_path(scan: &mut MCodeScanner, store: &mut RxStore, text: &mut RxText, prev: &mut u8, ring: &mut Vec<u8>, b: u8) -> (bool, Urgent) {
    let mut urgent = Urgent::Nothing;
    let realtime = text.classify(b);
    if !realtime {
        urgent = scan.feed(*prev, b);
        store.store(b, *prev, |x| {
            ring.push(x);
            true
        });
        *prev = b;
    }
    (realtime, urgent)
}

#[test]
fn the_fast_path_line_ends_and_line_starts() {
    let states = reachable_text_states();
    assert!(states.len() >= 4, "{states:?}");
    for &state in &states {
        let t0 = RxText { state };
        if t0.at_line_start() {
            assert_eq!(state, RxText::LINE_START);
        }
        for b in *b"\n\r" {
            let mut t = t0;
            assert!(!t.classify(b));
            assert_eq!(t.state, RxText::LINE_START, "state {state:#x}");
        }
    }
    assert!(MCodeScanner::new().ignores(b'\n') && MCodeScanner::new().ignores(b'\r'));
    let mut n = 0;
    for b in 0..=255u8 {
        if fast_path_byte(b) && !matches!(b, b' ' | b'N' | b'n') {
            let mut t = RxText::new();
            assert!(!t.classify(b));
            assert_eq!(t.state, RxText::MID_LINE, "byte {b:#x}");
            n += 1;
        }
    }
    assert_eq!(n, 0x7e - 0x20 - 7 - 3);
    let mut t = RxText::new();
    assert!(!t.classify(b' '));
    assert_eq!(t.state, RxText::LINE_START);
}

/// The slow path alone and the fast path with the slow path behind it
/// store the same bytes and end in the same states, byte for byte, over
/// random streams of G-code-ish bytes (line ends, `N`, `M112`, comments,
/// realtime bytes, Ctrl-X).
#[test]
fn the_fast_path_twin_matches_the_slow_path() {
    const ALPHABET: &[u8] = b"G1 X2.5Y-3\n\r\n\nNnMm1128(;)?!~\x18\tZ*0 \n";
    let mut seed = 0x2545_F491_u32;
    let mut fast_bytes = 0;
    for _ in 0..400 {
        let (mut scan_a, mut store_a, mut text_a, mut prev_a, mut ring_a) =
            (MCodeScanner::new(), RxStore::new(), RxText::new(), 0u8, Vec::new());
        let (mut scan_b, mut store_b, mut text_b, mut prev_b, mut ring_b) =
            (MCodeScanner::new(), RxStore::new(), RxText::new(), 0u8, Vec::new());
        let mut mode = rx_fast_mode(&scan_b, &store_b, &text_b);
        for _ in 0..200 {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            let b = ALPHABET[seed as usize % ALPHABET.len()];
            let (rt_a, urgent_a) = slow_path(&mut scan_a, &mut store_a, &mut text_a, &mut prev_a, &mut ring_a, b);
            if asm_fast_path(&mut mode, &mut text_b, &mut prev_b, &mut ring_b, b) {
                fast_bytes += 1;
                assert!(!rt_a && urgent_a == Urgent::Nothing, "byte {b:#x}");
            } else {
                let (rt_b, urgent_b) = slow_path(&mut scan_b, &mut store_b, &mut text_b, &mut prev_b, &mut ring_b, b);
                assert_eq!((rt_a, urgent_a), (rt_b, urgent_b));
                mode = rx_fast_mode(&scan_b, &store_b, &text_b);
            }
            assert_eq!((text_a, scan_a, prev_a), (text_b, scan_b, prev_b));
            assert_eq!(mode, rx_fast_mode(&scan_a, &store_a, &text_a));
        }
        assert_eq!(ring_a, ring_b);
    }
    assert!(fast_bytes > 20_000, "{fast_bytes}");
}

#[test]
fn the_fast_path_bytes_change_nothing() {
    let mut n = 0;
    for state in 0..16u8 {
        let t0 = RxText { state };
        if t0.at_line_start() {
            continue;
        }
        for b in 0..=255u8 {
            if fast_path_byte(b) {
                let mut t = t0;
                assert!(!t.classify(b));
                assert_eq!(t, t0, "state {state:#x}, byte {b:#x}");
                n += 1;
            }
        }
    }
    assert_eq!(n, 8 * (0x7e - 0x20 - 7));
}

#[test]
fn newline_or_carriage_return_ends_a_trimmed_line() {
    let mut a = LineAssembler::new();
    let out = assemble(&mut a, b"  G1 X10 \t\r\nM114\n");
    assert_eq!(out, vec![(Assembled::Line, b"G1 X10".to_vec()), (Assembled::Line, b"M114".to_vec())]);
}

#[test]
fn blank_lines_give_no_result() {
    let mut a = LineAssembler::new();
    assert!(assemble(&mut a, b"\n\r\n   \t \n\r\r").is_empty());
}

#[test]
fn line_is_empty_when_no_line_just_completed() {
    let mut a = LineAssembler::new();
    assert_eq!(a.push(b'G'), None);
    assert_eq!(a.line(), b"");
    assert_eq!(a.push(b'\n'), Some(Assembled::Line));
    assert_eq!(a.line(), b"G");
    assert_eq!(a.push(b'X'), None);
    assert_eq!(a.line(), b"");
}

#[test]
fn a_line_of_exactly_max_len_is_accepted() {
    let mut a = LineAssembler::new();
    let mut bytes = vec![b'X'; MAX_LINE_LEN];
    bytes.push(b'\n');
    let out = assemble(&mut a, &bytes);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].0, Assembled::Line);
    assert_eq!(out[0].1.len(), MAX_LINE_LEN);
}

#[test]
fn an_over_long_line_is_rejected_whole_and_the_next_line_is_clean() {
    let mut a = LineAssembler::new();
    let mut bytes = vec![b'Y'; MAX_LINE_LEN + 1];
    bytes.extend_from_slice(b"\nG0 X1\n");
    let out = assemble(&mut a, &bytes);
    assert_eq!(out, vec![(Assembled::TooLong, vec![]), (Assembled::Line, b"G0 X1".to_vec())]);
    assert_eq!(Assembled::TooLong.error(), Some(ProtoError::TooLong));
}

#[test]
fn trailing_blanks_do_not_count_toward_the_limit() {
    let mut a = LineAssembler::new();
    let mut bytes = vec![b'X'; MAX_LINE_LEN];
    bytes.extend([b' '; 200]);
    bytes.push(b'\n');
    let out = assemble(&mut a, &bytes);
    assert_eq!(out, vec![(Assembled::Line, vec![b'X'; MAX_LINE_LEN])]);
}

#[test]
fn text_after_blanks_past_the_limit_is_too_long() {
    let mut a = LineAssembler::new();
    let mut bytes = vec![b'X'; MAX_LINE_LEN];
    bytes.extend_from_slice(b"   Y\n");
    assert_eq!(assemble(&mut a, &bytes), vec![(Assembled::TooLong, vec![])]);
}

#[test]
fn leading_blanks_do_not_count_toward_the_limit() {
    let mut a = LineAssembler::new();
    let mut bytes = vec![b' '; 50];
    bytes.extend(vec![b'Z'; MAX_LINE_LEN]);
    bytes.push(b'\n');
    let out = assemble(&mut a, &bytes);
    assert_eq!(out[0].0, Assembled::Line);
}

#[test]
fn an_overrun_drops_the_line_in_progress_only() {
    let mut a = LineAssembler::new();
    let mut out = assemble(&mut a, b"G1 X");
    a.mark_overrun();
    out.extend(assemble(&mut a, b"10\nG1 X2\n"));
    assert_eq!(out, vec![(Assembled::Overrun, vec![]), (Assembled::Line, b"G1 X2".to_vec())]);
}

#[test]
fn an_overrun_at_a_line_start_is_reported_even_if_the_rest_is_blank() {
    let mut a = LineAssembler::new();
    assert_eq!(a.push(b'\r'), None);
    a.mark_overrun();
    assert_eq!(a.push(b'\n'), Some(Assembled::Overrun));
    assert_eq!(assemble(&mut a, b"M5\n"), vec![(Assembled::Line, b"M5".to_vec())]);
}

#[test]
fn binary_bytes_reject_the_line() {
    let mut a = LineAssembler::new();
    let out = assemble(&mut a, b"G1 X\x0010\nG1\xfe\nM3\x1b\nG1\tX1\n");
    assert_eq!(
        out,
        vec![
            (Assembled::BadByte, vec![]),
            (Assembled::BadByte, vec![]),
            (Assembled::BadByte, vec![]),
            (Assembled::Line, b"G1\tX1".to_vec()),
        ]
    );
}

#[test]
fn a_byte_order_mark_at_a_line_start_and_utf8_in_comments_are_text() {
    let mut a = LineAssembler::new();
    let out = assemble(&mut a, "\u{feff}G1 X1\n(Ø3 end mill)\nG1 X2 ; Größe\n\u{feff}  G0\n".as_bytes());
    let lines: Vec<_> = out.iter().map(|(r, l)| (*r, String::from_utf8(l.clone()).unwrap())).collect();
    assert_eq!(
        lines,
        [
            (Assembled::Line, "G1 X1".into()),
            (Assembled::Line, "(Ø3 end mill)".into()),
            (Assembled::Line, "G1 X2 ; Größe".into()),
            (Assembled::Line, "G0".into()),
        ]
    );
    // Outside a comment, or a mark cut short or not at the start: data.
    for bad in [&b"G1 X\xc3\x981\n"[..], b"\xef\xbbG1\n", b"\xef\n", b"G1 \xef\xbb\xbf\n", b"(a)\xc3\n", b"(\x01)\n"] {
        assert_eq!(assemble(&mut a, bad), [(Assembled::BadByte, vec![])], "{bad:?}");
    }
    // A mark alone is a blank line.
    assert_eq!(assemble(&mut a, b"\xef\xbb\xbf\nG0\n"), [(Assembled::Line, b"G0".to_vec())]);
}

#[test]
fn comment_text_past_the_limit_is_dropped_and_code_keeps_its_limit() {
    let mut a = LineAssembler::new();
    let semi = format!("G0 X1 ; {}\n", "d".repeat(300));
    let out = assemble(&mut a, semi.as_bytes());
    assert_eq!(out[0].0, Assembled::Line);
    assert_eq!(out[0].1, semi.as_bytes()[..MAX_LINE_LEN].to_vec());
    // An overflowing ( ) comment folds to (), the code after it stays.
    let paren = format!("G0 X1 ({}) Y2 (short)\n", "d".repeat(300));
    assert_eq!(assemble(&mut a, paren.as_bytes()), [(Assembled::Line, b"G0 X1 () Y2 (short)".to_vec())]);
    // A `(` inside the comment text leaves a comment that reads the same.
    let inner = format!("G0 X1 (a ({}) Y2\n", "d".repeat(300));
    assert_eq!(assemble(&mut a, inner.as_bytes()), [(Assembled::Line, b"G0 X1 (a () Y2".to_vec())]);
    // Code past the limit is too long, comment or not before it.
    let code = format!("G0 X1 ({}) Y{}\n", "d".repeat(300), "2".repeat(MAX_LINE_LEN));
    assert_eq!(assemble(&mut a, code.as_bytes()), [(Assembled::TooLong, vec![])]);
    // A `(` with no room for `()` is not stored; the code after it is.
    let edge = format!("{} (comment) \n", "G4".repeat(MAX_LINE_LEN / 2 - 1));
    let out = assemble(&mut a, edge.as_bytes());
    assert_eq!(out, [(Assembled::Line, "G4".repeat(MAX_LINE_LEN / 2 - 1).into_bytes())]);
    // A checksummed line whose comment was cut cannot be checked: too long.
    let numbered = format!("N5 G0 X1 ({})*12\n", "d".repeat(300));
    assert_eq!(assemble(&mut a, numbered.as_bytes()), [(Assembled::TooLong, vec![])]);
    let unchecked = format!("N5 G0 X1 ({})\n", "d".repeat(300));
    assert_eq!(assemble(&mut a, unchecked.as_bytes()), [(Assembled::Line, b"N5 G0 X1 ()".to_vec())]);
}

/// The line with its comments taken out.
fn code_of(line: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut paren = false;
    for &b in line {
        match b {
            b')' if paren => paren = false,
            _ if paren => {}
            b'(' => paren = true,
            b';' => break,
            _ => out.push(b),
        }
    }
    out
}

#[test]
fn long_lines_keep_their_code_exactly_on_random_lines() {
    let mut rng = XorShift(0x51ed_2701);
    let pieces: [&[u8]; 9] = [b"G1 ", b"X12.5", b"(", b")", b";", b"dddddddddddddddd", "Ø".as_bytes(), b" ", b"*7"];
    let mut a = LineAssembler::new();
    for _ in 0..20_000 {
        let mut line = Vec::new();
        let target = 1 + rng.next() as usize % 400;
        while line.len() < target {
            line.extend_from_slice(pieces[rng.next() as usize % pieces.len()]);
        }
        // Only text, not data: bytes from 0x80 up stay inside comments.
        let mut cut = LineCut::new();
        let mut text = Vec::new();
        for &b in &line {
            if b < 0x80 || cut.in_comment() {
                cut.keep(b, 0);
                text.push(b);
            }
        }
        let code = code_of(trim(&text));
        text.push(b'\n');
        let out = assemble(&mut a, &text);
        match out.first() {
            Some((Assembled::Line, got)) => {
                assert!(got.len() <= MAX_LINE_LEN);
                assert_eq!(trim(&code_of(got)), trim(&code), "{:?}", String::from_utf8_lossy(&text));
            }
            // Only a line over the limit is ever refused.
            Some((Assembled::TooLong, _)) => assert!(trim(&text[..text.len() - 1]).len() > MAX_LINE_LEN),
            None => assert!(code.is_empty() || trim(&code).is_empty()),
            other => panic!("{other:?} for {:?}", String::from_utf8_lossy(&text)),
        }
    }
}

#[test]
fn a_star_inside_a_comment_is_not_a_checksum() {
    let mut c = LineChecker::new();
    assert_eq!(c.check(b"G0 X5 ( *** move *** )"), Ok(&b"G0 X5 ( *** move *** )"[..]));
    assert_eq!(c.check(b"G0 X5 ; ** done **"), Ok(&b"G0 X5 ; ** done **"[..]));
    assert_eq!(c.check(b"G0 X5 (a*b) *12"), Err(ProtoError::MissingLineNumber));
    let body = "N1 G0 X1 ( *** move *** )";
    let l = format!("{}*{}", body, xor(body.as_bytes()));
    assert_eq!(c.check(l.as_bytes()), Ok(&b"G0 X1 ( *** move *** )"[..]));
    assert_eq!(c.last_line(), 1);
    assert_eq!(checksum_star(b"N1 G0 (*) X1*5 ; *"), Some(12));
    assert_eq!(checksum_star(b"G0 (*"), None);
}

/// `push` (the usual byte stored at once) against `push_slow` alone (the
/// assembler as it was), over random streams of the bytes that matter:
/// line ends, blanks, comments, bad bytes, the gap marker, a BOM, and
/// lines long enough to overflow the buffer.
#[test]
fn the_assembler_fast_path_matches_the_slow_one() {
    let mut rng = crate::test_util::XorShift(0xFA57);
    let special = [b'\n', b'\r', b' ', b'\t', b'(', b')', b';', b'*', b'N', 0xFF, 0xEF, 0xBB, 0xBF, 0x80, 0x7F, 0x01, 0x20, 0x21, 0x7E];
    for round in 0..400u32 {
        let (mut fast, mut slow) = (LineAssembler::new(), LineAssembler::new());
        // A third of the rounds with few line ends: lines past the buffer.
        let long = round.is_multiple_of(3);
        for _ in 0..4000 {
            let r = rng.next();
            let mut b = match r % 8 {
                0 | 1 => special[(r >> 8) as usize % special.len()],
                _ => (0x21 + (r >> 8) % 0x5E) as u8,
            };
            if long && matches!(b, b'\n' | b'\r') && !(r >> 20).is_multiple_of(16) {
                b = b'G';
            }
            let (f, s) = (fast.push(b), slow.push_slow(b));
            assert_eq!(f, s, "byte {b:#x}");
            assert_eq!(fast.line(), slow.line(), "byte {b:#x}");
            assert_eq!(fast.dropped_numbered(), slow.dropped_numbered());
            assert_eq!(fast.has_marks(), slow.has_marks());
        }
    }
}

/// A run of bytes as the firmware's RX ring holds them (from a tail
/// anywhere in its 256 slots, across the wrap), taken one at a time and,
/// where `bulk`, the usual ones in runs by `take_usual_plain`, as the
/// firmware's `mill_rx_take_usual` does.
struct Ring {
    ring: [u8; 256],
    head: u8,
    tail: u8,
    bulk: bool,
}

impl RxBytes for Ring {
    fn next_byte(&mut self) -> Option<u8> {
        if self.tail == self.head {
            return None;
        }
        let b = self.ring[self.tail as usize];
        self.tail = self.tail.wrapping_add(1);
        Some(b)
    }

    fn take_usual(&mut self, dst: &mut [u8], started: bool) -> usize {
        if !self.bulk {
            return 0;
        }
        take_usual_plain(&self.ring, self.head, &mut self.tail, dst, started)
    }
}

#[test]
fn pushing_a_stream_matches_pushing_byte_by_byte() {
    // `push_from` (the usual bytes in a loop with the length in a
    // register, or copied in runs by the source) against `push_slow` for
    // every byte, over random streams handed over in random runs (a run
    // ends when the ring is empty).
    let mut rng = crate::test_util::XorShift(0x5EED);
    let special = [b'\n', b'\r', b' ', b'\t', b'(', b')', b';', b'*', b'N', 0xFF, 0xEF, 0xBB, 0xBF, 0x80, 0x7F, 0x01, 0x20, 0x21, 0x7E];
    for round in 0..600u32 {
        let long = round.is_multiple_of(3);
        let bulk = !round.is_multiple_of(2);
        let bytes: Vec<u8> = (0..4000)
            .map(|_| {
                let r = rng.next();
                let b = match r % 8 {
                    0 | 1 => special[(r >> 8) as usize % special.len()],
                    _ => (0x21 + (r >> 8) % 0x5E) as u8,
                };
                if long && matches!(b, b'\n' | b'\r') && !(r >> 20).is_multiple_of(16) {
                    b'G'
                } else {
                    b
                }
            })
            .collect();
        let mut slow = LineAssembler::new();
        let mut want = Vec::new();
        for (i, &b) in bytes.iter().enumerate() {
            if let Some(done) = slow.push_slow(b) {
                want.push((i, done, slow.line().to_vec(), slow.dropped_numbered(), slow.has_marks()));
            }
        }
        let mut fast = LineAssembler::new();
        let mut got = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            // A run of 1..=64 bytes, as the RX ring may hold, from any slot.
            let end = (i + 1 + (rng.next() % 64) as usize).min(bytes.len());
            let t0 = rng.next() as u8;
            let mut src = Ring { ring: [0; 256], head: t0.wrapping_add((end - i) as u8), tail: t0, bulk };
            for (k, &b) in bytes[i..end].iter().enumerate() {
                src.ring[t0.wrapping_add(k as u8) as usize] = b;
            }
            // The slot after the run holds a usual byte the copy must not take.
            src.ring[src.head as usize] = b'7';
            while let Some(done) = fast.push_from(&mut src) {
                let used = i + src.tail.wrapping_sub(t0) as usize;
                got.push((used - 1, done, fast.line().to_vec(), fast.dropped_numbered(), fast.has_marks()));
            }
            assert_eq!(src.tail, src.head, "round {round}: the run was not all taken");
            i = end;
        }
        assert_eq!(got, want, "round {round}");
    }
}

#[test]
fn checking_a_line_without_marks_skips_the_star_scan() {
    // Lines assembled from random streams rich in the marks, N words and
    // checksums: a line the assembler reports without marks holds none,
    // and `check_marked` with that report answers as `check` does (also
    // on the checker's state).
    let mut rng = crate::test_util::XorShift(0xC4EC);
    let pieces: [&[u8]; 14] = [b"N", b"n", b"1", b"2", b"*", b"(", b")", b";", b" ", b"M110", b"G1 X1", b"\n", b"\n", b"$"];
    let (mut plain, mut marked) = (LineChecker::new(), LineChecker::new());
    let mut asm = LineAssembler::new();
    let mut lines = 0;
    for _ in 0..300_000 {
        let piece = pieces[(rng.next() as usize) % pieces.len()];
        for &b in piece {
            if asm.push(b) != Some(Assembled::Line) {
                continue;
            }
            lines += 1;
            let line = asm.line();
            let marks = asm.has_marks();
            assert!(marks || !line.iter().any(|&b| b"()*;".contains(&b)), "{line:?}");
            assert_eq!(marked.check_marked(line, marks), plain.check(line), "{:?}", String::from_utf8_lossy(line));
            assert_eq!(marked, plain);
        }
    }
    assert!(lines > 10_000);
}

/// The `*` finder as it was before its quick pass: every byte read with
/// its comment state.
fn plain_checksum_star(line: &[u8]) -> Option<usize> {
    let mut paren = false;
    let mut star = None;
    for (i, &b) in line.iter().enumerate() {
        match b {
            b')' if paren => paren = false,
            _ if paren => {}
            b'(' => paren = true,
            b';' => break,
            b'*' => star = Some(i),
            _ => {}
        }
    }
    star
}

#[test]
fn the_quick_star_scan_matches_the_plain_one() {
    let mut rng = crate::test_util::XorShift(0x57A2);
    // Lines of the bytes that matter, their neighbours, and G-code text.
    let alphabet = b"()*;'+):<GX1.-N \t";
    for n in 0..200_000u32 {
        let len = (rng.next() % 24) as usize;
        let line: Vec<u8> = (0..len)
            .map(|_| if n % 2 == 0 { alphabet[(rng.next() as usize) % alphabet.len()] } else { (rng.next() & 0x7F) as u8 })
            .collect();
        assert_eq!(checksum_star(&line), plain_checksum_star(&line), "{:?}", String::from_utf8_lossy(&line));
    }
    for b in 0..=255u8 {
        for line in [vec![b], vec![b, b'*'], vec![b'(', b, b'*'], vec![b'*', b, b'*', b')']] {
            assert_eq!(checksum_star(&line), plain_checksum_star(&line), "{line:?}");
        }
    }
}

#[test]
fn reset_forgets_the_line_in_progress() {
    let mut a = LineAssembler::new();
    assemble(&mut a, b"G1 X1");
    a.mark_overrun();
    a.reset();
    assert_eq!(assemble(&mut a, b"M5\n"), vec![(Assembled::Line, b"M5".to_vec())]);
}

use crate::test_util::XorShift;

#[test]
fn random_bytes_never_panic_and_never_give_a_line_over_the_limit() {
    let mut rng = XorShift(0x1234_5678);
    let mut a = LineAssembler::new();
    let mut checker = LineChecker::new();
    let mut lines = 0;
    for i in 0..200_000u32 {
        let r = rng.next();
        // Bias toward printable text and terminators so that lines end.
        let b = match r % 8 {
            0 => b'\n',
            1 => (r >> 8) as u8,
            _ => b' ' + ((r >> 8) % 95) as u8,
        };
        if i % 9973 == 0 {
            a.mark_overrun();
        }
        if let Some(Assembled::Line) = a.push(b) {
            let line = a.line();
            assert!(!line.is_empty() && line.len() <= MAX_LINE_LEN);
            // Bytes from 0x80 up only inside a comment.
            let mut cut = LineCut::new();
            for (k, &c) in line.iter().enumerate() {
                assert!((0x20..0x7f).contains(&c) || c == b'\t' || (c >= 0x80 && cut.in_comment()), "{line:?}");
                cut.keep(c, k);
            }
            let _ = checker.check(line);
            lines += 1;
        }
    }
    assert!(lines > 1000);
}

#[test]
fn unnumbered_lines_pass_as_they_are() {
    let mut c = LineChecker::new();
    assert_eq!(c.check(b"G1 X10"), Ok(&b"G1 X10"[..]));
    assert_eq!(c.last_line(), 0);
}

#[test]
fn numbered_lines_with_good_checksums_advance_the_line_number() {
    let mut c = LineChecker::new();
    let l1 = numbered(1, "G1 X10");
    assert_eq!(c.check(&l1), Ok(&b"G1 X10"[..]));
    let l2 = numbered(2, "M114");
    assert_eq!(c.check(&l2), Ok(&b"M114"[..]));
    assert_eq!(c.last_line(), 2);
    assert_eq!(c.resend_line(), 3);
}

#[test]
fn a_known_printcore_line_checks() {
    // printcore: prefix = "N1 G28", checksum = XOR of the prefix.
    let mut c = LineChecker::new();
    assert_eq!(xor(b"N1 G28"), 18);
    assert_eq!(c.check(b"N1 G28*18"), Ok(&b"G28"[..]));
}

#[test]
fn a_wrong_checksum_is_rejected_and_keeps_the_last_line() {
    let mut c = LineChecker::new();
    let mut l = numbered(1, "G1 X10");
    let n = l.len();
    l[n - 1] = if l[n - 1] == b'0' { b'1' } else { b'0' };
    assert_eq!(c.check(&l), Err(ProtoError::Checksum));
    assert_eq!(c.check(b"N1 G1*"), Err(ProtoError::Checksum));
    assert_eq!(c.check(b"N1 G1*abc"), Err(ProtoError::Checksum));
    assert_eq!(c.check(b"N1 G1*1000"), Err(ProtoError::Checksum));
    assert_eq!(c.last_line(), 0);
    assert_eq!(c.resend_line(), 1);
}

#[test]
fn a_skipped_or_repeated_line_number_is_rejected() {
    let mut c = LineChecker::new();
    assert_eq!(c.check(&numbered(2, "G0 X1")), Err(ProtoError::LineNumber));
    assert_eq!(c.check(&numbered(1, "G0 X1")), Ok(&b"G0 X1"[..]));
    assert_eq!(c.check(&numbered(1, "G0 X1")), Err(ProtoError::LineNumber));
    assert_eq!(c.resend_line(), 2);
}

#[test]
fn line_number_without_checksum_and_checksum_without_number_are_errors() {
    let mut c = LineChecker::new();
    // N without a checksum is a numbered file block, not the protocol's:
    // it passes unchecked, and the last line number stays.
    assert_eq!(c.check(b"N1 G1 X1"), Ok(&b"N1 G1 X1"[..]));
    assert_eq!(c.check(b"N0070 G1 X1"), Ok(&b"N0070 G1 X1"[..]));
    assert_eq!(c.last_line(), 0);
    assert_eq!(c.check(b"G1 X1*12"), Err(ProtoError::MissingLineNumber));
    let body = "NX G1";
    let l = format!("{}*{}", body, xor(body.as_bytes()));
    assert_eq!(c.check(l.as_bytes()), Err(ProtoError::BadLineNumber));
    assert_eq!(c.last_line(), 0);
}

/// A host that resends line 1 with the same bad checksum every time.
#[test]
fn a_line_that_keeps_failing_is_given_up_after_three_tries() {
    let mut c = LineChecker::new();
    let mut bad = numbered(1, "G1 X10");
    let n = bad.len();
    bad[n - 1] = if bad[n - 1] == b'0' { b'1' } else { b'0' };
    let mut replies = Vec::new();
    for _ in 0..3 {
        assert_eq!(c.check(&bad), Err(ProtoError::Checksum));
        replies.push(c.failed());
    }
    assert_eq!(replies, [Retry::Resend(1), Retry::Resend(1), Retry::GiveUp(1)]);
    // The host moves on: line 2 is accepted.
    assert_eq!(c.check(&numbered(2, "G1 X2")), Ok(&b"G1 X2"[..]));
}

#[test]
fn a_good_line_resets_the_tries_and_line_number_errors_are_not_tries() {
    let mut c = LineChecker::new();
    assert_eq!(c.failed(), Retry::Resend(1));
    assert_eq!(c.failed(), Retry::Resend(1));
    // Lines the host had in flight: line-number errors, not reported.
    assert_eq!(c.check(&numbered(2, "G0")), Err(ProtoError::LineNumber));
    assert!(c.check(&numbered(1, "G0")).is_ok());
    // Line 2 starts with a clean slate.
    assert_eq!(c.failed(), Retry::Resend(2));
    assert_eq!(c.failed(), Retry::Resend(2));
    assert_eq!(c.failed(), Retry::GiveUp(2));
    assert_eq!(c.last_line(), 2);
    assert_eq!(c.failed(), Retry::Resend(3));
}

/// Whatever a host sends, the same line is never asked for more than
/// MAX_TRIES - 1 times in a row by `failed`.
#[test]
fn random_failures_never_ask_for_the_same_line_more_than_twice() {
    let mut rng = XorShift(99);
    let mut c = LineChecker::new();
    let (mut same, mut last_req) = (0, i32::MIN);
    for _ in 0..100_000 {
        let n = c.resend_line();
        let line = if rng.next().is_multiple_of(3) { numbered(n, "G0") } else { b"N1 G0*0".to_vec() };
        match c.check(&line) {
            Ok(_) => same = 0,
            Err(ProtoError::LineNumber) => {}
            Err(_) => match c.failed() {
                Retry::Resend(r) => {
                    same = if r == last_req { same + 1 } else { 1 };
                    last_req = r;
                    assert!(same < MAX_TRIES as i32, "line {r} asked for {same} times");
                }
                Retry::GiveUp(_) => same = 0,
            },
        }
    }
}

#[test]
fn m110_sets_the_line_number_from_its_own_n_word() {
    let mut c = LineChecker::new();
    assert_eq!(c.check(&numbered(5, "M110 N100")), Ok(&b"M110 N100"[..]));
    assert_eq!(c.last_line(), 100);
    assert!(c.check(&numbered(101, "G1 X1")).is_ok());
}

#[test]
fn m110_without_n_word_uses_the_line_number_even_when_negative() {
    let mut c = LineChecker::new();
    c.check(&numbered(40, "M110")).unwrap();
    assert_eq!(c.last_line(), 40);
    // printcore resets with N-1 M110.
    assert_eq!(c.check(&numbered(-1, "M110")), Ok(&b"M110"[..]));
    assert_eq!(c.last_line(), -1);
    assert!(c.check(&numbered(0, "G28")).is_ok());
    assert_eq!(c.last_line(), 0);
}

#[test]
fn m1100_is_not_m110() {
    let mut c = LineChecker::new();
    assert_eq!(c.check(&numbered(7, "M1100 N3")), Err(ProtoError::LineNumber));
}

#[test]
fn a_bare_m110_sets_the_line_number() {
    let mut c = LineChecker::new();
    assert_eq!(c.check(b"M110 N42"), Ok(&b"M110 N42"[..]));
    assert_eq!(c.last_line(), 42);
    assert_eq!(c.check(b"m110 n-7"), Ok(&b"m110 n-7"[..]));
    assert_eq!(c.last_line(), -7);
    // Without an N word nothing changes.
    c.check(b"M110").unwrap();
    assert_eq!(c.last_line(), -7);
}

#[test]
fn extreme_line_numbers_do_not_overflow() {
    let mut c = LineChecker::new();
    c.check(&numbered(1, "M110 N2147483647")).unwrap();
    assert_eq!(c.resend_line(), i32::MIN);
    assert!(c.check(&numbered(-2147483648, "G0")).is_ok());
    assert_eq!(c.check(&numbered(1, "M110 N2147483648")), Ok(&b"M110 N2147483648"[..]));
    // An unparsable M110 N falls back to the line's own number.
    assert_eq!(c.last_line(), 1);
    let body = "N99999999999 G0";
    let l = format!("{}*{}", body, xor(body.as_bytes()));
    assert_eq!(c.check(l.as_bytes()), Err(ProtoError::BadLineNumber));
}

#[test]
fn the_checksum_covers_everything_before_the_last_star() {
    let mut c = LineChecker::new();
    let body = "N1 G1 (a*b) X1";
    let l = format!("{}*{}", body, xor(body.as_bytes()));
    assert_eq!(c.check(l.as_bytes()), Ok(&b"G1 (a*b) X1"[..]));
}

#[test]
fn every_error_has_a_message() {
    for e in [
        ProtoError::Checksum,
        ProtoError::LineNumber,
        ProtoError::MissingChecksum,
        ProtoError::MissingLineNumber,
        ProtoError::BadLineNumber,
        ProtoError::TooLong,
        ProtoError::Overrun,
        ProtoError::BadByte,
    ] {
        assert!(!e.message().is_empty());
    }
    assert_eq!(ProtoError::Checksum.message(), "checksum mismatch");
}

/// (M112s, M108s) that the scanner spots in `stream`.
fn urgent_fires(stream: &[u8]) -> (usize, usize) {
    let mut s = MCodeScanner::new();
    let (mut estops, mut continues) = (0, 0);
    let mut prev = 0;
    for &b in stream {
        match s.feed(prev, b) {
            Urgent::Estop => estops += 1,
            Urgent::Continue => continues += 1,
            Urgent::Nothing => {}
        }
        prev = b;
    }
    (estops, continues)
}

fn estop_fires(stream: &[u8]) -> usize {
    urgent_fires(stream).0
}

#[test]
fn m112_followed_by_a_non_digit_triggers_the_estop() {
    assert_eq!(estop_fires(b"M112\n"), 1);
    assert_eq!(estop_fires(b"m112 "), 1);
    assert_eq!(estop_fires(b"N7 M112*40\n"), 1);
    assert_eq!(estop_fires(b"G1 X5 M112;\n"), 1);
    assert_eq!(estop_fires(b"G0M112\n"), 1);
    assert_eq!(estop_fires(b"MM112\n"), 0);
    assert_eq!(estop_fires(b"M11M112\n"), 1);
    assert_eq!(estop_fires(b"M112\nM112\n"), 2);
    assert_eq!(estop_fires(b"M112M112 "), 2, "the M that ends one starts the next");
}

#[test]
fn near_misses_do_not_trigger_the_estop() {
    assert_eq!(estop_fires(b"M1120\n"), 0);
    assert_eq!(estop_fires(b"M11 2\n"), 0);
    assert_eq!(estop_fires(b"M 112\n"), 0);
    assert_eq!(estop_fires(b"M111\n"), 0);
    assert_eq!(estop_fires(b"M23 AM112.GCO\n"), 0);
    assert_eq!(estop_fires(b"zm112\n"), 0, "a lower-case letter before the M counts too");
    assert_eq!(estop_fires(b"M112"), 0, "needs the next byte to decide");
}

#[test]
fn m_code_scanner_is_one_byte() {
    assert_eq!(core::mem::size_of::<MCodeScanner>(), 1);
}

/// The RX ISR's fast path skips the scanner for the bytes it ignores:
/// in every state, after any byte, those must change nothing.
#[test]
fn a_byte_the_scanner_ignores_changes_nothing() {
    let mut skipped = 0;
    for state in 0..=S_M108 {
        for prev in 0..=255u8 {
            for b in 0..=255u8 {
                let mut s = MCodeScanner { state };
                if s.ignores(b) {
                    assert_eq!(s.feed(prev, b), Urgent::Nothing);
                    assert_eq!(s.state, state);
                    skipped += 1;
                }
            }
        }
    }
    assert_eq!(skipped, 254 * 256, "all but M and m when idle, nothing otherwise");
}

/// What the scanner must answer for the newest byte of `hist` (oldest
/// first): the code `M<abc>` (any case) not after a letter, then a
/// non-digit, spelled out from the rule instead of a state machine.
fn urgent_reference(hist: &[u8]) -> Urgent {
    let n = hist.len();
    if n < 5 || hist[n - 1].is_ascii_digit() {
        return Urgent::Nothing;
    }
    if n > 5 && hist[n - 6].is_ascii_alphabetic() {
        return Urgent::Nothing;
    }
    match hist[n - 5..n - 1].to_ascii_uppercase().as_slice() {
        b"M112" => Urgent::Estop,
        b"M108" => Urgent::Continue,
        _ => Urgent::Nothing,
    }
}

/// Random streams of near misses and hits (pieces of both codes in
/// both cases, letters, digits, blanks and a few others) agree with
/// [`urgent_reference`] byte for byte.
#[test]
fn the_m_code_scanner_matches_the_rule_on_random_streams() {
    const PIECES: &[&[u8]] = &[
        b"M112", b"m108", b"M11", b"M10", b"M1", b"M", b"m", b"1", b"0", b"2", b"8", b"9", b" ", b"\n", b"A", b"z", b"G", b"(", b"*",
        b"\xff", b"\x00",
    ];
    let mut rng = XorShift(0xC0DE);
    let mut s = MCodeScanner::new();
    let mut hist: Vec<u8> = Vec::new();
    let (mut estops, mut continues) = (0, 0);
    for _ in 0..100_000 {
        for &b in PIECES[rng.next() as usize % PIECES.len()] {
            let got = s.feed(hist.last().copied().unwrap_or(0), b);
            hist.push(b);
            let tail = &hist[hist.len().saturating_sub(8)..];
            assert_eq!(got, urgent_reference(&hist), "after {:?}", String::from_utf8_lossy(tail));
            estops += (got == Urgent::Estop) as u32;
            continues += (got == Urgent::Continue) as u32;
        }
    }
    assert!(estops > 1000 && continues > 1000, "{estops} M112, {continues} M108");
}

/// A model of the serial RX path: a 255-byte ring filled by the ISR's
/// `RxStore` faster than the main loop drains it into a `LineAssembler`,
/// with the main loop's `store_lost_ends` once a turn. The host sends
/// numbered lines `N<i> G4 P<i>`, ended by `\n`, `\r\n` or `\r`, and the
/// main loop now and then stalls (an override re-plan) while bytes keep
/// coming. Every line must get exactly one result, in order: intact if it
/// arrived complete, else `Overrun`, even when its line end was dropped.
#[test]
fn rx_losses_drop_exactly_the_damaged_lines() {
    use std::collections::VecDeque;
    let mut rng = XorShift(7);
    let mut store = RxStore::new();
    let mut asm = LineAssembler::new();
    let mut ring: VecDeque<u8> = VecDeque::new();
    let mut sent: Vec<u8> = Vec::new();
    const LINES: usize = 3000;
    for i in 0..LINES {
        let end = ["\n", "\r\n", "\r"][rng.next() as usize % 3];
        sent.extend(format!("N{i} G4 P{i}{end}").bytes());
    }
    let (mut next, mut prev, mut ends_dropped) = (0usize, 0u8, 0);
    let mut got: Vec<Result<String, ()>> = Vec::new();
    let enqueue = |ring: &mut VecDeque<u8>, x: u8| {
        if ring.len() < 255 {
            ring.push_back(x);
            true
        } else {
            false
        }
    };
    while next < sent.len() || !ring.is_empty() || store.gap_pending() {
        let stall = rng.next().is_multiple_of(200);
        for _ in 0..if stall { 300 } else { rng.next() % 4 } {
            if let Some(&b) = sent.get(next) {
                ends_dropped += (ring.len() == 255 && matches!(b, b'\n' | b'\r')) as usize;
                store.store(b, prev, |x| enqueue(&mut ring, x));
                prev = b;
                next += 1;
            }
        }
        if stall {
            continue;
        }
        store.store_lost_ends(&mut |x| enqueue(&mut ring, x));
        for _ in 0..rng.next() % 8 {
            if let Some(b) = ring.pop_front() {
                match asm.push(b) {
                    Some(Assembled::Line) => got.push(Ok(String::from_utf8(asm.line().to_vec()).unwrap())),
                    Some(Assembled::Overrun) => got.push(Err(())),
                    None => {}
                    other => panic!("{other:?}"),
                }
            }
        }
        if next == sent.len() && ring.is_empty() && store.gap_pending() {
            // Only a gap before a next byte that never comes is left.
            store.store_lost_ends(&mut |_| false);
            break;
        }
    }
    assert_eq!(got.len(), LINES, "one result per line sent");
    for (k, r) in got.iter().enumerate() {
        if let Ok(l) = r {
            assert_eq!(*l, format!("N{k} G4 P{k}"));
        }
    }
    let overruns = got.iter().filter(|r| r.is_err()).count();
    assert!((10..LINES / 2).contains(&overruns), "{overruns} overruns");
    assert!(ends_dropped >= 10, "{ends_dropped} line ends dropped");
}

/// A line whose end is dropped with a full ring, and nothing sent after
/// it (the host waits for its reply): the main loop's `store_lost_ends`
/// ends it as an overrun. The `\n` of a `\r\n` dropped after its `\r`
/// was stored ends nothing and damages nothing.
#[test]
fn a_dropped_line_end_still_ends_its_line() {
    for (line, dropped_from, results) in [
        (&b"G1 X1\n"[..], 3, vec![Assembled::Overrun]),
        (b"G1 X1\n", 5, vec![Assembled::Overrun]),
        (b"G1 X1\r\n", 6, vec![Assembled::Line]),
    ] {
        let mut store = RxStore::new();
        let mut ring: Vec<u8> = Vec::new();
        let mut prev = 0;
        for (i, &b) in line.iter().enumerate() {
            store.store(b, prev, |x| {
                let room = i < dropped_from;
                if room {
                    ring.push(x);
                }
                room
            });
            prev = b;
        }
        let mut asm = LineAssembler::new();
        let mut out: Vec<_> = ring.drain(..).filter_map(|b| asm.push(b)).collect();
        assert_eq!(store.gap_pending(), results[0] == Assembled::Overrun);
        store.store_lost_ends(&mut |x| {
            ring.push(x);
            true
        });
        assert!(!store.gap_pending());
        out.extend(ring.iter().filter_map(|&b| asm.push(b)));
        assert_eq!(out, results, "{line:?} dropped from {dropped_from}");
        // The next line arrives whole and runs.
        let next: Vec<_> = b"G0 Y2\n".iter().filter_map(|&b| asm.push(b)).collect();
        assert_eq!(next, vec![Assembled::Line]);
    }
}

#[test]
fn a_real_0xff_from_the_host_is_a_bad_byte_not_a_gap() {
    let mut store = RxStore::new();
    let mut ring = Vec::new();
    store.store(0xFF, 0, |x| {
        ring.push(x);
        true
    });
    assert_eq!(ring, vec![0xFE]);
    let mut asm = LineAssembler::new();
    ring.push(b'\n');
    let out: Vec<_> = ring.iter().filter_map(|&b| asm.push(b)).collect();
    assert_eq!(out, vec![Assembled::BadByte]);
}

#[test]
fn m108_is_caught_like_m112_and_neither_fires_for_the_other() {
    assert_eq!(urgent_fires(b"M108\n"), (0, 1));
    assert_eq!(urgent_fires(b"N3 m108*55\n"), (0, 1));
    assert_eq!(urgent_fires(b"M1080\nM10 8\nAM108\n"), (0, 0));
    assert_eq!(urgent_fires(b"M112\nM108\nM112 "), (2, 1));
    assert_eq!(urgent_fires(b"M118\nM102\nM10M112;M11M108;"), (1, 1));
}
