//! The product end to end: Lagrangian or Hamiltonian text → `System` → compiled right-hand
//! side → integrator, the way a user runs it. Every engine figure in README and BENCHMARKS
//! comes from here; hand-written Rust right-hand sides (parameters folded as constants, no
//! allocation, no zero-fill) are a separate column measured in the same run.
//!
//! ```text
//! cargo bench --bench pipeline                      # everything (~2 minutes on 2 cores)
//! cargo bench --bench pipeline -- quick             # fewer repeats, 10³ Kepler orbits
//! cargo bench --bench pipeline -- long              # Kepler over the full 10⁵ orbits
//! cargo bench --bench pipeline -- --json FILE       # also write one JSON object per row
//! ```
//!
//! What is measured, with the same statistics as the Python anchors (`benches/anchors/`):
//! - **Warm** times are the median and the minimum over repeats in one process (the interner,
//!   the rule table and the JIT already warm for derivations; for integrations, the compiled
//!   right-hand side is built once and only the integration is timed).
//! - **Cold** times are whole fresh processes of this binary (`cold-dp`, `cold-derive`
//!   sub-commands), text to final state, timed from outside (process start included); the
//!   process also reports its own phase times.
//! - **Errors** are maxima over the whole run: the final-state error of the chaotic double
//!   pendulum against its 50-digit reference, as a curve over tolerances; the Kepler energy
//!   error at every step, not at chosen phases.

use std::fmt::Write as _;
use std::hint::black_box;
use std::io::Write as _;
use std::process::Command;
use std::time::{Duration, Instant};

use lagrangian::diff::Differentiator;
use lagrangian::expr::Expr;
use lagrangian::integrate::problems::{DoublePendulum, Kepler};
use lagrangian::integrate::{Dop853, Integrate, Options, Rhs, Separable, Splitting, Status};
use lagrangian::mechanics::System;
use lagrangian::Declarations;

#[path = "../tests/it/support/n_link.rs"]
mod n_link;
use n_link::n_link_system;

/// The double pendulum as a user writes it (PHYSICS.md §3), relative angles from the vertical.
const DOUBLE: &str = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
                      + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
const DOUBLE_PARAMS: [(&str, f64); 5] = [("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)];
/// Kepler in Cartesian coordinates, `μ = 1`.
const KEPLER: &str = "(p_x^2 + p_y^2)/2 - 1/sqrt(x^2 + y^2)";
const TOLS: [f64; 10] = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15];

/// The double pendulum's right-hand side written by hand with the reference parameters folded
/// in as constants (unit masses and lengths, `g = 9.81`): the fair hand-written baseline.
struct DoubleHand;

impl Rhs for DoubleHand {
    fn dim(&self) -> usize {
        4
    }
    #[inline]
    fn eval(&self, _t: f64, y: &[f64], dy: &mut [f64]) {
        const G: f64 = 9.81;
        let (t1, t2, w1, w2) = (y[0], y[1], y[2], y[3]);
        let (s, c) = (t1 - t2).sin_cos();
        // W = [[2, c], [c, 1]], F = (−w2² s − 2 g sin θ1, w1² s − g sin θ2).
        let f1 = -w2 * w2 * s - 2.0 * G * t1.sin();
        let f2 = w1 * w1 * s - G * t2.sin();
        let det = 2.0 - c * c;
        dy[0] = w1;
        dy[1] = w2;
        dy[2] = (f1 - c * f2) / det;
        dy[3] = (2.0 * f2 - c * f1) / det;
    }
}

/// Median and minimum of repeated timings.
#[derive(Clone, Copy)]
struct Stat {
    median: f64,
    min: f64,
    reps: usize,
}

/// Times `f` at least 3 and at most 31 times, until `budget` is spent.
fn repeat<R>(budget: Duration, mut f: impl FnMut() -> R) -> (Stat, R) {
    let mut times = Vec::new();
    let started = Instant::now();
    let mut last;
    loop {
        let t = Instant::now();
        last = black_box(f());
        times.push(t.elapsed().as_secs_f64());
        if times.len() >= 31 || (times.len() >= 3 && started.elapsed() >= budget) {
            break;
        }
    }
    (stat(&mut times), last)
}

fn stat(times: &mut [f64]) -> Stat {
    times.sort_by(f64::total_cmp);
    let n = times.len();
    let median = if n % 2 == 1 { times[n / 2] } else { 0.5 * (times[n / 2 - 1] + times[n / 2]) };
    Stat { median, min: times[0], reps: n }
}

fn fmt_time(s: f64) -> String {
    if s < 1e-3 {
        format!("{:.1} µs", s * 1e6)
    } else if s < 1.0 {
        format!("{:.3} ms", s * 1e3)
    } else {
        format!("{s:.2} s")
    }
}

fn max_err(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Rows for `--json`: one JSON object per measurement, the schema the anchors also write.
struct Rows {
    out: Vec<String>,
}

impl Rows {
    fn push(&mut self, case: &str, tool: &str, kind: &str, param: f64, s: Stat, err: Option<f64>) {
        let err = err.map_or("null".to_string(), |e| format!("{e:e}"));
        self.out.push(format!(
            "{{\"tool\": \"{tool}\", \"case\": \"{case}\", \"kind\": \"{kind}\", \"param\": {param:e}, \"median_s\": {:e}, \"min_s\": {:e}, \"reps\": {}, \"err\": {err}}}",
            s.median, s.min, s.reps
        ));
    }
}

fn double_pendulum_system() -> System {
    System::from_lagrangian(DOUBLE, &["θ1", "θ2"])
        .and_then(|s| s.with_params(&DOUBLE_PARAMS))
        .expect("the double pendulum is valid")
}

fn dop_final<S: Rhs + ?Sized>(sys: &S, tol: f64) -> Vec<f64> {
    Dop853::new(tol, tol)
        .integrate_with(sys, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only())
        .expect("integrates")
        .last_state()
        .to_vec()
}

/// Double pendulum to t = 10, DOP853 over tolerances: engine (text → compiled rhs) and
/// hand-written Rust, integration alone, and the error curve.
fn double_pendulum(budget: Duration, rows: &mut Rows, report: &mut String) {
    let rhs = double_pendulum_system().compile_rhs().expect("compiles");
    let _ = writeln!(report, "\n### Double pendulum θ = (2.0, 2.5) at rest, DOP853 to t = 10: integration alone\n");
    let _ = writeln!(
        report,
        "| tol | engine median | engine min | hand-written median | hand-written min | engine / hand (median) | error vs 50-digit reference (engine; hand) | steps |"
    );
    let _ = writeln!(report, "|---|---|---|---|---|---|---|---|");
    let exact = DoublePendulum::REFERENCE_T10;
    for tol in TOLS {
        let (se, ye) = repeat(budget, || dop_final(&rhs, tol));
        let (sh, yh) = repeat(budget, || dop_final(&DoubleHand, tol));
        let steps = Dop853::new(tol, tol)
            .integrate_with(&rhs, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only())
            .expect("integrates")
            .stats
            .steps;
        let (ee, eh) = (max_err(&ye, &exact), max_err(&yh, &exact));
        rows.push("double_pendulum_dop853", "lagrangian (engine)", "warm", tol, se, Some(ee));
        rows.push("double_pendulum_dop853", "hand-written Rust", "warm", tol, sh, Some(eh));
        let _ = writeln!(
            report,
            "| {tol:.0e} | {} | {} | {} | {} | {:.2} | {ee:.1e}; {eh:.1e} | {steps} |",
            fmt_time(se.median),
            fmt_time(se.min),
            fmt_time(sh.median),
            fmt_time(sh.min),
            se.median / sh.median
        );
    }
}

/// The `cold-dp TOL` sub-command: text to final state in this (fresh) process. Prints one JSON
/// object with the phase times and the error.
fn cold_dp(tol: f64) {
    let t0 = Instant::now();
    let sys = double_pendulum_system();
    let rhs = sys.compile_rhs().expect("compiles");
    let t1 = Instant::now();
    let y = dop_final(&rhs, tol);
    let t2 = Instant::now();
    println!(
        "{{\"derive_compile_s\": {:e}, \"integrate_s\": {:e}, \"err\": {:e}}}",
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        max_err(&y, &DoublePendulum::REFERENCE_T10)
    );
}

/// The raw Euler–Lagrange expressions d/dt ∂L/∂q' − ∂L/∂q (no simplification): what the
/// SymEngine anchor builds.
fn raw_el(s: &System) -> Vec<Expr> {
    let l = s.lagrangian().expect("Lagrangian");
    let names: std::collections::BTreeSet<String> = s.coordinates().iter().map(|q| q.name().to_string()).collect();
    let mut d = Differentiator::new();
    s.coordinates()
        .iter()
        .zip(s.velocities())
        .map(|(q, v)| {
            let p = d.diff(l, v);
            d.dt(&p, &names).minus(&d.diff(l, q))
        })
        .collect()
}

/// The `cold-derive N` sub-command: parse the n-link text and derive W, F in this (fresh)
/// process.
fn cold_derive(n: usize) {
    let t0 = Instant::now();
    let s = n_link_system(n);
    let wf = s.mass_matrix_split().expect("W, F");
    let secs = t0.elapsed().as_secs_f64();
    black_box(wf);
    println!("{{\"derive_s\": {secs:e}}}");
}

/// Runs this binary with `args` `reps` times: the wall time of each whole process, and the
/// JSON line each printed.
fn fresh_processes(args: &[&str], reps: usize) -> (Stat, Vec<String>) {
    let exe = std::env::current_exe().expect("own path");
    let mut times = Vec::new();
    let mut lines = Vec::new();
    for _ in 0..reps {
        let t = Instant::now();
        let out = Command::new(&exe).args(args).output().expect("runs itself");
        times.push(t.elapsed().as_secs_f64());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        lines.push(String::from_utf8_lossy(&out.stdout).trim().to_string());
    }
    (stat(&mut times), lines)
}

/// The number after `"key": ` in a JSON line of ours.
fn field(line: &str, key: &str) -> f64 {
    let rest = line.split(&format!("\"{key}\": ")).nth(1).expect("key present");
    rest.split([',', '}']).next().and_then(|v| v.trim().parse().ok()).expect("a number")
}

fn cold(reps: usize, rows: &mut Rows, report: &mut String) {
    let _ = writeln!(report, "\n### Cold start: a fresh process, text to result ({reps} processes each)\n");
    let _ = writeln!(report, "| what | process wall median | min | inside the process (median): phases |");
    let _ = writeln!(report, "|---|---|---|---|");
    for tol in [1e-9, 1e-12] {
        let (s, lines) = fresh_processes(&["cold-dp", &format!("{tol:e}")], reps);
        let err = field(&lines[0], "err");
        let mut derive: Vec<f64> = lines.iter().map(|l| field(l, "derive_compile_s")).collect();
        let mut integrate: Vec<f64> = lines.iter().map(|l| field(l, "integrate_s")).collect();
        rows.push("double_pendulum_dop853", "lagrangian (engine)", "cold-process", tol, s, Some(err));
        let _ = writeln!(
            report,
            "| double pendulum text → DOP853 tol {tol:.0e} → state at t = 10 (error {err:.1e}) | {} | {} | text → compiled rhs {}, integration {} |",
            fmt_time(s.median),
            fmt_time(s.min),
            fmt_time(stat(&mut derive).median),
            fmt_time(stat(&mut integrate).median)
        );
    }
    for n in [2usize, 5, 10] {
        let (s, lines) = fresh_processes(&["cold-derive", &n.to_string()], reps);
        let mut inside: Vec<f64> = lines.iter().map(|l| field(l, "derive_s")).collect();
        let inside = stat(&mut inside);
        rows.push("n_link_derive_W_F", "lagrangian (engine)", "cold-process", n as f64, s, None);
        rows.push("n_link_derive_W_F", "lagrangian (engine)", "cold-first-call", n as f64, inside, None);
        let _ = writeln!(
            report,
            "| {n}-link text → W, F (tidied) | {} | {} | first derivation in the process {} (min {}) |",
            fmt_time(s.median),
            fmt_time(s.min),
            fmt_time(inside.median),
            fmt_time(inside.min)
        );
    }
}

/// Warm n-link derivations: the tidied W, F and the raw expressions.
fn derivations(budget: Duration, rows: &mut Rows, report: &mut String) {
    let _ = writeln!(report, "\n### n-link pendulum derivations, warm (same process, median and min)\n");
    let _ = writeln!(report, "| n | text → W, F tidied median | min | raw Euler–Lagrange median | min |");
    let _ = writeln!(report, "|---|---|---|---|---|");
    for n in [2usize, 5, 10] {
        let text = n_link::n_link(n);
        let (st, _) = repeat(budget, || {
            let (l, coords, positive) = &text;
            let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
            let d = Declarations::new().with_positive(positive.iter().map(String::as_str));
            System::from_lagrangian_with(l, &coords, &d).expect("valid").mass_matrix_split().expect("W, F")
        });
        let s = n_link_system(n);
        let (sr, _) = repeat(budget, || raw_el(&s));
        rows.push("n_link_derive_W_F", "lagrangian (engine)", "warm", n as f64, st, None);
        rows.push("n_link_raw_el", "lagrangian (engine)", "warm", n as f64, sr, None);
        let _ = writeln!(
            report,
            "| {n} | {} | {} | {} | {} |",
            fmt_time(st.median),
            fmt_time(st.min),
            fmt_time(sr.median),
            fmt_time(sr.min)
        );
    }
}

/// Kepler e = 0.5, Yoshida 8 with compensated summation, 512 steps per orbit: the engine's
/// separable Hamiltonian from text against the hand-written one; the relative energy error is
/// the maximum over every step.
fn kepler(orbits: usize, rows: &mut Rows, report: &mut String) {
    let per_orbit = 512usize;
    let h = 2.0 * std::f64::consts::PI / per_orbit as f64;
    let t_end = h * (orbits * per_orbit) as f64;
    let y0 = Kepler::pericentre(0.5);
    let e0 = Kepler.energy(&y0);
    let engine = System::from_hamiltonian(KEPLER, &["x", "y"]).expect("valid").compile_separable().expect("separable");
    let m = Splitting::yoshida8(h).compensated();
    let _ =
        writeln!(report, "\n### Kepler e = 0.5, {orbits} orbits, Yoshida 8 compensated, {per_orbit} steps per orbit\n");
    let _ = writeln!(
        report,
        "| right-hand side | integration alone (1 run) | max rel. energy error over every step | at the orbit's start phase only |"
    );
    let _ = writeln!(report, "|---|---|---|---|");
    fn run<S: Separable + ?Sized>(m: &Splitting, sys: &S, y0: &[f64], t_end: f64) -> (f64, Vec<f64>) {
        let t = Instant::now();
        let tr = m.integrate_with(sys, 0.0..t_end, y0, Options::new().final_only()).expect("integrates");
        (t.elapsed().as_secs_f64(), tr.last_state().to_vec())
    }
    fn energy_max<S: Separable + ?Sized>(
        m: &Splitting,
        sys: &S,
        y0: &[f64],
        t_end: f64,
        per_orbit: usize,
    ) -> (f64, f64) {
        let e0 = Kepler.energy(y0);
        let mut s = m.solver(sys, 0.0, y0, t_end).expect("valid");
        let (mut all, mut phase) = (0.0f64, 0.0f64);
        loop {
            let st = s.step().expect("no failure");
            let e = ((Kepler.energy(s.y()) - e0) / e0).abs();
            all = all.max(e);
            if s.steps() % per_orbit == 0 {
                phase = phase.max(e);
            }
            if st == Status::Finished {
                break;
            }
        }
        (all, phase)
    }
    for (name, which) in [("lagrangian (engine)", 0), ("hand-written Rust", 1)] {
        let (secs, y) = if which == 0 { run(&m, &engine, &y0, t_end) } else { run(&m, &Kepler, &y0, t_end) };
        let (all, phase) = if which == 0 {
            energy_max(&m, &engine, &y0, t_end, per_orbit)
        } else {
            energy_max(&m, &Kepler, &y0, t_end, per_orbit)
        };
        let final_rel = ((Kepler.energy(&y) - e0) / e0).abs();
        assert!(final_rel <= all, "the final state's error is part of the maximum");
        let s = Stat { median: secs, min: secs, reps: 1 };
        rows.push(&format!("kepler_yoshida8_{orbits}_orbits"), name, "warm", h, s, Some(all));
        let _ = writeln!(report, "| {name} | {} | {all:.2e} | {phase:.2e} |", fmt_time(secs));
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("cold-dp") => return cold_dp(args[1].parse().expect("a tolerance")),
        Some("cold-derive") => return cold_derive(args[1].parse().expect("a link count")),
        _ => {}
    }
    let quick = args.iter().any(|a| a == "quick");
    let long = args.iter().any(|a| a == "long");
    let json = args.iter().position(|a| a == "--json").map(|i| args[i + 1].clone());
    let budget = Duration::from_millis(if quick { 100 } else { 500 });
    let mut rows = Rows { out: Vec::new() };
    let mut report = String::new();
    double_pendulum(budget, &mut rows, &mut report);
    cold(if quick { 3 } else { 7 }, &mut rows, &mut report);
    derivations(budget, &mut rows, &mut report);
    kepler(
        if long {
            100_000
        } else if quick {
            1_000
        } else {
            10_000
        },
        &mut rows,
        &mut report,
    );
    println!("{report}");
    if let Some(path) = json {
        let mut f = std::fs::File::create(&path).expect("JSON output file");
        for r in &rows.out {
            writeln!(f, "{r}").expect("writes");
        }
    }
}
