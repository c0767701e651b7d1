"""`CompiledRhs.jac` reads every input form alike and equals finite differences of `f`. Its
cost per call against `f` (2.0–2.4× after reading the array in place, 9.5–19× before) is a
benchmark row (`python/benchmarks/bench.py`, section 2), not a timed test."""

import numpy as np
import pytest

import lagrangian as lg
from conftest import DOUBLE_PENDULUM, DP_PARAMS


@pytest.fixture(scope="module")
def f():
    return lg.System.from_lagrangian(DOUBLE_PENDULUM, ["θ1", "θ2"], params=DP_PARAMS, positive=list(DP_PARAMS)).compile()


def test_jac_reads_every_input_form_alike(f):
    y = np.array([0.3, -0.2, 0.1, 0.4])
    j = f.jac(0.0, y)
    assert j.shape == (4, 4)
    # A list, a strided view and an int array (converted) give the same matrix.
    np.testing.assert_array_equal(f.jac(0.0, list(y)), j)
    np.testing.assert_array_equal(f.jac(0.0, np.repeat(y, 2)[::2]), j)
    np.testing.assert_array_equal(f.jac(0.0, np.array([1, 0, 0, 0])), f.jac(0.0, np.array([1.0, 0, 0, 0])))
    # Against central differences of f (a second route).
    h = 1e-6
    fd = np.column_stack([(f(0.0, y + h * e) - f(0.0, y - h * e)) / (2 * h) for e in np.eye(4)])
    np.testing.assert_allclose(j, fd, atol=1e-6)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        f.jac(0.0, np.zeros(3))
    with pytest.raises(ValueError, match=r"shape \[4, 1\]"):
        f.jac(0.0, np.zeros((4, 1)))
