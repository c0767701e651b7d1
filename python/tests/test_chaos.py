"""Chaos tools from Python: `megno`, `lyapunov`, `fli`, `chaos_map`, `poincare` and the state
transition matrix `variational`, computed by the library's own chaos routines (the values the
scene statements print, checked against the command line), with hand-derived and second-route
checks."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import lagrangian as lg
from conftest import DOUBLE_PENDULUM, DP_PARAMS

ROOT = Path(__file__).resolve().parents[2]
LOW = {"θ1": 0.3, "θ2": 0.2, "θ1'": 0.0, "θ2'": 0.0}
HIGH = {"θ1": 2.0, "θ2": 2.5, "θ1'": 0.0, "θ2'": 0.0}


@pytest.fixture(scope="module")
def dp():
    return lg.System.from_lagrangian(DOUBLE_PENDULUM, ["θ1", "θ2"], params=DP_PARAMS, positive=list(DP_PARAMS))


def cli():
    """The command line built next to this package (cargo's target directory)."""
    candidates = [os.environ.get("LAGRANGIAN_BIN")]
    for d in (os.environ.get("CARGO_TARGET_DIR"), ROOT / "target"):
        if d:
            candidates += [Path(d) / "debug" / "lagrangian", Path(d) / "release" / "lagrangian"]
    candidates.append(shutil.which("lagrangian"))
    found = [Path(c) for c in candidates if c and Path(c).is_file()]
    if not found:
        pytest.skip("the command line is not built (cargo build); set LAGRANGIAN_BIN to it")
    return found[0]


def test_values_equal_the_scene_statements(dp, tmp_path):
    scene = tmp_path / "chaos.scene"
    scene.write_text(
        "coordinates θ1, θ2\n"
        "parameters m1 = 1, m2 = 1, l1 = 1, l2 = 1, g = 9.81 positive\n"
        "L = 1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2)"
        " + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)\n"
        "megno θ1 = 0.3, θ2 = 0.2, θ1' = 0, θ2' = 0 for t in 0..20 as low\n"
        "megno θ1 = 2.0, θ2 = 2.5, θ1' = 0, θ2' = 0 for t in 0..20 as high\n"
        "fli θ1 = 2.0, θ2 = 2.5, θ1' = 0, θ2' = 0 for t in 0..20 as f\n"
        "lyapunov θ1 = 2.0, θ2 = 2.5, θ1' = 0, θ2' = 0 for t in 0..20 as spectrum\n",
        encoding="utf-8",
    )
    out = subprocess.run(
        [str(cli()), "run", str(scene), "--out-dir", str(tmp_path)], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    lines = {line.split(":")[0]: line for line in out.stdout.splitlines()}
    for name, start in (("low", LOW), ("high", HIGH)):
        r = dp.indicators((0, 20), start, "megno")
        assert (
            f"MEGNO ⟨Y⟩ = {r.megno:.4f} at t = 20 (λ = {r.megno_lyapunov:.6f} from the slope of Y; {r.steps} Taylor steps)"
            in lines[name]
        )
    r = dp.indicators((0, 20), HIGH, "fli")
    assert f"FLI = {r.fli:.4f} at t = 20 ({r.steps} Taylor steps)" in lines["f"]
    spectrum = ", ".join(f"{x:.6f}" for x in dp.lyapunov((0, 20), HIGH))
    assert spectrum in lines["spectrum"]


def test_regular_and_chaotic_orbits(dp):
    # Cincotta & Simó: ⟨Y⟩ stays near 2 or below on regular motion, grows like λT/2 on chaos.
    assert dp.megno((0, 50), LOW) < 2.5
    high = dp.indicators((0, 50), HIGH, "megno")
    assert high.megno > 8 and abs(high.megno / (high.lyapunov[0] * 50 / 2) - 1) < 0.5
    # Liouville: the spectrum of a Hamiltonian flow sums to 0 and comes in ± pairs.
    spec = dp.lyapunov((0, 50), HIGH)
    assert spec.shape == (4,) and abs(spec.sum()) < 1e-6 and abs(spec[0] + spec[3]) < 0.1
    assert dp.fli((0, 50), HIGH) > dp.fli((0, 50), LOW)


def test_megno_of_the_harmonic_oscillator_tends_to_zero():
    # Isochronous motion: ⟨Y⟩ → 0 (Cincotta & Simó 2000); the pendulum's period depends on the
    # amplitude, so its small swings have ⟨Y⟩ → 2.
    osc = lg.System.from_lagrangian("1/2 x'^2 - 2 x^2", ["x"])
    assert abs(osc.megno((0, 200), {"x": 1.0, "x'": 0.0})) < 0.05
    pend = lg.System.from_lagrangian("1/2 θ'^2 + cos(θ)", ["θ"])
    assert abs(pend.megno((0, 2000), {"θ": 1.0, "θ'": 0.0}) - 2) < 0.1


def test_state_transition_matrix_of_the_oscillator():
    # H = p²/2 + 2x² (ω = 2): Φ(t) = [[cos ωt, sin ωt / ω], [−ω sin ωt, cos ωt]] by hand.
    osc = lg.System.from_hamiltonian("p_x^2/2 + 2 x^2", ["x"])
    phi, end = osc.variational((0, 1.3), [0.7, 0.1])
    w, t = 2.0, 1.3
    expected = [[np.cos(w * t), np.sin(w * t) / w], [-w * np.sin(w * t), np.cos(w * t)]]
    np.testing.assert_allclose(phi, expected, atol=1e-11)
    assert abs(np.linalg.det(phi) - 1) < 1e-11
    np.testing.assert_allclose(end[0], 0.7 * np.cos(w * t) + 0.1 / w * np.sin(w * t), atol=1e-11)


def test_state_transition_matrix_against_finite_differences(dp):
    # A second route: central differences of integrated end states, (q, p) start by start.
    x0 = dp.canonical_start(LOW)
    phi, end = dp.variational((0, 1.0), x0)
    ham = dp.legendre()
    names = ham.state_names("dop853")
    assert names == dp.canonical_names
    h = 1e-6
    fd = np.empty((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        plus = ham.integrate((0, 1.0), x0 + e, rtol=1e-13, atol=1e-13).y[:, -1]
        minus = ham.integrate((0, 1.0), x0 - e, rtol=1e-13, atol=1e-13).y[:, -1]
        fd[:, j] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(phi, fd, atol=1e-6)
    np.testing.assert_allclose(end, ham.integrate((0, 1.0), x0, rtol=1e-13, atol=1e-13).y[:, -1], atol=1e-10)


def test_the_initial_tangent_vector(dp):
    default = dp.megno((0, 20), HIGH)
    # e₁ is the default; a scaled one is normalised first: the same numbers.
    assert dp.megno((0, 20), HIGH, tangent=[1.0, 0, 0, 0]) == default
    assert dp.megno((0, 20), HIGH, tangent=[3.0, 0, 0, 0]) == default
    # Another direction is another (valid) measurement: same regime, not the same digits.
    other = dp.megno((0, 20), HIGH, tangent=[0, 0, 1.0, 1.0])
    assert other != default and other > 4
    with pytest.raises(lg.ArgumentError, match="tangent must be 4 finite numbers, not all zero"):
        dp.megno((0, 20), HIGH, tangent=[0, 0, 0, 0])
    with pytest.raises(ValueError, match="tangent must be 4"):
        dp.megno((0, 20), HIGH, tangent=[1.0, 0])


def test_chaos_map_is_an_xarray_of_the_single_orbit_values(dp):
    m = dp.chaos_map((0, 10), {"θ1": [0.3, 2.0], "θ2": [0.2, 2.5]}, {"θ1'": 0.0, "θ2'": 0.0})
    assert m.dims == ("θ1", "θ2") and m.shape == (2, 2) and m.name == "megno"
    np.testing.assert_array_equal(m["θ1"].values, [0.3, 2.0])
    assert m.sel({"θ1": 0.3, "θ2": 0.2}).item() == dp.megno((0, 10), LOW)
    assert m.sel({"θ1": 2.0, "θ2": 2.5}).item() == dp.megno((0, 10), HIGH)
    fli = dp.chaos_map((0, 10), {"θ1": [2.0]}, {"θ2": 2.5, "θ1'": 0.0, "θ2'": 0.0}, which="fli")
    # A map of the FLI integrates without MEGNO's accumulator (as the scene's chaos_map does),
    # so its steps differ from the single orbit's (which carries it): close, not identical.
    assert fli.item() == pytest.approx(dp.fli((0, 10), HIGH), rel=1e-3)


def test_poincare_section_is_the_runs_crossings(dp):
    sec = dp.poincare((0, 20), [2.0, 2.5, 0.0, 0.0], "θ1", rtol=1e-12)
    sol = dp.integrate((0, 20), [2.0, 2.5, 0.0, 0.0], rtol=1e-12, events=[lg.Event("θ1", direction=1)])
    np.testing.assert_array_equal(sec["t"], sol.t_events[0])
    np.testing.assert_array_equal(sec["θ2"], sol.y_events[0][:, 1])
    assert len(sec["t"]) > 3 and np.all(np.abs(sec["θ1"]) < 1e-9) and np.all(sec["θ1'"] > 0)


def test_chaos_refusals(dp):
    damped = lg.System.from_lagrangian("1/2 x'^2 - 1/2 x^2", ["x"], rayleigh="1/2 c x'^2", params={"c": 0.1})
    with pytest.raises(lg.ArgumentError, match="leave out the forces, dissipation and constraints"):
        damped.megno((0, 10), {"x": 1.0, "x'": 0.0})
    with pytest.raises(lg.ArgumentError, match="leave out"):
        damped.variational((0, 10), [1.0, 0.0])
    with pytest.raises(lg.ArgumentError, match="measured from t = 0"):
        dp.megno((1, 10), HIGH)
    with pytest.raises(lg.ArgumentError, match="every velocity"):
        dp.megno((0, 10), {"θ1": 1.0, "θ2": 1.0, "θ1'": 0.0})
    with pytest.raises(ValueError, match="unknown indicator"):
        dp.indicators((0, 10), HIGH, "entropy")


def test_chaos_map_megno_stop_marks_the_stopped_cells(dp):
    grid = {"θ1": [0.3, 2.0], "θ2": [0.2, 2.5]}
    rest = {"θ1'": 0.0, "θ2'": 0.0}
    plain = dp.chaos_map((0, 50), grid, rest)
    m = dp.chaos_map((0, 50), grid, rest, megno_stop=(3.0, 5.0))
    assert "stopped_at" not in plain.coords
    assert m.attrs["megno_stop_above"] == 3.0 and m.attrs["megno_stop_after"] == 5.0
    # The regular cell runs to the end, bit for bit as without the stop.
    low = {"θ1": 0.3, "θ2": 0.2}
    assert np.isnan(m["stopped_at"].sel(low).item())
    assert m.sel(low).item() == plain.sel(low).item() < 3.0
    # The chaotic cell stops where its full run's Ȳ(t) first reaches 3 after t = 5.
    high = {"θ1": 2.0, "θ2": 2.5}
    full = dp.indicators((0, 50), HIGH)
    k = np.flatnonzero((full.t >= 5.0) & (full.megno_t >= 3.0))[0]
    assert k + 1 < len(full.t), "the full run crosses 3 before its end"
    assert m["stopped_at"].sel(high).item() == full.t[k]
    assert m.sel(high).item() == full.megno_t[k] >= 3.0
    assert plain.sel(high).item() == full.megno


def test_chaos_map_megno_stop_refusals(dp):
    grid = {"θ1": [2.0]}
    rest = {"θ2": 2.5, "θ1'": 0.0, "θ2'": 0.0}
    with pytest.raises(lg.ArgumentError, match="megno` only"):
        dp.chaos_map((0, 10), grid, rest, which="fli", megno_stop=(5.0, 1.0))
    with pytest.raises(lg.ArgumentError, match="above 2"):
        dp.chaos_map((0, 10), grid, rest, megno_stop=(2.0, 1.0))
    with pytest.raises(lg.ArgumentError, match="at least 0"):
        dp.chaos_map((0, 10), grid, rest, megno_stop=(5.0, -1.0))
    with pytest.raises(lg.ArgumentError, match=r"\(above, after\)"):
        dp.chaos_map((0, 10), grid, rest, megno_stop=(5.0,))
