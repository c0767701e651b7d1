//! Running statements, and what many of them share: `run_scene` / `run_line` run a text
//! (`exec` dispatches each statement to its own `Stmt::run` with where it is, an `At`);
//! expressions are parsed and checked against the declarations, definitions demanded and
//! substituted, derivations looked up, built and recorded, and the plan closed. The session's
//! data is in `state.rs`; every statement, with its type, reader and handler, is in
//! `statements/`, one family per file.
//!
//! Demand-driven evaluation: a definition (`H = legendre(L)`, `E = el(L)`) and a `simulate`
//! only record what they would build. Outputs — `print`, a bare derivation (`el`), `plot`,
//! `export`, and in the REPL every statement — demand values, and a demand builds exactly the
//! derivations it needs, each once. Derivations are cached by their symbolic content
//! (the kind, the coordinates and the input expressions, which are hash-consed, so the key
//! compares in O(1)); numbers (parameter values, initial states, time spans) are not part of
//! a derivation's key, so re-running a scene with other numbers reuses the derivations —
//! from memory in the same process, from the disk cache ([`crate::cache`]) in another.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use miette::NamedSource;

use super::engine::backend::SystemRef;
use super::registry::{parse_scene, Statement};
use super::state::{backend_error, interruption, short, At, DefBody, Mode, Options, Refs, Session};
use super::syntax::ast::{symbol_span, DerivCall, DerivKind, Src};
use super::syntax::error::{did_you_mean, ErrorKind, SceneError, Span};
use super::syntax::source::{line_breaks, refuse_lookalikes};
use crate::expr::{Expr, Symbol};
use crate::parse::{parse_with, Declarations};

/// The derivations usable as functions inside expressions.
const DERIVATION_NAMES: &[&str] = &["el", "legendre", "hamilton", "conserved", "pb", "energy", "accelerations"];

pub use super::engine::plan::{PlanEntry, Status, Step};
pub use crate::cache::Cache;
use crate::cache::{CacheKey, Value};

/// The plan entries a REPL keeps (see `Session::bound_plan`).
const MAX_REPL_PLAN: usize = 2048;

impl Session {
    /// Checks every output of `stmts` before any of them runs: each path is allowed
    /// ([`Session::out_path`]) and has a known format, and no two outputs of this scene (or
    /// REPL entry) write the same file, where the second would silently replace the first.
    pub(in crate::scene) fn claim_outputs(&mut self, stmts: &[Statement]) -> Result<(), SceneError> {
        for st in stmts {
            let Some(out) = st.node.output() else { continue };
            let (file, span, _) = self.out_file(st.span, out.path, out.default, out.what, out.formats, out.hint)?;
            let span = if out.path.is_some() { span } else { st.span };
            self.staging.claim(&file).map_err(|e| e.at(span))?;
        }
        Ok(())
    }

    /// What each figure drawn so far shows (title, labels, series, ranges, legend), by file,
    /// in the order drawn: the content a test can check without reading pixels.
    pub fn figures(&self) -> &[(PathBuf, crate::plot::Description)] {
        &self.figures
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

    /// The warnings since the last call (each one line, `warning: …`), for standard error.
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
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
        let result = self.run_text(name, text).and_then(|()| {
            self.finish_plan();
            self.staging.commit().map_err(|e| e.with_source(&self.source))
        });
        self.settle_outputs(result)
    }

    /// Runs one REPL entry (one or more statements). Files are written as each succeeds.
    pub fn run_line(&mut self, text: &str) -> Result<(), SceneError> {
        let result =
            self.run_text("input", text).and_then(|()| self.staging.commit().map_err(|e| e.with_source(&self.source)));
        self.settle_outputs(result)
    }

    /// After a failure nothing staged is written: the files are removed and the lines that
    /// announced them withdrawn.
    fn settle_outputs(&mut self, result: Result<(), SceneError>) -> Result<(), SceneError> {
        if result.is_err() {
            self.staging.abort();
            for i in self.staging.withdrawn() {
                if i < self.output.len() {
                    self.output.remove(i);
                }
            }
        }
        result
    }

    pub(super) fn run_text(&mut self, name: &str, text: &str) -> Result<(), SceneError> {
        let text = &line_breaks(text);
        let saved = self.source.clone();
        self.source = Arc::new(NamedSource::new(name, text.to_string()));
        let src = self.source.clone();
        let result = refuse_lookalikes(text).and_then(|()| parse_scene(text)).and_then(|stmts| {
            self.claim_outputs(&stmts)?;
            // Line numbers by one forward pass: counting from the start for every statement
            // made a scene of 10⁵ definitions quadratic (44 s).
            let (mut line, mut at) = (1, 0);
            for st in &stmts {
                let pos = st.span.0.min(text.len()).max(at);
                line += text.as_bytes()[at..pos].iter().filter(|&&b| b == b'\n').count();
                at = pos;
                // Ctrl-C: stop before the next statement, and report a statement whose work
                // was cut short as interrupted whatever error the cut produced.
                interruption(st.span)?;
                let r = self.exec(st, line);
                interruption(st.span)?;
                r?;
            }
            Ok(())
        });
        self.source = saved;
        result.map_err(|e| e.with_source(&src))
    }

    /// Runs one statement: its own type's handler ([`Stmt::run`]), told where it is.
    pub(super) fn exec(&mut self, st: &Statement, line: usize) -> Result<(), SceneError> {
        st.node.run(self, At { line, span: st.span })
    }

    // ----- declarations -------------------------------------------------------------------

    pub(super) fn declarations(&self) -> Declarations {
        let positive = self.params.iter().filter(|(_, p)| p.positive).map(|(n, _)| n.clone());
        let names = self
            .coords
            .iter()
            .map(|c| c.name().to_string())
            .chain(self.params.keys().cloned())
            .chain(self.def_names.keys().cloned());
        Declarations::new().with_functions(self.functions.iter()).with_positive(positive).with_families_of(names)
    }

    pub(super) fn name_in_use(&self, name: &str) -> Option<&'static str> {
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

    // ----- expressions ---------------------------------------------------------------------

    /// Parses an expression in the session's context, checks that every symbol is known and
    /// returns the definitions it refers to.
    pub(super) fn expr(&mut self, src: &Src) -> Result<(Expr, Refs), SceneError> {
        // The derivations are functions inside an expression (`pb(pb(x, p_x), H)`), as on the
        // command line; `resolve` replaces each call by its result.
        let derivations: Vec<&str> =
            DERIVATION_NAMES.iter().copied().filter(|n| self.name_in_use(n).is_none()).collect();
        let decls = self.declarations().with_functions(derivations);
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
                self.referenced.insert(r);
                refs.push((s, r));
            }
        }
        Ok((e, refs))
    }

    /// `Some(def)` if `s` names a definition; an error if `s` is unknown.
    pub(super) fn check_symbol(&self, s: &Symbol, src: &Src) -> Result<Option<usize>, SceneError> {
        let name = s.name();
        // A local name matches exactly as spelled (`q'` is local only where a statement made it so).
        if s.is_time() || self.local_names.iter().any(|n| *n == s.to_string()) {
            return Ok(None);
        }
        if self.coords.iter().any(|c| c.name() == name) || self.dynamics.is_aux_name(s) {
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
    pub(super) fn number(&self, e: &Expr, span: Span) -> Result<f64, SceneError> {
        let v = crate::eval::eval_with(e, &|s: &Symbol| self.params.get(s.name()).and_then(|p| p.value));
        let exact_nonzero = e.as_num().is_some_and(|r| !num_traits::Zero::is_zero(r));
        match v {
            Ok(x) if x == 0.0 && exact_nonzero => Err(SceneError::new(
                ErrorKind::BadNumber,
                format!(
                    "`{}` underflows to 0 in f64 (the smallest positive f64 is about 4.9e-324)",
                    crate::print::short_number(e)
                ),
            )
            .at(span)
            .hint("rescale the units so the numbers stay within 1e-300..1e300")),
            Ok(x) if x.is_finite() => Ok(x),
            Ok(_) if exact_nonzero => Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("`{}` overflows f64 (the largest f64 is about 1.8e308)", crate::print::short_number(e)),
            )
            .at(span)
            .hint("rescale the units so the numbers stay within 1e-300..1e300")),
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

    pub(super) fn resolve(&mut self, at: At, raw: &Expr, refs: &Refs) -> Result<Expr, SceneError> {
        let substituted = self.substitute_definitions(at, raw, refs)?;
        self.derivations_inside(at, &substituted, &mut HashMap::new())
    }

    /// Replaces each derivation written as a function (`pb(f, g)`, `legendre(L)`,
    /// `energy(L)`) by its result, innermost first, so that calls nest. Memoised by node: a
    /// definition used twice is one shared node, derived once.
    fn derivations_inside(&mut self, at: At, e: &Expr, done: &mut HashMap<Expr, Expr>) -> Result<Expr, SceneError> {
        if let Some(v) = done.get(e) {
            return Ok(v.clone());
        }
        let mut kids = Vec::new();
        e.for_each_child(|c| kids.push(c.clone()));
        let mut new_kids = Vec::with_capacity(kids.len());
        for k in &kids {
            new_kids.push(self.derivations_inside(at, k, done)?);
        }
        let out = match e.node() {
            crate::expr::Node::Apply { name, orders, .. }
                if DERIVATION_NAMES.contains(&&**name) && !self.functions.contains(&**name) =>
            {
                let kind = DerivKind::from_keyword(name).ok_or_else(|| {
                    SceneError::new(ErrorKind::Syntax, format!("`{name}` is not a derivation")).at(at.span)
                })?;
                if orders.iter().any(|&o| o > 0) {
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("`{name}` cannot be differentiated by primes"),
                    )
                    .at(at.span)
                    .hint(format!("define it first, `D = {name}(…)`, and differentiate the definition")));
                }
                match self.derive(at, kind, new_kids, at.span)? {
                    Value::Expr(v) => v,
                    _ => {
                        return Err(SceneError::new(
                            ErrorKind::Syntax,
                            format!("`{name}(…)` is a list of equations, not an expression"),
                        )
                        .at(at.span)
                        .hint(format!("print it on its own: `{name}`")))
                    }
                }
            }
            _ if kids == new_kids => e.clone(),
            _ => e.with_children(new_kids),
        };
        done.insert(e.clone(), out.clone());
        Ok(out)
    }

    /// `raw` with the definitions it names replaced by their values.
    fn substitute_definitions(&mut self, at: At, raw: &Expr, refs: &Refs) -> Result<Expr, SceneError> {
        if refs.is_empty() {
            return Ok(raw.clone());
        }
        let mut map = HashMap::new();
        for (s, id) in refs {
            match self.demand_def(at, *id)? {
                Value::Expr(e) => {
                    map.insert(s.clone(), e);
                }
                _ => {
                    let name = self.defs[*id].name.clone();
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("`{name}` is a list of equations, not an expression"),
                    )
                    .at(at.span)
                    .hint(format!("print it on its own: `print {name}`")));
                }
            }
        }
        Ok(raw.subs(&map))
    }

    pub(super) fn resolved(&mut self, at: At, src: &Src) -> Result<Expr, SceneError> {
        let (raw, refs) = self.expr(src)?;
        self.resolve(at, &raw, &refs)
    }

    /// `src` resolved with `names` accepted as free symbols (differentials, unknowns).
    pub(super) fn resolved_local(&mut self, at: At, src: &Src, names: &[String]) -> Result<Expr, SceneError> {
        self.local_names = names.to_vec();
        let r = self.resolved(at, src);
        self.local_names.clear();
        r
    }

    pub(super) fn need_coordinates(&self, at: At, what: &str) -> Result<Vec<Symbol>, SceneError> {
        if self.coords.is_empty() {
            return Err(SceneError::new(
                ErrorKind::Undeclared,
                format!("`{what}` needs coordinates, and none are declared"),
            )
            .at(at.span)
            .hint("declare them first, for example `coordinates θ, φ`"));
        }
        Ok(self.coords.clone())
    }

    pub(super) fn numbers(&mut self, at: At, srcs: &[Src]) -> Result<Vec<f64>, SceneError> {
        let mut out = Vec::new();
        for src in srcs {
            let e = self.resolved(at, src)?;
            out.push(self.number(&e, src.span)?);
        }
        Ok(out)
    }

    // ----- definitions ---------------------------------------------------------------------

    pub(super) fn demand_def(&mut self, at: At, id: usize) -> Result<Value, SceneError> {
        if let Some(v) = &self.defs[id].value {
            return Ok(v.clone());
        }
        self.defs[id].demanded = true;
        let body = self.defs[id].body.clone();
        let v = match body {
            DefBody::Expr { raw, refs } => Value::Expr(self.resolve(at, &raw, &refs)?),
            DefBody::Deriv { kind, args, span } => {
                let at = At { span, ..at };
                let mut resolved = Vec::new();
                for (raw, refs) in &args {
                    resolved.push(self.resolve(at, raw, refs)?);
                }
                self.derive(at, kind, resolved, span)?
            }
        };
        self.defs[id].value = Some(v.clone());
        Ok(v)
    }

    pub(super) fn def_value(&mut self, at: At, name: &str) -> Result<Option<Expr>, SceneError> {
        let Some(&id) = self.def_names.get(name) else { return Ok(None) };
        match self.demand_def(at, id)? {
            Value::Expr(e) => Ok(Some(e)),
            _ => Err(SceneError::new(ErrorKind::Syntax, format!("`{name}` must be an expression")).at(at.span)),
        }
    }

    pub(super) fn lagrangian(&mut self, at: At) -> Result<Expr, SceneError> {
        match self.def_value(at, "L")? {
            Some(l) => Ok(l),
            None => Err(SceneError::new(ErrorKind::Undeclared, "no Lagrangian defined")
                .at(at.span)
                .label("needs `L`")
                .hint("define it first, for example `L = 1/2 m x'^2 - 1/2 k x^2`")),
        }
    }

    pub(super) fn hamiltonian(&mut self, at: At) -> Result<Expr, SceneError> {
        if let Some(h) = self.def_value(at, "H")? {
            return Ok(h);
        }
        if self.def_names.contains_key("L") {
            let l = self.lagrangian(at)?;
            return match self.derive(at, DerivKind::Legendre, vec![l], at.span)? {
                Value::Expr(h) => Ok(h),
                _ => Err(SceneError::new(ErrorKind::Derivation, "the Legendre transform gave no expression")),
            };
        }
        Err(SceneError::new(ErrorKind::Undeclared, "no Hamiltonian or Lagrangian defined")
            .at(at.span)
            .label("needs `H` or `L`")
            .hint("define `H = …` or `L = …` first"))
    }

    pub(super) fn derive_call(&mut self, at: At, call: &DerivCall) -> Result<Value, SceneError> {
        let mut args = Vec::new();
        for a in &call.args {
            args.push(self.resolved(at, a)?);
        }
        self.derive(at, call.kind, args, call.span)
    }

    pub(super) fn derive(
        &mut self,
        at: At,
        kind: DerivKind,
        mut args: Vec<Expr>,
        span: Span,
    ) -> Result<Value, SceneError> {
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
                DerivKind::El | DerivKind::Legendre | DerivKind::Accelerations => args.push(self.lagrangian(at)?),
                DerivKind::Hamilton => args.push(self.hamiltonian(at)?),
                DerivKind::Conserved | DerivKind::Energy => {
                    if self.def_names.contains_key("L") {
                        args.push(self.lagrangian(at)?)
                    } else {
                        args.push(self.hamiltonian(at)?)
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
        // `el`, `hamilton` and `conserved` include the declared forces, dissipation and
        // constraints; the cache key then holds them too (after the inputs, their layout in
        // `extra`), so a result without them is never reused for one with them.
        let with_dynamics =
            matches!(kind, DerivKind::El | DerivKind::Hamilton | DerivKind::Conserved | DerivKind::Accelerations)
                && !self.dynamics.is_empty();
        if with_dynamics && self.dynamics.velocity_constrained() {
            // These derivations would leave the velocity constraints out: refused, not wrong.
            return Err(SceneError::new(
                ErrorKind::Derivation,
                "this derivation does not include velocity constraints (the Lagrange–d'Alembert equations)",
            )
            .at(span)
            .hint("`lagrangian el L --coords … --velocity-constraint …` prints them; `simulate` runs them"));
        }
        let (forces, rayleigh, constraints) =
            if with_dynamics { self.resolved_dynamics(at)? } else { (Vec::new(), None, Vec::new()) };
        let sys = SystemRef {
            coords: &coords,
            decls: &decls,
            forces: &forces,
            rayleigh: rayleigh.as_ref(),
            constraints: &constraints,
        };
        let what = format!("of {}", short(&args[0]));
        let step = deriv_step(kind);
        let mut key = CacheKey::symbolic(step, &coords, args.clone());
        if with_dynamics {
            key.inputs.extend(forces.iter().cloned());
            key.inputs.extend(rayleigh.iter().cloned());
            key.inputs.extend(constraints.iter().cloned());
            key.extra = format!(
                "dynamics: {} forces, {} Rayleigh, {} constraints",
                forces.len(),
                usize::from(rayleigh.is_some()),
                constraints.len()
            );
        }
        let hamiltonian_input = is_h(&args[0]);
        if kind == DerivKind::Energy && hamiltonian_input {
            // The energy of a Hamiltonian system is `H` itself: nothing to derive.
            return Ok(Value::Expr(args[0].clone()));
        }
        if let Some(v) = self.lookup(at, &key, step, &what) {
            return Ok(v);
        }
        let backend = &*self.backend;
        let built = match kind {
            DerivKind::El => backend.euler_lagrange(&sys, &args[0]).map(Value::Lines),
            DerivKind::Legendre => backend.legendre(&sys, &args[0]).map(Value::Expr),
            DerivKind::Hamilton => backend.hamilton(&sys, &args[0]).map(Value::Lines),
            DerivKind::Conserved => backend.conserved(&sys, &args[0], hamiltonian_input).map(Value::Lines),
            DerivKind::Pb => backend.bracket(&sys, &args[0], &args[1]).map(Value::Expr),
            DerivKind::Energy => backend.energy(&sys, &args[0]).map(Value::Expr),
            DerivKind::Accelerations => backend.accelerations(&sys, &args[0]).map(Value::Lines),
        };
        self.record(at, step, what, key, built.map_err(|e| backend_error(e, span)))
    }

    /// A cached value, from memory or else from the disk cache, recording in the plan where
    /// it came from (once per session).
    pub(super) fn lookup(&mut self, at: At, key: &CacheKey, step: Step, what: &str) -> Option<Value> {
        let (v, status) = match self.cache.get(key) {
            Some(v) => (v, Status::Reused),
            None => {
                let decls = self.declarations();
                (self.cache.load(key, &decls)?, Status::Loaded)
            }
        };
        if !self.built_here.contains(key) {
            self.built_here.insert(key.clone());
            self.plan.push(PlanEntry { step, what: what.to_string(), line: Some(at.line), status });
            self.bound_plan();
        }
        Some(v)
    }

    /// A REPL keeps the plan of its last [`MAX_REPL_PLAN`] steps only: a session that derives
    /// for days would otherwise keep one entry (and one cache key) per derivation forever. A
    /// scene's plan is whole: it is printed at the end.
    fn bound_plan(&mut self) {
        if self.opts.mode == Mode::Repl && self.plan.len() > MAX_REPL_PLAN {
            self.plan.drain(..self.plan.len() - MAX_REPL_PLAN / 2);
            self.built_here.clear();
        }
    }

    /// Caches a value just built (a miss in [`Session::lookup`]) and records it in the plan.
    pub(super) fn record(
        &mut self,
        at: At,
        step: Step,
        what: String,
        key: CacheKey,
        built: Result<Value, SceneError>,
    ) -> Result<Value, SceneError> {
        // A value computed while Ctrl-C was pending may be cut short (a simplification
        // stopped early): it is never cached.
        interruption(at.span)?;
        let v = built?;
        self.cache.insert(key.clone(), v.clone());
        self.built_here.insert(key);
        self.plan.push(PlanEntry { step, what, line: Some(at.line), status: Status::Built });
        self.bound_plan();
        Ok(v)
    }

    /// Canonical momenta `p_i = ∂L/∂q'_i` (plain derivatives; used to turn initial
    /// velocities into momenta and for plots).
    pub(super) fn momenta(&mut self, at: At, l: &Expr) -> Result<Vec<Expr>, SceneError> {
        let key = CacheKey::symbolic(Step::Momenta, &self.coords, vec![l.clone()]);
        if let Some(Value::Exprs(v)) = self.lookup(at, &key, Step::Momenta, &format!("of {}", short(l))) {
            return Ok(v);
        }
        let ps: Vec<Expr> = self.coords.clone().iter().map(|q| self.diff.diff(l, &q.prime())).collect();
        match self.record(at, Step::Momenta, format!("of {}", short(l)), key, Ok(Value::Exprs(ps)))? {
            Value::Exprs(v) => Ok(v),
            _ => Ok(vec![]),
        }
    }
}

pub(super) fn deriv_step(kind: DerivKind) -> Step {
    match kind {
        DerivKind::El => Step::EulerLagrange,
        DerivKind::Legendre => Step::Legendre,
        DerivKind::Hamilton => Step::Hamilton,
        DerivKind::Conserved => Step::Conserved,
        DerivKind::Pb => Step::Bracket,
        DerivKind::Energy => Step::Energy,
        DerivKind::Accelerations => Step::Accelerations,
    }
}

/// Numbers in messages and reports ([`crate::print::fmt_num`]), where the scene's statements
/// import it from.
pub use crate::print::fmt_num;

impl Session {
    /// Lazy definitions and simulations nothing asked for, and the standard derivations
    /// nothing needed, go into the plan as skipped.
    pub(super) fn finish_plan(&mut self) {
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
                        r.spec.method.as_ref().map_or(crate::simulate::DEFAULT_METHOD.name(), |m| m.text.as_str())
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
        super::engine::plan::explain(&self.plan)
    }
}
