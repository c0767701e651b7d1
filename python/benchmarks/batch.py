"""Issue 28's ensemble rows of BENCHMARKS.md, both sides in one run: double-pendulum starts at
rest on an n × n grid of (θ1, θ2) in [−2, 2]², to t = 10, on one thread, at each tolerance.

Ours: `System.ensemble(..., "taylor", threads=1)`, the call a user makes (text → derived →
compiled once before timing → the batch Taylor method). heyoka.py: `taylor_adaptive_batch` at
its `recommended_simd_size()` and, where that is not 8, also at 8 (the lanes of an AVX-512
register, which earlier rows of BENCHMARKS.md used), built once from the same Lagrangian through
`heyoka.lagrangian`, propagating one batch of starts after another. Rounds alternate between the two sides; each
side's time is the process CPU time of a round (`time.process_time`), and the row gives the
median over the rounds. Run through `bash python/benchmarks/run.sh batch.py` (release build);
`BATCH_ROUNDS` sets the rounds (default 5).
"""

from __future__ import annotations

import os
import platform
import statistics
import time

import numpy as np

import heyoka as hy
import lagrangian as lg

from double_pendulum import HEYOKA_L, L_TEXT, PARAMS, T, heyoka_batch

ROWS = [(32, 1e-12), (40, 1e-16), (40, 1e-10), (40, 1e-8), (40, 1e-6)]


def main() -> None:
    rounds = int(os.environ.get("BATCH_ROUNDS", "5"))
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()}")
    print(f"# heyoka {hy.__version__}, recommended SIMD size {hy.recommended_simd_size()}, {rounds} rounds")
    exec(HEYOKA_L, g := {})
    sys_ = lg.System.from_lagrangian(L_TEXT, ["θ1", "θ2"], params=PARAMS, positive=list(PARAMS))
    sizes = sorted({hy.recommended_simd_size(), 8})
    cols = " | ".join(f"heyoka batch {b}" for b in sizes)
    ratios = " | ".join(f"ours ÷ heyoka {b}" for b in sizes)
    print(f"| starts | tol | {cols} | ours | {ratios} | median max-abs difference of final states |")
    print("|---" * (4 + 2 * len(sizes)) + "|")
    for side, tol in ROWS:
        angles = np.linspace(-2.0, 2.0, side)
        starts = np.array([[a, b, 0.0, 0.0] for a in angles for b in angles])

        def ours():
            return sys_.ensemble((0, T), starts, "taylor", tol=tol, threads=1, progress=False).y

        sides = [ours] + [heyoka_batch(g["SYS"], starts, b, tol) for b in sizes]
        for f in sides:
            f()  # compiled and warm before timing
        times = [[] for _ in sides]
        finals = [None for _ in sides]
        for _ in range(rounds):
            for i, f in enumerate(sides):
                t0 = time.process_time()
                finals[i] = f()
                times[i].append(time.process_time() - t0)
        med = [statistics.median(t) for t in times]
        diff = max(np.median(np.max(np.abs(finals[0] - y), axis=1)) for y in finals[1:])
        hy_cols = " | ".join(f"{1e3 * m:.0f} ms" for m in med[1:])
        hy_ratios = " | ".join(f"{med[0] / m:.2f}" for m in med[1:])
        print(f"| {side * side} | {tol:.0e} | {hy_cols} | {1e3 * med[0]:.0f} ms | {hy_ratios} | {diff:.1e} |")
    print(f"# load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
