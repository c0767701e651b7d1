//! The numeric side of `System`: compiled right-hand sides callable from Python (one state
//! or a batch; a drop-in `fun=` for SciPy's `solve_ivp`), `integrate` returning NumPy arrays
//! and `ensemble` over many initial states. Every integration runs with the GIL released.
//!
//! Every run goes through the engine's one simulation layer ([`lagrangian::simulate`]): the
//! method registry, the choice of equations for the system (with its typed refusal when a
//! method cannot run it), the compiled system and the drive loop. This file only translates
//! Python arguments into a [`RunOptions`] and the [`Trajectory`] back into arrays.
//! Progress bars and Ctrl-C are `progress.rs`'s; reading arguments is `convert.rs`'s.

use std::sync::Arc;

use lagrangian::integrate::{Crossing, EventRecord};
use lagrangian::mechanics::System;
use lagrangian::simulate::{
    self, Compiled, CompiledSystem, Derivations, Equations, EventSpec, Form, MethodId, RunOptions, Sampling,
    SimulateError, Trajectory,
};
use lagrangian::Expr;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{f64_vec, float_array, initial_state, method, relative_tolerance, span_then_states, time_span};
use crate::errors::{exc, integration_error, PyResultExt};
use crate::expr::to_expr;
use crate::progress::{progress_mode, with_progress, Control};
use crate::system::{CompiledKey, PySystem};

/// The derivations a formulation needs, from the process's derivation cache (`cache.rs`), so a
/// worker process or a new parameter set does not derive them again.
struct Cached;

impl Derivations for Cached {
    fn mass_matrix(&self, sys: &System) -> Result<(Vec<Vec<Expr>>, Vec<Expr>), lagrangian::mechanics::MechanicsError> {
        crate::cache::mass_matrix(sys)
    }
    fn hamiltonian(&self, sys: &System) -> Result<Expr, lagrangian::mechanics::MechanicsError> {
        crate::cache::hamiltonian(sys)
    }
}

/// A simulation error as Python sees it: a request the engine refuses is an `ArgumentError`
/// (a `ValueError`, with a hint in Python's terms), a start where the equations have no value
/// an `RhsError`, a failed run an `IntegrationError`, Ctrl-C a `KeyboardInterrupt`.
pub fn simulate_error(py: Python<'_>, e: SimulateError) -> PyErr {
    match e {
        SimulateError::Integrate { error, names, hint } => {
            let msg = SimulateError::Integrate { error: error.clone(), names, hint }.to_string();
            integration_error(py, error, msg)
        }
        SimulateError::Cancelled => PyKeyboardInterrupt::new_err("integration interrupted"),
        SimulateError::Compile(c) => exc::CompileError::new_err(c.to_string()),
        SimulateError::Mechanics(m) => exc::MechanicsError::new_err(m.to_string()),
        SimulateError::InitialState(reason) => exc::RhsError::new_err(format!("at the initial state: {reason}")),
        other => {
            let msg = match python_hint(&other).or_else(|| other.hint()) {
                Some(h) => format!("{} ({h})", python_message(&other)),
                None => python_message(&other),
            };
            exc::ArgumentError::new_err(msg)
        }
    }
}

/// The engine's message, with the tolerance named as the Python argument (`rtol`).
fn python_message(e: &SimulateError) -> String {
    match e {
        SimulateError::ToleranceBelowFloor { tol, floor, .. } => {
            format!("rtol={tol:e} is below what f64 can meet; the smallest usable rtol is {floor:.2e}")
        }
        other => other.to_string(),
    }
}

/// What would work, in this package's keyword arguments, where the engine's hint is written
/// in the scene language (`dt = 0.01`, `steps = 1000`, `tol = 1e-10`, `help simulate`).
fn python_hint(e: &SimulateError) -> Option<String> {
    let list = || simulate::method::method_names();
    Some(match e {
        SimulateError::UnknownMethod { suggestion: Some(s), .. } => {
            format!("did you mean `{s}`? lagrangian.METHODS lists them: {}", list())
        }
        SimulateError::UnknownMethod { suggestion: None, .. } => format!("lagrangian.METHODS lists them: {}", list()),
        SimulateError::NeedsStep { .. } => "pass a step, dt=0.01, or use an adaptive method such as `dop853`".into(),
        SimulateError::NeedsTolerance { .. } => {
            "leave out dt= and set rtol= (and atol=) if needed, or pick a fixed-step method such as `gauss6` or `rk4`"
                .into()
        }
        SimulateError::ToleranceBelowFloor { method: MethodId::Taylor, .. } => {
            "leave out rtol=: the Taylor method defaults to machine precision".into()
        }
        SimulateError::ToleranceBelowFloor { .. } => {
            "use rtol=1e-14 (DOP853 at 1e-14 is already near the rounding floor)".into()
        }
        _ => return None,
    })
}

/// The compiled system of `s` under `key`, from its cache or compiled now (GIL released).
fn compiled_with(
    py: Python<'_>,
    s: &PySystem,
    key: CompiledKey,
    build: impl FnOnce(&System) -> Result<Compiled, SimulateError> + Send,
) -> PyResult<Arc<Compiled>> {
    if let Some(c) = s.compiled.lock().ok().and_then(|m| m.get(&key).cloned()) {
        return Ok(c);
    }
    let sys = &s.sys;
    crate::cache::init(py);
    let c = Arc::new(py.allow_threads(|| build(sys)).map_err(|e| simulate_error(py, e))?);
    if let Ok(mut m) = s.compiled.lock() {
        m.insert(key, c.clone());
    }
    Ok(c)
}

/// The compiled system of the equations `eq` named by `System.compile(formulation=…)`.
fn compiled_for(py: Python<'_>, s: &PySystem, eq: Equations, form: Form) -> PyResult<Arc<Compiled>> {
    compiled_with(py, s, CompiledKey::Named(eq, form), |sys| {
        let f = simulate::formulation_of(sys, eq, &Cached)?;
        simulate::compile_formulation(sys, f, form, &[])
    })
}

/// The compiled system `method` integrates for `s`, or the engine's typed refusal naming the
/// methods that can run it. Cached by the method's form: the methods sharing a form share the
/// route, so a cached value was refused or accepted for them all alike.
pub fn compiled_for_method(py: Python<'_>, s: &PySystem, method: MethodId) -> PyResult<Arc<Compiled>> {
    compiled_with(py, s, CompiledKey::Method(method.form()), |sys| {
        simulate::compile_system_with(sys, method, &[], &Cached)
    })
}

/// The methods the binding runs: every method of the registry.
pub fn binding_methods() -> impl Iterator<Item = MethodId> {
    MethodId::all()
}

/// A compiled right-hand side ``f(t, y)`` (returned by :meth:`System.compile`).
///
/// ``f(t, y)`` with ``y`` of shape ``(n,)`` returns ``dy/dt`` of shape ``(n,)``; with ``y`` of
/// shape ``(n, k)`` (``k`` states as columns, SciPy's ``vectorized=True`` convention) it
/// returns ``(n, k)``. It is a drop-in ``fun=`` for ``scipy.integrate.solve_ivp``. A state
/// where the equations have no value (a singular mass matrix, a non-finite result) raises
/// :class:`RhsError`. ``f.jac(t, y)`` is the exact Jacobian, a drop-in ``jac=`` for
/// ``solve_ivp``'s implicit methods (Radau, BDF, LSODA).
#[pyclass(name = "CompiledRhs", module = "lagrangian", frozen)]
pub struct CompiledRhs {
    c: Arc<Compiled>,
    names: Vec<String>,
    /// The system and the equations, to compile the Jacobian on first use.
    system: Py<PySystem>,
    equations: Equations,
    jac: std::sync::OnceLock<Arc<Compiled>>,
}

impl CompiledRhs {
    /// The same equations with their exact Jacobian, compiled once.
    fn jacobian_code(&self, py: Python<'_>) -> PyResult<Arc<Compiled>> {
        if let Some(c) = self.jac.get() {
            return Ok(c.clone());
        }
        // A split integrates Hamilton's equations in the same state `(q, p)`.
        let eq = match self.equations {
            Equations::Separable => Equations::Hamiltonian,
            other => other,
        };
        let c = compiled_for(py, self.system.bind(py).get(), eq, Form::RhsWithJacobian)?;
        let _ = self.jac.set(c.clone());
        Ok(c)
    }

    fn eval_one(&self, t: f64, y: &[f64], dy: &mut [f64]) -> PyResult<()> {
        rhs_of(&self.c)?.try_eval(t, y, dy).map_err(|e| exc::RhsError::new_err(e.reason))
    }
}

#[pymethods]
impl CompiledRhs {
    /// The dimension ``n`` of the state.
    #[getter]
    fn dim(&self) -> usize {
        self.names.len()
    }

    /// The state variable names, in order.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    fn __repr__(&self) -> String {
        format!("CompiledRhs(state = ({}))", self.names.join(", "))
    }

    /// Pickles as its system and formulation, compiled again where it is unpickled (compiled
    /// code does not cross a process boundary; the derivation cache makes it cheap).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Reduced<'py>> {
        let f = py.import("lagrangian._pickle")?.getattr("_compiled")?;
        Ok((f, (self.system.clone_ref(py), formulation_name(self.equations))))
    }

    /// Equal when compiled from the same system (source, options and values) and formulation.
    fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> bool {
        let Ok(o) = other.downcast::<CompiledRhs>() else { return false };
        let o = o.get();
        self.equations == o.equations && self.system.bind(py).get().spec() == o.system.bind(py).get().spec()
    }

    /// The exact Jacobian ``J[i, j] = ∂f_i/∂y_j`` at ``(t, y)``, shape ``(n, n)``, from the
    /// symbolic derivatives of the equations compiled into a tape (on the first call; the
    /// same Jacobian the engine's implicit methods use). Pass it as
    /// ``solve_ivp(f, …, method="Radau", jac=f.jac)``.
    fn jac<'py>(&self, py: Python<'py>, t: f64, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.names.len();
        let c = self.jacobian_code(py)?;
        let mut j = vec![0.0; n * n];
        // Fast path, as in `__call__`: an aligned contiguous float64 vector (what solve_ivp
        // passes) is read in place; `numpy.require` alone cost more than the Jacobian.
        let fast = y.extract::<PyReadonlyArray1<'py, f64>>().ok();
        let owned;
        let v: &[f64] = match fast.as_ref().and_then(|v| v.as_slice().ok()) {
            Some(s) => s,
            None => {
                let a = float_array(y)?;
                let shape: Vec<usize> = a.getattr("shape")?.extract()?;
                if shape != [n] {
                    return Err(exc::ArgumentError::new_err(format!(
                        "y has shape {shape:?}; the Jacobian takes one state of shape ({n},) ({})",
                        self.names.join(", ")
                    )));
                }
                owned = f64_vec(&a)?;
                &owned
            }
        };
        if v.len() != n {
            return Err(exc::ArgumentError::new_err(format!(
                "y has shape ({},); the Jacobian takes one state of shape ({n},) ({})",
                v.len(),
                self.names.join(", ")
            )));
        }
        match c.system.try_jacobian(t, v, &mut j) {
            Some(r) => r.py()?,
            None => return Err(exc::ArgumentError::new_err("this formulation has no compiled Jacobian")),
        }
        Ok(PyArray1::from_vec(py, j).reshape([n, n])?.into_any())
    }

    fn __call__<'py>(&self, py: Python<'py>, t: f64, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.names.len();
        // Fast path: a contiguous float64 vector, as solve_ivp passes.
        if let Ok(v) = y.extract::<PyReadonlyArray1<'py, f64>>() {
            if v.len() != n {
                return Err(exc::ArgumentError::new_err(format!(
                    "y has shape ({},); expected ({n},) for one state or ({n}, k) for k states as columns (state: {})",
                    v.len(),
                    self.names.join(", ")
                )));
            }
            let aligned = (v.data() as usize) % std::mem::align_of::<f64>() == 0;
            let slice = if aligned { v.as_slice().ok() } else { None };
            if let Some(s) = slice {
                if s.len() != n {
                    return Err(exc::ArgumentError::new_err(format!(
                        "y has shape ({},); expected ({n},) for one state or ({n}, k) for k states as columns (state: {})",
                        s.len(),
                        self.names.join(", ")
                    )));
                }
                let mut dy = [0.0f64; 64];
                if n <= 64 {
                    self.eval_one(t, s, &mut dy[..n])?;
                    return Ok(PyArray1::from_slice(py, &dy[..n]).into_any());
                }
                let mut dy = vec![0.0; n];
                self.eval_one(t, s, &mut dy)?;
                return Ok(PyArray1::from_vec(py, dy).into_any());
            }
        }
        let a = float_array(y)?;
        let shape: Vec<usize> = a.getattr("shape")?.extract()?;
        match shape.as_slice() {
            [m] if *m == n => {
                let v = f64_vec(&a)?;
                let mut dy = vec![0.0; n];
                self.eval_one(t, &v, &mut dy)?;
                Ok(PyArray1::from_vec(py, dy).into_any())
            }
            [m, k] if *m == n => {
                let k = *k;
                let v = f64_vec(&a)?;
                let ys = &v[..];
                let rhs = rhs_of(&self.c)?;
                let system = &*self.c.system;
                let out = py.allow_threads(|| -> Result<Vec<f64>, String> {
                    let mut dy = vec![0.0; n * k];
                    if let CompiledSystem::Lagrangian(l) = system {
                        // Structure-of-arrays, exactly NumPy's (n, k) C order.
                        l.eval_batch(t, ys, &mut dy, k).map_err(|e| e.to_string())?;
                        return Ok(dy);
                    }
                    let (mut yi, mut di) = (vec![0.0; n], vec![0.0; n]);
                    for j in 0..k {
                        for i in 0..n {
                            yi[i] = ys[i * k + j];
                        }
                        rhs.try_eval(t, &yi, &mut di).map_err(|e| e.reason)?;
                        for i in 0..n {
                            dy[i * k + j] = di[i];
                        }
                    }
                    Ok(dy)
                });
                let out = out.map_err(exc::RhsError::new_err)?;
                Ok(PyArray1::from_vec(py, out).reshape([n, k])?.into_any())
            }
            _ => Err(exc::ArgumentError::new_err(format!(
                "y has shape {shape:?}; expected ({n},) for one state or ({n}, k) for k states as columns (state: {})",
                self.names.join(", ")
            ))),
        }
    }
}

/// What a `CompiledRhs` pickles as: the unpickling function, the system and the formulation.
type Reduced<'py> = (Bound<'py, PyAny>, (Py<PySystem>, &'static str));

/// The name `System.compile(formulation=…)` takes for the equations.
fn formulation_name(eq: Equations) -> &'static str {
    match eq {
        Equations::Hamiltonian => "hamiltonian",
        Equations::Separable => "separable",
        Equations::Lagrangian => "lagrangian",
    }
}

/// The first-order right-hand side of a compiled system (every form Python compiles has one).
fn rhs_of(c: &Compiled) -> PyResult<&dyn lagrangian::integrate::Rhs> {
    c.system
        .rhs()
        .ok_or_else(|| exc::ArgumentError::new_err("a discrete variational map has no right-hand side f(t, y)"))
}

/// Whether two arrays (or lists of arrays, or `None`s) hold the same shapes and values, NaN
/// equal to NaN (a failed ensemble row is NaN).
fn arrays_equal(py: Python<'_>, a: &Bound<'_, PyAny>, b: &Bound<'_, PyAny>) -> PyResult<bool> {
    if a.is_none() || b.is_none() {
        return Ok(a.is_none() && b.is_none());
    }
    if let (Ok(a), Ok(b)) = (a.downcast::<PyList>(), b.downcast::<PyList>()) {
        if a.len() != b.len() {
            return Ok(false);
        }
        for (x, y) in a.iter().zip(b.iter()) {
            if !arrays_equal(py, &x, &y)? {
                return Ok(false);
            }
        }
        return Ok(true);
    }
    let np = py.import("numpy")?;
    let kw = PyDict::new(py);
    let nan_ok = a.getattr("dtype").and_then(|d| d.getattr("kind")).and_then(|k| k.extract::<String>())? == "f";
    kw.set_item("equal_nan", nan_ok)?;
    np.call_method("array_equal", (a, b), Some(&kw))?.extract()
}

/// Refuses a start where a coordinate declared positive (`positive=["r"]`) is not: the
/// equations were simplified on that assumption (`sqrt(r²) = r`). Only the start is checked;
/// a trajectory that later crosses zero is the equations' business.
fn positive_start(sys: &System, names: &[String], y0: &[f64]) -> PyResult<()> {
    let positive = &sys.declarations().positive;
    for q in sys.coordinates() {
        let Some(i) = names.iter().position(|n| n == q.name()) else { continue };
        if positive.contains(q.name()) && y0[i] <= 0.0 {
            return Err(exc::ArgumentError::new_err(format!(
                "`{q}` was declared positive (positive=[…]) and the equations were simplified on that assumption, so it cannot start at {}; start it above 0, or build the system without `{q}` in positive=",
                y0[i]
            )));
        }
    }
    Ok(())
}

/// Refuses a start where the equations have no value (a singular mass matrix at `y0`): `y0` is
/// the bad argument, so it is an `RhsError` (a `ValueError`) naming the start, not an
/// `IntegrationError` of a run that "stopped" at `t0` before its first step.
fn admissible_start(c: &Compiled, t0: f64, y0: &[f64], names: &[String]) -> PyResult<()> {
    let Some(rhs) = c.system.rhs() else { return Ok(()) };
    let mut dy = vec![0.0; y0.len()];
    rhs.try_eval(t0, y0, &mut dy).map_err(|e| {
        let start: Vec<String> = names.iter().zip(y0).map(|(n, v)| format!("{n} = {v:?}")).collect();
        exc::RhsError::new_err(format!(
            "at the initial state ({}): {}; start where the equations have a value",
            start.join(", "),
            e.reason
        ))
    })
}

/// Reads the arguments shared by `integrate` and `ensemble` into the engine's run options,
/// with the compiled system (its events compiled in) and the state's names. The engine
/// checks them (`dt` or `tol` as the method needs, its tolerance floor, the span, the step
/// budget) and refuses a method that cannot run this system.
#[allow(clippy::too_many_arguments)]
fn run_spec(
    py: Python<'_>,
    s: &PySystem,
    method_name: Option<&str>,
    t_span: (f64, f64),
    dt: Option<f64>,
    tol: Option<f64>,
    atol: Option<f64>,
    max_steps: Option<usize>,
    events: Option<&Bound<'_, PyList>>,
    compensated: bool,
) -> PyResult<(RunOptions, Arc<Compiled>)> {
    let m = method_name.map_or(Ok(simulate::DEFAULT_METHOD), method)?;
    let (t0, t1) = t_span;
    let mut opts = RunOptions::new(m, t0, t1);
    opts.dt = dt;
    opts.rtol = tol;
    opts.atol = atol;
    if max_steps == Some(0) {
        return Err(exc::ArgumentError::new_err("max_steps must be at least 1 (None: the engine's default budget)"));
    }
    opts.max_steps = max_steps;
    opts.compensated = compensated;
    // What a run keeps is the caller's to set (and to check again): `every`, `t_eval`, or the
    // final state of an ensemble member. The final state fits any budget.
    opts.sampling = Sampling::Final;
    opts.check().map_err(|e| simulate_error(py, e))?;
    let c = compiled_for_method(py, s, m)?;
    let mut exprs = Vec::new();
    for ev in events.into_iter().flatten() {
        let (expr_obj, direction, terminal) = if let Ok(e) = ev.downcast::<PyEvent>() {
            let e = e.get();
            (e.expr.clone_ref(py).into_bound(py), e.direction, e.terminal)
        } else {
            (ev.clone(), 0, false)
        };
        exprs.push(to_expr(&expr_obj, s.sys.declarations(), true)?);
        let crossing = match direction.signum() {
            1 => Crossing::Rising,
            -1 => Crossing::Falling,
            _ => Crossing::Either,
        };
        opts.events.push(EventSpec { index: opts.events.len(), crossing, terminal });
    }
    let c = if exprs.is_empty() { c } else { Arc::new(c.with_events(&exprs).map_err(|e| simulate_error(py, e))?) };
    Ok((opts, c))
}

/// A zero crossing to detect during :meth:`System.integrate`: ``expr`` is an expression in
/// the state variables and ``t`` (``"θ1"``, ``"p_x - 1"``). ``direction`` is ``+1`` for
/// upward crossings only, ``-1`` for downward, ``0`` for both; a ``terminal`` event stops
/// the integration.
#[pyclass(name = "Event", module = "lagrangian", frozen)]
pub struct PyEvent {
    #[pyo3(get)]
    expr: PyObject,
    #[pyo3(get)]
    direction: i32,
    #[pyo3(get)]
    terminal: bool,
}

#[pymethods]
impl PyEvent {
    #[new]
    #[pyo3(signature = (expr, *, direction=0, terminal=false))]
    fn new(expr: PyObject, direction: i32, terminal: bool) -> PyEvent {
        PyEvent { expr, direction, terminal }
    }

    /// Pickles as its expression (an `Expr` pickles as text) and options.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (PyObject, i32, bool))> {
        let f = py.import("lagrangian._pickle")?.getattr("_event")?;
        Ok((f, (self.expr.clone_ref(py), self.direction, self.terminal)))
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "Event({}, direction={}, terminal={})",
            self.expr.bind(py).str()?,
            self.direction,
            if self.terminal { "True" } else { "False" }
        ))
    }
}

/// The result of :meth:`System.integrate`, laid out like SciPy's ``solve_ivp`` result:
/// ``t`` has shape ``(k,)``, ``y`` shape ``(n, k)`` (one row per state variable, named in
/// ``names``); ``t_events[i]`` and ``y_events[i]`` (shape ``(m, n)``) hold the crossings of
/// event ``i``.
#[pyclass(name = "Solution", module = "lagrangian", frozen)]
pub struct Solution {
    #[pyo3(get)]
    t: PyObject,
    #[pyo3(get)]
    y: PyObject,
    #[pyo3(get)]
    names: Vec<String>,
    #[pyo3(get)]
    t_events: PyObject,
    #[pyo3(get)]
    y_events: PyObject,
    /// ``None``, or with ``dense_output=True`` the continuous solution ``sol(t)``.
    sol: PyObject,
    /// ``"end"`` (the end of ``t_span`` was reached) or ``"event"`` (a terminal event).
    #[pyo3(get)]
    stop: &'static str,
    #[pyo3(get)]
    method: &'static str,
    #[pyo3(get)]
    steps: usize,
    #[pyo3(get)]
    rejected: usize,
    /// Right-hand-side evaluations (SciPy's ``nfev``; for a splitting method the force
    /// evaluations, for the Taylor method the series expansions).
    #[pyo3(get)]
    nfev: usize,
}

/// SciPy's message for each way a run ends.
const END_MESSAGE: &str = "The solver successfully reached the end of the integration interval.";
const EVENT_MESSAGE: &str = "A termination event occurred.";

#[pymethods]
impl Solution {
    /// SciPy's ``status``: ``0`` the end of ``t_span`` was reached, ``1`` a terminal event
    /// stopped the run. (SciPy's ``-1``, a failed step, is raised as
    /// :class:`IntegrationError` instead, with where it stopped.)
    #[getter]
    fn status(&self) -> i32 {
        i32::from(self.stop == "event")
    }

    /// Always ``True``: a run that fails raises :class:`IntegrationError` instead of returning.
    #[getter]
    fn success(&self) -> bool {
        true
    }

    /// SciPy's description of why the run ended.
    #[getter]
    fn message(&self) -> &'static str {
        if self.stop == "event" {
            EVENT_MESSAGE
        } else {
            END_MESSAGE
        }
    }

    /// The continuous solution with ``integrate(..., dense_output=True)``, else ``None``, as
    /// SciPy's: ``sol(t)`` is the state at ``t`` (``(n,)``) or at an array of times
    /// (``(n, m)``), the cubic Hermite interpolant of the accepted steps (error ``O(h⁴)``;
    /// see ``lagrangian._dense``). ``t_eval`` samples the method's own, more accurate, dense
    /// output during the run.
    #[getter]
    fn sol(&self, py: Python<'_>) -> PyObject {
        self.sol.clone_ref(py)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let n: usize = self.t.bind(py).len()?;
        Ok(format!(
            "Solution(method={}, points={n}, steps={}, status={}, state=({}))",
            self.method,
            self.steps,
            self.status(),
            self.names.join(", ")
        ))
    }

    /// Pickles as its arrays and counts (a Dask worker's result travels back whole).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let f = py.import("lagrangian._pickle")?.getattr("_solution")?;
        let d = PyDict::new(py);
        d.set_item("t", self.t.clone_ref(py))?;
        d.set_item("y", self.y.clone_ref(py))?;
        d.set_item("names", self.names.clone())?;
        d.set_item("t_events", self.t_events.clone_ref(py))?;
        d.set_item("y_events", self.y_events.clone_ref(py))?;
        d.set_item("sol", self.sol.clone_ref(py))?;
        d.set_item("stop", self.stop)?;
        d.set_item("method", self.method)?;
        d.set_item("steps", self.steps)?;
        d.set_item("rejected", self.rejected)?;
        d.set_item("nfev", self.nfev)?;
        Ok((f, (d,)))
    }

    /// Rebuilds a pickled solution (see ``__reduce__``).
    #[staticmethod]
    fn _restore(d: &Bound<'_, PyDict>) -> PyResult<Solution> {
        let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
            d.get_item(k)?.ok_or_else(|| exc::ArgumentError::new_err(format!("a pickled Solution without `{k}`")))
        };
        let method: String = get("method")?.extract()?;
        let method = MethodId::from_name(&method)
            .ok_or_else(|| exc::ArgumentError::new_err(format!("a pickled Solution of an unknown method `{method}`")))?
            .name();
        let stop: String = get("stop")?.extract()?;
        Ok(Solution {
            t: get("t")?.unbind(),
            y: get("y")?.unbind(),
            names: get("names")?.extract()?,
            t_events: get("t_events")?.unbind(),
            y_events: get("y_events")?.unbind(),
            sol: match d.get_item("sol")? {
                Some(s) => s.unbind(),
                None => d.py().None(),
            },
            stop: if stop == "event" { "event" } else { "end" },
            method,
            steps: get("steps")?.extract()?,
            rejected: get("rejected")?.extract()?,
            nfev: get("nfev")?.extract()?,
        })
    }

    /// Equal when every array, name and count is (what a pickle round trip keeps).
    fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> PyResult<bool> {
        let Ok(o) = other.downcast::<Solution>() else { return Ok(false) };
        let o = o.get();
        let same = |a: &PyObject, b: &PyObject| -> PyResult<bool> { arrays_equal(py, a.bind(py), b.bind(py)) };
        Ok(self.names == o.names
            && self.stop == o.stop
            && self.method == o.method
            && (self.steps, self.rejected, self.nfev) == (o.steps, o.rejected, o.nfev)
            && same(&self.t, &o.t)?
            && same(&self.y, &o.y)?
            && same(&self.t_events, &o.t_events)?
            && same(&self.y_events, &o.y_events)?
            && self.sol.bind(py).eq(o.sol.bind(py))?)
    }

    /// The row of ``y`` for the state variable ``name`` (``sol["θ1"]``).
    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let Some(i) = self.names.iter().position(|n| n == name) else {
            return Err(pyo3::exceptions::PyKeyError::new_err(format!(
                "`{name}` is not a state variable ({})",
                self.names.join(", ")
            )));
        };
        self.y.bind(py).get_item(i)
    }
}

fn solution(
    py: Python<'_>,
    out: Trajectory,
    names: Vec<String>,
    n_events: usize,
    method: &'static str,
    sol: PyObject,
) -> PyResult<Solution> {
    let n = names.len();
    let k = out.t.len();
    // One row per state variable: SciPy's (n, k).
    let mut y = vec![0.0; n * k];
    for (j, state) in out.y.iter().enumerate() {
        for (i, v) in state.iter().enumerate() {
            y[i * k + j] = *v;
        }
    }
    // SciPy's: `None` when no events were asked for, else one array per event.
    let (t_events, y_events) = if n_events == 0 {
        (py.None(), py.None())
    } else {
        let t_events = PyList::empty(py);
        let y_events = PyList::empty(py);
        for e in 0..n_events {
            let recs: Vec<&EventRecord> = out.events.iter().filter(|r| r.index == e).collect();
            let ts: Vec<f64> = recs.iter().map(|r| r.t).collect();
            let ys: Vec<f64> = recs.iter().flat_map(|r| r.state.iter().copied()).collect();
            t_events.append(PyArray1::from_vec(py, ts))?;
            y_events.append(PyArray1::from_vec(py, ys).reshape([recs.len(), n])?)?;
        }
        (t_events.into_any().unbind(), y_events.into_any().unbind())
    };
    Ok(Solution {
        t: PyArray1::from_vec(py, out.t).into_any().unbind(),
        y: PyArray1::from_vec(py, y).reshape([n, k])?.into_any().unbind(),
        names,
        t_events,
        y_events,
        sol,
        stop: if out.stopped_by.is_some() { "event" } else { "end" },
        method,
        steps: out.steps,
        rejected: out.rejected,
        nfev: out.evaluations,
    })
}

/// ``lagrangian._dense.DenseSolution`` of the accepted steps of `steps`: their states and the
/// right-hand side at each (evaluated here, with the GIL released; not counted in ``nfev``).
fn dense_solution(py: Python<'_>, rhs: &dyn lagrangian::integrate::Rhs, steps: &Trajectory) -> PyResult<PyObject> {
    let (k, n) = (steps.t.len(), steps.y.first().map_or(0, Vec::len));
    let derivatives = py.allow_threads(|| -> Result<Vec<f64>, String> {
        let mut dy = vec![0.0; n * k];
        let mut d = vec![0.0; n];
        for (j, (t, y)) in steps.t.iter().zip(&steps.y).enumerate() {
            rhs.try_eval(*t, y, &mut d).map_err(|e| format!("at t = {t}: {}", e.reason))?;
            for i in 0..n {
                dy[i * k + j] = d[i];
            }
        }
        Ok(dy)
    });
    let dy = derivatives.map_err(exc::RhsError::new_err)?;
    let mut y = vec![0.0; n * k];
    for (j, state) in steps.y.iter().enumerate() {
        for (i, v) in state.iter().enumerate() {
            y[i * k + j] = *v;
        }
    }
    let ts = PyArray1::from_vec(py, steps.t.clone());
    let ys = PyArray1::from_vec(py, y).reshape([n, k])?;
    let dys = PyArray1::from_vec(py, dy).reshape([n, k])?;
    Ok(py.import("lagrangian._dense")?.getattr("DenseSolution")?.call1((ts, ys, dys))?.unbind())
}

/// The result of :meth:`System.ensemble`: final times ``t`` ``(k,)`` and states ``y``
/// ``(k, n)`` (rows of NaN where a trajectory failed), ``ok`` ``(k,)`` and ``errors`` (the
/// engine's message for each failed trajectory, ``None`` for the others).
#[pyclass(name = "EnsembleResult", module = "lagrangian", frozen)]
pub struct EnsembleResult {
    #[pyo3(get)]
    t: PyObject,
    #[pyo3(get)]
    y: PyObject,
    #[pyo3(get)]
    ok: PyObject,
    #[pyo3(get)]
    errors: Vec<Option<String>>,
    #[pyo3(get)]
    names: Vec<String>,
}

#[pymethods]
impl EnsembleResult {
    /// Pickles as its arrays, messages and names.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let f = py.import("lagrangian._pickle")?.getattr("_ensemble_result")?;
        let d = PyDict::new(py);
        d.set_item("t", self.t.clone_ref(py))?;
        d.set_item("y", self.y.clone_ref(py))?;
        d.set_item("ok", self.ok.clone_ref(py))?;
        d.set_item("errors", self.errors.clone())?;
        d.set_item("names", self.names.clone())?;
        Ok((f, (d,)))
    }

    /// Rebuilds a pickled result (see ``__reduce__``).
    #[staticmethod]
    fn _restore(d: &Bound<'_, PyDict>) -> PyResult<EnsembleResult> {
        let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
            d.get_item(k)?.ok_or_else(|| exc::ArgumentError::new_err(format!("a pickled EnsembleResult without `{k}`")))
        };
        Ok(EnsembleResult {
            t: get("t")?.unbind(),
            y: get("y")?.unbind(),
            ok: get("ok")?.unbind(),
            errors: get("errors")?.extract()?,
            names: get("names")?.extract()?,
        })
    }

    /// Equal when every array, message and name is (NaN rows of failed trajectories too).
    fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> PyResult<bool> {
        let Ok(o) = other.downcast::<EnsembleResult>() else { return Ok(false) };
        let o = o.get();
        Ok(self.names == o.names
            && self.errors == o.errors
            && arrays_equal(py, self.t.bind(py), o.t.bind(py))?
            && arrays_equal(py, self.y.bind(py), o.y.bind(py))?
            && arrays_equal(py, self.ok.bind(py), o.ok.bind(py))?)
    }

    fn __repr__(&self) -> String {
        let failed = self.errors.iter().filter(|e| e.is_some()).count();
        format!(
            "EnsembleResult(trajectories={}, failed={failed}, state=({}))",
            self.errors.len(),
            self.names.join(", ")
        )
    }
}

#[pymethods]
impl PySystem {
    /// Compiles the equations of motion into a callable right-hand side ``f(t, y)``.
    /// ``formulation`` is ``"lagrangian"`` (state ``(q, q')``, the default for a Lagrangian
    /// system), ``"hamiltonian"`` (state ``(q, p_q)``, the default for a Hamiltonian one) or
    /// ``"separable"`` (``H = T(p) + V(q)``). Parameters need values (``params=`` or
    /// :meth:`with_params`).
    #[pyo3(signature = (formulation=None))]
    fn compile(slf: &Bound<'_, Self>, formulation: Option<&str>) -> PyResult<CompiledRhs> {
        let py = slf.py();
        let this = slf.get();
        let lagrangian = this.sys.lagrangian().is_some();
        let equations = match formulation {
            None if lagrangian => Equations::Lagrangian,
            None => Equations::Hamiltonian,
            Some("lagrangian") => Equations::Lagrangian,
            Some("hamiltonian") => Equations::Hamiltonian,
            Some("separable") => Equations::Separable,
            Some(other) => {
                return Err(exc::ArgumentError::new_err(format!(
                    "unknown formulation `{other}` (lagrangian, hamiltonian or separable)"
                )))
            }
        };
        let c = compiled_for(py, this, equations, Form::Rhs)?;
        Ok(CompiledRhs {
            names: c.state.clone(),
            c,
            system: slf.clone().unbind(),
            equations,
            jac: std::sync::OnceLock::new(),
        })
    }

    /// Integrates from ``y0`` over ``t_span = (t0, t1)`` (any two numbers: a tuple, a list,
    /// an array) and returns a :class:`Solution`.
    ///
    /// ``method`` is one of ``dop853`` and ``taylor`` (adaptive, tolerances ``rtol`` and
    /// ``atol`` as SciPy names them; ``tol`` is another name for ``rtol``), ``rk4``,
    /// ``euler``, ``midpoint``, ``gauss4``, ``gauss6`` (symplectic collocation),
    /// ``leapfrog``/``verlet``, ``yoshida4``/``6``/``8``, ``blanes_moan``,
    /// ``symplectic_euler`` (splitting methods, which need ``H = T(p) + V(q)`` and use the
    /// state ``(q, p_q)``); fixed-step methods need ``dt``. :meth:`state_names` gives the
    /// layout of ``y0`` (an array, or a dict by state name). ``t_eval`` asks for the states at
    /// given times (dense output) instead of at every step; ``every=k`` keeps every k-th
    /// step. ``events`` is a list of expressions or :class:`Event` objects, located on the
    /// step's interpolant; with ``t_eval`` too, as in SciPy, events are watched over the whole
    /// span and a terminal one ends the output at the last ``t_eval`` time before it.
    /// ``dense_output=True`` adds ``sol``, the continuous solution ``sol(t)`` (see
    /// :attr:`Solution.sol`); it needs every step (``every=1``) and a right-hand side (not the
    /// discrete ``variational`` maps). The GIL is
    /// released while the engine integrates; runs longer than a second show a progress bar
    /// (``progress=True`` at once, ``False`` never) and Ctrl-C stops them.
    #[pyo3(signature = (t_span, y0, method=None, *, dt=None, rtol=None, atol=None, tol=None, t_eval=None, events=None, every=1, max_steps=None, compensated=false, progress=None, dense_output=false))]
    #[allow(clippy::too_many_arguments)]
    fn integrate(
        &self,
        py: Python<'_>,
        t_span: &Bound<'_, PyAny>,
        y0: &Bound<'_, PyAny>,
        method: Option<&str>,
        dt: Option<f64>,
        rtol: Option<f64>,
        atol: Option<f64>,
        tol: Option<f64>,
        t_eval: Option<&Bound<'_, PyAny>>,
        events: Option<&Bound<'_, PyList>>,
        every: usize,
        max_steps: Option<usize>,
        compensated: bool,
        progress: Option<bool>,
        dense_output: bool,
    ) -> PyResult<Solution> {
        let (t_span, tol) = (time_span(t_span)?, relative_tolerance(rtol, tol)?);
        let (mut opts, c) = run_spec(py, self, method, t_span, dt, tol, atol, max_steps, events, compensated)?;
        let names = c.state.clone();
        let y0 = initial_state(y0, &names)?;
        positive_start(&self.sys, &names, &y0)?;
        admissible_start(&c, t_span.0, &y0, &names)?;
        if every == 0 {
            return Err(exc::ArgumentError::new_err("every must be at least 1 (every=k keeps every k-th step)"));
        }
        opts.sampling = Sampling::Every(every);
        opts.check().map_err(|e| simulate_error(py, e))?;
        if dense_output && every != 1 {
            return Err(exc::ArgumentError::new_err(format!(
                "dense_output=True interpolates between the accepted steps, so it needs every step: leave out every={every}, or use t_eval for chosen times"
            )));
        }
        let dense_rhs = match (dense_output, c.system.rhs()) {
            (false, _) => None,
            (true, Some(r)) => Some(r),
            (true, None) => {
                return Err(exc::ArgumentError::new_err(format!(
                    "dense_output=True needs the equations' right-hand side, and `{}` is a discrete map without one: use t_eval for chosen times, or a method such as `gauss6`",
                    opts.method.name()
                )))
            }
        };
        // With t_eval, the states at those times come from the method's dense output during
        // the run, and the interpolant from a second run that keeps every step.
        let mut step_opts = opts.clone();
        if let Some(te) = t_eval {
            let a = float_array(te)?;
            opts.sampling = Sampling::Times(f64_vec(&a.call_method0("ravel")?)?);
            opts.check().map_err(|e| simulate_error(py, e))?;
        }
        let ctl = Control::default();
        opts.cancel = Some(ctl.cancel.clone());
        let n_events = opts.events.len();
        let name = opts.method.name();
        step_opts.cancel = opts.cancel.clone();
        let second_run = dense_output && t_eval.is_some();
        let (result, steps) = with_progress(
            py,
            progress_mode(progress),
            name,
            &ctl,
            || ctl.fraction(),
            || {
                let out = simulate::integrate(&c, &y0, &opts, &mut |f| ctl.report(f));
                let steps = (second_run && out.is_ok())
                    .then(|| simulate::integrate(&c, &y0, &step_opts, &mut |f| ctl.report(f)));
                (out, steps)
            },
        )?;
        let out = result.map_err(|e| simulate_error(py, e))?;
        let sol = match dense_rhs {
            None => py.None(),
            Some(rhs) => {
                let steps = match steps {
                    Some(r) => r.map_err(|e| simulate_error(py, e))?,
                    None => out.clone(),
                };
                dense_solution(py, rhs, &steps)?
            }
        };
        solution(py, out, names, n_events, name, sol)
    }

    /// Integrates many initial states ``y0`` (shape ``(k, n)``, one state per row) over
    /// ``t_span`` in parallel (rayon; ``threads`` workers, default all cores) and returns
    /// their final states as an :class:`EnsembleResult`. One trajectory's failure does not
    /// stop the others. The arguments are those of :meth:`integrate`, in its order
    /// (``t_span`` first); a terminal event ends each trajectory at its crossing (``t`` then
    /// holds the crossing times).
    ///
    /// Layout: ``y0`` and the result's ``y`` are ``(k, n)``, one row per trajectory, not
    /// SciPy's ``(n, k)``: SciPy's columns are the times of one trajectory, here the axis is
    /// the trajectories, and one row per item is how NumPy stacks states
    /// (``np.array([s1, s2])``) and how pandas shows them.
    ///
    /// With ``t_eval`` (times inside ``t_span``) each trajectory keeps its states at those
    /// times: ``y`` is ``(k, n, m)``, each ``y[j]`` SciPy's ``(n, m)`` of one trajectory, and
    /// ``t`` is ``t_eval``. A trajectory that failed, or that a terminal event ended before
    /// some of the times, is NaN there.
    #[pyo3(signature = (t_span, y0, method=None, *, dt=None, rtol=None, atol=None, tol=None, t_eval=None, events=None, max_steps=None, compensated=false, threads=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn ensemble(
        &self,
        py: Python<'_>,
        t_span: &Bound<'_, PyAny>,
        y0: &Bound<'_, PyAny>,
        method: Option<&str>,
        dt: Option<f64>,
        rtol: Option<f64>,
        atol: Option<f64>,
        tol: Option<f64>,
        t_eval: Option<&Bound<'_, PyAny>>,
        events: Option<&Bound<'_, PyList>>,
        max_steps: Option<usize>,
        compensated: bool,
        threads: Option<usize>,
        progress: Option<bool>,
    ) -> PyResult<EnsembleResult> {
        let (t_span, tol) = (span_then_states(t_span, y0, "ensemble")?, relative_tolerance(rtol, tol)?);
        let (mut opts, c) = run_spec(py, self, method, t_span, dt, tol, atol, max_steps, events, compensated)?;
        opts.sampling = Sampling::Final;
        let times = match t_eval {
            Some(te) => Some(f64_vec(&float_array(te)?.call_method0("ravel")?)?),
            None => None,
        };
        if let Some(ts) = &times {
            opts.sampling = Sampling::Times(ts.clone());
            opts.check().map_err(|e| simulate_error(py, e))?;
        }
        let names = c.state.clone();
        let n = names.len();
        let a = float_array(y0)?;
        let shape: Vec<usize> = a.getattr("shape")?.extract()?;
        if shape.len() != 2 || shape[1] != n {
            return Err(exc::ArgumentError::new_err(format!(
                "y0 has shape {shape:?}; expected (k, {n}): one state ({}) per row",
                names.join(", ")
            )));
        }
        let k = shape[0];
        let flat = f64_vec(&a)?;
        let starts: Vec<Vec<f64>> = flat.chunks(n.max(1)).take(k).map(<[f64]>::to_vec).collect();
        for s in &starts {
            positive_start(&self.sys, &names, s)?;
        }
        let ctl = Control::default();
        opts.cancel = Some(ctl.cancel.clone());
        let results = with_progress(
            py,
            progress_mode(progress),
            "ensemble",
            &ctl,
            || ctl.fraction(),
            || simulate::ensemble(&c, &starts, &opts, threads, &mut |f| ctl.report(f)),
        )?;
        if ctl.cancel.is_cancelled() {
            return Err(PyKeyboardInterrupt::new_err("ensemble interrupted"));
        }
        if let Some(ts) = times {
            // (k, n, m): trajectory j's state i at ts[l], NaN where it has none.
            let m = ts.len();
            let mut ys = vec![f64::NAN; k * n * m];
            let mut ok = Vec::with_capacity(k);
            let mut errors = Vec::with_capacity(k);
            for (j, r) in results.into_iter().enumerate() {
                match r {
                    Ok(tr) => {
                        for (l, state) in tr.y.iter().take(m).enumerate() {
                            for (i, v) in state.iter().take(n).enumerate() {
                                ys[(j * n + i) * m + l] = *v;
                            }
                        }
                        ok.push(true);
                        errors.push(None);
                    }
                    Err(e) => {
                        ok.push(false);
                        errors.push(Some(e.to_string()));
                    }
                }
            }
            return Ok(EnsembleResult {
                t: PyArray1::from_vec(py, ts).into_any().unbind(),
                y: PyArray1::from_vec(py, ys).reshape([k, n, m])?.into_any().unbind(),
                ok: PyArray1::from_vec(py, ok).into_any().unbind(),
                errors,
                names,
            });
        }
        let results: Vec<Result<Vec<f64>, String>> = results
            .into_iter()
            .map(|r| match r {
                Ok(tr) => {
                    let mut v = tr.y.last().cloned().unwrap_or_default();
                    v.push(tr.t.last().copied().unwrap_or(f64::NAN));
                    Ok(v)
                }
                Err(e) => Err(e.to_string()),
            })
            .collect();
        let mut ys = Vec::with_capacity(k * n);
        let mut ts = Vec::with_capacity(k);
        let mut ok = Vec::with_capacity(k);
        let mut errors = Vec::with_capacity(k);
        for r in results {
            match r {
                Ok(v) => {
                    ys.extend_from_slice(&v[..n]);
                    ts.push(v[n]);
                    ok.push(true);
                    errors.push(None);
                }
                Err(e) => {
                    ys.extend(std::iter::repeat(f64::NAN).take(n));
                    ts.push(f64::NAN);
                    ok.push(false);
                    errors.push(Some(e));
                }
            }
        }
        Ok(EnsembleResult {
            t: PyArray1::from_vec(py, ts).into_any().unbind(),
            y: PyArray1::from_vec(py, ys).reshape([k, n])?.into_any().unbind(),
            ok: PyArray1::from_vec(py, ok).into_any().unbind(),
            errors,
            names,
        })
    }
}
