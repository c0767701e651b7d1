//! One Python exception class per engine error type. The message is the engine's own
//! diagnostic (for a parse error: the line, the caret under the column and the hint), so a
//! notebook shows exactly what the command line would.

use lagrangian::integrate::IntegrateError;
use pyo3::prelude::*;
use pyo3::types::PyList;

/// The exception classes, named as Python sees them.
pub mod exc {
    use pyo3::create_exception;
    use pyo3::exceptions::PyException;
    create_exception!(lagrangian, LagrangianError, PyException, "Base class of every error the engine raises.");
    create_exception!(
        lagrangian,
        ParseError,
        LagrangianError,
        "The text of an expression did not parse (`parse::ParseError`)."
    );
    create_exception!(
        lagrangian,
        MechanicsError,
        LagrangianError,
        "A mechanics derivation refused its input: a singular Hessian, an unknown parameter, a bad coordinate (`mechanics::MechanicsError`)."
    );
    create_exception!(
        lagrangian,
        CompileError,
        LagrangianError,
        "Equations could not be compiled: a parameter without a value, an undefined function (`compile::CompileError`)."
    );
    create_exception!(
        lagrangian,
        RhsError,
        LagrangianError,
        "A compiled right-hand side has no value at a state: a singular mass matrix, a non-finite value (`compile::RhsError`)."
    );
    create_exception!(
        lagrangian,
        IntegrationError,
        LagrangianError,
        "An integration stopped early (`integrate::IntegrateError`); `t`, `state` and `steps` say where."
    );
    create_exception!(
        lagrangian,
        EvalError,
        LagrangianError,
        "An expression has no numeric value: an unbound symbol (`eval::EvalError`)."
    );
    create_exception!(
        lagrangian,
        TransformError,
        LagrangianError,
        "A generating function was refused (`canonical::TransformError`)."
    );
    create_exception!(
        lagrangian,
        SolveError,
        LagrangianError,
        "An equation could not be solved in closed form (`canonical::SolveError`)."
    );
    create_exception!(
        lagrangian,
        PhaseSpaceError,
        LagrangianError,
        "A malformed phase space (`canonical::PhaseSpaceError`)."
    );
    create_exception!(lagrangian, LieError, LagrangianError, "A Lie series was refused (`canonical::LieError`).");
    create_exception!(
        lagrangian,
        ActionAngleError,
        LagrangianError,
        "The action-angle quadrature was refused (`canonical::ActionAngleError`)."
    );
    create_exception!(lagrangian, AverageError, LagrangianError, "An average was refused (`canonical::AverageError`).");
    create_exception!(
        lagrangian,
        EnsembleError,
        LagrangianError,
        "An ensemble could not run (`compile::EnsembleError`)."
    );
}

/// Registers the classes under their public names.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("LagrangianError", py.get_type::<exc::LagrangianError>())?;
    m.add("ParseError", py.get_type::<exc::ParseError>())?;
    m.add("MechanicsError", py.get_type::<exc::MechanicsError>())?;
    m.add("CompileError", py.get_type::<exc::CompileError>())?;
    m.add("RhsError", py.get_type::<exc::RhsError>())?;
    m.add("IntegrationError", py.get_type::<exc::IntegrationError>())?;
    m.add("EvalError", py.get_type::<exc::EvalError>())?;
    m.add("TransformError", py.get_type::<exc::TransformError>())?;
    m.add("SolveError", py.get_type::<exc::SolveError>())?;
    m.add("PhaseSpaceError", py.get_type::<exc::PhaseSpaceError>())?;
    m.add("LieError", py.get_type::<exc::LieError>())?;
    m.add("ActionAngleError", py.get_type::<exc::ActionAngleError>())?;
    m.add("AverageError", py.get_type::<exc::AverageError>())?;
    m.add("EnsembleError", py.get_type::<exc::EnsembleError>())?;
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
/// `steps`, so a caller can inspect or restart from the last good state.
pub fn integration_error(py: Python<'_>, e: IntegrateError) -> PyErr {
    let err = exc::IntegrationError::new_err(e.to_string());
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
