//! The mechanics stage: worked systems, routes, errors, the symmetry search (`src/mechanics/`).

mod errors;
mod map;
mod properties;
mod split_routes;
mod symmetry_search;
mod worked;
