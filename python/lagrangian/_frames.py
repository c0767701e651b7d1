"""pandas and xarray views of the results (pure Python; pandas and xarray are imported only
when asked for, so neither is a dependency of the package).

A :class:`Solution` is a time series: one row (pandas) or one point of the dimension ``t``
(xarray) per kept time, one column or variable per state name. An :class:`EnsembleResult` is one
row or point of the dimension ``trajectory`` per initial state, with its final time ``t``, its
state, ``ok`` and, in pandas, the engine's ``error`` message of a failed trajectory; one asked
for with ``t_eval`` adds the dimension ``t``.
"""

from __future__ import annotations

from typing import Any


def _need(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(f"this view needs {module}: pip install {module}") from e


def solution_to_pandas(self: Any) -> Any:
    """The states as a ``pandas.DataFrame`` indexed by ``t``, one column per state name."""
    pd = _need("pandas")
    index = pd.Index(self.t, name="t")
    return pd.DataFrame({name: self.y[i] for i, name in enumerate(self.names)}, index=index)


def solution_to_xarray(self: Any) -> Any:
    """The states as an ``xarray.Dataset`` over the dimension ``t``, one variable per state
    name; the method, step counts and ``nfev`` as attributes."""
    xr = _need("xarray")
    data = {name: ("t", self.y[i]) for i, name in enumerate(self.names)}
    attrs = {"method": self.method, "steps": self.steps, "rejected": self.rejected, "nfev": self.nfev, "status": self.status}
    return xr.Dataset(data, coords={"t": self.t}, attrs=attrs)


def ensemble_to_pandas(self: Any) -> Any:
    """One row per trajectory: its final ``t``, final state, ``ok`` and ``error`` (``None``
    where it succeeded). With ``t_eval`` (``y`` of shape ``(k, n, m)``): one row per trajectory
    and time, indexed by ``(trajectory, t)``."""
    pd = _need("pandas")
    if self.y.ndim == 3:
        k, _, m = self.y.shape
        index = pd.MultiIndex.from_product([range(k), self.t], names=["trajectory", "t"])
        cols = {name: self.y[:, i, :].reshape(k * m) for i, name in enumerate(self.names)}
        cols["ok"] = [bool(o) for o in self.ok for _ in range(m)]
        return pd.DataFrame(cols, index=index)
    cols: dict[str, Any] = {"t": self.t}
    cols.update({name: self.y[:, i] for i, name in enumerate(self.names)})
    cols["ok"] = self.ok
    cols["error"] = list(self.errors)
    return pd.DataFrame(cols, index=pd.RangeIndex(len(self.t), name="trajectory"))


def ensemble_to_xarray(self: Any) -> Any:
    """An ``xarray.Dataset`` over the dimension ``trajectory``: the final ``t``, one variable
    per state name and ``ok`` (the messages of failed trajectories stay in ``errors``). With
    ``t_eval``: each state over the dimensions ``(trajectory, t)``."""
    xr = _need("xarray")
    if self.y.ndim == 3:
        data3: dict[str, Any] = {name: (("trajectory", "t"), self.y[:, i, :]) for i, name in enumerate(self.names)}
        data3["ok"] = ("trajectory", self.ok)
        return xr.Dataset(data3, coords={"trajectory": range(self.y.shape[0]), "t": self.t})
    data: dict[str, Any] = {"t": ("trajectory", self.t)}
    data.update({name: ("trajectory", self.y[:, i]) for i, name in enumerate(self.names)})
    data["ok"] = ("trajectory", self.ok)
    return xr.Dataset(data, coords={"trajectory": range(len(self.t))})
