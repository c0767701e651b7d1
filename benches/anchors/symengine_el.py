"""SymEngine: the raw Euler-Lagrange expressions d/dt dL/dq' - dL/dq of the planar n-link
pendulum (no simplification), the baseline our `raw_el` row is compared with. SymEngine has no
time derivative of functions, so q, q', q'' are symbols and d/dt is the chain rule
sum_j (q'_j d/dq_j + q''_j d/dq'_j).

    python symengine_el.py [N ...]     (default 2 5 10)
"""

import sys
import time

import symengine as se

from common import emit, n_link_positions, repeat


def derive(n):
    q = se.symbols(" ".join(f"q{i}" for i in range(1, n + 1)))
    v = se.symbols(" ".join(f"v{i}" for i in range(1, n + 1)))
    a = se.symbols(" ".join(f"a{i}" for i in range(1, n + 1)))
    if n == 1:
        q, v, a = [q], [v], [a]
    m = se.symbols(" ".join(f"m{i}" for i in range(1, n + 1)))
    l = se.symbols(" ".join(f"l{i}" for i in range(1, n + 1)))
    if n == 1:
        m, l = [m], [l]
    g = se.Symbol("g")
    xs, ys = n_link_positions(n, se.sin, se.cos, q, l)

    def dt(e):
        return sum(se.diff(e, q[j]) * v[j] + se.diff(e, v[j]) * a[j] for j in range(n))

    xd = [dt(x) for x in xs]
    yd = [dt(y) for y in ys]
    L = sum(m[k] * (xd[k] ** 2 + yd[k] ** 2) / 2 - m[k] * g * ys[k] for k in range(n))
    return [dt(se.diff(L, v[i])) - se.diff(L, q[i]) for i in range(n)]


def main():
    ns = [int(x) for x in sys.argv[1:]] or [2, 5, 10]
    for n in ns:
        t = time.perf_counter()
        derive(n)
        emit("SymEngine", "n_link_raw_el", "cold-first-call", n, [time.perf_counter() - t])
        times, _ = repeat(lambda: derive(n), budget=1.0)
        emit("SymEngine", "n_link_raw_el", "warm", n, times)


if __name__ == "__main__":
    main()
