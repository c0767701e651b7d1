//! Canonical transformations, Poisson brackets, Lie-series perturbation theory,
//! action-angle variables and averaged Lagrangians (PHYSICS.md §4 and §2.5).
//!
//! Everything here works on expressions over a declared [`PhaseSpace`]: coordinates `q_i`
//! and their momenta `p_i` (spelled `p_x` for a coordinate `x`), with `t` the time. The sign
//! conventions are those of PHYSICS.md: `{f, g} = Σ (∂f/∂q ∂g/∂p − ∂f/∂p ∂g/∂q)`, and the
//! generating-function table F1–F4 of §4.
//!
//! Results are exact where the normal form of [`reduce`] decides them; where it cannot, the
//! answer says so and carries a numeric check at random points ([`ZeroCheck::Numeric`]),
//! never a claim of proof.
//!
//! Submodules, one operation each:
//! * [`mod@poisson`]: brackets, `df/dt`, integrals of motion, Poisson's theorem;
//! * [`mod@solve`]: the small equation solver behind generating-function inversion;
//! * [`compact`]: the short printed forms of `K` and the maps (terms over one denominator cancelled);
//! * [`generating`]: F1–F4, their relations, inverse and forward maps, `K = H + ∂F/∂t`;
//! * [`explicit`]: canonicity of explicit maps `Q(q,p,t)`, `P(q,p,t)`;
//! * [`lie`]: Lie series `exp(ε{·,G}) f` and the flow of `H` as a series in `t`;
//! * [`action_angle`]: `J(E)` and `ω(E)` by quadrature, with turning points by root finding;
//! * rotations (an angle turning over the top, no turning points) are part of [`action_angle`];
//! * [`report`]: the printed lines of `integral`, `action`, `average`, one text for the CLI and scenes;
//! * [`symmetry`]: point symmetries of `L` by a polynomial ansatz, each charge checked by `{Q, H}`;
//! * [`average`]: the exact phase average of a trial-function Lagrangian.

use std::fmt;

use crate::expr::{Expr, Symbol};

pub mod action_angle;
pub mod average;
pub mod compact;
pub mod explicit;
pub mod generating;
pub mod lie;
pub mod poisson;
pub mod reduce;
pub mod report;
pub mod solve;
pub mod symmetry;

pub use action_angle::{action_frequency, elliptic_e, elliptic_k, ActionAngleError, ActionFrequency};
pub use average::{
    average_lagrangian, grouped, leading_order, phase_average, solve_relations, sweep, AverageError, Averaged,
    LeadingOrder, LeadingOrderError, RelationPoint, RelationsError, Sweep, Trial, MAX_AVERAGE_ORDER,
};
pub use explicit::{check_map, invert_map, BracketCheck, Canonicity, ExplicitMap, MapHamiltonianError, MapReport};
pub use generating::{GeneratedTransform, Generator, GeneratorKind, NumericMapError, Relation, TransformError};
pub use lie::{lie_flow, lie_series, lie_terms, LieError};
pub use poisson::{is_integral, poisson, time_derivative};
pub use reduce::{decide_zero, normalize, ZeroCheck};
pub use solve::{solve, solve_system, Solution, SolveError};

/// A phase space: coordinates and their conjugate momenta, in matching order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PhaseSpace {
    /// `q_1 … q_n`.
    pub coords: Vec<Symbol>,
    /// `p_1 … p_n`, `momenta[i]` conjugate to `coords[i]`.
    pub momenta: Vec<Symbol>,
}

/// A phase space whose coordinate and momentum lists differ in length, or repeat a name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PhaseSpaceError {
    /// The lists have different lengths.
    #[error("{coords} coordinates but {momenta} momenta: each coordinate needs exactly one momentum")]
    Mismatch {
        /// Number of coordinates.
        coords: usize,
        /// Number of momenta.
        momenta: usize,
    },
    /// A name is used twice.
    #[error("the phase-space variable `{0}` is declared twice")]
    Repeated(String),
    /// No variables at all.
    #[error("a phase space needs at least one coordinate")]
    Empty,
    /// A name with a look-alike character (Cyrillic `х`): the parser's message.
    #[error("{0}")]
    Lookalike(String),
}

impl PhaseSpace {
    /// Coordinates by name, with momenta spelled `p_<name>` (`x` → `p_x`).
    pub fn new<S: AsRef<str>>(coords: impl IntoIterator<Item = S>) -> Result<PhaseSpace, PhaseSpaceError> {
        let coords: Vec<String> = coords.into_iter().map(|s| s.as_ref().to_string()).collect();
        let momenta: Vec<String> = coords.iter().map(|c| format!("p_{c}")).collect();
        PhaseSpace::with_momenta(coords, momenta)
    }

    /// Coordinates and momenta named explicitly (`Q`, `P`).
    pub fn with_momenta<S: AsRef<str>, T: AsRef<str>>(
        coords: impl IntoIterator<Item = S>,
        momenta: impl IntoIterator<Item = T>,
    ) -> Result<PhaseSpace, PhaseSpaceError> {
        let coords: Vec<Symbol> = coords.into_iter().map(|s| Symbol::new(s.as_ref())).collect();
        let momenta: Vec<Symbol> = momenta.into_iter().map(|s| Symbol::new(s.as_ref())).collect();
        for s in coords.iter().chain(&momenta) {
            if let Some((c, what)) = s.name().chars().find_map(|c| crate::parse::lookalike_kind(c).map(|w| (c, w))) {
                return Err(PhaseSpaceError::Lookalike(crate::parse::lookalike_message(c, what)));
            }
        }
        if coords.is_empty() {
            return Err(PhaseSpaceError::Empty);
        }
        if coords.len() != momenta.len() {
            return Err(PhaseSpaceError::Mismatch { coords: coords.len(), momenta: momenta.len() });
        }
        let mut seen = std::collections::BTreeSet::new();
        for s in coords.iter().chain(&momenta) {
            if !seen.insert(s.name().to_string()) {
                return Err(PhaseSpaceError::Repeated(s.name().to_string()));
            }
        }
        Ok(PhaseSpace { coords, momenta })
    }

    /// Number of degrees of freedom.
    pub fn dof(&self) -> usize {
        self.coords.len()
    }

    /// `(q_i, p_i)` pairs.
    pub fn pairs(&self) -> impl Iterator<Item = (&Symbol, &Symbol)> {
        self.coords.iter().zip(&self.momenta)
    }

    /// All `2n` variables, coordinates first.
    pub fn variables(&self) -> Vec<Symbol> {
        self.coords.iter().chain(&self.momenta).cloned().collect()
    }
}

impl fmt::Display for PhaseSpace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self.pairs().map(|(q, p)| format!("({q}, {p})")).collect();
        write!(f, "{}", parts.join(", "))
    }
}

/// The time symbol `t`.
pub fn time() -> Symbol {
    Symbol::new("t")
}

/// `e` in the normal form of [`reduce::normalize`]: what results are printed in.
pub fn simplified(e: &Expr) -> Expr {
    crate::simplify::simplify(&reduce::reduce_radicals(&normalize(e)))
}
