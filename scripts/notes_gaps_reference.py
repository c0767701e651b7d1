"""Independent reference values for the notes-gap tests (tests/it/notes/gaps.rs).

Run with a venv holding sympy and mpmath:
    python3 -m venv /tmp/venv-notes && /tmp/venv-notes/bin/pip install sympy mpmath
    /tmp/venv-notes/bin/python scripts/notes_gaps_reference.py
"""
import sympy as sp
import mpmath as mp

q, p, eps = sp.symbols('q p_q epsilon')


def pb(f, g):
    return sp.diff(f, q) * sp.diff(g, p) - sp.diff(f, p) * sp.diff(g, q)


def lie(f, g, order):
    """exp(eps{.,G}) f summed to a high bracket order, then truncated in eps."""
    total, cur = f, f
    for k in range(1, order + 3):
        cur = pb(cur, g)
        total += eps**k / sp.factorial(k) * cur
    return sp.series(sp.expand(total), eps, 0, order + 1).removeO()


print("# Lie series, f = p^2/2 + eps q^4, G = q^3 p_q")
for order in (1, 2, 3):
    print(order, sp.expand(lie(p**2 / 2 + eps * q**4, q**3 * p, order)))

print("# brachistochrone, y = t + t(1-t)(a + b t), L = sqrt((1 + y'^2)/y), t in 0..1")
mp.mp.dps = 30
t, a, b = sp.symbols('t a b')
y = t + t * (1 - t) * (a + b * t)
L = sp.sqrt((1 + sp.diff(y, t) ** 2) / y)
La, Lb = sp.diff(L, a), sp.diff(L, b)
fL, fa, fb = (sp.lambdify((t, a, b), e, 'mpmath') for e in (L, La, Lb))


def grad(av, bv):
    return [mp.quad(lambda tt: fa(tt, av, bv), [0, 1]), mp.quad(lambda tt: fb(tt, av, bv), [0, 1])]


sol = mp.findroot(lambda av, bv: grad(av, bv), (mp.mpf('0.5'), mp.mpf('0.5')))
av, bv = sol[0], sol[1]
S = mp.quad(lambda tt: fL(tt, av, bv), [0, 1])
print("a =", mp.nstr(av, 20))
print("b =", mp.nstr(bv, 20))
print("S =", mp.nstr(S, 20))
