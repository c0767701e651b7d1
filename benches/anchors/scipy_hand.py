"""SciPy DOP853 with a hand-written Python right-hand side (parameters folded as constants, the
`math` module, no arrays inside), the like-for-like Python baseline for the double pendulum.

    python scipy_hand.py            # warm: integration alone over the tolerances
    python scipy_hand.py --cold TOL # one fresh-process run
"""

import math
import sys
import time
import warnings

T0 = time.perf_counter()

from scipy.integrate import solve_ivp  # noqa: E402

from common import G, T_END, TOLS, Y0, emit, max_err, repeat  # noqa: E402

warnings.simplefilter("ignore")


def f(_t, y):
    t1, t2, w1, w2 = y
    s, c = math.sin(t1 - t2), math.cos(t1 - t2)
    f1 = -w2 * w2 * s - 2.0 * G * math.sin(t1)
    f2 = w1 * w1 * s - G * math.sin(t2)
    det = 2.0 - c * c
    return [w1, w2, (f1 - c * f2) / det, (2.0 * f2 - c * f1) / det]


def integrate(tol):
    sol = solve_ivp(f, (0.0, T_END), Y0, method="DOP853", rtol=tol, atol=tol)
    assert sol.success, sol.message
    return sol.y[:, -1]


def main():
    if "--cold" in sys.argv:
        tol = float(sys.argv[sys.argv.index("--cold") + 1])
        t1 = time.perf_counter()
        y = integrate(tol)
        print(f'{{"imports_s": {t1 - T0:e}, "integrate_s": {time.perf_counter() - t1:e}, "err": {max_err(y):e}}}')
        return
    for tol in TOLS:
        times, y = repeat(lambda: integrate(tol), budget=1.0)
        emit("SciPy DOP853, hand-written Python rhs", "double_pendulum_dop853", "warm", tol, times, max_err(y))


if __name__ == "__main__":
    main()
