//! Python arguments into engine values: NumPy arrays into `f64` slices, `t_span`, `y0`, the
//! tolerances and the method name. The bottom layer of the binding next to `errors.rs`: it
//! knows no Python class of this crate, so `expr.rs`, `system.rs` and `sim.rs` all read their
//! arguments here without importing one another.

use lagrangian::simulate::{self, MethodId, SimulateError};
use numpy::{PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::exc;

/// Reads a float64 array of any shape (converting lists and integer arrays), C-contiguous
/// and aligned.
pub fn float_array<'py>(y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    // Aligned as well as C-contiguous: arrays unpickled from a byte stream (a Dask worker's
    // input) may start at any address, and a slice needs an aligned one.
    let np = y.py().import("numpy")?;
    np.call_method1("require", (y, "float64", "CA"))
}

/// The elements of an array as float64 in C order. (An empty array is handled apart: its
/// data pointer need not be aligned, which a slice requires.)
pub fn f64_vec(a: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let a = float_array(a)?;
    let arr = a.downcast::<numpy::PyArrayDyn<f64>>()?.readonly();
    if arr.len() == 0 {
        return Ok(Vec::new());
    }
    Ok(arr.as_slice()?.to_vec())
}

/// Reads ``t_span``: any two numbers (a tuple, a list, a NumPy array), as SciPy takes it.
pub fn time_span(t_span: &Bound<'_, PyAny>) -> PyResult<(f64, f64)> {
    let bad = || {
        exc::ArgumentError::new_err(format!(
            "t_span must be two numbers (t0, t1): a tuple, a list or an array; got {}",
            t_span.repr().map(|r| r.to_string()).unwrap_or_else(|_| "an unprintable object".into())
        ))
    };
    if t_span.is_instance_of::<pyo3::types::PyString>() {
        return Err(bad());
    }
    let a = float_array(t_span).map_err(|_| bad())?;
    let v = f64_vec(&a.call_method0("ravel")?).map_err(|_| bad())?;
    let shape: Vec<usize> = a.getattr("shape")?.extract()?;
    match (shape.as_slice(), v.as_slice()) {
        ([2], [t0, t1]) => Ok((*t0, *t1)),
        _ => Err(bad()),
    }
}

/// Reads `y0`: an array of `n` numbers, or a dict by state name.
pub fn initial_state(y0: &Bound<'_, PyAny>, names: &[String]) -> PyResult<Vec<f64>> {
    if let Ok(d) = y0.downcast::<PyDict>() {
        let mut out = vec![f64::NAN; names.len()];
        for (k, v) in d.iter() {
            let k: String = k.extract()?;
            let Some(i) = names.iter().position(|n| *n == k) else {
                return Err(exc::ArgumentError::new_err(format!(
                    "`{k}` is not a state variable of this integration (the state is {})",
                    names.join(", ")
                )));
            };
            out[i] = v.extract()?;
        }
        finite_state(&out, names)?;
        if let Some(i) = out.iter().position(|v| v.is_nan()) {
            return Err(exc::ArgumentError::new_err(format!(
                "no initial value for `{}` (the state is {})",
                names[i],
                names.join(", ")
            )));
        }
        return Ok(out);
    }
    let a = float_array(y0)?;
    let shape: Vec<usize> = a.getattr("shape")?.extract()?;
    if shape.len() != 1 || shape[0] != names.len() {
        return Err(exc::ArgumentError::new_err(format!(
            "y0 has shape {shape:?}; expected ({},) for the state ({})",
            names.len(),
            names.join(", ")
        )));
    }
    let v = f64_vec(&a)?;
    finite_state(&v, names)?;
    Ok(v)
}

/// Reads ``t_span`` of a call taking ``(t_span, y0, …)`` (``ensemble``, the order of
/// ``integrate`` and of SciPy's ``solve_ivp``). When ``t_span`` is not two numbers but ``y0``
/// is, the caller wrote the order this package used to take, ``ensemble(y0, t_span)``: that is
/// refused naming the order, never read with the arguments swapped.
pub fn span_then_states(t_span: &Bound<'_, PyAny>, y0: &Bound<'_, PyAny>, call: &str) -> PyResult<(f64, f64)> {
    time_span(t_span).map_err(|e| {
        if time_span(y0).is_ok() {
            exc::ArgumentError::new_err(format!(
                "{call} takes t_span first: {call}(t_span, y0, …), as integrate and scipy's solve_ivp do; the arguments look swapped (the first is not two numbers, the second is)"
            ))
        } else {
            e
        }
    })
}

/// Refuses a start with a NaN or an infinite component: an argument error (`ValueError`),
/// not a failed integration.
pub fn finite_state(y0: &[f64], names: &[String]) -> PyResult<()> {
    match y0.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(exc::ArgumentError::new_err(format!(
            "the initial value of `{}` is {}: every component of y0 must be a finite number (the state is {})",
            names[i],
            y0[i],
            names.join(", ")
        ))),
        None => Ok(()),
    }
}

/// SciPy's names for the tolerances: ``rtol`` (``tol`` is its older name here, kept as an
/// alias) and ``atol``. Both names at once must agree.
pub fn relative_tolerance(rtol: Option<f64>, tol: Option<f64>) -> PyResult<Option<f64>> {
    match (rtol, tol) {
        (Some(r), Some(t)) if r != t => Err(exc::ArgumentError::new_err(format!(
            "rtol={r} and tol={t} disagree: tol is another name for rtol, so give one of them"
        ))),
        (r, t) => Ok(r.or(t)),
    }
}

/// The method called `name`, or a `ValueError` with the closest name and the list.
pub fn method(name: &str) -> PyResult<MethodId> {
    MethodId::from_name(name).ok_or_else(|| {
        let e = SimulateError::unknown_method(name);
        let list = simulate::method::method_names();
        match &e {
            SimulateError::UnknownMethod { suggestion: Some(s), .. } => exc::ArgumentError::new_err(format!(
                "unknown method `{name}`: did you mean `{s}`? (the methods are {list})"
            )),
            _ => exc::ArgumentError::new_err(format!("unknown method `{name}`; the methods are {list}")),
        }
    })
}
