//! The mechanics stage: worked systems, routes, errors, the symmetry search (`src/mechanics/`).

mod algebraic;
mod errors;
mod map;
mod nonholonomic;
mod properties;
mod split_routes;
mod symmetry_search;
mod tidy;
mod velocity_guards;
mod worked;
