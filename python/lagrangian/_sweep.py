"""Sweeps over a Dask cluster: a grid of initial states or parameter values is cut into
chunks, each chunk is one Dask task that integrates its rows with the Rust core
(``System.ensemble``), and the final states are gathered into NumPy arrays.

Dask does the scheduling, the retries of failed tasks and the recovery from lost workers;
nothing here schedules. The system travels as its printed source (see ``_pickle``) and is
compiled once per worker process; its derivation (``W q'' = F``, ``H``) comes from the
engine's on-disk derivation cache, so a machine derives it once, whichever process is first
(see ``cache_info``). A trajectory that fails is reported with its
initial condition and the engine's reason; a chunk whose task fails for good (its worker
killed more often than Dask allows, say) has all its rows reported with the task's error; the
rest of the sweep still returns.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np

from ._core import DEFAULT_METHOD, System
from ._errors import ArgumentError


@dataclass
class SweepResult:
    """Final states of a sweep, or its states on a time grid.

    ``y`` has shape ``grid_shape + (n,)`` (state variables in ``names``; the grid's axes
    first, so ``y[i, j]`` is the state at grid point ``(i, j)``, as xarray's dimensions are
    laid out, rather than SciPy's ``(n, k)``, whose columns are times), ``t`` the final
    times (the end of ``t_span``, or a terminal event's time). With ``t_eval`` (``m`` times),
    ``y`` has shape ``grid_shape + (n, m)``, each point's ``(n, m)`` as SciPy's ``solve_ivp``
    gives it (NaN after a terminal event or a failure), and ``t`` is ``t_eval``. ``ok`` whether each point
    integrated, ``errors`` the reason where it did not (``None`` elsewhere). ``axes`` maps each
    swept name to its values when the grid was given as axes. ``failures`` lists the failed
    points as dicts with ``index``, ``values`` (the swept values there) and ``reason``.
    ``method`` and ``t_span`` record the integration asked for.
    """

    y: np.ndarray
    t: np.ndarray
    ok: np.ndarray
    errors: np.ndarray
    names: list[str]
    axes: dict[str, np.ndarray]
    failures: list[dict[str, Any]] = field(default_factory=list)
    method: str = ""
    t_span: tuple[float, float] = (float("nan"), float("nan"))
    t_eval: Optional[np.ndarray] = None

    def __getitem__(self, name: str) -> np.ndarray:
        """Values of the state variable ``name`` over the grid (final, or ``grid_shape + (m,)``
        on the time grid)."""
        i = self.names.index(name)
        return self.y[..., i] if self.t_eval is None else self.y[..., i, :]

    def to_xarray(self) -> Any:
        """An ``xarray.Dataset`` (needs xarray) over one dimension per swept axis, named as
        in the grid with the swept values as coordinates (a grid given as an array of states
        has one dimension, ``point``): the final value of each state variable ``q`` as
        ``q_final`` (a swept initial ``θ`` and the final ``θ_final`` are different things),
        ``t_final`` and ``ok``; a sweep on a time grid has ``q(t)`` over the grid's axes and ``t``
        instead of ``q_final`` and ``t_final``. The attributes record ``method``, ``t0``, ``t1`` and the
        number of ``failed`` points."""
        import xarray as xr  # type: ignore[import-untyped]

        dims = list(self.axes) if self.axes else ["point"]
        coords = {k: v for k, v in self.axes.items()}
        if self.t_eval is None:
            data = {f"{n}_final": (dims, self.y[..., i]) for i, n in enumerate(self.names)}
            data["t_final"] = (dims, self.t)
        else:
            # On a time grid each state variable `q` is `q(t)` over the grid's axes and `t`
            # (a swept initial `θ` is a coordinate of the same name).
            coords["t"] = self.t_eval
            data = {f"{n}(t)": (dims + ["t"], self.y[..., i, :]) for i, n in enumerate(self.names)}
        data["ok"] = (dims, self.ok)
        attrs = {
            "method": self.method,
            "t0": float(self.t_span[0]),
            "t1": float(self.t_span[1]),
            "failed": len(self.failures),
        }
        return xr.Dataset(data, coords=coords, attrs=attrs)


def _run_chunk(
    system: System,
    states: np.ndarray,
    params: Optional[list[dict[str, float]]],
    run: dict[str, Any],
) -> dict[str, Any]:
    """One Dask task: integrates the rows of ``states`` (each with its own parameter values
    when ``params`` is given) and returns their final states (or their states at
    ``run["t_eval"]``) and errors."""
    if params is None:
        r = system.ensemble(y0=states, **run)
        return {"y": r.y, "t": r.t, "errors": r.errors}
    k, n = states.shape
    t_eval = run.get("t_eval")
    ys = np.full((k, n) if t_eval is None else (k, n, len(t_eval)), np.nan)
    ts = np.full(k, np.nan)
    errors: list[Optional[str]] = [None] * k
    for i in range(k):
        try:
            r = system.with_params(params[i]).ensemble(y0=states[i : i + 1], **run)
            ys[i], errors[i] = r.y[0], r.errors[0]
            if t_eval is None:
                ts[i] = r.t[0]
        except Exception as e:  # a bad parameter value fails its own row only
            errors[i] = f"{type(e).__name__}: {e}"
    return {"y": ys, "t": ts, "errors": errors}


def _is_span(x: Any) -> bool:
    """Whether ``x`` is two numbers, as ``t_span`` is."""
    if isinstance(x, (str, bytes, Mapping)):
        return False
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        return False
    return a.shape == (2,)


def sweep(
    system: System,
    t_span: Sequence[float],
    grid: Union[np.ndarray, Mapping[str, Sequence[float]]],
    method: Optional[str] = None,
    *,
    y0: Union[None, Sequence[float], Mapping[str, float]] = None,
    dt: Optional[float] = None,
    tol: Optional[float] = None,
    atol: Optional[float] = None,
    t_eval: Optional[Sequence[float]] = None,
    events: Optional[list[Any]] = None,
    max_steps: Optional[int] = None,
    chunk_size: int = 256,
    client: Any = None,
    retries: int = 2,
    threads: Optional[int] = 1,
) -> SweepResult:
    """Integrates ``system`` over ``t_span`` from every point of ``grid`` on a Dask cluster and
    returns the final states as a :class:`SweepResult` (with ``t_eval``, the states at those
    times, as ``System.ensemble`` gives them). ``t_span`` comes first, as in
    ``System.integrate``, ``System.ensemble`` and SciPy's ``solve_ivp``.

    ``grid`` is either an array of initial states, shape ``(k, n)``, or a dict of axes
    ``{name: values}`` whose outer product is swept: names are state variables (their other
    entries come from ``y0``) or parameters (their other values from the system). ``client``
    is a ``dask.distributed.Client`` (for any cluster: ``Client("tcp://…")``); by default a
    ``LocalCluster`` is started for the call and closed after. Each task integrates
    ``chunk_size`` points with ``threads`` threads (1 by default: Dask runs one task per
    worker thread already); a task that raises is retried ``retries`` times by Dask.
    """
    if not _is_span(t_span):
        if _is_span(grid):
            # The order this function used to take, sweep(system, grid, t_span): refused, never
            # read with the arguments swapped.
            raise ArgumentError(
                "sweep takes t_span first: sweep(system, t_span, grid, …), as System.integrate, "
                "System.ensemble and scipy's solve_ivp do; the arguments look swapped (the second "
                "is not two numbers, the third is)"
            )
        raise ArgumentError(f"t_span must be two numbers (t0, t1): a tuple, a list or an array; got {t_span!r}")
    t_span = (float(t_span[0]), float(t_span[1]))
    # The engine's registry decides the default method and tolerance.
    method = method or DEFAULT_METHOD
    names = system.state_names(method)
    n = len(names)
    params_list = set(system.parameters)
    axes: dict[str, np.ndarray] = {}
    if isinstance(grid, Mapping):
        if not grid:
            raise ArgumentError("the grid has no axes")
        for k, v in grid.items():
            if k not in names and k not in params_list:
                raise ArgumentError(
                    f"`{k}` is neither a state variable ({', '.join(names)}) nor a parameter "
                    f"({', '.join(sorted(params_list)) or 'none'})"
                )
            a = np.asarray(v, dtype=float).ravel()
            if a.size == 0:
                raise ArgumentError(f"the axis `{k}` is empty")
            axes[k] = a
        shape = tuple(a.size for a in axes.values())
        base = _base_state(y0, names, required=[x for x in names if x not in axes])
        points = list(itertools.product(*axes.values()))
        states = np.tile(base, (len(points), 1))
        param_rows: Optional[list[dict[str, float]]] = None
        pnames = [k for k in axes if k not in names]
        if pnames:
            param_rows = []
        for j, vals in enumerate(points):
            row = dict(zip(axes, vals))
            for k, v in row.items():
                if k in names:
                    states[j, names.index(k)] = v
            if param_rows is not None:
                param_rows.append({k: float(row[k]) for k in pnames})
    else:
        states = np.ascontiguousarray(grid, dtype=float)
        if states.ndim != 2 or states.shape[1] != n:
            raise ArgumentError(f"grid has shape {states.shape}; expected (k, {n}): one state ({', '.join(names)}) per row")
        shape = (states.shape[0],)
        param_rows = None
    if chunk_size < 1:
        raise ArgumentError("chunk_size must be at least 1")
    run = dict(method=method, dt=dt, tol=tol, atol=atol, events=events, max_steps=max_steps, threads=threads, progress=False)
    times = None if t_eval is None else np.asarray(t_eval, dtype=float).ravel()
    if times is not None:
        run["t_eval"] = times
    # Check the request once here (method, dt, events), not once per chunk on the workers.
    if len(states):
        system.ensemble(t_span, states[:0], **run)
    run["t_span"] = t_span

    total = states.shape[0]
    ys = np.full((total, n) if times is None else (total, n, times.size), np.nan)
    ts = np.full(total, np.nan)
    errors = np.empty(total, dtype=object)
    own = client is None
    if own:
        from dask.distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        from dask.distributed import as_completed

        futures = {}
        for start in range(0, total, chunk_size):
            stop = min(start + chunk_size, total)
            pr = param_rows[start:stop] if param_rows is not None else None
            fut = client.submit(_run_chunk, system, states[start:stop], pr, run, retries=retries, pure=False)
            futures[fut] = (start, stop, pr, 0)
        pending = as_completed(list(futures))
        for fut in pending:
            start, stop, pr, resubmitted = futures.pop(fut)
            try:
                r = fut.result()
            except Exception as exc:  # the task raised, or its result was lost with a worker
                if _lost(exc) and resubmitted < retries:
                    # A finished result that died with its worker before it was gathered: Dask
                    # does not recompute a released future, so ask for it again.
                    again = client.submit(_run_chunk, system, states[start:stop], pr, run, retries=retries, pure=False)
                    futures[again] = (start, stop, pr, resubmitted + 1)
                    pending.add(again)
                    continue
                reason = f"the chunk of points {start}..{stop - 1} failed: {type(exc).__name__}: {exc}"
                errors[start:stop] = [reason] * (stop - start)
                continue
            ys[start:stop] = r["y"]
            if times is None:
                ts[start:stop] = r["t"]
            errors[start:stop] = r["errors"]
    finally:
        if own:
            client.close()
            cluster.close()

    ok = np.array([e is None for e in errors], dtype=bool)
    failures = []
    for j in np.flatnonzero(~ok):
        idx = np.unravel_index(j, shape)
        if axes:
            values = {k: float(a[i]) for (k, a), i in zip(axes.items(), idx)}
        else:
            values = dict(zip(names, states[j].tolist()))
        failures.append({"index": tuple(int(i) for i in idx), "values": values, "reason": errors[j]})
    return SweepResult(
        y=ys.reshape(shape + ys.shape[1:]),
        t=ts.reshape(shape) if times is None else times,
        ok=ok.reshape(shape),
        errors=errors.reshape(shape),
        names=names,
        axes=axes,
        failures=failures,
        method=method,
        t_span=(float(t_span[0]), float(t_span[1])),
        t_eval=times,
    )


def _lost(exc: BaseException) -> bool:
    """Whether a task's result was lost (its worker died after computing it) rather than the
    task failing."""
    from distributed.client import FutureCancelledError
    from distributed.comm.core import CommClosedError

    return isinstance(exc, (FutureCancelledError, CommClosedError))


def _base_state(y0: Any, names: list[str], required: list[str]) -> np.ndarray:
    if y0 is None:
        if required:
            raise ArgumentError(f"y0 must give the state variables the grid does not sweep: {', '.join(required)}")
        return np.zeros(len(names))
    if isinstance(y0, Mapping):
        base = np.full(len(names), np.nan)
        for k, v in y0.items():
            if k not in names:
                raise ArgumentError(f"`{k}` is not a state variable ({', '.join(names)})")
            base[names.index(k)] = float(v)
        missing = [x for x in required if np.isnan(base[names.index(x)])]
        if missing:
            raise ArgumentError(f"y0 must give the state variables the grid does not sweep: {', '.join(missing)}")
        return np.nan_to_num(base)
    base = np.asarray(y0, dtype=float).ravel()
    if base.size != len(names):
        raise ArgumentError(f"y0 has {base.size} entries; the state has {len(names)} ({', '.join(names)})")
    return base
