"""`Solution.sol(t)` (dense output) and `t_events`/`y_events` as SciPy's `solve_ivp` has them.

`sol` is the cubic Hermite interpolant of the accepted steps (states and right-hand side at
each), so its error between steps is bounded by h⁴/384 · max|y''''| (the classical bound for
cubic Hermite interpolation); on the oscillator x = cos 2t that is h⁴/24. The tests check the
bound, the fourth order (halving h divides the error by 16), and that it is not a nearest-sample
lookup (which would be off by about h·|x'|/2)."""

import pickle

import numpy as np
import pytest

import lagrangian as lg


def midpoints(t):
    return 0.5 * (t[:-1] + t[1:])


def test_sol_interpolates_between_steps_within_the_hermite_bound(oscillator):
    # gauss6 is sixth order: at dt = 0.1 the states are exact to ~1e-9, far below the
    # interpolation error h⁴/24 ≈ 4.2e-6 it is checked against.
    sol = oscillator.integrate((0, 3), [1.0, 0.0], "gauss6", dt=0.1, dense_output=True)
    tm = midpoints(sol.t)
    x = sol.sol(tm)[0]
    err = np.abs(x - np.cos(2 * tm)).max()
    assert err <= 0.1**4 / 24 * 1.01
    # Not the nearest sample: that is off by up to h/2·|x'| = 0.05·2.
    nearest = np.abs(np.cos(2 * sol.t[:-1]) - np.cos(2 * tm)).max()
    assert err < nearest / 1000
    # At the step times it is the states themselves.
    np.testing.assert_array_equal(sol.sol(sol.t), sol.y)


def test_sol_is_fourth_order(oscillator):
    errs = []
    for dt in (0.1, 0.05):
        sol = oscillator.integrate((0, 3), [1.0, 0.0], "gauss6", dt=dt, dense_output=True)
        tm = midpoints(sol.t)
        errs.append(np.abs(sol.sol(tm)[0] - np.cos(2 * tm)).max())
    assert 14 < errs[0] / errs[1] < 18, errs


def test_sol_shapes_and_span(oscillator):
    sol = oscillator.integrate((0, 1), [1.0, 0.0], rtol=1e-10, dense_output=True)
    assert sol.sol(0.5).shape == (2,)
    assert sol.sol(np.linspace(0, 1, 7)).shape == (2, 7)
    assert sol.sol.t_min == 0.0 and sol.sol.t_max == 1.0
    np.testing.assert_array_equal(sol.sol.ts, sol.t)
    with pytest.raises(lg.ArgumentError, match=r"outside it"):
        sol.sol(1.5)
    with pytest.raises(ValueError, match=r"outside it"):
        sol.sol([0.5, -0.1])
    # Without dense_output, as SciPy.
    assert oscillator.integrate((0, 1), [1.0, 0.0]).sol is None


def test_sol_of_a_backward_run(oscillator):
    sol = oscillator.integrate((1, 0), [np.cos(2.0), -2 * np.sin(2.0)], "gauss6", dt=0.05, dense_output=True)
    t = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(sol.sol(t)[0], np.cos(2 * t), atol=0.05**4 / 24 * 1.01 + 1e-9)


def test_sol_with_t_eval(oscillator):
    te = np.linspace(0, 2, 9)
    sol = oscillator.integrate((0, 2), [1.0, 0.0], rtol=1e-12, t_eval=te, dense_output=True)
    np.testing.assert_array_equal(sol.t, te)
    np.testing.assert_allclose(sol.y[0], np.cos(2 * te), atol=1e-10)
    # The interpolant comes from a run that kept every step, so it has more points than t_eval.
    assert sol.sol.ts.size > te.size
    np.testing.assert_allclose(sol.sol(te), sol.y, atol=1e-5)


def test_dense_output_refusals(oscillator):
    with pytest.raises(lg.ArgumentError, match="every step"):
        oscillator.integrate((0, 1), [1.0, 0.0], every=2, dense_output=True)
    with pytest.raises(lg.ArgumentError, match="discrete map"):
        oscillator.integrate((0, 1), [1.0, 0.0], "variational", dt=0.01, dense_output=True)


def test_dense_solution_pickles(oscillator):
    sol = oscillator.integrate((0, 1), [1.0, 0.0], "rk4", dt=0.1, dense_output=True)
    back = pickle.loads(pickle.dumps(sol))
    assert back == sol
    np.testing.assert_array_equal(back.sol(0.55), sol.sol(0.55))


def test_t_events_and_y_events_as_scipy(oscillator):
    # None without events (SciPy's), one array per event with them, crossings equal to
    # SciPy's DOP853 on the same equations.
    assert oscillator.integrate((0, 1), [1.0, 0.0]).t_events is None
    assert oscillator.integrate((0, 1), [1.0, 0.0]).y_events is None
    scipy_integrate = pytest.importorskip("scipy.integrate")
    sol = oscillator.integrate((0, 4), [1.0, 0.0], rtol=1e-12, atol=1e-12, events=["x", lg.Event("x'", direction=1)])

    def x(t, y):
        return y[0]

    def v(t, y):
        return y[1]

    v.direction = 1
    ref = scipy_integrate.solve_ivp(
        lambda t, y: [y[1], -4 * y[0]], (0, 4), [1.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12, events=[x, v]
    )
    assert len(sol.t_events) == 2 and len(sol.y_events) == 2
    for mine, theirs in zip(sol.t_events, ref.t_events):
        np.testing.assert_allclose(mine, theirs, atol=1e-9)
    for mine, theirs in zip(sol.y_events, ref.y_events):
        assert mine.shape == theirs.shape
        np.testing.assert_allclose(mine, theirs, atol=1e-9)
