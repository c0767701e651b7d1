//! `conserved` beyond ignorable coordinates: the point symmetries that
//! [`crate::canonical::symmetry::point_symmetries`] finds (rotations in Cartesian
//! coordinates, Galilean boosts with their total-derivative term), added after the
//! mechanics stage's ignorable momenta and energy, each with the symmetry that gives it and
//! how its bracket with `H` was decided.

use crate::canonical::symmetry::point_symmetries;
use crate::canonical::{decide_zero, ZeroCheck};
use crate::expr::{Expr, Symbol};

use crate::mechanics::System;

use super::ast::Span;
use super::backend::Line;
use super::error::{ErrorKind, SceneError};
use super::session::Session;

/// One line per symmetry found that is not already an ignorable momentum in `known`, each
/// verified by `{Q, H} + ∂Q/∂t = 0`; the last line's note states the search's bound. A
/// Hamiltonian system is searched through its Lagrangian (the inverse Legendre transform) and
/// its charges are printed in momenta. Nothing when either transform does not exist.
pub(super) fn symmetry_lines(
    system: &System,
    coords: &[Symbol],
    known: &[Line],
    is_hamiltonian: bool,
    constraints: &[Expr],
) -> Vec<Line> {
    let Ok(h) = system.hamiltonian() else { return Vec::new() };
    let Ok(lsys) = system.inverse_legendre() else { return Vec::new() };
    let Some(l) = lsys.lagrangian() else { return Vec::new() };
    let search = point_symmetries(l, coords, &h);
    let mut out = Vec::new();
    for s in search.found {
        // A translation of one coordinate is its ignorable momentum, already listed.
        let moved: Vec<usize> = (0..coords.len()).filter(|&i| !s.generator[i].is_zero()).collect();
        if s.kind == "translation" && moved.len() == 1 {
            let p = format!("p_{}", coords[moved[0]].name());
            if known.iter().any(|k| k.lhs == Expr::var(&p)) {
                continue;
            }
        }
        if !s.check.is_zero() {
            continue;
        }
        // A constrained system keeps only generators along its constraints: δf = Σ ∂f/∂q ξ = 0.
        let along = constraints.iter().all(|f| {
            let df = Expr::add(coords.iter().zip(&s.generator).map(|(q, x)| crate::diff::diff(f, q).times(x)));
            decide_zero(&df) == ZeroCheck::Proven
        });
        if !along {
            continue;
        }
        let xi: Vec<String> = s.generator.iter().map(crate::print::plain).collect();
        let gauge = if s.gauge.is_zero() { String::new() } else { format!(", F = {}", crate::print::plain(&s.gauge)) };
        let note = format!("{}: ξ = ({}){gauge}; {{Q, H}} + ∂Q/∂t is {}", s.kind, xi.join(", "), s.check.describe());
        out.push(Line {
            label: None,
            lhs: Expr::var(&format!("Q{}", out.len() + 1)),
            rhs: if is_hamiltonian { s.charge } else { s.charge_velocities },
            note: Some(note),
        });
    }
    if let Some(last) = out.last_mut() {
        if let Some(n) = &mut last.note {
            n.push_str(&format!(" (searched: {})", search.bound));
        }
    }
    out
}

impl Session {
    /// `conserved` of a Lagrangian with forces, a Rayleigh function or constraints declared:
    /// the mechanics stage's quantities with those taken into account (a coordinate a force,
    /// dissipation or constraint acts on is not ignorable), and the point symmetries that
    /// preserve every constraint; with forces or dissipation no symmetry is searched (Noether's
    /// theorem needs `δL = dF/dt` of the whole dynamics), and the last line's note says so. Not cached: the
    /// derivation cache is keyed by `L` alone.
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
        let mut lines: Vec<Line> = system
            .conserved()
            .into_iter()
            .map(|c| Line { label: None, lhs: Expr::var(&c.name), rhs: c.expr, note: Some(c.reason.to_string()) })
            .collect();
        if forces.iter().all(Expr::is_zero) && rayleigh.is_none() {
            let free = System::from_lagrangian_expr(l.clone(), &self.coords).map_err(failed)?;
            let more = symmetry_lines(&free, &self.coords, &lines, false, &constraints);
            lines.extend(more);
        } else if let Some(last) = lines.last_mut() {
            let n = last.note.get_or_insert_with(String::new);
            n.push_str("; no symmetry search: with forces or dissipation δL = dF/dt gives no conserved charge");
        }
        Ok(lines)
    }
}
