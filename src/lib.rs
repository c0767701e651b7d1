//! # lagrangian
//!
//! Exact classical mechanics: write a Lagrangian or Hamiltonian as text, derive its equations
//! of motion exactly, integrate them fast.
//!
//! ```
//! use lagrangian::{parse, diff, Symbol};
//! let l = parse::parse("1/2 m x'^2 - 1/2 k x^2").unwrap();
//! let dl_dx = diff::diff(&l, &Symbol::new("x"));
//! assert_eq!(dl_dx.to_string(), "-k x");
//! ```
//!
//! The pipeline, one module per stage (see `ARCHITECTURE.md`):
//! [`parse`] text → [`expr`] canonical DAG → [`simplify`] (egg) → [`diff`] → [`print`] / [`eval`].

pub mod algebra;
pub mod canonical;
pub mod compile;
pub mod diff;
pub mod eval;
pub mod expr;
pub mod integrate;
pub mod mechanics;
pub mod parse;
pub mod plot;
pub mod print;
pub mod scene;
pub mod simplify;

pub use expr::{Expr, Func, Node, Rational, Symbol};
pub use parse::{parse, parse_with, Declarations, ParseError};
pub use print::Format;
