"""Expr: parsing, printing (plain, Unicode, LaTeX), calculus, substitution, evaluation on
scalars and arrays, arithmetic, pickling and the SymPy round trip."""

import math
import pickle

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import Expr


def test_plain_form_parses_back_to_the_same_expression():
    e = Expr("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))")
    assert Expr(str(e)) == e
    assert hash(Expr(str(e))) == hash(e)
    assert repr(e).startswith("Expr(")
    assert Expr("x + 1") != Expr("x + 2")


def test_latex_and_unicode_renderings():
    e = Expr("θ'^2 / 2")
    assert "\\dot{\\theta}" in e.latex()
    assert "θ̇" in e.unicode()
    r = e._repr_latex_()
    assert r.startswith("$") and r.endswith("$") and e.latex() in r
    assert "\\frac" in Expr("x / y").latex()


def test_diff_dt_simplify_subs():
    assert Expr("1/2 k x^2").diff("x") == Expr("k x")
    assert Expr("1/2 m x'^2").diff("x'") == Expr("m x'")
    assert Expr("x^2").dt(["x"]) == Expr("2 x x'")
    assert Expr("x y'").dt() == Expr("x y''")  # y is primed, so a coordinate; x is not
    assert Expr("x y'").dt(["x", "y"]) == Expr("x' y' + x y''")
    assert Expr("sin(x)^2 + cos(x)^2").simplify() == Expr("1")
    assert Expr("x^2").subs({"x": "r cos(φ)"}) == Expr("r^2 cos(φ)^2")
    # Floats become the exact rational they print as.
    assert Expr("x^2").subs({"x": 0.1}) == Expr("1/100")
    assert Expr("x + y").subs({Expr("y"): 3}) == Expr("x + 3")
    assert Expr("p_x x + t").free_symbols() == ["p_x", "t", "x"]


def test_arithmetic_operators():
    x = Expr("x")
    assert x * 2 + 1 == Expr("2 x + 1")
    assert 1 - x == Expr("1 - x")
    assert (x**2) / x == x
    assert 2**x == Expr("2^x")
    assert -x == Expr("-x")
    assert x / 4 == Expr("x/4")
    with pytest.raises(ValueError):
        x + float("nan")
    with pytest.raises(TypeError):
        x + "y"


def test_evaluate_scalars_and_broadcast_arrays():
    e = Expr("sin(x) y^2 + θ'")
    v = e.evaluate({"θ'": 0.5}, x=0.3, y=2.0)
    assert isinstance(v, float)
    assert v == pytest.approx(math.sin(0.3) * 4 + 0.5, rel=1e-15)
    xs = np.linspace(0, 1, 3).reshape(3, 1)
    ys = np.arange(4.0).reshape(1, 4)
    out = e.evaluate({"x": xs, "y": ys, "θ'": 0.5})
    assert out.shape == (3, 4) and out.dtype == np.float64
    np.testing.assert_allclose(out, np.sin(xs) * ys**2 + 0.5, rtol=1e-14)
    # Integer arrays and lists are read as floats.
    np.testing.assert_allclose(Expr("2 x").evaluate(x=[1, 2, 3]), [2.0, 4.0, 6.0])


def test_evaluate_missing_value_is_an_eval_error():
    with pytest.raises(lg.EvalError, match="`y`"):
        Expr("x + y").evaluate(x=1.0)
    with pytest.raises(lg.EvalError, match="`y`"):
        Expr("x + y").evaluate(x=np.ones(3))


def test_syntax_error_shows_the_caret_line():
    with pytest.raises(lg.ParseError) as info:
        Expr("1/2 m x'^2 + * k")
    msg = str(info.value)
    assert "line 1, column" in msg
    assert "1/2 m x'^2 + * k" in msg
    caret = [l for l in msg.splitlines() if l.strip().endswith("^")]
    assert caret, msg
    assert isinstance(info.value, lg.LagrangianError)


def test_pickle_keeps_expression_and_declarations():
    e = Expr("sqrt(m^2) V(r)", positive=["m"], functions=["V"])
    back = pickle.loads(pickle.dumps(e))
    assert back == e
    # The declarations travel too: m is still positive (sqrt(m^2) = m) and V still a function.
    assert back.simplify() == Expr("m V(r)", functions=["V"], positive=["m"])
    assert Expr("sqrt(m^2)").simplify() != Expr("m")


def test_sympy_round_trip():
    sympy = pytest.importorskip("sympy")
    e = Expr("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", positive=["m", "l", "g"])
    s = e.to_sympy()
    m, l, g = sympy.symbols("m l g", positive=True)
    th, thd = sympy.Symbol("θ"), sympy.Symbol("θ'")
    expected = sympy.Rational(1, 2) * m * l**2 * thd**2 - m * g * l * (1 - sympy.cos(th))
    assert sympy.simplify(s - expected) == 0
    assert lg.from_sympy(s) == e
    # Declared functions and the built-ins map both ways.
    f = Expr("V(r) + abs(atan2(y, x)) + exp(x/3)", functions=["V"])
    assert lg.from_sympy(f.to_sympy()) == f
    # A SymPy symbol named pi would silently become the constant: refused.
    with pytest.raises(ValueError, match="constant π"):
        lg.from_sympy(sympy.Symbol("pi") * sympy.Symbol("x"))


def test_pi_is_exact_both_ways():
    # The engine's `pi` is SymPy's `pi`, and trigonometric values at its rational multiples are
    # exact (checked against SymPy's own evaluation, an independent implementation).
    sympy = pytest.importorskip("sympy")
    x = sympy.Symbol("x")
    e = lg.from_sympy(sympy.pi * x / 3 + sympy.pi**2)
    assert e == Expr("pi x/3 + pi^2")
    assert e.to_sympy() == sympy.pi * x / 3 + sympy.pi**2
    for k in [sympy.Rational(n, d) for d in (1, 2, 3, 4, 6) for n in range(-13, 14)]:
        for f, name in ((sympy.sin, "sin"), (sympy.cos, "cos")):
            ours = Expr(f"{name}(({k}) pi)").to_sympy()
            assert sympy.simplify(ours - f(k * sympy.pi)) == 0, (name, k, ours)
    assert Expr("sin(pi)") == Expr("0") and Expr("acos(-1)") == Expr("pi")
    assert Expr("2 pi").latex() == r"2 \pi" and Expr("2 pi").unicode() == "2 π"
    # A name that would be shadowed by the constant is refused where it is declared.
    with pytest.raises(ValueError, match="constant π"):
        lg.System.from_lagrangian("x'^2/2 - x^2/2", ["x"], params={"pi": 3.0})
    with pytest.raises(ValueError, match="constant π"):
        lg.System.from_lagrangian("1/2 x'^2", ["pi"])


def test_every_builtin_maps_to_its_sympy_function_and_back():
    # The names come from the engine's function table (`_core.BUILTINS`), not a copy here.
    sympy = pytest.importorskip("sympy")
    from lagrangian import _core

    assert {name for name, _ in _core.BUILTINS} >= {"sin", "atan2", "abs"}
    for name, sympy_name in _core.BUILTINS:
        e = Expr(f"{name}(x, y)" if name == "atan2" else f"{name}(x)")
        s = e.to_sympy()
        assert s.func == getattr(sympy, sympy_name), (name, s)
        assert lg.from_sympy(s) == e, (name, s)
