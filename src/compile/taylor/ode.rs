//! [`TaylorOde`]: the Taylor expansion of an ODE's solution from a compiled tape, with the
//! per-order mass-matrix solve of `W q'' = F` systems.

use std::sync::Arc;

use crate::expr::Expr;
use crate::integrate::{RhsError as StepError, StepFailure, TaylorSystem};
use crate::mechanics::{Kind, System};

use super::interp::{cholesky_solve, dot_rev};
use super::ir::KinkAt;
use super::native::Ran;
use super::native::{CholeskySolve, Expansion, NativeTaylor, TaylorNative};
use super::tiers::{NativeCache, NATIVE_AFTER_EXPANSIONS};
use super::TaylorTape;
use crate::compile::error::CompileError;
use crate::compile::jit::jit_disabled_by_env;
use crate::compile::tape::Tape;
use crate::compile::{HamiltonianRhs, LagrangianRhs};
use crate::linalg::{factor, solve, Factor};

/// Why a Taylor expansion has no value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TaylorError {
    /// `|x|` evaluated where `x = 0` but `x` is not identically zero: not differentiable.
    #[error(
        "abs(…) is not differentiable at its kink: its argument is 0 at t = {t} and changes there; state {state:?}"
    )]
    AbsKink { t: f64, state: Vec<f64> },
    /// A coefficient is infinite or NaN (a singularity within reach, a domain error).
    #[error("non-finite Taylor coefficient of order {order} at t = {t}; state {state:?}")]
    NonFinite { t: f64, order: usize, state: Vec<f64> },
    /// `W q'' = F` with a singular `W` at the expansion point.
    #[error(
        "the mass matrix is singular at t = {t} (no pivot for the velocity of coordinate {index}); state {state:?}"
    )]
    SingularMassMatrix { t: f64, index: usize, state: Vec<f64> },
    /// The augmented matrix of a constrained system is singular at the expansion point: the
    /// constraints are redundant there, or `W` is singular on their tangent space.
    #[error(
        "the augmented matrix [W Φᵀ; Φ 0] is singular at t = {t} (no pivot for the row of constraint {constraint}: the constraints are redundant there); state {state:?}"
    )]
    SingularAugmented { t: f64, constraint: usize, state: Vec<f64> },
}
/// Where the derivative of a state component comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Derivative {
    /// Tape output `j`.
    Output(usize),
    /// State component `i` (`q' = v` of a second-order system).
    State(usize),
    /// Acceleration `i` of the solve `W a = F` (see [`TaylorOde::second_order`]).
    Solve(usize),
}
/// `W a = F` solved per order: the tape outputs of `W` (row-major) and `F`.
#[derive(Clone, Debug)]
pub(super) struct MassSolve {
    pub(super) n: usize,
    pub(super) w: Vec<usize>,
    pub(super) f: Vec<usize>,
    pub(super) symmetric: bool,
    /// Per row `i` of `W`, the columns `l` whose entry varies, with its coefficient row: the
    /// only ones with orders ≥ 1 (a constant entry, such as the `2` and `1` of the double
    /// pendulum's `W`, adds nothing to `Σ_{j≥1} W_j a_{k−j}`).
    pub(super) varying: Vec<Vec<(usize, usize)>>,
}
/// The Taylor expansion of the solution of `y' = f(t, y)` from a compiled tape: the state is
/// the first [`TaylorOde::dim`] inputs, the time (if the tape reads it) the input after them.
#[derive(Clone, Debug)]
pub struct TaylorOde {
    pub(super) tape: TaylorTape,
    /// The plain tape, for order-0 evaluation as a right-hand side.
    pub(super) plain: Tape,
    pub(super) dim: usize,
    pub(super) time: Option<usize>,
    pub(super) derivs: Vec<Derivative>,
    pub(super) solve: Option<MassSolve>,
    pub(super) native: Arc<NativeCache>,
}

impl TaylorOde {
    /// `y' = f(y, t)` with `f_i` tape output `i`; the tape's inputs are `y…, t` (the time last,
    /// as every compiled right-hand side has it) or `y…` alone.
    pub fn first_order(tape: &Tape) -> TaylorOde {
        let dim = tape.n_outputs();
        let time = (tape.n_inputs() > dim).then_some(dim);
        TaylorOde {
            tape: TaylorTape::new(tape),
            plain: tape.clone(),
            dim,
            time,
            derivs: (0..dim).map(Derivative::Output).collect(),
            solve: None,
            native: NativeCache::auto(),
        }
    }

    /// `W q'' = F` in `y = (q, q')` with `n` degrees of freedom, from a tape with inputs
    /// `q…, q'…, t` and outputs `W` (row-major, `n²`) then `F` (`n`). Per order `k` the
    /// accelerations solve `W₀ a_k = F_k − Σ_{j=1}^{k} W_j a_{k−j}` with one factorisation of
    /// `W₀` (Cholesky when `W` is symmetric and positive definite, else LU with pivoting).
    pub fn second_order(tape: &Tape, n: usize, symmetric: bool) -> TaylorOde {
        TaylorOde::second_order_solving(tape, n, n, symmetric)
    }

    /// [`TaylorOde::second_order`] whose accelerations are the first `n` unknowns of a larger
    /// linear system of size `big` (outputs: its matrix, row-major, then its right-hand side):
    /// the augmented system `[W Φᵀ; Φ 0] (q'', −λ) = (F, c)` of a constrained system, whose
    /// other unknowns are the multipliers.
    pub fn second_order_solving(tape: &Tape, n: usize, big: usize, symmetric: bool) -> TaylorOde {
        let mut derivs: Vec<Derivative> = (0..n).map(|i| Derivative::State(n + i)).collect();
        derivs.extend((0..n).map(Derivative::Solve));
        let taylor = TaylorTape::new(tape);
        let varying = (0..big)
            .map(|i| {
                (0..big)
                    .map(|l| (l, taylor.output_row(i * big + l)))
                    .filter(|&(_, r)| taylor.row_constant(r as u32).is_none())
                    .collect()
            })
            .collect();
        let solve = MassSolve {
            n: big,
            w: (0..big * big).collect(),
            f: (big * big..big * big + big).collect(),
            symmetric,
            varying,
        };
        TaylorOde {
            tape: taylor,
            plain: tape.clone(),
            dim: 2 * n,
            time: (tape.n_inputs() > 2 * n).then_some(2 * n),
            derivs,
            solve: Some(solve),
            native: NativeCache::auto(),
        }
    }

    /// The dimension of the state.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The Taylor form of the tape.
    pub fn taylor_tape(&self) -> &TaylorTape {
        &self.tape
    }

    pub(super) fn solve_len(&self, stride: usize) -> usize {
        match &self.solve {
            // accelerations (n · stride), factor (n²), perm (n), tmp (n), rhs (n), W₀ (n²)
            Some(m) => m.n * stride + 2 * m.n * m.n + 3 * m.n,
            None => 0,
        }
    }

    /// Scratch values [`TaylorOde::expand`] needs for `order`.
    pub fn scratch_len(&self, order: usize) -> usize {
        let stride = order + 1;
        let rows = self.tape.n_rows() + self.solve.as_ref().map_or(0, |m| m.n);
        self.mirror_at(stride) + rows * stride
    }

    /// Where the whole native expansion keeps the mirror images of its rows (after the rows
    /// and the solve's scratch; see `native::TaylorEmitter::pair`).
    pub(super) fn mirror_at(&self, stride: usize) -> usize {
        self.tape.n_rows() * stride + self.solve_len(stride)
    }

    /// Fills `coeffs[i · (order + 1) + k]` with the normalised Taylor coefficients
    /// `y_i⁽ᵏ⁾(t)/k!`, `k = 0..=order`, of the solution through `(t, y)`, and refuses
    /// non-finite ones ([`TaylorError::NonFinite`], naming the order). The integrator calls
    /// [`TaylorOde::expand_in_place`] instead, which neither copies nor scans.
    pub fn expand(
        &self,
        t: f64,
        y: &[f64],
        order: usize,
        scratch: &mut [f64],
        coeffs: &mut [f64],
    ) -> Result<(), TaylorError> {
        let s = order + 1;
        let n = self.dim * s;
        assert!(coeffs.len() >= n, "coefficient buffer too short");
        self.expand_in_place(t, y, order, scratch)?;
        coeffs[..n].copy_from_slice(&scratch[..n]);
        match coeffs[..n].iter().position(|x| !x.is_finite()) {
            Some(bad) => Err(self.non_finite_at(t, y, order, bad)),
            None => Ok(()),
        }
    }

    /// The error for the non-finite coefficient `coeffs[at]` of the expansion at `(t, y)`.
    fn non_finite_at(&self, t: f64, y: &[f64], order: usize, at: usize) -> TaylorError {
        TaylorError::NonFinite { t, order: at % (order + 1), state: y[..self.dim].to_vec() }
    }

    /// [`TaylorOde::expand`] without the copy and the check: the coefficients are left in
    /// `scratch[i · (order + 1) + k]` (the state's rows come first), and may be non-finite.
    /// The Taylor integrator finds non-finite ones from its step's result instead, at no
    /// cost to good steps (`integrate::TaylorSystem::taylor_coefficients`).
    pub fn expand_in_place(&self, t: f64, y: &[f64], order: usize, scratch: &mut [f64]) -> Result<(), TaylorError> {
        self.expand_into(t, y, order, scratch, false)
    }

    /// [`TaylorOde::expand_in_place`]; `prepared`: `scratch` is what an expansion of this
    /// system at this order left (`TaylorSystem::taylor_coefficients_again`), so its constant
    /// rows and the time's orders past 1 already hold what `TaylorTape::init` and the time
    /// row write. Nothing else writes them: the recurrences write only the rows of their
    /// operations and the solve's scratch. Filling them was a `memset` call per constant row
    /// on every step, 3 % of a double-pendulum step at tol 1e-6.
    fn expand_into(
        &self,
        t: f64,
        y: &[f64],
        order: usize,
        scratch: &mut [f64],
        prepared: bool,
    ) -> Result<(), TaylorError> {
        let s = order + 1;
        let dim = self.dim;
        assert!(y.len() >= dim, "state too short");
        let rows = self.tape.n_rows() * s;
        let len = self.scratch_len(order);
        let kink = |_| TaylorError::AbsKink { t, state: y[..dim].to_vec() };
        let native = self.native_tiered(order);
        {
            let c = &mut scratch[..rows];
            if !prepared {
                self.tape.init(c, s);
            }
            for i in 0..dim {
                c[i * s] = y[i];
            }
            if let Some(ti) = self.time {
                let r = &mut c[ti * s..(ti + 1) * s];
                if !prepared {
                    r.fill(0.0);
                    if s > 1 {
                        r[1] = 1.0;
                    }
                }
                r[0] = t;
            }
        }
        if let Some(code) = native.filter(|code| code.is_whole()) {
            match code.run_expansion(&mut scratch[..len]) {
                Ran::Done => return Ok(()),
                Ran::Kink => return Err(kink(KinkAt)),
                // `W₀` not finite or not positive definite: the interpreter redoes it all, and
                // factors by LU or reports the error.
                Ran::Redo => {}
            }
        }
        let native = native.filter(|code| !code.is_whole());
        let (c, rest) = scratch[..len].split_at_mut(rows);
        let mut kind = Factor::Cholesky;
        for k in 0..order {
            match native {
                Some(code) if k >= 1 => code.run_order(c, k).map_err(kink)?,
                _ => self.tape.run_order(c, s, k).map_err(kink)?,
            }
            if let Some(m) = &self.solve {
                let n = m.n;
                // The whole native expansion reads `acc` and `fm` at these offsets (the
                // `CholeskySolve` of `compile_native`).
                let (acc, rest) = rest.split_at_mut(n * s);
                let (fm, rest) = rest.split_at_mut(n * n);
                let (perm, rest) = rest.split_at_mut(n);
                let (tmp, rest) = rest.split_at_mut(n);
                let (rhs, rest) = rest.split_at_mut(n);
                let w0 = &mut rest[..n * n];
                let out = |j: usize| self.tape.output_row(j);
                if k == 0 {
                    for (e, &o) in w0.iter_mut().zip(&m.w) {
                        *e = c[out(o) * s];
                    }
                    if !w0.iter().all(|x| x.is_finite()) {
                        return Err(TaylorError::NonFinite { t, order: 0, state: y[..dim].to_vec() });
                    }
                    let dof = dim / 2;
                    kind = factor(w0, fm, perm, n, m.symmetric).map_err(|index| match index.checked_sub(dof) {
                        Some(j) => TaylorError::SingularAugmented { t, constraint: j + 1, state: y[..dim].to_vec() },
                        None => TaylorError::SingularMassMatrix { t, index, state: y[..dim].to_vec() },
                    })?;
                    if matches!(kind, Factor::Cholesky) {
                        // `perm` is LU's; a Cholesky factor keeps its diagonal's reciprocals there.
                        for i in 0..n {
                            perm[i] = 1.0 / fm[i * n + i];
                        }
                    }
                }
                for i in 0..n {
                    let mut v = c[out(m.f[i]) * s + k];
                    for &(l, r) in &m.varying[i] {
                        // Σ_{j=1}^{k} W_il,j a_l,k−j
                        v -= dot_rev(&c[r * s + 1..=r * s + k], &acc[l * s..l * s + k], true);
                    }
                    rhs[i] = v;
                }
                match kind {
                    Factor::Cholesky => cholesky_solve(fm, perm, n, rhs),
                    Factor::Lu => solve(kind, fm, perm, n, rhs, tmp),
                }
                for i in 0..n {
                    acc[i * s + k] = rhs[i];
                }
            }
            let inv = 1.0 / (k + 1) as f64;
            for i in 0..dim {
                let v = match self.derivs[i] {
                    Derivative::Output(j) => c[self.tape.output_row(j) * s + k],
                    Derivative::State(j) => c[j * s + k],
                    Derivative::Solve(j) => rest[j * s + k],
                };
                c[i * s + k + 1] = v * inv;
            }
        }
        Ok(())
    }

    /// The right-hand side `f(t, y)` at order 0 (the plain tape and, for `W q'' = F`, one
    /// solve): the first-order coefficients times one.
    pub fn eval_rate(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), TaylorError> {
        let mut scratch = vec![0.0; self.scratch_len(1)];
        let mut coeffs = vec![0.0; 2 * self.dim];
        self.expand(t, y, 1, &mut scratch, &mut coeffs)?;
        for i in 0..self.dim {
            dy[i] = coeffs[2 * i + 1];
        }
        Ok(())
    }

    /// The plain tape.
    pub fn tape(&self) -> &Tape {
        &self.plain
    }
}

impl TaylorSystem for TaylorOde {
    fn dim(&self) -> usize {
        self.dim
    }
    fn scratch_len(&self, order: usize) -> usize {
        TaylorOde::scratch_len(self, order)
    }
    fn taylor_coefficients(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), StepError> {
        self.expand_in_place(t, y, order, buf).map_err(|e| StepError::new(e.to_string()))
    }
    fn taylor_coefficients_again(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), StepError> {
        self.expand_into(t, y, order, buf, true).map_err(|e| StepError::new(e.to_string()))
    }
    /// Names the coefficient's order ([`TaylorError::NonFinite`]).
    fn non_finite(&self, t: f64, y: &[f64], order: usize, at: usize) -> StepFailure {
        StepError::new(self.non_finite_at(t, y, order, at).to_string()).into()
    }
    fn check_step(&self, scratch: &[f64], order: usize, h: f64) -> Result<(), StepError> {
        // Tape values are expanded to `order − 1` (the state's order-`order` terms come from
        // them), so their polynomial stops there.
        if self.tape.kink_within(scratch, order + 1, order - 1, h) {
            return Err(StepError::new(format!(
                "the argument of abs(…) changes sign within the step of size {h:e}: the right-hand side has a kink there, and the Taylor method needs it smooth"
            )));
        }
        Ok(())
    }
}
impl TaylorOde {
    /// The Taylor form of a compiled `W q'' = F` system (state `(q, q')`).
    pub fn from_lagrangian(rhs: &LagrangianRhs) -> TaylorOde {
        TaylorOde::second_order(rhs.tape(), rhs.dof(), rhs.is_symmetric())
    }

    /// The Taylor form of compiled Hamilton's equations (state `(q, p)`).
    pub fn from_hamiltonian(rhs: &HamiltonianRhs) -> TaylorOde {
        TaylorOde::first_order(rhs.tape())
    }

    /// `y' = f(y, t)` compiled from expressions: `state` names the components of `y` (plain
    /// spelling), `t` is the time, `params` are bound.
    pub fn from_exprs(f: &[Expr], state: &[&str], params: &[(&str, f64)]) -> Result<TaylorOde, CompileError> {
        if f.len() != state.len() {
            return Err(CompileError::Shape { what: "right-hand sides", expected: state.len(), got: f.len() });
        }
        let mut inputs: Vec<&str> = state.to_vec();
        inputs.push("t");
        let tape = Tape::compile(f, &inputs, params)?;
        Ok(TaylorOde::first_order(&tape))
    }
}
impl System {
    /// The Taylor form of the system's equations of motion: `W q'' = F` in `(q, q')` for a
    /// Lagrangian system, Hamilton's equations in `(q, p)` for a Hamiltonian one.
    ///
    /// For a Lagrangian system only the tape of `W` and `F` is built, and left interpreted:
    /// the Taylor tape evaluates every order itself, so the right-hand side's native code and
    /// unrolled Cholesky solve, which
    /// [`System::compile_rhs`] builds for the other methods, would be compiled for nothing —
    /// for the 10-link pendulum that was most of the cold start.
    pub fn compile_taylor(&self) -> Result<TaylorOde, CompileError> {
        match self.kind() {
            Kind::Hamiltonian(_) => Ok(TaylorOde::from_hamiltonian(&self.compile_hamiltonian()?)),
            _ => {
                if !self.constraints().is_empty() {
                    return Err(CompileError::Unsupported {
                        what: "holonomic constraints in compile_taylor (simulate::compile_system with MethodId::Taylor runs them, with projection onto the constraints)",
                    });
                }
                self.refuse_velocity_constraints("the Taylor method").map_err(CompileError::Mechanics)?;
                let (w, f) = self.mass_matrix_split().map_err(CompileError::Mechanics)?;
                let n = w.len();
                let mut outputs: Vec<Expr> = w.iter().flatten().cloned().collect();
                outputs.extend(f.iter().cloned());
                let coords: Vec<String> = self.coordinates().iter().map(|s| s.to_string()).collect();
                let inputs = crate::compile::rhs::state_inputs(&coords);
                let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
                let params: Vec<(String, f64)> = self.param_values().iter().map(|(k, v)| (k.to_string(), *v)).collect();
                let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
                let options = crate::compile::CompileOptions::default().with_native(false);
                let tape = Tape::compile_with_options(&outputs, &inputs, &params, &options)?;
                let symmetric = (0..n).all(|i| (0..i).all(|j| w[i][j] == w[j][i]));
                Ok(TaylorOde::second_order(&tape, n, symmetric))
            }
        }
    }
}

impl TaylorOde {
    /// Turns the native Taylor code on early or off. By default each order's code is
    /// compiled when a run has been long enough for it to repay its compile time: compact
    /// code after [`COMPACT_AFTER_EXPANSIONS`](super::tiers::COMPACT_AFTER_EXPANSIONS) expansions, then unrolled code after
    /// [`AUTO_NATIVE_AFTER_EXPANSIONS`](super::tiers::AUTO_NATIVE_AFTER_EXPANSIONS), or for a tape past [`COMPACT_ABOVE_TERMS`](super::tiers::COMPACT_ABOVE_TERMS) after
    /// [`UNROLL_AFTER_EXPANSIONS`](super::tiers::UNROLL_AFTER_EXPANSIONS). On: the fastest code after
    /// [`NATIVE_AFTER_EXPANSIONS`](super::tiers::NATIVE_AFTER_EXPANSIONS); off, never (nor ever when
    /// [`crate::compile::NO_JIT_ENV`] is set). Results are the same bits whichever code runs.
    pub fn with_native(mut self, on: bool) -> TaylorOde {
        let n = NATIVE_AFTER_EXPANSIONS;
        self.native = NativeCache::new(on, n, n, n);
        self
    }

    /// The native code for expansions of `order`, compiled now if it is not yet (`None`:
    /// native code is off, the host has no JIT, or the tape is too large for unrolled and for
    /// compact code).
    ///
    /// A first-order system, and a `W q'' = F` system with a symmetric `W`, get the whole
    /// expansion as one function (orders, the Cholesky solve and the steps from each order of
    /// the right-hand side to the next of the state, see `native.rs`); a non-symmetric `W`,
    /// whose LU solve stays in Rust, one function per order; a tape too large to unroll at
    /// this order, compact code called once per order.
    pub fn native_for(&self, order: usize) -> Option<TaylorNative> {
        self.native.final_code(order, || self.compile_native(order))
    }

    /// The native code compiled so far for expansions of `order` (the final code if it
    /// exists, else compact code), compiling nothing.
    pub fn native_compiled(&self, order: usize) -> Option<TaylorNative> {
        self.native.compiled(order)
    }

    pub(super) fn compile_native(&self, order: usize) -> Option<TaylorNative> {
        let stride = order + 1;
        // An LU-factored (non-symmetric) `W` keeps its solve in Rust, between per-order code.
        if self.solve.as_ref().is_some_and(|m| !m.symmetric) {
            return self.tape.compile_native(stride, order - 1);
        }
        if jit_disabled_by_env() {
            return None;
        }
        let expansion = self.expansion(order);
        match NativeTaylor::compile_expansion(&self.tape, stride, order - 1, &expansion) {
            Some(code) => Some(TaylorNative(Arc::new(code))),
            // Too large to unroll: compact code, one call per order (none past
            // `MAX_COMPACT_RECURRENCES`).
            None => self.tape.compile_native(stride, order - 1),
        }
    }

    /// The code an expansion of `order` runs on, compiled in the tiers [`TaylorOde::with_native`]
    /// describes: the interpreter (`None`), then compact code, then the final code
    /// ([`TaylorOde::native_for`]).
    pub(super) fn native_tiered(&self, order: usize) -> Option<&TaylorNative> {
        self.native.tiered(&self.tape, order, || self.compile_native(order))
    }

    /// What a whole native expansion of `order` does between orders, in `expand`'s layout.
    pub(super) fn expansion(&self, order: usize) -> Expansion {
        let stride = order + 1;
        let n_rows = self.tape.n_rows();
        let glue = (0..self.dim)
            .map(|i| {
                let src = match self.derivs[i] {
                    Derivative::Output(j) => self.tape.output_row(j),
                    Derivative::State(j) => j,
                    Derivative::Solve(j) => n_rows + j,
                };
                (i as u32, src as u32)
            })
            .collect();
        // The accelerations are the `n` rows after the tape's, then comes the factor of `W₀`
        // (the layout `expand` splits its scratch into).
        let solve = self.solve.as_ref().map(|m| CholeskySolve {
            n: m.n,
            f_rows: m.f.iter().map(|&o| self.tape.output_row(o) as u32).collect(),
            varying: m.varying.iter().map(|v| v.iter().map(|&(l, r)| (l, r as u32)).collect()).collect(),
            acc_row: n_rows as u32,
            factor_at: (n_rows + m.n) * stride,
            w_rows: m.w.iter().map(|&o| self.tape.output_row(o) as u32).collect(),
        });
        Expansion { glue, solve, mirror_at: self.mirror_at(stride), len: self.scratch_len(order) }
    }
}
