//! Iterated explicit maps of phase space (§3.1, §4.7.2): `p' = p + K sin q, q' = q + p'` (the
//! standard map) and any other map whose new values are explicit expressions of the old ones.
//!
//! The updates are assignments applied in order, each seeing the values already assigned in
//! the same step (the standard map's `q' = q + p'` uses the new `p`). They are composed
//! symbolically into one expression per variable of the old state, compiled once into a
//! [`Tape`], and the tape is evaluated once per iteration: no parsing or allocation per step.
//! Implicit maps (the notes' difference approximations solved for the new values) are not
//! iterated here.

use std::collections::HashMap;

use crate::compile::{CompileError, Tape};
use crate::expr::{Expr, Symbol};

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
    /// A start does not give one value per variable.
    #[error("a start has {got} value(s) for {want} variable(s)")]
    StartLength {
        /// Given.
        got: usize,
        /// Variables.
        want: usize,
    },
}

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
    pub fn orbits(&self, starts: &[Vec<f64>], iterations: usize) -> Result<Vec<Vec<Vec<f64>>>, MapError> {
        let states = starts.len().saturating_mul(iterations.saturating_add(1));
        if iterations > MAX_MAP_ITERATIONS || states > MAX_MAP_STATES {
            return Err(MapError::TooLarge { starts: starts.len(), iterations, limit: MAX_MAP_STATES });
        }
        let mut out = Vec::with_capacity(starts.len());
        for s in starts {
            if s.len() != self.dim {
                return Err(MapError::StartLength { got: s.len(), want: self.dim });
            }
            let mut orbit = Vec::with_capacity(iterations + 1);
            orbit.push(s.clone());
            let mut next = vec![0.0; self.dim];
            for _ in 0..iterations {
                let cur = orbit.last().map(Vec::as_slice).unwrap_or(s);
                self.step(cur, &mut next);
                orbit.push(next.clone());
                if next.iter().any(|x| !x.is_finite()) {
                    break;
                }
            }
            out.push(orbit);
        }
        Ok(out)
    }
}
