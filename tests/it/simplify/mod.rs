//! The algebra: properties over random expressions, the simplification table, determinism (`src/simplify.rs`, `src/algebra.rs`).

mod algebra;
mod determinism;
mod pi;
mod properties;
mod rules;
mod table;
