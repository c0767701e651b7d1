"""Jupyter display of what derivations return, and ``Expr.free_symbols``.

A list of :class:`Expr` (``euler_lagrange()``, ``accelerations()``) is an :class:`ExprList` and a
matrix (``mass_matrix()[0]``) an :class:`ExprMatrix`: plain Python lists (indexing, ``len``,
iteration, equality with lists unchanged) that Jupyter renders in LaTeX, as it renders one
``Expr``, instead of a row of ``Expr("…")`` reprs.
"""

from __future__ import annotations

from typing import Any


def _latex(e: Any) -> str:
    return e.latex() if hasattr(e, "latex") else str(e)


class ExprList(list):
    """A list of expressions that renders as LaTeX in Jupyter (one per line)."""

    def _repr_latex_(self) -> str:
        if not self:
            return r"$\displaystyle \left[\,\right]$"
        rows = r" \\ ".join(_latex(e) for e in self)
        return r"$\displaystyle \left[\begin{array}{l} " + rows + r" \end{array}\right]$"


class ExprMatrix(list):
    """A matrix (list of rows) of expressions that renders as a LaTeX matrix in Jupyter."""

    def __init__(self, rows: Any = ()) -> None:
        super().__init__(ExprList(r) for r in rows)

    def _repr_latex_(self) -> str:
        rows = r" \\ ".join(" & ".join(_latex(e) for e in row) for row in self)
        return r"$\displaystyle \begin{bmatrix} " + rows + r" \end{bmatrix}$"


class SymbolNames(list):
    """The sorted names of an expression's free symbols (``t`` included when present).

    ``free_symbols`` is a property, as SymPy's is; it used to be a method, so calling it,
    ``e.free_symbols()``, still returns the same list."""

    def __call__(self) -> list[str]:
        return list(self)


def free_symbols(self: Any) -> SymbolNames:
    """The sorted names of the free symbols (``t`` included when present)."""
    return SymbolNames(self._free_symbols())


def wrap(display: type, method: Any) -> Any:
    """``method`` returning its result as ``display`` (a list type); a tuple result (``W, F``
    of ``mass_matrix``, ``q', p'`` of ``hamilton``) has each part wrapped."""
    import functools

    @functools.wraps(method)
    def wrapped(self: Any, *args: Any, **kwargs: Any) -> Any:
        return display(method(self, *args, **kwargs))

    return wrapped


def install(Expr: Any, System: Any, lambdify: Any) -> None:
    """Attaches the displays and ``free_symbols`` to the native classes."""
    Expr.free_symbols = property(free_symbols, doc=free_symbols.__doc__)
    Expr.lambdify = lambda self, args: lambdify(args, self)
    Expr.lambdify.__doc__ = "``lambdify(args, self)``: this expression as a NumPy function of ``args``."
    for name in ("euler_lagrange", "equations", "accelerations", "canonical_momenta"):
        setattr(System, name, wrap(ExprList, getattr(System, name)))
    mass = System.mass_matrix

    def mass_matrix(self: Any) -> Any:
        w, f = mass(self)
        return ExprMatrix(w), ExprList(f)

    mass_matrix.__doc__ = mass.__doc__
    System.mass_matrix = mass_matrix
    ham = System.hamilton

    def hamilton(self: Any) -> Any:
        dq, dp = ham(self)
        return ExprList(dq), ExprList(dp)

    hamilton.__doc__ = ham.__doc__
    System.hamilton = hamilton
