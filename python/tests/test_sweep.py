"""Sweeps on a Dask LocalCluster with 2 worker processes: a grid of initial angles with a
chunk that fails, a worker killed mid-sweep (Dask reschedules its tasks), a parameter grid,
and a chunk lost for good when Dask allows no failures."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import lagrangian as lg

distributed = pytest.importorskip("dask.distributed")


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def pendulum():
    return lg.System.from_lagrangian(
        "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", ["θ"], params={"m": 1.0, "l": 1.0, "g": 1.0}, positive=["m", "l", "g"]
    )


def test_sweep_reports_failed_points_and_survives_a_killed_worker(client):
    sys = pendulum()
    # θ0 over a grid with NaN in it: the chunk holding the NaN fails point by point.
    theta = np.linspace(-2.5, 2.5, 64)
    theta[5] = np.nan
    grid = {"θ": theta}
    t_span = (0.0, 2000.0)
    result = {}

    def run():
        result["r"] = lg.sweep(sys, t_span, grid, "rk4", y0={"θ'": 0.0}, dt=0.01, chunk_size=4, client=client)

    pids_before = set(client.run(os.getpid).values())
    th = threading.Thread(target=run)
    th.start()
    # Kill one worker process while it is integrating a chunk.
    deadline = time.time() + 60
    victim = None
    while time.time() < deadline and victim is None:
        busy = [w for w, tasks in client.processing().items() if tasks]
        if busy:
            victim = busy[0]
        else:
            time.sleep(0.05)
    assert victim is not None, "no worker ever got a task"
    pid = client.run(os.getpid, workers=[victim])[victim]
    os.kill(pid, signal.SIGKILL)
    th.join(timeout=300)
    assert not th.is_alive()
    r = result["r"]
    assert pid in pids_before and pid not in set(client.run(os.getpid).values())

    assert r.y.shape == (64, 2) and r.t.shape == (64,) and r.names == ["θ", "θ'"]
    assert r.ok.sum() == 63 and not r.ok[5]
    assert len(r.failures) == 1
    f = r.failures[0]
    assert f["index"] == (5,) and np.isnan(f["values"]["θ"]) and "NaN" in f["reason"]
    # Every other point equals the same integration done locally.
    local = sys.ensemble(t_span, np.column_stack([theta, np.zeros(64)]), "rk4", dt=0.01)
    ok = r.ok
    np.testing.assert_array_equal(r.y[ok], local.y[ok])
    np.testing.assert_array_equal(r["θ"][ok], local.y[ok, 0])


def test_parameter_grid_and_state_grid(client):
    sys = pendulum()
    r = lg.sweep(
        sys, (0.0, 1.0), {"θ": [0.1, 0.2], "g": [1.0, 4.0, float("inf")]}, "gauss6", y0=[0.0, 0.0], dt=0.01, client=client
    )
    assert r.y.shape == (2, 3, 2)
    assert r.ok[:, :2].all() and not r.ok[:, 2].any()
    assert "non-finite" in r.errors[0, 2]
    for i, θ0 in enumerate([0.1, 0.2]):
        for j, g in enumerate([1.0, 4.0]):
            ref = sys.with_params(g=g).integrate((0, 1), [θ0, 0.0], "gauss6", dt=0.01)
            assert r.y[i, j, 0] == ref.y[0, -1]
    # An array of states is a flat list of points.
    states = np.array([[0.1, 0.0], [0.2, 0.1], [0.3, -0.1]])
    flat = lg.sweep(sys, (0, 1), states, tol=1e-10, chunk_size=2, client=client)
    assert flat.y.shape == (3, 2) and flat.ok.all()
    with pytest.raises(ValueError, match="is neither a state variable"):
        lg.sweep(sys, (0, 1), {"x": [1.0]}, client=client)
    with pytest.raises(ValueError, match="needs a step"):
        lg.sweep(sys, (0, 1), states, "rk4", client=client)


def test_to_xarray_matches_the_numpy_result(client):
    xr = pytest.importorskip("xarray")
    sys = pendulum()
    theta, g = [0.1, 0.2, 0.3], [1.0, 4.0]
    r = lg.sweep(sys, (0.0, 1.0), {"θ": theta, "g": g}, "gauss6", y0=[0.0, 0.0], dt=0.01, client=client)
    ds = r.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert dict(ds.sizes) == {"θ": 3, "g": 2}
    for name in ("θ_final", "θ'_final", "t_final", "ok"):
        assert ds[name].dims == ("θ", "g")
    np.testing.assert_array_equal(ds["θ_final"].values, r.y[..., 0])
    np.testing.assert_array_equal(ds["θ'_final"].values, r["θ'"])
    np.testing.assert_array_equal(ds["t_final"].values, r.t)
    np.testing.assert_array_equal(ds["ok"].values, r.ok)
    # The swept values are the coordinates, so a point is selected by its values.
    np.testing.assert_array_equal(ds.coords["θ"].values, theta)
    np.testing.assert_array_equal(ds.coords["g"].values, g)
    ref = sys.with_params(g=4.0).integrate((0, 1), [0.2, 0.0], "gauss6", dt=0.01)
    assert float(ds["θ_final"].sel(θ=0.2, g=4.0)) == ref.y[0, -1]
    assert ds.attrs == {"method": "gauss6", "t0": 0.0, "t1": 1.0, "failed": 0}
    # A grid of states has one dimension, `point`, and failures are counted.
    states = np.array([[0.1, 0.0], [float("nan"), 0.0]])
    flat = lg.sweep(sys, (0, 1), states, client=client).to_xarray()
    assert flat["θ'_final"].dims == ("point",) and flat.sizes["point"] == 2
    assert list(flat["ok"].values) == [True, False] and flat.attrs["failed"] == 1


def test_workers_share_the_on_disk_derivation_cache(client, tmp_path):
    # A Lagrangian no other test derives, so every count below is this test's.
    text = "1/2 m (x'^2 + y'^2) - 1/4 k (x^4 + y^4) - c x y + 1/2 m x' y' cos(x - y)"
    sys = lg.System.from_lagrangian(text, ["x", "y"], params={"m": 1.0, "k": 1.0, "c": 0.3}, positive=["m"])
    workers = sorted(client.scheduler_info()["workers"])
    assert len(workers) == 2
    before = client.run(lg.cache_info)
    old_dirs = {w: i["dir"] for w, i in before.items()}
    client.run(lg.set_cache_dir, str(tmp_path))
    try:

        def compile_here(system):
            system.compile()
            return lg.cache_info()

        first = client.run(compile_here, sys, workers=[workers[0]])[workers[0]]
        second = client.run(compile_here, sys, workers=[workers[1]])[workers[1]]
        # The first process derived W q'' = F once and wrote it; the second loaded it.
        assert first["dir"] == str(tmp_path) == second["dir"]
        assert first["derived"] - before[workers[0]]["derived"] == 1
        assert second["derived"] - before[workers[1]]["derived"] == 0
        assert second["hits"] - before[workers[1]]["hits"] == 1
        assert len(list(tmp_path.glob("*.json"))) == 1
        # A parameter sweep (a new System per parameter row) derives nothing more anywhere,
        # and gives what this process computes on its own.
        r = lg.sweep(sys, (0.0, 2.0), {"c": [0.0, 0.3, 0.6]}, y0=[1.0, 0.5, 0.0, 0.0], chunk_size=1, client=client)
        after = client.run(lg.cache_info)
        assert sum(after[w]["derived"] - before[w]["derived"] for w in workers) == 1
        for j, c in enumerate([0.0, 0.3, 0.6]):
            ref = sys.with_params(c=c).integrate((0.0, 2.0), [1.0, 0.5, 0.0, 0.0])
            np.testing.assert_array_equal(r.y[j], ref.y[:, -1])
    finally:
        for w, d in old_dirs.items():
            client.run(lg.set_cache_dir, d, workers=[w])


def test_a_chunk_lost_for_good_is_reported_and_the_rest_returns():
    import dask

    sys = pendulum()
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
        client = distributed.Client(cluster)
        try:
            grid = {"θ": np.linspace(0.1, 1.0, 6)}
            result = {}
            th = threading.Thread(
                target=lambda: result.update(
                    r=lg.sweep(sys, (0, 20000.0), grid, "rk4", y0=[0.0, 0.0], dt=0.01, chunk_size=2, client=client)
                )
            )
            th.start()
            victim = None
            while victim is None and th.is_alive():
                busy = [w for w, tasks in client.processing().items() if tasks]
                victim = busy[0] if busy else None
                time.sleep(0.02)
            pid = client.run(os.getpid, workers=[victim])[victim]
            os.kill(pid, signal.SIGKILL)
            th.join(timeout=300)
        finally:
            client.close()
            cluster.close()
    r = result["r"]
    lost = [f for f in r.failures if "KilledWorker" in f["reason"]]
    assert lost, r.failures
    assert all("the chunk of points" in f["reason"] for f in lost)
    assert r.ok.sum() == 6 - len(lost) and r.ok.sum() >= 2


def test_sweep_example_script(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "examples" / "sweep.py"
    out = tmp_path / "flip.png"
    run = subprocess.run(
        [sys.executable, str(script), "--n", "6", "--t", "3", "--workers", "1", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, MPLBACKEND="Agg"),
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "36 trajectories" in run.stdout and "0 failed" in run.stdout
    assert out.stat().st_size > 1000


def test_integrate_ensemble_and_compile_run_on_workers(client):
    # The results come back pickled from worker processes and equal the local ones.
    sys = pendulum()
    sol = client.submit(sys.integrate, [0, 5], [1.0, 0.0], rtol=1e-10).result(timeout=120)
    assert sol == sys.integrate([0, 5], [1.0, 0.0], rtol=1e-10)
    starts = np.array([[0.5, 0.0], [1.0, 0.0]])
    ens = client.submit(sys.ensemble, (0, 5), starts, rtol=1e-10).result(timeout=120)
    assert ens == sys.ensemble((0, 5), starts, rtol=1e-10)
    f = client.submit(sys.compile).result(timeout=120)
    assert f == sys.compile()
    np.testing.assert_allclose(f(0.0, np.array([0.5, 0.0])), [0.0, -np.sin(0.5)], rtol=1e-15)
    finals = client.gather(client.map(lambda y0: sys.integrate((0, 5), y0, rtol=1e-10).y[:, -1], list(starts)))
    np.testing.assert_array_equal(np.array(finals), ens.y)


def test_a_sweep_on_a_time_grid_equals_integrate_at_those_times(client):
    """With ``t_eval`` each grid point's ``(n, m)`` is ``integrate``'s at the same times (the
    same engine run, so the same bits), over a state axis and a parameter axis, and the
    xarray view has the grid's axes and ``t``."""
    sys = pendulum()
    times = [0.0, 0.25, 0.5, 1.0]
    r = lg.sweep(sys, (0.0, 1.0), {"θ": [0.1, 0.7], "g": [1.0, 9.0]}, "taylor", y0=[0.0, 0.0], tol=1e-12, t_eval=times, client=client)
    assert r.y.shape == (2, 2, 2, 4) and r.ok.all()
    np.testing.assert_array_equal(r.t, times)
    for i, θ0 in enumerate([0.1, 0.7]):
        for j, g in enumerate([1.0, 9.0]):
            ref = sys.with_params(g=g).integrate((0, 1), [θ0, 0.0], "taylor", tol=1e-12, t_eval=times)
            np.testing.assert_array_equal(r.y[i, j], ref.y)
    np.testing.assert_array_equal(r["θ"], r.y[..., 0, :])
    ds = r.to_xarray()
    assert ds["θ(t)"].dims == ("θ", "g", "t") and list(ds.coords["t"].values) == times
    np.testing.assert_array_equal(ds["θ'(t)"].sel(θ=0.7, g=9.0).values, r.y[1, 1, 1])
    # A grid of states, chunked unevenly: the same as the ensemble of those states.
    states = np.array([[0.1, 0.0], [0.2, 0.1], [2.0, -0.1]])
    flat = lg.sweep(sys, (0, 1), states, "taylor", tol=1e-12, t_eval=times, chunk_size=2, client=client)
    ens = sys.ensemble((0, 1), states, "taylor", tol=1e-12, t_eval=times)
    np.testing.assert_array_equal(flat.y, ens.y)
