"""Shared by the anchor scripts: the benchmark problems' data, the timing statistics and the
row format (one JSON object per line, the schema `benches/pipeline.rs --json` writes too).

Every anchor reports the same statistics as our side: the median and the minimum over
repeats in one process ("warm"), and whole fresh processes text to result ("cold", timed by
run.py from outside)."""

import json
import statistics
import sys
import time

# Double pendulum, unit masses and lengths, g = 9.81, released from rest at (2.0, 2.5); the
# state at t = 10 from a 50-digit Taylor integration (shared/reference/double_pendulum.md,
# the same digits as lagrangian::integrate::problems::DoublePendulum::REFERENCE_T10).
Y0 = [2.0, 2.5, 0.0, 0.0]
T_END = 10.0
G = 9.81
REF = [
    -0.75312887429491135322337236831363874419582724673327,
    1.6279330820537040840890643526897016618948841824665,
    -4.0873688513441969336361436527166877795014151532526,
    -8.8697025783875326087224420092458445392757368821853,
]
TOLS = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15]


def max_err(y):
    return max(abs(float(a) - b) for a, b in zip(y, REF))


def repeat(f, budget=0.5, min_reps=3, max_reps=31):
    """Times f() at least min_reps and at most max_reps times, until budget seconds are spent.
    Returns (times, last result)."""
    times, started = [], time.perf_counter()
    while True:
        t = time.perf_counter()
        r = f()
        times.append(time.perf_counter() - t)
        if len(times) >= max_reps or (len(times) >= min_reps and time.perf_counter() - started >= budget):
            return times, r


def emit(tool, case, kind, param, times, err=None):
    print(
        json.dumps(
            {
                "tool": tool,
                "case": case,
                "kind": kind,
                "param": param,
                "median_s": statistics.median(times),
                "min_s": min(times),
                "reps": len(times),
                "err": err,
            }
        ),
        flush=True,
    )


def note(text):
    print(text, file=sys.stderr, flush=True)


def n_link_positions(n, sin, cos, th, l):
    """Bob positions of the planar n-link pendulum, r_k = sum_{i<=k} l_i (sin th_i, -cos th_i):
    the formulation of tests/it/support/n_link.rs."""
    xs, ys = [], []
    x = y = 0
    for k in range(n):
        x = x + l[k] * sin(th[k])
        y = y - l[k] * cos(th[k])
        xs.append(x)
        ys.append(y)
    return xs, ys
