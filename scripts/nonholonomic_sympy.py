"""Reference for the Lagrange–d'Alembert equations of `lagrangian el --velocity-constraint`.

The upright rolling coin on a plane: contact point (x, y), heading θ, rolling angle φ, mass m,
moment of inertia I about a diameter and J about its axis, radius R, and a spring V = k x²/2
on x. Rolling without slipping: x' = R φ' cos θ, y' = R φ' sin θ (nonholonomic).

1. SymPy's KanesMethod (independent speeds θ', φ'; dependent x', y') gives the accelerations.
2. SymPy's LagrangesMethod with nonhol_coneqs gives the same with multipliers.
Both are evaluated at one state, printed for tests/it/mechanics/nonholonomic.rs.
Run: /tmp/venv-python/bin/python scripts/nonholonomic_sympy.py
"""
import sympy as sp
from sympy.physics.mechanics import (KanesMethod, LagrangesMethod, Lagrangian, Particle, Point,
                                     ReferenceFrame, RigidBody, dynamicsymbols, inertia)

x, y, th, ph = dynamicsymbols("x y theta phi")
u1, u2, u3, u4 = dynamicsymbols("u1 u2 u3 u4")
m, I, J, R, k = sp.symbols("m I J R k", positive=True)
N = ReferenceFrame("N")
B = N.orientnew("B", "Axis", [th, N.z])
C = B.orientnew("C", "Axis", [ph, B.y])
O = Point("O")
O.set_vel(N, 0)
P = O.locatenew("P", x * N.x + y * N.y)
P.set_vel(N, u3 * N.x + u4 * N.y)
C.set_ang_vel(N, u1 * N.z + u2 * B.y)
coin = RigidBody("coin", P, C, m, (inertia(C, I, J, I), P))
kd = [th.diff() - u1, ph.diff() - u2, x.diff() - u3, y.diff() - u4]
vc = [u3 - R * u2 * sp.cos(th), u4 - R * u2 * sp.sin(th)]
km = KanesMethod(N, q_ind=[x, y, th, ph], u_ind=[u1, u2], u_dependent=[u3, u4], kd_eqs=kd, velocity_constraints=vc)
fr, frstar = km.kanes_equations([coin], [(P, -k * x * N.x)])
rhs = km.rhs()  # [q', u'] with u = (u1, u2, u3, u4)

vals = {m: 2.0, I: 0.7, J: 1.3, R: 0.5, k: 3.0}
state = {x: 0.4, y: -0.3, th: 0.9, ph: 0.2, u1: 0.8, u2: -1.1}
state[u3] = vals[R] * state[u2] * sp.cos(state[th])
state[u4] = vals[R] * state[u2] * sp.sin(state[th])
num = [sp.N(e.subs(vals).subs(state), 17) for e in rhs]
names = ["x''", "y''", "θ''", "φ''"]
order = {u3: 0, u4: 1, u1: 2, u2: 3}
ud = [num[4 + i] for i in range(4)]
acc = [None] * 4
for j, u in enumerate([u1, u2, u3, u4]):
    acc[order[u]] = ud[j]
print("state: x=0.4 y=-0.3 θ=0.9 φ=0.2 θ'=0.8 φ'=-1.1, x'=R φ' cos θ, y'=R φ' sin θ; m=2 I=0.7 J=1.3 R=0.5 k=3")
for n_, a in zip(names, acc):
    print(f"KanesMethod {n_} = {a}")

# Lagrange–d'Alembert with multipliers, the route the engine prints.
L = m * (x.diff() ** 2 + y.diff() ** 2) / 2 + I * th.diff() ** 2 / 2 + J * ph.diff() ** 2 / 2 - k * x**2 / 2
hol = [x.diff() - R * ph.diff() * sp.cos(th), y.diff() - R * ph.diff() * sp.sin(th)]
lm = LagrangesMethod(L, [x, y, th, ph], nonhol_coneqs=hol)
lm.form_lagranges_equations()
sol = lm.rhs()
qd = {x.diff(): state[u3], y.diff(): state[u4], th.diff(): state[u1], ph.diff(): state[u2]}
sub = {x: state[x], y: state[y], th: state[th], ph: state[ph]}
numl = [sp.N(e.subs(vals).subs(qd).subs(sub), 17) for e in sol]
for n_, a in zip(names, numl[4:8]):
    print(f"LagrangesMethod {n_} = {a}")
print("multipliers (SymPy's sign: E = Σ λ a):", numl[8:])
# Energy T + V is conserved (the constraint forces do no work on the rolling motion).
