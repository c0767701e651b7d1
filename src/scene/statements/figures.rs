//! Outputs that read runs: `plot` (the figures) and `export` (CSV and JSON): the statements'
//! types, readers and handlers.

use std::path::{Component, PathBuf};

use super::simulate::state_names;
use crate::cache::Value;
use crate::expr::Symbol;
use crate::print::fmt_num;
use crate::print::Format;
use crate::scene::state::Mode;
use crate::scene::state::{At, Layout, Printed, RunResult, Session};
use crate::scene::statements::{Output, Stmt};
use crate::scene::syntax::ast::{DerivKind, Item, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `plot …`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct PlotSpec {
    /// What to draw.
    pub kind: PlotKind,
    /// `from RUN, RUN` (default: the latest run).
    pub runs: Vec<Src>,
    /// `to FILE` (default: a name derived from the scene and the plot kind).
    pub path: Option<Src>,
}

/// What a `plot` draws.
#[derive(Clone, Debug)]
pub(in crate::scene) enum PlotKind {
    /// Phase portrait of one coordinate with contours of `H`.
    Phase(Option<Src>),
    /// Relative energy error against time.
    Energy,
    /// A configuration-space path `(x, y)`.
    Path(Src, Src),
    /// The points recorded by a `record when` event.
    Poincare(Src, Src),
    /// Expressions against time.
    Series(Vec<Src>),
    /// log₁₀ of the phase-space distance between two runs against time.
    Separation(Src, Src),
    /// A chaos indicator (`lyapunov`, `megno`, `fli`) against time, from chaos statements.
    Chaos(Src),
    /// Error against work over several runs of the system, one line per method; the error
    /// is against the named reference run, else the largest relative energy error.
    WorkPrecision(Option<Src>),
}

/// `export … to FILE`
#[derive(Clone, Debug)]
pub(in crate::scene) struct Export {
    /// Columns or symbolic results (empty: the whole state).
    pub items: Vec<Item>,
    /// `from RUN`.
    pub run: Option<Src>,
    /// The file.
    pub path: Src,
}

impl PlotSpec {
    /// `plot …`: what is drawn, from which runs, to which file.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<PlotSpec, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut kind = None;
        let mut runs = Vec::new();
        let mut path = None;
        for q in inner {
            match q.as_rule() {
                Rule::plot_phase => {
                    let sym = q.into_inner().find(|s| s.as_rule() == Rule::symbol);
                    kind = Some(PlotKind::Phase(sym.map(|s| r.src(&s))));
                }
                Rule::plot_energy => kind = Some(PlotKind::Energy),
                Rule::plot_separation => {
                    let names: Vec<Src> =
                        q.into_inner().filter(|s| s.as_rule() == Rule::name).map(|s| r.src(&s)).collect();
                    if let [a, b] = &names[..] {
                        kind = Some(PlotKind::Separation(a.clone(), b.clone()));
                    }
                }
                Rule::plot_chaos => kind = q.into_inner().next().map(|k| PlotKind::Chaos(r.src(&k))),
                Rule::plot_work_precision => {
                    let reference = q.into_inner().find(|s| s.as_rule() == Rule::name);
                    kind = Some(PlotKind::WorkPrecision(reference.map(|s| r.src(&s))));
                }
                Rule::plot_path | Rule::plot_poincare => {
                    let is_path = q.as_rule() == Rule::plot_path;
                    let xs: Vec<Src> =
                        q.into_inner().filter(|s| s.as_rule() == Rule::sexpr).map(|s| r.src(&s)).collect();
                    if let [x, y] = &xs[..] {
                        kind = Some(if is_path {
                            PlotKind::Path(x.clone(), y.clone())
                        } else {
                            PlotKind::Poincare(x.clone(), y.clone())
                        });
                    }
                }
                Rule::plot_series => {
                    kind = Some(PlotKind::Series(
                        q.into_inner().filter(|s| s.as_rule() == Rule::sexpr).map(|s| r.src(&s)).collect(),
                    ));
                }
                Rule::name_list => runs = r.names(q),
                Rule::path => path = Some(r.path(q)),
                _ => {}
            }
        }
        let kind = kind.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected what to plot").at(span))?;
        Ok(PlotSpec { kind, runs, path })
    }
}

impl Export {
    /// `export …`: the items, the run and the file.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Export, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut items = Vec::new();
        let mut run = None;
        let mut path = None;
        for q in inner {
            match q.as_rule() {
                Rule::print_item => items.push(r.item(q)?),
                Rule::name => run = Some(r.src(&q)),
                Rule::path => path = Some(r.path(q)),
                _ => {}
            }
        }
        let path = path.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "expected `to FILE`").at(span))?;
        Ok(Export { items, run, path })
    }
}

/// Columns of numbers as CSV (a header of names, one row per index) or as JSON (the run, its
/// method and the named columns). Every column has the same length.
pub(in crate::scene) fn columns_text(columns: &[(String, Vec<f64>)], ext: &str, run: &str, method: &str) -> String {
    let rows = columns.first().map_or(0, |c| c.1.len());
    if ext == "csv" {
        let mut s = columns.iter().map(|c| csv_field(&c.0)).collect::<Vec<_>>().join(",");
        s.push('\n');
        for i in 0..rows {
            let row: Vec<String> = columns.iter().map(|c| format!("{:e}", c.1[i])).collect();
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    } else {
        let cols: Vec<serde_json::Value> =
            columns.iter().map(|(n, v)| serde_json::json!({ "name": n, "values": v })).collect();
        let v = serde_json::json!({ "run": run, "method": method, "columns": cols });
        let mut s = serde_json::to_string_pretty(&v).unwrap_or_default();
        s.push('\n');
        s
    }
}

/// One run's exported columns: its name, its method's name and the named columns.
pub(in crate::scene) type Member = (String, String, Vec<(String, Vec<f64>)>);

/// The columns of one run or of several (an ensemble's members): one run as
/// [`columns_text`]; several as one CSV table with the run's name in a first column `run`
/// (each member's rows in order), or JSON `{"runs": [{"run", "method", "columns"}, …]}`.
pub(in crate::scene) fn members_text(members: &[Member], ext: &str) -> String {
    if let [(run, method, columns)] = members {
        return columns_text(columns, ext, run, method);
    }
    if ext == "csv" {
        let Some((_, _, first)) = members.first() else { return String::new() };
        let mut s = std::iter::once("run".to_string())
            .chain(first.iter().map(|c| csv_field(&c.0)))
            .collect::<Vec<_>>()
            .join(",");
        s.push('\n');
        for (run, _, columns) in members {
            let rows = columns.first().map_or(0, |c| c.1.len());
            let name = csv_field(run);
            for i in 0..rows {
                let row: Vec<String> =
                    std::iter::once(name.clone()).chain(columns.iter().map(|c| format!("{:e}", c.1[i]))).collect();
                s.push_str(&row.join(","));
                s.push('\n');
            }
        }
        s
    } else {
        let runs: Vec<serde_json::Value> = members
            .iter()
            .map(|(run, method, columns)| {
                let cols: Vec<serde_json::Value> =
                    columns.iter().map(|(n, v)| serde_json::json!({ "name": n, "values": v })).collect();
                serde_json::json!({ "run": run, "method": method, "columns": cols })
            })
            .collect();
        let mut s = serde_json::to_string_pretty(&serde_json::json!({ "runs": runs })).unwrap_or_default();
        s.push('\n');
        s
    }
}

impl Session {
    // ----- outputs -------------------------------------------------------------------------

    /// Where an output goes. A relative path resolves inside the output directory and may
    /// not leave it, neither by `..` nor through a symbolic link to a directory outside; an
    /// absolute path is refused too. Both are allowed with `--allow-outside` (and in the
    /// REPL, whose user types the paths). So running a scene someone sent you writes only
    /// under the output directory.
    fn out_path(&self, stmt: Span, path: Option<&Src>, default: &str) -> Result<(PathBuf, Span), SceneError> {
        let Some(p) = path else {
            return Ok((self.opts.out_dir.join(format!("{}_{default}.svg", self.opts.stem)), stmt));
        };
        let pb = PathBuf::from(&p.text);
        let contained = self.opts.mode == Mode::Scene && !self.opts.allow_outside;
        let outside = |why: String| {
            SceneError::new(ErrorKind::Io, why)
                .at(p.span)
                .label("outside the output directory")
                .hint("write a path inside the output directory, or run with `--allow-outside`")
        };
        if pb.is_absolute() {
            if contained {
                return Err(outside(format!(
                    "`{}` is an absolute path; outputs are written inside the output directory `{}`",
                    p.text,
                    self.opts.out_dir.display()
                )));
            }
            return Ok((pb, p.span));
        }
        if !contained {
            return Ok((self.opts.out_dir.join(pb), p.span));
        }
        // Lexically: `a/../b.csv` is fine, `../b.csv` leaves.
        let mut rel = PathBuf::new();
        for c in pb.components() {
            match c {
                Component::Normal(n) => rel.push(n),
                Component::CurDir => {}
                Component::ParentDir if rel.pop() => {}
                _ => {
                    return Err(outside(format!(
                        "`{}` leaves the output directory `{}`",
                        p.text,
                        self.opts.out_dir.display()
                    )))
                }
            }
        }
        let full = self.opts.out_dir.join(&rel);
        // Through links: the directory the file lands in must resolve inside the output
        // directory. (A missing directory is reported when the file is written; a link in
        // the file's own place is replaced by the rename, not written through.)
        if let (Some(parent), Ok(root)) = (full.parent(), self.opts.out_dir.canonicalize()) {
            if let Ok(real) = parent.canonicalize() {
                if !real.starts_with(&root) {
                    return Err(outside(format!(
                        "`{}` leads through a symbolic link to `{}`, outside the output directory `{}`",
                        p.text,
                        real.display(),
                        self.opts.out_dir.display()
                    )));
                }
            }
        }
        Ok((full, p.span))
    }

    /// The output file of a plot or an export, its span (the statement's, `stmt`, when the
    /// file is the default one) and its lower-case extension, which must be one of `formats` (otherwise an error naming the file, with `hint`).
    pub(in crate::scene) fn out_file(
        &self,
        stmt: Span,
        path: Option<&Src>,
        default: &str,
        what: &str,
        formats: &[&str],
        hint: &str,
    ) -> Result<(PathBuf, Span, String), SceneError> {
        let (file, span) = self.out_path(stmt, path, default)?;
        let ext = file.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        if !formats.contains(&ext.as_str()) {
            return Err(SceneError::new(
                ErrorKind::Io,
                format!("cannot tell the {what} format of `{}`", file.display()),
            )
            .at(span)
            .hint(hint));
        }
        Ok((file, span, ext))
    }

    pub(in crate::scene) fn plot(&mut self, at: At, spec: &PlotSpec) -> Result<(), SceneError> {
        let (path, pspan, _) = self.out_file(
            at.span,
            spec.path.as_ref(),
            plot_default(&spec.kind),
            "image",
            &["svg", "png"],
            PLOT_FORMATS,
        )?;
        let figure = self.figure(at, spec)?;
        self.figures.push((path.clone(), figure.describe()));
        let tmp = self.staging.stage(&path).map_err(|e| e.at(pspan))?;
        crate::plot::draw(&figure, &tmp).map_err(|e| {
            SceneError::new(ErrorKind::Io, format!("cannot write the plot `{}`: {e}", path.display())).at(pspan)
        })?;
        self.wrote(&path);
        Ok(())
    }

    /// Refuses values of `what` along a run that are not finite at any stored state (a
    /// figure of nothing, which exports refuse too), and notes how many are not drawn when
    /// only some are not finite. `times` are the stored states' times.
    pub(in crate::scene) fn drawable(
        &mut self,
        values: &[f64],
        what: &str,
        run: &str,
        times: &[f64],
        span: Span,
    ) -> Result<(), SceneError> {
        let bad = values.iter().filter(|v| !v.is_finite()).count();
        if bad == 0 {
            return Ok(());
        }
        let what = what.trim();
        if bad == values.len() {
            return Err(SceneError::new(
                ErrorKind::Numeric,
                format!(
                    "`{what}` is not finite at any of the {} stored states of {run} (the first is {}): there is nothing to draw",
                    values.len(),
                    values[0]
                ),
            )
            .at(span)
            .hint("the expression leaves its domain (a square root or logarithm of a negative number, a division by zero) or overflows f64 all along the run; draw another expression, or change the run"));
        }
        let first = values.iter().position(|v| !v.is_finite()).unwrap_or(0);
        self.output.push(format!(
            "note: `{what}` is not finite at {bad} of the {} stored states of {run} (the first at t = {}); those points are not drawn",
            values.len(),
            times.get(first).map_or_else(|| "?".to_string(), |t| format!("{t}"))
        ));
        Ok(())
    }

    /// Announces an output file. The line is withdrawn if the file is not moved into place
    /// (a later statement of the scene fails), so "wrote" is never printed for a file that
    /// does not exist.
    pub(in crate::scene) fn wrote(&mut self, path: &std::path::Path) {
        self.output.push(format!("wrote {}", path.display()));
        self.staging.announced(self.output.len() - 1);
    }

    pub(in crate::scene) fn figure(&mut self, at: At, spec: &PlotSpec) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Figure, Series};
        match &spec.kind {
            PlotKind::Series(exprs) => {
                let ids = self.run_ids(at, &spec.runs)?;
                let labels: Vec<String> = exprs.iter().map(|s| self.unicode(s)).collect();
                let mut series = Vec::new();
                for &id in &ids {
                    let r = self.demand_run(at, id)?;
                    for (src, label) in exprs.iter().zip(&labels) {
                        let e = self.resolved(at, src)?;
                        let ys = self.along(at, &r, &e, src.span)?;
                        let run = self.runs[id].name.clone();
                        self.drawable(&ys, &src.text, &run, &r.traj.t, src.span)?;
                        let label =
                            if ids.len() > 1 { format!("{label}, {}", self.runs[id].name) } else { label.clone() };
                        series.push(Series { label, points: r.traj.t.iter().copied().zip(ys).collect() });
                    }
                }
                // `θ₂(t)` for a symbol, `(l₁ sin(θ₁))(t)` for a longer expression.
                let of_t: Vec<String> = exprs
                    .iter()
                    .zip(&labels)
                    .map(|(src, l)| {
                        if src.text.trim().chars().all(|c| c.is_alphanumeric() || c == '_' || c == '\'') {
                            format!("{l}(t)")
                        } else {
                            format!("({l})(t)")
                        }
                    })
                    .collect();
                let title = format!("{}, {}", of_t.join(", "), self.runs_phrase(&ids));
                Ok(Figure::lines(&title, "t", &labels.join(", "), series))
            }
            PlotKind::Path(x, y) | PlotKind::Poincare(x, y) => {
                let poincare = matches!(spec.kind, PlotKind::Poincare(..));
                let ids = self.run_ids(at, &spec.runs)?;
                let group = self.group_of(&ids).cloned();
                let mut series = Vec::new();
                for (k, &id) in ids.iter().enumerate() {
                    let r = self.demand_run(at, id)?;
                    let ex = self.resolved(at, x)?;
                    let ey = self.resolved(at, y)?;
                    let run = self.runs[id].name.clone();
                    let pts = if poincare {
                        let sub = self.section_of(at, &r)?;
                        let xs = self.along(at, &sub, &ex, x.span)?;
                        let ys = self.along(at, &sub, &ey, y.span)?;
                        self.drawable(&xs, &x.text, &run, &sub.traj.t, x.span)?;
                        self.drawable(&ys, &y.text, &run, &sub.traj.t, y.span)?;
                        xs.into_iter().zip(ys).collect()
                    } else {
                        let xs = self.along(at, &r, &ex, x.span)?;
                        let ys = self.along(at, &r, &ey, y.span)?;
                        self.drawable(&xs, &x.text, &run, &r.traj.t, x.span)?;
                        self.drawable(&ys, &y.text, &run, &r.traj.t, y.span)?;
                        xs.into_iter().zip(ys).collect()
                    };
                    let label = match &group {
                        Some(g) => format!("{} = {}", g.var, fmt_num(g.values[k])),
                        None => self.runs[id].name.clone(),
                    };
                    series.push(Series { label, points: pts });
                }
                let (xl, yl) = (self.unicode(x), self.unicode(y));
                let runs = self.runs_phrase(&ids);
                Ok(if poincare {
                    let at = self.section_phrase(ids[0]);
                    Figure::scatter(&format!("Poincaré section{at}, {runs}"), &xl, &yl, series)
                } else {
                    Figure::path(&format!("path ({xl}, {yl}), {runs}"), &xl, &yl, series)
                })
            }
            PlotKind::Energy => {
                let ids = self.run_ids(at, &spec.runs)?;
                let mut series = Vec::new();
                for &id in &ids {
                    let r = self.demand_run(at, id)?;
                    let errors = self.energy_errors(at, &r)?;
                    let run = self.runs[id].name.clone();
                    self.drawable(&errors, "|ΔE/E₀|", &run, &r.traj.t, at.span)?;
                    let pts = r.traj.t.iter().copied().zip(errors).collect();
                    series.push(Series { label: format!("{} ({})", self.runs[id].name, r.method.name()), points: pts });
                }
                let title = format!("relative energy error |ΔE/E₀|, {}", self.runs_phrase(&ids));
                Ok(Figure::log_y(&title, "t", "|ΔE/E₀|", series))
            }
            PlotKind::Separation(a, b) => self.separation(at, a, b),
            PlotKind::Phase(coord) => self.phase_figure(at, coord.as_ref(), &spec.runs),
            PlotKind::WorkPrecision(reference) => self.work_precision(at, reference.as_ref(), &spec.runs),
            PlotKind::Chaos(word) => self.chaos_figure(word, &spec.runs),
        }
    }

    /// The relative energy error `|E(t) − E(0)|/|E(0)|` along a run (absolute when
    /// `E(0) = 0`).
    fn energy_errors(&mut self, at: At, r: &RunResult) -> Result<Vec<f64>, SceneError> {
        let e = self.energy_of_run(at, r)?;
        let es = self.along(at, r, &e, at.span)?;
        let e0 = es.first().copied().unwrap_or(0.0);
        let scale = if e0.abs() > 0.0 { e0.abs() } else { 1.0 };
        Ok(es.iter().map(|e| ((e - e0) / scale).abs()).collect())
    }

    /// The work-precision diagram: for each run, its right-hand-side evaluations (counted,
    /// so the figure is deterministic) against its error, one line per method through its
    /// runs in order of work. The error is the largest distance of the final coordinates from
    /// those of the reference run, or without one the largest relative energy error along
    /// the run. Without `from`, every run but the reference is drawn.
    pub(in crate::scene) fn work_precision(
        &mut self,
        at: At,
        reference: Option<&Src>,
        runs: &[Src],
    ) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Figure, Series};
        let reference = match reference {
            Some(r) => Some(self.run_ids(at, std::slice::from_ref(r))?[0]),
            None => None,
        };
        let ids: Vec<usize> = if runs.is_empty() {
            (0..self.runs.len()).filter(|id| Some(*id) != reference).collect()
        } else {
            self.run_ids(at, runs)?
        };
        if ids.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "a work-precision diagram needs simulations")
                .at(at.span)
                .hint("simulate the system with several methods and steps, then `plot work_precision from a, b, c`"));
        }
        let exact = match reference {
            Some(id) => Some((self.runs[id].name.clone(), self.demand_run(at, id)?)),
            None => None,
        };
        let mut by_method: Vec<(&'static str, Vec<(f64, f64)>)> = Vec::new();
        for id in ids {
            let r = self.demand_run(at, id)?;
            let name = self.runs[id].name.clone();
            let error = match &exact {
                Some((ref_name, x)) => final_distance(&r, x, &name, ref_name).map_err(|m| {
                    SceneError::new(ErrorKind::BadNumber, m)
                        .at(at.span)
                        .hint("compare runs over the same time span that reach its end")
                })?,
                None => self.energy_errors(at, &r)?.into_iter().fold(0.0, f64::max),
            };
            let point = (r.traj.evaluations as f64, error);
            match by_method.iter_mut().find(|(m, _)| *m == r.method.name()) {
                Some((_, pts)) => pts.push(point),
                None => by_method.push((r.method.name(), vec![point])),
            }
        }
        let series = by_method
            .into_iter()
            .map(|(method, mut points)| {
                points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
                Series { label: method.to_string(), points }
            })
            .collect();
        let ylabel = match &exact {
            Some((name, _)) => format!("max |q(T) − q_{name}(T)|"),
            None => "max |ΔE/E₀|".to_string(),
        };
        let title = match &exact {
            Some((name, _)) => format!("work-precision diagram against run {name}"),
            None => "work-precision diagram".to_string(),
        };
        Ok(Figure::log_log(&title, "right-hand-side evaluations", &ylabel, series))
    }

    /// An expression as written, in Unicode (`θ2` → `θ₂`, `θ'` → `θ̇`); the text itself when
    /// it does not parse on its own.
    pub(in crate::scene) fn unicode(&mut self, src: &Src) -> String {
        let text = match self.expr(src) {
            Ok((e, _)) => crate::print::render(&e, Format::Unicode),
            Err(_) => src.text.trim().to_string(),
        };
        subscript_indices(&text)
    }

    /// `run a`, `runs a, b`, or `21 runs of sea on H = 1/8` for an ensemble.
    pub(in crate::scene) fn runs_phrase(&self, ids: &[usize]) -> String {
        if let Some(g) = self.group_of(ids) {
            return format!("{} runs of {} on {}", ids.len(), g.name, g.level);
        }
        let names: Vec<&str> = ids.iter().map(|i| self.runs[*i].name.as_str()).collect();
        match names.len() {
            1 => format!("run {}", names[0]),
            _ => format!("runs {}", names.join(", ")),
        }
    }

    /// ` at x = 0 (rising)`: the first `record when` event of a run.
    fn section_phrase(&mut self, id: usize) -> String {
        let Some(ev) = self.runs[id].spec.events.iter().find(|e| !e.terminal).cloned() else {
            return String::new();
        };
        let lhs = self.unicode(&ev.lhs);
        let rhs = ev.rhs.as_ref().map_or("0".to_string(), |r| self.unicode(r));
        let dir = match ev.rising {
            Some(true) => " (rising)",
            Some(false) => " (falling)",
            None => "",
        };
        format!(" at {lhs} = {rhs}{dir}")
    }

    /// `plot separation a, b`: log₁₀ of the Euclidean distance between the two runs' states
    /// against t, and a least-squares line through it up to where it first comes within a
    /// decade of its largest value (where the growth saturates). Its slope times ln 10 is a
    /// finite-time Lyapunov estimate, printed. The runs must share their stored times (two
    /// fixed-step runs with the same step and span), since interpolating one of them would
    /// add an error larger than the early separation.
    fn separation(&mut self, at: At, a: &Src, b: &Src) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Figure, Series};
        let ids = self.run_ids(at, &[a.clone(), b.clone()])?;
        let (ra, rb) = (self.demand_run(at, ids[0])?, self.demand_run(at, ids[1])?);
        let same_times = ra.traj.t.len() == rb.traj.t.len()
            && ra.traj.t.iter().zip(&rb.traj.t).all(|(x, y)| (x - y).abs() <= 1e-12 * x.abs().max(1.0));
        if ra.layout != rb.layout || ra.coords != rb.coords || !same_times {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("`{}` and `{}` do not share their states' times and variables", a.text, b.text),
            )
            .at((a.span.0, b.span.1))
            .hint("simulate both with the same fixed-step method, step and time span (for example `with gauss6 dt = 0.004`)"));
        }
        let pts: Vec<(f64, f64)> = ra
            .traj
            .t
            .iter()
            .zip(ra.traj.y.iter().zip(&rb.traj.y))
            .map(|(t, (ya, yb))| {
                let d = ya.iter().zip(yb).map(|(u, v)| (u - v) * (u - v)).sum::<f64>().sqrt();
                (*t, d.log10())
            })
            .filter(|(_, l)| l.is_finite())
            .collect();
        let mut series = vec![Series { label: "log₁₀ |Δz|".to_string(), points: pts.clone() }];
        if let Some((slope, intercept, t_end)) = growth_fit(&pts) {
            let t0 = pts[0].0;
            let lambda = slope * std::f64::consts::LN_10;
            self.output.push(format!(
                "separation of {} and {}: log₁₀ |Δz| grows by {} per unit time over t = {}..{}; finite-time Lyapunov estimate λ ≈ {}",
                a.text,
                b.text,
                fmt_sig(slope),
                fmt_num(t0),
                fmt_num(t_end),
                fmt_sig(lambda)
            ));
            series.push(Series {
                label: format!("fit: slope {}, λ ≈ {}", fmt_sig(slope), fmt_sig(lambda)),
                points: vec![(t0, intercept + slope * t0), (t_end, intercept + slope * t_end)],
            });
        }
        let title = format!("phase-space separation of runs {} and {}", a.text, b.text);
        Ok(Figure::lines(&title, "t", "log₁₀ |Δz|", series))
    }

    pub(in crate::scene) fn phase_figure(
        &mut self,
        at: At,
        coord: Option<&Src>,
        runs: &[Src],
    ) -> Result<crate::plot::Figure, SceneError> {
        use crate::plot::{Contours, Figure, Series};
        let index = match coord {
            None => 0,
            Some(c) => self.coords.iter().position(|q| q.name() == c.text).ok_or_else(|| {
                SceneError::new(ErrorKind::UndefinedSymbol, format!("`{}` is not a coordinate", c.text)).at(c.span)
            })?,
        };
        let Some(q) = self.coords.get(index).cloned() else {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared").at(at.span));
        };
        let one_dof = self.coords.len() == 1;
        let mut orbits = Vec::new();
        let mut layout = Layout::Momenta;
        let has_runs = !self.runs.is_empty();
        if has_runs {
            // Without `from`, every run is drawn (those in the latest run's variables: a
            // portrait in (q, q') cannot hold a run in (q, p)).
            let ids = if runs.is_empty() { (0..self.runs.len()).collect() } else { self.run_ids(at, runs)? };
            let mut results = Vec::new();
            for id in ids {
                results.push((id, self.demand_run(at, id)?));
            }
            layout = results.last().map_or(Layout::Momenta, |(_, r)| r.layout);
            let mut skipped = Vec::new();
            for (id, r) in results {
                if r.layout != layout {
                    skipped.push(self.runs[id].name.clone());
                    continue;
                }
                let n = r.coords.len();
                let pts = r.traj.y.iter().map(|y| (y[index], y[n + index])).collect();
                orbits.push(Series { label: self.runs[id].name.clone(), points: pts });
            }
            if !skipped.is_empty() {
                self.output.push(format!(
                    "note: the phase portrait leaves out {} (integrated in the other phase-space variables); name the runs with `from`",
                    skipped.join(", ")
                ));
            }
        }
        let vname = match layout {
            Layout::Momenta => format!("p_{}", q.name()),
            Layout::Velocities => format!("{}'", q.name()),
        };
        // Contours of the energy-like function, for one degree of freedom.
        let mut contours = None;
        if one_dof {
            let f = match layout {
                Layout::Momenta => self.hamiltonian(at)?,
                Layout::Velocities => {
                    let l = self.lagrangian(at)?;
                    match self.derive(at, DerivKind::Energy, vec![l], at.span)? {
                        Value::Expr(e) => e,
                        _ => return Err(SceneError::new(ErrorKind::Derivation, "no energy function").at(at.span)),
                    }
                }
            };
            let params = self.param_values();
            let qs = q.name().to_string();
            let f_num = move |x: f64, v: f64| -> f64 {
                crate::eval::eval_with(&f, &|s: &Symbol| {
                    if s.name() == qs && s.primes() == 0 {
                        Some(x)
                    } else if s.to_string() == vname {
                        Some(v)
                    } else if s.is_time() {
                        Some(0.0)
                    } else {
                        params.get(s.name()).copied()
                    }
                })
                .unwrap_or(f64::NAN)
            };
            if f_num(0.0, 0.0).is_nan() && f_num(0.5, 0.5).is_nan() {
                let missing = self.params.iter().find(|(_, p)| p.value.is_none()).map(|(n, _)| n.clone());
                return Err(SceneError::new(
                    ErrorKind::MissingValue,
                    "the phase portrait needs numbers for every parameter",
                )
                .at(at.span)
                .hint(match missing {
                    Some(m) => format!("declare `{m}` with a value before `plot`: `parameters {m} = …`"),
                    None => "give every parameter a value".to_string(),
                }));
            }
            contours = Some(Contours::new(Box::new(f_num)));
        } else if orbits.is_empty() {
            return Err(SceneError::new(
                ErrorKind::Undeclared,
                "a phase portrait of a system with several coordinates needs a simulation",
            )
            .at(at.span)
            .hint("add a `simulate …` statement before `plot phase`"));
        }
        let qs = crate::print::symbol(&q, Format::Unicode);
        let vlabel = match layout {
            Layout::Momenta => crate::print::symbol(&Symbol::new(&format!("p_{}", q.name())), Format::Unicode),
            Layout::Velocities => crate::print::symbol(&q.prime(), Format::Unicode),
        };
        Ok(Figure::phase(&format!("phase portrait of {qs}"), &qs, &vlabel, orbits, contours))
    }

    pub(in crate::scene) fn export(
        &mut self,
        at: At,
        items: &[Item],
        run: Option<&Src>,
        path: &Src,
    ) -> Result<(), SceneError> {
        let (file, pspan, ext) =
            self.out_file(at.span, Some(path), "export", "export", &["csv", "json"], EXPORT_FORMATS)?;
        let symbolic = items.iter().any(|i| matches!(i, Item::Derivation(_)));
        let text = if symbolic {
            if ext == "csv" {
                return Err(SceneError::new(ErrorKind::Io, "derived equations export to `.json`, not `.csv`").at(pspan));
            }
            let mut entries = Vec::new();
            for item in items {
                let label = match item {
                    Item::Derivation(c) => c.kind.keyword().to_string(),
                    Item::Expr(s) => s.text.clone(),
                };
                let value = match self.printed_item(at, item)? {
                    Printed::Named(_, e) | Printed::Value(e) => serde_json::json!(crate::print::plain(&e)),
                    Printed::Lines(lines) => crate::report::lines_json(&lines),
                };
                entries.push(serde_json::json!({ "name": label, "value": value }));
            }
            let mut s = serde_json::to_string_pretty(&serde_json::Value::Array(entries)).unwrap_or_default();
            s.push('\n');
            s
        } else {
            // Every run the `from` names: all members of an ensemble (the docs say so; only
            // the first used to be written, with no note).
            let ids = self.run_ids(at, &run.cloned().into_iter().collect::<Vec<_>>())?;
            let mut members = Vec::new();
            for &id in &ids {
                let r = self.demand_run(at, id)?;
                let mut columns: Vec<(String, Vec<f64>)> = vec![("t".to_string(), r.traj.t.clone())];
                if items.is_empty() {
                    let names = state_names(&r.coords, r.layout);
                    for (i, n) in names.iter().enumerate() {
                        columns.push((n.clone(), r.traj.y.iter().map(|y| y[i]).collect()));
                    }
                } else {
                    for item in items {
                        if let Item::Expr(src) = item {
                            if src.text.trim() == "t" {
                                continue;
                            }
                            let e = self.resolved(at, src)?;
                            columns.push((src.text.trim().to_string(), self.along(at, &r, &e, src.span)?));
                        }
                    }
                }
                let name = self.runs[id].name.clone();
                self.check_exported(&columns, &r.traj.t, &file, &ext, &name, ids.len() > 1, pspan)?;
                members.push((name, r.method.name().to_string(), columns));
            }
            members_text(&members, &ext)
        };
        let tmp = self.staging.stage(&file).map_err(|e| e.at(pspan))?;
        std::fs::write(&tmp, text)
            .map_err(|e| SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", file.display())).at(pspan))?;
        self.wrote(&file);
        Ok(())
    }

    /// Refuses inf and NaN in exported columns (they would land in the file silently, NaN as
    /// `null` in JSON), naming the column, the row and the time (and the member of an
    /// ensemble), unless `allow nonfinite` asked to keep them in a CSV (JSON has no spelling
    /// for them).
    #[allow(clippy::too_many_arguments)]
    fn check_exported(
        &mut self,
        columns: &[(String, Vec<f64>)],
        times: &[f64],
        file: &std::path::Path,
        ext: &str,
        run: &str,
        several: bool,
        pspan: Span,
    ) -> Result<(), SceneError> {
        let of_run = if several { format!(" of {run}") } else { String::new() };
        for (name, values) in columns {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                if self.allow_nonfinite && ext == "csv" {
                    let count: usize = columns.iter().map(|c| c.1.iter().filter(|v| !v.is_finite()).count()).sum();
                    self.output.push(format!(
                        "note: {} keeps {count} non-finite value{}{of_run} (`allow nonfinite`); the first is column `{name}` at row {}",
                        file.display(),
                        if count == 1 { "" } else { "s" },
                        i + 1
                    ));
                    break;
                }
                return Err(SceneError::new(
                    ErrorKind::Numeric,
                    format!(
                        "column `{name}`{of_run} is {} at t = {} (row {}): exported numbers must be finite",
                        values[i],
                        times.get(i).copied().unwrap_or(f64::NAN),
                        i + 1
                    ),
                )
                .at(pspan)
                .hint(if self.allow_nonfinite {
                    "JSON has no spelling for inf or NaN: export to `.csv` to keep them".to_string()
                } else {
                    "the value overflows f64 or leaves the domain of its expression; change the initial state, the parameters or the column, or write `allow nonfinite` before the export to keep it".to_string()
                }));
            }
        }
        Ok(())
    }
}

const PLOT_FORMATS: &str = "plots are written as `.svg` or `.png`";
const EXPORT_FORMATS: &str = "export to `.csv` (numbers along a run) or `.json`";

/// The default file name part of a plot without `to FILE` (`pendulum_phase.svg`).
fn plot_default(kind: &PlotKind) -> &'static str {
    match kind {
        PlotKind::Phase(_) => "phase",
        PlotKind::Energy => "energy",
        PlotKind::Path(..) => "path",
        PlotKind::Poincare(..) => "poincare",
        PlotKind::Series(_) => "series",
        PlotKind::WorkPrecision(_) => "work_precision",
        PlotKind::Separation(..) => "separation",
        PlotKind::Chaos(_) => "chaos",
    }
}

pub(in crate::scene) fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The largest difference of the final coordinates of two runs (the coordinates are the
/// first entries of every state layout), or why they cannot be compared.
fn final_distance(r: &RunResult, reference: &RunResult, name: &str, ref_name: &str) -> Result<f64, String> {
    let (Some(&t), Some(&t_ref)) = (r.traj.t.last(), reference.traj.t.last()) else {
        return Err(format!("`{name}` or `{ref_name}` has no states"));
    };
    if (t - t_ref).abs() > 1e-9 * t_ref.abs().max(1.0) {
        return Err(format!("`{name}` ends at t = {t} but the reference `{ref_name}` at t = {t_ref}"));
    }
    let n = r.coords.len();
    let (y, y_ref) = (&r.traj.y[r.traj.y.len() - 1], &reference.traj.y[reference.traj.y.len() - 1]);
    Ok(y[..n].iter().zip(&y_ref[..n]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
}

/// Four significant digits.
fn fmt_sig(x: f64) -> String {
    format!("{}", format!("{x:.3e}").parse::<f64>().unwrap_or(x))
}

/// The least-squares line `(slope, intercept, t_end)` through `(t, log₁₀ d)` from the start
/// to the first point within one decade of the largest value; `None` with fewer than three
/// points there.
pub(in crate::scene) fn growth_fit(pts: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let top = pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let end = pts.iter().position(|p| p.1 >= top - 1.0)?;
    let window = &pts[..=end];
    if window.len() < 3 {
        return None;
    }
    let n = window.len() as f64;
    let (mt, ml) = (window.iter().map(|p| p.0).sum::<f64>() / n, window.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = window.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum();
    let sxy: f64 = window.iter().map(|p| (p.0 - mt) * (p.1 - ml)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some((slope, ml - slope * mt, window[end].0))
}

/// Digits that end a name become subscripts (`θ2` → `θ₂`, `θ̇1` → `θ̇₁`, `p_θ2` → `p_θ₂`);
/// numbers standing alone (`0.5`, `2 y`) are left as they are.
pub(in crate::scene) fn subscript_indices(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut in_name = false;
    for c in s.chars() {
        if c.is_ascii_digit() && in_name {
            out.push_str(&crate::print::subscript(&c.to_string()));
            continue;
        }
        // A name continues through letters, `_`, combining marks (the dots of θ̇) and its
        // subscript digits.
        in_name = c.is_alphabetic() || c == '_' || ('\u{300}'..='\u{36f}').contains(&c);
        out.push(c);
    }
    out
}

impl Stmt for PlotSpec {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.plot(at, self)
    }

    fn output(&self) -> Option<Output<'_>> {
        let default = plot_default(&self.kind);
        Some(Output { path: self.path.as_ref(), default, what: "image", formats: &["svg", "png"], hint: PLOT_FORMATS })
    }
}

impl Stmt for Export {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.export(at, &self.items, self.run.as_ref(), &self.path)
    }

    fn output(&self) -> Option<Output<'_>> {
        Some(Output {
            path: Some(&self.path),
            default: "export",
            what: "export",
            formats: &["csv", "json"],
            hint: EXPORT_FORMATS,
        })
    }
}
