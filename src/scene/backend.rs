//! What the scene asks of the library stages, behind one trait.
//!
//! The session decides *what* must be built (demand-driven) and caches it; a [`Backend`]
//! knows *how*: it calls the mechanics, canonical, compile and integrate modules. Wiring a
//! new stage is a change to [`NativeBackend`] only. Tests substitute a backend that counts
//! calls, to prove what the session does and does not build.

use std::any::Any;
use std::fmt;
use std::sync::Arc;

use crate::expr::{Expr, Symbol};
use crate::parse::Declarations;

use super::sim::Method;

/// One printed line of a derivation: `lhs = rhs`, with an optional label (`E_θ`, a reason).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Line {
    /// A label printed before the equation (`E_θ`), if any.
    pub label: Option<String>,
    /// The left side.
    pub lhs: Expr,
    /// The right side.
    pub rhs: Expr,
    /// A note printed after it (why a quantity is conserved).
    pub note: Option<String>,
}

/// Why a backend could not do something.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BackendError {
    /// The library stage is not built yet.
    NotYetAvailable {
        /// What was asked for.
        what: String,
        /// Which stage provides it.
        stage: &'static str,
    },
    /// The stage refused the input (singular Hessian, non-canonical map, …).
    Failed(String),
    /// The integration stopped with an error (at a time, with a reason).
    Numeric(String),
}

impl fmt::Display for BackendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BackendError::NotYetAvailable { what, stage } => {
                write!(f, "{what} is not yet available (it needs the {stage} stage, which is still being built)")
            }
            BackendError::Failed(m) | BackendError::Numeric(m) => f.write_str(m),
        }
    }
}

/// The symbolic system handed to derivations.
#[derive(Clone, Debug)]
pub struct SystemRef<'a> {
    /// Coordinates in declaration order.
    pub coords: &'a [Symbol],
    /// How the text was parsed (functions, positive symbols).
    pub decls: &'a Declarations,
}

/// The equations of motion a simulation integrates.
#[derive(Clone, Debug)]
pub enum Formulation {
    /// `L(q, q', t)`: state `(q, q')`, accelerations from `W q'' = F`.
    Lagrangian(Expr),
    /// `H(q, p, t)`: state `(q, p)`, Hamilton's equations.
    Hamiltonian(Expr),
    /// `H = T(p) + V(q, t)`: drift and kick for splitting methods.
    Separable {
        /// The kinetic part `T(p)`.
        t: Expr,
        /// The potential part `V(q, t)`.
        v: Expr,
    },
}

/// What to compile: the formulation with its parameters bound.
#[derive(Clone, Debug)]
pub struct CompileRequest {
    /// Coordinates in order (the state is `(q…, v…)`).
    pub coords: Vec<Symbol>,
    /// The equations.
    pub formulation: Formulation,
    /// Parameter values, by plain name.
    pub params: Vec<(String, f64)>,
    /// The method the result is for (implicit methods want a Jacobian).
    pub method: Method,
    /// Event functions (zero crossings), in the state's variables.
    pub events: Vec<Expr>,
    /// Declarations the expressions were parsed with.
    pub decls: Declarations,
}

/// An event during integration.
#[derive(Clone, Debug, PartialEq)]
pub struct EventRequest {
    /// Index into [`CompileRequest::events`].
    pub index: usize,
    /// Stop the integration at the first crossing.
    pub terminal: bool,
    /// Only upward (`Some(true)`) or downward crossings.
    pub rising: Option<bool>,
}

/// One integration.
#[derive(Clone, Debug)]
pub struct RunRequest {
    /// The method.
    pub method: Method,
    /// The initial state `(q…, v…)`.
    pub y0: Vec<f64>,
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t1: f64,
    /// Fixed step (fixed-step methods).
    pub dt: Option<f64>,
    /// Tolerance (adaptive methods).
    pub tol: Option<f64>,
    /// Events.
    pub events: Vec<EventRequest>,
}

/// A computed trajectory.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    /// Times of the stored states.
    pub t: Vec<f64>,
    /// States `(q…, v…)`, one per time.
    pub y: Vec<Vec<f64>>,
    /// Recorded events: which event, when, and the state there.
    pub events: Vec<(usize, f64, Vec<f64>)>,
    /// Steps taken.
    pub steps: usize,
    /// Why the integration ended.
    pub stop: String,
}

/// A compiled system, opaque to the session (the backend downcasts it).
pub type Compiled = Arc<dyn Any + Send + Sync>;

/// The library stages as the scene sees them.
pub trait Backend {
    /// Euler–Lagrange expressions `E_i = d/dt ∂L/∂q'_i − ∂L/∂q_i`, one line per coordinate.
    fn euler_lagrange(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError>;
    /// The Legendre transform `H(q, p, t)` of `L`.
    fn legendre(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError>;
    /// Hamilton's equations `q' = ∂H/∂p`, `p' = −∂H/∂q`.
    fn hamilton(&self, sys: &SystemRef, h: &Expr) -> Result<Vec<Line>, BackendError>;
    /// Conserved quantities of `L` (`is_hamiltonian` false) or `H`, each with its reason.
    fn conserved(&self, sys: &SystemRef, f: &Expr, is_hamiltonian: bool) -> Result<Vec<Line>, BackendError>;
    /// The Poisson bracket `{f, g}` over the coordinates and their momenta `p_q`.
    fn bracket(&self, sys: &SystemRef, f: &Expr, g: &Expr) -> Result<Expr, BackendError>;
    /// Compiles a right-hand side.
    fn compile(&self, req: &CompileRequest) -> Result<Compiled, BackendError>;
    /// Integrates a compiled system; `progress` receives the fraction done.
    fn integrate(
        &self,
        compiled: &Compiled,
        run: &RunRequest,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Trajectory, BackendError>;
}

/// What [`NativeBackend::compile`] builds.
#[derive(Debug)]
pub enum NativeCompiled {
    /// Hamilton's equations with their Jacobian (implicit and explicit methods).
    Hamiltonian(crate::compile::HamiltonianRhs),
    /// Drift and kick (splitting methods).
    Separable(crate::compile::SeparableHamiltonian),
}

/// The real library.
#[derive(Clone, Copy, Debug, Default)]
pub struct NativeBackend;

const MECHANICS: &str = "mechanics (issue 3)";
const NUMERICS: &str = "compile and integrate (issue 5)";

fn not_yet(what: &str, stage: &'static str) -> BackendError {
    BackendError::NotYetAvailable { what: what.to_string(), stage }
}

impl Backend for NativeBackend {
    fn euler_lagrange(&self, _sys: &SystemRef, _l: &Expr) -> Result<Vec<Line>, BackendError> {
        Err(not_yet("`el` (Euler–Lagrange equations)", MECHANICS))
    }
    fn legendre(&self, _sys: &SystemRef, _l: &Expr) -> Result<Expr, BackendError> {
        Err(not_yet("`legendre` (the Legendre transform)", MECHANICS))
    }
    fn hamilton(&self, _sys: &SystemRef, _h: &Expr) -> Result<Vec<Line>, BackendError> {
        Err(not_yet("`hamilton` (Hamilton's equations)", MECHANICS))
    }
    fn conserved(&self, _sys: &SystemRef, _f: &Expr, _is_h: bool) -> Result<Vec<Line>, BackendError> {
        Err(not_yet("`conserved` (Noether's theorem)", MECHANICS))
    }
    fn bracket(&self, sys: &SystemRef, f: &Expr, g: &Expr) -> Result<Expr, BackendError> {
        let names: Vec<&str> = sys.coords.iter().map(|q| q.name()).collect();
        let ps = crate::canonical::PhaseSpace::new(names).map_err(|e| BackendError::Failed(e.to_string()))?;
        Ok(crate::canonical::poisson(f, g, &ps))
    }
    fn compile(&self, req: &CompileRequest) -> Result<Compiled, BackendError> {
        use crate::compile::{HamiltonianRhs, SeparableHamiltonian};
        let coords: Vec<&str> = req.coords.iter().map(|q| q.name()).collect();
        let momenta_owned: Vec<String> = coords.iter().map(|q| format!("p_{q}")).collect();
        let momenta: Vec<&str> = momenta_owned.iter().map(String::as_str).collect();
        let params: Vec<(&str, f64)> = req.params.iter().map(|(n, v)| (n.as_str(), *v)).collect();
        let failed = |e: crate::compile::CompileError| BackendError::Failed(e.to_string());
        let compiled: NativeCompiled = match &req.formulation {
            Formulation::Separable { t, v } => NativeCompiled::Separable(
                SeparableHamiltonian::new(&t.plus(v), &coords, &momenta, &params).map_err(failed)?,
            ),
            Formulation::Hamiltonian(h) => {
                NativeCompiled::Hamiltonian(HamiltonianRhs::new(h, &coords, &momenta, &params).map_err(failed)?)
            }
            Formulation::Lagrangian(_) => {
                return Err(not_yet("integrating `L` directly (its mass matrix W and forces F)", MECHANICS))
            }
        };
        Ok(Arc::new(compiled))
    }
    fn integrate(
        &self,
        _compiled: &Compiled,
        _run: &RunRequest,
        _progress: &mut dyn FnMut(f64),
    ) -> Result<Trajectory, BackendError> {
        Err(not_yet("`simulate` (integrators)", NUMERICS))
    }
}
