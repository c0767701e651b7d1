"""Velocity (nonholonomic) constraints from Python: `System.with_velocity_constraint` (and
`velocity_constraints=`). The rolling coin integrated here agrees with the scene
`examples/rolling_coin.scene` run by the command line (a second route through the engine) and
with SymPy's KanesMethod integrated by SciPy (scripts/nonholonomic_simulate_sympy.py, the
numbers tests/it/scene/examples.rs checks); every path that has no place for the constraints
is refused with a message naming what keeps them, never answered for the unconstrained
system."""

import csv
import math
import pickle
import subprocess

import numpy as np
import pytest

import lagrangian as lg
from test_chaos import ROOT, cli

L = "1/2 m (x'^2 + y'^2) + 1/2 I θ'^2 + 1/2 J φ'^2 - 1/2 k x^2"
ROLL = ["x' = R φ' cos(θ)", "y' = R φ' sin(θ)"]
PARAMS = {"m": 2.0, "I": 0.7, "J": 1.3, "R": 0.5, "k": 3.0}
START = {
    "x": 0.4,
    "y": -0.3,
    "θ": 0.9,
    "φ": 0.2,
    "x'": 0.5 * -1.1 * math.cos(0.9),
    "y'": 0.5 * -1.1 * math.sin(0.9),
    "θ'": 0.8,
    "φ'": -1.1,
}
# scripts/nonholonomic_simulate_sympy.py: KanesMethod + solve_ivp (rtol 1e-12) at t = 10.
KANE_T10 = {
    "x": 5.8207899448197931e-1,
    "y": -2.9097372864592512,
    "θ": 8.8999999999999986,
    "φ": -6.075042467565174,
    "x'": 4.1323362365473593e-1,
    "y'": -2.3923069206098174e-1,
    "θ'": 8.0000000000000004e-1,
    "φ'": -9.549729875610099e-1,
}
# What every refusal names: the routes that keep the constraints.
KEEPS = r"velocity \(nonholonomic\) constraint.*lagrange_dalembert.*simulation with a classical method"


@pytest.fixture(scope="module")
def coin():
    # `R` enters through the constraints only: its value is given once they are added.
    s = lg.System.from_lagrangian(L, ["x", "y", "θ", "φ"], positive=list(PARAMS))
    for g in ROLL:
        s = s.with_velocity_constraint(g)
    return s.with_params(PARAMS)


def residuals(sol):
    r = PARAMS["R"]
    g1 = sol["x'"] - r * sol["φ'"] * np.cos(sol["θ"])
    g2 = sol["y'"] - r * sol["φ'"] * np.sin(sol["θ"])
    return np.abs(g1).max(), np.abs(g2).max()


def test_the_keyword_and_the_builder_give_the_same_system(coin):
    kw = lg.System.from_lagrangian(
        L, ["x", "y", "θ", "φ"], params=PARAMS, positive=list(PARAMS), velocity_constraints=ROLL
    )
    assert [str(e) for e in kw.equations()] == [str(e) for e in coin.equations()]
    assert coin.source["velocity_constraints"] == kw.source["velocity_constraints"]
    assert len(coin.source["velocity_constraints"]) == 2


def test_the_rolling_coin_agrees_with_the_scene_and_with_kanes_method(coin, tmp_path):
    sol = coin.integrate((0, 10), START, "dop853", tol=1e-12)
    assert sol.success and sol.names == ["x", "y", "θ", "φ", "x'", "y'", "θ'", "φ'"]
    for name, want in KANE_T10.items():
        assert abs(sol[name][-1] - want) < 1e-8, (name, sol[name][-1], want)
    # On the constraints at every kept state (projection), and rolling does no work: the
    # energy ½ m (x'² + y'²) + ½ I θ'² + ½ J φ'² + ½ k x² stays 1.553 (by hand at the start).
    assert max(residuals(sol)) < 1e-12
    energy = (
        0.5 * 2.0 * (sol["x'"] ** 2 + sol["y'"] ** 2)
        + 0.5 * 0.7 * sol["θ'"] ** 2
        + 0.5 * 1.3 * sol["φ'"] ** 2
        + 0.5 * 3.0 * sol["x"] ** 2
    )
    assert np.abs(energy - 1.553).max() < 1e-9
    # The same start through the scene language and the command line.
    out = subprocess.run(
        [str(cli()), "run", str(ROOT / "examples" / "rolling_coin.scene"), "--out-dir", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    with open(tmp_path / "rolling_coin.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    last = rows[-1]
    assert float(last["t"]) == pytest.approx(10.0, abs=1e-12)
    for name in KANE_T10:
        assert abs(float(last[name]) - sol[name][-1]) < 1e-10, (name, last[name], sol[name][-1])


def test_the_default_method_runs_on_the_constraints(coin):
    sol = coin.integrate((0, 10), START)
    assert sol.success
    for name, want in KANE_T10.items():
        assert abs(sol[name][-1] - want) < 1e-5, (name, sol[name][-1], want)
    assert max(residuals(sol)) < 1e-10


def test_a_start_off_the_constraint_is_refused(coin):
    off = dict(START, **{"x'": 0.0})
    with pytest.raises(ValueError, match="violate velocity constraint 1"):
        coin.integrate((0, 1), off, "dop853", tol=1e-10)


def test_the_equations_carry_the_multipliers(coin):
    eqs = [str(e) for e in coin.equations()]
    assert "μ1" in eqs[0] and "μ2" in eqs[1] and "μ1" in eqs[3] and "μ2" in eqs[3], eqs
    assert "μ" not in eqs[2], eqs  # nothing acts on the heading θ
    el = coin.report("el", "plain").splitlines()
    assert el[0] == "E_x: k x + m x'' = μ1", el
    c = coin.constrained_equations()
    assert c["multipliers"] == ["μ1", "μ2"] and len(c["Phi"]) == 2


def test_the_accelerations_of_a_skate_eliminate_the_multiplier():
    # A knife edge: y' cos θ = x' sin θ. By hand: μ = m θ' v − k x sin θ with
    # v = x' cos θ + y' sin θ, and x'' = (−k x − μ sin θ)/m, y'' = μ cos θ/m, θ'' = 0.
    s = lg.System.from_lagrangian(
        "1/2 m (x'^2 + y'^2) + 1/2 I θ'^2 - 1/2 k x^2", ["x", "y", "θ"]
    ).with_velocity_constraint("y' cos(θ) = x' sin(θ)")
    m, k, x, th, w, v = 2.0, 3.0, 0.4, 0.9, 0.8, -0.6
    at = {"m": m, "I": 0.7, "k": k, "x": x, "y": -0.3, "θ": th, "θ'": w, "x'": v * math.cos(th), "y'": v * math.sin(th)}
    mu = m * w * v - k * x * math.sin(th)
    want = [(-k * x - mu * math.sin(th)) / m, mu * math.cos(th) / m, 0.0]
    for a, hand in zip(s.accelerations(), want):
        assert abs(a.evaluate(at) - hand) < 1e-12, (str(a), hand)


def test_conserved_respects_the_constraints(coin):
    # θ is ignorable and no constraint force turns it; y and φ are ignorable in L but the
    # contact force acts on them; the ideal constraints do no work, so h stays.
    names = sorted(name for name, _, _ in coin.conserved())
    assert names == ["h", "p_θ"], names
    report = coin.report("conserved", "plain")
    assert "p_y = m y'   (not conserved: dp_y/dt = μ2, broken by velocity constraint 2 (multiplier μ2))" in report


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.hamiltonian(),
        lambda s: s.hamilton(),
        lambda s: s.legendre(),
        lambda s: s.report("hamilton"),
        lambda s: s.report("legendre"),
        lambda s: s.time_derivative("x"),
        lambda s: s.is_integral("p_θ"),
        lambda s: s.lie_flow("x", 2),
        lambda s: s.series(),
        lambda s: s.average({"x": "A cos(ψ)"}, "ψ", "ω", ["A"]),
        lambda s: s.megno((0, 1), START),
        lambda s: s.fli((0, 1), START),
        lambda s: s.lyapunov((0, 1), START),
        lambda s: s.indicators((0, 1), START),
        lambda s: s.chaos_map((0, 1), {"x": [0.1, 0.2]}, START),
    ],
    ids=[
        "hamiltonian",
        "hamilton",
        "legendre",
        "report-hamilton",
        "report-legendre",
        "time_derivative",
        "is_integral",
        "lie_flow",
        "series",
        "average",
        "megno",
        "fli",
        "lyapunov",
        "indicators",
        "chaos_map",
    ],
)
def test_what_would_drop_the_constraints_is_refused_naming_what_keeps_them(coin, call):
    with pytest.raises(lg.LagrangianError, match=KEEPS):
        call(coin)


@pytest.mark.parametrize(("method", "step"), [("leapfrog", {"dt": 0.01}), ("yoshida4", {"dt": 0.01})])
def test_methods_that_would_drop_the_constraints_are_refused_naming_the_ones_that_run(coin, method, step):
    with pytest.raises(ValueError, match="these methods can run this system: .*gauss6.*dop853.*taylor"):
        coin.integrate((0, 1), START, method, **step)


def test_the_taylor_method_runs_on_the_constraints(coin):
    """The Taylor form of the augmented system, with projection after each step: KanesMethod's
    state at t = 10 (scripts/nonholonomic_simulate_sympy.py)."""
    sol = coin.integrate((0, 10), START, "taylor", tol=1e-13)
    for name, want in KANE_T10.items():
        assert abs(sol[name][-1] - want) < 1e-9, (name, sol[name][-1], want)


def test_hamiltons_equations_compiled_are_refused_naming_the_lagrangian_ones(coin):
    with pytest.raises(ValueError, match="leave out the forces, dissipation and constraints.*Lagrangian formulation"):
        coin.compile("hamiltonian")
    # The default (Lagrangian) formulation is the augmented system: KanesMethod's
    # accelerations at the start (scripts/nonholonomic_sympy.py).
    f = coin.compile()
    dy = f(0.0, np.array([START[n] for n in f.names]))
    kane = [0.28026401479385, -0.3546623552789419, 0.0, -0.2072033227568881]
    np.testing.assert_allclose(dy[4:], kane, atol=1e-12)


def test_a_collocation_method_runs_on_the_constraints(coin):
    sol = coin.integrate((0, 10), START, "gauss6", dt=0.01)
    for name, want in KANE_T10.items():
        assert abs(sol[name][-1] - want) < 1e-8, (name, sol[name][-1], want)
    assert max(residuals(sol)) < 1e-12


def test_a_pickled_system_keeps_its_constraints(coin):
    back = pickle.loads(pickle.dumps(coin))
    assert [str(e) for e in back.equations()] == [str(e) for e in coin.equations()]
    with pytest.raises(lg.MechanicsError, match=KEEPS):
        back.hamiltonian()


def test_a_point_transformation_carries_the_constraints(coin):
    polar = coin.transform({"x": "r cos(α)", "y": "r sin(α)"}, ["r", "α", "θ", "φ"])
    g = polar.source["velocity_constraints"]
    assert len(g) == 2 and all("r'" in x or "α'" in x for x in g), g
    with pytest.raises(lg.MechanicsError, match=KEEPS):
        polar.hamiltonian()


@pytest.mark.parametrize(
    ("text", "why"),
    [("x'^2 = 1", "not linear in the velocities"), ("x = 1", "contains no velocity"), ("q' = 1", "not a coordinate")],
)
def test_a_constraint_that_is_not_a_velocity_constraint_is_refused(coin, text, why):
    with pytest.raises(lg.LagrangianError, match=why):
        coin.with_velocity_constraint(text)


def test_a_hamiltonian_system_takes_no_velocity_constraint():
    h = lg.System.from_hamiltonian("p_x^2/2 + x^2/2", ["x"])
    with pytest.raises(lg.MechanicsError, match="needs a Lagrangian"):
        h.with_velocity_constraint("x' = 1")
