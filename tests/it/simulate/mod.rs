//! The simulate layer: every method × every kind of system (`src/simulate/`).

mod matrix;
mod nonholonomic;
