//! `lagrangian.Expr`: an exact expression (the engine's canonical hash-consed DAG) with the
//! parser declarations it was read with, so names in `diff`, `subs` and arithmetic are read
//! the same way (declared functions, positive symbols).

use std::collections::{BTreeSet, HashMap};

use lagrangian::compile::Tape;
use lagrangian::parse::{parse_with, Declarations};
use lagrangian::print::{render, Format};
use lagrangian::{Expr, Symbol};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt, PyString, PyTuple};

use crate::errors::{exc, PyResultExt};

/// An exact symbolic expression.
///
/// Build one from text (``Expr("1/2 m x'^2 - 1/2 k x^2", positive=["m", "k"])``) or with the
/// arithmetic operators; numbers are exact rationals (``0.1`` is ``1/10``). ``str(e)`` is the
/// plain form, which parses back to the identical expression; ``e.latex()`` and Jupyter's
/// rendering use the LaTeX printer.
#[pyclass(name = "Expr", module = "lagrangian", frozen, eq, hash)]
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct PyExpr {
    pub e: Expr,
    pub decls: Decls,
}

/// Parser declarations, hashable and comparable so `Expr` can be (they never affect equality
/// of two expressions read with the same names: the symbols themselves carry positivity).
#[derive(Clone, Debug, Default)]
pub struct Decls(pub Declarations);

impl PartialEq for Decls {
    fn eq(&self, _: &Decls) -> bool {
        true
    }
}
impl Eq for Decls {}
impl std::hash::Hash for Decls {
    fn hash<H: std::hash::Hasher>(&self, _: &mut H) {}
}

pub fn declarations(positive: Option<Vec<String>>, functions: Option<Vec<String>>) -> Declarations {
    Declarations::new().with_positive(positive.unwrap_or_default()).with_functions(functions.unwrap_or_default())
}

impl PyExpr {
    pub fn new(e: Expr, decls: &Declarations) -> PyExpr {
        PyExpr { e, decls: Decls(decls.clone()) }
    }
}

/// The exact rational nearest a Python float: its shortest round-trip spelling, parsed (so
/// `0.1` is `1/10`, as if typed).
fn float_expr(x: f64) -> PyResult<Expr> {
    if !x.is_finite() {
        return Err(exc::ArgumentError::new_err(format!(
            "{x} cannot enter an exact expression (only finite numbers can)"
        )));
    }
    lagrangian::parse(&format!("{x:?}")).py()
}

/// Reads an operand: an `Expr`, an int, a float or (when `allow_text`) text to parse.
pub fn to_expr(obj: &Bound<'_, PyAny>, decls: &Declarations, allow_text: bool) -> PyResult<Expr> {
    if let Ok(e) = obj.downcast::<PyExpr>() {
        return Ok(e.get().e.clone());
    }
    if obj.is_instance_of::<pyo3::types::PyBool>() {
        return Err(PyTypeError::new_err("a bool is not a number here"));
    }
    if obj.is_instance_of::<PyInt>() {
        let text: String = obj.str()?.extract()?;
        return lagrangian::parse(&text).py();
    }
    if obj.is_instance_of::<PyFloat>() {
        return float_expr(obj.extract()?);
    }
    if allow_text {
        if let Ok(s) = obj.downcast::<PyString>() {
            let text: String = s.extract()?;
            return parse_with(&text, decls).py();
        }
    }
    if let Ok(x) = obj.extract::<f64>() {
        // NumPy scalars and other objects with __float__.
        return float_expr(x);
    }
    Err(PyTypeError::new_err(format!(
        "expected an Expr, a number{}, got {}",
        if allow_text { " or text" } else { "" },
        obj.get_type().name()?
    )))
}

/// Reads a symbol given as a name (`"θ"`, `"θ'"`, `"p_x"`) or a symbol `Expr`.
pub fn to_symbol(obj: &Bound<'_, PyAny>, decls: &Declarations) -> PyResult<Symbol> {
    let e = to_expr(obj, decls, true)?;
    match e.as_sym() {
        Some(s) => Ok(s.clone()),
        None => Err(exc::ArgumentError::new_err(format!("expected a symbol name, got `{e}`"))),
    }
}

/// What an `Expr` pickles as: its plain text, positive symbols and declared functions.
type ExprState = (String, Vec<String>, Vec<String>);

/// The value of an `evaluate` argument: a float, or a flat float64 array after broadcasting.
enum Column {
    Scalar(f64),
    Array(Vec<f64>),
}

#[pymethods]
impl PyExpr {
    /// Parses ``text``. ``positive`` names symbols known to be positive (masses, lengths),
    /// ``functions`` names undefined functions (``V`` so that ``V(r)`` is a call).
    #[new]
    #[pyo3(signature = (text, *, positive=None, functions=None))]
    fn py_new(text: &str, positive: Option<Vec<String>>, functions: Option<Vec<String>>) -> PyResult<PyExpr> {
        let decls = declarations(positive, functions);
        let e = parse_with(text, &decls).py()?;
        Ok(PyExpr::new(e, &decls))
    }

    fn __str__(&self) -> String {
        render(&self.e, Format::Plain)
    }

    fn __repr__(&self) -> String {
        format!("Expr({:?})", render(&self.e, Format::Plain))
    }

    /// The plain form (ASCII operators, primes for time derivatives); parses back to the
    /// identical expression.
    fn plain(&self) -> String {
        render(&self.e, Format::Plain)
    }

    /// The Unicode form (``θ̇``, ``θ̈``, superscript powers).
    fn unicode(&self) -> String {
        render(&self.e, Format::Unicode)
    }

    /// The LaTeX form (``\dot{\theta}``, ``\frac``), without math delimiters.
    fn latex(&self) -> String {
        render(&self.e, Format::Latex)
    }

    /// Jupyter's rich display: the LaTeX form in display style.
    fn _repr_latex_(&self) -> String {
        format!("$\\displaystyle {}$", render(&self.e, Format::Latex))
    }

    /// The partial derivative by a symbol (``"x"``, ``"θ'"``, ``"t"``); time derivatives of
    /// coordinates are separate symbols here, as in ``∂L/∂q'``.
    fn diff(&self, var: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        let s = to_symbol(var, &self.decls.0)?;
        Ok(PyExpr::new(lagrangian::diff::diff(&self.e, &s), &self.decls.0))
    }

    /// The total time derivative ``d/dt`` along a path, where ``coords`` are the
    /// time-dependent coordinates (``x`` → ``x'``, ``x'`` → ``x''``). By default every symbol
    /// that occurs with a prime counts as a coordinate.
    #[pyo3(signature = (coords=None))]
    fn dt(&self, coords: Option<Vec<String>>) -> PyExpr {
        let names: BTreeSet<String> = match coords {
            Some(c) => c.into_iter().collect(),
            None => lagrangian::diff::primed_names(&self.e),
        };
        PyExpr::new(lagrangian::diff::dt(&self.e, &names), &self.decls.0)
    }

    /// Simplifies with the e-graph (under the engine's default budgets; the result is never
    /// worse than the input and agrees with it numerically).
    fn simplify(&self, py: Python<'_>) -> PyExpr {
        let e = self.e.clone();
        let s = py.allow_threads(move || lagrangian::simplify::simplify(&e));
        PyExpr::new(s, &self.decls.0)
    }

    /// Substitutes expressions for symbols: ``e.subs({"x": "r cos(φ)", "k": 2})``. Keys are
    /// names or symbol ``Expr``s; values are ``Expr``s, numbers (exact) or text.
    fn subs(&self, mapping: &Bound<'_, PyDict>) -> PyResult<PyExpr> {
        let mut map = HashMap::new();
        for (k, v) in mapping.iter() {
            let s = to_symbol(&k, &self.decls.0)?;
            map.insert(s, to_expr(&v, &self.decls.0, true)?);
        }
        Ok(PyExpr::new(self.e.subs(&map), &self.decls.0))
    }

    /// The names of the free symbols, sorted (``t`` included when present); the public
    /// ``free_symbols`` property reads it (``lagrangian/_display.py``).
    fn _free_symbols(&self) -> Vec<String> {
        let mut v: Vec<String> = self.e.free_symbols().iter().map(|s| s.to_string()).collect();
        v.sort();
        v.dedup();
        v
    }

    /// The number of operations of the printed form.
    fn op_count(&self) -> usize {
        self.e.op_count()
    }

    /// Evaluates numerically. Values are given as a dict and/or keywords, by plain name
    /// (``e.evaluate({"θ'": 0.1}, θ=np.linspace(0, 1, 5))``); scalars give a float, NumPy
    /// arrays broadcast against each other and give a float64 array of their common shape
    /// (evaluated by the compiled tape, with the GIL released).
    #[pyo3(signature = (values=None, **kwargs))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        values: Option<&Bound<'py, PyDict>>,
        kwargs: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<PyObject> {
        let mut names: Vec<String> = Vec::new();
        let mut objs: Vec<Bound<'py, PyAny>> = Vec::new();
        for d in [values, kwargs].into_iter().flatten() {
            for (k, v) in d.iter() {
                let name =
                    if let Ok(e) = k.downcast::<PyExpr>() { e.get().e.to_string() } else { k.extract::<String>()? };
                if let Some(i) = names.iter().position(|n| *n == name) {
                    objs[i] = v;
                } else {
                    names.push(name);
                    objs.push(v);
                }
            }
        }
        let np = py.import("numpy")?;
        let any_array = objs.iter().any(|o| !(o.is_instance_of::<PyFloat>() || o.is_instance_of::<PyInt>()));
        if !any_array {
            let env: HashMap<String, f64> = names
                .iter()
                .cloned()
                .zip(objs.iter().map(|o| o.extract::<f64>()))
                .map(|(n, v)| v.map(|v| (n, v)))
                .collect::<PyResult<_>>()?;
            let x = lagrangian::eval::eval(&self.e, &env).py()?;
            return Ok(x.into_pyobject(py)?.into_any().unbind());
        }
        // Broadcast the array arguments (NumPy's rules), then run the tape point by point.
        let arrays: Vec<Bound<'py, PyAny>> = objs
            .iter()
            .map(|o| np.call_method1("asarray", (o,)).and_then(|a| a.call_method1("astype", ("float64",))))
            .collect::<PyResult<_>>()?;
        let b = np.call_method1("broadcast_arrays", PyTuple::new(py, &arrays)?)?;
        let b: Vec<Bound<'py, PyAny>> = b.extract()?;
        let shape: Vec<usize> = if let Some(first) = b.first() { first.getattr("shape")?.extract()? } else { vec![] };
        let mut cols = Vec::with_capacity(b.len());
        for a in &b {
            let flat = np.call_method1("ascontiguousarray", (a.call_method0("ravel")?,))?;
            let v = crate::convert::f64_vec(&flat)?;
            if v.len() == 1 && shape.is_empty() {
                cols.push(Column::Scalar(v[0]));
            } else {
                cols.push(Column::Array(v));
            }
        }
        let points: usize = shape.iter().product();
        // Every free symbol must have a value; the compiler's error names the first missing.
        let free: Vec<String> = self._free_symbols();
        let input_idx: Vec<usize> = free
            .iter()
            .map(|s| {
                names
                    .iter()
                    .position(|n| n == s)
                    .ok_or_else(|| exc::EvalError::new_err(format!("`{s}` has no value (pass it to evaluate)")))
            })
            .collect::<PyResult<_>>()?;
        let inputs: Vec<&str> = free.iter().map(String::as_str).collect();
        let tape = Tape::compile(std::slice::from_ref(&self.e), &inputs, &[]).py()?;
        let out = py.allow_threads(|| {
            let mut x = vec![0.0; inputs.len()];
            let mut o = [0.0];
            let mut out = Vec::with_capacity(points);
            for k in 0..points {
                for (j, &i) in input_idx.iter().enumerate() {
                    x[j] = match &cols[i] {
                        Column::Scalar(v) => *v,
                        Column::Array(a) => a[k],
                    };
                }
                tape.eval(&x, &mut o);
                out.push(o[0]);
            }
            out
        });
        let arr = PyArray1::from_vec(py, out);
        Ok(arr.reshape(shape)?.into_any().unbind())
    }

    fn __add__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(self.e.plus(&to_expr(other, &self.decls.0, false)?), &self.decls.0))
    }
    fn __radd__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(to_expr(other, &self.decls.0, false)?.plus(&self.e), &self.decls.0))
    }
    fn __sub__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(self.e.minus(&to_expr(other, &self.decls.0, false)?), &self.decls.0))
    }
    fn __rsub__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(to_expr(other, &self.decls.0, false)?.minus(&self.e), &self.decls.0))
    }
    fn __mul__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(self.e.times(&to_expr(other, &self.decls.0, false)?), &self.decls.0))
    }
    fn __rmul__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(to_expr(other, &self.decls.0, false)?.times(&self.e), &self.decls.0))
    }
    fn __truediv__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(self.e.over(&to_expr(other, &self.decls.0, false)?), &self.decls.0))
    }
    fn __rtruediv__(&self, other: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        Ok(PyExpr::new(to_expr(other, &self.decls.0, false)?.over(&self.e), &self.decls.0))
    }
    fn __pow__(&self, other: &Bound<'_, PyAny>, modulo: Option<&Bound<'_, PyAny>>) -> PyResult<PyExpr> {
        if modulo.is_some() {
            return Err(PyTypeError::new_err("pow() with a modulus is not defined for expressions"));
        }
        Ok(PyExpr::new(Expr::pow(self.e.clone(), to_expr(other, &self.decls.0, false)?), &self.decls.0))
    }
    fn __rpow__(&self, other: &Bound<'_, PyAny>, modulo: Option<&Bound<'_, PyAny>>) -> PyResult<PyExpr> {
        if modulo.is_some() {
            return Err(PyTypeError::new_err("pow() with a modulus is not defined for expressions"));
        }
        Ok(PyExpr::new(Expr::pow(to_expr(other, &self.decls.0, false)?, self.e.clone()), &self.decls.0))
    }
    fn __neg__(&self) -> PyExpr {
        PyExpr::new(self.e.neg(), &self.decls.0)
    }
    fn __pos__(&self) -> PyExpr {
        self.clone()
    }

    /// Pickles as the plain text and the declarations; unpickling parses it again, which gives
    /// the identical expression.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, ExprState)> {
        let f = py.import("lagrangian._pickle")?.getattr("_expr")?;
        let d = &self.decls.0;
        Ok((
            f,
            (
                render(&self.e, Format::Plain),
                d.positive.iter().cloned().collect(),
                d.functions.iter().cloned().collect(),
            ),
        ))
    }
}

/// Parses ``text`` into an :class:`Expr` (the same as ``Expr(text, ...)``).
#[pyfunction]
#[pyo3(signature = (text, *, positive=None, functions=None))]
pub fn parse(text: &str, positive: Option<Vec<String>>, functions: Option<Vec<String>>) -> PyResult<PyExpr> {
    PyExpr::py_new(text, positive, functions)
}
