//! Why a set of expressions could not be compiled.

/// Why a set of expressions could not be compiled.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CompileError {
    /// A symbol is neither an input nor a bound parameter.
    #[error("`{name}` is neither a state variable nor a bound parameter; bind it with a parameter value")]
    Unbound { name: String },
    /// A declared function (`V(r)`) has no numeric definition.
    #[error(
        "the declared function `{name}` has no numeric definition; substitute an expression for it before compiling"
    )]
    UndefinedFunction { name: String },
    /// An expression is undefined (`1/0`).
    #[error("the expression is undefined (such as 1/0)")]
    Undefined,
    /// The same input name was given twice.
    #[error("the input `{name}` is listed twice")]
    DuplicateInput { name: String },
    /// A parameter has the name of an input.
    #[error("`{name}` is both a state variable and a parameter")]
    ParamIsInput { name: String },
    /// A parameter value is infinite or NaN.
    #[error("the parameter `{name}` has the non-finite value {value}")]
    NonFiniteParam { name: String, value: f64 },
    /// A subexpression of parameters alone folds to a non-finite number.
    #[error("`{expr}` evaluates to {value} with the given parameters")]
    NonFiniteConstant { expr: String, value: f64 },
    /// The expression is nested deeper than the compiler accepts.
    #[error("the expression is nested deeper than {limit} levels")]
    TooDeep { limit: usize },
    /// Inputs of inconsistent sizes (a mass matrix that is not `n × n`, …).
    #[error("{what}: expected {expected}, got {got}")]
    Shape { what: &'static str, expected: usize, got: usize },
    /// The mechanics stage could not provide the equations (its typed error).
    #[error("{0}")]
    Mechanics(#[from] crate::mechanics::MechanicsError),
    /// The system has a feature the compiled right-hand sides do not handle yet.
    #[error("compiling {what} is not supported")]
    Unsupported { what: &'static str },
    /// The Hamiltonian is not of the form `T(p) + V(q, t)`.
    #[error("the Hamiltonian is not separable into T(p) + V(q, t)")]
    NotSeparable,
}
