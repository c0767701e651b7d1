//! Honest long runs: the energy ledger of scene runs.
//!
//! * The example — Kepler started at rest at r = 1, `leapfrog dt = 0.01` through the
//!   collision at t ≈ 1.11 — warns on stderr naming the run and a time before the collision,
//!   and fails under `--strict` with no output file.
//! * A well-resolved run does not warn, and the drift its summary prints equals the drift
//!   recomputed independently: `H` evaluated by the expression evaluator on every exported
//!   state (`every 1`), not by the compiled tape the ledger uses.
//! * `h` is used for Lagrangian runs; explicitly time-dependent systems are skipped with a
//!   note; `drift = …` and `--drift` set the threshold.

use std::process::Command;

use lagrangian::scene::{Mode, Options, Session};

const KEPLER_AT_REST: &str = "\
coordinates x, y
parameters k = 1 positive
H = (p_x^2 + p_y^2)/2 - k/sqrt(x^2 + y^2)
simulate x = 1, y = 0, p_x = 0, p_y = 0 for t in 0..3 with leapfrog dt = 0.01 as fall
export t, x, p_x from fall to fall.csv
";

fn run(scene: &str, args: &[&str]) -> (Option<i32>, String, String, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.scene");
    std::fs::write(&path, scene).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .args(["run", path.to_str().unwrap(), "--no-cache", "--out-dir", dir.path().to_str().unwrap()])
        .args(args)
        .env("LAGRANGIAN_PROGRESS", "never")
        .output()
        .unwrap();
    let s = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.code(), s(&out.stdout), s(&out.stderr), dir)
}

/// The number after `key = ` in `s`.
fn number_after(s: &str, key: &str) -> f64 {
    let at = s.find(key).unwrap_or_else(|| panic!("no `{key}` in {s}")) + key.len();
    let rest = &s[at..];
    let end = rest.find(|c: char| !(c.is_ascii_digit() || "+-.e".contains(c))).unwrap_or(rest.len());
    rest[..end].parse().unwrap_or_else(|e| panic!("`{}`: {e}", &rest[..end]))
}

#[test]
fn kepler_from_rest_with_leapfrog_warns_and_fails_under_strict() {
    let (code, _out, err, dir) = run(KEPLER_AT_REST, &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(dir.path().join("fall.csv").exists());
    let warning = err.lines().find(|l| l.starts_with("warning: fall:")).unwrap_or_else(|| panic!("{err}"));
    assert!(warning.contains("energy H drifted beyond the threshold 1e-3"), "{warning}");
    // The drift passes 10⁻³ on the way in, before the collision at t = π/(2√2) ≈ 1.11
    // (free fall from rest at r = 1 under k = 1: half a period of the degenerate ellipse
    // with a = 1/2), and the largest drift is orders of magnitude above it.
    let collision = std::f64::consts::PI / (2.0 * 2f64.sqrt());
    let t = number_after(warning, "threshold 1e-3 at t = ");
    assert!(t > 0.5 && t < collision, "{warning}");
    assert!(number_after(warning, "max |ΔH/H₀| = ") > 1.0, "{warning}");

    let (code, _out, err, dir) = run(KEPLER_AT_REST, &["--strict"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("fall: the energy H drifted"), "{err}");
    assert!(!dir.path().join("fall.csv").exists(), "no output under --strict");
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 1, "only the scene file is left");
}

#[test]
fn a_well_resolved_run_does_not_warn_and_its_summary_matches_an_independent_drift() {
    let dir = tempfile::tempdir().unwrap();
    let mut opts = Options::new(Mode::Repl);
    opts.out_dir = dir.path().to_path_buf();
    let mut s = Session::new(opts);
    // Kepler, e = 0.5, one orbit (period 2π) with yoshida4 dt = 0.001 and every state kept.
    s.run_line(
        "coordinates x, y\nparameters k = 1 positive\nH = (p_x^2 + p_y^2)/2 - k/sqrt(x^2 + y^2)\n\
         simulate x = 0.5, y = 0, p_x = 0, p_y = 1.7320508075688772 for t in 0..6.3 with yoshida4 dt = 0.001 every 1 as orbit\n\
         export t, H from orbit to h.csv",
    )
    .unwrap();
    let out = s.take_output().join("\n");
    assert!(s.take_warnings().is_empty());
    let printed = number_after(&out, "energy drift max |ΔH/H₀| = ");
    let csv = std::fs::read_to_string(dir.path().join("h.csv")).unwrap();
    let h: Vec<f64> = csv.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().trim().parse().unwrap()).collect();
    assert_eq!(h.len(), 6301);
    let max = h.iter().map(|v| ((v - h[0]) / h[0]).abs()).fold(0.0, f64::max);
    assert!(max > 0.0 && max < 1e-3, "{max}");
    // The summary prints two significant digits: equal to the recomputed drift to 5 %.
    assert!((printed - max).abs() <= 0.05 * max, "printed {printed:e}, recomputed {max:e}");
}

#[test]
fn lagrangian_runs_check_h_and_time_dependent_ones_say_they_are_not_checked() {
    let mut s = Session::new(Options::new(Mode::Repl));
    s.run_line(
        "coordinates θ\nparameters g = 9.81\nL = 1/2 θ'^2 + g cos(θ)\n\
         simulate θ = 1, θ' = 0 for t in 0..2 with rk4 dt = 0.01 as free",
    )
    .unwrap();
    let out = s.take_output().join("\n");
    assert!(out.contains("; energy drift max |Δh/h₀| = "), "{out}");
    // The same pendulum driven at its pivot, L = ½θ'² + (g + cos t) cos θ: not conserved.
    s.run_line("L = 1/2 θ'^2 + (g + cos(t)) cos(θ)\nsimulate θ = 1, θ' = 0 for t in 0..2 with rk4 dt = 0.01 as driven")
        .unwrap();
    let out = s.take_output().join("\n");
    assert!(out.contains("driven: rk4") && out.contains("; energy not checked (L depends on t explicitly"), "{out}");
    assert!(s.take_warnings().is_empty());
}

#[test]
fn the_threshold_is_set_in_the_scene_and_on_the_command_line() {
    // A coarse RK4 pendulum: relative drift of h about 1e-5 (between 1e-7 and 1e-3).
    let scene = |extra: &str| {
        format!(
            "coordinates θ\nparameters g = 9.81\nL = 1/2 θ'^2 + g cos(θ)\n\
             simulate θ = 2, θ' = 0 for t in 0..10 with rk4 dt = 0.05 {extra} as coarse\nexport t, θ from coarse to c.csv\n"
        )
    };
    let (code, _, err, _d) = run(&scene(""), &[]);
    assert_eq!(code, Some(0));
    assert!(!err.contains("warning"), "default 1e-3 is not exceeded: {err}");
    let (code, _, err, _d) = run(&scene("drift = 1e-9"), &[]);
    assert_eq!(code, Some(0));
    assert!(err.contains("warning: coarse: the energy h drifted beyond the threshold 1e-9"), "{err}");
    let (_, _, err, _d) = run(&scene(""), &["--drift", "1e-9"]);
    assert!(err.contains("warning: coarse:"), "{err}");
    // The statement's own threshold wins over the command line's.
    let (_, _, err, _d) = run(&scene("drift = 0.5"), &["--drift", "1e-9"]);
    assert!(!err.contains("warning"), "{err}");
}
