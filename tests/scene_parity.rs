//! Issue 15 item 5: every derivation of the command line is usable from a scene with the same
//! output. Each test runs a scene statement and the matching `lagrangian` command on the same
//! input (plain format, the same positive symbols) and compares the printed lines; each also
//! checks the result itself against an independent value.

use std::process::Command;

use lagrangian::canonical::{decide_zero, elliptic_e, elliptic_k, ZeroCheck};
use lagrangian::scene::{Mode, Options, Session};
use lagrangian::{parse_with, Declarations};

fn cli(args: &[&str]) -> Vec<String> {
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian")).args(args).output().expect("binary runs");
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).lines().map(str::to_string).collect()
}

fn scene(text: &str) -> Vec<String> {
    let mut s = Session::new(Options::new(Mode::Scene));
    s.run_scene("parity", text).unwrap_or_else(|e| panic!("{e:?}"));
    s.take_output()
}

/// The lines a scene prints for its last statement (the earlier ones print nothing).
fn same(scene_text: &str, args: &[&str]) -> Vec<String> {
    let a = scene(scene_text);
    let b = cli(args);
    assert_eq!(a, b, "scene and command line differ");
    a
}

#[test]
fn lie_series_of_a_rotation() {
    let out = same(
        "coordinates x, y\nlie x with x p_y - y p_x order 5 as plain",
        &["lie", "x", "--generator", "x p_y - y p_x", "--order", "5", "--coords", "x,y"],
    );
    // exp(ε{·, L_z}) x = x cos ε − y sin ε: the series agrees to O(ε⁶).
    let d = Declarations::new();
    let series = parse_with(&out[0], &d).expect("re-parses");
    let (x, y, eps) = (0.7, -1.3, 0.05);
    let env: lagrangian::eval::Env =
        [("x", x), ("y", y), ("ε", eps)].into_iter().map(|(k, v)| (k.to_string(), v)).collect();
    let v = lagrangian::eval::eval(&series, &env).expect("evaluates");
    let exact = x * eps.cos() - y * eps.sin();
    assert!((v - exact).abs() < 2.0 * eps.powi(6), "{v} vs {exact}");
}

#[test]
fn lie_flow_of_the_oscillator() {
    let out = same(
        "coordinates q\nH = p_q^2/2 + q^2/2\nlie q flow order 4 as plain",
        &["lie", "q", "--flow", "p_q^2/2 + q^2/2", "--order", "4", "--coords", "q"],
    );
    // q(t) = q cos t + p sin t to order t⁴.
    let hand = parse_with("q (1 - t^2/2 + t^4/24) + p_q (t - t^3/6)", &Declarations::new()).expect("parses");
    let got = parse_with(&out[0], &Declarations::new()).expect("re-parses");
    assert_eq!(decide_zero(&got.minus(&hand)), ZeroCheck::Proven, "{}", out[0]);
}

#[test]
fn integral_of_angular_momentum_in_cartesian_kepler() {
    let h = "(p_x^2 + p_y^2)/2 - 1/sqrt(x^2 + y^2)";
    let out = same(
        &format!("coordinates x, y\nH = {h}\nintegral x p_y - y p_x as plain"),
        &["integral", "x p_y - y p_x", "--hamiltonian", h, "--coords", "x,y"],
    );
    assert_eq!(out[0], "df/dt = {f, H} + ∂f/∂t = 0");
    assert!(out[1].starts_with("an integral of motion"), "{out:?}");
    let out = same(
        &format!("coordinates x, y\nH = {h}\nintegral x p_x as plain"),
        &["integral", "x p_x", "--hamiltonian", h, "--coords", "x,y"],
    );
    assert!(out[1].starts_with("not an integral of motion"), "{out:?}");
}

/// Librations and rotations of the pendulum `H = p²/2 − cos θ`: the table equals the command
/// line's, and J, T agree with the closed forms in complete elliptic integrals.
#[test]
fn action_of_librations_and_rotations() {
    let out = same(
        "coordinates θ\nH = p_θ^2/2 - cos(θ)\naction at E = -0.5, 0.5, 2, 3",
        &["action", "--hamiltonian", "p_θ^2/2 - cos(θ)", "--coord", "θ", "--energy", "-0.5,0.5,2,3"],
    );
    let rows: Vec<Vec<f64>> =
        out[1..].iter().map(|l| l.split_whitespace().take(4).map(|x| x.parse().expect("a number")).collect()).collect();
    for row in &rows {
        let (e, j, t) = (row[0], row[1], row[2]);
        let (j_hand, t_hand) = if e < 1.0 {
            // Libration, k² = (E + 1)/2: J = (8/π)(E(k) − (1 − k²) K(k)), T = 4 K(k).
            let k = ((e + 1.0) / 2.0).sqrt();
            (8.0 / std::f64::consts::PI * (elliptic_e(k) - (1.0 - k * k) * elliptic_k(k)), 4.0 * elliptic_k(k))
        } else {
            // Rotation, k² = 2/(E + 1): J = (1/2π)∫₀^{2π} √(2(E + cos θ)) dθ = (2/π) √(2(E+1)) E(k),
            // T = ∫₀^{2π} dθ/√(2(E + cos θ)) = 4 K(k)/√(2(E+1)).
            let k = (2.0 / (e + 1.0)).sqrt();
            let s = (2.0 * (e + 1.0)).sqrt();
            (2.0 / std::f64::consts::PI * s * elliptic_e(k), 4.0 * elliptic_k(k) / s)
        };
        assert!((j - j_hand).abs() < 1e-12 * j_hand, "E = {e}: J = {j}, closed form {j_hand}");
        assert!((t - t_hand).abs() < 1e-12 * t_hand, "E = {e}: T = {t}, closed form {t_hand}");
    }
    assert!(out[3].contains("rotation") && out[4].contains("rotation") && !out[1].contains("rotation"));
}

#[test]
fn point_transformation_to_polar_coordinates() {
    let l = "1/2 m (x'^2 + y'^2) - 1/2 k (x^2 + y^2)";
    let out = same(
        &format!(
            "coordinates x, y\nparameters m, k positive\nL = {l}\ntransform with x = r cos(φ), y = r sin(φ) as plain"
        ),
        &[
            "transform",
            l,
            "--map",
            "x=r cos(φ)",
            "--map",
            "y=r sin(φ)",
            "--to",
            "r,φ",
            "--coords",
            "x,y",
            "--positive",
            "m,k",
        ],
    );
    let d = Declarations::new().with_positive(["m", "k"]);
    let got = parse_with(out[0].strip_prefix("L = ").expect("L = …"), &d).expect("re-parses");
    let hand = parse_with("1/2 m (r'^2 + r^2 φ'^2) - 1/2 k r^2", &d).expect("parses");
    assert_eq!(decide_zero(&got.minus(&hand)), ZeroCheck::Proven, "{}", out[0]);
    // Naming the new coordinates explicitly gives the same line.
    let named = scene(&format!(
        "coordinates x, y\nparameters m, k positive\nL = {l}\ntransform with x = r cos(φ), y = r sin(φ) to r, φ as plain"
    ));
    assert_eq!(named, out);
}

#[test]
fn average_solved_to_first_order_in_a_small_parameter() {
    let l = "1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)";
    let trial = "l0 (A cos(θ) + B cos(3 θ) + C sin(3 θ))";
    let out = same(
        &format!(
            "coordinates x\nparameters m, ω0, σ, l0 positive\nL = {l}\n\
             average L with x = {trial} phase θ frequency ω amplitudes A, B, C small σ unperturbed ω0 as plain"
        ),
        &[
            "average",
            l,
            "--trial",
            &format!("x = {trial}"),
            "--phase",
            "θ",
            "--frequency",
            "ω",
            "--small",
            "σ",
            "--unperturbed",
            "ω0",
            "--positive",
            "m,ω0,σ,l0",
        ],
    );
    // PHYSICS.md §2.8.2 to first order (Lindstedt for x'' + ω0² x + 2σω0² x³ = 0):
    // ω² = ω0² (1 + 3/2 σ A²), so ω = ω0 + 3/4 σ A² ω0; B = σ A³/16; C = 0.
    let d = Declarations::new().with_positive(["m", "ω0", "σ", "l0"]);
    let find = |p: &str| out.iter().find_map(|l| l.strip_prefix(p)).unwrap_or_else(|| panic!("no `{p}` in {out:?}"));
    let w = parse_with(find("  ω = "), &d).expect("re-parses");
    let w_hand = parse_with("ω0 + 3/4 σ A^2 ω0", &d).expect("parses");
    assert_eq!(decide_zero(&w.minus(&w_hand)), ZeroCheck::Proven, "{out:?}");
    let b = parse_with(find("  B = "), &d).expect("re-parses");
    assert_eq!(decide_zero(&b.minus(&parse_with("σ A^3/16", &d).expect("parses"))), ZeroCheck::Proven);
    assert_eq!(find("  C = "), "0");
}

/// `conserved` prints the same lines in a scene and on the command line, the symmetry search
/// included: Kepler in Cartesian coordinates (given by its Hamiltonian, so the charge is in
/// momenta) gives H and L_z = x p_y − y p_x with its generator and the search's bound.
#[test]
fn conserved_with_the_symmetry_search() {
    let h = "(p_x^2 + p_y^2)/(2 m) - k/sqrt(x^2 + y^2)";
    let out = same(
        &format!("coordinates x, y\nparameters m, k positive\nH = {h}\nconserved as plain"),
        &["conserved", h, "--hamiltonian", "--coords", "x,y", "--positive", "m,k"],
    );
    assert_eq!(out.len(), 2, "{out:#?}");
    let d = Declarations::new().with_positive(["m", "k"]);
    let value = |line: &str| {
        let rhs = line.split_once(" = ").expect("name = value").1;
        parse_with(rhs.split("   (").next().expect("a value"), &d).expect("re-parses")
    };
    assert!(out[0].starts_with("H = "));
    assert_eq!(decide_zero(&value(&out[0]).minus(&parse_with(h, &d).unwrap())), ZeroCheck::Proven, "{}", out[0]);
    assert!(out[1].starts_with("Q1 = ") && out[1].contains("rotation in (x, y)"), "{}", out[1]);
    let lz = parse_with("x p_y - y p_x", &d).unwrap();
    let q = value(&out[1]);
    assert!(
        decide_zero(&q.minus(&lz)) == ZeroCheck::Proven || decide_zero(&q.plus(&lz)) == ZeroCheck::Proven,
        "{}",
        out[1]
    );
    assert!(out[1].contains("point symmetries searched: "), "{}", out[1]);
}

/// `transform with F1 = …` prints `lagrangian canonical --f1 …`'s lines: the relations, both
/// maps, the branches and K. The oscillator's action–angle map (PHYSICS.md §4): q =
/// √(2P/(mω)) sin Q, p = √(2mωP) cos Q, K = ωP, checked at a point.
#[test]
fn generating_function_transform() {
    let h = "p_q^2/(2 m) + 1/2 m ω^2 q^2";
    let out = same(
        &format!("coordinates q\nparameters m, ω positive\nH = {h}\ntransform with F1 = 1/2 m ω q^2 cot(Q) new Q, P as plain"),
        &["canonical", "--hamiltonian", h, "--coords", "q", "--f1", "1/2 m ω q^2 cot(Q)", "--new", "Q,P", "--positive", "m,ω"],
    );
    assert_eq!(out[0], "relations (F1):");
    assert!(out.iter().any(|l| l == "old variables (inverse map):") && out.iter().any(|l| l.starts_with("branch: ")));
    let d = Declarations::new().with_positive(["m", "ω"]);
    let at = |prefix: &str, hand: &str| {
        // The last such line: the inverse map comes after the relations.
        let line =
            out.iter().rev().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in {out:?}"));
        let env: lagrangian::eval::Env =
            [("m", 2.0), ("ω", 3.0), ("P", 0.7), ("Q", 2.4)].into_iter().map(|(k, v)| (k.to_string(), v)).collect();
        let got = lagrangian::eval::eval(&parse_with(line, &d).expect("re-parses"), &env).unwrap();
        let want = lagrangian::eval::eval(&parse_with(hand, &d).unwrap(), &env).unwrap();
        assert!((got - want).abs() < 1e-14, "{prefix}{line}: {got} vs {want}");
    };
    at("  q = ", "sqrt(2 P/(m ω)) sin(Q)");
    at("  p_q = ", "sqrt(2 m ω P) cos(Q)");
    at("K = ", "ω P");
}

/// `average` without `small` prints `lagrangian average`'s lines. The oscillator with
/// x = A cos θ (PHYSICS.md §2.5.1): ⟨L⟩ = ¼ m A² (ω² − ω0²), ∂⟨L⟩/∂A = ½ m A (ω² − ω0²),
/// J = ½ m A² ω.
#[test]
fn average_without_a_small_parameter() {
    let l = "1/2 m (x'^2 - ω0^2 x^2)";
    let out = same(
        &format!(
            "coordinates x\nparameters m, ω0 positive\nL = {l}\naverage L with x = A cos(θ) phase θ frequency ω amplitudes A as plain"
        ),
        &["average", l, "--trial", "x = A cos(θ)", "--phase", "θ", "--frequency", "ω", "--positive", "m,ω0"],
    );
    assert_eq!(out.len(), 3, "{out:?}");
    let d = Declarations::new().with_positive(["m", "ω0"]);
    let check = |line: &str, prefix: &str, hand: &str| {
        let rhs = line.strip_prefix(prefix).unwrap_or_else(|| panic!("`{line}` does not start with `{prefix}`"));
        let got = parse_with(rhs.trim_end_matches(" = 0"), &d).expect("re-parses");
        let hand = parse_with(hand, &d).unwrap();
        assert_eq!(decide_zero(&got.minus(&hand)), ZeroCheck::Proven, "{line}");
    };
    check(&out[0], "⟨L⟩ = ", "1/4 m A^2 (ω^2 - ω0^2)");
    check(&out[1], "∂⟨L⟩/∂A = ", "1/2 m A (ω^2 - ω0^2)");
    check(&out[2], "J = ∂⟨L⟩/∂ω = ", "1/2 m A^2 ω");
}

/// The help examples of the new statements parse as one statement each (the REPL's `help`
/// shows them).
#[test]
fn help_examples_of_the_new_statements_parse() {
    for word in ["lie", "integral", "action", "transform (point)", "average"] {
        let t = lagrangian::scene::help::TOPICS.iter().find(|t| t.word == word).expect("a help topic");
        let parsed = lagrangian::scene::parser::parse_scene(t.example);
        assert!(matches!(&parsed, Ok(v) if v.len() == 1), "`{}`: {parsed:?}", t.example);
    }
}
