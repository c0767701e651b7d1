//! `conserved` beyond ignorable coordinates: the point symmetries that
//! [`crate::canonical::symmetry::point_symmetries`] finds (rotations in Cartesian
//! coordinates, Galilean boosts with their total-derivative term), added after the
//! mechanics stage's ignorable momenta and energy, each with the symmetry that gives it and
//! how its bracket with `H` was decided.

use crate::canonical::symmetry::point_symmetries;
use crate::expr::{Expr, Symbol};

use crate::mechanics::System;

use super::backend::Line;

/// One line per symmetry found that is not already an ignorable momentum in `known`, each
/// verified by `{Q, H} + ∂Q/∂t = 0`; the last line's note states the search's bound. A
/// Hamiltonian system is searched through its Lagrangian (the inverse Legendre transform) and
/// its charges are printed in momenta. Nothing when either transform does not exist.
pub(super) fn symmetry_lines(system: &System, coords: &[Symbol], known: &[Line], is_hamiltonian: bool) -> Vec<Line> {
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
