//! Taylor-mode automatic differentiation of a [`Tape`]: the normalised Taylor coefficients
//! `x_[k] = x⁽ᵏ⁾(t₀)/k!` of every value of the tape, order by order, and from them the Taylor
//! expansion of the solution of an ODE whose right-hand side the tape computes.
//!
//! Why a second form of the tape: the register tape reuses a slot as soon as its last reader
//! has run, which is right for one evaluation but wrong here, because order `k` of an
//! instruction reads orders `0..=k` of its operands, computed in earlier passes over the tape.
//! [`TaylorTape`] renames the tape into single assignment (one row of coefficients per value)
//! and adds, for the functions whose derivative is not a tape value already, one or two
//! auxiliary rows (the cosine of a lone sine, `1 + tan²`, `√(1 − a²)` of an arcsine, …), so
//! that every instruction has a recurrence of cost `O(k)` at order `k` (Griewank & Walther,
//! *Evaluating Derivatives*, 2nd ed. 2008, §13.2, Table 13.2; the same recurrences as
//! Jorba & Zou 2005, §2.1). Parameters and constants have order 0 only; the time input has
//! `t₀, 1, 0, …`.
//!
//! Order 0 is computed with exactly the floating-point operations of the interpreter, so the
//! zeroth coefficients equal a plain evaluation bit for bit. Orders ≥ 1 run recurrences
//! rewritten from those operations where a cheaper one gives the same series (scalings,
//! squares, fused powers: `higher_order_ops`).
//!
//! [`TaylorOde`] turns a tape into the right-hand side of an ODE in the integrators' layout:
//! for each state component the tape output (or the other state component, for `q' = v`) that
//! is its derivative, and optionally a linear solve `W a = F` per order for `W q'' = F`
//! systems (`W₀ a_k = F_k − Σ_{j≥1} W_j a_{k−j}`, one factorisation of `W₀` per expansion).

mod batch;
mod interp;
mod ir;
mod layout;
mod native;
mod ode;
mod tiers;
mod wide;

pub use batch::{LaneWork, TaylorBatch};
pub use ir::{KinkAt, TaylorTape};
pub use native::TaylorNative;
pub use ode::{Derivative, TaylorError, TaylorOde};
pub use tiers::{
    AUTO_NATIVE_AFTER_EXPANSIONS, COMPACT_ABOVE_TERMS, COMPACT_AFTER_EXPANSIONS, NATIVE_AFTER_EXPANSIONS,
    UNROLL_AFTER_EXPANSIONS,
};
#[doc(hidden)]
pub use wide::wide_encoding_samples;
