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
//! From a Lagrangian to a trajectory (the README's five lines):
//!
//! ```
//! use lagrangian::integrate::{Gauss6, Integrate};
//! use lagrangian::mechanics::System;
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let sys = System::from_lagrangian("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", &["θ"])?
//!     .with_params(&[("m", 1.0), ("l", 1.0), ("g", 9.81)])?;
//! let equations = sys.euler_lagrange()?; // exact: l m (g sin(θ) + l θ'') = 0
//! let rhs = sys.compile_rhs()?; // an allocation-free `integrate::Rhs`
//! let trajectory = Gauss6::new(0.01).integrate(&rhs, 0.0..20.0, &[3.0, 0.0])?;
//! # assert_eq!(equations[0].to_string(), "l m (g sin(θ) + l θ'')");
//! # assert!(trajectory.last_state().iter().all(|v| v.is_finite()));
//! # Ok(())
//! # }
//! ```
//!
//! The pipeline, one module per stage (see `ARCHITECTURE.md`):
//! [`parse`](mod@parse) text → [`expr`] canonical DAG → [`simplify`] (egg) → [`diff`] →
//! [`print`](mod@print) / [`eval`].

pub mod algebra;
#[cfg(feature = "frontends")]
pub mod animate;
pub mod cache;
pub mod cancel;
pub mod canonical;
pub mod chaos;
pub mod compile;
pub mod diff;
pub mod eval;
pub mod expr;
pub mod func;
pub mod integrate;
pub mod lanes;
#[doc(hidden)]
pub mod linalg;
pub mod mechanics;
pub mod parse;
#[cfg(feature = "frontends")]
pub mod plot;
pub mod print;
pub mod report;
#[cfg(feature = "frontends")]
pub mod scene;
pub mod simplify;
pub mod simulate;
mod suggest;

pub use expr::{live_nodes, Expr, Func, Node, Rational, Symbol};
pub use parse::{parse, parse_with, Declarations, ParseError};
pub use print::Format;
