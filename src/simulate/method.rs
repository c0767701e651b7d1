//! The method registry: every integration method a user can name, in one table.
//!
//! A row holds the method's name (and aliases), its scheme as data (splitting coefficients, a
//! Butcher tableau, a discrete-Lagrangian rule) or a marker for the schemes that are code
//! (DOP853, Taylor), and what it needs from the user (`dt` or `tol`). Everything else a front
//! end shows (order, symplecticity, symmetry) is read from the scheme's own data, so it cannot
//! disagree with what the integrator does. Which systems a method accepts is decided by
//! [`super::formulation::route`] from the row's [`Family`].
//!
//! Adding a data-only scheme is its coefficients in [`crate::integrate::coefficients`] plus a
//! variant and a row here.

use crate::integrate::coefficients::{self, SplittingScheme, Tableau};
use crate::integrate::{Dop853, MIN_TOL};
use crate::mechanics::Rule;

/// How a method advances the state, which decides the formulation it needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    /// Splitting (leapfrog, Yoshida): needs a conservative, separable `H = T(p) + V(q, t)`.
    Splitting,
    /// Implicit collocation (midpoint, Gauss–Legendre): any right-hand side, plus a Jacobian.
    Implicit,
    /// Explicit fixed step (Euler, RK4).
    Explicit,
    /// Adaptive with a tolerance (DOP853, Taylor).
    Adaptive,
    /// A discrete Lagrangian's map (`variational`): needs a conservative, regular `L`; state `(q, p)`.
    Variational,
}

/// What a method is, as data or as a marker for a scheme written as code.
#[derive(Clone, Copy, Debug)]
pub enum Scheme {
    /// A splitting of `H = T(p) + V(q, t)` into drifts and kicks.
    Splitting(&'static SplittingScheme),
    /// Implicit Runge–Kutta (collocation) from its tableau.
    Implicit(fn() -> Tableau),
    /// Explicit Runge–Kutta from its tableau.
    Explicit(fn() -> Tableau),
    /// Dormand–Prince 8(5,3) with step-size control.
    Dop853,
    /// The Taylor method of variable order.
    Taylor,
    /// The variational integrator of a discrete Lagrangian built by `rule`.
    Variational(Rule),
}

/// Every method a user can name. `MethodId::spec` gives its row of [`METHODS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MethodId {
    Leapfrog,
    Yoshida4,
    Yoshida6,
    KahanLi6,
    Yoshida8,
    KahanLi8,
    BlanesMoan,
    SymplecticEuler,
    Midpoint,
    Gauss4,
    Gauss6,
    Euler,
    Rk4,
    Dop853,
    Taylor,
    Variational,
    VariationalTrapezoid,
    VariationalGauss2,
}

/// One row of the registry.
#[derive(Clone, Copy, Debug)]
pub struct MethodSpec {
    /// The method.
    pub id: MethodId,
    /// Its name in the scene language, the command line and Python.
    pub name: &'static str,
    /// Other names accepted for it.
    pub aliases: &'static [&'static str],
    /// The scheme.
    pub scheme: Scheme,
}

/// Every method, in the order `help simulate` lists them (indexed by `MethodId as usize`).
pub const METHODS: &[MethodSpec] = &[
    row(MethodId::Leapfrog, "leapfrog", &["verlet"], Scheme::Splitting(&coefficients::LEAPFROG)),
    row(MethodId::Yoshida4, "yoshida4", &[], Scheme::Splitting(&coefficients::YOSHIDA4)),
    row(MethodId::Yoshida6, "yoshida6", &[], Scheme::Splitting(&coefficients::YOSHIDA6)),
    row(MethodId::KahanLi6, "kahan_li6", &[], Scheme::Splitting(&coefficients::KAHAN_LI6)),
    row(MethodId::Yoshida8, "yoshida8", &[], Scheme::Splitting(&coefficients::YOSHIDA8)),
    row(MethodId::KahanLi8, "kahan_li8", &[], Scheme::Splitting(&coefficients::KAHAN_LI8)),
    row(MethodId::BlanesMoan, "blanes_moan", &[], Scheme::Splitting(&coefficients::BLANES_MOAN4)),
    row(MethodId::SymplecticEuler, "symplectic_euler", &[], Scheme::Splitting(&coefficients::SYMPLECTIC_EULER)),
    row(MethodId::Midpoint, "midpoint", &[], Scheme::Implicit(Tableau::implicit_midpoint)),
    row(MethodId::Gauss4, "gauss4", &[], Scheme::Implicit(Tableau::gauss4)),
    row(MethodId::Gauss6, "gauss6", &[], Scheme::Implicit(Tableau::gauss6)),
    row(MethodId::Euler, "euler", &[], Scheme::Explicit(Tableau::euler)),
    row(MethodId::Rk4, "rk4", &[], Scheme::Explicit(Tableau::rk4)),
    row(MethodId::Dop853, "dop853", &[], Scheme::Dop853),
    row(MethodId::Taylor, "taylor", &[], Scheme::Taylor),
    row(MethodId::Variational, "variational", &[], Scheme::Variational(Rule::Midpoint)),
    row(MethodId::VariationalTrapezoid, "variational_trapezoid", &[], Scheme::Variational(Rule::Trapezoid)),
    row(MethodId::VariationalGauss2, "variational_gauss2", &[], Scheme::Variational(Rule::Gauss2)),
];

const fn row(id: MethodId, name: &'static str, aliases: &'static [&'static str], scheme: Scheme) -> MethodSpec {
    MethodSpec { id, name, aliases, scheme }
}

/// The default when a run names no method.
pub const DEFAULT_METHOD: MethodId = MethodId::Dop853;

/// The tolerance of an adaptive run that gives none, except the Taylor method's (below).
pub const DEFAULT_TOL: f64 = 1e-10;

/// What a method needs from the user besides the system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Needs {
    /// A fixed step `dt`.
    Step,
    /// A tolerance (it chooses its own steps).
    Tolerance,
}

/// What a method needs compiled: the same system serves every method with the same form.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Form {
    /// The right-hand side `y' = f(t, y)`.
    Rhs,
    /// The right-hand side with its exact Jacobian (implicit methods).
    RhsWithJacobian,
    /// Drift and kick of a separable `H`.
    Split,
    /// The Taylor form of the right-hand side.
    Taylor,
    /// The discrete map of a rule.
    Map(Rule),
}

impl MethodId {
    /// Every method, in table order.
    pub fn all() -> impl Iterator<Item = MethodId> {
        METHODS.iter().map(|m| m.id)
    }

    /// Its row.
    pub fn spec(self) -> &'static MethodSpec {
        &METHODS[self as usize]
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// The method called `name` (or one of its aliases).
    pub fn from_name(name: &str) -> Option<MethodId> {
        METHODS.iter().find(|m| m.name == name || m.aliases.contains(&name)).map(|m| m.id)
    }

    /// Its family.
    pub fn family(self) -> Family {
        match self.spec().scheme {
            Scheme::Splitting(_) => Family::Splitting,
            Scheme::Implicit(_) => Family::Implicit,
            Scheme::Explicit(_) => Family::Explicit,
            Scheme::Dop853 | Scheme::Taylor => Family::Adaptive,
            Scheme::Variational(_) => Family::Variational,
        }
    }

    /// Its classical order; `None` for the Taylor method, whose order follows the tolerance.
    pub fn order(self) -> Option<u32> {
        match self.spec().scheme {
            Scheme::Splitting(s) => Some(s.order),
            Scheme::Implicit(t) | Scheme::Explicit(t) => Some(t().order),
            Scheme::Dop853 => Some(8),
            Scheme::Taylor => None,
            Scheme::Variational(r) => Some(r.order()),
        }
    }

    /// Whether the step map is symplectic (for Hamiltonian systems).
    pub fn symplectic(self) -> bool {
        match self.spec().scheme {
            Scheme::Splitting(_) | Scheme::Variational(_) => true,
            Scheme::Implicit(t) | Scheme::Explicit(t) => t().symplectic,
            Scheme::Dop853 | Scheme::Taylor => false,
        }
    }

    /// Whether the step map is symmetric (time-reversible).
    pub fn symmetric(self) -> bool {
        match self.spec().scheme {
            Scheme::Splitting(s) => s.symmetric,
            Scheme::Implicit(t) | Scheme::Explicit(t) => t().symmetric,
            // Midpoint, trapezoid and Gauss discrete Lagrangians are all self-adjoint.
            Scheme::Variational(_) => true,
            Scheme::Dop853 | Scheme::Taylor => false,
        }
    }

    /// Whether it chooses its own steps.
    pub fn adaptive(self) -> bool {
        self.family() == Family::Adaptive
    }

    /// `dt` or `tol`.
    pub fn needs(self) -> Needs {
        if self.adaptive() {
            Needs::Tolerance
        } else {
            Needs::Step
        }
    }

    /// The smallest tolerance the method can meet in `f64` (adaptive methods): DOP853's is
    /// Hairer's 10·ε; the Taylor method controls the error of its series, which can go below ε.
    pub fn tolerance_floor(self) -> Option<f64> {
        match self.spec().scheme {
            Scheme::Dop853 => Some(Dop853::MIN_RTOL),
            Scheme::Taylor => Some(MIN_TOL),
            _ => None,
        }
    }

    /// The tolerance of a run that gives none: machine precision for the Taylor method (its
    /// cost grows only like ln(1/tol)), [`DEFAULT_TOL`] for the others.
    pub fn default_tolerance(self) -> Option<f64> {
        match self.spec().scheme {
            Scheme::Taylor => Some(f64::EPSILON),
            Scheme::Dop853 => Some(DEFAULT_TOL),
            _ => None,
        }
    }

    /// What it needs compiled.
    pub fn form(self) -> Form {
        match self.spec().scheme {
            Scheme::Splitting(_) => Form::Split,
            Scheme::Implicit(_) => Form::RhsWithJacobian,
            Scheme::Explicit(_) | Scheme::Dop853 => Form::Rhs,
            Scheme::Taylor => Form::Taylor,
            Scheme::Variational(r) => Form::Map(r),
        }
    }

    /// A one-line description for `help` and error messages: `gauss6 (order 6, symplectic)`.
    pub fn describe(self) -> String {
        let order = match self.order() {
            Some(p) => format!("order {p}"),
            None => "variable order".to_string(),
        };
        let mut props = vec![order];
        if self.symplectic() {
            props.push("symplectic".into());
        }
        if self.adaptive() {
            props.push("adaptive".into());
        }
        format!("{} ({})", self.name(), props.join(", "))
    }
}

/// One line per method for `help simulate` and Python's `lagrangian.METHODS` table: name
/// (aliases), order and properties, what it needs and what it integrates.
pub fn method_table() -> Vec<String> {
    METHODS
        .iter()
        .map(|m| {
            let mut name = m.name.to_string();
            for a in m.aliases {
                name.push_str(&format!(" (= {a})"));
            }
            let what = match m.id.family() {
                Family::Splitting => "splitting of a conservative, separable H = T(p) + V(q, t); state (q, p)",
                Family::Implicit => "implicit collocation of any system",
                Family::Explicit => "explicit Runge–Kutta of any system",
                Family::Adaptive if m.id == MethodId::Taylor => {
                    "Taylor series of any second-order system (constraints through the augmented system); tol defaults to machine precision"
                }
                Family::Adaptive => "embedded Runge–Kutta of any system (the default)",
                Family::Variational => "map of the discrete Lagrangian of a conservative L; state (q, p); no events",
            };
            let needs = match m.id.needs() {
                Needs::Step => "dt",
                Needs::Tolerance => "tol",
            };
            format!("{:<28} {}; {needs}; {what}", name, m.id.describe().trim_start_matches(m.name).trim())
        })
        .collect()
}

/// Every method's name, comma-separated, for messages.
pub fn method_names() -> String {
    METHODS.iter().map(|m| m.name).collect::<Vec<_>>().join(", ")
}
