"""Derives the splitting/composition coefficients in src/integrate/coefficients.rs to 40 digits.

The order conditions come from the Baker-Campbell-Hausdorff formula evaluated in a truncated
free associative algebra (words over graded generators): a composition is of order p iff the
logarithm of the product of exponentials equals h*(generator sum) up to degree p. Published
values (15 digits) are the starting guesses; Newton's method polishes them to 40 digits, and the
script prints the residuals before and after so the literature values are checked too.

Run: python3 scripts/integrator_coefficients.py   (needs mpmath)
"""
from mpmath import mp, mpf, matrix, lu_solve, cbrt, nstr
import itertools

mp.dps = 50


def mul(x, y, deg, maxdeg):
    out = {}
    for wa, ca in x.items():
        da = sum(deg[g] for g in wa)
        for wb, cb in y.items():
            if da + sum(deg[g] for g in wb) > maxdeg:
                continue
            w = wa + wb
            out[w] = out.get(w, 0) + ca * cb
    return out


def add(x, y, s=1):
    out = dict(x)
    for w, c in y.items():
        out[w] = out.get(w, 0) + s * c
    return out


def exp_(x, deg, maxdeg):
    """exp of an element with no constant term."""
    out = {(): mpf(1)}
    term = {(): mpf(1)}
    for k in range(1, maxdeg + 1):
        term = mul(term, x, deg, maxdeg)
        term = {w: c / k for w, c in term.items()}
        out = add(out, term)
    return out


def log_(x, deg, maxdeg):
    z = dict(x)
    z[()] = z.get((), 0) - 1
    z = {w: c for w, c in z.items() if w != () or c != 0}
    out = {}
    term = {(): mpf(1)}
    for k in range(1, maxdeg + 1):
        term = mul(term, z, deg, maxdeg)
        out = add(out, {w: c * (-1) ** (k + 1) / k for w, c in term.items()})
    return out


# ---- symmetric compositions of a symmetric 2nd-order method (Yoshida 1990) ----
# log S(h) = h Y1 + h^3 Y3 + h^5 Y5 + h^7 Y7 for any symmetric base method S.
DEG = {1: 1, 3: 3, 5: 5, 7: 7}


def composition_log(ws, maxdeg):
    prod = {(): mpf(1)}
    for w in ws:
        x = {(g,): w ** g for g in DEG if DEG[g] <= maxdeg}
        prod = mul(prod, exp_(x, DEG, maxdeg), DEG, maxdeg)
    return log_(prod, DEG, maxdeg)


def yoshida_conditions(free, order):
    """free = (w1..wm); stages wm..w1 w0 w1..wm with w0 = 1 - 2 sum(free)."""
    w0 = 1 - 2 * sum(free)
    ws = list(reversed(free)) + [w0] + list(free)
    lg = composition_log(ws, order - 1)
    # One word per Lie element that can appear (see the Rust docs): Y3, Y5, [Y1,[Y1,Y3]],
    # Y7, [Y1,[Y1,[Y1,[Y1,Y3]]]], [Y1,[Y1,Y5]], [Y3,[Y3,Y1]].
    words = [(3,), (1, 1, 3)] if order == 6 else []
    if order == 6:
        words = [(3,), (5,), (1, 1, 3)]
    if order == 8:
        words = [(3,), (5,), (1, 1, 3), (7,), (1, 1, 1, 1, 3), (1, 1, 5), (1, 3, 3)]
    return [lg.get(w, mpf(0)) for w in words]


def newton(fun, x0, iters=30):
    x = [mpf(v) for v in x0]
    for _ in range(iters):
        f = fun(x)
        n = len(x)
        J = matrix(n, n)
        for j in range(n):
            dx = mpf(10) ** (-25)
            xp = list(x)
            xp[j] += dx
            fp = fun(xp)
            for i in range(n):
                J[i, j] = (fp[i] - f[i]) / dx
        step = lu_solve(J, matrix(f))
        x = [x[i] - step[i] for i in range(n)]
        if max(abs(s) for s in step) < mpf(10) ** (-45):
            break
    return x


def report(name, fun, x0):
    r0 = max(abs(v) for v in fun([mpf(v) for v in x0]))
    x = newton(fun, x0)
    r1 = max(abs(v) for v in fun(x))
    print(f"# {name}: residual of published values {nstr(r0, 3)}, after Newton {nstr(r1, 3)}")
    for i, v in enumerate(x):
        print(f"  x{i + 1} = {nstr(v, 40)}   (published {x0[i]}, diff {nstr(v - mpf(x0[i]), 3)})")
    return x


# Yoshida 4: closed form check.
w1 = 1 / (2 - cbrt(2))
print("# Yoshida 4 closed form w1 =", nstr(w1, 40), " w0 =", nstr(-cbrt(2) * w1, 40))

# Yoshida 1990, Table 1, solution A (6th order, 7 stages).
y6 = report("Yoshida 6 solution A", lambda x: yoshida_conditions(x, 6),
            ["-1.17767998417887", "0.235573213359357", "0.784513610477560"])
print("  w0 =", nstr(1 - 2 * sum(y6), 40))

# Yoshida 1990, Table 2, solution A (8th order, 15 stages): checked, not used.
y8a = report("Yoshida 8 solution A", lambda x: yoshida_conditions(x, 8),
             ["-1.61582374150097", "-2.44699182370524", "-0.716989419708120e-2",
              "2.44002732616735", "0.157739928123617", "1.82020630970714", "1.04242620869991"])
print("  w0 =", nstr(1 - 2 * sum(y8a), 40))

# Yoshida 1990, Table 2, solution D (8th order, 15 stages): the one used.
y8 = report("Yoshida 8 solution D", lambda x: yoshida_conditions(x, 8),
            ["0.102799849391985", "-1.96061023297549", "1.93813913762276", "-0.158240635368243",
             "-1.44485223686048", "0.253693336566229", "0.914844246229740"])
print("  w0 =", nstr(1 - 2 * sum(y8), 40))

# ---- Blanes & Moan 2002, SRKN_6^b (order 4, kick first): B A B A B A B A B A B A B ----
DEGAB = {"A": 1, "B": 1}


def splitting_log(a, b, maxdeg):
    prod = {(): mpf(1)}
    for i in range(len(b)):
        prod = mul(prod, exp_({("B",): b[i]}, DEGAB, maxdeg), DEGAB, maxdeg)
        if i < len(a):
            prod = mul(prod, exp_({("A",): a[i]}, DEGAB, maxdeg), DEGAB, maxdeg)
    return log_(prod, DEGAB, maxdeg)


def bm_full(a1, a2, b1, b2, b3):
    a3 = mpf(1) / 2 - (a1 + a2)
    b4 = 1 - 2 * (b1 + b2 + b3)
    return [a1, a2, a3, a3, a2, a1], [b1, b2, b3, b4, b3, b2, b1]


BM = ["0.245298957184271", "0.604872665711080", "0.0829844064174052", "0.396309801498368",
      "-0.0390563049223486"]


def bm_conditions(x):
    # free a2, b3 (solved); a1, b1, b2 fixed at the published (optimised) values.
    a, b = bm_full(mpf(BM[0]), x[0], mpf(BM[2]), mpf(BM[3]), x[1])
    lg = splitting_log(a, b, 3)
    return [lg.get(("A", "A", "B"), mpf(0)), lg.get(("B", "B", "A"), mpf(0))]


bm = report("Blanes-Moan SRKN6b (a2, b3 solved; a1, b1, b2 as published)", bm_conditions,
            [BM[1], BM[4]])
a, b = bm_full(mpf(BM[0]), bm[0], mpf(BM[2]), mpf(BM[3]), bm[1])
print("  a =", [nstr(v, 40) for v in a[:3]])
print("  b =", [nstr(v, 40) for v in b[:4]])
lg = splitting_log(a, b, 5)
print("  degree-5 residuals (not required for order 4):",
      nstr(max(abs(lg.get(w, 0)) for w in itertools.product("AB", repeat=5)), 3))
