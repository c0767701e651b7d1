//! Shared helpers for the mechanics tests: building systems, numeric comparison at random
//! states (declared functions such as `V(r)` replaced by concrete smooth functions, with their
//! derivatives taken exactly), and the snapshot report.
#![allow(dead_code)]

use std::collections::{BTreeMap, BTreeSet};

use lagrangian::diff::diff;
use lagrangian::eval::eval_with;
use lagrangian::expr::{Expr, Node, Symbol};
use lagrangian::mechanics::System;
use lagrangian::{parse_with, Declarations};

pub use super::n_link;

/// A small deterministic generator (xorshift64*), so failures reproduce.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

pub fn decls(positive: &[&str], functions: &[&str]) -> Declarations {
    Declarations::new().with_positive(positive.iter().copied()).with_functions(functions.iter().copied())
}

pub fn system(l: &str, coords: &[&str], positive: &[&str], functions: &[&str]) -> System {
    System::from_lagrangian_with(l, coords, &decls(positive, functions)).expect("the Lagrangian is valid")
}

pub fn expr(text: &str, positive: &[&str], functions: &[&str]) -> Expr {
    parse_with(text, &decls(positive, functions)).expect("the hand form parses")
}

/// The concrete stand-in for a declared function of `arity` arguments `ξ1, ξ2, …`: smooth,
/// non-polynomial in every argument, different per name.
fn template(name: &str, arity: usize) -> Expr {
    let k = 1 + (name.chars().next().map_or(0, |c| c as u32) % 5) as i64;
    let text = match arity {
        1 => format!("{k} ξ1^3 + 1/ξ1"),
        2 => format!("{k} ξ1^2 ξ2 + sin(ξ2)"),
        3 => format!("{k} ξ1^2 ξ2 + sin(ξ3) + ξ1 ξ3^3"),
        _ => format!("{k} ξ1 ξ2 + ξ3^2 ξ4 + cos(ξ4 ξ1)"),
    };
    lagrangian::parse(&text).expect("template parses")
}

/// Replaces every declared function (and its partial derivatives) by its concrete stand-in.
pub fn concretize(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |x| match x.node() {
        Node::Apply { name, orders, args } => {
            let mut t = template(name, args.len());
            for (i, k) in orders.iter().enumerate() {
                for _ in 0..*k {
                    t = diff(&t, &Symbol::new(&format!("ξ{}", i + 1)));
                }
            }
            let map = args.iter().enumerate().map(|(i, a)| (Symbol::new(&format!("ξ{}", i + 1)), a.clone())).collect();
            Some(t.subs(&map))
        }
        _ => None,
    })
}

/// Random values for every symbol, except `overrides`: symbols declared positive (masses,
/// lengths, `g`) in `[0.5, 1.5)`; every other symbol — coordinates, velocities, momenta,
/// parameters of either sign — in `[-1.5, 1.5)`, so a state has negative coordinates and
/// coordinates near zero, and a sign error or a lost `|x|` shows.
pub fn random_env(exprs: &[&Expr], rng: &mut Rng, overrides: &[(&str, f64)]) -> BTreeMap<String, f64> {
    let mut syms: BTreeSet<Symbol> = BTreeSet::new();
    for e in exprs {
        syms.extend(e.free_symbols());
    }
    let mut env = BTreeMap::new();
    for s in syms {
        let v = if s.is_positive() { rng.range(0.5, 1.5) } else { rng.range(-1.5, 1.5) };
        env.insert(s.to_string(), v);
    }
    for (k, v) in overrides {
        env.insert((*k).to_string(), *v);
    }
    env
}

pub fn value(e: &Expr, env: &BTreeMap<String, f64>) -> f64 {
    let c = concretize(e);
    eval_with(&c, &|s: &Symbol| env.get(&s.to_string()).copied())
        .unwrap_or_else(|err| panic!("cannot evaluate {e}: {err}"))
}

/// Asserts `a = b` at `samples` random states (relative tolerance 1e-9).
pub fn assert_same(a: &Expr, b: &Expr, what: &str, overrides: &[(&str, f64)]) {
    let mut rng = Rng::new(a.dag_size() as u64 * 31 + b.dag_size() as u64);
    for _ in 0..5 {
        let env = random_env(&[a, b], &mut rng, overrides);
        let (x, y) = (value(a, &env), value(b, &env));
        assert!(
            (x - y).abs() <= 1e-9 * (1.0 + x.abs() + y.abs()),
            "{what}: {a} = {x} but the hand form {b} = {y} at {env:?}"
        );
    }
}

/// The plain-text report snapshotted for a worked system: equations, W, F, H, conserved.
pub fn report(title: &str, s: &System) -> String {
    let mut out = format!("# {title}\nL = {}\n", s.lagrangian().expect("Lagrangian system"));
    let names: Vec<String> = s.coordinates().iter().map(|q| q.to_string()).collect();
    for (q, e) in names.iter().zip(s.euler_lagrange().expect("EL")) {
        out += &format!("E_{q} = {e}\n");
    }
    let (w, f) = s.mass_matrix_split().expect("W, F");
    for i in 0..w.len() {
        for j in i..w.len() {
            out += &format!("W[{},{}] = {}\n", names[i], names[j], w[i][j]);
        }
    }
    for (q, e) in names.iter().zip(&f) {
        out += &format!("F_{q} = {e}\n");
    }
    match s.hamiltonian() {
        Ok(h) => out += &format!("H = {h}\n"),
        Err(e) => out += &format!("H: {e}\n"),
    }
    for c in s.conserved() {
        out += &format!("conserved {} = {}    # {}\n", c.name, c.expr, c.reason);
    }
    out
}

pub use super::snapshot;
