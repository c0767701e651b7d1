//! The session's data: what a scene has declared, defined and run so far, and what it has
//! written. Statements read and change it through `impl Session` blocks in `statements/`;
//! where a statement is (its line and span) is passed to them as an [`At`], never kept here.

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::path::PathBuf;
use std::sync::Arc;

use miette::NamedSource;

use super::engine::backend::{Backend, BackendError, Line, NativeBackend, Trajectory};
use super::engine::output::Staging;
use super::engine::plan::PlanEntry;
use super::engine::progress::Draw;
use super::syntax::ast::{DerivKind, SimSpec, Src};
use super::syntax::error::{ErrorKind, SceneError, Span};
use crate::cache::{Cache, CacheKey, Value};
use crate::chaos::{Indicator, Indicators};
use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::print::Format;
use crate::simulate::MethodId;

/// Where the statement being run is: its line (for the plan) and its span (for errors).
/// Handlers take it as an argument, so what an error points at is visible at the call.
#[derive(Clone, Copy, Debug)]
pub(super) struct At {
    pub(super) line: usize,
    pub(super) span: Span,
}

/// A parameter: a symbol with an optional value.
#[derive(Clone, Debug)]
pub(super) struct Param {
    pub(super) value: Option<f64>,
    pub(super) positive: bool,
}

/// A reference from an expression to a definition it uses.
pub(super) type Refs = Vec<(Symbol, usize)>;

#[derive(Clone)]
pub(super) enum DefBody {
    Expr { raw: Expr, refs: Refs },
    Deriv { kind: DerivKind, args: Vec<(Expr, Refs)>, span: Span },
}

pub(super) struct DefEntry {
    pub(super) name: String,
    pub(super) body: DefBody,
    pub(super) line: usize,
    pub(super) value: Option<Value>,
    pub(super) demanded: bool,
}

/// Which variables a trajectory's state holds after the coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Layout {
    Velocities,
    Momenta,
}

pub(super) struct RunEntry {
    pub(super) name: String,
    pub(super) spec: SimSpec,
    pub(super) line: usize,
    pub(super) result: Option<RunResult>,
    /// The forces, Rayleigh function and constraints declared before the `simulate`.
    pub(super) dynamics: Dynamics,
}

#[derive(Clone)]
pub(super) struct RunResult {
    pub(super) method: MethodId,
    pub(super) layout: Layout,
    pub(super) coords: Vec<Symbol>,
    pub(super) params: HashMap<String, f64>,
    pub(super) traj: Arc<Trajectory>,
    /// The energy-like function in the state's variables (`H` or `h`), when known.
    pub(super) lagrangian: Option<Expr>,
    pub(super) hamiltonian: Option<Expr>,
}

/// A statement's printed result, kept for `latex` (reprint in another format).
#[derive(Clone)]
pub(super) enum Printed {
    Named(String, Expr),
    Value(Expr),
    Lines(Vec<Line>),
}

/// A scene or REPL session.
pub struct Session {
    pub(super) opts: Options,
    pub(super) backend: Box<dyn Backend>,
    pub(super) cache: Cache,
    pub(super) built_here: HashSet<CacheKey>,
    pub(super) coords: Vec<Symbol>,
    pub(super) params: BTreeMap<String, Param>,
    pub(super) functions: BTreeSet<String>,
    pub(super) defs: Vec<DefEntry>,
    pub(super) def_names: HashMap<String, usize>,
    /// Definitions some expression refers to by id. A superseded definition outside this set
    /// can never be reached again (names find the newest), so the REPL drops its body.
    pub(super) referenced: HashSet<usize>,
    pub(super) runs: Vec<RunEntry>,
    pub(super) run_names: HashMap<String, usize>,
    pub(super) plan: Vec<PlanEntry>,
    pub(super) staging: Staging,
    pub(super) output: Vec<String>,
    /// Warnings for standard error (energy drift), in order.
    pub(super) warnings: Vec<String>,
    pub(super) last_printed: Vec<Printed>,
    pub(super) source: Arc<NamedSource<String>>,
    pub(super) load_depth: usize,
    pub(super) diff: Differentiator,
    /// Names a statement introduces for itself (the phase, frequency and amplitudes of
    /// `average`), accepted in its expressions.
    pub(super) local_names: Vec<String>,
    /// `force`, `rayleigh` and `constraint` statements so far.
    pub(super) dynamics: Dynamics,
    /// Ensembles: a name for several runs (`from NAME` means all of them), with what they
    /// share (the level set they start on), in statement order.
    pub(super) groups: Vec<Group>,
    /// What every figure drawn so far shows, by file.
    pub(super) figures: Vec<(PathBuf, crate::plot::Description)>,
    /// Finished `lyapunov` / `megno` / `fli` statements, for their plots.
    pub(super) chaos_runs: Vec<ChaosRun>,
    /// `allow nonfinite` was given: exports keep inf and NaN.
    pub(super) allow_nonfinite: bool,
}

impl Session {
    /// A session on the real library.
    pub fn new(opts: Options) -> Session {
        Session::with_backend(opts, Box::new(NativeBackend))
    }

    /// A session on another backend (tests count what is built).
    pub fn with_backend(opts: Options, backend: Box<dyn Backend>) -> Session {
        let staging = Staging::new(opts.mode == Mode::Repl);
        Session {
            opts,
            backend,
            cache: Cache::new(),
            built_here: HashSet::new(),
            coords: Vec::new(),
            params: BTreeMap::new(),
            functions: BTreeSet::new(),
            defs: Vec::new(),
            def_names: HashMap::new(),
            referenced: HashSet::new(),
            runs: Vec::new(),
            run_names: HashMap::new(),
            plan: Vec::new(),
            staging,
            output: Vec::new(),
            warnings: Vec::new(),
            last_printed: Vec::new(),
            source: Arc::new(NamedSource::new("input", String::new())),
            load_depth: 0,
            diff: Differentiator::new(),
            local_names: Vec::new(),
            dynamics: Default::default(),
            groups: Vec::new(),
            figures: Vec::new(),
            chaos_runs: Vec::new(),
            allow_nonfinite: false,
        }
    }
}

/// Where a session's text comes from, which decides when values are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// A scene file: definitions and simulations are lazy; only outputs demand work.
    Scene,
    /// The REPL: every statement is an explicit request, so definitions are derived and
    /// echoed at once and simulations run at once.
    Repl,
}

/// Session settings.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scene or REPL.
    pub mode: Mode,
    /// Where relative output paths go.
    pub out_dir: PathBuf,
    /// Where relative `load` paths are looked up.
    pub base_dir: PathBuf,
    /// The stem of default output names (`pendulum` → `pendulum_phase.svg`).
    pub stem: String,
    /// Where progress bars of long simulations go ([`Draw::from_env`] on a terminal).
    pub progress: Draw,
    /// Default output format.
    pub format: Format,
    /// Let a scene write outside `out_dir` (absolute paths, `..`, links): `--allow-outside`.
    pub allow_outside: bool,
    /// The relative energy drift above which a run is reported (`--drift`; a `simulate`
    /// statement's `drift = …` overrides it). See [`super::statements::drift`].
    pub drift_threshold: f64,
    /// Excess drift (or an energy jump in one step) is an error instead of a warning:
    /// `--strict`.
    pub strict: bool,
}

impl Options {
    /// Defaults for `mode`: outputs and loads relative to the current directory, Unicode.
    pub fn new(mode: Mode) -> Options {
        Options {
            mode,
            out_dir: PathBuf::from("."),
            base_dir: PathBuf::from("."),
            stem: "scene".to_string(),
            progress: Draw::Hidden,
            format: Format::Unicode,
            allow_outside: false,
            drift_threshold: crate::integrate::drift::DEFAULT_THRESHOLD,
            strict: false,
        }
    }
}

/// A finished one-orbit chaos statement, for `plot megno` and its kin.
pub(in crate::scene) struct ChaosRun {
    pub(in crate::scene) name: String,
    pub(in crate::scene) which: Indicator,
    pub(in crate::scene) result: Indicators,
}

/// A named set of runs from one `simulate … for each …` statement.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Group {
    /// The statement's run name.
    pub(in crate::scene) name: String,
    /// Its members' run ids, in order of the swept value.
    pub(in crate::scene) ids: Vec<usize>,
    /// The swept variable's values, one per member.
    pub(in crate::scene) values: Vec<f64>,
    /// The swept variable as written.
    pub(in crate::scene) var: String,
    /// `H = 1/8`, as written.
    pub(in crate::scene) level: String,
}

/// A declared expression: as parsed, the definitions it refers to, and its source.
#[derive(Clone)]
pub(in crate::scene) struct Declared {
    pub(in crate::scene) raw: Expr,
    pub(in crate::scene) refs: Refs,
    pub(in crate::scene) src: Src,
}

/// The forces, Rayleigh function and constraints declared so far.
#[derive(Clone, Default)]
pub(in crate::scene) struct Dynamics {
    /// Coordinate index and force.
    pub(in crate::scene) forces: Vec<(usize, Declared)>,
    pub(in crate::scene) rayleigh: Option<Declared>,
    pub(in crate::scene) constraints: Vec<Declared>,
    /// Velocity constraints `g(q, q', t) = 0`, linear in the velocities.
    pub(in crate::scene) velocity_constraints: Vec<Declared>,
}

pub(in crate::scene) fn backend_error(e: BackendError, span: Span) -> SceneError {
    let kind = match &e {
        BackendError::NotYetAvailable { .. } => ErrorKind::NotAvailable,
        BackendError::Failed(_) => ErrorKind::Derivation,
        BackendError::Numeric(_) | BackendError::Budget(_) => ErrorKind::Numeric,
        BackendError::Simulate(crate::simulate::SimulateError::Integrate { .. }) => ErrorKind::Numeric,
        BackendError::Simulate(_) => ErrorKind::Derivation,
    };
    let mut err = SceneError::new(kind, e.to_string()).at(span);
    if kind == ErrorKind::NotAvailable {
        err = err.hint("the statement is valid; this build of lagrangian cannot carry it out yet");
    }
    err
}

/// The first characters of an expression's plain form, for the plan.
pub(in crate::scene) fn short(e: &Expr) -> String {
    let s = crate::print::plain(e);
    if s.chars().count() > 48 {
        let cut: String = s.chars().take(45).collect();
        format!("{cut}…")
    } else {
        s
    }
}

/// `Err(Interrupted)` at `span` once Ctrl-C was pressed (the process-wide token).
pub(in crate::scene) fn interruption(span: Span) -> Result<(), SceneError> {
    crate::cancel::check().map_err(|_| {
        SceneError::new(ErrorKind::Interrupted, "interrupted (Ctrl-C); this statement's results were discarded")
            .at(span)
    })
}
