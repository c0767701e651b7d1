//! The symbolic tools that need no system, as the command line and scenes have them: the series
//! of an expression in small quantities, the Jacobian of a map of coordinates, and the orbits of
//! an explicit or implicit map of phase space. Each calls one library function.

use std::collections::BTreeMap;

use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::{self, PhaseMap};
use lagrangian::Declarations;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;

use crate::errors::{exc, PyResultExt, ToPyErr};
use crate::expr::{to_expr, to_symbol, PyExpr};

impl ToPyErr for mechanics::SeriesError {
    fn py_err(self) -> PyErr {
        exc::MechanicsError::new_err(self.to_string())
    }
}

impl ToPyErr for mechanics::MapError {
    fn py_err(self) -> PyErr {
        exc::MechanicsError::new_err(self.to_string())
    }
}

/// The declarations of the first `Expr` among `objs` (so results print as the inputs did).
fn decls_of<'a>(objs: impl IntoIterator<Item = &'a Bound<'a, PyAny>>) -> Declarations {
    objs.into_iter().find_map(|o| o.downcast::<PyExpr>().ok().map(|e| e.get().decls.0.clone())).unwrap_or_default()
}

/// The series of ``expr`` to order ``order`` in the small quantities ``small`` (total degree):
/// ``series("sin(x)", ["x"], 5)`` is ``x − x³/6 + x⁵/120``; each order tidied on its own.
#[pyfunction]
#[pyo3(signature = (expr, small, order=2))]
pub fn series(expr: &Bound<'_, PyAny>, small: Vec<Bound<'_, PyAny>>, order: usize) -> PyResult<PyExpr> {
    let decls = decls_of([expr]);
    let e = to_expr(expr, &decls, true)?;
    let small: Vec<Symbol> = small.iter().map(|s| to_symbol(s, &decls)).collect::<PyResult<_>>()?;
    Ok(PyExpr::new(mechanics::series(&e, &small, order).py()?, &decls))
}

/// The Jacobian matrix ``∂x_i/∂y_j`` of a map of coordinates ``x_i(y)`` and its determinant,
/// each simplified: ``jacobian(["r cos(φ)", "r sin(φ)"], ["r", "φ"])`` gives ``det = r``.
#[pyfunction]
pub fn jacobian(map: Vec<Bound<'_, PyAny>>, variables: Vec<Bound<'_, PyAny>>) -> PyResult<(Vec<Vec<PyExpr>>, PyExpr)> {
    let decls = decls_of(map.iter());
    let xs: Vec<Expr> = map.iter().map(|x| to_expr(x, &decls, true)).collect::<PyResult<_>>()?;
    let ys: Vec<Symbol> = variables.iter().map(|y| to_symbol(y, &decls)).collect::<PyResult<_>>()?;
    let Some((m, det)) = mechanics::jacobian(&xs, &ys) else {
        return Err(exc::ArgumentError::new_err(format!(
            "a Jacobian needs as many components as variables: {} and {}",
            xs.len(),
            ys.len()
        )));
    };
    let wrap = |e: Expr| PyExpr::new(e, &decls);
    Ok((m.into_iter().map(|row| row.into_iter().map(wrap).collect()).collect(), wrap(det)))
}

/// The orbits of a map of phase space from each row of ``starts`` (shape ``(k, n)``, the
/// values of ``variables`` in order) over ``steps`` iterations: an array ``(k, steps + 1, n)``.
///
/// ``updates`` is a list of ``(name, expression)``. Plain names are assignments applied in
/// order, each seeing the values already assigned this step (the standard map
/// ``[("p", "p + K sin(q)"), ("q", "q + p")]``). Primed names give the new values by equations
/// that may use them (the implicit midpoint rule ``[("q'", "q + h (p + p')/2"),
/// ("p'", "p - h (q + q')/2")]``), solved by Newton's method each step. An orbit that leaves
/// the finite numbers, or whose step has no solution, is NaN from there on.
#[pyfunction]
#[pyo3(signature = (updates, variables, starts, steps, *, params=None))]
pub fn iterate_map<'py>(
    py: Python<'py>,
    updates: Vec<(String, Bound<'py, PyAny>)>,
    variables: Vec<String>,
    starts: Vec<Vec<f64>>,
    steps: usize,
    params: Option<BTreeMap<String, f64>>,
) -> PyResult<Bound<'py, PyAny>> {
    let decls = decls_of(updates.iter().map(|(_, e)| e));
    let vars: Vec<Symbol> = variables.iter().map(|v| Symbol::new(v)).collect();
    let mut parsed = Vec::with_capacity(updates.len());
    for (name, value) in &updates {
        let primes = name.chars().rev().take_while(|c| *c == '\'').count();
        let base = name.trim_end_matches('\'');
        let target = Symbol::new(base).with_primes(u8::try_from(primes).unwrap_or(u8::MAX));
        parsed.push((target, to_expr(value, &decls, true)?));
    }
    let params = params.unwrap_or_default();
    let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let run = py.allow_threads(|| PhaseMap::new(&vars, &parsed, &params).and_then(|m| m.run(&starts, steps))).py()?;
    let orbits = run.orbits;
    let n = vars.len();
    let mut out = vec![f64::NAN; orbits.len() * (steps + 1) * n];
    for (k, orbit) in orbits.iter().enumerate() {
        for (i, state) in orbit.iter().enumerate() {
            out[(k * (steps + 1) + i) * n..][..n].copy_from_slice(state);
        }
    }
    Ok(PyArray1::from_vec(py, out).reshape([orbits.len(), steps + 1, n])?.into_any())
}
