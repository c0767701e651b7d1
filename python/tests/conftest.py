"""Shared model systems (the same ones the Rust tests use: pendulum, oscillator, double
pendulum), with expected values derived independently in each test."""

import atexit
import math
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# The derivation cache of this run (and of the Dask workers and scripts it starts, which
# inherit the environment) lives in a fresh directory: tests neither read the user's
# ~/.cache/lagrangian nor write to it.
_CACHE = tempfile.mkdtemp(prefix="lagrangian-test-cache-")
os.environ["LAGRANGIAN_CACHE_DIR"] = _CACHE
atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)

import lagrangian as lg  # noqa: E402

# The type stubs of the native module (read by the tests that check what they document).
STUB_PATH = Path(lg.__file__).with_name("_core.pyi")

PENDULUM = "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))"
DOUBLE_PENDULUM = (
    "1/2 (m1 + m2) l1^2 θ1'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + 1/2 m2 l2^2 θ2'^2"
    " + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)"
)
DP_PARAMS = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "g": 9.81}


@pytest.fixture
def pendulum():
    return lg.System.from_lagrangian(
        PENDULUM, ["θ"], params={"m": 1.0, "l": 2.0, "g": 9.81}, positive=["m", "l", "g"]
    )


@pytest.fixture
def oscillator():
    # ω = 2: x(t) = x0 cos 2t + v0/2 sin 2t.
    return lg.System.from_lagrangian("1/2 m x'^2 - 1/2 k x^2", ["x"], params={"m": 1.0, "k": 4.0})


@pytest.fixture
def double_pendulum():
    return lg.System.from_lagrangian(DOUBLE_PENDULUM, ["θ1", "θ2"], params=DP_PARAMS, positive=list(DP_PARAMS))


def pendulum_energy(y, m=1.0, l=2.0, g=9.81):
    θ, w = y
    return 0.5 * m * l**2 * w**2 - m * g * l * math.cos(θ)
