//! `flow θ = 1, θ' = 0 for t in 0..T [tol = …] [points N] [max_steps = N] [time_limit = S] [to FILE]`: the
//! flow's Jacobian `Φ(T) = ∂x(T)/∂x(0)` in `x = (q, p)` and its structural checks (notes
//! §4.6.1), the same computation and the same printed lines as `lagrangian flow`
//! ([`crate::chaos::flow_with`], [`crate::report::flow`]); this file holds the statement's type
//! and reader and resolves it.
//!
//! The flow is the scene's system with its forces and Rayleigh dissipation
//! ([`crate::compile::Variational::of_system`]): a damped oscillator's `det Φ` is `e^{−γT}`,
//! not the `1` of its undamped `H`. Constraints are refused: their multipliers are not
//! functions of the state. With a file, `|det Φ − 1|` and the symplectic defect are drawn
//! against time on a logarithmic axis ([`crate::report::flow_figure`]), or written as a table.

use std::collections::HashMap;

use crate::compile::Variational;
use crate::expr::{Expr, Symbol};
use crate::integrate::FailureReason;
use crate::mechanics::System;
use crate::print::fmt_num;
use crate::print::Format;
use crate::scene::engine::plan::{PlanEntry, Status, Step};
use crate::scene::state::{At, Session};
use crate::scene::statements::chaos::variational_run_refusals;
use crate::scene::statements::{Output, Stmt};
use crate::scene::syntax::ast::{SimSpec, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `flow θ = 1, θ' = 0 for t in 0..T [tol = …] [points N] [to FILE]`.
#[derive(Clone, Debug)]
#[doc(hidden)]
pub struct FlowSpec {
    /// The starts, time span and options, read like a `simulate` statement's.
    pub sim: SimSpec,
    /// `to FILE`: the checks against time, drawn or as a table.
    pub path: Option<Src>,
    /// The word `flow`.
    pub word: Span,
}

impl FlowSpec {
    /// `flow …`: a simulate-like start and an optional output file.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<FlowSpec, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let path = inner.iter().find(|q| q.as_rule() == Rule::path).map(|q| r.path(q.clone()));
        let word = (span.0, span.0 + "flow".len());
        Ok(FlowSpec { sim: r.simulate(inner, span)?, path, word })
    }
}

/// The default tolerance: `Φ` is compared with exact identities (`det Φ = 1`), so it is
/// integrated near machine precision, as `lagrangian flow` does.
const DEFAULT_TOL: f64 = 1e-14;

/// The default number of kept steps for the plot and the table.
const DEFAULT_POINTS: usize = 400;

/// The largest `points`.
const MAX_POINTS: usize = 1_000_000;

impl Session {
    /// `flow …`: prints the end state, `Φ(T)`, `det Φ − 1` and the symplectic defect; with a
    /// file, the checks against time.
    pub(in crate::scene) fn flow(&mut self, at: At, spec: &FlowSpec) -> Result<(), SceneError> {
        let sim = &spec.sim;
        let span = (spec.word.0, sim.span_span.1);
        if self.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(spec.word)
                .hint("declare them first, for example `coordinates θ`"));
        }
        self.flow_refusals(spec)?;
        let t0 = self.bound(at, &sim.t0)?;
        let t1 = self.bound(at, &sim.t1)?;
        if t0 != 0.0 || !(t1 > 0.0 && t1.is_finite()) {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("the flow is measured from t = 0 to a later time; found {}..{}", fmt_num(t0), fmt_num(t1)),
            )
            .at(sim.span_span)
            .hint("write `for t in 0..10`"));
        }
        let tol = self.flow_tol(at, spec)?;
        let points = self.flow_points(at, spec)?;
        let budget = self.chaos_budget(at, &spec.sim)?;
        let (path, ext) = match &spec.path {
            Some(p) => {
                let (path, pspan, ext) = self.out_file(
                    at.span,
                    Some(p),
                    "flow",
                    "flow",
                    &["svg", "png", "csv"],
                    "the flow's checks are drawn as `.svg` or `.png`, or written as a table to `.csv`",
                )?;
                (Some((path, pspan)), ext)
            }
            None => (None, String::new()),
        };
        let system = self.flow_system(at, span)?;
        let state: Vec<String> = system.coordinates().iter().chain(system.momenta()).map(Symbol::to_string).collect();
        let x0 = self.flow_start(at, spec, &system)?;
        let n = state.len();
        let var = Variational::of_system(&system, n, false).map_err(|e| {
            SceneError::new(ErrorKind::Derivation, format!("cannot compile the variational equations: {e}")).at(span)
        })?;
        let flow = crate::chaos::flow_with(&var, &x0, t1, tol, points, &budget).map_err(|e| {
            let err = SceneError::new(ErrorKind::Numeric, format!("the flow's integration failed: {e}")).at(span);
            match e.reason {
                FailureReason::StepLimit { .. } => err.hint(format!(
                    "to integrate longer, raise the step budget: `max_steps = N` (now {})",
                    budget.max_steps
                )),
                FailureReason::TimeLimit { seconds } => err.hint(format!(
                    "to integrate longer, raise the time budget: `time_limit = SECONDS` (now {})",
                    fmt_num(seconds)
                )),
                _ => err,
            }
        })?;
        self.plan.push(PlanEntry {
            step: Step::Integrate,
            what: format!("flow: Φ over 0..{} with taylor tol = {tol:e} ({} steps)", fmt_num(t1), flow.steps),
            line: Some(at.line),
            status: Status::Built,
        });
        for line in crate::report::flow(&state, t1, &flow) {
            self.output.push(crate::report::render_line(&line, Format::Plain));
        }
        if let Some((path, pspan)) = path {
            let tmp = self.staging.stage(&path).map_err(|e| e.at(pspan))?;
            let written = if ext == "csv" {
                std::fs::write(&tmp, crate::report::flow_table(&flow)).map_err(|e| e.to_string())
            } else {
                crate::plot::draw(&crate::report::flow_figure(&flow), &tmp).map_err(|e| e.to_string())
            };
            written.map_err(|e| {
                SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", path.display())).at(pspan)
            })?;
            self.wrote(&path);
        }
        Ok(())
    }

    /// What a `flow` statement does not take, each refused with what it takes instead, and
    /// constraints, which the variational equations cannot carry.
    fn flow_refusals(&self, spec: &FlowSpec) -> Result<(), SceneError> {
        let sim = &spec.sim;
        let hint = "`flow` integrates the variational equations with the Taylor method; it takes `tol = …`, `points N`, `max_steps = N`, `time_limit = S` and `to FILE`";
        let refuse = variational_run_refusals(sim, "flow", hint, "`every` (`points N` sets how many steps are kept)")?;
        refuse("`drift`", sim.drift.as_ref().map(|e| e.span))?;
        refuse("`as NAME`", sim.name.as_ref().map(|e| e.span))?;
        if self.dynamics.constrained() || self.dynamics.velocity_constrained() {
            return Err(SceneError::new(
                ErrorKind::Derivation,
                "`flow` needs the equations of motion as x' = f(x, t) in x = (q, p), and the constraints' multipliers are not functions of the state",
            )
            .at(spec.word)
            .hint("write the system in coordinates that satisfy the constraints (a pendulum in its angle), or integrate it with `simulate`"));
        }
        Ok(())
    }

    /// `tol = …`, checked; [`DEFAULT_TOL`] without it.
    fn flow_tol(&mut self, at: At, spec: &FlowSpec) -> Result<f64, SceneError> {
        let Some(src) = &spec.sim.tol else { return Ok(DEFAULT_TOL) };
        let e = self.resolved(at, src)?;
        let x = self.number(&e, src.span)?;
        if !(x > 0.0 && x.is_finite()) {
            return Err(SceneError::new(ErrorKind::BadNumber, format!("the tolerance must be positive, found {x}"))
                .at(src.span));
        }
        if x < crate::integrate::MIN_TOL {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!(
                    "tol = {x:e} is below what f64 can meet; the smallest usable tol is {:.2e}",
                    crate::integrate::MIN_TOL
                ),
            )
            .at(src.span)
            .label("too small"));
        }
        Ok(x)
    }

    /// `points N`, checked: a whole number from 2 to [`MAX_POINTS`].
    fn flow_points(&mut self, at: At, spec: &FlowSpec) -> Result<usize, SceneError> {
        let Some(src) = &spec.sim.points else { return Ok(DEFAULT_POINTS) };
        let e = self.resolved(at, src)?;
        let x = self.number(&e, src.span)?;
        if !(x >= 2.0 && x <= MAX_POINTS as f64 && x.fract() == 0.0) {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("`points` is a whole number from 2 to {MAX_POINTS}; found {}", fmt_num(x)),
            )
            .at(src.span));
        }
        Ok(x as usize)
    }

    /// The scene's system as the library's [`System`]: `H` if defined, else `L`, with the
    /// declared forces and Rayleigh function and every parameter's value.
    fn flow_system(&mut self, at: At, span: Span) -> Result<System, SceneError> {
        let coords = self.coords.clone();
        let mechanics =
            |e: crate::mechanics::MechanicsError| SceneError::new(ErrorKind::Derivation, e.to_string()).at(span);
        let from_h = self.def_names.contains_key("H") || !self.def_names.contains_key("L");
        let mut system = if from_h {
            let h = self.hamiltonian(at)?;
            System::from_hamiltonian_expr(h, &coords)
        } else {
            let l = self.lagrangian(at)?;
            if crate::simulate::is_first_order(&l, &coords) {
                return Err(SceneError::new(
                    ErrorKind::Derivation,
                    "`flow` needs Hamilton's equations in (q, p), but this L is first order in its velocities (a phase-space Lagrangian), so it has no momenta p_q",
                )
                .at(span)
                .hint("define the same system as `H = …` with its canonical pairs as coordinates and momenta `p_q`"));
            }
            System::from_lagrangian_expr(l, &coords)
        }
        .map_err(mechanics)?;
        if !self.dynamics.is_empty() {
            let (forces, rayleigh, _) = self.resolved_dynamics(at)?;
            for (q, f) in coords.iter().zip(&forces) {
                if !f.is_zero() {
                    system = system.with_force_expr(q.name(), f.clone()).map_err(mechanics)?;
                }
            }
            if let Some(r) = rayleigh {
                system = system.with_rayleigh_expr(r).map_err(mechanics)?;
            }
        }
        let exprs: Vec<&Expr> = system.lagrangian().into_iter().chain(system.hamiltonian_expr()).collect();
        if let Some(f) = exprs.iter().flat_map(|e| e.applied_functions()).next() {
            return Err(SceneError::new(
                ErrorKind::MissingValue,
                format!("the declared function `{f}` has no numeric definition"),
            )
            .at(span));
        }
        let mut values = Vec::new();
        for p in system.parameters() {
            if p.is_time() {
                continue;
            }
            match self.params.get(p.name()).and_then(|x| x.value) {
                Some(v) => values.push((p.name().to_string(), v)),
                None => {
                    return Err(SceneError::new(
                        ErrorKind::MissingValue,
                        format!("parameter `{}` has no value", p.name()),
                    )
                    .at(span)
                    .hint(format!("declare `{0}` with a value first: `parameters {0} = …`", p.name())))
                }
            }
        }
        let refs: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        system.with_params(&refs).map_err(mechanics)
    }

    /// The canonical start `(q, p)`: every coordinate, and either every momentum or every
    /// velocity (turned into momenta through `p = ∂L/∂q'`), each once.
    fn flow_start(&mut self, at: At, spec: &FlowSpec, system: &System) -> Result<Vec<f64>, SceneError> {
        let mut given: HashMap<String, f64> = HashMap::new();
        for (sym, val) in &spec.sim.inits {
            let key = self.state_key(sym)?;
            let v = self.resolved(at, val)?;
            let x = self.number(&v, val.span)?;
            if given.insert(key.clone(), x).is_some() {
                return Err(SceneError::new(ErrorKind::Syntax, format!("`{key}` is given twice")).at(sym.span));
            }
        }
        let coords = self.coords.clone();
        let velocities = coords.iter().any(|q| given.contains_key(&format!("{}'", q.name())));
        let momenta_given = coords.iter().any(|q| given.contains_key(&format!("p_{}", q.name())));
        if velocities && momenta_given {
            return Err(SceneError::new(ErrorKind::Syntax, "give either velocities or momenta, not both").at(spec.word));
        }
        for q in &coords {
            let need = if velocities { format!("{}'", q.name()) } else { format!("p_{}", q.name()) };
            for need in [q.name().to_string(), need] {
                if !given.contains_key(&need) {
                    return Err(SceneError::new(ErrorKind::MissingValue, format!("no starting value for `{need}`"))
                        .at(spec.word)
                        .hint(format!(
                            "add `{need} = …` (give every coordinate and every velocity, or every momentum)"
                        )));
                }
            }
        }
        let n = coords.len();
        let mut x: Vec<f64> = coords.iter().map(|q| given[q.name()]).collect();
        if !velocities {
            x.extend(coords.iter().map(|q| given[&format!("p_{}", q.name())]));
            return Ok(x);
        }
        if !self.def_names.contains_key("L") {
            return Err(SceneError::new(
                ErrorKind::Undeclared,
                "velocities are turned into momenta through `L`, and no `L` is defined",
            )
            .at(spec.word)
            .hint("give the momenta `p_q` instead, or define `L`"));
        }
        let l = self.lagrangian(at)?;
        let ps = self.momenta(at, &l)?;
        let mut env: HashMap<String, f64> =
            system.param_values().iter().map(|(k, v)| (k.name().to_string(), *v)).collect();
        env.extend(given.iter().map(|(k, v)| (k.clone(), *v)));
        env.insert("t".into(), 0.0);
        for p in ps.iter().take(n) {
            x.push(crate::eval::eval(p, &env).map_err(|e| self.value_error(e, spec.word))?);
        }
        Ok(x)
    }
}

impl Stmt for FlowSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.flow(at, self)
    }

    fn output(&self) -> Option<Output<'_>> {
        self.path.as_ref().map(|path| Output {
            path: Some(path),
            default: "flow",
            what: "flow",
            formats: &["svg", "png", "csv"],
            hint: "the flow's checks are drawn as `.svg` or `.png`, or written as a table to `.csv`",
        })
    }
}
