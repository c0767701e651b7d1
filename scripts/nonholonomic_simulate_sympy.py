"""Reference trajectory for simulating velocity constraints (tests/it/simulate/nonholonomic.rs).

The upright rolling coin of scripts/nonholonomic_sympy.py (contact point (x, y), heading θ,
rolling angle φ, mass m, moments I and J, radius R, spring V = k x²/2 on x; rolling without
slipping x' = R φ' cos θ, y' = R φ' sin θ), its equations from SymPy's KanesMethod (independent
speeds θ', φ'), integrated by scipy's solve_ivp (DOP853, rtol = atol = 1e-13) from the state
below to t = 10. Prints the final state and the energy at both ends.
Run: /tmp/venv-python/bin/python scripts/nonholonomic_simulate_sympy.py
"""
import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from sympy.physics.mechanics import (KanesMethod, Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia)

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
km.kanes_equations([coin], [(P, -k * x * N.x)])
vals = {m: 2.0, I: 0.7, J: 1.3, R: 0.5, k: 3.0}
# The state is (x, y, θ, φ, θ', φ'); the dependent speeds follow from the constraints.
rhs = km.rhs().subs(vals)  # [q' (x, y, θ, φ), u' (u1, u2, u3, u4)]
dep = {u3: vals[R] * u2 * sp.cos(th), u4: vals[R] * u2 * sp.sin(th)}
qd = [rhs[i].subs(dep) for i in range(4)]
ud = [rhs[4 + i].subs(dep) for i in range(2)]
f = sp.lambdify([x, y, th, ph, u1, u2], qd + ud, "numpy")

y0 = [0.4, -0.3, 0.9, 0.2, 0.8, -1.1]
sol = solve_ivp(lambda t, s: f(*s), (0.0, 10.0), y0, method="DOP853", rtol=1e-13, atol=1e-13)
xs, ys, ths, phs, w1, w2 = sol.y[:, -1]


def energy(s):
    x_, y_, th_, ph_, a, b = s
    vx, vy = 0.5 * b * np.cos(th_), 0.5 * b * np.sin(th_)
    return 0.5 * 2.0 * (vx**2 + vy**2) + 0.5 * 0.7 * a**2 + 0.5 * 1.3 * b**2 + 0.5 * 3.0 * x_**2


print("m=2 I=0.7 J=1.3 R=0.5 k=3; from x=0.4 y=-0.3 θ=0.9 φ=0.2 θ'=0.8 φ'=-1.1 to t = 10")
print(f"x = {xs:.16e}\ny = {ys:.16e}\nθ = {ths:.16e}\nφ = {phs:.16e}\nθ' = {w1:.16e}\nφ' = {w2:.16e}")
print(f"x' = {0.5 * w2 * np.cos(ths):.16e}\ny' = {0.5 * w2 * np.sin(ths):.16e}")
print(f"energy at 0 = {energy(y0):.16e}, at 10 = {energy(sol.y[:, -1]):.16e}")
