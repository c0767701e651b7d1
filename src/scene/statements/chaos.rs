//! Chaos statements: `lyapunov`, `megno` and `fli` (the indicator of one orbit, printed, and
//! kept for `plot lyapunov` / `plot megno` / `plot fli`), and `chaos_map` (an indicator over
//! a grid of starts, in parallel, written as a heat map or a CSV table).
//!
//! The indicators are properties of the Hamiltonian flow, so every statement works on `H`
//! (given, or `legendre(L)`), in canonical variables; velocities in the starts are turned
//! into momenta through `p = ∂L/∂q'` like `simulate` does. The variational system is
//! compiled here ([`crate::compile::Variational`]) and integrated by [`crate::chaos`] with the
//! Taylor method. Both go through the backend like a `simulate` run's stages
//! ([`crate::scene::engine::backend::Backend::compile_variational`], `indicators`, `chaos_map`): the compiled
//! system is cached by the content of `H`, the parameter values and the tangent count, so a
//! second statement on the same system reuses it, and `--explain` lists what was compiled
//! and integrated. They are outputs: in a scene file they run when reached, like `print`.
//!
//! A map may put its starts on a level set, `on H = 1/6 solve p_x > 0` (Hénon–Heiles on its
//! surface of section): each cell's missing variable is solved for by the ensemble's root
//! finder ([`super::ensemble::solve_level`]); cells where the level set has no point on that
//! side are left blank (no value drawn, an empty field in a CSV table), and counted.

use std::collections::HashMap;

use crate::cache::{CacheKey, Value};
use crate::chaos::Indicator;
use crate::expr::{Expr, Symbol};
use crate::print::fmt_num;
use crate::scene::engine::backend::{BackendError, CompiledVariational, VariationalRequest};
use crate::scene::engine::plan::{PlanEntry, Status, Step};
use crate::scene::engine::progress::Progress;
use crate::scene::state::backend_error;
use crate::scene::state::{At, ChaosRun, Layout, Session};
use crate::scene::statements::{Output, Stmt};
use crate::scene::syntax::ast::{SimSpec, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `megno …`, `lyapunov …`, `fli …` (one orbit) or `chaos_map INDICATOR …` (a grid).
#[derive(Clone, Debug)]
pub(in crate::scene) struct ChaosSpec {
    /// `lyapunov`, `megno` or `fli`.
    pub indicator: Src,
    /// The starts, time span, options and name, read like a `simulate` statement's.
    pub sim: SimSpec,
    /// `chaos_map`: over a grid of starts.
    pub map: bool,
    /// The map's axes: `θ1 = -3..3` as (coordinate, from, to).
    pub ranges: Vec<(Src, Src, Src)>,
    /// The map's `to FILE`.
    pub path: Option<Src>,
    /// The map's `on H = 1/6 solve p_x > 0`: every start on that level set.
    pub level: Option<LevelSpec>,
    /// The map's `stop megno >= 5 after 10`: the early stop of MEGNO maps.
    pub stop: Option<StopSpec>,
}

/// `stop megno >= 5 after 10` of a chaos map: the orbits' early stop
/// ([`crate::chaos::MegnoStop`]), as written; the library checks the numbers.
#[derive(Clone, Debug)]
pub(in crate::scene) struct StopSpec {
    /// The indicator compared (only `megno` is accepted).
    pub word: Src,
    /// The mean MEGNO at or above which an orbit stops.
    pub above: Src,
    /// The time from which an orbit may stop.
    pub after: Src,
    /// The whole clause.
    pub span: Span,
}

/// `on H = 1/6 solve p_x > 0` of a chaos map: the level set its starts lie on, and the state
/// variable solved for (on the given side of zero).
#[derive(Clone, Debug)]
pub(in crate::scene) struct LevelSpec {
    /// The named expression held fixed (`H`).
    pub on: Src,
    /// Its value.
    pub value: Src,
    /// The state variable solved for.
    pub solve: Src,
    /// Solve on the positive (`> 0`) or negative side.
    pub positive: bool,
    /// The whole clause.
    pub span: Span,
}

impl ChaosSpec {
    /// `lyapunov`/`megno`/`fli` of one orbit, or `chaos_map` (`map`) over a grid of starts.
    pub(in crate::scene) fn read(r: &Reader, map: bool, p: Pair<'_, Rule>) -> Result<ChaosSpec, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let indicator = inner.iter().find(|q| q.as_rule() == Rule::chaos_kw).map(|q| r.src(q));
        let mut ranges = Vec::new();
        let mut path = None;
        let mut level = None;
        let mut stop = None;
        for q in &inner {
            match q.as_rule() {
                Rule::map_range => {
                    let mut it = q.clone().into_inner();
                    if let (Some(s), Some(range)) = (it.next(), it.next()) {
                        let mut b = range.into_inner();
                        if let (Some(lo), Some(hi)) = (b.next(), b.next()) {
                            ranges.push((r.src(&s), r.src(&lo), r.src(&hi)));
                        }
                    }
                }
                Rule::path => path = Some(r.path(q.clone())),
                Rule::megno_stop => {
                    if stop.is_some() {
                        return Err(SceneError::new(ErrorKind::Syntax, "the early stop is given twice")
                            .at(r.span(q))
                            .hint("keep one `stop megno >= … after …`"));
                    }
                    let parts: Vec<Pair<Rule>> = r.inner(q);
                    if let [word, _, above, after] = &parts[..] {
                        stop = Some(StopSpec {
                            word: r.src(word),
                            above: r.src(above),
                            after: r.src(after),
                            span: r.span(q),
                        });
                    }
                }
                Rule::map_level => {
                    let lspan = r.span(q);
                    let parts: Vec<Pair<Rule>> = r.inner(q);
                    if let [on, value, solve, sign] = &parts[..] {
                        level = Some(LevelSpec {
                            on: r.src(on),
                            value: r.src(value),
                            solve: r.src(solve),
                            positive: sign.as_str() == ">",
                            span: lspan,
                        });
                    }
                }
                _ => {}
            }
        }
        let indicator =
            indicator.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected an indicator").at(span))?;
        let sim = r.simulate(inner, span)?;
        Ok(ChaosSpec { indicator, sim, map, ranges, path, level, stop })
    }
}

/// The default tolerance of chaos statements: the tangent vectors grow like `e^{λt}`, so
/// machine precision buys nothing for the indicator and costs steps.
const DEFAULT_TOL: f64 = 1e-12;

/// The default side of a chaos map's grid (`points N` sets it).
const DEFAULT_GRID: usize = 32;

/// The largest side of a chaos map's grid.
const MAX_GRID: usize = 2000;

/// The checks every statement that integrates the variational equations (the chaos
/// indicators, `flow`) makes of its `simulate`-like options: the time is `t`, and no method,
/// step, events, `stabilize` or `every` (named `every` as the caller words it) are given, each
/// refused at its span with `hint`. Returns the refusal, for the caller's own options.
pub(in crate::scene) fn variational_run_refusals<'a>(
    sim: &SimSpec,
    word: &'a str,
    hint: &'a str,
    every: &str,
) -> Result<impl Fn(&str, Option<Span>) -> Result<(), SceneError> + 'a, SceneError> {
    if sim.time_var.text != "t" {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("the time variable is `t`, not `{}`", sim.time_var.text),
        )
        .at(sim.time_var.span));
    }
    let refuse = move |what: &str, src: Option<Span>| -> Result<(), SceneError> {
        match src {
            None => Ok(()),
            Some(s) => {
                Err(SceneError::new(ErrorKind::Syntax, format!("`{word}` does not take {what}")).at(s).hint(hint))
            }
        }
    };
    refuse("a method", sim.method.as_ref().map(|m| m.span))?;
    refuse("a step", sim.dt.as_ref().or(sim.steps.as_ref()).map(|m| m.span))?;
    refuse("events", sim.events.first().map(|e| e.span))?;
    refuse(every, sim.every.as_ref().map(|e| e.span))?;
    refuse("`stabilize`", sim.stabilize.as_ref().map(|e| e.span))?;
    Ok(refuse)
}

/// The error for a word that names no indicator (the grammar's keywords make it unreachable
/// from scene text; kept as an error, not a panic).
fn unknown_indicator() -> SceneError {
    SceneError::new(ErrorKind::Syntax, "expected `lyapunov`, `megno` or `fli`")
}

fn label(which: Indicator) -> &'static str {
    match which {
        Indicator::Lyapunov => "maximal Lyapunov exponent λ",
        Indicator::Megno => "MEGNO ⟨Y⟩",
        Indicator::Fli => "FLI",
    }
}

/// What a chaos statement integrates: the variational system and how to build a start.
struct Setup {
    /// The variational system, compiled by the backend (cached).
    var: CompiledVariational,
    coords: Vec<Symbol>,
    /// `p = ∂L/∂q'` when the starts give velocities.
    momenta: Option<Vec<Expr>>,
    env: HashMap<String, f64>,
    t1: f64,
    tol: f64,
    /// Steps per orbit and time for the statement ([`crate::chaos::Budget`]).
    budget: crate::chaos::Budget,
    span: Span,
}

impl Setup {
    /// A budget error at the statement, with how to raise the budget that ran out.
    fn budget_error(&self, e: BackendError) -> SceneError {
        let steps = e.to_string().contains("step limit");
        let hint = if steps {
            format!(
                "to integrate longer, raise the step budget of each orbit: `max_steps = N` (now {})",
                self.budget.max_steps
            )
        } else {
            format!(
                "to integrate longer, raise the time budget of the statement: `time_limit = SECONDS` (now {})",
                self.budget.time_limit.map_or(0.0, |l| l.as_secs_f64())
            )
        };
        backend_error(e, self.span).hint(hint)
    }

    /// The canonical start `(q, p)` from values of the coordinates and their velocities or
    /// momenta (named `q`, `q'` or `p_q`).
    fn start(&self, given: &HashMap<String, f64>) -> Result<Vec<f64>, crate::eval::EvalError> {
        let n = self.coords.len();
        let mut x = vec![0.0; 2 * n];
        for (i, q) in self.coords.iter().enumerate() {
            x[i] = given[q.name()];
        }
        match &self.momenta {
            None => {
                for (i, q) in self.coords.iter().enumerate() {
                    x[n + i] = given[&format!("p_{}", q.name())];
                }
            }
            Some(ps) => {
                let mut env = self.env.clone();
                env.extend(given.iter().map(|(k, v)| (k.clone(), *v)));
                env.insert("t".into(), 0.0);
                for (i, p) in ps.iter().enumerate() {
                    x[n + i] = crate::eval::eval(p, &env)?;
                }
            }
        }
        Ok(x)
    }
}

/// A chaos map's `on H = E solve p_x > 0`: the level function in the canonical variables.
struct Level {
    /// The level function, in `(q, p)` and the parameters.
    on: Expr,
    /// Its value `E`.
    value: f64,
    /// The start's key solved for (`p_x`, or a velocity `x'`).
    key: String,
    /// Solve on the positive side of zero.
    positive: bool,
    /// Parameter values.
    env: HashMap<String, f64>,
    span: Span,
}

impl Level {
    /// Puts `given` on the level set by solving for `self.key` with the ensemble's root
    /// finder; `false` when the level set has no point on that side (the cell stays blank).
    fn solve(&self, setup: &Setup, given: &mut HashMap<String, f64>) -> Result<bool, SceneError> {
        let n = setup.coords.len();
        let mut names: Vec<String> = setup.coords.iter().map(|q| q.name().to_string()).collect();
        names.extend(setup.coords.iter().map(|q| format!("p_{}", q.name())));
        let f = |y: &[f64]| -> Result<f64, SceneError> {
            let mut g = given.clone();
            g.insert(self.key.clone(), y[0]);
            let x = setup.start(&g).map_err(|e| {
                SceneError::new(ErrorKind::BadNumber, format!("cannot evaluate the start: {e}")).at(self.span)
            })?;
            crate::eval::eval_with(&self.on, &|s: &Symbol| {
                if s.is_time() {
                    return Some(0.0);
                }
                let spelled = s.to_string();
                names[..2 * n]
                    .iter()
                    .position(|m| *m == spelled)
                    .map(|i| x[i])
                    .or_else(|| self.env.get(s.name()).copied())
            })
            .map_err(|e| {
                SceneError::new(ErrorKind::BadNumber, format!("cannot evaluate the level function: {e}")).at(self.span)
            })
        };
        let mut y = [0.0];
        let found = super::ensemble::solve_level(&f, &mut y, 0, self.value, self.positive)?;
        if found {
            given.insert(self.key.clone(), y[0]);
        }
        Ok(found)
    }
}

/// A chaos map's axis: the state variable and its range.
type Axis = (Src, f64, f64);

impl Session {
    /// The level clause of a chaos map, checked, with its function in `(q, p)`.
    fn chaos_level(&mut self, at: At, l: &LevelSpec, setup: &Setup) -> Result<Level, SceneError> {
        let key = self.state_key(&l.solve)?;
        let on = self.resolved(at, &l.on)?;
        let on = self.in_layout(at, &on, Layout::Momenta, None, None, l.on.span)?;
        let value = self.resolved(at, &l.value)?;
        let value = self.number(&value, l.value.span)?;
        // Every symbol of the level function must be a state variable or a parameter with a
        // value (as the equations' own parameters are checked).
        let env = self.param_values();
        for s in on.free_symbols() {
            let state = setup.coords.iter().any(|q| q.name() == s.name() || format!("p_{}", q.name()) == s.name());
            if s.primes() == 0 && (state || env.contains_key(s.name()) || s.is_time()) {
                continue;
            }
            return Err(SceneError::new(
                ErrorKind::MissingValue,
                format!("`{s}` in the level function `{}` has no value", l.on.text),
            )
            .at(l.on.span)
            .hint("a level set of a chaos map is in the state variables and parameters with values"));
        }
        Ok(Level { on, value, key, positive: l.positive, env, span: l.span })
    }

    /// `megno …`, `lyapunov …`, `fli …`, `chaos_map …`.
    pub(in crate::scene) fn chaos(&mut self, at: At, spec: &ChaosSpec) -> Result<(), SceneError> {
        let which = Indicator::named(&spec.indicator.text).ok_or_else(unknown_indicator)?;
        if spec.map {
            self.chaos_map(at, spec, which)
        } else {
            self.chaos_orbit(at, spec, which)
        }
    }

    fn chaos_orbit(&mut self, at: At, spec: &ChaosSpec, which: Indicator) -> Result<(), SceneError> {
        let given = self.chaos_values(at, spec, &[])?;
        // The full spectrum for `lyapunov` (2n tangents); one tangent and the MEGNO
        // accumulator otherwise.
        let n = self.coords.len();
        let (tangents, megno) = if which == Indicator::Lyapunov { (2 * n, false) } else { (1, true) };
        let setup = self.chaos_setup(at, spec, tangents, megno)?;
        let x0 = setup.start(&given).map_err(|e| self.value_error(e, setup.span))?;
        let name = match &spec.sim.name {
            Some(n) => n.text.clone(),
            None => format!("{}{}", spec.indicator.text, self.chaos_runs.len() + 1),
        };
        let r = self.backend.indicators(&setup.var, &x0, setup.t1, setup.tol, &setup.budget).map_err(|e| match e {
            BackendError::Budget(_) => setup.budget_error(e),
            e => backend_error(e, setup.span),
        })?;
        self.plan.push(PlanEntry {
            step: Step::Integrate,
            what: format!(
                "{} {name}: one orbit with taylor tol = {:e} ({} steps)",
                spec.indicator.text, setup.tol, r.steps
            ),
            line: Some(at.line),
            status: Status::Built,
        });
        let t = fmt_num(setup.t1);
        let line = match which {
            Indicator::Lyapunov => format!(
                "{name}: Lyapunov exponents at t = {t}: {} ({} Taylor steps)",
                r.lyapunov.iter().map(|l| format!("{l:.6}")).collect::<Vec<_>>().join(", "),
                r.steps
            ),
            Indicator::Megno => format!(
                "{name}: MEGNO ⟨Y⟩ = {:.4} at t = {t} (λ = {:.6} from the slope of Y; {} Taylor steps)",
                r.megno, r.megno_lyapunov, r.steps
            ),
            Indicator::Fli => format!("{name}: FLI = {:.4} at t = {t} ({} Taylor steps)", r.fli, r.steps),
        };
        self.output.push(line);
        self.chaos_runs.retain(|c| c.name != name);
        self.chaos_runs.push(ChaosRun { name, which, result: r });
        Ok(())
    }

    fn chaos_map(&mut self, at: At, spec: &ChaosSpec, which: Indicator) -> Result<(), SceneError> {
        let (side, axes) = self.map_grid(at, spec)?;
        let stop = match &spec.stop {
            Some(s) => Some(self.megno_stop(at, s, which)?),
            None => None,
        };
        let mut names: Vec<Src> = axes.iter().map(|a| a.0.clone()).collect();
        names.extend(spec.level.as_ref().map(|l| l.solve.clone()));
        let base = self.chaos_values(at, spec, &names)?;
        let mut setup = self.chaos_setup(at, spec, 1, which == Indicator::Megno)?;
        setup.budget.megno_stop = stop;
        let level = match &spec.level {
            Some(l) => Some(self.chaos_level(at, l, &setup)?),
            None => None,
        };
        let (path, pspan, ext) = self.out_file(
            at.span,
            spec.path.as_ref(),
            "chaos_map",
            "chaos map",
            &["svg", "png", "csv"],
            "a chaos map is drawn as `.svg` or `.png`, or written as a table to `.csv`",
        )?;
        let (kx, ky) = (self.state_key(&axes[0].0)?, self.state_key(&axes[1].0)?);
        // The starts, and which cells have one (all of them without a level set).
        let mut starts = Vec::with_capacity(side * side);
        let mut on_surface = Vec::with_capacity(side * side);
        for j in 0..side {
            for i in 0..side {
                let mut given = base.clone();
                given.insert(kx.clone(), centre(side, i, &axes[0]));
                given.insert(ky.clone(), centre(side, j, &axes[1]));
                if let Some(level) = &level {
                    if !level.solve(&setup, &mut given)? {
                        on_surface.push(false);
                        continue;
                    }
                }
                on_surface.push(true);
                starts.push(setup.start(&given).map_err(|e| self.value_error(e, setup.span))?);
            }
        }
        if starts.is_empty() {
            let l = spec.level.as_ref().map_or(setup.span, |l| l.span);
            return Err(SceneError::new(ErrorKind::BadNumber, "no cell of the grid has a point on the level set")
                .at(l)
                .hint("check the level's value against the energy over the grid"));
        }
        let mut bar = Progress::new("chaos map", self.opts.progress);
        let computed =
            self.backend
                .chaos_map(&setup.var, &starts, setup.t1, setup.tol, &setup.budget, which, &mut |x| bar.update(x));
        bar.finish();
        // A start that ran out of the budget has no value, and a blank there would read as a
        // failed (escaping) orbit: the map is refused, naming the budget.
        if let Some(Err(e)) = computed.iter().find(|r| matches!(r, Err(BackendError::Budget(_)))) {
            return Err(setup.budget_error(e.clone()));
        }
        // A start whose integration fails (escapes, meets a singularity) is blank too, but
        // counted apart from the cells off the level set.
        let blank = crate::chaos::Cell::BLANK;
        let mut computed = computed.into_iter().map(|r| r.unwrap_or(blank));
        let cells: Vec<crate::chaos::Cell> =
            on_surface.iter().map(|&on| if on { computed.next().unwrap_or(blank) } else { blank }).collect();
        let values: Vec<f64> = cells.iter().map(|c| c.value).collect();
        let stopped_at: Vec<Option<f64>> = cells.iter().map(|c| c.stopped_at).collect();
        let stopped = stopped_at.iter().filter(|t| t.is_some()).count();
        let off = on_surface.iter().filter(|on| !**on).count();
        let failed = values.iter().zip(&on_surface).filter(|(v, on)| **on && !v.is_finite()).count();
        self.plan.push(PlanEntry {
            step: Step::Integrate,
            what: format!(
                "chaos map {}: {} starts with taylor tol = {:e}",
                spec.indicator.text,
                starts.len(),
                setup.tol
            ),
            line: Some(at.line),
            status: Status::Built,
        });
        let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        finite.sort_by(f64::total_cmp);
        let median = finite.get(finite.len() / 2).copied().unwrap_or(f64::NAN);
        let (xn, yn) = (&axes[0].0.text, &axes[1].0.text);
        let tmp = self.staging.stage(&path).map_err(|e| e.at(pspan))?;
        if ext == "csv" {
            let s = map_table(&axes, side, &on_surface, &values, &spec.indicator.text, stop.map(|_| &stopped_at[..]));
            std::fs::write(&tmp, s).map_err(|e| {
                SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", path.display())).at(pspan)
            })?;
        } else {
            // A stopped cell's colour is its ⟨Y⟩ at the stop, not at `T`: the title says so
            // (in the legend it would widen the box over the cells).
            let title = match &stop {
                None => format!("{} at t = {}", label(which), fmt_num(setup.t1)),
                Some(st) => format!(
                    "{} at t = {}; ⟨Y⟩ ≥ {} after t = {}: stopped there (colour at the stop)",
                    label(which),
                    fmt_num(setup.t1),
                    fmt_num(st.above),
                    fmt_num(st.after)
                ),
            };
            let fig = crate::plot::Figure::heat_map(
                &title,
                xn,
                yn,
                (axes[0].1, axes[0].2),
                (axes[1].1, axes[1].2),
                side,
                values.clone(),
            );
            crate::plot::draw(&fig, &tmp).map_err(|e| {
                SceneError::new(ErrorKind::Io, format!("cannot write the plot `{}`: {e}", path.display())).at(pspan)
            })?;
        }
        self.output.push(format!(
            "chaos map: {} over {xn} ∈ [{}, {}] × {yn} ∈ [{}, {}], {side}×{side} starts to t = {}: median {median:.4}{}",
            label(which),
            fmt_num(axes[0].1),
            fmt_num(axes[0].2),
            fmt_num(axes[1].1),
            fmt_num(axes[1].2),
            fmt_num(setup.t1),
            match &spec.level {
                Some(l) => format!(
                    ", {} of {} cells on {} = {} ({off} blank: no {} {} 0 there)",
                    side * side - off,
                    side * side,
                    l.on.text,
                    l.value.text,
                    l.solve.text,
                    if l.positive { ">" } else { "<" }
                ),
                None => String::new(),
            } + &if failed > 0 { format!(", {failed} starts failed (blank)") } else { String::new() }
                + &match &stop {
                    Some(st) => format!(
                        ", {stopped} stopped early at ⟨Y⟩ ≥ {} after t = {} (their value is ⟨Y⟩ at the stop)",
                        fmt_num(st.above),
                        fmt_num(st.after)
                    ),
                    None => String::new(),
                }
        ));
        self.wrote(&path);
        Ok(())
    }

    /// A map's `stop megno >= L after T` as the library's [`crate::chaos::MegnoStop`]: refused
    /// on a map of another indicator (it compares MEGNO) and for a word other than `megno`;
    /// the numbers are checked by [`crate::chaos::MegnoStop::new`], whose message is put at
    /// the clause.
    fn megno_stop(&mut self, at: At, s: &StopSpec, which: Indicator) -> Result<crate::chaos::MegnoStop, SceneError> {
        if which != Indicator::Megno {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!("`stop megno >= …` applies to MEGNO maps only, not to a `{}` map", which.name()),
            )
            .at(s.span)
            .hint(
                "the early stop ends orbits whose mean MEGNO has diverged: map `megno`, or remove the `stop` clause",
            ));
        }
        if s.word.text != "megno" {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!("the early stop compares MEGNO ⟨Y⟩, not `{}`", s.word.text),
            )
            .at(s.word.span)
            .hint("write `stop megno >= 5 after 10`"));
        }
        let above = self.bound(at, &s.above)?;
        let after = self.bound(at, &s.after)?;
        crate::chaos::MegnoStop::new(above, after).map_err(|m| {
            SceneError::new(ErrorKind::BadNumber, m)
                .at(s.span)
                .hint("for example `stop megno >= 5 after 10`: an orbit stops once t ≥ 10 and ⟨Y⟩ ≥ 5")
        })
    }

    /// A chaos map's grid: the side (`points`, default [`DEFAULT_GRID`]) and the two axes,
    /// each a state variable with a finite range whose width f64 holds.
    fn map_grid(&mut self, at: At, spec: &ChaosSpec) -> Result<(usize, Vec<Axis>), SceneError> {
        if spec.ranges.len() != 2 {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!("a chaos map needs two ranges, found {}", spec.ranges.len()),
            )
            .at(spec.indicator.span)
            .hint("write the two axes as ranges: `chaos_map megno θ1 = -3..3, θ2 = -3..3, θ1' = 0, θ2' = 0 for t in 0..50`"));
        }
        let side = match &spec.sim.points {
            None => DEFAULT_GRID,
            Some(src) => {
                let e = self.resolved(at, src)?;
                let x = self.number(&e, src.span)?;
                if !(x.fract() == 0.0 && (2.0..=MAX_GRID as f64).contains(&x)) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("`points` is the grid's side, a whole number from 2 to {MAX_GRID}; found {x}"),
                    )
                    .at(src.span));
                }
                x as usize
            }
        };
        let mut axes = Vec::new();
        for (sym, lo, hi) in &spec.ranges {
            let (a, b) = (self.bound(at, lo)?, self.bound(at, hi)?);
            if !(a < b && a.is_finite() && b.is_finite()) {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!("the range of `{}` must run from a smaller to a larger number", sym.text),
                )
                .at((lo.span.0, hi.span.1)));
            }
            // The cells' centres are a + (b − a)(k + ½)/N: a range wider than f64 holds
            // (−1e308..1e308) would make them infinite, and every start would fail.
            if !(b - a).is_finite() {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!("the range of `{}` is wider than f64 can hold ({b:e} − ({a:e}) overflows)", sym.text),
                )
                .at((lo.span.0, hi.span.1))
                .hint("narrow the range so that its width is below 1.8e308"));
            }
            axes.push((sym.clone(), a, b));
        }
        Ok((side, axes))
    }

    /// The state variable a start names (`θ`, `θ'` or `p_θ`), as the key of its value.
    pub(in crate::scene) fn state_key(&mut self, sym: &Src) -> Result<String, SceneError> {
        let (e, _) = self.expr(sym)?;
        let s = e.as_sym().cloned().ok_or_else(|| {
            SceneError::new(ErrorKind::Syntax, "expected a coordinate, velocity or momentum").at(sym.span)
        })?;
        let coords = &self.coords;
        let is_state = coords.iter().any(|c| c.name() == s.name() && s.primes() <= 1)
            || (s.primes() == 0 && s.name().strip_prefix("p_").is_some_and(|c| coords.iter().any(|q| q.name() == c)));
        if !is_state {
            return Err(SceneError::new(
                ErrorKind::UndefinedSymbol,
                format!("`{}` is not part of the state", sym.text),
            )
            .at(sym.span)
            .hint("give coordinates, their velocities (`θ'`) or their momenta (`p_θ`)"));
        }
        Ok(s.to_string())
    }

    /// The fixed starting values of a chaos statement (`axes` are given by the map's grid):
    /// every coordinate, and either every velocity or every momentum, exactly once.
    fn chaos_values(&mut self, at: At, spec: &ChaosSpec, axes: &[Src]) -> Result<HashMap<String, f64>, SceneError> {
        let stmt = spec.indicator.span;
        if self.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(stmt)
                .hint("declare them first, for example `coordinates θ`"));
        }
        // A phase-space Lagrangian `a(z)·z' − H(z)` has no momenta to ask for: its coordinates
        // are already the phase-space variables.
        if self.def_names.contains_key("L") && !self.def_names.contains_key("H") {
            let l = self.lagrangian(at)?;
            if crate::simulate::is_first_order(&l, &self.coords) {
                return Err(SceneError::new(
                    ErrorKind::Derivation,
                    format!("`{}` needs Hamilton's equations in (q, p), but this L is first order in its velocities (a phase-space Lagrangian), so it has no momenta p_q", spec.indicator.text),
                )
                .at(stmt)
                .hint("define the same system as `H = …` with its canonical pairs as coordinates and momenta `p_q` (for L = x y' − H(x, y): coordinate y, momentum p_y = x)"));
            }
        }
        let mut given = HashMap::new();
        let mut seen = Vec::new();
        for sym in axes {
            let k = self.state_key(sym)?;
            seen.push((k, sym.span));
        }
        for (sym, val) in &spec.sim.inits {
            let k = self.state_key(sym)?;
            let v = self.resolved(at, val)?;
            let x = self.number(&v, val.span)?;
            given.insert(k.clone(), x);
            seen.push((k, sym.span));
        }
        for (i, (k, span)) in seen.iter().enumerate() {
            if seen[..i].iter().any(|(o, _)| o == k) {
                return Err(SceneError::new(ErrorKind::Syntax, format!("`{k}` is given twice")).at(*span));
            }
        }
        let has = |k: &str| seen.iter().any(|(o, _)| o == k);
        let coords = self.coords.clone();
        let velocities = coords.iter().any(|q| has(&format!("{}'", q.name())));
        for q in &coords {
            let v = format!("{}'", q.name());
            let p = format!("p_{}", q.name());
            for need in [q.name(), if velocities { v.as_str() } else { p.as_str() }] {
                if !has(need) {
                    return Err(SceneError::new(ErrorKind::MissingValue, format!("no starting value for `{need}`"))
                        .at(stmt)
                        .hint(format!(
                            "add `{need} = …` (give every coordinate and every velocity, or every momentum)"
                        )));
                }
            }
            if velocities && has(&p) {
                return Err(SceneError::new(ErrorKind::Syntax, "give either velocities or momenta, not both").at(stmt));
            }
        }
        Ok(given)
    }

    /// The options of a chaos statement, checked before anything is derived: the time variable,
    /// no integration option the Taylor method's variational run cannot honour, the span from
    /// t = 0, and the tolerance; `(t1, tol)`.
    fn chaos_options(&mut self, at: At, spec: &ChaosSpec) -> Result<(f64, f64), SceneError> {
        let sim = &spec.sim;
        let word = &spec.indicator.text;
        let hint = "a chaos indicator integrates the variational equations with the Taylor method; it takes `tol = …` (and a map `points N`)";
        let refuse = variational_run_refusals(sim, word, hint, "`every`")?;
        if !spec.map {
            refuse("`points` (only `chaos_map` has a grid)", sim.points.as_ref().map(|e| e.span))?;
        }
        let t0 = self.bound(at, &sim.t0)?;
        let t1 = self.bound(at, &sim.t1)?;
        if t0 != 0.0 || !(t1 > 0.0 && t1.is_finite()) {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!(
                    "a chaos indicator is measured from t = 0 to a later time; found {}..{}",
                    fmt_num(t0),
                    fmt_num(t1)
                ),
            )
            .at(sim.span_span)
            .hint("write `for t in 0..100`"));
        }
        let tol = match &sim.tol {
            None => DEFAULT_TOL,
            Some(src) => {
                let e = self.resolved(at, src)?;
                let x = self.number(&e, src.span)?;
                if !(x > 0.0 && x.is_finite()) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("the tolerance must be positive, found {x}"),
                    )
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
                x
            }
        };
        Ok((t1, tol))
    }

    /// The parameters `H` and the momenta (when velocities are given) use, with their values,
    /// sorted by name: what the compiled code binds and what its cache key records.
    fn chaos_params(
        &self,
        span: Span,
        h: &Expr,
        momenta: Option<&Vec<Expr>>,
    ) -> Result<Vec<(String, f64)>, SceneError> {
        let mut params = Vec::new();
        let mut needed: Vec<String> = h
            .free_symbols()
            .into_iter()
            .filter(|s| s.primes() == 0 && self.params.contains_key(s.name()))
            .map(|s| s.name().to_string())
            .collect();
        for e in momenta.into_iter().flatten() {
            needed.extend(
                e.free_symbols()
                    .into_iter()
                    .filter(|s| self.params.contains_key(s.name()))
                    .map(|s| s.name().to_string()),
            );
        }
        needed.sort();
        needed.dedup();
        for p in needed {
            match self.params.get(&p).and_then(|x| x.value) {
                Some(v) => params.push((p, v)),
                None => {
                    return Err(SceneError::new(ErrorKind::MissingValue, format!("parameter `{p}` has no value"))
                        .at(span)
                        .hint(format!("declare `{p}` with a value first: `parameters {p} = …`")))
                }
            }
        }
        Ok(params)
    }

    /// The checked options, `H`, its parameters and the compiled variational system.
    fn chaos_setup(&mut self, at: At, spec: &ChaosSpec, tangents: usize, megno: bool) -> Result<Setup, SceneError> {
        let sim = &spec.sim;
        let span = (spec.indicator.span.0, sim.span_span.1);
        let (t1, tol) = self.chaos_options(at, spec)?;
        if !self.dynamics.is_empty() {
            return Err(SceneError::new(
                ErrorKind::Derivation,
                "chaos indicators are computed on the Hamiltonian flow; forces, dissipation and constraints are not part of it",
            )
            .at(span));
        }
        let coords = self.coords.clone();
        let velocities = sim.inits.iter().any(|(s, _)| s.text.trim_end().ends_with('\''))
            || spec.ranges.iter().any(|(s, _, _)| s.text.trim_end().ends_with('\''))
            || spec.level.as_ref().is_some_and(|l| l.solve.text.trim_end().ends_with('\''));
        let momenta = if velocities {
            let l = self.lagrangian(at).map_err(|e| {
                e.hint("velocities are turned into momenta through `L`: give the momenta `p_q` instead, or define `L`")
            })?;
            Some(self.momenta(at, &l)?)
        } else {
            None
        };
        let h = self.hamiltonian(at)?;
        if let Some(f) = h.applied_functions().into_iter().next() {
            return Err(SceneError::new(
                ErrorKind::MissingValue,
                format!("the declared function `{f}` has no numeric definition"),
            )
            .at(span));
        }
        let params = self.chaos_params(span, &h, momenta.as_ref())?;
        // Compiled through the backend, cached like a run's right-hand side: by the content
        // of H, the parameter values and what rides along.
        let key = CacheKey {
            step: Step::Compile,
            coords: coords.clone(),
            inputs: vec![h.clone()],
            numbers: params.iter().map(|(_, v)| v.to_bits()).collect(),
            extra: format!(
                "variational:{tangents}:{megno}:{}",
                params.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(",")
            ),
        };
        let what = format!(
            "variational equations of H, {tangents} tangent vector{}{}, for taylor",
            if tangents == 1 { "" } else { "s" },
            if megno { " and MEGNO's accumulator" } else { "" }
        );
        let var = match self.lookup(at, &key, Step::Compile, &what) {
            Some(Value::Variational(c)) => c,
            _ => {
                let req = VariationalRequest { coords: coords.clone(), h, params: params.clone(), tangents, megno };
                let built =
                    self.backend.compile_variational(&req).map(Value::Variational).map_err(|e| backend_error(e, span));
                match self.record(at, Step::Compile, what, key, built)? {
                    Value::Variational(c) => c,
                    _ => return Err(SceneError::new(ErrorKind::Numeric, "compilation gave no code").at(span)),
                }
            }
        };
        let env = params.into_iter().collect();
        let budget = self.chaos_budget(at, sim)?;
        Ok(Setup { var, coords, momenta, env, t1, tol, budget, span })
    }

    /// `max_steps = N` and `time_limit = S` of a chaos statement, checked, as its budget; the
    /// time counts from here.
    pub(in crate::scene) fn chaos_budget(
        &mut self,
        at: At,
        sim: &crate::scene::syntax::ast::SimSpec,
    ) -> Result<crate::chaos::Budget, SceneError> {
        use crate::chaos::Budget;
        let max_steps = self.step_budget(at, sim)?.unwrap_or(Budget::DEFAULT_STEPS);
        let seconds = match &sim.time_limit {
            None => Budget::DEFAULT_SECONDS,
            Some(src) => {
                let e = self.resolved(at, src)?;
                let x = self.number(&e, src.span)?;
                if !(x > 0.0 && x.is_finite() && x < 1e9) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("`time_limit` is a positive number of seconds below 10⁹; found {}", fmt_num(x)),
                    )
                    .at(src.span));
                }
                x
            }
        };
        Ok(Budget::new(max_steps, std::time::Duration::from_secs_f64(seconds)))
    }

    /// `plot lyapunov | megno | fli [from NAME, …]`: the indicator against time.
    pub(in crate::scene) fn chaos_figure(
        &mut self,
        word: &Src,
        runs: &[Src],
    ) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Figure, Series};
        let which = Indicator::named(&word.text).ok_or_else(|| unknown_indicator().at(word.span))?;
        let usable = |c: &ChaosRun| which != Indicator::Megno || c.which != Indicator::Lyapunov;
        let mut chosen = Vec::new();
        if runs.is_empty() {
            match self.chaos_runs.iter().rev().find(|c| usable(c)) {
                Some(c) => chosen.push(c),
                None => {
                    return Err(SceneError::new(
                        ErrorKind::Undeclared,
                        format!(
                            "no `{}` statement before this plot",
                            if which == Indicator::Lyapunov { "lyapunov` or `megno" } else { word.text.as_str() }
                        ),
                    )
                    .at(word.span)
                    .hint(format!("compute it first: `{} θ = 1, θ' = 0 for t in 0..100`", word.text)))
                }
            }
        }
        for r in runs {
            match self.chaos_runs.iter().find(|c| c.name == r.text) {
                Some(c) if usable(c) => chosen.push(c),
                Some(_) => {
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("`{}` computed Lyapunov exponents, not MEGNO", r.text),
                    )
                    .at(r.span)
                    .hint("use `megno …` for MEGNO"))
                }
                None => {
                    return Err(SceneError::new(
                        ErrorKind::Undeclared,
                        format!("no chaos statement named `{}`", r.text),
                    )
                    .at(r.span)
                    .hint("name one with `as NAME`: `megno θ = 1, θ' = 0 for t in 0..100 as orbit`"))
                }
            }
        }
        let series = chosen
            .iter()
            .map(|c| Series {
                label: c.name.clone(),
                points: c
                    .result
                    .samples
                    .iter()
                    .scan(0.0f64, |fli, s| {
                        *fli = fli.max(s.log_norm);
                        let y = match which {
                            Indicator::Lyapunov => s.lyapunov,
                            Indicator::Megno => s.megno,
                            Indicator::Fli => *fli,
                        };
                        Some((s.t, y))
                    })
                    .collect(),
            })
            .collect();
        Ok(Figure::lines(label(which), "t", label(which), series))
    }
}

/// The centre of cell `k` of `side` along an axis: cell centres, row by row (the second
/// axis outer), are a + (b − a)(k + ½)/N.
fn centre(side: usize, k: usize, (_, a, b): &Axis) -> f64 {
    a + (b - a) * (k as f64 + 0.5) / side as f64
}

/// A chaos map as a CSV table of x, y and the value; a cell off the level set has no value.
/// With an early stop (`stopped_at`), a last column `stopped_at` gives the time a cell's orbit
/// stopped, empty for one that ran to the end (and for a cell without an orbit); without it
/// the table has only the three columns.
fn map_table(
    axes: &[Axis],
    side: usize,
    on_surface: &[bool],
    values: &[f64],
    indicator: &str,
    stopped_at: Option<&[Option<f64>]>,
) -> String {
    let mut s = format!(
        "{},{},{}{}\n",
        super::figures::csv_field(&axes[0].0.text),
        super::figures::csv_field(&axes[1].0.text),
        indicator,
        if stopped_at.is_some() { ",stopped_at" } else { "" }
    );
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            let (x, y) = (centre(side, i, &axes[0]), centre(side, j, &axes[1]));
            match (on_surface[k], values[k]) {
                // Off the level set: no value at all.
                (false, _) => s.push_str(&format!("{x:e},{y:e},")),
                (true, v) => s.push_str(&format!("{x:e},{y:e},{v:e}")),
            }
            match stopped_at.map(|st| st[k]) {
                None => {}
                Some(None) => s.push(','),
                Some(Some(t)) => s.push_str(&format!(",{t:e}")),
            }
            s.push('\n');
        }
    }
    s
}

impl Stmt for ChaosSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.chaos(at, self)
    }

    fn output(&self) -> Option<Output<'_>> {
        self.map.then_some(Output {
            path: self.path.as_ref(),
            default: "chaos_map",
            what: "chaos map",
            formats: &["svg", "png", "csv"],
            hint: "a chaos map is drawn as `.svg` or `.png`, or written as a table to `.csv`",
        })
    }
}
