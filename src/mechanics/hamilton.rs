//! Hamilton's equations (3.12) and the phase-space Lagrangian (3.31).

use std::collections::HashMap;

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::system::System;
use super::tidy::tidy;
use super::MechanicsError;

/// Hamilton's equations `q'_i = ∂H/∂p_i`, `p'_i = −∂H/∂q_i`.
#[derive(Clone, Debug, PartialEq)]
pub struct HamiltonEquations {
    /// The Hamiltonian they come from.
    pub hamiltonian: Expr,
    /// `∂H/∂p_i`, one per coordinate.
    pub qdot: Vec<Expr>,
    /// `−∂H/∂q_i`, one per coordinate, plus what drives it (forces, dissipation, constraint
    /// forces; see [`System::hamilton_equations`]).
    pub pdot: Vec<Expr>,
}

impl System {
    /// Hamilton's equations of the system's Hamiltonian (a Lagrangian is transformed first).
    /// Generalized forces, the Rayleigh function and constraints add their
    /// [`System::driving_forces`] `Q_i − ∂R/∂q'_i + Σ_j λ_j ∂f_j/∂q_i` to `p'_i`, with every
    /// velocity written as `∂H/∂p` (so `p'` is in `q, p, t` and the multipliers): they are never
    /// dropped.
    pub fn hamilton_equations(&self) -> Result<HamiltonEquations, MechanicsError> {
        let h = self.hamiltonian()?;
        let mut d = Differentiator::new();
        let qdot: Vec<Expr> = self.momenta.iter().map(|p| tidy(&d.diff(&h, p))).collect();
        let mut pdot: Vec<Expr> = self.coords.iter().map(|q| tidy(&d.diff(&h, q).neg())).collect();
        if self.has_driving_forces() {
            let to_momenta: HashMap<Symbol, Expr> = self.velocities.iter().cloned().zip(qdot.iter().cloned()).collect();
            for (p, x) in pdot.iter_mut().zip(self.driving_forces()) {
                *p = tidy(&p.plus(&x.subs(&to_momenta)));
            }
        }
        Ok(HamiltonEquations { hamiltonian: h, qdot, pdot })
    }

    /// The phase-space Lagrangian `L_ph = Σ p_i q'_i − H(q, p, t)` (3.31): its Euler–Lagrange
    /// equations in the variables `(q, p)` are Hamilton's equations.
    pub fn phase_space_lagrangian(&self) -> Result<Expr, MechanicsError> {
        let h = self.hamiltonian()?;
        let pq: Vec<Expr> = self
            .momenta
            .iter()
            .zip(&self.velocities)
            .map(|(p, v)| Expr::sym(p.clone()).times(&Expr::sym(v.clone())))
            .collect();
        Ok(Expr::add(pq).minus(&h))
    }
}
