"""Reference for the Ritz method with a free end (natural boundary condition (1.18), §1.4).

L = x'^2/2 + x^2/2 on [0, 1], x(0) = 1, x(1) free. Euler–Lagrange: x'' = x; the natural
condition ∂L/∂x' = x'(1) = 0 gives the exact path x = cosh(1 - t)/cosh(1), whose action is
S = [x x'/2]_0^1 = tanh(1)/2. The Ritz trial x = 1 + a t + b t^2 + c t^3 is solved exactly
here (rational coefficients), with the residual a + 2b + 3c of the natural condition.
Run: /tmp/venv-python/bin/python scripts/natural_bc_sympy.py
"""
import sympy as sp

t, a, b, c = sp.symbols("t a b c")
x = 1 + a * t + b * t**2 + c * t**3
L = sp.diff(x, t) ** 2 / 2 + x**2 / 2
S = sp.integrate(sp.expand(L), (t, 0, 1))
sol = sp.solve([sp.diff(S, u) for u in (a, b, c)], [a, b, c], dict=True)[0]
print("a =", sol[a], "=", sp.N(sol[a], 17))
print("b =", sol[b], "=", sp.N(sol[b], 17))
print("c =", sol[c], "=", sp.N(sol[c], 17))
print("S =", sp.N(S.subs(sol), 17))
print("natural residual x'(1) =", sp.N((a + 2 * b + 3 * c).subs(sol), 17))
xe = sp.cosh(1 - t) / sp.cosh(1)
assert sp.simplify(sp.diff(xe, t, 2) - xe) == 0 and sp.simplify(sp.diff(xe, t).subs(t, 1)) == 0
Se = sp.integrate(sp.diff(xe, t) ** 2 / 2 + xe**2 / 2, (t, 0, 1))
print("exact S =", sp.N(Se, 17), " tanh(1)/2 =", sp.N(sp.tanh(1) / 2, 17))
print("exact x'(0) =", sp.N(-sp.tanh(1), 17))
