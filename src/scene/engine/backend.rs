//! What the scene asks of the library stages, behind one trait.
//!
//! The session decides *what* must be built (demand-driven) and caches it; a [`Backend`]
//! knows *how*: it calls the mechanics, canonical, compile and integrate modules. Wiring a
//! new stage is a change to [`NativeBackend`] only. Tests substitute a backend that counts
//! calls, to prove what the session does and does not build.

use std::fmt;
use std::sync::Arc;

use crate::expr::{Expr, Symbol};
use crate::parse::Declarations;
use crate::simulate::{self, RunOptions, SimulateError};

pub use crate::simulate::{CompileRequest, ExtendedLagrangian, Formulation, Trajectory};

pub use crate::report::Line;

/// Why a backend could not do something.
#[derive(Clone, Debug, PartialEq)]
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
    /// The simulation layer refused or failed, with its typed reason.
    Simulate(SimulateError),
    /// A step or time budget ran out ([`crate::chaos::Budget`]); the message names it.
    Budget(String),
}

impl fmt::Display for BackendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BackendError::NotYetAvailable { what, stage } => {
                write!(f, "{what} is not yet available (it needs the {stage} stage, which is still being built)")
            }
            BackendError::Failed(m) | BackendError::Numeric(m) | BackendError::Budget(m) => f.write_str(m),
            BackendError::Simulate(e) => write!(f, "{e}"),
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
    /// The generalized force on each coordinate (empty, or one per coordinate, zero where
    /// none): `el`, `hamilton` and `conserved` include them.
    pub forces: &'a [Expr],
    /// The Rayleigh dissipation function, if declared.
    pub rayleigh: Option<&'a Expr>,
    /// Holonomic constraints `f_j(q, t) = 0`.
    pub constraints: &'a [Expr],
}

impl<'a> SystemRef<'a> {
    /// A system with no forces, dissipation or constraints.
    pub fn closed(coords: &'a [Symbol], decls: &'a Declarations) -> SystemRef<'a> {
        SystemRef { coords, decls, forces: &[], rayleigh: None, constraints: &[] }
    }
}

/// What the chaos statements compile: the variational equations of `H` (Hamilton's
/// equations, `tangents` tangent vectors under the exact Jacobian and, with `megno`, MEGNO's
/// accumulator), in the canonical state `(q, p)`.
#[derive(Clone, Debug)]
pub struct VariationalRequest {
    /// Coordinates in order (the momenta are `p_q`).
    pub coords: Vec<Symbol>,
    /// `H(q, p)`.
    pub h: Expr,
    /// Parameter values, by plain name.
    pub params: Vec<(String, f64)>,
    /// How many tangent vectors ride along (1 for MEGNO and FLI, `2n` for the spectrum).
    pub tangents: usize,
    /// Whether MEGNO's accumulator is part of the state.
    pub megno: bool,
}

/// One integration: the initial state and the library's run options.
#[derive(Clone, Debug)]
pub struct RunRequest {
    /// The initial state, in the compiled system's layout.
    pub y0: Vec<f64>,
    /// Method, span, step or tolerance, events, sampling, energy check.
    pub options: RunOptions,
}

/// A compiled system ([`crate::simulate::Compiled`]), shared by the runs that use it.
pub type Compiled = Arc<simulate::Compiled>;

/// The compiled variational equations of the chaos statements.
pub type CompiledVariational = Arc<crate::compile::Variational>;

/// The library stages as the scene sees them.
pub trait Backend {
    /// The Euler–Lagrange equations `E_i = Q_i − ∂R/∂q'_i + Σ λ_j ∂f_j/∂q_i`, one line per
    /// coordinate ([`crate::report::euler_lagrange`]), with the system's forces, dissipation and
    /// constraints.
    fn euler_lagrange(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError>;
    /// The Legendre transform `H(q, p, t)` of `L`.
    fn legendre(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError>;
    /// Hamilton's equations `q' = ∂H/∂p`, `p' = −∂H/∂q` (+ the driving terms)
    /// ([`crate::report::hamilton`]).
    fn hamilton(&self, sys: &SystemRef, h: &Expr) -> Result<Vec<Line>, BackendError>;
    /// Conserved quantities of `L` (`is_hamiltonian` false) or `H`, each with its reason, and
    /// the candidates the forces break ([`crate::report::conserved`]).
    fn conserved(&self, sys: &SystemRef, f: &Expr, is_hamiltonian: bool) -> Result<Vec<Line>, BackendError>;
    /// The accelerations `q'' = …` of `L` with the system's forces and dissipation; with
    /// constraints the constrained ones and the multipliers `λ_j = …`
    /// ([`crate::report::accelerations`]).
    fn accelerations(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError> {
        let _ = (sys, l);
        Err(BackendError::NotYetAvailable { what: "the accelerations".into(), stage: "mechanics" })
    }
    /// The energy function `h = Σ q' ∂L/∂q' − L` of a Lagrangian.
    fn energy(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError>;
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
    /// Compiles the variational equations for the chaos statements (`lyapunov`, `megno`,
    /// `fli`, `chaos_map`).
    fn compile_variational(&self, req: &VariationalRequest) -> Result<CompiledVariational, BackendError> {
        let _ = req;
        Err(BackendError::NotYetAvailable { what: "the variational equations".into(), stage: "chaos" })
    }
    /// The chaos indicators of one orbit from the canonical start `x0` over `0..t_end`, by the
    /// Taylor method at `tol` within `budget`, on a system from [`Backend::compile_variational`].
    fn indicators(
        &self,
        compiled: &CompiledVariational,
        x0: &[f64],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
    ) -> Result<crate::chaos::Indicators, BackendError> {
        let _ = (compiled, x0, t_end, tol, budget);
        Err(BackendError::NotYetAvailable { what: "chaos indicators".into(), stage: "chaos" })
    }
    /// One indicator from each of many starts (a chaos map); `progress` receives the fraction
    /// of starts finished. Only the final value is kept per start (a 200 × 200 map would not
    /// hold every start's samples), with when the budget's MEGNO stop ended it early (so a
    /// stopped cell is never read as a value at `t_end`). One at a time unless a backend does
    /// better.
    // The statement's settings (span, tolerance, budget, indicator) and the progress sink
    // are the request; a struct for them would be one more type for each backend to build.
    #[allow(clippy::too_many_arguments)]
    fn chaos_map(
        &self,
        compiled: &CompiledVariational,
        starts: &[Vec<f64>],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
        which: crate::chaos::Indicator,
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<crate::chaos::Cell, BackendError>> {
        let n = starts.len().max(1) as f64;
        starts
            .iter()
            .enumerate()
            .map(|(k, x0)| {
                let out = self.indicators(compiled, x0, t_end, tol, budget).map(|r| r.cell(which));
                progress((k + 1) as f64 / n);
                out
            })
            .collect()
    }
    /// Integrates one compiled system from several initial states (an ensemble); `progress`
    /// receives the fraction of runs finished. One at a time unless a backend does better.
    fn integrate_many(
        &self,
        compiled: &Compiled,
        runs: &[RunRequest],
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<Trajectory, BackendError>> {
        let n = runs.len().max(1) as f64;
        runs.iter()
            .enumerate()
            .map(|(k, r)| {
                let out = self.integrate(compiled, r, &mut |_| {});
                progress((k + 1) as f64 / n);
                out
            })
            .collect()
    }
}

/// The real library.
#[derive(Clone, Copy, Debug, Default)]
pub struct NativeBackend;

fn mechanics_error(e: crate::mechanics::MechanicsError) -> BackendError {
    BackendError::Failed(e.to_string())
}

fn lagrangian_system(sys: &SystemRef, l: &Expr) -> Result<crate::mechanics::System, BackendError> {
    crate::mechanics::System::from_lagrangian_expr(l.clone(), sys.coords).map_err(mechanics_error)
}

fn hamiltonian_system(sys: &SystemRef, h: &Expr) -> Result<crate::mechanics::System, BackendError> {
    crate::mechanics::System::from_hamiltonian_expr(h.clone(), sys.coords).map_err(mechanics_error)
}

/// `system` with the forces, Rayleigh function and constraints of `sys`.
fn with_dynamics(
    mut system: crate::mechanics::System,
    sys: &SystemRef,
) -> Result<crate::mechanics::System, BackendError> {
    for (q, force) in sys.coords.iter().zip(sys.forces) {
        if !force.is_zero() {
            system = system.with_force_expr(q.name(), force.clone()).map_err(mechanics_error)?;
        }
    }
    if let Some(r) = sys.rayleigh {
        system = system.with_rayleigh_expr(r.clone()).map_err(mechanics_error)?;
    }
    for f in sys.constraints {
        system = system.with_constraint_expr(f.clone()).map_err(mechanics_error)?;
    }
    Ok(system)
}

impl Backend for NativeBackend {
    fn euler_lagrange(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError> {
        let system = with_dynamics(lagrangian_system(sys, l)?, sys)?;
        crate::report::euler_lagrange(&system).map_err(mechanics_error)
    }
    fn legendre(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
        lagrangian_system(sys, l)?.hamiltonian().map_err(mechanics_error)
    }
    fn accelerations(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError> {
        let system = with_dynamics(lagrangian_system(sys, l)?, sys)?;
        crate::report::accelerations(&system).map_err(mechanics_error)
    }
    fn hamilton(&self, sys: &SystemRef, h: &Expr) -> Result<Vec<Line>, BackendError> {
        let system = with_dynamics(hamiltonian_system(sys, h)?, sys)?;
        crate::report::hamilton(&system).map_err(mechanics_error)
    }
    fn conserved(&self, sys: &SystemRef, f: &Expr, is_hamiltonian: bool) -> Result<Vec<Line>, BackendError> {
        let system = if is_hamiltonian { hamiltonian_system(sys, f)? } else { lagrangian_system(sys, f)? };
        Ok(crate::report::conserved(&with_dynamics(system, sys)?))
    }
    fn energy(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
        Ok(lagrangian_system(sys, l)?.energy_function())
    }
    fn bracket(&self, sys: &SystemRef, f: &Expr, g: &Expr) -> Result<Expr, BackendError> {
        let names: Vec<&str> = sys.coords.iter().map(|q| q.name()).collect();
        let ps = crate::canonical::PhaseSpace::new(names).map_err(|e| BackendError::Failed(e.to_string()))?;
        Ok(crate::canonical::poisson(f, g, &ps))
    }
    fn compile(&self, req: &CompileRequest) -> Result<Compiled, BackendError> {
        simulate::compile(req).map(Arc::new).map_err(BackendError::Simulate)
    }
    fn integrate(
        &self,
        compiled: &Compiled,
        run: &RunRequest,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Trajectory, BackendError> {
        simulate::integrate(compiled, &run.y0, &run.options, progress).map_err(BackendError::Simulate)
    }

    fn compile_variational(&self, req: &VariationalRequest) -> Result<CompiledVariational, BackendError> {
        let q: Vec<&str> = req.coords.iter().map(|c| c.name()).collect();
        let p_owned: Vec<String> = q.iter().map(|c| format!("p_{c}")).collect();
        let p: Vec<&str> = p_owned.iter().map(String::as_str).collect();
        let params: Vec<(&str, f64)> = req.params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let var = crate::compile::Variational::hamiltonian(&req.h, &q, &p, &params, req.tangents, req.megno)
            .map_err(|e| BackendError::Failed(format!("cannot compile the variational equations: {e}")))?;
        Ok(Arc::new(var))
    }

    fn indicators(
        &self,
        compiled: &CompiledVariational,
        x0: &[f64],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
    ) -> Result<crate::chaos::Indicators, BackendError> {
        crate::chaos::indicators_with(compiled, x0, t_end, tol, budget).map_err(chaos_error)
    }

    /// The starts in parallel on rayon's pool, in lane groups of the Taylor method's batch mode
    /// where it pays (each start's value is that of its run alone, so the values do not depend
    /// on the number of threads or lanes); this thread reports progress every 50 ms.
    fn chaos_map(
        &self,
        compiled: &CompiledVariational,
        starts: &[Vec<f64>],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
        which: crate::chaos::Indicator,
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<crate::chaos::Cell, BackendError>> {
        let var = &**compiled;
        let done = std::sync::atomic::AtomicUsize::new(0);
        simulate::with_progress(&done, starts.len(), progress, || {
            crate::chaos::indicators_map_counting(var, starts, t_end, tol, budget, &done)
                .into_iter()
                .map(|r| r.map(|r| r.cell(which)).map_err(chaos_error))
                .collect()
        })
        .unwrap_or_else(|_| {
            starts.iter().map(|_| Err(BackendError::Failed("internal: a chaos map worker panicked".into()))).collect()
        })
    }

    /// The runs in parallel on rayon's pool; this thread reports how many have finished
    /// (every 50 ms). The runs share their options (an ensemble differs only in its starts).
    fn integrate_many(
        &self,
        compiled: &Compiled,
        runs: &[RunRequest],
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<Trajectory, BackendError>> {
        let Some(first) = runs.first() else { return Vec::new() };
        let starts: Vec<Vec<f64>> = runs.iter().map(|r| r.y0.clone()).collect();
        simulate::ensemble(compiled, &starts, &first.options, None, progress)
            .into_iter()
            .map(|r| r.map_err(BackendError::Simulate))
            .collect()
    }
}

/// An orbit's failure: a budget that ran out ([`crate::chaos::is_budget`]) apart from the
/// dynamics' own failures, so that a chaos map refuses it instead of leaving the cell blank.
fn chaos_error(e: crate::integrate::IntegrateError) -> BackendError {
    if crate::chaos::is_budget(&e) {
        BackendError::Budget(format!("the variational equations stopped: {e}"))
    } else {
        BackendError::Numeric(format!("the variational equations failed: {e}"))
    }
}
