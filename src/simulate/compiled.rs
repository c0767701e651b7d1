//! A formulation compiled for a method's [`Form`]: one typed value per kind of compiled
//! system, with the event functions of the runs that will use it.

use std::sync::Arc;

use super::error::SimulateError;
use super::formulation::Formulation;
use super::method::{Form, MethodId};
use crate::compile::{
    CompileError, ConstrainedRhs, FirstOrderRhs, HamiltonianRhs, LagrangianJacobian, LagrangianRhs,
    SeparableHamiltonian, Tape, TaylorOde, VariationalMap, WithVelocitySlots,
};
use crate::expr::{Expr, Symbol};
use crate::integrate::{Jacobian, Rhs};
use crate::mechanics::{Rule, System};

/// What to compile.
#[derive(Clone, Debug)]
pub struct CompileRequest {
    /// Coordinates in order (the state is `(q…, v…)`, `v` the velocities or momenta).
    pub coords: Vec<Symbol>,
    /// The equations.
    pub formulation: Formulation,
    /// Parameter values, by plain name.
    pub params: Vec<(String, f64)>,
    /// What the method needs compiled ([`MethodId::form`]).
    pub form: Form,
    /// Event functions (zero crossings) in the state's variables and `t`.
    pub events: Vec<Expr>,
}

/// The numeric system behind a [`Compiled`].
#[derive(Debug)]
pub enum CompiledSystem {
    /// `W q'' = F` (explicit and adaptive methods).
    Lagrangian(LagrangianRhs),
    /// `W q'' = F` with its Jacobian (implicit methods).
    LagrangianJacobian(LagrangianJacobian),
    /// Hamilton's equations with their Jacobian.
    Hamiltonian(HamiltonianRhs),
    /// Drift and kick (splitting methods).
    Separable(SeparableHamiltonian),
    /// `ω z' = b` of a first-order Lagrangian, on the `(z, z')` layout.
    FirstOrder(WithVelocitySlots),
    /// The augmented system of a constrained Lagrangian.
    Constrained(ConstrainedRhs),
    /// The variational map of a discrete Lagrangian, with its rule.
    Variational(VariationalMap, Rule),
    /// The Taylor form of `W q'' = F` or of Hamilton's equations, and the right-hand side it
    /// was made from (for `f(t, y)` calls).
    Taylor(TaylorOde, Box<CompiledSystem>),
}

impl CompiledSystem {
    /// The first-order right-hand side `y' = f(t, y)`, where the system has one (a discrete
    /// map does not).
    pub fn rhs(&self) -> Option<&dyn Rhs> {
        Some(match self {
            CompiledSystem::Lagrangian(r) => r,
            CompiledSystem::LagrangianJacobian(r) => r,
            CompiledSystem::Hamiltonian(r) => r,
            CompiledSystem::Separable(r) => r,
            CompiledSystem::FirstOrder(r) => r,
            CompiledSystem::Constrained(r) => r,
            CompiledSystem::Variational(..) => return None,
            CompiledSystem::Taylor(_, r) => return r.rhs(),
        })
    }

    /// The exact Jacobian `∂f/∂y`, where this form carries one.
    pub fn jacobian(&self) -> Option<&dyn Jacobian> {
        match self {
            CompiledSystem::LagrangianJacobian(r) => Some(r),
            CompiledSystem::Hamiltonian(r) => Some(r),
            _ => None,
        }
    }

    /// Writes `∂f_i/∂y_j` into `jac[i * dim + j]`, reporting a state where it has no value;
    /// `None` where this form carries no Jacobian.
    pub fn try_jacobian(&self, t: f64, y: &[f64], jac: &mut [f64]) -> Option<Result<(), crate::compile::RhsError>> {
        match self {
            CompiledSystem::LagrangianJacobian(r) => Some(r.try_jacobian(t, y, jac)),
            CompiledSystem::Hamiltonian(r) => Some(r.try_jacobian(t, y, jac)),
            _ => None,
        }
    }
}

/// A compiled system, its state's names and its compiled event functions.
#[derive(Debug)]
pub struct Compiled {
    /// The numeric system (shared by compiled values that differ only in their events).
    pub system: Arc<CompiledSystem>,
    /// The form it was compiled for.
    pub form: Form,
    /// Plain names of the state's entries (`x`, then `x'` or `p_x`).
    pub state: Vec<String>,
    /// The event functions `g(state…, t)`, one tape each.
    pub events: Vec<Arc<Tape>>,
    /// The parameter values bound into it.
    pub params: Vec<(String, f64)>,
}

impl Compiled {
    /// The same system with the event functions `events` (expressions in the state's
    /// variables and `t`) in place of its own: the system is shared, only the events compile.
    pub fn with_events(&self, events: &[Expr]) -> Result<Compiled, SimulateError> {
        Ok(Compiled {
            system: self.system.clone(),
            form: self.form,
            state: self.state.clone(),
            events: compile_events(events, &self.state, &self.params)?,
            params: self.params.clone(),
        })
    }

    /// Whether `method` can run on this compiled system (it was compiled for its form).
    pub fn serves(&self, method: MethodId) -> bool {
        self.form == method.form()
            || (self.form == Form::RhsWithJacobian && method.form() == Form::Rhs)
            || (matches!(*self.system, CompiledSystem::Constrained(_) | CompiledSystem::FirstOrder(_))
                && matches!(method.form(), Form::Rhs | Form::RhsWithJacobian))
    }
}

fn mechanics(e: crate::mechanics::MechanicsError) -> SimulateError {
    SimulateError::Mechanics(e)
}

/// Compiles `req`: derives what the formulation still needs (`W`, `F`, constraints' terms)
/// and compiles it for the method's form.
pub fn compile(req: &CompileRequest) -> Result<Compiled, SimulateError> {
    let coords: Vec<&str> = req.coords.iter().map(|q| q.name()).collect();
    let momenta_owned: Vec<String> = coords.iter().map(|q| format!("p_{q}")).collect();
    let momenta: Vec<&str> = momenta_owned.iter().map(String::as_str).collect();
    let params: Vec<(&str, f64)> = req.params.iter().map(|(n, v)| (n.as_str(), *v)).collect();
    let second_order = |w: &[Vec<Expr>], f: &[Expr]| -> Result<CompiledSystem, CompileError> {
        let rhs = LagrangianRhs::new(w, f, &coords, &params)?;
        Ok(match req.form {
            Form::RhsWithJacobian => CompiledSystem::LagrangianJacobian(rhs.with_jacobian()?),
            Form::Taylor => {
                CompiledSystem::Taylor(TaylorOde::from_lagrangian(&rhs), Box::new(CompiledSystem::Lagrangian(rhs)))
            }
            _ => CompiledSystem::Lagrangian(rhs),
        })
    };
    let lagrangian = |l: &Expr| System::from_lagrangian_expr(l.clone(), &req.coords).map_err(mechanics);
    let system = match &req.formulation {
        Formulation::Separable { t, v } => {
            CompiledSystem::Separable(SeparableHamiltonian::new(&t.plus(v), &coords, &momenta, &params)?)
        }
        Formulation::Hamiltonian(h) => {
            let rhs = HamiltonianRhs::new(h, &coords, &momenta, &params)?;
            match req.form {
                Form::Taylor => CompiledSystem::Taylor(
                    TaylorOde::from_hamiltonian(&rhs),
                    Box::new(CompiledSystem::Hamiltonian(rhs)),
                ),
                _ => CompiledSystem::Hamiltonian(rhs),
            }
        }
        Formulation::FirstOrder(l) => {
            let f = lagrangian(l)?.first_order().map_err(mechanics)?;
            f.check_nondegenerate().map_err(mechanics)?;
            CompiledSystem::FirstOrder(WithVelocitySlots(FirstOrderRhs::new(&f.omega, &f.force, &coords, &params)?))
        }
        Formulation::Variational(l) => {
            let Form::Map(rule) = req.form else {
                return Err(SimulateError::Internal("a variational formulation compiled for a continuous method"));
            };
            // The step is an input of the compiled map, so one compilation serves every `dt`;
            // the placeholder bound here is never stepped with.
            let step = "h__variational";
            let d = lagrangian(l)?.discretize(rule, &Expr::var(step)).map_err(mechanics)?;
            let mut bound = params.clone();
            bound.push((step, 1.0));
            CompiledSystem::Variational(VariationalMap::new(&d, &bound)?, rule)
        }
        Formulation::Lagrangian(l) => {
            let (w, f) = lagrangian(l)?.mass_matrix_split().map_err(mechanics)?;
            second_order(&w, &f)?
        }
        Formulation::Equations { w, f } => second_order(w, f)?,
        Formulation::Extended(x) => {
            let mut system = lagrangian(&x.l)?;
            for (q, force) in req.coords.iter().zip(&x.forces) {
                if !force.is_zero() {
                    system = system.with_force_expr(q.name(), force.clone()).map_err(mechanics)?;
                }
            }
            if let Some(r) = &x.rayleigh {
                system = system.with_rayleigh_expr(r.clone()).map_err(mechanics)?;
            }
            for f in &x.constraints {
                system = system.with_constraint_expr(f.clone()).map_err(mechanics)?;
            }
            for g in &x.velocity_constraints {
                system = system.with_velocity_constraint_expr(g.clone()).map_err(mechanics)?;
            }
            let (w, f) = system.mass_matrix_split().map_err(mechanics)?;
            if x.constraints.is_empty() && x.velocity_constraints.is_empty() {
                second_order(&w, &f)?
            } else {
                let (holonomic, velocity) = (system.constraints(), system.velocity_constraints());
                let rhs = ConstrainedRhs::with_velocity_constraints(
                    &w,
                    &f,
                    holonomic,
                    velocity,
                    &req.coords,
                    &params,
                    x.stabilization,
                )?;
                match req.form {
                    Form::Taylor => CompiledSystem::Taylor(
                        ConstrainedRhs::taylor(&w, &f, holonomic, velocity, &req.coords, &params, x.stabilization)?,
                        Box::new(CompiledSystem::Constrained(rhs)),
                    ),
                    _ => CompiledSystem::Constrained(rhs),
                }
            }
        }
    };
    let velocities = req.formulation.has_velocities();
    let mut state: Vec<String> = coords.iter().map(|q| q.to_string()).collect();
    state.extend(coords.iter().map(|q| if velocities { format!("{q}'") } else { format!("p_{q}") }));
    let events = compile_events(&req.events, &state, &req.params)?;
    Ok(Compiled { system: Arc::new(system), form: req.form, state, events, params: req.params.clone() })
}

/// Each event function as a tape over the state's names and `t`, with the parameters it uses
/// bound.
fn compile_events(
    events: &[Expr],
    state: &[String],
    params: &[(String, f64)],
) -> Result<Vec<Arc<Tape>>, SimulateError> {
    let mut inputs: Vec<&str> = state.iter().map(String::as_str).collect();
    inputs.push("t");
    events
        .iter()
        .map(|e| {
            let free = e.free_symbols();
            let used: Vec<(&str, f64)> = params
                .iter()
                .filter(|(k, _)| free.iter().any(|s| s.name() == k && s.primes() == 0))
                .map(|(k, v)| (k.as_str(), *v))
                .collect();
            Ok(Arc::new(Tape::compile(std::slice::from_ref(e), &inputs, &used)?))
        })
        .collect()
}

/// A constrained run's initial state must lie on the constraints (positions and velocities),
/// and the augmented matrix must be regular there: otherwise the run is refused before it
/// starts, naming the constraint.
pub(super) fn check_constrained_start(r: &ConstrainedRhs, t0: f64, y0: &[f64]) -> Result<(), SimulateError> {
    // A velocity constraint restricts the initial velocities; projection would move a start
    // off it silently after the first step, so it is refused here instead.
    let (m, mh, n) = (r.constraints(), r.holonomic(), r.dof());
    if m > mh && y0.len() >= 2 * n {
        let mut g = vec![0.0; m];
        r.residuals(t0, y0, &mut g);
        let scale = y0[..2 * n].iter().fold(1.0f64, |s, v| s.max(v.abs()));
        if let Some((j, v)) = g.iter().enumerate().skip(mh).find(|(_, v)| v.is_nan() || v.abs() > 1e-9 * scale) {
            return Err(SimulateError::InitialState(format!(
                "the initial velocities violate velocity constraint {} (its residual is {v:e}); start with velocities that satisfy it",
                j - mh + 1
            )));
        }
    }
    let mut dy = vec![0.0; y0.len()];
    r.try_eval(t0, y0, &mut dy).map_err(|e| SimulateError::InitialState(e.to_string()))
}
