//! The example scenes of issue 11 run end to end: printed derivations snapshotted, numbers
//! checked against closed forms computed here (the oscillator's cosine, the vortex pair's
//! rigid rotation) and conserved quantities.

// The checks read several CSV columns at one row index.
#![allow(clippy::needless_range_loop)]

mod support;

use support::{example as scene, run};

#[test]
fn phase_space_oscillator() {
    let s = scene("phase_space_oscillator");
    let c = s.csv("phase_space_oscillator.csv");
    // m = 2, k = 8: x = cos(2 t), p = m x' = −4 sin(2 t); the velocity columns are z' = ω⁻¹ ∂H/∂z.
    let (m, w) = (2.0, 2.0);
    let mut worst: f64 = 0.0;
    for i in 0..c["t"].len() {
        let t = c["t"][i];
        let (x, p) = ((w * t).cos(), -m * w * (w * t).sin());
        worst = worst.max((c["x"][i] - x).abs()).max((c["p"][i] - p).abs());
        assert!((c["x'"][i] - c["p"][i] / m).abs() < 1e-14, "x' = p/m");
        assert!((c["p'"][i] + 8.0 * c["x"][i]).abs() < 1e-13, "p' = −k x");
    }
    // Gauss4's stability function is the (2, 2) Padé approximant of e^z, whose error is
    // z⁵/720 + O(z⁶) (error constant k! j!/((k+j)! (k+j+1)!)): a phase error of (h ω)⁵/720 per
    // step, times the amplitude m ω of p.
    let (h, steps) = (0.01, 1000.0);
    let bound = 1.2 * m * w * steps * (h * w).powi(5) / 720.0;
    assert!(worst < bound, "gauss4 at dt = 0.01 against the exact cosine: {worst:e} (bound {bound:e})");
    assert_eq!(c["t"].len(), 1001);
}

#[test]
fn point_vortices() {
    let s = scene("point_vortices");
    let c = s.csv("point_vortices.csv");
    let (g1, g2) = (1.0, 0.5);
    let cx = &c["Γ1 x1 + Γ2 x2"];
    let cy = &c["Γ1 y1 + Γ2 y2"];
    let r = &c["sqrt((x1 - x2)^2 + (y1 - y2)^2)"];
    let drift = |v: &[f64]| v.iter().map(|x| (x - v[0]).abs()).fold(0.0, f64::max);
    assert!(drift(cx) < 2e-14 && drift(cy) < 2e-14, "centre of vorticity: {:e} {:e}", drift(cx), drift(cy));
    assert!(drift(r) < 2e-14, "distance: {:e}", drift(r));
    // Rigid rotation at Ω = (Γ1 + Γ2)/(2π r²), checked on the unwrapped angle of x1 − x2.
    let omega = (g1 + g2) / (2.0 * std::f64::consts::PI * r[0] * r[0]);
    let angle = |i: usize| (c["y1"][i] - c["y2"][i]).atan2(c["x1"][i] - c["x2"][i]);
    let mut unwrapped = angle(0);
    for i in 1..c["t"].len() {
        let mut d = angle(i) - angle(i - 1);
        d -= (d / (2.0 * std::f64::consts::PI)).round() * 2.0 * std::f64::consts::PI;
        unwrapped += d;
        let expected = angle(0) + omega * c["t"][i];
        assert!((unwrapped - expected).abs() < 2e-14, "t = {}: angle {unwrapped} vs {expected}", c["t"][i]);
    }
}

#[test]
fn first_order_scene_refuses_velocities_as_initial_data() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.scene");
    std::fs::write(
        &file,
        "coordinates x, p\nparameters m = 1, k = 1\nL = p x' - p^2/(2 m) - k x^2/2\n\
         simulate x = 1, p = 0, x' = 0 for t in 0..1 with rk4 dt = 0.1\nexport to run.csv\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let (code, _, err) = run(&["run", file.to_str().unwrap(), "--out-dir", out.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("first order") && err.contains("x'"), "{err}");
    assert!(!out.join("run.csv").exists());
    // A degenerate two-form: y has no one-form term.
    std::fs::write(
        &file,
        "coordinates x, p, y\nparameters m = 1\nL = p x' - p^2/(2 m) - x^2/2 - y^2\n\
         simulate x = 1, p = 0, y = 0 for t in 0..1 with rk4 dt = 0.1\nexport to run.csv\n",
    )
    .unwrap();
    let (code, _, err) = run(&["run", file.to_str().unwrap(), "--out-dir", out.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("degenerate") && err.contains("(0, 0, 1)"), "{err}");
    assert!(!out.join("run.csv").exists());
}

#[test]
fn variational_integrator() {
    let s = scene("variational_integrator");
    let c = s.csv("variational_long.csv");
    // Symplectic: the energy error of the midpoint map over 40,000 steps (32 orbits) is
    // bounded, the last tenth no worse than the first.
    let e0 = c["H"][0];
    let de: Vec<f64> = c["H"].iter().map(|e| (e - e0).abs()).collect();
    let tenth = de.len() / 10;
    let first = de[..tenth].iter().cloned().fold(0.0, f64::max);
    let last = de[de.len() - tenth..].iter().cloned().fold(0.0, f64::max);
    assert!(first < 1e-3 && last <= 1.5 * first, "max |ΔE| first tenth {first:e}, last tenth {last:e}");
    // Discrete Noether: L is invariant under rotations, so x p_y − y p_x is conserved.
    let lz = &c["x p_y - y p_x"];
    let drift = lz.iter().map(|v| (v - lz[0]).abs() / lz[0].abs()).fold(0.0, f64::max);
    assert!(drift <= 1e-12, "relative drift of x p_y − y p_x: {drift:e}");
    // Orders from the work-precision runs (steps 4:1 apart): the final position's distance
    // from the DOP853 reference falls like 4² for the midpoint map and 4⁴ for gauss2.
    let end = |file: &str| {
        let c = s.csv(file);
        let k = c["t"].len() - 1;
        assert_eq!(c["t"][k], 20.0);
        (c["x"][k], c["y"][k])
    };
    let reference = end("variational_reference.csv");
    let err = |file: &str| {
        let (x, y) = end(file);
        (x - reference.0).hypot(y - reference.1)
    };
    for (a, b, order) in
        [("variational_v1.csv", "variational_v3.csv", 2.0), ("variational_g1.csv", "variational_g3.csv", 4.0)]
    {
        let (ea, eb) = (err(a), err(b));
        let observed = (ea / eb).ln() / 4f64.ln();
        assert!((observed - order).abs() < 0.25, "{a} → {b}: errors {ea:e}, {eb:e}, order {observed:.3}");
    }
    let svg = std::fs::read_to_string(s.out.join("variational_work_precision.svg")).unwrap();
    for m in ["variational", "variational_gauss2", "leapfrog", "gauss4"] {
        assert!(svg.contains(&format!("\n{m}\n")), "the work-precision diagram has no line for {m}");
    }
}

#[test]
fn variational_method_refuses_events_and_forces() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.scene");
    let out = dir.path().join("out");
    for (extra, sim_tail, needle) in [("", "record when x = 0", "events"), ("force x = -x'\n", "", "forces")] {
        std::fs::write(
            &file,
            format!(
                "coordinates x\nL = x'^2/2 - x^2/2\n{extra}simulate x = 1, x' = 0 for t in 0..1 with variational dt = 0.1 {sim_tail}\nexport to run.csv\n"
            ),
        )
        .unwrap();
        let (code, _, err) = run(&["run", file.to_str().unwrap(), "--out-dir", out.to_str().unwrap()]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains(needle) || err.contains("event"), "{err}");
        assert!(err.contains(":4:") || err.contains(":3:"), "no source location: {err}");
        assert!(!out.join("run.csv").exists());
    }
}

#[test]
fn geodesic_sphere() {
    let s = scene("geodesic_sphere");
    let c = s.csv("geodesic_sphere.csv");
    let u = |th: f64, ph: f64| [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
    let du = |th: f64, ph: f64, dth: f64, dph: f64| {
        [
            dth * th.cos() * ph.cos() - dph * th.sin() * ph.sin(),
            dth * th.cos() * ph.sin() + dph * th.sin() * ph.cos(),
            -dth * th.sin(),
        ]
    };
    // The plane of the great circle through the start: normal u × u'.
    let (a, b) = (u(c["θ"][0], c["φ"][0]), du(c["θ"][0], c["φ"][0], c["θ'"][0], c["φ'"][0]));
    let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let mut worst: f64 = 0.0;
    for i in 0..c["t"].len() {
        let p = u(c["θ"][i], c["φ"][i]);
        worst = worst.max((p[0] * n[0] + p[1] * n[1] + p[2] * n[2]).abs() / norm);
    }
    assert!(worst < 1e-10, "distance from the great circle's plane: {worst:e}");
    // Constant speed along a great circle: the arc covered is speed × t.
    let speed = c["θ'^2 + sin(θ)^2 φ'^2"][0].sqrt();
    let k = c["t"].len() - 1;
    let arc = (u(c["θ"][k], c["φ"][k]).iter().zip(a.iter()).map(|(x, y)| x * y).sum::<f64>()).acos();
    let turns = speed * c["t"][k] / (2.0 * std::f64::consts::PI);
    let expected = {
        let r = (speed * c["t"][k]) % (2.0 * std::f64::consts::PI);
        r.min(2.0 * std::f64::consts::PI - r)
    };
    assert!((arc - expected).abs() < 1e-9, "arc {arc} vs {expected} ({turns} turns)");
    for col in ["sin(θ)^2 φ'", "θ'^2 + sin(θ)^2 φ'^2"] {
        let v = &c[col];
        let drift = v.iter().map(|x| (x - v[0]).abs()).fold(0.0, f64::max);
        assert!(drift < 1e-11, "{col} drifts by {drift:e}");
    }
}
