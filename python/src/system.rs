//! `lagrangian.System`: a mechanical system and every derivation of the library on it. The
//! numeric side (compile, integrate, ensemble) is in `sim.rs`.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::{Arc, Mutex};

use lagrangian::canonical::{self, Generator, GeneratorKind, PhaseSpace, Trial};
use lagrangian::mechanics::{Kind, MechanicsError, System};
use lagrangian::parse::{parse_with, Declarations};
use lagrangian::print::{render, Format};
use lagrangian::simulate::{Compiled, Equations, Form};
use lagrangian::{Expr, Symbol};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::errors::{exc, PyResultExt};
use crate::expr::{declarations, to_expr, to_symbol, PyExpr};

/// What a compiled system of a `System` is cached by: the equations a method (or a named
/// formulation) integrates, and the form they are compiled to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CompiledKey {
    /// What `method` needs.
    Method(Form),
    /// The equations named by `System.compile(formulation=…)`, with or without the Jacobian.
    Named(Equations, Form),
}

/// Compiled systems of one `System` (compiling is done once per process and key).
pub type CompiledCache = Arc<Mutex<HashMap<CompiledKey, Arc<Compiled>>>>;

/// A mechanical system given by a Lagrangian ``L(q, q', t)`` or a Hamiltonian
/// ``H(q, p_q, t)``, with parameter values and optional forces, Rayleigh dissipation,
/// holonomic constraints and velocity (nonholonomic) constraints.
///
/// Coordinates are named (``["θ1", "θ2"]``); their velocities are ``θ1'`` and their momenta
/// ``p_θ1``. Every other free symbol except ``t`` is a parameter. Derivations return exact
/// :class:`Expr` objects; :meth:`compile` and :meth:`integrate` are the numeric side.
/// Systems pickle as their printed source and options, and are derived again when unpickled
/// (on a Dask worker, for instance).
#[pyclass(name = "System", module = "lagrangian", frozen)]
pub struct PySystem {
    pub sys: System,
    pub compiled: CompiledCache,
}

impl PySystem {
    pub fn wrap(sys: System) -> PySystem {
        PySystem { sys, compiled: Arc::new(Mutex::new(HashMap::new())) }
    }

    fn decls(&self) -> &Declarations {
        self.sys.declarations()
    }

    fn ex(&self, e: Expr) -> PyExpr {
        PyExpr::new(e, self.decls())
    }

    fn exs(&self, v: Vec<Expr>) -> Vec<PyExpr> {
        v.into_iter().map(|e| self.ex(e)).collect()
    }

    fn phase_space(&self) -> PyResult<PhaseSpace> {
        let q: Vec<&str> = self.sys.coordinates().iter().map(Symbol::name).collect();
        let p: Vec<&str> = self.sys.momenta().iter().map(Symbol::name).collect();
        PhaseSpace::with_momenta(q, p).py()
    }

    /// Refuses names outside this system's phase space and parameters (see [`check_phase_space`]).
    fn check_names(&self, exprs: &[&Expr]) -> PyResult<()> {
        let coords: Vec<String> = self.sys.coordinates().iter().map(|s| s.name().to_string()).collect();
        let params: Vec<String> = self.sys.parameters().iter().map(|s| s.name().to_string()).collect();
        check_phase_space(exprs, &coords, &params, true)
    }

    fn h(&self, py: Python<'_>) -> PyResult<Expr> {
        let sys = &self.sys;
        py.allow_threads(|| sys.hamiltonian()).py()
    }

    /// The printed source and options: what a pickle carries, and what `from_*` rebuilds.
    pub fn spec(&self) -> Spec {
        let sys = &self.sys;
        let (kind, e) = match sys.kind() {
            Kind::Lagrangian(l) => ("lagrangian", l),
            Kind::Hamiltonian(h) => ("hamiltonian", h),
        };
        let coords: Vec<String> = sys.coordinates().iter().map(|s| s.name().to_string()).collect();
        let forces = coords
            .iter()
            .zip(sys.forces())
            .filter(|(_, f)| !f.is_zero())
            .map(|(c, f)| (c.clone(), render(f, Format::Plain)))
            .collect();
        Spec {
            kind,
            text: render(e, Format::Plain),
            coords,
            params: sys.param_values().iter().map(|(k, v)| (k.name().to_string(), *v)).collect(),
            positive: sys.declarations().positive.iter().cloned().collect(),
            functions: sys.declarations().functions.iter().cloned().collect(),
            forces,
            rayleigh: sys.rayleigh().map(|r| render(r, Format::Plain)),
            constraints: sys.constraints().iter().map(|c| render(c, Format::Plain)).collect(),
            velocity_constraints: sys.velocity_constraints().iter().map(|g| render(g, Format::Plain)).collect(),
        }
    }
}

/// See [`PySystem::spec`].
#[derive(PartialEq)]
pub struct Spec {
    pub kind: &'static str,
    pub text: String,
    pub coords: Vec<String>,
    pub params: BTreeMap<String, f64>,
    pub positive: Vec<String>,
    pub functions: Vec<String>,
    pub forces: Vec<(String, String)>,
    pub rayleigh: Option<String>,
    pub constraints: Vec<String>,
    pub velocity_constraints: Vec<String>,
}

#[allow(clippy::too_many_arguments)]
fn build(
    hamiltonian: bool,
    text: &str,
    coords: Vec<String>,
    params: Option<&Bound<'_, PyDict>>,
    positive: Option<Vec<String>>,
    functions: Option<Vec<String>>,
    forces: Option<&Bound<'_, PyDict>>,
    rayleigh: Option<String>,
    constraints: Option<Vec<String>>,
    velocity_constraints: Option<Vec<String>>,
) -> PyResult<PySystem> {
    let decls = declarations(positive, functions);
    let cs: Vec<&str> = coords.iter().map(String::as_str).collect();
    let mut sys = if hamiltonian {
        System::from_hamiltonian_with(text, &cs, &decls)
    } else {
        System::from_lagrangian_with(text, &cs, &decls)
    }
    .py()?;
    if let Some(f) = forces {
        for (k, v) in f.iter() {
            let coord: String = k.extract()?;
            let text: String = v.str()?.extract()?;
            sys = sys.with_force(&coord, &text).py()?;
        }
    }
    if let Some(r) = rayleigh {
        sys = sys.with_rayleigh(&r).py()?;
    }
    for c in constraints.unwrap_or_default() {
        sys = sys.with_constraint(&c).py()?;
    }
    for g in velocity_constraints.unwrap_or_default() {
        sys = sys.with_velocity_constraint(&g).py()?;
    }
    if hamiltonian {
        sys.check_momenta().map_err(|e| match e {
            MechanicsError::MomentumNames(why) => exc::ArgumentError::new_err(why),
            other => exc::ArgumentError::new_err(other.to_string()),
        })?;
    }
    if let Some(p) = params {
        sys = with_params(sys, p)?;
    }
    Ok(PySystem::wrap(sys))
}

/// Parameter values, checked against the system's `positive=` declaration: the engine
/// simplified with `sqrt(m²) = m` and `|m| = m` for such a symbol, so `m = -1` would integrate
/// other equations (`cosh` where `cos` is right) without a word.
fn with_params(sys: System, values: &Bound<'_, PyDict>) -> PyResult<System> {
    let mut owned: Vec<(String, f64)> = Vec::new();
    for (k, v) in values.iter() {
        let (name, value): (String, f64) = (k.extract()?, v.extract()?);
        if value <= 0.0 && sys.declarations().positive.contains(&name) {
            return Err(exc::ArgumentError::new_err(format!(
                "`{name}` was declared positive (positive=[…]) and the equations were simplified on that assumption, so it cannot be {value}; give a positive value, or build the system without `{name}` in positive="
            )));
        }
        owned.push((name, value));
    }
    let refs: Vec<(&str, f64)> = owned.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    sys.with_params(&refs).py()
}

fn matrix(v: Vec<Vec<Expr>>, d: &Declarations) -> Vec<Vec<PyExpr>> {
    v.into_iter().map(|row| row.into_iter().map(|e| PyExpr::new(e, d)).collect()).collect()
}

fn relations<'py>(py: Python<'py>, rel: &[(Symbol, Expr)], d: &Declarations) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (s, e) in rel {
        out.set_item(s.to_string(), PyExpr::new(e.clone(), d))?;
    }
    Ok(out)
}

#[pymethods]
impl PySystem {
    /// A Lagrangian system. ``params`` gives parameter values (needed to compile),
    /// ``positive`` names positive symbols, ``functions`` undefined functions (``V`` for
    /// ``V(r)``), ``forces`` generalized forces by coordinate (``{"x": "-c x'"}``),
    /// ``rayleigh`` a dissipation function, ``constraints`` holonomic constraints
    /// (``"x^2 + y^2 = l^2"``) and ``velocity_constraints`` nonholonomic ones, linear in the
    /// velocities (``"x' = R φ' cos(θ)"``; see :meth:`with_velocity_constraint`).
    #[staticmethod]
    #[pyo3(signature = (text, coords, *, params=None, positive=None, functions=None, forces=None, rayleigh=None, constraints=None, velocity_constraints=None))]
    #[allow(clippy::too_many_arguments)]
    fn from_lagrangian(
        text: &str,
        coords: Vec<String>,
        params: Option<&Bound<'_, PyDict>>,
        positive: Option<Vec<String>>,
        functions: Option<Vec<String>>,
        forces: Option<&Bound<'_, PyDict>>,
        rayleigh: Option<String>,
        constraints: Option<Vec<String>>,
        velocity_constraints: Option<Vec<String>>,
    ) -> PyResult<PySystem> {
        build(false, text, coords, params, positive, functions, forces, rayleigh, constraints, velocity_constraints)
    }

    /// A Hamiltonian system: ``H`` in the coordinates, the momenta ``p_q`` and ``t``.
    #[staticmethod]
    #[pyo3(signature = (text, coords, *, params=None, positive=None, functions=None))]
    fn from_hamiltonian(
        text: &str,
        coords: Vec<String>,
        params: Option<&Bound<'_, PyDict>>,
        positive: Option<Vec<String>>,
        functions: Option<Vec<String>>,
    ) -> PyResult<PySystem> {
        build(true, text, coords, params, positive, functions, None, None, None, None)
    }

    fn __repr__(&self) -> String {
        let s = self.spec();
        let head = if s.kind == "lagrangian" { "L" } else { "H" };
        format!("System({head} = {}, coords = [{}])", s.text, s.coords.join(", "))
    }

    /// Jupyter's rich display: ``L = …`` or ``H = …`` in LaTeX.
    fn _repr_latex_(&self) -> String {
        let (head, e) = match self.sys.kind() {
            Kind::Lagrangian(l) => ("L", l),
            Kind::Hamiltonian(h) => ("H", h),
        };
        format!("$\\displaystyle {head} = {}$", render(e, Format::Latex))
    }

    /// ``"lagrangian"`` or ``"hamiltonian"``.
    #[getter]
    fn kind(&self) -> &'static str {
        self.spec().kind
    }

    /// The Lagrangian, or ``None`` for a Hamiltonian system.
    #[getter]
    fn lagrangian(&self) -> Option<PyExpr> {
        self.sys.lagrangian().map(|l| self.ex(l.clone()))
    }

    /// The coordinate names, in order.
    #[getter]
    fn coordinates(&self) -> Vec<String> {
        self.sys.coordinates().iter().map(|s| s.to_string()).collect()
    }

    /// The velocity names (``q'``).
    #[getter]
    fn velocities(&self) -> Vec<String> {
        self.sys.velocities().iter().map(|s| s.to_string()).collect()
    }

    /// The momentum names (``p_q``).
    #[getter]
    fn momenta(&self) -> Vec<String> {
        self.sys.momenta().iter().map(|s| s.to_string()).collect()
    }

    /// The parameter names (every free symbol but the coordinates, velocities, momenta and t).
    #[getter]
    fn parameters(&self) -> Vec<String> {
        self.sys.parameters().iter().map(|s| s.to_string()).collect()
    }

    /// The parameter values given so far.
    #[getter]
    fn params(&self) -> BTreeMap<String, f64> {
        self.spec().params
    }

    /// The printed source and options this system pickles as (a dict that
    /// ``System.from_lagrangian`` / ``from_hamiltonian`` accept back as keywords).
    #[getter]
    fn source<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.spec();
        let d = PyDict::new(py);
        d.set_item("kind", s.kind)?;
        d.set_item("text", s.text)?;
        d.set_item("coords", s.coords)?;
        d.set_item("params", s.params)?;
        d.set_item("positive", s.positive)?;
        d.set_item("functions", s.functions)?;
        if s.kind == "lagrangian" {
            let f = PyDict::new(py);
            for (c, t) in s.forces {
                f.set_item(c, t)?;
            }
            d.set_item("forces", f)?;
            d.set_item("rayleigh", s.rayleigh)?;
            d.set_item("constraints", s.constraints)?;
            d.set_item("velocity_constraints", s.velocity_constraints)?;
        }
        Ok(d)
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let f = py.import("lagrangian._pickle")?.getattr("_system")?;
        Ok((f, (self.source(py)?,)))
    }

    /// A copy with parameter values set (merged with those already given):
    /// ``sys.with_params(g=9.81)`` or ``sys.with_params({"g": 9.81})``.
    #[pyo3(signature = (values=None, **kwargs))]
    fn with_params(
        &self,
        values: Option<&Bound<'_, PyDict>>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PySystem> {
        let mut sys = self.sys.clone();
        for d in [values, kwargs].into_iter().flatten() {
            sys = with_params(sys, d)?;
        }
        Ok(PySystem::wrap(sys))
    }

    /// A copy with a generalized force ``Q`` on ``coord`` added: the equation becomes ``E = Q``.
    fn with_force(&self, coord: &str, text: &str) -> PyResult<PySystem> {
        Ok(PySystem::wrap(self.sys.clone().with_force(coord, text).py()?))
    }

    /// A copy with a Rayleigh dissipation function ``R(q, q')``.
    fn with_rayleigh(&self, text: &str) -> PyResult<PySystem> {
        Ok(PySystem::wrap(self.sys.clone().with_rayleigh(text).py()?))
    }

    /// A copy with a holonomic constraint ``f(q, t) = 0`` (``"f = g"`` means ``f − g``).
    fn with_constraint(&self, text: &str) -> PyResult<PySystem> {
        Ok(PySystem::wrap(self.sys.clone().with_constraint(text).py()?))
    }

    /// A copy with a velocity (nonholonomic) constraint ``a(q, t)·q' + b(q, t) = 0``, linear in
    /// the velocities (``"x' = R φ' cos(θ)"``; ``"f = g"`` means ``f − g``): a disc rolling
    /// without slipping, a knife edge. Its force ``μ ∂g/∂q'`` enters :meth:`equations` (the
    /// Lagrange–d'Alembert equations, multipliers ``μ1, μ2, …``), :meth:`accelerations`,
    /// :meth:`constrained_equations` and ``report("el")``; :meth:`integrate` with a classical
    /// method holds the run on it (a start must satisfy it) and :meth:`conserved` respects it.
    /// What has no place for it (the Hamiltonian and everything built on ``H``: ``hamilton``,
    /// ``legendre``, brackets with ``H``, chaos indicators, Taylor and symplectic methods;
    /// ``series``, ``average``) raises :class:`MechanicsError` naming what keeps it. A
    /// constraint without a velocity, or not linear in them, is refused.
    fn with_velocity_constraint(&self, text: &str) -> PyResult<PySystem> {
        Ok(PySystem::wrap(self.sys.clone().with_velocity_constraint(text).py()?))
    }

    /// The Euler–Lagrange expressions ``E_i = d/dt ∂L/∂q'_i − ∂L/∂q_i`` (each ``= 0``;
    /// accelerations appear as ``q''``).
    fn euler_lagrange(&self, py: Python<'_>) -> PyResult<Vec<PyExpr>> {
        let sys = &self.sys;
        Ok(self.exs(py.allow_threads(|| sys.euler_lagrange()).py()?))
    }

    /// The full equations of motion, each ``= 0``: Euler–Lagrange with forces, dissipation
    /// and constraint multipliers (``λ`` of holonomic constraints, ``μ`` of velocity ones:
    /// the Lagrange–d'Alembert equations).
    fn equations(&self, py: Python<'_>) -> PyResult<Vec<PyExpr>> {
        let sys = &self.sys;
        Ok(self.exs(py.allow_threads(|| sys.equations()).py()?))
    }

    /// The split ``W q'' = F``: returns ``(W, F)``, ``W`` as a list of rows.
    fn mass_matrix(&self, py: Python<'_>) -> PyResult<(Vec<Vec<PyExpr>>, Vec<PyExpr>)> {
        let sys = &self.sys;
        let (w, f) = py.allow_threads(|| sys.mass_matrix_split()).py()?;
        Ok((matrix(w, self.decls()), self.exs(f)))
    }

    /// The accelerations ``q'' = W⁻¹ F`` in closed form (up to four coupled coordinates, or
    /// four unknowns with the constraint multipliers, which are eliminated).
    fn accelerations(&self, py: Python<'_>) -> PyResult<Vec<PyExpr>> {
        let sys = &self.sys;
        Ok(self.exs(py.allow_threads(|| sys.accelerations()).py()?))
    }

    /// The canonical momenta ``p_i = ∂L/∂q'_i``.
    fn canonical_momenta(&self) -> PyResult<Vec<PyExpr>> {
        Ok(self.exs(self.sys.canonical_momenta().py()?))
    }

    /// The Legendre transform: the Hamiltonian system ``H = p·q' − L``.
    fn legendre(&self, py: Python<'_>) -> PyResult<PySystem> {
        let sys = &self.sys;
        Ok(PySystem::wrap(py.allow_threads(|| sys.legendre()).py()?))
    }

    /// The inverse Legendre transform: the Lagrangian system of a Hamiltonian.
    fn inverse_legendre(&self, py: Python<'_>) -> PyResult<PySystem> {
        let sys = &self.sys;
        Ok(PySystem::wrap(py.allow_threads(|| sys.inverse_legendre()).py()?))
    }

    /// The Hamiltonian: the system's own, or the Legendre transform of its Lagrangian.
    fn hamiltonian(&self, py: Python<'_>) -> PyResult<PyExpr> {
        Ok(self.ex(self.h(py)?))
    }

    /// Hamilton's equations: ``(qdot, pdot)`` with ``qdot[i] = ∂H/∂p_i`` and
    /// ``pdot[i] = −∂H/∂q_i``.
    fn hamilton(&self, py: Python<'_>) -> PyResult<(Vec<PyExpr>, Vec<PyExpr>)> {
        let sys = &self.sys;
        let eq = py.allow_threads(|| sys.hamilton_equations()).py()?;
        Ok((self.exs(eq.qdot), self.exs(eq.pdot)))
    }

    /// The series of ``L`` about the point ``about`` (one value per coordinate, default all 0)
    /// to order ``order`` in the displacements and velocities: the small-oscillation
    /// Lagrangian ``L_lin`` of the notes (2.29) at order 2. A coordinate's name stands for its
    /// displacement from the point in the result.
    #[pyo3(signature = (about=None, order=2))]
    fn series(&self, about: Option<Vec<Bound<'_, PyAny>>>, order: usize) -> PyResult<PyExpr> {
        let Some(l) = self.sys.lagrangian() else {
            return Err(exc::ArgumentError::new_err(
                "series expands a Lagrangian about a point; this system is Hamiltonian (use lagrangian.series on H with the small names)",
            ));
        };
        self.sys.refuse_velocity_constraints("a series of L (the small-oscillation Lagrangian)").py()?;
        let coords = self.sys.coordinates();
        let about: Vec<Expr> = match about {
            None => vec![Expr::zero(); coords.len()],
            Some(v) => v.iter().map(|x| to_expr(x, self.decls(), true)).collect::<PyResult<_>>()?,
        };
        if about.len() != coords.len() {
            return Err(exc::ArgumentError::new_err(format!(
                "`about` has {} value(s) for {} coordinate(s)",
                about.len(),
                coords.len()
            )));
        }
        let (series, _) = lagrangian::mechanics::series_about(l, coords, &about, order).py()?;
        Ok(self.ex(series))
    }

    /// The energy function ``h = Σ q' ∂L/∂q' − L`` (or ``H`` of a Hamiltonian system).
    fn energy(&self) -> PyExpr {
        self.ex(self.sys.energy_function())
    }

    /// The printed lines of a derivation, the same text as ``lagrangian el|legendre|hamilton|
    /// conserved`` and the scene statements print (one builder and one renderer serve all three),
    /// joined by newlines. ``what`` is ``el`` (``E_q: E_q = Q_q − ∂R/∂q' + Σ λ ∂f/∂q``),
    /// ``mass_matrix`` (``W`` and ``F``), ``constraints`` (``Φ`` and ``c``), ``accelerations``
    /// (with constraints the constrained ones and the multipliers), ``momenta``, ``legendre``
    /// (the momenta and ``H``), ``hamilton`` or ``conserved`` (with what breaks each candidate);
    /// ``format`` is ``plain``, ``unicode``, ``latex`` or ``json`` (a JSON array of the lines).
    #[pyo3(signature = (what, format = "unicode"))]
    fn report(&self, py: Python<'_>, what: &str, format: &str) -> PyResult<String> {
        use lagrangian::report;
        const WHAT: &str = "el, mass_matrix, constraints, accelerations, momenta, legendre, hamilton, conserved";
        let fmt = match format {
            "plain" => Some(Format::Plain),
            "unicode" => Some(Format::Unicode),
            "latex" => Some(Format::Latex),
            "json" => None,
            other => {
                return Err(exc::ArgumentError::new_err(format!(
                    "unknown format `{other}`: plain, unicode, latex or json"
                )))
            }
        };
        let sys = &self.sys;
        let lines = py
            .allow_threads(|| match what {
                "el" => report::euler_lagrange(sys).map(Some),
                "mass_matrix" => report::mass_matrix_split(sys).map(Some),
                "constraints" => report::constraints(sys).map(Some),
                "accelerations" => report::accelerations(sys).map(Some),
                "momenta" => report::momenta(sys).map(Some),
                "legendre" => report::legendre(sys).map(Some),
                "hamilton" => report::hamilton(sys).map(Some),
                "conserved" => Ok(Some(report::conserved(sys))),
                _ => Ok(None),
            })
            .py()?;
        let Some(lines) = lines else {
            return Err(exc::ArgumentError::new_err(format!("unknown derivation `{what}`: one of {WHAT}")));
        };
        Ok(match fmt {
            Some(f) => report::render_lines(&lines, f).join("\n"),
            None => report::lines_json(&lines).to_string(),
        })
    }

    /// Conserved quantities found by Noether's theorem: a list of ``(name, expr, reason)``.
    fn conserved(&self, py: Python<'_>) -> Vec<(String, PyExpr, String)> {
        let sys = &self.sys;
        py.allow_threads(|| sys.conserved())
            .into_iter()
            .map(|c| (c.name, self.ex(c.expr), c.reason.to_string()))
            .collect()
    }

    /// The point transformation ``q = Q(s, t)``: ``mapping`` gives each old coordinate in the
    /// new ones (``{"x": "r cos(φ)", "y": "r sin(φ)"}``), ``new_coords`` names them.
    fn transform(&self, py: Python<'_>, mapping: &Bound<'_, PyDict>, new_coords: Vec<String>) -> PyResult<PySystem> {
        let mut pairs: Vec<(String, String)> = Vec::new();
        for (k, v) in mapping.iter() {
            pairs.push((k.extract()?, v.str()?.extract()?));
        }
        let refs: Vec<(&str, &str)> = pairs.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
        let new: Vec<&str> = new_coords.iter().map(String::as_str).collect();
        let sys = &self.sys;
        Ok(PySystem::wrap(py.allow_threads(|| sys.transform(&refs, &new)).py()?))
    }

    /// The gauge-transformed system ``L + dΛ/dt`` (same equations of motion).
    fn gauge(&self, lam: &str) -> PyResult<PySystem> {
        Ok(PySystem::wrap(self.sys.with_gauge(lam).py()?))
    }

    /// The equations of a constrained system: a dict with ``multipliers``, ``equations``,
    /// ``W``, ``F``, ``Phi`` (``∂f_j/∂q_i``) and ``c`` (``Φ q'' = c``).
    fn constrained_equations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sys = &self.sys;
        let c = py.allow_threads(|| sys.constrained_equations()).py()?;
        let d = PyDict::new(py);
        let decls = self.decls();
        d.set_item("multipliers", c.multipliers.iter().map(|s| s.to_string()).collect::<Vec<_>>())?;
        d.set_item("equations", self.exs(c.equations))?;
        d.set_item("W", matrix(c.w, decls))?;
        d.set_item("F", self.exs(c.f))?;
        d.set_item("Phi", matrix(c.phi, decls))?;
        d.set_item("c", self.exs(c.c))?;
        Ok(d)
    }

    /// The Poisson bracket ``{f, g}`` over this system's phase space (``q``, ``p_q``).
    fn poisson(&self, f: &Bound<'_, PyAny>, g: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        let ps = self.phase_space()?;
        let f = to_expr(f, self.decls(), true)?;
        let g = to_expr(g, self.decls(), true)?;
        self.check_names(&[&f, &g])?;
        Ok(self.ex(canonical::poisson(&f, &g, &ps)))
    }

    /// ``df/dt = {f, H} + ∂f/∂t`` along the flow.
    fn time_derivative(&self, py: Python<'_>, f: &Bound<'_, PyAny>) -> PyResult<PyExpr> {
        let ps = self.phase_space()?;
        let f = to_expr(f, self.decls(), true)?;
        self.check_names(&[&f])?;
        let h = self.h(py)?;
        Ok(self.ex(canonical::time_derivative(&f, &h, &ps)))
    }

    /// Whether ``f`` is an integral of motion: ``(is_integral, how it was decided)``.
    fn is_integral(&self, py: Python<'_>, f: &Bound<'_, PyAny>) -> PyResult<(bool, String)> {
        let ps = self.phase_space()?;
        let f = to_expr(f, self.decls(), true)?;
        self.check_names(&[&f])?;
        let h = self.h(py)?;
        let z = canonical::is_integral(&f, &h, &ps);
        Ok((z.is_zero(), z.describe()))
    }

    /// A canonical transformation from a generating function ``F`` of type ``kind``
    /// (``"F1"`` … ``"F4"``) to new variables ``new_coords`` with momenta ``new_momenta``.
    /// Returns a dict: ``relations`` (the defining equations), ``inverse`` (old variables in
    /// the new), ``forward`` (new in the old), ``branches`` and ``hamiltonian`` (the new
    /// ``K``); an entry that could not be solved is the error message instead.
    #[pyo3(signature = (generator, kind, new_coords, new_momenta))]
    fn canonical_transform<'py>(
        &self,
        py: Python<'py>,
        generator: &Bound<'py, PyAny>,
        kind: &str,
        new_coords: Vec<String>,
        new_momenta: Vec<String>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let kind = match kind {
            "F1" | "f1" => GeneratorKind::F1,
            "F2" | "f2" => GeneratorKind::F2,
            "F3" | "f3" => GeneratorKind::F3,
            "F4" | "f4" => GeneratorKind::F4,
            other => {
                return Err(exc::ArgumentError::new_err(format!("unknown generator kind `{other}` (F1, F2, F3 or F4)")))
            }
        };
        let decls = self.decls().clone();
        let f = to_expr(generator, &decls, true)?;
        let new = PhaseSpace::with_momenta(&new_coords, &new_momenta).py()?;
        let old = self.phase_space()?;
        let h = self.h(py)?;
        let gen = Generator::new(kind, f, old, new).py()?;
        let t = py.allow_threads(|| gen.transform(Some(&h))).py()?;
        let d = PyDict::new(py);
        d.set_item("kind", kind.to_string())?;
        d.set_item("relations", relations(py, &t.relations, &decls)?)?;
        let either = |r: &Result<Vec<(Symbol, Expr)>, canonical::SolveError>| -> PyResult<PyObject> {
            Ok(match r {
                Ok(rel) => relations(py, rel, &decls)?.into_any().unbind(),
                Err(e) => e.to_string().into_pyobject(py)?.into_any().unbind(),
            })
        };
        d.set_item("inverse", either(&t.inverse)?)?;
        d.set_item("forward", either(&t.forward)?)?;
        d.set_item("branches", t.branches.clone())?;
        match &t.hamiltonian {
            Some(Ok(k)) => d.set_item("hamiltonian", PyExpr::new(k.clone(), &decls))?,
            Some(Err(e)) => d.set_item("hamiltonian", e.to_string())?,
            None => d.set_item("hamiltonian", py.None())?,
        }
        Ok(d)
    }

    /// The flow of ``f`` under ``H`` as a truncated Lie series ``Σ tᵏ/k! {…{f, H}…, H}``.
    fn lie_flow(&self, py: Python<'_>, f: &Bound<'_, PyAny>, order: usize) -> PyResult<PyExpr> {
        let ps = self.phase_space()?;
        let f = to_expr(f, self.decls(), true)?;
        let h = self.h(py)?;
        Ok(self.ex(py.allow_threads(|| canonical::lie_flow(&f, &h, order, &ps)).py()?))
    }

    /// The Lie series ``exp(ε L_g) f = Σ εᵏ/k! {…{f, g}…, g}`` to ``order``.
    fn lie_series(
        &self,
        py: Python<'_>,
        f: &Bound<'_, PyAny>,
        g: &Bound<'_, PyAny>,
        epsilon: &Bound<'_, PyAny>,
        order: usize,
    ) -> PyResult<PyExpr> {
        let ps = self.phase_space()?;
        let decls = self.decls();
        let (f, g, eps) = (to_expr(f, decls, true)?, to_expr(g, decls, true)?, to_symbol(epsilon, decls)?);
        Ok(self.ex(py.allow_threads(|| canonical::lie_series(&f, &g, &eps, order, &ps))))
    }

    /// Action ``J(E)``, period and frequency of a one-degree-of-freedom Hamiltonian on the
    /// orbit of energy ``energy`` through ``q = inside`` (parameters from the system's values).
    /// Returns a dict with ``energy``, ``action``, ``period``, ``omega``, ``turning_points``
    /// and ``error_estimate``.
    fn action_frequency<'py>(&self, py: Python<'py>, energy: f64, inside: f64) -> PyResult<Bound<'py, PyDict>> {
        if self.sys.coordinates().len() != 1 {
            return Err(exc::ArgumentError::new_err("action-angle variables are computed for one degree of freedom"));
        }
        let h = self.h(py)?;
        let q = &self.sys.coordinates()[0];
        let p = &self.sys.momenta()[0];
        let env: HashMap<String, f64> = self.spec().params.into_iter().collect();
        let r = py.allow_threads(|| canonical::action_angle::action_frequency(&h, q, p, energy, &env, inside)).py()?;
        let d = PyDict::new(py);
        d.set_item("energy", r.energy)?;
        d.set_item("action", r.action)?;
        d.set_item("period", r.period)?;
        d.set_item("omega", r.omega)?;
        d.set_item("turning_points", r.turning_points)?;
        d.set_item("error_estimate", r.error_estimate)?;
        Ok(d)
    }

    /// The averaged Lagrangian of trial functions (``{"x": "l0 (A cos(θ) + B cos(3θ))"}``) over
    /// the phase ``phase`` with frequency ``frequency`` and amplitudes ``amplitudes``. Returns a
    /// dict: ``lagrangian`` ⟨L⟩, ``grouped`` (the same, grouped for reading as the notes write
    /// it), ``relations`` (``∂⟨L⟩/∂A_k``, each ``= 0``) and ``action`` ``∂⟨L⟩/∂ω``.
    ///
    /// With ``small`` and ``unperturbed`` (``ω0``): ``series``, the relations solved as a
    /// series in ``small`` to ``order`` (``{"frequency": Expr, "amplitudes": [(name, Expr)]}``,
    /// the first amplitude, or ``principal``, left free). With ``sweep`` as well (values of that
    /// amplitude): ``solved``, the relations solved numerically at each value with this
    /// system's parameter values, by Newton's method continued along them
    /// (``{"<amplitude>": values, "<frequency>": …, "<frequency>_series": …, "<other amplitude>":
    /// …}``, NumPy arrays).
    #[pyo3(signature = (trials, phase, frequency, amplitudes, *, small=None, unperturbed=None, principal=None, order=1, sweep=None))]
    #[allow(clippy::too_many_arguments)]
    fn average<'py>(
        &self,
        py: Python<'py>,
        trials: &Bound<'py, PyDict>,
        phase: &str,
        frequency: &str,
        amplitudes: Vec<String>,
        small: Option<String>,
        unperturbed: Option<Bound<'py, PyAny>>,
        principal: Option<String>,
        order: usize,
        sweep: Option<Vec<f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let Some(l) = self.sys.lagrangian() else {
            return Err(exc::MechanicsError::new_err("error: averaging needs a Lagrangian system"));
        };
        self.sys.refuse_velocity_constraints("an averaged Lagrangian").py()?;
        let decls = self.decls().clone();
        let mut ts = Vec::new();
        for (k, v) in trials.iter() {
            let coord = to_symbol(&k, &decls)?;
            let text: String = v.str()?.extract()?;
            ts.push(Trial { coord, expr: parse_with(&text, &decls).py()? });
        }
        let phase = to_symbol(&phase.into_pyobject(py)?.into_any(), &decls)?;
        let freq = to_symbol(&frequency.into_pyobject(py)?.into_any(), &decls)?;
        let amps: Vec<Symbol> =
            amplitudes.iter().map(|a| to_symbol(&a.into_pyobject(py)?.into_any(), &decls)).collect::<PyResult<_>>()?;
        let avg = py.allow_threads(|| canonical::average::average_lagrangian(l, &ts, &phase, &freq, &amps)).py()?;
        let d = PyDict::new(py);
        d.set_item("lagrangian", PyExpr::new(avg.lagrangian.clone(), &decls))?;
        let grouped = canonical::average::grouped(&avg.lagrangian, small.as_deref(), &amps);
        d.set_item("grouped", PyExpr::new(grouped, &decls))?;
        let rel = PyList::empty(py);
        for (s, e) in &avg.relations {
            rel.append((s.to_string(), PyExpr::new(e.clone(), &decls)))?;
        }
        d.set_item("relations", rel)?;
        d.set_item("action", PyExpr::new(avg.action.clone(), &decls))?;
        let (Some(small), Some(w0)) = (small, unperturbed) else {
            if sweep.is_some() {
                return Err(exc::ArgumentError::new_err(
                    "`sweep` needs `small` and `unperturbed` (the series gives the first guess)",
                ));
            }
            return Ok(d);
        };
        let sigma = to_symbol(&small.into_pyobject(py)?.into_any(), &decls)?;
        let w0 = to_expr(&w0, &decls, true)?;
        let principal = match principal {
            Some(a) => to_symbol(&a.into_pyobject(py)?.into_any(), &decls)?,
            None => amps.first().cloned().ok_or_else(|| exc::ArgumentError::new_err("no amplitudes to solve for"))?,
        };
        let lo = canonical::leading_order(&avg, &freq, &w0, &sigma, &principal, order)
            .map_err(|e| exc::AverageError::new_err(e.to_string()))?;
        let series = PyDict::new(py);
        series.set_item("order", lo.order)?;
        series.set_item("frequency", PyExpr::new(lo.frequency.clone(), &decls))?;
        let pairs = PyList::empty(py);
        for (a, e) in &lo.amplitudes {
            pairs.append((a.to_string(), PyExpr::new(e.clone(), &decls)))?;
        }
        series.set_item("amplitudes", pairs)?;
        d.set_item("series", series)?;
        if let Some(values) = sweep {
            let params: HashMap<String, f64> = self.spec().params.into_iter().collect();
            let lookup = |s: &Symbol| params.get(s.name()).copied();
            let swept = py
                .allow_threads(|| canonical::sweep(&avg, &freq, &w0, &lo, &principal, &values, &lookup))
                .map_err(|e| exc::AverageError::new_err(e.to_string()))?;
            let points = &swept.points;
            let solved = PyDict::new(py);
            solved.set_item(principal.to_string(), numpy::PyArray1::from_vec(py, values.clone()))?;
            solved.set_item(freq.to_string(), numpy::PyArray1::from_iter(py, points.iter().map(|p| p.frequency)))?;
            solved.set_item(format!("{freq}_series"), numpy::PyArray1::from_vec(py, swept.series.clone()))?;
            for (k, (a, _)) in points.first().map(|p| p.amplitudes.clone()).unwrap_or_default().iter().enumerate() {
                solved.set_item(
                    a.to_string(),
                    numpy::PyArray1::from_iter(py, points.iter().map(|p| p.amplitudes[k].1)),
                )?;
            }
            d.set_item("solved", solved)?;
        }
        Ok(d)
    }

    /// The state variable names of the formulation ``method`` integrates: ``(q…, q'…)`` for a
    /// Lagrangian system with a Runge–Kutta or collocation method, ``(q…, p_q…)`` for a
    /// Hamiltonian system or a splitting method.
    #[pyo3(signature = (method=None))]
    fn state_names(&self, method: Option<&str>) -> PyResult<Vec<String>> {
        let m = method.map_or(Ok(lagrangian::simulate::DEFAULT_METHOD), crate::convert::method)?;
        let route = lagrangian::simulate::route(m, &lagrangian::simulate::shape_of(&self.sys))
            .map_err(|r| exc::ArgumentError::new_err(format!("{r} ({})", r.hint())))?;
        let second = if route.has_velocities() { self.sys.velocities() } else { self.sys.momenta() };
        Ok(self.sys.coordinates().iter().chain(second).map(|s| s.to_string()).collect())
    }
}

/// The Poisson bracket ``{f, g}`` over the phase space of ``coords`` (momenta ``p_q``).
/// Every other name in ``f`` and ``g`` must be listed in ``params`` (constants, whose
/// bracket with everything is 0): a name that is neither is refused, since reading it as a
/// constant would silently drop its part of the bracket (``{x p_x, y}`` over ``q`` is not 0
/// if ``x`` and ``y`` were meant as coordinates).
#[pyfunction]
#[pyo3(signature = (f, g, coords, *, params=None))]
pub fn poisson(
    f: &Bound<'_, PyAny>,
    g: &Bound<'_, PyAny>,
    coords: Vec<String>,
    params: Option<Vec<String>>,
) -> PyResult<PyExpr> {
    let decls = match f.downcast::<PyExpr>() {
        Ok(e) => e.get().decls.0.clone(),
        Err(_) => Declarations::new(),
    };
    let ps = PhaseSpace::new(&coords).py()?;
    let (f, g) = (to_expr(f, &decls, true)?, to_expr(g, &decls, true)?);
    check_phase_space(&[&f, &g], &coords, &params.unwrap_or_default(), false)?;
    Ok(PyExpr::new(canonical::poisson(&f, &g, &ps), &decls))
}

/// Refuses names in `exprs` that are neither a coordinate, a momentum `p_q`, `t` nor one of
/// `params`: a bracket reads any other name as a constant, so a name meant as a coordinate
/// would silently drop its part (`{x p_x, y}` over `q` came out 0).
fn check_phase_space(exprs: &[&Expr], coords: &[String], params: &[String], system: bool) -> PyResult<()> {
    let known = |s: &Symbol| {
        let n = s.name();
        s.primes() == 0
            && (s.is_time()
                || params.iter().any(|p| p == n)
                || coords.iter().any(|q| q == n || n.strip_prefix("p_") == Some(q.as_str())))
    };
    let unknown: BTreeSet<String> =
        exprs.iter().flat_map(|e| e.free_symbols()).filter(|s| !known(s)).map(|s| s.to_string()).collect();
    if unknown.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = unknown.iter().map(|n| format!("`{n}`")).collect();
    let momenta: Vec<String> = coords.iter().map(|q| format!("p_{q}")).collect();
    let fix = if system {
        "use the system's coordinates, momenta and parameters".to_string()
    } else {
        "add the coordinates to `coords` (`p_x` is the momentum of `x`), list constants in params=[…], or use System.poisson, which knows its system's parameters".to_string()
    };
    Err(exc::ArgumentError::new_err(format!(
        "{} {} neither a coordinate nor a momentum of the phase space ({}; {}){}; {fix}",
        list.join(", "),
        if list.len() == 1 { "is" } else { "are" },
        coords.join(", "),
        momenta.join(", "),
        if system { " nor a parameter of the system" } else { "" },
    )))
}
