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
//! * The native back ends (`tape/native.rs`, `taylor/native.rs`, over `jit.rs`): every tape is also compiled to machine code with
//!   Cranelift and evaluated there, with the same bits as the interpreter, which remains the
//!   reference and the fallback ([`CompileOptions::native`], [`NO_JIT_ENV`]).
//!
//! This stage never parses: it receives [`Expr`](crate::Expr)s and symbol names.

mod constrained;
mod discrete;
mod ensemble;
mod error;
mod first_order;
mod geodesic;
mod jit;
mod rhs;
mod system;
mod tape;
mod taylor;
mod variational;

pub use constrained::{ConstrainedRhs, Projected, Stabilization};
pub use discrete::{DiscretePoint, StepperWork, VariationalError, VariationalMap, VariationalStepper, MAX_NEWTON};
pub use ensemble::{ensemble, ensemble_with_threads, simd_lanes, EnsembleError};
pub use error::CompileError;
pub use first_order::{FirstOrderRhs, WithVelocitySlots, MAX_FIRST_ORDER_DIM};
pub use geodesic::{shoot, shoot_with, ShootBudget, ShootError, Shot};
pub use jit::NO_JIT_ENV;
pub use rhs::{
    split_separable, HamiltonianRhs, ImplicitLegendreRhs, LagrangianJacobian, LagrangianRhs, RhsError,
    SeparableHamiltonian,
};
pub use tape::{CompileOptions, Instr, OpCounts, Tape, LANES};
#[doc(hidden)]
pub use taylor::wide_encoding_samples;
pub use taylor::{
    Derivative, KinkAt, LaneWork, TaylorBatch, TaylorError, TaylorNative, TaylorOde, TaylorTape,
    AUTO_NATIVE_AFTER_EXPANSIONS, COMPACT_ABOVE_TERMS, COMPACT_AFTER_EXPANSIONS, NATIVE_AFTER_EXPANSIONS,
    UNROLL_AFTER_EXPANSIONS,
};
pub use variational::Variational;

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
