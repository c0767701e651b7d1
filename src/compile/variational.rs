//! Variational equations: the state `x` of `x' = f(x, t)` together with `m` tangent vectors
//! `w_j' = J(x, t) w_j` (`J = ∂f/∂x`, differentiated exactly and compiled into the same tape
//! as `f`, so what they share is computed once), and optionally the MEGNO accumulator
//! `y' = t · (w₀ · J w₀) / (w₀ · w₀)` (Cincotta & Simó 2000, eq. 2; its time average is the
//! MEGNO of `chaos`).
//!
//! With `m = dim` and `w_j(0) = e_j` the tangent vectors are the columns of the state
//! transition matrix `Φ(t)`. The result is one first-order system: its [`TaylorOde`] is
//! integrated by [`crate::integrate::Taylor`], and it is also an [`Rhs`] for DOP853 and the
//! Gauss methods.
//!
//! State layout: `x` (`n`), then `w_0 … w_{m−1}` (`n` each), then `y` when MEGNO is on.

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::integrate::{Rhs, RhsError as StepError, StepFailure, TaylorBatchSystem, TaylorSystem};
use crate::lanes::Lanes;
use crate::mechanics::System;

use super::error::CompileError;
use super::{Tape, TaylorOde};

/// `x' = f(x, t)` with `m` tangent vectors and an optional MEGNO accumulator.
#[derive(Clone, Debug)]
pub struct Variational {
    n: usize,
    m: usize,
    megno: bool,
    /// Whether `f` is Hamilton's vector field in `(q, p)`, so that the flow is symplectic and
    /// `ΦᵀJΦ = J` is a check of `Φ`.
    hamiltonian: bool,
    tape: Tape,
    taylor: TaylorOde,
}

/// The symbol named `name` in `exprs` (so a positive `m` is found by its name), else a plain one.
fn symbol_named(exprs: &[Expr], name: &str) -> Symbol {
    for e in exprs {
        if let Some(s) = e.free_symbols().into_iter().find(|s| s.to_string() == name) {
            return s;
        }
    }
    Symbol::new(name)
}

impl Variational {
    /// The variational system of `x' = f(x, t)`: `state` names `x` (plain spelling), the time
    /// is `t`, `params` are bound; `tangents` vectors, and MEGNO's accumulator when `megno`
    /// (which follows tangent vector 0).
    pub fn new(
        f: &[Expr],
        state: &[&str],
        params: &[(&str, f64)],
        tangents: usize,
        megno: bool,
    ) -> Result<Variational, CompileError> {
        let n = state.len();
        if f.len() != n {
            return Err(CompileError::Shape { what: "right-hand sides", expected: n, got: f.len() });
        }
        if tangents == 0 && megno {
            return Err(CompileError::Shape { what: "tangent vectors for MEGNO", expected: 1, got: 0 });
        }
        let xs: Vec<Symbol> = state.iter().map(|s| symbol_named(f, s)).collect();
        let names: Vec<Vec<String>> = (0..tangents).map(|j| (0..n).map(|i| format!("δ{j}_{i}")).collect()).collect();
        let mut d = Differentiator::new();
        let jac: Vec<Vec<Expr>> = f.iter().map(|fi| xs.iter().map(|x| d.diff(fi, x)).collect()).collect();
        let mut outputs: Vec<Expr> = f.to_vec();
        let mut jw0 = Vec::new();
        for row_names in &names {
            let w: Vec<Expr> = row_names.iter().map(|s| Expr::var(s)).collect();
            for row in &jac {
                let e = Expr::add(row.iter().zip(&w).filter(|(j, _)| !j.is_zero()).map(|(j, wk)| j.times(wk)));
                outputs.push(e);
            }
            if jw0.is_empty() {
                jw0 = outputs[n..2 * n].to_vec();
            }
        }
        let mut inputs: Vec<String> = state.iter().map(|s| s.to_string()).collect();
        inputs.extend(names.iter().flatten().cloned());
        if megno {
            let w0: Vec<Expr> = names[0].iter().map(|s| Expr::var(s)).collect();
            let num = Expr::add(w0.iter().zip(&jw0).map(|(w, jw)| w.times(jw)));
            let den = Expr::add(w0.iter().map(|w| w.powi(2)));
            outputs.push(Expr::var("t").times(&num.over(&den)));
            inputs.push("δmegno".to_string());
        }
        inputs.push("t".to_string());
        let input_refs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        let tape = Tape::compile(&outputs, &input_refs, params)?;
        let taylor = TaylorOde::first_order(&tape);
        Ok(Variational { n, m: tangents, megno, hamiltonian: false, tape, taylor })
    }

    /// The variational system of Hamilton's equations of `h` (state `(q, p)`).
    pub fn hamiltonian(
        h: &Expr,
        coords: &[&str],
        momenta: &[&str],
        params: &[(&str, f64)],
        tangents: usize,
        megno: bool,
    ) -> Result<Variational, CompileError> {
        let syms: Vec<Symbol> =
            coords.iter().chain(momenta).map(|s| symbol_named(std::slice::from_ref(h), s)).collect();
        let n = coords.len();
        let mut d = Differentiator::new();
        let mut f: Vec<Expr> = syms[n..].iter().map(|p| d.diff(h, p)).collect();
        f.extend(syms[..n].iter().map(|q| d.diff(h, q).neg()));
        let state: Vec<&str> = coords.iter().chain(momenta).copied().collect();
        let mut var = Variational::new(&f, &state, params, tangents, megno)?;
        var.hamiltonian = true;
        Ok(var)
    }

    /// The variational system of a mechanics [`System`] in canonical coordinates `(q, p)`:
    /// Hamilton's equations of its Hamiltonian (derived by the Legendre transform for a
    /// Lagrangian system), plus its generalized forces and Rayleigh dissipation in `p'`
    /// ([`System::hamilton_equations`]), so a damped or driven system has its own flow, not the
    /// flow of its `H`; only a system without them is [`Variational::is_hamiltonian`].
    /// Constraints are refused: their multipliers are not functions of `(q, p, t)` here.
    pub fn of_system(sys: &System, tangents: usize, megno: bool) -> Result<Variational, CompileError> {
        // A velocity constraint gets the refusal that names the routes keeping it.
        sys.refuse_velocity_constraints("the variational equations (chaos indicators, the flow's Jacobian)")
            .map_err(CompileError::Mechanics)?;
        if !sys.constraints().is_empty() {
            return Err(CompileError::Unsupported {
                what: "the variational equations of a constrained system (the multipliers are not functions of (q, p, t)); write the system in coordinates that satisfy the constraints",
            });
        }
        let q: Vec<String> = sys.coordinates().iter().map(|s| s.to_string()).collect();
        let p: Vec<String> = sys.momenta().iter().map(|s| s.to_string()).collect();
        let params: Vec<(String, f64)> = sys.param_values().iter().map(|(k, v)| (k.to_string(), *v)).collect();
        let refs: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let qs: Vec<&str> = q.iter().map(String::as_str).collect();
        let ps: Vec<&str> = p.iter().map(String::as_str).collect();
        if !sys.has_driving_forces() {
            let h = sys.hamiltonian().map_err(CompileError::Mechanics)?;
            return Variational::hamiltonian(&h, &qs, &ps, &refs, tangents, megno);
        }
        let eqs = sys.hamilton_equations().map_err(CompileError::Mechanics)?;
        let mut f = eqs.qdot;
        f.extend(eqs.pdot);
        let state: Vec<&str> = qs.iter().chain(&ps).copied().collect();
        Variational::new(&f, &state, &refs, tangents, megno)
    }

    /// Whether the flow is Hamiltonian (built from a Hamiltonian alone), so symplectic.
    pub fn is_hamiltonian(&self) -> bool {
        self.hamiltonian
    }

    /// The dimension `n` of `x`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The number of tangent vectors.
    pub fn tangents(&self) -> usize {
        self.m
    }

    /// Whether the MEGNO accumulator is the last state component.
    pub fn has_megno(&self) -> bool {
        self.megno
    }

    /// The dimension of the whole state.
    pub fn dim(&self) -> usize {
        self.n * (1 + self.m) + usize::from(self.megno)
    }

    /// The initial state: `x0`, then the first `m` unit vectors as tangents (all of them: `Φ(0)
    /// = I`), then a zero accumulator.
    pub fn initial_state(&self, x0: &[f64]) -> Vec<f64> {
        let n = self.n;
        let mut y = vec![0.0; self.dim()];
        y[..n].copy_from_slice(&x0[..n]);
        for j in 0..self.m {
            y[n + j * n + (j % n)] = 1.0;
        }
        y
    }

    /// The compiled tape (`f`, the `J w_j`, the MEGNO integrand).
    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    /// The Taylor form.
    pub fn taylor(&self) -> &TaylorOde {
        &self.taylor
    }

    /// The same system with native code from the first expansion (`true`) or never (`false`),
    /// as [`TaylorOde::with_native`]: for comparing the single run with the batch lanes on
    /// each kind of code.
    pub fn with_native(mut self, on: bool) -> Variational {
        self.taylor = self.taylor.with_native(on);
        self
    }
}

impl Rhs for Variational {
    fn dim(&self) -> usize {
        Variational::dim(self)
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        let d = Variational::dim(self);
        self.tape.eval_split(&y[..d], t, &mut dy[..d]);
    }
}

impl TaylorSystem for Variational {
    fn dim(&self) -> usize {
        Variational::dim(self)
    }
    fn scratch_len(&self, order: usize) -> usize {
        self.taylor.scratch_len(order)
    }
    fn taylor_coefficients(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), StepError> {
        self.taylor.taylor_coefficients(t, y, order, buf)
    }
    /// The inner system's: a run's buffer is the inner expansion's, so its constant rows can
    /// stay as the last step left them, as in a run of the [`TaylorOde`] alone.
    fn taylor_coefficients_again(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), StepError> {
        self.taylor.taylor_coefficients_again(t, y, order, buf)
    }
    fn check_step(&self, scratch: &[f64], order: usize, h: f64) -> Result<(), StepError> {
        self.taylor.check_step(scratch, order, h)
    }
    fn non_finite(&self, t: f64, y: &[f64], order: usize, at: usize) -> StepFailure {
        self.taylor.non_finite(t, y, order, at)
    }
}

/// The chaos maps' batch: the variational system is its [`TaylorOde`], so its lanes are that
/// tape's batch expansions (native wide or lane-pair code once the tiers compile it), each lane
/// with the single expansion's bits.
impl TaylorBatchSystem for Variational {
    type Batch = <TaylorOde as TaylorBatchSystem>::Batch;

    fn batch(&self, order: usize, lanes: usize) -> Option<Self::Batch> {
        self.taylor.batch(order, lanes)
    }
    fn lanes(batch: &Self::Batch) -> usize {
        <TaylorOde as TaylorBatchSystem>::lanes(batch)
    }
    fn expand_batch<const B: usize>(
        &self,
        batch: &mut Self::Batch,
        t: &[f64],
        y: &[f64],
        out: &mut [Lanes<B>],
        failed: &mut [bool],
    ) {
        self.taylor.expand_batch(batch, t, y, out, failed)
    }
}
