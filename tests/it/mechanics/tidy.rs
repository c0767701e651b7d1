//! Tests of `src/mechanics/tidy.rs` (formerly its in-crate unit tests).
use lagrangian::mechanics::tidy::*;
use lagrangian::parse::parse;

use lagrangian::{Expr, Symbol};
fn p(s: &str) -> Expr {
    parse(s).unwrap()
}

#[test]
fn contracts_angle_addition_and_pythagoras() {
    assert_eq!(tidy(&p("cos(a) cos(b) + sin(a) sin(b)")), p("cos(a - b)"));
    assert_eq!(tidy(&p("m cos(a)^2 + m sin(a)^2")), p("m"));
    assert_eq!(tidy(&p("k - k cos(a)^2")), p("k sin(a)^2"));
    assert_eq!(tidy(&p("sin(a) cos(b) - cos(a) sin(b)")), p("sin(a - b)"));
}

#[test]
fn pulls_content_and_merges_equal_cofactors() {
    let e = p("m1 l^2 c + m2 l^2 c + m1 l^2 s + m2 l^2 s");
    assert_eq!(tidy(&e), p("l^2 (c + s) (m1 + m2)"));
}

#[test]
fn signed_symbol_sums_are_already_tidy() {
    for s in ["a - b", "a + b", "b - a + c", "θ1 + θ2 - θ3"] {
        let e = p(s);
        assert!(is_signed_symbol_sum(&e), "{s}");
        assert_eq!(tidy(&e), e, "{s}");
    }
    for s in ["-a - b", "2 a - b", "a b + c", "a"] {
        assert!(!is_signed_symbol_sum(&p(s)), "{s}");
    }
}

/// Which Lagrangians take the quadratic (Christoffel) route of `mass_matrix_split`.
#[test]
fn quadratic_split_accepts_exactly_the_quadratic_lagrangians() {
    let v = |names: &[&str]| names.iter().map(|n| Symbol::new(n).with_primes(1)).collect::<Vec<_>>();
    let split = |l: &str, vs: &[&str]| {
        let mut ctx = Ctx::new();
        let lp = ctx.poly(&p(l));
        ctx.quadratic_split(&lp, &v(vs)).map(|q| {
            let w = q.w.iter().flatten().filter(|x| !x.is_zero()).count();
            let b = q.b.iter().filter(|x| !x.is_zero()).count();
            (w, b, !q.l0.is_zero())
        })
    };
    // ½ m (x'² + y'²) + e B x y' − V: W diagonal (2 entries), one linear term, L0.
    assert_eq!(split("1/2 m (x'^2 + y'^2) + e B x y' - k x^2", &["x", "y"]), Some((2, 1, true)));
    // A cross term x' y' fills the upper triangle only.
    assert_eq!(split("x'^2 + x' y' cos(x - y)", &["x", "y"]), Some((2, 0, false)));
    for l in ["-m sqrt(1 - x'^2)", "x'^3", "1/x'", "exp(x') + y'", "x'' x", "x'^2 y'"] {
        assert_eq!(split(l, &["x", "y"]), None, "{l}");
    }
}

#[test]
fn never_lengthens() {
    let e = p("m (a - u t)^2 φ'");
    assert_eq!(tidy(&e), e);
}
