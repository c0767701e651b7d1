"""compile / integrate / ensemble: shapes and dtypes, batch against scalar, SciPy interop,
accuracy against exact solutions, events, the GIL, and errors for bad input."""

import math
import pickle
import threading
import time

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import System

from conftest import pendulum_energy


def test_compiled_rhs_matches_the_equations(pendulum):
    f = pendulum.compile()
    assert f.dim == 2 and f.names == ["θ", "θ'"]
    dy = f(0.0, np.array([0.5, 0.25]))
    assert dy.shape == (2,) and dy.dtype == np.float64
    assert dy[0] == 0.25
    assert dy[1] == pytest.approx(-9.81 / 2.0 * math.sin(0.5), rel=1e-14)
    # Lists and integer arrays are converted.
    np.testing.assert_array_equal(f(0.0, [0.5, 0.25]), dy)
    np.testing.assert_array_equal(f(0.0, np.array([1, 0])), f(0.0, np.array([1.0, 0.0])))


KEPLER = lg.System.from_hamiltonian("(p_x^2 + p_y^2)/2 - 1/sqrt(x^2 + y^2)", ["x", "y"])


@pytest.mark.parametrize("formulation", ["lagrangian", "hamiltonian", "separable"])
def test_batch_equals_scalar(double_pendulum, formulation):
    # The double pendulum's H is not separable; Kepler's is.
    f = KEPLER.compile(formulation) if formulation == "separable" else double_pendulum.compile(formulation)
    rng = np.random.default_rng(7)
    Y = rng.uniform(-2, 2, size=(4, 9))
    out = f(0.0, Y)
    assert out.shape == (4, 9) and out.dtype == np.float64
    for j in range(Y.shape[1]):
        np.testing.assert_allclose(out[:, j], f(0.0, Y[:, j]), rtol=1e-13, atol=1e-15)
    # A non-contiguous view gives the same.
    np.testing.assert_allclose(f(0.0, np.asfortranarray(Y)), out, rtol=0, atol=0)


def test_empty_and_unaligned_arrays(pendulum):
    f = pendulum.compile()
    # An array that does not start on an 8-byte boundary (as unpickled data may not).
    raw = b"\0" + np.array([0.5, 0.25, 0.1, 0.0]).tobytes()
    odd = np.frombuffer(raw, dtype=np.float64, offset=1)
    assert odd.ctypes.data % 8 != 0
    np.testing.assert_array_equal(f(0.0, odd[:2]), f(0.0, np.array([0.5, 0.25])))
    np.testing.assert_array_equal(f(0.0, odd.reshape(2, 2)), f(0.0, np.array([[0.5, 0.25], [0.1, 0.0]])))
    r = pendulum.ensemble((0, 1), odd.reshape(2, 2))
    assert r.ok.all()
    assert f(0.0, np.zeros((2, 0))).shape == (2, 0)
    r = pendulum.ensemble((0, 1), np.zeros((0, 2)))
    assert r.y.shape == (0, 2) and r.t.shape == (0,) and r.errors == []
    assert lg.Expr("2 x").evaluate(x=np.zeros(0)).shape == (0,)


def test_wrong_shapes_are_value_errors(pendulum):
    f = pendulum.compile()
    with pytest.raises(ValueError, match=r"\(2,\)"):
        f(0.0, np.zeros(3))
    with pytest.raises(ValueError, match=r"\(2, k\)"):
        f(0.0, np.zeros((3, 2)))
    with pytest.raises(ValueError):
        f(0.0, np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="y0 has shape"):
        pendulum.integrate((0, 1), [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="y0 has shape"):
        pendulum.ensemble((0, 1), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="formulation"):
        pendulum.compile("newtonian")
    dp = lg.System.from_lagrangian("1/2 (x'^2 + y'^2) + x' y' cos(x - y)", ["x", "y"])
    # Refused by the engine's route, naming the term that mixes q and p and what can run it.
    with pytest.raises(ValueError, match="needs a separable H") as e:
        dp.compile("separable")
    assert "cos(x - y)" in str(e.value) and "gauss6" in str(e.value)


def test_singular_mass_matrix_at_a_state():
    # W = diag(1, x²) is singular at x = 0.
    s = System.from_lagrangian("1/2 x'^2 + 1/2 x^2 y'^2 - 1/2 y^2", ["x", "y"])
    f = s.compile()
    with pytest.raises(lg.RhsError, match="singular"):
        f(0.0, np.array([0.0, 1.0, 0.0, 0.0]))
    # The same start given to integrate is a bad y0 (a ValueError), not a failed run.
    with pytest.raises(lg.RhsError, match="initial state .*singular"):
        s.integrate((0, 1), [0.0, 1.0, 0.0, 0.0], "rk4", dt=0.01)


def test_nan_start_is_an_argument_error(pendulum):
    # A NaN start is a bad argument (ValueError), not a run that failed (IntegrationError).
    with pytest.raises(ValueError, match="initial value of `θ` is NaN") as e:
        pendulum.integrate((0, 1), [float("nan"), 0.0])
    assert not isinstance(e.value, lg.IntegrationError)


def test_bad_integration_requests(pendulum):
    with pytest.raises(ValueError, match="needs a step"):
        pendulum.integrate((0, 1), [0.1, 0.0], "gauss6")
    with pytest.raises(ValueError, match="tol"):
        pendulum.integrate((0, 1), [0.1, 0.0], "dop853", dt=0.1)
    with pytest.raises(ValueError, match="unknown method `rk45`"):
        pendulum.integrate((0, 1), [0.1, 0.0], "rk45")
    # Every method of the engine's registry runs here; the discrete variational maps in their
    # own state, the coordinates and the discrete momenta.
    assert "variational" in lg.METHODS and "taylor" in lg.METHODS
    assert pendulum.state_names("variational") == ["θ", "p_θ"]
    with pytest.raises(ValueError, match="positive"):
        pendulum.integrate((0, 1), [0.1, 0.0], "rk4", dt=-0.1)
    with pytest.raises(ValueError, match="outside"):
        pendulum.integrate((0, 1), [0.1, 0.0], t_eval=[0.5, 2.0])
    with pytest.raises(ValueError, match="not a state variable"):
        pendulum.integrate((0, 1), {"θ": 0.1, "x": 0.0})


def test_dop853_matches_the_exact_oscillator(oscillator):
    t_eval = np.linspace(0, 10, 51)
    sol = oscillator.integrate((0, 10), [1.0, 0.5], t_eval=t_eval, tol=1e-12)
    assert sol.t.shape == (51,) and sol.y.shape == (2, 51) and sol.y.dtype == np.float64
    np.testing.assert_array_equal(sol.t, t_eval)
    exact = np.cos(2 * t_eval) + 0.25 * np.sin(2 * t_eval)
    np.testing.assert_allclose(sol["x"], exact, atol=1e-9)
    np.testing.assert_allclose(sol.y[1], -2 * np.sin(2 * t_eval) + 0.5 * np.cos(2 * t_eval), atol=1e-9)
    assert sol.status == 0 and sol.stop == "end" and sol.steps > 0 and sol.method == "dop853"
    # Every step kept, from t0 to t1.
    full = oscillator.integrate((0, 10), {"x": 1.0, "x'": 0.5})
    assert full.t[0] == 0.0 and full.t[-1] == 10.0 and full.y.shape == (2, len(full.t))


@pytest.mark.parametrize("method,dt", [("gauss6", 0.05), ("rk4", 0.005), ("yoshida8", 0.05), ("leapfrog", 0.001)])
def test_fixed_step_methods_conserve_energy(pendulum, method, dt):
    sol = pendulum.integrate((0, 5), [2.0, 0.0], method, dt=dt, every=10)
    e0 = pendulum_energy([2.0, 0.0])
    if sol.names[1] == "p_θ":  # splitting methods integrate (θ, p_θ): θ' = p/(m l²)
        w = sol.y[1] / 4.0
    else:
        w = sol.y[1]
    drift = max(abs(pendulum_energy([a, b]) - e0) for a, b in zip(sol.y[0], w))
    assert drift < 1e-5 * abs(e0)
    assert sol.t[-1] == 5.0


def test_events_find_the_pendulum_period(pendulum):
    scipy_special = pytest.importorskip("scipy.special")
    θ0 = 1.0
    sol = pendulum.integrate((0, 20), [θ0, 0.0], events=[lg.Event("θ", direction=-1)], tol=1e-12)
    # Downward crossings of θ = 0 are a period apart: T = 4 K(sin²(θ0/2)) / ω, ω² = g/l.
    period = 4 * scipy_special.ellipk(math.sin(θ0 / 2) ** 2) / math.sqrt(9.81 / 2.0)
    te = sol.t_events[0]
    assert len(te) >= 2 and sol.y_events[0].shape == (len(te), 2)
    np.testing.assert_allclose(np.diff(te), period, rtol=1e-9)
    np.testing.assert_allclose(te[0], period / 4, rtol=1e-9)
    ev = pickle.loads(pickle.dumps(lg.Event(lg.Expr("θ"), terminal=True)))
    assert ev.terminal and ev.direction == 0 and ev.expr == lg.Expr("θ")
    stop = pendulum.integrate((0, 20), [θ0, 0.0], events=[ev])
    assert stop.status == 1 and stop.stop == "event" and stop.t[-1] == pytest.approx(period / 4, rel=1e-8)


def test_solve_ivp_interop(double_pendulum):
    integrate = pytest.importorskip("scipy.integrate")
    f = double_pendulum.compile()
    y0 = [1.0, 0.5, 0.0, 0.0]
    ref = double_pendulum.integrate((0, 3), y0, tol=1e-12)
    sp = integrate.solve_ivp(f, (0, 3), y0, method="DOP853", rtol=1e-12, atol=1e-12)
    assert sp.success
    np.testing.assert_allclose(sp.y[:, -1], ref.y[:, -1], atol=1e-8)
    vec = integrate.solve_ivp(f, (0, 0.5), y0, method="Radau", vectorized=True, rtol=1e-8, atol=1e-8)
    assert vec.success
    np.testing.assert_allclose(vec.y[:, -1], double_pendulum.integrate((0, 0.5), y0, tol=1e-12).y[:, -1], atol=1e-5)


def test_ensemble_final_states_and_failures(oscillator):
    Y0 = np.array([[1.0, 0.0], [0.0, 2.0], [float("nan"), 0.0], [0.5, -1.0]])
    r = oscillator.ensemble((0, 3), Y0, tol=1e-12, threads=2)
    assert r.y.shape == (4, 2) and r.t.shape == (4,) and r.ok.dtype == np.bool_
    assert list(r.ok) == [True, True, False, True]
    assert r.errors[2] is not None and "NaN" in r.errors[2] and r.errors[0] is None
    assert np.isnan(r.y[2]).all()
    for i in (0, 1, 3):
        x0, v0 = Y0[i]
        assert r.y[i, 0] == pytest.approx(x0 * math.cos(6) + v0 / 2 * math.sin(6), abs=1e-9)
        assert r.t[i] == 3.0
    # The same trajectories one by one.
    one = oscillator.integrate((0, 3), Y0[1], tol=1e-12)
    np.testing.assert_array_equal(one.y[:, -1], r.y[1])


def test_integration_releases_the_gil(double_pendulum):
    # While another thread integrates, this one must be able to run Python code: with the GIL
    # held it could only record `t_main` after the integration returned.
    marks = {}

    def work():
        marks["start"] = time.perf_counter()
        double_pendulum.integrate((0, 3000), [2.0, 1.0, 0.0, 0.0], tol=1e-12, progress=False)
        marks["end"] = time.perf_counter()

    th = threading.Thread(target=work)
    th.start()
    while "start" not in marks:
        time.sleep(0.001)
    time.sleep(0.05)
    t_main = time.perf_counter()
    th.join()
    assert marks["end"] - marks["start"] > 0.1, "the run is too short to tell"
    assert t_main < marks["end"]


def test_progress_bar_reaches_the_end(pendulum, capsys):
    pendulum.integrate((0, 50), [1.0, 0.0], "gauss6", dt=0.01, progress=True)
    err = capsys.readouterr().err
    assert "100.0%" in err or "1000/1000" in err


@pytest.mark.parametrize("method,dt,atol", [("dop853", None, 1e-9), ("gauss6", 0.01, 1e-9), ("taylor", None, 1e-9)])
def test_t_eval_with_events(oscillator, method, dt, atol):
    # x'' = -4 x from x = 1 at rest: x = cos 2t, zero at t = π/4 + kπ/2, falling for even k.
    t_eval = np.linspace(0, 10, 101)
    kw = dict(t_eval=t_eval, dt=dt) if dt else dict(t_eval=t_eval, tol=1e-13)
    sol = oscillator.integrate((0, 10), [1.0, 0.0], method, events=["x", lg.Event("x", direction=-1)], **kw)
    zeros = np.pi / 4 + np.arange(6) * np.pi / 2
    assert sol.status == 0 and sol.stop == "end"
    np.testing.assert_array_equal(sol.t, t_eval)
    np.testing.assert_allclose(sol["x"], np.cos(2 * t_eval), atol=atol)
    np.testing.assert_allclose(sol.t_events[0], zeros, atol=atol)
    np.testing.assert_allclose(sol.t_events[1], zeros[::2], atol=atol)
    np.testing.assert_allclose(sol.y_events[0][:, 1], -2 * np.sin(2 * zeros), atol=atol)
    # A terminal event: the first upward zero, at 3π/4. t_eval is sampled up to it.
    stop = oscillator.integrate((0, 10), [1.0, 0.0], method, events=[lg.Event("x", direction=1, terminal=True)], **kw)
    assert stop.status == 1 and stop.stop == "event"
    assert stop.t_events[0] == pytest.approx([3 * np.pi / 4], abs=atol)
    kept = t_eval[t_eval <= 3 * np.pi / 4]
    np.testing.assert_array_equal(stop.t, kept)
    assert stop.y.shape == (2, len(kept)) == (2, 24)
    np.testing.assert_allclose(stop.y[0], np.cos(2 * kept), atol=atol)


def test_taylor_is_the_taylor_method(pendulum, oscillator):
    # Not DOP853 under another name (as it once was): at one tolerance the Taylor method, of
    # order 16 there against DOP853's 8, takes far fewer steps.
    t = oscillator.integrate((0, 10), [1.0, 0.0], "taylor", tol=1e-13)
    d = oscillator.integrate((0, 10), [1.0, 0.0], "dop853", tol=1e-13)
    assert t.method == "taylor" and t.rejected == 0 and t.steps < d.steps / 2
    assert t["x"][-1] == pytest.approx(math.cos(20), abs=1e-13)
    # Hamiltonian systems too, in (q, p).
    h = lg.System.from_hamiltonian("p_x^2/2 + 2 x^2", ["x"])
    sol = h.integrate((0, 10), [1.0, 0.0], "taylor", tol=1e-15)
    assert sol.names == ["x", "p_x"] and sol["x"][-1] == pytest.approx(math.cos(20), abs=1e-13)
    r = pendulum.ensemble((0, 5), np.array([[1.0, 0.0], [2.0, 0.0]]), "taylor")
    assert r.ok.all()
    np.testing.assert_allclose(r.y, pendulum.ensemble((0, 5), np.array([[1.0, 0.0], [2.0, 0.0]]), tol=1e-13).y, atol=1e-8)


def finite_difference_jacobian(f, t, y, h=1e-6):
    cols = []
    for j in range(len(y)):
        e = np.zeros(len(y))
        e[j] = h
        cols.append((f(t, y + e) - f(t, y - e)) / (2 * h))
    return np.column_stack(cols)


@pytest.mark.parametrize("formulation", ["lagrangian", "hamiltonian"])
def test_exact_jacobian_against_finite_differences(double_pendulum, formulation):
    f = double_pendulum.compile(formulation)
    rng = np.random.default_rng(3)
    for _ in range(3):
        y = rng.uniform(-1.5, 1.5, 4)
        J = f.jac(0.0, y)
        assert J.shape == (4, 4) and J.dtype == np.float64
        np.testing.assert_allclose(J, finite_difference_jacobian(f, 0.0, y), rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match=r"\(4,\)"):
        f.jac(0.0, np.zeros((4, 2)))
    # Separable: Hamilton's equations of the same H, so the same Jacobian.
    k = KEPLER.compile("separable")
    y = np.array([1.0, 0.3, -0.2, 0.9])
    np.testing.assert_allclose(k.jac(0.0, y), finite_difference_jacobian(k, 0.0, y), rtol=1e-6, atol=1e-7)


def test_exact_jacobian_drives_a_stiff_solve():
    integrate = pytest.importorskip("scipy.integrate")
    # x'' + c x' + x = 0 with c = 1000: rates λ = (-c ± sqrt(c² - 4))/2 ≈ -1000 and -0.001.
    c = 1000.0
    s = System.from_lagrangian("1/2 x'^2 - 1/2 x^2", ["x"], rayleigh="1/2 c x'^2", params={"c": c})
    f = s.compile()
    l1, l2 = (-c + math.sqrt(c * c - 4)) / 2, (-c - math.sqrt(c * c - 4)) / 2
    # x(0) = 1, x'(0) = 0: x = (l2 e^{l1 t} - l1 e^{l2 t}) / (l2 - l1).
    exact = lambda t: (l2 * math.exp(l1 * t) - l1 * math.exp(l2 * t)) / (l2 - l1)  # noqa: E731
    for method in ("Radau", "BDF", "LSODA"):
        sol = integrate.solve_ivp(f, (0, 10), [1.0, 0.0], method=method, jac=f.jac, rtol=1e-8, atol=1e-10)
        assert sol.success and sol.njev >= 1, method
        assert sol.y[0, -1] == pytest.approx(exact(10.0), rel=1e-5), method
    explicit = integrate.solve_ivp(f, (0, 4), [1.0, 0.0], method="RK45", rtol=1e-8, atol=1e-10)
    radau = integrate.solve_ivp(f, (0, 4), [1.0, 0.0], method="Radau", jac=f.jac, rtol=1e-8, atol=1e-10)
    # Stiff: the explicit method is held to |h λ| ≲ 3 by stability, the implicit one is not.
    assert explicit.nfev > 10 * radau.nfev
