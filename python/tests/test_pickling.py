"""Every result travels: ``Solution``, ``EnsembleResult`` and ``CompiledRhs`` pickle and
come back equal, and cross a process boundary (what Dask, ``ProcessPoolExecutor`` and joblib
need)."""

import concurrent.futures
import math
import multiprocessing
import pickle

import numpy as np
import pytest

import lagrangian as lg


def oscillator():
    return lg.System.from_lagrangian("1/2 m x'^2 - 1/2 k x^2", ["x"], params={"m": 1.0, "k": 4.0})


def test_a_solution_with_events_round_trips_equal():
    sol = oscillator().integrate((0, 3), [1.0, 0.0], events=["x", lg.Event("x", direction=1, terminal=True)])
    back = pickle.loads(pickle.dumps(sol))
    assert back == sol and back is not sol
    assert back.stop == "event" and back.status == 1 and back.nfev == sol.nfev and back.method == "dop853"
    np.testing.assert_array_equal(back.y_events[1], sol.y_events[1])
    # Equality looks at the numbers: a different run is not equal.
    assert sol != oscillator().integrate((0, 3), [1.0, 0.1])


def test_an_ensemble_with_a_failed_trajectory_round_trips_equal():
    # The second start needs more than 20 steps over (0, 50): it fails, its row is NaN.
    ens = oscillator().ensemble((0, 50), [[0.0, 0.0], [1.0, 0.0]], max_steps=20)
    assert list(ens.ok) == [True, False] and np.isnan(ens.y[1]).all()
    back = pickle.loads(pickle.dumps(ens))
    assert back == ens and back.errors == ens.errors and back.errors[1]


def test_a_compiled_rhs_round_trips_equal_and_evaluates_the_same():
    f = oscillator().compile()
    back = pickle.loads(pickle.dumps(f))
    assert back == f and back.names == ["x", "x'"]
    y = np.array([0.3, -0.7])
    np.testing.assert_array_equal(back(0.0, y), f(0.0, y))
    np.testing.assert_array_equal(back(0.0, y), [-0.7, -4 * 0.3])  # x'' = -k/m x
    np.testing.assert_array_equal(back.jac(0.0, y), [[0.0, 1.0], [-4.0, 0.0]])
    h = pickle.loads(pickle.dumps(oscillator().compile("hamiltonian")))
    assert h.names == ["x", "p_x"] and h != f


def _run(sys):
    return sys.integrate((0, 1), [1.0, 0.0], tol=1e-12), sys.ensemble((0, 1), [[1.0, 0.0]], tol=1e-12), sys.compile()


def test_results_come_back_from_another_process():
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx) as pool:
        sol, ens, f = pool.submit(_run, oscillator()).result(timeout=120)
    here = _run(oscillator())
    assert sol == here[0] and ens == here[1] and f == here[2]
    assert sol.y[0, -1] == pytest.approx(math.cos(2.0), abs=1e-9)
    np.testing.assert_array_equal(f(0.0, np.array([1.0, 0.0])), [0.0, -4.0])
