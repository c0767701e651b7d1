//! The integrators: coefficient data, orders, events, stress, structure, the energy ledger (`src/integrate/`).

mod coefficients;
mod drift;
mod drift_bound;
mod events;
mod order;
mod polynomial;
mod problems;
mod stress;
mod structure;
