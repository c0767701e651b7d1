//! Euler–Lagrange for every Lagrangian: a singular Hessian W still gives
//! the expressions E_i, with one note line naming the velocity or null direction, while
//! `--accelerations`, `legendre` and `simulate` keep their errors. The E_i are checked against
//! hand forms and against finite differences of L along random paths.

use crate::support::notes as notes_support;

use lagrangian::algebra::expand;
use lagrangian::mechanics::System;
use lagrangian::{parse, Expr};
use notes_support::{fd_euler_lagrange, run, snapshot, value_on_path, Rng};

/// The singular example of the issue: L linear in y' (W = diag(m, 0)).
const SINGULAR: &str = "1/2 m x'^2 + b x^2 y' - c y^4";
/// The phase-space oscillator of §3.4 (3.31) with coordinates x, p: W ≡ 0.
const PHASE_SPACE: &str = "p x' - p^2/(2 m) - k x^2/2";

fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in\n{out}"))
}

/// `printed` is an `el` line's `E = 0` (no force) or an expression.
fn same(printed: &str, hand: &str) {
    let printed = printed.strip_suffix(" = 0").unwrap_or(printed);
    let d = expand(&parse(printed).unwrap().minus(&parse(hand).unwrap())).unwrap();
    assert!(d.is_zero(), "{printed} differs from {hand} by {d}");
}

/// The library's E_i agree with finite differences of L at random points of random paths.
fn check_numerically(l: &str, coords: &[&str], params: &[(&str, f64)]) {
    let s = System::from_lagrangian(l, coords).unwrap();
    let el = s.euler_lagrange().unwrap();
    let lx: Expr = s.lagrangian().unwrap().clone();
    let mut rng = Rng::new(l.len() as u64);
    for _ in 0..6 {
        let path = rng.path(coords.len());
        let t = rng.uniform(-1.0, 1.0);
        let fd = fd_euler_lagrange(&lx, coords, &path, t, params);
        for (i, e) in el.iter().enumerate() {
            let exact = value_on_path(e, coords, &path, t, params);
            assert!(
                (exact - fd[i]).abs() < 1e-5 * (1.0 + exact.abs()),
                "E_{}: {exact} vs finite differences {}",
                coords[i],
                fd[i]
            );
        }
    }
}

#[test]
fn singular_lagrangian_prints_its_equations_and_one_note() {
    let (code, out, err) = run(&["el", SINGULAR, "--coords", "x,y"]);
    assert_eq!(code, 0, "{err}");
    // By hand: ∂L/∂x' = m x', ∂L/∂x = 2 b x y'; ∂L/∂y' = b x², d/dt = 2 b x x', ∂L/∂y = −4 c y³.
    same(line(&out, "E_x: "), "m x'' - 2 b x y'");
    same(line(&out, "E_y: "), "2 b x x' + 4 c y^3");
    let notes: Vec<&str> = out.lines().filter(|l| l.starts_with("note: ")).collect();
    assert_eq!(notes.len(), 1, "{out}");
    assert!(notes[0].contains("`y'`"), "the note names the velocity without inertia: {}", notes[0]);
    snapshot(
        "notes_el_singular",
        format!("# Remark 3.1: L linear in y'\n$ lagrangian el \"{SINGULAR}\" --coords x,y\n{out}"),
    );
    check_numerically(SINGULAR, &["x", "y"], &[("m", 1.3), ("b", 0.7), ("c", 0.4)]);

    let (code, json, _) = run(&["el", SINGULAR, "--coords", "x,y", "--format", "json"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    assert!(v["note"].as_str().unwrap().contains("y'"));
    let (_, json, _) = run(&["el", "1/2 m x'^2", "--coords", "x", "--format", "json"]);
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    assert!(v["note"].is_null(), "a regular W has no note");
}

#[test]
fn singular_lagrangian_keeps_the_errors_that_need_accelerations() {
    for args in [
        vec!["el", SINGULAR, "--coords", "x,y", "--accelerations"],
        vec!["legendre", SINGULAR, "--coords", "x,y"],
        vec!["hamilton", SINGULAR, "--coords", "x,y", "--lagrangian"],
    ] {
        let (code, out, err) = run(&args);
        assert_eq!(code, 2, "{args:?}: {out}");
        assert!(out.is_empty(), "{args:?}: nothing printed on failure, got {out}");
        assert!(err.contains("singular") && err.contains("y'"), "{args:?}: {err}");
    }
}

#[test]
fn null_direction_is_named_in_the_note() {
    // W = [[1, 1], [1, 1]]: singular along x' − y'.
    let (code, out, err) = run(&["el", "1/2 (x' + y')^2 - x^2 - y^2", "--coords", "x,y"]);
    assert_eq!(code, 0, "{err}");
    let note = line(&out, "note: ");
    assert!(note.contains("(1, -1)") || note.contains("(-1, 1)"), "{note}");
    same(line(&out, "E_x: "), "x'' + y'' + 2 x");
    same(line(&out, "E_y: "), "x'' + y'' + 2 y");
}

#[test]
fn phase_space_oscillator_euler_lagrange_are_hamiltons_equations() {
    // (3.31)–(3.32): E_x = p' + k x and E_p = p/m − x', i.e. p' = −∂H/∂x and x' = ∂H/∂p for
    // H = p²/2m + k x²/2 (3.16 with k = m ω0²).
    let (code, out, err) = run(&["el", PHASE_SPACE, "--coords", "x,p"]);
    assert_eq!(code, 0, "{err}");
    same(line(&out, "E_x: "), "p' + k x");
    same(line(&out, "E_p: "), "p/m - x'");
    assert!(line(&out, "note: ").contains("first-order"), "{out}");
    snapshot("notes_el_phase_space_oscillator", format!("# (3.31)-(3.32): E_i of the phase-space Lagrangian are Hamilton's equations (3.12) of (3.16)\n$ lagrangian el \"{PHASE_SPACE}\" --coords x,p\n{out}"));
    // The same equations from the ordinary Hamiltonian route.
    let (code, ham, _) = run(&["hamilton", "p_x^2/(2 m) + k x^2/2", "--coords", "x"]);
    assert_eq!(code, 0);
    same(line(&ham, "x' = "), "p_x/m");
    same(line(&ham, "p_x' = "), "-k x");
    check_numerically(PHASE_SPACE, &["x", "p"], &[("m", 1.7), ("k", 0.6)]);
}

#[test]
fn scene_el_notes_a_singular_hessian_and_simulate_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("singular.scene");
    std::fs::write(&scene, "coordinates x, y\nparameters m = 1, b = 1, c = 1\nL = 1/2 m x'^2 + b x^2 y' - c y^4\nel\n")
        .unwrap();
    let out_dir = dir.path().join("out");
    let (code, out, err) = run(&["run", scene.to_str().unwrap(), "--out-dir", out_dir.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("E_y") && out.contains("singular") && out.contains("y'"), "{out}");
    std::fs::write(
        &scene,
        "coordinates x, y\nparameters m = 1, b = 1, c = 1\nL = 1/2 m x'^2 + b x^2 y' - c y^4\n\
         simulate x = 1, y = 0, x' = 0, y' = 0 for t in 0..1 with rk4 dt = 0.1\nexport to run.csv\n",
    )
    .unwrap();
    let (code, _, err) = run(&["run", scene.to_str().unwrap(), "--out-dir", out_dir.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("singular"), "{err}");
    assert!(!out_dir.join("run.csv").exists(), "nothing written");
}
