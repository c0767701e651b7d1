//! The statement `geodesic` (§1.4.1, §1.6.3), which calls the same library functions as
//! `lagrangian geodesic` and prints the same lines ([`Geodesic::report`]): its type, its reader,
//! its handler.

use crate::mechanics::{embedded, geodesic, geodesic_from_metric, Geodesic};
use crate::print::Format;
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `geodesic …`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct GeodesicSpec {
    /// The line element, metric or embedding.
    pub geometry: Geometry,
    /// `from (…) to (…)`: a shooting solution between two points.
    pub ends: Option<(Vec<Src>, Vec<Src>)>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// The geometry of a `geodesic` statement.
#[derive(Clone, Debug)]
pub(in crate::scene) enum Geometry {
    /// `ds^2 = dθ^2 + sin(θ)^2 dφ^2`
    LineElement(Src),
    /// `metric (1, 0), (0, sin(θ)^2)`: the rows.
    Metric(Vec<Vec<Src>>),
    /// `embedding (X, Y, Z)`: a surface in Euclidean space.
    Embedding(Vec<Src>),
}

impl GeodesicSpec {
    /// Reads the rule `geodesic`: the geometry, then the two end tuples of `from … to …`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> GeodesicSpec {
        let inner = r.inner(&p);
        let (mut geometry, mut tuples, mut format) = (None, Vec::new(), None);
        for q in inner {
            match q.as_rule() {
                Rule::geo_line => {
                    geometry =
                        q.into_inner().find(|x| x.as_rule() == Rule::sexpr).map(|x| Geometry::LineElement(r.src(&x)))
                }
                Rule::geo_metric => {
                    let rows = q.into_inner().filter(|x| x.as_rule() == Rule::geo_tuple).map(|x| r.tuple(x));
                    geometry = Some(Geometry::Metric(rows.collect()));
                }
                Rule::geo_embedding => {
                    geometry =
                        q.into_inner().find(|x| x.as_rule() == Rule::geo_tuple).map(|x| Geometry::Embedding(r.tuple(x)))
                }
                Rule::geo_tuple => tuples.push(r.tuple(q)),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        let mut it = tuples.into_iter();
        let ends = it.next().zip(it.next());
        GeodesicSpec { geometry: geometry.unwrap_or(Geometry::Embedding(Vec::new())), ends, format }
    }
}

impl Session {
    /// `geodesic …`: the metric, Christoffel symbols, geodesic equations, curvature and
    /// conserved quantities of the scene's coordinates (as `lagrangian geodesic`), the
    /// tangential components of the curvature vector for an embedding, and with
    /// `from (…) to (…)` a shooting solution in unit time.
    pub(in crate::scene) fn geodesic(&mut self, at: At, spec: &GeodesicSpec) -> Result<(), SceneError> {
        let coords = self.need_coordinates(at, "geodesic")?;
        let span = at.span;
        let bad = |e: crate::mechanics::MechanicsError, at: Span| {
            SceneError::new(ErrorKind::Derivation, e.to_string().trim_start_matches("error: ").to_string()).at(at)
        };
        let (g, emb): (Geodesic, _) = match &spec.geometry {
            Geometry::LineElement(src) => {
                let diffs: Vec<String> = coords.iter().map(|q| format!("d{}", q.name())).collect();
                let ds2 = self.resolved_local(at, src, &diffs)?;
                (geodesic(&ds2, &coords).map_err(|e| bad(e, src.span))?, None)
            }
            Geometry::Metric(rows) => {
                let mut m = Vec::new();
                for row in rows {
                    let mut r = Vec::new();
                    for src in row {
                        r.push(self.resolved(at, src)?);
                    }
                    m.push(r);
                }
                (geodesic_from_metric(m, &coords).map_err(|e| bad(e, span))?, None)
            }
            Geometry::Embedding(xs) => {
                let mut x = Vec::new();
                for src in xs {
                    x.push(self.resolved(at, src)?);
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
            let (a, b) = (self.numbers(at, from)?, self.numbers(at, to)?);
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
}

impl Stmt for GeodesicSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.geodesic(at, self)
    }
}
