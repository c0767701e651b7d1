//! The variational integrator of a discrete Lagrangian (see `mechanics::Discrete`): the
//! implicit map `p_k = −D₁L_d(q_k, q_{k+1})` is solved for `q_{k+1}` by Newton's method with
//! the exact Jacobian `−D₂D₁L_d` (compiled with the residual, one tape), then
//! `p_{k+1} = D₂L_d(q_k, q_{k+1})` (Marsden & West 2001, §1.5, "position-momentum form").
//! A Newton iteration that does not converge is a typed error carrying the time and state,
//! never a silently wrong step.

use std::collections::HashMap;

use crate::diff::Differentiator;
use crate::eval::eval_with;
use crate::expr::{Expr, Symbol};
use crate::mechanics::Discrete;

use super::first_order::{solve_in_place, MAX_FIRST_ORDER_DIM};
use super::tape::Tape;
use super::CompileError;

/// Newton iterations allowed per step.
pub const MAX_NEWTON: usize = 50;

/// Why a variational step failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VariationalError {
    /// Newton's method for `p_k = −D₁L_d(q_k, q_{k+1})` did not converge.
    #[error("the discrete Legendre map did not converge at t = {t} after {iterations} Newton steps (residual {residual:e}); state q = {q:?}, p = {p:?} (try a smaller step)")]
    Newton { t: f64, iterations: usize, residual: f64, q: Vec<f64>, p: Vec<f64> },
    /// `∂D₁L_d/∂q_{k+1}` is singular at an iterate.
    #[error("the Jacobian of the discrete Legendre map is singular at t = {t}; state q = {q:?}")]
    Singular { t: f64, q: Vec<f64> },
    /// Ctrl-C (the process-wide [`crate::cancel`] token) stopped the iteration at `t`.
    #[error("interrupted at t = {t}; state q = {q:?}")]
    Interrupted { t: f64, q: Vec<f64> },
}

/// One point of a discrete trajectory.
#[derive(Clone, Debug, PartialEq)]
pub struct DiscretePoint {
    /// `t_k`.
    pub t: f64,
    /// `q_k`.
    pub q: Vec<f64>,
    /// `p_k` (the discrete Legendre momentum).
    pub p: Vec<f64>,
}

/// The compiled map `(q_k, p_k) → (q_{k+1}, p_{k+1})`.
#[derive(Debug)]
pub struct VariationalMap {
    n: usize,
    h: f64,
    /// Inputs `q_k, q_{k+1}, t`; outputs `D₁L_d` (n) then `∂D₁L_d/∂q_{k+1}` (n × n, row-major).
    residual: Tape,
    /// Inputs `q_k, q_{k+1}, t`; outputs `D₂L_d` (n).
    momentum: Tape,
}

impl VariationalMap {
    /// Compiles the map of `d`, with `params` bound (including the step when `d.h` is a
    /// symbol).
    pub fn new(d: &Discrete, params: &[(&str, f64)]) -> Result<VariationalMap, CompileError> {
        let n = d.coords.len();
        if n > MAX_FIRST_ORDER_DIM {
            return Err(CompileError::Shape {
                what: "coordinates of a variational map (at most 16)",
                expected: 16,
                got: n,
            });
        }
        let h = eval_with(&d.h, &|s| params.iter().find(|(k, _)| *k == s.to_string()).map(|(_, v)| *v))
            .map_err(|_| CompileError::Unbound { name: d.h.to_string() })?;
        if !h.is_finite() || h <= 0.0 {
            return Err(CompileError::NonFiniteParam { name: d.h.to_string(), value: h });
        }
        // The unknown is the increment Δ = q_{k+1} − q_k, not q_{k+1}: the difference
        // quotients (q_{k+1} − q_k)/h in L_d then come out as Δ/h without cancellation, so
        // the momenta are not rounded to ε |q|/h at each step (which, accumulated, would
        // break the exact conservation of the discrete Noether momenta).
        let incr: Vec<Symbol> = d.coords.iter().map(|q| Symbol::new(&format!("{}_step", q.name()))).collect();
        let shift: HashMap<Symbol, Expr> =
            d.q1.iter()
                .zip(&d.q0)
                .zip(&incr)
                .map(|((b, a), s)| (b.clone(), Expr::sym(a.clone()).plus(&Expr::sym(s.clone()))))
                .collect();
        let d1: Vec<Expr> = d.d1.iter().map(|e| e.subs(&shift)).collect();
        let d2: Vec<Expr> = d.d2.iter().map(|e| e.subs(&shift)).collect();
        let mut diff = Differentiator::new();
        let mut outs: Vec<Expr> = d1.clone();
        for e in &d1 {
            for s in &incr {
                outs.push(diff.diff(e, s));
            }
        }
        let names: Vec<String> = d.q0.iter().chain(&incr).map(|s| s.to_string()).chain(["t".to_string()]).collect();
        let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
        let residual = Tape::compile(&outs, &inputs, params)?;
        let momentum = Tape::compile(&d2, &inputs, params)?;
        Ok(VariationalMap { n, h, residual, momentum })
    }

    /// The step `h`.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// One step from `(t, q, p)`: `dq` holds the guess for the increment `q_{k+1} − q_k` on
    /// entry and the increment on return, `p1` receives `p_{k+1}`; returns the Newton
    /// iterations used.
    pub fn step(
        &self,
        t: f64,
        q: &[f64],
        p: &[f64],
        dq: &mut [f64],
        p1: &mut [f64],
    ) -> Result<usize, VariationalError> {
        const M: usize = MAX_FIRST_ORDER_DIM;
        let n = self.n;
        let mut x = [0.0f64; 2 * M];
        let mut out = [0.0f64; M + M * M];
        x[..n].copy_from_slice(&q[..n]);
        let mut residual = f64::INFINITY;
        for it in 1..=MAX_NEWTON {
            x[n..2 * n].copy_from_slice(&dq[..n]);
            self.residual.eval_split(&x[..2 * n], t, &mut out[..n + n * n]);
            let (r, jac) = out.split_at_mut(n);
            for i in 0..n {
                r[i] = -(p[i] + r[i]);
            }
            let new_residual = r[..n].iter().fold(0.0f64, |s, v| s.max(v.abs()));
            if !new_residual.is_finite() {
                break;
            }
            residual = new_residual;
            solve_in_place(&mut jac[..n * n], &mut r[..n], n)
                .map_err(|_| VariationalError::Singular { t, q: q[..n].to_vec() })?;
            let mut dmax = 0.0f64;
            let mut scale = 0.0f64;
            for i in 0..n {
                dq[i] += r[i];
                dmax = dmax.max(r[i].abs());
                scale = scale.max(dq[i].abs());
            }
            if !dmax.is_finite() {
                break;
            }
            // Newton converges quadratically: after a correction of 1e-10 of the increment
            // the iterate is correct to about its square, far below rounding.
            if dmax <= 1e-10 * scale || dmax <= 1e-300 {
                x[n..2 * n].copy_from_slice(&dq[..n]);
                self.momentum.eval_split(&x[..2 * n], t, &mut p1[..n]);
                return Ok(it);
            }
        }
        Err(VariationalError::Newton { t, iterations: MAX_NEWTON, residual, q: q[..n].to_vec(), p: p[..n].to_vec() })
    }

    /// `steps` steps from `(t0, q0, p0)`, keeping every `every`-th point (and the first and
    /// last).
    pub fn integrate(
        &self,
        t0: f64,
        q0: &[f64],
        p0: &[f64],
        steps: usize,
        every: usize,
    ) -> Result<Vec<DiscretePoint>, VariationalError> {
        let n = self.n;
        let every = every.max(1);
        let (mut q, mut p) = (q0[..n].to_vec(), p0[..n].to_vec());
        // The first guess for the increment is zero, later ones the previous increment.
        let (mut dq, mut p1) = (vec![0.0; n], vec![0.0; n]);
        let mut out = vec![DiscretePoint { t: t0, q: q.clone(), p: p.clone() }];
        for k in 0..steps {
            let t = t0 + k as f64 * self.h;
            if crate::cancel::interrupted() {
                return Err(VariationalError::Interrupted { t, q });
            }
            self.step(t, &q, &p, &mut dq, &mut p1)?;
            for i in 0..n {
                q[i] += dq[i];
            }
            p.copy_from_slice(&p1);
            if (k + 1) % every == 0 || k + 1 == steps {
                out.push(DiscretePoint { t: t0 + (k + 1) as f64 * self.h, q: q.clone(), p: p.clone() });
            }
        }
        Ok(out)
    }
}
