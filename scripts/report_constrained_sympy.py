"""Independent reference for tests/it/scene/parity.rs (constrained accelerations and multipliers).

SymPy's LagrangesMethod on the two constrained systems the tests print with
`lagrangian el --accelerations --constraint …`:
  1. a disc rolling down an incline, L = 1/2 m y'^2 + 1/4 m R^2 θ'^2 + m g y sin(α), y = R θ;
  2. a damped pendulum in Cartesian coordinates, L = 1/2 m (x'^2 + y'^2) - m g y,
     R = 1/2 b (x'^2 + y'^2), x^2 + y^2 = l^2,
and prints the accelerations and the multiplier (in this engine's sign, L + λ f) in closed form
and at the test's sample point. Run in a throwaway venv:
  python3 -m venv /tmp/v && /tmp/v/bin/pip install sympy && /tmp/v/bin/python scripts/report_constrained_sympy.py
"""
import sympy as sp
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

t = sp.Symbol("t")
m, g, R, alpha, b, l = sp.symbols("m g R alpha b l", positive=True)


def solve(L, qs, constraint, forces=()):
    # SymPy's equations are E − λ ∂f/∂q = 0, the engine's sign (stationary ∫ (L + λ f) dt).
    lm = LagrangesMethod(L, qs, hol_coneqs=[constraint], forcelist=list(forces), frame=None)
    lm.form_lagranges_equations()
    rhs = lm.rhs()
    n = len(qs)
    acc = [sp.simplify(rhs[n + i]) for i in range(n)]
    lam = [sp.simplify(x) for x in rhs[2 * n:]]
    return acc, lam


y, th = dynamicsymbols("y theta")
L1 = sp.Rational(1, 2) * m * y.diff(t) ** 2 + sp.Rational(1, 4) * m * R**2 * th.diff(t) ** 2 + m * g * y * sp.sin(alpha)
acc, lam = solve(L1, [y, th], y - R * th)
print("disc: y'' =", acc[0], " θ'' =", acc[1], " λ(sympy) =", lam)

x, yy = dynamicsymbols("x y")
L2 = sp.Rational(1, 2) * m * (x.diff(t) ** 2 + yy.diff(t) ** 2) - m * g * yy
# Rayleigh R = 1/2 b v^2 as generalized forces -b x', -b y' (LagrangesMethod takes forces on
# coordinates through a frame; here add them to the Lagrange equations by hand instead).
from sympy import Matrix

qd = [x.diff(t), yy.diff(t)]
qdd = [x.diff(t, 2), yy.diff(t, 2)]
lamb = sp.Symbol("lam")
f = x**2 + yy**2 - l**2
E = [sp.diff(sp.diff(L2, v), t) - sp.diff(L2, q) for q, v in zip([x, yy], qd)]
eqs = [E[i] - (-b * qd[i]) - lamb * sp.diff(f, q) for i, q in enumerate([x, yy])]
eqs.append(sp.diff(f, t, 2))
sol = sp.solve(eqs, qdd + [lamb], dict=True)[0]
X, Y, VX, VY = sp.symbols("X Y VX VY")
sub = {x.diff(t): VX, yy.diff(t): VY}
sub2 = {x: X, yy: Y}
point = {X: 0.6, Y: -0.7, VX: 0.3, VY: 0.25, m: 1.3, g: 9.81, b: 0.4, l: 1.0}
for name, e in [("x''", sol[qdd[0]]), ("y''", sol[qdd[1]]), ("λ1", sol[lamb])]:
    e = sp.simplify(e.subs(sub).subs(sub2))
    print(f"pendulum: {name} = {e}  at the sample point: {sp.N(e.subs(point), 17)}")
