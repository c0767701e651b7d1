//! Coordinates without their velocity (§3.2.1, Remark 3.1): when `L` does not contain `y'`,
//! the Euler–Lagrange equation of `y` is the algebraic equation `∂L/∂y = 0`, the mass matrix
//! is singular, and no integrator of `W q'' = F` can run. When that equation is linear in
//! `y` it is solved for `y` and substituted back into `L`. That is exact, not an
//! approximation: since `∂L/∂y = 0` along the solution, the reduced `L_r(x, x') = L(x, x',
//! y(x, x'))` has the same Euler–Lagrange equations for the remaining coordinates (the chain
//! rule terms carry the factor `∂L/∂y`). A nonlinear equation is refused, naming it.

use std::collections::HashMap;

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::system::System;
use super::tidy::tidy;
use super::MechanicsError;

/// The reduced system after eliminating the coordinates that have no velocity in `L`.
#[derive(Clone, Debug, PartialEq)]
pub struct AlgebraicElimination {
    /// Each eliminated coordinate with its solution in the remaining coordinates (and their
    /// velocities), in the order they were solved; later ones are already substituted.
    pub eliminated: Vec<(Symbol, Expr)>,
    /// The remaining coordinates.
    pub coords: Vec<Symbol>,
    /// The reduced Lagrangian `L_r`.
    pub lagrangian: Expr,
}

impl System {
    /// The coordinates whose velocity does not occur in `L` (none for a Hamiltonian system).
    pub fn velocity_free_coordinates(&self) -> Vec<Symbol> {
        let Some(l) = self.lagrangian() else { return Vec::new() };
        let free = l.free_symbols();
        self.coords.iter().zip(&self.velocities).filter(|(_, v)| !free.contains(v)).map(|(q, _)| q.clone()).collect()
    }

    /// Eliminates every coordinate without its velocity by solving its (linear) algebraic
    /// equation `∂L/∂y = 0` for it. Refused, with what would work, when the equation is not
    /// linear in `y`, does not contain `y` at all (then it constrains the other coordinates),
    /// or no coordinate with a velocity is left.
    pub fn eliminate_velocity_free(&self) -> Result<AlgebraicElimination, MechanicsError> {
        let mut l = self.need_lagrangian("eliminating a coordinate without velocity")?.clone();
        let lacking = self.velocity_free_coordinates();
        let coords: Vec<Symbol> = self.coords.iter().filter(|q| !lacking.contains(q)).cloned().collect();
        if coords.is_empty() {
            return Err(MechanicsError::WrongKind(
                "no coordinate of this Lagrangian has its velocity in L: there is nothing to integrate (a Lagrangian with at least one velocity would work)".into(),
            ));
        }
        let mut d = Differentiator::new();
        let mut eliminated: Vec<(Symbol, Expr)> = Vec::new();
        for y in &lacking {
            let g = tidy(&d.diff(&l, y));
            let slope = tidy(&d.diff(&g, y));
            if slope.is_zero() {
                return Err(MechanicsError::WrongKind(format!(
                    "the equation of `{y}`, which has no velocity in L, is ∂L/∂{y} = {} = 0: it does not contain {y}, so it \
                     constrains the other coordinates instead of fixing {y} (write it as a constraint, or give {y} a kinetic term)",
                    g
                )));
            }
            if slope.contains(y) {
                return Err(MechanicsError::WrongKind(format!(
                    "the equation of `{y}`, which has no velocity in L, is ∂L/∂{y} = {g} = 0, not linear in {y}: it is not solved \
                     in closed form and no per-step Newton solve is done; a Lagrangian at most quadratic in {y} would work \
                     (or solve for {y} by hand and substitute)"
                )));
            }
            let at0: HashMap<Symbol, Expr> = [(y.clone(), Expr::int(0))].into_iter().collect();
            let sol = tidy(&g.subs(&at0).neg().over(&slope));
            let by: HashMap<Symbol, Expr> = [(y.clone(), sol.clone())].into_iter().collect();
            l = tidy(&l.subs(&by));
            for (_, e) in eliminated.iter_mut() {
                *e = tidy(&e.subs(&by));
            }
            eliminated.push((y.clone(), sol));
        }
        Ok(AlgebraicElimination { eliminated, coords, lagrangian: l })
    }
}

impl System {
    /// The system with its velocity-free coordinates eliminated ([`System::eliminate_velocity_free`]):
    /// the remaining coordinates, the reduced `L`, and the parameter values and declarations
    /// kept. Forces, dissipation and constraints are refused, since the algebraic equation
    /// would then no longer be `∂L/∂y = 0` alone.
    pub fn reduced_system(&self) -> Result<(AlgebraicElimination, System), MechanicsError> {
        if self.forces.iter().any(|f| !f.is_zero())
            || self.rayleigh.is_some()
            || !self.constraints.is_empty()
            || !self.velocity_constraints.is_empty()
        {
            return Err(MechanicsError::WrongKind(
                "a coordinate without velocity is eliminated only from a conservative, unconstrained L (forces, \
                 dissipation and constraints would enter its algebraic equation); eliminate it by hand, or give it a \
                 kinetic term"
                    .into(),
            ));
        }
        let red = self.eliminate_velocity_free()?;
        let mut sys = self.with_kind(super::system::Kind::Lagrangian(red.lagrangian.clone()));
        let keep: Vec<bool> = self.coords.iter().map(|q| red.coords.contains(q)).collect();
        let pick = |v: &[Symbol]| v.iter().zip(&keep).filter(|(_, k)| **k).map(|(s, _)| s.clone()).collect::<Vec<_>>();
        sys.velocities = pick(&self.velocities);
        sys.momenta = pick(&self.momenta);
        sys.coords = red.coords.clone();
        sys.forces = vec![Expr::zero(); sys.coords.len()];
        Ok((red, sys))
    }
}
