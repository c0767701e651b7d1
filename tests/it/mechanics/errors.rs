//! Bad input to the mechanics module: each is a typed error with the offending name in it,
//! never a panic; the CLI turns them into exit code 2 with the message on stderr.

use std::process::Command;

use lagrangian::mechanics::{MechanicsError, System};
use lagrangian::Declarations;

fn lag(text: &str, coords: &[&str]) -> Result<System, MechanicsError> {
    System::from_lagrangian(text, coords)
}

#[test]
fn singular_hessian_names_the_velocity() {
    // Remark 3.1: L linear in y' (no inertia in y).
    let s = lag("1/2 m x'^2 + b y' - V0 y", &["x", "y"]).unwrap();
    let e = s.hamiltonian().unwrap_err();
    assert_eq!(e, MechanicsError::SingularHessian { function: "L", var: "y'".into() });
    assert!(e.to_string().contains("y'"));
    assert_eq!(s.accelerations().unwrap_err(), e);
    assert_eq!(s.check_regular().unwrap_err(), e);
}

#[test]
fn singular_hessian_names_the_null_direction() {
    // W = [[1, 1], [1, 1]]: singular along x' − y'.
    let s = lag("1/2 (x' + y')^2 - x^2 - y^2", &["x", "y"]).unwrap();
    match s.hamiltonian().unwrap_err() {
        MechanicsError::SingularHessianDirection { direction, .. } => {
            assert!(direction.contains("(1, -1)") || direction.contains("(-1, 1)"), "{direction}");
            assert!(direction.contains("x'") && direction.contains("y'"));
        }
        other => panic!("wrong error {other}"),
    }
    // The same with a declared function, where only the symbolic determinant can tell.
    let d = Declarations::new().with_functions(["f"]);
    let s = System::from_lagrangian_with("1/2 f(x) (x' + y')^2", &["x", "y"], &d).unwrap();
    assert!(matches!(s.legendre().unwrap_err(), MechanicsError::SingularHessianDirection { .. }));
    // Homogeneous of degree one (the length functional (1.19)): singular along q' itself.
    let s = lag("sqrt(x'^2 + y'^2)", &["x", "y"]).unwrap();
    assert!(matches!(s.hamiltonian().unwrap_err(), MechanicsError::SingularHessianDirection { .. }));
}

#[test]
fn coordinate_that_does_not_appear() {
    let e = lag("1/2 m x'^2", &["x", "y"]).unwrap_err();
    assert!(matches!(&e, MechanicsError::CoordinateAbsent { coordinate, .. } if coordinate == "y"));
    assert!(e.to_string().contains("`y`"));
    assert!(matches!(
        System::from_hamiltonian("p_x^2/2", &["x", "y"]).unwrap_err(),
        MechanicsError::CoordinateAbsent { .. }
    ));
}

#[test]
fn coordinate_declared_twice() {
    assert_eq!(lag("x'^2", &["x", "x"]).unwrap_err(), MechanicsError::DuplicateCoordinate("x".into()));
    assert_eq!(lag("x'^2", &[]).unwrap_err(), MechanicsError::NoCoordinates);
    assert!(matches!(lag("x'^2 t", &["t"]).unwrap_err(), MechanicsError::BadCoordinate(_)));
    assert!(matches!(lag("x'^2", &["x'"]).unwrap_err(), MechanicsError::BadCoordinate(_)));
}

#[test]
fn constraint_that_is_not_holonomic() {
    let s = lag("1/2 m (x'^2 + y'^2)", &["x", "y"]).unwrap();
    let e = s.clone().with_constraint("x' - y").unwrap_err();
    assert!(matches!(&e, MechanicsError::NotHolonomic { why, .. } if why.contains("x'")));
    assert!(matches!(s.clone().with_constraint("a - b").unwrap_err(), MechanicsError::NotHolonomic { .. }));
    assert!(matches!(s.with_constraint("x +").unwrap_err(), MechanicsError::Parse(_)));
}

#[test]
fn higher_derivatives_in_the_lagrangian() {
    let e = lag("x'''^2 + x'^2", &["x"]).unwrap_err();
    assert_eq!(e, MechanicsError::HigherDerivative { symbol: "x'''".into(), order: 3, what: "Lagrangian" });
    assert!(matches!(lag("x'' x", &["x"]).unwrap_err(), MechanicsError::HigherDerivative { order: 2, .. }));
    assert!(matches!(lag("x'^2 + y'^2", &["x"]).unwrap_err(), MechanicsError::VelocityOfNonCoordinate { .. }));
    assert!(matches!(
        System::from_hamiltonian("p_x^2 + x'", &["x"]).unwrap_err(),
        MechanicsError::VelocityInHamiltonian(_)
    ));
}

#[test]
fn no_closed_form_legendre() {
    let s = lag("x'^4/4 - x^2", &["x"]).unwrap();
    assert!(matches!(s.hamiltonian().unwrap_err(), MechanicsError::NoClosedFormLegendre(_)));
    let h = System::from_hamiltonian("p_x^4 + x^2", &["x"]).unwrap();
    assert!(matches!(h.inverse_legendre().unwrap_err(), MechanicsError::NoClosedFormLegendre(_)));
}

#[test]
fn other_refusals() {
    assert!(matches!(lag("1/2 m x'^2 +", &["x"]).unwrap_err(), MechanicsError::Parse(_)));
    assert!(matches!(lag("V(x) + x'^2", &["x"]).unwrap_err(), MechanicsError::Parse(_)));
    let s = lag("1/2 m x'^2 - k x^2", &["x"]).unwrap();
    assert_eq!(s.clone().with_params(&[("q", 1.0)]).unwrap_err(), MechanicsError::UnknownParameter("q".into()));
    assert!(matches!(s.clone().with_params(&[("m", f64::NAN)]).unwrap_err(), MechanicsError::BadParameterValue { .. }));
    assert_eq!(s.clone().with_force("y", "1").unwrap_err(), MechanicsError::ForceOnNonCoordinate("y".into()));
    assert!(matches!(s.transform(&[("z", "r")], &["r"]).unwrap_err(), MechanicsError::BadTransform(_)));
    assert!(matches!(s.with_gauge("x'").unwrap_err(), MechanicsError::BadTransform(_)));
    assert!(matches!(lag("x'^2 + p_x", &["x"]).unwrap_err(), MechanicsError::MomentumNameClash(_)));
    let h = System::from_hamiltonian("p_x^2/2", &["x"]).unwrap();
    assert!(matches!(h.euler_lagrange().unwrap_err(), MechanicsError::WrongKind(_)));
    // Parameters with values and builder chains keep working.
    let s = s.with_params(&[("m", 2.0), ("k", 3.0)]).unwrap();
    assert_eq!(s.param_values().len(), 2);
    let s = s.with_positive(&["m"]);
    assert!(s.parameters().iter().any(|p| p.name() == "m" && p.is_positive()));
    // Functions declared after the fact re-parse the source: `V (x)` was a product, and with
    // `V` a function it is an error that says how to call it.
    let e = System::from_lagrangian("x'^2 - V (x)", &["x"]).unwrap().with_functions(&["V"]).unwrap_err();
    assert!(matches!(&e, MechanicsError::Parse(p) if p.hint.is_some()), "{e}");
}

fn cli(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian")).args(args).output().expect("runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn cli_reports_bad_input_with_exit_code_2() {
    for args in [
        // A singular W prints E_i and a note; only the accelerations are refused.
        &["el", "1/2 (x' + y')^2", "--coords", "x,y", "--accelerations"][..],
        &["el", "x'''^2", "--coords", "x"],
        &["el", "x'^2", "--coords", "x,x"],
        &["el", "x'^2", "--coords", "x,y"],
        &["el", "x'^2", "--coords", "x", "--constraint", "x' - 1"],
        &["legendre", "x'^4", "--coords", "x"],
        &["hamilton", "p_x^2 +", "--coords", "x"],
        &["transform", "x'^2", "--coords", "x"],
    ] {
        let (code, stdout, stderr) = cli(args);
        assert_eq!(code, 2, "{args:?}: {stdout} {stderr}");
        assert!(stderr.starts_with("error"), "{args:?}: {stderr}");
    }
}

#[test]
fn cli_prints_the_issue_examples() {
    // The worked commands, checked against the hand forms (2.28), (3.29), (3.16), (2.39).
    let (code, out, _) = cli(&["el", "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", "--coords", "θ", "--positive", "m,l,g"]);
    assert_eq!(code, 0);
    assert!(out.contains("E_θ: l m (g sin(θ) + l θ'') = 0"), "{out}");
    let (_, out, _) = cli(&["legendre", "1/2 m (r'^2 + r^2 φ'^2) - V(r)", "--coords", "r,φ", "--functions", "V"]);
    assert!(out.contains("H = p_r^2/(2 m) + p_φ^2/(2 m r^2) + V(r)"), "{out}");
    let (_, out, _) = cli(&["hamilton", "p_x^2/(2 m) + 1/2 m ω^2 x^2", "--coords", "x"]);
    assert!(out.contains("x' = p_x/m") && out.contains("p_x' = -m x ω^2"), "{out}");
    let (_, out, _) = cli(&["conserved", "1/2 m (u^2 + (a - u t)^2 φ'^2)", "--coords", "φ"]);
    assert!(out.contains("p_φ = m φ' (a - t u)^2"), "{out}");
    assert!(!out.contains("h ="), "energy is not conserved: {out}");
    // JSON carries the plain forms.
    let (_, out, _) = cli(&["el", "1/2 m x'^2 - 1/2 k x^2", "--coords", "x", "--format", "json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["coordinates"][0], "x");
    assert_eq!(v["equations"][0]["coordinate"], "x");
    assert_eq!(v["equations"][0]["expr"], "k x + m x''");
    assert_eq!(v["mass_matrix"][0][0], "m");
    // Transform to polar coordinates.
    let (_, out, _) = cli(&[
        "transform",
        "1/2 m (x'^2 + y'^2)",
        "--coords",
        "x,y",
        "--map",
        "x=r cos(φ)",
        "--map",
        "y=r sin(φ)",
        "--to",
        "r,φ",
    ]);
    assert!(out.contains("L = m (r'^2 + r^2 φ'^2)/2"), "{out}");
}

/// Five coupled velocities: the closed-form inverse of W (adjugate over determinant) is refused
/// with `TooLarge` beyond four, for the accelerations and for the Legendre transform alike,
/// while four still work and the compiled route (numeric solve) handles five.
#[test]
fn closed_form_inverse_beyond_four_coupled_velocities_is_too_large() {
    let coupled = |n: usize| {
        let qs: Vec<String> = (1..=n).map(|i| format!("q{i}")).collect();
        let sum: Vec<String> = qs.iter().map(|q| format!("{q}'")).collect();
        let squares: Vec<String> = qs.iter().map(|q| format!("{q}'^2 - {q}^2")).collect();
        // W = I + 1 1ᵀ: positive definite, every entry non-zero.
        let l = format!("1/2 ({})^2 + 1/2 ({})", sum.join(" + "), squares.join(" + "));
        let coords: Vec<&str> = qs.iter().map(String::as_str).collect();
        lag(&l, &coords).unwrap()
    };
    let five = coupled(5);
    let expected = MechanicsError::TooLarge { n: 5, limit: 4 };
    assert_eq!(five.accelerations().unwrap_err(), expected);
    assert_eq!(five.hamiltonian().unwrap_err(), expected);
    // The message says what does work: the unsolved split and a numeric simulation.
    let text = expected.to_string();
    assert!(
        text.contains("more than 4 coupled") && text.contains("without `--accelerations`") && text.contains("simulate"),
        "{text}"
    );
    assert!(coupled(4).accelerations().is_ok());
    assert!(coupled(4).hamiltonian().is_ok());
    assert!(five.compile_rhs().is_ok(), "the numeric solve of W q'' = F needs no closed-form inverse");
}

/// Beyond four coordinates, a matrix that decouples into blocks is inverted block by block:
/// accelerations of two uncoupled chains (checked by multiplying back, W q'' − F = 0, a route
/// that forms no inverse) and the geodesics of the unit 5-sphere, whose scalar curvature is
/// n(n − 1) = 20 (the round sphere's closed form).
#[test]
fn block_diagonal_inverses_reach_any_dimension() {
    let l = "1/2 (a'^2 + b'^2 + c'^2 + a' b' + c' d' + d'^2 + e'^2 + d' e') - a b c d e";
    let s = lag(l, &["a", "b", "c", "d", "e"]).unwrap();
    let acc = s.accelerations().expect("blocks {a, b} and {c, d, e}");
    let (w, f) = s.mass_matrix_split().unwrap();
    for i in 0..5 {
        let back = lagrangian::Expr::add((0..5).map(|j| w[i][j].times(&acc[j]))).minus(&f[i]);
        assert!(lagrangian::mechanics::tidy(&back).is_zero(), "row {i}: {back}");
    }
    let decls = Declarations::default();
    let sphere =
        lagrangian::parse_with("da^2 + sin(a)^2 (db^2 + sin(b)^2 (dc^2 + sin(c)^2 (dd^2 + sin(d)^2 de^2)))", &decls)
            .unwrap();
    let coords: Vec<lagrangian::Symbol> =
        ["a", "b", "c", "d", "e"].iter().map(|q| lagrangian::Symbol::new(q)).collect();
    let g = lagrangian::mechanics::geodesic(&sphere, &coords).expect("a diagonal metric in five dimensions");
    assert_eq!(g.curvature().scalar, lagrangian::Expr::int(20));
    // One block of five is still refused, naming what works.
    let coupled = lagrangian::parse_with("(da+db+dc+dd+de)^2 + da^2+db^2+dc^2+dd^2+de^2", &decls).unwrap();
    assert_eq!(
        lagrangian::mechanics::geodesic(&coupled, &coords).unwrap_err(),
        MechanicsError::TooLarge { n: 5, limit: 4 }
    );
}
