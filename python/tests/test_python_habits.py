"""The package welcomes what a Python user writes: floats, SymPy's mechanics objects, SymPy's
`free_symbols` property, LaTeX display of lists and matrices in Jupyter, and `lambdify`."""

import pickle
from fractions import Fraction

import numpy as np
import pytest

import lagrangian as lg
from conftest import DOUBLE_PENDULUM, DP_PARAMS


# Floats: the shortest decimal that reads back as the same float (repr(float)). Why: `0.1` in
# Python is what the user typed as 0.1, and the text language reads `0.1` as 1/10, so
# `0.1 * x` and `Expr("0.1 x")` are the same expression; the exact binary value
# (3602879701896397/36028797018963968) would make them differ, and still not be 1/10.
@pytest.mark.parametrize("v", [0.1, 1 / 3, 2.5e-7, 6.02214076e23, 1e300, 5e-324, -0.7, np.float64(0.3)])
def test_floats_become_their_shortest_round_trip_decimal(v):
    e = lg.Expr("x") * v
    coef = e.diff("x")
    # The exact rational is the decimal repr(float) prints, which reads back as v.
    expected = Fraction(repr(float(v)))
    got = Fraction(coef.plain().replace(" ", "")) if "e" not in coef.plain() else None
    if got is not None:
        assert got == expected, (coef.plain(), expected)
    assert coef.evaluate() == float(v)


def test_a_python_float_equals_the_typed_decimal():
    assert lg.Expr("x") * 0.1 == lg.Expr("0.1 x") == lg.Expr("x/10")
    assert (lg.Expr("x") * (1 / 3)).plain() == "3333333333333333 x/10000000000000000"
    with pytest.raises(ValueError, match="finite"):
        lg.Expr("x") * float("nan")


def test_from_sympy_takes_rationals_floats_and_lagranges_method_objects():
    sympy = pytest.importorskip("sympy")
    me = pytest.importorskip("sympy.physics.mechanics")
    x = sympy.Symbol("x")
    assert lg.from_sympy(sympy.Rational(1, 3) * x) == lg.Expr("x/3")
    # A SymPy float prints with 15 digits; it is read as the float it holds.
    e = lg.from_sympy(sympy.Float(1 / 3) * x)
    assert e.diff("x").evaluate() == 1 / 3
    # dynamicsymbols and their derivatives: the coordinates q, q' and q''.
    q = me.dynamicsymbols("q")
    m, k = sympy.symbols("m k", positive=True)
    L = sympy.Rational(1, 2) * m * q.diff() ** 2 - sympy.Rational(1, 2) * k * q**2
    assert lg.from_sympy(L) == lg.Expr("1/2 m q'^2 - 1/2 k q^2", positive=["m", "k"])
    assert lg.from_sympy(q.diff(me.dynamicsymbols._t, 2) + q) == lg.Expr("q'' + q")
    # A given function of time stays a function when named in functions=.
    F = sympy.Function("F")
    t = me.dynamicsymbols._t
    assert lg.from_sympy(F(t) * q, functions=["F"]) == lg.Expr("F(t) q", functions=["F"])
    # Another derivative has no meaning here: refused naming it.
    with pytest.raises(ValueError, match="Derivative"):
        lg.from_sympy(sympy.Derivative(F(x), x))


def test_lagranges_method_equations_equal_the_engines():
    sympy = pytest.importorskip("sympy")
    me = pytest.importorskip("sympy.physics.mechanics")
    q = me.dynamicsymbols("q")
    m, l, g = sympy.symbols("m l g", positive=True)
    L = sympy.Rational(1, 2) * m * l**2 * q.diff() ** 2 + m * g * l * sympy.cos(q)
    lm = me.LagrangesMethod(L, [q])
    theirs = lg.from_sympy(lm.form_lagranges_equations()[0])
    sys = lg.System.from_lagrangian(str(lg.from_sympy(L)), ["q"], positive=["m", "l", "g"])
    (ours,) = sys.euler_lagrange()
    assert (theirs - ours).simplify() == lg.Expr("0")


def test_free_symbols_is_a_property_and_calling_it_still_works():
    e = lg.Expr("m x'^2 + k x + t")
    assert e.free_symbols == ["k", "m", "t", "x", "x'"]
    assert "k" in e.free_symbols
    assert e.free_symbols() == ["k", "m", "t", "x", "x'"]


def test_lists_and_matrices_render_as_latex():
    sys = lg.System.from_lagrangian(DOUBLE_PENDULUM, ["θ1", "θ2"], params=DP_PARAMS)
    el = sys.euler_lagrange()
    assert isinstance(el, list) and len(el) == 2
    latex = el._repr_latex_()
    assert latex.startswith("$\\displaystyle") and el[0].latex() in latex and el[1].latex() in latex
    w, f = sys.mass_matrix()
    assert w._repr_latex_().count("&") == 2 and "bmatrix" in w._repr_latex_()
    assert w[0][1].latex() in w._repr_latex_()
    assert f._repr_latex_() and sys.accelerations()._repr_latex_()
    dq, dp = sys.legendre().hamilton()
    assert dq._repr_latex_() and dp._repr_latex_()
    # Still plain lists.
    assert el == list(el) and pickle.loads(pickle.dumps(list(el))) == list(el)


def test_lambdify_agrees_with_evaluate():
    e = lg.Expr("sin(θ) θ'^2 + exp(-t/2) θ")
    f = lg.lambdify(["θ", "θ'", "t"], e)
    rng = np.random.default_rng(1)
    th, w, t = rng.normal(size=(3, 50))
    got = f(th, w, t)
    assert got.shape == (50,)
    np.testing.assert_array_equal(got, e.evaluate({"θ": th, "θ'": w, "t": t}))
    # Against NumPy written by hand (a second route).
    np.testing.assert_allclose(got, np.sin(th) * w**2 + np.exp(-t / 2) * th, rtol=1e-14)
    # Broadcasting and scalars.
    assert f(th[:, None], w[None, :5], 0.0).shape == (50, 5)
    assert isinstance(f(0.1, 0.2, 0.3), float)
    # Several expressions: one leading axis per expression.
    sys = lg.System.from_lagrangian(DOUBLE_PENDULUM, ["θ1", "θ2"], params=DP_PARAMS)
    acc = [a.subs(DP_PARAMS) for a in sys.accelerations()]
    g = lg.lambdify(["θ1", "θ2", "θ1'", "θ2'"], acc)
    y = np.array([0.3, -0.2, 0.1, 0.4])
    np.testing.assert_allclose(g(*y), sys.compile()(0.0, y)[2:], rtol=1e-13)
    assert g(*(np.tile(y[:, None], 3))).shape == (2, 3)
    # The method form, and pickling.
    h = e.lambdify(["θ", "θ'", "t"])
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(h))(th, w, t), got)


def test_lambdify_refuses_a_symbol_that_is_not_an_argument():
    with pytest.raises(lg.ArgumentError, match="`k` is not among the arguments"):
        lg.lambdify(["x"], lg.Expr("k x"))
    with pytest.raises(ValueError, match="takes 1 argument"):
        lg.lambdify(["x"], "x^2")(1.0, 2.0)
