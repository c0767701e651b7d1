//! Holonomic constraints by Lagrange multipliers (1.25–1.29).

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::euler_lagrange::null_direction;
use super::linalg::{adjugate, determinant, MAX_CLOSED_FORM};
use super::system::System;
use super::tidy::tidy;
use super::MechanicsError;

/// The augmented equations of a constrained system: stationary `∫ (L + Σ λ_j f_j) dt` gives
/// `W q'' − Φᵀ λ = F` with `Φ_ji = ∂f_j/∂q_i`, and `Φ q'' = c` from `d²f_j/dt² = 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstrainedEquations {
    /// The multipliers `λ1, λ2, …`, one per constraint.
    pub multipliers: Vec<Symbol>,
    /// `E_i − Q_i + ∂R/∂q'_i − Σ_j λ_j ∂f_j/∂q_i`, each `= 0`.
    pub equations: Vec<Expr>,
    /// The mass matrix `W`.
    pub w: Vec<Vec<Expr>>,
    /// The forcing `F`.
    pub f: Vec<Expr>,
    /// `Φ_ji = ∂f_j/∂q_i` (one row per holonomic constraint), then `a_ji = ∂g_j/∂q_i'` (one
    /// row per velocity constraint).
    pub phi: Vec<Vec<Expr>>,
    /// `c_j = −(d²f_j/dt² − Σ_i Φ_ji q_i'')` (or `−(dg_j/dt − Σ_i a_ji q_i'')`): the right side
    /// of `Φ q'' = c`.
    pub c: Vec<Expr>,
}

impl System {
    /// The names of the constraint multipliers, `λ1, λ2, …`.
    pub fn multipliers(&self) -> Vec<Symbol> {
        (1..=self.constraints.len()).map(|j| Symbol::new(&format!("λ{j}"))).collect()
    }

    /// Every multiplier of the augmented system: `λ1, λ2, …` of the holonomic constraints,
    /// then `μ1, μ2, …` of the velocity constraints.
    pub fn constraint_multipliers(&self) -> Vec<Symbol> {
        let mut all = self.multipliers();
        all.extend(self.velocity_multipliers(self.velocity_constraints.len()));
        all
    }

    /// The augmented equations of motion with one multiplier per holonomic constraint (`λ`,
    /// its row `∂f/∂q` and `c` from `d²f/dt² = 0`) and then one per velocity constraint (`μ`,
    /// its row `∂g/∂q'` and `c` from `dg/dt = 0`, as in [`System::lagrange_dalembert`]).
    pub fn constrained_equations(&self) -> Result<ConstrainedEquations, MechanicsError> {
        let equations = self.equations()?;
        let (w, f) = self.mass_matrix_split()?;
        let names = self.coord_names();
        let mut d = Differentiator::new();
        let acc: Vec<Symbol> = self.accelerations_symbols();
        let mut phi = Vec::new();
        let mut c = Vec::new();
        for fj in &self.constraints {
            let row: Vec<Expr> = self.coords.iter().map(|q| tidy(&d.diff(fj, q))).collect();
            let d1 = d.dt(fj, &names);
            let d2 = d.dt(&d1, &names);
            let lhs: Vec<Expr> = row.iter().zip(&acc).map(|(p, a)| p.times(&Expr::sym(a.clone()))).collect();
            c.push(tidy(&Expr::add(lhs).minus(&d2)));
            phi.push(row);
        }
        let (vphi, vc) = self.velocity_constraint_rows()?;
        phi.extend(vphi);
        c.extend(vc);
        Ok(ConstrainedEquations { multipliers: self.constraint_multipliers(), equations, w, f, phi, c })
    }

    /// The accelerations `q''` and the multipliers `λ` of a constrained system, in closed
    /// form: `λ` is eliminated with the constraints differentiated twice, that is the
    /// augmented system `W q'' − Φᵀ λ = F`, `Φ q'' = c` is solved by the fraction-free
    /// adjugate of `[W −Φᵀ; Φ 0]` (up to four unknowns in all). A singular augmented matrix
    /// (redundant constraints) is an error naming its null direction.
    pub fn constrained_accelerations(&self) -> Result<(Vec<Expr>, Vec<Expr>), MechanicsError> {
        let c = self.constrained_equations()?;
        let n = self.coords.len();
        let k = c.phi.len();
        let mut m = vec![vec![Expr::zero(); n + k]; n + k];
        for i in 0..n {
            for j in 0..n {
                m[i][j] = c.w[i][j].clone();
            }
        }
        for (j, row) in c.phi.iter().enumerate() {
            for (i, x) in row.iter().enumerate() {
                m[i][n + j] = x.neg();
                m[n + j][i] = x.clone();
            }
        }
        let mut unknowns: Vec<Symbol> = self.accelerations_symbols();
        unknowns.extend(c.multipliers.iter().cloned());
        if let Some(direction) = null_direction(&m, &unknowns) {
            return Err(MechanicsError::SingularConstraints { direction });
        }
        if n + k > MAX_CLOSED_FORM {
            return Err(MechanicsError::TooLarge { n: n + k, limit: MAX_CLOSED_FORM });
        }
        let b: Vec<Expr> = c.f.iter().chain(&c.c).cloned().collect();
        let det = determinant(&m);
        let adj = adjugate(&m);
        let solved: Vec<Expr> = (0..n + k)
            .map(|i| {
                let num = tidy(&Expr::add((0..n + k).map(|j| adj[i][j].times(&b[j]))));
                tidy(&crate::algebra::cancel(&num.over(&det)))
            })
            .collect();
        let lambdas = solved[n..].to_vec();
        let mut acc = solved;
        acc.truncate(n);
        Ok((acc, lambdas))
    }
}
