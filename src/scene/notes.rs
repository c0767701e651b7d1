//! Scene-side rules for first-order (phase-space) Lagrangians `L = Σ a_i(z, t) z'_i − H(z, t)`
//! (§3.4): which `L` takes that route in `simulate`, and what its initial state and events
//! may mention. The equations are `mechanics::FirstOrder`'s; the session only routes.
//! Also the `variational` simulate methods (§4.7.2): which rule each names, the compiled
//! map, and what such a run refuses; and the statements `geodesic` (§1.4.1, §1.6.3) and
//! `ritz` (§1.4.2), which call the same library functions as `lagrangian geodesic` and
//! `lagrangian ritz` and print the same lines ([`Geodesic::report`], [`Ritz::report`]).

use std::collections::HashMap;

use crate::expr::{Expr, Symbol};

use crate::mechanics::{embedded, geodesic, geodesic_from_metric, Geodesic, Ritz, System};

use super::ast::{GeodesicSpec, Geometry, RitzSpec, SimSpec, Src};
use super::error::{ErrorKind, SceneError, Span};
use super::session::Session;

/// The state of a first-order Lagrangian is `z` alone: its velocities follow from
/// `ω z' = b` and are not initial data, and there are no momenta `p_z`.
pub(super) fn check_first_order_inits(
    coords: &[Symbol],
    given: &HashMap<String, (f64, Span)>,
) -> Result<(), SceneError> {
    for q in coords {
        for name in [format!("{}'", q.name()), format!("p_{}", q.name())] {
            if let Some((_, span)) = given.get(&name) {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    format!(
                        "`L` is first order in the velocities, so its state is {} alone: `{name}` is not initial data",
                        coords.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
                    ),
                )
                .at(*span)
                .hint(format!("remove `{name} = …`; the velocities follow from ω z' = ∂H/∂z")));
            }
        }
    }
    Ok(())
}

/// Events of a first-order run are functions of `z` and `t` (the velocity slots are filled
/// only at the kept states, not inside a step).
pub(super) fn check_first_order_event(e: &Expr, span: Span) -> Result<(), SceneError> {
    if let Some(v) = e.free_symbols().into_iter().find(|s| s.primes() > 0) {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("an event of a first-order Lagrangian's run must not use the velocity `{v}`"),
        )
        .at(span)
        .hint("write the event in the phase-space variables z and t"));
    }
    Ok(())
}

/// A `variational` run needs `L` and takes no events (the map has no continuous rate to
/// locate a crossing inside a step).
pub(super) fn check_variational_run(method: &str, spec: &SimSpec, has_l: bool, span: Span) -> Result<(), SceneError> {
    if let Some(ev) = spec.events.first() {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("`{method}` steps a discrete map and cannot locate events inside a step"),
        )
        .at(ev.span)
        .hint("drop the `record`/`stop` clause, or use `gauss4` or `dop853` for the event"));
    }
    if !has_l {
        return Err(SceneError::new(
            ErrorKind::Undeclared,
            format!("`{method}` discretizes the Lagrangian, and no `L` is defined"),
        )
        .at(span)
        .hint("define `L = …` first"));
    }
    Ok(())
}

impl Session {
    /// `src` resolved with `names` accepted as free symbols (differentials, unknowns).
    fn resolved_local(&mut self, src: &Src, names: &[String]) -> Result<Expr, SceneError> {
        self.local_names = names.to_vec();
        let r = self.resolved(src);
        self.local_names.clear();
        r
    }

    fn need_coordinates(&self, what: &str) -> Result<Vec<Symbol>, SceneError> {
        if self.coords.is_empty() {
            return Err(SceneError::new(
                ErrorKind::Undeclared,
                format!("`{what}` needs coordinates, and none are declared"),
            )
            .at(self.span)
            .hint("declare them first, for example `coordinates θ, φ`"));
        }
        Ok(self.coords.clone())
    }

    fn numbers(&mut self, srcs: &[Src]) -> Result<Vec<f64>, SceneError> {
        let mut out = Vec::new();
        for src in srcs {
            let e = self.resolved(src)?;
            out.push(self.number(&e, src.span)?);
        }
        Ok(out)
    }

    /// `geodesic …`: the metric, Christoffel symbols, geodesic equations, curvature and
    /// conserved quantities of the scene's coordinates (as `lagrangian geodesic`), the
    /// tangential components of the curvature vector for an embedding, and with
    /// `from (…) to (…)` a shooting solution in unit time.
    pub(super) fn geodesic(&mut self, spec: &GeodesicSpec) -> Result<(), SceneError> {
        let coords = self.need_coordinates("geodesic")?;
        let span = self.span;
        let bad = |e: crate::mechanics::MechanicsError, at: Span| {
            SceneError::new(ErrorKind::Derivation, e.to_string().trim_start_matches("error: ").to_string()).at(at)
        };
        let (g, emb): (Geodesic, _) = match &spec.geometry {
            Geometry::LineElement(src) => {
                let diffs: Vec<String> = coords.iter().map(|q| format!("d{}", q.name())).collect();
                let ds2 = self.resolved_local(src, &diffs)?;
                (geodesic(&ds2, &coords).map_err(|e| bad(e, src.span))?, None)
            }
            Geometry::Metric(rows) => {
                let mut m = Vec::new();
                for row in rows {
                    let mut r = Vec::new();
                    for src in row {
                        r.push(self.resolved(src)?);
                    }
                    m.push(r);
                }
                (geodesic_from_metric(m, &coords).map_err(|e| bad(e, span))?, None)
            }
            Geometry::Embedding(xs) => {
                let mut x = Vec::new();
                for src in xs {
                    x.push(self.resolved(src)?);
                }
                let emb = embedded(&x, &coords).map_err(|e| bad(e, span))?;
                (emb.geodesic.clone(), Some(emb))
            }
        };
        let fmt = spec.format.unwrap_or(self.opts.format);
        let curv = g.curvature();
        let system = g.system().map_err(|e| bad(e, span))?;
        let mut lines = g.report(&curv, &system.conserved(), fmt);
        if let Some(emb) = &emb {
            lines.extend(emb.report(fmt));
        }
        if let Some((from, to)) = &spec.ends {
            for end in [from, to] {
                if end.len() != coords.len() {
                    let at = end.first().map_or(span, |s| (s.span.0, end[end.len() - 1].span.1));
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("a point has {} coordinates here, {} given", coords.len(), end.len()),
                    )
                    .at(at)
                    .hint("give one value per coordinate, in the order of `coordinates`"));
                }
            }
            let (a, b) = (self.numbers(from)?, self.numbers(to)?);
            let values = self.param_values();
            let params: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            let shot = crate::compile::shoot(&g, &a, &b, &params, 1).map_err(|e| {
                let kind = match e {
                    crate::compile::ShootError::Interrupted { .. } => ErrorKind::Interrupted,
                    _ => ErrorKind::Numeric,
                };
                let err = SceneError::new(kind, e.to_string()).at((from[0].span.0, to[to.len() - 1].span.1));
                match e {
                    crate::compile::ShootError::Budget { .. } => err.hint(
                        "the scene statement shoots within the default budget; `lagrangian geodesic … --max-steps N \
                         --time-limit S` shoots with a larger one",
                    ),
                    _ => err,
                }
            })?;
            lines.push(shot.report_line());
        }
        self.output.extend(lines);
        Ok(())
    }

    /// `ritz [L] with x = TRIAL for t in A..B from x = … to x = … solve a, b [near …]`: the
    /// trial-function method, as `lagrangian ritz`.
    pub(super) fn ritz(&mut self, spec: &RitzSpec) -> Result<(), SceneError> {
        let coords = self.need_coordinates("ritz")?;
        let span = self.span;
        if spec.time_var.text != "t" {
            return Err(SceneError::new(ErrorKind::Syntax, "the trial path's variable must be `t`")
                .at(spec.time_var.span)
                .hint("write `for t in 0..1`"));
        }
        let local: Vec<String> = spec.unknowns.iter().map(|u| u.text.clone()).collect();
        let l = match &spec.l {
            Some(src) => self.resolved_local(src, &local)?,
            None => self.lagrangian()?,
        };
        let mut unknowns = Vec::new();
        for u in &spec.unknowns {
            match self.resolved_local(u, &local)?.as_sym() {
                Some(s) if s.primes() == 0 && !s.is_time() && !coords.contains(s) => unknowns.push(s.clone()),
                _ => {
                    return Err(SceneError::new(
                        ErrorKind::Syntax,
                        format!("`{}` cannot be an unknown coefficient", u.text),
                    )
                    .at(u.span)
                    .hint("the unknowns are new names a, b, … that the trial paths contain"))
                }
            }
        }
        // One trial path and one value at each end per coordinate, taken in coordinate order.
        let mut lists: Vec<Vec<Expr>> = Vec::new();
        for (list, what) in [(&spec.trials, "trial path"), (&spec.from, "start value"), (&spec.to, "end value")] {
            for (q, _) in list.iter() {
                if !coords.iter().any(|c| c.name() == q.text) {
                    return Err(SceneError::new(
                        ErrorKind::UndefinedSymbol,
                        format!("`{}` is not a coordinate", q.text),
                    )
                    .at(q.span)
                    .hint(format!("each {what} is given for a coordinate: `{} = …`", coords[0].name())));
                }
            }
            let mut exprs = Vec::new();
            for c in &coords {
                let Some((_, e)) = list.iter().find(|(q, _)| q.text == c.name()) else {
                    return Err(SceneError::new(ErrorKind::Syntax, format!("no {what} for the coordinate `{c}`"))
                        .at(span)
                        .hint(format!("add `{c} = …` to the {what}s")));
                };
                exprs.push(self.resolved_local(e, &local)?);
            }
            lists.push(exprs);
        }
        let t0 = self.resolved(&spec.t0)?;
        let t1 = self.resolved(&spec.t1)?;
        let derivation = |e: crate::mechanics::MechanicsError| {
            SceneError::new(ErrorKind::Derivation, e.to_string().trim_start_matches("error: ").to_string()).at(span)
        };
        let system = System::from_lagrangian_expr(l, &coords).map_err(derivation)?;
        let r: Ritz = system.ritz(&lists[0], &unknowns, (&t0, &t1), (&lists[1], &lists[2])).map_err(derivation)?;
        let guess = self.numbers(&spec.guess)?;
        let values = self.param_values();
        let params: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let sol = r.solve(&guess, &params).map_err(|e| {
            SceneError::new(ErrorKind::Numeric, e.to_string().trim_start_matches("error: ").to_string()).at(span)
        })?;
        let fmt = spec.format.unwrap_or(self.opts.format);
        self.output.extend(r.report(&sol, fmt));
        Ok(())
    }
}
