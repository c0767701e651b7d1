//! From a system and a method name to a trajectory: the layer every front end (scenes, the
//! command line, Python) calls, so they cannot disagree.
//!
//! ```text
//! MethodId ──route(method, Shape)──▶ Formulation ──compile──▶ Compiled ──integrate(RunOptions)──▶ Trajectory
//! ```
//!
//! * [`method`]: the registry, one row per method (name, scheme as data, what it needs).
//! * [`formulation`]: which equations a method integrates for a kind of system, or a typed
//!   [`Refusal`] naming the methods that can run it. No front end dispatches on a family.
//! * [`compiled`]: the formulation compiled for the method's [`Form`], one typed value.
//! * [`run`]: the one drive loop (sampling, events, budgets, cancellation, energy ledger).
//!
//! ```
//! use lagrangian::mechanics::System;
//! use lagrangian::simulate::{self, MethodId, RunOptions};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let sys = System::from_lagrangian("1/2 x'^2 - 1/2 x^2", &["x"])?.with_rayleigh("1/2 c x'^2")?
//!     .with_params(&[("c", 0.5)])?;
//! // A splitting method cannot run a damped system: refused, naming what can.
//! let refused = simulate::compile_system(&sys, MethodId::Leapfrog, &[]);
//! assert!(matches!(refused, Err(simulate::SimulateError::Refused(_))));
//! let c = simulate::compile_system(&sys, MethodId::Dop853, &[])?;
//! let traj = simulate::integrate(&c, &[1.0, 0.0], &RunOptions::new(MethodId::Dop853, 0.0, 20.0), &mut |_| {})?;
//! assert!(traj.last_state().unwrap()[0].abs() < 0.01);
//! # Ok(())
//! # }
//! ```

pub mod compiled;
pub mod energy;
mod error;
pub mod formulation;
mod limits;
pub mod method;
pub mod run;
mod system;

pub use compiled::{compile, CompileRequest, Compiled, CompiledSystem};
pub use energy::{EnergyCheck, Ledger};
pub use error::SimulateError;
pub use formulation::{not_separable, route, ExtendedLagrangian, Formulation, Refusal, RefusalReason, Route, Shape};
pub use method::{Family, Form, MethodId, MethodSpec, Needs, Scheme, DEFAULT_METHOD, METHODS};
pub use run::{
    default_every, ensemble, integrate, par_map_with_progress, with_progress, EventSpec, RunOptions, Sampling,
    Trajectory, WorkerPanicked, MAX_ADAPTIVE_STEPS, MAX_FIXED_STEPS, MAX_POINTS, MAX_STORED_STATES,
};
pub use system::{
    compile_formulation, compile_system, compile_system_with, formulation_for, formulation_of, is_first_order,
    shape_of, Derivations, Equations, Fresh,
};
