//! `lagrangian flow`: the flow's Jacobian Φ(T) with Liouville's and the symplectic check
//! (notes §4.6.1), against the oscillator's exact flow, finite differences of the flow itself,
//! and the refusal of a misnamed momentum.

use crate::support::run;

/// `(end, Φ rows, det Φ − 1, symplectic defect)` of `lagrangian flow … --format json`.
fn flow(h: &str, coords: &str, at: &str, time: f64) -> (Vec<f64>, Vec<Vec<f64>>, f64, f64) {
    let t = time.to_string();
    let (code, out, err) = run(&["flow", h, "--coords", coords, "--at", at, "--time", &t, "--format", "json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let nums =
        |x: &serde_json::Value| -> Vec<f64> { x.as_array().unwrap().iter().map(|y| y.as_f64().unwrap()).collect() };
    let phi = v["phi"].as_array().unwrap().iter().map(nums).collect();
    (nums(&v["end"]), phi, v["det_minus_one"].as_f64().unwrap(), v["symplectic_defect"].as_f64().unwrap())
}

#[test]
fn the_oscillators_flow_is_a_rotation() {
    // q(t) = q0 cos t + p0 sin t, p(t) = −q0 sin t + p0 cos t: Φ = [[cos T, sin T], [−sin T, cos T]].
    let t: f64 = 7.3;
    let (end, phi, det, defect) = flow("p_q^2/2 + q^2/2", "q", "q=0.6,p_q=-0.2", t);
    let exact = [[t.cos(), t.sin()], [-t.sin(), t.cos()]];
    for i in 0..2 {
        for j in 0..2 {
            assert!((phi[i][j] - exact[i][j]).abs() < 1e-13, "Φ[{i}][{j}] = {} against {}", phi[i][j], exact[i][j]);
        }
    }
    assert!((end[0] - (0.6 * t.cos() - 0.2 * t.sin())).abs() < 1e-13);
    assert!(det.abs() < 1e-13 && defect < 1e-13, "det − 1 = {det}, defect {defect}");
}

#[test]
fn phi_matches_finite_differences_of_the_flow_and_keeps_the_structure() {
    // Hénon–Heiles, a chaotic start at E ≈ 1/8: Φ's columns against central differences of
    // the end state in each start coordinate (the end states from the same command).
    let h = "1/2 (p_x^2 + p_y^2) + 1/2 (x^2 + y^2) + x^2 y - y^3/3";
    let start = [0.0, -0.1, 0.45, 0.1];
    let names = ["x", "y", "p_x", "p_y"];
    let at = |x: &[f64]| names.iter().zip(x).map(|(n, v)| format!("{n}={v}")).collect::<Vec<_>>().join(",");
    let t = 5.0;
    let (_, phi, det, defect) = flow(h, "x,y", &at(&start), t);
    let eps = 1e-6;
    for j in 0..4 {
        let (mut up, mut down) = (start, start);
        up[j] += eps;
        down[j] -= eps;
        let (a, ..) = flow(h, "x,y", &at(&up), t);
        let (b, ..) = flow(h, "x,y", &at(&down), t);
        for i in 0..4 {
            let fd = (a[i] - b[i]) / (2.0 * eps);
            assert!((phi[i][j] - fd).abs() < 1e-6 * (1.0 + fd.abs()), "Φ[{i}][{j}] = {} against {fd}", phi[i][j]);
        }
    }
    assert!(det.abs() < 1e-12 && defect < 1e-12, "det − 1 = {det}, defect {defect}");
}

#[test]
fn a_momentum_not_named_after_its_coordinate_is_refused() {
    let (code, out, err) = run(&["flow", "p^2/2 - cos(q)", "--coords", "q", "--at", "q=1,p_q=0", "--time", "1"]);
    assert_eq!(code, 2, "{out}");
    assert!(err.contains("write `p_q` for the momentum of `q`"), "{err}");
    let (code, _, err) = run(&["flow", "p_q^2/2 - cos(q)", "--coords", "q", "--at", "q=1", "--time", "1"]);
    assert_eq!(code, 2);
    assert!(err.contains("no value for `p_q`"), "{err}");
}
