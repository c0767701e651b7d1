//! Derivation benchmarks for the planar n-link pendulum: `W` and `F` (tidied) for
//! n = 1, 2, 5, 6, 10, 20, 30, `H` for n = 1, 2, 3, and, measured in the same run, the raw
//! unsimplified Euler–Lagrange expressions (plain memoised differentiation, no tidying) as the
//! baseline comparable to SymEngine's and heyoka's raw figures.
//!
//! The Lagrangian is written the way a user (or SymPy's `LagrangesMethod`) writes it: Cartesian
//! bob velocities in terms of the angles, `½ Σ_k m_k |r_k'|² − Σ_k m_k g y_k` with
//! `r_k = Σ_{i≤k} l_i (sin θ_i, −cos θ_i)`. Operation counts (`Expr::op_count`, the printed
//! tree, W's upper triangle plus F) are printed to stderr.
//!
//! The `cancel` group times `algebra::cancel` (the simplifier's and `canonical::compact`'s
//! rational cancellation) on the shapes it meets: rational and monomial content, a sum factor
//! of the denominator that divides the numerator, a multivariate factor, and the univariate
//! gcd of two expanded polynomials.
//!
//! Run: `cargo bench --bench mechanics`; only the cancellation rows: `-- cancel`

use std::collections::BTreeSet;
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use lagrangian::algebra::{cancel, expand};
use lagrangian::diff::Differentiator;
use lagrangian::expr::Expr;
use lagrangian::mechanics::System;
use lagrangian::{parse_with, Declarations};

#[path = "../tests/it/support/n_link.rs"]
mod n_link;
use n_link::n_link;

fn build(n: usize) -> System {
    let (l, coords, positive) = n_link(n);
    let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
    let d = Declarations::new().with_positive(positive.iter().map(String::as_str));
    System::from_lagrangian_with(&l, &coords, &d).expect("valid Lagrangian")
}

fn ops(w: &[Vec<Expr>], f: &[Expr]) -> usize {
    let w_ops: usize = w.iter().enumerate().map(|(i, r)| r[i..].iter().map(Expr::op_count).sum::<usize>()).sum();
    w_ops + f.iter().map(Expr::op_count).sum::<usize>()
}

/// The raw Euler–Lagrange expressions d/dt ∂L/∂q' − ∂L/∂q, untidied.
fn raw_el(s: &System) -> Vec<Expr> {
    let l = s.lagrangian().expect("Lagrangian");
    let names: BTreeSet<String> = s.coordinates().iter().map(|q| q.name().to_string()).collect();
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

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("n_link_W_F");
    g.sample_size(10);
    for n in [1usize, 2, 5, 6, 10, 20, 30] {
        let s = build(n);
        let (w, f) = s.mass_matrix_split().expect("W, F");
        let raw: usize = raw_el(&s).iter().map(Expr::op_count).sum();
        eprintln!("n = {n}: tidied W+F {} ops; raw Euler–Lagrange expressions {raw} ops", ops(&w, &f));
        g.bench_with_input(BenchmarkId::new("tidied", n), &s, |b, s| b.iter(|| black_box(s.mass_matrix_split())));
        g.bench_with_input(BenchmarkId::new("raw_el", n), &s, |b, s| b.iter(|| black_box(raw_el(s))));
    }
    g.finish();
    let mut g = c.benchmark_group("n_link_H");
    g.sample_size(10);
    for n in [1usize, 2, 3] {
        let s = build(n);
        let h = s.hamiltonian().expect("H");
        eprintln!("n = {n}: H {} ops", h.op_count());
        g.bench_with_input(BenchmarkId::new("legendre", n), &s, |b, s| b.iter(|| black_box(s.hamiltonian())));
    }
    g.finish();
}

/// `algebra::cancel` on the shapes it meets (see the module docs).
fn cancel_cases(c: &mut Criterion) {
    let d = Declarations::new().with_positive(["m1", "m2", "l1", "l2"]);
    let p = |s: &str| parse_with(s, &d).expect("parses");
    // Expanded numerator and denominator: only the univariate gcd finds (x + 1)^3.
    let n = expand(&p("(x + 1)^10 (x - 2)^5")).expect("expands");
    let den = expand(&p("(x + 1)^3 (x + 3)^4")).expect("expands");
    let cases = [
        ("content", p("(2 a x + 4 a y)/(6 a^2)")),
        ("sum_factor", p("(x^2 - 1)/(x - 1)")),
        ("multivariate_factor", p("(a^2 x - b^2 x)/((a + b) (a + y))")),
        (
            "double_pendulum_factor",
            p("(l2 p1 - l1 p2 cos(a - b)) (m1 + m2 sin(a - b)^2) / (l1^2 l2 (m1 + m2 sin(a - b)^2)^2)"),
        ),
        ("gcd_deg2", p("(x^2 - 1)/(x^2 + 2x + 1)")),
        ("gcd_deg15", n.over(&den)),
    ];
    let mut g = c.benchmark_group("cancel");
    for (name, e) in &cases {
        eprintln!("cancel {name}: {e} -> {}", cancel(e));
        g.bench_with_input(BenchmarkId::from_parameter(name), e, |b, e| b.iter(|| black_box(cancel(e))));
    }
    g.finish();
}

criterion_group!(benches, bench, cancel_cases);
criterion_main!(benches);
