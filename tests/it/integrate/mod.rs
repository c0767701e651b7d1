//! The integrators: coefficient data, orders, events, stress, structure, the energy ledger (`src/integrate/`).

mod coefficients;
mod drift;
mod events;
mod order;
mod stress;
mod structure;
