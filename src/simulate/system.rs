//! A [`System`] (Lagrangian or Hamiltonian, with its forces, dissipation and constraints) as
//! the formulation a method needs: the library route for callers that hold a whole system
//! (Python, the command line, library users).

use super::compiled::{compile, CompileRequest, Compiled};
use super::error::SimulateError;
use super::formulation::{not_separable, route, ExtendedLagrangian, Formulation, Route, Shape};
use super::method::MethodId;
use crate::compile::{split_separable, Stabilization};
use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::mechanics::{Kind, MechanicsError, System};

/// Whether `L` is first order in the velocities (`L = a(q)·q' − H(q)`): some velocity appears,
/// and no `∂L/∂q'` contains a velocity, so `W = 0` and the state is `q` alone.
pub fn is_first_order(l: &Expr, coords: &[Symbol]) -> bool {
    let velocities: Vec<Symbol> = coords.iter().map(Symbol::prime).collect();
    let free = l.free_symbols();
    if !velocities.iter().any(|v| free.contains(v)) {
        return false;
    }
    let mut d = Differentiator::new();
    velocities.iter().all(|v| {
        let a = d.diff(l, v).free_symbols();
        !velocities.iter().any(|w| a.contains(w))
    })
}

/// What [`route`] needs to know about `sys`.
pub fn shape_of(sys: &System) -> Shape {
    let (lagrangian, first_order) = match sys.kind() {
        Kind::Lagrangian(l) => (true, is_first_order(l, sys.coordinates())),
        Kind::Hamiltonian(_) => (false, false),
    };
    Shape {
        lagrangian,
        hamiltonian: !lagrangian,
        first_order,
        forces: sys.forces().iter().any(|f| !f.is_zero()) || sys.rayleigh().is_some(),
        constraints: !sys.constraints().is_empty(),
        velocity_constraints: !sys.velocity_constraints().is_empty(),
    }
}

/// The symbolic derivations a formulation needs, so a caller with a derivation cache (the
/// Python package) can supply them; the defaults derive them afresh.
pub trait Derivations {
    /// `W q'' = F` of `sys`, forces and dissipation included.
    fn mass_matrix(&self, sys: &System) -> Result<(Vec<Vec<Expr>>, Vec<Expr>), MechanicsError> {
        sys.mass_matrix_split()
    }
    /// `H` of `sys` (its own, or the Legendre transform of `L`).
    fn hamiltonian(&self, sys: &System) -> Result<Expr, MechanicsError> {
        sys.hamiltonian()
    }
}

/// Derives everything afresh.
pub struct Fresh;
impl Derivations for Fresh {}

/// The formulation `method` integrates for `sys`, or the typed refusal naming what can.
pub fn formulation_for(sys: &System, method: MethodId, derive: &dyn Derivations) -> Result<Formulation, SimulateError> {
    let shape = shape_of(sys);
    let r = route(method, &shape).map_err(|mut refusal| {
        // `route` knows the shape, not `H`: a given `H` that does not split leaves the
        // splitting methods out of the alternatives.
        if let Kind::Hamiltonian(h) = sys.kind() {
            if split_of(sys, h).is_none() {
                refusal.alternatives.retain(|m| m.family() != super::method::Family::Splitting);
            }
        }
        SimulateError::Refused(refusal)
    })?;
    Ok(match r {
        Route::Lagrangian => {
            let (w, f) = derive.mass_matrix(sys)?;
            Formulation::Equations { w, f }
        }
        Route::Extended if sys.constraints().is_empty() && sys.velocity_constraints().is_empty() => {
            let (w, f) = derive.mass_matrix(sys)?;
            Formulation::Equations { w, f }
        }
        Route::Extended => {
            let Kind::Lagrangian(l) = sys.kind() else { unreachable!("route refuses forces without L") };
            Formulation::Extended(Box::new(ExtendedLagrangian {
                l: l.clone(),
                forces: sys.forces().to_vec(),
                rayleigh: sys.rayleigh().cloned(),
                constraints: sys.constraints().to_vec(),
                velocity_constraints: sys.velocity_constraints().to_vec(),
                // As scenes do by default: projection holds the run on f = 0 and ḟ = 0.
                stabilization: Stabilization::Projection,
            }))
        }
        Route::FirstOrder | Route::Variational => {
            let Kind::Lagrangian(l) = sys.kind() else { unreachable!("these routes need L") };
            if r == Route::FirstOrder {
                Formulation::FirstOrder(l.clone())
            } else {
                Formulation::Variational(l.clone())
            }
        }
        Route::Hamiltonian => Formulation::Hamiltonian(derive.hamiltonian(sys)?),
        Route::Separable => {
            let h = derive.hamiltonian(sys)?;
            let Some((t, v)) = split_of(sys, &h) else {
                let term = h.terms().into_iter().find(|x| split_of(sys, x).is_none()).unwrap_or(h);
                return Err(SimulateError::Refused(not_separable(method, &shape, crate::print::plain(&term))));
            };
            Formulation::Separable { t, v }
        }
    })
}

/// Equations a caller names directly (a right-hand side for SciPy, say) rather than through
/// a method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Equations {
    /// `W q'' = F` with forces and dissipation, or the augmented constrained system; state `(q, q')`.
    Lagrangian,
    /// Hamilton's equations of `H`; state `(q, p)`.
    Hamiltonian,
    /// Hamilton's equations of a separable `H = T(p) + V(q, t)`; state `(q, p)`.
    Separable,
}

/// The formulation of `equations` for `sys`, refusing equations that would leave out part of
/// the system (Hamilton's equations drop forces, dissipation and constraints).
pub fn formulation_of(
    sys: &System,
    equations: Equations,
    derive: &dyn Derivations,
) -> Result<Formulation, SimulateError> {
    let shape = shape_of(sys);
    let conservative = !shape.forces && !shape.constraints && !shape.velocity_constraints;
    match equations {
        Equations::Lagrangian => match sys.kind() {
            Kind::Hamiltonian(_) => Err(SimulateError::InvalidRun(
                "a system given by its Hamiltonian has no Lagrangian formulation here: ask for the Hamiltonian one"
                    .into(),
            )),
            Kind::Lagrangian(_) => formulation_for(sys, MethodId::Dop853, derive),
        },
        Equations::Hamiltonian if !conservative => {
            Err(SimulateError::DropsTerms { equations: "Hamilton's equations of H" })
        }
        Equations::Hamiltonian => Ok(Formulation::Hamiltonian(derive.hamiltonian(sys)?)),
        Equations::Separable if !conservative => {
            Err(SimulateError::DropsTerms { equations: "a drift/kick split of H" })
        }
        Equations::Separable => formulation_for(sys, MethodId::Leapfrog, derive),
    }
}

/// `h = T(p) + V(q, t)` over the coordinates and momenta of `sys`, if it splits.
fn split_of(sys: &System, h: &Expr) -> Option<(Expr, Expr)> {
    let q: Vec<&str> = sys.coordinates().iter().map(|s| s.name()).collect();
    let p: Vec<String> = sys.momenta().iter().map(|s| s.to_string()).collect();
    let p: Vec<&str> = p.iter().map(String::as_str).collect();
    split_separable(h, &q, &p)
}

/// Compiles `sys` for `method` with its bound parameters and the event functions `events`
/// (expressions in the state's variables and `t`).
pub fn compile_system(sys: &System, method: MethodId, events: &[Expr]) -> Result<Compiled, SimulateError> {
    compile_system_with(sys, method, events, &Fresh)
}

/// [`compile_system`] with the derivations supplied by `derive`.
pub fn compile_system_with(
    sys: &System,
    method: MethodId,
    events: &[Expr],
    derive: &dyn Derivations,
) -> Result<Compiled, SimulateError> {
    // A coordinate without its velocity (Remark 3.1) has an algebraic equation and a zero row
    // in `W`: the reduced system, with that equation solved, is what runs (its state names
    // say so), or the elimination's refusal says why not.
    if let Kind::Lagrangian(l) = sys.kind() {
        if !is_first_order(l, sys.coordinates()) && !sys.velocity_free_coordinates().is_empty() {
            let (_, reduced) = sys.reduced_system()?;
            return compile_system_with(&reduced, method, events, derive);
        }
    }
    compile_formulation(sys, formulation_for(sys, method, derive)?, method.form(), events)
}

/// Compiles `formulation` of `sys` (its coordinates and bound parameters) for `form`.
pub fn compile_formulation(
    sys: &System,
    formulation: Formulation,
    form: super::method::Form,
    events: &[Expr],
) -> Result<Compiled, SimulateError> {
    let params: Vec<(String, f64)> = sys.param_values().iter().map(|(k, v)| (k.name().to_string(), *v)).collect();
    compile(&CompileRequest { coords: sys.coordinates().to_vec(), formulation, params, form, events: events.to_vec() })
}
