//! Numerical integration of compiled equations of motion.
//!
//! The interfaces between the compiler and the integrators live here, with the schemes in
//! submodules. A system is one of:
//!
//! * a first-order right-hand side `y' = f(t, y)` ([`Rhs`]), optionally with its Jacobian
//!   `∂f/∂y` ([`Jacobian`]) for implicit methods;
//! * a separable Hamiltonian `H = T(p) + V(q)` split into its two exactly solvable flows
//!   ([`Separable`]): the drift `q' = ∂T/∂p` and the kick `p' = −∂V/∂q`, for splitting methods.
//!
//! State layout: `y = (q_1 … q_n, v_1 … v_n)` where `v` is the velocity `q'` (Lagrangian
//! systems) or the momentum `p` (Hamiltonian systems).
//!
//! Every method implements [`Method`] for the kind of system it can integrate (splitting
//! methods for [`Separable`], Runge–Kutta and collocation methods for [`Rhs`]), and so gets the
//! one user-facing API, [`Integrate`]:
//!
//! ```
//! use lagrangian::integrate::{Integrate, Splitting, problems::Pendulum};
//! let pendulum = Pendulum { omega: 1.0 };
//! let traj = Splitting::yoshida8(0.05).integrate(&pendulum, 0.0..10.0, &[1.0, 0.0]).unwrap();
//! let exact = pendulum.exact_from_rest(1.0, 10.0);
//! assert!((traj.last_state()[0] - exact[0]).abs() < 1e-9);
//! ```
//!
//! | method | system | order | properties | constructor |
//! |---|---|---|---|---|
//! | explicit Euler | [`Rhs`] | 1 | teaching baseline | [`ExplicitRk::euler`] |
//! | symplectic Euler | [`Separable`] | 1 | symplectic | [`Splitting::symplectic_euler`] |
//! | Störmer–Verlet | [`Separable`] | 2 | symplectic, symmetric | [`Splitting::leapfrog`] |
//! | Yoshida 4/6/8 | [`Separable`] | 4/6/8 | symplectic, symmetric | [`Splitting::yoshida4`] … |
//! | Blanes–Moan | [`Separable`] | 4 | symplectic, symmetric, optimised | [`Splitting::blanes_moan4`] |
//! | implicit midpoint, Gauss 4/6 | [`Rhs`] (+[`Jacobian`]) | 2/4/6 | symplectic, symmetric | [`Gauss::midpoint`], [`Gauss4`], [`Gauss6`] … |
//! | RK4 | [`Rhs`] | 4 | | [`ExplicitRk::rk4`] |
//! | DOP853 | [`Rhs`] | 8 | adaptive, dense output | [`Dop853::new`] |
//! | Taylor | [`TaylorSystem`] | ⌈−½ ln ε + 1⌉ | adaptive, dense output, no rejected steps | [`Taylor::new`] |
//!
//! Failures (non-finite values, step-size collapse, a non-converging implicit solve, a
//! right-hand side that reports an error, the step budget) end the integration with an
//! [`IntegrateError`] carrying the last good time and state; no method panics or returns a
//! NaN trajectory.

// Numerical kernels index several parallel arrays (state, stages, scales) with one index;
// zipped iterators over four slices read worse than the formula they implement.
#![allow(clippy::needless_range_loop)]

mod batch;
pub mod coefficients;
mod dop853;
pub mod drift;
mod error;
mod gauss;
pub mod problems;
mod rk;
mod solver;
mod splitting;
#[doc(hidden)]
pub mod taylor;

pub use batch::{BatchOutput, KeepStates, LaneRun, LaneTask, RunState, TaylorBatchSystem, BATCH_FROM_ORDER};
pub use dop853::Dop853;
pub use error::{fmt_state, fmt_value, FailureReason, IntegrateError, RhsError, StepFailure};
pub use gauss::{Gauss, Gauss4, Gauss6, ImplicitSolver};
pub use rk::ExplicitRk;
pub(crate) use solver::sort_in_time;
pub use solver::{
    Crossing, Event, EventAction, EventRecord, Integrate, Options, Output, Solver, Stats, Status, StopReason,
    Trajectory,
};
pub use splitting::Splitting;
pub use taylor::{Taylor, TaylorSystem, TaylorWork, MIN_TOL};

/// A first-order system `y' = f(t, y)`.
pub trait Rhs: Sync {
    /// The dimension of `y`.
    fn dim(&self) -> usize;
    /// Writes `f(t, y)` into `dy` (both of length [`Rhs::dim`]). Must not allocate.
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]);
    /// Like [`Rhs::eval`], but may report that `f` cannot be evaluated at `(t, y)` (a singular
    /// mass matrix, a state outside the domain). The integrators call this one; the default
    /// forwards to [`Rhs::eval`] and never fails.
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        self.eval(t, y, dy);
        Ok(())
    }
    /// The Jacobian of this system, if it has one: implementors of [`Jacobian`] return
    /// `Some(self)` so that implicit methods use Newton's method instead of fixed-point
    /// iteration (Rust has no specialisation, so the system says so itself).
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        None
    }
}

/// The Jacobian `∂f/∂y` of a right-hand side, for implicit methods.
pub trait Jacobian: Rhs {
    /// Writes `∂f_i/∂y_j` into `jac[i * dim + j]` (row-major, `dim × dim`). Must not allocate.
    fn jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]);
}

/// A separable Hamiltonian `H(q, p, t) = T(p) + V(q, t)` with `n` degrees of freedom.
pub trait Separable: Sync {
    /// Degrees of freedom `n` (the state has `2n` entries).
    fn dof(&self) -> usize;
    /// Drift velocity `∂T/∂p` at momenta `p`, written into `dq`.
    fn drift(&self, p: &[f64], dq: &mut [f64]);
    /// Kick force `−∂V/∂q` at `(q, t)`, written into `dp`.
    fn kick(&self, t: f64, q: &[f64], dp: &mut [f64]);
    /// Like [`Separable::drift`] but may fail; the default never does.
    fn try_drift(&self, p: &[f64], dq: &mut [f64]) -> Result<(), RhsError> {
        self.drift(p, dq);
        Ok(())
    }
    /// Like [`Separable::kick`] but may fail; the default never does.
    fn try_kick(&self, t: f64, q: &[f64], dp: &mut [f64]) -> Result<(), RhsError> {
        self.kick(t, q, dp);
        Ok(())
    }
}

/// Any closure of the right shape is a right-hand side (for hand-written systems and tests).
pub struct FnRhs<F> {
    /// The dimension of the state.
    pub dim: usize,
    /// The function `f(t, y, dy)`.
    pub f: F,
}

impl<F: Fn(f64, &[f64], &mut [f64]) + Sync> Rhs for FnRhs<F> {
    fn dim(&self) -> usize {
        self.dim
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        (self.f)(t, y, dy)
    }
}

/// A closure right-hand side with a closure Jacobian (row-major, see [`Jacobian::jacobian`]).
pub struct FnJacobian<F, J> {
    /// The dimension of the state.
    pub dim: usize,
    /// The function `f(t, y, dy)`.
    pub f: F,
    /// The Jacobian `jac(t, y, out)`.
    pub jac: J,
}

impl<F, J> Rhs for FnJacobian<F, J>
where
    F: Fn(f64, &[f64], &mut [f64]) + Sync,
    J: Fn(f64, &[f64], &mut [f64]) + Sync,
{
    fn dim(&self) -> usize {
        self.dim
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        (self.f)(t, y, dy)
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        Some(self)
    }
}

impl<F, J> Jacobian for FnJacobian<F, J>
where
    F: Fn(f64, &[f64], &mut [f64]) + Sync,
    J: Fn(f64, &[f64], &mut [f64]) + Sync,
{
    fn jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) {
        (self.jac)(t, y, jac)
    }
}

/// A closure right-hand side that may fail: `f(t, y, dy) -> Result<(), RhsError>`.
pub struct TryFnRhs<F> {
    /// The dimension of the state.
    pub dim: usize,
    /// The function.
    pub f: F,
}

impl<F: Fn(f64, &[f64], &mut [f64]) -> Result<(), RhsError> + Sync> Rhs for TryFnRhs<F> {
    fn dim(&self) -> usize {
        self.dim
    }
    /// Evaluates and ignores a failure (the integrators call [`Rhs::try_eval`]); on failure
    /// `dy` is filled with NaN so a caller of `eval` cannot mistake it for a value.
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if (self.f)(t, y, dy).is_err() {
            dy.fill(f64::NAN);
        }
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        (self.f)(t, y, dy)
    }
}

/// A separable system seen as a first-order right-hand side `(q, p)' = (∂T/∂p, −∂V/∂q)`, so
/// that Runge–Kutta methods can integrate it too (for comparisons with splitting methods).
pub struct SeparableRhs<'a, S: ?Sized>(pub &'a S);

impl<S: Separable + ?Sized> Rhs for SeparableRhs<'_, S> {
    fn dim(&self) -> usize {
        2 * self.0.dof()
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        let n = self.0.dof();
        let (dq, dp) = dy.split_at_mut(n);
        self.0.drift(&y[n..], dq);
        self.0.kick(t, &y[..n], dp);
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        let n = self.0.dof();
        let (dq, dp) = dy.split_at_mut(n);
        self.0.try_drift(&y[n..], dq)?;
        self.0.try_kick(t, &y[..n], dp)
    }
}

/// Static facts about a method, for tables, plots and tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MethodInfo {
    /// Short name.
    pub name: &'static str,
    /// Classical order of accuracy.
    pub order: u32,
    /// The step map is symplectic (for Hamiltonian systems).
    pub symplectic: bool,
    /// The step map is symmetric: `Φ_{−h} ∘ Φ_h = id`.
    pub symmetric: bool,
    /// The step size is chosen by error control.
    pub adaptive: bool,
}

/// One integration scheme for systems of type `S`. Implemented by every method; users call the
/// provided [`Integrate`] methods or drive a [`Solver`] step by step.
pub trait Method<S: ?Sized> {
    /// Scratch storage, allocated once per integration so that steps do not allocate.
    type Work;
    /// Name, order and structural properties.
    fn info(&self) -> MethodInfo;
    /// The dimension of the state of `sys`.
    fn dim(&self, sys: &S) -> usize;
    /// Allocates the scratch storage for `sys`.
    fn work(&self, sys: &S) -> Self::Work;
    /// The step size of a fixed-step method (positive); `None` for adaptive methods.
    fn fixed_step(&self) -> Option<f64>;
    /// Refuses settings the method cannot honour in `f64` (a tolerance below rounding, a
    /// non-finite parameter), with a message naming the smallest usable value; checked by
    /// [`Solver::new`] before the first step, so such a request fails at once instead of
    /// spinning. The default accepts everything.
    fn check(&self) -> Result<(), String> {
        Ok(())
    }
    /// Advances `(t, y)` in place by the signed step `h` (fixed-step methods) or by at most `h`
    /// (adaptive methods), returning the step actually taken. On error `y` may hold garbage:
    /// the [`Solver`] restores the last good state.
    fn step(&self, sys: &S, work: &mut Self::Work, t: f64, y: &mut [f64], h: f64) -> Result<f64, StepFailure>;
    /// The time derivative of the state, for interpolation between steps.
    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure>;
    /// Dense output at the fraction `theta ∈ [0, 1]` of the last step, if the method has its
    /// own (otherwise the solver uses cubic Hermite interpolation). Returns `Ok(false)` when
    /// the method has none.
    fn dense(&self, _sys: &S, _work: &mut Self::Work, _theta: f64, _out: &mut [f64]) -> Result<bool, StepFailure> {
        Ok(false)
    }
    /// Forgets values cached from the previous step (called when the state is changed from
    /// outside the method).
    fn reset(&self, _work: &mut Self::Work) {}
    /// Rejected steps so far (adaptive methods).
    fn rejected(&self, _work: &Self::Work) -> usize {
        0
    }
}

/// Adds `scale · inc` to `y`, with Kahan's compensated summation when `comp` is given: the
/// low-order bits lost in each addition are carried in `comp` and fed into the next one, so
/// the round-off of a long run grows like `√N ε` (random walk) instead of `N ε`.
/// Generic over [`Lane`](crate::lanes::Lane) so that the batch Taylor step updates its lanes
/// with these same operations.
#[inline(always)]
pub(crate) fn add_scaled<L: crate::lanes::Lane>(y: &mut [L], comp: Option<&mut [L]>, scale: L, inc: &[L]) {
    match comp {
        None => {
            for (yi, di) in y.iter_mut().zip(inc) {
                *yi += scale * *di;
            }
        }
        Some(c) => {
            for ((yi, di), ci) in y.iter_mut().zip(inc).zip(c.iter_mut()) {
                let d = scale * *di - *ci;
                let s = *yi + d;
                *ci = (s - *yi) - d;
                *yi = s;
            }
        }
    }
}
