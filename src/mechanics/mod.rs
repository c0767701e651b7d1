//! Mechanics: from a Lagrangian or Hamiltonian to equations of motion.
//!
//! The physics and its sign conventions are those of `PHYSICS.md` sections 1–3:
//!
//! * Euler–Lagrange expressions `E_i = d/dt(∂L/∂q'_i) − ∂L/∂q_i` (the equation is `E_i = 0`),
//!   the split `W q'' = F` with `W = ∂²L/∂q'∂q'` (3.4) and
//!   `F = ∂L/∂q − ∂²L/∂q'∂t − (∂²L/∂q'∂q) q'` (3.5), generalized forces and a Rayleigh
//!   function (2.12);
//! * the Legendre transform `H = p·q' − L` (3.10), exact for natural systems
//!   `H = ½ (p − b)ᵀ W⁻¹ (p − b) + V` (3.23–3.27) through a fraction-free inverse, and for
//!   Lagrangians `a + k·sqrt(c₀ + q'ᵀ G q')` (the relativistic particle);
//! * Hamilton's equations (3.12) and the phase-space Lagrangian (3.31);
//! * Noether's conserved quantities (2.7), point and gauge transformations (2.6), holonomic
//!   constraints with multipliers (1.25–1.29).
//!
//! Everything starts from a [`System`]:
//!
//! ```
//! use lagrangian::mechanics::System;
//! let s = System::from_lagrangian("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", &["θ"]).unwrap();
//! let h = s.hamiltonian().unwrap();
//! assert_eq!(h.to_string(), "g l m (1 - cos(θ)) + p_θ^2/(2 l^2 m)");
//! ```
//!
//! Results are tidied by [`tidy`]: expanded, trigonometric products contracted
//! (`cos a cos b + sin a sin b = cos(a − b)`, `a − a cos² x = a sin² x`), common factors
//! pulled out greedily, then handed to [`crate::simplify::simplify`]; the smaller of that and
//! the untouched canonical form is kept, so tidying never makes a result longer.

// Matrix code (W_ij, adj_ij, Φ_ji) reads as the mathematics with explicit indices.
#![allow(clippy::needless_range_loop)]

mod algebraic;
mod constraints;
mod discrete;
mod euler_lagrange;
mod first_order;
mod geodesic;
mod hamilton;
mod legendre;
mod linalg;
mod map;
mod noether;
mod nonholonomic;
mod ritz;
mod series;
mod system;
#[doc(hidden)]
pub mod tidy;
mod transform;

pub use algebraic::AlgebraicElimination;
pub use constraints::ConstrainedEquations;
pub use discrete::{point_names, Discrete, Rule};
pub use first_order::FirstOrder;
pub use geodesic::{embedded, geodesic, geodesic_from_metric, Curvature, Embedding, Geodesic};
pub use hamilton::HamiltonEquations;
pub use linalg::{adjugate, determinant};
pub use map::{
    ExplicitMap, ImplicitMap, MapError, MapRun, Orbit, PhaseMap, MAX_MAP_ITERATIONS, MAX_MAP_STATES, PRINTED_ORBITS,
};
pub use noether::{Conserved, Reason};
pub use ritz::{ritz_quadrature_points, Ritz, RitzSolution};
pub use series::{jacobian, series, series_about, series_terms, SeriesError, MAX_SERIES_ORDER};
#[cfg(feature = "frontends")]
pub(crate) use system::constant_constraint;
pub(crate) use system::zero_out;
pub use system::{Kind, System};
pub use tidy::tidy;

use crate::parse::ParseError;

/// Why a mechanics operation refused its input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MechanicsError {
    /// The text did not parse.
    #[error("{0}")]
    Parse(#[from] ParseError),
    /// A Hamiltonian's momenta are not named after its coordinates (`p` for `p_q`): the
    /// name would be a parameter and a coordinate would never move.
    #[error("error: {0}")]
    MomentumNames(String),
    /// A coordinate is named like the momentum `p_q` of another coordinate `q`, so the
    /// equations could not tell the two apart.
    #[error("error: coordinate `{momentum}` has the name of the momentum of `{coord}` (momenta are named p_<coordinate>); rename it, e.g. `{suggestion}`")]
    MomentumNameCollision {
        /// The coordinate `q`.
        coord: String,
        /// The coordinate named `p_q`.
        momentum: String,
        /// A name that does not collide.
        suggestion: String,
    },
    /// An empty name in the list of coordinates (`--coords x,,y`).
    #[error("error: an empty coordinate name in the list of coordinates (two commas in a row, or a trailing comma?)")]
    EmptyCoordinate,
    /// The same coordinate was listed twice.
    #[error("error: coordinate `{0}` is declared twice")]
    DuplicateCoordinate(String),
    /// No coordinates were given.
    #[error("error: no coordinates given (pass at least one, e.g. --coords x)")]
    NoCoordinates,
    /// A coordinate name is not a plain variable name (or is the time `t`).
    #[error("error: `{0}` cannot be a coordinate (expected a plain name such as x or θ1, not t)")]
    BadCoordinate(String),
    /// Neither the coordinate nor its velocity occurs in the Lagrangian or Hamiltonian.
    #[error("error: coordinate `{coordinate}` does not appear in the {what} (neither `{coordinate}` nor `{velocity}` occurs)")]
    CoordinateAbsent { coordinate: String, velocity: String, what: &'static str },
    /// A second or higher time derivative (`x''`, `x'''`) occurs where only velocities may.
    #[error("error: `{symbol}` is a time derivative of order {order} in the {what}; only coordinates and velocities may appear")]
    HigherDerivative { symbol: String, order: u8, what: &'static str },
    /// A velocity of something that is not a coordinate.
    #[error("error: `{symbol}` is a velocity, but `{base}` is not a coordinate (add it to the coordinates)")]
    VelocityOfNonCoordinate { symbol: String, base: String },
    /// A velocity occurs in a Hamiltonian.
    #[error(
        "error: the Hamiltonian contains the velocity `{0}`; it must be a function of coordinates, momenta `p_q` and t"
    )]
    VelocityInHamiltonian(String),
    /// A symbol such as a momentum name clashes with a parameter of a Lagrangian.
    #[error("error: the Lagrangian already uses `{0}`, the name of a canonical momentum")]
    MomentumNameClash(String),
    /// The Hessian `∂²L/∂q'∂q'` (or `∂²H/∂p∂p`) is singular along a coordinate direction.
    #[error("error: the Hessian of {function} is singular: its row for `{var}` is zero (Remark 3.1: {function} is at most linear in {var}, which has no inertia, so the Legendre transform and the accelerations do not exist)")]
    SingularHessian { function: &'static str, var: String },
    /// The Hessian is singular along a combination of velocities.
    #[error("error: the Hessian of {function} is singular along the direction {direction} (Remark 3.1: no Legendre transform, the accelerations are not determined)")]
    SingularHessianDirection { function: &'static str, direction: String },
    /// The Legendre map has no closed-form inverse that this engine knows.
    #[error(
        "error: no closed-form Legendre transform: {0} (the numeric implicit Legendre map comes with the compiler)"
    )]
    NoClosedFormLegendre(String),
    /// A constraint is not of the holonomic shape `f(q, t) = 0`.
    #[error("error: constraint `{constraint}` is not holonomic: {why}")]
    NotHolonomic { constraint: String, why: String },
    /// The operation needs a Lagrangian but the system has a Hamiltonian, or vice versa.
    #[error("error: {0}")]
    WrongKind(String),
    /// `pi` (or `π`) named as a coordinate or parameter: expressions read it as the exact
    /// constant, so the name would never refer to the variable.
    #[error("error: `{0}` is the exact constant π and cannot name a coordinate or parameter (choose another name, such as phi)")]
    ConstantName(String),
    /// A parameter value was given for a name that is not a parameter.
    #[error("error: `{0}` is not a parameter of the system")]
    UnknownParameter(String),
    /// A parameter value is not finite.
    #[error("error: parameter `{name}` has the non-finite value {value}")]
    BadParameterValue { name: String, value: f64 },
    /// A point transformation is incomplete or malformed.
    #[error("error: bad transformation: {0}")]
    BadTransform(String),
    /// A generalized force names an unknown coordinate.
    #[error("error: a force is given for `{0}`, which is not a coordinate")]
    ForceOnNonCoordinate(String),
    /// The expression is undefined (it divides by zero).
    #[error("error: the {0} is undefined (it divides by zero)")]
    Undefined(&'static str),
    /// A first-order form was asked of a Lagrangian that is not linear in the velocities.
    #[error("error: the Lagrangian is not first order in the velocities: ∂L/∂{velocity} still contains a velocity (a phase-space Lagrangian is Σ a_i(z, t) z_i' − H(z, t))")]
    NotFirstOrder { velocity: String },
    /// The two-form of a first-order Lagrangian is degenerate.
    #[error("error: the two-form ω = da of this first-order Lagrangian is degenerate along {direction}: a gauge freedom or a constraint, so ω z' = ∂H/∂z does not determine z' (remove that variable or add the missing momentum term)")]
    DegenerateTwoForm { direction: String },
    /// A line element, metric or embedding that does not define a (regular, symmetric) metric.
    #[error("error: bad metric: {0}")]
    BadMetric(String),
    /// The constraints do not determine the accelerations together with `W`: the augmented
    /// matrix `[W −Φᵀ; Φ 0]` is singular (redundant constraints, or a direction that neither
    /// the inertia nor a constraint fixes).
    #[error("error: the constrained system is singular: [W −Φᵀ; Φ 0] has the null direction {direction} (are two constraints the same, or does a coordinate have neither inertia nor a constraint?)")]
    SingularConstraints { direction: String },
    /// A derivation that has no place for the system's velocity (nonholonomic) constraints:
    /// its result would be that of the unconstrained system. Such constraints are not
    /// variational (no Hamiltonian, no phase-space form, no discrete or averaged Lagrangian
    /// carries them), so the error names the routes that do keep them.
    #[error("error: {what} would leave out the velocity (nonholonomic) constraint{plural} {constraints} and give the unconstrained result; what keeps them: the Lagrange–d'Alembert equations with multipliers μ (`equations`, `lagrange_dalembert`, `el`), the accelerations with μ eliminated, `conserved`, and a simulation with a classical method (dop853, rk4, gauss6, …), which holds the run on the constraints")]
    DropsVelocityConstraints {
        /// The derivation refused (`the Hamiltonian`, `the Taylor method`).
        what: &'static str,
        /// The constraints, printed `g1 = 0, g2 = 0`.
        constraints: String,
        /// `s` for more than one constraint.
        plural: &'static str,
    },
    /// The system is too large for a closed-form symbolic inverse.
    #[error("error: {n} coupled velocities: a closed-form inverse is not formed for more than {limit} coupled ones (its size grows like n!); `el` without `--accelerations` prints W q'' = F unsolved, and a simulation (a scene's `simulate`, Python's `System.integrate`) solves it numerically at every step")]
    TooLarge { n: usize, limit: usize },
}
