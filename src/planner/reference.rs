//! The planner against a plain f64 re-implementation of the same rules,
//! written here from the docs (grbl's `plan_buffer_line` and
//! `planner_recalculate`, docs/SPEC.md §6): on random 3-axis paths, with
//! reversals, repeats and one-step segments, under three sets of settings,
//! every block's junction limit (max entry speed²) and planned entry speed²
//! stay within 1 % of the reference after every move. The planner's float
//! shortcuts (cached roots, reciprocals and junction thresholds, bit-pattern
//! compares, the look-ahead's early stop) must never move it further.

use super::junction::REVERSAL_STEP_S;
use super::*;
use crate::config::{Settings, MAX_STEP_RATE_HZ, MIN_STEP_RATE_HZ};
use crate::N_AXES;

/// One block as the reference sees it.
#[derive(Clone, Copy, Debug)]
struct RefBlock {
    unit: [f64; N_AXES],
    mm: f64,
    accel: f64,
    nominal_sqr: f64,
    max_entry_sqr: f64,
    entry_sqr: f64,
}

/// The reference planner: a ring of at most `BLOCK_BUFFER_LEN` blocks,
/// fully re-planned after every move.
struct RefPlanner {
    s: Settings,
    blocks: Vec<RefBlock>,
    pos: [i32; N_AXES],
}

impl RefPlanner {
    fn push(&mut self, target: [i32; N_AXES], speed: Speed) {
        let s = &self.s;
        let mut mm_axis = [0.0f64; N_AXES];
        let mut max_steps = 0u32;
        for i in 0..N_AXES {
            let d = target[i] - self.pos[i];
            mm_axis[i] = d as f64 / s.steps_per_mm[i] as f64;
            max_steps = max_steps.max(d.unsigned_abs());
        }
        self.pos = target;
        if max_steps == 0 {
            return;
        }
        let xyz = (0..3).map(|i| mm_axis[i] * mm_axis[i]).sum::<f64>().sqrt();
        let mm = if xyz > 0.0 { xyz } else { mm_axis[3].abs() };
        let unit = mm_axis.map(|m| m / mm);
        let (mut accel, mut t_axes) = (f64::INFINITY, 0.0f64);
        for i in 0..N_AXES {
            if unit[i] != 0.0 {
                accel = accel.min(s.accel_mm_per_s2[i] as f64 / unit[i].abs());
                t_axes = t_axes.max(unit[i].abs() * 60.0 / s.max_feed_mm_per_min[i] as f64);
            }
        }
        let mut t = match speed {
            Speed::Rapid => t_axes,
            Speed::Feed(f) | Speed::Fixed(f) => t_axes.max(60.0 / f as f64),
        };
        let steps_per_mm = max_steps as f64 / mm;
        if steps_per_mm / t > MAX_STEP_RATE_HZ as f64 {
            t = steps_per_mm / MAX_STEP_RATE_HZ as f64;
        } else if steps_per_mm / t < MIN_STEP_RATE_HZ as f64 {
            t = steps_per_mm / MIN_STEP_RATE_HZ as f64;
        }
        let nominal_sqr = 1.0 / (t * t);
        let max_entry_sqr = match self.blocks.last() {
            None => 0.0,
            Some(p) => {
                let cos = -(0..N_AXES).map(|i| p.unit[i] * unit[i]).sum::<f64>();
                let v_sqr = if cos > 0.999_999 {
                    0.0
                } else if cos < -0.999_999 {
                    f64::INFINITY
                } else {
                    let sin_half = ((1.0 - cos) / 2.0).sqrt();
                    let mut v = accel.min(p.accel) * s.junction_deviation_mm as f64 * sin_half / (1.0 - sin_half);
                    for i in 0..N_AXES {
                        if p.unit[i] * unit[i] < 0.0 {
                            let dv = REVERSAL_STEP_S as f64 * s.accel_mm_per_s2[i] as f64 / (p.unit[i].abs() + unit[i].abs());
                            v = v.min(dv * dv);
                        }
                    }
                    v
                };
                v_sqr.min(nominal_sqr).min(p.nominal_sqr)
            }
        };
        let entry_sqr = if self.blocks.is_empty() { 0.0 } else { max_entry_sqr };
        self.blocks.push(RefBlock { unit, mm, accel, nominal_sqr, max_entry_sqr, entry_sqr });
        self.replan();
    }

    /// Backward from a stop after the newest block, then forward from the
    /// executing block's entry (which is kept: that block is running).
    fn replan(&mut self) {
        let b = &mut self.blocks;
        let mut exit = 0.0f64;
        for i in (1..b.len()).rev() {
            b[i].entry_sqr = b[i].max_entry_sqr.min(exit + 2.0 * b[i].accel * b[i].mm);
            exit = b[i].entry_sqr;
        }
        for i in 1..b.len() {
            let reach = b[i - 1].entry_sqr + 2.0 * b[i - 1].accel * b[i - 1].mm;
            b[i].entry_sqr = b[i].entry_sqr.min(reach);
        }
    }
}

/// A random path: mostly short moves, with one-step moves, repeats of the
/// last move (collinear), exact reversals, and some long moves.
fn random_moves(seed: u32, n: usize) -> Vec<([i32; N_AXES], Speed)> {
    let mut r = seed;
    let mut next = move |m: u32| {
        r = r.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        (r >> 8) % m
    };
    let mut pos = [0i32; N_AXES];
    let mut last = [1i32, 0, 0, 0];
    let mut v = Vec::new();
    for _ in 0..n {
        let d = match next(8) {
            0 => last,
            1 => last.map(|x| -x),
            2 => [next(3) as i32 - 1, next(3) as i32 - 1, next(3) as i32 - 1, 0],
            3 => [next(4001) as i32 - 2000, next(4001) as i32 - 2000, next(201) as i32 - 100, 0],
            _ => [next(41) as i32 - 20, next(41) as i32 - 20, next(11) as i32 - 5, 0],
        };
        if d == [0; N_AXES] {
            continue;
        }
        last = d;
        for i in 0..N_AXES {
            pos[i] += d[i];
        }
        let speed = match next(10) {
            0 => Speed::Rapid,
            1 => Speed::Fixed(250.0),
            _ => Speed::Feed([3000.0, 600.0, 1800.0, 5000.0, 40.0, 20.0][next(6) as usize]),
        };
        v.push((pos, speed));
    }
    v
}

/// Default settings, one with a slower, differently geared Z, and one with
/// X/Y/Z all at different steps/mm and limits.
fn settings_variants() -> Vec<Settings> {
    let mut v = vec![Settings::DEFAULT];
    let mut z = Settings::DEFAULT;
    z.steps_per_mm[2] = 400.0;
    z.accel_mm_per_s2[2] = 200.0;
    z.max_feed_mm_per_min[2] = 600.0;
    v.push(z);
    let mut all = Settings::DEFAULT;
    all.steps_per_mm = [80.0, 100.0, 320.0, all.steps_per_mm[3]];
    all.accel_mm_per_s2 = [800.0, 1200.0, 150.0, 50.0];
    all.max_feed_mm_per_min = [5000.0, 4000.0, 900.0, 600.0];
    all.junction_deviation_mm = 0.05;
    v.push(all);
    v
}

fn within(got: f32, want: f64, what: &str) {
    let tol = 0.01 * want.abs() + 1e-6;
    assert!(((got as f64) - want).abs() <= tol, "{what}: {got} vs reference {want}");
}

/// Compare every queued block with the reference.
fn compare(p: &Planner, r: &RefPlanner, what: &str) {
    assert_eq!(p.len(), r.blocks.len(), "{what}: blocks queued");
    for (k, rb) in r.blocks.iter().enumerate() {
        let b = p.block(k).unwrap();
        within(b.nominal_speed_sqr, rb.nominal_sqr, &format!("{what} block {k} nominal²"));
        within(crate::F_CPU / b.dv_cycles, rb.accel, &format!("{what} block {k} acceleration"));
        if k > 0 {
            within(b.max_entry_speed_sqr, rb.max_entry_sqr, &format!("{what} block {k} junction²"));
            within(b.entry_speed_sqr, rb.entry_sqr, &format!("{what} block {k} entry²"));
        }
    }
}

#[test]
fn junction_and_entry_speeds_match_an_f64_reference_on_random_paths() {
    for (v, st) in settings_variants().into_iter().enumerate() {
        for seed in 1..=6u32 {
            let mut p = Planner::new();
            let mut r = RefPlanner { s: st, blocks: Vec::new(), pos: [0; N_AXES] };
            for (i, (target, speed)) in random_moves(seed * 7919 + v as u32, 600).into_iter().enumerate() {
                if p.is_full() {
                    // The executing block is done; the next one keeps its entry.
                    p.discard_current_block();
                    r.blocks.remove(0);
                }
                let before = p.len();
                p.push_move(target, speed, &st).unwrap();
                r.push(target, speed);
                if p.len() == before {
                    continue;
                }
                compare(&p, &r, &format!("settings {v} seed {seed} move {i}"));
            }
        }
    }
}

#[test]
fn accepted_moves_get_the_reference_junctions_once_flushed() {
    for (v, st) in settings_variants().into_iter().enumerate() {
        let mut p = Planner::new();
        let mut r = RefPlanner { s: st, blocks: Vec::new(), pos: [0; N_AXES] };
        for (i, (target, speed)) in random_moves(31 + v as u32, 800).into_iter().enumerate() {
            if p.is_full() {
                p.flush(&st);
                p.discard_current_block();
                r.blocks.remove(0);
            }
            p.accept_line(&target, speed, &st).unwrap();
            r.push(target, speed);
            p.flush(&st);
            p.replan();
            compare(&p, &r, &format!("settings {v} move {i} (accepted)"));
        }
    }
}

/// The plain junction rule (f64): v² = a·δ·s/(1 − s), s = sin(θ/2), at most
/// `cap`, with the reversal limit, for unit vectors `p` then `u`.
fn plain_junction(p: &[f64; N_AXES], u: &[f64; N_AXES], a: f64, cap: f64, s: &Settings) -> f64 {
    let cos = -(0..N_AXES).map(|i| p[i] * u[i]).sum::<f64>();
    if cos > 0.999_999 {
        return 0.0;
    }
    if cos < -0.999_999 {
        return cap;
    }
    let sin_half = ((1.0 - cos) / 2.0).sqrt();
    let mut v = a * s.junction_deviation_mm as f64 * sin_half / (1.0 - sin_half);
    for i in 0..N_AXES {
        if p[i] * u[i] < 0.0 {
            let dv = REVERSAL_STEP_S as f64 * s.accel_mm_per_s2[i] as f64 / (p[i].abs() + u[i].abs());
            v = v.min(dv * dv);
        }
    }
    v.min(cap)
}

#[test]
fn the_junction_threshold_cache_gives_the_plain_junction_rule() {
    use super::junction::{junction_sqr, reversing_plain, CapCache};
    let mut r = 99u32;
    let mut next = move || {
        r = r.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        ((r >> 8) % 2001) as f64 / 1000.0 - 1.0
    };
    let mut cache = CapCache::EMPTY;
    let mut straight = 0;
    for (v, st) in settings_variants().into_iter().enumerate() {
        let mut prev = [1.0f64, 0.0, 0.0, 0.0];
        for k in 0..20_000 {
            // Mostly gentle turns (a curve's chords), some sharp ones.
            let turn = if k % 4 == 0 { 1.0 } else { 0.01 };
            let mut u = [prev[0] + turn * next(), prev[1] + turn * next(), prev[2] + turn * 0.3 * next(), 0.0];
            if k % 50 == 0 {
                u[3] = 0.2 * next();
            }
            let n = u.iter().map(|x| x * x).sum::<f64>().sqrt();
            let u = u.map(|x| x / n);
            let moving = (0..N_AXES).fold(0u8, |m, i| if u[i] != 0.0 { m | 1 << i } else { m });
            // A path's acceleration is at least its slowest axis'.
            let a_floor =
                (0..N_AXES).filter(|&i| u[i] != 0.0 || prev[i] != 0.0).map(|i| st.accel_mm_per_s2[i] as f64).fold(f64::INFINITY, f64::min);
            // Half the junctions at one of two accelerations, as a
            // curve's chords repeat them, under caps that change: the
            // (a·δ + L)² cache hits, and must not across caps.
            let (a0, a1) = if k % 2 == 0 {
                (a_floor * (1.0 + next().abs()), a_floor * (1.0 + next().abs()))
            } else {
                let a = a_floor * [1.5, 1.25][k % 4 / 2];
                (a, a)
            };
            let cap = [2500.0f64, 900.0, 40.0][k % 3];
            let (pf, uf) = (prev.map(|x| x as f32), u.map(|x| x as f32));
            let e_axis = moving & 0b1000 != 0 || pf[3] != 0.0;
            let got = junction_sqr(
                false,
                || super::junction::cos_theta(&pf, &uf, moving),
                e_axis,
                reversing_plain(&pf, &uf),
                || (pf, uf),
                || (a0 as f32).min(a1 as f32),
                cap as f32,
                &mut cache,
                &st,
            )
            .min(cap as f32);
            let want = plain_junction(&prev, &u, a0.min(a1), cap, &st);
            assert!((got as f64 - want).abs() <= 1e-3 * want + 1e-6, "settings {v} junction {k}: {got} vs plain {want} ({prev:?} → {u:?})");
            straight += (got as f64 == cap) as u32;
            prev = u;
        }
    }
    assert!(straight > 10_000, "the cached threshold is taken: {straight}");
}

#[test]
fn a_short_moves_acceleration_from_the_reciprocal_table_is_the_plain_division() {
    // X/Y/Z at one steps/mm and the same limits: the cached-root path.
    let st = Settings::DEFAULT;
    for dx in -17i32..=17 {
        for dy in -17i32..=17 {
            for dz in [-3i32, 0, 5] {
                if (dx, dy, dz) == (0, 0, 0) {
                    continue;
                }
                let mut p = Planner::new();
                p.push_line([dx, dy, dz, 0], 3000.0, false, &st).unwrap();
                let b = p.block(0).unwrap();
                // The plain way: the largest unit component, then a₀ / it.
                let n = (dx * dx + dy * dy + dz * dz) as f32;
                let u_max = dx.abs().max(dy.abs()).max(dz.abs()) as f32 / n.sqrt();
                let want = 1.0 / (u_max * (1.0 / st.accel_mm_per_s2[0]));
                // The acceleration in the block's 2·a·mm, and F_CPU over it.
                let a = b.max_delta_speed_sqr / (2.0 * b.millimeters);
                assert!((a - want).abs() <= 6e-7 * want, "({dx}, {dy}, {dz}): {a} vs {want}");
                let k = b.dv_cycles as f64;
                let want_k = crate::F_CPU as f64 / want as f64;
                assert!((k - want_k).abs() <= 4e-7 * k, "({dx}, {dy}, {dz}): F_CPU/a {k} vs {want_k}");
            }
        }
    }
}

#[test]
fn the_largest_unit_component_is_the_dominant_axis_share() {
    // The cached-root path at a feed above the axes' limit, so that the
    // per-axis limit sets the nominal speed: the plain way takes |u|max as
    // n·(1/√S) (n the dominant axis' steps), the planner as the largest
    // unit component; bit for bit the same (both roots by the planner's
    // `sqrt_1ulp`, which has its own twin test against the exact root).
    let st = Settings::DEFAULT;
    for dx in -40i32..=40 {
        for dy in -40i32..=40 {
            for dz in [-7i32, 0, 3] {
                if (dx, dy, dz) == (0, 0, 0) {
                    continue;
                }
                let mut p = Planner::new();
                p.push_line([dx, dy, dz, 0], 1.0e5, false, &st).unwrap();
                let b = p.block(0).unwrap();
                let n = dx.abs().max(dy.abs()).max(dz.abs()) as f32;
                let inv_root = 1.0 / crate::math::sqrt_1ulp((dx * dx + dy * dy + dz * dz) as f32);
                let u_max = n * inv_root;
                let v = 1.0 / (u_max * (60.0 / st.max_feed_mm_per_min[0]));
                assert_eq!(b.nominal_speed_sqr.to_bits(), (v * v).to_bits(), "({dx}, {dy}, {dz})");
                if crate::math::recip_small(n as u32).is_none() {
                    let inv_a = u_max * (1.0 / st.accel_mm_per_s2[0]);
                    assert_eq!(b.dv_cycles.to_bits(), (inv_a * crate::F_CPU).to_bits(), "({dx}, {dy}, {dz})");
                }
            }
        }
    }
}

#[test]
fn the_reciprocal_table_is_one_over_n() {
    assert_eq!(crate::math::recip_small(0), None);
    for n in 1..=16u32 {
        assert_eq!(crate::math::recip_small(n), Some(1.0 / n as f32));
    }
    assert_eq!(crate::math::recip_small(17), None);
}
