//! Nonholonomic constraints linear in the velocities, `g_j = Σ_i a_ji(q, t) q_i' + b_j(q, t) = 0`
//! (§1.5, §1.6.2): the Lagrange–d'Alembert equations `E_i − Q_i + ∂R/∂q_i' = Σ_j μ_j a_ji`
//! (virtual displacements satisfy `Σ_i a_ji δq_i = 0`, so the constraint forces are
//! combinations of the rows `a_j`), and the constraints differentiated once,
//! `Σ_i a_ji q_i'' = c_j`, which with `W q'' = F + aᵀμ` determine `q''` and `μ`.

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::constraints::ConstrainedEquations;
use super::system::System;
use super::tidy::tidy;
use super::MechanicsError;

impl System {
    /// The multipliers of velocity constraints, `μ1, μ2, …` (the holonomic ones are `λ`).
    pub fn velocity_multipliers(&self, k: usize) -> Vec<Symbol> {
        (1..=k).map(|j| Symbol::new(&format!("μ{j}"))).collect()
    }

    /// The row `a_j = ∂g/∂q'` of a velocity constraint `g = 0`, or why `g` is not one: an
    /// acceleration, a velocity of a non-coordinate, no velocity at all (holonomic) or a
    /// velocity left in `∂g/∂q'` (not linear) is refused naming what would work.
    pub(crate) fn velocity_constraint_row(&self, g: &Expr) -> Result<Vec<Expr>, MechanicsError> {
        let mut d = Differentiator::new();
        let free = g.free_symbols();
        if let Some(s) = free.iter().find(|s| s.primes() > 1) {
            return Err(MechanicsError::WrongKind(format!(
                "the velocity constraint `{g}` contains the acceleration `{s}`; a velocity constraint is a(q, t)·q' + b(q, t) = 0"
            )));
        }
        if let Some(s) = free.iter().find(|s| s.primes() == 1 && !self.velocities.contains(s)) {
            return Err(MechanicsError::VelocityOfNonCoordinate { symbol: s.to_string(), base: s.name().to_string() });
        }
        let row: Vec<Expr> = self.velocities.iter().map(|v| tidy(&d.diff(g, v))).collect();
        if row.iter().all(Expr::is_zero) {
            return Err(MechanicsError::WrongKind(format!(
                "the velocity constraint `{g}` contains no velocity: a constraint f(q, t) = 0 is holonomic, give it as a (holonomic) constraint"
            )));
        }
        if let Some((v, _)) =
            self.velocities.iter().zip(&row).find(|(_, a)| a.free_symbols().iter().any(|s| self.velocities.contains(s)))
        {
            return Err(MechanicsError::WrongKind(format!(
                "the velocity constraint `{g}` is not linear in the velocities (∂g/∂{v} still contains one): only \
                 a(q, t)·q' + b(q, t) = 0 is handled (Lagrange–d'Alembert); a constraint linear in the velocities would work"
            )));
        }
        Ok(row)
    }

    /// The Lagrange–d'Alembert equations of `L` (with its forces, dissipation and holonomic
    /// constraints) under the system's own velocity constraints followed by `extra` ones
    /// `g_j = 0`, each linear in the velocities. In the result `phi` holds the rows
    /// `a_ji = ∂g_j/∂q_i'` and `c` the right sides of `Σ_i a_ji q_i'' = c_j` (`dg_j/dt = 0`),
    /// one per velocity constraint, multipliers `μ1, μ2, …` in that order. A constraint that is
    /// not linear in the velocities, or has none, is refused naming what would work.
    pub fn lagrange_dalembert(&self, extra: &[Expr]) -> Result<ConstrainedEquations, MechanicsError> {
        let mut all = self.clone();
        for g in extra {
            all = all.with_velocity_constraint_expr(g.clone())?;
        }
        let mut bare = all.clone();
        bare.velocity_constraints.clear();
        let base = bare.equations()?;
        let (w, f) = all.mass_matrix_split()?;
        let (phi, c) = all.velocity_constraint_rows()?;
        let mus = all.velocity_multipliers(phi.len());
        let equations = base
            .into_iter()
            .enumerate()
            .map(|(i, e)| {
                let mut terms = vec![e];
                for (row, mu) in phi.iter().zip(&mus) {
                    terms.push(Expr::sym(mu.clone()).times(&row[i]).neg());
                }
                tidy(&Expr::add(terms))
            })
            .collect();
        Ok(ConstrainedEquations { multipliers: mus, equations, w, f, phi, c })
    }

    /// The rows `a_j = ∂g_j/∂q'` of the system's velocity constraints and the right sides
    /// `c_j = Σ_i a_ji q_i'' − dg_j/dt` of their derivatives `Σ_i a_ji q_i'' = c_j`.
    pub(crate) fn velocity_constraint_rows(&self) -> Result<(Vec<Vec<Expr>>, Vec<Expr>), MechanicsError> {
        let names = self.coord_names();
        let acc = self.accelerations_symbols();
        let mut d = Differentiator::new();
        let (mut phi, mut c) = (Vec::new(), Vec::new());
        for g in &self.velocity_constraints {
            let row = self.velocity_constraint_row(g)?;
            let dg = d.dt(g, &names);
            let lhs: Vec<Expr> = row.iter().zip(&acc).map(|(a, s)| a.times(&Expr::sym(s.clone()))).collect();
            c.push(tidy(&Expr::add(lhs).minus(&dg)));
            phi.push(row);
        }
        Ok((phi, c))
    }
}
