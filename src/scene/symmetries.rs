//! `conserved` beyond ignorable coordinates: the scene side of
//! [`crate::canonical::report::conserved_lines`], which adds the point symmetries (rotations in
//! Cartesian coordinates, Galilean boosts with their total-derivative term, time changes) after
//! the mechanics stage's ignorable momenta and energy and states the search's bound. The same
//! function prints `lagrangian conserved`, so scene and command line give the same lines.

use crate::canonical::report::{conserved_lines, ConservedLine, SymmetryInput};
use crate::expr::Expr;

use crate::mechanics::System;

use super::ast::Span;
use super::backend::Line;
use super::error::{ErrorKind, SceneError};
use super::session::Session;

/// `conserved` of `system` as lines: its Noether quantities, then the point symmetries that
/// preserve every constraint (none searched with forces or dissipation). A Hamiltonian system
/// is searched through its Lagrangian (the inverse Legendre transform) and its charges are
/// printed in momenta; nothing is searched when either transform does not exist.
pub(super) fn conserved_of(system: &System) -> Vec<Line> {
    let known: Vec<ConservedLine> = system
        .conserved()
        .into_iter()
        .map(|c| ConservedLine { name: c.name, value: c.expr, note: c.reason.to_string() })
        .collect();
    let h = system.hamiltonian().ok();
    let l = system.inverse_legendre().ok().and_then(|s| s.lagrangian().cloned());
    let input = SymmetryInput {
        lagrangian_hamiltonian: l.as_ref().zip(h.as_ref()),
        coords: system.coordinates(),
        in_momenta: system.hamiltonian_expr().is_some(),
        constraints: system.constraints(),
        dissipative: system.forces().iter().any(|f| !f.is_zero()) || system.rayleigh().is_some(),
    };
    // A scene prints nothing for an empty list, so an unattached bound has no line to go to.
    let (lines, _bound) = conserved_lines(known, &input);
    lines.into_iter().map(|c| Line { label: None, lhs: Expr::var(&c.name), rhs: c.value, note: Some(c.note) }).collect()
}

impl Session {
    /// `conserved` of a Lagrangian with forces, a Rayleigh function or constraints declared:
    /// the mechanics stage's quantities with those taken into account (a coordinate a force,
    /// dissipation or constraint acts on is not ignorable), and the point symmetries that
    /// preserve every constraint; with forces or dissipation no symmetry is searched (Noether's
    /// theorem needs `δL = dF/dt` of the whole dynamics), and the last line's note says so.
    /// Not cached: the derivation cache is keyed by `L` alone.
    pub(super) fn conserved_with_dynamics(&mut self, l: &Expr, span: Span) -> Result<Vec<Line>, SceneError> {
        let (forces, rayleigh, constraints) = self.resolved_dynamics()?;
        let failed =
            |e: crate::mechanics::MechanicsError| SceneError::new(ErrorKind::Derivation, e.to_string()).at(span);
        let mut system = System::from_lagrangian_expr(l.clone(), &self.coords).map_err(failed)?;
        for (q, f) in self.coords.iter().zip(&forces) {
            if !f.is_zero() {
                system = system.with_force_expr(q.name(), f.clone()).map_err(failed)?;
            }
        }
        if let Some(r) = &rayleigh {
            system = system.with_rayleigh_expr(r.clone()).map_err(failed)?;
        }
        for f in &constraints {
            system = system.with_constraint_expr(f.clone()).map_err(failed)?;
        }
        Ok(conserved_of(&system))
    }
}
