//! The variational integrator of a discrete Lagrangian (see `mechanics::Discrete`): the
//! implicit map `p_k = −D₁L_d(q_k, q_{k+1})` is solved for `q_{k+1}` by Newton's method with
//! the exact Jacobian `−D₂D₁L_d` (compiled with the residual, one tape), then
//! `p_{k+1} = D₂L_d(q_k, q_{k+1})` (Marsden & West 2001, §1.5, "position-momentum form").
//! A Newton iteration that does not converge is a typed error carrying the time and state,
//! never a silently wrong step.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::diff::Differentiator;
use crate::eval::eval_with;
use crate::expr::{Expr, Symbol};
use crate::mechanics::Discrete;

use crate::integrate::{FailureReason, Method, MethodInfo, StepFailure};

use super::error::CompileError;
use super::first_order::MAX_FIRST_ORDER_DIM;
use super::tape::Tape;
use crate::linalg::solve_in_place;

/// The name of the step among the compiled inputs.
const STEP_INPUT: &str = "h__step";

/// Newton iterations allowed per step.
pub const MAX_NEWTON: usize = 50;

/// Why a variational step failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VariationalError {
    /// Newton's method for `p_k = −D₁L_d(q_k, q_{k+1})` did not converge.
    #[error("the discrete Legendre map did not converge at t = {t} after {iterations} Newton steps (residual {residual:e}); state q = {q:?}, p = {p:?} (try a smaller step)")]
    Newton { t: f64, iterations: usize, residual: f64, q: Vec<f64>, p: Vec<f64> },
    /// A map compiled with a numeric step was asked for another step.
    #[error("this variational map was derived with the numeric step {h} and cannot take a step of {asked}; discretize with a symbolic step")]
    FixedStep { h: f64, asked: f64 },
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
    /// Inner control points of a Galerkin rule (0 for midpoint and trapezoid).
    inner: usize,
    h: f64,
    /// The step is an input of the tapes (a symbolic `h` in `L_d`).
    variable_step: bool,
    /// Inputs `q_k, Δ, Δ_m, h, t` (`Δ = q_{k+1} − q_k`, `Δ_m = Q − q_k`); outputs `D₁L_d` (n)
    /// and `∂L̃/∂Q` (inner), then their Jacobian in `(Δ, Δ_m)` (row-major).
    residual: Tape,
    /// Inputs as `residual`; outputs `D₂L_d` (n).
    momentum: Tape,
    /// Evaluations of `residual` so far (one per Newton iteration): the work measure of a
    /// work-precision diagram.
    evaluations: AtomicUsize,
}

impl VariationalMap {
    /// Compiles the map of `d`, with `params` bound (including the step when `d.h` is a
    /// symbol). The step stays an input of the compiled code, so [`VariationalMap::step_by`]
    /// can take a shorter last step or run backwards.
    pub fn new(d: &Discrete, params: &[(&str, f64)]) -> Result<VariationalMap, CompileError> {
        let n = d.coords.len();
        let inner = d.inner.len();
        if n + inner > MAX_FIRST_ORDER_DIM {
            return Err(CompileError::Shape {
                what: "unknowns of a variational map (coordinates and inner points, at most 16)",
                expected: 16,
                got: n + inner,
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
        // break the exact conservation of the discrete Noether momenta). Inner points
        // likewise as Q − q_k.
        let incr: Vec<Symbol> = d.coords.iter().map(|q| Symbol::new(&format!("{}_step", q.name()))).collect();
        let mid_incr: Vec<Symbol> =
            d.coords.iter().take(inner).map(|q| Symbol::new(&format!("{}_mstep", q.name()))).collect();
        let mut shift: HashMap<Symbol, Expr> = HashMap::new();
        for ((b, a), s) in d.q1.iter().zip(&d.q0).zip(&incr) {
            shift.insert(b.clone(), Expr::sym(a.clone()).plus(&Expr::sym(s.clone())));
        }
        for ((m, a), s) in d.inner.iter().zip(&d.q0).zip(&mid_incr) {
            shift.insert(m.clone(), Expr::sym(a.clone()).plus(&Expr::sym(s.clone())));
        }
        // A symbolic step becomes an input of the compiled code (under a name no `L` uses);
        // a numeric one is fixed (`step_by` then takes that step only).
        let step_input = d.h.as_sym().cloned();
        if let Some(s) = &step_input {
            shift.insert(s.clone(), Expr::var(STEP_INPUT));
        }
        let rename = |e: &Expr| e.subs(&shift);
        let d1: Vec<Expr> = d.d1.iter().map(rename).collect();
        let dm: Vec<Expr> = d.dm.iter().map(rename).collect();
        let d2: Vec<Expr> = d.d2.iter().map(rename).collect();
        let unknowns: Vec<Symbol> = incr.iter().chain(&mid_incr).cloned().collect();
        let mut diff = Differentiator::new();
        let eqs: Vec<Expr> = d1.iter().chain(&dm).cloned().collect();
        let mut outs: Vec<Expr> = eqs.clone();
        for e in &eqs {
            for s in &unknowns {
                outs.push(diff.diff(e, s));
            }
        }
        let names: Vec<String> =
            d.q0.iter()
                .chain(&unknowns)
                .map(|s| s.to_string())
                .chain([STEP_INPUT.to_string(), "t".to_string()])
                .collect();
        let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
        let params: Vec<(&str, f64)> = match &step_input {
            Some(s) => params.iter().filter(|(k, _)| *k != s.to_string()).copied().collect(),
            None => params.to_vec(),
        };
        let residual = Tape::compile(&outs, &inputs, &params)?;
        let momentum = Tape::compile(&d2, &inputs, &params)?;
        Ok(VariationalMap {
            n,
            inner,
            h,
            variable_step: step_input.is_some(),
            residual,
            momentum,
            evaluations: AtomicUsize::new(0),
        })
    }

    /// The step `h`.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Newton iterations (evaluations of the residual and its Jacobian) since compilation.
    pub fn evaluations(&self) -> usize {
        self.evaluations.load(Ordering::Relaxed)
    }

    /// The number of Newton unknowns per step (coordinates and inner points).
    pub fn unknowns(&self) -> usize {
        self.n + self.inner
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
        self.step_by(self.h, t, q, p, dq, p1)
    }

    /// [`VariationalMap::step`] with the step `h` (signed: negative runs backwards).
    pub fn step_by(
        &self,
        h: f64,
        t: f64,
        q: &[f64],
        p: &[f64],
        dq: &mut [f64],
        p1: &mut [f64],
    ) -> Result<usize, VariationalError> {
        const M: usize = MAX_FIRST_ORDER_DIM;
        let (n, u) = (self.n, self.n + self.inner);
        if !self.variable_step && h != self.h {
            return Err(VariationalError::FixedStep { h: self.h, asked: h });
        }
        // Inputs q_k, then the unknowns, then h.
        let mut x = [0.0f64; 2 * M + 1];
        let mut out = [0.0f64; M + M * M];
        x[..n].copy_from_slice(&q[..n]);
        x[n..2 * n].copy_from_slice(&dq[..n]);
        // The inner points start at the midpoint of the guessed step.
        for i in 0..self.inner {
            x[2 * n + i] = 0.5 * dq[i];
        }
        x[n + u] = h;
        let mut residual = f64::INFINITY;
        for it in 1..=MAX_NEWTON {
            if crate::cancel::interrupted() {
                return Err(VariationalError::Interrupted { t, q: q[..n].to_vec() });
            }
            self.residual.eval_split(&x[..n + u + 1], t, &mut out[..u + u * u]);
            self.evaluations.fetch_add(1, Ordering::Relaxed);
            let (r, jac) = out.split_at_mut(u);
            for i in 0..u {
                r[i] = if i < n { -(p[i] + r[i]) } else { -r[i] };
            }
            let new_residual = r[..u].iter().fold(0.0f64, |s, v| s.max(v.abs()));
            if !new_residual.is_finite() {
                break;
            }
            residual = new_residual;
            solve_in_place(&mut jac[..u * u], &mut r[..u], u)
                .map_err(|_| VariationalError::Singular { t, q: q[..n].to_vec() })?;
            let mut dmax = 0.0f64;
            let mut scale = 0.0f64;
            for i in 0..u {
                x[n + i] += r[i];
                dmax = dmax.max(r[i].abs());
                scale = scale.max(x[n + i].abs());
            }
            if !dmax.is_finite() {
                break;
            }
            // Newton converges quadratically: after a correction of 1e-10 of the increment
            // the iterate is correct to about its square, far below rounding.
            if dmax <= 1e-10 * scale || dmax <= 1e-300 {
                dq[..n].copy_from_slice(&x[n..2 * n]);
                self.momentum.eval_split(&x[..n + u + 1], t, &mut p1[..n]);
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

/// The variational map as a fixed-step integrator of the state `y = (q, p)` (`p` the
/// discrete Legendre momentum), so that it runs under the common [`crate::integrate::Solver`]
/// (output thinning, step budget) like every other method; the scene's `variational`
/// method is this. The map has no continuous rate, so it offers no interpolation inside a
/// step: events are refused before a run (by the scene), and [`Method::rate`] is an error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VariationalStepper {
    /// The step.
    pub h: f64,
    /// The order of the rule the map was derived with (for [`MethodInfo`]).
    pub order: u32,
}

/// The increment guess and momentum buffer carried from step to step.
#[derive(Clone, Debug)]
pub struct StepperWork {
    dq: Vec<f64>,
    p1: Vec<f64>,
    last_h: f64,
}

impl Method<VariationalMap> for VariationalStepper {
    type Work = StepperWork;
    fn info(&self) -> MethodInfo {
        MethodInfo { name: "variational", order: self.order, symplectic: true, symmetric: true, adaptive: false }
    }
    fn dim(&self, sys: &VariationalMap) -> usize {
        2 * sys.n
    }
    fn work(&self, sys: &VariationalMap) -> StepperWork {
        StepperWork { dq: vec![0.0; sys.n], p1: vec![0.0; sys.n], last_h: 0.0 }
    }
    fn fixed_step(&self) -> Option<f64> {
        Some(self.h)
    }
    fn step(
        &self,
        sys: &VariationalMap,
        work: &mut StepperWork,
        t: f64,
        y: &mut [f64],
        h: f64,
    ) -> Result<f64, StepFailure> {
        let n = sys.n;
        // A shorter (last) step starts from the scaled previous increment.
        if work.dq.iter().any(|v| *v != 0.0) && work.last_h != 0.0 && work.last_h != h {
            let r = h / work.last_h;
            work.dq.iter_mut().for_each(|v| *v *= r);
        }
        work.last_h = h;
        let (q, p) = y.split_at_mut(n);
        sys.step_by(h, t, q, p, &mut work.dq, &mut work.p1).map_err(|e| match e {
            VariationalError::Newton { iterations, residual, .. } => {
                StepFailure(FailureReason::ImplicitSolve { iterations, last_correction: residual, newton: true })
            }
            other => StepFailure(FailureReason::InvalidInput(other.to_string())),
        })?;
        for (qi, di) in q.iter_mut().zip(&work.dq) {
            *qi += di;
        }
        p.copy_from_slice(&work.p1);
        Ok(h)
    }
    fn rate(&self, _sys: &VariationalMap, t: f64, _y: &[f64], _dy: &mut [f64]) -> Result<(), StepFailure> {
        Err(StepFailure(FailureReason::InvalidInput(format!(
            "the variational map has no rate at t = {t}: it cannot interpolate inside a step (no events)"
        ))))
    }
    fn reset(&self, work: &mut StepperWork) {
        work.dq.iter_mut().for_each(|v| *v = 0.0);
        work.last_h = 0.0;
    }
}
