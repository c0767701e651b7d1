//! The scene's `flow` statement and the flow of forced and damped systems
//! (`Variational::of_system` with forces and Rayleigh dissipation, `chaos::flow_with`):
//! Φ against central differences of the flow itself, Liouville's and the symplectic check of a
//! Hamiltonian flow, a damped oscillator's det Φ = e^{−γT} (derived by hand), the kept checks
//! and the file they are written to, and the refusals.

use lagrangian::chaos;
use lagrangian::compile::Variational;
use lagrangian::mechanics::System;
use lagrangian::scene::{ErrorKind, Mode, Options, SceneError, Session};

fn scene_in(dir: &std::path::Path, text: &str) -> Result<Vec<String>, SceneError> {
    let mut opts = Options::new(Mode::Scene);
    opts.out_dir = dir.to_path_buf();
    opts.base_dir = dir.to_path_buf();
    let mut s = Session::new(opts);
    s.run_scene("flow", text)?;
    Ok(s.take_output())
}

fn scene(text: &str) -> Result<Vec<String>, SceneError> {
    let dir = tempfile::tempdir().expect("a temporary directory");
    scene_in(dir.path(), text)
}

/// The number after `key` on the line starting with `prefix`.
fn number(out: &[String], prefix: &str, key: &str) -> f64 {
    let line = out.iter().find(|l| l.starts_with(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in {out:?}"));
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("no `{key}` in {line}")) + key.len()..];
    rest.split([' ', ':', ')']).find(|s| !s.is_empty()).unwrap().parse().unwrap()
}

/// A damped, driven pendulum: `θ'' = −sin θ − b θ' + a cos(Ω t)`, the damping as a Rayleigh
/// function and the drive as a force, so the flow is time dependent and not Hamiltonian.
fn driven_pendulum() -> System {
    System::from_lagrangian("1/2 θ'^2 + cos(θ)", &["θ"])
        .and_then(|s| s.with_rayleigh("1/2 b θ'^2"))
        .and_then(|s| s.with_force("θ", "a cos(Ω t)"))
        .and_then(|s| s.with_params(&[("b", 0.2), ("a", 0.9), ("Ω", 0.7)]))
        .expect("the system builds")
}

#[test]
fn phi_of_a_driven_damped_pendulum_matches_central_differences_of_its_flow() {
    let sys = driven_pendulum();
    let var = Variational::of_system(&sys, 2, false).expect("compiles");
    assert!(!var.is_hamiltonian());
    let (x0, t) = ([0.8, -0.3], 7.5);
    let f = chaos::flow(&var, &x0, t, 1e-14).expect("integrates");
    assert_eq!(f.symplectic_defect, None, "a damped flow has no symplectic check");
    // The end states of the same flow from nudged starts (the Φ columns are ignored here).
    let end = |x: [f64; 2]| chaos::flow(&var, &x, t, 1e-14).expect("integrates").end;
    let eps = 1e-6;
    for j in 0..2 {
        let (mut up, mut down) = (x0, x0);
        up[j] += eps;
        down[j] -= eps;
        let (a, b) = (end(up), end(down));
        for i in 0..2 {
            let fd = (a[i] - b[i]) / (2.0 * eps);
            let phi = f.phi[i * 2 + j];
            assert!((phi - fd).abs() < 1e-7 * (1.0 + fd.abs()), "Φ[{i}][{j}] = {phi} against {fd}");
        }
    }
    // Liouville's formula: det Φ = exp(∫ tr ∂f/∂x) = e^{−bT} (tr = −b whatever the drive).
    let det = f.det_minus_one + 1.0;
    assert!((det - (-0.2 * t).exp()).abs() < 1e-13, "det Φ = {det}, e^(−bT) = {}", (-0.2f64 * t).exp());
}

#[test]
fn the_scene_prints_a_pendulums_flow_as_volume_keeping_and_symplectic() {
    let out = scene(
        "coordinates θ\nparameters g = 9.81, l = 1\nL = 1/2 l^2 θ'^2 + g l cos(θ)\nflow θ = 1, θ' = 0 for t in 0..10",
    )
    .expect("runs");
    assert_eq!(out.len(), 6, "{out:?}");
    assert!(out[1].starts_with("Φ(T), rows and columns in the order θ, p_θ"), "{out:?}");
    let det = number(&out, "det Φ − 1", "= ");
    let defect = number(&out, "max |ΦᵀJΦ − J|", "= ");
    assert!(det.abs() <= 1e-12 && defect <= 1e-12, "{out:?}");
    // The same start through the library at a looser tolerance: the residuals measure the
    // integration error, so they grow with the tolerance (the check is not vacuous).
    let sys = System::from_lagrangian("1/2 l^2 θ'^2 + g l cos(θ)", &["θ"])
        .and_then(|s| s.with_params(&[("g", 9.81), ("l", 1.0)]))
        .unwrap();
    let var = Variational::of_system(&sys, 2, false).unwrap();
    let loose = chaos::flow(&var, &[1.0, 0.0], 10.0, 1e-6).unwrap();
    assert!(loose.symplectic_defect.unwrap() > 1e-9, "{loose:?}");
}

/// `x'' = −γx' − ω²x`: `tr ∂f/∂x = −γ`, so det Φ(T) = e^{−γT} in (x, x') and, `p = m x'` being a
/// constant linear change of variables, in (x, p) too. With `m x'' = −b x' − k x`, γ = b/m.
#[test]
fn a_damped_oscillators_det_phi_is_exp_minus_gamma_t_by_rayleigh_or_by_a_force() {
    let (m, b, k, t): (f64, f64, f64, f64) = (2.0, 0.6, 5.0, 4.0);
    let expected: f64 = (-(b / m) * t).exp() - 1.0;
    for damping in ["rayleigh 1/2 b x'^2", "force x = -b x'"] {
        let dir = tempfile::tempdir().unwrap();
        let out = scene_in(
            dir.path(),
            &format!(
                "coordinates x\nparameters m = {m}, b = {b}, k = {k}\nL = 1/2 m x'^2 - 1/2 k x^2\n{damping}\nflow x = 1, x' = 0.5 for t in 0..{t} to checks.csv"
            ),
        )
        .unwrap_or_else(|e| panic!("{damping}: {e:?}"));
        // The printed det Φ (7 significant digits), then the table's exact last row.
        let det = number(&out, "det Φ − 1", "det Φ = ");
        assert!((det - (expected + 1.0)).abs() < 1e-6, "{damping}: {out:?}");
        assert!(out.iter().any(|l| l.starts_with("no symplectic defect")), "{out:?}");
        let table = std::fs::read_to_string(dir.path().join("checks.csv")).unwrap();
        let rows: Vec<Vec<&str>> = table.lines().skip(1).map(|l| l.split(',').collect()).collect();
        assert_eq!(rows[0], ["0e0", "0e0", ""], "Φ(0) = I");
        let last = rows.last().unwrap();
        assert_eq!(last[0].parse::<f64>().unwrap(), t);
        let got: f64 = last[1].parse().unwrap();
        assert!((got - expected).abs() < 1e-13, "{damping}: det Φ − 1 = {got}, e^(−γT) − 1 = {expected}");
        // Along the run too: det Φ(t) = e^{−γt} at every kept step.
        for r in &rows {
            let (s, d): (f64, f64) = (r[0].parse().unwrap(), r[1].parse().unwrap());
            assert!((d - ((-(b / m) * s).exp() - 1.0)).abs() < 1e-13, "t = {s}: {d}");
        }
    }
}

#[test]
fn the_checks_are_drawn_on_a_log_axis() {
    let dir = tempfile::tempdir().unwrap();
    let out = scene_in(
        dir.path(),
        "coordinates q\nH = p_q^2/2 + q^4/4\nflow q = 1, p_q = 0 for t in 0..20 points 50 to flow.svg",
    )
    .expect("runs");
    assert!(out.last().is_some_and(|l| l.starts_with("wrote ") && l.ends_with("flow.svg")), "{out:?}");
    let svg = std::fs::read_to_string(dir.path().join("flow.svg")).expect("the plot is written");
    assert!(svg.contains("|det Φ − 1|") && svg.contains("max |ΦᵀJΦ − J|"), "both curves in the legend");
}

#[test]
fn what_flow_cannot_run_is_refused_with_what_would_work() {
    let pendulum = "coordinates x, y\nparameters g = 1\nL = 1/2 (x'^2 + y'^2) - g y\nconstraint x^2 + y^2 = 1\n";
    let e = scene(&format!("{pendulum}flow x = 1, y = 0, x' = 0, y' = 0 for t in 0..1")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::Derivation);
    assert!(e.message.contains("multipliers"), "{}", e.message);
    assert!(e.hint.as_deref().is_some_and(|h| h.contains("coordinates that satisfy the constraints")));
    assert!(e.span.is_some());

    let osc = "coordinates q\nH = p_q^2/2 + q^2/2\n";
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 0..1 with rk4")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::Syntax);
    assert!(e.message.contains("does not take a method"), "{}", e.message);
    let e = scene(&format!("{osc}flow q = 1 for t in 0..1")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::MissingValue);
    assert!(e.message.contains("p_q"), "{}", e.message);
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 2..1")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::BadNumber);
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 0..1 points 1")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::BadNumber);
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 0..1 to flow.gif")).expect_err("refused");
    assert!(e.message.contains("gif") || e.hint.as_deref().is_some_and(|h| h.contains(".csv")), "{e:?}");
    // Velocities need L to become momenta.
    let e = scene(&format!("{osc}flow q = 1, q' = 0 for t in 0..1")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::Undeclared);
    // A parameter without a value.
    let e = scene("coordinates q\nparameters k\nH = p_q^2/2 + k q^2/2\nflow q = 1, p_q = 0 for t in 0..1")
        .expect_err("refused");
    assert_eq!(e.kind, ErrorKind::MissingValue);
    assert!(e.message.contains("`k`"), "{}", e.message);
}

#[test]
fn help_describes_flow() {
    let mut s = Session::new(Options::new(Mode::Scene));
    s.run_scene("help", "help flow").expect("help runs");
    let out = s.take_output().join("\n");
    assert!(out.contains("flow q = …") && out.contains("det Φ − 1") && out.contains("e^{−γT}"), "{out}");
}

/// On a chaotic orbit Φ grows like e^{λT}, and rounding in det Φ and ΦᵀJΦ (products of two
/// entries cancelling to O(1)) swamps the integration error: the printout says so rather than
/// presenting 10¹² as a Liouville residual, and says nothing on a short run.
#[test]
fn residuals_swamped_by_rounding_on_a_chaotic_orbit_are_flagged() {
    let dp = "coordinates θ1, θ2\nparameters m1 = 1, m2 = 1, l1 = 1, l2 = 1, g = 9.81\n\
              L = 1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)\n";
    let long = scene(&format!("{dp}flow θ1 = 2, θ2 = 2.5, θ1' = 0, θ2' = 0 for t in 0..20")).unwrap();
    let note = long.iter().find(|l| l.starts_with("note: Φ has entries up to")).unwrap_or_else(|| panic!("{long:?}"));
    assert!(note.contains("do not measure the integration"), "{note}");
    // The flagged scale is right: the residuals are below it.
    let floor = number(&long, "note:", "= ");
    assert!(number(&long, "det Φ − 1", "= ").abs() <= floor && number(&long, "max |ΦᵀJΦ − J|", "= ") <= floor);
    let short = scene(&format!("{dp}flow θ1 = 2, θ2 = 2.5, θ1' = 0, θ2' = 0 for t in 0..3")).unwrap();
    assert!(!short.iter().any(|l| l.starts_with("note:")), "{short:?}");
    assert!(number(&short, "det Φ − 1", "= ").abs() < 1e-11 && number(&short, "max |ΦᵀJΦ − J|", "= ") < 1e-11);
}

/// A span the budget cannot cover stops with the budget named, and how to raise it.
#[test]
fn a_flow_past_its_budget_names_the_option_that_raises_it() {
    let osc = "coordinates q\nH = p_q^2/2 + q^2/2\n";
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 0..1e9 max_steps = 1000")).expect_err("stopped");
    assert_eq!(e.kind, ErrorKind::Numeric);
    assert!(e.hint.as_deref().is_some_and(|h| h.contains("`max_steps = N` (now 1000)")), "{e:?}");
    let started = std::time::Instant::now();
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 0..1e9 time_limit = 0.05")).expect_err("stopped");
    assert!(started.elapsed().as_secs_f64() < 30.0);
    assert!(e.hint.as_deref().is_some_and(|h| h.contains("`time_limit = SECONDS` (now 0.05)")), "{e:?}");
    let e = scene(&format!("{osc}flow q = 1, p_q = 0 for t in 0..1 time_limit = -1")).expect_err("refused");
    assert_eq!(e.kind, ErrorKind::BadNumber);
}

/// The example scene as shipped: the undamped oscillator keeps volume to round-off, the damped
/// one has det Φ(10) = e^{−(b/m)·10} = e^{−3} along the whole run.
#[test]
fn the_liouville_example_shows_both_flows() {
    let text =
        std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/liouville.scene"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = scene_in(dir.path(), &text).expect("the example runs");
    let first = number(&out, "det Φ − 1", "= ");
    assert!(first.abs() < 1e-13, "{out:?}");
    assert!(dir.path().join("liouville_undamped.svg").is_file());
    let table = std::fs::read_to_string(dir.path().join("liouville_damped.csv")).unwrap();
    for row in table.lines().skip(1) {
        let v: Vec<f64> = row.split(',').take(2).map(|x| x.parse().unwrap()).collect();
        assert!((v[1] - (-0.3 * v[0]).exp_m1()).abs() < 1e-13, "{row}");
    }
    assert!(table.lines().last().unwrap().starts_with("1e1,"), "the table ends at T = 10");
}
