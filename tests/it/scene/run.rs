//! `lagrangian run SCENE`: statements, printed results, diagnostics and the rule that a
//! failing scene writes no output file.

use crate::support;

use std::path::Path;

use support::run_scene_in as run_in;

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn prints_definitions_in_three_formats() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
# the pendulum's Hamiltonian (3.20), written by hand
coordinates θ
parameters m, l, g positive
T = p_θ^2/(2 m l^2)
V = m g l (1 - cos(θ))
H = T + V
print H
print H as plain
print H as latex
";
    let (code, out, err) = run_in(dir.path(), scene, &[]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "H = g l m (1 - cos(θ)) + p_θ²/(2 l² m)");
    assert_eq!(lines[1], "H = g l m (1 - cos(θ)) + p_θ^2/(2 l^2 m)");
    assert!(lines[2].starts_with("H = g l m \\left(1 - \\cos"), "{}", lines[2]);
    // The plain form re-parses to the same expression as the hand-written (3.20).
    let d = lagrangian::Declarations::new().with_positive(["m", "l", "g"]);
    let printed = lagrangian::parse_with(lines[1].trim_start_matches("H = "), &d).unwrap();
    let hand = lagrangian::parse_with("p_θ^2/(2 m l^2) + m g l (1 - cos(θ))", &d).unwrap();
    assert_eq!(printed, hand);
}

/// Every diagnostic: exit code 2, the message, the source line with a caret, a hint.
fn check_error(scene: &str, message: &str, hint: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, err) = run_in(dir.path(), scene, &[]);
    assert_eq!(code, 2, "stdout: {out}\nstderr: {err}");
    assert!(err.contains(message), "expected `{message}` in:\n{err}");
    assert!(err.contains(hint), "expected hint `{hint}` in:\n{err}");
    assert!(err.contains('╰') || err.contains('^'), "no caret in:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

#[test]
fn diagnostics_point_at_the_mistake() {
    let base = "coordinates θ\nparameters m = 1, l = 1, g = 9.81 positive\n";
    let err = check_error(&format!("{base}simulat θ = 1"), "unknown statement `simulat`", "did you mean `simulate`?");
    assert!(err.contains("3 │ simulat θ = 1"), "{err}");
    check_error(
        &format!("{base}L = 1/2 m l^2 θ'^2 - m g l (1 - cos(θ)) + k θ"),
        "undefined symbol `k`",
        "parameters k",
    );
    check_error(&format!("{base}print m g ll θ''"), "undefined symbol `ll`", "did you mean `l`?");
    check_error(&format!("{base}print θ'' + θ1"), "undefined symbol `θ1`", "did you mean `θ`?");
    check_error(&format!("{base}print θ + (1"), "expected", "a `(` is never closed");
    check_error(
        &format!("{base}parameters k positive\nH = p_θ^2/2 + k θ^2\nplot phase"),
        "parameter",
        "declare `k` with a value before `plot`",
    );
    check_error(
        &format!("{base}H = p_θ^2/2 + θ^2\nsimulate θ = 1, p_θ = 0 for t in 0..10 with gausss6 dt = 0.1\nplot phase"),
        "unknown integration method `gausss6`",
        "did you mean `gauss6`?",
    );
    check_error(
        &format!("{base}H = p_θ^2/2 + θ^2\nsimulate θ = 1, p_θ = 0 for t in 10..0 with rk4 dt = 0.1\nplot phase"),
        "the time span runs backwards",
        "for t in 0..10",
    );
    // `steps = N` fixes the step, which an adaptive method chooses itself: refused, not ignored.
    check_error(
        &format!("{base}H = p_θ^2/2 + θ^2\nsimulate θ = 1, p_θ = 0 for t in 0..10 with dop853 steps = 100\nplot phase"),
        "`dop853` chooses its own steps",
        "tol = 1e-10",
    );
    // A splitting method on a damped system: refused, naming the methods that run it.
    check_error(
        &format!("{base}L = 1/2 θ'^2 - θ^2/2\nrayleigh 1/2 θ'^2\nsimulate θ = 1, θ' = 0 for t in 0..10 with leapfrog dt = 0.1\nplot phase"),
        "`leapfrog` splits a conservative H",
        "`gauss6`",
    );
    check_error(&format!("{base}m = 3"), "`m` is already a parameter", "another name");
    check_error(&format!("{base}coordinates θ"), "coordinate `θ` is declared twice", "");
    check_error(&format!("{base}el"), "no Lagrangian defined", "define it first");
}

#[test]
fn diagnostic_rendering_is_stable() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, err) = run_in(dir.path(), "coordinates x\nprint x'' + y\n", &[]);
    assert_eq!(code, 2);
    // The caret sits under `y`, column 13 of line 2 (by counting).
    let err = err.replace(&dir.path().join("test.scene").display().to_string(), "test.scene");
    support::snapshot("scene_diagnostic_undefined_symbol", &err);
    assert!(err.contains("[test.scene:2:13]"), "{err}");
}

#[test]
fn a_failing_scene_writes_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates θ
parameters g = 9.81
H = p_θ^2/2 + g (1 - cos(θ))
plot phase to first.svg
print nonsense
";
    let (code, _, err) = run_in(dir.path(), scene, &[]);
    assert_eq!(code, 2, "{err}");
    // The plot was drawn before the error, but nothing (not even a temporary file) remains.
    assert_eq!(files(dir.path()), ["test.scene"]);
    // Without the error it is written.
    let (code, out, err) = run_in(dir.path(), &scene.replace("print nonsense\n", ""), &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wrote ./first.svg"), "{out}");
    assert_eq!(files(dir.path()), ["first.svg", "test.scene"]);
}

#[test]
fn pendulum_phase_portrait_from_h() {
    // Fig. 3.1: contours of H = p²/(2 m l²) + m g l (1 − cos θ), O at θ = 0, X at ±π,
    // separatrix H = 2 m g l.
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates θ
parameters m = 1, l = 1, g = 9.81 positive
H = p_θ^2/(2 m l^2) + m g l (1 - cos(θ))
plot phase to phase.svg
plot phase to phase.png
";
    let (code, out, err) = run_in(dir.path(), scene, &["--explain"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wrote ./phase.svg") && out.contains("wrote ./phase.png"), "{out}");
    let svg = std::fs::read_to_string(dir.path().join("phase.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    // plotters writes each text on its own line.
    let text = |t: &str| svg.matches(&format!(">\n{t}\n</text>")).count();
    // θ is an angle (H is 2π-periodic in it): the frame is (−π, π] and the one saddle,
    // θ = ±π, is marked once.
    assert_eq!((text("separatrix"), text("O"), text("X")), (1, 1, 1), "labels missing");
    let png = std::fs::read(dir.path().join("phase.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    // Nothing symbolic was derived: H was given and only evaluated.
    assert!(out.contains("0 built, 0 reused"), "{out}");
}

#[test]
fn poisson_brackets_of_angular_momentum() {
    // {L_x, L_y} = L_z (PHYSICS.md §4.4), and {H, L_z} = 0 for a central potential.
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates x, y, z
parameters m, k positive
Lx = y p_z - z p_y
Ly = z p_x - x p_z
Lz = x p_y - y p_x
H = (p_x^2 + p_y^2 + p_z^2)/(2 m) + k (x^2 + y^2 + z^2)
pb Lx, Ly as plain
pb H, Lz as plain
";
    let (code, out, err) = run_in(dir.path(), scene, &[]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    let lz = lagrangian::parse("x p_y - y p_x").unwrap();
    let first = lines[0].strip_prefix("{Lx, Ly} = ").expect(lines[0]);
    assert_eq!(lagrangian::parse(first).unwrap(), lz);
    assert_eq!(lines[1], "{H, Lz} = 0");
}

#[test]
fn explain_shows_what_a_splitting_run_skips() {
    // The real stages: only the Legendre transform, its split, the momenta (to turn θ' into
    // p_θ), the compiled drift/kick and the integration are built.
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates θ
parameters m = 1, l = 1, g = 9.81 positive
L = 1/2 m l^2 θ'^2 - m g l (1 - cos(θ))
E = el(L)
simulate θ = 1, θ' = 0 for t in 0..1 with yoshida4 dt = 0.01
plot θ vs t to theta.svg
";
    let (code, out, err) = run_in(dir.path(), scene, &["--explain"]);
    assert_eq!(code, 0, "{err}");
    let built: Vec<&str> = out.lines().filter(|l| l.trim_start().starts_with("built")).collect();
    assert_eq!(built.len(), 5, "{out}");
    for (line, what) in built.iter().zip([
        "Legendre transform",
        "separable split",
        "canonical momenta",
        "compiled right-hand side drift",
        "integration run1 with yoshida4 (100 steps, energy drift max |ΔH/H₀| = ",
    ]) {
        assert!(line.contains(what), "{line} / {what}");
    }
    for skipped in [
        "Euler–Lagrange equations `E` (el) — no output uses `E`",
        "Hamilton's equations — no output needs it",
        "conserved quantities — no output needs it",
        "energy function — no output needs it",
        "Poisson bracket — no output needs it",
    ] {
        assert!(out.contains(skipped), "{skipped} not in\n{out}");
    }
    assert!(out.contains("5 built, 0 reused, 5 skipped"), "{out}");
}

/// The oscillator `H = (p² + x²)/2` from `x = 1`: the exact solution is `x = cos t`.
const WP: &str = "\
coordinates x
H = 1/2 p_x^2 + 1/2 x^2
simulate x = 1, p_x = 0 for t in 0..10 with dop853 tol = 1e-13 as exact
simulate x = 1, p_x = 0 for t in 0..10 with leapfrog dt = 0.02 as l1
simulate x = 1, p_x = 0 for t in 0..10 with leapfrog dt = 0.01 as l2
simulate x = 1, p_x = 0 for t in 0..10 with rk4 dt = 0.1 as r1
simulate x = 1, p_x = 0 for t in 0..10 with rk4 dt = 0.05 as r2
simulate x = 1, p_x = 0 for t in 0..10 with rk4 dt = 0.025 as r3
";

/// The `(x, y)` centres of the markers of an SVG plot, in drawing order.
fn markers(svg: &str) -> Vec<(f64, f64)> {
    svg.split("<circle")
        .skip(1)
        .map(|c| {
            let attr = |name: &str| -> f64 {
                let at = c.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
                c[at..].split('"').next().unwrap().parse().unwrap()
            };
            (attr("cx"), attr("cy"))
        })
        .collect()
}

#[test]
fn work_precision_diagram_has_one_line_per_method_with_its_order() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!("{WP}plot work_precision against exact to wp.svg\n");
    let (code, out, err) = run_in(dir.path(), &scene, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wp.svg"), "{out}");
    let svg = std::fs::read_to_string(dir.path().join("wp.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    // Legend entries are text elements whose content is on a line of its own.
    let text = |s: &str| svg.lines().any(|l| l.trim() == s);
    assert!(text("leapfrog") && text("rk4"), "legend");
    assert!(!text("dop853"), "the reference is not a series");
    // Five runs, one marker each; without `from`, every run but the reference.
    let m = markers(&svg);
    assert_eq!(m.len(), 5, "{m:?}");
    // On log–log axes, halving the step doubles the work and divides the error by 2^order:
    // the slope in pixels is order × (the height of a decade / the width of a decade), so
    // the ratio of the two methods' slopes is 4/2 (rk4 against leapfrog).
    let slope = |a: (f64, f64), b: (f64, f64)| (b.1 - a.1) / (b.0 - a.0);
    let (leap, rk) = (slope(m[0], m[1]), slope(m[2], m[4]));
    assert!((rk / leap - 2.0).abs() < 0.25, "slopes {leap} {rk}");
}

#[test]
fn work_precision_without_a_reference_uses_the_energy_error() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!("{WP}plot work_precision from l1, l2, r1 to wp.svg\n");
    let (code, _, err) = run_in(dir.path(), &scene, &[]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(dir.path().join("wp.svg")).unwrap();
    assert!(svg.contains("|ΔE/E₀|"), "energy error axis");
    assert_eq!(markers(&svg).len(), 3);
}

#[test]
fn work_precision_against_a_run_of_another_span_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let scene =
        format!("{WP}simulate x = 1, p_x = 0 for t in 0..5 with rk4 dt = 0.1 as short\nplot work_precision against short from l1 to wp.svg\n");
    let (code, _, err) = run_in(dir.path(), &scene, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("ends at t = 10 but the reference `short` at t = 5"), "{err}");
    assert!(!dir.path().join("wp.svg").exists());
}
