"""The double pendulum both benchmark scripts (`bench.py`, `batch.py`) run: its Lagrangian as our
text and as heyoka's expression, its parameters and end time, and heyoka's batch-mode ensemble."""

from __future__ import annotations

import numpy as np

L_TEXT = (
    "1/2 (m1 + m2) l1^2 θ1'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + 1/2 m2 l2^2 θ2'^2"
    " + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)"
)
PARAMS = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "g": 9.81}
T = 10.0

HEYOKA_L = """
import heyoka as hy
th1, th2, w1, w2 = hy.make_vars("θ1", "θ2", "w1", "w2")
G = 9.81
L = w1 * w1 + 0.5 * w2 * w2 + w1 * w2 * hy.cos(th1 - th2) + 2.0 * G * hy.cos(th1) + G * hy.cos(th2)
SYS = hy.lagrangian(L, [th1, th2], [w1, w2])
"""


def heyoka_batch(system, starts, bs, tol):
    """heyoka's batch mode over `starts` (one per row), `bs` at a time, each batch to `T`: a
    function returning the final states (the integrator is built once, before timing)."""
    import heyoka as hy  # only the rows against heyoka need it
    ta = hy.taylor_adaptive_batch(system, np.zeros((4, bs)), tol=tol)

    def run():
        out = np.empty_like(starts)
        for k in range(0, len(starts), bs):
            ta.set_time(0.0)
            ta.state[:] = starts[k : k + bs].T
            ta.propagate_until(T)
            out[k : k + bs] = ta.state.T
        return out

    return run
