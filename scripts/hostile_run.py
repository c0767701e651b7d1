#!/usr/bin/env python3
"""The hostile run, repeatable: every reproduction of the 509-case run's sixteen defects
(D1–D15, bounded memory) and nineteen unclear messages (U1–U19), run against a binary under a
time limit and an address-space cap, each classified:

  fine     exit 0 with the expected output, or exit 2 with every expected phrase
  unclear  exit 2 but an expected phrase is missing, or Rust `Debug` text / a 30-digit number
  wrong    exit 0 where a refusal or another answer was expected (silently wrong)
  hang     still running at the time limit
  crash    a signal, a panic, exit 101, or an abort under the memory cap

Usage: python3 scripts/hostile_run.py [BINARY]   (default: target/debug/lagrangian)
Prints one line per case and the counts; exits 1 if any case is not `fine`.
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field

MEMORY_CAP = 1 << 30  # 1 GiB of address space, as the original run
TIME_LIMIT = 60.0

OSC = "coordinates x\nparameters m = 1, k = 1\nL = 1/2 m x'^2 - 1/2 k x^2\n"
PEND = "coordinates θ\nparameters m = 1, l = 1, g = 9.81 positive\nL = 1/2 m l^2 θ'^2 + m g l cos(θ)\n"


@dataclass
class Case:
    name: str
    args: list[str] = field(default_factory=list)
    scene: str | None = None
    stdin: str | None = None
    code: int = 2
    expect: list[str] = field(default_factory=list)  # phrases the output must contain
    check: object = None  # a function of (stdout, stderr, dir) -> bool, for exit-0 answers


def horner(n: int) -> str:
    s = "1"
    for i in range(n, 0, -1):
        s = f"{i} + x ({s})"
    return s


CASES = [
    # D1: geodesic shooting with no budget.
    Case("D1 geodesic singular between the points", ["geodesic", "dx^2/(x-1/2)^2 + dy^2", "--coords", "x,y", "--from", "0,0", "--to", "1,0"],
         expect=["budget", "--max-steps"]),
    # D1b: every state kept.
    Case("D1b every 1 over 10^8 steps", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1e6 with rk4 dt = 0.01 every 1 as r\nexport x from r to r.csv\n",
         expect=["every"]),
    # D2: chaos indicators to 1e9.
    Case("D2 megno to 1e9", scene=PEND + "megno θ = 1, θ' = 0 for t in 0..1e9\n", expect=["max_steps"]),
    Case("D2 chaos_map to 1e7", scene=PEND + "chaos_map megno θ = -1..1, θ' = -1..1 for t in 0..1e7 points 2 to m.csv\n",
         expect=["max_steps"]),
    # D3: look-alike letters.
    Case("D3 Cyrillic х in el", ["el", "1/2 m x'^2 - 1/2 k х^2", "--coords", "x"], expect=["U+0445"]),
    # D4: Horner input.
    Case("D4 400-deep Horner simplify", ["simplify", horner(400)], code=0,
         check=lambda out, err, d: out.strip() != ""),
    # D5: deep el output re-parses (degree 300 keeps it quick).
    Case("D5 degree-300 potential round trip", ["el", "1/2 x'^2 - (" + " + ".join(f"x^{k}" for k in range(1, 301)) + ")", "--coords", "x"], code=0,
         check=lambda out, err, d: out.count("(") < 1000),
    # D6: --set against --positive.
    Case("D6 --set R=-2 --positive R", ["geodesic", "R^2 dθ^2 + R^2 sin(θ)^2 dφ^2", "--coords", "θ,φ", "--from", "1,0", "--to", "2,1.5",
                                         "--set", "R=-2", "--positive", "R"], expect=["positive"]),
    # D7: ritz quadrature on an oscillatory integrand.
    Case("D7 ritz x sin(10^6 t)", ["ritz", "1/2 x'^2 + x sin(1000000 t)", "--coords", "x", "--trial", "a t (1 - t)", "--unknowns", "a",
                                    "--span", "0,1", "--from", "0", "--to", "0"], expect=["quadrature", "not reliable"]),
    # D8: a statement over many piped lines.
    Case("D8 100 000 piped continuation lines", ["repl"], stdin="f = (1\n" + "+ 1\n" * 100_000 + ")\nprint f\n", code=0,
         check=lambda out, err, d: "100001" in out),
    # D10: steps with an adaptive method.
    Case("D10 steps = N with dop853", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1 with dop853 steps = 100 as r\nexport x from r to r.csv\n",
         expect=["steps"]),
    # D11: chaos_map over the whole f64 range.
    Case("D11 chaos_map θ = -1e308..1e308", scene=PEND + "chaos_map megno θ = -1e308..1e308, θ' = -1..1 for t in 0..1 points 2 to m.csv\n",
         expect=["range"]),
    # D12: discretize --step t.
    Case("D12 discretize --step t", ["discretize", "1/2 x'^2", "--coords", "x", "--step", "t"], expect=["step"]),
    # D13: rayleigh named L.
    Case("D13 rayleigh L = …", scene=OSC + "rayleigh L = 1/2 x'^2\n", expect=["rayleigh"]),
    # D14: a plot of an expression NaN everywhere.
    Case("D14 plot of sqrt(-1 - x^2)", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1 as r\nplot sqrt(-1 - x^2) from r to p.svg\n",
         expect=["finite"]),
    # D15: export of an ensemble writes every member.
    Case("D15 export from an ensemble", scene=OSC + "E = 1/2 m x'^2 + 1/2 k x^2\nsimulate for each x in 0..1 step 0.5 on E = 1/2 solve x' > 0 for t in 0..1 as e\nexport x from e to e.csv\n",
         code=0, check=lambda out, err, d: {l.split(",")[0] for l in open(os.path.join(d, "e.csv")).read().splitlines()[1:]} == {"e_1", "e_2", "e_3"}),
    # Errors a program can read.
    Case("JSON error object", ["simplify", "x +", "--format", "json"], expect=['"error"', '"span"']),
    # U1: a fixed-step blow-up.
    Case("U1 rk4 blow-up", scene="coordinates x\nL = 1/2 x'^2 - 1/2 x^4\nsimulate x = 1e3, x' = 0 for t in 0..10 with rk4 dt = 0.1 as r\nexport x from r to r.csv\n",
         expect=["halve `dt`", "1.5687081687771783e149"]),
    # U2: options after the name.
    Case("U2 record after as r", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1 as r record when x = 0\n", expect=["ends the statement"]),
    # U3: an empty side of a map.
    Case("U3 is-canonical Q = , P = q", ["is-canonical", "Q = , P = q", "--coords", "q"], expect=["column 5", "`Q =` has no expression"]),
    # U4: huge and tiny numbers in messages.
    Case("U4 m = 1e-400", scene="coordinates x\nparameters m = 1e-400\nL = 1/2 m x'^2\nsimulate x = 1, x' = 0 for t in 0..1 as r\nexport x from r to r.csv\n",
         expect=["`1e-400` underflows"]),
    Case("U4 tol = 2.5e-400", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1 with dop853 tol = 2.5e-400 as r\nexport x from r to r.csv\n", expect=["`2.5e-400` underflows"]),
    # U5: a plot of a run that does not exist.
    Case("U5 plot from a missing run", scene=OSC + "plot x from nothing to p.svg\n", expect=["no simulation named `nothing`"]),
    # U6: the adaptive step budget.
    Case("U6 oscillator over 0..1e7", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1e7 with dop853 tol = 1e-9 as r\nexport x from r to r.csv\n",
         expect=["max_steps = 3e7"]),
    # U7: megno of a phase-space Lagrangian.
    Case("U7 megno of a first-order L", scene="coordinates x, y\nL = x y' - 1/2 (x^2 + y^2)\nmegno x = 1, y = 0 for t in 0..10\n",
         expect=["first order in its velocities"]),
    # U8: a diagonal metric in five dimensions now works.
    Case("U8 5-D diagonal metric", ["geodesic", "da^2 + db^2 + dc^2 + dd^2 + de^2", "--coords", "a,b,c,d,e"], code=0,
         check=lambda out, err, d: "geodesic_e: e'' = 0" in out),
    Case("U8 5 coupled velocities", ["el", "1/2 (a' + b' + c' + d' + e')^2 + 1/2 (a'^2 + b'^2 + c'^2 + d'^2 + e'^2)", "--coords", "a,b,c,d,e", "--accelerations"],
         expect=["without `--accelerations`", "simulate"]),
    # U9: NaN as --from.
    Case("U9 --from nan", ["geodesic", "dx^2 + dy^2", "--coords", "x,y", "--from", "nan,0", "--to", "1,0"], expect=["nan"]),
    # U10: shooting where a geodesic exists.
    Case("U10 half-plane (0,1) → (100,1)", ["geodesic", "(dx^2 + dy^2)/y^2", "--coords", "x,y", "--from", "0,1", "--to", "100,1"], code=0,
         check=lambda out, err, d: "0.184173975727, 9.208698786363" in out),
    # U12: a GIF on a full disk is in hostile_run_enospc (needs a small tmpfs); here: a read-only target.
    Case("U12 plot into a missing directory", scene=OSC + "simulate x = 1, x' = 0 for t in 0..1 as r\nplot x from r to nodir/p.png\n",
         expect=["nodir"]),
    # U13: control bytes.
    Case("U13 ESC in an expression", ["simplify", "x + \x1b[2J"], expect=["\\u{1b}"]),
    # U14: CR-only line ends.
    Case("U14 CR-only scene", scene="coordinates x\rL = 1/2 x'^2\rsimulate oops\r", expect=["test.scene:3:"]),
    # U15: the piped REPL continues indented lines.
    Case("U15 piped indented continuation", ["repl"], stdin=OSC + "simulate x = 1, x' = 0 for t in 0..7\n    record when x = 0 as r\nexport x from r to r.csv\n",
         code=0, check=lambda out, err, d: "2 events" in out and "unknown statement" not in out),
    # U16: a one-dof ensemble.
    Case("U16 1-dof ensemble", scene=OSC + "E = 1/2 m x'^2 + 1/2 k x^2\nsimulate for each x in 0..1 step 0.5 on E = 1/2 solve x' > 0 for t in 0..1 as e\nexport x from e to e.csv\n",
         code=0, check=lambda out, err, d: os.path.exists(os.path.join(d, "e.csv"))),
    # U17: constraint 1 = 0.
    Case("U17 constraint 1 = 0 (scene)", scene=OSC + "constraint 1 = 0\n", expect=["contradictory"]),
    Case("U17 constraint 1 (command line)", ["el", "1/2 m x'^2", "--coords", "x", "--constraint", "1"], expect=["contradictory"]),
    # U18: numbers close to 1.
    Case("U18 for t in 1.0000001..2 backwards", scene=OSC + "simulate x = 1, x' = 0 for t in 2..1.0000001 as r\nexport x from r to r.csv\n",
         expect=["1.0000001"]),
    # U19: an energy infinite at the start.
    Case("U19 h₀ = inf", scene=OSC + "simulate x = 1e200, x' = 0 for t in 0..1 with rk4 dt = 0.01 as r\nexport x from r to r.csv\n",
         code=0, check=lambda out, err, d: "is inf at the start" in err and "h₀ = 0" not in err),
]

DEBUG_TEXT = re.compile(r"\b(Os \{|Some\(|Custom \{|kind: [A-Z])")
LONG_NUMBER = re.compile(r"\d{30,}")


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


def run(binary: str, case: Case) -> tuple[str, float, str]:
    with tempfile.TemporaryDirectory() as d:
        args = list(case.args)
        if case.scene is not None:
            path = os.path.join(d, "test.scene")
            with open(path, "w", newline="") as f:
                f.write(case.scene)
            args = ["run", path]
        env = dict(os.environ, LAGRANGIAN_CACHE_DIR="off", LAGRANGIAN_HISTORY=os.path.join(d, "history"))
        t0 = time.monotonic()
        try:
            p = subprocess.run([binary, *args], input=(case.stdin or "").encode(), capture_output=True, cwd=d, env=env,
                               timeout=TIME_LIMIT, preexec_fn=limit_memory)
        except subprocess.TimeoutExpired:
            return "hang", TIME_LIMIT, ""
        took = time.monotonic() - t0
        out, err = p.stdout.decode(errors="replace"), p.stderr.decode(errors="replace")
        text = out + err
        if p.returncode < 0 or p.returncode in (101, 134) or "panicked" in text:
            return "crash", took, f"exit {p.returncode}"
        if p.returncode != case.code:
            return ("wrong" if p.returncode == 0 else "unclear"), took, f"exit {p.returncode}: {text.strip()[:160]!r}"
        if DEBUG_TEXT.search(text) or LONG_NUMBER.search(text):
            return "unclear", took, f"Debug text or a long number: {text.strip()[:160]!r}"
        missing = [e for e in case.expect if e not in text]
        if missing:
            return "unclear", took, f"missing {missing}: {text.strip()[:160]!r}"
        if case.check is not None and not case.check(out, err, d):
            return "wrong", took, f"answer: {text.strip()[:160]!r}"
        return "fine", took, ""


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else "target/debug/lagrangian"
    binary = os.path.abspath(binary)
    counts: dict[str, int] = {}
    for case in CASES:
        verdict, took, why = run(binary, case)
        counts[verdict] = counts.get(verdict, 0) + 1
        print(f"{verdict:8} {took:6.2f} s  {case.name}{'  — ' + why if why else ''}")
    total = sum(counts.values())
    print(f"\n{total} cases: " + ", ".join(f"{k} {counts.get(k, 0)}" for k in ["fine", "unclear", "wrong", "hang", "crash"]))
    sys.exit(0 if counts.get("fine", 0) == total else 1)


if __name__ == "__main__":
    main()
