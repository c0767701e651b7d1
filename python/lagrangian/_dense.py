"""``Solution.sol``: the continuous solution of a run made with ``dense_output=True``.

The engine's drive loop does not keep its steps' own interpolants once a run is over (DOP853's
seventh-order dense output, the Taylor series), so this is the cubic Hermite interpolant of the
accepted steps: on each step ``[t_i, t_{i+1}]`` the cubic that matches the states ``y_i``,
``y_{i+1}`` and the derivatives ``f(t_i, y_i)``, ``f(t_{i+1}, y_{i+1})`` (the compiled right-hand
side, evaluated once per step point after the run). Its error between steps is at most
``h⁴/384 · max|y⁗|`` (``O(h⁴)`` in the step ``h``): good for plots and for locating features,
less accurate than the steps themselves for a high-order method with long steps. For values
as accurate as the method's, ask for the times in advance with ``t_eval``, which samples the
method's own dense output during the run.

Called outside ``[t0, t1]`` it raises rather than extrapolate (SciPy's ``OdeSolution``
extrapolates the end steps' polynomials, which can be far off).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ._errors import ArgumentError


class DenseSolution:
    """``sol(t)``: the state at ``t`` (shape ``(n,)``) or at each of the times of an array
    ``t`` (shape ``(n, m)``), as SciPy's ``OdeSolution``. ``ts`` are the step times,
    ``t_min``/``t_max`` the span covered, ``order`` the interpolant's degree (3)."""

    order = 3

    def __init__(self, ts: Any, ys: Any, dys: Any) -> None:
        ts = np.asarray(ts, dtype=float)
        ys = np.asarray(ys, dtype=float)
        dys = np.asarray(dys, dtype=float)
        if ts.ndim != 1 or ys.shape != (ys.shape[0], ts.size) or dys.shape != ys.shape:
            raise ArgumentError(f"inconsistent dense output: t {ts.shape}, y {ys.shape}, dy/dt {dys.shape}")
        if ts.size < 2:
            raise ArgumentError("dense output needs at least two step points")
        self.ts = ts
        self._y = ys
        self._dy = dys
        self._ascending = ts[-1] >= ts[0]
        self.t_min = float(min(ts[0], ts[-1]))
        self.t_max = float(max(ts[0], ts[-1]))

    def __call__(self, t: Any) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        scalar = t.ndim == 0
        tt = np.atleast_1d(t).ravel()
        outside = (tt < self.t_min) | (tt > self.t_max) | ~np.isfinite(tt)
        if outside.any():
            bad = tt[outside][0]
            raise ArgumentError(
                f"sol(t) is defined on [{self.t_min!r}, {self.t_max!r}], the span integrated; t = {bad!r} is "
                "outside it (integrate over a longer span instead of extrapolating)"
            )
        # The step [t_i, t_{i+1}] holding each time (in the direction of integration).
        if self._ascending:
            i = np.searchsorted(self.ts, tt, side="right") - 1
        else:
            i = np.searchsorted(-self.ts, -tt, side="right") - 1
        i = np.clip(i, 0, self.ts.size - 2)
        t0, t1 = self.ts[i], self.ts[i + 1]
        h = t1 - t0
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(h != 0, (tt - t0) / h, 0.0)
        s2, s3 = s * s, s * s * s
        h00 = 2 * s3 - 3 * s2 + 1
        h10 = s3 - 2 * s2 + s
        h01 = -2 * s3 + 3 * s2
        h11 = s3 - s2
        y0, y1 = self._y[:, i], self._y[:, i + 1]
        d0, d1 = self._dy[:, i], self._dy[:, i + 1]
        out = h00 * y0 + (h10 * h) * d0 + h01 * y1 + (h11 * h) * d1
        return out[:, 0] if scalar else out.reshape((self._y.shape[0],) + t.shape)

    def __repr__(self) -> str:
        return f"DenseSolution(cubic Hermite, {self.ts.size - 1} steps on [{self.t_min}, {self.t_max}])"

    def __reduce__(self) -> Any:
        return (DenseSolution, (self.ts, self._y, self._dy))

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, DenseSolution)
            and np.array_equal(self.ts, other.ts)
            and np.array_equal(self._y, other._y)
            and np.array_equal(self._dy, other._dy)
        )
