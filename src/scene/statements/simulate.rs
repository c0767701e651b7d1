//! `simulate`: the formulation a method needs, the initial state, events, compilation and
//! integration of one run, and the values of expressions along a run.

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

use super::drift::EnergyPlan;
use crate::cache::{CacheKey, Value};
use crate::expr::{Expr, Symbol};
use crate::print::fmt_num;
use crate::print::{render, Format};
use crate::scene::engine::backend::{CompileRequest, Compiled, Formulation, RunRequest, Trajectory};
use crate::scene::engine::plan::{PlanEntry, Status, Step};
use crate::scene::engine::progress::Progress;
use crate::scene::state::{backend_error, short};
use crate::scene::state::{At, Dynamics, Layout, Mode, RunEntry, RunResult, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::{DerivKind, EventSpec, SimSpec, Src};
use crate::scene::syntax::error::{did_you_mean, ErrorKind, SceneError, Span};
use crate::simulate::{
    self as sim, route, EventSpec as RunEvent, Family, MethodId, Refusal, RefusalReason, Route, RunOptions, Sampling,
    Shape, SimulateError,
};

impl Session {
    // ----- simulation ----------------------------------------------------------------------

    pub(in crate::scene) fn simulate(&mut self, at: At, spec: &SimSpec) -> Result<(), SceneError> {
        if spec.ensemble.is_some() {
            return self.simulate_ensemble(at, spec);
        }
        // Validate the parts that need no derivation now, so a typo is reported at once.
        self.check_method(spec)?;
        let name = match &spec.name {
            Some(n) => n.text.clone(),
            None => format!("run{}", self.runs.len() + 1),
        };
        let id = self.runs.len();
        let dynamics = self.dynamics.clone();
        self.runs.push(RunEntry { name: name.clone(), spec: spec.clone(), line: at.line, result: None, dynamics });
        let previous = self.run_names.insert(name.clone(), id);
        if self.opts.mode == Mode::Repl {
            if let Err(e) = self.demand_run(at, id) {
                // A run that failed is not a run: its name (or the run it replaced) is as before.
                self.runs.pop();
                match previous {
                    Some(old) => self.run_names.insert(name, old),
                    None => self.run_names.remove(&name),
                };
                return Err(e);
            }
            let summary = self.run_summary(id);
            self.output.push(summary);
        }
        Ok(())
    }

    pub(in crate::scene) fn check_method(&self, spec: &SimSpec) -> Result<MethodId, SceneError> {
        if spec.time_var.text != "t" {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!("the time variable is `t`, not `{}`", spec.time_var.text),
            )
            .at(spec.time_var.span)
            .hint("write `for t in 0..10`"));
        }
        match &spec.method {
            None => Ok(sim::DEFAULT_METHOD),
            Some(m) => MethodId::from_name(&m.text).ok_or_else(|| {
                let e = SimulateError::unknown_method(&m.text);
                let err = SceneError::new(ErrorKind::UnknownMethod, e.to_string()).at(m.span).label("not a method");
                match e.hint() {
                    Some(h) => err.hint(h),
                    None => err,
                }
            }),
        }
    }

    pub(in crate::scene) fn run_summary(&self, id: usize) -> String {
        let run = &self.runs[id];
        let Some(r) = &run.result else { return String::new() };
        let tr = &r.traj;
        let mut s = format!(
            "{}: {} from t = {} to t = {} in {} steps",
            run.name,
            r.method.name(),
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
        let drift = tr
            .aux
            .iter()
            .filter(|(n, _)| n.starts_with("residual"))
            .flat_map(|(_, v)| v.iter())
            .fold(None, |m: Option<f64>, x| Some(m.unwrap_or(0.0).max(x.abs())));
        if let Some(d) = drift {
            s.push_str(&format!("; constraint drift max |f| = {d:.1e}"));
        }
        s.push_str(&super::drift::summary_clause(&tr.energy));
        s
    }

    pub(in crate::scene) fn demand_run(&mut self, at: At, id: usize) -> Result<RunResult, SceneError> {
        if let Some(r) = &self.runs[id].result {
            return Ok(r.clone());
        }
        let spec = self.runs[id].spec.clone();
        // The run's work is planned at its own statement's line.
        let at = At { line: self.runs[id].line, ..at };
        let dynamics = self.runs[id].dynamics.clone();
        let r = self.run_simulation(at, &spec, &self.runs[id].name.clone(), &dynamics);
        let r = r?;
        self.runs[id].result = Some(r.clone());
        Ok(r)
    }

    pub(in crate::scene) fn run_simulation(
        &mut self,
        at: At,
        spec: &SimSpec,
        name: &str,
        dynamics: &Dynamics,
    ) -> Result<RunResult, SceneError> {
        let (compiled, run, template, energy) = self.prepare_run(at, spec, name, dynamics)?;
        let stmt_span = run_span(spec);
        let at = At { span: stmt_span, ..at };
        let mut traj = self.integrate(at, &compiled, &run, name, stmt_span)?;
        self.settle_energy(name, &energy, &mut traj, stmt_span)?;
        // The `--explain` plan carries the ledger too (scenes print no run summary).
        if let Some(entry) = self.plan.iter_mut().rev().find(|e| e.step == Step::Integrate) {
            let clause = super::drift::summary_clause(&traj.energy);
            if let Some(open) = entry.what.rfind(')') {
                entry.what.insert_str(open, &clause.replacen(';', ",", 1));
            }
        }
        Ok(RunResult { traj: Arc::new(traj), ..template })
    }

    /// Everything of a run but its integration: the compiled system, the request (with the
    /// initial state and the energy check), the result without its trajectory, and which
    /// energy is checked (or why none is). Its errors point at the `simulate` statement
    /// ([`run_span`]), whoever demanded the run.
    pub(in crate::scene) fn prepare_run(
        &mut self,
        at: At,
        spec: &SimSpec,
        name: &str,
        dynamics: &Dynamics,
    ) -> Result<(Compiled, RunRequest, RunResult, EnergyPlan), SceneError> {
        let stmt_span = run_span(spec);
        let at = At { span: stmt_span, ..at };
        let method = self.check_method(spec)?;
        if self.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(stmt_span)
                .hint("declare them first, for example `coordinates θ`"));
        }
        let (mut options, dt) = self.run_options(at, spec, method)?;
        let (t0, t1) = (options.t0, options.t1);
        // The formulation this method needs: this decides what is derived.
        let (formulation, layout, l_expr, h_expr) = self.formulation(at, spec, method, dynamics)?;
        let coords = self.coords.clone();
        let first_order = matches!(formulation, Formulation::FirstOrder(_));
        let y0 = self.initial_state(at, spec, layout, first_order, t0)?;
        if let Formulation::Extended(ext) = &formulation {
            if dynamics.constrained() || dynamics.velocity_constrained() {
                let values: Vec<(String, f64)> = self.param_values().into_iter().collect();
                self.check_initial_constraints(dynamics, ext, &y0, t0, &values, stmt_span)?;
            }
        }

        let (event_exprs, events) = self.run_events(at, spec, layout, l_expr.as_ref(), h_expr.as_ref(), first_order)?;
        let params = self.run_params(stmt_span, &formulation, &event_exprs)?;
        let compiled = self.compile_run(at, method, &coords, &formulation, &params, &event_exprs)?;
        let every = self.thinning(at, spec, dt, t0, t1, name)?;
        let names = super::drift::input_names(&coords, layout);
        let check = self.energy_check(at, spec, &formulation, &names, &params)?;
        let energy = check.as_ref().ok().map(|(_, c)| c.clone());
        options.events = events;
        options.sampling = every.map_or(Sampling::Auto, Sampling::Every);
        // Again with the sampling: what it keeps must fit (`every 1` over 10⁸ steps does not).
        options.check().map_err(|e| run_option_error(e, spec, stmt_span))?;
        options.energy = energy;
        let run = RunRequest { y0, options };
        let template = RunResult {
            method,
            layout,
            coords,
            params: params.into_iter().collect(),
            traj: Arc::new(Trajectory::default()),
            lagrangian: l_expr,
            hamiltonian: h_expr,
        };
        Ok((compiled, run, template, check.map(|(symbol, _)| symbol)))
    }

    /// `max_steps = N`, checked: a whole number of steps, at least 1.
    pub(in crate::scene) fn step_budget(&mut self, at: At, spec: &SimSpec) -> Result<Option<usize>, SceneError> {
        let Some(src) = &spec.max_steps else { return Ok(None) };
        let e = self.resolved(at, src)?;
        let x = self.number(&e, src.span)?;
        if !(x >= 1.0 && x.fract() == 0.0 && x < usize::MAX as f64) {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("`max_steps` is a whole number of steps, at least 1; found {}", fmt_num(x)),
            )
            .at(src.span));
        }
        Ok(Some(x as usize))
    }

    /// The library's options of a run from its time span, `dt`, `tol` and `steps` (checked
    /// by the library), and the fixed step if one was asked.
    fn run_options(
        &mut self,
        at: At,
        spec: &SimSpec,
        method: MethodId,
    ) -> Result<(RunOptions, Option<f64>), SceneError> {
        let stmt_span = at.span;
        let t0 = self.bound(at, &spec.t0)?;
        let t1 = self.bound(at, &spec.t1)?;
        if t1 == t0 {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("the time span is empty: it starts and ends at {}", fmt_num(t0)),
            )
            .at(spec.span_span)
            .label("end must be after start")
            .hint(format!("write `for t in {}..{}`", fmt_num(t0), fmt_num(t0 + 10.0))));
        }
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
            let e = this.resolved(at, src)?;
            let x = this.number(&e, src.span)?;
            if !(x > 0.0 && x.is_finite()) {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!("{what} must be positive and finite, found {x}"),
                )
                .at(src.span));
            }
            Ok(Some(x))
        };
        let mut dt = positive(&spec.dt, self, "the step `dt`")?;
        let tol = positive(&spec.tol, self, "the tolerance `tol`")?;
        let steps = positive(&spec.steps, self, "`steps`")?;
        if let Some(n) = steps {
            if n.fract() != 0.0 {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!("`steps` must be a whole number, found {n}"),
                )
                .at(spec.steps.as_ref().map_or(stmt_span, |s| s.span))
                .hint(format!("write `steps = {}`", n.round().max(1.0))));
            }
            dt = Some((t1 - t0) / n);
        }
        let mut options = RunOptions::new(method, t0, t1);
        options.dt = dt;
        options.rtol = tol;
        options.max_steps = self.step_budget(at, spec)?;
        options.check().map_err(|e| run_option_error(e, spec, stmt_span))?;
        Ok((options, dt))
    }

    /// The formulation `method` integrates (the library's route for what the scene
    /// defines), the state's layout and the `L` and `H` it was built from.
    fn formulation(
        &mut self,
        at: At,
        spec: &SimSpec,
        method: MethodId,
        dynamics: &Dynamics,
    ) -> Result<(Formulation, Layout, Option<Expr>, Option<Expr>), SceneError> {
        let stmt_span = at.span;
        let has_l = self.def_names.contains_key("L");
        let has_h = self.def_names.contains_key("H");
        if spec.stabilize.is_some() && dynamics.is_empty() {
            let s = spec.stabilize.as_ref().map_or(stmt_span, |s| s.span);
            return Err(SceneError::new(ErrorKind::Syntax, "`stabilize` applies to constrained runs only")
                .at(s)
                .hint("declare a constraint first (`constraint x^2 + y^2 = l^2`), or drop `stabilize`"));
        }
        if method.family() == Family::Variational && dynamics.is_empty() {
            super::variational::check_variational_run(method.name(), spec, has_l, stmt_span)?;
        }
        // Whether L is first order matters unless a splitting method runs the user's own H.
        let l_if_needed =
            if has_l && !(method.family() == Family::Splitting && has_h) { Some(self.lagrangian(at)?) } else { None };
        // A phase-space Lagrangian (first order in every velocity) has its own route; a
        // second-order L with a coordinate lacking its velocity is refused with the reduction.
        if let Some(l) = l_if_needed.as_ref().filter(|l| !sim::is_first_order(l, &self.coords)) {
            self.refuse_velocity_free(l, stmt_span)?;
        }
        let shape = Shape {
            lagrangian: has_l,
            hamiltonian: has_h,
            first_order: l_if_needed.as_ref().is_some_and(|l| sim::is_first_order(l, &self.coords)),
            forces: dynamics.forced(),
            constraints: dynamics.constrained(),
            velocity_constraints: dynamics.velocity_constrained(),
        };
        let route = route(method, &shape).map_err(|r| refusal_error(r, spec, stmt_span))?;
        let (formulation, l_expr, h_expr) = match route {
            Route::Extended => {
                let l = self.lagrangian(at)?;
                let ext = self.extended(at, l.clone(), dynamics, spec)?;
                (Formulation::Extended(Box::new(ext)), Some(l), None)
            }
            Route::Variational => {
                let l = self.lagrangian(at)?;
                let h = self.hamiltonian(at)?;
                (Formulation::Variational(l.clone()), Some(l), Some(h))
            }
            Route::Separable => {
                let h = self.hamiltonian(at)?;
                let (t, v) = self.split(at, &h, method)?;
                (Formulation::Separable { t, v }, None, Some(h))
            }
            Route::FirstOrder => {
                let l = self.lagrangian(at)?;
                (Formulation::FirstOrder(l.clone()), Some(l), None)
            }
            Route::Lagrangian => {
                let l = self.lagrangian(at)?;
                (Formulation::Lagrangian(l.clone()), Some(l), None)
            }
            Route::Hamiltonian => {
                let h = self.hamiltonian(at)?;
                (Formulation::Hamiltonian(h.clone()), None, Some(h))
            }
        };
        let layout = if route.has_velocities() { Layout::Velocities } else { Layout::Momenta };
        Ok((formulation, layout, l_expr, h_expr))
    }

    /// A coordinate without its velocity in `L` (Remark 3.1) makes the mass matrix singular:
    /// refused before any integration, with the reduced system the library derives by solving
    /// the algebraic equation `∂L/∂y = 0` (which the scene can simulate instead), or with why
    /// that equation is not solved.
    fn refuse_velocity_free(&self, l: &Expr, span: Span) -> Result<(), SceneError> {
        let system = match crate::mechanics::System::from_lagrangian_expr(l.clone(), &self.coords) {
            Ok(s) => s,
            Err(_) => return Ok(()),
        };
        let lacking = system.velocity_free_coordinates();
        if lacking.is_empty() {
            return Ok(());
        }
        let names = lacking.iter().map(|q| format!("`{q}`")).collect::<Vec<_>>().join(", ");
        let head = format!("{names} has no velocity in L (Remark 3.1): its Euler–Lagrange equation ∂L/∂q = 0 is algebraic and the mass matrix is singular");
        match system.eliminate_velocity_free() {
            Ok(red) => {
                let sols = red.eliminated.iter().map(|(y, e)| format!("{y} = {e}")).collect::<Vec<_>>().join(", ");
                let coords = red.coords.iter().map(|q| q.to_string()).collect::<Vec<_>>().join(", ");
                Err(SceneError::new(ErrorKind::Derivation, format!("{head}; solved, it gives {sols}")).at(span).hint(
                    format!("simulate the reduced system instead: `coordinates {coords}` and `L = {}`", red.lagrangian),
                ))
            }
            Err(e) => Err(SceneError::new(
                ErrorKind::Derivation,
                format!("{head}; {}", e.to_string().trim_start_matches("error: ")),
            )
            .at(span)),
        }
    }

    /// The values the `simulate` statement gives (coordinates, velocities or momenta), each
    /// with its span, checked to be part of the state and given once.
    fn given_values(&mut self, at: At, spec: &SimSpec) -> Result<HashMap<String, (f64, Span)>, SceneError> {
        let coords = self.coords.clone();
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
            let v = self.resolved(at, val)?;
            let x = self.number(&v, val.span)?;
            if given.contains_key(&s.to_string()) {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    format!("`{}` is given twice in this `simulate` statement", sym.text),
                )
                .at(sym.span)
                .label("second value")
                .hint("keep one of them: the values would otherwise silently replace each other"));
            }
            given.insert(s.to_string(), (x, sym.span));
        }
        Ok(given)
    }

    /// The initial state in `layout`: coordinates, then velocities or momenta (velocities
    /// turned into momenta through `p = ∂L/∂q'` when the method integrates `H`).
    fn initial_state(
        &mut self,
        at: At,
        spec: &SimSpec,
        layout: Layout,
        first_order: bool,
        t0: f64,
    ) -> Result<Vec<f64>, SceneError> {
        let stmt_span = at.span;
        let coords = self.coords.clone();
        let n = coords.len();
        let given = self.given_values(at, spec)?;
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
        if first_order {
            super::first_order::check_first_order_inits(&coords, &given)?;
        }
        match layout {
            Layout::Velocities if first_order => {}
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
                    let l = self.lagrangian(at).map_err(|e| {
                        e.hint(
                            "this method integrates `H`: give the momenta `p_q`, or define `L` to convert velocities",
                        )
                    })?;
                    let ps = self.momenta(at, &l)?;
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
        Ok(y0)
    }

    /// The events of a run, in the state's variables, and how each is located.
    fn run_events(
        &mut self,
        at: At,
        spec: &SimSpec,
        layout: Layout,
        l_expr: Option<&Expr>,
        h_expr: Option<&Expr>,
        first_order: bool,
    ) -> Result<(Vec<Expr>, Vec<RunEvent>), SceneError> {
        let mut event_exprs = Vec::new();
        let mut events = Vec::new();
        for (index, ev) in spec.events.iter().enumerate() {
            let e = self.event_expr(at, ev, layout, l_expr, h_expr)?;
            if first_order {
                super::first_order::check_first_order_event(&e, ev.span)?;
            }
            event_exprs.push(e);
            let crossing = match ev.rising {
                Some(true) => crate::integrate::Crossing::Rising,
                Some(false) => crate::integrate::Crossing::Falling,
                None => crate::integrate::Crossing::Either,
            };
            events.push(RunEvent { index, crossing, terminal: ev.terminal });
        }
        Ok((event_exprs, events))
    }

    /// The values of the parameters the equations and events use: each needs one, and a
    /// declared function with no numeric definition cannot be integrated.
    fn run_params(
        &self,
        stmt_span: Span,
        formulation: &Formulation,
        event_exprs: &[Expr],
    ) -> Result<Vec<(String, f64)>, SceneError> {
        let mut needed: BTreeSet<String> = BTreeSet::new();
        let exprs = formulation.exprs();
        for e in exprs.iter().chain(event_exprs.iter()) {
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
        Ok(params)
    }

    /// The compiled run, cached by symbolic content and parameter values.
    fn compile_run(
        &mut self,
        at: At,
        method: MethodId,
        coords: &[Symbol],
        formulation: &Formulation,
        params: &[(String, f64)],
        event_exprs: &[Expr],
    ) -> Result<Compiled, SceneError> {
        let stmt_span = at.span;
        let req = CompileRequest {
            coords: coords.to_vec(),
            formulation: formulation.clone(),
            params: params.to_vec(),
            form: method.form(),
            events: event_exprs.to_vec(),
        };
        let mut inputs: Vec<Expr> = formulation.exprs();
        inputs.extend(event_exprs.iter().cloned());
        let key = CacheKey {
            step: Step::Compile,
            coords: coords.to_vec(),
            inputs,
            numbers: params.iter().map(|(_, v)| v.to_bits()).collect(),
            extra: format!(
                "{:?}{:?}{}{}",
                method.family(),
                method.form(),
                match &formulation {
                    // Which input is which, and the stabilisation, are part of the content.
                    Formulation::Extended(x) => format!(
                        "extended:{}:{}:{}:{:?}",
                        x.forces.len(),
                        x.rayleigh.is_some(),
                        x.constraints.len(),
                        x.stabilization
                    ),
                    // The rule is part of the content (the methods share a family).
                    Formulation::Variational(_) => format!("variational:{}", method.name()),
                    _ => String::new(),
                },
                params.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(",")
            ),
        };
        let what = format!("{} for {}", formulation.describe(), method.name());
        let compiled = match self.lookup(at, &key, Step::Compile, &what) {
            Some(Value::Compiled(c)) => c,
            _ => {
                let built = self.backend.compile(&req).map(Value::Compiled).map_err(|e| backend_error(e, stmt_span));
                match self.record(at, Step::Compile, what, key, built)? {
                    Value::Compiled(c) => c,
                    _ => return Err(SceneError::new(ErrorKind::Numeric, "compilation gave no code").at(stmt_span)),
                }
            }
        };
        Ok(compiled)
    }

    /// Which steps a run keeps: `every N`, `points N`, or by default at most
    /// [`crate::scene::engine::backend::MAX_POINTS`] states of a fixed-step run, with a printed note when that
    /// thins it (no data is dropped without a word).
    fn thinning(
        &mut self,
        at: At,
        spec: &SimSpec,
        dt: Option<f64>,
        t0: f64,
        t1: f64,
        name: &str,
    ) -> Result<Option<usize>, SceneError> {
        let count = |this: &mut Session, src: &Src, what: &str| -> Result<usize, SceneError> {
            let e = this.resolved(at, src)?;
            let x = this.number(&e, src.span)?;
            if x < 1.0 || x.fract() != 0.0 || x > 1e12 {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!("{what} must be a whole number ≥ 1, found {x}"),
                )
                .at(src.span)
                .hint(format!("for example `{what} 10`")));
            }
            Ok(x as usize)
        };
        if let (Some(a), Some(_)) = (&spec.every, &spec.points) {
            return Err(SceneError::new(ErrorKind::Syntax, "give `every` or `points`, not both").at(a.span));
        }
        if let Some(src) = &spec.every {
            return count(self, src, "every").map(Some);
        }
        if let Some(src) = &spec.points {
            let n = count(self, src, "points")?;
            let Some(h) = dt else {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    "`points` needs a fixed step; an adaptive method's step count is not known in advance",
                )
                .at(src.span)
                .hint("use `every N` to keep every N-th step"));
            };
            let steps = ((t1 - t0) / h).ceil() as usize;
            return Ok(Some(steps.div_ceil(n).max(1)));
        }
        if dt.is_none() {
            // An adaptive run's step count is unknown: the backend keeps at most MAX_POINTS
            // states, evenly spaced in steps, and says so when it thins.
            return Ok(None);
        }
        let every = dt.map_or(1, |h| sim::default_every(h, t0, t1));
        if every > 1 {
            let steps = dt.map_or(0, |h| ((t1 - t0) / h).ceil() as usize);
            self.output.push(format!(
                "note: {name} keeps 1 state in {every} of its {steps} steps ({} states); add `every 1` to keep all, or `points N`",
                steps.div_ceil(every) + 1
            ));
        }
        Ok(Some(every))
    }

    pub(in crate::scene) fn integrate(
        &mut self,
        at: At,
        compiled: &Compiled,
        run: &RunRequest,
        name: &str,
        span: Span,
    ) -> Result<Trajectory, SceneError> {
        let mut bar = Progress::new(name, self.opts.progress);
        let mut progress = |frac: f64| bar.update(frac);
        let result = self.backend.integrate(compiled, run, &mut progress);
        if result.is_ok() {
            bar.finish();
        } else {
            bar.abandon();
        }
        let traj = result.map_err(|e| backend_error(e, span))?;
        self.plan.push(PlanEntry {
            step: Step::Integrate,
            what: format!("{name} with {} ({} steps)", run.options.method.name(), traj.steps),
            line: Some(at.line),
            status: Status::Built,
        });
        Ok(traj)
    }

    pub(in crate::scene) fn value_error(&self, e: crate::eval::EvalError, span: Span) -> SceneError {
        match e {
            crate::eval::EvalError::Unbound(name) => {
                SceneError::new(ErrorKind::MissingValue, format!("`{name}` has no value"))
                    .at(span)
                    .hint(format!("declare `{name}` with a value before `simulate`: `parameters {name} = …`"))
            }
            other => SceneError::new(ErrorKind::BadNumber, other.to_string()).at(span),
        }
    }

    pub(in crate::scene) fn param_values(&self) -> HashMap<String, f64> {
        self.params.iter().filter_map(|(n, p)| p.value.map(|v| (n.clone(), v))).collect()
    }

    pub(in crate::scene) fn bound(&mut self, at: At, src: &Src) -> Result<f64, SceneError> {
        let e = self.resolved(at, src)?;
        self.number(&e, src.span)
    }

    /// Splits `H` into `T(p) + V(q, t)` with the compiler's own test of separability, so
    /// that what the session accepts is what [`crate::compile::SeparableHamiltonian`]
    /// compiles. When `H` is not separable, the first term that mixes coordinates and
    /// momenta is named in the error.
    pub(in crate::scene) fn split(&mut self, at: At, h: &Expr, method: MethodId) -> Result<(Expr, Expr), SceneError> {
        let key = CacheKey::symbolic(Step::Split, &self.coords, vec![h.clone()]);
        let what = format!("of {}", short(h));
        if let Some(Value::Exprs(v)) = self.lookup(at, &key, Step::Split, &what) {
            if let [t, v] = &v[..] {
                return Ok((t.clone(), v.clone()));
            }
        }
        let coords: Vec<&str> = self.coords.iter().map(|q| q.name()).collect();
        let momenta_owned: Vec<String> = coords.iter().map(|q| format!("p_{q}")).collect();
        let momenta: Vec<&str> = momenta_owned.iter().map(String::as_str).collect();
        let Some((t, v)) = crate::compile::split_separable(h, &coords, &momenta) else {
            let term = h.terms().into_iter().find(|x| crate::compile::split_separable(x, &coords, &momenta).is_none());
            return Err(SceneError::new(
                ErrorKind::Derivation,
                format!(
                    "`{}` needs a separable H = T(p) + V(q), but the term `{}` mixes coordinates and momenta",
                    method.name(),
                    render(term.as_ref().unwrap_or(h), Format::Plain)
                ),
            )
            .at(at.span)
            .hint("use `gauss6` (symplectic for any H) or `dop853`"));
        };
        self.record(at, Step::Split, what, key, Ok(Value::Exprs(vec![t.clone(), v.clone()])))?;
        Ok((t, v))
    }

    pub(in crate::scene) fn event_expr(
        &mut self,
        at: At,
        ev: &EventSpec,
        layout: Layout,
        l: Option<&Expr>,
        h: Option<&Expr>,
    ) -> Result<Expr, SceneError> {
        let lhs = self.resolved(at, &ev.lhs)?;
        let e = match &ev.rhs {
            Some(r) => lhs.minus(&self.resolved(at, r)?),
            None => lhs,
        };
        self.in_layout(at, &e, layout, l, h, ev.span)
    }

    /// Rewrites an expression into the state variables of a layout: momenta become
    /// `∂L/∂q'` in a velocity layout, velocities become `∂H/∂p` in a momentum layout.
    pub(in crate::scene) fn in_layout(
        &mut self,
        at: At,
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
                    let l = l.cloned().map_or_else(|| self.lagrangian(at), Ok)?;
                    self.diff.diff(&l, &q.prime())
                }
                Layout::Momenta => {
                    let h = h.cloned().map_or_else(|| self.hamiltonian(at), Ok)?;
                    self.diff.diff(&h, &Symbol::new(&format!("p_{}", q.name())))
                }
            };
            map.insert(s.clone(), value);
        }
        Ok(if map.is_empty() { e.clone() } else { e.subs(&map) })
    }

    pub(in crate::scene) fn run_ids(&mut self, at: At, names: &[Src]) -> Result<Vec<usize>, SceneError> {
        if names.is_empty() {
            return match self.runs.len() {
                0 => Err(SceneError::new(ErrorKind::Undeclared, "no simulation to use")
                    .at(at.span)
                    .hint("add a `simulate …` statement before it")),
                // The latest statement's runs: all of an ensemble.
                n => Ok(self
                    .groups
                    .last()
                    .filter(|g| g.ids.last() == Some(&(n - 1)))
                    .map_or(vec![n - 1], |g| g.ids.clone())),
            };
        }
        let mut out = Vec::new();
        for n in names {
            if let Some(g) = self.groups.iter().rev().find(|g| g.name == n.text) {
                out.extend(g.ids.iter().copied());
                continue;
            }
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
    pub(in crate::scene) fn along(
        &mut self,
        at: At,
        r: &RunResult,
        e: &Expr,
        span: Span,
    ) -> Result<Vec<f64>, SceneError> {
        let e = self.in_layout(at, e, r.layout, r.lagrangian.as_ref(), r.hamiltonian.as_ref(), span)?;
        let names = state_names(&r.coords, r.layout);
        let mut out = Vec::with_capacity(r.traj.t.len());
        let params = self.param_values();
        for (k, (t, y)) in r.traj.t.iter().zip(&r.traj.y).enumerate() {
            // Ctrl-C: a long run evaluated for a plot or an export stops here (about 4096
            // evaluations, well under a millisecond, between checks).
            if k % 4096 == 0 {
                crate::scene::state::interruption(span)?;
            }
            let lookup = |s: &Symbol| -> Option<f64> {
                if s.is_time() {
                    return Some(*t);
                }
                let spelled = s.to_string();
                if let Some(i) = names.iter().position(|n| *n == spelled) {
                    return y.get(i).copied();
                }
                if let Some((_, v)) = r.traj.aux.iter().find(|(n, _)| *n == spelled) {
                    return v.get(k).copied();
                }
                r.params.get(s.name()).or_else(|| params.get(s.name())).copied()
            };
            let v = crate::eval::eval_with(&e, &lookup).map_err(|err| self.value_error(err, span))?;
            out.push(v);
        }
        Ok(out)
    }

    pub(in crate::scene) fn energy_of_run(&mut self, at: At, r: &RunResult) -> Result<Expr, SceneError> {
        match r.layout {
            Layout::Momenta => match &r.hamiltonian {
                Some(h) => Ok(h.clone()),
                None => self.hamiltonian(at),
            },
            Layout::Velocities => {
                let l = match &r.lagrangian {
                    Some(l) => l.clone(),
                    None => self.lagrangian(at)?,
                };
                match self.derive(at, DerivKind::Energy, vec![l], at.span)? {
                    Value::Expr(e) => Ok(e),
                    _ => Err(SceneError::new(ErrorKind::Derivation, "no energy function").at(at.span)),
                }
            }
        }
    }
}

/// Every expression a formulation compiles from.
/// A refused `simulate` option as the scene reports it, at the clause it concerns.
/// The span a run's errors point at: its `simulate` statement from the time variable's
/// clause to the time span.
pub(in crate::scene) fn run_span(spec: &SimSpec) -> Span {
    (spec.time_var.span.0.saturating_sub(1), spec.span_span.1)
}

fn run_option_error(e: SimulateError, spec: &SimSpec, stmt: Span) -> SceneError {
    let at = |src: &Option<Src>| src.as_ref().map_or(stmt, |s| s.span);
    let (kind, span, label) = match &e {
        SimulateError::NeedsStep { .. } => (ErrorKind::MissingValue, stmt, None),
        SimulateError::NeedsTolerance { .. } => {
            (ErrorKind::BadNumber, at(if spec.steps.is_some() { &spec.steps } else { &spec.dt }), None)
        }
        SimulateError::ToleranceBelowFloor { .. } => (ErrorKind::BadNumber, at(&spec.tol), Some("too small")),
        SimulateError::TooManySteps { .. } => (ErrorKind::BadNumber, at(&spec.dt), None),
        SimulateError::TooManyStates { .. } => (ErrorKind::BadNumber, at(&spec.every), Some("too many states to keep")),
        _ => (ErrorKind::BadNumber, stmt, None),
    };
    let mut err = SceneError::new(kind, e.to_string()).at(span);
    if let Some(l) = label {
        err = err.label(l);
    }
    match e.hint() {
        Some(h) => err.hint(h),
        None => err,
    }
}

/// A method refused for the scene's system, pointing at the method.
fn refusal_error(r: Refusal, spec: &SimSpec, stmt: Span) -> SceneError {
    let (kind, span) = match r.reason {
        RefusalReason::NothingToIntegrate | RefusalReason::NeedsLagrangian => (ErrorKind::Undeclared, stmt),
        _ => (ErrorKind::Derivation, spec.method.as_ref().map_or(stmt, |m| m.span)),
    };
    SceneError::new(kind, r.to_string()).at(span).hint(r.hint())
}

pub(in crate::scene) fn state_names(coords: &[Symbol], layout: Layout) -> Vec<String> {
    let mut names: Vec<String> = coords.iter().map(|q| q.name().to_string()).collect();
    for q in coords {
        names.push(match layout {
            Layout::Velocities => format!("{}'", q.name()),
            Layout::Momenta => format!("p_{}", q.name()),
        });
    }
    names
}

impl Stmt for SimSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.simulate(at, self)
    }
}
