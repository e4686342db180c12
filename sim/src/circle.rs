//! The streaming benchmark's job (docs/SPEC.md §11): 2,000 G1 moves of 0.1 mm around
//! a circle of radius 20 mm centred at X22.5 Y22.5 (1.6 turns, so no corner
//! slows it), targets rounded to 0.001 mm. `tools/bench` and the profiler
//! (`sim/src/bin/profile.rs`) run this same job.

/// Moves in the job.
pub const MOVES: usize = 2000;
/// Centre of the circle, mm.
pub const CENTRE: (f64, f64) = (22.5, 22.5);
/// Radius, mm.
pub const RADIUS: f64 = 20.0;

/// The angle one 0.1 mm chord spans, rad.
pub fn chord_angle() -> f64 {
    2.0 * (0.05 / RADIUS).asin()
}

/// Target `k` (0 = the start), mm, rounded to 0.001 mm as the G-code
/// carries it.
pub fn point(k: usize) -> (f64, f64) {
    let th = k as f64 * chord_angle();
    let x = (CENTRE.0 + RADIUS * th.cos()) * 1000.0;
    let y = (CENTRE.1 + RADIUS * th.sin()) * 1000.0;
    (x.round() / 1000.0, y.round() / 1000.0)
}

/// The lines that bring the machine to the start at `feed` mm/min and wait
/// there. Above the factory 3000 mm/min per axis they raise the X/Y limit
/// first (M203 is mm/s), so that the feed alone sets the speed.
pub fn setup(feed: f64) -> Vec<String> {
    let mut v = Vec::new();
    if feed > 3000.0 {
        v.push(format!("M203 X{0} Y{0}", (feed / 60.0).ceil()));
    }
    let (x0, y0) = point(0);
    v.push(format!("G1 X{x0:.3} Y{y0:.3} F{feed}"));
    v.push("M400".to_string());
    v
}

/// The 2,000 moves (modal feed: the one [`setup`] set).
pub fn moves() -> Vec<String> {
    (1..=MOVES)
        .map(|k| {
            let (x, y) = point(k);
            format!("G1 X{x:.3} Y{y:.3}")
        })
        .collect()
}
