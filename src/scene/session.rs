//! Executing statements: the session's declarations, its lazy definitions, the derivation
//! cache and the plan that `--explain` prints.
//!
//! Demand-driven evaluation: a definition (`H = legendre(L)`, `E = el(L)`) and a `simulate`
//! only record what they would build. Outputs — `print`, a bare derivation (`el`), `plot`,
//! `export`, and in the REPL every statement — demand values, and a demand builds exactly the
//! derivations it needs, each once. Derivations are cached by their symbolic content
//! (the kind, the coordinates and the input expressions, which are hash-consed, so the key
//! compares in O(1)); numbers (parameter values, initial states, time spans) are not part of
//! a derivation's key, so re-running a scene with other numbers reuses the derivations.

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use miette::NamedSource;

use super::ast::{
    DefValue, DerivCall, DerivKind, EventSpec, Item, PlotKind, PlotSpec, SimSpec, Src, Statement, StmtKind,
};
use super::backend::{
    Backend, BackendError, CompileRequest, Compiled, EventRequest, Formulation, Line, NativeBackend, RunRequest,
    SystemRef, Trajectory,
};
use super::error::{did_you_mean, ErrorKind, SceneError, Span};
use super::output::Staging;
use super::parser;
use super::sim::{self, Family, Method};
use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::parse::{parse_with, Declarations};
use crate::print::{render, Format};

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
    /// Show a progress bar for long simulations (only ever on a terminal).
    pub progress: bool,
    /// Default output format.
    pub format: Format,
}

impl Options {
    /// Defaults for `mode`: outputs and loads relative to the current directory, Unicode.
    pub fn new(mode: Mode) -> Options {
        Options {
            mode,
            out_dir: PathBuf::from("."),
            base_dir: PathBuf::from("."),
            stem: "scene".to_string(),
            progress: false,
            format: Format::Unicode,
        }
    }
}

/// One kind of work the plan reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Step {
    /// Euler–Lagrange equations.
    EulerLagrange,
    /// Legendre transform.
    Legendre,
    /// Hamilton's equations.
    Hamilton,
    /// Conserved quantities.
    Conserved,
    /// A Poisson bracket.
    Bracket,
    /// An averaged Lagrangian.
    Average,
    /// A canonical transformation.
    Transform,
    /// The energy function.
    Energy,
    /// Canonical momenta `p = ∂L/∂q'` (for initial states and plots).
    Momenta,
    /// The split `H = T(p) + V(q)`.
    Split,
    /// A compiled right-hand side.
    Compile,
    /// An integration.
    Integrate,
}

impl Step {
    /// A short name for the plan.
    pub fn name(self) -> &'static str {
        match self {
            Step::EulerLagrange => "Euler–Lagrange equations",
            Step::Legendre => "Legendre transform",
            Step::Hamilton => "Hamilton's equations",
            Step::Conserved => "conserved quantities",
            Step::Bracket => "Poisson bracket",
            Step::Average => "averaged Lagrangian",
            Step::Transform => "canonical transformation",
            Step::Energy => "energy function",
            Step::Momenta => "canonical momenta",
            Step::Split => "separable split H = T(p) + V(q)",
            Step::Compile => "compiled right-hand side",
            Step::Integrate => "integration",
        }
    }
}

/// What happened to one piece of work.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Status {
    /// Computed in this run.
    Built,
    /// Found in the derivation cache (same symbolic content as an earlier run).
    Reused,
    /// Not computed, with the reason.
    Skipped(String),
}

/// One line of the plan.
#[derive(Clone, Debug)]
pub struct PlanEntry {
    /// The kind of work.
    pub step: Step,
    /// What exactly (`of L`, `run 1 with gauss6`).
    pub what: String,
    /// The statement's line that caused it (1-based), if any.
    pub line: Option<usize>,
    /// Built, reused or skipped.
    pub status: Status,
}

/// The derivation cache: symbolic results keyed by their symbolic inputs. Keep one alive
/// across runs (the REPL does, and [`Session::with_cache`] lets callers do it) to reuse work.
#[derive(Default)]
pub struct Cache {
    map: HashMap<CacheKey, Value>,
}

impl Cache {
    /// An empty cache.
    pub fn new() -> Cache {
        Cache::default()
    }

    /// How many results it holds.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// Whether it is empty.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }
}

#[derive(Clone, PartialEq, Eq, Hash)]
struct CacheKey {
    step: Step,
    coords: Vec<Symbol>,
    inputs: Vec<Expr>,
    /// Numbers that are part of the content (compiled code binds parameter values).
    numbers: Vec<u64>,
    extra: String,
}

#[derive(Clone)]
enum Value {
    Expr(Expr),
    Lines(Vec<Line>),
    Exprs(Vec<Expr>),
    Compiled(Compiled),
}

/// A parameter: a symbol with an optional value.
#[derive(Clone, Debug)]
struct Param {
    value: Option<f64>,
    positive: bool,
}

/// A reference from an expression to a definition it uses.
type Refs = Vec<(Symbol, usize)>;

#[derive(Clone)]
enum DefBody {
    Expr { raw: Expr, refs: Refs },
    Deriv { kind: DerivKind, args: Vec<(Expr, Refs)>, span: Span },
}

struct DefEntry {
    name: String,
    body: DefBody,
    line: usize,
    value: Option<Value>,
    demanded: bool,
}

/// Which variables a trajectory's state holds after the coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    Velocities,
    Momenta,
}

struct RunEntry {
    name: String,
    spec: SimSpec,
    line: usize,
    result: Option<RunResult>,
}

#[derive(Clone)]
struct RunResult {
    method: Method,
    layout: Layout,
    coords: Vec<Symbol>,
    params: HashMap<String, f64>,
    traj: Arc<Trajectory>,
    /// The energy-like function in the state's variables (`H` or `h`), when known.
    lagrangian: Option<Expr>,
    hamiltonian: Option<Expr>,
}

/// A statement's printed result, kept for `latex` (reprint in another format).
#[derive(Clone)]
enum Printed {
    Named(String, Expr),
    Value(Expr),
    Lines(Vec<Line>),
}

/// A scene or REPL session.
pub struct Session {
    opts: Options,
    backend: Box<dyn Backend>,
    cache: Cache,
    built_here: HashSet<CacheKey>,
    coords: Vec<Symbol>,
    params: BTreeMap<String, Param>,
    functions: BTreeSet<String>,
    defs: Vec<DefEntry>,
    def_names: HashMap<String, usize>,
    runs: Vec<RunEntry>,
    run_names: HashMap<String, usize>,
    plan: Vec<PlanEntry>,
    staging: Staging,
    output: Vec<String>,
    last_printed: Vec<Printed>,
    source: Arc<NamedSource<String>>,
    line: usize,
    span: Span,
    load_depth: usize,
    diff: Differentiator,
    /// Names a statement introduces for itself (the phase, frequency and amplitudes of
    /// `average`), accepted in its expressions.
    local_names: Vec<String>,
}

/// The deepest chain of `load` statements.
const MAX_LOAD_DEPTH: usize = 8;

/// The largest scene file read, in bytes.
pub const MAX_SCENE_BYTES: u64 = 4 << 20;

fn line_of(text: &str, pos: usize) -> usize {
    let pos = pos.min(text.len());
    text.as_bytes()[..pos].iter().filter(|&&b| b == b'\n').count() + 1
}

fn backend_error(e: BackendError, span: Span) -> SceneError {
    let kind = match &e {
        BackendError::NotYetAvailable { .. } => ErrorKind::NotAvailable,
        BackendError::Failed(_) => ErrorKind::Derivation,
        BackendError::Numeric(_) => ErrorKind::Numeric,
    };
    let mut err = SceneError::new(kind, e.to_string()).at(span);
    if kind == ErrorKind::NotAvailable {
        err = err.hint("the statement is valid; this build of lagrangian cannot carry it out yet");
    }
    err
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
            runs: Vec::new(),
            run_names: HashMap::new(),
            plan: Vec::new(),
            staging,
            output: Vec::new(),
            last_printed: Vec::new(),
            source: Arc::new(NamedSource::new("input", String::new())),
            line: 0,
            span: (0, 0),
            load_depth: 0,
            diff: Differentiator::new(),
            local_names: Vec::new(),
        }
    }

    /// Starts with the derivations of an earlier session.
    pub fn with_cache(mut self, cache: Cache) -> Session {
        self.cache = cache;
        self
    }

    /// Ends the session, keeping its derivation cache.
    pub fn into_cache(self) -> Cache {
        self.cache
    }

    /// The plan so far.
    pub fn plan(&self) -> &[PlanEntry] {
        &self.plan
    }

    /// Lines printed since the last call.
    pub fn take_output(&mut self) -> Vec<String> {
        std::mem::take(&mut self.output)
    }

    /// The session's options.
    pub fn options(&self) -> &Options {
        &self.opts
    }

    /// Names for completion: coordinates (with their velocities), momenta, parameters,
    /// definitions and functions.
    pub fn known_names(&self) -> Vec<String> {
        let mut out = Vec::new();
        for c in &self.coords {
            out.push(c.name().to_string());
            out.push(format!("{}'", c.name()));
            out.push(format!("p_{}", c.name()));
        }
        out.extend(self.params.keys().cloned());
        out.extend(self.defs.iter().map(|d| d.name.clone()));
        out.extend(self.functions.iter().cloned());
        out.extend(self.run_names.keys().cloned());
        out.sort();
        out.dedup();
        out
    }

    /// Runs a whole scene text. On success every output file is in place; on error none of
    /// this call's files are written (they were staged in temporary files and are removed).
    pub fn run_scene(&mut self, name: &str, text: &str) -> Result<(), SceneError> {
        let result = self.run_text(name, text);
        match result {
            Ok(()) => {
                self.finish_plan();
                self.staging.commit().map_err(|e| e.with_source(&self.source))
            }
            Err(e) => {
                self.staging.abort();
                Err(e)
            }
        }
    }

    /// Runs one REPL entry (one or more statements). Files are written as each succeeds.
    pub fn run_line(&mut self, text: &str) -> Result<(), SceneError> {
        let result = self.run_text("input", text);
        match result {
            Ok(()) => self.staging.commit().map_err(|e| e.with_source(&self.source)),
            Err(e) => {
                self.staging.abort();
                Err(e)
            }
        }
    }

    fn run_text(&mut self, name: &str, text: &str) -> Result<(), SceneError> {
        let saved = self.source.clone();
        self.source = Arc::new(NamedSource::new(name, text.to_string()));
        let src = self.source.clone();
        let result = parser::parse_scene(text).and_then(|stmts| {
            for st in &stmts {
                self.exec(st, text)?;
            }
            Ok(())
        });
        self.source = saved;
        result.map_err(|e| e.with_source(&src))
    }

    fn exec(&mut self, st: &Statement, text: &str) -> Result<(), SceneError> {
        self.line = line_of(text, st.span.0);
        self.span = st.span;
        match &st.kind {
            StmtKind::Coordinates(names) => self.declare_coordinates(names),
            StmtKind::Parameters { params, positive } => self.declare_parameters(params, *positive),
            StmtKind::Functions(names) => self.declare_functions(names),
            StmtKind::Define { name, value } => self.define(name, value),
            StmtKind::Derive { call, format } => {
                let v = self.derive_call(call)?;
                let printed = match v {
                    Value::Expr(e) => {
                        let label = match call.kind {
                            DerivKind::Legendre => "H".to_string(),
                            DerivKind::Energy => "E".to_string(),
                            _ => format!(
                                "{{{}}}",
                                call.args.iter().map(|a| a.text.trim()).collect::<Vec<_>>().join(", ")
                            ),
                        };
                        Printed::Named(label, e)
                    }
                    Value::Lines(l) => Printed::Lines(l),
                    _ => return Ok(()),
                };
                self.print_all(vec![printed], *format);
                Ok(())
            }
            StmtKind::Print { items, format } => {
                let mut printed = Vec::new();
                for item in items {
                    printed.push(self.printed_item(item)?);
                }
                self.print_all(printed, *format);
                Ok(())
            }
            StmtKind::Simulate(spec) => self.simulate(spec),
            StmtKind::Plot(spec) => self.plot(spec),
            StmtKind::Export { items, run, path } => self.export(items, run.as_ref(), path),
            StmtKind::Average { l, trials, phase, frequency, amplitudes, format } => {
                self.local_names = std::iter::once(phase)
                    .chain(std::iter::once(frequency))
                    .chain(amplitudes)
                    .map(|n| n.text.clone())
                    .collect();
                let r = self.average(l.as_ref(), trials, phase, frequency, amplitudes);
                self.local_names.clear();
                let lines = r?;
                self.print_all(vec![Printed::Lines(lines)], *format);
                Ok(())
            }
            StmtKind::Transform { h, kind, f, new, format } => {
                self.local_names = new.iter().map(|n| n.text.clone()).collect();
                let r = self.transform(h.as_ref(), kind, f, new);
                self.local_names.clear();
                let lines = r?;
                self.print_all(vec![Printed::Lines(lines)], *format);
                Ok(())
            }
            StmtKind::Load(path) => self.load(path),
            StmtKind::Help(word) => {
                let text = super::help::help(word.as_ref().map(|w| w.text.as_str()));
                self.output.push(text);
                Ok(())
            }
            StmtKind::History => {
                self.output.push("(history is kept by the REPL)".to_string());
                Ok(())
            }
            StmtKind::Format { format, set_default } => {
                if *set_default {
                    self.opts.format = *format;
                    self.output.push(format!("output format: {}", format_name(*format)));
                } else if self.last_printed.is_empty() {
                    self.output.push("nothing to reprint yet".to_string());
                } else {
                    let last = self.last_printed.clone();
                    self.print_all(last, Some(*format));
                }
                Ok(())
            }
        }
    }

    // ----- declarations -------------------------------------------------------------------

    fn declarations(&self) -> Declarations {
        let positive = self.params.iter().filter(|(_, p)| p.positive).map(|(n, _)| n.clone());
        Declarations::new().with_functions(self.functions.iter()).with_positive(positive)
    }

    fn name_in_use(&self, name: &str) -> Option<&'static str> {
        if self.coords.iter().any(|c| c.name() == name) {
            Some("a coordinate")
        } else if self.params.contains_key(name) {
            Some("a parameter")
        } else if self.functions.contains(name) {
            Some("a function")
        } else if self.def_names.contains_key(name) {
            Some("a definition")
        } else {
            None
        }
    }

    fn declare_coordinates(&mut self, names: &[Src]) -> Result<(), SceneError> {
        let mut seen = BTreeSet::new();
        for n in names {
            let name = n.text.as_str();
            if !seen.insert(name) || self.coords.iter().any(|c| c.name() == name) {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("coordinate `{name}` is declared twice"))
                    .at(n.span)
                    .label("declared again here"));
            }
            if let Some(what) = self.name_in_use(name) {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("`{name}` is already {what}"))
                    .at(n.span)
                    .label("already declared"));
            }
            if name == "t" {
                return Err(SceneError::new(ErrorKind::Redeclared, "`t` is time and cannot be a coordinate")
                    .at(n.span)
                    .hint("choose another name"));
            }
        }
        self.coords.extend(names.iter().map(|n| Symbol::new(&n.text)));
        Ok(())
    }

    fn declare_parameters(&mut self, params: &[(Src, Option<Src>)], positive: bool) -> Result<(), SceneError> {
        for (n, v) in params {
            let name = n.text.as_str();
            if let Some(what) = self.name_in_use(name).filter(|w| *w != "a parameter") {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("`{name}` is already {what}"))
                    .at(n.span)
                    .label("already declared"));
            }
            let value = match v {
                Some(src) => {
                    let (e, refs) = self.expr(src)?;
                    if !refs.is_empty() {
                        return Err(SceneError::new(ErrorKind::Syntax, "a parameter value must be a number")
                            .at(src.span)
                            .hint("use numbers and earlier parameters only"));
                    }
                    Some(self.number(&e, src.span)?)
                }
                None => self.params.get(name).and_then(|p| p.value),
            };
            let was_positive = self.params.get(name).is_some_and(|p| p.positive);
            if positive {
                if let Some(x) = value.filter(|x| *x <= 0.0) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("`{name}` is declared positive but its value is {x}"),
                    )
                    .at(n.span)
                    .hint("drop `positive` or give a positive value"));
                }
            }
            self.params.insert(name.to_string(), Param { value, positive: positive || was_positive });
        }
        Ok(())
    }

    fn declare_functions(&mut self, names: &[Src]) -> Result<(), SceneError> {
        for n in names {
            if let Some(what) = self.name_in_use(&n.text).filter(|w| *w != "a function") {
                return Err(SceneError::new(ErrorKind::Redeclared, format!("`{}` is already {what}", n.text))
                    .at(n.span)
                    .label("already declared"));
            }
            self.functions.insert(n.text.clone());
        }
        Ok(())
    }

    // ----- expressions ---------------------------------------------------------------------

    /// Parses an expression in the session's context, checks that every symbol is known and
    /// returns the definitions it refers to.
    fn expr(&mut self, src: &Src) -> Result<(Expr, Refs), SceneError> {
        let decls = self.declarations();
        let e = parse_with(&src.text, &decls).map_err(|pe| {
            let start = src.span.0 + pe.span.0.min(src.text.len());
            let end = src.span.0 + pe.span.1.min(src.text.len());
            let mut err = SceneError::new(ErrorKind::Syntax, pe.message.clone()).at((start, end.max(start + 1)));
            if let Some(h) = &pe.hint {
                err = err.hint(h.clone());
            }
            err
        })?;
        let mut refs = Vec::new();
        for s in e.free_symbols() {
            if let Some(r) = self.check_symbol(&s, src)? {
                refs.push((s, r));
            }
        }
        Ok((e, refs))
    }

    /// `Some(def)` if `s` names a definition; an error if `s` is unknown.
    fn check_symbol(&self, s: &Symbol, src: &Src) -> Result<Option<usize>, SceneError> {
        let name = s.name();
        if s.is_time() || (s.primes() == 0 && self.local_names.iter().any(|n| n == name)) {
            return Ok(None);
        }
        if self.coords.iter().any(|c| c.name() == name) {
            return Ok(None);
        }
        if let Some(c) = name.strip_prefix("p_") {
            if s.primes() <= 1 && self.coords.iter().any(|q| q.name() == c) {
                return Ok(None);
            }
        }
        let spelled = s.to_string();
        let span = symbol_span(src, &spelled);
        if let Some(&id) = self.def_names.get(name) {
            if s.primes() == 0 {
                return Ok(Some(id));
            }
            return Err(SceneError::new(
                ErrorKind::UndefinedSymbol,
                format!("`{spelled}`: `{name}` is a definition, not a coordinate"),
            )
            .at(span)
            .label("primes apply to coordinates")
            .hint(format!("declare a coordinate with `coordinates {name}`, or take d/dt of `{name}` with `print`")));
        }
        if self.params.contains_key(name) {
            if s.primes() == 0 {
                return Ok(None);
            }
            return Err(SceneError::new(
                ErrorKind::UndefinedSymbol,
                format!("`{spelled}`: `{name}` is a parameter, which does not change in time"),
            )
            .at(span)
            .label("a parameter has no velocity")
            .hint(format!("if `{name}` moves, declare it with `coordinates {name}`")));
        }
        let mut candidates: Vec<String> = Vec::new();
        for c in &self.coords {
            candidates.push(c.name().to_string());
            candidates.push(format!("{}'", c.name()));
            candidates.push(format!("{}''", c.name()));
            candidates.push(format!("p_{}", c.name()));
        }
        candidates.extend(self.params.keys().cloned());
        candidates.extend(self.def_names.keys().cloned());
        let mut err = SceneError::new(ErrorKind::UndefinedSymbol, format!("undefined symbol `{spelled}`"))
            .at(span)
            .label("not declared");
        err = match did_you_mean(&spelled, candidates.iter().map(String::as_str)) {
            Some(c) => err.hint(format!("did you mean `{c}`?")),
            None if s.primes() > 0 => err.hint(format!("declare the coordinate first: `coordinates {name}`")),
            None => err.hint(format!(
                "declare it first: `parameters {name} = …` for a constant, `coordinates {name}` for a coordinate, or define `{name} = …`"
            )),
        };
        Err(err)
    }

    /// The numeric value of an expression of numbers and parameters with values.
    fn number(&self, e: &Expr, span: Span) -> Result<f64, SceneError> {
        let v = crate::eval::eval_with(e, &|s: &Symbol| self.params.get(s.name()).and_then(|p| p.value));
        match v {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(x) => Err(SceneError::new(ErrorKind::BadNumber, format!("the value is {x}")).at(span)),
            Err(crate::eval::EvalError::Unbound(name)) => {
                Err(SceneError::new(ErrorKind::MissingValue, format!("`{name}` has no value"))
                    .at(span)
                    .label("needs a number")
                    .hint(format!("declare `{name}` with a value first: `parameters {name} = …`")))
            }
            Err(e) => Err(SceneError::new(ErrorKind::BadNumber, e.to_string()).at(span)),
        }
    }

    fn resolve(&mut self, raw: &Expr, refs: &Refs) -> Result<Expr, SceneError> {
        if refs.is_empty() {
            return Ok(raw.clone());
        }
        let mut map = HashMap::new();
        for (s, id) in refs {
            match self.demand_def(*id)? {
                Value::Expr(e) => {
                    map.insert(s.clone(), e);
                }
                _ => {
                    let name = self.defs[*id].name.clone();
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("`{name}` is a list of equations, not an expression"),
                    )
                    .at(self.span)
                    .hint(format!("print it on its own: `print {name}`")));
                }
            }
        }
        Ok(raw.subs(&map))
    }

    fn resolved(&mut self, src: &Src) -> Result<Expr, SceneError> {
        let (raw, refs) = self.expr(src)?;
        self.resolve(&raw, &refs)
    }

    // ----- definitions ---------------------------------------------------------------------

    fn define(&mut self, name: &Src, value: &DefValue) -> Result<(), SceneError> {
        let n = name.text.as_str();
        if let Some(what) = self.name_in_use(n).filter(|w| *w != "a definition") {
            return Err(SceneError::new(ErrorKind::Redeclared, format!("`{n}` is already {what}"))
                .at(name.span)
                .label("cannot be redefined")
                .hint("choose another name for the definition"));
        }
        if n == "t" {
            return Err(SceneError::new(ErrorKind::Redeclared, "`t` is time and cannot be defined").at(name.span));
        }
        let body = match value {
            DefValue::Expr(src) => {
                let (raw, refs) = self.expr(src)?;
                DefBody::Expr { raw, refs }
            }
            DefValue::Derivation(call) => {
                let mut args = Vec::new();
                for a in &call.args {
                    args.push(self.expr(a)?);
                }
                DefBody::Deriv { kind: call.kind, args, span: call.span }
            }
        };
        let id = self.defs.len();
        self.defs.push(DefEntry { name: n.to_string(), body, line: self.line, value: None, demanded: false });
        self.def_names.insert(n.to_string(), id);
        if self.opts.mode == Mode::Repl {
            let v = self.demand_def(id)?;
            let printed = match v {
                Value::Expr(e) => Printed::Named(n.to_string(), e),
                Value::Lines(l) => Printed::Lines(l),
                _ => return Ok(()),
            };
            self.print_all(vec![printed], None);
        }
        Ok(())
    }

    fn demand_def(&mut self, id: usize) -> Result<Value, SceneError> {
        if let Some(v) = &self.defs[id].value {
            return Ok(v.clone());
        }
        self.defs[id].demanded = true;
        let body = self.defs[id].body.clone();
        let v = match body {
            DefBody::Expr { raw, refs } => Value::Expr(self.resolve(&raw, &refs)?),
            DefBody::Deriv { kind, args, span } => {
                let saved = self.span;
                self.span = span;
                let mut resolved = Vec::new();
                for (raw, refs) in &args {
                    resolved.push(self.resolve(raw, refs)?);
                }
                let v = self.derive(kind, resolved, span);
                self.span = saved;
                v?
            }
        };
        self.defs[id].value = Some(v.clone());
        Ok(v)
    }

    fn def_value(&mut self, name: &str) -> Result<Option<Expr>, SceneError> {
        let Some(&id) = self.def_names.get(name) else { return Ok(None) };
        match self.demand_def(id)? {
            Value::Expr(e) => Ok(Some(e)),
            _ => Err(SceneError::new(ErrorKind::Syntax, format!("`{name}` must be an expression")).at(self.span)),
        }
    }

    fn lagrangian(&mut self) -> Result<Expr, SceneError> {
        match self.def_value("L")? {
            Some(l) => Ok(l),
            None => Err(SceneError::new(ErrorKind::Undeclared, "no Lagrangian defined")
                .at(self.span)
                .label("needs `L`")
                .hint("define it first, for example `L = 1/2 m x'^2 - 1/2 k x^2`")),
        }
    }

    fn hamiltonian(&mut self) -> Result<Expr, SceneError> {
        if let Some(h) = self.def_value("H")? {
            return Ok(h);
        }
        if self.def_names.contains_key("L") {
            let l = self.lagrangian()?;
            return match self.derive(DerivKind::Legendre, vec![l], self.span)? {
                Value::Expr(h) => Ok(h),
                _ => Err(SceneError::new(ErrorKind::Derivation, "the Legendre transform gave no expression")),
            };
        }
        Err(SceneError::new(ErrorKind::Undeclared, "no Hamiltonian or Lagrangian defined")
            .at(self.span)
            .label("needs `H` or `L`")
            .hint("define `H = …` or `L = …` first"))
    }

    fn derive_call(&mut self, call: &DerivCall) -> Result<Value, SceneError> {
        let mut args = Vec::new();
        for a in &call.args {
            args.push(self.resolved(a)?);
        }
        self.derive(call.kind, args, call.span)
    }

    fn derive(&mut self, kind: DerivKind, mut args: Vec<Expr>, span: Span) -> Result<Value, SceneError> {
        let want = if kind == DerivKind::Pb { 2 } else { 1 };
        if !args.is_empty() && args.len() != want {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!(
                    "`{}` takes {want} argument{}, found {}",
                    kind.keyword(),
                    if want == 1 { "" } else { "s" },
                    args.len()
                ),
            )
            .at(span));
        }
        if args.is_empty() {
            match kind {
                DerivKind::El | DerivKind::Legendre => args.push(self.lagrangian()?),
                DerivKind::Hamilton => args.push(self.hamiltonian()?),
                DerivKind::Conserved | DerivKind::Energy => {
                    if self.def_names.contains_key("L") {
                        args.push(self.lagrangian()?)
                    } else {
                        args.push(self.hamiltonian()?)
                    }
                }
                DerivKind::Pb => {
                    return Err(SceneError::new(ErrorKind::Syntax, "`pb` needs two expressions")
                        .at(span)
                        .hint("write `pb f, g`, for example `pb x p_y - y p_x, H`"))
                }
            }
        }
        if self.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(span)
                .hint("declare them first, for example `coordinates θ`"));
        }
        let is_h = |e: &Expr| e.free_symbols().iter().any(|s| s.name().starts_with("p_") && s.primes() == 0);
        let decls = self.declarations();
        let coords = self.coords.clone();
        let sys = SystemRef { coords: &coords, decls: &decls };
        let what = format!("of {}", short(&args[0]));
        let step = match kind {
            DerivKind::El => Step::EulerLagrange,
            DerivKind::Legendre => Step::Legendre,
            DerivKind::Hamilton => Step::Hamilton,
            DerivKind::Conserved => Step::Conserved,
            DerivKind::Pb => Step::Bracket,
            DerivKind::Energy => Step::Energy,
        };
        let key =
            CacheKey { step, coords: coords.clone(), inputs: args.clone(), numbers: vec![], extra: String::new() };
        let a = args.clone();
        let hamiltonian_input = is_h(&args[0]);
        let energy = |d: &mut Differentiator| energy_function(d, &coords, &a[0]);
        let result = match kind {
            DerivKind::Energy if hamiltonian_input => Ok(Value::Expr(args[0].clone())),
            DerivKind::Energy => {
                let mut d = std::mem::take(&mut self.diff);
                let e = energy(&mut d);
                self.diff = d;
                return self.record(step, what, key, Ok(Value::Expr(e)), span);
            }
            _ => Err(()),
        };
        if let Ok(v) = result {
            return Ok(v);
        }
        if let Some(v) = self.lookup(&key, step, &what) {
            return Ok(v);
        }
        let backend = &*self.backend;
        let built = match kind {
            DerivKind::El => backend.euler_lagrange(&sys, &args[0]).map(Value::Lines),
            DerivKind::Legendre => backend.legendre(&sys, &args[0]).map(Value::Expr),
            DerivKind::Hamilton => backend.hamilton(&sys, &args[0]).map(Value::Lines),
            DerivKind::Conserved => backend.conserved(&sys, &args[0], hamiltonian_input).map(Value::Lines),
            DerivKind::Pb => backend.bracket(&sys, &args[0], &args[1]).map(Value::Expr),
            DerivKind::Energy => unreachable_energy(),
        };
        self.record(step, what, key, built.map_err(|e| backend_error(e, span)), span)
    }

    /// A cached value, recording its reuse in the plan.
    fn lookup(&mut self, key: &CacheKey, step: Step, what: &str) -> Option<Value> {
        let v = self.cache.map.get(key)?.clone();
        if !self.built_here.contains(key) {
            self.built_here.insert(key.clone());
            self.plan.push(PlanEntry { step, what: what.to_string(), line: Some(self.line), status: Status::Reused });
        }
        Some(v)
    }

    fn record(
        &mut self,
        step: Step,
        what: String,
        key: CacheKey,
        built: Result<Value, SceneError>,
        _span: Span,
    ) -> Result<Value, SceneError> {
        if let Some(v) = self.lookup(&key, step, &what) {
            return Ok(v);
        }
        let v = built?;
        self.cache.map.insert(key.clone(), v.clone());
        self.built_here.insert(key);
        self.plan.push(PlanEntry { step, what, line: Some(self.line), status: Status::Built });
        Ok(v)
    }

    /// Canonical momenta `p_i = ∂L/∂q'_i` (plain derivatives; used to turn initial
    /// velocities into momenta and for plots).
    fn momenta(&mut self, l: &Expr) -> Result<Vec<Expr>, SceneError> {
        let key = CacheKey {
            step: Step::Momenta,
            coords: self.coords.clone(),
            inputs: vec![l.clone()],
            numbers: vec![],
            extra: String::new(),
        };
        if let Some(Value::Exprs(v)) = self.lookup(&key, Step::Momenta, &format!("of {}", short(l))) {
            return Ok(v);
        }
        let ps: Vec<Expr> = self.coords.clone().iter().map(|q| self.diff.diff(l, &q.prime())).collect();
        match self.record(Step::Momenta, format!("of {}", short(l)), key, Ok(Value::Exprs(ps)), self.span)? {
            Value::Exprs(v) => Ok(v),
            _ => Ok(vec![]),
        }
    }

    fn average(
        &mut self,
        l: Option<&Src>,
        trials: &[(Src, Src)],
        phase: &Src,
        frequency: &Src,
        amplitudes: &[Src],
    ) -> Result<Vec<Line>, SceneError> {
        let l = match l {
            Some(src) => self.resolved(src)?,
            None => self.lagrangian()?,
        };
        let mut pairs = Vec::new();
        for (q, e) in trials {
            if !self.coords.iter().any(|c| c.name() == q.text) {
                return Err(SceneError::new(ErrorKind::UndefinedSymbol, format!("`{}` is not a coordinate", q.text))
                    .at(q.span)
                    .hint("a trial function replaces a coordinate: `x = A cos(θ)`"));
            }
            pairs.push((Symbol::new(&q.text), self.resolved(e)?));
        }
        let phase = Symbol::new(&phase.text);
        let frequency = Symbol::new(&frequency.text);
        let amps: Vec<Symbol> = amplitudes.iter().map(|a| Symbol::new(&a.text)).collect();
        let mut inputs = vec![l.clone(), Expr::sym(phase.clone()), Expr::sym(frequency.clone())];
        for (q, e) in &pairs {
            inputs.push(Expr::sym(q.clone()));
            inputs.push(e.clone());
        }
        inputs.extend(amps.iter().cloned().map(Expr::sym));
        let key = CacheKey {
            step: Step::Average,
            coords: self.coords.clone(),
            inputs,
            numbers: vec![],
            extra: String::new(),
        };
        let what = format!("of {}", short(&l));
        if let Some(Value::Lines(v)) = self.lookup(&key, Step::Average, &what) {
            return Ok(v);
        }
        let built = self
            .backend
            .average(&l, &pairs, &phase, &frequency, &amps)
            .map(Value::Lines)
            .map_err(|e| backend_error(e, self.span));
        match self.record(Step::Average, what, key, built, self.span)? {
            Value::Lines(v) => Ok(v),
            _ => Ok(vec![]),
        }
    }

    fn transform(&mut self, h: Option<&Src>, kind: &str, f: &Src, new: &[Src]) -> Result<Vec<Line>, SceneError> {
        let n = self.coords.len();
        if n == 0 {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(self.span)
                .hint("declare them first, for example `coordinates q`"));
        }
        if new.len() != 2 * n {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!(
                    "{} new names for {n} coordinate(s): give {n} new coordinates, then {n} new momenta",
                    new.len()
                ),
            )
            .at(new.first().map_or(self.span, |s| (s.span.0, new[new.len() - 1].span.1)))
            .hint("for one coordinate: `new Q, P`"));
        }
        let h = match h {
            Some(src) => self.resolved(src)?,
            None => self.hamiltonian()?,
        };
        let f_expr = self.resolved(f)?;
        let new_q: Vec<Symbol> = new[..n].iter().map(|s| Symbol::new(&s.text)).collect();
        let new_p: Vec<Symbol> = new[n..].iter().map(|s| Symbol::new(&s.text)).collect();
        let mut inputs = vec![h.clone(), f_expr.clone()];
        inputs.extend(new_q.iter().chain(&new_p).cloned().map(Expr::sym));
        let key = CacheKey {
            step: Step::Transform,
            coords: self.coords.clone(),
            inputs,
            numbers: vec![],
            extra: kind.to_string(),
        };
        let what = format!("by {kind} = {}", short(&f_expr));
        if let Some(Value::Lines(v)) = self.lookup(&key, Step::Transform, &what) {
            return Ok(v);
        }
        let decls = self.declarations();
        let coords = self.coords.clone();
        let sys = SystemRef { coords: &coords, decls: &decls };
        let built = self
            .backend
            .transform(&sys, &h, kind, &f_expr, &new_q, &new_p)
            .map(Value::Lines)
            .map_err(|e| backend_error(e, self.span));
        match self.record(Step::Transform, what, key, built, self.span)? {
            Value::Lines(v) => Ok(v),
            _ => Ok(vec![]),
        }
    }

    // ----- printing ------------------------------------------------------------------------

    fn printed_item(&mut self, item: &Item) -> Result<Printed, SceneError> {
        match item {
            Item::Derivation(call) => Ok(match self.derive_call(call)? {
                Value::Expr(e) => Printed::Named(call.kind.keyword().to_string(), e),
                Value::Lines(l) => Printed::Lines(l),
                _ => Printed::Lines(vec![]),
            }),
            Item::Expr(src) => {
                let (raw, refs) = self.expr(src)?;
                if let (Some(s), [(_, id)]) = (raw.as_sym(), &refs[..]) {
                    let name = s.name().to_string();
                    return Ok(match self.demand_def(*id)? {
                        Value::Expr(e) => Printed::Named(name, e),
                        Value::Lines(l) => Printed::Lines(l),
                        _ => Printed::Lines(vec![]),
                    });
                }
                Ok(Printed::Value(self.resolve(&raw, &refs)?))
            }
        }
    }

    fn print_all(&mut self, printed: Vec<Printed>, format: Option<Format>) {
        let f = format.unwrap_or(self.opts.format);
        for p in &printed {
            match p {
                Printed::Named(n, e) => {
                    let name = match f {
                        Format::Latex => render(&Expr::var(n), f),
                        _ => n.clone(),
                    };
                    self.output.push(format!("{name} = {}", render(e, f)));
                }
                Printed::Value(e) => self.output.push(render(e, f)),
                Printed::Lines(lines) => {
                    for l in lines {
                        self.output.push(render_line(l, f));
                    }
                }
            }
        }
        self.last_printed = printed;
    }

    // ----- simulation ----------------------------------------------------------------------

    fn simulate(&mut self, spec: &SimSpec) -> Result<(), SceneError> {
        // Validate the parts that need no derivation now, so a typo is reported at once.
        self.check_method(spec)?;
        let name = match &spec.name {
            Some(n) => n.text.clone(),
            None => format!("run{}", self.runs.len() + 1),
        };
        let id = self.runs.len();
        self.runs.push(RunEntry { name: name.clone(), spec: spec.clone(), line: self.line, result: None });
        self.run_names.insert(name, id);
        if self.opts.mode == Mode::Repl {
            self.demand_run(id)?;
            let summary = self.run_summary(id);
            self.output.push(summary);
        }
        Ok(())
    }

    fn check_method(&self, spec: &SimSpec) -> Result<Method, SceneError> {
        if spec.time_var.text != "t" {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!("the time variable is `t`, not `{}`", spec.time_var.text),
            )
            .at(spec.time_var.span)
            .hint("write `for t in 0..10`"));
        }
        match &spec.method {
            None => Ok(sim::method(sim::DEFAULT_METHOD).unwrap_or(sim::METHODS[0])),
            Some(m) => sim::method(&m.text).ok_or_else(|| {
                let names = sim::METHODS.iter().map(|m| m.name);
                let err = SceneError::new(ErrorKind::UnknownMethod, format!("unknown integration method `{}`", m.text))
                    .at(m.span)
                    .label("not a method");
                match did_you_mean(&m.text, names) {
                    Some(s) => err.hint(format!("did you mean `{s}`? (`help simulate` lists the methods)")),
                    None => err.hint(format!(
                        "the methods are {}",
                        sim::METHODS.iter().map(|m| m.name).collect::<Vec<_>>().join(", ")
                    )),
                }
            }),
        }
    }

    fn run_summary(&self, id: usize) -> String {
        let run = &self.runs[id];
        let Some(r) = &run.result else { return String::new() };
        let tr = &r.traj;
        let mut s = format!(
            "{}: {} from t = {} to t = {} in {} steps",
            run.name,
            r.method.name,
            fmt_num(tr.t.first().copied().unwrap_or(0.0)),
            fmt_num(tr.t.last().copied().unwrap_or(0.0)),
            tr.steps
        );
        if let Some(y) = tr.y.last() {
            let names = state_names(&r.coords, r.layout);
            let parts: Vec<String> = names.iter().zip(y).map(|(n, v)| format!("{n} = {}", fmt_num(*v))).collect();
            s.push_str(&format!("; final {}", parts.join(", ")));
        }
        if !tr.events.is_empty() {
            s.push_str(&format!("; {} events", tr.events.len()));
        }
        s
    }

    fn demand_run(&mut self, id: usize) -> Result<RunResult, SceneError> {
        if let Some(r) = &self.runs[id].result {
            return Ok(r.clone());
        }
        let spec = self.runs[id].spec.clone();
        let saved = (self.line, self.span);
        self.line = self.runs[id].line;
        let r = self.run_simulation(&spec, &self.runs[id].name.clone());
        (self.line, self.span) = saved;
        let r = r?;
        self.runs[id].result = Some(r.clone());
        Ok(r)
    }

    fn run_simulation(&mut self, spec: &SimSpec, name: &str) -> Result<RunResult, SceneError> {
        let stmt_span = (spec.time_var.span.0.saturating_sub(1), spec.span_span.1);
        self.span = stmt_span;
        let method = self.check_method(spec)?;
        if self.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(stmt_span)
                .hint("declare them first, for example `coordinates θ`"));
        }
        let t0 = self.bound(&spec.t0)?;
        let t1 = self.bound(&spec.t1)?;
        if t1 <= t0 {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("the time span runs backwards: it ends at {} before it starts at {}", fmt_num(t1), fmt_num(t0)),
            )
            .at(spec.span_span)
            .label("end must be after start")
            .hint(format!("write `for t in {}..{}`", fmt_num(t1.min(t0)), fmt_num(t1.max(t0)))));
        }
        let positive = |s: &Option<Src>, this: &mut Session, what: &str| -> Result<Option<f64>, SceneError> {
            let Some(src) = s else { return Ok(None) };
            let e = this.resolved(src)?;
            let x = this.number(&e, src.span)?;
            if x <= 0.0 {
                return Err(
                    SceneError::new(ErrorKind::BadNumber, format!("{what} must be positive, found {x}")).at(src.span)
                );
            }
            Ok(Some(x))
        };
        let mut dt = positive(&spec.dt, self, "the step `dt`")?;
        let mut tol = positive(&spec.tol, self, "the tolerance `tol`")?;
        let steps = positive(&spec.steps, self, "`steps`")?;
        if let Some(n) = steps {
            dt = Some((t1 - t0) / n.round().max(1.0));
        }
        match method.family {
            Family::Adaptive => {
                if spec.dt.is_some() {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("`{}` chooses its own steps; give a tolerance instead of `dt`", method.name),
                    )
                    .at(spec.dt.as_ref().map_or(stmt_span, |s| s.span))
                    .hint("write `tol = 1e-10`, or pick a fixed-step method such as `gauss6` or `rk4`"));
                }
                tol = Some(tol.unwrap_or(1e-10));
            }
            _ => {
                if dt.is_none() {
                    return Err(SceneError::new(
                        ErrorKind::MissingValue,
                        format!("`{}` is a fixed-step method and needs a step", method.name),
                    )
                    .at(stmt_span)
                    .hint("add `dt = 0.01` (or `steps = 1000`)"));
                }
            }
        }
        if let Some(d) = dt {
            if (t1 - t0) / d > 1e9 {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!("{} steps is more than the limit of 10⁹", fmt_num((t1 - t0) / d)),
                )
                .at(spec.dt.as_ref().map_or(stmt_span, |s| s.span))
                .hint("use a larger `dt` or a shorter time span"));
            }
        }

        // The formulation this method needs: this decides what is derived.
        let has_l = self.def_names.contains_key("L");
        let has_h = self.def_names.contains_key("H");
        let (formulation, layout, l_expr, h_expr) = match method.family {
            Family::Splitting => {
                let h = self.hamiltonian()?;
                let (t, v) = self.split(&h, method)?;
                (Formulation::Separable { t, v }, Layout::Momenta, None, Some(h))
            }
            _ if has_l => {
                let l = self.lagrangian()?;
                (Formulation::Lagrangian(l.clone()), Layout::Velocities, Some(l), None)
            }
            _ if has_h => {
                let h = self.hamiltonian()?;
                (Formulation::Hamiltonian(h.clone()), Layout::Momenta, None, Some(h))
            }
            _ => {
                return Err(SceneError::new(ErrorKind::Undeclared, "nothing to simulate: no `L` or `H` defined")
                    .at(stmt_span)
                    .hint("define `L = …` or `H = …` first"))
            }
        };

        // Initial state.
        let coords = self.coords.clone();
        let n = coords.len();
        let mut given: HashMap<String, (f64, Span)> = HashMap::new();
        for (sym, val) in &spec.inits {
            let (e, _) = self.expr(sym)?;
            let Some(s) = e.as_sym().cloned() else {
                return Err(
                    SceneError::new(ErrorKind::Syntax, "expected a coordinate, velocity or momentum").at(sym.span)
                );
            };
            let is_state = coords.iter().any(|c| c.name() == s.name() && s.primes() <= 1)
                || (s.primes() == 0
                    && s.name().strip_prefix("p_").is_some_and(|c| coords.iter().any(|q| q.name() == c)));
            if !is_state {
                return Err(SceneError::new(
                    ErrorKind::UndefinedSymbol,
                    format!("`{}` is not part of the state", sym.text),
                )
                .at(sym.span)
                .hint("give coordinates, their velocities (`θ'`) or their momenta (`p_θ`)"));
            }
            let v = self.resolved(val)?;
            let x = self.number(&v, val.span)?;
            given.insert(s.to_string(), (x, sym.span));
        }
        let mut y0 = vec![0.0; 2 * n];
        for (i, q) in coords.iter().enumerate() {
            y0[i] = match given.get(q.name()) {
                Some((x, _)) => *x,
                None => {
                    return Err(SceneError::new(
                        ErrorKind::MissingValue,
                        format!("no initial value for `{}`", q.name()),
                    )
                    .at(stmt_span)
                    .hint(format!("add `{} = …` to the `simulate` statement", q.name())))
                }
            };
        }
        let vel = |q: &Symbol| format!("{}'", q.name());
        let mom = |q: &Symbol| format!("p_{}", q.name());
        match layout {
            Layout::Velocities => {
                for (i, q) in coords.iter().enumerate() {
                    if let Some((_, span)) = given.get(&mom(q)) {
                        return Err(SceneError::new(
                            ErrorKind::Syntax,
                            format!("this simulation integrates `L`, so give the velocity `{}`", vel(q)),
                        )
                        .at(*span)
                        .hint(format!("write `{} = …`, or choose a splitting method to integrate `H`", vel(q))));
                    }
                    y0[n + i] = given.get(&vel(q)).map(|v| v.0).ok_or_else(|| {
                        SceneError::new(ErrorKind::MissingValue, format!("no initial value for `{}`", vel(q)))
                            .at(stmt_span)
                            .hint(format!("add `{} = 0` (or another value) to the `simulate` statement", vel(q)))
                    })?;
                }
            }
            Layout::Momenta => {
                let any_velocity = coords.iter().any(|q| given.contains_key(&vel(q)));
                let any_momentum = coords.iter().any(|q| given.contains_key(&mom(q)));
                if any_velocity && any_momentum {
                    return Err(
                        SceneError::new(ErrorKind::Syntax, "give either velocities or momenta, not both").at(stmt_span)
                    );
                }
                if any_velocity {
                    // Velocities → momenta through p = ∂L/∂q' at the initial state.
                    let l = self.lagrangian().map_err(|e| {
                        e.hint(
                            "this method integrates `H`: give the momenta `p_q`, or define `L` to convert velocities",
                        )
                    })?;
                    let ps = self.momenta(&l)?;
                    let mut env: HashMap<String, f64> = self.param_values();
                    for (i, q) in coords.iter().enumerate() {
                        env.insert(q.name().to_string(), y0[i]);
                        let v = given.get(&vel(q)).map(|v| v.0).ok_or_else(|| {
                            SceneError::new(ErrorKind::MissingValue, format!("no initial value for `{}`", vel(q)))
                                .at(stmt_span)
                                .hint(format!("add `{} = 0` to the `simulate` statement", vel(q)))
                        })?;
                        env.insert(vel(q), v);
                    }
                    env.insert("t".into(), t0);
                    for (i, p) in ps.iter().enumerate() {
                        y0[n + i] = crate::eval::eval(p, &env).map_err(|e| self.value_error(e, stmt_span))?;
                    }
                } else {
                    for (i, q) in coords.iter().enumerate() {
                        y0[n + i] = given.get(&mom(q)).map(|v| v.0).ok_or_else(|| {
                            SceneError::new(ErrorKind::MissingValue, format!("no initial value for `{}`", mom(q)))
                                .at(stmt_span)
                                .hint(format!(
                                    "add `{} = 0` (or the velocity `{}`) to the `simulate` statement",
                                    mom(q),
                                    vel(q)
                                ))
                        })?;
                    }
                }
            }
        }

        // Events, in the state's variables.
        let mut event_exprs = Vec::new();
        let mut events = Vec::new();
        for (index, ev) in spec.events.iter().enumerate() {
            let e = self.event_expr(ev, layout, l_expr.as_ref(), h_expr.as_ref())?;
            event_exprs.push(e);
            events.push(EventRequest { index, terminal: ev.terminal, rising: ev.rising });
        }

        // Every parameter the equations use needs a value.
        let mut needed: BTreeSet<String> = BTreeSet::new();
        let exprs: Vec<&Expr> = match &formulation {
            Formulation::Lagrangian(e) | Formulation::Hamiltonian(e) => vec![e],
            Formulation::Separable { t, v } => vec![t, v],
        };
        for e in exprs.iter().copied().chain(event_exprs.iter()) {
            if let Some(f) = e.applied_functions().into_iter().next() {
                return Err(SceneError::new(
                    ErrorKind::MissingValue,
                    format!(
                        "the declared function `{f}` has no numeric definition, so the equations cannot be integrated"
                    ),
                )
                .at(stmt_span)
                .hint(format!("replace `{f}(…)` in `L` or `H` by an explicit expression before `simulate`")));
            }
            for s in e.free_symbols() {
                if self.params.contains_key(s.name()) && s.primes() == 0 {
                    needed.insert(s.name().to_string());
                }
            }
        }
        let mut params = Vec::new();
        for p in &needed {
            match self.params.get(p).and_then(|x| x.value) {
                Some(v) => params.push((p.clone(), v)),
                None => {
                    return Err(SceneError::new(ErrorKind::MissingValue, format!("parameter `{p}` has no value"))
                        .at(stmt_span)
                        .label(format!("needs a value for `{p}`"))
                        .hint(format!("declare `{p}` with a value before `simulate`: `parameters {p} = …`")))
                }
            }
        }

        // Compile (cached by symbolic content and parameter values), then integrate.
        let req = CompileRequest {
            coords: coords.clone(),
            formulation: formulation.clone(),
            params: params.clone(),
            method,
            events: event_exprs.clone(),
            decls: self.declarations(),
        };
        let mut inputs: Vec<Expr> = match &formulation {
            Formulation::Lagrangian(e) | Formulation::Hamiltonian(e) => vec![e.clone()],
            Formulation::Separable { t, v } => vec![t.clone(), v.clone()],
        };
        inputs.extend(event_exprs.iter().cloned());
        let key = CacheKey {
            step: Step::Compile,
            coords: coords.clone(),
            inputs,
            numbers: params.iter().map(|(_, v)| v.to_bits()).collect(),
            extra: format!(
                "{:?}{}",
                method.family,
                params.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(",")
            ),
        };
        let what = format!("{} for {}", formulation_name(&formulation), method.name);
        let compiled = match self.lookup(&key, Step::Compile, &what) {
            Some(Value::Compiled(c)) => c,
            _ => {
                let built = self.backend.compile(&req).map(Value::Compiled).map_err(|e| backend_error(e, stmt_span));
                match self.record(Step::Compile, what, key, built, stmt_span)? {
                    Value::Compiled(c) => c,
                    _ => return Err(SceneError::new(ErrorKind::Numeric, "compilation gave no code").at(stmt_span)),
                }
            }
        };
        let run = RunRequest { method, y0, t0, t1, dt, tol, events };
        let traj = self.integrate(&compiled, &run, name, stmt_span)?;
        Ok(RunResult {
            method,
            layout,
            coords,
            params: params.into_iter().collect(),
            traj: Arc::new(traj),
            lagrangian: l_expr,
            hamiltonian: h_expr,
        })
    }

    fn integrate(
        &mut self,
        compiled: &Compiled,
        run: &RunRequest,
        name: &str,
        span: Span,
    ) -> Result<Trajectory, SceneError> {
        let started = Instant::now();
        let mut bar: Option<indicatif::ProgressBar> = None;
        let show = self.opts.progress && std::io::IsTerminal::is_terminal(&std::io::stderr());
        let mut progress = |frac: f64| {
            if !show {
                return;
            }
            // Only simulations that take longer than about a second get a bar.
            if bar.is_none() && started.elapsed().as_secs_f64() > 1.0 && frac < 0.9 {
                let b = indicatif::ProgressBar::new(1000);
                if let Ok(style) = indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ETA {eta}") {
                    b.set_style(style);
                }
                b.set_message(name.to_string());
                bar = Some(b);
            }
            if let Some(b) = &bar {
                b.set_position((frac.clamp(0.0, 1.0) * 1000.0) as u64);
            }
        };
        let result = self.backend.integrate(compiled, run, &mut progress);
        if let Some(b) = bar {
            b.finish_and_clear();
        }
        let traj = result.map_err(|e| backend_error(e, span))?;
        self.plan.push(PlanEntry {
            step: Step::Integrate,
            what: format!("{name} with {} ({} steps)", run.method.name, traj.steps),
            line: Some(self.line),
            status: Status::Built,
        });
        Ok(traj)
    }

    fn value_error(&self, e: crate::eval::EvalError, span: Span) -> SceneError {
        match e {
            crate::eval::EvalError::Unbound(name) => {
                SceneError::new(ErrorKind::MissingValue, format!("`{name}` has no value"))
                    .at(span)
                    .hint(format!("declare `{name}` with a value before `simulate`: `parameters {name} = …`"))
            }
            other => SceneError::new(ErrorKind::BadNumber, other.to_string()).at(span),
        }
    }

    fn param_values(&self) -> HashMap<String, f64> {
        self.params.iter().filter_map(|(n, p)| p.value.map(|v| (n.clone(), v))).collect()
    }

    fn bound(&mut self, src: &Src) -> Result<f64, SceneError> {
        let e = self.resolved(src)?;
        self.number(&e, src.span)
    }

    /// Splits `H` into `T(p) + V(q, t)` term by term; a term mixing both makes `H`
    /// non-separable, which a splitting method cannot integrate.
    fn split(&mut self, h: &Expr, method: Method) -> Result<(Expr, Expr), SceneError> {
        let key = CacheKey {
            step: Step::Split,
            coords: self.coords.clone(),
            inputs: vec![h.clone()],
            numbers: vec![],
            extra: String::new(),
        };
        if let Some(Value::Exprs(v)) = self.lookup(&key, Step::Split, &format!("of {}", short(h))) {
            return Ok((v[0].clone(), v[1].clone()));
        }
        let coords = self.coords.clone();
        let is_p = |s: &Symbol| s.name().strip_prefix("p_").is_some_and(|c| coords.iter().any(|q| q.name() == c));
        let is_q = |s: &Symbol| s.is_time() || coords.iter().any(|q| q.name() == s.name());
        let mut t = Vec::new();
        let mut v = Vec::new();
        for term in h.terms() {
            let syms = term.free_symbols();
            let has_p = syms.iter().any(is_p);
            let has_q = syms.iter().any(is_q);
            if has_p && has_q {
                return Err(SceneError::new(
                    ErrorKind::Derivation,
                    format!(
                        "`{}` needs a separable H = T(p) + V(q), but the term `{}` mixes coordinates and momenta",
                        method.name,
                        render(&term, Format::Plain)
                    ),
                )
                .at(self.span)
                .hint("use `gauss6` (symplectic for any H) or `dop853`"));
            }
            if has_p {
                t.push(term);
            } else {
                v.push(term);
            }
        }
        let (t, v) = (Expr::add(t), Expr::add(v));
        self.record(
            Step::Split,
            format!("of {}", short(h)),
            key,
            Ok(Value::Exprs(vec![t.clone(), v.clone()])),
            self.span,
        )?;
        Ok((t, v))
    }

    fn event_expr(
        &mut self,
        ev: &EventSpec,
        layout: Layout,
        l: Option<&Expr>,
        h: Option<&Expr>,
    ) -> Result<Expr, SceneError> {
        let lhs = self.resolved(&ev.lhs)?;
        let e = match &ev.rhs {
            Some(r) => lhs.minus(&self.resolved(r)?),
            None => lhs,
        };
        self.in_layout(&e, layout, l, h, ev.span)
    }

    /// Rewrites an expression into the state variables of a layout: momenta become
    /// `∂L/∂q'` in a velocity layout, velocities become `∂H/∂p` in a momentum layout.
    fn in_layout(
        &mut self,
        e: &Expr,
        layout: Layout,
        l: Option<&Expr>,
        h: Option<&Expr>,
        span: Span,
    ) -> Result<Expr, SceneError> {
        let coords = self.coords.clone();
        let syms = e.free_symbols();
        let mut map = HashMap::new();
        for s in &syms {
            let Some(q) = coords.iter().find(|q| {
                (layout == Layout::Velocities && s.name() == format!("p_{}", q.name()) && s.primes() == 0)
                    || (layout == Layout::Momenta && s.name() == q.name() && s.primes() == 1)
            }) else {
                if coords.iter().any(|q| q.name() == s.name() && s.primes() >= 2) {
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("`{s}` is an acceleration, which is not part of the state"),
                    )
                    .at(span)
                    .hint("use coordinates, velocities or momenta"));
                }
                continue;
            };
            let value = match layout {
                Layout::Velocities => {
                    let l = l.cloned().map_or_else(|| self.lagrangian(), Ok)?;
                    self.diff.diff(&l, &q.prime())
                }
                Layout::Momenta => {
                    let h = h.cloned().map_or_else(|| self.hamiltonian(), Ok)?;
                    self.diff.diff(&h, &Symbol::new(&format!("p_{}", q.name())))
                }
            };
            map.insert(s.clone(), value);
        }
        Ok(if map.is_empty() { e.clone() } else { e.subs(&map) })
    }

    fn run_ids(&mut self, names: &[Src]) -> Result<Vec<usize>, SceneError> {
        if names.is_empty() {
            return match self.runs.len() {
                0 => Err(SceneError::new(ErrorKind::Undeclared, "no simulation to use")
                    .at(self.span)
                    .hint("add a `simulate …` statement before it")),
                n => Ok(vec![n - 1]),
            };
        }
        let mut out = Vec::new();
        for n in names {
            match self.run_names.get(&n.text) {
                Some(&id) => out.push(id),
                None => {
                    let known: Vec<&str> = self.run_names.keys().map(String::as_str).collect();
                    let err = SceneError::new(ErrorKind::UndefinedSymbol, format!("no simulation named `{}`", n.text))
                        .at(n.span);
                    return Err(match did_you_mean(&n.text, known) {
                        Some(k) => err.hint(format!("did you mean `{k}`?")),
                        None => err.hint("name a run with `simulate … as NAME`"),
                    });
                }
            }
        }
        Ok(out)
    }

    /// Values of `e` along a run.
    fn along(&mut self, r: &RunResult, e: &Expr, span: Span) -> Result<Vec<f64>, SceneError> {
        let e = self.in_layout(e, r.layout, r.lagrangian.as_ref(), r.hamiltonian.as_ref(), span)?;
        let names = state_names(&r.coords, r.layout);
        let mut out = Vec::with_capacity(r.traj.t.len());
        let params = self.param_values();
        for (t, y) in r.traj.t.iter().zip(&r.traj.y) {
            let lookup = |s: &Symbol| -> Option<f64> {
                if s.is_time() {
                    return Some(*t);
                }
                let spelled = s.to_string();
                if let Some(i) = names.iter().position(|n| *n == spelled) {
                    return y.get(i).copied();
                }
                r.params.get(s.name()).or_else(|| params.get(s.name())).copied()
            };
            let v = crate::eval::eval_with(&e, &lookup).map_err(|err| self.value_error(err, span))?;
            out.push(v);
        }
        Ok(out)
    }

    fn energy_of_run(&mut self, r: &RunResult) -> Result<Expr, SceneError> {
        match r.layout {
            Layout::Momenta => match &r.hamiltonian {
                Some(h) => Ok(h.clone()),
                None => self.hamiltonian(),
            },
            Layout::Velocities => {
                let l = match &r.lagrangian {
                    Some(l) => l.clone(),
                    None => self.lagrangian()?,
                };
                match self.derive(DerivKind::Energy, vec![l], self.span)? {
                    Value::Expr(e) => Ok(e),
                    _ => Err(SceneError::new(ErrorKind::Derivation, "no energy function").at(self.span)),
                }
            }
        }
    }

    // ----- outputs -------------------------------------------------------------------------

    fn out_path(&self, path: Option<&Src>, default: &str) -> (PathBuf, Span) {
        match path {
            Some(p) => {
                let pb = PathBuf::from(&p.text);
                (if pb.is_absolute() { pb } else { self.opts.out_dir.join(pb) }, p.span)
            }
            None => (self.opts.out_dir.join(format!("{}_{default}.svg", self.opts.stem)), self.span),
        }
    }

    fn plot(&mut self, spec: &PlotSpec) -> Result<(), SceneError> {
        let default = match &spec.kind {
            PlotKind::Phase(_) => "phase",
            PlotKind::Energy => "energy",
            PlotKind::Path(..) => "path",
            PlotKind::Poincare(..) => "poincare",
            PlotKind::Series(_) => "series",
        };
        let (path, pspan) = self.out_path(spec.path.as_ref(), default);
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        if ext != "svg" && ext != "png" {
            return Err(SceneError::new(
                ErrorKind::Io,
                format!("cannot tell the image format of `{}`", path.display()),
            )
            .at(pspan)
            .hint("plots are written as `.svg` or `.png`"));
        }
        let figure = self.figure(spec)?;
        let tmp = self.staging.stage(&path).map_err(|e| e.at(pspan))?;
        crate::plot::draw(&figure, &tmp).map_err(|e| {
            SceneError::new(ErrorKind::Io, format!("cannot write the plot `{}`: {e}", path.display())).at(pspan)
        })?;
        self.output.push(format!("wrote {}", path.display()));
        Ok(())
    }

    fn figure(&mut self, spec: &PlotSpec) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Figure, Series};
        match &spec.kind {
            PlotKind::Series(exprs) => {
                let ids = self.run_ids(&spec.runs)?;
                let mut series = Vec::new();
                for id in ids {
                    let r = self.demand_run(id)?;
                    for src in exprs {
                        let e = self.resolved(src)?;
                        let ys = self.along(&r, &e, src.span)?;
                        let label = if spec.runs.len() > 1 {
                            format!("{} ({})", src.text, self.runs[id].name)
                        } else {
                            src.text.clone()
                        };
                        series.push(Series { label, points: r.traj.t.iter().copied().zip(ys).collect() });
                    }
                }
                Ok(Figure::lines("time series", "t", "value", series))
            }
            PlotKind::Path(x, y) | PlotKind::Poincare(x, y) => {
                let poincare = matches!(spec.kind, PlotKind::Poincare(..));
                let ids = self.run_ids(&spec.runs)?;
                let mut series = Vec::new();
                for id in ids {
                    let r = self.demand_run(id)?;
                    let ex = self.resolved(x)?;
                    let ey = self.resolved(y)?;
                    let pts = if poincare {
                        if r.traj.events.is_empty() {
                            return Err(SceneError::new(
                                ErrorKind::Undeclared,
                                "the run recorded no events for a Poincaré section",
                            )
                            .at(self.span)
                            .hint("add `record when … = 0` to the `simulate` statement"));
                        }
                        let sub = RunResult {
                            traj: Arc::new(Trajectory {
                                t: r.traj.events.iter().map(|e| e.1).collect(),
                                y: r.traj.events.iter().map(|e| e.2.clone()).collect(),
                                ..Trajectory::default()
                            }),
                            ..r.clone()
                        };
                        let xs = self.along(&sub, &ex, x.span)?;
                        let ys = self.along(&sub, &ey, y.span)?;
                        xs.into_iter().zip(ys).collect()
                    } else {
                        let xs = self.along(&r, &ex, x.span)?;
                        let ys = self.along(&r, &ey, y.span)?;
                        xs.into_iter().zip(ys).collect()
                    };
                    series.push(Series { label: self.runs[id].name.clone(), points: pts });
                }
                Ok(if poincare {
                    Figure::scatter("Poincaré section", &x.text, &y.text, series)
                } else {
                    Figure::lines("configuration-space path", &x.text, &y.text, series)
                })
            }
            PlotKind::Energy => {
                let ids = self.run_ids(&spec.runs)?;
                let mut series = Vec::new();
                for id in ids {
                    let r = self.demand_run(id)?;
                    let e = self.energy_of_run(&r)?;
                    let es = self.along(&r, &e, self.span)?;
                    let e0 = es.first().copied().unwrap_or(0.0);
                    let scale = if e0.abs() > 0.0 { e0.abs() } else { 1.0 };
                    let pts = r.traj.t.iter().zip(&es).map(|(t, e)| (*t, ((e - e0) / scale).abs())).collect();
                    series.push(Series { label: format!("{} ({})", self.runs[id].name, r.method.name), points: pts });
                }
                Ok(Figure::log_y("relative energy error", "t", "|ΔE/E₀|", series))
            }
            PlotKind::Phase(coord) => self.phase_figure(coord.as_ref(), &spec.runs),
        }
    }

    fn phase_figure(&mut self, coord: Option<&Src>, runs: &[Src]) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Contours, Figure, Series};
        let index = match coord {
            None => 0,
            Some(c) => self.coords.iter().position(|q| q.name() == c.text).ok_or_else(|| {
                SceneError::new(ErrorKind::UndefinedSymbol, format!("`{}` is not a coordinate", c.text)).at(c.span)
            })?,
        };
        let Some(q) = self.coords.get(index).cloned() else {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared").at(self.span));
        };
        let one_dof = self.coords.len() == 1;
        let mut orbits = Vec::new();
        let mut layout = Layout::Momenta;
        let has_runs = !self.runs.is_empty();
        if has_runs {
            for id in self.run_ids(runs)? {
                let r = self.demand_run(id)?;
                layout = r.layout;
                let n = r.coords.len();
                let pts = r.traj.y.iter().map(|y| (y[index], y[n + index])).collect();
                orbits.push(Series { label: self.runs[id].name.clone(), points: pts });
            }
        }
        let vname = match layout {
            Layout::Momenta => format!("p_{}", q.name()),
            Layout::Velocities => format!("{}'", q.name()),
        };
        // Contours of the energy-like function, for one degree of freedom.
        let mut contours = None;
        if one_dof {
            let f = match layout {
                Layout::Momenta => self.hamiltonian()?,
                Layout::Velocities => {
                    let l = self.lagrangian()?;
                    match self.derive(DerivKind::Energy, vec![l], self.span)? {
                        Value::Expr(e) => e,
                        _ => return Err(SceneError::new(ErrorKind::Derivation, "no energy function").at(self.span)),
                    }
                }
            };
            let params = self.param_values();
            let qs = q.name().to_string();
            let f_num = move |x: f64, v: f64| -> f64 {
                crate::eval::eval_with(&f, &|s: &Symbol| {
                    if s.name() == qs && s.primes() == 0 {
                        Some(x)
                    } else if s.to_string() == vname {
                        Some(v)
                    } else if s.is_time() {
                        Some(0.0)
                    } else {
                        params.get(s.name()).copied()
                    }
                })
                .unwrap_or(f64::NAN)
            };
            if f_num(0.0, 0.0).is_nan() && f_num(0.5, 0.5).is_nan() {
                let missing = self.params.iter().find(|(_, p)| p.value.is_none()).map(|(n, _)| n.clone());
                return Err(SceneError::new(
                    ErrorKind::MissingValue,
                    "the phase portrait needs numbers for every parameter",
                )
                .at(self.span)
                .hint(match missing {
                    Some(m) => format!("declare `{m}` with a value before `plot`: `parameters {m} = …`"),
                    None => "give every parameter a value".to_string(),
                }));
            }
            contours = Some(Contours::new(Box::new(f_num)));
        } else if orbits.is_empty() {
            return Err(SceneError::new(
                ErrorKind::Undeclared,
                "a phase portrait of a system with several coordinates needs a simulation",
            )
            .at(self.span)
            .hint("add a `simulate …` statement before `plot phase`"));
        }
        let vlabel = match layout {
            Layout::Momenta => format!("p_{}", q.name()),
            Layout::Velocities => format!("{}'", q.name()),
        };
        Ok(Figure::phase("phase portrait", q.name(), &vlabel, orbits, contours))
    }

    fn export(&mut self, items: &[Item], run: Option<&Src>, path: &Src) -> Result<(), SceneError> {
        let (file, pspan) = self.out_path(Some(path), "export");
        let ext = file.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        if ext != "csv" && ext != "json" {
            return Err(SceneError::new(
                ErrorKind::Io,
                format!("cannot tell the export format of `{}`", file.display()),
            )
            .at(pspan)
            .hint("export to `.csv` (numbers along a run) or `.json`"));
        }
        let symbolic = items.iter().any(|i| matches!(i, Item::Derivation(_)));
        let text = if symbolic {
            if ext == "csv" {
                return Err(SceneError::new(ErrorKind::Io, "derived equations export to `.json`, not `.csv`").at(pspan));
            }
            let mut entries = Vec::new();
            for item in items {
                let label = match item {
                    Item::Derivation(c) => c.kind.keyword().to_string(),
                    Item::Expr(s) => s.text.clone(),
                };
                let value = match self.printed_item(item)? {
                    Printed::Named(_, e) | Printed::Value(e) => serde_json::json!(crate::print::plain(&e)),
                    Printed::Lines(lines) => serde_json::Value::Array(
                        lines
                            .iter()
                            .map(|l| {
                                serde_json::json!({
                                    "label": l.label,
                                    "lhs": crate::print::plain(&l.lhs),
                                    "rhs": crate::print::plain(&l.rhs),
                                    "note": l.note,
                                })
                            })
                            .collect(),
                    ),
                };
                entries.push(serde_json::json!({ "name": label, "value": value }));
            }
            let mut s = serde_json::to_string_pretty(&serde_json::Value::Array(entries)).unwrap_or_default();
            s.push('\n');
            s
        } else {
            let ids = self.run_ids(&run.cloned().into_iter().collect::<Vec<_>>())?;
            let r = self.demand_run(ids[0])?;
            let mut columns: Vec<(String, Vec<f64>)> = vec![("t".to_string(), r.traj.t.clone())];
            if items.is_empty() {
                let names = state_names(&r.coords, r.layout);
                for (i, n) in names.iter().enumerate() {
                    columns.push((n.clone(), r.traj.y.iter().map(|y| y[i]).collect()));
                }
            } else {
                for item in items {
                    if let Item::Expr(src) = item {
                        if src.text.trim() == "t" {
                            continue;
                        }
                        let e = self.resolved(src)?;
                        columns.push((src.text.trim().to_string(), self.along(&r, &e, src.span)?));
                    }
                }
            }
            if ext == "csv" {
                let mut s = columns.iter().map(|c| csv_field(&c.0)).collect::<Vec<_>>().join(",");
                s.push('\n');
                for i in 0..r.traj.t.len() {
                    let row: Vec<String> = columns.iter().map(|c| format!("{:e}", c.1[i])).collect();
                    s.push_str(&row.join(","));
                    s.push('\n');
                }
                s
            } else {
                let cols: Vec<serde_json::Value> =
                    columns.iter().map(|(n, v)| serde_json::json!({ "name": n, "values": v })).collect();
                let v = serde_json::json!({ "run": self.runs[ids[0]].name, "method": r.method.name, "columns": cols });
                let mut s = serde_json::to_string_pretty(&v).unwrap_or_default();
                s.push('\n');
                s
            }
        };
        let tmp = self.staging.stage(&file).map_err(|e| e.at(pspan))?;
        std::fs::write(&tmp, text)
            .map_err(|e| SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", file.display())).at(pspan))?;
        self.output.push(format!("wrote {}", file.display()));
        Ok(())
    }

    fn load(&mut self, path: &Src) -> Result<(), SceneError> {
        if self.load_depth >= MAX_LOAD_DEPTH {
            return Err(SceneError::new(ErrorKind::Io, format!("`load` nested deeper than {MAX_LOAD_DEPTH} files"))
                .at(path.span)
                .hint("a scene probably loads itself"));
        }
        let p = PathBuf::from(&path.text);
        let full = if p.is_absolute() { p } else { self.opts.base_dir.join(p) };
        let text = read_scene(&full).map_err(|e| {
            if e.has_source() {
                e
            } else {
                let span = e.span.unwrap_or(path.span);
                let e = if e.span.is_none() { e.at(span) } else { e };
                e.with_source(&self.source)
            }
        })?;
        let name = full.display().to_string();
        self.load_depth += 1;
        let saved = (self.line, self.span);
        let r = self.run_text(&name, &text);
        self.load_depth -= 1;
        (self.line, self.span) = saved;
        r?;
        self.output.push(format!("loaded {name}"));
        Ok(())
    }

    // ----- the plan ------------------------------------------------------------------------

    fn finish_plan(&mut self) {
        // Lazy definitions and simulations nothing asked for.
        for d in &self.defs {
            if let (DefBody::Deriv { kind, .. }, false) = (&d.body, d.demanded) {
                self.plan.push(PlanEntry {
                    step: deriv_step(*kind),
                    what: format!("`{}` ({})", d.name, kind.keyword()),
                    line: Some(d.line),
                    status: Status::Skipped(format!("no output uses `{}`", d.name)),
                });
            }
        }
        for r in &self.runs {
            if r.result.is_none() {
                self.plan.push(PlanEntry {
                    step: Step::Integrate,
                    what: format!(
                        "{} ({})",
                        r.name,
                        r.spec.method.as_ref().map_or(sim::DEFAULT_METHOD, |m| m.text.as_str())
                    ),
                    line: Some(r.line),
                    status: Status::Skipped(format!("no plot or export uses `{}`", r.name)),
                });
            }
        }
        // The standard derivations of the system that nothing needed.
        let has_l = self.def_names.contains_key("L");
        let has_h = self.def_names.contains_key("H") || has_l;
        let mut standard = Vec::new();
        if has_l {
            standard.push(Step::EulerLagrange);
            standard.push(Step::Legendre);
        }
        if has_h {
            standard.push(Step::Hamilton);
            standard.push(Step::Conserved);
            standard.push(Step::Energy);
            standard.push(Step::Bracket);
        }
        for step in standard {
            if !self.plan.iter().any(|e| e.step == step) {
                self.plan.push(PlanEntry {
                    step,
                    what: String::new(),
                    line: None,
                    status: Status::Skipped("no output needs it".to_string()),
                });
            }
        }
    }

    /// The plan as text, for `--explain`.
    pub fn explain(&self) -> String {
        let mut s = String::from("plan:\n");
        for e in &self.plan {
            let status = match &e.status {
                Status::Built => "built  ".to_string(),
                Status::Reused => "reused ".to_string(),
                Status::Skipped(_) => "skipped".to_string(),
            };
            let line = e.line.map_or("        ".to_string(), |l| format!("line {l:<3}"));
            let mut what = e.step.name().to_string();
            if !e.what.is_empty() {
                what.push(' ');
                what.push_str(&e.what);
            }
            let why = match &e.status {
                Status::Skipped(r) => format!(" — {r}"),
                Status::Reused => " — same symbolic input as an earlier run".to_string(),
                Status::Built => String::new(),
            };
            s.push_str(&format!("  {status} {line} {what}{why}\n"));
        }
        let count = |f: &dyn Fn(&Status) -> bool| self.plan.iter().filter(|e| f(&e.status)).count();
        s.push_str(&format!(
            "{} built, {} reused, {} skipped\n",
            count(&|s| *s == Status::Built),
            count(&|s| *s == Status::Reused),
            count(&|s| matches!(s, Status::Skipped(_)))
        ));
        s
    }
}

fn unreachable_energy() -> Result<Value, BackendError> {
    Err(BackendError::Failed("internal: energy is computed by the session".to_string()))
}

fn deriv_step(kind: DerivKind) -> Step {
    match kind {
        DerivKind::El => Step::EulerLagrange,
        DerivKind::Legendre => Step::Legendre,
        DerivKind::Hamilton => Step::Hamilton,
        DerivKind::Conserved => Step::Conserved,
        DerivKind::Pb => Step::Bracket,
        DerivKind::Energy => Step::Energy,
    }
}

/// The energy function `h = Σ q'_i ∂L/∂q'_i − L` (PHYSICS.md §2, Noether).
fn energy_function(d: &mut Differentiator, coords: &[Symbol], l: &Expr) -> Expr {
    let mut terms: Vec<Expr> = coords.iter().map(|q| Expr::sym(q.prime()).times(&d.diff(l, &q.prime()))).collect();
    terms.push(l.neg());
    Expr::add(terms)
}

fn formulation_name(f: &Formulation) -> &'static str {
    match f {
        Formulation::Lagrangian(_) => "W q'' = F from L",
        Formulation::Hamiltonian(_) => "Hamilton's equations of H",
        Formulation::Separable { .. } => "drift ∂T/∂p and kick −∂V/∂q",
    }
}

fn state_names(coords: &[Symbol], layout: Layout) -> Vec<String> {
    let mut names: Vec<String> = coords.iter().map(|q| q.name().to_string()).collect();
    for q in coords {
        names.push(match layout {
            Layout::Velocities => format!("{}'", q.name()),
            Layout::Momenta => format!("p_{}", q.name()),
        });
    }
    names
}

/// The first characters of an expression's plain form, for the plan.
fn short(e: &Expr) -> String {
    let s = crate::print::plain(e);
    if s.chars().count() > 48 {
        let cut: String = s.chars().take(45).collect();
        format!("{cut}…")
    } else {
        s
    }
}

fn format_name(f: Format) -> &'static str {
    match f {
        Format::Plain => "plain",
        Format::Unicode => "unicode",
        Format::Latex => "latex",
    }
}

fn render_line(l: &Line, f: Format) -> String {
    let mut s = String::new();
    if let Some(label) = &l.label {
        s.push_str(label);
        s.push_str(": ");
    }
    s.push_str(&render(&l.lhs, f));
    s.push_str(" = ");
    s.push_str(&render(&l.rhs, f));
    if let Some(n) = &l.note {
        s.push_str("   (");
        s.push_str(n);
        s.push(')');
    }
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// A number for messages: short, deterministic.
pub fn fmt_num(x: f64) -> String {
    if x == x.trunc() && x.abs() < 1e15 {
        format!("{x:.0}")
    } else {
        let s = format!("{x:.6}");
        s.trim_end_matches('0').to_string()
    }
}

/// The span of the first whole-word occurrence of `spelled` in `src`, else all of `src`.
fn symbol_span(src: &Src, spelled: &str) -> Span {
    let text = &src.text;
    let is_ident = |c: char| c.is_alphanumeric() || c == '_' || c == '\'';
    let mut from = 0;
    while let Some(i) = text[from..].find(spelled) {
        let start = from + i;
        let end = start + spelled.len();
        let before_ok = text[..start].chars().next_back().map_or(true, |c| !is_ident(c));
        let after_ok = text[end..].chars().next().map_or(true, |c| !is_ident(c));
        if before_ok && after_ok {
            return (src.span.0 + start, src.span.0 + end);
        }
        from = end;
    }
    src.span
}

/// Reads a scene file: at most [`MAX_SCENE_BYTES`], valid UTF-8, or a clear error.
pub fn read_scene(path: &Path) -> Result<String, SceneError> {
    let meta = std::fs::metadata(path)
        .map_err(|e| SceneError::new(ErrorKind::Io, format!("cannot read `{}`: {e}", path.display())))?;
    if meta.len() > MAX_SCENE_BYTES {
        return Err(SceneError::new(
            ErrorKind::TooLarge,
            format!(
                "`{}` is {:.1} MB; scene files are limited to {} MB",
                path.display(),
                meta.len() as f64 / 1e6,
                MAX_SCENE_BYTES >> 20
            ),
        )
        .hint("a scene is a short list of statements; generate large inputs as data files"));
    }
    let bytes = std::fs::read(path)
        .map_err(|e| SceneError::new(ErrorKind::Io, format!("cannot read `{}`: {e}", path.display())))?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        let col = bytes[..at].iter().rev().take_while(|&&b| b != b'\n').count() + 1;
        SceneError::new(
            ErrorKind::Encoding,
            format!("`{}` is not UTF-8: invalid byte 0x{:02x} at line {line}, column {col}", path.display(), bytes[at]),
        )
        .hint("save the scene as UTF-8 (Greek letters such as θ must be UTF-8 encoded)")
    })
}
