//! Which equations a method integrates for a given kind of system, and the refusal (with the
//! methods that would work) when the pair makes no sense.
//!
//! This is the one place that decides method × system. Every front end describes its system
//! as a [`Shape`], asks [`route`], and builds the [`Formulation`] the route names; nothing
//! outside this module dispatches on a method's family to pick equations.

use std::fmt;

use super::method::{Family, MethodId};
use crate::compile::Stabilization;
use crate::expr::Expr;

/// What a front end knows about the system it wants to integrate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Shape {
    /// A Lagrangian `L` is available (given, or the system is Lagrangian).
    pub lagrangian: bool,
    /// A Hamiltonian `H` was given directly (not only derivable from `L`).
    pub hamiltonian: bool,
    /// `L` is first order in the velocities (`L = a(z)·z' − H(z)`), so `W` is singular.
    pub first_order: bool,
    /// Generalized forces or a Rayleigh dissipation function act on the coordinates.
    pub forces: bool,
    /// Holonomic constraints `f(q, t) = 0` hold.
    pub constraints: bool,
    /// Velocity (nonholonomic) constraints `a(q, t)·q' + b(q, t) = 0` hold.
    pub velocity_constraints: bool,
}

impl Shape {
    /// A conservative, regular Lagrangian system.
    pub fn lagrangian() -> Shape {
        Shape { lagrangian: true, ..Shape::default() }
    }
    /// A system given by its Hamiltonian.
    pub fn hamiltonian() -> Shape {
        Shape { hamiltonian: true, ..Shape::default() }
    }
    fn conservative(&self) -> bool {
        !self.forces && !self.constraints && !self.velocity_constraints
    }
}

/// The equations a route integrates (the front end builds the matching [`Formulation`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Route {
    /// `W q'' = F` from a conservative `L`; state `(q, q')`.
    Lagrangian,
    /// `W q'' = F` with forces and dissipation, or the augmented constrained system; state `(q, q')`.
    Extended,
    /// `ω z' = ∂H/∂z` of a first-order `L`; state `(z, z')`.
    FirstOrder,
    /// Hamilton's equations of `H`; state `(q, p)`.
    Hamiltonian,
    /// Drift and kick of a separable `H`; state `(q, p)`.
    Separable,
    /// The discrete Euler–Lagrange map of `L`; state `(q, p)`.
    Variational,
}

impl Route {
    /// Whether the second half of the state is the velocities `q'` (else the momenta `p_q`).
    pub fn has_velocities(self) -> bool {
        matches!(self, Route::Lagrangian | Route::Extended | Route::FirstOrder)
    }
}

/// Why a method cannot integrate a system.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RefusalReason {
    /// Splitting and variational methods need a conservative system.
    NotConservative,
    /// The method needs `L` (variational maps; forces and constraints act on `L`'s equations).
    NeedsLagrangian,
    /// The method needs a regular `L` (its Legendre map inverts), and this one is first order.
    FirstOrder,
    /// Neither `L` nor `H` is given.
    NothingToIntegrate,
    /// A splitting method needs `H = T(p) + V(q, t)`, and this term mixes coordinates and
    /// momenta (found when `H` is known, after [`route`]).
    NotSeparable {
        /// The first term that does not split, in plain form.
        term: String,
    },
}

/// A method refused for a system, with the methods that can run it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// The method asked for.
    pub method: MethodId,
    /// Why it cannot run the system.
    pub reason: RefusalReason,
    /// Every method that can.
    pub alternatives: Vec<MethodId>,
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = self.method.name();
        match (&self.reason, self.method.family()) {
            (RefusalReason::NotConservative, Family::Splitting) => write!(
                f,
                "`{m}` splits a conservative H = T(p) + V(q); forces, dissipation and constraints are not part of H"
            ),
            (RefusalReason::NotConservative, _) => write!(
                f,
                "`{m}` discretizes a Lagrangian alone; forces, dissipation and constraints are not part of L_d"
            ),
            (RefusalReason::NeedsLagrangian, Family::Variational) => {
                write!(f, "`{m}` discretizes the Lagrangian, and no `L` is defined")
            }
            (RefusalReason::NeedsLagrangian, _) => {
                write!(f, "forces, dissipation and constraints act on the equations of `L`, and no `L` is defined")
            }
            (RefusalReason::FirstOrder, Family::Splitting) => write!(
                f,
                "`{m}` splits H = T(p) + V(q), and this L is first order in the velocities, so it has no such H"
            ),
            (RefusalReason::FirstOrder, _) => write!(
                f,
                "`{m}` needs a regular L: this L is first order in the velocities, so its discrete Legendre map has no inverse"
            ),
            (RefusalReason::NothingToIntegrate, _) => f.write_str("nothing to simulate: no `L` or `H` defined"),
            (RefusalReason::NotSeparable { term }, _) => write!(
                f,
                "`{m}` needs a separable H = T(p) + V(q), but the term `{term}` mixes coordinates and momenta"
            ),
        }
    }
}

impl Refusal {
    /// The hint a front end prints: the methods that would work.
    pub fn hint(&self) -> String {
        if self.alternatives.is_empty() {
            return match self.reason {
                RefusalReason::NothingToIntegrate => "define `L = …` or `H = …` first".into(),
                _ => "define the Lagrangian: `L = …`".into(),
            };
        }
        let names: Vec<String> = self.alternatives.iter().map(|m| format!("`{}`", m.name())).collect();
        format!("these methods can run this system: {}", names.join(", "))
    }
}

/// The refusal of splitting `method` for a system of this shape whose `H` does not split at
/// `term`: every method that routes and does not split is an alternative.
pub fn not_separable(method: MethodId, shape: &Shape, term: String) -> Refusal {
    Refusal {
        method,
        reason: RefusalReason::NotSeparable { term },
        alternatives: MethodId::all()
            .filter(|m| m.family() != Family::Splitting && route_reason(*m, shape).is_ok())
            .collect(),
    }
}

/// The equations `method` integrates for a system of this shape, or why it cannot.
pub fn route(method: MethodId, shape: &Shape) -> Result<Route, Refusal> {
    route_reason(method, shape).map_err(|reason| Refusal {
        method,
        reason,
        alternatives: MethodId::all().filter(|m| route_reason(*m, shape).is_ok()).collect(),
    })
}

fn route_reason(method: MethodId, s: &Shape) -> Result<Route, RefusalReason> {
    if !s.lagrangian && !s.hamiltonian {
        return Err(RefusalReason::NothingToIntegrate);
    }
    match method.family() {
        Family::Splitting => {
            if !s.conservative() {
                return Err(RefusalReason::NotConservative);
            }
            if !s.hamiltonian && s.first_order {
                return Err(RefusalReason::FirstOrder);
            }
            Ok(Route::Separable)
        }
        Family::Variational => {
            if !s.conservative() {
                return Err(RefusalReason::NotConservative);
            }
            if !s.lagrangian {
                return Err(RefusalReason::NeedsLagrangian);
            }
            if s.first_order {
                return Err(RefusalReason::FirstOrder);
            }
            Ok(Route::Variational)
        }
        Family::Implicit | Family::Explicit | Family::Adaptive => {
            let taylor = method == MethodId::Taylor;
            if !s.conservative() {
                if !s.lagrangian {
                    return Err(RefusalReason::NeedsLagrangian);
                }
                if taylor && s.first_order {
                    return Err(RefusalReason::FirstOrder);
                }
                return Ok(Route::Extended);
            }
            if s.lagrangian {
                if s.first_order {
                    if taylor {
                        return Err(RefusalReason::FirstOrder);
                    }
                    return Ok(Route::FirstOrder);
                }
                return Ok(Route::Lagrangian);
            }
            Ok(Route::Hamiltonian)
        }
    }
}

/// The equations of motion a run integrates, symbolically.
#[derive(Clone, Debug)]
pub enum Formulation {
    /// `L(q, q', t)`: state `(q, q')`, accelerations from `W q'' = F`.
    Lagrangian(Expr),
    /// `W q'' = F` already derived (by a front end's derivation cache): state `(q, q')`.
    Equations {
        /// The mass matrix `W = ∂²L/∂q'∂q'`.
        w: Vec<Vec<Expr>>,
        /// The forcing `F`.
        f: Vec<Expr>,
    },
    /// `H(q, p, t)`: state `(q, p)`, Hamilton's equations.
    Hamiltonian(Expr),
    /// `L = Σ a_i(z, t) z'_i − H(z, t)`, first order in the velocities: state `(z, z')`,
    /// `ω z' = ∂H/∂z + ∂a/∂t` integrated for `z`, the velocities filled in at kept states.
    FirstOrder(Expr),
    /// `L(q, q', t)` with generalized forces, a Rayleigh function, holonomic or velocity
    /// constraints: state `(q, q')`, accelerations from `W q'' = F` or the augmented system.
    Extended(Box<ExtendedLagrangian>),
    /// `L(q, q', t)` discretized (`variational` methods): state `(q, p)`, the map
    /// `(q_k, p_k) → (q_{k+1}, p_{k+1})` of the discrete Lagrangian.
    Variational(Expr),
    /// `H = T(p) + V(q, t)`: drift and kick for splitting methods.
    Separable {
        /// The kinetic part `T(p)`.
        t: Expr,
        /// The potential part `V(q, t)`.
        v: Expr,
    },
}

impl Formulation {
    /// Every expression the compiled system depends on (for cache keys and parameter checks).
    pub fn exprs(&self) -> Vec<Expr> {
        match self {
            Formulation::Lagrangian(e)
            | Formulation::Hamiltonian(e)
            | Formulation::FirstOrder(e)
            | Formulation::Variational(e) => vec![e.clone()],
            Formulation::Equations { w, f } => w.iter().flatten().chain(f).cloned().collect(),
            Formulation::Separable { t, v } => vec![t.clone(), v.clone()],
            Formulation::Extended(x) => x.exprs(),
        }
    }

    /// What it integrates, in words (for `--explain` plans).
    pub fn describe(&self) -> &'static str {
        match self {
            Formulation::Lagrangian(_) | Formulation::Equations { .. } => "W q'' = F from L",
            Formulation::FirstOrder(_) => "ω z' = ∂H/∂z from a first-order L",
            Formulation::Variational(_) => "the discrete Euler–Lagrange map of L",
            Formulation::Extended(x) if !x.velocity_constraints.is_empty() => {
                "the augmented system [W Aᵀ; A 0] of the Lagrange–d'Alembert equations from L"
            }
            Formulation::Extended(x) if !x.constraints.is_empty() => "the augmented system [W Φᵀ; Φ 0] from L",
            Formulation::Extended(_) => "W q'' = F from L with forces",
            Formulation::Hamiltonian(_) => "Hamilton's equations of H",
            Formulation::Separable { .. } => "drift ∂T/∂p and kick −∂V/∂q",
        }
    }

    /// Whether the second half of the state is the velocities `q'` (else the momenta `p_q`).
    pub fn has_velocities(&self) -> bool {
        !matches!(self, Formulation::Hamiltonian(_) | Formulation::Separable { .. } | Formulation::Variational(_))
    }
}

/// A Lagrangian with the generalized forces, Rayleigh function and constraints that act on it.
#[derive(Clone, Debug)]
pub struct ExtendedLagrangian {
    /// `L(q, q', t)`.
    pub l: Expr,
    /// The generalized force `Q_i(q, q', t)` on each coordinate (zero where none).
    pub forces: Vec<Expr>,
    /// The Rayleigh dissipation function `R(q, q')`.
    pub rayleigh: Option<Expr>,
    /// Holonomic constraints `f_j(q, t)`, each `= 0`.
    pub constraints: Vec<Expr>,
    /// Velocity constraints `g_j(q, q', t)`, each `= 0` and linear in the velocities.
    pub velocity_constraints: Vec<Expr>,
    /// How a constrained run is held on its constraints.
    pub stabilization: Stabilization,
}

impl ExtendedLagrangian {
    /// Every expression the compiled system depends on (for cache keys and parameter checks).
    pub fn exprs(&self) -> Vec<Expr> {
        let mut v = vec![self.l.clone()];
        v.extend(self.forces.iter().cloned());
        v.extend(self.rayleigh.iter().cloned());
        v.extend(self.constraints.iter().cloned());
        v.extend(self.velocity_constraints.iter().cloned());
        v
    }
}
