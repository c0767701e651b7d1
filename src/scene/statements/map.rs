//! `map`: iterates an explicit or implicit map of phase space through
//! [`crate::mechanics::PhaseMap`]
//! (the iteration is the library's; this file holds the statement's type and reader, resolves
//! it and draws the orbits).

use crate::expr::Symbol;
use crate::mechanics::PhaseMap;
use crate::plot::{Figure, Series};
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `map q = …, p = … for N steps from q = A..B, p = C [points N] [to FILE]`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Map {
    /// The assignments, in order.
    pub updates: Vec<(Src, Src)>,
    /// The number of iterations.
    pub steps: Src,
    /// The starts: a variable and a value, or a range `lo..hi`.
    pub starts: Vec<(Src, Src, Option<Src>)>,
    /// `points N`: values per range (default 10).
    pub points: Option<Src>,
    /// `to FILE`.
    pub path: Option<Src>,
}

impl Map {
    /// Reads the rule `map_stmt`: the `x = …` before `for` are the updates, those after it the
    /// starts (a range `lo..hi` is a `map_range`).
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Map, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let (mut updates, mut steps, mut starts, mut points, mut path) = (Vec::new(), None, Vec::new(), None, None);
        for q in inner {
            match q.as_rule() {
                Rule::init if steps.is_none() => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        updates.push((r.src(&s), r.src(&v)));
                    }
                }
                Rule::sexpr => steps = Some(r.src(&q)),
                Rule::init => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        starts.push((r.src(&s), r.src(&v), None));
                    }
                }
                Rule::map_range => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(range)) = (it.next(), it.next()) {
                        let mut b = range.into_inner();
                        if let (Some(lo), Some(hi)) = (b.next(), b.next()) {
                            starts.push((r.src(&s), r.src(&lo), Some(r.src(&hi))));
                        }
                    }
                }
                Rule::points => points = q.into_inner().find(|x| x.as_rule() == Rule::sexpr).map(|x| r.src(&x)),
                Rule::path => path = Some(r.path(q)),
                _ => {}
            }
        }
        let steps = steps.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected `for N steps`").at(span))?;
        Ok(Map { updates, steps, starts, points, path })
    }
}

/// The most values per range (`points`).
const MAX_POINTS: f64 = 1000.0;

impl Session {
    /// `map … for N steps from … [points N] [to FILE]`.
    pub(in crate::scene) fn map(
        &mut self,
        at: At,
        updates: &[(Src, Src)],
        steps: &Src,
        starts: &[(Src, Src, Option<Src>)],
        points: Option<&Src>,
        path: Option<&Src>,
    ) -> Result<(), SceneError> {
        // The state's variables are the names the starts give, in order.
        let names: Vec<String> = starts.iter().map(|(n, _, _)| n.text.trim().to_string()).collect();
        for (k, n) in names.iter().enumerate() {
            if names[..k].contains(n) {
                return Err(
                    SceneError::new(ErrorKind::Syntax, format!("`{n}` is given two starts")).at(starts[k].0.span)
                );
            }
        }
        // An implicit map writes its new values primed (`q' = q + h (p + p')/2`).
        let implicit = updates.iter().any(|(n, _)| n.text.contains('\''));
        // The new values `x'` resolve in both kinds, so that an explicit map using one gets the
        // library's explanation rather than "undefined symbol".
        self.local_names = names.clone();
        self.local_names.extend(names.iter().map(|n| format!("{n}'")));
        let resolved: Result<Vec<(Symbol, crate::expr::Expr)>, SceneError> = updates
            .iter()
            .map(|(n, v)| {
                let primes = n.text.trim().chars().rev().take_while(|c| *c == '\'').count();
                let base = n.text.trim().trim_end_matches('\'');
                let target = Symbol::new(base).with_primes(primes.min(255) as u8);
                if implicit && primes != 1 {
                    return Err(SceneError::new(ErrorKind::Syntax, "an implicit map writes every new value primed")
                        .at(n.span)
                        .hint(format!("write `{base}' = …` (the old value is `{base}`, the new one `{base}'`)")));
                }
                if !names.contains(&base.to_string()) {
                    return Err(SceneError::new(ErrorKind::Syntax, format!("`{base}` is assigned but has no start"))
                        .at(n.span)
                        .hint(format!("give it one after `from`: `{base} = 0`")));
                }
                Ok((target, self.resolved(at, v)?))
            })
            .collect();
        self.local_names.clear();
        let updates = resolved?;
        let n_steps = self.bound(at, steps)?;
        if !(n_steps >= 0.0 && n_steps.fract() == 0.0 && n_steps <= crate::mechanics::MAX_MAP_ITERATIONS as f64) {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("the number of steps must be a whole number 0..={}", crate::mechanics::MAX_MAP_ITERATIONS),
            )
            .at(steps.span));
        }
        let per_range = match points {
            None => 10,
            Some(src) => {
                let v = self.bound(at, src)?;
                if !(v >= 1.0 && v.fract() == 0.0 && v <= MAX_POINTS) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("`points` must be a whole number 1..={MAX_POINTS}"),
                    )
                    .at(src.span));
                }
                v as usize
            }
        };
        // The starts: the product of each variable's values.
        let mut grid: Vec<Vec<f64>> = vec![vec![]];
        for (_, lo, hi) in starts {
            let a = self.bound(at, lo)?;
            let values: Vec<f64> = match hi {
                None => vec![a],
                Some(hi) => {
                    let b = self.bound(at, hi)?;
                    if per_range == 1 {
                        vec![(a + b) / 2.0]
                    } else {
                        (0..per_range).map(|k| a + (b - a) * k as f64 / (per_range - 1) as f64).collect()
                    }
                }
            };
            grid = grid.iter().flat_map(|g| values.iter().map(move |v| [g.clone(), vec![*v]].concat())).collect();
        }
        let vars: Vec<Symbol> = names.iter().map(|n| Symbol::new(n)).collect();
        let params = self.param_values();
        let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let fail = |e: crate::mechanics::MapError| SceneError::new(ErrorKind::Numeric, e.to_string()).at(at.span);
        let run = PhaseMap::new(&vars, &updates, &params).and_then(|m| m.run(&grid, n_steps as usize)).map_err(fail)?;
        self.output.extend(run.report());
        let orbits = run.orbits;
        if path.is_some() {
            if names.len() < 2 {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    "a map's orbits are drawn in the plane of its first two variables; this map has one",
                )
                .at(at.span));
            }
            let (file, pspan, _) = self.out_file(
                at.span,
                path,
                "map.svg",
                "image",
                &["svg", "png"],
                "write `to orbits.svg` or `to orbits.png`",
            )?;
            let series: Vec<Series> = orbits
                .iter()
                .map(|o| Series {
                    label: format!("({})", o[0].iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(", ")),
                    points: o.iter().filter(|s| s[0].is_finite() && s[1].is_finite()).map(|s| (s[0], s[1])).collect(),
                })
                .collect();
            let figure =
                Figure::scatter(&format!("orbits of the map, {} steps", n_steps), &names[0], &names[1], series);
            self.figures.push((file.clone(), figure.describe()));
            let tmp = self.staging.stage(&file).map_err(|e| e.at(pspan))?;
            crate::plot::draw(&figure, &tmp).map_err(|e| {
                SceneError::new(ErrorKind::Io, format!("cannot write the plot `{}`: {e}", file.display())).at(pspan)
            })?;
            self.wrote(&file);
        }
        Ok(())
    }
}

impl Stmt for Map {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.map(at, &self.updates, &self.steps, &self.starts, self.points.as_ref(), self.path.as_ref())
    }
}
