//! Fuzz target: arbitrary bytes through the host input path (docs/SPEC.md §10).
//!
//! ```text
//!  bytes ─► MCodeScanner (M112, M108; checked against a reference)
//!        ─► LineAssembler ─► LineChecker ─► gcode::parse
//! ```
//!
//! Invariants: nothing panics; every assembled line is 1..=MAX_LINE_LEN
//! printable bytes (bytes from 0x80 up only inside a comment); a rejected
//! numbered line leaves the line number alone; a line wrapped as
//! `N<next> … *<xor>` always checks (unless the `*` falls in a comment); every parsed value is
//! finite and within ±1e6; T is a whole number 0..=255; file names and error
//! columns point inside the text. The raw input is also parsed directly, since
//! the SD-card path may hand the parser bytes the serial assembler would drop.
//! Byte 0xFF stands for "the RX ring overflowed here" (mark_overrun).
#![no_main]

use libfuzzer_sys::fuzz_target;
use mill::gcode::{self, ParseError, ParseErrorKind, Word};
use mill::protocol::{checksum_star, Assembled, LineAssembler, LineChecker, LineCut, MCodeScanner, Urgent, MAX_LINE_LEN};

/// Check the parser's promises for the text `src`.
fn check_parse(src: &[u8]) {
    match gcode::parse(src) {
        Ok(line) => {
            for (w, v) in line.words.iter() {
                assert!(
                    v.is_finite() && v.abs() <= 1e6,
                    "{} = {v} from {src:?}",
                    w.letter() as char
                );
            }
            if let Some(t) = line.word(Word::T) {
                assert!((0.0..=255.0).contains(&t) && t == t as u8 as f32, "T{t}");
                assert_eq!(line.tool(), Some(t as u8));
            }
            if let Some((start, len)) = line.text_arg {
                assert!(len > 0 && start as usize + len as usize <= src.len());
                assert_eq!(line.text(src).map(<[u8]>::len), Some(len as usize));
            }
        }
        Err(ParseError {
            kind: ParseErrorKind::LineTooLong,
            ..
        }) => assert!(src.len() > 255),
        Err(e) => assert!(
            e.col >= 1 && e.col as usize <= src.len(),
            "{e:?} for {src:?}"
        ),
    }
}

/// Reference for MCodeScanner: `M112` or `M108` (any case) not after a
/// letter, then a non-digit, ending at the newest byte of `hist` (oldest
/// first).
fn urgent_reference(hist: &[u8]) -> Urgent {
    let n = hist.len();
    if n < 5 {
        return Urgent::Nothing;
    }
    let tok = &hist[n - 5..n - 1];
    let after = hist[n - 1];
    let before_ok = n == 5 || !hist[n - 6].is_ascii_alphabetic();
    if after.is_ascii_digit() || !before_ok {
        Urgent::Nothing
    } else if tok.eq_ignore_ascii_case(b"M112") {
        Urgent::Estop
    } else if tok.eq_ignore_ascii_case(b"M108") {
        Urgent::Continue
    } else {
        Urgent::Nothing
    }
}

fuzz_target!(|data: &[u8]| {
    check_parse(data);

    let mut asm = LineAssembler::new();
    let mut checker = LineChecker::new();
    let mut numbered = LineChecker::new();
    let mut scanner = MCodeScanner::new();
    let mut hist: Vec<u8> = Vec::new();

    for &b in data {
        let prev = hist.last().copied().unwrap_or(0);
        hist.push(b);
        if hist.len() > 6 {
            hist.remove(0);
        }
        assert_eq!(
            scanner.feed(prev, b),
            urgent_reference(&hist),
            "M-code scanner after {hist:?}"
        );

        if b == 0xFF {
            asm.mark_overrun();
            continue;
        }
        if asm.push(b) != Some(Assembled::Line) {
            continue;
        }
        let line = asm.line();
        assert!(!line.is_empty() && line.len() <= MAX_LINE_LEN);
        // Printable ASCII and tab; bytes from 0x80 up only inside a comment.
        let mut cut = LineCut::new();
        for (k, &c) in line.iter().enumerate() {
            assert!((0x20..0x7f).contains(&c) || c == b'\t' || (c >= 0x80 && cut.in_comment()));
            cut.keep(c, k);
        }
        assert!(
            !matches!(line.first(), Some(b' ' | b'\t'))
                && !matches!(line.last(), Some(b' ' | b'\t'))
        );

        let last = checker.last_line();
        match checker.check(line) {
            Ok(cmd) => check_parse(cmd),
            Err(_) => assert_eq!(
                checker.last_line(),
                last,
                "a rejected line moved the line number"
            ),
        }

        // The same line as a host would number it must always pass.
        if !line.contains(&b'*') {
            let mut wrapped = format!("N{} ", numbered.resend_line()).into_bytes();
            wrapped.extend_from_slice(line);
            let sum = wrapped.iter().fold(0u8, |a, &c| a ^ c);
            let star = wrapped.len();
            wrapped.extend_from_slice(format!("*{sum}").as_bytes());
            // A `*` after `;` or inside an unclosed `(` is comment text: the
            // line then has no checksum (a host strips comments first).
            if checksum_star(&wrapped) == Some(star) {
            assert_eq!(
                numbered.check(&wrapped),
                Ok(line),
                "{:?}",
                String::from_utf8_lossy(&wrapped)
            );
            }
        }
    }
});
