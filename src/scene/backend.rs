//! What the scene asks of the library stages, behind one trait.
//!
//! The session decides *what* must be built (demand-driven) and caches it; a [`Backend`]
//! knows *how*: it calls the mechanics, canonical, compile and integrate modules. Wiring a
//! new stage is a change to [`NativeBackend`] only. Tests substitute a backend that counts
//! calls, to prove what the session does and does not build.

use std::any::Any;
use std::fmt;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use crate::expr::{Expr, Symbol};
use crate::parse::Declarations;

use super::sim::{Family, Method};
use crate::integrate::{Jacobian, Rhs, RhsError, Separable};

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
    /// `L = Σ a_i(z, t) z'_i − H(z, t)`, first order in the velocities: state `(z, z')`,
    /// `ω z' = ∂H/∂z + ∂a/∂t` integrated for `z`, the velocities filled in at kept states.
    FirstOrder(Expr),
    /// `L(q, q', t)` with generalized forces, a Rayleigh function or holonomic constraints:
    /// state `(q, q')`, accelerations from `W q'' = F` or the augmented system.
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

/// A Lagrangian with what `force`, `rayleigh` and `constraint` statements add to it.
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
    /// How a constrained run is held on its constraints.
    pub stabilization: crate::compile::Stabilization,
}

impl ExtendedLagrangian {
    /// Every expression the compiled system depends on (for cache keys and parameter checks).
    pub fn exprs(&self) -> Vec<Expr> {
        let mut v = vec![self.l.clone()];
        v.extend(self.forces.iter().cloned());
        v.extend(self.rayleigh.iter().cloned());
        v.extend(self.constraints.iter().cloned());
        v
    }
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
    /// Keep every `k`-th step (`Some(1)`: all); `None` keeps at most [`MAX_POINTS`] states
    /// (every k-th of a fixed-step run for a k chosen up front; evenly thinned as an adaptive
    /// run grows).
    pub every: Option<usize>,
    /// The conserved energy to check after every step ([`super::drift`]); `None`: unchecked.
    pub energy: Option<super::drift::EnergyCheck>,
}

impl RunRequest {
    /// The fixed step, or a thousandth of the span when none was given.
    pub fn step(&self) -> f64 {
        self.dt.unwrap_or((self.t1 - self.t0) / 1000.0)
    }

    /// The tolerance, or 1e-10 when none was given.
    pub fn tolerance(&self) -> f64 {
        self.tol.unwrap_or(1e-10)
    }
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
    /// Right-hand-side evaluations (for splitting methods, kicks: the force evaluations),
    /// counted during the run: the work axis of a work-precision diagram, deterministic
    /// where wall time is not. Jacobian evaluations of implicit methods are not included.
    pub evaluations: usize,
    /// Why the integration ended.
    pub stop: String,
    /// Further named values at each stored state, computed by the compiled system (the
    /// multipliers `λ1, …` and the constraint residuals `residual1, …` of a constrained run).
    pub aux: Vec<(String, Vec<f64>)>,
    /// The energy ledger: what [`RunRequest::energy`] saw (the session names it).
    pub energy: super::drift::Ledger,
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
    fn compile_variational(&self, req: &VariationalRequest) -> Result<Compiled, BackendError> {
        let _ = req;
        Err(BackendError::NotYetAvailable { what: "the variational equations".into(), stage: "chaos" })
    }
    /// The chaos indicators of one orbit from the canonical start `x0` over `0..t_end`, by the
    /// Taylor method at `tol` within `budget`, on a system from [`Backend::compile_variational`].
    fn indicators(
        &self,
        compiled: &Compiled,
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
    /// hold every start's samples). One at a time unless a backend does better.
    // The statement's settings (span, tolerance, budget, indicator) and the progress sink
    // are the request; a struct for them would be one more type for each backend to build.
    #[allow(clippy::too_many_arguments)]
    fn chaos_map(
        &self,
        compiled: &Compiled,
        starts: &[Vec<f64>],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
        which: crate::chaos::Indicator,
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<f64, BackendError>> {
        let n = starts.len().max(1) as f64;
        starts
            .iter()
            .enumerate()
            .map(|(k, x0)| {
                let out = self.indicators(compiled, x0, t_end, tol, budget).map(|r| r.value(which));
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

/// What [`NativeBackend::compile`] builds.
#[derive(Debug)]
pub enum NativeCompiled {
    /// Hamilton's equations with their Jacobian (implicit and explicit methods).
    Hamiltonian(crate::compile::HamiltonianRhs),
    /// Drift and kick (splitting methods).
    Separable(crate::compile::SeparableHamiltonian),
    /// `W q'' = F` (explicit and adaptive methods).
    Lagrangian(crate::compile::LagrangianRhs),
    /// `W q'' = F` with its Jacobian (implicit methods).
    LagrangianJacobian(crate::compile::LagrangianJacobian),
    /// `ω z' = b` of a first-order Lagrangian, on the `(z, z')` layout.
    FirstOrder(crate::compile::WithVelocitySlots),
    /// The augmented system of a constrained Lagrangian.
    Constrained(crate::compile::ConstrainedRhs),
    /// The variational map of a discrete Lagrangian, with the order of its rule.
    Variational(crate::compile::VariationalMap, u32),
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

fn momentum(q: &Symbol) -> Symbol {
    Symbol::new(&format!("p_{}", q.name()))
}

impl Backend for NativeBackend {
    fn euler_lagrange(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError> {
        let system = lagrangian_system(sys, l)?;
        let eqs = system.euler_lagrange().map_err(mechanics_error)?;
        let mut lines: Vec<Line> = sys
            .coords
            .iter()
            .zip(eqs)
            .map(|(q, e)| Line { label: Some(format!("E_{}", q.name())), lhs: e, rhs: Expr::zero(), note: None })
            .collect();
        // A singular W: the E_i stand, the last one carries the note saying why no
        // accelerations follow from them.
        if let Some(note) = system.hessian_note().map_err(mechanics_error)? {
            if let Some(last) = lines.last_mut() {
                last.note = Some(note.trim_start_matches("note: ").to_string());
            }
        }
        Ok(lines)
    }
    fn legendre(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
        lagrangian_system(sys, l)?.hamiltonian().map_err(mechanics_error)
    }
    fn hamilton(&self, sys: &SystemRef, h: &Expr) -> Result<Vec<Line>, BackendError> {
        let eqs = hamiltonian_system(sys, h)?.hamilton_equations().map_err(mechanics_error)?;
        let mut lines = Vec::new();
        for (q, e) in sys.coords.iter().zip(&eqs.qdot) {
            lines.push(Line { label: None, lhs: Expr::sym(q.prime()), rhs: e.clone(), note: None });
        }
        for (q, e) in sys.coords.iter().zip(&eqs.pdot) {
            lines.push(Line { label: None, lhs: Expr::sym(momentum(q).prime()), rhs: e.clone(), note: None });
        }
        Ok(lines)
    }
    fn conserved(&self, sys: &SystemRef, f: &Expr, is_hamiltonian: bool) -> Result<Vec<Line>, BackendError> {
        let system = if is_hamiltonian { hamiltonian_system(sys, f)? } else { lagrangian_system(sys, f)? };
        Ok(super::symmetries::conserved_of(&system))
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
        use crate::compile::{HamiltonianRhs, LagrangianRhs, SeparableHamiltonian};
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
            Formulation::FirstOrder(l) => {
                let system =
                    crate::mechanics::System::from_lagrangian_expr(l.clone(), &req.coords).map_err(mechanics_error)?;
                let f = system.first_order().map_err(mechanics_error)?;
                f.check_nondegenerate().map_err(mechanics_error)?;
                let rhs = crate::compile::FirstOrderRhs::new(&f.omega, &f.force, &coords, &params).map_err(failed)?;
                NativeCompiled::FirstOrder(crate::compile::WithVelocitySlots(rhs))
            }
            Formulation::Variational(l) => {
                let (map, order) = super::notes::variational_map(l, &req.coords, req.method.name, &params)?;
                NativeCompiled::Variational(map, order)
            }
            Formulation::Lagrangian(l) => {
                let system =
                    crate::mechanics::System::from_lagrangian_expr(l.clone(), &req.coords).map_err(mechanics_error)?;
                let (w, f) = system.mass_matrix_split().map_err(mechanics_error)?;
                let rhs = LagrangianRhs::new(&w, &f, &coords, &params).map_err(failed)?;
                if req.method.family == Family::Implicit {
                    NativeCompiled::LagrangianJacobian(rhs.with_jacobian().map_err(failed)?)
                } else {
                    NativeCompiled::Lagrangian(rhs)
                }
            }
            Formulation::Extended(x) => {
                let mut system = crate::mechanics::System::from_lagrangian_expr(x.l.clone(), &req.coords)
                    .map_err(mechanics_error)?;
                for (q, force) in req.coords.iter().zip(&x.forces) {
                    if !force.is_zero() {
                        system = system.with_force_expr(q.name(), force.clone()).map_err(mechanics_error)?;
                    }
                }
                if let Some(r) = &x.rayleigh {
                    system = system.with_rayleigh_expr(r.clone()).map_err(mechanics_error)?;
                }
                if x.constraints.is_empty() {
                    let (w, f) = system.mass_matrix_split().map_err(mechanics_error)?;
                    let rhs = LagrangianRhs::new(&w, &f, &coords, &params).map_err(failed)?;
                    if req.method.family == Family::Implicit {
                        NativeCompiled::LagrangianJacobian(rhs.with_jacobian().map_err(failed)?)
                    } else {
                        NativeCompiled::Lagrangian(rhs)
                    }
                } else {
                    for f in &x.constraints {
                        system = system.with_constraint_expr(f.clone()).map_err(mechanics_error)?;
                    }
                    let (w, f) = system.mass_matrix_split().map_err(mechanics_error)?;
                    NativeCompiled::Constrained(
                        crate::compile::ConstrainedRhs::new(
                            &w,
                            &f,
                            system.constraints(),
                            &req.coords,
                            &params,
                            x.stabilization,
                        )
                        .map_err(failed)?,
                    )
                }
            }
        };
        let lagrangian = matches!(
            req.formulation,
            Formulation::Lagrangian(_) | Formulation::FirstOrder(_) | Formulation::Extended(_)
        );
        // (A `Variational` state is `(q, p)`, the discrete Legendre momenta.)
        let mut state: Vec<String> = coords.iter().map(|q| q.to_string()).collect();
        state.extend(coords.iter().map(|q| if lagrangian { format!("{q}'") } else { format!("p_{q}") }));
        Ok(Arc::new(Native { rhs: compiled, events: req.events.clone(), state, params: req.params.clone() }))
    }
    fn integrate(
        &self,
        compiled: &Compiled,
        run: &RunRequest,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Trajectory, BackendError> {
        use crate::integrate::Splitting;
        let Some(native) = compiled.downcast_ref::<Native>() else {
            return Err(BackendError::Failed("internal: not a natively compiled system".into()));
        };
        let c = &native.rhs;
        let events = native.event_fns(&run.events);
        let names = &native.state;
        let count = AtomicUsize::new(0);
        let (dt, tol) = (run.step(), run.tolerance());
        if run.method.name == "taylor" {
            return taylor(c, run, tol, &events, names, progress);
        }
        match c {
            NativeCompiled::Separable(s) => {
                let m = match run.method.name {
                    "leapfrog" | "verlet" => Splitting::leapfrog(dt),
                    "yoshida4" => Splitting::yoshida4(dt),
                    "yoshida6" => Splitting::yoshida6(dt),
                    "yoshida8" => Splitting::yoshida8(dt),
                    "blanes_moan" => Splitting::blanes_moan4(dt),
                    "symplectic_euler" => Splitting::symplectic_euler(dt),
                    other => return Err(BackendError::Failed(format!("`{other}` is not a splitting method"))),
                };
                drive(&m, &Counted::new(s, &count), run, &events, names, progress)
            }
            NativeCompiled::Hamiltonian(r) => by_method(&Counted::new(r, &count), run, &events, names, progress, None),
            NativeCompiled::Lagrangian(r) => by_method(&Counted::new(r, &count), run, &events, names, progress, None),
            NativeCompiled::LagrangianJacobian(r) => {
                by_method(&Counted::new(r, &count), run, &events, names, progress, None)
            }
            NativeCompiled::Constrained(r) => {
                check_constrained_start(r, run)?;
                let project = (r.stabilization() == crate::compile::Stabilization::Projection).then_some(r);
                by_method(&Counted::new(r, &count), run, &events, names, progress, project).map(|mut t| {
                    t.aux = constrained_aux(r, &t);
                    t
                })
            }
            NativeCompiled::Variational(m, order) => {
                let before = m.evaluations();
                let stepper = crate::compile::VariationalStepper { h: dt, order: *order };
                drive(&stepper, m, run, &events, names, progress)
                    .inspect(|_| count.store(m.evaluations() - before, Ordering::Relaxed))
            }
            NativeCompiled::FirstOrder(r) => by_method(&Counted::new(r, &count), run, &events, names, progress, None)
                .and_then(|mut traj| {
                    let fill = |t: f64, y: &mut Vec<f64>| {
                        r.0.fill_velocities(t, y).map_err(|e| BackendError::Numeric(e.to_string()))
                    };
                    for (t, y) in traj.t.iter().zip(traj.y.iter_mut()) {
                        fill(*t, y)?;
                    }
                    for (_, t, y) in traj.events.iter_mut() {
                        fill(*t, y)?;
                    }
                    Ok(traj)
                }),
        }
        .map(|mut t| {
            t.evaluations = count.load(Ordering::Relaxed);
            if t.stop.is_empty() {
                t.stop = "end of the time span".into();
            }
            t
        })
    }

    fn compile_variational(&self, req: &VariationalRequest) -> Result<Compiled, BackendError> {
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
        compiled: &Compiled,
        x0: &[f64],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
    ) -> Result<crate::chaos::Indicators, BackendError> {
        let var = variational(compiled)?;
        crate::chaos::indicators_with(var, x0, t_end, tol, budget).map_err(chaos_error)
    }

    /// The starts in parallel on rayon's pool (each start on one thread, so the values do not
    /// depend on the number of threads); this thread reports progress every 50 ms.
    fn chaos_map(
        &self,
        compiled: &Compiled,
        starts: &[Vec<f64>],
        t_end: f64,
        tol: f64,
        budget: &crate::chaos::Budget,
        which: crate::chaos::Indicator,
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<f64, BackendError>> {
        let var = match variational(compiled) {
            Ok(v) => v,
            Err(e) => return starts.iter().map(|_| Err(e.clone())).collect(),
        };
        par_map_with_progress(starts, "a chaos map worker", progress, |x0| {
            crate::chaos::indicators_with(var, x0, t_end, tol, budget).map(|r| r.value(which)).map_err(chaos_error)
        })
    }

    /// The runs in parallel on rayon's pool; this thread reports how many have finished
    /// (every 50 ms) while a scoped thread waits for the pool.
    fn integrate_many(
        &self,
        compiled: &Compiled,
        runs: &[RunRequest],
        progress: &mut dyn FnMut(f64),
    ) -> Vec<Result<Trajectory, BackendError>> {
        par_map_with_progress(runs, "an ensemble worker", progress, |r| {
            NativeBackend.integrate(compiled, r, &mut |_| {})
        })
    }
}

/// The variational system inside a [`Compiled`] from [`NativeBackend::compile_variational`].
fn variational(compiled: &Compiled) -> Result<&crate::compile::Variational, BackendError> {
    compiled
        .downcast_ref::<crate::compile::Variational>()
        .ok_or_else(|| BackendError::Failed("internal: not a compiled variational system".into()))
}

/// A compiled system that counts its evaluations (see [`Trajectory::evaluations`]). One run
/// is integrated on one thread, so the count is a relaxed load and store, not a locked
/// read-modify-write: plain moves on common targets, small next to an evaluation.
struct Counted<'a, S: ?Sized> {
    inner: &'a S,
    count: &'a AtomicUsize,
}

impl<'a, S: ?Sized> Counted<'a, S> {
    fn new(inner: &'a S, count: &'a AtomicUsize) -> Self {
        Counted { inner, count }
    }
    fn bump(&self) {
        self.count.store(self.count.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
    }
}

impl<S: Rhs + ?Sized> Rhs for Counted<'_, S> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        self.bump();
        self.inner.eval(t, y, dy);
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        self.bump();
        self.inner.try_eval(t, y, dy)
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        self.inner.as_jacobian()
    }
}

impl<S: Separable + ?Sized> Separable for Counted<'_, S> {
    fn dof(&self) -> usize {
        self.inner.dof()
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        self.inner.drift(p, dq);
    }
    fn kick(&self, t: f64, q: &[f64], dp: &mut [f64]) {
        self.bump();
        self.inner.kick(t, q, dp);
    }
    fn try_drift(&self, p: &[f64], dq: &mut [f64]) -> Result<(), RhsError> {
        self.inner.try_drift(p, dq)
    }
    fn try_kick(&self, t: f64, q: &[f64], dp: &mut [f64]) -> Result<(), RhsError> {
        self.bump();
        self.inner.try_kick(t, q, dp)
    }
}

/// Event functions with their parameters bound, evaluated on the state.
type EventFns = Vec<(Box<dyn Fn(f64, &[f64]) -> f64 + Sync>, EventRequest)>;

/// A compiled right-hand side with the event functions of its run.
struct Native {
    rhs: NativeCompiled,
    events: Vec<Expr>,
    /// Plain names of the state's entries (`x`, `x'` or `p_x`).
    state: Vec<String>,
    params: Vec<(String, f64)>,
}

impl Native {
    /// Event functions evaluated by the reference evaluator (called once per step, so
    /// their cost is small next to the right-hand side's).
    fn event_fns(&self, requests: &[EventRequest]) -> EventFns {
        requests
            .iter()
            .filter_map(|r| {
                let e = self.events.get(r.index)?.clone();
                let state = self.state.clone();
                let params = self.params.clone();
                let g = move |t: f64, y: &[f64]| -> f64 {
                    crate::eval::eval_with(&e, &|s: &Symbol| {
                        if s.is_time() {
                            return Some(t);
                        }
                        let name = s.to_string();
                        if let Some(i) = state.iter().position(|n| *n == name) {
                            return y.get(i).copied();
                        }
                        params.iter().find(|(n, _)| n == s.name()).map(|(_, v)| *v)
                    })
                    .unwrap_or(f64::NAN)
                };
                Some((Box::new(g) as Box<dyn Fn(f64, &[f64]) -> f64 + Sync>, r.clone()))
            })
            .collect()
    }
}

/// Integrates with the method named in `run`; with `project`, every step is followed by a
/// projection onto those constraints ([`crate::compile::Projected`]).
fn by_method<S: crate::integrate::Rhs>(
    sys: &S,
    run: &RunRequest,
    events: &EventFns,
    names: &[String],
    progress: &mut dyn FnMut(f64),
    project: Option<&crate::compile::ConstrainedRhs>,
) -> Result<Trajectory, BackendError> {
    use crate::compile::Projected;
    use crate::integrate::{Dop853, ExplicitRk, Gauss};
    let (dt, tol) = (run.step(), run.tolerance());
    macro_rules! go {
        ($m:expr) => {
            match project {
                Some(c) => drive(&Projected { method: &$m, constraints: c }, sys, run, events, names, progress),
                None => drive(&$m, sys, run, events, names, progress),
            }
        };
    }
    match run.method.name {
        "midpoint" => go!(Gauss::midpoint(dt)),
        "gauss4" => go!(Gauss::gauss4(dt)),
        "gauss6" => go!(Gauss::gauss6(dt)),
        "euler" => go!(ExplicitRk::euler(dt)),
        "rk4" => go!(ExplicitRk::rk4(dt)),
        "dop853" => go!(Dop853::new(tol, tol)),
        other => Err(BackendError::Failed(format!("`{other}` cannot integrate this system"))),
    }
}

/// A constrained run's initial state must lie on the constraints (positions and velocities),
/// and the augmented matrix must be regular there: otherwise the run is refused before it
/// starts, naming the constraint.
fn check_constrained_start(r: &crate::compile::ConstrainedRhs, run: &RunRequest) -> Result<(), BackendError> {
    let mut dy = vec![0.0; run.y0.len()];
    r.try_eval(run.t0, &run.y0, &mut dy).map_err(|e| BackendError::Failed(format!("at the initial state: {e}")))
}

/// The multipliers and residuals of a constrained run at each stored state.
fn constrained_aux(r: &crate::compile::ConstrainedRhs, tr: &Trajectory) -> Vec<(String, Vec<f64>)> {
    let m = r.constraints();
    let mut lambda = vec![vec![0.0; tr.t.len()]; m];
    let mut resid = vec![vec![0.0; tr.t.len()]; m];
    let (mut l, mut f) = (vec![0.0; m], vec![0.0; m]);
    for (k, (t, y)) in tr.t.iter().zip(&tr.y).enumerate() {
        if r.multipliers(*t, y, &mut l).is_err() {
            l.fill(f64::NAN);
        }
        r.residuals(*t, y, &mut f);
        for (column, value) in lambda.iter_mut().zip(&l).chain(resid.iter_mut().zip(&f)) {
            column[k] = *value;
        }
    }
    let mut out = Vec::new();
    for (j, v) in lambda.into_iter().enumerate() {
        out.push((format!("λ{}", j + 1), v));
    }
    for (j, v) in resid.into_iter().enumerate() {
        out.push((format!("residual{}", j + 1), v));
    }
    out
}

/// The most states a trajectory keeps: fixed-step runs keep every k-th step for a k chosen
/// up front, adaptive runs thin as they go ([`crate::integrate::Output::AtMost`]), so the
/// memory of a run is bounded whatever its length (issue 16: an adaptive run used to keep
/// every step, and a stiff one ran the allocator dry).
pub const MAX_POINTS: usize = 20_000;

/// The step budget of an adaptive run. Fixed-step runs are refused up front by the session
/// when they need more than 10⁹ steps; an adaptive run cannot know its count, so it stops
/// here with an error that says where it got to and why (typically stiffness).
pub const MAX_ADAPTIVE_STEPS: usize = 1_000_000;

/// `name = value` pairs of a state, for error messages.
fn named_state(names: &[String], y: &[f64]) -> String {
    let parts: Vec<String> = names.iter().zip(y).map(|(n, v)| format!("{n} = {v}")).collect();
    if parts.len() == y.len() {
        parts.join(", ")
    } else {
        crate::integrate::fmt_state(y)
    }
}

/// The integrator's typed failure as the scene reports it: the time, the last good state by
/// name, the reason, and for an adaptive run that ran out of steps the likely cause.
fn numeric_error(e: crate::integrate::IntegrateError, run: &RunRequest, names: &[String]) -> BackendError {
    use crate::integrate::FailureReason;
    let mut msg = format!("integration stopped at t = {} (state {}): {}", e.t, named_state(names, &e.state), e.reason);
    if let FailureReason::StepLimit { .. } = e.reason {
        if run.method.family == Family::Adaptive {
            let done = e.t - run.t0;
            let avg = done / e.steps.max(1) as f64;
            msg.push_str(&format!(
                "; the average step was {avg:.3e} over {done:.3e} of the {:.3e} span, so the problem is stiff (or very oscillatory) at this tolerance: use an implicit method with a fixed step (`with gauss6 dt = …`), a looser `tol`, or a shorter span",
                run.t1 - run.t0
            ));
        }
    }
    BackendError::Numeric(msg)
}

/// The Taylor method on the Taylor form of a compiled system. Its work is counted in series
/// expansions (one per step), reported as [`Trajectory::evaluations`].
fn taylor(
    c: &NativeCompiled,
    run: &RunRequest,
    tol: f64,
    events: &EventFns,
    names: &[String],
    progress: &mut dyn FnMut(f64),
) -> Result<Trajectory, BackendError> {
    use crate::compile::TaylorOde;
    let ode = match c {
        NativeCompiled::Lagrangian(r) => TaylorOde::from_lagrangian(r),
        NativeCompiled::LagrangianJacobian(r) => TaylorOde::from_lagrangian(r.rhs()),
        NativeCompiled::Hamiltonian(r) => TaylorOde::from_hamiltonian(r),
        NativeCompiled::Separable(_) => {
            return Err(BackendError::Failed("`taylor` cannot integrate a drift/kick split".into()))
        }
        NativeCompiled::FirstOrder(_) | NativeCompiled::Constrained(_) | NativeCompiled::Variational(..) => {
            return Err(BackendError::Failed(
                "`taylor` does not yet integrate first-order or constrained Lagrangians: use dop853 or gauss6".into(),
            ))
        }
    };
    let method = crate::integrate::Taylor::new(tol);
    method.validate().map_err(BackendError::Failed)?;
    let mut t = drive(&method, &ode, run, events, names, progress)?;
    t.evaluations = t.steps;
    if t.stop.is_empty() {
        t.stop = "end of the time span".into();
    }
    Ok(t)
}

/// The thinning of a fixed-step run that keeps at most [`MAX_POINTS`] states (1 for an
/// adaptive run, whose count is not known in advance).
pub fn default_every(dt: Option<f64>, t0: f64, t1: f64) -> usize {
    let expected_steps = dt.map_or(MAX_POINTS, |h| ((t1 - t0) / h).ceil() as usize);
    expected_steps.div_ceil(MAX_POINTS).max(1)
}

fn drive<S: ?Sized, M: crate::integrate::Method<S>>(
    method: &M,
    sys: &S,
    run: &RunRequest,
    events: &EventFns,
    names: &[String],
    progress: &mut dyn FnMut(f64),
) -> Result<Trajectory, BackendError> {
    use crate::integrate::{Crossing, Event, Integrate, Options, StopReason};
    // The driver that locates events takes no progress callback, but it evaluates every
    // event function once per step at the step's end: one more "event" that never changes
    // sign reports the time reached, throttled to every 256th step.
    let span = run.t1 - run.t0;
    let calls = std::cell::Cell::new(0usize);
    let progress = std::cell::RefCell::new(progress);
    // The same per-step hook feeds the energy ledger (every accepted step, the initial state
    // first), so a step that jumps is seen even when the output is thinned.
    let monitor = run.energy.as_ref().map(|c| std::cell::RefCell::new(c.monitor()));
    let watch = Event::new(|t, y: &[f64]| {
        if let Some(m) = &monitor {
            m.borrow_mut().observe(t, y);
        }
        calls.set(calls.get() + 1);
        if calls.get() % 256 == 0 {
            if let Ok(mut p) = progress.try_borrow_mut() {
                p((t - run.t0) / span);
            }
        }
        1.0
    });
    // The session refuses fixed-step runs of more than 10⁹ steps before this point; an
    // adaptive run stops at its step budget, so even `every 1` keeps a bounded number.
    let budget = if run.dt.is_some() { usize::MAX } else { MAX_ADAPTIVE_STEPS };
    let mut opts = match (run.every, run.dt) {
        (Some(k), _) => Options::new().every(k.max(1)),
        (None, Some(_)) => Options::new().every(default_every(run.dt, run.t0, run.t1)),
        (None, None) => Options::new().at_most(MAX_POINTS),
    }
    .max_steps(budget)
    .event(watch);
    for (g, req) in events {
        let mut e = Event::new(|t, y: &[f64]| g(t, y)).crossing(match req.rising {
            Some(true) => Crossing::Rising,
            Some(false) => Crossing::Falling,
            None => Crossing::Either,
        });
        if req.terminal {
            e = e.stop();
        }
        opts = opts.event(e);
    }
    let tr = method.integrate_with(sys, run.t0..run.t1, &run.y0, opts).map_err(|e| numeric_error(e, run, names))?;
    (progress.into_inner())(1.0);
    let report = monitor.and_then(|m| m.into_inner().report());
    let dim = tr.dim;
    Ok(Trajectory {
        t: tr.times.clone(),
        y: tr.states.chunks(dim).map(<[f64]>::to_vec).collect(),
        // The watch is event 0 and never fires; the scene's events are numbered from 1.
        events: tr.events.iter().filter(|e| e.index > 0).map(|e| (e.index - 1, e.t, e.state.clone())).collect(),
        steps: tr.stats.steps,
        evaluations: 0,
        stop: match tr.stop {
            StopReason::ReachedEnd => "end of the time span".to_string(),
            StopReason::Event { index, t } => format!("event {} at t = {t}", index.saturating_sub(1)),
        },
        aux: Vec::new(),
        energy: match report {
            Some(report) => super::drift::Ledger::Checked { symbol: "", report },
            None => super::drift::Ledger::Unchecked,
        },
    })
}

/// `f` over `items` in parallel on rayon's pool, while this thread reports the fraction
/// finished every 50 ms. A worker that panics turns every result into an internal error
/// naming `worker` (the panic has already been printed by the hook).
/// An orbit's failure: a budget that ran out ([`crate::chaos::is_budget`]) apart from the
/// dynamics' own failures, so that a chaos map refuses it instead of leaving the cell blank.
fn chaos_error(e: crate::integrate::IntegrateError) -> BackendError {
    if crate::chaos::is_budget(&e) {
        BackendError::Budget(format!("the variational equations stopped: {e}"))
    } else {
        BackendError::Numeric(format!("the variational equations failed: {e}"))
    }
}

fn par_map_with_progress<T: Sync, R: Send>(
    items: &[T],
    worker: &str,
    progress: &mut dyn FnMut(f64),
    f: impl Fn(&T) -> Result<R, BackendError> + Sync,
) -> Vec<Result<R, BackendError>> {
    use rayon::prelude::*;
    let done = AtomicUsize::new(0);
    let n = items.len().max(1) as f64;
    std::thread::scope(|scope| {
        let work = scope.spawn(|| {
            items
                .par_iter()
                .map(|x| {
                    let out = f(x);
                    done.fetch_add(1, Ordering::Relaxed);
                    out
                })
                .collect::<Vec<_>>()
        });
        while !work.is_finished() {
            progress(done.load(Ordering::Relaxed) as f64 / n);
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        progress(1.0);
        work.join().unwrap_or_else(|_| {
            items.iter().map(|_| Err(BackendError::Failed(format!("internal: {worker} panicked")))).collect()
        })
    })
}
