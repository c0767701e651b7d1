"""Ctrl-C stops every run within 0.2 s and leaves the objects usable: with the progress bar
on, off, and at the moment the bar is being created (about 1 s into a run with the default
``progress=None``), for ``integrate`` and ``ensemble``. Each case runs in a subprocess that
receives a real SIGINT; the two processes read the same monotonic clock, so the delay from the
signal to the ``KeyboardInterrupt`` is measured, not assumed."""

import signal
import subprocess
import sys
import time

import pytest

CHILD = r"""
import sys, time
import numpy as np
import lagrangian as lg
progress = {"on": True, "off": False, "auto": None}[sys.argv[1]]
s = lg.System.from_lagrangian("1/2 x'^2 - 1/2 x^2", ["x"])
s.integrate((0, 0.1), [1.0, 0.0], "rk4", dt=1e-2)  # compiled before the clock starts
print("ready", flush=True)
try:
    if sys.argv[2] == "integrate":
        s.integrate((0, 5e4), [1.0, 0.0], "rk4", dt=1e-4, every=10**9, progress=progress)
    else:
        s.ensemble((0, 5e4), np.tile([1.0, 0.0], (8, 1)), "rk4", dt=1e-4, progress=progress)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("interrupted", time.monotonic(), flush=True)
sol = s.integrate((0, 1), [1.0, 0.0], tol=1e-12)
print("usable", sol.y[0, -1], flush=True)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process is POSIX")
@pytest.mark.parametrize(
    "progress,call,delay",
    [
        ("off", "integrate", 0.3),
        ("on", "integrate", 0.3),
        ("auto", "integrate", 0.3),
        # The bar of the default mode is created about 1 s in: the signal lands around it.
        ("auto", "integrate", 0.95),
        ("auto", "integrate", 1.0),
        ("auto", "integrate", 1.05),
        ("off", "ensemble", 0.3),
        ("auto", "ensemble", 1.0),
    ],
)
def test_ctrl_c_raises_keyboard_interrupt_within_a_fifth_of_a_second(progress, call, delay):
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, progress, call],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout.readline().strip() == "ready"
        time.sleep(delay)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=20)
    finally:
        child.kill()
    lines = out.splitlines()
    assert lines and lines[0].startswith("interrupted"), (out, err)
    assert float(lines[0].split()[1]) - sent < 0.2, (out, err)
    # The system integrates again after the interrupt: x = cos t.
    assert lines[1].startswith("usable") and abs(float(lines[1].split()[1]) - 0.5403023058681398) < 1e-9
