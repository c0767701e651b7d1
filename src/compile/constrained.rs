//! Holonomic constraints `f_j(q, t) = 0` as a compiled right-hand side: the index-reduced
//! augmented system (PHYSICS.md §2, (1.25)–(1.29))
//!
//! ```text
//! [ W  Φᵀ ] [ q'' ]   [ F ]
//! [ Φ  0  ] [ −λ  ] = [ c ]        Φ_ji = ∂f_j/∂q_i,   Φ q'' = c  ⇔  d²f_j/dt² = 0,
//! ```
//!
//! solved at every evaluation, with two ways of holding the solution on the constraint
//! manifold, which the exact equations keep but rounding and truncation do not:
//!
//! * **Baumgarte stabilisation**: the second row becomes `d²f/dt² + 2α ḟ + β² f = 0`, which
//!   damps a drift instead of letting it grow (no change to the integrator);
//! * **projection**: after every accepted step the state is moved back onto `f = 0` (Newton
//!   on the positions, along `Φᵀ`) and onto `ḟ = Φ q' + ∂f/∂t = 0` (the velocities), by the
//!   [`Projected`] method wrapper.
//!
//! `W`, `F`, `Φ`, `c` and the values `f`, `∂f/∂t` are one tape, so what they share is computed
//! once; the augmented matrix is symmetric but indefinite, so it is factorised by LU with
//! partial pivoting on the per-thread scratch (no allocation per call). A pivot that vanishes
//! means the constraints are redundant or the mass matrix is singular on their tangent space:
//! [`RhsError::SingularAugmented`] names the constraint whose row has no pivot.
//!
//! Velocity constraints `g_j = a_j(q, t)·q' + b_j(q, t) = 0` (nonholonomic, §1.5) enter the
//! same matrix: their rows of `Φ` are `a_j = ∂g_j/∂q'` (Lagrange–d'Alembert: the constraint
//! forces are `Σ μ_j a_j`) and their `c_j = −dg_j/dt|_{q''=0}` (one derivative, not two).
//! Their drift lives in the velocities alone: Baumgarte damps it by `dg/dt + 2α g = 0`, and
//! projection moves `q'` onto `g = 0` (exact in one step, `g` being linear in `q'`).

// The augmented matrix is assembled with explicit indices, as it is written.
#![allow(clippy::needless_range_loop)]

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::integrate::{Jacobian, Method, MethodInfo, Rhs, RhsError as StepError, StepFailure};

use super::error::CompileError;
use super::rhs::{state_inputs, RhsError};
use super::tape::{CompileOptions, Tape};
use super::taylor::TaylorOde;
use crate::linalg::{factor, solve};

/// How a constrained right-hand side keeps the solution on the constraint manifold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stabilization {
    /// The index-reduced equations alone (`d²f/dt² = 0`): the drift grows with time.
    None,
    /// `d²f/dt² + 2α ḟ + β² f = 0`, with `α = β = rate`.
    Baumgarte {
        /// The damping rate (1/time); about the inverse of a few steps is a common choice.
        rate: f64,
    },
    /// Projection onto `f = 0` and `ḟ = 0` after every step ([`Projected`]).
    Projection,
}

/// `W q'' − Φᵀ λ = F`, `Φ q'' = c` as a first-order system in `y = (q, q')`.
#[derive(Debug)]
pub struct ConstrainedRhs {
    n: usize,
    m: usize,
    /// The first `mh` of the `m` constraints are holonomic, the rest velocity constraints.
    mh: usize,
    coords: Vec<String>,
    /// Outputs: `W` (n·n, row-major), `F` (n), `Φ` (m·n), `c` (m), `f` (m), `∂f/∂t` (m);
    /// for a velocity constraint the `f` slot holds `g` and the `∂f/∂t` slot 0.
    tape: Tape,
    /// Outputs: `f` (m), `Φ` (m·n), `∂f/∂t` (m): what a projection needs (same slots).
    manifold: Tape,
    stabilization: Stabilization,
}

/// The constraint functions differentiated for the augmented system: `Φ` (one row per
/// constraint), `c = −d²f/dt²|_{q''=0}` and `∂f/∂t`.
fn constraint_parts(constraints: &[Expr], coords: &[Symbol]) -> (Vec<Vec<Expr>>, Vec<Expr>, Vec<Expr>) {
    let mut d = Differentiator::new();
    let names: std::collections::BTreeSet<String> = coords.iter().map(|q| q.name().to_string()).collect();
    let zero_acc: std::collections::HashMap<Symbol, Expr> =
        coords.iter().map(|q| (Symbol::new(q.name()).with_primes(2), Expr::zero())).collect();
    let t = Symbol::new("t");
    let mut phi = Vec::new();
    let mut c = Vec::new();
    let mut ft = Vec::new();
    for f in constraints {
        phi.push(coords.iter().map(|q| d.diff(f, q)).collect());
        let d1 = d.dt(f, &names);
        let d2 = d.dt(&d1, &names);
        c.push(d2.subs(&zero_acc).neg());
        ft.push(d.diff(f, &t));
    }
    (phi, c, ft)
}

/// [`constraint_parts`] for velocity constraints `g_j = 0`, each linear in the velocities:
/// `Φ_ji = ∂g_j/∂q_i'`, `c_j = −dg_j/dt|_{q''=0}`, and 0 in the `∂f/∂t` slot.
fn velocity_constraint_parts(constraints: &[Expr], coords: &[Symbol]) -> (Vec<Vec<Expr>>, Vec<Expr>, Vec<Expr>) {
    let mut d = Differentiator::new();
    let names: std::collections::BTreeSet<String> = coords.iter().map(|q| q.name().to_string()).collect();
    let zero_acc: std::collections::HashMap<Symbol, Expr> =
        coords.iter().map(|q| (Symbol::new(q.name()).with_primes(2), Expr::zero())).collect();
    let mut phi = Vec::new();
    let mut c = Vec::new();
    for g in constraints {
        phi.push(coords.iter().map(|q| d.diff(g, &q.prime())).collect());
        c.push(d.dt(g, &names).subs(&zero_acc).neg());
    }
    (phi, c, vec![Expr::zero(); constraints.len()])
}

/// `Φ` (one row per constraint), `c` and `∂f/∂t`.
type Parts = (Vec<Vec<Expr>>, Vec<Expr>, Vec<Expr>);

/// The shape check of `W q'' = F`, then the holonomic constraints' parts followed by the
/// velocity constraints': the rows of the augmented system, in order.
fn all_parts(
    w: &[Vec<Expr>],
    f: &[Expr],
    holonomic: &[Expr],
    velocity: &[Expr],
    coords: &[Symbol],
) -> Result<Parts, CompileError> {
    let n = coords.len();
    if f.len() != n || w.len() != n || w.iter().any(|r| r.len() != n) {
        return Err(CompileError::Shape { what: "mass matrix and forces", expected: n, got: f.len() });
    }
    let (mut phi, mut c, mut ft) = constraint_parts(holonomic, coords);
    let (vphi, vc, vft) = velocity_constraint_parts(velocity, coords);
    phi.extend(vphi);
    c.extend(vc);
    ft.extend(vft);
    Ok((phi, c, ft))
}

impl ConstrainedRhs {
    /// Compiles the augmented system of `W q'' = F` (from the mechanics stage, forces
    /// included) and the constraints `f_j = 0` for the coordinates `coords`, with `params`
    /// bound. Coordinates are matched by name, so sign assumptions do not matter.
    pub fn new(
        w: &[Vec<Expr>],
        f: &[Expr],
        constraints: &[Expr],
        coords: &[Symbol],
        params: &[(&str, f64)],
        stabilization: Stabilization,
    ) -> Result<ConstrainedRhs, CompileError> {
        ConstrainedRhs::with_velocity_constraints(w, f, constraints, &[], coords, params, stabilization)
    }

    /// [`ConstrainedRhs::new`] with velocity constraints `g_j = 0` (each linear in the
    /// velocities, as [`crate::mechanics::System::with_velocity_constraint`] checks) besides
    /// the holonomic ones: their multipliers follow the holonomic ones.
    pub fn with_velocity_constraints(
        w: &[Vec<Expr>],
        f: &[Expr],
        holonomic: &[Expr],
        velocity: &[Expr],
        coords: &[Symbol],
        params: &[(&str, f64)],
        stabilization: Stabilization,
    ) -> Result<ConstrainedRhs, CompileError> {
        let n = coords.len();
        let mh = holonomic.len();
        let m = mh + velocity.len();
        let (phi, c, ft) = all_parts(w, f, holonomic, velocity, coords)?;
        let constraints: Vec<Expr> = holonomic.iter().chain(velocity).cloned().collect();
        let constraints = &constraints[..];
        let names: Vec<String> = coords.iter().map(|q| q.name().to_string()).collect();
        let inputs = state_inputs(&names);
        let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        let mut outputs: Vec<Expr> = w.iter().flatten().cloned().collect();
        outputs.extend(f.iter().cloned());
        outputs.extend(phi.iter().flatten().cloned());
        outputs.extend(c.iter().cloned());
        outputs.extend(constraints.iter().cloned());
        outputs.extend(ft.iter().cloned());
        let options = CompileOptions::default();
        let tape = Tape::compile_with_options(&outputs, &inputs, params, &options)?;
        let mut man: Vec<Expr> = constraints.to_vec();
        man.extend(phi.iter().flatten().cloned());
        man.extend(ft.iter().cloned());
        let manifold = Tape::compile_with_options(&man, &inputs, params, &options)?;
        Ok(ConstrainedRhs { n, m, mh, coords: names, tape, manifold, stabilization })
    }

    /// The Taylor form of the same augmented system, for the Taylor method: a tape of the
    /// matrix `[W Φᵀ; Φ 0]` and the right-hand side `(F, c)` (with Baumgarte's terms when
    /// that is the stabilisation), expanded order by order with one LU factorisation of the
    /// matrix per expansion ([`TaylorOde::second_order_solving`]). Projection, when that is the
    /// stabilisation, wraps the method as for any other ([`Projected`]).
    pub fn taylor(
        w: &[Vec<Expr>],
        f: &[Expr],
        holonomic: &[Expr],
        velocity: &[Expr],
        coords: &[Symbol],
        params: &[(&str, f64)],
        stabilization: Stabilization,
    ) -> Result<TaylorOde, CompileError> {
        let n = coords.len();
        let (phi, mut c, ft) = all_parts(w, f, holonomic, velocity, coords)?;
        let (mh, m) = (holonomic.len(), holonomic.len() + velocity.len());
        let big = n + m;
        // The rate is bound as a parameter of the tape, under a name no user can write.
        const RATE: &str = "baumgarte__rate";
        let mut params = params.to_vec();
        if let Stabilization::Baumgarte { rate } = stabilization {
            let rate_expr = Expr::var(RATE);
            params.push((RATE, rate));
            let residuals: Vec<&Expr> = holonomic.iter().chain(velocity).collect();
            for j in 0..m {
                let correction = if j >= mh {
                    // dg/dt + 2α g = 0.
                    Expr::mul([Expr::int(2), rate_expr.clone(), residuals[j].clone()])
                } else {
                    // d²f/dt² + 2α ḟ + α² f = 0, ḟ = Φ q' + ∂f/∂t.
                    let fdot = coords
                        .iter()
                        .enumerate()
                        .fold(ft[j].clone(), |acc, (i, q)| acc.plus(&phi[j][i].times(&Expr::sym(q.prime()))));
                    Expr::mul([Expr::int(2), rate_expr.clone(), fdot]).plus(&Expr::mul([
                        rate_expr.clone(),
                        rate_expr.clone(),
                        residuals[j].clone(),
                    ]))
                };
                c[j] = c[j].minus(&correction);
            }
        }
        let mut outputs = Vec::with_capacity(big * big + big);
        for i in 0..n {
            outputs.extend(w[i].iter().cloned());
            outputs.extend((0..m).map(|j| phi[j][i].clone()));
        }
        for j in 0..m {
            outputs.extend(phi[j].iter().cloned());
            outputs.extend((0..m).map(|_| Expr::zero()));
        }
        outputs.extend(f.iter().cloned());
        outputs.extend(c);
        let names: Vec<String> = coords.iter().map(|q| q.name().to_string()).collect();
        let inputs = state_inputs(&names);
        let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        let options = CompileOptions::default().with_native(false);
        let tape = Tape::compile_with_options(&outputs, &inputs, &params, &options)?;
        Ok(TaylorOde::second_order_solving(&tape, n, big, false))
    }

    /// Degrees of freedom (coordinates).
    pub fn dof(&self) -> usize {
        self.n
    }

    /// Number of constraints (and multipliers).
    pub fn constraints(&self) -> usize {
        self.m
    }

    /// How many of them are holonomic (they come first; the rest are velocity constraints).
    pub fn holonomic(&self) -> usize {
        self.mh
    }

    /// The stabilisation chosen at compile time.
    pub fn stabilization(&self) -> Stabilization {
        self.stabilization
    }

    /// Evaluates the accelerations into `dy[n..2n]` (and `q'` into `dy[..n]`) and the
    /// multipliers `λ` into `lambda` (when given).
    fn solve_at(&self, t: f64, y: &[f64], dy: &mut [f64], lambda: Option<&mut [f64]>) -> Result<(), RhsError> {
        let (n, m) = (self.n, self.m);
        let big = n + m;
        let nout = n * n + n + m * n + 3 * m;
        assert!(y.len() >= 2 * n && dy.len() >= 2 * n, "state or derivative shorter than 2n");
        let state = || y[..2 * n].to_vec();
        self.tape.with_slots(nout + 2 * big * big + 3 * big, |slots, rest| {
            slots[..2 * n].copy_from_slice(&y[..2 * n]);
            slots[2 * n] = t;
            let (out, rest) = rest.split_at_mut(nout);
            self.tape.eval_staged(slots, out);
            let (a, rest) = rest.split_at_mut(big * big);
            let (lu, rest) = rest.split_at_mut(big * big);
            let (perm, rest) = rest.split_at_mut(big);
            let (x, tmp) = rest.split_at_mut(big);
            let (w, rest_out) = out.split_at(n * n);
            let (fv, rest_out) = rest_out.split_at(n);
            let (phi, rest_out) = rest_out.split_at(m * n);
            let (c, rest_out) = rest_out.split_at(m);
            let (fval, ft) = rest_out.split_at(m);
            if !out.iter().all(|v| v.is_finite()) {
                return Err(RhsError::NonFinite { t, state: state(), what: "constrained system" });
            }
            for i in 0..n {
                a[i * big..i * big + n].copy_from_slice(&w[i * n..(i + 1) * n]);
                for j in 0..m {
                    a[i * big + n + j] = phi[j * n + i];
                }
            }
            for j in 0..m {
                a[(n + j) * big..(n + j) * big + n].copy_from_slice(&phi[j * n..(j + 1) * n]);
                a[(n + j) * big + n..(n + j + 1) * big].fill(0.0);
            }
            x[..n].copy_from_slice(fv);
            for j in 0..m {
                let mut cj = c[j];
                if let (Stabilization::Baumgarte { rate }, true) = (self.stabilization, j >= self.mh) {
                    // A velocity constraint's residual is `g` itself: dg/dt + 2α g = 0.
                    cj -= 2.0 * rate * fval[j];
                } else if let Stabilization::Baumgarte { rate } = self.stabilization {
                    let fdot: f64 = (0..n).map(|i| phi[j * n + i] * y[n + i]).sum::<f64>() + ft[j];
                    cj -= 2.0 * rate * fdot + rate * rate * fval[j];
                }
                x[n + j] = cj;
            }
            let kind = factor(a, lu, perm, big, false).map_err(|col| {
                if col >= n {
                    RhsError::SingularAugmented { t, state: state(), constraint: col - n + 1 }
                } else {
                    RhsError::SingularMassMatrix {
                        t,
                        state: state(),
                        velocity: super::velocity_name(&self.coords[col]),
                    }
                }
            })?;
            solve(kind, lu, perm, big, x, tmp);
            if !x.iter().all(|v| v.is_finite()) {
                return Err(RhsError::NonFinite { t, state: state(), what: "acceleration" });
            }
            dy[..n].copy_from_slice(&y[n..2 * n]);
            dy[n..2 * n].copy_from_slice(&x[..n]);
            if let Some(l) = lambda {
                for j in 0..m.min(l.len()) {
                    l[j] = -x[n + j];
                }
            }
            Ok(())
        })
    }

    /// Evaluates `y' = (q', q'')`, or says why it cannot.
    pub fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        self.solve_at(t, y, dy, None)
    }

    /// The multipliers `λ_j` at a state (the generalized constraint forces are `Φᵀ λ`).
    pub fn multipliers(&self, t: f64, y: &[f64], lambda: &mut [f64]) -> Result<(), RhsError> {
        let mut dy = vec![0.0; 2 * self.n];
        self.solve_at(t, y, &mut dy, Some(lambda))
    }

    /// The constraint values `f_j(q, t)` at a state (the residual: zero on the manifold), and
    /// `g_j(q, q', t)` for the velocity constraints.
    pub fn residuals(&self, t: f64, y: &[f64], f: &mut [f64]) {
        let mut out = vec![0.0; self.m + self.m * self.n + self.m];
        let mut input = y[..2 * self.n].to_vec();
        input.push(t);
        self.manifold.eval(&input, &mut out);
        f[..self.m].copy_from_slice(&out[..self.m]);
    }

    /// Moves `y` onto the constraint manifold at time `t`: Newton on the positions along
    /// `Φᵀ` (the nearest point in the Euclidean metric of the coordinates, to first order),
    /// then the velocities onto `Φ q' + ∂f/∂t = 0` by the same least-change correction,
    /// together with the velocity constraints `g = 0` (which hold no position).
    pub fn project(&self, t: f64, y: &mut [f64]) -> Result<(), RhsError> {
        let (n, m, mh) = (self.n, self.m, self.mh);
        let nout = m + m * n + m;
        let mut out = vec![0.0; nout];
        let mut input = vec![0.0; 2 * n + 1];
        let mut g = vec![0.0; m * m];
        let mut lu = vec![0.0; m * m];
        let mut perm = vec![0.0; m];
        let mut r = vec![0.0; m];
        let mut tmp = vec![0.0; m];
        let eval = |y: &[f64], input: &mut [f64], out: &mut [f64]| {
            input[..2 * n].copy_from_slice(&y[..2 * n]);
            input[2 * n] = t;
            self.manifold.eval(input, out);
        };
        // Solves (Φ Φᵀ) δ = r over the first k rows of Φ and applies y[off..off+n] −= Φᵀ δ.
        let correct = |k: usize,
                       out: &[f64],
                       r: &mut [f64],
                       y: &mut [f64],
                       off: usize,
                       g: &mut [f64],
                       lu: &mut [f64],
                       perm: &mut [f64],
                       tmp: &mut [f64]|
         -> Result<(), RhsError> {
            let phi = &out[m..m + m * n];
            let (g, lu, perm, r, tmp) = (&mut g[..k * k], &mut lu[..k * k], &mut perm[..k], &mut r[..k], &mut tmp[..k]);
            for a in 0..k {
                for b in 0..k {
                    g[a * k + b] = (0..n).map(|i| phi[a * n + i] * phi[b * n + i]).sum();
                }
            }
            let kind = factor(g, lu, perm, k, true).map_err(|col| RhsError::SingularAugmented {
                t,
                state: y[..2 * n].to_vec(),
                constraint: col + 1,
            })?;
            solve(kind, lu, perm, k, r, tmp);
            for i in 0..n {
                y[off + i] -= (0..k).map(|a| phi[a * n + i] * r[a]).sum::<f64>();
            }
            Ok(())
        };
        for _ in 0..8 {
            if mh == 0 {
                break;
            }
            eval(y, &mut input, &mut out);
            let scale = y[..n].iter().fold(1.0f64, |s, v| s.max(v.abs()));
            if out[..mh].iter().all(|v| v.abs() <= 4.0 * f64::EPSILON * scale) {
                break;
            }
            r[..mh].copy_from_slice(&out[..mh]);
            correct(mh, &out, &mut r, y, 0, &mut g, &mut lu, &mut perm, &mut tmp)?;
        }
        eval(y, &mut input, &mut out);
        for j in 0..m {
            r[j] = if j < mh {
                (0..n).map(|i| out[m + j * n + i] * y[n + i]).sum::<f64>() + out[m + m * n + j]
            } else {
                out[j]
            };
        }
        correct(m, &out, &mut r, y, n, &mut g, &mut lu, &mut perm, &mut tmp)?;
        if !y[..2 * n].iter().all(|v| v.is_finite()) {
            return Err(RhsError::NonFinite { t, state: y[..2 * n].to_vec(), what: "projected state" });
        }
        Ok(())
    }
}

impl Rhs for ConstrainedRhs {
    fn dim(&self) -> usize {
        2 * self.n
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if self.try_eval(t, y, dy).is_err() {
            dy[..2 * self.n].iter_mut().for_each(|x| *x = f64::NAN);
        }
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepError> {
        ConstrainedRhs::try_eval(self, t, y, dy).map_err(StepError::from)
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        None
    }
}

/// A method whose every accepted step is followed by [`ConstrainedRhs::project`]: the
/// projection method of drift control. Dense output falls back to the driver's Hermite
/// interpolation between the projected states (the inner method's own would interpolate the
/// unprojected step).
pub struct Projected<'a, M> {
    /// The integration method.
    pub method: &'a M,
    /// The constraints to project onto.
    pub constraints: &'a ConstrainedRhs,
}

impl<S: ?Sized, M: Method<S>> Method<S> for Projected<'_, M> {
    type Work = M::Work;
    fn info(&self) -> MethodInfo {
        self.method.info()
    }
    fn dim(&self, sys: &S) -> usize {
        self.method.dim(sys)
    }
    fn work(&self, sys: &S) -> Self::Work {
        self.method.work(sys)
    }
    fn fixed_step(&self) -> Option<f64> {
        self.method.fixed_step()
    }
    fn check(&self) -> Result<(), String> {
        self.method.check()
    }
    fn step(&self, sys: &S, work: &mut Self::Work, t: f64, y: &mut [f64], h: f64) -> Result<f64, StepFailure> {
        let taken = self.method.step(sys, work, t, y, h)?;
        self.constraints.project(t + taken, y).map_err(|e| StepFailure::from(StepError::from(e)))?;
        // The inner method may carry values of the unprojected state into its next step.
        self.method.reset(work);
        Ok(taken)
    }
    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure> {
        self.method.rate(sys, t, y, dy)
    }
    fn reset(&self, work: &mut Self::Work) {
        self.method.reset(work);
    }
    fn rejected(&self, work: &Self::Work) -> usize {
        self.method.rejected(work)
    }
}
