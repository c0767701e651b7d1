"""Inputs that used to give a silently wrong answer are refused, with a message saying what
would work: a Hamiltonian whose momentum is not named after its coordinate (the name became a
parameter and the coordinate never moved), a value that contradicts ``positive=`` (the
equations were simplified for a positive symbol), a Poisson bracket over names that are not in
its phase space (read as constants, the bracket was 0)."""

import math

import pytest

import lagrangian as lg


def test_a_momentum_not_named_after_its_coordinate_is_refused_naming_both():
    with pytest.raises(ValueError) as e:
        lg.System.from_hamiltonian("p^2/2 + q^2/2", ["q"])
    msg = str(e.value)
    assert "`p_q`" in msg and "`p` is not one of them" in msg and "parameter" in msg
    # The same system written as the message says runs: q(t) = cos t.
    h = lg.System.from_hamiltonian("p_q^2/2 + q^2/2", ["q"])
    sol = h.integrate((0, 1), [1.0, 0.0], tol=1e-12)
    assert sol.y[0, -1] == pytest.approx(math.cos(1.0), abs=1e-9)


def test_a_coordinate_whose_momentum_is_absent_is_refused():
    # y would be frozen: y' = ∂H/∂p_y = 0.
    with pytest.raises(ValueError, match="`p_y`, the momentum of `y`"):
        lg.System.from_hamiltonian("p_x^2/2 + x^2/2 + y^2/2", ["x", "y"])


def test_the_momentum_of_a_name_that_is_not_a_coordinate_is_refused():
    with pytest.raises(ValueError, match="`y` is not a coordinate"):
        lg.System.from_hamiltonian("(p_x^2 + p_y^2)/2 + x^2/2", ["x"])


def test_a_value_against_positive_is_refused_everywhere_a_value_enters():
    text = "1/2 m x'^2 - 1/2 k x^2"
    with pytest.raises(ValueError, match="`m` was declared positive"):
        lg.System.from_lagrangian(text, ["x"], params={"m": -1.0, "k": 1.0}, positive=["m"])
    s = lg.System.from_lagrangian(text, ["x"], positive=["m"])
    with pytest.raises(ValueError, match="declared positive"):
        s.with_params(m=-1.0, k=1.0)
    with pytest.raises(ValueError, match="declared positive"):
        s.with_params({"m": 0.0, "k": 1.0})
    # Without the declaration a negative value is the user's to give.
    lg.System.from_lagrangian(text, ["x"], params={"m": -1.0, "k": 1.0})
    # And with it, a positive one still runs: x = cos(t sqrt(k/m)).
    sol = s.with_params(m=4.0, k=1.0).integrate((0, 2), [1.0, 0.0], tol=1e-12)
    assert sol.y[0, -1] == pytest.approx(math.cos(1.0), abs=1e-9)


def test_a_bracket_over_names_outside_the_phase_space_is_refused():
    with pytest.raises(ValueError) as e:
        lg.poisson("x*p_x", "y", ["q"])
    msg = str(e.value)
    assert "`p_x`, `x`, `y` are neither a coordinate nor a momentum" in msg and "params=" in msg
    with pytest.raises(ValueError, match="`q'`"):
        lg.poisson("q'", "p_q", ["q"])
    # Over the right phase space, {x p_x, x} = -x (by hand: ∂f/∂x ∂g/∂p_x - ∂f/∂p_x ∂g/∂x).
    assert lg.poisson("x*p_x", "x", ["x"]) == lg.Expr("-x")
    # Constants are named, and bracket to nothing: {p_q^2/(2m), q} = -p_q/m.
    assert lg.poisson("p_q^2/(2 m)", "q", ["q"], params=["m"]) == lg.Expr("-p_q/m")
    assert lg.poisson("t q", "p_q", ["q"]) == lg.Expr("t")


def test_a_systems_brackets_refuse_names_outside_its_phase_space_and_parameters():
    kepler = lg.System.from_hamiltonian("(p_x^2 + p_y^2)/(2 m) - k/sqrt(x^2 + y^2)", ["x", "y"])
    # z is not a coordinate, so p_z would be read as a constant and its bracket dropped.
    with pytest.raises(ValueError, match="`p_z` is neither a coordinate nor a momentum"):
        kepler.is_integral("x p_z")
    with pytest.raises(ValueError, match="`z`"):
        kepler.poisson("z", "p_x")
    with pytest.raises(ValueError, match="`w`"):
        kepler.time_derivative("w x")
    # The system's parameters are known: {p_x, H} = -k x / r^3 at (x, y) = (3, 4) is -3k/125.
    bracket = kepler.poisson("p_x", kepler.hamiltonian())
    assert bracket.evaluate({"x": 3.0, "y": 4.0, "k": 2.0, "m": 1.0}) == pytest.approx(-6.0 / 125, rel=1e-14)
    ok, how = kepler.is_integral("x p_y - y p_x")
    assert ok, how


def test_a_coordinate_declared_positive_cannot_start_at_or_below_zero():
    # Central force in polar coordinates with r declared positive.
    s = lg.System.from_lagrangian("1/2 (r'^2 + r^2 φ'^2) + 1/r", ["r", "φ"], positive=["r"])
    with pytest.raises(ValueError, match="`r` was declared positive .* cannot start at -1"):
        s.integrate((0, 1), [-1.0, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="cannot start at 0"):
        s.ensemble((0, 1), [[1.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]])
    # A circular orbit (r = 1, φ' = 1: r φ'^2 = 1/r^2) stays at r = 1.
    sol = s.integrate((0, 1), [1.0, 0.0, 0.0, 1.0], rtol=1e-12)
    assert sol.y[0, -1] == pytest.approx(1.0, abs=1e-9) and sol.y[1, -1] == pytest.approx(1.0, abs=1e-9)
