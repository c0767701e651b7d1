"""The symbolic tools without a system (series, Jacobians, iterated maps) and ``System.series``,
against hand results and a plain-Python iteration of the same maps."""

import math

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import Expr


def test_series_of_an_expression_is_the_taylor_polynomial():
    assert lg.series("sin(x)", ["x"], 5) == Expr("x - x^3/6 + x^5/120")
    # Total degree in several small names: cos(x) cos(y) to order 2.
    assert lg.series(Expr("cos(x) cos(y)"), ["x", "y"], 2) == Expr("1 - x^2/2 - y^2/2")


def test_system_series_is_the_small_oscillation_lagrangian():
    # (2.29): the pendulum about θ = 0 to second order, ½ m l² θ'² − ½ m g l θ² plus the constant 0.
    s = lg.System.from_lagrangian("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", ["θ"], positive=["m", "g", "l"])
    lin = s.series()
    assert (lin - Expr("1/2 m l^2 θ'^2 - 1/2 m g l θ^2", positive=["m", "g", "l"])).simplify() == Expr("0")
    # About the inverted point θ = π the potential term changes sign (and a constant 2 m g l appears).
    up = s.series(["pi"], 2)
    want = Expr("1/2 m l^2 θ'^2 + 1/2 m g l θ^2 - 2 m g l", positive=["m", "g", "l"])
    assert (up - want).simplify() == Expr("0")
    with pytest.raises(ValueError, match="about"):
        s.series([0, 1])
    with pytest.raises(ValueError, match="Hamiltonian"):
        lg.System.from_hamiltonian("p_q^2/2 + q^2/2", ["q"]).series()


def test_jacobian_of_polar_coordinates():
    m, det = lg.jacobian(["r cos(φ)", "r sin(φ)"], ["r", "φ"])
    assert m == [[Expr("cos(φ)"), Expr("-r sin(φ)")], [Expr("sin(φ)"), Expr("r cos(φ)")]]
    assert det == Expr("r")
    with pytest.raises(ValueError, match="as many components"):
        lg.jacobian(["r cos(φ)"], ["r", "φ"])


def test_iterate_map_explicit_matches_a_python_iteration():
    k, steps = 0.9, 50
    starts = np.array([[1.0, 0.5], [0.2, -1.1]])
    orbits = lg.iterate_map([("p", "p + K sin(q)"), ("q", "q + p")], ["q", "p"], starts, steps, params={"K": k})
    assert orbits.shape == (2, steps + 1, 2)
    for start, orbit in zip(starts, orbits):
        q, p = start
        for n in range(steps + 1):
            assert orbit[n, 0] == pytest.approx(q, abs=1e-9) and orbit[n, 1] == pytest.approx(p, abs=1e-9)
            p = p + k * math.sin(q)
            q = q + p


def test_iterate_map_implicit_midpoint_is_the_cayley_rotation():
    h, steps = 0.1, 200
    updates = [("q'", "q + h (p + p')/2"), ("p'", "p - h (q + q')/2")]
    orbits = lg.iterate_map(updates, ["q", "p"], [[1.0, 0.0]], steps, params={"h": h})
    a = steps * 2 * math.atan(h / 2)
    assert orbits[0, -1, 0] == pytest.approx(math.cos(a), abs=1e-12)
    assert orbits[0, -1, 1] == pytest.approx(-math.sin(a), abs=1e-12)
    # No real solution (q' = q + q'² + 1 for q > −3/4): NaN from the failed step on.
    bad = lg.iterate_map([("q'", "q + q'^2 + 1")], ["q"], [[0.0]], 3)
    assert bad[0, 0, 0] == 0.0 and np.isnan(bad[0, 1:, 0]).all()
    with pytest.raises(lg.MechanicsError, match="implicit map"):
        lg.iterate_map([("q'", "q + p"), ("p", "p")], ["q", "p"], [[0.0, 1.0]], 3)


def test_average_series_and_relations_solved_along_the_amplitude():
    # The hard-spring anharmonic oscillator of the notes (§2.8.2) with m = ω0 = l0 = σ = 1.
    # Second-order series: ω = ω0 (1 + 3σA²/4 − 15σ²A⁴/64), B = σA³/16 − 21σ²A⁵/256 (SymPy,
    # scripts/average_series_sympy.py); the relations at A = 1: ω = 1.5943146199509888,
    # B = 0.026489365310534100 (SymPy's nsolve, same script).
    s = lg.System.from_lagrangian(
        "1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)", ["x"],
        params={"m": 1.0, "ω0": 1.0, "σ": 1.0, "l0": 1.0}, positive=["m", "ω0", "l0"],
    )
    trial = {"x": "l0 (A cos(θ) + B cos(3 θ) + C sin(3 θ))"}
    r = s.average(trial, "θ", "ω", ["A", "B", "C"], small="σ", unperturbed="ω0", order=2,
                  sweep=[0.5, 0.75, 1.0])
    pos = ["m", "ω0", "l0"]
    assert (r["series"]["frequency"] - Expr("ω0 (1 + 3 σ A^2/4 - 15 σ^2 A^4/64)", positive=pos)).simplify() == Expr("0")
    assert r["series"]["amplitudes"][0][0] == "B"
    assert (r["series"]["amplitudes"][0][1] - Expr("σ A^3/16 - 21 σ^2 A^5/256")).simplify() == Expr("0")
    assert (r["grouped"] - r["lagrangian"]).simplify() == Expr("0")
    solved = r["solved"]
    assert list(solved["A"]) == [0.5, 0.75, 1.0]
    assert solved["ω"][-1] == pytest.approx(1.5943146199509888, abs=1e-12)
    assert solved["B"][-1] == pytest.approx(0.026489365310534100, abs=1e-12)
    assert np.all(np.abs(solved["C"]) < 1e-14)
    assert solved["ω_series"][-1] == pytest.approx(1 + 3 / 4 - 15 / 64, abs=1e-14)
    with pytest.raises(ValueError, match="needs `small`"):
        s.average(trial, "θ", "ω", ["A", "B", "C"], sweep=[1.0])


def test_ensemble_on_a_time_grid_matches_integrate_and_the_closed_form():
    # The oscillator x'' = −x from (x, x') = (a, 0): x(t) = a cos t. Each trajectory of the
    # ensemble at t_eval equals `integrate` with the same t_eval (one code path) and the cosine.
    s = lg.System.from_lagrangian("1/2 x'^2 - 1/2 x^2", ["x"])
    starts = np.array([[1.0, 0.0], [0.5, 0.0], [-2.0, 0.0]])
    t_eval = np.linspace(0.0, 3.0, 7)
    r = s.ensemble((0, 3), starts, "dop853", tol=1e-12, t_eval=t_eval, threads=1, progress=False)
    assert r.y.shape == (3, 2, 7) and list(r.t) == list(t_eval)
    for j, y0 in enumerate(starts):
        one = s.integrate((0, 3), y0, "dop853", tol=1e-12, t_eval=t_eval, progress=False)
        assert np.array_equal(r.y[j], one.y)
        assert np.allclose(r.y[j, 0], y0[0] * np.cos(t_eval), atol=1e-9)
    ds = r.to_xarray()
    assert ds["x"].dims == ("trajectory", "t") and ds["x"].shape == (3, 7)
    df = r.to_pandas()
    assert len(df) == 21 and df.loc[(2, 0.0), "x"] == -2.0
    # A terminal event ends a trajectory: the times after it are NaN.
    ev = lg.Event("x", terminal=True, direction=-1)
    r = s.ensemble((0, 3), starts[:1], "dop853", tol=1e-12, t_eval=t_eval, events=[ev], threads=1, progress=False)
    after = t_eval > np.pi / 2
    assert np.isnan(r.y[0][:, after]).all() and not np.isnan(r.y[0][:, ~after]).any()
