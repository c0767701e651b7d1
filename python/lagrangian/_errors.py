"""The exceptions the engine raises, in one hierarchy.

Every one is a :class:`LagrangianError`. Every error that says an *argument* was wrong is also
a :class:`ValueError`, so code written for NumPy and SciPy (``except ValueError``) catches it:
text that does not parse, a derivation the input does not allow, a parameter without a value,
a method that cannot run this system, a bad ``t_span`` or ``y0``, a state where the equations
have no value. Only an integration that was asked for correctly and failed along the way
(:class:`IntegrationError`: the step size collapsed, the step budget ran out) is not a
``ValueError``; SciPy reports that case as ``status = -1`` and this package raises it with
where the run stopped. Wrong *types* (a dict where a number belongs) stay ``TypeError`` and
Ctrl-C stays ``KeyboardInterrupt``.

Why defined in Python: a class with two bases (``LagrangianError`` and ``ValueError``) is one
line here; the native module raises these very classes (``pyo3::import_exception``).
"""

from __future__ import annotations


class LagrangianError(Exception):
    """Base class of every error the engine raises."""


class ArgumentError(LagrangianError, ValueError):
    """An argument the engine refuses that no more specific class covers: an unknown method, a
    method that cannot run this system, a missing ``dt``, a tolerance below what ``f64`` can
    meet, a bad ``t_span``, ``y0``, ``t_eval`` or parameter value."""


class ParseError(LagrangianError, ValueError):
    """The text of an expression did not parse (``parse::ParseError``); the message has the
    line, a caret under the column and a hint."""


class MechanicsError(LagrangianError, ValueError):
    """A mechanics derivation refused its input: a singular Hessian, an unknown parameter, a
    bad coordinate (``mechanics::MechanicsError``)."""


class CompileError(LagrangianError, ValueError):
    """Equations could not be compiled: a parameter without a value, an undefined function
    (``compile::CompileError``)."""


class RhsError(LagrangianError, ValueError):
    """The equations have no value at the state given: a singular mass matrix, a non-finite
    value (``compile::RhsError``). Raised by a compiled ``f(t, y)`` and by ``integrate`` for a
    start ``y0`` where the right-hand side has no value."""


class EvalError(LagrangianError, ValueError):
    """An expression has no numeric value: an unbound symbol (``eval::EvalError``)."""


class TransformError(LagrangianError, ValueError):
    """A generating function was refused (``canonical::TransformError``)."""


class SolveError(LagrangianError, ValueError):
    """An equation could not be solved in closed form (``canonical::SolveError``)."""


class PhaseSpaceError(LagrangianError, ValueError):
    """A malformed phase space (``canonical::PhaseSpaceError``)."""


class LieError(LagrangianError, ValueError):
    """A Lie series was refused (``canonical::LieError``)."""


class ActionAngleError(LagrangianError, ValueError):
    """The action-angle quadrature was refused (``canonical::ActionAngleError``)."""


class AverageError(LagrangianError, ValueError):
    """An average was refused (``canonical::AverageError``)."""


class EnsembleError(LagrangianError, ValueError):
    """An ensemble could not run (``compile::EnsembleError``)."""


class IntegrationError(LagrangianError):
    """An integration that was asked for correctly stopped early (``integrate::IntegrateError``):
    the step size collapsed, the state became non-finite, the step budget ran out. Not a
    ``ValueError``: the arguments were acceptable and the failure happened along the way.
    ``t``, ``state`` and ``steps`` say where, so a run can be inspected or restarted."""

    t: float
    state: list[float]
    steps: int


ALL = [
    LagrangianError,
    ArgumentError,
    ParseError,
    MechanicsError,
    CompileError,
    RhsError,
    EvalError,
    TransformError,
    SolveError,
    PhaseSpaceError,
    LieError,
    ActionAngleError,
    AverageError,
    EnsembleError,
    IntegrationError,
]

# Shown and pickled under the package's name (``lagrangian.ParseError``), where users import them.
for _cls in ALL:
    _cls.__module__ = "lagrangian"
del _cls
