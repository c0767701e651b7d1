//! Poincaré sections as data: the states a `record when …` event recorded, as a run of their
//! own. `plot poincare` draws them and `export poincare` writes them, from the same points.

use std::sync::Arc;

use super::figures::members_text;
use super::simulate::state_names;
use crate::scene::engine::backend::Trajectory;
use crate::scene::state::{At, RunResult, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `export poincare [EXPR, …] [from RUN] to FILE`
#[derive(Clone, Debug)]
pub(in crate::scene) struct ExportPoincare {
    /// Expressions at the recorded points (empty: the state).
    pub items: Vec<Src>,
    /// `from RUN`.
    pub run: Option<Src>,
    /// The file.
    pub path: Src,
}

impl ExportPoincare {
    /// `export poincare …`: the section's columns, the run and the file.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<ExportPoincare, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut items = Vec::new();
        let mut run = None;
        let mut path = None;
        for q in inner {
            match q.as_rule() {
                Rule::sexpr => items.push(r.src(&q)),
                Rule::name => run = Some(r.src(&q)),
                Rule::path => path = Some(r.path(q)),
                _ => {}
            }
        }
        let path = path.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected `to FILE`").at(span))?;
        Ok(ExportPoincare { items, run, path })
    }
}

impl Session {
    /// The run's recorded event states as a trajectory (time = the crossing's time), or an
    /// error when it recorded none.
    pub(in crate::scene) fn section_of(&self, at: At, r: &RunResult) -> Result<RunResult, SceneError> {
        if r.traj.events.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "the run recorded no events for a Poincaré section")
                .at(at.span)
                .hint("add `record when … = 0` to the `simulate` statement"));
        }
        Ok(RunResult {
            traj: Arc::new(Trajectory {
                t: r.traj.events.iter().map(|e| e.t).collect(),
                y: r.traj.events.iter().map(|e| e.state.clone()).collect(),
                ..Trajectory::default()
            }),
            ..r.clone()
        })
    }

    /// `export poincare [EXPR, …] [from RUN] to FILE`: one row per recorded event, with the
    /// event's time, which event it was (numbered from 1 in the `simulate` statement), and the
    /// expressions (default: the state) at the crossing.
    pub(in crate::scene) fn export_poincare(
        &mut self,
        at: At,
        items: &[Src],
        run: Option<&Src>,
        path: &Src,
    ) -> Result<(), SceneError> {
        let (file, pspan, ext) = self.out_file(
            at.span,
            Some(path),
            "poincare",
            "export",
            &["csv", "json"],
            "export Poincaré points to `.csv` or `.json`",
        )?;
        // Every run the `from` names: all members of an ensemble, each with its own rows.
        let ids = self.run_ids(at, &run.cloned().into_iter().collect::<Vec<_>>())?;
        let mut members = Vec::new();
        let mut points = 0;
        for &id in &ids {
            let r = self.demand_run(at, id)?;
            let sub = self.section_of(at, &r)?;
            let mut columns: Vec<(String, Vec<f64>)> = vec![
                ("t".to_string(), sub.traj.t.clone()),
                ("event".to_string(), r.traj.events.iter().map(|e| (e.index + 1) as f64).collect()),
            ];
            if items.is_empty() {
                for (i, n) in state_names(&r.coords, r.layout).iter().enumerate() {
                    columns.push((n.clone(), sub.traj.y.iter().map(|y| y[i]).collect()));
                }
            } else {
                for src in items {
                    if src.text.trim() == "t" {
                        continue;
                    }
                    let e = self.resolved(at, src)?;
                    columns.push((src.text.trim().to_string(), self.along(at, &sub, &e, src.span)?));
                }
            }
            points += sub.traj.t.len();
            members.push((self.runs[id].name.clone(), r.method.name().to_string(), columns));
        }
        let text = members_text(&members, &ext);
        let tmp = self.staging.stage(&file).map_err(|e| e.at(pspan))?;
        std::fs::write(&tmp, text)
            .map_err(|e| SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", file.display())).at(pspan))?;
        let of = if ids.len() > 1 { format!(" of {} runs", ids.len()) } else { String::new() };
        self.output.push(format!("wrote {} ({points} points{of})", file.display()));
        Ok(())
    }
}

impl Stmt for ExportPoincare {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.export_poincare(at, &self.items, self.run.as_ref(), &self.path)
    }
}
