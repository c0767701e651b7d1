//! `simulate … with taylor` in a scene: the method, its default tolerance and its errors.

use crate::support;

use std::path::Path;

fn run_in(dir: &Path, scene: &str) -> (i32, String, String) {
    support::run_scene_in(dir, scene, &[])
}

/// The last row of a CSV export as numbers.
fn last_row(csv: &str) -> Vec<f64> {
    csv.lines().last().unwrap().split(',').map(|x| x.trim().parse().unwrap()).collect()
}

#[test]
fn taylor_integrates_l_and_h_at_machine_precision_by_default() {
    // x = cos t for both formulations; the default tolerance is machine precision.
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates x
L = 1/2 x'^2 - 1/2 x^2
simulate x = 1, x' = 0 for t in 0..10 with taylor as viaL
export t, x from viaL to l.csv
";
    let (code, _, err) = run_in(dir.path(), scene);
    assert_eq!(code, 0, "{err}");
    let row = last_row(&std::fs::read_to_string(dir.path().join("l.csv")).unwrap());
    assert_eq!(row[0], 10.0);
    assert!((row[1] - 10f64.cos()).abs() < 1e-13, "{row:?}");
    let scene = "\
coordinates x
H = 1/2 p_x^2 + 1/2 x^2
simulate x = 1, p_x = 0 for t in 0..10 with taylor tol = 1e-12 record when x = 0 rising
export t, x to h.csv
";
    let (code, _, err) = run_in(dir.path(), scene);
    assert_eq!(code, 0, "{err}");
    let row = last_row(&std::fs::read_to_string(dir.path().join("h.csv")).unwrap());
    assert!((row[1] - 10f64.cos()).abs() < 1e-10, "{row:?}");
}

#[test]
fn taylor_rejects_a_step_and_an_unmeetable_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let base = "coordinates x\nH = 1/2 p_x^2 + 1/2 x^2\n";
    let (code, _, err) = run_in(
        dir.path(),
        &format!("{base}simulate x = 1, p_x = 0 for t in 0..1 with taylor dt = 0.1\nexport t, x to a.csv\n"),
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("chooses its own steps"), "{err}");
    let (code, _, err) = run_in(
        dir.path(),
        &format!("{base}simulate x = 1, p_x = 0 for t in 0..1 with taylor tol = 1e-30\nexport t, x to a.csv\n"),
    );
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("below what f64 can meet"), "{err}");
    assert!(!dir.path().join("a.csv").exists());
}
