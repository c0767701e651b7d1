//! Right-hand sides for the integrators, compiled from equations of motion.
//!
//! Every type here evaluates its tapes as native code when they have it (no scratch at all
//! on the hot paths: a small Lagrangian system is one call of the generated function) and
//! otherwise, or for the matrices of a pivoting solve, on one per-thread scratch buffer laid
//! out as `tape slots | matrices | vectors`; either way a call never allocates. Every type is
//! `Sync` so ensembles can share it across threads. Failures along a trajectory (a mass matrix that becomes
//! singular, a non-finite value, a Legendre map that does not converge) are returned by the
//! fallible `try_*` methods; the infallible [`Rhs::eval`] writes NaN, which the integrators'
//! non-finite guard catches, and keeps the reason for [`LagrangianRhs::last_error`].

use std::sync::Mutex;

use crate::diff::Differentiator;
use crate::expr::{Expr, Node, Symbol};
use crate::integrate::{Jacobian, Rhs, RhsError as StepError, Separable};
use crate::linalg::{factor, solve, Factor};

use super::error::CompileError;
use super::tape::{with_scratch, CompileOptions, Tape, LANES};
use super::tape::{Epilogue, NativeCode};
use super::velocity_name;

/// Why a right-hand side has no value at a state.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RhsError {
    /// `W q'' = F` cannot be solved: the mass matrix is singular to working precision.
    #[error("the mass matrix is singular at t = {t} (no pivot for the velocity `{velocity}`); state {state:?}")]
    SingularMassMatrix { t: f64, state: Vec<f64>, velocity: String },
    /// A mass-matrix entry, a force or a derivative is infinite or NaN.
    #[error("non-finite {what} at t = {t}; state {state:?}")]
    NonFinite { t: f64, state: Vec<f64>, what: &'static str },
    /// The augmented matrix `[W Φᵀ; Φ 0]` of a constrained system is singular: the
    /// constraint (numbered from 1) has no pivot, so it is redundant with the others (or the
    /// constraints are not independent at this state).
    #[error("the augmented matrix [W Φᵀ; Φ 0] is singular at t = {t}: constraint {constraint} is redundant (its gradient is a combination of the others' or zero); state {state:?}")]
    SingularAugmented { t: f64, state: Vec<f64>, constraint: usize },
    /// Newton's method for `p = ∂L/∂q'` did not converge.
    #[error("the Legendre map did not converge at t = {t} after {iterations} Newton steps (residual {residual:e}); state {state:?}")]
    LegendreNewton { t: f64, state: Vec<f64>, iterations: usize, residual: f64 },
    /// Ctrl-C (the process-wide [`crate::cancel`] token) stopped the Legendre map's Newton
    /// iteration.
    #[error("interrupted in the Legendre map at t = {t}; state {state:?}")]
    Interrupted { t: f64, state: Vec<f64> },
}

impl RhsError {
    /// The reason alone, without the time and the stage state: an integrator reports the
    /// last *accepted* time and state beside it, and a stage's state (a trial point inside a
    /// step) would only be a second, confusing pair.
    pub fn reason(&self) -> String {
        match self {
            RhsError::SingularMassMatrix { velocity, .. } => {
                format!("the mass matrix became singular (no pivot for the velocity `{velocity}`)")
            }
            RhsError::NonFinite { what, .. } => format!("the {what} became infinite or NaN"),
            RhsError::SingularAugmented { constraint, .. } => format!(
                "the augmented matrix [W Φᵀ; Φ 0] became singular: constraint {constraint} is redundant (its gradient is a combination of the others' or zero)"
            ),
            RhsError::LegendreNewton { iterations, residual, .. } => format!(
                "the Legendre map did not converge after {iterations} Newton steps (residual {})",
                crate::integrate::fmt_value(*residual)
            ),
            RhsError::Interrupted { .. } => "interrupted in the Legendre map".to_string(),
        }
    }
}

/// The integrators' error carries the reason only: the driver adds the last accepted time
/// and state.
impl From<RhsError> for StepError {
    fn from(e: RhsError) -> StepError {
        StepError::new(e.reason())
    }
}

/// Where a failed evaluation keeps its reason. Locked only on failure and when asked.
#[derive(Debug, Default)]
struct ErrorSlot(Mutex<Option<RhsError>>);

impl ErrorSlot {
    fn set(&self, e: RhsError) {
        if let Ok(mut g) = self.0.lock() {
            *g = Some(e);
        }
    }
    fn get(&self) -> Option<RhsError> {
        self.0.lock().ok().and_then(|g| g.clone())
    }
    fn take(&self) -> Option<RhsError> {
        self.0.lock().ok().and_then(|mut g| g.take())
    }
}

/// The inputs of every compiled tape of a system with coordinates `q`: `q…, q'…, t`.
pub(super) fn state_inputs(coords: &[String]) -> Vec<String> {
    let mut v: Vec<String> = coords.to_vec();
    v.extend(coords.iter().map(|q| velocity_name(q)));
    v.push("t".to_string());
    v
}

fn as_strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The symbol of a name as the compiler matches it (by plain spelling, so sign assumptions do
/// not matter): `θ'` is `θ` with one prime.
fn symbol_of(name: &str) -> Symbol {
    let primes = name.chars().rev().take_while(|c| *c == '\'').count();
    Symbol::new(&name[..name.len() - primes]).with_primes(primes as u8)
}

/// The symbol in `e` spelt `name`, if any (so a positive `m` is found by the name `m`).
fn find_symbol(exprs: &[&Expr], name: &str) -> Symbol {
    for e in exprs {
        if let Some(s) = e.free_symbols().into_iter().find(|s| s.to_string() == name) {
            return s;
        }
    }
    symbol_of(name)
}

fn owned_params(params: &[(&str, f64)]) -> Vec<(String, f64)> {
    params.iter().map(|(k, v)| (k.to_string(), *v)).collect()
}

fn borrowed(params: &[(String, f64)]) -> Vec<(&str, f64)> {
    params.iter().map(|(k, v)| (k.as_str(), *v)).collect()
}

/// Up to this many degrees of freedom the Cholesky solve is unrolled into the tape (where
/// constant and zero entries of `W` fold away) when the tape is interpreted; beyond, its
/// `n³/6` operations run faster as the compiled loops of [`factor`] than through the
/// interpreter.
const UNROLL_MAX_DOF: usize = 4;

/// The same limit when the tape runs as native code, where the unrolled solve is straight-line
/// machine code with the zeros of `W` folded away, faster than the loops of [`factor`]. At
/// `n = 16` the unrolled factorisation is about 1,400 instructions; much beyond, the code
/// outgrows the instruction cache for little gain.
const UNROLL_MAX_DOF_NATIVE: usize = 16;

/// Whether `W` is constant once the parameters are bound (no coordinate, velocity or time in
/// it) and the fast path's pivots pass [`LagrangianRhs::fast_ok`]'s threshold: then they pass
/// it at every state, and the native solve checks only that the accelerations are finite.
/// The pivots are read from one evaluation of the solve tape `fast` (at the zero state: a
/// constant `W` does not depend on it, whatever `F` does there).
fn constant_positive_definite(w: &[Vec<Expr>], params: &[(&str, f64)], fast: &Tape, n: usize) -> bool {
    let constant = w.iter().flatten().all(|e| {
        e.free_symbols().iter().all(|s| {
            let name = s.to_string();
            params.iter().any(|(p, _)| *p == name)
        })
    });
    if !constant {
        return false;
    }
    let mut out = vec![0.0; 3 * n];
    fast.eval_split(&vec![0.0; 2 * n], 0.0, &mut out);
    let scale = out[2 * n..].iter().fold(0.0f64, |a, &b| a.max(b));
    let tol = n as f64 * f64::EPSILON * scale;
    out[n..2 * n].iter().all(|&d| d > tol)
}

/// `W q'' = F` as a first-order system in `y = (q, q')`.
///
/// `W` is the mass matrix `∂²L/∂q'_i∂q'_j` and `F_i = ∂L/∂q_i − Σ_j ∂²L/∂q'_i∂q_j q'_j −
/// ∂²L/∂q'_i∂t` (PHYSICS.md §2). Both are compiled into one tape, so what they share (the
/// `cos(θ1 − θ2)` of a double pendulum) is computed once; the solve is an in-place Cholesky
/// (LU with pivoting when `W` is not positive definite) on the same scratch.
#[derive(Debug)]
pub struct LagrangianRhs {
    n: usize,
    coords: Vec<String>,
    tape: Tape,
    /// `W`, `F` and an unrolled Cholesky solve in one tape (symmetric `W` only): the fast path.
    fast: Option<Tape>,
    /// The fast path as one native function writing `(q', q'')` and checking the pivots.
    fast_native: Option<NativeCode>,
    symmetric: bool,
    w: Vec<Vec<Expr>>,
    f: Vec<Expr>,
    params: Vec<(String, f64)>,
    options: CompileOptions,
    error: ErrorSlot,
}

impl LagrangianRhs {
    /// Compiles `W q'' = F` for the coordinates `coords` (names; velocities are the primed
    /// names), with `params` bound. The time symbol is `t`.
    pub fn new(
        w: &[Vec<Expr>],
        f: &[Expr],
        coords: &[&str],
        params: &[(&str, f64)],
    ) -> Result<LagrangianRhs, CompileError> {
        LagrangianRhs::with_options(w, f, coords, params, &CompileOptions::default())
    }

    /// [`LagrangianRhs::new`] with explicit code generator choices (such as forcing the
    /// interpreter with [`CompileOptions::with_native`]).
    pub fn with_options(
        w: &[Vec<Expr>],
        f: &[Expr],
        coords: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<LagrangianRhs, CompileError> {
        let n = coords.len();
        check_shape("forces F", n, f.len())?;
        check_shape("rows of the mass matrix W", n, w.len())?;
        for row in w {
            check_shape("columns of the mass matrix W", n, row.len())?;
        }
        let coords: Vec<String> = coords.iter().map(|s| s.to_string()).collect();
        let mut outputs: Vec<Expr> = w.iter().flatten().cloned().collect();
        outputs.extend(f.iter().cloned());
        let inputs = state_inputs(&coords);
        let tape = Tape::compile_with_options(&outputs, &as_strs(&inputs), params, options)?;
        let symmetric = (0..n).all(|i| (0..i).all(|j| w[i][j] == w[j][i]));
        let unroll = if options.native { UNROLL_MAX_DOF_NATIVE } else { UNROLL_MAX_DOF };
        let fast = if symmetric && n <= unroll {
            Some(Tape::compile_cholesky_solve(w, f, &as_strs(&inputs), params, options)?)
                // Interpreted, a large unrolled solve loses to the loops of `factor`.
                .filter(|t| n <= UNROLL_MAX_DOF || t.is_native())
        } else {
            None
        };
        let check_pivots = !fast.as_ref().is_some_and(|t| constant_positive_definite(w, params, t, n));
        let fast_native = fast
            .as_ref()
            .filter(|t| t.is_native())
            .and_then(|t| NativeCode::compile(t, Epilogue::LagrangianSolve { n, check_pivots }));
        Ok(LagrangianRhs {
            n,
            coords,
            tape,
            fast,
            fast_native,
            symmetric,
            w: w.to_vec(),
            f: f.to_vec(),
            params: owned_params(params),
            options: options.clone(),
            error: ErrorSlot::default(),
        })
    }

    /// Degrees of freedom.
    pub fn dof(&self) -> usize {
        self.n
    }

    /// The compiled tape (`W` row-major, then `F`), for inspection and operation counts.
    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    /// Whether `W` is symmetric (structurally), so its factorisation may be Cholesky.
    pub fn is_symmetric(&self) -> bool {
        self.symmetric
    }

    /// The tape of the fast path, `W`, `F` and the unrolled Cholesky solve (outputs: the
    /// accelerations, the pivots, the diagonal of `W`); `None` when `W` is not symmetric.
    pub fn solve_tape(&self) -> Option<&Tape> {
        self.fast.as_ref()
    }

    /// Whether the unrolled Cholesky on `slot(k)` succeeded with safely positive pivots and
    /// finite accelerations (same threshold as [`factor`]: `n·ε·max W_jj`, which bounds every
    /// `|W_ij|` of a positive definite matrix).
    fn fast_ok(&self, slot: impl Fn(usize) -> f64) -> bool {
        let n = self.n;
        let mut scale = 0.0f64;
        for j in 0..n {
            scale = scale.max(slot(2 * n + j));
        }
        let tol = n as f64 * f64::EPSILON * scale;
        (0..n).all(|j| slot(n + j) > tol && slot(j).is_finite())
    }

    /// Evaluates `y' = (q', q'')`, or says why it cannot.
    ///
    /// The native fast path is kept apart from the rest, so that a call which it answers is
    /// the length check and one indirect call, with none of the stack frame of the fallbacks.
    #[inline]
    pub fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        let n = self.n;
        assert!(y.len() >= 2 * n && dy.len() >= 2 * n, "state or derivative shorter than 2n");
        if let Some(code) = &self.fast_native {
            // SAFETY: `y` has the 2n inputs read and `dy` the 2n outputs written, stride 1.
            if unsafe { code.call_solve(y.as_ptr(), 1, t, dy.as_mut_ptr(), 1) } {
                return Ok(());
            }
        }
        self.try_eval_fallback(t, y, dy)
    }

    /// [`LagrangianRhs::try_eval`] when the native fast path is absent or declined the state:
    /// the interpreted unrolled solve, else the pivoting solve.
    #[inline(never)]
    fn try_eval_fallback(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        let n = self.n;
        dy[..n].copy_from_slice(&y[n..2 * n]);
        if let (Some(fast), None) = (&self.fast, &self.fast_native) {
            // Accelerations, pivots, diagonal of W: on the stack, no scratch.
            let mut out = [0.0; 3 * UNROLL_MAX_DOF_NATIVE];
            fast.eval_split(&y[..2 * n], t, &mut out);
            if self.fast_ok(|k| out[k]) {
                dy[n..2 * n].copy_from_slice(&out[..n]);
                return Ok(());
            }
            // Not safely positive definite (or not finite): the pivoting path solves it or
            // says why not.
        }
        self.tape.with_slots(2 * n * n + 3 * n, |slots, rest| {
            self.accel_on(t, y, slots, rest, &mut dy[n..2 * n]).map(|_| ())
        })
    }

    /// Runs the tape at `(t, y)` and solves for the accelerations into `acc`, leaving the
    /// factorisation in `rest` (`a | b | m | perm | tmp`) and `(q, q', t)` in the input slots.
    fn accel_on(
        &self,
        t: f64,
        y: &[f64],
        slots: &mut [f64],
        rest: &mut [f64],
        acc: &mut [f64],
    ) -> Result<Factor, RhsError> {
        let n = self.n;
        slots[..2 * n].copy_from_slice(&y[..2 * n]);
        slots[2 * n] = t;
        let (ab, rest) = rest.split_at_mut(n * n + n);
        self.tape.eval_staged(slots, ab);
        let (a, b) = ab.split_at(n * n);
        let (m, rest) = rest.split_at_mut(n * n);
        let (perm, tmp) = rest.split_at_mut(n);
        self.finish_solve(t, y, a, m, perm, b, tmp, acc)
    }

    #[allow(clippy::too_many_arguments)]
    fn finish_solve(
        &self,
        t: f64,
        y: &[f64],
        a: &[f64],
        m: &mut [f64],
        perm: &mut [f64],
        b: &[f64],
        tmp: &mut [f64],
        acc: &mut [f64],
    ) -> Result<Factor, RhsError> {
        let n = self.n;
        if !a.iter().all(|x| x.is_finite()) {
            return Err(RhsError::NonFinite { t, state: state_of(y, n), what: "mass matrix" });
        }
        if !b.iter().all(|x| x.is_finite()) {
            return Err(RhsError::NonFinite { t, state: state_of(y, n), what: "force" });
        }
        let kind = factor(a, m, perm, n, self.symmetric).map_err(|j| RhsError::SingularMassMatrix {
            t,
            state: state_of(y, n),
            velocity: velocity_name(&self.coords[j]),
        })?;
        acc[..n].copy_from_slice(&b[..n]);
        solve(kind, m, perm, n, acc, tmp);
        if !acc[..n].iter().all(|x| x.is_finite()) {
            return Err(RhsError::NonFinite { t, state: state_of(y, n), what: "acceleration" });
        }
        Ok(kind)
    }

    /// The reason the most recent failed [`Rhs::eval`] wrote NaN, if any.
    pub fn last_error(&self) -> Option<RhsError> {
        self.error.get()
    }

    /// Returns and clears the last error.
    pub fn take_error(&self) -> Option<RhsError> {
        self.error.take()
    }

    /// Evaluates many states at once, structure-of-arrays: component `i` of state `k` is
    /// `y[i * points + k]`, and likewise for `dy`. The tape runs [`LANES`] states per
    /// instruction dispatch; the small solves follow per state.
    pub fn eval_batch(&self, t: f64, y: &[f64], dy: &mut [f64], points: usize) -> Result<(), RhsError> {
        let n = self.n;
        let Some(fast) = &self.fast else {
            return self.eval_batch_native(t, y, dy, points);
        };
        let mut failed: Option<usize> = None;
        if let Some(code) = &self.fast_native {
            assert!(y.len() >= 2 * n * points && dy.len() >= 2 * n * points, "batch buffers too short");
            for k in 0..points {
                // SAFETY: point k reads y[i·points + k] and writes dy[i·points + k] for i < 2n,
                // all below 2n·points (asserted above).
                let ok = unsafe { code.call_solve(y.as_ptr().add(k), points, t, dy.as_mut_ptr().add(k), points) };
                if !ok {
                    return self.batch_rest(t, y, dy, points, k);
                }
            }
            return Ok(());
        }
        if fast.is_native() {
            // One call of the machine code per point, reading the point in place.
            let mut out = [0.0; 3 * UNROLL_MAX_DOF_NATIVE];
            for k in 0..points {
                fast.eval_strided(&y[k..], points, t, &mut out, 1);
                if !self.fast_ok(|o| out[o]) {
                    failed = Some(k);
                    break;
                }
                for i in 0..n {
                    dy[i * points + k] = y[(n + i) * points + k];
                    dy[(n + i) * points + k] = out[i];
                }
            }
            return match failed {
                None => Ok(()),
                Some(k0) => self.batch_rest(t, y, dy, points, k0),
            };
        }
        let slots_len = fast.scratch_len() * LANES;
        with_scratch(slots_len, |slots| {
            let mut start = 0;
            while start < points {
                let len = LANES.min(points - start);
                for i in 0..2 * n {
                    let dst = &mut slots[i * LANES..(i + 1) * LANES];
                    dst[..len].copy_from_slice(&y[i * points + start..i * points + start + len]);
                    dst[len..].fill(0.5);
                }
                slots[2 * n * LANES..(2 * n + 1) * LANES].fill(t);
                fast.run_lanes_in_place(slots);
                for l in 0..len {
                    let k = start + l;
                    if !self.fast_ok(|o| slots[fast.output_slot(o) * LANES + l]) {
                        failed = Some(k);
                        return;
                    }
                    for i in 0..n {
                        dy[i * points + k] = y[(n + i) * points + k];
                        dy[(n + i) * points + k] = slots[fast.output_slot(i) * LANES + l];
                    }
                }
                start += len;
            }
        });
        match failed {
            None => Ok(()),
            Some(k0) => self.batch_rest(t, y, dy, points, k0),
        }
    }

    /// Finishes a batch state by state from point `k0`, which the fast path rejected.
    fn batch_rest(&self, t: f64, y: &[f64], dy: &mut [f64], points: usize, k0: usize) -> Result<(), RhsError> {
        let n = self.n;
        let (mut ys, mut ds) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
        for k in k0..points {
            (0..2 * n).for_each(|i| ys[i] = y[i * points + k]);
            self.try_eval(t, &ys, &mut ds)?;
            (0..2 * n).for_each(|i| dy[i * points + k] = ds[i]);
        }
        Ok(())
    }

    /// The batch path without an unrolled solve: `W` and `F` through the machine code point
    /// by point, or the lane interpreter, then the solve of [`factor`] state by state.
    fn eval_batch_native(&self, t: f64, y: &[f64], dy: &mut [f64], points: usize) -> Result<(), RhsError> {
        let n = self.n;
        let slots_len = if self.tape.is_native() { 0 } else { self.tape.scratch_len() * LANES };
        let mut failure: Option<(usize, RhsError)> = None;
        with_scratch(slots_len + 2 * n * n + 5 * n, |s| {
            let (slots, rest) = s.split_at_mut(slots_len);
            let (ab, rest) = rest.split_at_mut(n * n + n);
            let (m, rest) = rest.split_at_mut(n * n);
            let (perm, rest) = rest.split_at_mut(n);
            let (tmp, rest) = rest.split_at_mut(n);
            let acc = &mut rest[..n];
            if self.tape.is_native() {
                for k in 0..points {
                    self.tape.eval_strided(&y[k..], points, t, ab, 1);
                    let (a, b) = ab.split_at(n * n);
                    if let Err(e) = self.finish_solve(t, &[], a, m, perm, b, tmp, acc) {
                        failure = Some((k, e));
                        return;
                    }
                    for i in 0..n {
                        dy[i * points + k] = y[(n + i) * points + k];
                        dy[(n + i) * points + k] = acc[i];
                    }
                }
                return;
            }
            let (a, b) = ab.split_at_mut(n * n);
            let mut start = 0;
            while start < points {
                let len = LANES.min(points - start);
                for i in 0..2 * n {
                    let dst = &mut slots[i * LANES..(i + 1) * LANES];
                    dst[..len].copy_from_slice(&y[i * points + start..i * points + start + len]);
                    dst[len..].fill(0.5);
                }
                slots[2 * n * LANES..(2 * n + 1) * LANES].fill(t);
                self.tape.run_lanes_in_place(slots);
                for l in 0..len {
                    let k = start + l;
                    for (o, x) in a.iter_mut().enumerate() {
                        *x = slots[self.tape.output_slot(o) * LANES + l];
                    }
                    for (i, x) in b.iter_mut().enumerate() {
                        *x = slots[self.tape.output_slot(n * n + i) * LANES + l];
                    }
                    if let Err(e) = self.finish_solve(t, &[], a, m, perm, b, tmp, acc) {
                        failure = Some((k, e));
                        return;
                    }
                    for i in 0..n {
                        dy[i * points + k] = y[(n + i) * points + k];
                        dy[(n + i) * points + k] = acc[i];
                    }
                }
                start += len;
            }
        });
        match failure {
            None => Ok(()),
            Some((k, _)) => {
                // Redo the failing state alone for an error that carries its state.
                let ys: Vec<f64> = (0..2 * n).map(|i| y[i * points + k]).collect();
                let mut ds = vec![0.0; 2 * n];
                self.try_eval(t, &ys, &mut ds)
            }
        }
    }

    /// Compiles the exact Jacobian `∂f/∂y` too (for implicit methods).
    ///
    /// With `a = W⁻¹F`, `∂a/∂y_j = W⁻¹ (∂F/∂y_j − (∂W/∂y_j) a)`: the derivatives of `W` and `F`
    /// are symbolic and compiled into one tape; the solve reuses the factorisation of `W`.
    pub fn with_jacobian(self) -> Result<LagrangianJacobian, CompileError> {
        let n = self.n;
        let inputs = state_inputs(&self.coords);
        let exprs: Vec<&Expr> = self.w.iter().flatten().chain(self.f.iter()).collect();
        let vars: Vec<Symbol> = inputs[..2 * n].iter().map(|name| find_symbol(&exprs, name)).collect();
        let mut d = Differentiator::new();
        let mut outputs = Vec::with_capacity(2 * n * (n + n * n));
        for v in &vars {
            for fi in &self.f {
                outputs.push(d.diff(fi, v));
            }
            for row in &self.w {
                for wik in row {
                    outputs.push(d.diff(wik, v));
                }
            }
        }
        let jac = Tape::compile_with_options(&outputs, &as_strs(&inputs), &borrowed(&self.params), &self.options)?;
        Ok(LagrangianJacobian { rhs: self, jac })
    }
}

/// The state for an error report (empty when the caller reports it itself).
fn state_of(y: &[f64], n: usize) -> Vec<f64> {
    y.get(..2 * n).map(<[f64]>::to_vec).unwrap_or_default()
}

fn check_shape(what: &'static str, expected: usize, got: usize) -> Result<(), CompileError> {
    if expected == got {
        Ok(())
    } else {
        Err(CompileError::Shape { what, expected, got })
    }
}

fn fail_nan(dy: &mut [f64]) {
    dy.iter_mut().for_each(|x| *x = f64::NAN);
}

impl Rhs for LagrangianRhs {
    fn dim(&self) -> usize {
        2 * self.n
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepError> {
        LagrangianRhs::try_eval(self, t, y, dy).map_err(StepError::from)
    }
    #[inline]
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if let Err(e) = self.try_eval(t, y, dy) {
            fail_nan(&mut dy[..2 * self.n]);
            self.error.set(e);
        }
    }
}

/// A [`LagrangianRhs`] with its exact Jacobian compiled (see [`LagrangianRhs::with_jacobian`]).
#[derive(Debug)]
pub struct LagrangianJacobian {
    rhs: LagrangianRhs,
    jac: Tape,
}

impl LagrangianJacobian {
    /// The right-hand side.
    pub fn rhs(&self) -> &LagrangianRhs {
        &self.rhs
    }

    /// The Jacobian tape, for inspection and operation counts.
    pub fn tape(&self) -> &Tape {
        &self.jac
    }

    /// Writes `∂f_i/∂y_j` into `jac[i * 2n + j]`, or says why it cannot.
    pub fn try_jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<(), RhsError> {
        let n = self.rhs.n;
        let dim = 2 * n;
        let slots_len = self.rhs.tape.scratch_len().max(self.jac.scratch_len());
        let njac = dim * (n + n * n);
        with_scratch(slots_len + 2 * n * n + 4 * n + njac, |s| {
            let (slots, rest) = s.split_at_mut(slots_len);
            let (solver, rest) = rest.split_at_mut(2 * n * n + 3 * n);
            let (acc, jv) = rest.split_at_mut(n);
            let kind = self.rhs.accel_on(t, y, slots, solver, acc)?;
            // The input slots are never reused as registers, so they still hold (q, q', t).
            self.jac.eval_staged(slots, jv);
            if !jv.iter().all(|x| x.is_finite()) {
                return Err(RhsError::NonFinite { t, state: y[..dim].to_vec(), what: "Jacobian" });
            }
            // `F` (after `W` in `ab`) was consumed by the solve: its room holds the columns.
            let (ab, rest) = solver.split_at_mut(n * n + n);
            let r = &mut ab[n * n..];
            let (m, rest) = rest.split_at_mut(n * n);
            let (perm, tmp) = rest.split_at_mut(n);
            for i in 0..n {
                for j in 0..dim {
                    jac[i * dim + j] = if j == n + i { 1.0 } else { 0.0 };
                }
            }
            for j in 0..dim {
                let block = &jv[j * (n + n * n)..(j + 1) * (n + n * n)];
                let (df, dw) = block.split_at(n);
                for i in 0..n {
                    let mut v = df[i];
                    for k in 0..n {
                        v -= dw[i * n + k] * acc[k];
                    }
                    r[i] = v;
                }
                solve(kind, m, perm, n, r, tmp);
                for i in 0..n {
                    jac[(n + i) * dim + j] = r[i];
                }
            }
            Ok(())
        })
    }
}

impl Rhs for LagrangianJacobian {
    fn dim(&self) -> usize {
        self.rhs.dim()
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        self.rhs.eval(t, y, dy)
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepError> {
        self.rhs.try_eval(t, y, dy).map_err(StepError::from)
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        Some(self)
    }
}

impl Jacobian for LagrangianJacobian {
    fn jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) {
        if let Err(e) = self.try_jacobian(t, y, jac) {
            let d = self.rhs.dim();
            fail_nan(&mut jac[..d * d]);
            self.rhs.error.set(e);
        }
    }
}

/// Hamilton's equations `q' = ∂H/∂p`, `p' = −∂H/∂q` for any `H(q, p, t)`, with the exact
/// Jacobian compiled alongside. State `y = (q, p)`.
#[derive(Debug)]
pub struct HamiltonianRhs {
    n: usize,
    tape: Tape,
    jac: Tape,
    error: ErrorSlot,
}

/// The inputs of a Hamiltonian tape: `q…, p…, t`.
fn phase_inputs(coords: &[&str], momenta: &[&str]) -> Vec<String> {
    coords.iter().chain(momenta).map(|s| s.to_string()).chain(["t".to_string()]).collect()
}

impl HamiltonianRhs {
    /// Compiles Hamilton's equations of `h` with coordinates `coords` and their conjugate
    /// momenta `momenta` (names, in the same order), `params` bound.
    pub fn new(
        h: &Expr,
        coords: &[&str],
        momenta: &[&str],
        params: &[(&str, f64)],
    ) -> Result<HamiltonianRhs, CompileError> {
        HamiltonianRhs::with_options(h, coords, momenta, params, &CompileOptions::default())
    }

    /// [`HamiltonianRhs::new`] with explicit code generator choices.
    pub fn with_options(
        h: &Expr,
        coords: &[&str],
        momenta: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<HamiltonianRhs, CompileError> {
        let n = coords.len();
        check_shape("momenta", n, momenta.len())?;
        let inputs = phase_inputs(coords, momenta);
        let syms: Vec<Symbol> = inputs[..2 * n].iter().map(|s| find_symbol(&[h], s)).collect();
        let mut d = Differentiator::new();
        let mut f: Vec<Expr> = syms[n..].iter().map(|p| d.diff(h, p)).collect();
        f.extend(syms[..n].iter().map(|q| d.diff(h, q).neg()));
        let mut jac_exprs = Vec::with_capacity(4 * n * n);
        for fi in &f {
            for s in &syms {
                jac_exprs.push(d.diff(fi, s));
            }
        }
        let tape = Tape::compile_with_options(&f, &as_strs(&inputs), params, options)?;
        let jac = Tape::compile_with_options(&jac_exprs, &as_strs(&inputs), params, options)?;
        Ok(HamiltonianRhs { n, tape, jac, error: ErrorSlot::default() })
    }

    /// The tape of `(∂H/∂p, −∂H/∂q)`.
    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    /// The tape of the Jacobian, row-major.
    pub fn jacobian_tape(&self) -> &Tape {
        &self.jac
    }

    /// Evaluates Hamilton's equations, or reports a non-finite value.
    pub fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        eval_phase(&self.tape, self.n, t, y, dy, "derivative of H")
    }

    /// The Jacobian `∂f_i/∂y_j` into `jac[i * 2n + j]`, or reports a non-finite value.
    pub fn try_jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) -> Result<(), RhsError> {
        eval_phase(&self.jac, self.n, t, y, jac, "Jacobian")
    }

    /// The reason the most recent failed evaluation wrote NaN, if any.
    pub fn last_error(&self) -> Option<RhsError> {
        self.error.get()
    }
}

fn eval_phase(tape: &Tape, n: usize, t: f64, y: &[f64], out: &mut [f64], what: &'static str) -> Result<(), RhsError> {
    tape.eval_split(&y[..2 * n], t, out);
    if out[..tape.n_outputs()].iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(RhsError::NonFinite { t, state: y[..2 * n].to_vec(), what })
    }
}

impl Rhs for HamiltonianRhs {
    fn dim(&self) -> usize {
        2 * self.n
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepError> {
        HamiltonianRhs::try_eval(self, t, y, dy).map_err(StepError::from)
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        Some(self)
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if let Err(e) = self.try_eval(t, y, dy) {
            self.error.set(e);
        }
    }
}

impl Jacobian for HamiltonianRhs {
    fn jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) {
        if let Err(e) = self.try_jacobian(t, y, jac) {
            self.error.set(e);
        }
    }
}

/// Splits `h` into `(T(p), V(q, t))` when it is separable: every term of the sum depends on
/// momenta only or on coordinates and time only (terms of parameters alone go to `V`).
/// Products of parameters with a separable sum distribute (`½ (p² + q²)`). Returns `None`
/// when some term mixes them (`p² / r²`).
pub fn split_separable(h: &Expr, coords: &[&str], momenta: &[&str]) -> Option<(Expr, Expr)> {
    let is_p = |s: &Symbol| momenta.contains(&s.to_string().as_str());
    let is_q = |s: &Symbol| s.is_time() || coords.contains(&s.to_string().as_str());
    split_rec(h, &is_p, &is_q)
}

fn split_rec(e: &Expr, is_p: &dyn Fn(&Symbol) -> bool, is_q: &dyn Fn(&Symbol) -> bool) -> Option<(Expr, Expr)> {
    let syms = e.free_symbols();
    let has_p = syms.iter().any(is_p);
    let has_q = syms.iter().any(is_q);
    match (has_p, has_q) {
        (false, _) => return Some((Expr::zero(), e.clone())),
        (true, false) => return Some((e.clone(), Expr::zero())),
        _ => {}
    }
    match e.node() {
        Node::Add(ts) => {
            let mut tt = Vec::new();
            let mut vv = Vec::new();
            for term in ts {
                let (a, b) = split_rec(term, is_p, is_q)?;
                tt.push(a);
                vv.push(b);
            }
            Some((Expr::add(tt), Expr::add(vv)))
        }
        Node::Mul(fs) => {
            // Exactly one factor may depend on the state; the rest are parameters.
            let (state, coeff): (Vec<Expr>, Vec<Expr>) =
                fs.iter().cloned().partition(|f| f.free_symbols().iter().any(|s| is_p(s) || is_q(s)));
            if state.len() != 1 {
                return None;
            }
            let (a, b) = split_rec(&state[0], is_p, is_q)?;
            let c = Expr::mul(coeff);
            Some((c.times(&a), c.times(&b)))
        }
        _ => None,
    }
}

/// A separable Hamiltonian `H = T(p) + V(q, t)` compiled as the two exactly solvable flows
/// of splitting methods: the drift `∂T/∂p` and the kick `−∂V/∂q`.
#[derive(Debug)]
pub struct SeparableHamiltonian {
    n: usize,
    drift: Tape,
    kick: Tape,
}

impl SeparableHamiltonian {
    /// Splits and compiles `h`; [`CompileError::NotSeparable`] if it does not split.
    pub fn new(
        h: &Expr,
        coords: &[&str],
        momenta: &[&str],
        params: &[(&str, f64)],
    ) -> Result<SeparableHamiltonian, CompileError> {
        SeparableHamiltonian::with_options(h, coords, momenta, params, &CompileOptions::default())
    }

    /// [`SeparableHamiltonian::new`] with explicit code generator choices.
    pub fn with_options(
        h: &Expr,
        coords: &[&str],
        momenta: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<SeparableHamiltonian, CompileError> {
        let n = coords.len();
        check_shape("momenta", n, momenta.len())?;
        let (t, v) = split_separable(h, coords, momenta).ok_or(CompileError::NotSeparable)?;
        let mut d = Differentiator::new();
        let dt: Vec<Expr> = momenta.iter().map(|p| d.diff(&t, &find_symbol(&[h], p))).collect();
        let dv: Vec<Expr> = coords.iter().map(|q| d.diff(&v, &find_symbol(&[h], q)).neg()).collect();
        let drift = Tape::compile_with_options(&dt, momenta, params, options)?;
        let mut kick_inputs: Vec<&str> = coords.to_vec();
        kick_inputs.push("t");
        let kick = Tape::compile_with_options(&dv, &kick_inputs, params, options)?;
        Ok(SeparableHamiltonian { n, drift, kick })
    }

    /// The drift tape `∂T/∂p`.
    pub fn drift_tape(&self) -> &Tape {
        &self.drift
    }

    /// The kick tape `−∂V/∂q`.
    pub fn kick_tape(&self) -> &Tape {
        &self.kick
    }
}

fn finite_or(out: &[f64], what: &str) -> Result<(), StepError> {
    if out.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(StepError::new(format!("the {what} became infinite or NaN")))
    }
}

impl Separable for SeparableHamiltonian {
    fn dof(&self) -> usize {
        self.n
    }
    fn try_drift(&self, p: &[f64], dq: &mut [f64]) -> Result<(), StepError> {
        self.drift(p, dq);
        finite_or(&dq[..self.n], "drift ∂T/∂p")
    }
    fn try_kick(&self, t: f64, q: &[f64], dp: &mut [f64]) -> Result<(), StepError> {
        self.kick(t, q, dp);
        finite_or(&dp[..self.n], "kick −∂V/∂q")
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        self.drift.eval(p, dq);
    }
    fn kick(&self, t: f64, q: &[f64], dp: &mut [f64]) {
        self.kick.eval_split(&q[..self.n], t, dp);
    }
}

impl Rhs for SeparableHamiltonian {
    fn dim(&self) -> usize {
        2 * self.n
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepError> {
        self.eval(t, y, dy);
        finite_or(&dy[..2 * self.n], "derivative of H")
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        let n = self.n;
        let (dq, dp) = dy.split_at_mut(n);
        self.drift(&y[n..2 * n], dq);
        self.kick(t, &y[..n], dp);
    }
}

/// Hamilton's equations of a Lagrangian whose Legendre transform has no closed form: the
/// state is `(q, p)`; each call solves `p = ∂L/∂q'(q, q', t)` for `q'` by Newton's method
/// (Jacobian `W = ∂²L/∂q'²`, backtracking when a step leaves the domain or does not reduce
/// the residual), then returns `q' ` and `p' = ∂L/∂q`.
#[derive(Debug)]
pub struct ImplicitLegendreRhs {
    n: usize,
    coords: Vec<String>,
    /// Outputs `∂L/∂q'` (n) then `W` (n², row-major).
    newton: Tape,
    /// Outputs `∂L/∂q` (n).
    force: Tape,
    symmetric: bool,
    error: ErrorSlot,
}

/// Newton iterations allowed for the Legendre map.
const NEWTON_MAX_ITER: usize = 60;

impl ImplicitLegendreRhs {
    /// Compiles the implicit Legendre map of `l` with coordinates `coords`, `params` bound.
    pub fn new(l: &Expr, coords: &[&str], params: &[(&str, f64)]) -> Result<ImplicitLegendreRhs, CompileError> {
        ImplicitLegendreRhs::with_options(l, coords, params, &CompileOptions::default())
    }

    /// [`ImplicitLegendreRhs::new`] with explicit code generator choices.
    pub fn with_options(
        l: &Expr,
        coords: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<ImplicitLegendreRhs, CompileError> {
        let n = coords.len();
        let coords: Vec<String> = coords.iter().map(|s| s.to_string()).collect();
        let inputs = state_inputs(&coords);
        let syms: Vec<Symbol> = inputs[..2 * n].iter().map(|s| find_symbol(&[l], s)).collect();
        let mut d = Differentiator::new();
        let p: Vec<Expr> = syms[n..].iter().map(|v| d.diff(l, v)).collect();
        let mut outs = p.clone();
        let mut w = Vec::new();
        for pi in &p {
            let row: Vec<Expr> = syms[n..].iter().map(|v| d.diff(pi, v)).collect();
            outs.extend(row.iter().cloned());
            w.push(row);
        }
        let symmetric = (0..n).all(|i| (0..i).all(|j| w[i][j] == w[j][i]));
        let force: Vec<Expr> = syms[..n].iter().map(|q| d.diff(l, q)).collect();
        let newton = Tape::compile_with_options(&outs, &as_strs(&inputs), params, options)?;
        let force = Tape::compile_with_options(&force, &as_strs(&inputs), params, options)?;
        Ok(ImplicitLegendreRhs { n, coords, newton, force, symmetric, error: ErrorSlot::default() })
    }

    fn slots_len(&self) -> usize {
        self.newton.scratch_len().max(self.force.scratch_len())
    }

    /// Residual `∂L/∂q'(q, v, t) − p` into `r` and `W` into `a` (`r | a` contiguous in `ra`);
    /// returns `max |r_i|`, NaN when anything is non-finite.
    fn residual(&self, slots: &mut [f64], v: &[f64], p: &[f64], ra: &mut [f64]) -> f64 {
        let n = self.n;
        slots[n..2 * n].copy_from_slice(&v[..n]);
        self.newton.eval_staged(slots, ra);
        let mut norm = 0.0f64;
        for i in 0..n {
            ra[i] -= p[i];
            norm = if ra[i].is_finite() { norm.max(ra[i].abs()) } else { f64::NAN };
        }
        if !ra[n..].iter().all(|x| x.is_finite()) {
            norm = f64::NAN;
        }
        norm
    }

    /// Solves `p = ∂L/∂q'(q, v, t)` for the velocities `v`; returns the Newton steps taken.
    pub fn legendre(&self, t: f64, q: &[f64], p: &[f64], v: &mut [f64]) -> Result<usize, RhsError> {
        let n = self.n;
        let state = || q[..n].iter().chain(&p[..n]).copied().collect::<Vec<f64>>();
        with_scratch(self.slots_len() + 2 * n * n + 5 * n, |s| {
            let (slots, rest) = s.split_at_mut(self.slots_len());
            let (ra, rest) = rest.split_at_mut(n + n * n);
            let (m, rest) = rest.split_at_mut(n * n);
            let (perm, rest) = rest.split_at_mut(n);
            let (tmp, rest) = rest.split_at_mut(n);
            let (trial, rest) = rest.split_at_mut(n);
            let step = &mut rest[..n];
            slots[..n].copy_from_slice(&q[..n]);
            slots[2 * n] = t;
            v[..n].fill(0.0);
            let pscale = 1.0 + p[..n].iter().fold(0.0f64, |s, x| s.max(x.abs()));
            let mut norm = self.residual(slots, v, p, ra);
            for iter in 0..NEWTON_MAX_ITER {
                if crate::cancel::interrupted() {
                    return Err(RhsError::Interrupted { t, state: state() });
                }
                if !norm.is_finite() {
                    return Err(RhsError::NonFinite { t, state: state(), what: "momentum ∂L/∂q'" });
                }
                if norm <= 4.0 * f64::EPSILON * pscale {
                    return Ok(iter);
                }
                let kind = factor(&ra[n..], m, perm, n, self.symmetric).map_err(|j| RhsError::SingularMassMatrix {
                    t,
                    state: state(),
                    velocity: velocity_name(&self.coords[j]),
                })?;
                step.copy_from_slice(&ra[..n]);
                solve(kind, m, perm, n, step, tmp);
                let vscale = 1.0 + v[..n].iter().fold(0.0f64, |s, x| s.max(x.abs()));
                let small = step.iter().all(|d| d.abs() <= 2.0 * f64::EPSILON * vscale);
                // Backtracking: halve the step until the residual is finite and smaller.
                let mut lambda = 1.0;
                loop {
                    for i in 0..n {
                        trial[i] = v[i] - lambda * step[i];
                    }
                    let new = self.residual(slots, trial, p, ra);
                    if new.is_finite() && (new < norm || lambda < 1e-3 || small) {
                        norm = new;
                        break;
                    }
                    lambda *= 0.5;
                    if lambda < 1e-12 {
                        return Err(RhsError::LegendreNewton { t, state: state(), iterations: iter, residual: norm });
                    }
                }
                v[..n].copy_from_slice(trial);
                if small {
                    return Ok(iter + 1);
                }
            }
            Err(RhsError::LegendreNewton { t, state: state(), iterations: NEWTON_MAX_ITER, residual: norm })
        })
    }

    /// Evaluates `(q', p')` at `(q, p)`, or says why it cannot.
    pub fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        let n = self.n;
        let (dq, dp) = dy.split_at_mut(n);
        self.legendre(t, &y[..n], &y[n..2 * n], dq)?;
        with_scratch(self.force.scratch_len(), |s| {
            s[..n].copy_from_slice(&y[..n]);
            s[n..2 * n].copy_from_slice(&dq[..n]);
            s[2 * n] = t;
            self.force.eval_staged(s, dp);
        });
        if dp[..n].iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(RhsError::NonFinite { t, state: y[..2 * n].to_vec(), what: "force ∂L/∂q" })
        }
    }

    /// The reason the most recent failed evaluation wrote NaN, if any.
    pub fn last_error(&self) -> Option<RhsError> {
        self.error.get()
    }
}

impl Rhs for ImplicitLegendreRhs {
    fn dim(&self) -> usize {
        2 * self.n
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepError> {
        ImplicitLegendreRhs::try_eval(self, t, y, dy).map_err(StepError::from)
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if let Err(e) = self.try_eval(t, y, dy) {
            fail_nan(&mut dy[..2 * self.n]);
            self.error.set(e);
        }
    }
}
