//! The compiled right-hand side of a first-order (phase-space) Lagrangian: `ω(z, t) z' = b(z, t)`
//! with `b = ∂H/∂z + ∂a/∂t` (see `mechanics::FirstOrder`).
//!
//! One tape evaluates the entries of `ω` and `b` together (shared subexpressions once); the
//! linear solve happens numerically at each call, by Gaussian elimination with partial
//! pivoting on a stack buffer, so a call never allocates and no symbolic inverse of `ω` is
//! needed (it costs `n!` symbolically, `n³/3` here). The state is `z` itself: `n` values, not
//! `2n`. Every method that takes an [`Rhs`] integrates it (Runge–Kutta, DOP853, the
//! Gauss–Legendre methods, which iterate without a Jacobian); splitting methods do not apply,
//! `ω z' = b` has no drift/kick split in general.

use crate::expr::Expr;
use crate::integrate::{Rhs, RhsError};

use super::error::CompileError;
use super::tape::{CompileOptions, Tape};
use crate::linalg::solve_in_place;

/// The largest number of phase-space variables the stack solve takes.
pub const MAX_FIRST_ORDER_DIM: usize = 16;

/// `z' = ω⁻¹ b`, solved numerically at each call. State `y = z`.
#[derive(Debug)]
pub struct FirstOrderRhs {
    n: usize,
    names: Vec<String>,
    tape: Tape,
}

impl FirstOrderRhs {
    /// Compiles `ω` (`n × n`, row-major rows) and `b` (`n`) over the state `coords` and `t`,
    /// `params` bound.
    pub fn new(
        omega: &[Vec<Expr>],
        b: &[Expr],
        coords: &[&str],
        params: &[(&str, f64)],
    ) -> Result<FirstOrderRhs, CompileError> {
        FirstOrderRhs::with_options(omega, b, coords, params, &CompileOptions::default())
    }

    /// [`FirstOrderRhs::new`] with explicit code generator choices.
    pub fn with_options(
        omega: &[Vec<Expr>],
        b: &[Expr],
        coords: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<FirstOrderRhs, CompileError> {
        let n = coords.len();
        if n > MAX_FIRST_ORDER_DIM {
            return Err(CompileError::Shape { what: "phase-space variables (at most 16)", expected: 16, got: n });
        }
        if omega.len() != n || omega.iter().any(|r| r.len() != n) {
            return Err(CompileError::Shape { what: "the two-form ω", expected: n, got: omega.len() });
        }
        if b.len() != n {
            return Err(CompileError::Shape { what: "the forcing ∂H/∂z", expected: n, got: b.len() });
        }
        let mut outputs: Vec<Expr> = omega.iter().flatten().cloned().collect();
        outputs.extend(b.iter().cloned());
        let inputs: Vec<&str> = coords.iter().copied().chain(["t"]).collect();
        let tape = Tape::compile_with_options(&outputs, &inputs, params, options)?;
        Ok(FirstOrderRhs { n, names: coords.iter().map(|s| s.to_string()).collect(), tape })
    }

    /// The tape of `(ω row-major, b)`.
    pub fn tape(&self) -> &Tape {
        &self.tape
    }

    /// Evaluates `z' = ω⁻¹ b`, or reports a non-finite value or a degenerate `ω` (naming the
    /// variable whose column has no pivot).
    pub fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        const M: usize = MAX_FIRST_ORDER_DIM;
        let n = self.n;
        let mut buf = [0.0f64; M * M + M];
        let out = &mut buf[..n * n + n];
        self.tape.eval_split(&y[..n], t, out);
        if let Some(k) = out.iter().position(|x| !x.is_finite()) {
            let what = if k < n * n { "entry of the two-form ω" } else { "derivative of H" };
            return Err(RhsError::new(format!("non-finite {what} at t = {t}; state {:?}", &y[..n])));
        }
        let (a, b) = out.split_at_mut(n * n);
        solve_in_place(a, b, n).map_err(|j| {
            RhsError::new(format!(
                "the two-form ω is degenerate at t = {t} (no pivot for `{}`); state {:?}",
                self.names[j],
                &y[..n]
            ))
        })?;
        dy[..n].copy_from_slice(b);
        Ok(())
    }
}

impl Rhs for FirstOrderRhs {
    fn dim(&self) -> usize {
        self.n
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        FirstOrderRhs::try_eval(self, t, y, dy)
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if self.try_eval(t, y, dy).is_err() {
            dy[..self.n].fill(f64::NAN);
        }
    }
}

impl crate::mechanics::System {
    /// The first-order equations `ω z' = ∂H/∂z + ∂a/∂t` of a phase-space Lagrangian
    /// `L = Σ a_i z'_i − H`, parameters bound to the values given by
    /// [`crate::mechanics::System::with_params`]; state `z` (the coordinates). A degenerate
    /// two-form is refused here, naming its null direction.
    ///
    /// ```
    /// use lagrangian::mechanics::System;
    /// use lagrangian::integrate::Rhs;
    /// let sys = System::from_lagrangian("p x' - p^2/(2 m) - k x^2/2", &["x", "p"]).unwrap()
    ///     .with_params(&[("m", 2.0), ("k", 3.0)]).unwrap();
    /// let rhs = sys.compile_first_order().unwrap();
    /// let mut dz = [0.0; 2];
    /// rhs.eval(0.0, &[0.5, 1.0], &mut dz);
    /// assert_eq!(dz, [1.0 / 2.0, -3.0 * 0.5]); // Hamilton's equations x' = p/m, p' = −k x
    /// ```
    pub fn compile_first_order(&self) -> Result<FirstOrderRhs, CompileError> {
        let mech = |e: crate::mechanics::MechanicsError| CompileError::Mechanics(e);
        let f = self.first_order().map_err(mech)?;
        f.check_nondegenerate().map_err(mech)?;
        let coords: Vec<String> = self.coordinates().iter().map(|s| s.to_string()).collect();
        let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
        let params: Vec<(String, f64)> = self.param_values().iter().map(|(k, v)| (k.to_string(), *v)).collect();
        let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        FirstOrderRhs::new(&f.omega, &f.force, &coords, &params)
    }
}

/// A [`FirstOrderRhs`] on the state layout `(z, z')` that Lagrangian runs use, so that a
/// first-order Lagrangian's trajectory has velocity columns like any other: the first half
/// is integrated, the second is carried with zero derivative (it never feeds back into the
/// first, so the `z` trajectory is exactly that of the `n`-dimensional system, for every
/// method) and is refreshed with `z' = ω⁻¹ b` at the kept states by
/// [`FirstOrderRhs::fill_velocities`].
#[derive(Debug)]
pub struct WithVelocitySlots(pub FirstOrderRhs);

impl Rhs for WithVelocitySlots {
    fn dim(&self) -> usize {
        2 * self.0.n
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        let n = self.0.n;
        self.0.try_eval(t, &y[..n], &mut dy[..n])?;
        dy[n..2 * n].fill(0.0);
        Ok(())
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        if self.try_eval(t, y, dy).is_err() {
            dy[..2 * self.0.n].fill(f64::NAN);
        }
    }
}

impl FirstOrderRhs {
    /// Writes `z' = ω⁻¹ b` at `(t, y[..n])` into `y[n..2n]`.
    pub fn fill_velocities(&self, t: f64, y: &mut [f64]) -> Result<(), RhsError> {
        let n = self.n;
        let (z, v) = y.split_at_mut(n);
        self.try_eval(t, z, &mut v[..n])
    }
}
