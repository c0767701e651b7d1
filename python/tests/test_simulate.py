"""One engine under the binding: every method × kind of system either computes the right answer
or raises a ValueError naming the methods that can run the system. Each case here used to give a
silently wrong answer (forces, dissipation and constraints dropped by splitting methods and by
``compile("hamiltonian")``) or could not run at all (constrained systems, variational maps).

The closed forms are by hand: the damped oscillator ``x'' + c x' + x = 0`` is
``e^{-ct/2} (cos ωt + c/(2ω) sin ωt)`` with ``ω = sqrt(1 - c²/4)``; a particle held on the line
``y = x`` by a constraint in the isotropic oscillator moves as ``x = y = cos t``.
"""

import math

import numpy as np
import pytest

import lagrangian as lg


def damped(c=0.5):
    return lg.System.from_lagrangian("1/2 x'^2 - 1/2 x^2", ["x"]).with_rayleigh("1/2 c x'^2").with_params({"c": c})


def damped_exact(t, c=0.5):
    w = math.sqrt(1 - c * c / 4)
    return math.exp(-c * t / 2) * (math.cos(w * t) + c / (2 * w) * math.sin(w * t))


def on_a_line():
    return lg.System.from_lagrangian("1/2 (x'^2 + y'^2) - 1/2 (x^2 + y^2)", ["x", "y"]).with_constraint("y - x")


SPLITTING = ["leapfrog", "verlet", "yoshida4", "yoshida6", "yoshida8", "blanes_moan", "symplectic_euler"]


@pytest.mark.parametrize("method", SPLITTING + ["variational", "variational_trapezoid", "variational_gauss2"])
def test_a_method_that_would_drop_the_dissipation_is_refused_naming_what_works(method):
    with pytest.raises(ValueError, match="forces, dissipation and constraints") as e:
        damped().integrate((0, 20), [1.0, 0.0], method, dt=0.01)
    assert "dop853" in str(e.value) and "gauss6" in str(e.value)


@pytest.mark.parametrize("method,dt", [("dop853", None), ("taylor", None), ("rk4", 1e-3), ("gauss6", 1e-2)])
def test_the_damped_oscillator_decays_as_its_closed_form(method, dt):
    sol = damped().integrate((0, 20), [1.0, 0.0], method, dt=dt)
    assert sol.y[0, -1] == pytest.approx(damped_exact(20.0), abs=1e-7)
    assert abs(sol.y[0, -1]) < 0.01  # not cos(20) = 0.41


def test_hamiltons_equations_of_a_damped_system_are_refused_not_undamped():
    with pytest.raises(ValueError, match="leave out the forces"):
        damped().compile("hamiltonian")
    with pytest.raises(ValueError, match="leave out the forces"):
        damped().compile("separable")
    f = damped().compile()  # W q'' = F with the dissipation
    np.testing.assert_allclose(f(0.0, np.array([0.0, 1.0])), [1.0, -0.5])


def test_a_constrained_system_runs_on_its_constraint_and_splitting_refuses_it():
    with pytest.raises(ValueError, match="these methods can run this system"):
        on_a_line().integrate((0, 2), [1.0, 1.0, 0.0, 0.0], "leapfrog", dt=0.01)
    sol = on_a_line().integrate((0, 2), [1.0, 1.0, 0.0, 0.0], "dop853", tol=1e-12)
    assert sol.names == ["x", "y", "x'", "y'"]
    np.testing.assert_allclose(sol.y[0, -1], math.cos(2.0), atol=1e-8)
    np.testing.assert_allclose(sol.y[1, -1], math.cos(2.0), atol=1e-8)


def test_an_unknown_method_is_refused_with_the_closest_name():
    with pytest.raises(ValueError, match="did you mean `gauss6`"):
        damped().integrate((0, 1), [1.0, 0.0], "gaus6", dt=0.1)


def test_variational_maps_run_from_python_at_their_order(oscillator):
    # ω = 2, x(0) = 1, p(0) = 0: x = cos 2t; the midpoint rule is of order 2.
    errors = []
    for dt in (0.02, 0.01):
        sol = oscillator.integrate((0, 1), [1.0, 0.0], "variational", dt=dt)
        errors.append(abs(sol.y[0, -1] - math.cos(2.0)))
    assert 3.5 < errors[0] / errors[1] < 4.5
