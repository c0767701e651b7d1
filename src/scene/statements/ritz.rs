//! The statement `ritz` (§1.4.2), which calls the same library function as `lagrangian ritz`
//! and prints the same lines ([`Ritz::report`]).

use crate::expr::Expr;
use crate::mechanics::{Ritz, System};
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::RitzSpec;
use crate::scene::syntax::error::{ErrorKind, SceneError};

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
