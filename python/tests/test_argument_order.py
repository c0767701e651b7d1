"""One argument order everywhere: `t_span` first, then the initial state(s), as in SciPy's
`solve_ivp(fun, t_span, y0)`: `integrate(t_span, y0)`, `ensemble(t_span, y0)`,
`sweep(system, t_span, grid)`. The order `ensemble` and `sweep` used to take is refused naming
the new one, never read with the arguments swapped."""

import numpy as np
import pytest

import lagrangian as lg


def test_ensemble_takes_t_span_first(oscillator):
    starts = np.array([[1.0, 0.0], [0.0, 2.0]])
    r = oscillator.ensemble((0, 1), starts, tol=1e-12)
    # ω = 2: x(1) = x0 cos 2 + v0/2 sin 2.
    np.testing.assert_allclose(r.y[:, 0], [np.cos(2.0), np.sin(2.0)], atol=1e-9)
    # Keywords in either order are the same call.
    assert oscillator.ensemble(y0=starts, t_span=(0, 1), tol=1e-12) == r


@pytest.mark.parametrize("starts", [[[1.0, 0.0], [0.0, 2.0]], [[1.0, 0.0]], np.zeros((3, 2))])
def test_the_old_ensemble_order_is_refused_naming_the_new(oscillator, starts):
    with pytest.raises(ValueError, match=r"ensemble takes t_span first: ensemble\(t_span, y0") as e:
        oscillator.ensemble(starts, (0, 1), tol=1e-12)
    assert isinstance(e.value, lg.ArgumentError)


def test_a_state_of_two_numbers_is_not_mistaken_for_a_span(oscillator):
    # A (1, 2) table of one start, given first, with a real span second, is still refused: the
    # two-number test reads shapes, and (1, 2) is not (2,).
    with pytest.raises(ValueError, match="takes t_span first"):
        oscillator.ensemble(np.array([[0.0, 1.0]]), [0.0, 1.0])
    # Neither argument a span: the plain t_span message.
    with pytest.raises(ValueError, match="t_span must be two numbers"):
        oscillator.ensemble([[1.0, 0.0]], [[1.0, 0.0]])


def test_the_old_sweep_order_is_refused_naming_the_new(oscillator):
    # Refused before any cluster starts (client=None would start one).
    with pytest.raises(ValueError, match=r"sweep takes t_span first: sweep\(system, t_span, grid"):
        lg.sweep(oscillator, {"x": [1.0, 2.0]}, (0, 1), y0=[0.0, 0.0])
    with pytest.raises(lg.ArgumentError, match="sweep takes t_span first"):
        lg.sweep(oscillator, np.array([[1.0, 0.0], [2.0, 0.0]]), (0, 1))
    with pytest.raises(lg.ArgumentError, match="t_span must be two numbers"):
        lg.sweep(oscillator, {"x": [1.0]}, {"x": [1.0]})


def test_layouts_are_documented():
    # SciPy's (n, k) for a time series; (k, n) for the ensemble, with the reason given.
    assert "(n, k)" in lg.Solution.__doc__
    doc = lg.System.ensemble.__doc__
    assert "(k, n)" in doc and "not" in doc and "SciPy" in doc
    assert "grid point" in lg.SweepResult.__doc__
