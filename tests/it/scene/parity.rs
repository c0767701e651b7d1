//! every derivation of the command line is usable from a scene with the same
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

/// The second-order series and the relations solved along A (`order 2 for A in 0.5..1 points
/// 3` against `--order 2 --sweep A=0.5..1 --points 3 --params …`): the same lines; the row at
/// A = 1 is SymPy's nsolve value (scripts/average_series_sympy.py) to the six printed decimals.
#[test]
fn average_to_second_order_and_swept_along_the_amplitude() {
    let l = "1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)";
    let trial = "l0 (A cos(θ) + B cos(3 θ) + C sin(3 θ))";
    let out = same(
        &format!(
            "coordinates x\nparameters m = 1, ω0 = 1, σ = 1, l0 = 1 positive\nL = {l}\n\
             average L with x = {trial} phase θ frequency ω amplitudes A, B, C small σ unperturbed ω0 order 2 \
             for A in 0.5..1 points 3 as plain"
        ),
        &[
            "average",
            l,
            "--trial",
            &format!("x = {trial}"),
            "--small",
            "σ",
            "--unperturbed",
            "ω0",
            "--order",
            "2",
            "--sweep",
            "A=0.5..1",
            "--points",
            "3",
            "--params",
            "m=1,ω0=1,σ=1,l0=1",
            "--positive",
            "m,ω0,σ,l0",
        ],
    );
    assert!(out.iter().any(|l| l == "to second order in σ:"), "{out:?}");
    assert_eq!(out.last().map(String::as_str), Some("  A = 1: ω = 1.594315 (series 1.515625), B = 0.026489, C = 0"));
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

/// A system given both ways: scene declarations and the command line's flags.
struct Twin {
    coords: &'static str,
    positive: &'static str,
    l: &'static str,
    /// `(coordinate, Q)` pairs.
    forces: &'static [(&'static str, &'static str)],
    rayleigh: Option<&'static str>,
    constraints: &'static [&'static str],
}

impl Twin {
    fn scene(&self, statement: &str) -> Vec<String> {
        let mut text = format!(
            "coordinates {}\nparameters {} positive\nL = {}\n",
            self.coords.replace(',', ", "),
            self.positive.replace(',', ", "),
            self.l
        );
        for (q, f) in self.forces {
            text.push_str(&format!("force {q} = {f}\n"));
        }
        if let Some(r) = self.rayleigh {
            text.push_str(&format!("rayleigh {r}\n"));
        }
        for c in self.constraints {
            text.push_str(&format!("constraint {c}\n"));
        }
        text.push_str(statement);
        scene(&text)
    }

    fn cli(&self, command: &str, extra: &[&str], format: &str) -> Vec<String> {
        let mut args: Vec<String> = vec![command.into(), self.l.into()];
        args.extend(extra.iter().map(|s| s.to_string()));
        args.extend(["--coords".into(), self.coords.into(), "--positive".into(), self.positive.into()]);
        for (q, f) in self.forces {
            args.extend(["--force".into(), format!("{q}={f}")]);
        }
        if let Some(r) = self.rayleigh {
            args.extend(["--rayleigh".into(), r.into()]);
        }
        for c in self.constraints {
            args.extend(["--constraint".into(), c.to_string()]);
        }
        args.extend(["--format".into(), format.into()]);
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        cli(&refs)
    }
}

const PENDULUM: Twin = Twin {
    coords: "θ",
    positive: "m,l,g",
    l: "1/2 m l^2 θ'^2 + m g l cos(θ)",
    forces: &[],
    rayleigh: None,
    constraints: &[],
};
const KEPLER: Twin = Twin {
    coords: "r,φ",
    positive: "m,k",
    l: "1/2 m (r'^2 + r^2 φ'^2) + k/r",
    forces: &[],
    rayleigh: None,
    constraints: &[],
};
const DRIVEN_DAMPED: Twin = Twin {
    coords: "x",
    positive: "m,k,b,A,Ω",
    l: "1/2 m x'^2 - 1/2 k x^2",
    forces: &[("x", "A cos(Ω t)")],
    rayleigh: Some("1/2 b x'^2"),
    constraints: &[],
};
const SPIRAL_DRAG: Twin = Twin {
    coords: "r,φ",
    positive: "m,k,c",
    l: "1/2 m (r'^2 + r^2 φ'^2) + k/r",
    forces: &[("φ", "-c φ'")],
    rayleigh: None,
    constraints: &[],
};
const DISC: Twin = Twin {
    coords: "y,θ",
    positive: "m,R,g,α",
    l: "1/2 m y'^2 + 1/4 m R^2 θ'^2 + m g y sin(α)",
    forces: &[],
    rayleigh: None,
    constraints: &["y - R θ"],
};
const DAMPED_CARTESIAN_PENDULUM: Twin = Twin {
    coords: "x,y",
    positive: "m,g,b,l",
    l: "1/2 m (x'^2 + y'^2) - m g y",
    forces: &[],
    rayleigh: Some("1/2 b (x'^2 + y'^2)"),
    constraints: &["x^2 + y^2 = l^2"],
};

const TWINS: [&Twin; 6] = [&PENDULUM, &KEPLER, &DRIVEN_DAMPED, &SPIRAL_DRAG, &DISC, &DAMPED_CARTESIAN_PENDULUM];

/// Every derivation statement with a command-line twin prints the same bytes both ways, in
/// plain and Unicode, on conservative, forced, damped and constrained systems: `el` (the
/// command line's first lines, before `W`), `accelerations` (the last lines of
/// `el --accelerations`), `legendre` (its `H` line, after the momenta), `hamilton` and
/// `conserved` (all lines).
#[test]
fn derivations_print_the_same_bytes_in_scenes_and_on_the_command_line() {
    for twin in TWINS {
        for format in ["plain", "unicode"] {
            let el = twin.scene(&format!("el as {format}"));
            let cli_el = twin.cli("el", &[], format);
            assert!(!el.is_empty());
            assert_eq!(el[..], cli_el[..el.len()], "{}: el, {format}", twin.l);
            assert!(cli_el[el.len()].starts_with("W["), "{}: el section ends before W: {cli_el:#?}", twin.l);

            let h = twin.scene(&format!("legendre as {format}"));
            let cli_h = twin.cli("legendre", &[], format);
            assert_eq!(h.len(), 1);
            assert_eq!(h[0], cli_h[cli_h.len() - 1], "{}: legendre, {format}", twin.l);

            let ham = twin.scene(&format!("hamilton as {format}"));
            assert_eq!(ham, twin.cli("hamilton", &["--lagrangian"], format), "{}: hamilton, {format}", twin.l);

            let acc = twin.scene(&format!("accelerations as {format}"));
            let cli_acc = twin.cli("el", &["--accelerations"], format);
            assert!(!acc.is_empty() && acc.len() < cli_acc.len());
            assert_eq!(acc[..], cli_acc[cli_acc.len() - acc.len()..], "{}: accelerations, {format}", twin.l);

            let cons = twin.scene(&format!("conserved as {format}"));
            assert_eq!(cons, twin.cli("conserved", &[], format), "{}: conserved, {format}", twin.l);
        }
    }
}

fn rhs_of(lines: &[String], prefix: &str, d: &Declarations) -> lagrangian::Expr {
    let line =
        lines.iter().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in {lines:#?}"));
    parse_with(line.split("   (").next().unwrap(), d).unwrap_or_else(|e| panic!("`{line}`: {e}"))
}

/// Scene `el` with a constraint shows the multiplier terms, with a force and a Rayleigh
/// function the generalized forces (they were dropped before): the disc's `E_y = λ1`,
/// `E_θ = −R λ1` (L + λ (y − R θ)), the driven damped oscillator's `E_x = A cos(Ω t) − b x'`.
#[test]
fn scene_el_shows_multipliers_and_generalized_forces() {
    let d = Declarations::new().with_positive(["m", "R", "g", "α", "k", "b", "A", "Ω"]);
    let out = DISC.scene("el as plain");
    let lhs_rhs = |line: &str| {
        let (lhs, rhs) = line.split_once(": ").unwrap().1.split_once(" = ").unwrap();
        (parse_with(lhs, &d).unwrap(), parse_with(rhs, &d).unwrap())
    };
    let proven = |a: &lagrangian::Expr, b: &str| {
        assert_eq!(decide_zero(&a.minus(&parse_with(b, &d).unwrap())), ZeroCheck::Proven, "{a} vs {b}")
    };
    let (e, r) = lhs_rhs(&out[0]);
    proven(&e, "m y'' - m g sin(α)");
    proven(&r, "λ1");
    let (e, r) = lhs_rhs(&out[1]);
    proven(&e, "1/2 m R^2 θ''");
    proven(&r, "-R λ1");
    let out = DRIVEN_DAMPED.scene("el as plain");
    let (e, r) = lhs_rhs(&out[0]);
    proven(&e, "m x'' + k x");
    proven(&r, "A cos(Ω t) - b x'");
}

/// Scene and command-line `conserved` with a force say which candidate breaks and why, with
/// its rate of change: for the driven damped oscillator dh/dt = x' (Q − ∂R/∂x') =
/// x' (A cos Ω t − b x'); for a central force with a drag on φ, p_φ changes at Q_φ = −c φ'
/// and h at φ' Q_φ = −c φ'² (PHYSICS.md §1: E_i = Q_i, dh/dt = Σ q' Q − ∂L/∂t).
#[test]
fn conserved_says_what_breaks_each_candidate() {
    let d = Declarations::new().with_positive(["m", "k", "b", "A", "Ω", "c"]);
    let rate = |line: &str| {
        let after = line.split("not conserved: ").nth(1).unwrap_or_else(|| panic!("{line}"));
        let value = after.split_once(" = ").unwrap().1.split(", broken by").next().unwrap();
        parse_with(value, &d).unwrap()
    };
    let proven = |a: &lagrangian::Expr, b: &str| {
        assert_eq!(decide_zero(&a.minus(&parse_with(b, &d).unwrap())), ZeroCheck::Proven, "{a} vs {b}")
    };
    let out = DRIVEN_DAMPED.scene("conserved as plain");
    assert_eq!(out.len(), 1, "{out:#?}");
    assert!(out[0].starts_with("h = ") && out[0].contains("force on x") && out[0].contains("Rayleigh"), "{}", out[0]);
    proven(&rate(&out[0]), "x' (A cos(Ω t) - b x')");
    let out = SPIRAL_DRAG.scene("conserved as plain");
    assert_eq!(out.len(), 2, "{out:#?}");
    assert!(out[0].starts_with("p_φ = ") && out[0].contains("broken by the force on φ"), "{}", out[0]);
    proven(&rate(&out[0]), "-c φ'");
    proven(&rate(&out[1]), "-c φ'^2");
    assert_eq!(out, SPIRAL_DRAG.cli("conserved", &[], "plain"));
    // JSON lists the broken candidates apart from the conserved quantities.
    let json: serde_json::Value = serde_json::from_str(&SPIRAL_DRAG.cli("conserved", &[], "json").join("\n")).unwrap();
    assert_eq!(json["conserved"].as_array().map(Vec::len), Some(0), "{json}");
    let broken = json["not_conserved"].as_array().expect("an array");
    assert_eq!(broken.iter().map(|b| b["name"].as_str().unwrap()).collect::<Vec<_>>(), ["p_φ", "h"]);
}

/// `lagrangian el --accelerations` with a constraint solves the augmented system (λ eliminated
/// by the twice-differentiated constraint): the disc rolls down with y'' = 2 g sin α/3 (not the
/// free g sin α), θ'' = y''/R, λ1 = −m g sin α/3; the damped pendulum on x² + y² = l² matches
/// SymPy's LagrangesMethod-style solve (scripts/report_constrained_sympy.py) at a sample state.
#[test]
fn constrained_accelerations_and_multipliers() {
    let d = Declarations::new().with_positive(["m", "R", "g", "α", "b", "l"]);
    let out = DISC.cli("el", &["--accelerations"], "plain");
    let proven = |e: lagrangian::Expr, b: &str| {
        assert_eq!(decide_zero(&e.minus(&parse_with(b, &d).unwrap())), ZeroCheck::Proven, "{e} vs {b}")
    };
    proven(rhs_of(&out, "y'' = ", &d), "2 g sin(α)/3");
    proven(rhs_of(&out, "θ'' = ", &d), "2 g sin(α)/(3 R)");
    proven(rhs_of(&out, "λ1 = ", &d), "-m g sin(α)/3");

    let out = DAMPED_CARTESIAN_PENDULUM.cli("el", &["--accelerations"], "plain");
    let env: lagrangian::eval::Env =
        [("x", 0.6), ("y", -0.7), ("x'", 0.3), ("y'", 0.25), ("m", 1.3), ("g", 9.81), ("b", 0.4), ("l", 1.0)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
    // SymPy, 17 digits: x'' = −5.0461628959276021, y'' = −4.1074253393665163,
    // λ1 = −5.3666764705882377 (the same by hand: λ = (m g y − m v² + b (x x' + y y'))/(2 r²)).
    for (name, want) in
        [("x'' = ", -5.046_162_895_927_602), ("y'' = ", -4.107_425_339_366_516), ("λ1 = ", -5.366_676_470_588_238)]
    {
        let got = lagrangian::eval::eval(&rhs_of(&out, name, &d), &env).unwrap();
        assert!((got - want).abs() < 1e-13 * want.abs(), "{name}{got} vs {want}");
    }
}

/// `pb f, g` prints `{f, g} = …`, the command line `lagrangian pb f g` the value alone (its
/// documented output, like `diff`): the value is the same bytes in plain and Unicode. By hand,
/// {L_x, L_y} = L_z = x p_y − y p_x, and {x p_x, p_x²/2 + x²} = p_x² − 2 x².
#[test]
fn pb_prints_the_same_value() {
    let d = Declarations::new();
    for (f, g, coords, hand) in
        [("y p_z - z p_y", "z p_x - x p_z", "x,y,z", "x p_y - y p_x"), ("x p_x", "p_x^2/2 + x^2", "x", "p_x^2 - 2 x^2")]
    {
        for format in ["plain", "unicode"] {
            let s = scene(&format!("coordinates {}\npb {f}, {g} as {format}", coords.replace(',', ", ")));
            let c = cli(&["pb", f, g, "--coords", coords, "--format", format]);
            assert_eq!(s, vec![format!("{{{f}, {g}}} = {}", c[0])], "pb {f}, {g} as {format}");
        }
        let v = cli(&["pb", f, g, "--coords", coords]);
        let got = parse_with(&v[0], &d).unwrap();
        assert_eq!(decide_zero(&got.minus(&parse_with(hand, &d).unwrap())), ZeroCheck::Proven, "{}", v[0]);
    }
}

/// `geodesic` with a shooting solution: the same lines in a scene and on the command line
/// (plain and Unicode), and the sphere's Christoffel symbol Γ^θ_φφ = −sin θ cos θ by hand.
#[test]
fn geodesic_of_the_sphere_with_shooting() {
    for format in ["plain", "unicode"] {
        let lines = same(
            &format!("coordinates θ, φ\ngeodesic ds^2 = dθ^2 + sin(θ)^2 dφ^2 from (1, 0) to (2, 1.5) as {format}\n"),
            &[
                "geodesic",
                "dθ^2 + sin(θ)^2 dφ^2",
                "--coords",
                "θ,φ",
                "--from",
                "1,0",
                "--to",
                "2,1.5",
                "--format",
                format,
            ],
        );
        assert!(lines.iter().any(|l| l == "Γ^θ_φφ = -sin(θ) cos(θ)"), "{lines:#?}");
        assert!(lines.iter().any(|l| l.starts_with("shooting: q'(0) = (")), "{lines:#?}");
    }
}

/// `ritz` (§1.4.2): the same lines in a scene and on the command line (plain and Unicode).
/// By hand, the trial x = t + a t (1 − t) for L = ½ x'² − ½ x² on [0, 1] gives
/// S(a) = 1/3 − a/12 + 3a²/20, stationary at a = 5/18.
#[test]
fn ritz_of_the_oscillator() {
    for format in ["plain", "unicode"] {
        let lines = same(
            &format!("coordinates x\nL = 1/2 x'^2 - 1/2 x^2\nritz with x = t + a t (1 - t) for t in 0..1 from x = 0 to x = 1 solve a as {format}\n"),
            &[
                "ritz", "1/2 x'^2 - 1/2 x^2", "--coords", "x", "--trial", "t + a t (1 - t)", "--unknowns", "a", "--span",
                "0,1", "--from", "0", "--to", "1", "--format", format,
            ],
        );
        let a: f64 = lines.iter().find_map(|l| l.strip_prefix("a ≈ ")).expect("the solution line").parse().unwrap();
        assert!((a - 5.0 / 18.0).abs() < 1e-15, "{lines:#?}");
    }
}

/// `series` of an expression in a small quantity: sin x to order 5 is the Taylor polynomial
/// x − x³/6 + x⁵/120 (by hand), and the scene prints what `lagrangian series` prints.
#[test]
fn series_of_sine_equals_the_command_line() {
    let out = same("series sin(x) in x order 5 as plain", &["series", "sin(x)", "--in", "x", "--order", "5"]);
    let hand = parse_with("x - x^3/6 + x^5/120", &Declarations::new()).expect("parses");
    let got = parse_with(&out[0], &Declarations::new()).expect("re-parses");
    assert_eq!(decide_zero(&got.minus(&hand)), ZeroCheck::Proven, "{out:?}");
}

/// The pendulum about its lower equilibrium, the notes' L_lin of (2.29):
/// ½ m l² θ̇² − ½ m g l θ² (1 − cos θ = θ²/2 + O(θ⁴)); about θ = π the sign of the potential
/// term flips (1 − cos(π + η) = 2 − η²/2 + …), and both print the displacement note.
#[test]
fn series_of_the_pendulum_about_its_equilibria_equals_the_command_line() {
    let l = "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))";
    let out = same(
        &format!("coordinates θ\nparameters m, g, l positive\nL = {l}\nseries L about θ = 0 order 2 as plain"),
        &["series", l, "--coords", "θ", "--order", "2", "--positive", "m,g,l"],
    );
    let d = Declarations::new();
    let hand = parse_with("1/2 m l^2 θ'^2 - 1/2 m g l θ^2", &d).expect("parses");
    assert_eq!(decide_zero(&parse_with(&out[0], &d).expect("re-parses").minus(&hand)), ZeroCheck::Proven, "{out:?}");
    let out = same(
        &format!("coordinates θ\nparameters m, g, l positive\nL = {l}\nseries L about θ = 3.14159 order 2 as plain"),
        &["series", l, "--coords", "θ", "--about", "3.14159", "--order", "2", "--positive", "m,g,l"],
    );
    assert_eq!(out[0], "# each coordinate stands for its displacement from --about");
}

/// The Jacobian of polar coordinates: [[cos φ, −r sin φ], [sin φ, r cos φ]], det = r
/// (cos² + sin² = 1, by hand), the same lines as `lagrangian jacobian`.
#[test]
fn jacobian_of_polar_coordinates_equals_the_command_line() {
    let out =
        same("jacobian (r cos(φ), r sin(φ)) in r, φ as plain", &["jacobian", "r cos(φ), r sin(φ)", "--in", "r,φ"]);
    assert_eq!(out.len(), 3, "{out:?}");
    assert_eq!(out[2], "det = r");
}

/// `map` (explicit and implicit) prints the same lines in a scene and on the command line; the
/// standard map's three steps are the hand iteration (Python floats: 5.375066801394972,
/// 1.1643125003166652) and the implicit midpoint rule's hundred steps the rotation by
/// 100 · 2 atan(h/2).
#[test]
fn map_explicit_and_implicit() {
    let out = same(
        "parameters K = 0.9\nmap p = p + K sin(q), q = q + p for 3 steps from q = 1, p = 0.5",
        &[
            "map",
            "p = p + K sin(q)",
            "q = q + p",
            "--vars",
            "q,p",
            "--from",
            "1,0.5",
            "--steps",
            "3",
            "--params",
            "K=0.9",
        ],
    );
    assert_eq!(out[1], "  (1, 0.5) → (5.375066801394972, 1.1643125003166652)");
    let out = same(
        "parameters h = 0.1\nmap q' = q + h (p + p')/2, p' = p - h (q + q')/2 for 100 steps from q = 1, p = 0",
        &[
            "map",
            "q' = q + h (p + p')/2",
            "p' = p - h (q + q')/2",
            "--vars",
            "q,p",
            "--from",
            "1,0",
            "--steps",
            "100",
            "--params",
            "h=0.1",
        ],
    );
    let last = crate::support::map_last_state(&out[1]);
    let a = 100.0 * 2.0 * 0.05f64.atan();
    assert!((last[0] - a.cos()).abs() < 1e-12 && (last[1] + a.sin()).abs() < 1e-12, "{out:?}");
}

/// The flow's Jacobian: the scene's `flow` and `lagrangian flow` print the same lines through
/// `report::flow`, for a Hamiltonian flow (with its symplectic check) and a damped one (det Φ
/// as a value). Each is also checked: the oscillator's Φ(T) is the rotation by T, and the
/// damped one's det Φ = e^{−γT} (γ = b/m; tr ∂f/∂x = −b/m).
#[test]
fn flow_of_an_oscillator_and_of_a_damped_one() {
    let out = same(
        "coordinates q\nH = p_q^2/2 + q^2/2\nflow q = 0.6, p_q = -0.2 for t in 0..7.3",
        &["flow", "p_q^2/2 + q^2/2", "--coords", "q", "--at", "q=0.6,p_q=-0.2", "--time", "7.3"],
    );
    let row = |line: &str| -> Vec<f64> {
        line.trim()
            .trim_start_matches('[')
            .trim_end_matches(']')
            .split(',')
            .map(|x| x.trim().parse().unwrap())
            .collect()
    };
    let t: f64 = 7.3;
    assert_eq!(row(&out[2]).len(), 2, "{out:?}");
    for (got, want) in row(&out[2]).iter().chain(&row(&out[3])).zip([t.cos(), t.sin(), -t.sin(), t.cos()]) {
        assert!((got - want).abs() < 1e-13, "{out:?}");
    }
    assert!(out[5].starts_with("max |ΦᵀJΦ − J| = "), "{out:?}");

    let out = same(
        "coordinates x\nparameters m = 2, b = 0.6, k = 5\nL = 1/2 m x'^2 - 1/2 k x^2\nrayleigh 1/2 b x'^2\nflow x = 1, p_x = 0 for t in 0..4",
        &[
            "flow",
            "1/2 m x'^2 - 1/2 k x^2",
            "--lagrangian",
            "--coords",
            "x",
            "--at",
            "x=1,p_x=0",
            "--time",
            "4",
            "--set",
            "m=2,b=0.6,k=5",
            "--rayleigh",
            "1/2 b x'^2",
        ],
    );
    let line = &out[4];
    let det: f64 =
        line[line.find("det Φ = ").unwrap() + "det Φ = ".len()..].split(':').next().unwrap().parse().unwrap();
    assert!((det - (-0.3f64 * 4.0).exp()).abs() < 1e-6, "{out:?}");
    assert!(out[5].starts_with("no symplectic defect"), "{out:?}");
}
