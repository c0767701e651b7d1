"""Conversion to and from SymPy through the engine's plain printed form (SymPy is imported
only when these are called).

The plain form is regular enough to translate token by token: names with primes (``θ'``)
become SymPy symbols of the same name, juxtaposition becomes ``*``, ``^`` becomes ``**``,
built-in functions map to SymPy's, declared functions to ``sympy.Function``. Positive
symbols become ``Symbol(..., positive=True)``.
"""

from __future__ import annotations

import re
from typing import Any, Iterable, Optional

from ._core import BUILTINS, Expr
from ._sympy_input import prepare

# The engine's built-in functions with their SymPy names, plus `sqrt` (a power in the engine)
# and `cot` (the parser's shorthand for cos/sin), which the printed form never contains but a
# user may type.
_BUILTINS = {**dict(BUILTINS), "sqrt": "sqrt", "cot": "cot"}

_TOKEN = re.compile(
    r"\s*(?:(?P<num>\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)"
    r"|(?P<name>[^\W\d]\w*'*)(?P<call>\()?"
    r"|(?P<op>\*\*|[-+*/^(),]))",
    re.UNICODE,
)


def _tokens(text: str) -> list[tuple[str, str]]:
    out = []
    pos = 0
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            raise ValueError(f"cannot convert `{text}` to SymPy: unexpected text at {text[pos:pos + 10]!r}")
        if m.group("num"):
            out.append(("num", m.group("num")))
        elif m.group("name"):
            out.append(("call" if m.group("call") else "name", m.group("name")))
        else:
            out.append(("op", m.group("op")))
        pos = m.end()
    return out


def to_sympy(e: Expr) -> Any:
    """The SymPy expression equal to ``e`` (needs SymPy)."""
    import sympy

    positive = set(e.__reduce__()[1][1])  # the names declared positive
    text = e.plain()
    names: dict[str, Any] = {}
    keys: dict[str, str] = {}
    pieces: list[str] = []
    prev = None
    for kind, tok in _tokens(text):
        operand_start = kind in ("num", "name", "call") or tok == "("
        if prev is not None and operand_start and (prev[0] in ("num", "name") or prev[1] == ")"):
            pieces.append("*")
        if kind == "num":
            pieces.append(f"Rational('{tok}')" if ("." in tok or "e" in tok.lower()) else tok)
        elif kind == "name" and tok == "pi":
            pieces.append("pi")  # the engine's exact constant
        elif kind == "name":
            if tok not in keys:
                keys[tok] = f"_s{len(names)}"
                names[keys[tok]] = sympy.Symbol(tok, positive=True) if tok in positive else sympy.Symbol(tok)
            pieces.append(keys[tok])
        elif kind == "call":
            if tok in _BUILTINS:
                pieces.append(_BUILTINS[tok] + "(")
            elif "'" in tok:
                raise ValueError(f"cannot convert `{text}` to SymPy: the derivative `{tok}(…)` of a declared function")
            else:
                key = f"_f{len(names)}"
                names[key] = sympy.Function(tok)
                pieces.append(key + "(")
        else:
            pieces.append("**" if tok in ("^", "**") else tok)
        prev = (kind, tok) if kind != "call" else ("op", "(")
    ns = {k: getattr(sympy, k) for k in set(_BUILTINS.values())}
    ns["Rational"] = sympy.Rational
    ns["pi"] = sympy.pi
    ns.update(names)
    return sympy.sympify("".join(pieces), locals=ns, rational=True)


def from_sympy(expr: Any, *, positive: Optional[Iterable[str]] = None, functions: Optional[Iterable[str]] = None) -> Expr:
    """The :class:`Expr` equal to the SymPy expression ``expr`` (exact: a SymPy float becomes
    the shortest decimal that reads back as it; ``sympy.pi`` becomes the exact constant ``pi``). ``dynamicsymbols`` coordinates ``q(t)`` and
    their derivatives become ``q``, ``q'``, ``q''`` (a name in ``functions`` stays a function of
    time). Symbols SymPy knows to be positive are declared positive, other undefined SymPy
    functions are declared as functions."""
    import sympy
    from sympy.core.function import AppliedUndef

    expr = prepare(sympy.sympify(expr), functions or ())
    if expr.has(sympy.I, sympy.oo, sympy.zoo, sympy.nan):
        raise ValueError(f"`{expr}` contains I or an infinity, which the engine has no exact form for")
    clash = sorted(s.name for s in expr.free_symbols if s.name in ("pi", "π"))
    if clash:
        # The engine reads the name as the constant π, so the symbol would silently become it.
        raise ValueError(f"`{expr}` has a symbol named `{clash[0]}`, which the engine reads as the constant π; rename it (sympy.pi is the constant)")
    if expr.has(sympy.Derivative):
        raise ValueError(f"`{expr}` contains an unevaluated Derivative; substitute or evaluate it first")
    pos = set(positive or ())
    pos |= {s.name for s in expr.free_symbols if s.is_positive}
    funcs = set(functions or ())
    funcs |= {f.func.__name__ for f in expr.atoms(AppliedUndef)}
    expr = expr.subs(sympy.E, sympy.exp(1))
    text = sympy.sstr(expr, order="none")
    text = text.replace("**", "^")
    for name, sympy_name in BUILTINS:
        if name != sympy_name:
            text = text.replace(sympy_name + "(", name + "(")
    return Expr(text, positive=sorted(pos), functions=sorted(funcs))
