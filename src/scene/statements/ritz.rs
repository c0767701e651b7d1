//! The statement `ritz` (§1.4.2), which calls the same library function as `lagrangian ritz`
//! and prints the same lines ([`Ritz::report`]): its type, its reader, its handler.

use crate::expr::Expr;
use crate::mechanics::{Ritz, System};
use crate::print::Format;
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{once_each, Pair, Reader, Rule};

/// `ritz …`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct RitzSpec {
    /// The Lagrangian (default `L`).
    pub l: Option<Src>,
    /// Each coordinate's trial path.
    pub trials: Vec<(Src, Src)>,
    /// The name after `for` (must be `t`).
    pub time_var: Src,
    /// The end times.
    pub t0: Src,
    pub t1: Src,
    /// `from x = …`: the values at `t0`.
    pub from: Vec<(Src, Src)>,
    /// `to x = …`: the values at `t1`.
    pub to: Vec<(Src, Src)>,
    /// `solve a, b`: the unknown coefficients.
    pub unknowns: Vec<Src>,
    /// `near 0.1, 0`: Newton's starting values (default 0).
    pub guess: Vec<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

impl RitzSpec {
    /// Reads the rule `ritz`: each `x = …` goes to the trial paths, the start values or the end
    /// values by the keyword (`with`, `from`, `to`) before it.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<RitzSpec, SceneError> {
        let (span, inner) = (r.span(&p), p.into_inner().collect::<Vec<_>>());
        let (mut l, mut time_var, mut t0, mut t1, mut format) = (None, None, None, None, None);
        let (mut trials, mut from, mut to, mut unknowns, mut guess) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        // Which list an `x = …` belongs to: the keyword before it.
        let mut group = Rule::kw_with;
        for q in inner {
            match q.as_rule() {
                kw @ (Rule::kw_with | Rule::kw_from | Rule::kw_to) => group = kw,
                Rule::sexpr => l = Some(r.src(&q)),
                Rule::init => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        let pair = (r.src(&s), r.src(&v));
                        match group {
                            Rule::kw_from => from.push(pair),
                            Rule::kw_to => to.push(pair),
                            _ => trials.push(pair),
                        }
                    }
                }
                Rule::name => time_var = Some(r.src(&q)),
                Rule::time_span => {
                    let mut it = q.into_inner();
                    t0 = it.next().map(|b| r.src(&b));
                    t1 = it.next().map(|b| r.src(&b));
                }
                Rule::name_list => unknowns = r.names(q),
                Rule::ritz_near => guess = r.tuple(q),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        once_each(trials.iter().map(|(x, _)| x), Some("trial path"))?;
        once_each(from.iter().map(|(x, _)| x), Some("start value"))?;
        once_each(to.iter().map(|(x, _)| x), Some("end value"))?;
        once_each(&unknowns, None)?;
        match (time_var, t0, t1) {
            (Some(time_var), Some(t0), Some(t1)) => {
                Ok(RitzSpec { l, trials, time_var, t0, t1, from, to, unknowns, guess, format })
            }
            _ => Err(SceneError::new(ErrorKind::Syntax, "malformed `ritz`").at(span)),
        }
    }
}

impl Session {
    /// `ritz [L] with x = TRIAL for t in A..B from x = … to x = … solve a, b [near …]`: the
    /// trial-function method, as `lagrangian ritz`.
    pub(in crate::scene) fn ritz(&mut self, at: At, spec: &RitzSpec) -> Result<(), SceneError> {
        let coords = self.need_coordinates(at, "ritz")?;
        let span = at.span;
        if spec.time_var.text != "t" {
            return Err(SceneError::new(ErrorKind::Syntax, "the trial path's variable must be `t`")
                .at(spec.time_var.span)
                .hint("write `for t in 0..1`"));
        }
        let local: Vec<String> = spec.unknowns.iter().map(|u| u.text.clone()).collect();
        let l = match &spec.l {
            Some(src) => self.resolved_local(at, src, &local)?,
            None => self.lagrangian(at)?,
        };
        let mut unknowns = Vec::new();
        for u in &spec.unknowns {
            match self.resolved_local(at, u, &local)?.as_sym() {
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
                exprs.push(self.resolved_local(at, e, &local)?);
            }
            lists.push(exprs);
        }
        let t0 = self.resolved(at, &spec.t0)?;
        let t1 = self.resolved(at, &spec.t1)?;
        let derivation = |e: crate::mechanics::MechanicsError| {
            SceneError::new(ErrorKind::Derivation, e.to_string().trim_start_matches("error: ").to_string()).at(span)
        };
        let system = System::from_lagrangian_expr(l, &coords).map_err(derivation)?;
        let r: Ritz = system.ritz(&lists[0], &unknowns, (&t0, &t1), (&lists[1], &lists[2])).map_err(derivation)?;
        let guess = self.numbers(at, &spec.guess)?;
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

impl Stmt for RitzSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.ritz(at, self)
    }
}
