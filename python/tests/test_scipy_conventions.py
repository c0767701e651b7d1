"""SciPy's calling conventions: ``t_span`` as any two numbers, ``rtol``/``atol`` (with ``tol``
kept as another name of ``rtol``), and a ``Solution`` with SciPy's ``success``, integer
``status``, ``message`` and ``nfev``; pandas and xarray views of every result. The SciPy
reference is SciPy itself: the same problem through ``solve_ivp`` ends with the same status and
message."""

import math

import numpy as np
import pytest

import lagrangian as lg


@pytest.mark.parametrize("span", [(0, 2), [0, 2], np.array([0.0, 2.0]), range(0, 3, 2)])
def test_any_two_numbers_are_a_time_span(oscillator, span):
    sol = oscillator.integrate(span, [1.0, 0.0], tol=1e-12)
    assert sol.t[0] == 0.0 and sol.t[-1] == 2.0
    assert sol.y[0, -1] == pytest.approx(math.cos(4.0), abs=1e-9)  # x = cos 2t
    ens = oscillator.ensemble(span, [[1.0, 0.0]], tol=1e-12)
    assert ens.y[0, 0] == pytest.approx(math.cos(4.0), abs=1e-9)


@pytest.mark.parametrize("span", [(0, 1, 2), [1.0], "01", 3.0, [0, "a"], np.zeros((2, 2))])
def test_anything_else_is_refused_saying_what_a_span_is(oscillator, span):
    with pytest.raises(ValueError, match="t_span must be two numbers"):
        oscillator.integrate(span, [1.0, 0.0])
    with pytest.raises(ValueError, match="t_span must be two numbers"):
        oscillator.ensemble(span, [[1.0, 0.0]])


def test_rtol_and_atol_are_scipys_names_and_tol_is_rtol(oscillator):
    a = oscillator.integrate((0, 5), [1.0, 0.0], rtol=1e-8, atol=1e-10)
    b = oscillator.integrate((0, 5), [1.0, 0.0], tol=1e-8, atol=1e-10)
    c = oscillator.integrate((0, 5), [1.0, 0.0], rtol=1e-12, atol=1e-10)
    np.testing.assert_array_equal(a.y, b.y)
    assert len(c.t) > len(a.t)  # the tolerance reached the solver
    assert oscillator.integrate((0, 5), [1.0, 0.0], rtol=1e-8, tol=1e-8, atol=1e-10).steps == a.steps
    with pytest.raises(ValueError, match="tol is another name for rtol"):
        oscillator.integrate((0, 5), [1.0, 0.0], rtol=1e-8, tol=1e-6)
    e = oscillator.ensemble((0, 5), [[1.0, 0.0]], rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(e.y[0], a.y[:, -1])


def test_status_success_and_message_are_scipys():
    scipy_integrate = pytest.importorskip("scipy.integrate")
    s = lg.System.from_lagrangian("1/2 x'^2 - 1/2 x^2", ["x"])
    f = s.compile()

    def down(t, y):
        return y[0]

    down.terminal = True
    ref_end = scipy_integrate.solve_ivp(f, (0, 1), [1.0, 0.0])
    ref_event = scipy_integrate.solve_ivp(f, (0, 3), [1.0, 0.0], events=down, rtol=1e-10, atol=1e-12)
    end = s.integrate((0, 1), [1.0, 0.0])
    event = s.integrate((0, 3), [1.0, 0.0], events=[lg.Event("x", terminal=True)])
    assert (end.status, end.success, end.message) == (ref_end.status, ref_end.success, ref_end.message) == (0, True, ref_end.message)
    assert (event.status, event.success, event.message) == (ref_event.status, ref_event.success, ref_event.message)
    assert event.status == 1 and event.stop == "event" and end.stop == "end"
    assert event.t[-1] == pytest.approx(math.pi / 2, abs=1e-9) == pytest.approx(ref_event.t[-1], abs=1e-8)
    assert end.sol is None  # as SciPy's without dense_output; t_eval samples the interpolants


def test_nfev_counts_right_hand_side_evaluations(oscillator):
    # RK4 evaluates f four times a step (its Butcher tableau has four stages).
    sol = oscillator.integrate((0, 1), [1.0, 0.0], "rk4", dt=0.01)
    assert sol.steps == 100 and sol.nfev == 400
    # An adaptive run evaluates more often than it accepts steps.
    assert oscillator.integrate((0, 1), [1.0, 0.0], rtol=1e-10).nfev > 0


def test_a_solution_as_pandas_and_xarray(oscillator):
    pytest.importorskip("pandas")
    pytest.importorskip("xarray")
    sol = oscillator.integrate((0, 1), [1.0, 0.0], t_eval=np.linspace(0, 1, 11), tol=1e-12)
    df = sol.to_pandas()
    assert list(df.columns) == ["x", "x'"] and df.index.name == "t"
    np.testing.assert_array_equal(df.index.to_numpy(), sol.t)
    np.testing.assert_array_equal(df["x"].to_numpy(), sol.y[0])
    np.testing.assert_allclose(df["x"].to_numpy(), np.cos(2 * sol.t), atol=1e-9)
    ds = sol.to_xarray()
    np.testing.assert_array_equal(ds["x'"].values, sol.y[1])
    np.testing.assert_array_equal(ds["t"].values, sol.t)
    assert ds.attrs["method"] == "dop853" and ds.attrs["nfev"] == sol.nfev
    assert float(ds["x"].sel(t=0.5)) == pytest.approx(math.cos(1.0), abs=1e-9)


def test_an_ensemble_as_pandas_and_xarray(oscillator):
    pytest.importorskip("pandas")
    pytest.importorskip("xarray")
    starts = np.array([[1.0, 0.0], [0.5, 0.0], [0.0, 2.0]])
    ens = oscillator.ensemble((0, 1), starts, tol=1e-12)
    df = ens.to_pandas()
    assert list(df.columns) == ["t", "x", "x'", "ok", "error"] and df.index.name == "trajectory"
    # x = x0 cos 2t + v0/2 sin 2t at t = 1.
    exact = starts[:, 0] * math.cos(2) + starts[:, 1] / 2 * math.sin(2)
    np.testing.assert_allclose(df["x"].to_numpy(), exact, atol=1e-9)
    assert df["ok"].all() and df["error"].isna().all()
    ds = ens.to_xarray()
    np.testing.assert_array_equal(ds["x"].values, ens.y[:, 0])
    np.testing.assert_array_equal(ds["t"].values, ens.t)
    assert list(ds["trajectory"].values) == [0, 1, 2]


@pytest.mark.parametrize(
    "kw,match",
    [
        (dict(y0=[float("nan"), 0.0]), "initial value of `x` is NaN"),
        (dict(y0={"x": 1.0, "x'": float("inf")}), "initial value of `x'` is inf"),
        (dict(max_steps=0), "max_steps must be at least 1"),
        (dict(every=0), "every must be at least 1"),
    ],
)
def test_bad_arguments_are_value_errors_not_integration_errors(oscillator, kw, match):
    kw = dict(kw)
    y0 = kw.pop("y0", [1.0, 0.0])
    with pytest.raises(ValueError, match=match) as e:
        oscillator.integrate((0, 1), y0, **kw)
    assert not isinstance(e.value, lg.IntegrationError)
