//! Ensembles: `simulate x = 0, p_y = 0 for each y in 0..0.4 step 0.02 on H = 1/8 solve p_x > 0
//! for t in …` starts one run per value of the swept variable, each on the level set
//! `H = 1/8`, by solving for the named variable on the given side of zero. The system is
//! compiled once; the runs are integrated in parallel ([`crate::scene::engine::backend::Backend::integrate_many`])
//! behind one progress bar, and named as a group: `from NAME` (or no `from` after it) means
//! all of them, and `NAME_k` is the k-th. Values for which the level set has no point on that
//! side are skipped with a note, never started off the surface.
//!
//! An ensemble runs when its statement is reached, also in a scene (its members are not
//! demand-driven one by one).

use std::collections::HashMap;
use std::sync::Arc;

use super::simulate::state_names;
use crate::expr::Symbol;
use crate::print::fmt_num;
use crate::scene::engine::plan::{PlanEntry, Status, Step};
use crate::scene::engine::progress::Progress;
use crate::scene::state::{At, Group, RunEntry, RunResult, Session};
use crate::scene::syntax::ast::{EnsembleSpec, SimSpec, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError};

/// The most members one ensemble may have.
pub const MAX_MEMBERS: usize = 10_000;

impl Session {
    pub(in crate::scene) fn simulate_ensemble(&mut self, at: At, spec: &SimSpec) -> Result<(), SceneError> {
        let Some(ens) = spec.ensemble.clone() else { return Ok(()) };
        self.check_method(spec)?;
        let (a, b, values) = self.sweep_values(at, &ens)?;

        // The base run: the swept and the solved variable get placeholder values, replaced
        // per member below.
        let (base, sweep, solve) = self.ensemble_base(spec, &ens)?;
        let name = match &spec.name {
            Some(n) => n.text.clone(),
            None => format!("run{}", self.runs.len() + 1),
        };
        let dynamics = self.dynamics.clone();
        let (compiled, run, template, energy) = self.prepare_run(at, &base, &name, &dynamics)?;
        // From here on the statement's errors point where the run's do.
        let stmt_span = super::simulate::run_span(&base);
        let at = At { span: stmt_span, ..at };
        let names = state_names(&template.coords, template.layout);
        let index = |s: &Symbol, src: &Src| {
            names.iter().position(|n| *n == s.to_string()).ok_or_else(|| {
                SceneError::new(
                    ErrorKind::UndefinedSymbol,
                    format!("`{}` is not a variable of this run's state ({})", src.text, names.join(", ")),
                )
                .at(src.span)
            })
        };
        let (i_sweep, i_solve) = (index(&sweep, &ens.var)?, index(&solve, &ens.solve)?);

        // The level function in the state's variables, and its value.
        let on = self.resolved(at, &ens.on)?;
        let on = self.in_layout(
            at,
            &on,
            template.layout,
            template.lagrangian.as_ref(),
            template.hamiltonian.as_ref(),
            ens.on.span,
        )?;
        let value = self.resolved(at, &ens.value)?;
        let level = self.number(&value, ens.value.span)?;
        let mut params: HashMap<String, f64> = self.param_values();
        params.extend(template.params.iter().map(|(k, v)| (k.clone(), *v)));
        let t0 = run.options.t0;
        let on_span = ens.on.span;
        let f = |y: &[f64]| -> Result<f64, SceneError> {
            crate::eval::eval_with(&on, &|s: &Symbol| {
                if s.is_time() {
                    return Some(t0);
                }
                let spelled = s.to_string();
                names.iter().position(|n| *n == spelled).map(|i| y[i]).or_else(|| params.get(s.name()).copied())
            })
            .map_err(|e| {
                SceneError::new(ErrorKind::BadNumber, format!("cannot evaluate the level function: {e}")).at(on_span)
            })
        };

        let mut requests = Vec::new();
        let mut kept = Vec::new();
        let mut skipped = Vec::new();
        for &v in &values {
            let mut y0 = run.y0.clone();
            y0[i_sweep] = v;
            match solve_level(&f, &mut y0, i_solve, level, ens.positive)? {
                true => {
                    kept.push(v);
                    requests.push(crate::scene::engine::backend::RunRequest { y0, ..run.clone() });
                }
                false => skipped.push(v),
            }
        }
        if requests.is_empty() {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!(
                    "no value of `{}` in {}..{} has a point on {} = {} with {} {} 0",
                    ens.var.text,
                    fmt_num(a),
                    fmt_num(b),
                    ens.on.text,
                    ens.value.text,
                    ens.solve.text,
                    if ens.positive { ">" } else { "<" }
                ),
            )
            .at(ens.span)
            .hint("check the level's value against the energy at the other initial values"));
        }

        let mut bar = Progress::new(&name, self.opts.progress);
        let results = self.backend.integrate_many(&compiled, &requests, &mut |x| bar.update(x));
        bar.finish();
        let mut ids = Vec::new();
        for (k, r) in results.into_iter().enumerate() {
            let traj = r.map_err(|e| {
                crate::scene::state::backend_error(e, stmt_span).hint(format!(
                    "in the ensemble member {} = {}",
                    ens.var.text,
                    fmt_num(kept[k])
                ))
            })?;
            let member = format!("{name}_{}", k + 1);
            let mut traj = traj;
            self.settle_energy(&member, &energy, &mut traj, stmt_span)?;
            let id = self.runs.len();
            let mut member_spec = base.clone();
            member_spec.name = Some(Src { text: member.clone(), span: stmt_span });
            self.runs.push(RunEntry {
                name: member.clone(),
                spec: member_spec,
                line: at.line,
                result: Some(RunResult { traj: Arc::new(traj), ..template.clone() }),
                dynamics: dynamics.clone(),
            });
            self.run_names.insert(member, id);
            ids.push(id);
        }
        self.plan.push(PlanEntry {
            step: Step::Integrate,
            what: format!("ensemble {name}: {} runs with {}", ids.len(), run.options.method.name()),
            line: Some(at.line),
            status: Status::Built,
        });
        // The largest departure from the level at the start, from the stored initial states.
        let worst = ids
            .iter()
            .filter_map(|&id| self.runs[id].result.as_ref().and_then(|r| r.traj.y.first().cloned()))
            .map(|y| f(&y).map(|e| (e - level).abs()))
            .collect::<Result<Vec<f64>, _>>()?
            .into_iter()
            .fold(0.0, f64::max);
        let line = summary_line(&name, &ens, ids.len(), &kept, &skipped, worst);
        self.output.push(line);
        self.groups.push(Group {
            name: name.clone(),
            ids,
            values: kept,
            var: ens.var.text.clone(),
            level: format!("{} = {}", ens.on.text, ens.value.text),
        });
        self.run_names.remove(&name);
        Ok(())
    }

    /// The swept values `A, A + H, …` up to `B`, with `A` and `B`: a non-empty sweep of at
    /// most [`MAX_MEMBERS`] values.
    fn sweep_values(&mut self, at: At, ens: &EnsembleSpec) -> Result<(f64, f64, Vec<f64>), SceneError> {
        let (a, b, h) = (self.bound(at, &ens.from)?, self.bound(at, &ens.to)?, self.bound(at, &ens.step)?);
        if !(h > 0.0 && h.is_finite()) || b < a {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("the sweep {}..{} step {} has no values", fmt_num(a), fmt_num(b), fmt_num(h)),
            )
            .at(ens.span)
            .hint("write `for each y in 0..0.4 step 0.02`: the end after the start, a positive step"));
        }
        let count = ((b - a) / h + 1e-9).floor() + 1.0;
        if count > MAX_MEMBERS as f64 {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("{count:.0} ensemble members is more than the limit of {MAX_MEMBERS}"),
            )
            .at(ens.step.span)
            .hint("use a larger step"));
        }
        let values: Vec<f64> = (0..count as usize).map(|k| a + h * k as f64).collect();
        Ok((a, b, values))
    }

    /// The base run of an ensemble (its swept and solved variables given placeholder values)
    /// and those two variables, which the statement may not also give.
    fn ensemble_base(&mut self, spec: &SimSpec, ens: &EnsembleSpec) -> Result<(SimSpec, Symbol, Symbol), SceneError> {
        let sweep = self.state_symbol(&ens.var)?;
        let solve = self.state_symbol(&ens.solve)?;
        for (sym, _) in &spec.inits {
            let s = self.state_symbol(sym)?;
            if s == sweep || s == solve {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    format!("`{}` is set by the ensemble clause; remove its initial value", sym.text),
                )
                .at(sym.span)
                .label("given twice"));
            }
        }
        let mut base = spec.clone();
        base.ensemble = None;
        base.inits.push((ens.var.clone(), Src { text: "0".into(), span: ens.var.span }));
        base.inits.push((ens.solve.clone(), Src { text: "0".into(), span: ens.solve.span }));
        Ok((base, sweep, solve))
    }

    /// The state variable named by `src` (`y`, `y'` or `p_y`).
    fn state_symbol(&mut self, src: &Src) -> Result<Symbol, SceneError> {
        let (e, _) = self.expr(src)?;
        e.as_sym().cloned().ok_or_else(|| {
            SceneError::new(ErrorKind::Syntax, "expected a coordinate, velocity or momentum").at(src.span)
        })
    }

    /// The group whose members are exactly `ids`, if any.
    pub(in crate::scene) fn group_of(&self, ids: &[usize]) -> Option<&Group> {
        self.groups.iter().find(|g| g.ids == ids)
    }
}

/// The line an ensemble prints: its members, the swept values, the level and the largest
/// departure from it at the start, and the values skipped.
fn summary_line(name: &str, ens: &EnsembleSpec, members: usize, kept: &[f64], skipped: &[f64], worst: f64) -> String {
    let mut line = format!(
        "{name}: {} runs ({name}_1 … {name}_{}) for {} = {} … {} on {} = {} (largest |{} − {}| at the start {:.1e})",
        members,
        members,
        ens.var.text,
        fmt_num(kept[0]),
        fmt_num(kept[kept.len() - 1]),
        ens.on.text,
        ens.value.text,
        ens.on.text,
        ens.value.text,
        worst
    );
    if !skipped.is_empty() {
        line.push_str(&format!(
            "; skipped {} = {} (no point of the level set with {} {} 0)",
            ens.var.text,
            skipped.iter().map(|v| fmt_num(*v)).collect::<Vec<_>>().join(", "),
            ens.solve.text,
            if ens.positive { ">" } else { "<" }
        ));
    }
    line
}

/// Sets `y[i]` so that `f(y) = level`, searching outward from zero on the positive (or
/// negative) side: doubling until `f − level` changes sign, then bisection down to adjacent
/// floats, keeping the end with the smaller residual. `false` when no sign change is found
/// up to |y[i]| = 10⁶ (the level set has no point there). Also the level clause of a chaos
/// map ([`super::chaos`]).
pub(in crate::scene) fn solve_level(
    f: &dyn Fn(&[f64]) -> Result<f64, SceneError>,
    y: &mut [f64],
    i: usize,
    level: f64,
    positive: bool,
) -> Result<bool, SceneError> {
    let sign = if positive { 1.0 } else { -1.0 };
    // Ctrl-C is checked at every evaluation of H (each a few microseconds; the session
    // reports the statement as interrupted).
    let g = |u: f64, y: &mut [f64]| -> Result<f64, SceneError> {
        crate::cancel::check().map_err(|_| SceneError::new(ErrorKind::Interrupted, "interrupted"))?;
        y[i] = sign * u;
        Ok(f(y)? - level)
    };
    let g0 = g(0.0, y)?;
    if g0 == 0.0 {
        return Ok(true);
    }
    let (mut lo, mut hi) = (0.0, 1e-3);
    loop {
        let gh = g(hi, y)?;
        if gh.is_finite() && gh.signum() != g0.signum() {
            break;
        }
        lo = hi;
        hi *= 2.0;
        if hi > 1e6 {
            return Ok(false);
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if g(mid, y)?.signum() == g0.signum() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let (gl, gh) = (g(lo, y)?.abs(), g(hi, y)?.abs());
    y[i] = sign * if gl < gh { lo } else { hi };
    Ok(true)
}
