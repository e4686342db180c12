//! The operator's side of the virtual machine: the OLED read back as text
//! with the firmware's own font, the encoder turned and pressed, and golden
//! screenshots. Included with `#[path = "common/panel.rs"] mod panel;`.
#![allow(dead_code)]

use sim::{oled, Vm};
use std::path::PathBuf;

/// Read the OLED's 8 text lines back from its display RAM with the
/// firmware's own font: `[text]` marks an inverted (highlighted) line. The
/// bottom pixel row (bit 7) is not read: the font leaves it blank, and a
/// title bar keeps it dark.
pub fn screen(vm: &Vm) -> Vec<String> {
    use mill::ui::font::{column, CELL_W};
    let ram = vm.oled().ram();
    (0..8)
        .map(|page| {
            let row = &ram[page][oled::COLUMN_OFFSET..oled::COLUMN_OFFSET + 128];
            let inverted = row[126] & 0x7F == 0x7F;
            let mut s = String::new();
            for cell in 0..21 {
                let cols: Vec<u8> = (0..CELL_W).map(|c| (row[cell * CELL_W + c] ^ if inverted { 0xFF } else { 0 }) & 0x7F).collect();
                let ch = (0x20u8..0x7F).find(|&ch| (0..CELL_W).all(|c| column(ch, c) == cols[c])).unwrap_or(b'~');
                s.push(ch as char);
            }
            let s = s.trim_end().to_string();
            if inverted {
                format!("[{s}]")
            } else {
                s
            }
        })
        .collect()
}

/// Let the firmware react and draw (a frame is at most 200 ms apart).
pub fn redraw(vm: &mut Vm) {
    vm.run_for(0.35).unwrap();
}

pub fn press(vm: &mut Vm) {
    vm.press_button(0.05).unwrap();
    redraw(vm);
}

pub fn turn(vm: &mut Vm, detents: i32) {
    vm.turn_encoder(detents, 0.1).unwrap();
    redraw(vm);
}

/// Compare what the display shows with `tests/golden/<name>.png`; on a
/// difference save the picture to `target/ui-shots/` and fail.
/// `MILL_UPDATE_GOLDEN=1` writes the golden file instead.
pub fn golden(vm: &Vm, name: &str) {
    golden_masked(vm, name, 0, 0..0);
}

/// [`golden`], but the cells `cols` of text line `row` are not compared:
/// a figure that depends on how fast the firmware runs (its text is
/// checked by the caller).
pub fn golden_masked(vm: &Vm, name: &str, row: usize, cols: std::ops::Range<usize>) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let golden = dir.join("tests/golden").join(format!("{name}.png"));
    let shot = dir.join("target/ui-shots").join(format!("{name}.png"));
    vm.screenshot(&shot, 2).unwrap();
    if std::env::var_os("MILL_UPDATE_GOLDEN").is_some() {
        vm.screenshot(&golden, 2).unwrap();
        return;
    }
    let want = oled::read_png(&golden).unwrap_or_else(|e| panic!("{}: {e} (MILL_UPDATE_GOLDEN=1 to create it)", golden.display()));
    let got = vm.oled().pixels();
    let cell_w = mill::ui::font::CELL_W;
    let masked = |i: usize| {
        let (x, y) = (i % oled::WIDTH, i / oled::WIDTH);
        y / 8 == row && (cols.start * cell_w..cols.end * cell_w).contains(&x)
    };
    let diff = want.iter().zip(&got).enumerate().filter(|(i, (a, b))| a != b && !masked(*i)).count();
    assert_eq!(diff, 0, "{name}: {diff} pixels differ from {}; see {}\n{}", golden.display(), shot.display(), screen(vm).join("\n"));
}
