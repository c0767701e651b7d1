//! Iterated maps of phase space (§3.1, §4.7.2): explicit ones such as the standard map
//! `p' = p + K sin q, q' = q + p'`, and implicit ones such as the notes' difference
//! approximations (the implicit midpoint rule `q' = q + h (p + p')/2, p' = p − h (q + q')/2`).
//!
//! An explicit map's updates are assignments applied in order, each seeing the values already
//! assigned in the same step (the standard map's `q' = q + p'` uses the new `p`). They are
//! composed symbolically into one expression per variable of the old state, compiled once into
//! a [`Tape`], and the tape is evaluated once per iteration: no parsing or allocation per step.
//!
//! An implicit map gives each new value `x'` as an expression of the old state and the new one.
//! Its equations `x' − F(x, x') = 0` and their Jacobian `I − ∂F/∂x'` are compiled into one tape
//! and solved per step by Newton's method from the fixed-point guess `F(x, x)`; a step Newton
//! cannot solve ends its orbit and is counted, never replaced by a guess.

use std::collections::HashMap;

use crate::compile::{CompileError, Tape};
use crate::diff::diff;
use crate::expr::{Expr, Symbol};
use crate::linalg::solve_in_place;

/// The most iterations of one orbit.
pub const MAX_MAP_ITERATIONS: usize = 10_000_000;
/// The most states computed by one call (starts × iterations).
pub const MAX_MAP_STATES: usize = 50_000_000;

/// Why a map was not iterated.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// An update assigns a name that is not a variable of the state.
    #[error("`{0}` is not one of the map's variables")]
    NotAVariable(String),
    /// The compiled map refers to a symbol with no value.
    #[error("{0}")]
    Compile(#[from] CompileError),
    /// Too much work asked for.
    #[error("{starts} start(s) × {iterations} iteration(s) is above the limit of {limit} states")]
    TooLarge {
        /// Starts.
        starts: usize,
        /// Iterations.
        iterations: usize,
        /// [`MAX_MAP_STATES`].
        limit: usize,
    },
    /// An implicit map mixes `x' = …` with plain assignments, or an explicit one reads a new
    /// value `x'` it never defines.
    #[error("{0}")]
    Mixed(String),
    /// A start does not give one value per variable.
    #[error("a start has {got} value(s) for {want} variable(s)")]
    StartLength {
        /// Given.
        got: usize,
        /// Variables.
        want: usize,
    },
}

/// One orbit: its states, the start first.
pub type Orbit = Vec<Vec<f64>>;

/// An explicit map compiled for iteration.
pub struct ExplicitMap {
    tape: Tape,
    dim: usize,
    /// The composed map: the new value of each variable as an expression of the old state.
    composed: Vec<Expr>,
}

impl ExplicitMap {
    /// Composes `updates` (assignments in order) over the state `vars` and compiles the result
    /// with `params` bound. A variable no update assigns keeps its value.
    pub fn new(vars: &[Symbol], updates: &[(Symbol, Expr)], params: &[(&str, f64)]) -> Result<ExplicitMap, MapError> {
        let mut current: HashMap<Symbol, Expr> = vars.iter().map(|v| (v.clone(), Expr::sym(v.clone()))).collect();
        for (target, value) in updates {
            if !vars.contains(target) {
                return Err(MapError::NotAVariable(target.to_string()));
            }
            if let Some(new) = value.free_symbols().into_iter().find(|s| s.primes() > 0 && vars.contains(&s.base())) {
                return Err(MapError::Mixed(format!(
                    "`{new}` (a new value) appears in an explicit map: an implicit map writes every new value as `x' = …`, or an explicit one assigns `{}` before using it",
                    new.base()
                )));
            }
            let v = value.subs(&current);
            current.insert(target.clone(), v);
        }
        let composed: Vec<Expr> = vars.iter().map(|v| current[v].clone()).collect();
        let names: Vec<String> = vars.iter().map(|v| v.to_string()).collect();
        let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
        let tape = Tape::compile(&composed, &inputs, params)?;
        Ok(ExplicitMap { tape, dim: vars.len(), composed })
    }

    /// The composed map, one expression per variable.
    pub fn composed(&self) -> &[Expr] {
        &self.composed
    }

    /// One step from `state` into `out`.
    pub fn step(&self, state: &[f64], out: &mut [f64]) {
        self.tape.eval(state, out);
    }

    /// The orbits of `starts` over `iterations` steps: for each start its states, the start
    /// first. An orbit stops at its first state that is not finite (which is kept, so a caller
    /// can say where it left).
    pub fn orbits(&self, starts: &[Vec<f64>], iterations: usize) -> Result<Vec<Orbit>, MapError> {
        iterate(starts, iterations, self.dim, |s, out| {
            self.step(s, out);
            true
        })
    }
}

/// The orbits of `starts` under `step` (which returns false for a step it could not take; the
/// orbit then ends with a state of NaN), each stopping at its first state that is not finite.
fn iterate(
    starts: &[Vec<f64>],
    iterations: usize,
    dim: usize,
    mut step: impl FnMut(&[f64], &mut [f64]) -> bool,
) -> Result<Vec<Orbit>, MapError> {
    let states = starts.len().saturating_mul(iterations.saturating_add(1));
    if iterations > MAX_MAP_ITERATIONS || states > MAX_MAP_STATES {
        return Err(MapError::TooLarge { starts: starts.len(), iterations, limit: MAX_MAP_STATES });
    }
    let mut out = Vec::with_capacity(starts.len());
    for s in starts {
        if s.len() != dim {
            return Err(MapError::StartLength { got: s.len(), want: dim });
        }
        let mut orbit = Vec::with_capacity(iterations + 1);
        orbit.push(s.clone());
        let mut next = vec![0.0; dim];
        for _ in 0..iterations {
            let cur = orbit.last().map(Vec::as_slice).unwrap_or(s);
            if !step(cur, &mut next) {
                next.fill(f64::NAN);
            }
            orbit.push(next.clone());
            if next.iter().any(|x| !x.is_finite()) {
                break;
            }
        }
        out.push(orbit);
    }
    Ok(out)
}

/// Newton iterations allowed per step of an implicit map.
const MAX_NEWTON: usize = 50;

/// An implicit map compiled for iteration: `x' = F(x, x')` for each variable `x`.
pub struct ImplicitMap {
    /// Inputs: the old state, then the new; outputs: `F`, then `∂F/∂x'` row by row.
    tape: Tape,
    dim: usize,
}

impl ImplicitMap {
    /// The map whose new values satisfy `updates` (`x' = F(x, x')`, in any order) over the state
    /// `vars`, compiled with `params` bound. A variable no update names keeps its value.
    pub fn new(vars: &[Symbol], updates: &[(Symbol, Expr)], params: &[(&str, f64)]) -> Result<ImplicitMap, MapError> {
        let mut f: Vec<Expr> = vars.iter().map(|v| Expr::sym(v.clone())).collect();
        for (target, value) in updates {
            let Some(k) = vars.iter().position(|v| *v == target.base()) else {
                return Err(MapError::NotAVariable(target.to_string()));
            };
            if target.primes() != 1 {
                return Err(MapError::Mixed(format!(
                    "`{target}` is assigned in an implicit map: write every new value as `{}' = …`",
                    target.base()
                )));
            }
            f[k] = value.clone();
        }
        let new: Vec<Symbol> = vars.iter().map(|v| v.with_primes(1)).collect();
        let mut outputs = f.clone();
        for fi in &f {
            outputs.extend(new.iter().map(|v| diff(fi, v)));
        }
        let names: Vec<String> = vars.iter().chain(&new).map(|v| v.to_string()).collect();
        let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
        let tape = Tape::compile(&outputs, &inputs, params)?;
        Ok(ImplicitMap { tape, dim: vars.len() })
    }

    /// One step from `state` into `out`: the Newton iterations it took, or `None` when they did
    /// not converge (a singular Jacobian, a non-finite residual, or no convergence in 50).
    pub fn step(&self, state: &[f64], out: &mut [f64]) -> Option<usize> {
        let n = self.dim;
        let mut x = [state, state].concat();
        let mut buf = vec![0.0; n + n * n];
        // The fixed-point guess x' = F(x, x).
        self.tape.eval(&x, &mut buf);
        x[n..].copy_from_slice(&buf[..n]);
        for it in 1..=MAX_NEWTON {
            self.tape.eval(&x, &mut buf);
            let (f, jac) = buf.split_at_mut(n);
            // Residual r = F − x' and Jacobian I − ∂F/∂x': the correction solves (I − ∂F/∂x') d = r.
            for i in 0..n {
                f[i] -= x[n + i];
                for j in 0..n {
                    jac[i * n + j] = f64::from(u8::from(i == j)) - jac[i * n + j];
                }
            }
            if f.iter().any(|v| !v.is_finite()) || solve_in_place(jac, f, n).is_err() {
                return None;
            }
            let (mut dmax, mut scale) = (0.0f64, 0.0f64);
            for i in 0..n {
                x[n + i] += f[i];
                dmax = dmax.max(f[i].abs());
                scale = scale.max(x[n + i].abs());
            }
            if !dmax.is_finite() {
                return None;
            }
            // Quadratic convergence: after a correction of 1e-10 of the values the iterate is
            // right to about its square, below rounding.
            if dmax <= 1e-10 * scale || dmax <= 1e-15 {
                out[..n].copy_from_slice(&x[n..]);
                return Some(it);
            }
        }
        None
    }

    /// The orbits of `starts` over `iterations` steps, as [`ExplicitMap::orbits`]; a step whose
    /// equations Newton's method could not solve ends its orbit with a state of NaN. The second
    /// value counts those orbits.
    pub fn orbits(&self, starts: &[Vec<f64>], iterations: usize) -> Result<(Vec<Orbit>, usize), MapError> {
        let mut unsolved = 0;
        let orbits = iterate(starts, iterations, self.dim, |s, out| {
            let ok = self.step(s, out).is_some();
            unsolved += usize::from(!ok);
            ok
        })?;
        Ok((orbits, unsolved))
    }
}

/// The most orbits whose last state [`MapRun::report`] prints.
pub const PRINTED_ORBITS: usize = 10;

/// A map of phase space, explicit or implicit as its updates are written: plain targets are
/// assignments in order ([`ExplicitMap`]), primed ones (`q' = …`) equations for the new values
/// ([`ImplicitMap`]). Every front end builds its map here, so the choice is made once.
pub enum PhaseMap {
    /// Assignments in order.
    Explicit(ExplicitMap),
    /// Equations for the new values, solved by Newton's method.
    Implicit(ImplicitMap),
}

/// Orbits of a [`PhaseMap`] and how they ended.
#[derive(Clone, Debug)]
pub struct MapRun {
    /// Each start's states, the start first; a stopped orbit ends with its non-finite state.
    pub orbits: Vec<Orbit>,
    /// Orbits stopped at a step whose implicit equations had no solution found.
    pub unsolved: usize,
    /// Whether the map was implicit.
    pub implicit: bool,
    /// The iterations asked for.
    pub steps: usize,
}

impl PhaseMap {
    /// The map of `updates` over the state `vars` with `params` bound.
    pub fn new(vars: &[Symbol], updates: &[(Symbol, Expr)], params: &[(&str, f64)]) -> Result<PhaseMap, MapError> {
        if updates.iter().any(|(t, _)| t.primes() > 0) {
            ImplicitMap::new(vars, updates, params).map(PhaseMap::Implicit)
        } else {
            ExplicitMap::new(vars, updates, params).map(PhaseMap::Explicit)
        }
    }

    /// The orbits of `starts` over `steps` iterations.
    pub fn run(&self, starts: &[Vec<f64>], steps: usize) -> Result<MapRun, MapError> {
        let (orbits, unsolved, implicit) = match self {
            PhaseMap::Explicit(m) => (m.orbits(starts, steps)?, 0, false),
            PhaseMap::Implicit(m) => {
                let (o, u) = m.orbits(starts, steps)?;
                (o, u, true)
            }
        };
        Ok(MapRun { orbits, unsolved, implicit, steps })
    }
}

impl MapRun {
    /// What every front end prints: the orbits, how many stopped and why, and the first and last
    /// state of the first [`PRINTED_ORBITS`] orbits.
    pub fn report(&self) -> Vec<String> {
        let stopped = self.orbits.iter().filter(|o| o.last().is_some_and(|s| s.iter().any(|x| !x.is_finite()))).count();
        let left = stopped.saturating_sub(self.unsolved);
        let mut stops = Vec::new();
        if left > 0 {
            stops.push(format!("{left} left the finite numbers and stopped"));
        }
        if self.unsolved > 0 {
            stops.push(format!(
                "{} stopped at a step whose implicit equations Newton's method could not solve (a smaller step parameter would help)",
                self.unsolved
            ));
        }
        let mut out = vec![format!(
            "map: {} orbit(s) of {} step(s){}{}",
            self.orbits.len(),
            self.steps,
            if self.implicit { ", implicit (Newton's method per step)" } else { "" },
            stops.iter().map(|s| format!("; {s}")).collect::<String>()
        )];
        for o in self.orbits.iter().take(PRINTED_ORBITS) {
            let fmt = |s: &[f64]| s.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(", ");
            out.push(format!("  ({}) → ({})", fmt(&o[0]), fmt(o.last().map(Vec::as_slice).unwrap_or(&[]))));
        }
        out
    }
}
