//! `force`, `rayleigh` and `constraint`: what a scene adds to its Lagrangian beyond `L`
//! (PHYSICS.md §1–2: generalized forces `E_i = Q_i` (2.12), a Rayleigh function
//! `E_i + ∂R/∂q'_i = 0`, holonomic constraints `f_j(q, t) = 0` with multipliers (1.25–1.29)).
//!
//! The statements are checked when they are read (the coordinate exists, the expression uses
//! only known names, a constraint has no velocities) and resolved when a run needs them. A
//! `simulate` keeps the statements declared before it, so a later `force` does not change an
//! earlier run. A constrained run's initial state must satisfy the constraints and their time
//! derivatives; otherwise the run is refused with the residual named.

use std::collections::{BTreeSet, HashMap};

use crate::compile::Stabilization;
use crate::expr::{Expr, Symbol};
use crate::print::fmt_num;
use crate::scene::engine::backend::ExtendedLagrangian;
use crate::scene::state::{At, Declared, Dynamics, Mode, Session};
use crate::scene::statements::Stmt;
use crate::scene::syntax::ast::symbol_span;
use crate::scene::syntax::ast::{SimSpec, Src};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};
use crate::scene::syntax::parser::{Pair, Reader, Rule};

/// `force x = …`: a generalized force on a coordinate.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Force {
    /// The coordinate.
    pub coord: Src,
    /// The force `Q(q, q', t)`.
    pub value: Src,
}

/// `rayleigh [R =] …`: the Rayleigh dissipation function.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Rayleigh {
    /// The name it is defined as, if any.
    pub name: Option<Src>,
    /// `R(q, q')`.
    pub value: Src,
}

/// `constraint f = g`: the holonomic constraint `f − g = 0`; `constraint velocity g = h`:
/// the velocity constraint `g − h = 0`, linear in the velocities.
#[derive(Clone, Debug)]
pub(in crate::scene) struct Constraint {
    /// Whether it is a velocity (nonholonomic) constraint.
    pub velocity: bool,
    /// The left side.
    pub lhs: Src,
    /// The right side (zero when absent).
    pub rhs: Option<Src>,
}

impl Force {
    /// `force q = Q`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Force, SceneError> {
        let span = r.span(&p);
        let mut it = r.inner(&p).into_iter();
        match (it.next(), it.next()) {
            (Some(c), Some(v)) => Ok(Force { coord: r.src(&c), value: r.src(&v) }),
            _ => Err(SceneError::new(ErrorKind::Syntax, "malformed `force`").at(span)),
        }
    }
}

impl Rayleigh {
    /// `rayleigh [R =] …`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Rayleigh, SceneError> {
        let span = r.span(&p);
        let mut name = None;
        let mut value = None;
        for q in r.inner(&p) {
            match q.as_rule() {
                Rule::name => name = Some(r.src(&q)),
                _ => value = Some(r.src(&q)),
            }
        }
        let value = value.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "malformed `rayleigh`").at(span))?;
        Ok(Rayleigh { name, value })
    }
}

impl Constraint {
    /// `constraint [velocity] f [= g]`.
    pub(in crate::scene) fn read(r: &Reader, p: Pair<'_, Rule>) -> Result<Constraint, SceneError> {
        let span = r.span(&p);
        let velocity = p.clone().into_inner().any(|q| q.as_rule() == Rule::kw_velocity);
        let mut it = r.inner(&p).into_iter();
        let lhs = it.next().map(|q| r.src(&q));
        let rhs = it.next().map(|q| r.src(&q));
        let lhs = lhs.ok_or_else(|| SceneError::new(ErrorKind::Syntax, "malformed `constraint`").at(span))?;
        Ok(Constraint { velocity, lhs, rhs })
    }
}

/// Forces per coordinate, the Rayleigh function and the constraints, resolved.
pub(in crate::scene) type ResolvedDynamics = (Vec<Expr>, Option<Expr>, Vec<Expr>);

/// The default Baumgarte rate `α = β` (1/time) when `stabilize baumgarte` gives none.
pub(in crate::scene) const DEFAULT_BAUMGARTE_RATE: f64 = 10.0;

impl Dynamics {
    /// Nothing beyond `L`.
    pub(in crate::scene) fn is_empty(&self) -> bool {
        self.forces.is_empty()
            && self.rayleigh.is_none()
            && self.constraints.is_empty()
            && self.velocity_constraints.is_empty()
    }

    /// Whether there are velocity constraints.
    pub(in crate::scene) fn velocity_constrained(&self) -> bool {
        !self.velocity_constraints.is_empty()
    }

    /// Whether forces or a Rayleigh function act on the coordinates.
    pub(in crate::scene) fn forced(&self) -> bool {
        !self.forces.is_empty() || self.rayleigh.is_some()
    }

    /// Whether there are constraints.
    pub(in crate::scene) fn constrained(&self) -> bool {
        !self.constraints.is_empty()
    }

    /// `λ1…λm`, `μ1…μk` and `residual1…residual(m+k)` name values along a constrained run
    /// (the velocity constraints' residuals follow the holonomic ones).
    pub(in crate::scene) fn is_aux_name(&self, s: &Symbol) -> bool {
        if s.primes() != 0 {
            return false;
        }
        let name = s.name();
        let (m, k) = (self.constraints.len(), self.velocity_constraints.len());
        let (index, count) = if let Some(i) = name.strip_prefix('λ') {
            (i, m)
        } else if let Some(i) = name.strip_prefix('μ') {
            (i, k)
        } else if let Some(i) = name.strip_prefix("residual") {
            (i, m + k)
        } else {
            return false;
        };
        index.parse::<usize>().ok().is_some_and(|j| j >= 1 && j <= count)
    }
}

impl Session {
    /// Parses an expression of coordinates, velocities, parameters, definitions and `t` for a
    /// force, Rayleigh function or constraint: no accelerations, no momenta, and (for a
    /// constraint) no velocities.
    fn dynamics_expr(&mut self, src: &Src, what: &str, velocities: bool) -> Result<Declared, SceneError> {
        let (raw, refs) = self.expr(src)?;
        for s in raw.free_symbols() {
            let spelled = s.to_string();
            let is_coord = self.coords.iter().any(|q| q.name() == s.name());
            if is_coord && s.primes() >= 2 {
                return Err(SceneError::new(ErrorKind::Syntax, format!("`{spelled}` is an acceleration"))
                    .at(symbol_span(src, &spelled))
                    .hint(format!("a {what} depends on coordinates, velocities and `t` only")));
            }
            if is_coord && s.primes() == 1 && !velocities {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    format!("a constraint with the velocity `{spelled}` is not holonomic"),
                )
                .at(symbol_span(src, &spelled))
                .hint("a holonomic constraint is f(q, t) = 0: coordinates, parameters and `t` only"));
            }
            if s.primes() <= 1 && s.name().strip_prefix("p_").is_some_and(|c| self.coords.iter().any(|q| q.name() == c))
            {
                return Err(SceneError::new(ErrorKind::Syntax, format!("`{spelled}` is a momentum"))
                    .at(symbol_span(src, &spelled))
                    .hint(format!("write the {what} with velocities (`x'`), the state of a Lagrangian run")));
            }
        }
        Ok(Declared { raw, refs, src: src.clone() })
    }

    /// `force x = Q`.
    pub(in crate::scene) fn declare_force(&mut self, coord: &Src, value: &Src) -> Result<(), SceneError> {
        let Some(i) = self.coords.iter().position(|q| q.name() == coord.text) else {
            let known: Vec<&str> = self.coords.iter().map(|q| q.name()).collect();
            let err = SceneError::new(ErrorKind::UndefinedSymbol, format!("`{}` is not a coordinate", coord.text))
                .at(coord.span)
                .label("a force acts on a coordinate");
            return Err(if known.is_empty() {
                err.hint(format!("declare it first: `coordinates {}`", coord.text))
            } else {
                err.hint(format!("the coordinates are {}", known.join(", ")))
            });
        };
        let d = self.dynamics_expr(value, "force", true)?;
        if self.opts.mode == Mode::Repl {
            self.output.push(format!("force on {}: Q = {}", coord.text, d.raw));
        }
        self.dynamics.forces.push((i, d));
        Ok(())
    }

    /// `rayleigh [R =] …`.
    pub(in crate::scene) fn declare_rayleigh(
        &mut self,
        at: At,
        name: Option<&Src>,
        value: &Src,
    ) -> Result<(), SceneError> {
        if let Some(old) = &self.dynamics.rayleigh {
            return Err(SceneError::new(ErrorKind::Redeclared, "a Rayleigh function is already declared")
                .at(value.span)
                .hint(format!("add the terms to the first one: `{}`", old.src.text)));
        }
        if let Some(n) = name {
            // `rayleigh L = …` would make the dissipation function the Lagrangian (the run
            // integrated R as L), and a name already defined would be silently replaced.
            let what = match n.text.as_str() {
                "L" => Some("the name of the Lagrangian".to_string()),
                "H" => Some("the name of the Hamiltonian".to_string()),
                other => self.name_in_use(other).map(|w| format!("already {w}")),
            };
            if let Some(what) = what {
                return Err(SceneError::new(
                    ErrorKind::Redeclared,
                    format!("`{}` is {what}; a Rayleigh function needs a name of its own", n.text),
                )
                .at(n.span)
                .label("already has a meaning")
                .hint("name it `R` (`rayleigh R = …`), or leave the name out (`rayleigh …`)"));
            }
        }
        let d = self.dynamics_expr(value, "Rayleigh function", true)?;
        if let Some(n) = name {
            self.define(at, n, &crate::scene::syntax::ast::DefValue::Expr(value.clone()))?;
        }
        if self.opts.mode == Mode::Repl && name.is_none() {
            self.output.push(format!("R = {}", d.raw));
        }
        self.dynamics.rayleigh = Some(d);
        Ok(())
    }

    /// `lhs [= rhs]` of a constraint statement as one expression that vanishes (`lhs − rhs`),
    /// with the references and source text of both sides.
    fn constraint_expr(
        &mut self,
        lhs: &Src,
        rhs: Option<&Src>,
        what: &str,
        velocities: bool,
    ) -> Result<Declared, SceneError> {
        let mut d = self.dynamics_expr(lhs, what, velocities)?;
        if let Some(r) = rhs {
            let b = self.dynamics_expr(r, what, velocities)?;
            d.raw = d.raw.minus(&b.raw);
            d.refs.extend(b.refs);
            d.src = Src { text: format!("{} = {}", lhs.text, r.text), span: (lhs.span.0, r.span.1) };
        }
        Ok(d)
    }

    /// `constraint f = g`.
    pub(in crate::scene) fn declare_constraint(&mut self, lhs: &Src, rhs: Option<&Src>) -> Result<(), SceneError> {
        let d = self.constraint_expr(lhs, rhs, "constraint", false)?;
        // The command line's words for `1 = 0` and `x = x`, so both front ends say the same.
        if d.refs.is_empty() {
            if let Some(crate::mechanics::MechanicsError::WrongKind(why)) =
                crate::mechanics::constant_constraint(&d.raw, &d.src.text)
            {
                return Err(SceneError::new(ErrorKind::Syntax, why)
                    .at(d.src.span)
                    .hint("a constraint restricts the coordinates: `constraint x^2 + y^2 = l^2`"));
            }
        }
        let coords: BTreeSet<&str> = self.coords.iter().map(|q| q.name()).collect();
        if !d.raw.free_symbols().iter().any(|s| coords.contains(s.name())) && d.refs.is_empty() {
            return Err(SceneError::new(ErrorKind::Syntax, "the constraint involves no coordinate")
                .at(d.src.span)
                .hint("a constraint restricts the coordinates: `constraint x^2 + y^2 = l^2`"));
        }
        let j = self.dynamics.constraints.len() + 1;
        if self.opts.mode == Mode::Repl {
            self.output.push(format!("constraint {j}: {} = 0 (multiplier λ{j})", d.raw));
        }
        self.dynamics.constraints.push(d);
        Ok(())
    }

    /// `constraint velocity g = h`: the velocity constraint `g − h = 0`, linear in the
    /// velocities (checked when a run resolves it against the system).
    pub(in crate::scene) fn declare_velocity_constraint(
        &mut self,
        lhs: &Src,
        rhs: Option<&Src>,
    ) -> Result<(), SceneError> {
        let d = self.constraint_expr(lhs, rhs, "velocity constraint", true)?;
        let coords: BTreeSet<&str> = self.coords.iter().map(|q| q.name()).collect();
        if d.refs.is_empty() && !d.raw.free_symbols().iter().any(|s| s.primes() == 1 && coords.contains(s.name())) {
            return Err(SceneError::new(ErrorKind::Syntax, "the velocity constraint contains no velocity")
                .at(d.src.span)
                .hint("a constraint f(q, t) = 0 is holonomic: write it `constraint f = 0`; a velocity constraint is `constraint velocity x' = R φ' cos(θ)`"));
        }
        let j = self.dynamics.velocity_constraints.len() + 1;
        if self.opts.mode == Mode::Repl {
            self.output.push(format!("velocity constraint {j}: {} = 0 (multiplier μ{j})", d.raw));
        }
        self.dynamics.velocity_constraints.push(d);
        Ok(())
    }

    /// The declared forces (per coordinate), Rayleigh function and constraints, resolved
    /// against the current definitions (what `conserved` must respect).
    pub(in crate::scene) fn resolved_dynamics(&mut self, at: At) -> Result<ResolvedDynamics, SceneError> {
        let dynamics = self.dynamics.clone();
        let mut forces = vec![Expr::zero(); self.coords.len()];
        for (i, d) in &dynamics.forces {
            forces[*i] = forces[*i].plus(&self.resolve(at, &d.raw, &d.refs)?);
        }
        let rayleigh = match &dynamics.rayleigh {
            Some(d) => Some(self.resolve(at, &d.raw, &d.refs)?),
            None => None,
        };
        let mut constraints = Vec::new();
        for d in &dynamics.constraints {
            constraints.push(self.resolve(at, &d.raw, &d.refs)?);
        }
        Ok((forces, rayleigh, constraints))
    }

    /// The extended Lagrangian of a run: `L` with the run's forces, Rayleigh function and
    /// constraints resolved.
    pub(in crate::scene) fn extended(
        &mut self,
        at: At,
        l: Expr,
        dynamics: &Dynamics,
        spec: &SimSpec,
    ) -> Result<ExtendedLagrangian, SceneError> {
        let n = self.coords.len();
        let mut forces = vec![Expr::zero(); n];
        for (i, d) in &dynamics.forces {
            let q = self.resolve(at, &d.raw, &d.refs)?;
            forces[*i] = forces[*i].plus(&q);
        }
        let rayleigh = match &dynamics.rayleigh {
            Some(d) => Some(self.resolve(at, &d.raw, &d.refs)?),
            None => None,
        };
        let mut constraints = Vec::new();
        for d in &dynamics.constraints {
            let f = self.resolve(at, &d.raw, &d.refs)?;
            if f.free_symbols().iter().any(|s| s.primes() > 0) {
                return Err(SceneError::new(ErrorKind::Syntax, "the constraint is not holonomic: it has a velocity")
                    .at(d.src.span)
                    .hint("a holonomic constraint is f(q, t) = 0"));
            }
            constraints.push(f);
        }
        let mut velocity_constraints = Vec::new();
        for d in &dynamics.velocity_constraints {
            velocity_constraints.push(self.resolve(at, &d.raw, &d.refs)?);
        }
        // Linear in the velocities, with a velocity of a coordinate: the library's check, at
        // the statement that declared it.
        if !velocity_constraints.is_empty() {
            let probe = crate::mechanics::System::from_lagrangian_expr(l.clone(), &self.coords)
                .map_err(|e| SceneError::new(ErrorKind::Derivation, e.to_string()).at(at.span))?;
            for (g, d) in velocity_constraints.iter().zip(&dynamics.velocity_constraints) {
                if let Err(e) = probe.clone().with_velocity_constraint_expr(g.clone()) {
                    return Err(SceneError::new(ErrorKind::Syntax, e.to_string()).at(d.src.span).hint(
                        "a velocity constraint is a(q, t)·q' + b(q, t) = 0: `constraint velocity x' = R φ' cos(θ)`",
                    ));
                }
            }
        }
        let stabilization = match &spec.stabilize {
            None => Stabilization::Projection,
            Some(s) => match s.kind.as_str() {
                "projection" => Stabilization::Projection,
                "none" => Stabilization::None,
                _ => {
                    let rate = match &s.rate {
                        Some(src) => {
                            let e = self.resolved(at, src)?;
                            let x = self.number(&e, src.span)?;
                            if x <= 0.0 {
                                return Err(SceneError::new(
                                    ErrorKind::BadNumber,
                                    format!("the Baumgarte rate must be positive, found {}", fmt_num(x)),
                                )
                                .at(src.span)
                                .hint("a rate of a few over the time step's scale, such as `baumgarte = 10`"));
                            }
                            x
                        }
                        None => DEFAULT_BAUMGARTE_RATE,
                    };
                    Stabilization::Baumgarte { rate }
                }
            },
        };
        if let Some(s) = &spec.stabilize {
            if constraints.is_empty() && velocity_constraints.is_empty() {
                return Err(SceneError::new(ErrorKind::Syntax, "`stabilize` applies to constrained runs only")
                    .at(s.span)
                    .hint("declare a constraint first (`constraint x^2 + y^2 = l^2`), or drop `stabilize`"));
            }
        }
        Ok(ExtendedLagrangian { l, forces, rayleigh, constraints, velocity_constraints, stabilization })
    }

    /// Refuses an initial state off the constraints: each `f_j(q0, t0)` and
    /// `ḟ_j = Φ q0' + ∂f/∂t` must vanish (to 1e-9 of the coordinates' scale).
    pub(in crate::scene) fn check_initial_constraints(
        &mut self,
        dynamics: &Dynamics,
        ext: &ExtendedLagrangian,
        y0: &[f64],
        t0: f64,
        params: &[(String, f64)],
        span: Span,
    ) -> Result<(), SceneError> {
        let n = self.coords.len();
        let mut env: HashMap<String, f64> = self.param_values();
        env.extend(params.iter().cloned());
        for (i, q) in self.coords.iter().enumerate() {
            env.insert(q.name().to_string(), y0[i]);
            env.insert(format!("{}'", q.name()), y0[n + i]);
        }
        env.insert("t".into(), t0);
        let names: BTreeSet<String> = self.coords.iter().map(|q| q.name().to_string()).collect();
        let scale = y0[..n].iter().fold(1.0f64, |s, v| s.max(v.abs()));
        let vscale = y0[n..].iter().fold(1.0f64, |s, v| s.max(v.abs()));
        let state: Vec<String> =
            self.coords.iter().enumerate().map(|(i, q)| format!("{} = {}", q.name(), fmt_num(y0[i]))).collect();
        for (j, (f, d)) in ext.constraints.iter().zip(&dynamics.constraints).enumerate() {
            let value = crate::eval::eval(f, &env).map_err(|e| self.value_error(e, span))?;
            if value.is_nan() || value.abs() > 1e-9 * scale * scale {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!(
                        "the initial state violates constraint {} (`{}`): its residual is {:e} at {}",
                        j + 1,
                        d.src.text,
                        value,
                        state.join(", ")
                    ),
                )
                .at(span)
                .label(format!("residual{} = {value:e}", j + 1))
                .hint("start on the constraint: choose initial coordinates that satisfy it exactly"));
            }
            let rate = self.diff.dt(f, &names);
            let value = crate::eval::eval(&rate, &env).map_err(|e| self.value_error(e, span))?;
            if value.is_nan() || value.abs() > 1e-9 * scale * vscale {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!(
                        "the initial velocities violate constraint {} (`{}`): its time derivative is {:e}",
                        j + 1,
                        d.src.text,
                        value
                    ),
                )
                .at(span)
                .label(format!("d/dt residual{} = {value:e}", j + 1))
                .hint("start with velocities tangent to the constraint (d/dt of it must vanish)"));
            }
        }
        for (j, (g, d)) in ext.velocity_constraints.iter().zip(&dynamics.velocity_constraints).enumerate() {
            let value = crate::eval::eval(g, &env).map_err(|e| self.value_error(e, span))?;
            if value.is_nan() || value.abs() > 1e-9 * vscale.max(scale) {
                return Err(SceneError::new(
                    ErrorKind::BadNumber,
                    format!(
                        "the initial velocities violate velocity constraint {} (`{}`): its residual is {:e} at {}",
                        j + 1,
                        d.src.text,
                        value,
                        state.join(", ")
                    ),
                )
                .at(span)
                .label(format!("residual{} = {value:e}", ext.constraints.len() + j + 1))
                .hint("start with velocities that satisfy it (solve it for one velocity)"));
            }
        }
        Ok(())
    }
}

impl Stmt for Force {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        s.declare_force(&self.coord, &self.value)
    }
}

impl Stmt for Rayleigh {
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError> {
        s.declare_rayleigh(at, self.name.as_ref(), &self.value)
    }
}

impl Stmt for Constraint {
    fn run(&self, s: &mut Session, _: At) -> Result<(), SceneError> {
        if self.velocity {
            s.declare_velocity_constraint(&self.lhs, self.rhs.as_ref())
        } else {
            s.declare_constraint(&self.lhs, self.rhs.as_ref())
        }
    }
}
