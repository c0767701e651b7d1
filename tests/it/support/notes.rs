//! Shared helpers of the `notes_*` tests: running the binary, and an independent numeric
//! route to the Euler–Lagrange expressions (finite differences of L along a path).

#![allow(dead_code)]

use std::collections::HashMap;

use lagrangian::eval::eval;
use lagrangian::Expr;

// Running the binary and snapshots are the scene tests' helpers (`tests/it/support`).
use crate::support;
pub use support::{run, snapshot};

/// A smooth test path `q_i(s) = c0 + c1 s + c2 s² + c3 sin(s)` with its first two derivatives.
pub struct Path {
    pub c: Vec<[f64; 4]>,
}

impl Path {
    pub fn q(&self, s: f64) -> Vec<f64> {
        self.c.iter().map(|c| c[0] + c[1] * s + c[2] * s * s + c[3] * s.sin()).collect()
    }
    pub fn v(&self, s: f64) -> Vec<f64> {
        self.c.iter().map(|c| c[1] + 2.0 * c[2] * s + c[3] * s.cos()).collect()
    }
    pub fn a(&self, s: f64) -> Vec<f64> {
        self.c.iter().map(|c| 2.0 * c[2] - c[3] * s.sin()).collect()
    }
}

fn env_at(coords: &[&str], q: &[f64], v: &[f64], a: &[f64], t: f64, params: &[(&str, f64)]) -> HashMap<String, f64> {
    let mut env: HashMap<String, f64> = params.iter().map(|(k, x)| (k.to_string(), *x)).collect();
    for (i, c) in coords.iter().enumerate() {
        env.insert(c.to_string(), q[i]);
        env.insert(format!("{c}'"), v[i]);
        env.insert(format!("{c}''"), a[i]);
    }
    env.insert("t".into(), t);
    env
}

/// `E_i = d/dt ∂L/∂q'_i − ∂L/∂q_i` at time `t` along `path`, by central differences of the
/// numeric values of `L` only (no symbolic derivative involved).
pub fn fd_euler_lagrange(l: &Expr, coords: &[&str], path: &Path, t: f64, params: &[(&str, f64)]) -> Vec<f64> {
    let n = coords.len();
    let lval = |q: &[f64], v: &[f64], s: f64| eval(l, &env_at(coords, q, v, &vec![0.0; n], s, params)).unwrap();
    let dl_dv = |i: usize, s: f64| {
        let (q, mut v) = (path.q(s), path.v(s));
        let h = 1e-5 * (1.0 + v[i].abs());
        v[i] += h;
        let up = lval(&q, &v, s);
        v[i] -= 2.0 * h;
        (up - lval(&q, &v, s)) / (2.0 * h)
    };
    (0..n)
        .map(|i| {
            let ht = 1e-4;
            let ddt = (dl_dv(i, t + ht) - dl_dv(i, t - ht)) / (2.0 * ht);
            let (mut q, v) = (path.q(t), path.v(t));
            let h = 1e-5 * (1.0 + q[i].abs());
            q[i] += h;
            let up = lval(&q, &v, t);
            q[i] -= 2.0 * h;
            ddt - (up - lval(&q, &v, t)) / (2.0 * h)
        })
        .collect()
}

/// The value of an expression (of `q, q', q'', t` and parameters) along `path` at `t`.
pub fn value_on_path(e: &Expr, coords: &[&str], path: &Path, t: f64, params: &[(&str, f64)]) -> f64 {
    eval(e, &env_at(coords, &path.q(t), &path.v(t), &path.a(t), t, params)).unwrap()
}

/// Deterministic pseudo-random numbers in `[lo, hi)` (xorshift).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
    pub fn path(&mut self, n: usize) -> Path {
        Path { c: (0..n).map(|_| [0; 4].map(|_| self.uniform(-1.0, 1.0))).collect() }
    }
}
