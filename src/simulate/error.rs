//! Why a simulation could not be set up or did not finish, with the data a front end needs
//! to say so in its own words (the method, the system's shape, the last good state).

use super::formulation::Refusal;
use super::method::{method_names, MethodId};
use crate::compile::CompileError;
use crate::integrate::{FailureReason, IntegrateError};
use crate::mechanics::MechanicsError;

/// A failed simulation.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimulateError {
    /// No method has this name.
    #[error("unknown integration method `{name}`")]
    UnknownMethod {
        /// What was asked for.
        name: String,
        /// The closest method name, if one is close.
        suggestion: Option<&'static str>,
    },
    /// The method cannot integrate this kind of system.
    #[error("{0}")]
    Refused(Refusal),
    /// A fixed-step method without `dt`.
    #[error("`{}` is a fixed-step method and needs a step", method.name())]
    NeedsStep {
        /// The method.
        method: MethodId,
    },
    /// `dt` given to a method that chooses its own steps.
    #[error("`{}` chooses its own steps; give a tolerance instead of `dt`", method.name())]
    NeedsTolerance {
        /// The method.
        method: MethodId,
    },
    /// A tolerance below what the method can meet in `f64`.
    #[error("tol = {tol:e} is below what f64 can meet; the smallest usable tol is {floor:.2e}")]
    ToleranceBelowFloor {
        /// The method.
        method: MethodId,
        /// What was asked for.
        tol: f64,
        /// The method's floor.
        floor: f64,
    },
    /// A number that must be positive and finite is not.
    #[error("{what} must be positive and finite, found {value}")]
    NotPositive {
        /// What it is (`the step dt`).
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// More fixed steps than the budget allows.
    #[error("{steps:.3e} steps is more than the limit of {}", limit_text(*limit))]
    TooManySteps {
        /// Steps the run would take.
        steps: f64,
        /// The budget.
        limit: f64,
    },
    /// More kept states than [`super::limits::MAX_STORED_STATES`].
    #[error("the run would keep {states:.3e} states, more than the limit of {limit}")]
    TooManyStates {
        /// States the run would keep.
        states: f64,
        /// The limit.
        limit: usize,
        /// The smallest `every` that keeps the run within the limit, when stepping is what
        /// keeps states.
        every: Option<u64>,
    },
    /// Equations asked for by name that would leave out part of the system (Hamilton's
    /// equations of `H` without its forces, dissipation or constraints).
    #[error("{equations} leave out the forces, dissipation and constraints of this system")]
    DropsTerms {
        /// The equations asked for (`Hamilton's equations of H`).
        equations: &'static str,
    },
    /// An invalid run request (empty or backward span, a bad sampling grid, a wrong state size).
    #[error("{0}")]
    InvalidRun(String),
    /// The symbolic stage could not provide the equations.
    #[error("{0}")]
    Mechanics(MechanicsError),
    /// The equations could not be compiled.
    #[error("{0}")]
    Compile(#[from] CompileError),
    /// The initial state is not admissible (off a constraint, a singular augmented matrix).
    #[error("at the initial state: {0}")]
    InitialState(String),
    /// The integration stopped with an error.
    #[error("integration stopped at t = {} (state {}): {}{}", error.t, named_state(names, &error.state), error.reason, hint.as_deref().unwrap_or(""))]
    Integrate {
        /// The integrator's error.
        error: IntegrateError,
        /// The state's names, for the message.
        names: Vec<String>,
        /// What to do about it (`; the average step was …`), empty if nothing is known.
        hint: Option<String>,
    },
    /// The run was cancelled (Ctrl-C, a cancelled token).
    #[error("interrupted")]
    Cancelled,
    /// A front end asked for something inconsistent (a bug, not a user error).
    #[error("internal: {0}")]
    Internal(&'static str),
}

impl SimulateError {
    /// The unknown-method error for `name`, with the closest name as a suggestion.
    pub fn unknown_method(name: &str) -> SimulateError {
        let suggestion = crate::suggest::did_you_mean(name, MethodId::all().map(MethodId::name));
        SimulateError::UnknownMethod { name: name.to_string(), suggestion }
    }

    /// What the user can do about it, if something is known.
    pub fn hint(&self) -> Option<String> {
        match self {
            SimulateError::UnknownMethod { suggestion: Some(s), .. } => {
                Some(format!("did you mean `{s}`? (`help simulate` lists the methods)"))
            }
            SimulateError::UnknownMethod { suggestion: None, .. } => {
                Some(format!("the methods are {}", method_names()))
            }
            SimulateError::Refused(r) => Some(r.hint()),
            SimulateError::NeedsStep { .. } => Some("add `dt = 0.01` (or `steps = 1000`)".into()),
            SimulateError::NeedsTolerance { .. } => {
                Some("write `tol = 1e-10`, or pick a fixed-step method such as `gauss6` or `rk4`".into())
            }
            SimulateError::ToleranceBelowFloor { method: MethodId::Taylor, .. } => {
                Some("omit `tol`: the Taylor method defaults to machine precision".into())
            }
            SimulateError::ToleranceBelowFloor { .. } => {
                Some("write `tol = 1e-14` (DOP853 at 1e-14 is already near the rounding floor)".into())
            }
            SimulateError::TooManySteps { .. } => Some("use a larger `dt` or a shorter time span".into()),
            SimulateError::TooManyStates { every: Some(k), .. } => {
                Some(format!("keep fewer states: `every {k}` (or more), or `points N` for N evenly spaced ones"))
            }
            SimulateError::TooManyStates { every: None, .. } => Some("ask for fewer sample times".into()),
            SimulateError::DropsTerms { .. } => {
                Some("use the Lagrangian formulation (W q'' = F, or the augmented system with constraints), which includes them".into())
            }
            _ => None,
        }
    }

    /// The integrator's error as a simulation error: Ctrl-C is [`SimulateError::Cancelled`].
    pub(super) fn integration(error: IntegrateError, names: &[String], hint: Option<String>) -> SimulateError {
        if error.reason == FailureReason::Interrupted {
            return SimulateError::Cancelled;
        }
        SimulateError::Integrate { error, names: names.to_vec(), hint }
    }
}

impl From<MechanicsError> for SimulateError {
    fn from(e: MechanicsError) -> Self {
        SimulateError::Mechanics(e)
    }
}

/// `name = value` pairs of a state, for error messages.
fn named_state(names: &[String], y: &[f64]) -> String {
    if names.len() == y.len() {
        names
            .iter()
            .zip(y)
            .map(|(n, v)| format!("{n} = {}", crate::integrate::fmt_value(*v)))
            .collect::<Vec<_>>()
            .join(", ")
    } else {
        crate::integrate::fmt_state(y)
    }
}

/// `10⁹` for the default fixed-step budget, the plain number for a budget the caller set.
fn limit_text(limit: f64) -> String {
    if limit == super::limits::MAX_FIXED_STEPS {
        "10⁹".to_string()
    } else {
        format!("{limit:.0}")
    }
}
