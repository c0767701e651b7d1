"""SymEngine on the issue-16 large-input targets (run by robust_symengine.sh, same inputs as
benches/robust.rs): least thread CPU time of 3 runs per row."""
import time
from math import comb

import symengine as se


def least(runs, f):
    best = float("inf")
    for _ in range(runs):
        t0 = time.thread_time()
        f()
        best = min(best, time.thread_time() - t0)
    return best


def row(name, t, note=""):
    print(f"symengine/{name:<28} {t:>10.4f} s   {note}")


import sys

x5 = se.Symbol("x5")
if sys.argv[1:] == ["sum"]:
    # Run alone under a cap by robust_symengine.sh: SymEngine's parser is superlinear on wide
    # sums (about N^2.6) and this row may not finish.
    big = " + ".join(f"x{i}" for i in range(100_000))
    row("sum_1e5_parse_diff", least(1, lambda: se.sympify(big).diff(x5)), "(one run)")
    sys.exit(0)

poly = " + ".join(f"{1 + (k * 7 + 3) % 9}*x**{k}" for k in range(401))
row("degree_400_expand", least(3, lambda: se.expand(se.sympify(poly))), "(expand: SymEngine has no simplify)")

expansion = " + ".join(f"{comb(400, k)}*x**{k}" for k in range(401))
binom = f"(x + 1)**400 - ({expansion})"
row("binomial_400_minus_exp", least(3, lambda: se.expand(se.sympify(binom))), "(expand gives 0)")
assert se.expand(se.sympify(binom)) == 0

# 4 000 → 16 000 terms: its parser is about N^2.6, and 10⁵ terms (25 000 → 10⁵) did not
# finish in 5 minutes.
for n in (4_000,):
    a = se.sympify(" + ".join(f"x{i}" for i in range(n)))
    b = se.sympify(" + ".join(f"x{i}" for i in range(4 * n)))
    ta, tb = least(5, lambda: a.diff(x5)), least(5, lambda: b.diff(x5))
    import math
    row(f"diff_sum_{n}_vs_{4*n}", ta, f"{tb:.4f} s   exponent {math.log(tb / ta) / math.log(4):.2f}")
