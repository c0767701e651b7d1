"""heyoka's side of the Taylor benchmarks (BENCHMARKS.md, "Taylor method"): the same problems,
tolerances and measures as `cargo bench --bench taylor`. Run by scripts/bench_taylor.sh."""
import math
import os
import struct
import sys
import time

import heyoka as hy
import numpy as np

REF = [-0.75312887429491135322337236831363874419582724673327,
       1.6279330820537040840890643526897016618948841824665,
       -4.0873688513441969336361436527166877795014151532526,
       -8.8697025783875326087224420092458445392757368821853]


def best(reps, f):
    """Minimum CPU time of this thread over `reps` runs (as the Rust side measures: on a
    loaded machine wall time counts other processes' time slices)."""
    t, r = math.inf, None
    for _ in range(reps):
        t0 = time.thread_time()
        r = f()
        t = min(t, time.thread_time() - t0)
    return t, r


def nudged(x, j):
    """`x` moved by `j` units in the last place (as `f64::from_bits(x.to_bits() + j)`)."""
    return struct.unpack("<d", struct.pack("<q", struct.unpack("<q", struct.pack("<d", x))[0] + j))[0]


KEPLER_STARTS = 11


def kepler():
    print("## heyoka: Kepler e = 0.9, 1000 orbits, sampled once per orbit")
    print(f"Time: best of 3 from the pericentre. Error: max relative energy error over the samples, "
          f"median [range] over {KEPLER_STARTS} starts x0 + j ulp (as the Rust bench).")
    x, y, px, py = hy.make_vars("x", "y", "px", "py")
    r3 = (x * x + y * y) ** -1.5
    e = 0.9
    y0 = [1 - e, 0.0, 0.0, math.sqrt((1 + e) / (1 - e))]
    grid = 2 * math.pi * np.arange(0, 1001, dtype=float)

    def energy(s):
        return 0.5 * (s[..., 2] ** 2 + s[..., 3] ** 2) - 1 / np.hypot(s[..., 0], s[..., 1])

    for tol in [1e-15, 1e-14, 1e-13]:
        tc = time.perf_counter()
        ta = hy.taylor_adaptive([(x, px), (y, py), (px, -x * r3), (py, -y * r3)], y0, tol=tol)
        compile_s = time.perf_counter() - tc

        def run(start):
            ta.time = 0.0
            ta.state[:] = start
            return ta.propagate_grid(grid)

        t, res = best(3, lambda: run(y0))
        errs = []
        for j in range(KEPLER_STARTS):
            start = [nudged(y0[0], j)] + y0[1:]
            e0 = energy(np.array(start))
            errs.append(np.max(np.abs((energy(run(start)[-1]) - e0) / e0)))
        errs.sort()
        err = f"{errs[len(errs) // 2]:.2e} [{errs[0]:.1e}, {errs[-1]:.1e}]"
        print(f"| heyoka tol {tol:.0e} (order {ta.order}) | {t*1e3:.1f} ms | {err} | {res[3]} steps | compile {compile_s:.2f} s |")


def double_pendulum():
    print("## heyoka: double pendulum to t = 10 (explicit W⁻¹F, as problems::DoublePendulum)")
    t1, t2, w1, w2 = hy.make_vars("t1", "t2", "w1", "w2")
    g = 9.81
    s, c = hy.sin(t1 - t2), hy.cos(t1 - t2)
    a, b, d = 2.0, c, 1.0
    f1 = -w2 * w2 * s - 2.0 * g * hy.sin(t1)
    f2 = w1 * w1 * s - g * hy.sin(t2)
    det = a * d - b * b
    eqs = [(t1, w1), (t2, w2), (w1, (d * f1 - b * f2) / det), (w2, (a * f2 - b * f1) / det)]
    y0 = [2.0, 2.5, 0.0, 0.0]
    for tol in [1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 1e-15, 1e-16]:
        ta = hy.taylor_adaptive(eqs, y0, tol=tol)

        def run():
            ta.time = 0.0
            ta.state[:] = y0
            ta.propagate_until(10.0)
            return ta.state.copy()

        t, st = best(5, run)
        err = max(abs(st[i] - REF[i]) for i in range(4))
        print(f"| heyoka tol {tol:.0e} | {t*1e3:.3f} ms | {err:.1e} |")


def cold_start():
    print("## heyoka: cold start, n-link pendulum (hy.lagrangian → taylor_adaptive → t = 1, tol 1e-12)")
    print("Time to the first trajectory: derive + compile + integrate, CPU time of the process "
          "(LLVM may compile on other threads), wall in brackets. Compact mode for n ≥ 5, as heyoka's "
          "documentation advises for large systems; its default (unrolled) mode for n = 2. The default "
          "mode at n = 10 took 678 s in the 2026-11-25 run and is not repeated (HEYOKA_COLD_UNROLLED_MAX_N "
          "raises the largest n run unrolled).")
    if not hasattr(hy, "lagrangian"):
        print("this heyoka has no hy.lagrangian; skipped")
        return
    # heyoka ≥ 7.10 keeps compiled code in an on-disk cache shared by every run (its "JIT
    # compilation and caching" tutorial): a second run would time a cache lookup, not a cold
    # start. Off for this section, and the in-memory cache cleared before each system.
    if hasattr(hy.llvm_state, "set_diskcache_enabled"):
        hy.llvm_state.set_diskcache_enabled(False)
    max_n = int(os.environ.get("HEYOKA_COLD_MAX_N", "10"))
    unrolled_max = int(os.environ.get("HEYOKA_COLD_UNROLLED_MAX_N", "2"))
    print("| n | mode | derive + compile | integrate | total (CPU) | total (wall) |")
    print("|---|---|---|---|---|---|")
    cases = [(2, False), (5, True), (10, True)] + [(n, False) for n in (5, 10) if n <= unrolled_max]
    for n, compact in [c for c in cases if c[0] <= max_n]:
        hy.llvm_state.clear_memcache()
        w0, c0 = time.perf_counter(), time.process_time()
        th = [hy.make_vars(f"th{i}") for i in range(n)]
        om = [hy.make_vars(f"om{i}") for i in range(n)]
        xs, ys, vx, vy = 0, 0, 0, 0
        T, V = 0, 0
        for k in range(n):
            xs = xs + hy.sin(th[k])
            ys = ys - hy.cos(th[k])
            vx = vx + hy.cos(th[k]) * om[k]
            vy = vy + hy.sin(th[k]) * om[k]
            T = T + 0.5 * (vx * vx + vy * vy)
            V = V + 9.81 * ys
        eqs = hy.lagrangian(T - V, th, om)
        y0 = [0.5 + 0.1 * i for i in range(n)] + [0.0] * n
        ta = hy.taylor_adaptive(eqs, y0, tol=1e-12, compact_mode=compact)
        c1 = time.process_time()
        ta.propagate_until(1.0)
        w2, c2 = time.perf_counter(), time.process_time()
        mode = "compact" if compact else "default (unrolled)"
        print(f"| {n} | {mode} | {(c1-c0)*1e3:.0f} ms | {(c2-c1)*1e3:.1f} ms | {(c2-c0)*1e3:.0f} ms "
              f"| {(w2-w0)*1e3:.0f} ms |", flush=True)


if __name__ == "__main__":
    print(f"heyoka {hy.__version__}")
    want = sys.argv[1:]
    for name, f in [("kepler", kepler), ("double-pendulum", double_pendulum), ("cold-start", cold_start)]:
        if not want or name in want:
            f()
