//! `lagrangian.lambdify(args, exprs)`: expressions compiled once into a NumPy function, the
//! engine's counterpart of SymPy's `lambdify`. The expressions go through the same compiled
//! tape as the equations of motion (shared subexpressions computed once), so a call costs one
//! tape run per point with the GIL released, not a Python expression tree.

use std::sync::Arc;

use lagrangian::compile::Tape;
use lagrangian::print::{render, Format};
use lagrangian::Expr;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use crate::convert::f64_vec;
use crate::errors::{exc, PyResultExt};
use crate::expr::{to_expr, to_symbol, PyExpr};

/// What a `Lambdified` pickles as: the unpickling function, the argument names, the expressions.
type Reduced<'py> = (Bound<'py, PyAny>, (Vec<String>, PyObject));

/// A compiled function of ``args`` (returned by :func:`lambdify`).
///
/// ``f(a, b, …)`` takes one value per argument, numbers or arrays that broadcast against one
/// another (NumPy's rules), and returns a float64 array of the broadcast shape (a float for
/// scalars); for a list of expressions the result has one more leading axis, one entry per
/// expression.
#[pyclass(name = "Lambdified", module = "lagrangian", frozen)]
pub struct Lambdified {
    tape: Arc<Tape>,
    args: Vec<String>,
    exprs: Vec<PyExpr>,
    /// Whether one expression was given (not a list): the result has no leading axis.
    single: bool,
}

#[pymethods]
impl Lambdified {
    /// The argument names, in order.
    #[getter]
    fn args(&self) -> Vec<String> {
        self.args.clone()
    }

    /// The expressions it computes.
    #[getter]
    fn exprs(&self) -> Vec<PyExpr> {
        self.exprs.clone()
    }

    fn __repr__(&self) -> String {
        let body: Vec<String> = self.exprs.iter().map(|e| render(&e.e, Format::Plain)).collect();
        format!("Lambdified(({}) -> {})", self.args.join(", "), body.join(", "))
    }

    /// Pickles as its argument names and expressions, compiled again where unpickled.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Reduced<'py>> {
        let f = py.import("lagrangian._pickle")?.getattr("_lambdified")?;
        let exprs: PyObject = if self.single {
            self.exprs[0].clone().into_pyobject(py)?.into_any().unbind()
        } else {
            PyList::new(py, self.exprs.clone())?.into_any().unbind()
        };
        Ok((f, (self.args.clone(), exprs)))
    }

    #[pyo3(signature = (*values))]
    fn __call__<'py>(&self, py: Python<'py>, values: &Bound<'py, PyTuple>) -> PyResult<PyObject> {
        if values.len() != self.args.len() {
            return Err(exc::ArgumentError::new_err(format!(
                "this function takes {} argument(s) ({}), got {}",
                self.args.len(),
                self.args.join(", "),
                values.len()
            )));
        }
        let np = py.import("numpy")?;
        let arrays: Vec<Bound<'py, PyAny>> =
            values.iter().map(|o| np.call_method1("asarray", (o, "float64"))).collect::<PyResult<_>>()?;
        let scalar = arrays.iter().all(|a| a.getattr("ndim").and_then(|d| d.extract::<usize>()).unwrap_or(1) == 0);
        let shape: Vec<usize> = if arrays.is_empty() {
            vec![]
        } else {
            np.call_method1(
                "broadcast_shapes",
                PyTuple::new(py, arrays.iter().map(|a| a.getattr("shape")).collect::<PyResult<Vec<_>>>()?)?,
            )?
            .extract()?
        };
        let points: usize = shape.iter().product();
        let cols: Vec<Vec<f64>> = arrays
            .iter()
            .map(|a| {
                let b = np.call_method1("broadcast_to", (a, PyTuple::new(py, &shape)?))?;
                f64_vec(&np.call_method1("ascontiguousarray", (b.call_method0("ravel")?,))?)
            })
            .collect::<PyResult<_>>()?;
        let m = self.exprs.len();
        let tape = &self.tape;
        let out = py.allow_threads(|| {
            let mut x = vec![0.0; cols.len()];
            let mut o = vec![0.0; m];
            // One row per expression: the (m,) + shape layout, C order.
            let mut out = vec![0.0; m * points];
            for k in 0..points {
                for (j, c) in cols.iter().enumerate() {
                    x[j] = c[k];
                }
                tape.eval(&x, &mut o);
                for (i, v) in o.iter().enumerate() {
                    out[i * points + k] = *v;
                }
            }
            out
        });
        if scalar && self.single {
            return Ok(out[0].into_pyobject(py)?.into_any().unbind());
        }
        let mut full = Vec::with_capacity(shape.len() + 1);
        if !self.single {
            full.push(m);
        }
        full.extend_from_slice(&shape);
        Ok(PyArray1::from_vec(py, out).reshape(full)?.into_any().unbind())
    }
}

/// ``lambdify(args, exprs)``: compiles ``exprs`` (one :class:`Expr` or text, or a list of
/// them) into a NumPy function of the symbols ``args`` (names like ``"θ"``, ``"θ'"``, ``"t"``
/// or symbol ``Expr``s), like SymPy's ``lambdify``. Every free symbol must be an argument (a
/// parameter is bound first with ``subs``); a symbol missing is refused naming it, never read
/// as 0.
#[pyfunction]
#[pyo3(signature = (args, exprs))]
pub fn lambdify(args: &Bound<'_, PyAny>, exprs: &Bound<'_, PyAny>) -> PyResult<Lambdified> {
    let single = exprs.downcast::<PyExpr>().is_ok() || exprs.is_instance_of::<pyo3::types::PyString>();
    let items: Vec<Bound<'_, PyAny>> =
        if single { vec![exprs.clone()] } else { exprs.try_iter()?.collect::<PyResult<_>>()? };
    let decls =
        items.iter().find_map(|e| e.downcast::<PyExpr>().ok().map(|e| e.get().decls.0.clone())).unwrap_or_default();
    let es: Vec<Expr> = items.iter().map(|e| to_expr(e, &decls, true)).collect::<PyResult<_>>()?;
    let arg_items: Vec<Bound<'_, PyAny>> =
        if args.is_instance_of::<pyo3::types::PyString>() || args.downcast::<PyExpr>().is_ok() {
            vec![args.clone()]
        } else {
            args.try_iter()?.collect::<PyResult<_>>()?
        };
    let names: Vec<String> =
        arg_items.iter().map(|a| to_symbol(a, &decls).map(|s| s.to_string())).collect::<PyResult<_>>()?;
    let missing: std::collections::BTreeSet<String> =
        es.iter().flat_map(|e| e.free_symbols()).map(|s| s.to_string()).filter(|s| !names.contains(s)).collect();
    if !missing.is_empty() {
        let list: Vec<String> = missing.iter().map(|n| format!("`{n}`")).collect();
        return Err(exc::ArgumentError::new_err(format!(
            "{} {} not among the arguments ({}); add {} to args, or give {} a value first with .subs({{…}})",
            list.join(", "),
            if list.len() == 1 { "is" } else { "are" },
            names.join(", "),
            if list.len() == 1 { "it" } else { "them" },
            if list.len() == 1 { "it" } else { "them" },
        )));
    }
    let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
    let tape = Tape::compile(&es, &inputs, &[]).py()?;
    Ok(Lambdified {
        tape: Arc::new(tape),
        args: names,
        exprs: es.into_iter().map(|e| PyExpr::new(e, &decls)).collect(),
        single,
    })
}
