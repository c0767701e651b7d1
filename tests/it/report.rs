//! Tests of `src/report.rs` (formerly its in-crate unit tests).
use lagrangian::canonical::{decide_zero, ZeroCheck};
use lagrangian::parse::{parse_with, Declarations};
use lagrangian::report::*;

use lagrangian::mechanics::{MechanicsError, System};
use lagrangian::{Expr, Format};
fn decls() -> Declarations {
    Declarations::new().with_positive(["m", "g", "l", "k", "b", "R"])
}

fn same(e: &Expr, hand: &str) {
    let d = e.minus(&parse_with(hand, &decls()).unwrap());
    assert_eq!(decide_zero(&d), ZeroCheck::Proven, "{e} vs {hand}");
}

fn lagrangian(l: &str, coords: &[&str]) -> System {
    System::from_lagrangian_with(l, coords, &decls()).unwrap()
}

#[test]
fn a_line_renders_in_every_format_and_as_json() {
    let s = lagrangian("1/2 m l^2 θ'^2 + m g l cos(θ)", &["θ"]);
    let lines = euler_lagrange(&s).unwrap();
    assert_eq!(lines.len(), 1);
    let plain_text = render_line(&lines[0], Format::Plain);
    assert!(plain_text.starts_with("E_θ: ") && plain_text.ends_with(" = 0"), "{plain_text}");
    let unicode = render_line(&lines[0], Format::Unicode);
    assert!(unicode.contains("θ̈"), "{unicode}");
    let latex = render_line(&lines[0], Format::Latex);
    assert!(latex.starts_with("E_{\\theta}: ") && latex.contains("\\ddot{\\theta}"), "{latex}");
    let w = mass_matrix_split(&lagrangian("1/2 m (θ1'^2 + x'^2)", &["θ1", "x"])).unwrap();
    assert_eq!(render_line(&w[1], Format::Latex), "W[\\theta_{1},x] = 0");
    assert_eq!(render_line(&w[1], Format::Unicode), "W[θ1,x] = 0");
    // JSON carries the plain forms, which re-parse to the same expressions.
    let j = line_json(&lines[0]);
    assert_eq!(j["label"], "E_θ");
    let lhs = parse_with(j["lhs"].as_str().unwrap(), &decls()).unwrap();
    same(&lhs, "m l^2 θ'' + m g l sin(θ)");
    assert_eq!(j["rhs"], "0");
    // A line of text is printed as it is, in every format.
    let t = Line::text("note: W is singular");
    for f in [Format::Plain, Format::Unicode, Format::Latex] {
        assert_eq!(render_line(&t, f), "note: W is singular");
    }
    assert_eq!(line_json(&t)["text"], "note: W is singular");
}

/// A Hamiltonian with a velocity-dependent force: the force enters `p'` with `x'`
/// written as `∂H/∂p = p_x/m`, so `p_x' = −k x − b p_x/m`.
#[test]
fn hamilton_adds_the_force_in_canonical_variables() {
    let s = System::from_hamiltonian_with("p_x^2/(2 m) + k x^2/2", &["x"], &decls())
        .unwrap()
        .with_force("x", "-b x'")
        .unwrap();
    let lines = hamilton(&s).unwrap();
    same(lines[0].rhs().unwrap(), "p_x/m");
    same(lines[1].rhs().unwrap(), "-k x - b p_x/m");
}

/// Two copies of one constraint leave the multipliers undetermined: a typed error, not
/// a division by zero.
#[test]
fn redundant_constraints_are_refused() {
    let s = lagrangian("1/2 m y'^2 + 1/4 m R^2 θ'^2 + m g y", &["y", "θ"])
        .with_constraint("y - R θ")
        .unwrap()
        .with_constraint("2 y - 2 R θ")
        .unwrap();
    assert!(matches!(accelerations(&s), Err(MechanicsError::SingularConstraints { .. })), "{:?}", accelerations(&s));
}
