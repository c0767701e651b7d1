//! The `lagrangian` Python package's native module, `lagrangian._core`.
//!
//! It mirrors the library, not the command line: [`expr::PyExpr`] wraps an expression,
//! [`system::PySystem`] a mechanical system with every derivation, `sim.rs` the numeric side
//! (compiled right-hand sides and their Jacobians, `integrate`, `ensemble`) and `cache.rs` the
//! on-disk derivation cache shared with the command line. Errors become one Python exception
//! class per engine error type (`errors.rs`). The pure-Python parts of the package (pickling
//! helpers, progress bar, SymPy conversion, Dask sweeps) live in `lagrangian/`.
//!
//! Layers, each importing only those before it: `errors` and `convert` (Python arguments into
//! engine values), `expr`, `lambdify`, `system`, then the numeric files (`progress`, `sim`, `chaos`); `cache` stands
//! alone. No file imports one after it.

use pyo3::prelude::*;

mod cache;
mod chaos;
mod convert;
mod errors;
mod expr;
mod lambdify;
mod progress;
mod sim;
mod system;
mod tools;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<expr::PyExpr>()?;
    m.add_class::<system::PySystem>()?;
    m.add_class::<sim::CompiledRhs>()?;
    m.add_class::<sim::Solution>()?;
    m.add_class::<sim::EnsembleResult>()?;
    m.add_class::<sim::PyEvent>()?;
    m.add_class::<lambdify::Lambdified>()?;
    m.add_function(wrap_pyfunction!(expr::parse, m)?)?;
    m.add_function(wrap_pyfunction!(system::poisson, m)?)?;
    m.add_function(wrap_pyfunction!(lambdify::lambdify, m)?)?;
    m.add_function(wrap_pyfunction!(tools::series, m)?)?;
    m.add_function(wrap_pyfunction!(tools::jacobian, m)?)?;
    m.add_function(wrap_pyfunction!(tools::iterate_map, m)?)?;
    m.add_function(wrap_pyfunction!(cache::cache_info, m)?)?;
    m.add_function(wrap_pyfunction!(cache::set_cache_dir, m)?)?;
    m.add("METHODS", sim::binding_methods().map(|m| m.name()).collect::<Vec<_>>())?;
    m.add("DEFAULT_METHOD", lagrangian::simulate::DEFAULT_METHOD.name())?;
    // The SymPy bridge maps built-in names through this rather than a copy of its own.
    m.add("BUILTINS", lagrangian::func::Func::ALL.iter().map(|f| (f.name(), f.spec().sympy)).collect::<Vec<_>>())?;
    errors::register(m)?;
    Ok(())
}
