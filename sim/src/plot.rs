//! The toolpath picture (`out/toolpath.png`), drawn with `plotters`.
//!
//! Two paths over each other, in a top view (X/Y) and a side view (X/Z):
//! - the **commanded** path, from the job's G-code ([`commanded_path`]: a
//!   small interpreter for G0–G3, G17, G20/G21, G28, G90/G91 and T words,
//!   in machine mm, valid once the job has homed), thin and grey;
//!
//! Both are in the user's frame of the firmware's G-code: +Z up, machine Z
//! 0 at the top switch and negative below it (the recorder's physical steps
//! count Z downward; [`recorded_path`] negates them).
//! - the path **reconstructed from the recorded steps**, thick, coloured by
//!   the tool in the spindle (from the firmware's `NowSelectedTool:` lines).
//!
//! If they do not overlay, the firmware did not cut what the job asked for.

use crate::Vm;
use plotters::prelude::*;
use std::path::Path;

/// Where G28 leaves each axis (X, Y, Z; user frame): the firmware's default
/// pull-off, 1 mm off each switch; Z's switch is at the top, so below it.
const HOME_MM: [f64; 3] = [1.0, 1.0, -1.0];

/// A stretch of commanded path with one tool in the spindle.
#[derive(Clone, Debug, PartialEq)]
pub struct Polyline {
    pub tool: u8,
    /// Points in machine mm (X, Y, Z; +Z up).
    pub points: Vec<[f64; 3]>,
}

/// Interpret the motion of a job (machine mm; work offsets and tool length
/// offsets are not applied, which leaves X/Y exact when the job uses none).
pub fn commanded_path(lines: &[String]) -> Vec<Polyline> {
    let mut out: Vec<Polyline> = Vec::new();
    let mut pos = [0.0f64; 3];
    let (mut inches, mut incremental, mut motion, mut tool) = (false, false, 0u8, 0u8);
    // Arc plane as (first axis, second axis): G17 X/Y, G18 Z/X, G19 Y/Z.
    let mut plane = (0usize, 1usize);
    for raw in lines {
        let words = words(raw);
        let get = |c: char| words.iter().find(|(l, _)| *l == c).map(|&(_, v)| v);
        let scale = |v: f64, inches: bool| if inches { v * 25.4 } else { v };
        let mut is_home = false;
        for &(l, v) in &words {
            match (l, v as i32) {
                ('G', 20) => inches = true,
                ('G', 21) => inches = false,
                ('G', 90) => incremental = false,
                ('G', 91) => incremental = true,
                ('G', 28) => is_home = true,
                ('G', 17) => plane = (0, 1),
                ('G', 18) => plane = (2, 0),
                ('G', 19) => plane = (1, 2),
                ('G', c @ 0..=3) if v.fract() == 0.0 => motion = c as u8,
                ('T', t) => tool = t as u8,
                _ => {}
            }
        }
        if is_home {
            // Homing ends pulled off the switch by the default 1 mm ($27).
            let named: Vec<usize> = (0..3).filter(|&a| get(['X', 'Y', 'Z'][a]).is_some()).collect();
            for a in if named.is_empty() { vec![0, 1, 2] } else { named } {
                pos[a] = HOME_MM[a];
            }
            continue;
        }
        let mut target = pos;
        let mut any = false;
        for (a, c) in ['X', 'Y', 'Z'].into_iter().enumerate() {
            if let Some(v) = get(c) {
                let v = scale(v, inches);
                target[a] = if incremental { pos[a] + v } else { v };
                any = true;
            }
        }
        if !any {
            continue;
        }
        if out.last().is_none_or(|p| p.tool != tool) {
            out.push(Polyline { tool, points: vec![pos] });
        }
        let poly = out.last_mut().expect("just pushed");
        if motion >= 2 {
            let off = |a: usize| scale(get(['I', 'J', 'K'][a]).unwrap_or(0.0), inches);
            let (a, b) = plane;
            let centre = match get('R') {
                Some(r) => r_centre([pos[a], pos[b]], [target[a], target[b]], scale(r, inches), motion == 2),
                None => [pos[a] + off(a), pos[b] + off(b)],
            };
            arc_points(pos, target, centre, plane, motion == 2, &mut poly.points);
        } else {
            poly.points.push(target);
        }
        pos = target;
    }
    out
}

/// Letter/value pairs of a line, comments removed.
fn words(line: &str) -> Vec<(char, f64)> {
    let mut text = String::new();
    let mut depth = 0;
    for c in line.split(';').next().unwrap_or("").chars() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            _ if depth == 0 && !c.is_whitespace() => text.push(c.to_ascii_uppercase()),
            _ => {}
        }
    }
    let mut out = Vec::new();
    let mut it = text.chars().peekable();
    while let Some(l) = it.next() {
        let mut num = String::new();
        while let Some(&c) = it.peek() {
            if c.is_ascii_digit() || c == '.' || c == '-' || c == '+' {
                num.push(c);
                it.next();
            } else {
                break;
            }
        }
        if let Ok(v) = num.parse() {
            out.push((l, v));
        }
    }
    out
}

fn r_centre(p: [f64; 2], t: [f64; 2], r: f64, cw: bool) -> [f64; 2] {
    let (dx, dy) = (t[0] - p[0], t[1] - p[1]);
    let d = (dx * dx + dy * dy).sqrt();
    let h = ((r * r - d * d / 4.0).max(0.0)).sqrt() * if cw == (r > 0.0) { -1.0 } else { 1.0 };
    [p[0] + dx / 2.0 - h * dy / d, p[1] + dy / 2.0 + h * dx / d]
}

/// Chords of an arc in `plane` (first, second axis), helical along the third.
fn arc_points(p: [f64; 3], t: [f64; 3], c: [f64; 2], plane: (usize, usize), cw: bool, out: &mut Vec<[f64; 3]>) {
    let (u, v) = plane;
    let w = 3 - u - v;
    let a0 = (p[v] - c[1]).atan2(p[u] - c[0]);
    let a1 = (t[v] - c[1]).atan2(t[u] - c[0]);
    let mut sweep = a1 - a0;
    if cw && sweep >= -1e-9 {
        sweep -= std::f64::consts::TAU;
    } else if !cw && sweep <= 1e-9 {
        sweep += std::f64::consts::TAU;
    }
    let r = ((p[u] - c[0]).powi(2) + (p[v] - c[1]).powi(2)).sqrt();
    let n = ((sweep.abs() * r / 0.2).ceil() as usize).clamp(4, 720);
    for k in 1..=n {
        let f = k as f64 / n as f64;
        let a = a0 + sweep * f;
        let mut q = [0.0; 3];
        q[u] = c[0] + r * a.cos();
        q[v] = c[1] + r * a.sin();
        q[w] = p[w] + (t[w] - p[w]) * f;
        out.push(q);
    }
}

/// The recorded path, split where the tool changes. X/Y in machine mm; Z is
/// the tool tip's in the user's frame (+Z up: the negated physical Z, less
/// the tool's length, since the tip hangs below the spindle), so that it
/// compares with the job's work Z.
pub fn recorded_path(vm: &Vm) -> Vec<Polyline> {
    let atc = &vm.config().machine.atc;
    let length =
        |id: u8| atc.pockets.iter().chain(std::iter::once(&atc.spindle)).flatten().find(|t| t.id == id).map_or(0.0, |t| t.length_mm);
    let spm = vm.config().machine.steps_per_mm;
    let changes: Vec<(u64, u8)> = vm
        .line_log()
        .iter()
        .filter_map(|(c, l)| l.strip_prefix("NowSelectedTool:").and_then(|t| t.trim().parse().ok()).map(|t| (*c, t)))
        .collect();
    let mut out: Vec<Polyline> = Vec::new();
    let mut next_change = 0;
    let mut tool = 0u8;
    let mut last = [f64::NAN; 3];
    vm.recorder().for_each_step(|p| {
        while next_change < changes.len() && changes[next_change].0 <= p.cycle {
            tool = changes[next_change].1;
            next_change += 1;
        }
        let mut mm = [0, 1, 2].map(|a| p.position[a] as f64 / spm[a]);
        mm[2] = -mm[2] - length(tool);
        if out.last().is_none_or(|l| l.tool != tool) {
            out.push(Polyline { tool, points: vec![] });
        }
        // Thin to about a point per 0.05 mm.
        let far = (0..3).any(|a| (mm[a] - last[a]).abs() >= 0.05) || last[0].is_nan();
        if far {
            out.last_mut().expect("pushed").points.push(mm);
            last = mm;
        }
    });
    out
}

fn tool_colour(tool: u8) -> RGBColor {
    const PALETTE: [RGBColor; 7] = [
        RGBColor(90, 90, 90),
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(23, 190, 207),
    ];
    PALETTE[tool as usize % PALETTE.len()]
}

/// Draw `out/toolpath.png`: top view (X/Y) and side view (X/Z).
pub fn write_toolpath_png(path: &Path, commanded: &[Polyline], recorded: &[Polyline]) -> Result<(), String> {
    let font = std::fs::read("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf").ok();
    if let Some(bytes) = font {
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        // Registering twice (a second picture in one process) is harmless.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    }
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (top, side) = root.split_horizontally(700);
    let all: Vec<[f64; 3]> = commanded.iter().chain(recorded).flat_map(|p| p.points.iter().copied()).collect();
    let range = |a: usize| {
        let lo = all.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
        let hi = all.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() {
            (lo - 2.0)..(hi + 2.0)
        } else {
            0.0..1.0
        }
    };
    for (area, (ax, ay), title) in [(&top, (0, 1), "top view X/Y (mm)"), (&side, (0, 2), "side view X/Z tip (mm, +Z up)")] {
        let yr = range(ay);
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(30)
            .y_label_area_size(45)
            .build_cartesian_2d(range(ax), yr)
            .map_err(|x| e(&x))?;
        chart.configure_mesh().light_line_style(RGBColor(235, 235, 235)).draw().map_err(|x| e(&x))?;
        let mut labelled = Vec::new();
        for p in recorded {
            let c = tool_colour(p.tool);
            let first_of_tool = !labelled.contains(&p.tool);
            labelled.push(p.tool);
            let s = chart.draw_series(LineSeries::new(p.points.iter().map(|q| (q[ax], q[ay])), c.stroke_width(4))).map_err(|x| e(&x))?;
            if ax == 0 && ay == 1 && first_of_tool {
                s.label(format!("recorded, T{}", p.tool))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(4)));
            }
        }
        for p in commanded {
            let s =
                chart.draw_series(LineSeries::new(p.points.iter().map(|q| (q[ax], q[ay])), BLACK.stroke_width(1))).map_err(|x| e(&x))?;
            if ax == 0 && ay == 1 && p.tool == commanded[0].tool {
                s.label("commanded").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
            }
        }
        if ax == 0 && ay == 1 {
            chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|x| e(&x))?;
        }
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(s: &str) -> Vec<String> {
        s.lines().map(String::from).collect()
    }

    #[test]
    fn commanded_path_follows_units_modes_arcs_and_tools() {
        let p = commanded_path(&lines("G28\nG21 G90\nG1 X10 Y0 F100\nT2\nG91 G1 Y5\nG90 G20 X1 ; inch\nG21 G2 X35.4 Y5 I5 J0"));
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].tool, 0);
        // G28 leaves every axis at the 1 mm pull-off: Z 1 mm below its top switch.
        assert_eq!(p[0].points, vec![[1.0, 1.0, -1.0], [10.0, 0.0, -1.0]]);
        assert_eq!(p[1].tool, 2);
        assert_eq!(p[1].points[1], [10.0, 5.0, -1.0]);
        assert_eq!(p[1].points[2], [25.4, 5.0, -1.0]);
        // A half circle of radius 5 clockwise from (25.4, 5) over the top.
        let arc = &p[1].points[3..];
        let end = arc.last().unwrap();
        assert!((end[0] - 35.4).abs() < 1e-9 && (end[1] - 5.0).abs() < 1e-9);
        assert!(arc.iter().all(|q| (((q[0] - 30.4).powi(2) + (q[1] - 5.0).powi(2)).sqrt() - 5.0).abs() < 1e-9));
        assert!(arc.iter().any(|q| q[1] > 9.9), "clockwise from the left goes over the top");
    }

    #[test]
    fn r_arcs_pick_the_short_way_for_positive_r() {
        let p = commanded_path(&lines("G1 X0 Y0\nG2 X10 Y0 R5"));
        let arc = &p[0].points;
        assert!(arc.iter().all(|q| q[1] >= -1e-9), "cw from (0,0) to (10,0) with R5 goes over the top: {arc:?}");
    }

    #[test]
    fn g18_arcs_lie_in_the_xz_plane() {
        let p = commanded_path(&lines("G1 X30 Y30 Z0\nG18 G2 X40 Z0 I5 K0"));
        let arc = &p[0].points[2..];
        assert!(arc.iter().all(|q| q[1] == 30.0));
        assert!(arc.iter().all(|q| (((q[0] - 35.0).powi(2) + q[2].powi(2)).sqrt() - 5.0).abs() < 1e-9));
        assert!((arc.last().unwrap()[0] - 40.0).abs() < 1e-9);
    }
}
