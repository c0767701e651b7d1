//! Core engine benchmarks: parse + simplify + differentiate the 10-link planar pendulum's
//! Lagrangian, and the simplifier on `(a+b+c+d)^8 − (its expansion)`.
//!
//! Run: `cargo bench --bench core`.

use criterion::{criterion_group, criterion_main, Criterion};
use lagrangian::algebra::expand;
use lagrangian::diff::Differentiator;
use lagrangian::simplify::simplify;
use lagrangian::{parse, parse_with, Declarations, Expr, Symbol};

const LINKS: usize = 10;

/// The Lagrangian of an n-link planar pendulum, absolute angles θk from the downward vertical:
/// bob k sits at x_k = Σ_{i≤k} l_i sin θi, y_k = −Σ_{i≤k} l_i cos θi, so
/// L = Σ_k ½ m_k (ẋ_k² + ẏ_k²) + g Σ_k m_k Σ_{i≤k} l_i cos θi (PHYSICS.md: L = T − V, V = m g y).
fn pendulum_text(n: usize) -> String {
    let mut terms = Vec::new();
    for k in 1..=n {
        let vx: Vec<String> = (1..=k).map(|i| format!("l{i} θ{i}' cos(θ{i})")).collect();
        let vy: Vec<String> = (1..=k).map(|i| format!("l{i} θ{i}' sin(θ{i})")).collect();
        terms.push(format!("1/2 m{k} (({})^2 + ({})^2)", vx.join(" + "), vy.join(" + ")));
        let y: Vec<String> = (1..=k).map(|i| format!("l{i} cos(θ{i})")).collect();
        terms.push(format!("g m{k} ({})", y.join(" + ")));
    }
    terms.join(" + ")
}

fn declarations(n: usize) -> Declarations {
    let mut pos: Vec<String> = vec!["g".into()];
    for k in 1..=n {
        pos.push(format!("m{k}"));
        pos.push(format!("l{k}"));
    }
    Declarations::new().with_positive(pos)
}

/// ∂L/∂θk and ∂L/∂θk' for every link, simplified: the pieces of the Euler–Lagrange equations.
fn derivatives(l: &Expr, n: usize) -> Vec<Expr> {
    let mut d = Differentiator::new();
    let mut out = Vec::new();
    for k in 1..=n {
        let q = Symbol::new(&format!("θ{k}"));
        out.push(simplify(&d.diff(l, &q)));
        out.push(simplify(&d.diff(l, &q.prime())));
    }
    out
}

fn pendulum(c: &mut Criterion) {
    let text = pendulum_text(LINKS);
    let decls = declarations(LINKS);
    let parsed = parse_with(&text, &decls).expect("the generated Lagrangian parses");
    let simplified = simplify(&parsed);
    eprintln!(
        "10-link pendulum L: {} bytes of text, {} ops parsed, {} ops simplified",
        text.len(),
        parsed.op_count(),
        simplified.op_count()
    );
    let mut g = c.benchmark_group("pendulum10");
    g.sample_size(10);
    g.bench_function("parse", |b| b.iter(|| parse_with(&text, &decls).expect("parses")));
    g.bench_function("simplify", |b| b.iter(|| simplify(&parsed)));
    g.bench_function("diff_all_simplified", |b| b.iter(|| derivatives(&simplified, LINKS)));
    g.bench_function("parse_simplify_diff", |b| {
        b.iter(|| {
            let l = simplify(&parse_with(&text, &decls).expect("parses"));
            derivatives(&l, LINKS)
        })
    });
    g.finish();
}

fn polynomial(c: &mut Criterion) {
    let power = parse("(a+b+c+d)^8").expect("parses");
    let expanded = expand(&power).expect("165 terms is within the budget");
    let zero = power.minus(&expanded);
    assert!(simplify(&zero).is_zero());
    let mut g = c.benchmark_group("polynomial");
    g.sample_size(10);
    g.bench_function("simplify_(a+b+c+d)^8_minus_expanded", |b| b.iter(|| simplify(&zero)));
    g.bench_function("expand_(a+b+c+d)^8", |b| b.iter(|| expand(&power)));
    g.finish();
}

criterion_group!(benches, pendulum, polynomial);
criterion_main!(benches);
