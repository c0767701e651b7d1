//! Byte-identical output under CPU load. The simplifier's default budget is
//! counts only, so the same input must print the same bytes whether the machine is idle or
//! busy. The inputs are the ones behind the n-link and canonical snapshots: the raw
//! Euler–Lagrange expressions and the `W`, `F`, `H` of the n-link pendulum, and the
//! generating-function transforms and Runge–Lenz brackets of the canonical tests. They are
//! derived once on a quiet main thread, then again on worker threads while other threads spin,
//! and every printed line must match. A wall-clock limit anywhere in the default path (the old
//! 2 s egg limit, or any shorter one) shows up here as a differing line or as a result marked
//! budget-limited.

use crate::support::mechanics as mechanics_support;

use std::collections::BTreeSet;
use std::hint::black_box;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;

use lagrangian::canonical::{poisson, Generator, GeneratorKind, PhaseSpace};
use lagrangian::diff::Differentiator;
use lagrangian::simplify::{simplify_with, Budget};
use lagrangian::{parse_with, Declarations, Expr};
use mechanics_support::system;

/// Simplifies `e` with the default budget and asserts no clock decided it.
fn simplified(e: &Expr, what: &str) -> String {
    let out = simplify_with(e, &Budget::default());
    assert!(!out.budget_limited(), "{what}: the default budget hit a time limit ({})", out.stop);
    out.expr.to_string()
}

/// The n-link lines: simplified raw Euler–Lagrange expressions, then `W`, `F` and `H`.
fn n_link_lines(n: usize, out: &mut Vec<String>) {
    let (l, coords, positive) = mechanics_support::n_link::n_link(n);
    let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
    let positive: Vec<&str> = positive.iter().map(String::as_str).collect();
    let s = system(&l, &coords, &positive, &[]);
    let lag = s.lagrangian().expect("a Lagrangian");
    let names: BTreeSet<String> = coords.iter().map(|c| c.to_string()).collect();
    let mut d = Differentiator::new();
    for (q, v) in s.coordinates().iter().zip(s.velocities()) {
        let p = d.diff(lag, v);
        let raw = d.dt(&p, &names).minus(&d.diff(lag, q));
        out.push(format!("{n}-link E_{q} = {}", simplified(&raw, &format!("{n}-link E_{q}"))));
    }
    let (w, f) = s.mass_matrix_split().expect("W, F");
    out.push(format!("{n}-link W = {w:?}"));
    out.push(format!("{n}-link F = {f:?}"));
    out.push(format!("{n}-link H = {}", s.hamiltonian().expect("H")));
}

/// The canonical lines: the transforms and brackets of `tests/it/canonical/transform.rs` and
/// `tests/it/canonical/poisson.rs`, and their inputs simplified directly.
fn canonical_lines(out: &mut Vec<String>) {
    let decls = Declarations::new().with_functions(["V", "ω"]).with_positive(["m", "w", "k"]);
    let p = |s: &str| parse_with(s, &decls).expect("test input parses");
    let one = |q: &str| PhaseSpace::new([q]).expect("valid");
    let new = |q: &[&str], pm: &[&str]| PhaseSpace::with_momenta(q, pm).expect("valid");
    let cases = [
        (GeneratorKind::F1, "1/2 m w q^2 cot(Q)", one("q"), new(&["Q"], &["P"]), "p_q^2/(2 m) + 1/2 m w^2 q^2"),
        (GeneratorKind::F1, "1/2 m ω(t) q^2 cot(Q)", one("q"), new(&["Q"], &["P"]), "p_q^2/(2 m) + 1/2 m ω(t)^2 q^2"),
        (
            GeneratorKind::F2,
            "P_X r cos(φ) + P_Y r sin(φ)",
            PhaseSpace::new(["r", "φ"]).expect("valid"),
            new(&["X", "Y"], &["P_X", "P_Y"]),
            "p_r^2/(2 m) + p_φ^2/(2 m r^2)",
        ),
    ];
    for (kind, f, old, newps, h) in cases {
        let t =
            Generator::new(kind, p(f), old, newps).expect("valid generator").transform(Some(&p(h))).expect("transform");
        out.push(format!("{f}: relations {:?}", t.relations));
        out.push(format!("{f}: inverse {:?}", t.inverse));
        out.push(format!("{f}: forward {:?}", t.forward));
        out.push(format!("{f}: K {:?}", t.hamiltonian));
        out.push(format!("{f}: simplified {}", simplified(&p(f), f)));
        out.push(format!("{h}: simplified {}", simplified(&p(h), h)));
    }
    let ps = PhaseSpace::new(["x", "y", "z"]).expect("valid");
    let h = p("(p_x^2 + p_y^2 + p_z^2)/(2 m) - k/sqrt(x^2 + y^2 + z^2)");
    let ax = p("p_y (x p_y - y p_x) - p_z (z p_x - x p_z) - m k x/sqrt(x^2 + y^2 + z^2)");
    out.push(format!("{{A_x, H}} = {}", poisson(&ax, &h, &ps)));
    out.push(format!("A_x = {}", simplified(&ax, "A_x")));
}

fn all_lines() -> Vec<String> {
    let mut out = Vec::new();
    for n in 2..=4 {
        n_link_lines(n, &mut out);
    }
    canonical_lines(&mut out);
    out
}

#[test]
fn simplification_is_byte_identical_under_cpu_load() {
    let quiet = all_lines();
    let stop = Arc::new(AtomicBool::new(false));
    // More spinning threads than cores, so the workers are preempted often.
    let spinners: Vec<_> = (0..4)
        .map(|_| {
            let stop = Arc::clone(&stop);
            thread::spawn(move || {
                let mut x = 1.0f64;
                while !stop.load(Ordering::Relaxed) {
                    for _ in 0..10_000 {
                        x = black_box(x * 1.000_000_1 + 1e-9);
                    }
                }
                x
            })
        })
        .collect();
    let workers: Vec<_> = (0..2).map(|_| thread::spawn(all_lines)).collect();
    let loaded: Vec<Vec<String>> = workers.into_iter().map(|w| w.join().expect("worker")).collect();
    stop.store(true, Ordering::Relaxed);
    for s in spinners {
        s.join().expect("spinner");
    }
    for (k, run) in loaded.iter().enumerate() {
        assert_eq!(run.len(), quiet.len());
        for (a, b) in quiet.iter().zip(run) {
            assert_eq!(a, b, "worker {k}: output under load differs from the quiet run");
        }
    }
}
