//! The compiler: symbolic equations of motion → fast numeric closures.
//!
//! ```text
//! demanded outputs ──▶ shared DAG (hash-consed, so CSE is free) ──▶ register tape ──▶ Rhs
//! ```
//!
//! * [`Tape`]: the demanded outputs of a set of expressions as a flat, printable instruction
//!   list over numbered slots, with parameters bound and folded; evaluation does not allocate.
//! * Right-hand sides for the integrators ([`crate::integrate`]): [`LagrangianRhs`] solves
//!   `W q'' = F` in place; [`HamiltonianRhs`] evaluates Hamilton's equations and their exact
//!   Jacobian; [`SeparableHamiltonian`] is the drift/kick split of `H = T(p) + V(q, t)`;
//!   [`ImplicitLegendreRhs`] inverts `p = ∂L/∂q'` by Newton when no closed form exists;
//!   [`FirstOrderRhs`] solves `ω z' = ∂H/∂z + ∂a/∂t` of a phase-space Lagrangian.
//! * [`VariationalMap`]: the variational integrator of a discrete Lagrangian (Newton with
//!   the exact Jacobian on the discrete Legendre map).
//! * [`TaylorTape`], [`TaylorOde`]: Taylor-mode automatic differentiation of a tape (the
//!   coefficients of the ODE solution to any order), for the Taylor integrator.
//! * [`ConstrainedRhs`]: holonomic constraints by the augmented system `[W Φᵀ; Φ 0]`, with
//!   Baumgarte stabilisation or projection ([`Projected`]) against drift.
//! * [`ensemble`]: many initial conditions in parallel (rayon) for any integrator closure.
//! * The native back end (`native.rs`): every tape is also compiled to machine code with
//!   Cranelift and evaluated there, with the same bits as the interpreter, which remains the
//!   reference and the fallback ([`CompileOptions::native`], [`NO_JIT_ENV`]).
//!
//! This stage never parses: it receives [`Expr`](crate::Expr)s and symbol names.

mod constrained;
mod discrete;
mod ensemble;
mod first_order;
mod geodesic;
mod native;
mod rhs;
mod system;
mod tape;
mod taylor;
mod variational;

pub use constrained::{ConstrainedRhs, Projected, Stabilization};
pub use discrete::{DiscretePoint, StepperWork, VariationalError, VariationalMap, VariationalStepper, MAX_NEWTON};
pub use ensemble::{ensemble, ensemble_with_threads, EnsembleError};
pub use first_order::{FirstOrderRhs, WithVelocitySlots, MAX_FIRST_ORDER_DIM};
pub use geodesic::{shoot, shoot_with, ShootBudget, ShootError, Shot};
pub use native::NO_JIT_ENV;
pub use rhs::{
    split_separable, HamiltonianRhs, ImplicitLegendreRhs, LagrangianJacobian, LagrangianRhs, RhsError,
    SeparableHamiltonian,
};
pub use tape::{CompileOptions, Instr, OpCounts, Tape, LANES};
pub use taylor::{
    Derivative, KinkAt, TaylorError, TaylorNative, TaylorOde, TaylorTape, AUTO_NATIVE_AFTER_EXPANSIONS,
    COMPACT_ABOVE_TERMS, COMPACT_AFTER_EXPANSIONS, NATIVE_AFTER_EXPANSIONS, UNROLL_AFTER_EXPANSIONS,
};
pub use variational::Variational;

/// Why a set of expressions could not be compiled.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CompileError {
    /// A symbol is neither an input nor a bound parameter.
    #[error("`{name}` is neither a state variable nor a bound parameter; bind it with a parameter value")]
    Unbound { name: String },
    /// A declared function (`V(r)`) has no numeric definition.
    #[error(
        "the declared function `{name}` has no numeric definition; substitute an expression for it before compiling"
    )]
    UndefinedFunction { name: String },
    /// An expression is undefined (`1/0`).
    #[error("the expression is undefined (such as 1/0)")]
    Undefined,
    /// The same input name was given twice.
    #[error("the input `{name}` is listed twice")]
    DuplicateInput { name: String },
    /// A parameter has the name of an input.
    #[error("`{name}` is both a state variable and a parameter")]
    ParamIsInput { name: String },
    /// A parameter value is infinite or NaN.
    #[error("the parameter `{name}` has the non-finite value {value}")]
    NonFiniteParam { name: String, value: f64 },
    /// A subexpression of parameters alone folds to a non-finite number.
    #[error("`{expr}` evaluates to {value} with the given parameters")]
    NonFiniteConstant { expr: String, value: f64 },
    /// The expression is nested deeper than the compiler accepts.
    #[error("the expression is nested deeper than {limit} levels")]
    TooDeep { limit: usize },
    /// Inputs of inconsistent sizes (a mass matrix that is not `n × n`, …).
    #[error("{what}: expected {expected}, got {got}")]
    Shape { what: &'static str, expected: usize, got: usize },
    /// The mechanics stage could not provide the equations (its typed error).
    #[error("{0}")]
    Mechanics(#[from] crate::mechanics::MechanicsError),
    /// The system has a feature the compiled right-hand sides do not handle yet.
    #[error("compiling {what} is not supported")]
    Unsupported { what: &'static str },
    /// The Hamiltonian is not of the form `T(p) + V(q, t)`.
    #[error("the Hamiltonian is not separable into T(p) + V(q, t)")]
    NotSeparable,
}

/// The plain spelling of the velocity of coordinate `q` (`θ` → `θ'`).
pub(crate) fn velocity_name(q: &str) -> String {
    format!("{q}'")
}

// Compiled systems are shared across ensemble threads.
const _: () = {
    const fn sync_send<T: Sync + Send>() {}
    sync_send::<Tape>();
    sync_send::<LagrangianRhs>();
    sync_send::<HamiltonianRhs>();
    sync_send::<SeparableHamiltonian>();
    sync_send::<ImplicitLegendreRhs>();
    sync_send::<ConstrainedRhs>();
};
