//! The scene statements that mirror derivations of the command line: `transform … with x = …`
//! (a point transformation), `lie`, `integral`, `action` and `average … small σ`.
//!
//! Each calls the same library function as the matching command and prints the same lines
//! (the text comes from [`crate::canonical::report`] or the same `name = value` shape), so a
//! scene and `lagrangian pb|lie|integral|action|average|transform` agree line for line in the
//! same format (tested in `tests/it/scene/parity.rs`). These are quick symbolic steps or a
//! quadrature, so they go straight to the library instead of through the cached, counted
//! [`crate::scene::engine::backend::Backend`] stages that simulations need.

use crate::canonical::{self, PhaseSpace, Trial};
use crate::expr::{Expr, Symbol};
use crate::print::{render, Format};

use crate::plot::{Figure, Series};
use crate::scene::state::{At, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::Src;
use crate::scene::syntax::error::{ErrorKind, SceneError};
use crate::scene::syntax::parser::{once_each, Pair, Reader, Rule};

/// `average [L] with x = … phase θ frequency ω amplitudes A, B`
#[derive(Clone, Debug)]
pub(in crate::scene) struct Average {
    /// The Lagrangian (default `L`).
    pub l: Option<Src>,
    /// Trial functions: coordinate and its value as a function of the phase.
    pub trials: Vec<(Src, Src)>,
    /// The phase.
    pub phase: Src,
    /// The frequency `ω = θ'`.
    pub frequency: Src,
    /// The amplitudes.
    pub amplitudes: Vec<Src>,
    /// `small σ unperturbed ω0 [principal A]`: solve to first order in `σ`.
    pub small: Option<SmallSpec>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `transform [H] with F1 = … new Q, P`
#[derive(Clone, Debug)]
pub(in crate::scene) struct Transform {
    /// The Hamiltonian (default `H`, or `legendre(L)`).
    pub h: Option<Src>,
    /// `F1` … `F4`.
    pub kind: String,
    /// The generating function.
    pub f: Src,
    /// New coordinates then new momenta.
    pub new: Vec<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `transform [L] with x = r cos(φ), … [to r, φ]`: a point transformation.
#[derive(Clone, Debug)]
pub(in crate::scene) struct PointTransform {
    /// The Lagrangian (default `L`).
    pub l: Option<Src>,
    /// Old coordinate and its value in the new coordinates.
    pub map: Vec<(Src, Src)>,
    /// The new coordinates (empty: the map's new symbols, in order).
    pub to: Vec<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `lie f with G [order N] [in ε]` or `lie f flow [H] [order N]`.
#[derive(Clone, Debug)]
#[doc(hidden)]
pub struct Lie {
    /// The function transformed.
    pub f: Src,
    /// `with G` (a Lie series in `ε`) or `flow [H]` (the flow of H in `t`).
    pub generator: LieGenerator,
    /// `order N` (default 3, as on the command line).
    pub order: Option<Src>,
    /// `in ε` (default `ε`).
    pub epsilon: Option<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `integral f [with H]`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Integral {
    /// The candidate.
    pub f: Src,
    /// The Hamiltonian (default the session's).
    pub h: Option<Src>,
    /// `as latex`.
    pub format: Option<Format>,
}

/// `action [H] at E = … [near q0]`.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Action {
    /// The Hamiltonian (default the session's).
    pub h: Option<Src>,
    /// The energies.
    pub energies: Vec<Src>,
    /// A coordinate value inside the well (default 0).
    pub near: Option<Src>,
}

/// `small σ unperturbed ω0 [principal A] [order N]` of an `average` statement.
#[derive(Clone, Debug)]
pub(in crate::scene) struct SmallSpec {
    /// The small parameter.
    pub small: Src,
    /// The frequency at zeroth order.
    pub unperturbed: Src,
    /// The amplitude left free (default: the first).
    pub principal: Option<Src>,
    /// The order of the series in the small parameter (default 1).
    pub order: Option<Src>,
    /// `for A in a..b [points N] [to FILE]`: the relations solved numerically along `A`.
    pub sweep: Option<Box<AverageSweep>>,
}

/// `for A in a..b [points N] [to FILE]` of an `average … small` statement.
#[derive(Clone, Debug)]
pub(in crate::scene) struct AverageSweep {
    /// The principal amplitude swept.
    pub amplitude: Src,
    /// The first and last amplitude.
    pub from: Src,
    /// The last amplitude.
    pub to: Src,
    /// How many amplitudes (default 20).
    pub points: Option<Src>,
    /// The figure or table written.
    pub path: Option<Src>,
}

/// The generator of a `lie` statement.
#[derive(Clone, Debug)]
#[doc(hidden)]
pub enum LieGenerator {
    /// `with G`.
    With(Src),
    /// `flow [H]`.
    Flow(Option<Src>),
}

impl Average {
    /// `average …`: `L`, the trial solution, its phase, frequency and amplitudes, and `small`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Average, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut l = None;
        let mut trials = Vec::new();
        let mut names = Vec::new();
        let mut amplitudes = Vec::new();
        let mut small = None;
        let mut format = None;
        for q in inner {
            match q.as_rule() {
                Rule::sexpr => l = Some(r.src(&q)),
                Rule::init => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        trials.push((r.src(&s), r.src(&v)));
                    }
                }
                Rule::name => names.push(r.src(&q)),
                Rule::name_list => amplitudes = r.names(q),
                Rule::average_small => small = Some(SmallSpec::read(r, q)),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        once_each(trials.iter().map(|(x, _)| x), Some("trial function"))?;
        once_each(&amplitudes, None)?;
        let mut it = names.into_iter();
        Ok(match (it.next(), it.next()) {
            (Some(phase), Some(frequency)) => Average { l, trials, phase, frequency, amplitudes, small, format },
            _ => return Err(SceneError::new(ErrorKind::Syntax, "malformed `average`").at(span)),
        })
    }
}

impl Transform {
    /// `transform … with F1 = …`: `H`, the generating function's kind and expression, the new names.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Transform, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut exprs = Vec::new();
        let mut kind = String::new();
        let mut new = Vec::new();
        let mut format = None;
        for q in inner {
            match q.as_rule() {
                Rule::sexpr => exprs.push(r.src(&q)),
                Rule::gen_kind => kind = q.as_str().to_string(),
                Rule::name_list => new = r.names(q),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        let f = exprs.pop().ok_or_else(|| SceneError::new(ErrorKind::Syntax, "malformed `transform`").at(span))?;
        Ok(Transform { h: exprs.pop(), kind, f, new, format })
    }
}

impl PointTransform {
    /// Reads the statement's pair.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> PointTransform {
        let inner = r.inner(&p);
        let (mut l, mut map, mut to, mut format) = (None, Vec::new(), Vec::new(), None);
        for q in inner {
            match q.as_rule() {
                Rule::sexpr => l = Some(r.src(&q)),
                Rule::init => {
                    let mut it = q.into_inner();
                    if let (Some(s), Some(v)) = (it.next(), it.next()) {
                        map.push((r.src(&s), r.src(&v)));
                    }
                }
                Rule::name_list => to = r.names(q),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        PointTransform { l, map, to, format }
    }
}

impl Lie {
    /// Reads the statement's pair.
    pub fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Lie, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let (mut f, mut generator, mut order, mut epsilon, mut format) = (None, None, None, None, None);
        for q in inner {
            match q.as_rule() {
                Rule::sexpr if f.is_none() => f = Some(r.src(&q)),
                Rule::sexpr => order = Some(r.src(&q)),
                Rule::lie_with => {
                    let g = q.into_inner().find(|x| x.as_rule() == Rule::sexpr).map(|x| r.src(&x));
                    generator = g.map(LieGenerator::With);
                }
                Rule::lie_flow => {
                    let h = q.into_inner().find(|x| x.as_rule() == Rule::sexpr).map(|x| r.src(&x));
                    generator = Some(LieGenerator::Flow(h));
                }
                Rule::name => epsilon = Some(r.src(&q)),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        match (f, generator) {
            (Some(f), Some(generator)) => Ok(Lie { f, generator, order, epsilon, format }),
            _ => Err(SceneError::new(ErrorKind::Syntax, "malformed `lie`")
                .at(span)
                .hint("`lie f with G order 3` or `lie f flow H order 3`")),
        }
    }
}

impl Integral {
    /// Reads the statement's pair.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Integral, SceneError> {
        let (span, inner) = (r.span(&p), r.inner(&p));
        let mut exprs = Vec::new();
        let mut format = None;
        for q in inner {
            match q.as_rule() {
                Rule::sexpr => exprs.push(r.src(&q)),
                Rule::as_format => format = Some(r.format(q)),
                _ => {}
            }
        }
        let mut it = exprs.into_iter();
        let f = it.next().ok_or_else(|| SceneError::new(ErrorKind::Syntax, "malformed `integral`").at(span))?;
        Ok(Integral { f, h: it.next(), format })
    }
}

impl Action {
    /// Reads the statement's pair.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Action {
        let inner = r.inner(&p);
        let (mut h, mut energies, mut near) = (None, Vec::new(), None);
        let first = |q: Pair<Rule>| q.into_inner().find(|x| x.as_rule() == Rule::sexpr).map(|x| r.src(&x));
        for q in inner {
            match q.as_rule() {
                Rule::action_h => h = first(q),
                Rule::action_energy => energies.extend(first(q)),
                Rule::action_near => near = first(q),
                _ => {}
            }
        }
        Action { h, energies, near }
    }
}

impl SmallSpec {
    /// Reads the statement's pair.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> SmallSpec {
        let mut names = Vec::new();
        let mut exprs = Vec::new();
        let mut sweep = None;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::name => names.push(r.src(&q)),
                Rule::sexpr => exprs.push(r.src(&q)),
                Rule::average_sweep => sweep = AverageSweep::read(r, q).map(Box::new),
                _ => {}
            }
        }
        let mut it = names.into_iter();
        let small = it.next().unwrap_or_else(|| r.empty());
        let mut exprs = exprs.into_iter();
        let unperturbed = exprs.next().unwrap_or_else(|| small.clone());
        SmallSpec { small, unperturbed, principal: it.next(), order: exprs.next(), sweep }
    }
}

impl AverageSweep {
    /// Reads the statement's pair.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Option<AverageSweep> {
        let (mut amplitude, mut bounds, mut points, mut path) = (None, Vec::new(), None, None);
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::name => amplitude = Some(r.src(&q)),
                Rule::time_span => bounds = q.into_inner().map(|b| r.src(&b)).collect(),
                Rule::points => points = q.into_inner().find(|x| x.as_rule() == Rule::sexpr).map(|x| r.src(&x)),
                Rule::path => path = Some(r.src(&q)),
                _ => {}
            }
        }
        let mut b = bounds.into_iter();
        Some(AverageSweep { amplitude: amplitude?, from: b.next()?, to: b.next()?, points, path })
    }
}

fn failed(what: &str, e: impl std::fmt::Display, span: crate::scene::syntax::ast::Span) -> SceneError {
    SceneError::new(ErrorKind::Derivation, format!("{what}: {e}")).at(span)
}

impl Session {
    fn phase_space(&self, at: At) -> Result<PhaseSpace, SceneError> {
        if self.coords.is_empty() {
            return Err(SceneError::new(ErrorKind::Undeclared, "no coordinates declared")
                .at(at.span)
                .hint("declare them first, for example `coordinates q`"));
        }
        PhaseSpace::new(self.coords.iter().map(|q| q.name())).map_err(|e| failed("phase space", e, at.span))
    }

    /// Resolves `src` with `names` accepted as free symbols (a small parameter, new coordinates).
    fn resolved_with(&mut self, at: At, src: &Src, names: &[String]) -> Result<Expr, SceneError> {
        self.local_names = names.to_vec();
        let r = self.resolved(at, src);
        self.local_names.clear();
        r
    }

    /// The symbol `src` names, as the scene parses it (a declared parameter carries its
    /// assumptions, so `Symbol::new` would be a different symbol).
    fn symbol_of(&mut self, at: At, src: &Src, names: &[String]) -> Result<Symbol, SceneError> {
        let e = self.resolved_with(at, src, names)?;
        e.as_sym()
            .cloned()
            .ok_or_else(|| SceneError::new(ErrorKind::Syntax, format!("`{}` is not a name", src.text)).at(src.span))
    }

    fn emit(&mut self, lines: Vec<String>) {
        self.output.extend(lines);
    }

    fn count(&mut self, at: At, src: &Src, what: &str) -> Result<usize, SceneError> {
        let e = self.resolved(at, src)?;
        let x = self.number(&e, src.span)?;
        if x < 0.0 || x.fract() != 0.0 || x > canonical::lie::MAX_ORDER as f64 {
            return Err(SceneError::new(
                ErrorKind::BadNumber,
                format!("{what} must be a whole number 0..={}", canonical::lie::MAX_ORDER),
            )
            .at(src.span)
            .hint("nested brackets grow quickly; orders up to about 6 are practical"));
        }
        Ok(x as usize)
    }

    /// `transform [L] with x = r cos(φ), … [to r, φ]`: `lagrangian transform L --map … --to …`.
    pub(in crate::scene) fn point_transform(
        &mut self,
        at: At,
        l: Option<&Src>,
        map: &[(Src, Src)],
        to: &[Src],
        format: Option<Format>,
    ) -> Result<(), SceneError> {
        let known = |s: &Session, name: &str| {
            s.coords.iter().any(|c| c.name() == name) || s.params.contains_key(name) || name == "t"
        };
        let new: Vec<String> = if to.is_empty() {
            // The map's symbols that the scene does not know, in the order they are written.
            let mut found: Vec<(usize, String)> = Vec::new();
            for (_, rhs) in map {
                let raw = crate::parse::parse_with(&rhs.text, &self.declarations())
                    .map_err(|e| SceneError::new(ErrorKind::Syntax, e.message.clone()).at(rhs.span))?;
                for s in raw.free_symbols() {
                    let n = s.name().to_string();
                    if s.primes() == 0 && !known(self, &n) && !found.iter().any(|(_, f)| *f == n) {
                        let pos = rhs.span.0 + rhs.text.find(n.as_str()).unwrap_or(0);
                        found.push((pos, n));
                    }
                }
            }
            found.sort();
            found.into_iter().map(|(_, n)| n).collect()
        } else {
            to.iter().map(|s| s.text.clone()).collect()
        };
        if new.is_empty() {
            return Err(SceneError::new(ErrorKind::Syntax, "the map names no new coordinates")
                .at(at.span)
                .hint("name them: `transform with x = r cos(φ), y = r sin(φ) to r, φ`"));
        }
        let l = match l {
            Some(src) => self.resolved_with(at, src, &new)?,
            None => self.lagrangian(at)?,
        };
        let mut pairs = Vec::new();
        for (old, rhs) in map {
            if !self.coords.iter().any(|c| c.name() == old.text) {
                return Err(SceneError::new(ErrorKind::UndefinedSymbol, format!("`{}` is not a coordinate", old.text))
                    .at(old.span)
                    .hint("the map gives each old coordinate in terms of the new ones: `x = r cos(φ)`"));
            }
            let v = self.resolved_with(at, rhs, &new)?;
            pairs.push((old.text.clone(), crate::print::plain(&v)));
        }
        let decls = self.declarations();
        let coords: Vec<&str> = self.coords.iter().map(|q| q.name()).collect();
        let system = crate::mechanics::System::from_lagrangian_with(&crate::print::plain(&l), &coords, &decls)
            .map_err(|e| failed("point transformation", e, at.span))?;
        let pairs: Vec<(&str, &str)> = pairs.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
        let to: Vec<&str> = new.iter().map(String::as_str).collect();
        let out = system.transform(&pairs, &to).map_err(|e| failed("point transformation", e, at.span))?;
        let f = format.unwrap_or(self.opts.format);
        if let Some(l) = out.lagrangian() {
            self.emit(vec![format!("L = {}", render(l, f))]);
        }
        Ok(())
    }

    /// `lie f with G [order N] [in ε]` / `lie f flow [H] [order N]`: `lagrangian lie`.
    pub(in crate::scene) fn lie(
        &mut self,
        at: At,
        f: &Src,
        generator: &LieGenerator,
        order: Option<&Src>,
        epsilon: Option<&Src>,
        format: Option<Format>,
    ) -> Result<(), SceneError> {
        let ps = self.phase_space(at)?;
        let order = match order {
            Some(src) => self.count(at, src, "the order")?,
            None => 3,
        };
        let eps = epsilon.map_or_else(|| "ε".to_string(), |e| e.text.clone());
        let eps_sym = match epsilon {
            Some(src) => self.symbol_of(at, src, std::slice::from_ref(&eps))?,
            None => Symbol::new(&eps),
        };
        let fe = self.resolved_with(at, f, std::slice::from_ref(&eps))?;
        let series = match generator {
            LieGenerator::With(g) => {
                let ge = self.resolved_with(at, g, std::slice::from_ref(&eps))?;
                canonical::lie_series(&fe, &ge, &eps_sym, order, &ps)
            }
            LieGenerator::Flow(h) => {
                let he = match h {
                    Some(src) => self.resolved(at, src)?,
                    None => self.hamiltonian(at)?,
                };
                canonical::lie_flow(&fe, &he, order, &ps).map_err(|e| failed("lie", e, at.span))?
            }
        };
        let fmt = format.unwrap_or(self.opts.format);
        self.emit(vec![render(&series, fmt)]);
        Ok(())
    }

    /// `integral f [with H]`: `lagrangian integral f --hamiltonian H`.
    pub(in crate::scene) fn integral(
        &mut self,
        at: At,
        f: &Src,
        h: Option<&Src>,
        format: Option<Format>,
    ) -> Result<(), SceneError> {
        let ps = self.phase_space(at)?;
        let fe = self.resolved(at, f)?;
        let he = match h {
            Some(src) => self.resolved(at, src)?,
            None => self.hamiltonian(at)?,
        };
        let dfdt = canonical::time_derivative(&fe, &he, &ps);
        let check = canonical::is_integral(&fe, &he, &ps);
        let fmt = format.unwrap_or(self.opts.format);
        self.emit(canonical::report::integral_lines(&dfdt, &check, fmt));
        Ok(())
    }

    /// `action [H] at E = … [near q0]`: `lagrangian action`, librations and rotations.
    pub(in crate::scene) fn action(
        &mut self,
        at: At,
        h: Option<&Src>,
        energies: &[Src],
        near: Option<&Src>,
    ) -> Result<(), SceneError> {
        let ps = self.phase_space(at)?;
        if ps.dof() != 1 {
            return Err(SceneError::new(
                ErrorKind::Derivation,
                format!("`action` needs one degree of freedom; the scene has {}", ps.dof()),
            )
            .at(at.span));
        }
        let he = match h {
            Some(src) => self.resolved(at, src)?,
            None => self.hamiltonian(at)?,
        };
        let inside = match near {
            Some(src) => {
                let e = self.resolved(at, src)?;
                self.number(&e, src.span)?
            }
            None => 0.0,
        };
        let env: crate::eval::Env = self.params.iter().filter_map(|(n, p)| p.value.map(|v| (n.clone(), v))).collect();
        let mut rows = Vec::new();
        for src in energies {
            let e = self.resolved(at, src)?;
            let energy = self.number(&e, src.span)?;
            let r = canonical::action_frequency(&he, &ps.coords[0], &ps.momenta[0], energy, &env, inside).map_err(
                |err| SceneError::new(ErrorKind::Derivation, format!("at E = {energy}: {err}")).at(src.span),
            )?;
            rows.push(r);
        }
        self.emit(canonical::report::action_table(&rows));
        Ok(())
    }

    /// `average [L] with x = … phase θ frequency ω amplitudes A… [small σ unperturbed ω0
    /// [principal A]]`: `lagrangian average`, with `--small` the relations solved to first order.
    pub(in crate::scene) fn average_statement(&mut self, at: At, st: &Average) -> Result<(), SceneError> {
        let Average { l, trials, phase, frequency, amplitudes, small, format } = st;
        let (l, format) = (l.as_ref(), *format);
        let mut local: Vec<String> = [Some(phase), Some(frequency), small.as_ref().map(|s| &s.small)]
            .into_iter()
            .flatten()
            .map(|s| s.text.clone())
            .chain(amplitudes.iter().map(|a| a.text.clone()))
            .collect();
        local.dedup();
        let l = match l {
            Some(src) => self.resolved_with(at, src, &local)?,
            None => self.lagrangian(at)?,
        };
        let mut ts = Vec::new();
        for (q, e) in trials {
            if !self.coords.iter().any(|c| c.name() == q.text) {
                return Err(SceneError::new(ErrorKind::UndefinedSymbol, format!("`{}` is not a coordinate", q.text))
                    .at(q.span)
                    .hint("a trial function replaces a coordinate: `x = A cos(θ)`"));
            }
            ts.push(Trial { coord: Symbol::new(&q.text), expr: self.resolved_with(at, e, &local)? });
        }
        let w = Symbol::new(&frequency.text);
        let amps: Vec<Symbol> = amplitudes.iter().map(|a| Symbol::new(&a.text)).collect();
        let avg = canonical::average_lagrangian(&l, &ts, &Symbol::new(&phase.text), &w, &amps)
            .map_err(|e| failed("average", e, at.span))?;
        let fmt = format.unwrap_or(self.opts.format);
        let Some(small) = small else {
            self.emit(canonical::report::average_lines(&avg, &w, None, fmt));
            return Ok(());
        };
        let w0 = self.resolved_with(at, &small.unperturbed, &local)?;
        let principal = match &small.principal {
            Some(a) => Symbol::new(&a.text),
            None => amps
                .first()
                .cloned()
                .ok_or_else(|| SceneError::new(ErrorKind::Syntax, "no amplitudes to solve for").at(at.span))?,
        };
        let sigma = self.symbol_of(at, &small.small, &local)?;
        let order = match &small.order {
            None => 1,
            Some(src) => {
                let v = self.bound(at, src)?;
                if !(v >= 1.0 && v.fract() == 0.0 && v <= canonical::MAX_AVERAGE_ORDER as f64) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("the order must be a whole number 1..={}", canonical::MAX_AVERAGE_ORDER),
                    )
                    .at(src.span));
                }
                v as usize
            }
        };
        let lo = canonical::leading_order(&avg, &w, &w0, &sigma, &principal, order)
            .map_err(|e| failed("average", e, at.span))?;
        self.emit(canonical::report::average_lines(&avg, &w, Some((&small.small.text, &lo)), fmt));
        if let Some(sweep) = &small.sweep {
            self.average_sweep(at, &avg, &w, &w0, &lo, sweep)?;
        }
        Ok(())
    }

    /// `… for A in a..b [points N] [to FILE]`: the relations solved numerically at each
    /// amplitude with the scene's parameter values, beside the series; a table of a few rows,
    /// and the figure (ω and each secondary amplitude against A) or a CSV of every row.
    fn average_sweep(
        &mut self,
        at: At,
        avg: &canonical::Averaged,
        w: &Symbol,
        w0: &crate::expr::Expr,
        lo: &canonical::LeadingOrder,
        sweep: &AverageSweep,
    ) -> Result<(), SceneError> {
        let principal = Symbol::new(sweep.amplitude.text.trim());
        if !avg.relations.iter().any(|(a, _)| *a == principal) {
            return Err(SceneError::new(ErrorKind::Syntax, format!("`{}` is not one of the amplitudes", principal))
                .at(sweep.amplitude.span));
        }
        let (a, b) = (self.bound(at, &sweep.from)?, self.bound(at, &sweep.to)?);
        let n = match &sweep.points {
            None => 20,
            Some(src) => {
                let v = self.bound(at, src)?;
                if !(v >= 2.0 && v.fract() == 0.0 && v <= 10_000.0) {
                    return Err(
                        SceneError::new(ErrorKind::BadNumber, "`points` must be a whole number 2..=10000").at(src.span)
                    );
                }
                v as usize
            }
        };
        let values: Vec<f64> = (0..n).map(|k| a + (b - a) * k as f64 / (n - 1) as f64).collect();
        let params = self.param_values();
        let result = canonical::sweep(avg, w, w0, lo, &principal, &values, &|s: &Symbol| params.get(s.name()).copied())
            .map_err(|e| {
                let kind = if matches!(e, canonical::RelationsError::Unbound(_)) {
                    ErrorKind::MissingValue
                } else {
                    ErrorKind::Numeric
                };
                SceneError::new(kind, e.to_string()).at(at.span)
            })?;
        self.emit(canonical::report::sweep_lines(&result, &principal, w));
        let (points, series_w) = (&result.points, &result.series);
        let wn = w.to_string();
        let Some(path) = &sweep.path else { return Ok(()) };
        let (file, pspan, ext) = self.out_file(
            at.span,
            Some(path),
            "relations.svg",
            "figure or table",
            &["svg", "png", "csv"],
            "write `to relations.svg`, `to relations.png` or `to relations.csv`",
        )?;
        let tmp = self.staging.stage(&file).map_err(|e| e.at(pspan))?;
        if ext == "csv" {
            let mut text = format!("{principal},{wn},{wn}_series");
            for (s, _) in &points[0].amplitudes {
                text.push_str(&format!(",{s}"));
            }
            text.push('\n');
            for (p, ws) in points.iter().zip(series_w) {
                text.push_str(&format!("{},{},{}", p.principal, p.frequency, ws));
                for (_, v) in &p.amplitudes {
                    text.push_str(&format!(",{v}"));
                }
                text.push('\n');
            }
            std::fs::write(&tmp, text).map_err(|e| {
                SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", file.display())).at(pspan)
            })?;
        } else {
            let curve = |label: String, ys: Vec<f64>| Series {
                label,
                points: points.iter().zip(ys).map(|(p, y)| (p.principal, y)).collect(),
            };
            let mut series = vec![
                curve(format!("{wn} (relations)"), points.iter().map(|p| p.frequency).collect()),
                curve(format!("{wn} (series, order {})", lo.order), series_w.clone()),
            ];
            for (k, (s, _)) in points[0].amplitudes.iter().enumerate() {
                series.push(curve(s.to_string(), points.iter().map(|p| p.amplitudes[k].1).collect()));
            }
            let figure = Figure::lines(
                &format!("averaged relations against {principal}"),
                &principal.to_string(),
                "value",
                series,
            );
            self.figures.push((file.clone(), figure.describe()));
            crate::plot::draw(&figure, &tmp).map_err(|e| {
                SceneError::new(ErrorKind::Io, format!("cannot write the plot `{}`: {e}", file.display())).at(pspan)
            })?;
        }
        self.wrote(&file);
        Ok(())
    }

    /// `transform [H] with F1 = … new Q, P`: `lagrangian canonical --f1 … --new Q,P
    /// --hamiltonian H`, the same lines (relations, inverse and forward maps, branches, `K`).
    pub(in crate::scene) fn generating_transform(
        &mut self,
        at: At,
        h: Option<&Src>,
        kind: &str,
        f: &Src,
        new: &[Src],
        format: Option<Format>,
    ) -> Result<(), SceneError> {
        let old = self.phase_space(at)?;
        let n = old.dof();
        if new.len() != 2 * n {
            return Err(SceneError::new(
                ErrorKind::Syntax,
                format!(
                    "{} new names for {n} coordinate(s): give {n} new coordinates, then {n} new momenta",
                    new.len()
                ),
            )
            .at(new.first().map_or(at.span, |s| (s.span.0, new[new.len() - 1].span.1)))
            .hint("for one coordinate: `new Q, P`"));
        }
        let names: Vec<String> = new.iter().map(|s| s.text.clone()).collect();
        let h = match h {
            Some(src) => self.resolved_with(at, src, &names)?,
            None => self.hamiltonian(at)?,
        };
        let f_expr = self.resolved_with(at, f, &names)?;
        let kind = match kind {
            "F1" => canonical::GeneratorKind::F1,
            "F2" => canonical::GeneratorKind::F2,
            "F3" => canonical::GeneratorKind::F3,
            _ => canonical::GeneratorKind::F4,
        };
        let new_space = PhaseSpace::with_momenta(names[..n].iter(), names[n..].iter())
            .map_err(|e| failed("canonical transformation", e, at.span))?;
        let g = canonical::Generator::new(kind, f_expr, old, new_space)
            .map_err(|e| failed("canonical transformation", e, at.span))?;
        let t = g.transform(Some(&h)).map_err(|e| failed("canonical transformation", e, at.span))?;
        let fmt = format.unwrap_or(self.opts.format);
        self.emit(canonical::report::transform_lines(&t, fmt));
        Ok(())
    }
}

impl Stmt for Average {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.average_statement(at, self)
    }
}

impl Stmt for Transform {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.generating_transform(at, self.h.as_ref(), &self.kind, &self.f, &self.new, self.format)
    }
}

impl Stmt for PointTransform {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.point_transform(at, self.l.as_ref(), &self.map, &self.to, self.format)
    }
}

impl Stmt for Lie {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.lie(at, &self.f, &self.generator, self.order.as_ref(), self.epsilon.as_ref(), self.format)
    }
}

impl Stmt for Integral {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.integral(at, &self.f, self.h.as_ref(), self.format)
    }
}

impl Stmt for Action {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.action(at, self.h.as_ref(), &self.energies, self.near.as_ref())
    }
}
