//! The numeric side of `System`: compiled right-hand sides callable from Python (one state
//! or a batch; a drop-in `fun=` for SciPy's `solve_ivp`), `integrate` returning NumPy arrays
//! and `ensemble` over many initial states. Every integration runs with the GIL released.
//!
//! Progress and Ctrl-C: the driver adds one event whose function records the current time on
//! every step (the progress bar reads it), and hands the run the engine's cancellation token
//! ([`lagrangian::cancel::CancelToken`], checked before every step), which the waiting thread
//! sets on `KeyboardInterrupt`. The calling thread waits with the GIL released and, a few
//! times a second, takes the GIL to draw the bar and check for the signal.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use lagrangian::compile::{
    CompileError, HamiltonianRhs, LagrangianJacobian, LagrangianRhs, SeparableHamiltonian, Tape, TaylorOde,
};
use lagrangian::integrate::{
    Crossing, Dop853, Event, EventRecord, ExplicitRk, FailureReason, Gauss, Integrate, IntegrateError, Options, Rhs,
    Separable, Splitting, Status, StopReason, Taylor,
};
use lagrangian::mechanics::{Kind, System};
use lagrangian::scene::sim::{self as methods, Family};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{exc, integration_error, PyResultExt};
use crate::expr::to_expr;
use crate::system::PySystem;

/// Which equations a method integrates, and so the state layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Formulation {
    /// `W q'' = F`; state `(q, q')`.
    Lagrangian,
    /// `W q'' = F` with its exact Jacobian (implicit methods); state `(q, q')`.
    LagrangianJacobian,
    /// Hamilton's equations; state `(q, p)`.
    Hamiltonian,
    /// `H = T(p) + V(q, t)` split into drift and kick (splitting methods); state `(q, p)`.
    Separable,
    /// The Taylor form of `W q'' = F` (state `(q, q')`) or of Hamilton's equations (state
    /// `(q, p)`), for the Taylor method.
    Taylor,
}

impl Formulation {
    /// What `method` needs from `sys`.
    pub fn for_method(sys: &System, m: methods::Method) -> Formulation {
        let lagrangian = matches!(sys.kind(), Kind::Lagrangian(_));
        match m.family {
            Family::Splitting => Formulation::Separable,
            Family::Adaptive if m.name == "taylor" => Formulation::Taylor,
            Family::Implicit if lagrangian => Formulation::LagrangianJacobian,
            _ if lagrangian => Formulation::Lagrangian,
            _ => Formulation::Hamiltonian,
        }
    }

    /// `(q…, q'…)` or `(q…, p_q…)`.
    pub fn state_names(self, sys: &System) -> Vec<String> {
        let lagrangian = matches!(sys.kind(), Kind::Lagrangian(_));
        let second = match self {
            Formulation::Lagrangian | Formulation::LagrangianJacobian => sys.velocities(),
            Formulation::Taylor if lagrangian => sys.velocities(),
            _ => sys.momenta(),
        };
        sys.coordinates().iter().chain(second).map(|s| s.to_string()).collect()
    }
}

/// A compiled system.
pub enum Compiled {
    Lagrangian(LagrangianRhs),
    LagrangianJacobian(LagrangianJacobian),
    Hamiltonian(HamiltonianRhs),
    Separable(SeparableHamiltonian),
    /// The Taylor form, and the right-hand side it was made from (for `f(t, y)` calls).
    Taylor(TaylorOde, Box<Compiled>),
}

impl Compiled {
    fn rhs(&self) -> &dyn Rhs {
        match self {
            Compiled::Lagrangian(r) => r,
            Compiled::LagrangianJacobian(r) => r,
            Compiled::Hamiltonian(r) => r,
            Compiled::Separable(r) => r,
            Compiled::Taylor(_, r) => r.rhs(),
        }
    }

    /// Writes the exact Jacobian `∂f_i/∂y_j` into `jac[i * dim + j]`, if this formulation
    /// carries one.
    fn jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) -> Option<Result<(), lagrangian::compile::RhsError>> {
        match self {
            Compiled::LagrangianJacobian(r) => Some(r.try_jacobian(t, y, jac)),
            Compiled::Hamiltonian(r) => Some(r.try_jacobian(t, y, jac)),
            _ => None,
        }
    }
}

/// Compiles `f` for `sys`, taking the symbolic inputs from the derivation cache
/// (`cache.rs`), so a worker process or a new parameter set does not derive them again.
fn compile_formulation(sys: &System, f: Formulation) -> Result<Compiled, CompileError> {
    let params: Vec<(String, f64)> = sys.param_values().iter().map(|(k, v)| (k.to_string(), *v)).collect();
    let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let q: Vec<String> = sys.coordinates().iter().map(|s| s.to_string()).collect();
    let p: Vec<String> = sys.momenta().iter().map(|s| s.to_string()).collect();
    let q: Vec<&str> = q.iter().map(String::as_str).collect();
    let p: Vec<&str> = p.iter().map(String::as_str).collect();
    let lagrangian_rhs = || match sys.kind() {
        // The checks of `System::compile_rhs` (constraints, a Hamiltonian system) come first.
        Kind::Lagrangian(l) if sys.constraints().is_empty() => {
            let (w, f) = crate::cache::mass_matrix(sys, l)?;
            LagrangianRhs::new(&w, &f, &q, &params)
        }
        _ => sys.compile_rhs(),
    };
    Ok(match f {
        Formulation::Lagrangian => Compiled::Lagrangian(lagrangian_rhs()?),
        Formulation::LagrangianJacobian => Compiled::LagrangianJacobian(lagrangian_rhs()?.with_jacobian()?),
        Formulation::Hamiltonian => {
            Compiled::Hamiltonian(HamiltonianRhs::new(&crate::cache::hamiltonian(sys)?, &q, &p, &params)?)
        }
        Formulation::Separable => {
            Compiled::Separable(SeparableHamiltonian::new(&crate::cache::hamiltonian(sys)?, &q, &p, &params)?)
        }
        Formulation::Taylor => match sys.kind() {
            Kind::Lagrangian(_) => {
                let r = lagrangian_rhs()?;
                Compiled::Taylor(TaylorOde::from_lagrangian(&r), Box::new(Compiled::Lagrangian(r)))
            }
            Kind::Hamiltonian(_) => {
                let r = HamiltonianRhs::new(&crate::cache::hamiltonian(sys)?, &q, &p, &params)?;
                Compiled::Taylor(TaylorOde::from_hamiltonian(&r), Box::new(Compiled::Hamiltonian(r)))
            }
        },
    })
}

/// Compiled systems of one `System`, by formulation (compiling is done once per process).
pub type CompiledCache = Arc<Mutex<HashMap<Formulation, Arc<Compiled>>>>;

/// The compiled `f` of `sys` for `f`, from the cache or compiled now (GIL released).
pub fn compiled(py: Python<'_>, s: &PySystem, f: Formulation) -> PyResult<Arc<Compiled>> {
    if let Some(c) = s.compiled.lock().ok().and_then(|m| m.get(&f).cloned()) {
        return Ok(c);
    }
    let sys = &s.sys;
    crate::cache::init(py);
    let c = py.allow_threads(|| compile_formulation(sys, f)).py()?;
    let c = Arc::new(c);
    if let Ok(mut m) = s.compiled.lock() {
        m.insert(f, c.clone());
    }
    Ok(c)
}

/// The methods the binding runs. The discrete variational maps (`variational`, …) integrate
/// the discrete Lagrangian's map with its own state `(q, p)` and are offered by scenes and
/// `lagrangian discretize`, not here yet.
pub fn binding_methods() -> impl Iterator<Item = &'static methods::Method> {
    methods::METHODS.iter().filter(|m| !matches!(m.family, Family::Variational))
}

/// The method called `name`, or a `ValueError` listing them.
pub fn method(name: &str) -> PyResult<methods::Method> {
    let names = || binding_methods().map(|m| m.name).collect::<Vec<_>>().join(", ");
    match methods::method(name) {
        Some(m) if matches!(m.family, Family::Variational) => Err(PyValueError::new_err(format!(
            "`{name}` (a discrete variational map) runs in scenes and `lagrangian discretize`, not in the \
             Python binding; the methods here are {}",
            names()
        ))),
        Some(m) => Ok(m),
        None => Err(PyValueError::new_err(format!("unknown method `{name}`; the methods are {}", names()))),
    }
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

/// Reads a float64 array of any shape (converting lists and integer arrays), C-contiguous
/// and aligned.
fn float_array<'py>(y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    // Aligned as well as C-contiguous: arrays unpickled from a byte stream (a Dask worker's
    // input) may start at any address, and a slice needs an aligned one.
    let np = y.py().import("numpy")?;
    np.call_method1("require", (y, "float64", "CA"))
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
    /// The system and formulation, to compile the Jacobian on first use.
    system: Py<PySystem>,
    formulation: Formulation,
    jac: std::sync::OnceLock<Arc<Compiled>>,
}

impl CompiledRhs {
    /// The formulation with the exact Jacobian of this one's equations, compiled once.
    fn jacobian_code(&self, py: Python<'_>) -> PyResult<Arc<Compiled>> {
        if let Some(c) = self.jac.get() {
            return Ok(c.clone());
        }
        let f = match self.formulation {
            Formulation::Lagrangian | Formulation::LagrangianJacobian => Formulation::LagrangianJacobian,
            // The split integrates Hamilton's equations in the same state `(q, p)`.
            Formulation::Hamiltonian | Formulation::Separable | Formulation::Taylor => Formulation::Hamiltonian,
        };
        let c = compiled(py, self.system.bind(py).get(), f)?;
        let _ = self.jac.set(c.clone());
        Ok(c)
    }

    fn eval_one(&self, t: f64, y: &[f64], dy: &mut [f64]) -> PyResult<()> {
        self.c.rhs().try_eval(t, y, dy).map_err(|e| exc::RhsError::new_err(e.reason))
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

    /// The exact Jacobian ``J[i, j] = ∂f_i/∂y_j`` at ``(t, y)``, shape ``(n, n)``, from the
    /// symbolic derivatives of the equations compiled into a tape (on the first call; the
    /// same Jacobian the engine's implicit methods use). Pass it as
    /// ``solve_ivp(f, …, method="Radau", jac=f.jac)``.
    fn jac<'py>(&self, py: Python<'py>, t: f64, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.names.len();
        let a = float_array(y)?;
        let shape: Vec<usize> = a.getattr("shape")?.extract()?;
        if shape != [n] {
            return Err(PyValueError::new_err(format!(
                "y has shape {shape:?}; the Jacobian takes one state of shape ({n},) ({})",
                self.names.join(", ")
            )));
        }
        let v = f64_vec(&a)?;
        let c = self.jacobian_code(py)?;
        let mut j = vec![0.0; n * n];
        match c.jacobian(t, &v, &mut j) {
            Some(r) => r.py()?,
            None => return Err(PyValueError::new_err("this formulation has no compiled Jacobian")),
        }
        Ok(PyArray1::from_vec(py, j).reshape([n, n])?.into_any())
    }

    fn __call__<'py>(&self, py: Python<'py>, t: f64, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.names.len();
        // Fast path: a contiguous float64 vector, as solve_ivp passes.
        if let Ok(v) = y.extract::<PyReadonlyArray1<'py, f64>>() {
            if v.len() != n {
                return Err(PyValueError::new_err(format!(
                    "y has shape ({},); expected ({n},) for one state or ({n}, k) for k states as columns (state: {})",
                    v.len(),
                    self.names.join(", ")
                )));
            }
            let aligned = (v.data() as usize) % std::mem::align_of::<f64>() == 0;
            let slice = if aligned { v.as_slice().ok() } else { None };
            if let Some(s) = slice {
                if s.len() != n {
                    return Err(PyValueError::new_err(format!(
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
                let c = &self.c;
                let out = py.allow_threads(|| -> Result<Vec<f64>, String> {
                    let mut dy = vec![0.0; n * k];
                    if let Compiled::Lagrangian(l) = &**c {
                        // Structure-of-arrays, exactly NumPy's (n, k) C order.
                        l.eval_batch(t, ys, &mut dy, k).map_err(|e| e.to_string())?;
                        return Ok(dy);
                    }
                    let (mut yi, mut di) = (vec![0.0; n], vec![0.0; n]);
                    for j in 0..k {
                        for i in 0..n {
                            yi[i] = ys[i * k + j];
                        }
                        c.rhs().try_eval(t, &yi, &mut di).map_err(|e| e.reason)?;
                        for i in 0..n {
                            dy[i * k + j] = di[i];
                        }
                    }
                    Ok(dy)
                });
                let out = out.map_err(exc::RhsError::new_err)?;
                Ok(PyArray1::from_vec(py, out).reshape([n, k])?.into_any())
            }
            _ => Err(PyValueError::new_err(format!(
                "y has shape {shape:?}; expected ({n},) for one state or ({n}, k) for k states as columns (state: {})",
                self.names.join(", ")
            ))),
        }
    }
}

/// Where an integration is, shared between the integrating thread and the one drawing the
/// progress bar.
#[derive(Default)]
pub struct Control {
    t: AtomicU64,
    done: AtomicUsize,
    cancel: lagrangian::cancel::CancelToken,
}

/// One integration request, checked.
#[derive(Clone)]
pub struct RunSpec {
    pub method: methods::Method,
    pub t0: f64,
    pub t1: f64,
    pub dt: Option<f64>,
    pub rtol: f64,
    pub atol: f64,
    pub max_steps: usize,
    pub every: usize,
    pub final_only: bool,
    pub compensated: bool,
    pub t_eval: Option<Vec<f64>>,
    pub events: Vec<EventSpec>,
}

/// A compiled event function `g(state, t)` with its direction and whether it stops.
#[derive(Clone)]
pub struct EventSpec {
    tape: Arc<Tape>,
    crossing: Crossing,
    terminal: bool,
}

impl EventSpec {
    /// `g(t, y)`.
    fn function(&self) -> impl Fn(f64, &[f64]) -> f64 {
        let tape = self.tape.clone();
        move |t, y| {
            let mut x = Vec::with_capacity(y.len() + 1);
            x.extend_from_slice(y);
            x.push(t);
            let mut o = [0.0];
            tape.eval(&x, &mut o);
            o[0]
        }
    }
}

/// The result of one integration.
pub struct Out {
    times: Vec<f64>,
    states: Vec<f64>,
    events: Vec<EventRecord>,
    stop: Option<(usize, f64)>,
    steps: usize,
    rejected: usize,
}

pub enum RunError {
    Failed(IntegrateError),
    Cancelled,
}

impl From<IntegrateError> for RunError {
    /// The token's [`FailureReason::Interrupted`] is the user's Ctrl-C, not a failure.
    fn from(e: IntegrateError) -> Self {
        if e.reason == FailureReason::Interrupted {
            RunError::Cancelled
        } else {
            RunError::Failed(e)
        }
    }
}

fn drive<S: ?Sized, M: Integrate<S>>(m: &M, sys: &S, y0: &[f64], p: &RunSpec, ctl: &Control) -> Result<Out, RunError> {
    if let Some(te) = &p.t_eval {
        return drive_dense(m, sys, y0, p, te, ctl);
    }
    let mut opts = Options::new().max_steps(p.max_steps).every(p.every);
    if p.final_only {
        opts = opts.final_only();
    }
    // Event 0 is the progress hook (see the module docs); the user's follow.
    opts = opts.cancel(ctl.cancel.clone()).event(
        Event::new(|t, _| {
            ctl.t.store(t.to_bits(), Ordering::Relaxed);
            1.0
        })
        .crossing(Crossing::Falling)
        .stop(),
    );
    for e in &p.events {
        let mut ev = Event::new(e.function()).crossing(e.crossing);
        if e.terminal {
            ev = ev.stop();
        }
        opts = opts.event(ev);
    }
    let traj = m.integrate_with(sys, p.t0..p.t1, y0, opts)?;
    let stop = match traj.stop {
        // The progress hook never changes sign, so event 0 never stops a run.
        StopReason::Event { index: 0, .. } => return Err(RunError::Cancelled),
        StopReason::Event { index, t } => Some((index - 1, t)),
        StopReason::ReachedEnd => None,
    };
    let events =
        traj.events.into_iter().filter(|e| e.index > 0).map(|e| EventRecord { index: e.index - 1, ..e }).collect();
    Ok(Out {
        times: traj.times,
        states: traj.states,
        events,
        stop,
        steps: traj.stats.steps,
        rejected: traj.stats.rejected,
    })
}

/// Steps with a [`lagrangian::integrate::Solver`] and interpolates at the requested times
/// (the method's dense output, or Hermite interpolation for methods without one). Events are
/// watched as the engine's own driver does: after each step every event function is evaluated
/// at the step's end, and a sign change is located on the same interpolant
/// ([`lagrangian::integrate::Solver::locate`]). As in SciPy's `solve_ivp`, the integration
/// then runs over the whole span (events may come after the last requested time), and a
/// terminal event ends the output at the last requested time before it.
fn drive_dense<S: ?Sized, M: Integrate<S>>(
    m: &M,
    sys: &S,
    y0: &[f64],
    p: &RunSpec,
    t_eval: &[f64],
    ctl: &Control,
) -> Result<Out, RunError> {
    let n = y0.len();
    let mut solver = m.solver(sys, p.t0, y0, p.t1)?;
    solver.set_cancel(ctl.cancel.clone());
    let dir = if p.t1 >= p.t0 { 1.0 } else { -1.0 };
    let mut times = Vec::with_capacity(t_eval.len());
    let mut states = vec![0.0; t_eval.len() * n];
    let mut next = 0;
    while next < t_eval.len() && t_eval[next] == p.t0 {
        states[next * n..(next + 1) * n].copy_from_slice(y0);
        times.push(p.t0);
        next += 1;
    }
    let gs: Vec<_> = p.events.iter().map(EventSpec::function).collect();
    let mut g_prev: Vec<f64> = gs.iter().map(|g| g(p.t0, y0)).collect();
    let mut events = Vec::new();
    let mut stop = None;
    while next < t_eval.len() || !gs.is_empty() {
        if solver.steps() >= p.max_steps {
            return Err(RunError::Failed(IntegrateError {
                t: solver.t(),
                state: solver.y().to_vec(),
                reason: lagrangian::integrate::FailureReason::StepLimit { max_steps: p.max_steps },
                steps: solver.steps(),
            }));
        }
        if ctl.cancel.is_cancelled() {
            return Err(RunError::Cancelled);
        }
        let status = solver.step()?;
        let t = solver.t();
        ctl.t.store(t.to_bits(), Ordering::Relaxed);
        // This step's crossings in time order; a terminal one ends the output there.
        let mut hits = Vec::new();
        for (i, g) in gs.iter().enumerate() {
            let g1 = g(t, solver.y());
            if p.events[i].crossing.crossed(g_prev[i], g1) {
                let (te, ye) = solver.locate(g, g_prev[i], g1)?;
                hits.push(EventRecord { index: i, t: te, state: ye });
            }
            g_prev[i] = g1;
        }
        hits.sort_by(|a, b| (dir * a.t).total_cmp(&(dir * b.t)));
        let mut until = t;
        for h in hits {
            let (i, te) = (h.index, h.t);
            events.push(h);
            if p.events[i].terminal {
                stop = Some((i, te));
                until = te;
                break;
            }
        }
        while next < t_eval.len() && dir * (t_eval[next] - until) <= 0.0 {
            solver.interpolate(t_eval[next], &mut states[next * n..(next + 1) * n])?;
            times.push(t_eval[next]);
            next += 1;
        }
        if stop.is_some() || status == Status::Finished {
            break;
        }
    }
    states.truncate(times.len() * n);
    Ok(Out { times, states, events, stop, steps: solver.steps(), rejected: solver.rejected() })
}

/// Runs `p` on `c` from `y0`.
pub fn run(c: &Compiled, y0: &[f64], p: &RunSpec, ctl: &Control) -> Result<Out, RunError> {
    let m = p.method;
    let dt = p.dt.unwrap_or(f64::NAN);
    match m.family {
        Family::Splitting => {
            let Compiled::Separable(sep) = c else { unreachable!("splitting methods are compiled separable") };
            let mut s = match m.name {
                "leapfrog" | "verlet" => Splitting::leapfrog(dt),
                "yoshida4" => Splitting::yoshida4(dt),
                "yoshida6" => Splitting::yoshida6(dt),
                "yoshida8" => Splitting::yoshida8(dt),
                "blanes_moan" => Splitting::blanes_moan4(dt),
                _ => Splitting::symplectic_euler(dt),
            };
            if p.compensated {
                s = s.compensated();
            }
            drive(&s, sep as &dyn Separable, y0, p, ctl)
        }
        Family::Implicit => {
            let mut g = match m.name {
                "midpoint" => Gauss::midpoint(dt),
                "gauss4" => Gauss::gauss4(dt),
                _ => Gauss::gauss6(dt),
            };
            if p.compensated {
                g = g.compensated();
            }
            drive(&g, c.rhs(), y0, p, ctl)
        }
        Family::Explicit => {
            let mut r = if m.name == "euler" { ExplicitRk::euler(dt) } else { ExplicitRk::rk4(dt) };
            if p.compensated {
                r = r.compensated();
            }
            drive(&r, c.rhs(), y0, p, ctl)
        }
        Family::Adaptive if m.name == "taylor" => {
            let Compiled::Taylor(ode, _) = c else { unreachable!("the Taylor method is compiled to its Taylor form") };
            let mut t = Taylor::with_tolerances(p.rtol, p.atol);
            if p.compensated {
                t = t.compensated();
            }
            t.validate().map_err(|msg| {
                RunError::Failed(IntegrateError {
                    t: p.t0,
                    state: y0.to_vec(),
                    reason: lagrangian::integrate::FailureReason::InvalidInput(msg),
                    steps: 0,
                })
            })?;
            drive(&t, ode, y0, p, ctl)
        }
        Family::Variational => Err(RunError::Failed(IntegrateError {
            t: p.t0,
            state: y0.to_vec(),
            reason: lagrangian::integrate::FailureReason::InvalidInput(format!(
                "`{}` runs in scenes, not in the Python binding",
                m.name
            )),
            steps: 0,
        })),
        Family::Adaptive => {
            let mut d = Dop853::new(p.rtol, p.atol);
            if p.compensated {
                d = d.compensated();
            }
            drive(&d, c.rhs(), y0, p, ctl)
        }
    }
}

/// How a progress bar is shown.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum ProgressMode {
    /// No bar and no polling thread (the fastest path, for short runs and benchmarks).
    Off,
    /// A bar once the run has taken more than a second.
    Auto,
    /// A bar from the start.
    On,
}

pub fn progress_mode(p: Option<bool>) -> ProgressMode {
    match p {
        None => ProgressMode::Auto,
        Some(true) => ProgressMode::On,
        Some(false) => ProgressMode::Off,
    }
}

/// Runs `work` with the GIL released. Unless `mode` is `Off`, `work` runs on a scoped thread
/// while this one draws the bar (`fraction()` in [0, 1]) and turns Ctrl-C into a cancel.
fn with_progress<R: Send>(
    py: Python<'_>,
    mode: ProgressMode,
    label: &str,
    ctl: &Control,
    fraction: impl Fn() -> f64 + Send + Sync,
    work: impl FnOnce() -> R + Send,
) -> PyResult<R> {
    if mode == ProgressMode::Off {
        return Ok(py.allow_threads(work));
    }
    let (result, interrupted) = py.allow_threads(|| {
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel();
            s.spawn(move || {
                let _ = tx.send(work());
            });
            let start = Instant::now();
            let mut bar: Option<PyObject> = None;
            let mut interrupted: Option<PyErr> = None;
            let delay = if mode == ProgressMode::On { Duration::ZERO } else { Duration::from_secs(1) };
            let show = |bar: &mut Option<PyObject>| {
                Python::with_gil(|py| {
                    if bar.is_none() && start.elapsed() >= delay {
                        *bar = py
                            .import("lagrangian._progress")
                            .and_then(|m| m.getattr("Bar")?.call1((label,)))
                            .map(|b| b.unbind())
                            .ok();
                    }
                })
            };
            if mode == ProgressMode::On {
                show(&mut bar);
            }
            loop {
                match rx.recv_timeout(Duration::from_millis(100)) {
                    Ok(r) => {
                        Python::with_gil(|py| {
                            if let Some(b) = &bar {
                                let _ = b.call_method1(py, "update", (1.0,));
                                let _ = b.call_method0(py, "close");
                            }
                        });
                        return (Some(r), interrupted);
                    }
                    Err(mpsc::RecvTimeoutError::Disconnected) => return (None, interrupted),
                    Err(mpsc::RecvTimeoutError::Timeout) => {}
                }
                show(&mut bar);
                Python::with_gil(|py| {
                    if let Err(e) = py.check_signals() {
                        ctl.cancel.cancel();
                        interrupted.get_or_insert(e);
                    }
                    if let Some(b) = &bar {
                        let _ = b.call_method1(py, "update", (fraction().clamp(0.0, 1.0),));
                    }
                });
            }
        })
    });
    if let Some(e) = interrupted {
        return Err(e);
    }
    result.ok_or_else(|| PyKeyboardInterrupt::new_err("the integration thread ended without a result"))
}

/// Reads `y0`: an array of `n` numbers, or a dict by state name.
fn initial_state(y0: &Bound<'_, PyAny>, names: &[String]) -> PyResult<Vec<f64>> {
    if let Ok(d) = y0.downcast::<PyDict>() {
        let mut out = vec![f64::NAN; names.len()];
        for (k, v) in d.iter() {
            let k: String = k.extract()?;
            let Some(i) = names.iter().position(|n| *n == k) else {
                return Err(PyValueError::new_err(format!(
                    "`{k}` is not a state variable of this integration (the state is {})",
                    names.join(", ")
                )));
            };
            out[i] = v.extract()?;
        }
        if let Some(i) = out.iter().position(|v| v.is_nan()) {
            return Err(PyValueError::new_err(format!(
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
        return Err(PyValueError::new_err(format!(
            "y0 has shape {shape:?}; expected ({},) for the state ({})",
            names.len(),
            names.join(", ")
        )));
    }
    f64_vec(&a)
}

/// Checks the arguments shared by `integrate` and `ensemble`.
#[allow(clippy::too_many_arguments)]
fn run_spec(
    py: Python<'_>,
    s: &PySystem,
    method_name: &str,
    t_span: (f64, f64),
    dt: Option<f64>,
    tol: f64,
    atol: Option<f64>,
    max_steps: Option<usize>,
    events: Option<&Bound<'_, PyList>>,
    compensated: bool,
) -> PyResult<(RunSpec, Arc<Compiled>, Vec<String>)> {
    let m = method(method_name)?;
    let (t0, t1) = t_span;
    if !t0.is_finite() || !t1.is_finite() {
        return Err(PyValueError::new_err(format!("t_span ({t0}, {t1}) is not finite")));
    }
    match (m.family, dt) {
        (Family::Adaptive, Some(_)) => {
            return Err(PyValueError::new_err(format!(
                "`{}` chooses its own steps: give `tol` instead of `dt` (or pick a fixed-step method such as gauss6)",
                m.name
            )))
        }
        (Family::Adaptive, None) => {}
        (_, None) => {
            return Err(PyValueError::new_err(format!(
                "`{}` is a fixed-step method and needs a step: pass dt=…",
                m.name
            )))
        }
        (_, Some(h)) if !(h.is_finite() && h > 0.0) => {
            return Err(PyValueError::new_err(format!("dt = {h} must be positive and finite")))
        }
        (_, Some(h)) if (t1 - t0).abs() / h > 1e10 => {
            return Err(PyValueError::new_err(format!(
                "{:.3e} steps of dt = {h} is more than the limit of 10¹⁰",
                (t1 - t0).abs() / h
            )))
        }
        _ => {}
    }
    if !(tol.is_finite() && tol > 0.0) {
        return Err(PyValueError::new_err(format!("tol = {tol} must be positive and finite")));
    }
    let f = Formulation::for_method(&s.sys, m);
    let names = f.state_names(&s.sys);
    let c = compiled(py, s, f)?;
    let mut evs = Vec::new();
    let params: Vec<(String, f64)> = s.sys.param_values().iter().map(|(k, v)| (k.name().to_string(), *v)).collect();
    for ev in events.into_iter().flatten() {
        let (expr_obj, direction, terminal) = if let Ok(e) = ev.downcast::<PyEvent>() {
            let e = e.get();
            (e.expr.clone_ref(py).into_bound(py), e.direction, e.terminal)
        } else {
            (ev.clone(), 0, false)
        };
        let e = to_expr(&expr_obj, s.sys.declarations(), true)?;
        let mut inputs: Vec<&str> = names.iter().map(String::as_str).collect();
        inputs.push("t");
        let refs: Vec<(&str, f64)> = params
            .iter()
            .filter(|(k, _)| e.free_symbols().iter().any(|s| s.name() == k))
            .map(|(k, v)| (k.as_str(), *v))
            .collect();
        let tape = Tape::compile(&[e], &inputs, &refs).py()?;
        let crossing = match direction.signum() {
            1 => Crossing::Rising,
            -1 => Crossing::Falling,
            _ => Crossing::Either,
        };
        evs.push(EventSpec { tape: Arc::new(tape), crossing, terminal });
    }
    let spec = RunSpec {
        method: m,
        t0,
        t1,
        dt,
        rtol: tol,
        atol: atol.unwrap_or(tol),
        max_steps: max_steps.unwrap_or(100_000_000),
        every: 1,
        final_only: false,
        compensated,
        t_eval: None,
        events: evs,
    };
    Ok((spec, c, names))
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
    /// ``"end"`` (the end of ``t_span`` was reached) or ``"event"`` (a terminal event).
    #[pyo3(get)]
    status: &'static str,
    #[pyo3(get)]
    method: &'static str,
    #[pyo3(get)]
    steps: usize,
    #[pyo3(get)]
    rejected: usize,
}

#[pymethods]
impl Solution {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let n: usize = self.t.bind(py).len()?;
        Ok(format!(
            "Solution(method={}, points={n}, steps={}, status={}, state=({}))",
            self.method,
            self.steps,
            self.status,
            self.names.join(", ")
        ))
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

fn solution(py: Python<'_>, out: Out, names: Vec<String>, n_events: usize, method: &'static str) -> PyResult<Solution> {
    let n = names.len();
    let k = out.times.len();
    // (k, n) row-major → (n, k): one row per state variable.
    let mut y = vec![0.0; n * k];
    for j in 0..k {
        for i in 0..n {
            y[i * k + j] = out.states[j * n + i];
        }
    }
    let t_events = PyList::empty(py);
    let y_events = PyList::empty(py);
    for e in 0..n_events {
        let recs: Vec<&EventRecord> = out.events.iter().filter(|r| r.index == e).collect();
        let ts: Vec<f64> = recs.iter().map(|r| r.t).collect();
        let ys: Vec<f64> = recs.iter().flat_map(|r| r.state.iter().copied()).collect();
        t_events.append(PyArray1::from_vec(py, ts))?;
        y_events.append(PyArray1::from_vec(py, ys).reshape([recs.len(), n])?)?;
    }
    Ok(Solution {
        t: PyArray1::from_vec(py, out.times).into_any().unbind(),
        y: PyArray1::from_vec(py, y).reshape([n, k])?.into_any().unbind(),
        names,
        t_events: t_events.into_any().unbind(),
        y_events: y_events.into_any().unbind(),
        status: if out.stop.is_some() { "event" } else { "end" },
        method,
        steps: out.steps,
        rejected: out.rejected,
    })
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
        let lagrangian = matches!(this.sys.kind(), Kind::Lagrangian(_));
        let f = match formulation {
            None if lagrangian => Formulation::Lagrangian,
            None => Formulation::Hamiltonian,
            Some("lagrangian") => Formulation::Lagrangian,
            Some("hamiltonian") => Formulation::Hamiltonian,
            Some("separable") => Formulation::Separable,
            Some(other) => {
                return Err(PyValueError::new_err(format!(
                    "unknown formulation `{other}` (lagrangian, hamiltonian or separable)"
                )))
            }
        };
        let c = compiled(py, this, f)?;
        Ok(CompiledRhs {
            c,
            names: f.state_names(&this.sys),
            system: slf.clone().unbind(),
            formulation: f,
            jac: std::sync::OnceLock::new(),
        })
    }

    /// Integrates from ``y0`` over ``t_span = (t0, t1)`` and returns a :class:`Solution`.
    ///
    /// ``method`` is one of ``dop853`` and ``taylor`` (adaptive, tolerance ``tol``/``atol``), ``rk4``,
    /// ``euler``, ``midpoint``, ``gauss4``, ``gauss6`` (symplectic collocation),
    /// ``leapfrog``/``verlet``, ``yoshida4``/``6``/``8``, ``blanes_moan``,
    /// ``symplectic_euler`` (splitting methods, which need ``H = T(p) + V(q)`` and use the
    /// state ``(q, p_q)``); fixed-step methods need ``dt``. :meth:`state_names` gives the
    /// layout of ``y0`` (an array, or a dict by state name). ``t_eval`` asks for the states at
    /// given times (dense output) instead of at every step; ``every=k`` keeps every k-th
    /// step. ``events`` is a list of expressions or :class:`Event` objects, located on the
    /// step's interpolant; with ``t_eval`` too, as in SciPy, events are watched over the whole
    /// span and a terminal one ends the output at the last ``t_eval`` time before it.
    /// The GIL is
    /// released while the engine integrates; runs longer than a second show a progress bar
    /// (``progress=True`` at once, ``False`` never) and Ctrl-C stops them.
    #[pyo3(signature = (t_span, y0, method="dop853", *, dt=None, tol=1e-10, atol=None, t_eval=None, events=None, every=1, max_steps=None, compensated=false, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn integrate(
        &self,
        py: Python<'_>,
        t_span: (f64, f64),
        y0: &Bound<'_, PyAny>,
        method: &str,
        dt: Option<f64>,
        tol: f64,
        atol: Option<f64>,
        t_eval: Option<&Bound<'_, PyAny>>,
        events: Option<&Bound<'_, PyList>>,
        every: usize,
        max_steps: Option<usize>,
        compensated: bool,
        progress: Option<bool>,
    ) -> PyResult<Solution> {
        let (mut spec, c, names) = run_spec(py, self, method, t_span, dt, tol, atol, max_steps, events, compensated)?;
        let y0 = initial_state(y0, &names)?;
        spec.every = every.max(1);
        if let Some(te) = t_eval {
            let a = float_array(te)?;
            let te: Vec<f64> = f64_vec(&a.call_method0("ravel")?)?;
            let (t0, t1) = t_span;
            let dir = if t1 >= t0 { 1.0 } else { -1.0 };
            if let Some(x) = te.iter().find(|x| !(dir * (**x - t0) >= 0.0 && dir * (t1 - **x) >= 0.0)) {
                return Err(PyValueError::new_err(format!("t_eval value {x} is outside t_span ({t0}, {t1})")));
            }
            if te.windows(2).any(|w| dir * (w[1] - w[0]) < 0.0) {
                return Err(PyValueError::new_err("t_eval must be sorted in the direction of integration"));
            }
            spec.t_eval = Some(te);
        }
        let ctl = Control::default();
        let n_events = spec.events.len();
        let (t0, t1) = t_span;
        let frac = || {
            let t = f64::from_bits(ctl.t.load(Ordering::Relaxed));
            if t1 == t0 {
                1.0
            } else {
                (t - t0) / (t1 - t0)
            }
        };
        ctl.t.store(t0.to_bits(), Ordering::Relaxed);
        let result =
            with_progress(py, progress_mode(progress), spec.method.name, &ctl, frac, || run(&c, &y0, &spec, &ctl))?;
        match result {
            Ok(out) => solution(py, out, names, n_events, spec.method.name),
            Err(RunError::Failed(e)) => Err(integration_error(py, e)),
            Err(RunError::Cancelled) => Err(PyKeyboardInterrupt::new_err("integration interrupted")),
        }
    }

    /// Integrates many initial states ``Y0`` (shape ``(k, n)``, one state per row) over
    /// ``t_span`` in parallel (rayon; ``threads`` workers, default all cores) and returns
    /// their final states as an :class:`EnsembleResult`. One trajectory's failure does not
    /// stop the others. The arguments are those of :meth:`integrate`; a terminal event ends
    /// each trajectory at its crossing (``t`` then holds the crossing times).
    #[pyo3(signature = (y0, t_span, method="dop853", *, dt=None, tol=1e-10, atol=None, events=None, max_steps=None, compensated=false, threads=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn ensemble(
        &self,
        py: Python<'_>,
        y0: &Bound<'_, PyAny>,
        t_span: (f64, f64),
        method: &str,
        dt: Option<f64>,
        tol: f64,
        atol: Option<f64>,
        events: Option<&Bound<'_, PyList>>,
        max_steps: Option<usize>,
        compensated: bool,
        threads: Option<usize>,
        progress: Option<bool>,
    ) -> PyResult<EnsembleResult> {
        let (mut spec, c, names) = run_spec(py, self, method, t_span, dt, tol, atol, max_steps, events, compensated)?;
        spec.final_only = true;
        let n = names.len();
        let a = float_array(y0)?;
        let shape: Vec<usize> = a.getattr("shape")?.extract()?;
        if shape.len() != 2 || shape[1] != n {
            return Err(PyValueError::new_err(format!(
                "Y0 has shape {shape:?}; expected (k, {n}): one state ({}) per row",
                names.join(", ")
            )));
        }
        let k = shape[0];
        let flat = f64_vec(&a)?;
        let ctl = Control::default();
        let frac = || if k == 0 { 1.0 } else { ctl.done.load(Ordering::Relaxed) as f64 / k as f64 };
        let one = |y: &[f64]| -> Result<Vec<f64>, String> {
            if ctl.cancel.is_cancelled() {
                return Err("cancelled".into());
            }
            let r = match run(&c, y, &spec, &ctl) {
                Ok(out) => {
                    let last = out.times.len() - 1;
                    let mut v = out.states[last * n..(last + 1) * n].to_vec();
                    v.push(out.times[last]);
                    Ok(v)
                }
                Err(RunError::Failed(e)) => Err(e.to_string()),
                Err(RunError::Cancelled) => Err("cancelled".into()),
            };
            ctl.done.fetch_add(1, Ordering::Relaxed);
            r
        };
        let results = with_progress(py, progress_mode(progress), "ensemble", &ctl, frac, || match threads {
            Some(th) => lagrangian::compile::ensemble_with_threads(th.max(1), &flat, n, one),
            None => lagrangian::compile::ensemble(&flat, n, one),
        })?;
        if ctl.cancel.is_cancelled() {
            return Err(PyKeyboardInterrupt::new_err("ensemble interrupted"));
        }
        let results = match results {
            Ok(r) => r,
            Err(e) => return Err(crate::errors::ToPyErr::py_err(e)),
        };
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
