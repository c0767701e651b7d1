"""SymPy + lambdify + SciPy DOP853: the double pendulum's Lagrangian derived by SymPy's
LagrangesMethod, q'' = W^-1 F formed symbolically (LagrangesMethod.rhs), parameters
substituted as numbers, lambdify'd to plain `math` code, integrated by
scipy.integrate.solve_ivp(method="DOP853", rtol=tol, atol=tol) to t = 10.

    python scipy_lambdify.py            # warm: integration alone over the tolerances
    python scipy_lambdify.py --cold TOL # one fresh-process run, text to final state

SciPy raises rtol below 100 eps (2.2e-14) to that floor with a warning; the rows at 1e-14 and
1e-15 therefore run at rtol = 2.2e-14 (atol as given).
"""

import sys
import time
import warnings

T0 = time.perf_counter()

import sympy as sp  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols  # noqa: E402

from common import G, T_END, TOLS, Y0, emit, max_err, repeat  # noqa: E402

warnings.simplefilter("ignore")


def build():
    th1, th2 = dynamicsymbols("th1 th2")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g", positive=True)
    t = dynamicsymbols._t
    w1, w2 = sp.diff(th1, t), sp.diff(th2, t)
    L = (
        (m1 + m2) * l1**2 * w1**2 / 2
        + m2 * l2**2 * w2**2 / 2
        + m2 * l1 * l2 * w1 * w2 * sp.cos(th1 - th2)
        + (m1 + m2) * g * l1 * sp.cos(th1)
        + m2 * g * l2 * sp.cos(th2)
    )
    lm = LagrangesMethod(L, [th1, th2])
    lm.form_lagranges_equations()
    rhs = lm.rhs().subs({m1: 1, m2: 1, l1: 1, l2: 1, g: G})
    a, b, c, d = sp.symbols("a b c d")
    rhs = rhs.subs({w1: c, w2: d}).subs({th1: a, th2: b})
    f = sp.lambdify((a, b, c, d), list(rhs), modules="math")
    return lambda _t, y: f(y[0], y[1], y[2], y[3])


def integrate(f, tol):
    sol = solve_ivp(f, (0.0, T_END), Y0, method="DOP853", rtol=tol, atol=tol)
    assert sol.success, sol.message
    return sol.y[:, -1]


def main():
    if "--cold" in sys.argv:
        tol = float(sys.argv[sys.argv.index("--cold") + 1])
        t1 = time.perf_counter()
        y = integrate(build(), tol)
        print(f'{{"imports_s": {t1 - T0:e}, "derive_integrate_s": {time.perf_counter() - t1:e}, "err": {max_err(y):e}}}')
        return
    f = build()
    for tol in TOLS:
        times, y = repeat(lambda: integrate(f, tol), budget=1.0)
        emit("SciPy DOP853 + SymPy lambdify", "double_pendulum_dop853", "warm", tol, times, max_err(y))


if __name__ == "__main__":
    main()
