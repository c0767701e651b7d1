//! The register tape: the demanded outputs of a set of expressions lowered into a flat list of
//! instructions over numbered slots, evaluated in a tight loop.
//!
//! Lowering walks the hash-consed DAG from the demanded outputs only (so dead outputs cost
//! nothing) and memoises on node identity (so every shared subexpression is one slot). On
//! top of that it value-numbers the emitted instructions (two different nodes that lower to
//! the same `a·b` share it) and makes the choices that are cheap in floating point rather than
//! small as trees: integer powers become multiplication chains, half-integer powers `sqrt`,
//! negative powers a division (or, when the reciprocal is used more than once, one reciprocal
//! shared by all its users), `sin` and `cos` of one argument one `sin_cos`, and every
//! subexpression of bound parameters alone is folded to a constant at compile time.
//!
//! Slots are laid out as `inputs | constants | registers`; after lowering, registers are
//! reassigned by a liveness scan so the scratch a call needs stays small.

mod interp;
mod ir;
mod lower;
mod native;

pub(crate) use interp::with_scratch;
pub use interp::LANES;
pub use ir::{CompileOptions, Instr, OpCounts, Tape};
pub(crate) use native::{Epilogue, NativeCode, MAX_NATIVE_INSTRS};
