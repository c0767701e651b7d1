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
