"""Exact Lagrangian and Hamiltonian mechanics from Python.

Write a Lagrangian or Hamiltonian as text; the Rust engine derives the equations of motion
exactly and integrates them fast::

    import lagrangian as lg
    sys = lg.System.from_lagrangian(
        "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", ["θ"],
        params={"m": 1, "l": 1, "g": 9.81}, positive=["m", "l", "g"])
    sys.euler_lagrange()          # [Expr("g l m sin(θ) + l^2 m θ''")]
    sol = sys.integrate((0, 10), [3.0, 0.0], method="gauss6", dt=0.01)
    sol.t.shape, sol.y.shape      # ((1001,), (2, 1001))

``System.compile()`` gives a right-hand side ``f(t, y)`` for SciPy's ``solve_ivp``;
``System.ensemble`` integrates many initial states in parallel; :func:`sweep` maps a grid of
initial states or parameter values over a Dask cluster. Derivations are kept in the same
on-disk cache as the command line's (``$LAGRANGIAN_CACHE_DIR``, else ``~/.cache/lagrangian``;
see :func:`cache_info` and :func:`set_cache_dir`).

Errors: every exception is a :class:`LagrangianError`; every one that says an argument was
wrong (text that does not parse, a method that cannot run the system, a bad ``y0``) is also a
``ValueError``. Only :class:`IntegrationError`, a run that failed along the way, is not.
"""

from ._core import (
    DEFAULT_METHOD,
    METHODS,
    CompiledRhs,
    EnsembleResult,
    Event,
    Expr,
    Solution,
    System,
    Lambdified,
    cache_info,
    iterate_map,
    jacobian,
    lambdify,
    parse,
    poisson,
    series,
    set_cache_dir,
)
from ._errors import (
    ActionAngleError,
    ArgumentError,
    AverageError,
    CompileError,
    EnsembleError,
    EvalError,
    IntegrationError,
    LagrangianError,
    LieError,
    MechanicsError,
    ParseError,
    PhaseSpaceError,
    RhsError,
    SolveError,
    TransformError,
)
from ._chaos import Indicators, install as _install_chaos
from ._dense import DenseSolution
from ._display import ExprList, ExprMatrix, SymbolNames, install as _install_display
from ._frames import ensemble_to_pandas, ensemble_to_xarray, solution_to_pandas, solution_to_xarray
from ._sympy import from_sympy, to_sympy
from ._sweep import SweepResult, sweep

__all__ = [
    "DEFAULT_METHOD",
    "METHODS",
    "ActionAngleError",
    "ArgumentError",
    "AverageError",
    "CompiledRhs",
    "CompileError",
    "DenseSolution",
    "EnsembleError",
    "EnsembleResult",
    "EvalError",
    "Event",
    "Expr",
    "ExprList",
    "ExprMatrix",
    "Indicators",
    "IntegrationError",
    "LagrangianError",
    "Lambdified",
    "LieError",
    "MechanicsError",
    "ParseError",
    "PhaseSpaceError",
    "RhsError",
    "Solution",
    "SolveError",
    "SweepResult",
    "SymbolNames",
    "System",
    "TransformError",
    "cache_info",
    "from_sympy",
    "iterate_map",
    "jacobian",
    "lambdify",
    "parse",
    "poisson",
    "series",
    "set_cache_dir",
    "sweep",
    "to_sympy",
]

# `Expr.to_sympy()` / `Expr.from_sympy(...)` as methods too (the conversion is pure Python).
Expr.to_sympy = to_sympy  # type: ignore[attr-defined]
Expr.from_sympy = staticmethod(from_sympy)  # type: ignore[attr-defined]

# pandas and xarray views of the results, imported only when called.
Solution.to_pandas = solution_to_pandas  # type: ignore[attr-defined]
Solution.to_xarray = solution_to_xarray  # type: ignore[attr-defined]
EnsembleResult.to_pandas = ensemble_to_pandas  # type: ignore[attr-defined]
EnsembleResult.to_xarray = ensemble_to_xarray  # type: ignore[attr-defined]

# LaTeX display of lists and matrices of Expr, the free_symbols property and Expr.lambdify.
_install_display(Expr, System, lambdify)

# Chaos indicators, chaos maps, Poincaré sections (the scene statements).
_install_chaos(System)
