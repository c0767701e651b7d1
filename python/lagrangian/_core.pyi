"""Type stubs of the native module (signatures and short docs for editors)."""

import os
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

METHODS: list[str]
DEFAULT_METHOD: str
BUILTINS: list[tuple[str, str]]

ArrayLike = npt.ArrayLike
Operand = Union["Expr", int, float]

# The exceptions (defined in ``_errors.py``): every one is a ``LagrangianError``; every
# argument error is also a ``ValueError``; only ``IntegrationError`` (a run asked for
# correctly that failed along the way) is not.
class LagrangianError(Exception):
    """Base class of every error the engine raises."""
class ArgumentError(LagrangianError, ValueError):
    """An argument refused that no more specific class covers: an unknown method, a method that cannot run this system, a missing ``dt``, a bad ``t_span``, ``y0`` or parameter value."""
class ParseError(LagrangianError, ValueError):
    """The text did not parse; the message has the line, a caret and a hint."""
class MechanicsError(LagrangianError, ValueError):
    """A derivation refused its input: a singular Hessian, an unknown parameter."""
class CompileError(LagrangianError, ValueError):
    """Equations could not be compiled: a parameter without a value."""
class RhsError(LagrangianError, ValueError):
    """The equations have no value at the state given (a compiled ``f(t, y)``, or the start ``y0`` of ``integrate``)."""
class EvalError(LagrangianError, ValueError):
    """An expression has no numeric value: an unbound symbol."""
class TransformError(LagrangianError, ValueError): ...
class SolveError(LagrangianError, ValueError): ...
class PhaseSpaceError(LagrangianError, ValueError): ...
class LieError(LagrangianError, ValueError): ...
class ActionAngleError(LagrangianError, ValueError): ...
class AverageError(LagrangianError, ValueError): ...
class EnsembleError(LagrangianError, ValueError): ...

class IntegrationError(LagrangianError):
    """A run asked for correctly that stopped early (step size collapse, step budget); not a ``ValueError``."""

    t: float
    """Time of the last accepted state."""
    state: list[float]
    """The last accepted state."""
    steps: int

class Expr:
    """An exact symbolic expression (the engine's canonical DAG)."""

    def __init__(self, text: str, *, positive: Optional[Sequence[str]] = None, functions: Optional[Sequence[str]] = None) -> None: ...
    def plain(self) -> str: ...
    def unicode(self) -> str: ...
    def latex(self) -> str: ...
    def _repr_latex_(self) -> str: ...
    def diff(self, var: Union[str, "Expr"]) -> "Expr": ...
    def dt(self, coords: Optional[Sequence[str]] = None) -> "Expr": ...
    def simplify(self) -> "Expr": ...
    def subs(self, mapping: Mapping[Union[str, "Expr"], Union["Expr", int, float, str]]) -> "Expr": ...
    free_symbols: "SymbolNames"
    """The sorted names of the free symbols (a property, as SymPy's; calling it still works)."""
    def _free_symbols(self) -> list[str]: ...
    def lambdify(self, args: Union[str, "Expr", Sequence[Union[str, "Expr"]]]) -> "Lambdified":
        """This expression as a NumPy function of ``args`` (see :func:`lambdify`)."""
    def op_count(self) -> int: ...
    def evaluate(self, values: Optional[Mapping[Union[str, "Expr"], ArrayLike]] = None, **kwargs: ArrayLike) -> Union[float, np.ndarray]: ...
    def to_sympy(self) -> Any: ...
    @staticmethod
    def from_sympy(expr: Any, *, positive: Optional[Iterable[str]] = None, functions: Optional[Iterable[str]] = None) -> "Expr": ...
    def __add__(self, other: Operand) -> "Expr": ...
    def __radd__(self, other: Operand) -> "Expr": ...
    def __sub__(self, other: Operand) -> "Expr": ...
    def __rsub__(self, other: Operand) -> "Expr": ...
    def __mul__(self, other: Operand) -> "Expr": ...
    def __rmul__(self, other: Operand) -> "Expr": ...
    def __truediv__(self, other: Operand) -> "Expr": ...
    def __rtruediv__(self, other: Operand) -> "Expr": ...
    def __pow__(self, other: Operand) -> "Expr": ...
    def __rpow__(self, other: Operand) -> "Expr": ...
    def __neg__(self) -> "Expr": ...
    def __pos__(self) -> "Expr": ...
    def __eq__(self, other: object) -> bool: ...
    def __hash__(self) -> int: ...

class SymbolNames(list[str]):
    def __call__(self) -> list[str]: ...

class ExprList(list["Expr"]):
    """A list of expressions rendered as LaTeX in Jupyter."""
    def _repr_latex_(self) -> str: ...

class ExprMatrix(list[ExprList]):
    """A matrix of expressions rendered as a LaTeX matrix in Jupyter."""
    def _repr_latex_(self) -> str: ...

class Lambdified:
    """Expressions compiled into a NumPy function: ``f(a, b, …)`` broadcasts its arguments."""

    args: list[str]
    exprs: list[Expr]
    def __call__(self, *values: ArrayLike) -> Union[float, np.ndarray]: ...
    def __reduce__(self) -> tuple[Any, ...]: ...

def lambdify(args: Union[str, Expr, Sequence[Union[str, Expr]]], exprs: Union[str, Expr, Sequence[Union[str, Expr]]]) -> Lambdified:
    """``exprs`` compiled into a NumPy function of ``args`` (SymPy's ``lambdify``); every free symbol must be an argument."""

def series(expr: Union[Expr, str], small: Sequence[Union[str, Expr]], order: int = 2) -> Expr:
    """The series of ``expr`` to order ``order`` (total degree) in the small quantities ``small``."""

def jacobian(map: Sequence[Union[Expr, str]], variables: Sequence[Union[str, Expr]]) -> tuple[list[list[Expr]], Expr]:
    """The Jacobian matrix ``∂x_i/∂y_j`` of a map of coordinates and its determinant, simplified."""

def iterate_map(updates: Sequence[tuple[str, Union[Expr, str]]], variables: Sequence[str], starts: ArrayLike, steps: int, *, params: Optional[Mapping[str, float]] = None) -> np.ndarray:
    """Orbits ``(k, steps + 1, n)`` of an explicit (plain names, assigned in order) or implicit (primed names, solved by Newton's method) map of phase space."""

def parse(text: str, *, positive: Optional[Sequence[str]] = None, functions: Optional[Sequence[str]] = None) -> Expr: ...
def poisson(f: Union[Expr, str], g: Union[Expr, str], coords: Sequence[str], *, params: Optional[Sequence[str]] = None) -> Expr: ...
def cache_info() -> dict[str, Any]:
    """The derivation cache's ``dir`` (``None``: memory only) and this process's ``derived`` and ``hits`` counts."""
def set_cache_dir(path: Union[str, "os.PathLike[str]", None]) -> None:
    """Keeps derivations in ``path`` from now on (``None``: in memory only)."""

class Event:
    """A zero crossing of ``expr`` (in the state variables and ``t``) to detect."""

    expr: Union[Expr, str]
    direction: int
    terminal: bool
    def __init__(self, expr: Union[Expr, str], *, direction: int = 0, terminal: bool = False) -> None: ...

class CompiledRhs:
    """``f(t, y)``: ``y`` of shape ``(n,)`` or ``(n, k)``; a drop-in ``fun=`` for ``solve_ivp``."""

    dim: int
    names: list[str]
    def __call__(self, t: float, y: ArrayLike) -> np.ndarray: ...
    def jac(self, t: float, y: ArrayLike) -> np.ndarray:
        """The exact Jacobian ``(n, n)``: ``solve_ivp(f, ..., method="Radau", jac=f.jac)``."""
    def __reduce__(self) -> tuple[Any, ...]: ...
    def __eq__(self, other: object) -> bool: ...

class DenseSolution:
    """``sol(t)``: the state at ``t`` ``(n,)`` or at an array of times ``(n, m)``, inside ``[t_min, t_max]``."""

    ts: np.ndarray
    t_min: float
    t_max: float
    order: int
    def __call__(self, t: ArrayLike) -> np.ndarray: ...

class Solution:
    """``t`` ``(k,)``, ``y`` ``(n, k)``, events per event function; like ``solve_ivp``'s result."""

    t: np.ndarray
    y: np.ndarray
    names: list[str]
    t_events: Optional[list[np.ndarray]]
    """One array of crossing times per event; ``None`` without events (SciPy's)."""
    y_events: Optional[list[np.ndarray]]
    """One ``(m, n)`` array of crossing states per event; ``None`` without events."""
    status: int
    stop: str
    success: bool
    message: str
    nfev: int
    sol: Optional["DenseSolution"]
    """With ``dense_output=True``: ``sol(t)``, the cubic Hermite interpolant of the steps (error ``O(h⁴)``)."""
    method: str
    steps: int
    rejected: int
    def __getitem__(self, name: str) -> np.ndarray: ...
    def __reduce__(self) -> tuple[Any, ...]: ...
    def __eq__(self, other: object) -> bool: ...
    @staticmethod
    def _restore(state: dict[str, Any]) -> "Solution": ...
    def to_pandas(self) -> Any:
        """A ``pandas.DataFrame`` indexed by ``t``, one column per state name."""
    def to_xarray(self) -> Any:
        """An ``xarray.Dataset`` over ``t``, one variable per state name."""

class EnsembleResult:
    """Final ``t`` ``(k,)`` and ``y`` ``(k, n)``, ``ok`` ``(k,)`` and per-trajectory ``errors``.

    ``(k, n)``, one row per trajectory, not SciPy's ``(n, k)``: SciPy's columns are the times
    of one trajectory; here the axis is the trajectories, stacked as NumPy stacks states."""

    t: np.ndarray
    y: np.ndarray
    ok: np.ndarray
    errors: list[Optional[str]]
    names: list[str]
    def __reduce__(self) -> tuple[Any, ...]: ...
    def __eq__(self, other: object) -> bool: ...
    @staticmethod
    def _restore(state: dict[str, Any]) -> "EnsembleResult": ...
    def to_pandas(self) -> Any:
        """A ``pandas.DataFrame``, one row per trajectory."""
    def to_xarray(self) -> Any:
        """An ``xarray.Dataset`` over ``trajectory``."""

class System:
    """A mechanical system from a Lagrangian or a Hamiltonian, with every derivation."""

    @staticmethod
    def from_lagrangian(
        text: str,
        coords: Sequence[str],
        *,
        params: Optional[Mapping[str, float]] = None,
        positive: Optional[Sequence[str]] = None,
        functions: Optional[Sequence[str]] = None,
        forces: Optional[Mapping[str, str]] = None,
        rayleigh: Optional[str] = None,
        constraints: Optional[Sequence[str]] = None,
        velocity_constraints: Optional[Sequence[str]] = None,
    ) -> "System": ...
    @staticmethod
    def from_hamiltonian(
        text: str,
        coords: Sequence[str],
        *,
        params: Optional[Mapping[str, float]] = None,
        positive: Optional[Sequence[str]] = None,
        functions: Optional[Sequence[str]] = None,
    ) -> "System": ...
    kind: str
    lagrangian: Optional[Expr]
    coordinates: list[str]
    velocities: list[str]
    momenta: list[str]
    parameters: list[str]
    params: dict[str, float]
    source: dict[str, Any]
    def _repr_latex_(self) -> str: ...
    def with_params(self, values: Optional[Mapping[str, float]] = None, **kwargs: float) -> "System": ...
    def with_force(self, coord: str, text: str) -> "System": ...
    def with_rayleigh(self, text: str) -> "System": ...
    def with_constraint(self, text: str) -> "System": ...
    def with_velocity_constraint(self, text: str) -> "System":
        """A copy with a velocity (nonholonomic) constraint linear in the velocities (``"x' = R φ' cos(θ)"``): in ``equations`` with multipliers μ, held by ``integrate``; what would drop it (``hamiltonian``, chaos indicators, Taylor/symplectic methods, ``series``) raises ``MechanicsError``."""
    def euler_lagrange(self) -> ExprList: ...
    def equations(self) -> ExprList: ...
    def mass_matrix(self) -> tuple[ExprMatrix, ExprList]: ...
    def accelerations(self) -> ExprList: ...
    def canonical_momenta(self) -> ExprList: ...
    def legendre(self) -> "System": ...
    def inverse_legendre(self) -> "System": ...
    def hamiltonian(self) -> Expr: ...
    def hamilton(self) -> tuple[ExprList, ExprList]: ...
    def series(self, about: Optional[Sequence[Union[Expr, str, float]]] = None, order: int = 2) -> Expr:
        """L about a point to order ``order`` in the displacements and velocities (L_lin of (2.29) at order 2)."""
    def energy(self) -> Expr: ...
    def report(self, what: str, format: str = "unicode") -> str: ...
    def conserved(self) -> list[tuple[str, Expr, str]]: ...
    def transform(self, mapping: Mapping[str, str], new_coords: Sequence[str]) -> "System": ...
    def gauge(self, lam: str) -> "System": ...
    def constrained_equations(self) -> dict[str, Any]: ...
    def poisson(self, f: Union[Expr, str], g: Union[Expr, str]) -> Expr: ...
    def time_derivative(self, f: Union[Expr, str]) -> Expr: ...
    def is_integral(self, f: Union[Expr, str]) -> tuple[bool, str]: ...
    def canonical_transform(self, generator: Union[Expr, str], kind: str, new_coords: Sequence[str], new_momenta: Sequence[str]) -> dict[str, Any]: ...
    def lie_flow(self, f: Union[Expr, str], order: int) -> Expr: ...
    def lie_series(self, f: Union[Expr, str], g: Union[Expr, str], epsilon: Union[Expr, str], order: int) -> Expr: ...
    def action_frequency(self, energy: float, inside: float) -> dict[str, Any]: ...
    def average(self, trials: Mapping[str, str], phase: str, frequency: str, amplitudes: Sequence[str], *, small: Optional[str] = None, unperturbed: Optional[Union[Expr, str, float]] = None, principal: Optional[str] = None, order: int = 1, sweep: Optional[Sequence[float]] = None) -> dict[str, Any]:
        """⟨L⟩ (and ``grouped``), the relations and J; with ``small``/``unperturbed`` their series to ``order``; with ``sweep`` the relations solved numerically at those amplitudes."""
    def state_names(self, method: Optional[str] = None) -> list[str]: ...
    def compile(self, formulation: Optional[str] = None) -> CompiledRhs: ...
    # Chaos tools (lagrangian/_chaos.py over the library's chaos routines; the scene statements).
    canonical_names: list[str]
    """The canonical state ``(q…, p_q…)``: the layout of a start given as an array."""
    def canonical_start(self, y0: Union[ArrayLike, Mapping[str, float]]) -> np.ndarray: ...
    def indicators(self, t_span: ArrayLike, y0: Union[ArrayLike, Mapping[str, float]], which: str = "megno", *, tol: Optional[float] = None, tangent: Optional[ArrayLike] = None, max_steps: Optional[int] = None) -> Any:
        """Every indicator of one orbit (``Indicators``), with the samples along it."""
    def megno(self, t_span: ArrayLike, y0: Union[ArrayLike, Mapping[str, float]], *, tol: Optional[float] = None, tangent: Optional[ArrayLike] = None) -> float: ...
    def fli(self, t_span: ArrayLike, y0: Union[ArrayLike, Mapping[str, float]], *, tol: Optional[float] = None, tangent: Optional[ArrayLike] = None) -> float: ...
    def lyapunov(self, t_span: ArrayLike, y0: Union[ArrayLike, Mapping[str, float]], *, tol: Optional[float] = None, tangent: Optional[ArrayLike] = None) -> np.ndarray: ...
    def chaos_map(self, t_span: ArrayLike, grid: Mapping[str, ArrayLike], y0: Optional[Mapping[str, float]] = None, which: str = "megno", *, tol: Optional[float] = None, client: Any = None, chunk_size: int = 256, megno_stop: Optional[tuple[float, float]] = None) -> Any:
        """An indicator over a grid of starts, an ``xarray.DataArray``; with a Dask ``client``, in chunks on the cluster (the same values bit for bit)."""
    def flow(self, t_span: ArrayLike, y0: Union[ArrayLike, Mapping[str, float]], *, tol: Optional[float] = None, points: Optional[int] = None, max_steps: Optional[int] = None) -> Any:
        """The flow's Jacobian ``Φ(T)`` with ``det Φ − 1`` and the symplectic defect (``lagrangian._chaos.Flow``), the scene's ``flow``."""
    def poincare(self, t_span: ArrayLike, y0: Union[ArrayLike, Mapping[str, float]], section: Union[Expr, str], method: Optional[str] = None, *, direction: int = 1, **kwargs: Any) -> dict[str, np.ndarray]: ...
    def variational(self, t_span: ArrayLike, x0: ArrayLike, *, tol: Optional[float] = None) -> tuple[np.ndarray, np.ndarray]:
        """The state transition matrix ``Φ(t1)`` ``(2n, 2n)`` of ``(q, p)`` and the state ``x(t1)``."""
    def _indicators(self, t_span: ArrayLike, x0: ArrayLike, which: str, *, tol: Optional[float] = None, tangent: Optional[ArrayLike] = None, max_steps: Optional[int] = None) -> dict[str, Any]: ...
    def _chaos_map(self, t_span: ArrayLike, starts: ArrayLike, which: str, *, tol: Optional[float] = None, megno_stop: Optional[tuple[float, float]] = None) -> Any: ...
    def _flow(self, t_span: ArrayLike, x0: ArrayLike, *, tol: Optional[float] = None, points: Optional[int] = None, max_steps: Optional[int] = None) -> dict[str, Any]: ...
    def integrate(
        self,
        t_span: ArrayLike,
        y0: Union[ArrayLike, Mapping[str, float]],
        method: Optional[str] = None,
        *,
        dt: Optional[float] = None,
        rtol: Optional[float] = None,
        atol: Optional[float] = None,
        tol: Optional[float] = None,
        t_eval: Optional[ArrayLike] = None,
        events: Optional[list[Union[Expr, str, Event]]] = None,
        every: int = 1,
        max_steps: Optional[int] = None,
        compensated: bool = False,
        progress: Optional[bool] = None,
        dense_output: bool = False,
    ) -> Solution: ...
    def ensemble(
        self,
        t_span: ArrayLike,
        y0: ArrayLike,
        method: Optional[str] = None,
        *,
        dt: Optional[float] = None,
        rtol: Optional[float] = None,
        atol: Optional[float] = None,
        tol: Optional[float] = None,
        t_eval: Optional[ArrayLike] = None,
        events: Optional[list[Union[Expr, str, Event]]] = None,
        max_steps: Optional[int] = None,
        compensated: bool = False,
        threads: Optional[int] = None,
        progress: Optional[bool] = None,
    ) -> EnsembleResult:
        """Final states of many starts ``y0`` ``(k, n)`` over ``t_span`` (``t_span`` first, as in ``integrate``); with ``t_eval``, ``y`` is ``(k, n, m)`` at those times."""
