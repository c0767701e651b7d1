//! Gauss–Legendre collocation (implicit midpoint, orders 4 and 6): symplectic and symmetric
//! for any Hamiltonian, separable or not. The stage equations
//! `Z_i = h Σ_j a_ij f(t + c_j h, y + Z_j)` are solved to rounding, by simplified Newton
//! iteration with the system's Jacobian when it has one ([`super::Rhs::as_jacobian`]) and by
//! fixed-point iteration otherwise (which converges only for `h ‖∂f/∂y‖` below about 1).

use nalgebra::{DMatrix, DVector};

use super::coefficients::Tableau;
use super::error::{FailureReason, StepFailure};
use super::{add_scaled, Method, MethodInfo, Rhs};

/// How the implicit stage equations are solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImplicitSolver {
    /// Newton with the system's Jacobian if it provides one, fixed point otherwise.
    Auto,
    /// Always fixed-point iteration.
    FixedPoint,
    /// Always Newton; the Jacobian is approximated by forward differences when the system
    /// provides none.
    Newton,
}

/// A Gauss–Legendre collocation method with fixed step `h`.
#[derive(Debug, Clone, PartialEq)]
pub struct Gauss {
    tableau: Tableau,
    h: f64,
    compensated: bool,
    solver: ImplicitSolver,
    max_iterations: usize,
}

impl Gauss {
    /// The collocation method of `tableau` with step `h`.
    pub fn new(tableau: Tableau, h: f64) -> Self {
        Gauss { tableau, h, compensated: false, solver: ImplicitSolver::Auto, max_iterations: 0 }
    }
    /// The implicit midpoint rule (order 2).
    pub fn midpoint(h: f64) -> Self {
        Self::new(Tableau::implicit_midpoint(), h)
    }
    /// Two-stage Gauss–Legendre (order 4).
    pub fn gauss4(h: f64) -> Self {
        Self::new(Tableau::gauss4(), h)
    }
    /// Three-stage Gauss–Legendre (order 6).
    pub fn gauss6(h: f64) -> Self {
        Self::new(Tableau::gauss6(), h)
    }
    /// Uses Kahan-compensated summation for the state update.
    pub fn compensated(mut self) -> Self {
        self.compensated = true;
        self
    }
    /// Chooses how the stage equations are solved.
    pub fn solver(mut self, solver: ImplicitSolver) -> Self {
        self.solver = solver;
        self
    }
    /// Iteration budget per step (default: 20 for Newton, 100 for fixed point).
    pub fn max_iterations(mut self, n: usize) -> Self {
        self.max_iterations = n;
        self
    }
    /// Name, order and properties.
    pub fn info(&self) -> MethodInfo {
        self.tableau.info()
    }
    /// The tableau.
    pub fn tableau(&self) -> &Tableau {
        &self.tableau
    }
}

/// The issue's spelling of two-stage Gauss–Legendre (order 4): `Gauss4::new(h)` is
/// [`Gauss::gauss4`]`(h)`, the same integrator, not a second one.
#[derive(Debug, Clone, Copy)]
pub struct Gauss4;

impl Gauss4 {
    /// [`Gauss::gauss4`] with step `h`.
    #[allow(clippy::new_ret_no_self)]
    pub fn new(h: f64) -> Gauss {
        Gauss::gauss4(h)
    }
}

/// The issue's spelling of three-stage Gauss–Legendre (order 6): `Gauss6::new(h)` is
/// [`Gauss::gauss6`]`(h)`.
///
/// ```
/// use lagrangian::integrate::{Gauss, Gauss6, Integrate};
/// use lagrangian::mechanics::System;
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let sys = System::from_lagrangian("1/2 m l^2 θ'^2 + m g l cos(θ)", &["θ"])?
///     .with_params(&[("m", 1.0), ("l", 1.0), ("g", 9.81)])?;
/// let rhs = sys.compile_rhs()?;
/// let y0 = [1.0, 0.0];
/// let traj = Gauss6::new(1e-2).integrate(&rhs, 0.0..100.0, &y0)?;
/// // The same integrator as the older spelling, step for step.
/// let same = Gauss::gauss6(1e-2).integrate(&rhs, 0.0..100.0, &y0)?;
/// assert_eq!(traj.last_state(), same.last_state());
/// // Symplectic: the pendulum's energy ½θ'² − g cos θ stays put over ~70 periods.
/// let energy = |y: &[f64]| 0.5 * y[1] * y[1] - 9.81 * y[0].cos();
/// assert!((energy(traj.last_state()) - energy(&y0)).abs() < 1e-8);
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Gauss6;

impl Gauss6 {
    /// [`Gauss::gauss6`] with step `h`.
    #[allow(clippy::new_ret_no_self)]
    pub fn new(h: f64) -> Gauss {
        Gauss::gauss6(h)
    }
}

/// Scratch storage of a [`Gauss`] integration.
pub struct GaussWork {
    z: Vec<f64>,
    f: Vec<f64>,
    stage: Vec<f64>,
    jac: Vec<f64>,
    m: DMatrix<f64>,
    rhs: DVector<f64>,
    f0: Vec<f64>,
    inc: Vec<f64>,
    comp: Vec<f64>,
}

/// Largest correction relative to the state's scale.
fn norm(dz: &[f64], y: &[f64]) -> f64 {
    let n = y.len();
    dz.iter().enumerate().fold(0.0, |m, (k, d)| {
        let r = (d / (1.0 + y[k % n].abs())).abs();
        if r.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(r)
        }
    })
}

impl Gauss {
    fn eval_stages<S: Rhs + ?Sized>(
        &self,
        sys: &S,
        w: &mut GaussWork,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<(), StepFailure> {
        let n = y.len();
        for i in 0..self.tableau.stages {
            for k in 0..n {
                w.stage[k] = y[k] + w.z[i * n + k];
            }
            sys.try_eval(t + self.tableau.c[i] * h, &w.stage, &mut w.f[i * n..(i + 1) * n])?;
        }
        Ok(())
    }

    fn jacobian<S: Rhs + ?Sized>(&self, sys: &S, w: &mut GaussWork, t: f64, y: &[f64]) -> Result<(), StepFailure> {
        let n = y.len();
        if let Some(j) = sys.as_jacobian() {
            j.jacobian(t, y, &mut w.jac);
            return Ok(());
        }
        // Forward differences, column by column.
        w.stage.copy_from_slice(y);
        for c in 0..n {
            let d = f64::EPSILON.sqrt() * (1.0 + y[c].abs());
            w.stage[c] = y[c] + d;
            sys.try_eval(t, &w.stage, &mut w.inc)?;
            w.stage[c] = y[c];
            for r in 0..n {
                w.jac[r * n + c] = (w.inc[r] - w.f0[r]) / d;
            }
        }
        Ok(())
    }
}

impl<S: Rhs + ?Sized> Method<S> for Gauss {
    type Work = GaussWork;

    fn info(&self) -> MethodInfo {
        Gauss::info(self)
    }

    fn dim(&self, sys: &S) -> usize {
        sys.dim()
    }

    fn work(&self, sys: &S) -> GaussWork {
        let n = sys.dim();
        let sn = self.tableau.stages * n;
        GaussWork {
            z: vec![0.0; sn],
            f: vec![0.0; sn],
            stage: vec![0.0; n],
            jac: vec![0.0; n * n],
            m: DMatrix::zeros(sn, sn),
            rhs: DVector::zeros(sn),
            f0: vec![0.0; n],
            inc: vec![0.0; n],
            comp: vec![0.0; n],
        }
    }

    fn fixed_step(&self) -> Option<f64> {
        Some(self.h)
    }

    fn step(&self, sys: &S, w: &mut GaussWork, t: f64, y: &mut [f64], h: f64) -> Result<f64, StepFailure> {
        let tab = &self.tableau;
        let (s, n) = (tab.stages, y.len());
        let newton = match self.solver {
            ImplicitSolver::Auto => sys.as_jacobian().is_some(),
            ImplicitSolver::FixedPoint => false,
            ImplicitSolver::Newton => true,
        };
        let max_iter = match (self.max_iterations, newton) {
            (0, true) => 20,
            (0, false) => 100,
            (m, _) => m,
        };
        sys.try_eval(t, y, &mut w.f0)?;
        for i in 0..s {
            for k in 0..n {
                w.z[i * n + k] = tab.c[i] * h * w.f0[k];
            }
        }
        let lu = if newton {
            self.jacobian(sys, w, t, y)?;
            // M = I − h (A ⊗ J)
            for i in 0..s {
                for j in 0..s {
                    let a = h * tab.a(i, j);
                    for r in 0..n {
                        for c in 0..n {
                            let id = if i == j && r == c { 1.0 } else { 0.0 };
                            w.m[(i * n + r, j * n + c)] = id - a * w.jac[r * n + c];
                        }
                    }
                }
            }
            Some(w.m.clone().lu())
        } else {
            None
        };
        let mut prev = f64::INFINITY;
        let mut first = f64::NAN;
        let mut converged = false;
        let mut iterations = 0;
        let mut last = f64::NAN;
        while iterations < max_iter {
            if crate::cancel::interrupted() {
                return Err(StepFailure(FailureReason::Interrupted));
            }
            iterations += 1;
            self.eval_stages(sys, w, t, y, h)?;
            // Residual G(Z) = Z − h (A ⊗ I) F(Z), stored negated in rhs.
            for i in 0..s {
                for k in 0..n {
                    let mut acc = 0.0;
                    for j in 0..s {
                        acc += tab.a(i, j) * w.f[j * n + k];
                    }
                    w.rhs[i * n + k] = h * acc - w.z[i * n + k];
                }
            }
            if let Some(lu) = &lu {
                if !lu.solve_mut(&mut w.rhs) {
                    return Err(StepFailure(FailureReason::ImplicitSolve {
                        iterations,
                        last_correction: f64::INFINITY,
                        newton,
                    }));
                }
            }
            for (zi, d) in w.z.iter_mut().zip(w.rhs.iter()) {
                *zi += d;
            }
            let d = norm(w.rhs.as_slice(), y);
            last = d;
            if first.is_nan() {
                first = d;
            }
            if !d.is_finite() || d > 1e6 * first.max(1e-300) + 1.0 {
                break; // diverging
            }
            // Converged when the correction is at rounding level, or when the linear rate
            // θ = d/prev predicts the remaining error θ/(1 − θ)·d to be (Hairer & Wanner,
            // Solving ODEs II, IV.8; only trusted for θ < 1/2), or when round-off stops the
            // decrease below 1e-13.
            let theta = if prev.is_finite() { d / prev } else { f64::NAN };
            if d <= 4.0 * f64::EPSILON
                || (theta < 0.5 && theta / (1.0 - theta) * d <= f64::EPSILON)
                || (d >= prev && d < 1e-13)
            {
                converged = true;
                break;
            }
            prev = d;
        }
        if !converged {
            return Err(StepFailure(FailureReason::ImplicitSolve { iterations, last_correction: last, newton }));
        }
        self.eval_stages(sys, w, t, y, h)?;
        w.inc.fill(0.0);
        for i in 0..s {
            let b = tab.b[i];
            for k in 0..n {
                w.inc[k] += b * w.f[i * n + k];
            }
        }
        add_scaled(y, self.compensated.then_some(&mut w.comp[..]), h, &w.inc);
        Ok(h)
    }

    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure> {
        Ok(sys.try_eval(t, y, dy)?)
    }

    fn reset(&self, w: &mut GaussWork) {
        w.comp.fill(0.0);
    }
}
