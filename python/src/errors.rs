//! One Python exception class per engine error type, every argument error a `ValueError`
//! too (the hierarchy and why: `lagrangian/_errors.py`). The message is the engine's own
//! diagnostic (for a parse error: the line, the caret under the column and the hint), so a
//! notebook shows exactly what the command line would.

use lagrangian::integrate::IntegrateError;
use pyo3::prelude::*;
use pyo3::types::PyList;

/// The exception classes, defined in `lagrangian/_errors.py` (where a class with two bases,
/// `LagrangianError` and `ValueError`, is one line) and raised from here as those very classes.
pub mod exc {
    use pyo3::import_exception;
    import_exception!(lagrangian._errors, LagrangianError);
    import_exception!(lagrangian._errors, ArgumentError);
    import_exception!(lagrangian._errors, ParseError);
    import_exception!(lagrangian._errors, MechanicsError);
    import_exception!(lagrangian._errors, CompileError);
    import_exception!(lagrangian._errors, RhsError);
    import_exception!(lagrangian._errors, IntegrationError);
    import_exception!(lagrangian._errors, EvalError);
    import_exception!(lagrangian._errors, TransformError);
    import_exception!(lagrangian._errors, SolveError);
    import_exception!(lagrangian._errors, PhaseSpaceError);
    import_exception!(lagrangian._errors, LieError);
    import_exception!(lagrangian._errors, ActionAngleError);
    import_exception!(lagrangian._errors, AverageError);
    import_exception!(lagrangian._errors, EnsembleError);
}

/// Registers the classes under their public names in the native module too.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let errors = m.py().import("lagrangian._errors")?;
    for cls in errors.getattr("ALL")?.try_iter()? {
        let cls = cls?;
        m.add(cls.getattr("__name__")?.extract::<String>()?, cls)?;
    }
    Ok(())
}

/// Conversion of an engine error into its Python exception.
pub trait ToPyErr {
    /// The exception.
    fn py_err(self) -> PyErr;
}

impl ToPyErr for lagrangian::parse::ParseError {
    fn py_err(self) -> PyErr {
        exc::ParseError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::mechanics::MechanicsError {
    fn py_err(self) -> PyErr {
        match self {
            // The cause is the text: the parse error's own class, caret and all.
            lagrangian::mechanics::MechanicsError::Parse(p) => p.py_err(),
            other => exc::MechanicsError::new_err(other.to_string()),
        }
    }
}

impl ToPyErr for lagrangian::compile::CompileError {
    fn py_err(self) -> PyErr {
        exc::CompileError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::compile::RhsError {
    fn py_err(self) -> PyErr {
        exc::RhsError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::eval::EvalError {
    fn py_err(self) -> PyErr {
        exc::EvalError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::canonical::TransformError {
    fn py_err(self) -> PyErr {
        exc::TransformError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::canonical::SolveError {
    fn py_err(self) -> PyErr {
        exc::SolveError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::canonical::PhaseSpaceError {
    fn py_err(self) -> PyErr {
        exc::PhaseSpaceError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::canonical::LieError {
    fn py_err(self) -> PyErr {
        exc::LieError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::canonical::ActionAngleError {
    fn py_err(self) -> PyErr {
        exc::ActionAngleError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::canonical::AverageError {
    fn py_err(self) -> PyErr {
        exc::AverageError::new_err(self.to_string())
    }
}

impl ToPyErr for lagrangian::compile::EnsembleError {
    fn py_err(self) -> PyErr {
        exc::EnsembleError::new_err(self.to_string())
    }
}

/// An integration error keeps where it stopped as attributes: `t`, `state` (a list) and
/// `steps`, so a caller can inspect or restart from the last good state. `message` is the
/// simulation layer's (the state by name, and what to do about it).
pub fn integration_error(py: Python<'_>, e: IntegrateError, message: String) -> PyErr {
    let err = exc::IntegrationError::new_err(message);
    let value = err.value(py);
    let _ = value.setattr("t", e.t);
    let _ = value.setattr("steps", e.steps);
    if let Ok(list) = PyList::new(py, &e.state) {
        let _ = value.setattr("state", list);
    }
    err
}

/// `result.map_err(ToPyErr::py_err)` in one call.
pub trait PyResultExt<T> {
    /// The value, or the Python exception of the error.
    fn py(self) -> PyResult<T>;
}

impl<T, E: ToPyErr> PyResultExt<T> for Result<T, E> {
    fn py(self) -> PyResult<T> {
        self.map_err(ToPyErr::py_err)
    }
}
