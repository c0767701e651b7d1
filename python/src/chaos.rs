//! Chaos indicators and the variational equations of a `System`, as the scene statements
//! `megno`, `lyapunov`, `fli`, `chaos_map` compute them: the library's
//! [`lagrangian::chaos`] on [`lagrangian::compile::Variational`] of Hamilton's equations,
//! integrated by the Taylor method (default tolerance 1e-12, the scenes'). Nothing is
//! re-implemented here; this file reads arguments and returns arrays. The public Python
//! methods (`megno`, `fli`, `lyapunov`, `indicators`, `chaos_map`, `poincare`, `flow`) are in
//! `lagrangian/_chaos.py` over these; `flow` is the scene's `flow` statement and
//! `lagrangian flow` ([`lagrangian::chaos::flow_with`], its lines from
//! [`lagrangian::report::flow`]).

use lagrangian::chaos::{self, Budget, Indicator, MegnoStop};
use lagrangian::compile::Variational;
use lagrangian::print::Format;
use lagrangian::report;
use lagrangian::Symbol;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::types::PyList;

use crate::convert::{f64_vec, float_array, time_span};
use crate::errors::{exc, integration_error, PyResultExt};
use crate::system::PySystem;

/// The scenes' tolerance for chaos indicators.
const DEFAULT_TOL: f64 = 1e-12;

/// The tolerance of the scene's `flow` and `lagrangian flow`: `Φ` is checked against exact
/// identities (`det Φ = 1`), so it is integrated near machine precision.
const FLOW_TOL: f64 = 1e-14;

/// The scene's `flow`: checks kept at about this many steps.
const FLOW_POINTS: usize = 400;

impl PySystem {
    /// The canonical state `(q, p)` names.
    fn canonical_names(&self) -> Vec<String> {
        self.sys.coordinates().iter().chain(self.sys.momenta()).map(Symbol::to_string).collect()
    }

    /// Refuses what Hamilton's equations of `H` would leave out: the indicators measure the flow
    /// of `H`, so a force, a dissipation or a constraint would be dropped without a word.
    fn hamiltonian_flow_only(&self, what: &str) -> PyResult<()> {
        let forced = self.sys.forces().iter().any(|f| !f.is_zero());
        if forced || self.sys.rayleigh().is_some() || !self.sys.constraints().is_empty() {
            return Err(exc::ArgumentError::new_err(format!(
                "{what} is computed from the variational equations of Hamilton's equations of H, which leave out the forces, dissipation and constraints of this system; integrate it instead (System.integrate), or remove them"
            )));
        }
        Ok(())
    }

    fn variational_system(&self, py: Python<'_>, tangents: usize, megno: bool) -> PyResult<Variational> {
        let sys = &self.sys;
        py.allow_threads(|| Variational::of_system(sys, tangents, megno)).py()
    }
}

/// `0..t_end` from a `t_span`, or the refusal: an indicator is measured from t = 0.
fn from_zero(t_span: &Bound<'_, PyAny>) -> PyResult<f64> {
    let (t0, t1) = time_span(t_span)?;
    if t0 != 0.0 || !(t1 > 0.0 && t1.is_finite()) {
        return Err(exc::ArgumentError::new_err(format!(
            "a chaos indicator is measured from t = 0 to a later time; got t_span = ({t0}, {t1}): write (0, {})",
            if t1 > 0.0 { t1 } else { 100.0 }
        )));
    }
    Ok(t1)
}

fn tolerance(tol: Option<f64>) -> PyResult<f64> {
    let tol = tol.unwrap_or(DEFAULT_TOL);
    if !(tol > 0.0 && tol.is_finite()) {
        return Err(exc::ArgumentError::new_err(format!("tol must be positive and finite, found {tol}")));
    }
    Ok(tol)
}

/// A canonical start `(q, p)` of `2n` numbers.
fn canonical_start(x0: &Bound<'_, PyAny>, names: &[String]) -> PyResult<Vec<f64>> {
    let v = f64_vec(&float_array(x0)?.call_method0("ravel")?)?;
    if v.len() != names.len() || v.iter().any(|x| !x.is_finite()) {
        return Err(exc::ArgumentError::new_err(format!(
            "the start must be {} finite numbers, the canonical state ({}); got {v:?}",
            names.len(),
            names.join(", ")
        )));
    }
    Ok(v)
}

fn chaos_error(py: Python<'_>, e: lagrangian::integrate::IntegrateError) -> PyErr {
    let msg = e.to_string();
    integration_error(py, e, msg)
}

#[pymethods]
impl PySystem {
    /// The indicators of one orbit from the canonical start ``x0`` (``(q, p)``), as a dict:
    /// ``lyapunov`` (one exponent per tangent vector), ``fli``, ``megno``, ``megno_lyapunov``
    /// (the exponent from the slope of MEGNO's ``Y(t)``, as REBOUND reports it), ``steps`` and the
    /// samples ``t``, ``lyapunov_t``, ``log_norm_t``, ``megno_t``. ``which`` is ``"megno"``
    /// or ``"fli"`` (one tangent vector and MEGNO's accumulator) or ``"lyapunov"`` (2n tangent
    /// vectors, the spectrum), as the scene statements. ``tangent`` is the first tangent
    /// vector (default ``e₁``).
    #[pyo3(signature = (t_span, x0, which, *, tol=None, tangent=None, max_steps=None))]
    #[allow(clippy::too_many_arguments)]
    fn _indicators<'py>(
        &self,
        py: Python<'py>,
        t_span: &Bound<'py, PyAny>,
        x0: &Bound<'py, PyAny>,
        which: &str,
        tol: Option<f64>,
        tangent: Option<&Bound<'py, PyAny>>,
        max_steps: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.hamiltonian_flow_only(which)?;
        let (t1, tol) = (from_zero(t_span)?, tolerance(tol)?);
        let names = self.canonical_names();
        let n = names.len();
        let x0 = canonical_start(x0, &names)?;
        let (tangents, megno) = match Indicator::named(which).ok_or_else(|| unknown_indicator(which))? {
            Indicator::Lyapunov => (n, false),
            Indicator::Megno | Indicator::Fli => (1, true),
        };
        let var = self.variational_system(py, tangents, megno)?;
        let y0 = match tangent {
            None => var.initial_state(&x0),
            Some(w) => {
                let w = f64_vec(&float_array(w)?.call_method0("ravel")?)?;
                chaos::initial_state_along(&var, &x0, &w).ok_or_else(|| {
                    exc::ArgumentError::new_err(format!(
                        "tangent must be {n} finite numbers, not all zero (a direction in ({})); got {w:?}",
                        names.join(", ")
                    ))
                })?
            }
        };
        let mut budget = Budget::default();
        if let Some(m) = max_steps {
            budget.max_steps = m;
        }
        let r =
            py.allow_threads(|| chaos::indicators_from(&var, &y0, t1, tol, &budget)).map_err(|e| chaos_error(py, e))?;
        let d = PyDict::new(py);
        d.set_item("lyapunov", PyArray1::from_vec(py, r.lyapunov.clone()))?;
        d.set_item("fli", r.fli)?;
        d.set_item("megno", r.megno)?;
        d.set_item("megno_lyapunov", r.megno_lyapunov)?;
        d.set_item("steps", r.steps)?;
        d.set_item("t", PyArray1::from_iter(py, r.samples.iter().map(|s| s.t)))?;
        d.set_item("lyapunov_t", PyArray1::from_iter(py, r.samples.iter().map(|s| s.lyapunov)))?;
        d.set_item("log_norm_t", PyArray1::from_iter(py, r.samples.iter().map(|s| s.log_norm)))?;
        d.set_item("megno_t", PyArray1::from_iter(py, r.samples.iter().map(|s| s.megno)))?;
        d.set_item("names", names)?;
        Ok(d)
    }

    /// One indicator (``"megno"``, ``"fli"`` or ``"lyapunov"``, the maximal exponent) for
    /// each canonical start, a row of ``starts`` ``(k, 2n)``, in parallel; NaN where an orbit
    /// failed (escaped, hit a singularity, ran out of the budget), as the library's
    /// ``chaos_map``. With ``megno_stop = (above, after)`` (a MEGNO map only) an orbit whose
    /// mean MEGNO reaches ``above`` at ``t ≥ after`` stops there (``chaos::MegnoStop``), and
    /// the result is the pair ``(values, stopped_at)``, ``stopped_at`` NaN for a cell that ran
    /// to the end.
    #[pyo3(signature = (t_span, starts, which, *, tol=None, megno_stop=None))]
    fn _chaos_map<'py>(
        &self,
        py: Python<'py>,
        t_span: &Bound<'py, PyAny>,
        starts: &Bound<'py, PyAny>,
        which: &str,
        tol: Option<f64>,
        megno_stop: Option<(f64, f64)>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.hamiltonian_flow_only("a chaos map")?;
        let (t1, tol) = (from_zero(t_span)?, tolerance(tol)?);
        let names = self.canonical_names();
        let n = names.len();
        let a = float_array(starts)?;
        let shape: Vec<usize> = a.getattr("shape")?.extract()?;
        if shape.len() != 2 || shape[1] != n {
            return Err(exc::ArgumentError::new_err(format!(
                "starts has shape {shape:?}; expected (k, {n}), one canonical state ({}) per row",
                names.join(", ")
            )));
        }
        let flat = f64_vec(&a)?;
        let rows: Vec<Vec<f64>> = flat.chunks(n.max(1)).map(<[f64]>::to_vec).collect();
        let which = Indicator::named(which).ok_or_else(|| unknown_indicator(which))?;
        let stop = match megno_stop {
            None => None,
            Some(_) if which != Indicator::Megno => {
                return Err(exc::ArgumentError::new_err(
                    "megno_stop stops orbits by their mean MEGNO: it applies to a map of `megno` only",
                ))
            }
            Some((above, after)) => Some(MegnoStop::new(above, after).map_err(exc::ArgumentError::new_err)?),
        };
        let var = self.variational_system(py, 1, which == Indicator::Megno)?;
        let Some(stop) = stop else {
            let values = py.allow_threads(|| chaos::chaos_map(&var, &rows, t1, tol, which));
            return Ok(PyArray1::from_vec(py, values).into_any());
        };
        // Each start within a default budget of its own, as `chaos::chaos_map` runs them.
        let cells: Vec<(f64, f64)> = py.allow_threads(|| {
            let budget = Budget { megno_stop: Some(stop), ..Budget::default() };
            let map = chaos::chaos_map_each(&var, &rows, t1, tol, which, &budget);
            map.iter().map(|c| (c.value, c.stopped_at.unwrap_or(f64::NAN))).collect()
        });
        let values = PyArray1::from_iter(py, cells.iter().map(|c| c.0));
        let stopped = PyArray1::from_iter(py, cells.iter().map(|c| c.1));
        Ok((values, stopped).into_pyobject(py)?.into_any())
    }

    /// The state transition matrix ``Φ(t1) = ∂x(t1)/∂x(0)`` of the canonical state
    /// ``x = (q, p)`` from ``x0``, shape ``(2n, 2n)``, and the state ``x(t1)``: the
    /// variational equations ``Φ' = J Φ``, ``Φ(0) = I``, integrated with the orbit by the
    /// Taylor method at ``tol`` (default 1e-12). ``t_span`` starts at 0.
    #[pyo3(signature = (t_span, x0, *, tol=None))]
    fn variational<'py>(
        &self,
        py: Python<'py>,
        t_span: &Bound<'py, PyAny>,
        x0: &Bound<'py, PyAny>,
        tol: Option<f64>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        self.hamiltonian_flow_only("the state transition matrix")?;
        let (t1, tol) = (from_zero(t_span)?, tolerance(tol)?);
        let names = self.canonical_names();
        let n = names.len();
        let x0 = canonical_start(x0, &names)?;
        let var = self.variational_system(py, n, false)?;
        let (phi, end) =
            py.allow_threads(|| chaos::transition_matrix(&var, &x0, t1, tol)).map_err(|e| chaos_error(py, e))?;
        Ok((PyArray1::from_vec(py, phi).reshape([n, n])?.into_any(), PyArray1::from_vec(py, end).into_any()))
    }

    /// The flow's Jacobian ``Φ(t1)`` of the canonical state from ``x0`` with its structural
    /// checks, as the scene's ``flow`` statement and ``lagrangian flow`` compute and print them:
    /// a dict with ``phi`` ``(2n, 2n)``, ``end``, ``det_minus_one``, ``symplectic_defect``
    /// (``None`` when forces or dissipation make the flow non-Hamiltonian; they are part of
    /// the flow here), ``steps``, the checks along the run (``t``, ``det_minus_one_t``,
    /// ``symplectic_defect_t``, at about ``points`` steps), ``names`` and the printed
    /// ``lines``. Constraints are refused. Default tolerance 1e-14, the scene's.
    #[pyo3(signature = (t_span, x0, *, tol=None, points=None, max_steps=None))]
    #[allow(clippy::too_many_arguments)]
    fn _flow<'py>(
        &self,
        py: Python<'py>,
        t_span: &Bound<'py, PyAny>,
        x0: &Bound<'py, PyAny>,
        tol: Option<f64>,
        points: Option<usize>,
        max_steps: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let t1 = from_zero(t_span)?;
        let tol = tolerance(Some(tol.unwrap_or(FLOW_TOL)))?;
        let points = points.unwrap_or(FLOW_POINTS);
        if points < 2 {
            return Err(exc::ArgumentError::new_err(format!("points must be at least 2, found {points}")));
        }
        let names = self.canonical_names();
        let n = names.len();
        let x0 = canonical_start(x0, &names)?;
        let var = self.variational_system(py, n, false)?;
        let mut budget = Budget::default();
        if let Some(m) = max_steps {
            budget.max_steps = m;
        }
        let flow = py
            .allow_threads(|| chaos::flow_with(&var, &x0, t1, tol, points, &budget))
            .map_err(|e| chaos_error(py, e))?;
        let d = PyDict::new(py);
        d.set_item("phi", PyArray1::from_vec(py, flow.phi.clone()).reshape([n, n])?)?;
        d.set_item("end", PyArray1::from_vec(py, flow.end.clone()))?;
        d.set_item("det_minus_one", flow.det_minus_one)?;
        d.set_item("symplectic_defect", flow.symplectic_defect)?;
        d.set_item("steps", flow.steps)?;
        d.set_item("t", PyArray1::from_iter(py, flow.samples.iter().map(|s| s.t)))?;
        d.set_item("det_minus_one_t", PyArray1::from_iter(py, flow.samples.iter().map(|s| s.det_minus_one)))?;
        d.set_item(
            "symplectic_defect_t",
            PyArray1::from_iter(py, flow.samples.iter().map(|s| s.symplectic_defect.unwrap_or(f64::NAN))),
        )?;
        let lines: Vec<String> =
            report::flow(&names, t1, &flow).iter().map(|l| report::render_line(l, Format::Plain)).collect();
        d.set_item("lines", PyList::new(py, lines)?)?;
        d.set_item("names", names)?;
        Ok(d)
    }
}

/// The error for an indicator name the library does not know, listing the ones it does.
fn unknown_indicator(name: &str) -> PyErr {
    let known: Vec<&str> = Indicator::ALL.iter().map(|i| i.name()).collect();
    exc::ArgumentError::new_err(format!("unknown indicator `{name}`: {}", known.join(", ")))
}
