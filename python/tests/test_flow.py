"""`System.flow` (the scene's `flow` statement and `lagrangian flow` from Python: Φ(T),
det Φ − 1 and the symplectic defect, the same printed lines) and `chaos_map(..., client=)` on a
Dask cluster, equal bit for bit to the local map."""

import pickle
import subprocess

import numpy as np
import pytest

import lagrangian as lg
from conftest import DOUBLE_PENDULUM, DP_PARAMS
from test_chaos import cli


@pytest.fixture(scope="module")
def dp():
    return lg.System.from_lagrangian(DOUBLE_PENDULUM, ["θ1", "θ2"], params=DP_PARAMS, positive=list(DP_PARAMS))


def test_flow_prints_the_command_lines_lines():
    pend = lg.System.from_hamiltonian("p_q^2/2 - cos(q)", ["q"])
    f = pend.flow((0, 6.5), {"q": 1.2, "p_q": 0.1})
    out = subprocess.run(
        [str(cli()), "flow", "p_q^2/2 - cos(q)", "--coords", "q", "--at", "q=1.2,p_q=0.1", "--time", "6.5"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert f.lines == out.stdout.splitlines()
    assert str(f) == out.stdout.rstrip("\n")
    # A Hamiltonian flow: both residuals at round-off level, and Φ is the state transition
    # matrix of `variational` (a second route through the library, at the same tolerance).
    assert abs(f.det_minus_one) <= 1e-12 and f.symplectic_defect is not None and f.symplectic_defect <= 1e-12
    phi, end = pend.variational((0, 6.5), [1.2, 0.1], tol=1e-14)
    np.testing.assert_array_equal(f.phi, phi)
    np.testing.assert_array_equal(f.end, end)
    assert f.t[0] == 0 and f.t[-1] == 6.5 and f.det_minus_one_t[-1] == f.det_minus_one


def test_flow_of_a_damped_oscillator_loses_volume_as_exp_minus_gamma_t():
    # m x'' = −b x' − k x: tr ∂f/∂x = −b/m, so det Φ(t) = e^{−bt/m} (Liouville's formula), the
    # same in (x, p = m x') as in (x, x').
    m, b, k = 2.0, 0.6, 5.0
    osc = lg.System.from_lagrangian("1/2 m x'^2 - 1/2 k x^2", ["x"], params={"m": m, "b": b, "k": k}, rayleigh="1/2 b x'^2")
    f = osc.flow((0, 4.0), {"x": 1.0, "x'": 0.5})
    assert f.symplectic_defect is None and np.isnan(f.symplectic_defect_t).all()
    assert abs(f.det_minus_one - (np.exp(-b / m * 4.0) - 1)) < 1e-13
    np.testing.assert_allclose(f.det_minus_one_t, np.expm1(-b / m * f.t), rtol=0, atol=1e-13)
    assert f.lines[-1].startswith("no symplectic defect")


def test_flow_refuses_constraints():
    sys = lg.System.from_lagrangian("1/2 (x'^2 + y'^2) - y", ["x", "y"], constraints=["x^2 + y^2 - 1"])
    with pytest.raises(Exception, match="constrained system"):
        sys.flow((0, 1.0), [1.0, 0.0, 0.0, 0.0])


def test_a_dask_chaos_map_equals_the_local_one_bit_for_bit(dp):
    distributed = pytest.importorskip("dask.distributed")
    grid = {"θ1": np.linspace(-2, 2, 4), "θ2": np.linspace(-2.5, 2.5, 3)}
    rest = {"θ1'": 0.0, "θ2'": 0.0}
    local = dp.chaos_map((0, 10), grid, rest)
    with distributed.Client(processes=False, n_workers=2, threads_per_worker=1, dashboard_address=None) as client:
        # Chunks of 5 do not divide the 12 starts: the last chunk is short.
        remote = dp.chaos_map((0, 10), grid, rest, client=client, chunk_size=5)
        fli_remote = dp.chaos_map((0, 10), grid, rest, which="fli", client=client, chunk_size=1)
    assert type(remote) is type(local) and remote.dims == local.dims and remote.name == "megno"
    assert remote.values.tobytes() == local.values.tobytes()
    for axis in grid:
        np.testing.assert_array_equal(remote[axis].values, local[axis].values)
    assert fli_remote.values.tobytes() == dp.chaos_map((0, 10), grid, rest, which="fli").values.tobytes()
    # The values are the single-orbit ones, so a regular and a chaotic cell differ.
    assert np.nanmax(local.values) > 4 and np.nanmin(local.values) < 3


def test_a_chunk_computed_by_an_unpickled_system_is_the_same(dp):
    # What a worker process receives: the system pickled (as its source) and a chunk of starts.
    from lagrangian._chaos import _chaos_chunk

    rows = np.array([dp.canonical_start({"θ1": 0.3, "θ2": 0.2, "θ1'": 0.0, "θ2'": 0.0}), dp.canonical_start({"θ1": 2.0, "θ2": 2.5, "θ1'": 0.0, "θ2'": 0.0})])
    again = pickle.loads(pickle.dumps(dp))
    assert _chaos_chunk(again, (0, 10), rows, "megno", None).tobytes() == dp._chaos_map((0, 10), rows, "megno").tobytes()


def test_a_dask_chaos_map_checks_its_request_before_submitting(dp):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as client:
        with pytest.raises(lg.ArgumentError, match="unknown indicator"):
            dp.chaos_map((0, 10), {"θ1": [0.1]}, {"θ2": 0.0, "θ1'": 0.0, "θ2'": 0.0}, which="nope", client=client)
        with pytest.raises(lg.ArgumentError, match="chunk_size"):
            dp.chaos_map((0, 10), {"θ1": [0.1]}, {"θ2": 0.0, "θ1'": 0.0, "θ2'": 0.0}, client=client, chunk_size=0)


def test_the_scenes_chaos_map_equals_pythons_local_and_dask_maps(dp, tmp_path):
    # A second route: the scene's chaos_map written as a table (values in shortest round-trip
    # form) against Python's map at the same cell centres a + (b − a)(k + ½)/N.
    distributed = pytest.importorskip("dask.distributed")
    scene = tmp_path / "map.scene"
    scene.write_text(
        "coordinates θ1, θ2\n"
        "parameters m1 = 1, m2 = 1, l1 = 1, l2 = 1, g = 9.81 positive\n"
        "L = 1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2)"
        " + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)\n"
        "chaos_map megno θ1 = -2..2, θ2 = -2.5..2.5, θ1' = 0, θ2' = 0 for t in 0..10 points 3 to map.csv\n",
        encoding="utf-8",
    )
    out = subprocess.run([str(cli()), "run", str(scene), "--out-dir", str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    rows = [line.split(",") for line in (tmp_path / "map.csv").read_text().splitlines()[1:]]
    side = 3
    centres = lambda a, b: [a + (b - a) * (k + 0.5) / side for k in range(side)]  # noqa: E731
    grid = {"θ1": centres(-2.0, 2.0), "θ2": centres(-2.5, 2.5)}
    local = dp.chaos_map((0, 10), grid, {"θ1'": 0.0, "θ2'": 0.0})
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as client:
        remote = dp.chaos_map((0, 10), grid, {"θ1'": 0.0, "θ2'": 0.0}, client=client, chunk_size=4)
    # The table runs row by row with θ2 outer; the DataArray is indexed [θ1, θ2].
    for j in range(side):
        for i in range(side):
            x, y, v = rows[j * side + i]
            assert (float(x), float(y)) == (grid["θ1"][i], grid["θ2"][j])
            assert float(v) == local.values[i, j] == remote.values[i, j]


def test_a_chaos_map_on_worker_processes_equals_the_local_one(dp):
    # Across a process boundary: the system is pickled as its source and derived again there.
    distributed = pytest.importorskip("dask.distributed")
    grid = {"θ1": [0.3, 2.0], "θ2": [0.2, 2.5]}
    rest = {"θ1'": 0.0, "θ2'": 0.0}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            remote = dp.chaos_map((0, 10), grid, rest, client=client, chunk_size=1)
    assert remote.values.tobytes() == dp.chaos_map((0, 10), grid, rest).values.tobytes()
