"""The outer solar system over 10³ Jupiter orbits, ours against REBOUND's IAS15 in one run:
the same initial conditions (read from examples/outer_solar_system.scene, barycentric), the
same output times, the relative energy error of both computed here by the same formula
(Σ |p|²/2m − G Σ m_i m_j / r_ij), and the CPU time of each (ours: the `lagrangian run` child
process; REBOUND: this process around `sim.integrate`).

    benches/anchors/solar_system.sh          # makes a throwaway venv with rebound, runs this

Our binary is $LAGRANGIAN (default target/release/lagrangian)."""

import csv
import math
import os
import resource
import subprocess
import sys
import tempfile
import time

import rebound

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
SCENE = os.path.join(ROOT, "examples", "outer_solar_system.scene")
BIN = os.environ.get("LAGRANGIAN", os.path.join(ROOT, "target", "release", "lagrangian"))


def read_scene():
    text = open(SCENE).read()
    line = lambda p: next(l[len(p):] for l in text.splitlines() if l.startswith(p))
    # `G = …, m[0..4] = v0, v1, …`: a family's values go to m0, m1, … in order.
    params, family = {}, []
    for piece in line("parameters ").removesuffix(" positive").split(", "):
        if " = " in piece:
            name, piece = piece.split(" = ")
            if "[" in name:
                base, rng = name.rstrip("]").split("[")
                lo, hi = map(int, rng.split(".."))
                family = [f"{base}{k}" for k in range(lo, hi + 1)]
            else:
                family = [name]
        params[family.pop(0)] = float(piece)
    starts_text, rest = line("simulate ").split(" for t in 0..")
    t_end = float(rest.split()[0])
    starts = {}
    for s in starts_text.split(", "):
        k, v = s.split(" = ")
        starts[k] = eval(v, {}, params)  # `m1 * 0.00565429` or a number
    return params, starts, t_end


def energy(G, m, q, p):
    e = sum((p[i][0] ** 2 + p[i][1] ** 2 + p[i][2] ** 2) / (2 * m[i]) for i in range(len(m)))
    for i in range(len(m)):
        for j in range(i + 1, len(m)):
            e -= G * m[i] * m[j] / math.dist(q[i], q[j])
    return e


def main():
    params, starts, t_end = read_scene()
    G = params["G"]
    m = [params[f"m{k}"] for k in range(5)]
    q0 = [[starts[f"{a}{k}"] for a in "xyz"] for k in range(5)]
    p0 = [[starts[f"p_{a}{k}"] for a in "xyz"] for k in range(5)]
    e0 = energy(G, m, q0, p0)

    # Ours: the example scene as a user runs it.
    with tempfile.TemporaryDirectory() as out:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([BIN, "run", SCENE, "--out-dir", out], check=True, capture_output=True,
                       env={**os.environ, "LAGRANGIAN_CACHE_DIR": "off"})
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        ours_cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        rows = list(csv.DictReader(open(os.path.join(out, "outer_solar_system.csv"))))
    ours = [(float(r["t"]), abs((energy(G, m, [[float(r[f"{a}{k}"]) for a in "xyz"] for k in range(5)],
                                          [[float(r[f"p_{a}{k}"]) for a in "xyz"] for k in range(5)]) - e0) / e0))
            for r in rows]

    # REBOUND IAS15 from the same state, sampled at our output times.
    sim = rebound.Simulation()
    sim.G = G
    for k in range(5):
        sim.add(m=m[k], x=q0[k][0], y=q0[k][1], z=q0[k][2],
                vx=p0[k][0] / m[k], vy=p0[k][1] / m[k], vz=p0[k][2] / m[k])
    sim.integrator = "ias15"
    times = [t for t, _ in ours]
    theirs = []
    cpu0 = time.process_time()
    for t in times:
        sim.integrate(t, exact_finish_time=1)
        ps = sim.particles
        q = [[ps[k].x, ps[k].y, ps[k].z] for k in range(5)]
        p = [[m[k] * ps[k].vx, m[k] * ps[k].vy, m[k] * ps[k].vz] for k in range(5)]
        theirs.append((t, abs((energy(G, m, q, p) - e0) / e0)))
    rebound_cpu = time.process_time() - cpu0

    def worst_until(errs, t):
        return max(e for s, e in errs if s <= t)

    print(f"rebound {rebound.__version__}; {len(times)} output times to t = {t_end:.0f} days (10³ Jupiter orbits)")
    print("| run | CPU s | rel. energy error to 10² orbits | to 10³ orbits | growth exponent |")
    print("|---|---|---|---|---|")
    for name, errs, cpu in [("lagrangian, Taylor tol 1e-16 (the example scene)", ours, ours_cpu),
                            ("REBOUND IAS15 (default ε)", theirs, rebound_cpu)]:
        a, b = worst_until(errs, t_end / 10), worst_until(errs, t_end)
        print(f"| {name} | {cpu:.2f} | {a:.2e} | {b:.2e} | {math.log10(b / a):.2f} |")


if __name__ == "__main__":
    sys.exit(main())
