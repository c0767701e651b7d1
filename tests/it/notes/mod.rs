//! What the lecture notes ask of the engine: singular and first-order Lagrangians, geodesics, Ritz, discrete mechanics.

mod discrete;
mod examples;
mod first_order;
mod geodesic;
mod jacobian;
mod printed;
mod ritz;
mod series;
mod singular;
