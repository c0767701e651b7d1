//! Explicit transformations `Q = Q(q, p, t)`, `P = P(q, p, t)` and their canonicity by the
//! fundamental brackets (PHYSICS.md §4.6.2): `{Q_i, P_j} = δ_ij`, `{Q_i, Q_j} = {P_i, P_j} = 0`.
//!
//! Each bracket is decided by [`decide_zero`]; when the normal form cannot decide, the report
//! says so and carries the numeric check (never a proof). A map that fails a bracket is
//! reported as not canonical with the offending bracket and a point where it fails.

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::poisson::poisson_raw;
use super::reduce::{decide_zero, normalize, tidy, ZeroCheck};
use super::solve::{solve_system, SolveError};
use super::{time, PhaseSpace};

/// A map from `old` to `new` variables given explicitly.
#[derive(Clone, Debug)]
pub struct ExplicitMap {
    /// Old variables `(q, p)`.
    pub old: PhaseSpace,
    /// New variables `(Q, P)`.
    pub new: PhaseSpace,
    /// `Q_i(q, p, t)`, in the order of `new.coords`.
    pub q_new: Vec<Expr>,
    /// `P_i(q, p, t)`, in the order of `new.momenta`.
    pub p_new: Vec<Expr>,
}

/// The verdict on canonicity.
#[derive(Clone, Debug, PartialEq)]
pub enum Canonicity {
    /// Every fundamental bracket reduced to its value symbolically.
    Proven,
    /// Some bracket could not be decided symbolically but holds numerically at random points.
    NumericOnly {
        /// Points evaluated per undecided bracket.
        points: usize,
        /// Largest deviation seen.
        max_residual: f64,
    },
    /// Not canonical: the first bracket that fails.
    NotCanonical {
        /// The bracket, e.g. `{Q, P}`.
        bracket: String,
        /// Its value (normal form).
        value: Expr,
        /// What it should be.
        expected: Expr,
    },
    /// No bracket failed, but one could be neither simplified nor evaluated.
    Undecided {
        /// The bracket.
        bracket: String,
    },
}

impl Canonicity {
    /// Whether the map is canonical (proven or numerically).
    pub fn is_canonical(&self) -> bool {
        matches!(self, Canonicity::Proven | Canonicity::NumericOnly { .. })
    }
    /// A one-line description for people.
    pub fn describe(&self) -> String {
        match self {
            Canonicity::Proven => "canonical (all fundamental brackets proven symbolically)".into(),
            Canonicity::NumericOnly { points, max_residual } => format!(
                "canonical numerically only: simplification could not decide every bracket; they hold to {max_residual:.1e} at {points} random points (not a proof)"
            ),
            Canonicity::NotCanonical { bracket, value, expected } => {
                format!("not canonical: {bracket} = {value}, but a canonical map needs {expected}")
            }
            Canonicity::Undecided { bracket } => format!("undecided: {bracket} could not be simplified or evaluated"),
        }
    }
}

/// One fundamental bracket and its check.
#[derive(Clone, Debug)]
pub struct BracketCheck {
    /// `{Q, P}` and so on.
    pub name: String,
    /// The value in normal form.
    pub value: Expr,
    /// The value a canonical map has (`0` or `1`).
    pub expected: Expr,
    /// How `value − expected = 0` was decided.
    pub check: ZeroCheck,
}

/// Why the new Hamiltonian was not produced.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MapHamiltonianError {
    /// The map is not canonical, so there is no `K`.
    #[error("the map is not canonical, so it has no new Hamiltonian")]
    NotCanonical,
    /// Explicitly time-dependent maps need the generating function's `∂F/∂t`.
    #[error("the map depends on t explicitly: K = H + ∂F/∂t needs a generating function (use `canonical --f1/--f2/--f3/--f4`)")]
    TimeDependent,
    /// The map could not be inverted in closed form.
    #[error("cannot express H in the new variables: {0}")]
    Inversion(#[from] SolveError),
}

/// The canonicity report.
#[derive(Clone, Debug)]
pub struct MapReport {
    /// Every fundamental bracket.
    pub brackets: Vec<BracketCheck>,
    /// The verdict.
    pub canonicity: Canonicity,
    /// `(q, p)` in terms of `(Q, P)` when a Hamiltonian was asked for.
    pub inverse: Option<Result<Vec<(Symbol, Expr)>, SolveError>>,
    /// The new Hamiltonian `K(Q, P)` when asked for and the map is canonical.
    pub hamiltonian: Option<Result<Expr, MapHamiltonianError>>,
}

/// Checks the fundamental brackets of `map` and, given `h`, expresses it in the new variables.
#[allow(clippy::needless_range_loop)] // i, j index Q, P and the map's expressions alike
pub fn check_map(map: &ExplicitMap, h: Option<&Expr>) -> MapReport {
    let mut d = Differentiator::new();
    // Guard against inconsistent lengths (a library caller's map): compare what exists.
    let n = map.q_new.len().min(map.p_new.len()).min(map.new.coords.len()).min(map.new.momenta.len());
    let mut brackets = Vec::new();
    let mut push = |name: String, f: &Expr, g: &Expr, expected: Expr, d: &mut Differentiator| {
        let raw = poisson_raw(f, g, &map.old, d);
        let value = normalize(&raw);
        let check = decide_zero(&value.minus(&expected));
        // A bracket proven equal to its expected value is that value, and prints as it (the
        // implicit midpoint map's {Q, P} is 1, not four terms over (h²/4 + 1)²); otherwise
        // the shorter of the normal form and the simplifier's.
        let value = if check == ZeroCheck::Proven {
            expected.clone()
        } else {
            let simple = crate::simplify::simplify(&value);
            if simple.op_count() < value.op_count() {
                simple
            } else {
                value
            }
        };
        brackets.push(BracketCheck { name, value, expected, check });
    };
    let (qs, ps) = (&map.new.coords, &map.new.momenta);
    for i in 0..n {
        for j in 0..n {
            let expected = if i == j { Expr::one() } else { Expr::zero() };
            push(format!("{{{}, {}}}", qs[i], ps[j]), &map.q_new[i], &map.p_new[j], expected, &mut d);
        }
    }
    for i in 0..n {
        for j in i + 1..n {
            push(format!("{{{}, {}}}", qs[i], qs[j]), &map.q_new[i], &map.q_new[j], Expr::zero(), &mut d);
            push(format!("{{{}, {}}}", ps[i], ps[j]), &map.p_new[i], &map.p_new[j], Expr::zero(), &mut d);
        }
    }
    let mut canonicity = Canonicity::Proven;
    let mut worst: f64 = 0.0;
    let mut points = 0;
    for b in &brackets {
        match &b.check {
            ZeroCheck::Proven => {}
            ZeroCheck::Numeric { points: p, max_residual } => {
                worst = worst.max(*max_residual);
                points = *p;
                if canonicity == Canonicity::Proven {
                    canonicity = Canonicity::NumericOnly { points, max_residual: worst };
                }
            }
            ZeroCheck::NonZero { .. } => {
                canonicity = Canonicity::NotCanonical {
                    bracket: b.name.clone(),
                    value: b.value.clone(),
                    expected: b.expected.clone(),
                };
                break;
            }
            ZeroCheck::Undecided => {
                if canonicity.is_canonical() {
                    canonicity = Canonicity::Undecided { bracket: b.name.clone() };
                }
            }
        }
    }
    if let Canonicity::NumericOnly { .. } = canonicity {
        canonicity = Canonicity::NumericOnly { points, max_residual: worst };
    }
    let (inverse, hamiltonian) = match h {
        None => (None, None),
        Some(h) => {
            let inv = invert_map(map);
            let k = if !canonicity.is_canonical() {
                Err(MapHamiltonianError::NotCanonical)
            } else if map.q_new.iter().chain(&map.p_new).any(|e| e.contains(&time())) {
                Err(MapHamiltonianError::TimeDependent)
            } else {
                match &inv {
                    Ok(sol) => {
                        let m: std::collections::HashMap<Symbol, Expr> = sol.iter().cloned().collect();
                        Ok(normalize(&tidy(&h.subs(&m))))
                    }
                    Err(e) => Err(MapHamiltonianError::Inversion(e.clone())),
                }
            };
            (Some(inv), Some(k))
        }
    };
    MapReport { brackets, canonicity, inverse, hamiltonian }
}

/// `(q, p)` as functions of `(Q, P, t)`, by the equation solver.
pub fn invert_map(map: &ExplicitMap) -> Result<Vec<(Symbol, Expr)>, SolveError> {
    let mut eqs = Vec::new();
    for (s, e) in map.new.coords.iter().zip(&map.q_new).chain(map.new.momenta.iter().zip(&map.p_new)) {
        eqs.push(Expr::sym(s.clone()).minus(e));
    }
    let (sol, _) = solve_system(&eqs, &map.old.variables())?;
    Ok(sol.into_iter().map(|(s, v)| (s, normalize(&v))).collect())
}
