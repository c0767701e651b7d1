//! Point transformations (2.6.1) and gauge terms (2.6.2).

use std::collections::{BTreeSet, HashMap};

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::parse::parse_with;

use super::system::{Kind, System};
use super::tidy::tidy;
use super::MechanicsError;

impl System {
    /// The point transformation `q = Q(s, t)`: `map` gives each old coordinate as an expression
    /// in the new coordinates `new_coords` and `t` (`[("x", "r cos(φ)"), ("y", "r sin(φ)")]`).
    /// The new Lagrangian is `L(Q(s,t), d/dt Q(s,t), t)`, tidied. Velocity constraints are
    /// carried over the same way (`g(Q, dQ/dt, t)` is again linear in the new velocities):
    /// dropping them would make the new system the unconstrained one. Forces, dissipation and
    /// holonomic constraints are not carried over.
    pub fn transform(&self, map: &[(&str, &str)], new_coords: &[&str]) -> Result<System, MechanicsError> {
        let l = self.need_lagrangian("a point transformation")?;
        let new_names: BTreeSet<String> = new_coords.iter().map(|s| s.trim().to_string()).collect();
        let decls = self.decls.clone();
        let mut subs: HashMap<Symbol, Expr> = HashMap::new();
        let mut d = Differentiator::new();
        for (old, rhs) in map {
            let Some(i) = self.coords.iter().position(|q| q.name() == old.trim()) else {
                return Err(MechanicsError::BadTransform(format!("`{old}` is not a coordinate of the system")));
            };
            if subs.contains_key(&self.coords[i]) {
                return Err(MechanicsError::BadTransform(format!("`{old}` is given twice")));
            }
            let q = parse_with(rhs, &decls)?;
            for s in q.free_symbols() {
                if s.primes() > 0 {
                    return Err(MechanicsError::BadTransform(format!(
                        "`{old} = {}` contains the velocity `{s}`; a point transformation is q = Q(s, t)",
                        rhs.trim()
                    )));
                }
                if self.coords.iter().any(|c| c.name() == s.name()) && !new_names.contains(s.name()) {
                    return Err(MechanicsError::BadTransform(format!(
                        "`{old} = {}` uses the old coordinate `{s}`",
                        rhs.trim()
                    )));
                }
            }
            let qdot = d.dt(&q, &new_names);
            subs.insert(self.coords[i].clone(), q);
            subs.insert(self.velocities[i].clone(), qdot);
        }
        if let Some(q) = self.coords.iter().find(|q| !subs.contains_key(q)) {
            if !new_names.contains(q.name()) {
                return Err(MechanicsError::BadTransform(format!(
                    "no expression given for the old coordinate `{q}` (and it is not a new coordinate)"
                )));
            }
        }
        let new_l = tidy(&l.subs(&subs));
        let coords: Vec<&str> = new_coords.iter().map(|s| s.trim()).collect();
        let text = new_l.to_string();
        let mut sys = System::from_lagrangian_with(&text, &coords, &decls)?;
        for g in &self.velocity_constraints {
            sys = sys.with_velocity_constraint_expr(tidy(&g.subs(&subs)))?;
        }
        Ok(System {
            values: self.values.iter().filter(|(k, _)| sys.params.contains(k)).map(|(k, v)| (k.clone(), *v)).collect(),
            ..sys
        })
    }

    /// The gauge-transformed system `L + d/dt Λ(q, t)` (2.6.2), which has the same equations of
    /// motion. `Λ` must not depend on velocities.
    pub fn with_gauge(&self, lambda: &str) -> Result<System, MechanicsError> {
        let l = self.need_lagrangian("a gauge term")?;
        let g = parse_with(lambda, &self.decls)?;
        if let Some(v) = g.free_symbols().into_iter().find(|s| s.primes() > 0) {
            return Err(MechanicsError::BadTransform(format!(
                "the gauge function contains the velocity `{v}`; it must be Λ(q, t)"
            )));
        }
        let dg = Differentiator::new().dt(&g, &self.coord_names());
        // Tidied like a point transformation's result: the terms of dΛ/dt cancel against L's.
        let mut out = self.with_kind(Kind::Lagrangian(tidy(&l.plus(&dg))));
        out.forces = self.forces.clone();
        out.rayleigh = self.rayleigh.clone();
        out.constraints = self.constraints.clone();
        out.velocity_constraints = self.velocity_constraints.clone();
        Ok(out)
    }
}
