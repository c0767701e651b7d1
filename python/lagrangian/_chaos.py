"""Chaos tools of a :class:`System`: the scene statements ``megno``, ``lyapunov``, ``fli``,
``chaos_map`` and ``plot poincare`` from Python, computed by the same library calls
(``lagrangian::chaos`` on the variational equations of Hamilton's equations, Taylor method,
tolerance 1e-12 by default), plus the state transition matrix (``System.variational``) and
the scene's ``flow`` statement (``System.flow``: ``Φ(T)``, ``det Φ − 1`` and the symplectic
defect, with the lines ``lagrangian flow`` prints). ``chaos_map(..., client=)`` spreads a map
over a Dask cluster; each start is computed alone, so the result is the local one bit for bit.

Starts are given as in the scenes: a dict with the coordinates and either the velocities
(``θ1'``; the momenta are computed from them) or the momenta (``p_θ1``), or an array of the
canonical state ``(q, p)`` (``System.canonical_names``). ``tangent`` sets the first tangent
vector, the direction MEGNO and the FLI measure (default the unit vector along the first
coordinate, the scenes' choice).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np

from ._errors import ArgumentError

Start = Union[Sequence[float], np.ndarray, Mapping[str, float]]


@dataclass
class Indicators:
    """The indicators of one orbit at the end time, and along it (one sample per Taylor step,
    thinned evenly to at most 20 000): ``t``, ``lyapunov_t`` (the finite-time maximal exponent),
    ``log_norm_t`` (``ln ‖w‖``, whose running maximum is the FLI) and ``megno_t`` (``Ȳ(t)``; NaN
    for a spectrum run). ``lyapunov`` has one exponent per tangent vector; ``megno_lyapunov`` is
    the maximal exponent from the least-squares slope of MEGNO's ``Y(t)`` (what the scene's
    ``megno`` prints and REBOUND's ``lyapunov()`` returns: near 0 on a regular orbit, where
    the finite-time exponent decays only like ln t / t; NaN for a spectrum run)."""

    lyapunov: np.ndarray
    fli: float
    megno: float
    megno_lyapunov: float
    steps: int
    t: np.ndarray
    lyapunov_t: np.ndarray
    log_norm_t: np.ndarray
    megno_t: np.ndarray
    names: list[str]

    def to_xarray(self) -> Any:
        """The samples as an ``xarray.Dataset`` over ``t``."""
        import xarray as xr  # type: ignore[import-untyped]

        data = {"lyapunov": ("t", self.lyapunov_t), "log_norm": ("t", self.log_norm_t), "megno": ("t", self.megno_t)}
        return xr.Dataset(data, coords={"t": self.t}, attrs={"fli": self.fli, "steps": self.steps})


@dataclass
class Flow:
    """The flow's Jacobian ``Φ(T) = ∂x(T)/∂x(0)`` of the canonical state and its checks (notes
    §4.6.1), as the scene's ``flow`` statement and ``lagrangian flow`` give them: ``phi``
    ``(2n, 2n)`` (rows and columns in ``names``), the end state ``end``, ``det_minus_one``
    (Liouville: 0 for a Hamiltonian flow; ``e^{−γT} − 1`` for ``x'' = −γx' − ω²x``) and
    ``symplectic_defect`` ``max |ΦᵀJΦ − J|`` (``None`` when forces or dissipation make the flow
    non-Hamiltonian), the checks along the run (``t``, ``det_minus_one_t``,
    ``symplectic_defect_t``), the Taylor ``steps`` and the printed ``lines``."""

    phi: np.ndarray
    end: np.ndarray
    det_minus_one: float
    symplectic_defect: Optional[float]
    steps: int
    t: np.ndarray
    det_minus_one_t: np.ndarray
    symplectic_defect_t: np.ndarray
    lines: list[str]
    names: list[str]

    def __str__(self) -> str:
        return "\n".join(self.lines)


def flow(
    self: Any,
    t_span: Sequence[float],
    y0: Start,
    *,
    tol: Optional[float] = None,
    points: Optional[int] = None,
    max_steps: Optional[int] = None,
) -> Flow:
    """The flow's Jacobian over ``t_span = (0, T)`` from ``y0`` (a dict with the coordinates
    and every velocity or every momentum, or the canonical state ``(q, p)``): the scene's
    ``flow`` statement. Forces and Rayleigh dissipation are part of the flow; constraints are
    refused. ``tol`` defaults to 1e-14; the checks are kept at about ``points`` steps (400)."""
    d = self._flow(t_span, canonical_start(self, y0), tol=tol, points=points, max_steps=max_steps)
    return Flow(**d)


def canonical_names(self: Any) -> list[str]:
    """The canonical state's names, ``(q…, p_q…)``: the layout of a start given as an array."""
    return list(self.coordinates) + list(self.momenta)


def canonical_start(self: Any, y0: Start) -> np.ndarray:
    """The canonical start ``(q, p)`` of ``y0``: an array in that order, or a dict with the
    coordinates and either every velocity or every momentum."""
    names = canonical_names(self)
    if not isinstance(y0, Mapping):
        return np.asarray(y0, dtype=float)
    q = list(self.coordinates)
    unknown = [k for k in y0 if k not in names and k not in self.velocities]
    if unknown:
        raise ArgumentError(
            f"{', '.join(f'`{k}`' for k in unknown)} is not a coordinate, velocity or momentum "
            f"(the start takes {', '.join(q)} and either {', '.join(self.velocities)} or {', '.join(self.momenta)})"
        )
    missing = [c for c in q if c not in y0]
    if missing:
        raise ArgumentError(f"the start needs every coordinate; missing {', '.join(missing)}")
    if all(p in y0 for p in self.momenta):
        return np.array([float(y0[c]) for c in names])
    if all(v in y0 for v in self.velocities):
        if self.kind != "lagrangian":
            raise ArgumentError("a Hamiltonian system's start takes momenta (p_q), not velocities")
        env = {k: float(v) for k, v in y0.items()}
        env.update(self.params)
        env["t"] = 0.0
        p = [m.evaluate(env) for m in self.canonical_momenta()]
        return np.array([float(y0[c]) for c in q] + p)
    raise ArgumentError(
        f"the start needs every velocity ({', '.join(self.velocities)}) or every momentum ({', '.join(self.momenta)})"
    )


def indicators(
    self: Any,
    t_span: Sequence[float],
    y0: Start,
    which: str = "megno",
    *,
    tol: Optional[float] = None,
    tangent: Optional[Sequence[float]] = None,
    max_steps: Optional[int] = None,
) -> Indicators:
    """Every indicator of one orbit over ``t_span = (0, T)``: ``which="megno"`` (or
    ``"fli"``) follows one tangent vector with MEGNO's accumulator, ``"lyapunov"`` follows
    ``2n`` (the spectrum), as the scene statements do."""
    d = self._indicators(t_span, canonical_start(self, y0), which, tol=tol, tangent=tangent, max_steps=max_steps)
    return Indicators(**d)


def megno(self: Any, t_span: Sequence[float], y0: Start, *, tol: Optional[float] = None, tangent: Optional[Sequence[float]] = None) -> float:
    """MEGNO ``⟨Y⟩`` at the end of ``t_span = (0, T)`` (Cincotta & Simó 2000): → 0 for stable
    isochronous motion, → 2 for quasi-periodic motion, ≈ λT/2 for chaotic motion. The scene's
    ``megno`` statement."""
    return indicators(self, t_span, y0, "megno", tol=tol, tangent=tangent).megno


def fli(self: Any, t_span: Sequence[float], y0: Start, *, tol: Optional[float] = None, tangent: Optional[Sequence[float]] = None) -> float:
    """The fast Lyapunov indicator ``sup ln ‖w(t)‖`` over ``t_span = (0, T)`` (Froeschlé, Lega &
    Gonczi 1997). The scene's ``fli`` statement."""
    return indicators(self, t_span, y0, "fli", tol=tol, tangent=tangent).fli


def lyapunov(self: Any, t_span: Sequence[float], y0: Start, *, tol: Optional[float] = None, tangent: Optional[Sequence[float]] = None) -> np.ndarray:
    """The finite-time Lyapunov spectrum at the end of ``t_span = (0, T)``, ``2n`` exponents
    (Benettin's algorithm; they sum to 0 for a Hamiltonian flow). The scene's ``lyapunov``."""
    return indicators(self, t_span, y0, "lyapunov", tol=tol, tangent=tangent).lyapunov


def chaos_map(
    self: Any,
    t_span: Sequence[float],
    grid: Mapping[str, Sequence[float]],
    y0: Optional[Mapping[str, float]] = None,
    which: str = "megno",
    *,
    tol: Optional[float] = None,
    client: Any = None,
    chunk_size: int = 256,
    megno_stop: Optional[tuple[float, float]] = None,
) -> Any:
    """An indicator over a grid of starts, as an ``xarray.DataArray`` with one dimension per
    axis of ``grid`` (``{"θ1": values, "θ2": values}``; names of coordinates, velocities or
    momenta), the swept values as coordinates. ``y0`` gives the other entries of the start.
    Orbits run in parallel; one that fails (escapes, hits a singularity, runs out of the budget)
    is NaN. The scene's ``chaos_map`` (which takes cell centres of ranges).

    With ``client`` (a ``dask.distributed.Client``), the starts are split into chunks of
    ``chunk_size``, each computed by a task on the cluster (the system travels pickled, as its
    source), and the values assembled in order: every start is integrated alone by the same
    code, so the array equals the local one bit for bit.

    ``megno_stop = (above, after)`` (a MEGNO map only; ``above > 2``) stops an orbit at the first
    step ending at ``t ≥ after`` with ``⟨Y⟩ ≥ above``: most of a map's time goes to chaotic orbits
    whose class is already settled. Such a cell's value is ``⟨Y⟩`` at its stop and stands for
    "``⟨Y⟩ ≥ above``", not for a value at the end time; the coordinate ``stopped_at`` (same dims)
    holds its stop time, NaN for cells that ran to the end, which are unchanged bit for bit.
    Whether a stopped orbit could have come back below a threshold by the end is not checked:
    on the double pendulum's 200 × 200 map to t = 100, ``(5, 10)`` keeps exactly the cells with
    ``⟨Y⟩ < 2.5`` at 3.3× less CPU (BENCHMARKS.md)."""
    import xarray as xr  # type: ignore[import-untyped]

    if not grid:
        raise ArgumentError("the grid has no axes")
    if chunk_size < 1:
        raise ArgumentError(f"chunk_size must be at least 1, found {chunk_size}")
    axes = {k: np.asarray(v, dtype=float).ravel() for k, v in grid.items()}
    base = dict(y0 or {})
    starts = []
    for point in itertools.product(*axes.values()):
        start = dict(base)
        start.update(zip(axes, point))
        starts.append(canonical_start(self, start))
    rows = np.array(starts)
    stop = None if megno_stop is None else tuple(float(v) for v in megno_stop)
    if stop is not None and len(stop) != 2:
        raise ArgumentError(f"megno_stop is (above, after), found {megno_stop!r}")
    if client is None:
        result = self._chaos_map(t_span, rows, which, tol=tol, megno_stop=stop)
    else:
        # Checked here once (indicator, span, tolerance, shape, stop), not in every task.
        self._chaos_map(t_span, rows[:0], which, tol=tol, megno_stop=stop)
        futures = [
            client.submit(_chaos_chunk, self, t_span, rows[k : k + chunk_size], which, tol, stop, pure=False)
            for k in range(0, len(rows), chunk_size)
        ]
        parts = client.gather(futures)
        if stop is None:
            result = np.concatenate(parts) if parts else np.empty(0)
        else:
            result = tuple(np.concatenate([p[i] for p in parts]) if parts else np.empty(0) for i in range(2))
    values, stopped = (result, None) if stop is None else result
    shape = tuple(a.size for a in axes.values())
    coords: dict[str, Any] = dict(axes)
    attrs = {"t_end": float(t_span[1]), "tol": float(tol or 1e-12)}
    if stop is not None:
        coords["stopped_at"] = (list(axes), np.asarray(stopped).reshape(shape))
        attrs["megno_stop_above"], attrs["megno_stop_after"] = stop
    return xr.DataArray(np.asarray(values).reshape(shape), dims=list(axes), coords=coords, name=which, attrs=attrs)


def _chaos_chunk(
    system: Any, t_span: Sequence[float], rows: np.ndarray, which: str, tol: Optional[float], stop: Optional[tuple[float, float]] = None
) -> Any:
    """One task of a distributed chaos map: the indicator for each row of ``rows`` (and the stop
    times, with ``stop``)."""
    if stop is None:
        return np.asarray(system._chaos_map(t_span, rows, which, tol=tol))
    values, stopped = system._chaos_map(t_span, rows, which, tol=tol, megno_stop=stop)
    return np.asarray(values), np.asarray(stopped)


def poincare(
    self: Any,
    t_span: Sequence[float],
    y0: Any,
    section: Any,
    method: Optional[str] = None,
    *,
    direction: int = 1,
    **kwargs: Any,
) -> Any:
    """The Poincaré section of one orbit: the states where ``section`` (an expression in the
    state variables, ``"θ1"``) crosses zero in ``direction`` (``+1`` upward, the default;
    ``-1``; ``0`` both), located on the steps' interpolants, as the scenes' ``plot poincare``
    (the crossings of a run's event). Returns a ``pandas.DataFrame``-ready dict: ``t`` ``(m,)``
    and one array per state name; the arguments are those of :meth:`System.integrate`."""
    from ._core import Event

    sol = self.integrate(t_span, y0, method, events=[Event(section, direction=direction)], **kwargs)
    ys = sol.y_events[0]
    out = {"t": sol.t_events[0]}
    out.update({name: ys[:, i] for i, name in enumerate(sol.names)})
    return out


def install(System: Any) -> None:
    """Attaches the chaos tools to ``System``."""
    System.canonical_names = property(canonical_names, doc=canonical_names.__doc__)
    System.canonical_start = canonical_start
    System.indicators = indicators
    System.megno = megno
    System.fli = fli
    System.lyapunov = lyapunov
    System.chaos_map = chaos_map
    System.flow = flow
    System.poincare = poincare
