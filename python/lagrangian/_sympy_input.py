"""What ``from_sympy`` accepts beyond ``_sympy.py``'s table of functions, prepared before the
expression is printed for the engine (kept apart so that table stays one place):

- what ``sympy.physics.mechanics`` users hold: a coordinate is ``dynamicsymbols("q")``, the
  undefined function ``q(t)``, and its velocity ``Derivative(q(t), t)``; the engine names them
  ``q`` and ``q'`` (``q''`` for the second derivative);
- SymPy floats, which print with 15 significant digits (``Float(1/3)`` as
  ``0.333333333333333``, not the float it holds): each becomes the shortest decimal that
  reads back as the same ``float``, as ``Expr`` arithmetic does with Python floats.
"""

from __future__ import annotations

from typing import Any, Iterable


def coordinates_as_symbols(expr: Any, functions: Iterable[str] = ()) -> Any:
    """``expr`` with every undefined function of ``t`` alone (a ``dynamicsymbols`` coordinate)
    replaced by the symbol of its name, and its time derivatives by the primed names. A name in
    ``functions`` stays a function call (a given function of time such as a forcing ``F(t)``).
    Derivatives of anything else are left for ``from_sympy`` to refuse."""
    import sympy
    from sympy.core.function import AppliedUndef

    t = sympy.Symbol("t")  # sympy.physics.mechanics.dynamicsymbols._t
    keep = set(functions)

    def coordinate(f: Any) -> bool:
        return isinstance(f, AppliedUndef) and f.args == (t,) and f.func.__name__ not in keep

    derivatives = {}
    for d in expr.atoms(sympy.Derivative):
        if coordinate(d.expr) and all(v == t for v, _ in d.variable_count):
            order = sum(int(c) for _, c in d.variable_count)
            derivatives[d] = sympy.Symbol(d.expr.func.__name__ + "'" * order)
    expr = expr.xreplace(derivatives)
    coords = {f: sympy.Symbol(f.func.__name__) for f in expr.atoms(AppliedUndef) if coordinate(f)}
    return expr.xreplace(coords)


def exact_floats(expr: Any) -> Any:
    """``expr`` with each SymPy ``Float`` of double precision (or less) replaced by the rational
    of its shortest round-trip decimal (``repr(float)``), and a wider one by the rational of
    all its printed digits."""
    import sympy

    reps = {}
    for f in expr.atoms(sympy.Float):
        text = repr(float(f)) if f._prec <= 53 else str(f)
        reps[f] = sympy.Rational(text)
    return expr.xreplace(reps)


def prepare(expr: Any, functions: Iterable[str] = ()) -> Any:
    """Both of the above."""
    return exact_floats(coordinates_as_symbols(expr, functions))
