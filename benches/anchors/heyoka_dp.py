"""heyoka (Taylor method, LLVM JIT): the double pendulum from its Lagrangian by
heyoka.lagrangian, integrated to t = 10 at each tolerance. Warm: integration alone (the
integrator built and JIT-compiled once per tolerance, time and state reset before each run);
the build (JIT) time is reported as its own row.

    python heyoka_dp.py            # warm, over the tolerances
    python heyoka_dp.py --cold TOL # one fresh-process run, Lagrangian to final state
"""

import sys
import time

T0 = time.perf_counter()

import heyoka as hy  # noqa: E402
import numpy as np  # noqa: E402

from common import G, T_END, TOLS, Y0, emit, max_err, repeat  # noqa: E402


def system():
    th1, th2, w1, w2 = hy.make_vars("th1", "th2", "w1", "w2")
    L = (
        w1 * w1
        + 0.5 * w2 * w2
        + w1 * w2 * hy.cos(th1 - th2)
        + 2.0 * G * hy.cos(th1)
        + G * hy.cos(th2)
    )
    return hy.lagrangian(L, [th1, th2], [w1, w2])


def build(tol):
    return hy.taylor_adaptive(system(), np.array(Y0), tol=tol)


def integrate(ta):
    ta.time = 0.0
    ta.state[:] = Y0
    ta.propagate_until(T_END)
    return ta.state.copy()


def main():
    if "--cold" in sys.argv:
        tol = float(sys.argv[sys.argv.index("--cold") + 1])
        t1 = time.perf_counter()
        y = integrate(build(tol))
        print(f'{{"imports_s": {t1 - T0:e}, "build_integrate_s": {time.perf_counter() - t1:e}, "err": {max_err(y):e}}}')
        return
    for tol in TOLS:
        t = time.perf_counter()
        ta = build(tol)
        emit("heyoka", "double_pendulum_build_jit", "warm", tol, [time.perf_counter() - t])
        times, y = repeat(lambda: integrate(ta), budget=1.0)
        emit("heyoka", "double_pendulum_dop853", "warm", tol, times, max_err(y))


if __name__ == "__main__":
    main()
