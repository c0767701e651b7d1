//! Canonical transformations, Poisson brackets, Lie series, averaging and action-angle variables (`src/canonical/`).

mod action;
mod average;
mod branches;
mod cli;
mod lie;
mod poisson;
mod props;
mod reduce;
mod transform;
