//! The Taylor method: recurrences, the native emitter, the integrator and its scene statement.

mod batch;
mod constrained;
mod integrate;
mod native;
mod recurrences;
mod scene;
mod solar_system;
