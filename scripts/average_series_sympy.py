"""Independent reference for `lagrangian average --small σ --order 2` (tests/it/canonical/average.rs):
the anharmonic oscillator of the notes (§2.8.2), L = ½ m x'² − ½ m ω0² (x² + σ x⁴/l0²), with the
trial x = l0 (A cos θ + B cos 3θ + C sin 3θ). SymPy averages L over θ by integration, forms the
relations ∂⟨L⟩/∂A = ∂⟨L⟩/∂B = ∂⟨L⟩/∂C = 0, substitutes ω = ω0 + σ ω1 + σ² ω2, B = σ b1 + σ² b2,
C = σ c1 + σ² c2, and solves the coefficients of σ and σ² (the A relation divided by A).
Usage: python3 scripts/average_series_sympy.py (needs sympy)."""
import sympy as sp

m, w0, l0, s, A, B, C, w, th = sp.symbols("m omega0 l0 sigma A B C omega theta", positive=True)
x = l0 * (A * sp.cos(th) + B * sp.cos(3 * th) + C * sp.sin(3 * th))
xdot = w * sp.diff(x, th)
L = sp.Rational(1, 2) * m * xdot**2 - sp.Rational(1, 2) * m * w0**2 * (x**2 + s * x**4 / l0**2)
avg = sp.expand(sp.integrate(sp.expand(L), (th, 0, 2 * sp.pi)) / (2 * sp.pi))
rels = [sp.expand(sp.diff(avg, A) / A), sp.diff(avg, B), sp.diff(avg, C)]
w1, w2, b1, b2, c1, c2 = sp.symbols("w1 w2 b1 b2 c1 c2")
sub = {w: w0 + s * w1 + s**2 * w2, B: s * b1 + s**2 * b2, C: s * c1 + s**2 * c2}
series = [sp.expand(sp.series(r.subs(sub), s, 0, 3).removeO()) for r in rels]
first = sp.solve([e.coeff(s, 1) for e in series], [w1, b1, c1], dict=True)[0]
second = sp.solve([e.coeff(s, 2).subs(first) for e in series], [w2, b2, c2], dict=True)[0]
print("omega1 =", sp.factor(first[w1]), "; omega2 =", sp.factor(second[w2]))
print("b1 =", sp.factor(first[b1]), "; b2 =", sp.factor(second[b2]))
print("c1 =", first[c1], "; c2 =", second[c2])

# The relations themselves (no series) at σ = 1 (hard spring), m = ω0 = l0 = 1, A = 1 and A = 0.5,
# by SymPy's nsolve (C = 0 solves its relation; the A relation divided by A).
vals = {m: 1, w0: 1, l0: 1, s: 1}
for a in (1, sp.Rational(1, 2)):
    eqs = [r.subs(vals).subs({A: a, C: 0}) for r in rels[:2]]
    sol = sp.nsolve(eqs, [w, B], [1.5, 0.02], prec=30)
    print(f"A = {a}: omega = {sp.N(sol[0], 17)}, B = {sp.N(sol[1], 17)}")
