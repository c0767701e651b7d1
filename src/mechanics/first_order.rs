//! First-order (phase-space) Lagrangians `L = Σ a_i(z, t) z'_i − H(z, t)`: Hamilton's
//! principle in phase space (PHYSICS.md (3.31)–(3.32)), guiding-centre motion, point vortices.
//!
//! Such an `L` has `W = ∂²L/∂z'∂z' ≡ 0`, so the route through `W q'' = F` does not exist; the
//! Euler–Lagrange expressions do, and they are first order. With the one-form `a` and the
//! two-form (Faddeev–Jackiw)
//!
//! `ω_ij = ∂a_j/∂z_i − ∂a_i/∂z_j`,
//!
//! `E_i = d/dt a_i − ∂L/∂z_i = Σ_j (∂a_i/∂z_j − ∂a_j/∂z_i) z'_j + ∂a_i/∂t + ∂H/∂z_i`, so
//! `E = 0` reads
//!
//! `ω z' = ∂H/∂z + ∂a/∂t`.
//!
//! When `ω` is non-degenerate its inverse `P = ω⁻¹` is the Poisson tensor of the reduced phase
//! space: `z' = P (∂H/∂z + ∂a/∂t)` and `{f, g} = Σ_ij ∂f/∂z_i P_ij ∂g/∂z_j`. For `L = p x' − H`
//! this is `{x, p} = 1` and Hamilton's equations. A degenerate `ω` (always so in odd
//! dimension) is a gauge freedom or a constraint; the error names its null direction.

use crate::algebra::expand;
use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::euler_lagrange::null_direction;
use super::linalg::{adjugate, determinant, MAX_CLOSED_FORM};
use super::system::{contains_any, time, zero_out, System};
use super::tidy::tidy;
use super::MechanicsError;

/// A Lagrangian first order in the velocities, with its geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct FirstOrder {
    /// The phase-space variables `z` (the system's coordinates), in order.
    pub coords: Vec<Symbol>,
    /// The one-form `a_i = ∂L/∂z'_i`.
    pub a: Vec<Expr>,
    /// The Hamiltonian `H = Σ a_i z'_i − L`.
    pub h: Expr,
    /// The two-form `ω_ij = ∂a_j/∂z_i − ∂a_i/∂z_j` (antisymmetric).
    pub omega: Vec<Vec<Expr>>,
    /// The right-hand side `∂H/∂z_i + ∂a_i/∂t` of `ω z' = …`.
    pub force: Vec<Expr>,
}

impl System {
    /// Recognises `L = Σ a_i(z, t) z'_i − H(z, t)` and derives its one-form, Hamiltonian,
    /// two-form and forcing. A Lagrangian with a velocity in some `∂L/∂z'_i` (one that is not
    /// linear in the velocities) is refused, naming that velocity.
    pub fn first_order(&self) -> Result<FirstOrder, MechanicsError> {
        let l = self.need_lagrangian("the first-order (phase-space) form")?;
        self.refuse_velocity_constraints("the first-order (phase-space) form")?;
        let mut d = Differentiator::new();
        let mut a = Vec::with_capacity(self.coords.len());
        for v in &self.velocities {
            let ai = without_velocities(&d.diff(l, v), &self.velocities)
                .ok_or_else(|| MechanicsError::NotFirstOrder { velocity: v.to_string() })?;
            a.push(ai);
        }
        let h = tidy(&zero_out(l, &self.velocities).neg());
        let n = self.coords.len();
        let mut omega = vec![vec![Expr::zero(); n]; n];
        for i in 0..n {
            for j in i + 1..n {
                let w = tidy(&d.diff(&a[j], &self.coords[i]).minus(&d.diff(&a[i], &self.coords[j])));
                omega[j][i] = w.neg();
                omega[i][j] = w;
            }
        }
        let t = time();
        let force = (0..n).map(|i| tidy(&d.diff(&h, &self.coords[i]).plus(&d.diff(&a[i], &t)))).collect::<Vec<_>>();
        Ok(FirstOrder { coords: self.coords.clone(), a, h, omega, force })
    }
}

/// `e` tidied, if it is free of the velocities (after expansion when its canonical form still
/// shows one that cancels).
fn without_velocities(e: &Expr, velocities: &[Symbol]) -> Option<Expr> {
    let e = tidy(e);
    if !contains_any(&e, velocities) {
        return Some(e);
    }
    let x = expand(&e).ok()?;
    (!contains_any(&x, velocities)).then(|| tidy(&x))
}

impl FirstOrder {
    /// The equations `(ω z')_i − ∂H/∂z_i − ∂a_i/∂t`, each `= 0` (equal to `−E_i`).
    pub fn equations(&self) -> Vec<Expr> {
        let v: Vec<Expr> = self.coords.iter().map(|z| Expr::sym(z.prime())).collect();
        self.omega
            .iter()
            .zip(&self.force)
            .map(|(row, f)| tidy(&Expr::add(row.iter().zip(&v).map(|(w, z)| w.times(z))).minus(f)))
            .collect()
    }

    /// Checks that `ω` is non-degenerate; otherwise the error names a null direction (a gauge
    /// freedom of `L`, or a constraint among the `z`).
    pub fn check_nondegenerate(&self) -> Result<(), MechanicsError> {
        match null_direction(&self.omega, &self.coords) {
            None => Ok(()),
            Some(direction) => Err(MechanicsError::DegenerateTwoForm { direction }),
        }
    }

    /// The Poisson tensor `P = ω⁻¹` in closed form (fraction-free adjugate over the
    /// determinant, up to four variables).
    pub fn poisson_tensor(&self) -> Result<Vec<Vec<Expr>>, MechanicsError> {
        self.check_nondegenerate()?;
        let n = self.coords.len();
        if n > MAX_CLOSED_FORM {
            return Err(MechanicsError::TooLarge { n, limit: MAX_CLOSED_FORM });
        }
        let det = determinant(&self.omega);
        let adj = adjugate(&self.omega);
        Ok(adj.iter().map(|row| row.iter().map(|x| tidy(&x.over(&det))).collect()).collect())
    }

    /// The velocities `z' = P (∂H/∂z + ∂a/∂t)`.
    pub fn velocities(&self) -> Result<Vec<Expr>, MechanicsError> {
        let p = self.poisson_tensor()?;
        Ok(p.iter().map(|row| tidy(&Expr::add(row.iter().zip(&self.force).map(|(x, f)| x.times(f))))).collect())
    }

    /// The Poisson bracket `{f, g} = Σ_ij ∂f/∂z_i P_ij ∂g/∂z_j` of the reduced phase space.
    pub fn bracket(&self, f: &Expr, g: &Expr) -> Result<Expr, MechanicsError> {
        let p = self.poisson_tensor()?;
        let mut d = Differentiator::new();
        let df: Vec<Expr> = self.coords.iter().map(|z| d.diff(f, z)).collect();
        let dg: Vec<Expr> = self.coords.iter().map(|z| d.diff(g, z)).collect();
        let mut terms = Vec::new();
        for (i, row) in p.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                if !x.is_zero() {
                    terms.push(Expr::mul([df[i].clone(), x.clone(), dg[j].clone()]));
                }
            }
        }
        Ok(tidy(&Expr::add(terms)))
    }

    /// Whether `H` or `a` depends on the time explicitly.
    pub fn is_time_dependent(&self) -> bool {
        let t = time();
        self.h.contains(&t) || self.a.iter().any(|a| a.contains(&t))
    }
}
