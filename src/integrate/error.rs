//! Why an integration stopped early: typed errors carrying the time, the last good state and
//! the reason, so a caller can report or resume instead of receiving a NaN trajectory.

use std::fmt;

/// A right-hand side (or one of its half-maps) could not be evaluated at the given state, for
/// example because a mass matrix became singular or the state left the domain of a square root.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{reason}")]
pub struct RhsError {
    /// What went wrong, for the user.
    pub reason: String,
}

impl RhsError {
    /// An error with the given explanation.
    pub fn new(reason: impl Into<String>) -> Self {
        RhsError { reason: reason.into() }
    }
}

/// Why an integration could not continue.
#[derive(Debug, Clone, PartialEq)]
pub enum FailureReason {
    /// A state component (or a right-hand-side value) became infinite or NaN during the step
    /// that started at the reported time.
    NonFinite {
        /// Index of the first offending component.
        component: usize,
    },
    /// The adaptive step size fell below what floating point can resolve at this time.
    StepSizeCollapse {
        /// The step size that was too small.
        h: f64,
    },
    /// The implicit stage equations of a collocation method did not converge.
    ImplicitSolve {
        /// Iterations performed.
        iterations: usize,
        /// Size of the last correction, relative to the state scale.
        last_correction: f64,
        /// `true` for Newton's method with the system's Jacobian, `false` for fixed point.
        newton: bool,
    },
    /// The right-hand side reported that it cannot be evaluated.
    Rhs(RhsError),
    /// The step budget ([`super::Options::max_steps`]) was used up before the stop time, or a
    /// fixed-step run would need more steps than the budget (refused before the first step).
    StepLimit {
        /// The budget.
        max_steps: usize,
    },
    /// The wall-clock budget ([`super::Options::time_limit`]) was used up before the stop time.
    TimeLimit {
        /// The budget in seconds.
        seconds: f64,
    },
    /// The request itself is invalid (wrong dimension, non-finite initial state, bad span or
    /// step size).
    InvalidInput(String),
    /// The run's [`crate::cancel::CancelToken`] (or Ctrl-C through the process-wide one) asked
    /// it to stop; the state is the last accepted one, so the run can be resumed from it.
    Interrupted,
}

impl fmt::Display for FailureReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FailureReason::NonFinite { component } => {
                write!(f, "state component {component} became non-finite (the step is unstable or the solution blows up)")
            }
            FailureReason::StepSizeCollapse { h } => {
                write!(f, "step size collapsed to {h:e} (a singularity or extreme stiffness)")
            }
            FailureReason::ImplicitSolve { iterations, last_correction, newton } => write!(
                f,
                "implicit stage equations did not converge by {} after {iterations} iterations (last correction {last_correction:e}); reduce the step size",
                if *newton { "Newton's method" } else { "fixed-point iteration" }
            ),
            FailureReason::Rhs(e) => write!(f, "right-hand side failed: {e}"),
            FailureReason::StepLimit { max_steps } => {
                write!(f, "step limit of {max_steps} steps reached before the stop time")
            }
            FailureReason::TimeLimit { seconds } => {
                write!(f, "time limit of {seconds} s reached before the stop time")
            }
            FailureReason::InvalidInput(s) => write!(f, "invalid input: {s}"),
            FailureReason::Interrupted => write!(f, "interrupted"),
        }
    }
}

/// An integration that stopped before its stop time. `t` and `state` are the last state the
/// method accepted (always finite), so the caller can inspect or restart from it. The message
/// names all three: `integration stopped at t = 1.1 with state [0.5, -2]: step size collapsed …`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("integration stopped at t = {t} with state {}: {reason}", fmt_state(state))]
pub struct IntegrateError {
    /// Time of the last accepted state.
    pub t: f64,
    /// The last accepted state.
    pub state: Vec<f64>,
    /// Why the integration could not go on.
    pub reason: FailureReason,
    /// Accepted steps before the failure.
    pub steps: usize,
}

/// The state as `[a, b, …]` with each entry in Rust's shortest round-trip form; very long
/// states are cut after 8 entries (the full state is in [`IntegrateError::state`]).
pub fn fmt_state(state: &[f64]) -> String {
    const SHOWN: usize = 8;
    let mut parts: Vec<String> = state.iter().take(SHOWN).map(|x| fmt_value(*x)).collect();
    if state.len() > SHOWN {
        parts.push(format!("… {} more", state.len() - SHOWN));
    }
    format!("[{}]", parts.join(", "))
}

/// One state value in messages: Rust's shortest round-trip form, in scientific notation
/// outside [1e-4, 1e15) so that `1.57e149` is never written out as 150 digits.
pub fn fmt_value(x: f64) -> String {
    if x == 0.0 || (1e-4..1e15).contains(&x.abs()) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A failure inside one step, before the driver attaches the last good state.
#[derive(Debug, Clone, PartialEq)]
pub struct StepFailure(pub FailureReason);

impl From<RhsError> for StepFailure {
    fn from(e: RhsError) -> Self {
        StepFailure(FailureReason::Rhs(e))
    }
}

/// Whether some entry of `v` is infinite or NaN. Every step of every method asks this of
/// whole vectors (a Taylor step of all its coefficients), and nearly always the answer is no:
/// the test is folded over the slice without a branch per entry, which vectorises.
///
/// Short vectors are tested entry by entry instead: they are typically a state that the
/// step's update has just stored entry by entry, and a 16-byte load of two entries stored
/// separately waits until both stores complete (no store forwarding), 3 % of a
/// double-pendulum step at tol 1e-6 (BENCHMARKS.md).
#[inline]
pub(crate) fn any_non_finite(v: &[f64]) -> bool {
    if v.len() <= 8 {
        return v.iter().any(|x| !x.is_finite());
    }
    v.iter().fold(false, |bad, x| bad | !x.is_finite())
}

/// First non-finite entry of `v`, as a step failure.
pub(crate) fn check_finite(v: &[f64]) -> Result<(), StepFailure> {
    if !any_non_finite(v) {
        return Ok(());
    }
    match v.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(component) => Err(StepFailure(FailureReason::NonFinite { component })),
    }
}
