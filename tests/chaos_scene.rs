//! The chaos statements of scenes (`megno`, `lyapunov`, `fli`, `chaos_map`, `plot megno`):
//! the example scene of the double pendulum separates regular from chaotic motion, the
//! Lyapunov spectrum obeys Liouville's theorem, and bad statements get located errors.

mod support;

use std::collections::HashMap;
use std::path::Path;

fn run_in(dir: &Path, scene: &str) -> (i32, String, String) {
    support::run_scene_in(dir, scene, &["--out-dir", dir.to_str().expect("a UTF-8 path")])
}

/// The number after `key` on the line starting with `prefix`.
fn value(stdout: &str, prefix: &str, key: &str) -> f64 {
    let line = stdout.lines().find(|l| l.starts_with(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in {stdout}"));
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("no `{key}` in {line}")) + key.len()..];
    rest.split([' ', ';', '(']).find(|s| !s.is_empty()).unwrap().parse().unwrap()
}

#[test]
fn double_pendulum_example_separates_regular_from_chaotic_motion() {
    // The example scene as shipped, with the map made smaller (8 × 8 to t = 20) and written as
    // a table so its numbers can be read.
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/double_pendulum_chaos.scene"))
            .unwrap();
    let map_line = text.lines().find(|l| l.starts_with("chaos_map")).unwrap();
    let small = map_line
        .replace("points 24", "points 8")
        .replace("0..30", "0..20")
        .replace("double_pendulum_megno_map.svg", "map.csv");
    assert_ne!(small, map_line);
    let text = text.replace(map_line, &small);
    let dir = tempfile::tempdir().unwrap();
    let (code, out, err) = run_in(dir.path(), &text);
    assert_eq!(code, 0, "{err}");

    // A small swing is regular: MEGNO stays bounded (quasi-periodic motion has ⟨Y⟩ → 2, a
    // nearly linear one less) and the finite-time exponent is small; a large one is chaotic:
    // ⟨Y⟩ grows like λt/2.
    let (y_small, l_small) = (value(&out, "low:", "⟨Y⟩ = "), value(&out, "low:", "λ = "));
    let (y_large, l_large) = (value(&out, "high:", "⟨Y⟩ = "), value(&out, "high:", "λ = "));
    assert!(y_small < 2.5 && l_small < 0.1, "{out}");
    assert!(y_large > 8.0 && l_large > 0.5, "{out}");
    // For a chaotic orbit MEGNO's slope is half the exponent: ⟨Y⟩ ≈ λt/2 at t = 50, to the
    // accuracy of a finite-time estimate.
    assert!((y_large / (l_large * 50.0 / 2.0) - 1.0).abs() < 0.5, "{out}");

    // The spectrum: Liouville's theorem (det Φ = 1) makes the exponents sum to zero up to the
    // integration error, and a Hamiltonian spectrum comes in ± pairs.
    let line = out.lines().find(|l| l.starts_with("spectrum:")).unwrap();
    let spectrum: Vec<f64> =
        line.split(": ").nth(2).unwrap().split(" (").next().unwrap().split(", ").map(|s| s.parse().unwrap()).collect();
    assert_eq!(spectrum.len(), 4, "{line}");
    assert!(spectrum.iter().sum::<f64>().abs() < 1e-6, "{line}");
    assert!(spectrum[0] > 0.5 && (spectrum[0] + spectrum[3]).abs() < 0.1 && (spectrum[1] + spectrum[2]).abs() < 0.2);

    // The map: the four cells around the origin are regular; most cells beyond |θ| = 2 are
    // chaotic.
    let csv = std::fs::read_to_string(dir.path().join("map.csv")).unwrap();
    let mut cells: HashMap<(i64, i64), f64> = HashMap::new();
    for row in csv.lines().skip(1) {
        let v: Vec<f64> = row.split(',').map(|x| x.parse().unwrap()).collect();
        cells.insert(((v[0] * 8.0).round() as i64, (v[1] * 8.0).round() as i64), v[2]);
    }
    assert_eq!(cells.len(), 64);
    for c in [(-3, -3), (-3, 3), (3, -3), (3, 3)] {
        assert!(cells[&c] < 2.5, "cell {c:?}: {}", cells[&c]);
    }
    let outer: Vec<f64> = cells.iter().filter(|((x, y), _)| x.abs().max(y.abs()) > 16).map(|(_, v)| *v).collect();
    let chaotic = outer.iter().filter(|v| **v > 4.0).count();
    assert!(2 * chaotic > outer.len(), "{chaotic} of {} outer cells chaotic", outer.len());

    let svg = std::fs::read_to_string(dir.path().join("double_pendulum_megno.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("polyline"), "the MEGNO plot has no curve");
}

#[test]
fn oscillator_map_is_drawn_and_isochronous_megno_is_zero() {
    // A harmonic oscillator is linear and isochronous: ⟨Y⟩ → 0 for every start (Cincotta &
    // Simó 2000), its exponents are 0, and the map is one colour.
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates x
H = 1/2 p_x^2 + 1/2 x^2
megno x = 1, p_x = 0 for t in 0..200
fli x = 1, p_x = 0 for t in 0..200 as f
plot megno
plot fli from f to fli.svg
chaos_map megno x = -1..1, p_x = -1..1 for t in 0..50 points 3 tol = 1e-12 to map.svg
";
    let (code, out, err) = run_in(dir.path(), scene);
    assert_eq!(code, 0, "{err}");
    assert!(value(&out, "megno1:", "⟨Y⟩ = ").abs() < 0.05, "{out}");
    // FLI of a linear flow grows like ln t at most: ‖w(200)‖ ≤ 1 for a rotation.
    assert!(value(&out, "f:", "FLI = ") < 1e-6, "{out}");
    let svg = std::fs::read_to_string(dir.path().join("map.svg")).unwrap();
    assert!(svg.matches("<rect").count() >= 9, "the heat map has no cells");
    assert!(dir.path().join("test_chaos.svg").exists() && dir.path().join("fli.svg").exists(), "{out}");
}

#[test]
fn bad_chaos_statements_are_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    let base = "coordinates x\nH = 1/2 p_x^2 + 1/2 x^2\n";
    for (stmt, says) in [
        ("megno x = 1, p_x = 0 for t in 0..10 with dop853", "does not take a method"),
        ("megno x = 1, p_x = 0 for t in 0..10 tol = 0", "must be positive"),
        ("megno x = 1, p_x = 0 for t in 0..10 tol = 1e-30", "below what f64 can meet"),
        ("megno x = 1, p_x = 0 for t in 5..10", "from t = 0"),
        ("megno x = 1 for t in 0..10", "no starting value for `p_x`"),
        ("lyapunov x = 1, p_x = 0 for t in 0..10 points 4", "does not take `points`"),
        ("plot megno", "no `megno` statement"),
        ("chaos_map megno x = -1..1, p_x = 0 for t in 0..10", "two ranges"),
        ("chaos_map megno x = -1..1, p_x = 1..-1 for t in 0..10", "smaller to a larger"),
        ("chaos_map megno x = -1..1, p_x = -1..1 for t in 0..10 points 1", "whole number from 2"),
        ("chaos_map megno x = -1..1, p_x = -1..1 for t in 0..10 to map.txt", "chaos map"),
    ] {
        let (code, _, err) = run_in(dir.path(), &format!("{base}{stmt}\n"));
        assert_eq!(code, 2, "{stmt}: {err}");
        assert!(err.contains(says), "{stmt}: {err}");
        assert!(err.contains("test.scene:3:"), "{stmt}: no location in {err}");
    }
    // Velocities need `L`.
    let (code, _, err) = run_in(dir.path(), &format!("{base}megno x = 1, x' = 0 for t in 0..10\n"));
    assert_eq!(code, 2);
    assert!(err.contains("no Lagrangian"), "{err}");
}
