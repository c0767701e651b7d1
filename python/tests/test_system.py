"""System: every derivation, checked numerically against formulas derived by hand (textbook
forms in PHYSICS.md), and the errors for bad input."""

import json
import math
import pickle
import random

import pytest

import lagrangian as lg
from lagrangian import Expr, System

from conftest import DOUBLE_PENDULUM, DP_PARAMS, PENDULUM


def at(e, **values):
    return e.evaluate(values)


def test_pendulum_euler_lagrange_and_accelerations(pendulum):
    (el,) = pendulum.euler_lagrange()
    (acc,) = pendulum.accelerations()
    rng = random.Random(1)
    for _ in range(5):
        v = dict(m=rng.uniform(0.5, 2), l=rng.uniform(0.5, 2), g=rng.uniform(1, 10), θ=rng.uniform(-3, 3))
        v["θ'"], v["θ''"] = rng.uniform(-2, 2), rng.uniform(-2, 2)
        # E = m l² θ'' + m g l sin θ (by hand).
        expected = v["m"] * v["l"] ** 2 * v["θ''"] + v["m"] * v["g"] * v["l"] * math.sin(v["θ"])
        assert at(el, **v) == pytest.approx(expected, rel=1e-12, abs=1e-12)
        assert at(acc, **v) == pytest.approx(-v["g"] / v["l"] * math.sin(v["θ"]), rel=1e-12, abs=1e-12)


def test_double_pendulum_mass_matrix(double_pendulum):
    (w, f) = double_pendulum.mass_matrix()
    assert len(w) == 2 and len(w[0]) == 2 and len(f) == 2
    v = dict(DP_PARAMS, θ1=0.3, θ2=-1.1)
    v["θ1'"], v["θ2'"] = 0.7, -0.4
    m1, m2, l1, l2 = v["m1"], v["m2"], v["l1"], v["l2"]
    c = math.cos(v["θ1"] - v["θ2"])
    # Textbook W (PHYSICS.md, the double pendulum).
    expected = [[(m1 + m2) * l1**2, m2 * l1 * l2 * c], [m2 * l1 * l2 * c, m2 * l2**2]]
    for i in range(2):
        for j in range(2):
            assert at(w[i][j], **v) == pytest.approx(expected[i][j], rel=1e-13)


def test_legendre_hamiltonian_and_hamilton(pendulum):
    h = pendulum.hamiltonian()
    hs = pendulum.legendre()
    assert hs.kind == "hamiltonian" and pendulum.kind == "lagrangian"
    v = dict(m=1.3, l=0.7, g=9.81, θ=0.4, p_θ=0.9)
    # H = p²/(2 m l²) + m g l (1 − cos θ).
    expected = v["p_θ"] ** 2 / (2 * v["m"] * v["l"] ** 2) + v["m"] * v["g"] * v["l"] * (1 - math.cos(v["θ"]))
    assert at(h, **v) == pytest.approx(expected, rel=1e-13)
    qdot, pdot = pendulum.hamilton()
    assert at(qdot[0], **v) == pytest.approx(v["p_θ"] / (v["m"] * v["l"] ** 2), rel=1e-13)
    assert at(pdot[0], **v) == pytest.approx(-v["m"] * v["g"] * v["l"] * math.sin(v["θ"]), rel=1e-13)
    back = hs.inverse_legendre()
    assert back.kind == "lagrangian"
    w = dict(m=1.3, l=0.7, g=9.81, θ=0.4)
    w["θ'"] = 0.8
    assert at(back.lagrangian, **w) == pytest.approx(at(pendulum.lagrangian, **w), rel=1e-13)
    (p,) = pendulum.canonical_momenta()
    assert at(p, **w) == pytest.approx(w["m"] * w["l"] ** 2 * w["θ'"], rel=1e-13)


def test_conserved_quantities_of_a_central_force():
    s = System.from_lagrangian("1/2 m (r'^2 + r^2 φ'^2) + k/r", ["r", "φ"])
    found = {name: (expr, reason) for name, expr, reason in s.conserved()}
    assert "p_φ" in found and "ignorable" in found["p_φ"][1]
    v = {"m": 2.0, "r": 1.5, "r'": 0.1, "φ'": 0.3, "k": 1.0}
    assert at(found["p_φ"][0], **v) == pytest.approx(2.0 * 1.5**2 * 0.3)
    e = s.energy()
    assert at(e, **v) == pytest.approx(0.5 * 2.0 * (0.1**2 + 1.5**2 * 0.3**2) - 1.0 / 1.5)


def test_point_transformation_to_polar_coordinates():
    s = System.from_lagrangian("1/2 m (x'^2 + y'^2)", ["x", "y"])
    p = s.transform({"x": "r cos(φ)", "y": "r sin(φ)"}, ["r", "φ"])
    assert p.coordinates == ["r", "φ"]
    assert p.lagrangian.simplify() == Expr("1/2 m (r'^2 + r^2 φ'^2)").simplify()
    g = s.gauge("x y")
    # A gauge term leaves the equations of motion unchanged.
    assert [e.simplify() for e in g.euler_lagrange()] == [e.simplify() for e in s.euler_lagrange()]


def test_constrained_pendulum_in_cartesian_coordinates():
    s = System.from_lagrangian("1/2 m (x'^2 + y'^2) - m g y", ["x", "y"], constraints=["x^2 + y^2 = l^2"])
    c = s.constrained_equations()
    assert c["multipliers"] == ["λ1"]
    v = {"x": 0.6, "y": -0.8}
    assert [at(e, **v) for e in c["Phi"][0]] == pytest.approx([1.2, -1.6])


def test_poisson_brackets_and_integrals():
    assert lg.poisson("x", "p_x", ["x"]) == Expr("1")
    lx, ly, lz = "y p_z - z p_y", "z p_x - x p_z", "x p_y - y p_x"
    assert lg.poisson(lx, ly, ["x", "y", "z"]).simplify() == Expr(lz)
    kepler = System.from_hamiltonian("(p_x^2 + p_y^2)/(2 m) - k/sqrt(x^2 + y^2)", ["x", "y"])
    ok, how = kepler.is_integral("x p_y - y p_x")
    assert ok, how
    ok, _ = kepler.is_integral("x p_x")
    assert not ok


def test_generating_function_solves_the_oscillator():
    h = System.from_hamiltonian("p_q^2/(2 m) + 1/2 m ω^2 q^2", ["q"], positive=["m", "ω"])
    r = h.canonical_transform("1/2 m ω q^2 cot(Q)", "F1", ["Q"], ["P"])
    assert r["hamiltonian"] == Expr("P ω", positive=["ω"])


def test_lie_flow_of_the_oscillator_is_exact_at_order_two():
    h = System.from_hamiltonian("p_x^2/2 + x^2/2", ["x"])
    # x(t) = x cos t + p sin t; to second order: x + t p − t²/2 x.
    assert h.lie_flow("x", 2) == Expr("x + t p_x - t^2/2 x")


def test_action_of_the_oscillator():
    h = System.from_hamiltonian("p_x^2/(2 m) + 1/2 m ω^2 x^2", ["x"], params={"m": 2.0, "ω": 3.0})
    r = h.action_frequency(1.5, 0.0)
    assert r["action"] == pytest.approx(1.5 / 3.0, rel=1e-10)  # J = E/ω
    assert r["omega"] == pytest.approx(3.0, rel=1e-10)


def test_averaged_lagrangian_of_the_oscillator():
    s = System.from_lagrangian("1/2 m x'^2 - 1/2 m ω0^2 x^2", ["x"])
    a = s.average({"x": "A cos(θ)"}, "θ", "ω", ["A"])
    # ⟨L⟩ = m A² (ω² − ω0²)/4 (⟨sin²⟩ = ⟨cos²⟩ = 1/2).
    v = {"m": 1.7, "A": 0.3, "ω": 2.1, "ω0": 1.3}
    assert at(a["lagrangian"], **v) == pytest.approx(1.7 * 0.09 * (2.1**2 - 1.3**2) / 4, rel=1e-14)
    ((amp, rel),) = a["relations"]
    assert amp == "A" and at(rel, **v) == pytest.approx(1.7 * 0.3 * (2.1**2 - 1.3**2) / 2, rel=1e-14)


def test_singular_hessian_is_a_mechanics_error():
    s = System.from_lagrangian("x' y - x y' - x^2 - y^2", ["x", "y"])
    with pytest.raises(lg.MechanicsError, match="singular"):
        s.accelerations()
    with pytest.raises(lg.MechanicsError, match="singular"):
        s.legendre()


def test_bad_systems():
    with pytest.raises(lg.ParseError, match=r"\^"):
        System.from_lagrangian("1/2 m x'^2 +", ["x"])
    with pytest.raises(lg.MechanicsError, match="declared twice"):
        System.from_lagrangian("x'^2", ["x", "x"])
    with pytest.raises(lg.MechanicsError, match="not a parameter"):
        System.from_lagrangian(PENDULUM, ["θ"], params={"mass": 1.0})
    with pytest.raises(lg.MechanicsError, match="non-finite"):
        System.from_lagrangian(PENDULUM, ["θ"], params={"m": float("inf")})


def test_missing_parameter_value_is_a_compile_error():
    s = System.from_lagrangian(PENDULUM, ["θ"], params={"m": 1.0, "l": 1.0})
    with pytest.raises(lg.CompileError, match="`g`"):
        s.compile()
    with pytest.raises(lg.CompileError, match="`g`"):
        s.integrate((0, 1), [0.1, 0.0])


def test_system_pickles_as_source_and_options(double_pendulum):
    s = double_pendulum.with_force("θ1", "-1/10 θ1'")
    back = pickle.loads(pickle.dumps(s))
    assert back.params == s.params
    assert back.source == s.source
    assert back.equations() == s.equations()
    # A derived system pickles too (as its printed Hamiltonian).
    h = double_pendulum.legendre()
    hb = pickle.loads(pickle.dumps(h))
    assert hb.hamiltonian() == h.hamiltonian()
    assert "System(L = " in repr(s) and s._repr_latex_().startswith("$")


def test_params_and_names(double_pendulum):
    assert double_pendulum.coordinates == ["θ1", "θ2"]
    assert double_pendulum.velocities == ["θ1'", "θ2'"]
    assert double_pendulum.momenta == ["p_θ1", "p_θ2"]
    assert sorted(double_pendulum.parameters) == sorted(DP_PARAMS)
    s2 = double_pendulum.with_params(g=1.0)
    assert s2.params["g"] == 1.0 and double_pendulum.params["g"] == 9.81
    assert double_pendulum.state_names("gauss6") == ["θ1", "θ2", "θ1'", "θ2'"]
    assert double_pendulum.state_names("yoshida8") == ["θ1", "θ2", "p_θ1", "p_θ2"]
    with pytest.raises(ValueError, match="unknown method"):
        double_pendulum.state_names("rk45")


def test_report_prints_the_command_line_lines():
    # The disc rolling down an incline, y = R θ (L + λ (y − R θ)): by hand and by SymPy's
    # LagrangesMethod (scripts/report_constrained_sympy.py) y'' = 2 g sin α / 3, θ'' = y''/R,
    # λ1 = −m g sin α / 3; the lines are those of `lagrangian el --accelerations` and of the
    # scene statement `accelerations` (one builder, one renderer).
    s = System.from_lagrangian(
        "1/2 m y'^2 + 1/4 m R^2 θ'^2 + m g y sin(α)", ["y", "θ"], positive=["m", "R", "g", "α"]
    ).with_constraint("y - R θ")
    assert s.report("accelerations", "plain").splitlines() == [
        "y'' = 2 g sin(α)/3",
        "θ'' = 2 g sin(α)/(3 R)",
        "λ1 = -g m sin(α)/3",
    ]
    assert s.report("el").splitlines() == ["E_y: m (y\u0308 - g sin(α)) = λ1", "E_θ: R² m θ\u0308/2 = -R λ1"]
    lines = json.loads(s.report("el", "json"))
    assert lines[0] == {"label": "E_y", "lhs": "m (y'' - g sin(α))", "rhs": "λ1", "note": None}
    with pytest.raises(ValueError, match="unknown derivation `eel`"):
        s.report("eel")
    with pytest.raises(ValueError, match="unknown format"):
        s.report("el", "html")
