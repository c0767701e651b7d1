//! The chaos-map rows of BENCHMARKS.md (`harness = false`: prints a table). The
//! measure: MEGNO of the double pendulum over a 200 × 200 grid of (θ1, θ2) at rest, to
//! t = 100, on 2 threads.
//!
//! ```text
//! cargo bench --bench chaos_map                    # every 10th row and column of the 200 × 200 grid
//! CHAOS_STRIDE=1 cargo bench --bench chaos_map     # the whole 200 × 200 grid (long)
//! CHAOS_STRIDE=5 cargo bench --bench chaos_map -- double-pendulum
//! cargo bench --bench chaos_map -- henon-heiles    # the scene statement on the surface of section
//! CHAOS_STOP=5,20 cargo bench --bench chaos_map -- double-pendulum   # with the early stop Ȳ ≥ 5 after t = 20
//! CHAOS_STRIDE=5 cargo bench --bench chaos_map -- megno-stop-scan    # which early stops keep the regular cells
//! CHAOS_PATHS=cells,lanes CHAOS_ROUNDS=2 cargo bench --bench chaos_map -- double-pendulum   # one orbit at a time against the batch lanes, interleaved
//! CHAOS_TOL=1e-6 CHAOS_PATHS=cells,lanes cargo bench --bench chaos_map -- double-pendulum    # another tolerance (default 1e-9)
//! ```
//!
//! `CHAOS_PATHS` (default `lanes`): `lanes` is `chaos_map_with` (orbits in lane groups of the
//! Taylor method's batch mode), `cells` one `indicators_with` per orbit (the map before the
//! lanes); every run after the first is checked bit for bit against the first.
//!
//! A stride `s` keeps the cells `(i, j)` of the full grid with `i, j ≡ s/2 (mod s)`: the same
//! cell centres as the full map, spread evenly over it, so regular and chaotic regions are in
//! the sample in the proportion of the whole map and the full map's time is the sample's
//! times `s²` (an extrapolation, printed as such).
//!
//! Threads: rayon's global pool set to exactly 2 (`CHAOS_THREADS` changes it), whatever the
//! machine has (global, because the scene's backend runs the map from a thread of its own).

use std::f64::consts::PI;
use std::time::Instant;

use lagrangian::chaos::{chaos_map_with, indicators_with, Budget, Cell, Indicator, MegnoStop};
use lagrangian::compile::Variational;
use lagrangian::mechanics::System;

const SIDE: usize = 200;

fn env(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

/// The process's CPU time (user + system, every thread) in seconds, from /proc/self/stat
/// (Linux; clock ticks of 1/100 s). On a loaded machine wall time measures the load as much
/// as the code; CPU time does not.
fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            // The fields after the command name (which is in parentheses and may hold spaces).
            let rest = s.rsplit_once(')')?.1.split_whitespace().collect::<Vec<_>>();
            let (utime, stime): (f64, f64) = (rest.get(11)?.parse().ok()?, rest.get(12)?.parse().ok()?);
            Some((utime + stime) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

/// The early stop of `CHAOS_STOP=Y,T` (`Ȳ ≥ Y` after `t = T`), if set.
fn megno_stop() -> Option<MegnoStop> {
    let spec = std::env::var("CHAOS_STOP").ok()?;
    let (y, t) = spec.split_once(',').expect("CHAOS_STOP=Y,T");
    Some(MegnoStop::new(y.trim().parse().expect("Y"), t.trim().parse().expect("T")).expect("a valid stop"))
}

/// The double pendulum's variational system (one tangent vector and the MEGNO accumulator),
/// its compile time, and the sample of cell centres kept at `stride`.
fn double_pendulum_map(stride: usize) -> (Variational, f64, Vec<usize>, Vec<Vec<f64>>) {
    let l = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
             + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
    let t_compile = Instant::now();
    let sys = System::from_lagrangian(l, &["θ1", "θ2"])
        .and_then(|s| s.with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)]))
        .expect("valid L");
    let var = Variational::of_system(&sys, 1, true).expect("compiles");
    let compile = t_compile.elapsed().as_secs_f64();
    // Cell centres of the 200 × 200 grid over [−π, π]², at rest (p = 0).
    let centre = |k: usize| -PI + (k as f64 + 0.5) * 2.0 * PI / SIDE as f64;
    let picked: Vec<usize> = (0..SIDE).filter(|k| k % stride == stride / 2).collect();
    let starts: Vec<Vec<f64>> =
        picked.iter().flat_map(|&j| picked.iter().map(move |&i| vec![centre(i), centre(j), 0.0, 0.0])).collect();
    (var, compile, picked, starts)
}

fn double_pendulum() {
    let stride = env("CHAOS_STRIDE", 10).clamp(1, SIDE);
    // The example's tolerance; `CHAOS_TOL` for where the lanes pay (the order follows it).
    let tol: f64 = std::env::var("CHAOS_TOL").ok().and_then(|s| s.parse().ok()).unwrap_or(1e-9);
    let stop = megno_stop();
    let (var, compile, picked, starts) = double_pendulum_map(stride);
    println!(
        "## Double pendulum MEGNO, 200 × 200 grid over (θ1, θ2) ∈ [−π, π]² at rest, t = 100, tol {tol:e}, \
         stride {stride}: {} × {} cells, {} threads, early stop {}, load {}",
        picked.len(),
        picked.len(),
        rayon::current_num_threads(),
        stop.map_or("none".to_string(), |s| format!("Ȳ ≥ {} after t = {}", s.above, s.after)),
        load()
    );
    // No step or time budget: the measure is the whole map.
    let budget = Budget { max_steps: usize::MAX, deadline: None, time_limit: None, max_samples: 2, megno_stop: stop };
    let paths: Vec<String> = std::env::var("CHAOS_PATHS")
        .unwrap_or_else(|_| "lanes".into())
        .split(',')
        .map(|p| p.trim().to_string())
        .collect();
    let rounds = env("CHAOS_ROUNDS", 1).max(1);
    println!("compile (text → variational tape): {:.1} ms", 1e3 * compile);
    let mut first: Option<(String, Vec<Cell>)> = None;
    for round in 1..=rounds {
        for path in &paths {
            let (t0, c0) = (Instant::now(), cpu_seconds());
            let cells: Vec<Cell> = match path.as_str() {
                // One orbit at a time on each thread: the reference, and the map before the lanes.
                "cells" => {
                    use rayon::prelude::*;
                    starts
                        .par_iter()
                        .map(|x0| match indicators_with(&var, x0, 100.0, tol, &budget) {
                            Ok(r) => Cell { value: r.megno, stopped_at: r.stopped_at },
                            Err(_) => Cell { value: f64::NAN, stopped_at: None },
                        })
                        .collect()
                }
                "lanes" => chaos_map_with(&var, &starts, 100.0, tol, Indicator::Megno, &budget),
                other => panic!("CHAOS_PATHS: `{other}` is neither `cells` nor `lanes`"),
            };
            let (secs, cpu) = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
            report(path, round, &cells, secs, cpu, stride);
            match &first {
                None => first = Some((path.clone(), cells)),
                Some((p0, c)) => {
                    let same = c.iter().zip(&cells).all(|(a, b)| {
                        a.value.to_bits() == b.value.to_bits()
                            && a.stopped_at.map(f64::to_bits) == b.stopped_at.map(f64::to_bits)
                    });
                    assert!(same, "{path} (round {round}) differs from {p0}'s first run");
                    println!("  every cell bit for bit as {p0}'s first run");
                }
            }
        }
    }
    println!("load after: {}", load());
}

/// One run of the map: its counts, wall and CPU time.
fn report(path: &str, round: usize, cells: &[Cell], secs: f64, cpu: f64, stride: usize) {
    let map: Vec<f64> = cells.iter().map(|c| c.value).collect();
    let stopped = cells.iter().filter(|c| c.stopped_at.is_some()).count();
    let n = cells.len() as f64;
    let failed = map.iter().filter(|v| v.is_nan()).count();
    let regular = map.iter().filter(|v| **v < 2.5).count();
    println!(
        "[{path}, round {round}] {} points in {secs:.1} s: {:.1} points/s ({failed} failed; {regular} with ⟨Y⟩ < 2.5, {stopped} stopped early, max {:.1}), load {}",
        cells.len(),
        n / secs,
        map.iter().copied().filter(|v| v.is_finite()).fold(0.0, f64::max),
        load()
    );
    println!(
        "  CPU time {cpu:.1} s ({:.1} points per CPU-second; 2 cores to themselves would give about {:.1} points/s, \
         the full map about {:.0} s)",
        n / cpu,
        2.0 * n / cpu,
        40000.0 / (2.0 * n / cpu)
    );
    if stride > 1 {
        println!(
            "  full 200 × 200 map extrapolated from this sample's wall time: {:.0} s at {:.1} points/s",
            40000.0 / (n / secs),
            n / secs
        );
    }
}

/// Which early stops (`Ȳ ≥ Y` after `t = T`) would keep the regular cells (⟨Y⟩ < 2.5 at
/// t = 100) of the sample, and what each would save: every orbit runs to its end keeping
/// every step's running mean, then each candidate stop is applied to those series. A stop
/// changes nothing before it, so a cell it spares ends bit for bit as without it; the
/// regular cells are kept exactly when no stopped cell would have ended below 2.5.
fn megno_stop_scan() {
    let stride = env("CHAOS_STRIDE", 5).clamp(1, SIDE);
    let tol = 1e-9;
    let (var, _, picked, starts) = double_pendulum_map(stride);
    println!(
        "## Early stops on the double pendulum's MEGNO map, stride {stride} ({} × {} cells), t = 100, tol {tol:e}, load {}",
        picked.len(),
        picked.len(),
        load()
    );
    let budget =
        Budget { max_steps: usize::MAX, deadline: None, time_limit: None, max_samples: usize::MAX, megno_stop: None };
    let t0 = Instant::now();
    let runs: Vec<_> = {
        use rayon::prelude::*;
        starts.par_iter().map(|x0| indicators_with(&var, x0, 100.0, tol, &budget).ok()).collect()
    };
    println!("{} orbits in {:.1} s", runs.len(), t0.elapsed().as_secs_f64());
    let runs: Vec<_> = runs.into_iter().flatten().collect();
    let total: usize = runs.iter().map(|r| r.steps).sum();
    let regular = runs.iter().filter(|r| r.megno < 2.5).count();
    println!("{} finished ({regular} with ⟨Y⟩ < 2.5), {total} steps", runs.len());
    println!("| stop Ȳ ≥ | after t | stopped | of them ending < 2.5 | least final Ȳ of a stopped cell | steps left |");
    println!("|---|---|---|---|---|---|");
    for above in [3.0, 4.0, 5.0, 8.0] {
        for after in [5.0, 10.0, 20.0, 30.0] {
            let (mut stopped, mut wrong, mut least, mut steps) = (0, 0, f64::INFINITY, 0usize);
            for r in &runs {
                match r.samples.iter().position(|s| s.t >= after && s.megno >= above) {
                    Some(k) if k + 1 < r.samples.len() => {
                        stopped += 1;
                        wrong += usize::from(r.megno < 2.5);
                        least = least.min(r.megno);
                        steps += k + 1;
                    }
                    _ => steps += r.steps,
                }
            }
            println!(
                "| {above} | {after} | {stopped} | {wrong} | {least:.2} | {:.1} % |",
                100.0 * steps as f64 / total as f64
            );
        }
    }
}

/// The scene statement on the Hénon–Heiles surface of section (the product path: parse,
/// compile through the backend, solve p_x per cell, integrate, write the table).
fn henon_heiles() {
    use lagrangian::scene::{Mode, Options, Session};
    let side = env("HH_POINTS", 40);
    let dir = std::env::temp_dir().join(format!("lagrangian-chaos-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let scene = format!(
        "coordinates x, y\nH = (p_x^2 + p_y^2)/2 + (x^2 + y^2)/2 + x^2 y - y^3/3\n\
         chaos_map megno y = -0.6..1.1, p_y = -0.65..0.65, x = 0 for t in 0..100 on H = 1/6 solve p_x > 0 \
         tol = 1e-9 points {side} to map.csv\n"
    );
    let mut opts = Options::new(Mode::Scene);
    opts.out_dir = dir.clone();
    let mut session = Session::new(opts);
    println!(
        "## Hénon–Heiles MEGNO on its surface of section x = 0, H = 1/6 (p_x > 0 solved per cell), \
         {side} × {side} scene `chaos_map`, t = 100, tol 1e-9, {} threads, load {}",
        rayon::current_num_threads(),
        load()
    );
    let (t0, c0) = (Instant::now(), cpu_seconds());
    session.run_scene("bench", &scene).expect("the scene runs");
    let (secs, cpu) = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
    let csv = std::fs::read_to_string(dir.join("map.csv")).expect("the map was written");
    let on: Vec<f64> = csv
        .lines()
        .skip(1)
        .filter_map(|r| r.split(',').nth(2))
        .filter(|v| !v.is_empty())
        .map(|v| v.parse().unwrap_or(f64::NAN))
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "{} cells ({} on the surface) in {secs:.1} s, CPU {cpu:.1} s: {:.1} points/s on the surface, {:.1} per CPU-second \
         ({} with ⟨Y⟩ < 2.5, {} above 5)",
        side * side,
        on.len(),
        on.len() as f64 / secs,
        on.len() as f64 / cpu,
        on.iter().filter(|v| **v < 2.5).count(),
        on.iter().filter(|v| **v > 5.0).count()
    );
    for line in session.take_output() {
        println!("{line}");
    }
    println!("load after: {}", load());
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let want = |s: &str| args.is_empty() || args.iter().any(|a| a == s);
    rayon::ThreadPoolBuilder::new().num_threads(env("CHAOS_THREADS", 2)).build_global().expect("rayon's global pool");
    if want("double-pendulum") {
        double_pendulum();
    }
    if args.iter().any(|a| a == "megno-stop-scan") {
        megno_stop_scan();
    }
    if want("henon-heiles") {
        henon_heiles();
    }
}
