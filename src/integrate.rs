//! Numerical integration of compiled equations of motion.
//!
//! The interfaces between the compiler and the integrators live here; the schemes are added
//! beside them. A system is one of:
//!
//! * a first-order right-hand side `y' = f(t, y)` ([`Rhs`]), optionally with its Jacobian
//!   `∂f/∂y` ([`Jacobian`]) for implicit methods;
//! * a separable Hamiltonian `H = T(p) + V(q)` split into its two exactly solvable flows
//!   ([`Separable`]): the drift `q' = ∂T/∂p` and the kick `p' = −∂V/∂q`, for splitting methods.
//!
//! State layout: `y = (q_1 … q_n, v_1 … v_n)` where `v` is the velocity `q'` (Lagrangian
//! systems) or the momentum `p` (Hamiltonian systems).

/// A first-order system `y' = f(t, y)`.
pub trait Rhs: Sync {
    /// The dimension of `y`.
    fn dim(&self) -> usize;
    /// Writes `f(t, y)` into `dy` (both of length [`Rhs::dim`]). Must not allocate.
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]);
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
