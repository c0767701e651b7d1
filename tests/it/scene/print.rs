//! `print` of an expression: identically zero prints `0`, inverse-function compositions are
//! reduced.

use lagrangian::scene::{Mode, Options, Session};

fn printed(scene: &str) -> Vec<String> {
    let mut s = Session::new(Options::new(Mode::Scene));
    s.run_scene("test", scene).unwrap_or_else(|e| panic!("{e:?}"));
    s.take_output()
}

/// The Jacobi identity for the components of angular momentum, written as a sum of three
/// nested brackets: one line, `0`.
#[test]
fn an_identically_zero_sum_prints_0() {
    let out = printed(
        "coordinates x, y, z
Lx = y p_z - z p_y
Ly = z p_x - x p_z
Lz = x p_y - y p_x
J1 = pb(Ly, Lz)
J2 = pb(Lz, Lx)
J3 = pb(Lx, Ly)
A = pb(Lx, J1)
B = pb(Ly, J2)
C = pb(Lz, J3)
print A + B + C as plain",
    );
    assert_eq!(out, ["0"]);
}

#[test]
fn inverse_function_compositions_reduce() {
    let out = printed(
        "coordinates q
parameters a positive
print exp(log(a q^2 + a)), sin(asin(q)), sinh(log(q + sqrt(q^2 + 1)))^2 as plain",
    );
    assert_eq!(out.len(), 3);
    let d = lagrangian::Declarations::new().with_positive(["a"]);
    assert_eq!(lagrangian::parse_with(&out[0], &d).unwrap(), lagrangian::parse_with("a q^2 + a", &d).unwrap());
    assert!(!out[0].contains("exp") && !out[0].contains("log"), "{}", out[0]);
    assert_eq!(out[1], "q");
    // sinh(asinh q)² written with the logarithmic form of asinh (the case).
    assert_eq!(out[2], "q^2");
}

/// `print` simplifies the way the command line's `simplify` does: sin² + cos² is 1 (and with
/// the 1 subtracted, 0), not the unsimplified sum.
#[test]
fn print_uses_the_command_lines_simplification() {
    let out = printed("coordinates x\nprint sin(x)^2 + cos(x)^2 as plain\nprint sin(x)^2 + cos(x)^2 - 1 as plain");
    assert_eq!(out, ["1", "0"]);
}

/// `pb` is a function inside expressions, nested and combined: {x, p_x} = 1, so {{x, p_x}, H}
/// = 0; {x, H} = ∂H/∂p_x = p_x; {x p_y − y p_x, p_x} = ∂L_z/∂x = p_y (by hand); the Jacobi
/// identity written inline prints 0.
#[test]
fn pb_nests_inside_scene_expressions() {
    let out = printed(
        "coordinates x, y
H = (p_x^2 + p_y^2)/2 + x^4
print pb(pb(x, p_x), H) as plain
print pb(x, H) + 1 as plain
Lz = x p_y - y p_x
print 2 pb(Lz, p_x) as plain
print pb(x, pb(y, H)) + pb(y, pb(H, x)) + pb(H, pb(x, y)) as plain",
    );
    assert_eq!(out, ["pb = 0", "p_x + 1", "2 p_y", "0"]);
}

/// A derivation that gives equations, not an expression, is refused inside an expression.
#[test]
fn a_list_of_equations_inside_an_expression_is_refused() {
    let mut s = Session::new(Options::new(Mode::Scene));
    let e = s.run_scene("test", "coordinates x\nL = x'^2/2 - x^2/2\nprint el(L) + 1").expect_err("refused");
    assert!(e.message.contains("list of equations"), "{}", e.message);
    assert!(e.span.is_some());
}
