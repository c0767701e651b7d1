"""The Python rows of BENCHMARKS.md, measured in one run (run through
`python/benchmarks/run.sh`, which builds the package with the release profile):

1. text → trajectory for the double pendulum to t = 10: `lagrangian` from the text of L
   (parse, derive, compile, integrate with DOP853) against SymPy (`LagrangesMethod`, solve
   for the accelerations, `lambdify`) + SciPy `solve_ivp(method="DOP853")`, each at the
   loosest tolerance whose final error is at most the target, against a reference from
   `lagrangian`'s compensated DOP853 at tol 1e-14 (checked against SciPy at rtol 1e-13);
2. the cost of one call of the compiled right-hand side from Python (`f(t, y)`), against the
   per-point cost of a large batch call (the Rust evaluation with the Python overhead
   amortised away) and a SymPy-lambdified call;
3. sweep throughput (trajectories per second) on a LocalCluster with 1 and 2 workers;
4. against heyoka.py in the same run (both Taylor methods, LLVM JIT on heyoka's side, Cranelift
   on ours): text → first trajectory in a fresh process; an ensemble of 1600 double-pendulum
   starts on one thread (heyoka's batch mode at its recommended SIMD width); MEGNO ⟨Y⟩ of the
   double pendulum to t = 100 (heyoka has no MEGNO: its user integrates the tangent equations,
   built with `heyoka.diff`, on a dense grid and takes the quadrature, as done here).
"""

from __future__ import annotations

import os
import platform
import statistics
import time

import numpy as np

import lagrangian as lg
from double_pendulum import HEYOKA_L, L_TEXT, PARAMS, T, heyoka_batch

Y0 = [2.0, 2.5, 0.0, 0.0]


def best(f, reps):
    times = []
    out = None
    for _ in range(reps):
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times), out


def ours_pipeline(tol):
    def run():
        s = lg.System.from_lagrangian(L_TEXT, ["θ1", "θ2"], params=PARAMS, positive=list(PARAMS))
        return s.integrate((0, T), Y0, "dop853", tol=tol, t_eval=[T], progress=False).y[:, -1]

    return run


def sympy_derive():
    import sympy as sp
    from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

    q1, q2 = dynamicsymbols("θ1 θ2")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g", positive=True)
    t = sp.Symbol("t")
    u1, u2 = q1.diff(t), q2.diff(t)
    Ls = (
        sp.Rational(1, 2) * (m1 + m2) * l1**2 * u1**2
        + m2 * l1 * l2 * u1 * u2 * sp.cos(q1 - q2)
        + sp.Rational(1, 2) * m2 * l2**2 * u2**2
        + (m1 + m2) * g * l1 * sp.cos(q1)
        + m2 * g * l2 * sp.cos(q2)
    )
    lm = LagrangesMethod(Ls, [q1, q2])
    lm.form_lagranges_equations()
    acc = lm.mass_matrix.LUsolve(lm.forcing)
    a1, a2, b1, b2 = sp.symbols("a1 a2 b1 b2")
    acc = acc.subs({u1: b1, u2: b2}).subs({q1: a1, q2: a2})
    num = {m1: 1.0, m2: 1.0, l1: 1.0, l2: 1.0, g: 9.81}
    f = sp.lambdify([a1, a2, b1, b2], list(acc.subs(num)), "math")

    def rhs(t, y):
        a = f(y[0], y[1], y[2], y[3])
        return [y[2], y[3], a[0], a[1]]

    return rhs


def main():
    from scipy.integrate import solve_ivp

    print(f"# machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()}")
    ref_sys = lg.System.from_lagrangian(L_TEXT, ["θ1", "θ2"], params=PARAMS, positive=list(PARAMS))
    ref = ref_sys.integrate((0, T), Y0, "dop853", tol=1e-14, compensated=True, t_eval=[T], progress=False).y[:, -1]

    t0 = time.perf_counter()
    rhs = sympy_derive()
    sympy_derive_s = time.perf_counter() - t0
    check = solve_ivp(rhs, (0, T), Y0, method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
    print(f"reference check: |ours(1e-14) − SciPy(1e-13)| = {np.max(np.abs(check - ref)):.1e}")

    print("\n## 1. text → trajectory, double pendulum to t = 10")
    print("| target error | SymPy + lambdify + SciPy DOP853 | lagrangian (Python) | speed-up |")
    print("|---|---|---|---|")
    # One level only: the reference agrees with SciPy at rtol 1e-13 to about 5e-5 (chaos), so
    # tighter targets are not resolved by it.
    for target in (1e-3,):
        # SciPy: the loosest rtol = atol (decades) meeting the target.
        for rtol in [10.0**-k for k in range(3, 14)]:
            sp_y = solve_ivp(rhs, (0, T), Y0, method="DOP853", rtol=rtol, atol=rtol).y[:, -1]
            if np.max(np.abs(sp_y - ref)) <= target:
                break
        sp_err = np.max(np.abs(sp_y - ref))
        sp_int, _, _ = best(lambda: solve_ivp(rhs, (0, T), Y0, method="DOP853", rtol=rtol, atol=rtol), 3)
        for tol in [10.0**-k for k in range(3, 15)]:
            y = ours_pipeline(tol)()
            if np.max(np.abs(y - ref)) <= target:
                break
        err = np.max(np.abs(y - ref))
        ours_t, ours_med, _ = best(ours_pipeline(tol), 20)
        sp_total = sympy_derive_s + sp_int
        print(
            f"| ≤ {target:.0e} | {sp_total * 1e3:.0f} ms (derive + lambdify {sympy_derive_s * 1e3:.0f} ms, "
            f"integrate {sp_int * 1e3:.0f} ms at rtol {rtol:.0e}; error {sp_err:.1e}) "
            f"| {ours_t * 1e3:.2f} ms (median {ours_med * 1e3:.2f}; tol {tol:.0e}; error {err:.1e}) "
            f"| {sp_total / ours_t:.0f}× (integration alone: {sp_int / ours_t:.0f}×) |"
        )

    print("\n## 2. one call of the compiled right-hand side")
    f = ref_sys.compile()
    y = np.array(Y0)
    n_calls = 200_000
    t0 = time.perf_counter()
    for _ in range(n_calls):
        f(0.0, y)
    per_call = (time.perf_counter() - t0) / n_calls
    k = 100_000
    Y = np.random.default_rng(1).uniform(-2, 2, size=(4, k))
    batch, _, _ = best(lambda: f(0.0, Y), 10)
    n_sym = 20_000
    t0 = time.perf_counter()
    for _ in range(n_sym):
        rhs(0.0, Y0)
    sym_call = (time.perf_counter() - t0) / n_sym
    t0 = time.perf_counter()
    for _ in range(n_calls):
        f.jac(0.0, y)
    jac_call = (time.perf_counter() - t0) / n_calls
    print("| call | time per evaluation |")
    print("|---|---|")
    print(f"| `f(t, y)` from Python, one state | {per_call * 1e9:.0f} ns |")
    print(f"| `f(t, Y)` from Python, batch of {k} (≈ the Rust evaluation) | {batch / k * 1e9:.1f} ns per point |")
    print(f"| Python overhead of one call | {(per_call - batch / k) * 1e9:.0f} ns |")
    print(f"| SymPy `lambdify` (math module) + list, one state | {sym_call * 1e9:.0f} ns |")
    print(f"| `f.jac(t, y)` from Python, one state (4 × 4) | {jac_call * 1e9:.0f} ns ({jac_call / per_call:.1f}× `f`) |")

    print("\n## 3. sweep throughput (double pendulum to t = 10, DOP853 tol 1e-9, 4096 points)")
    from dask.distributed import Client, LocalCluster

    angles = np.linspace(-2.5, 2.5, 64)
    grid = {"θ1": angles, "θ2": angles}
    print("| workers | trajectories / s | wall |")
    print("|---|---|---|")
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=None) as cluster, Client(cluster) as client:
            lg.sweep(ref_sys, (0, T), {"θ1": angles[:4], "θ2": angles[:4]}, y0=Y0, tol=1e-9, client=client)  # warm up
            t0 = time.perf_counter()
            r = lg.sweep(ref_sys, (0, T), grid, y0=Y0, tol=1e-9, chunk_size=256, client=client)
            wall = time.perf_counter() - t0
            assert r.ok.all()
            print(f"| {workers} | {r.t.size / wall:.0f} | {wall:.2f} s |")
    t0 = time.perf_counter()
    states = np.array([[a, b, 0.0, 0.0] for a in angles for b in angles])
    e = ref_sys.ensemble((0, T), states, tol=1e-9, threads=1)
    wall = time.perf_counter() - t0
    print(f"| (in-process `ensemble`, 1 thread, no Dask) | {e.t.size / wall:.0f} | {wall:.2f} s |")
    heyoka_rows()
    print(f"\n# load after: {os.getloadavg()}")


def cold(code: str, cache_dir: str | None = None) -> float:
    """Runs `code` in a fresh interpreter and returns the seconds it prints: the time after the
    imports (both packages imported before the clock starts), text to the first final state.

    With `cache_dir=None` neither side has a cache: ours runs with its derivation cache off, and
    heyoka with an empty cache directory (heyoka keeps compiled code in an on-disk cache under
    `$XDG_CACHE_HOME/heyoka`, so a second process with the default directory skips LLVM; an
    earlier version of this script measured that by mistake). With a directory, both caches
    live there, so a second call measures a warm start."""
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as fresh:
        where = cache_dir or fresh
        env = dict(os.environ, LAGRANGIAN_CACHE_DIR=cache_dir or "off", XDG_CACHE_HOME=where)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def heyoka_rows():
    try:
        import heyoka as hy
    except ImportError:
        print("\n## 4. heyoka.py: not installed (run.sh installs it)")
        return
    print(f"\n## 4. against heyoka.py {hy.__version__}, same run")
    tol = 1e-10
    ours_code = (
        "import time, lagrangian as lg\nt0 = time.perf_counter()\n"
        f"s = lg.System.from_lagrangian({L_TEXT!r}, ['θ1', 'θ2'], params={PARAMS!r}, positive={list(PARAMS)!r})\n"
        f"s.integrate((0, {T}), {Y0!r}, 'taylor', tol={tol}, t_eval=[{T}], progress=False)\n"
        "print(time.perf_counter() - t0)"
    )
    hy_code = (
        "import time\nimport numpy as np\nimport heyoka\nt0 = time.perf_counter()\n" + HEYOKA_L
        + f"ta = hy.taylor_adaptive(SYS, np.array({Y0!r}), tol={tol})\nta.propagate_until({T})\n"
        "print(time.perf_counter() - t0)"
    )
    import tempfile

    print("| row | heyoka.py | lagrangian (Python) | ratio (ours / heyoka) |")
    print("|---|---|---|---|")
    for label, cached in (("no cache on either side", False), ("second process, both caches warm", True)):
        ours, hy_ = [], []
        for _ in range(3):
            with tempfile.TemporaryDirectory() as d:
                if cached:
                    cold(ours_code, d), cold(hy_code, d)  # fill both caches
                ours.append(cold(ours_code, d if cached else None))
                hy_.append(cold(hy_code, d if cached else None))
        o, h = statistics.median(ours), statistics.median(hy_)
        print(
            f"| text → first trajectory, fresh process, {label}, double pendulum to t = 10, tol 1e-10 "
            f"(median of 3) | {1e3 * h:.1f} ms | {1e3 * o:.1f} ms | {o / h:.2f} |"
        )

    # 1600 starts at rest on a 40 × 40 grid of angles in [−2, 2]², to t = 10, one thread.
    exec(HEYOKA_L, g := {})
    angles = np.linspace(-2.0, 2.0, 40)
    starts = np.array([[a, b, 0.0, 0.0] for a in angles for b in angles])
    sys_ = lg.System.from_lagrangian(L_TEXT, ["θ1", "θ2"], params=PARAMS, positive=list(PARAMS))
    ours_ens = lambda: sys_.ensemble((0, T), starts, "taylor", tol=tol, threads=1, progress=False).y  # noqa: E731
    ours_ens()  # compile once, as heyoka's integrator below is built once
    bs = hy.recommended_simd_size()
    hy_ens = heyoka_batch(g["SYS"], starts, bs, tol)

    ours_t, _, ours_y = best(ours_ens, 3)
    hy_t, _, hy_y = best(hy_ens, 3)
    agree = np.median(np.max(np.abs(ours_y - hy_y), axis=1))
    print(
        f"| ensemble of 1600 starts, tol 1e-10, one thread (heyoka batch size {bs}; best of 3; median "
        f"|ours − heyoka| over starts {agree:.1e}) | {1e3 * hy_t:.0f} ms | {1e3 * ours_t:.0f} ms | {ours_t / hy_t:.2f} |"
    )

    # MEGNO ⟨Y⟩ to t = 100 with the tangent vector (1, 0, 0, 0), as `megno` starts it. The
    # values differ at finite t by the norm of the tangent vector: ours is measured in (q, p)
    # (the Hamiltonian flow), heyoka's here in (q, q') (its Lagrangian form); both tend to the
    # same limit (2 for quasi-periodic motion, λt/2 for chaotic).
    t_end = 100.0
    xs = [v for v, _ in g["SYS"]]
    fs = [f for _, f in g["SYS"]]
    ds = hy.make_vars("d0", "d1", "d2", "d3")
    tangent = [sum((hy.diff(f, x) * d for x, d in zip(xs, ds)), start=hy.expression(0.0)) for f in fs]
    var_sys = list(g["SYS"]) + list(zip(ds, tangent))
    tv = hy.taylor_adaptive(var_sys, np.zeros(8), tol=tol)
    grid = np.linspace(0.0, t_end, 20001)

    def hy_megno(start):
        tv.time = 0.0
        tv.state[:] = list(start) + [1.0, 0.0, 0.0, 0.0]
        out = tv.propagate_grid(grid)[-1]
        x, d = out[:, :4], out[:, 4:]
        # δ̇ from the tangent equations at each grid point, through a compiled function.
        ddot = tangent_fn(np.ascontiguousarray(np.hstack([x, d]).T)).T
        gt = grid * np.sum(ddot * d, axis=1) / np.sum(d * d, axis=1)
        # Y(t) = (2/t) ∫₀ᵗ s g(s) ds, ⟨Y⟩ = (1/T) ∫₀ᵀ Y dt, by the trapezoid rule on the grid.
        w = np.concatenate([[0.0], np.cumsum((gt[1:] + gt[:-1]) / 2 * np.diff(grid))])
        y = np.where(grid > 0, 2 * w / np.where(grid > 0, grid, 1.0), 0.0)
        return np.trapezoid(y, grid) / t_end

    tangent_fn = hy.cfunc(tangent, vars=xs + list(ds))
    rows = []
    for start in ([0.5, 0.5, 0.0, 0.0], [2.0, 2.5, 0.0, 0.0]):
        sys_.megno((0, t_end), start, tol=tol)  # compile once
        o_t, _, o_val = best(lambda: sys_.megno((0, t_end), start, tol=tol), 3)
        h_t, _, h_val = best(lambda: hy_megno(start), 3)
        rows.append((start, o_t, o_val, h_t, h_val))
    for start, o_t, o_val, h_t, h_val in rows:
        print(
            f"| MEGNO ⟨Y⟩ to t = 100 from θ = ({start[0]}, {start[1]}), tol 1e-10 (heyoka: tangent equations on a "
            f"20 001-point grid + trapezoid; best of 3) | {1e3 * h_t:.1f} ms (⟨Y⟩ = {h_val:.3f}) "
            f"| {1e3 * o_t:.1f} ms (⟨Y⟩ = {o_val:.3f}) | {o_t / h_t:.2f} |"
        )


if __name__ == "__main__":
    main()
