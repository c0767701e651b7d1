//! Conserved quantities by Noether's theorem (2.7) and `dH/dt = ∂H/∂t` (3.30).

use std::fmt;

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::system::{time, Kind, System};
use super::tidy::tidy;

/// Why a quantity is conserved.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reason {
    /// `∂L/∂q = 0` (or `∂H/∂q = 0`): the coordinate is ignorable, its momentum conserved.
    Ignorable(Symbol),
    /// `∂L/∂t = 0`: the energy function `h = Σ q' ∂L/∂q' − L` is conserved.
    LagrangianTimeIndependent,
    /// `∂H/∂t = 0`: `H` is conserved.
    HamiltonianTimeIndependent,
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reason::Ignorable(q) => write!(f, "{q} is ignorable (the equations do not depend on {q})"),
            Reason::LagrangianTimeIndependent => {
                write!(f, "L does not depend on t explicitly (energy function h, (2.7))")
            }
            Reason::HamiltonianTimeIndependent => {
                write!(f, "H does not depend on t explicitly (dH/dt = ∂H/∂t = 0, (3.30))")
            }
        }
    }
}

/// A conserved quantity with its name (`p_φ`, `h`, `H`) and the reason it is conserved.
#[derive(Clone, Debug, PartialEq)]
pub struct Conserved {
    pub name: String,
    pub expr: Expr,
    pub reason: Reason,
}

impl System {
    /// The energy function `h = Σ q' ∂L/∂q' − L` (2.7) of a Lagrangian system, in canonical
    /// form (not tidied: callers that print it choose), or `H` itself for a Hamiltonian one.
    /// `conserved` reports it (tidied) when `∂L/∂t = 0`, and front ends take it as the energy
    /// of a trajectory in velocities; one definition serves both.
    pub fn energy_function(&self) -> Expr {
        match &self.kind {
            Kind::Lagrangian(l) => {
                let mut d = Differentiator::new();
                let terms: Vec<Expr> =
                    self.velocities.iter().map(|v| Expr::sym(v.clone()).times(&d.diff(l, v))).collect();
                Expr::add(terms).minus(l)
            }
            Kind::Hamiltonian(h) => h.clone(),
        }
    }

    /// The conserved quantities Noether's theorem gives directly: the momentum of each
    /// ignorable coordinate, the energy function `h` when `∂L/∂t = 0`, or `H` when `∂H/∂t = 0`.
    /// Generalized forces, dissipation and constraints that involve a coordinate (or time)
    /// break the corresponding law, which is then not reported. A velocity constraint
    /// `a·q' + b = 0` breaks the momentum of every coordinate its force `μ a` acts on, and the
    /// energy unless it is ideal (`b = 0`, no `t`), when its force does no work.
    pub fn conserved(&self) -> Vec<Conserved> {
        let mut d = Differentiator::new();
        let mut out = Vec::new();
        let t = time();
        let breaks = |i: usize, d: &mut Differentiator| {
            !self.forces[i].is_zero()
                || self.rayleigh.as_ref().is_some_and(|r| !tidy(&d.diff(r, &self.velocities[i])).is_zero())
                || self.constraints.iter().any(|f| !tidy(&d.diff(f, &self.coords[i])).is_zero())
                || self.velocity_constraints.iter().any(|g| !tidy(&d.diff(g, &self.velocities[i])).is_zero())
        };
        let at_rest: std::collections::HashMap<Symbol, Expr> =
            self.velocities.iter().map(|v| (v.clone(), Expr::zero())).collect();
        let dissipative = self.forces.iter().any(|f| !f.is_zero())
            || self.rayleigh.is_some()
            || self.constraints.iter().any(|f| f.contains(&t))
            || self.velocity_constraints.iter().any(|g| g.contains(&t) || !tidy(&g.subs(&at_rest)).is_zero());
        match &self.kind {
            Kind::Lagrangian(l) => {
                for i in 0..self.coords.len() {
                    if tidy(&d.diff(l, &self.coords[i])).is_zero() && !breaks(i, &mut d) {
                        out.push(Conserved {
                            name: self.momenta[i].to_string(),
                            expr: tidy(&d.diff(l, &self.velocities[i])),
                            reason: Reason::Ignorable(self.coords[i].clone()),
                        });
                    }
                }
                if !l.contains(&t) && !dissipative {
                    out.push(Conserved {
                        name: "h".to_string(),
                        expr: energy_as_printed(&self.energy_function()),
                        reason: Reason::LagrangianTimeIndependent,
                    });
                }
            }
            Kind::Hamiltonian(h) => {
                for i in 0..self.coords.len() {
                    if tidy(&d.diff(h, &self.coords[i])).is_zero() {
                        out.push(Conserved {
                            name: self.momenta[i].to_string(),
                            expr: Expr::sym(self.momenta[i].clone()),
                            reason: Reason::Ignorable(self.coords[i].clone()),
                        });
                    }
                }
                if !h.contains(&t) {
                    out.push(Conserved {
                        name: "H".to_string(),
                        expr: h.clone(),
                        reason: Reason::HamiltonianTimeIndependent,
                    });
                }
            }
        }
        out
    }
}

/// The energy function as `conserved` prints it. Its canonical form keeps the grouping of
/// `L`'s terms (`g l m (1 − cos θ) + l² m θ'²/2`, the form the scene's `energy` and the notes
/// print); that form is kept when its terms do not interact: expanded one by one they give as
/// many monomials as the whole expanded (nothing cancels or merges), and tidying a term does
/// not shorten it, and the tidied whole is not shorter by more than one operation per term.
/// Otherwise (`y' (m y' + e B x) − e B x y'`) the tidied whole.
fn energy_as_printed(h: &Expr) -> Expr {
    use crate::canonical::normalize;
    let terms = h.terms();
    let separate: usize = terms.iter().map(|t| normalize(t).terms().len()).sum();
    let independent =
        separate == normalize(h).terms().len() && terms.iter().all(|t| tidy(t).op_count() >= t.op_count());
    let tidied = tidy(h);
    // …and when pulling factors out saves no more than one operation per term.
    if independent && h.op_count() <= tidied.op_count() + terms.len() {
        h.clone()
    } else {
        tidied
    }
}
