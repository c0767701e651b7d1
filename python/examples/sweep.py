"""A Dask sweep of the double pendulum: the time until the lower rod first flips over (|θ2|
passes π), over a grid of initial angles, drawn as an image — the classic picture of where
the motion is regular and where it is chaotic.

    python python/examples/sweep.py                       # a LocalCluster on this machine
    python python/examples/sweep.py --scheduler tcp://host:8786 --n 400

Each task integrates a chunk of the grid in the Rust core; points that never flip within the
time span keep t = T (the colour of "no flip").
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import lagrangian as lg

L = (
    "1/2 (m1 + m2) l1^2 θ1'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + 1/2 m2 l2^2 θ2'^2"
    " + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)"
)
PARAMS = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "g": 9.81}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=120, help="grid points per axis")
    ap.add_argument("--t", type=float, default=10.0, help="time span")
    ap.add_argument("--scheduler", default=None, help="address of a running Dask scheduler")
    ap.add_argument("--workers", type=int, default=2, help="local workers (without --scheduler)")
    ap.add_argument("--out", default="flip_time.png")
    args = ap.parse_args()

    from dask.distributed import Client, LocalCluster

    if args.scheduler:
        client = Client(args.scheduler)
    else:
        client = Client(LocalCluster(n_workers=args.workers, threads_per_worker=1, dashboard_address=None))
    system = lg.System.from_lagrangian(L, ["θ1", "θ2"], params=PARAMS, positive=list(PARAMS))
    angles = np.linspace(-3.0, 3.0, args.n)
    # A terminal event: the lower rod passes the upright position, θ2 = ±π.
    flip = [lg.Event("θ2 - 3.141592653589793", terminal=True), lg.Event("θ2 + 3.141592653589793", terminal=True)]
    start = time.perf_counter()
    result = lg.sweep(
        system,
        (0.0, args.t),
        {"θ1": angles, "θ2": angles},
        "dop853",
        y0={"θ1'": 0.0, "θ2'": 0.0},
        tol=1e-9,
        events=flip,
        chunk_size=400,
        client=client,
    )
    elapsed = time.perf_counter() - start
    print(f"{result.t.size} trajectories in {elapsed:.2f} s ({result.t.size / elapsed:.0f}/s), {len(result.failures)} failed")
    for f in result.failures[:5]:
        print("failed:", f)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 5))
    im = ax.imshow(result.t.T, origin="lower", extent=(-3, 3, -3, 3), cmap="magma", interpolation="nearest")
    ax.set_xlabel("θ1(0)")
    ax.set_ylabel("θ2(0)")
    ax.set_title("double pendulum: time until the lower rod flips")
    fig.colorbar(im, label="t")
    fig.savefig(args.out, dpi=120, bbox_inches="tight")
    print("wrote", args.out)
    client.close()


if __name__ == "__main__":
    main()
