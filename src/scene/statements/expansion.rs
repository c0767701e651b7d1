//! `series` and `jacobian`: the command line's `lagrangian series` and `lagrangian jacobian`
//! in a scene, through the same library functions and printing the same lines, so a scene and
//! the command line agree byte for byte.

use crate::expr::{Expr, Symbol};
use crate::mechanics::{self, SeriesError};
use crate::print::{render, Format};
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{once_each, Pair, Reader, Rule};

/// `series f in x, … [order N]` or `series L about q = q0, … [order N]`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Series {
    /// The expanded expression.
    pub f: Src,
    /// `in x, y`: the small quantities.
    pub small: Vec<Src>,
    /// `about q = q0, …`: the coordinates and the point.
    pub about: Vec<(Src, Src)>,
    /// `order N` (default 2, as on the command line).
    pub order: Option<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `jacobian (X1, …) in y1, …`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Jacobian {
    /// The map's components.
    pub map: Vec<Src>,
    /// The variables they depend on.
    pub vars: Vec<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

impl Series {
    /// Reads the rule `series`: the first expression is expanded, a second one is the order.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Series, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let (mut exprs, mut small, mut about, mut format) = (Vec::new(), Vec::new(), Vec::new(), None);
        for q in inner {
            match q.as_rule() {
                Rule::sexpr => exprs.push(r.src(&q)),
                Rule::series_in => small = q.into_inner().flat_map(|n| r.names(n)).collect(),
                Rule::series_about => {
                    for init in q.into_inner().filter(|i| i.as_rule() == Rule::init) {
                        let mut it = init.into_inner();
                        if let (Some(s), Some(v)) = (it.next(), it.next()) {
                            about.push((r.src(&s), r.src(&v)));
                        }
                    }
                }
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        once_each(about.iter().map(|(q, _)| q), Some("expansion point"))?;
        once_each(&small, None)?;
        let mut it = exprs.into_iter();
        let f = it.next().ok_or_else(|| SceneError::new(ErrorKind::Syntax, "malformed `series`").at(span))?;
        Ok(Series { f, small, about, order: it.next(), format })
    }
}

impl Jacobian {
    /// Reads the rule `jacobian`: the map's tuple and the variables.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Jacobian {
        let inner = r.inner(&p);
        let (mut map, mut vars, mut format) = (Vec::new(), Vec::new(), None);
        for q in inner {
            match q.as_rule() {
                Rule::geo_tuple => map = r.tuple(q),
                Rule::name_list => vars = r.names(q),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        Jacobian { map, vars, format }
    }
}

impl Session {
    /// `name` as a symbol, accepted even when nothing declared it (a small quantity `ε`).
    fn free_symbol(&mut self, at: At, src: &Src) -> Result<Symbol, SceneError> {
        self.local_names = vec![src.text.trim().to_string()];
        let e = self.resolved(at, src);
        self.local_names.clear();
        e?.as_sym().cloned().ok_or_else(|| {
            SceneError::new(ErrorKind::Syntax, format!("`{}` is not a variable", src.text.trim()))
                .at(src.span)
                .hint("name a variable: a coordinate, a parameter or a new symbol")
        })
    }

    /// `series f in x, … [order N]` or `series L about q = q0, … [order N]`.
    pub(in crate::scene) fn series(
        &mut self,
        at: At,
        f: &Src,
        small: &[Src],
        about: &[(Src, Src)],
        order: Option<&Src>,
        format: Option<Format>,
    ) -> Result<(), SceneError> {
        let small_names: Vec<String> = small.iter().map(|s| s.text.trim().to_string()).collect();
        self.local_names = small_names;
        let e = self.resolved(at, f);
        self.local_names.clear();
        let e = e?;
        let order = match order {
            None => 2,
            Some(src) => {
                let v = self.resolved(at, src)?;
                let x = self.number(&v, src.span)?;
                if x < 0.0 || x.fract() != 0.0 || x > mechanics::MAX_SERIES_ORDER as f64 {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("the order must be a whole number 0..={}", mechanics::MAX_SERIES_ORDER),
                    )
                    .at(src.span)
                    .hint("each order differentiates the whole expression once more"));
                }
                x as usize
            }
        };
        let refuse = |err: SeriesError| SceneError::new(ErrorKind::Derivation, err.to_string()).at(at.span);
        let mut lines = Vec::new();
        let result = if about.is_empty() {
            let vars: Vec<Symbol> = small.iter().map(|s| self.free_symbol(at, s)).collect::<Result<_, _>>()?;
            mechanics::series(&e, &vars, order).map_err(refuse)?
        } else {
            let mut qs = Vec::new();
            let mut point = Vec::new();
            for (q, q0) in about {
                qs.push(self.free_symbol(at, q)?);
                point.push(self.resolved(at, q0)?);
            }
            if !point.iter().all(Expr::is_zero) {
                lines.push("# each coordinate stands for its displacement from --about".to_string());
            }
            mechanics::series_about(&e, &qs, &point, order).map_err(refuse)?.0
        };
        lines.push(render(&result, format.unwrap_or(self.opts.format)));
        self.output.extend(lines);
        Ok(())
    }

    /// `jacobian (X1, …) in y1, …`: the matrix row by row, then `det = …`.
    pub(in crate::scene) fn jacobian(
        &mut self,
        at: At,
        map: &[Src],
        vars: &[Src],
        format: Option<Format>,
    ) -> Result<(), SceneError> {
        let names: Vec<String> = vars.iter().map(|s| s.text.trim().to_string()).collect();
        self.local_names = names;
        let comps: Result<Vec<Expr>, SceneError> = map.iter().map(|c| self.resolved(at, c)).collect();
        self.local_names.clear();
        let comps = comps?;
        let ys: Vec<Symbol> = vars.iter().map(|v| self.free_symbol(at, v)).collect::<Result<_, _>>()?;
        let Some((m, det)) = mechanics::jacobian(&comps, &ys) else {
            return Err(SceneError::new(
                ErrorKind::Derivation,
                format!(
                    "the map has {} component(s) but `in` names {} variable(s); a Jacobian determinant needs as many of each",
                    comps.len(),
                    ys.len()
                ),
            )
            .at(at.span));
        };
        let f = format.unwrap_or(self.opts.format);
        for row in &m {
            self.output.push(format!("[{}]", row.iter().map(|e| render(e, f)).collect::<Vec<_>>().join(", ")));
        }
        self.output.push(format!("det = {}", render(&det, f)));
        Ok(())
    }
}

impl Stmt for Series {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.series(at, &self.f, &self.small, &self.about, self.order.as_ref(), self.format)
    }
}

impl Stmt for Jacobian {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.jacobian(at, &self.map, &self.vars, self.format)
    }
}
