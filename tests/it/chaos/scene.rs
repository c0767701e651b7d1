//! The chaos statements of scenes (`megno`, `lyapunov`, `fli`, `chaos_map`, `plot megno`):
//! the example scene of the double pendulum separates regular from chaotic motion, the
//! Lyapunov spectrum obeys Liouville's theorem, the Hénon–Heiles maps lie on the energy
//! surface with the cells off it blank, the statements go through the backend (compiled once,
//! listed by `--explain`), and bad statements get located errors.

use crate::support;

use std::collections::HashMap;
use std::path::Path;

fn run_in(dir: &Path, scene: &str) -> (i32, String, String) {
    run_with(dir, scene, &[])
}

fn run_with(dir: &Path, scene: &str, args: &[&str]) -> (i32, String, String) {
    let mut all = vec!["--out-dir", dir.to_str().expect("a UTF-8 path")];
    all.extend_from_slice(args);
    support::run_scene_in(dir, scene, &all)
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
    // integration error, and a Hamiltonian spectrum comes in ± pairs. Each exponent is printed
    // to 6 decimals, so the printed four of an exactly zero-sum spectrum may sum to ±2e-6; the
    // unrounded sum is held to 1e-10 by
    // `chaos::indicators::hamiltonian_spectrum_comes_in_opposite_pairs`.
    let line = out.lines().find(|l| l.starts_with("spectrum:")).unwrap();
    let spectrum: Vec<f64> =
        line.split(": ").nth(2).unwrap().split(" (").next().unwrap().split(", ").map(|s| s.parse().unwrap()).collect();
    assert_eq!(spectrum.len(), 4, "{line}");
    assert!(spectrum.iter().sum::<f64>().abs() <= 4.0 * 0.5e-6 + 1e-9, "{line}");
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

    // The level clause of a map.
    for (stmt, says) in [
        ("chaos_map megno x = -1..1, p_x = -1..1 for t in 0..10 on H = 1 solve p_x > 0", "`p_x` is given twice"),
        ("chaos_map megno x = -1..1, p_x = -1..1 for t in 0..10 on H = 1 solve x > 0", "`x` is given twice"),
        ("chaos_map megno x = -1..1, p_x = -1..1 for t in 0..10 on H = 1 solve q > 0", "undefined symbol `q`"),
        ("chaos_map megno x = -1..1, p_x = 0 for t in 0..10 on H = k solve p_x > 0", "two ranges"),
    ] {
        let (code, _, err) = run_in(dir.path(), &format!("{base}{stmt}\n"));
        assert_eq!(code, 2, "{stmt}: {err}");
        assert!(err.contains(says), "{stmt}: {err}");
        assert!(err.contains("test.scene:3:"), "{stmt}: no location in {err}");
    }
    // No cell of the grid reaches the level (H ≥ 0 everywhere): a located error, no file.
    let two = "coordinates x, y\nH = 1/2 (p_x^2 + p_y^2 + x^2 + y^2)\n";
    let (code, _, err) = run_in(
        dir.path(),
        &format!(
            "{two}chaos_map megno x = -1..1, p_x = -1..1, y = 0 for t in 0..10 on H = -1 solve p_y > 0 to m.csv\n"
        ),
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no cell of the grid") && err.contains("test.scene:3:"), "{err}");
    assert!(!dir.path().join("m.csv").exists());
    // A level function with an unknown symbol.
    let (code, _, err) = run_in(
        dir.path(),
        &format!("{two}chaos_map megno x = -1..1, p_x = -1..1, y = 0 for t in 0..10 on H + c = 1 solve p_y > 0\n"),
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("test.scene:3:"), "{err}");
}

#[test]
fn kinks_and_singular_mass_matrices_stop_chaos_statements_with_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    // V = |x|: no Taylor series at the kink x = 0, which the orbit crosses.
    let (code, _, err) =
        run_in(dir.path(), "coordinates x\nH = 1/2 p_x^2 + abs(x)\nmegno x = 1, p_x = 0 for t in 0..10\n");
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("kink") && err.contains("test.scene:3:"), "{err}");
    // W = x² is singular at x = 0, which the orbit reaches from rest at x = 1 by t ≈ 0.94
    // (E = 1: t = ∫₀¹ x dx/√(2(1 − x)) = 2√2/3).
    let (code, _, err) = run_in(
        dir.path(),
        "coordinates x\nL = 1/2 x^2 x'^2 - x\nlyapunov x = 1, x' = 0 for t in 0..5\nplot lyapunov to l.svg\n",
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("the variational equations failed") && err.contains("test.scene:3:"), "{err}");
    assert!(!dir.path().join("l.svg").exists());
}

/// `E − H(0, y, 0, p_y)` of Hénon–Heiles: `p_x²/2` at x = 0 on the surface H = E, so the
/// section has a real `p_x` exactly where it is ≥ 0.
fn px_squared_half(e: f64, y: f64, py: f64) -> f64 {
    e - py * py / 2.0 - y * y / 2.0 + y * y * y / 3.0
}

/// The cells of a chaos map written as CSV: (x, y, value or None when blank).
fn map_cells(csv: &str) -> Vec<(f64, f64, Option<f64>)> {
    csv.lines()
        .skip(1)
        .map(|row| {
            let f: Vec<&str> = row.split(',').collect();
            assert_eq!(f.len(), 3, "{row}");
            (f[0].parse().unwrap(), f[1].parse().unwrap(), (!f[2].is_empty()).then(|| f[2].parse().unwrap()))
        })
        .collect()
}

#[test]
fn henon_heiles_map_lies_on_the_energy_surface_and_separates_order_from_chaos() {
    // The example's E = 1/6 map, smaller (20 × 20) and written as a table.
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/henon_heiles_chaos.scene"))
        .unwrap();
    let header: String = text.lines().take_while(|l| !l.starts_with("chaos_map")).map(|l| format!("{l}\n")).collect();
    let e6 = text.lines().position(|l| l.contains("H = 1/6 solve")).expect("the E = 1/6 map");
    let map = format!("{}\n{}\n", text.lines().nth(e6).unwrap(), text.lines().nth(e6 + 1).unwrap())
        .replace("points 40", "points 20")
        .replace("henon_heiles_megno_e6.svg", "map.csv");
    assert!(map.contains("points 20") && map.contains("map.csv"), "{map}");
    let dir = tempfile::tempdir().unwrap();
    let (code, out, err) = run_in(dir.path(), &format!("{header}{map}"));
    assert_eq!(code, 0, "{err}");
    let cells = map_cells(&std::fs::read_to_string(dir.path().join("map.csv")).unwrap());
    assert_eq!(cells.len(), 400);

    // Blank exactly where H = 1/6 has no real p_x at x = 0 (checked from the closed form, not
    // from the engine's root finder); every other cell has a value.
    let e = 1.0 / 6.0;
    let blank = cells.iter().filter(|c| c.2.is_none()).count();
    for &(y, py, v) in &cells {
        assert_eq!(v.is_none(), px_squared_half(e, y, py) < 0.0, "cell y = {y}, p_y = {py}: {v:?}");
    }
    assert!(blank > 80 && blank < 280, "{blank} blank cells: the grid reaches past the surface on every side");
    assert!(out.contains(&format!("{} of 400 cells on H = 1/6 ({blank} blank", 400 - blank)), "{out}");

    // Both kinds of motion appear: quasi-periodic tori with ⟨Y⟩ near 2, and chaos with ⟨Y⟩ far
    // above it (⟨Y⟩ ≈ λt/2 grows without bound).
    let values: Vec<(f64, f64, f64)> = cells.iter().filter_map(|&(y, py, v)| v.map(|v| (y, py, v))).collect();
    let regular: Vec<_> = values.iter().filter(|c| (c.2 - 2.0).abs() < 0.25).collect();
    let chaotic = values.iter().filter(|c| c.2 > 6.0).count();
    assert!(!regular.is_empty() && chaotic >= 5, "{} regular, {chaotic} chaotic: {values:?}", regular.len());

    // A second route for one regular cell: the library's indicators from the closed-form
    // p_x = √(2(E − …)) give the same ⟨Y⟩ (a torus is insensitive to the last bits of p_x).
    let h = lagrangian::parse("(p_x^2 + p_y^2)/2 + (x^2 + y^2)/2 + x^2 y - y^3/3").unwrap();
    let var = lagrangian::compile::Variational::hamiltonian(&h, &["x", "y"], &["p_x", "p_y"], &[], 1, true).unwrap();
    let start = |y: f64, py: f64| [0.0, y, (2.0 * px_squared_half(e, y, py)).sqrt(), py];
    let &&(y, py, v) = regular.iter().min_by(|a, b| (a.2 - 2.0).abs().total_cmp(&(b.2 - 2.0).abs())).unwrap();
    let r = lagrangian::chaos::indicators(&var, &start(y, py), 300.0, 1e-10).unwrap();
    assert!((r.megno - v).abs() < 1e-3 * v, "library {} vs map {v}", r.megno);
    // And the classification holds over a longer time: on the torus ⟨Y⟩ stays near 2, in
    // the sea it keeps growing like λt/2.
    let r = lagrangian::chaos::indicators(&var, &start(y, py), 1500.0, 1e-10).unwrap();
    assert!((r.megno - 2.0).abs() < 0.5, "regular cell ({y}, {py}): ⟨Y⟩(1500) = {}", r.megno);
    // (E = 1/6 is the escape energy: a chaotic orbit may slip through a saddle and blow up
    // by rounding, which is a typed error; the most chaotic cells are tried in turn.)
    let mut chaotic: Vec<&(f64, f64, f64)> = values.iter().filter(|c| c.2 > 6.0).collect();
    chaotic.sort_by(|a, b| b.2.total_cmp(&a.2));
    let (r, (y, py, v)) = chaotic
        .iter()
        .take(5)
        .find_map(|&&(y, py, v)| {
            lagrangian::chaos::indicators(&var, &start(y, py), 1500.0, 1e-10).ok().map(|r| (r, (y, py, v)))
        })
        .expect("one of the five most chaotic cells stays bound to t = 1500");
    assert!(
        r.megno > 2.0 * v && r.lyapunov[0] > 0.02,
        "chaotic cell ({y}, {py}): ⟨Y⟩(1500) = {}, λ = {:?}",
        r.megno,
        r.lyapunov
    );
}

#[test]
fn chaos_statements_compile_once_and_show_in_the_explain_plan() {
    // Three statements with one tangent vector and MEGNO's accumulator share one compiled
    // system; the spectrum (four tangents) needs its own. `--explain` lists both compilations
    // and every integration.
    let dir = tempfile::tempdir().unwrap();
    let scene = "\
coordinates x, y
H = (p_x^2 + p_y^2)/2 + (x^2 + y^2)/2 + x^2 y - y^3/3
megno x = 0, y = 0.1, p_x = 0.3, p_y = 0 for t in 0..10 as a
fli x = 0, y = 0.2, p_x = 0.3, p_y = 0 for t in 0..10 as b
chaos_map megno y = -0.2..0.2, p_y = -0.2..0.2, x = 0 for t in 0..5 on H = 1/12 solve p_x > 0 points 2 to m.csv
lyapunov x = 0, y = 0.1, p_x = 0.3, p_y = 0 for t in 0..10 as s
";
    let (code, out, err) = run_with(dir.path(), scene, &["--explain"]);
    assert_eq!(code, 0, "{err}");
    let built: Vec<&str> = out.lines().filter(|l| l.trim_start().starts_with("built")).collect();
    let compiled: Vec<&&str> = built.iter().filter(|l| l.contains("variational equations of H")).collect();
    assert_eq!(compiled.len(), 2, "{out}");
    assert!(compiled[0].contains("line 3") && compiled[0].contains("1 tangent vector and MEGNO"), "{out}");
    assert!(compiled[1].contains("line 6") && compiled[1].contains("4 tangent vectors,"), "{out}");
    let runs: Vec<&&str> = built.iter().filter(|l| l.contains("integration")).collect();
    assert_eq!(runs.len(), 4, "{out}");
    for (line, what) in
        runs.iter().zip(["megno a: one orbit", "fli b: one orbit", "chaos map megno: 4 starts", "lyapunov s"])
    {
        assert!(line.contains(what) && line.contains("with taylor"), "{line} / {what}");
    }
}

/// The real backend, counting what the chaos statements ask of it.
struct Counting(std::sync::Arc<std::sync::Mutex<HashMap<&'static str, usize>>>);

impl Counting {
    fn bump(&self, what: &'static str) {
        *self.0.lock().unwrap().entry(what).or_default() += 1;
    }
}

mod counting {
    use super::Counting;
    use lagrangian::chaos::{Budget, Indicator, Indicators};
    use lagrangian::expr::Expr;
    use lagrangian::scene::backend::{
        CompileRequest, Compiled, CompiledVariational, RunRequest, SystemRef, VariationalRequest,
    };
    use lagrangian::scene::{Backend, BackendError, Line, NativeBackend, Trajectory};

    impl Backend for Counting {
        fn euler_lagrange(&self, sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError> {
            NativeBackend.euler_lagrange(sys, l)
        }
        fn legendre(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
            NativeBackend.legendre(sys, l)
        }
        fn hamilton(&self, sys: &SystemRef, h: &Expr) -> Result<Vec<Line>, BackendError> {
            NativeBackend.hamilton(sys, h)
        }
        fn conserved(&self, sys: &SystemRef, f: &Expr, h: bool) -> Result<Vec<Line>, BackendError> {
            NativeBackend.conserved(sys, f, h)
        }
        fn energy(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
            NativeBackend.energy(sys, l)
        }
        fn bracket(&self, sys: &SystemRef, f: &Expr, g: &Expr) -> Result<Expr, BackendError> {
            NativeBackend.bracket(sys, f, g)
        }
        fn compile(&self, req: &CompileRequest) -> Result<Compiled, BackendError> {
            NativeBackend.compile(req)
        }
        fn integrate(
            &self,
            c: &Compiled,
            run: &RunRequest,
            progress: &mut dyn FnMut(f64),
        ) -> Result<Trajectory, BackendError> {
            NativeBackend.integrate(c, run, progress)
        }
        fn compile_variational(&self, req: &VariationalRequest) -> Result<CompiledVariational, BackendError> {
            self.bump("compile_variational");
            NativeBackend.compile_variational(req)
        }
        fn indicators(
            &self,
            c: &CompiledVariational,
            x0: &[f64],
            t: f64,
            tol: f64,
            budget: &Budget,
        ) -> Result<Indicators, BackendError> {
            self.bump("indicators");
            NativeBackend.indicators(c, x0, t, tol, budget)
        }
        fn chaos_map(
            &self,
            c: &CompiledVariational,
            starts: &[Vec<f64>],
            t: f64,
            tol: f64,
            budget: &Budget,
            which: Indicator,
            progress: &mut dyn FnMut(f64),
        ) -> Vec<Result<lagrangian::chaos::Cell, BackendError>> {
            self.bump("chaos_map");
            NativeBackend.chaos_map(c, starts, t, tol, budget, which, progress)
        }
    }
}

#[test]
fn repeated_chaos_statements_reuse_the_compiled_system() {
    use lagrangian::scene::{Mode, Options, Session, Status, Step};
    let counts = std::sync::Arc::new(std::sync::Mutex::new(HashMap::new()));
    let dir = tempfile::tempdir().unwrap();
    let session = || {
        let mut opts = Options::new(Mode::Scene);
        opts.out_dir = dir.path().to_path_buf();
        Session::with_backend(opts, Box::new(Counting(counts.clone())))
    };
    let get = |k: &str| counts.lock().unwrap().get(k).copied().unwrap_or(0);
    let scene = "\
coordinates x
parameters k = 2
H = 1/2 p_x^2 + 1/2 k x^2
megno x = 1, p_x = 0 for t in 0..10
fli x = 0.5, p_x = 0 for t in 0..10
chaos_map megno x = -1..1, p_x = -1..1 for t in 0..5 points 2 to m.csv
";
    // Three statements on one system: compiled once, integrated three times.
    let mut first = session();
    first.run_scene("a", scene).unwrap();
    assert_eq!((get("compile_variational"), get("indicators"), get("chaos_map")), (1, 2, 1));
    // The same scene again on the kept cache: nothing recompiled, and the plan says why.
    let mut second = session().with_cache(first.into_cache());
    second.run_scene("a", scene).unwrap();
    assert_eq!((get("compile_variational"), get("indicators"), get("chaos_map")), (1, 4, 2));
    assert!(second.plan().iter().any(|e| e.step == Step::Compile && e.status == Status::Reused), "{:?}", second.plan());
    // A new parameter value is new code.
    let mut third = session().with_cache(second.into_cache());
    third.run_scene("a", &scene.replace("k = 2", "k = 3")).unwrap();
    assert_eq!(get("compile_variational"), 2);
}

#[test]
fn taylor_runs_stop_at_kinks_singular_mass_matrices_and_bad_tolerances_with_located_errors() {
    // The same bad-input list for `simulate … with taylor`: each a located, typed
    // error and no file written, never a hang.
    let dir = tempfile::tempdir().unwrap();
    let export = "export t, x to a.csv\n";
    for (scene, says) in [
        // V = |x|: a kink at x = 0, started on it and reached from x = 1.
        ("coordinates x\nH = 1/2 p_x^2 + abs(x)\nsimulate x = 0, p_x = 1 for t in 0..5 with taylor\n", "kink"),
        ("coordinates x\nH = 1/2 p_x^2 + abs(x)\nsimulate x = 1, p_x = 0 for t in 0..5 with taylor\n", "kink"),
        ("coordinates x\nH = 1/2 p_x^2 + x^2\nsimulate x = 1, p_x = 0 for t in 0..5 with taylor tol = 0\n", "positive"),
        (
            "coordinates x\nH = 1/2 p_x^2 + x^2\nsimulate x = 1, p_x = 0 for t in 0..5 with taylor tol = -1e-3\n",
            "positive",
        ),
        (
            "coordinates x\nH = 1/2 p_x^2 + x^2\nsimulate x = 1, p_x = 0 for t in 0..5 with taylor tol = 1e-30\n",
            "below what f64",
        ),
    ] {
        let (code, _, err) = run_in(dir.path(), &format!("{scene}{export}"));
        assert_eq!(code, 2, "{scene}: {err}");
        assert!(err.contains(says) && err.contains("test.scene:3:"), "{scene}: {err}");
        assert!(!dir.path().join("a.csv").exists(), "{scene}");
    }
    // W = x² (L = x² x'²/2 − x) is singular at x = 0, reached from rest at x = 1 at
    // t = ∫₀¹ x dx/√(2(1 − x)) = 2√2/3 (energy x² x'²/2 + x = 1): the run stops there.
    let (code, _, err) = run_in(
        dir.path(),
        &format!("coordinates x\nL = 1/2 x^2 x'^2 - x\nsimulate x = 1, x' = 0 for t in 0..5 with taylor\n{export}"),
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("test.scene:3:"), "{err}");
    let at = err.find("stopped at t = ").map(|i| &err[i + 15..]).unwrap_or_else(|| panic!("{err}"));
    let t: f64 = at.split([' ', '(']).next().unwrap().parse().unwrap();
    assert!((t - 2.0 * 2f64.sqrt() / 3.0).abs() < 1e-6, "stopped at {t}: {err}");
}
