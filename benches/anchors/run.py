"""Runs our pipeline benchmark and every anchor back to back, then writes the comparison
tables to benches/anchors/RESULTS.md (raw rows in results.jsonl). Started by run.sh with the
throwaway virtual environment's Python; anchors whose packages did not install are skipped
with a note. Run from the repository root.

    python benches/anchors/run.py [--quick] [--skip NAME,...] [--cold-reps N]
"""

import json
import os
import platform
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ANCHORS = {
    # script: (packages it needs, label)
    "scipy_hand.py": (["scipy", "numpy"], "SciPy DOP853, hand-written Python rhs"),
    "scipy_lambdify.py": (["scipy", "sympy"], "SciPy DOP853 + SymPy lambdify"),
    "heyoka_dp.py": (["heyoka", "numpy"], "heyoka"),
    "sympy_lagranges.py": (["sympy"], "SymPy LagrangesMethod"),
    "symengine_el.py": (["symengine"], "SymEngine"),
}
COLD_TOL = 1e-12


def log(text):
    print(text, file=sys.stderr, flush=True)


def available(pkg):
    try:
        __import__(pkg)
        return True
    except Exception:  # noqa: BLE001 - any import failure means "not installed"
        return False


def rows_of(text):
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("{") and '"tool"' in line:
            out.append(json.loads(line))
    return out


def run(cmd, **kw):
    log("$ " + " ".join(cmd))
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw)


def cold_processes(script, reps):
    """Whole fresh processes of an anchor's --cold mode: wall times and the last JSON line."""
    times, last = [], ""
    for _ in range(reps):
        t = time.perf_counter()
        p = run([sys.executable, os.path.join(HERE, script), "--cold", repr(COLD_TOL)], cwd=HERE)
        times.append(time.perf_counter() - t)
        last = p.stdout.strip().splitlines()[-1]
    return times, json.loads(last)


def fmt(s):
    if s is None:
        return "–"
    if s < 1e-3:
        return f"{s * 1e6:.1f} µs"
    if s < 1.0:
        return f"{s * 1e3:.3g} ms"
    return f"{s:.3g} s"


def versions():
    from importlib import metadata

    out = []
    for pkg in ["numpy", "scipy", "sympy", "symengine", "heyoka"]:
        try:
            out.append(f"{pkg} {metadata.version(pkg)}")
        except metadata.PackageNotFoundError:
            out.append(f"{pkg} not installed")
    out.append("Python " + platform.python_version())
    return out


def load_avg():
    try:
        return "/".join(f"{x:.1f}" for x in os.getloadavg())
    except OSError:
        return "?"


def main():
    quick = "--quick" in sys.argv
    skip = set()
    if "--skip" in sys.argv:
        skip = set(sys.argv[sys.argv.index("--skip") + 1].split(","))
    cold_reps = 3 if quick else 5
    if "--cold-reps" in sys.argv:
        cold_reps = int(sys.argv[sys.argv.index("--cold-reps") + 1])
    root = os.path.dirname(os.path.dirname(HERE))
    notes, rows = [], []
    loads = [("start", load_avg())]

    # Ours first, then the anchors, back to back.
    ours = os.path.join(HERE, "ours.jsonl")
    args = ["cargo", "bench", "--bench", "pipeline", "--", "--json", ours] + (["quick"] if quick else [])
    p = run(args, cwd=root)
    pipeline_report = p.stdout
    with open(ours) as f:
        rows += rows_of(f.read())
    os.remove(ours)
    loads.append(("after ours", load_avg()))

    cold = {}
    for script, (pkgs, label) in ANCHORS.items():
        missing = [k for k in pkgs if not available(k)]
        if script.removesuffix(".py") in skip or missing:
            notes.append(f"{label} ({script}) skipped: {'not installed: ' + ', '.join(missing) if missing else 'asked to skip'}.")
            continue
        try:
            extra = ["2", "5"] if quick else ["2", "5", "10"]
            p = run([sys.executable, os.path.join(HERE, script)] + (extra if "lagranges" in script or "symengine" in script else []), cwd=HERE)
            rows += rows_of(p.stdout)
            if "--cold" in open(os.path.join(HERE, script)).read():
                cold[label] = cold_processes(script, cold_reps)
        except subprocess.CalledProcessError as e:
            notes.append(f"{label} ({script}) failed: {e.stderr.strip().splitlines()[-1:]}")
        loads.append((f"after {script}", load_avg()))

    with open(os.path.join(HERE, "results.jsonl"), "w") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")
    write_tables(rows, cold, notes, loads, pipeline_report, quick)


def write_tables(rows, cold, notes, loads, pipeline_report, quick):
    out = []
    w = out.append
    w("# Anchors: the engine against other software, one run\n")
    w(f"Written by `benches/anchors/run.sh`{' (quick mode)' if quick else ''} on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. ")
    w(f"Machine: {platform.machine()}, {os.cpu_count()} cores, {platform.processor() or platform.platform()}; ")
    w("versions: " + ", ".join(versions()) + "; ")
    w("load average (1/5/15 min) at each stage: " + "; ".join(f"{k} {v}" for k, v in loads) + ".\n")
    w("Times are median and minimum over repeats in one process (warm) or over whole fresh processes")
    w("(cold); errors are max-norm errors of the state at t = 10 against the 50-digit reference.\n")
    for n in notes:
        w(f"- note: {n}")
    # Double pendulum curve.
    dp = [r for r in rows if r["case"] == "double_pendulum_dop853" and r["kind"] == "warm"]
    tools = []
    for r in dp:
        if r["tool"] not in tools:
            tools.append(r["tool"])
    w("\n## Double pendulum to t = 10: integration alone, over tolerances\n")
    w("Each cell: median / minimum time, error. DOP853 everywhere except heyoka (Taylor, its own tolerance).\n")
    w("| tol | " + " | ".join(tools) + " |")
    w("|---|" + "---|" * len(tools))
    tols = sorted({r["param"] for r in dp}, reverse=True)
    for tol in tols:
        cells = []
        for tool in tools:
            r = next((x for x in dp if x["tool"] == tool and x["param"] == tol), None)
            cells.append("–" if r is None else f"{fmt(r['median_s'])} / {fmt(r['min_s'])}, {r['err']:.1e}")
        w(f"| {tol:.0e} | " + " | ".join(cells) + " |")
    ours = {r["param"]: r for r in dp if r["tool"] == "lagrangian (engine)"}
    w("\nRatio of median times, other / engine, at the same tolerance (above 1: the engine is faster):\n")
    w("| tol | " + " | ".join(t for t in tools if t != "lagrangian (engine)") + " |")
    w("|---|" + "---|" * (len(tools) - 1))
    for tol in tols:
        if tol not in ours:
            continue
        cells = []
        for tool in tools:
            if tool == "lagrangian (engine)":
                continue
            r = next((x for x in dp if x["tool"] == tool and x["param"] == tol), None)
            cells.append("–" if r is None else f"{r['median_s'] / ours[tol]['median_s']:.3g}")
        w(f"| {tol:.0e} | " + " | ".join(cells) + " |")
    # Equal accuracy: the fastest run of each tool reaching each error level.
    w("\nFastest median time of each tool whose error is at most the target (any tolerance):\n")
    targets = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    w("| tool | " + " | ".join(f"err ≤ {t:.0e}" for t in targets) + " |")
    w("|---|" + "---|" * len(targets))
    for tool in tools:
        cells = []
        for t in targets:
            ok = [x for x in dp if x["tool"] == tool and x["err"] is not None and x["err"] <= t]
            best = min(ok, key=lambda x: x["median_s"], default=None)
            cells.append("–" if best is None else f"{fmt(best['median_s'])} (tol {best['param']:.0e}, {best['err']:.1e})")
        w(f"| {tool} | " + " | ".join(cells) + " |")
    build = [r for r in rows if r["case"] == "double_pendulum_build_jit"]
    if build:
        w("\nheyoka's integrator construction (JIT compilation), per tolerance, not included above: "
          + ", ".join(f"{r['param']:.0e}: {fmt(r['median_s'])}" for r in build) + ".")
    # Cold.
    w(f"\n## Cold start: a fresh process, text (or source) to the state at t = 10, tol {COLD_TOL:.0e}\n")
    w("| tool | process wall median | min | error | inside the last process |")
    w("|---|---|---|---|---|")
    for r in rows:
        if r["case"] == "double_pendulum_dop853" and r["kind"] == "cold-process" and r["param"] == COLD_TOL:
            w(f"| {r['tool']} | {fmt(r['median_s'])} | {fmt(r['min_s'])} | {r['err']:.1e} | see the pipeline report below |")
    for label, (times, inside) in cold.items():
        parts = ", ".join(f"{k} {fmt(v)}" for k, v in inside.items() if k != "err")
        w(f"| {label} | {fmt(statistics.median(times))} | {fmt(min(times))} | {inside.get('err', float('nan')):.1e} | {parts} |")
    # Derivations.
    w("\n## n-link pendulum: W and F from the Lagrangian\n")
    w("`cold-first-call`: the first derivation in a fresh process (after imports / start-up), median")
    w("and minimum over processes (ours) or one process (SymPy, SymEngine); `warm`: repeated in one")
    w("process. Ours is the tidied W, F (`mass_matrix_split`); SymPy's is LagrangesMethod's")
    w("mass matrix and forcing (unsimplified); SymEngine's and our `raw` row are the raw")
    w("Euler–Lagrange expressions.\n")
    w("| tool | what | kind | n | median | min | reps |")
    w("|---|---|---|---|---|---|---|")
    for r in rows:
        if r["case"] in ("n_link_derive_W_F", "n_link_raw_el"):
            what = "W, F" if r["case"] == "n_link_derive_W_F" else "raw EL"
            w(f"| {r['tool']} | {what} | {r['kind']} | {int(r['param'])} | {fmt(r['median_s'])} | {fmt(r['min_s'])} | {r['reps']} |")
    w("\n## Our pipeline benchmark's own report (same run)\n")
    w(pipeline_report.strip())
    text = "\n".join(out) + "\n"
    with open(os.path.join(HERE, "RESULTS.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
