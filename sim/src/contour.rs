//! A contour with every corner kind of cutter radius compensation (G41/G42):
//! line-line, line-arc and arc-line corners turning both ways (inside for
//! one side, outside for the other), tangent junctions, arcs with the tool
//! inside and outside. `tests/dialect.rs` checks its tool path against the
//! independent reference; `tools/bench` runs it for its SRAM row (a
//! compensated contour is the deepest stack path the tests know).

/// The job, work mm: to the start, the entry move with `comp` (the
/// compensation words, `G41 D1`), the contour, and a G40 exit.
pub fn job(comp: &str) -> String {
    format!(
        "G21 G90 G17\nG0 X5 Y5 Z-5\n{comp} G1 X10 Y10 F1200\n\
         G1 X20 Y10 F1200\nG1 X22 Y14\nG2 X30 Y14 I4 J0\nG1 X25 Y8\nG1 X12 Y8\nG2 X12 Y14 I0 J3\nG1 X18 Y16\n\
         G40 G0 X5 Y5\n"
    )
}
