"""Unpickling. ``Expr`` and ``System`` pickle as their printed source and options (see their
``__reduce__``), and are parsed and derived again here; a ``CompiledRhs`` as its system and
formulation, compiled again here; nothing compiled crosses a process boundary, so a Dask worker
needs only this package. ``Solution`` and ``EnsembleResult`` pickle as their arrays.

Systems are cached per process by their source, so the many chunks of a sweep that a worker
receives derive and compile the system once (the compiled right-hand sides live on the
``System`` object).
"""

from __future__ import annotations

import threading
from typing import Any

from ._core import CompiledRhs, EnsembleResult, Event, Expr, Solution, System

_cache: dict[Any, System] = {}
_lock = threading.Lock()
_CACHE_SIZE = 64


def _expr(text: str, positive: list[str], functions: list[str]) -> Expr:
    return Expr(text, positive=positive, functions=functions)


def _event(expr: object, direction: int, terminal: bool) -> Event:
    return Event(expr, direction=direction, terminal=terminal)


def _solution(state: dict[str, Any]) -> Solution:
    return Solution._restore(state)


def _ensemble_result(state: dict[str, Any]) -> EnsembleResult:
    return EnsembleResult._restore(state)


def _lambdified(args: list[str], exprs: Any) -> Any:
    from ._core import lambdify

    return lambdify(args, exprs)


def _compiled(system: System, formulation: str) -> CompiledRhs:
    return system.compile(formulation)


def _key(source: dict[str, Any]) -> Any:
    def freeze(v: Any) -> Any:
        if isinstance(v, dict):
            return tuple(sorted((k, freeze(x)) for k, x in v.items()))
        if isinstance(v, (list, tuple)):
            return tuple(freeze(x) for x in v)
        return v

    return freeze(source)


def _system(source: dict[str, Any]) -> System:
    key = _key(source)
    with _lock:
        hit = _cache.get(key)
    if hit is not None:
        return hit
    kw = dict(source)
    kind = kw.pop("kind")
    text = kw.pop("text")
    coords = kw.pop("coords")
    if kind == "lagrangian":
        sys = System.from_lagrangian(text, coords, **kw)
    else:
        sys = System.from_hamiltonian(text, coords, **kw)
    with _lock:
        if len(_cache) >= _CACHE_SIZE:
            _cache.pop(next(iter(_cache)))
        _cache[key] = sys
    return sys
