//! `series` (§2.4.1): an expression to a given order in named small
//! quantities, and a Lagrangian about an equilibrium (L_lin of the notes (2.29)).
//! Expected series by hand and by SymPy (`series(sqrt(1 + x) exp(y))`, the coefficients of
//! the Taylor polynomial of total degree ≤ 2).

use lagrangian::mechanics::{series, series_about, SeriesError};
use lagrangian::{parse, Expr, Symbol};

use crate::support::notes::run;

fn p(s: &str) -> Expr {
    parse(s).expect("test input parses")
}

#[test]
fn small_angle_pendulum_lagrangian_is_l_lin_of_2_29() {
    // L = ½ m l² θ'² − m g l (1 − cos θ) to second order in (θ, θ'): ½ m l² θ'² − ½ m g l θ².
    let (code, out, err) = run(&["series", "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", "--coords", "θ", "--order", "2"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "l^2 m θ'^2/2 - g l m θ^2/2");
    // Fourth order adds + m g l θ⁴/24 (1 − cos θ = θ²/2 − θ⁴/24 + …).
    let th = Symbol::new("θ");
    let (l4, terms) =
        series_about(&p("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))"), &[th], &[Expr::zero()], 4).expect("analytic");
    assert_eq!(terms.len(), 5);
    assert!(terms[1].is_zero() && terms[3].is_zero(), "{terms:?}");
    let hand = p("1/2 m l^2 θ'^2 - 1/2 m g l θ^2 + m g l θ^4/24");
    assert!(lagrangian::canonical::normalize(&l4.minus(&hand)).is_zero(), "{l4}");
}

#[test]
fn series_about_a_shifted_equilibrium() {
    // A spring of rest length a in polar coordinates, about r = a: r → a + r gives
    // ½ m r'² + ½ m a² φ'² − ½ k r² to second order (the m a r φ'² term is of order 3).
    let (r, phi) = (Symbol::new("r"), Symbol::new("φ"));
    let (s, _) = series_about(&p("1/2 m (r'^2 + r^2 φ'^2) - k (r - a)^2/2"), &[r, phi], &[p("a"), Expr::zero()], 2)
        .expect("analytic");
    let hand = p("1/2 m r'^2 + 1/2 m a^2 φ'^2 - 1/2 k r^2");
    assert!(lagrangian::canonical::normalize(&s.minus(&hand)).is_zero(), "{s}");
}

#[test]
fn series_in_two_small_quantities_and_refusals() {
    let (x, y) = (Symbol::new("x"), Symbol::new("y"));
    let s = series(&p("sqrt(1 + x) exp(y)"), &[x.clone(), y.clone()], 2).expect("analytic");
    let sympy = p("1 + x/2 + y - x^2/8 + x y/2 + y^2/2");
    assert!(lagrangian::canonical::normalize(&s.minus(&sympy)).is_zero(), "{s}");
    // No power series: a pole, a root, an absolute value at 0.
    for bad in ["1/x", "sqrt(x) + y", "sqrt(x^2)"] {
        let r = series(&p(bad), &[x.clone(), y.clone()], 2);
        assert!(matches!(r, Err(SeriesError::NotAnalytic { .. })), "{bad}: {r:?}");
    }
    let (code, out, err) = run(&["series", "1/x", "--in", "x"]);
    assert_eq!((code, out.as_str()), (2, ""));
    assert!(err.contains("has no power series in x"), "{err}");
    let (code, _, err) = run(&["series", "x^2", "--in", "x", "--order", "99"]);
    assert_eq!(code, 2);
    assert!(err.contains("above the limit"), "{err}");
}

#[test]
fn substitution_is_simultaneous_when_a_parent_collapses_to_the_symbol() {
    // (r − a)² under r → a + r is r²: the rebuilt r − a is the symbol r, which must not be
    // substituted again (it was, giving (r + a)²).
    let mut map = std::collections::HashMap::new();
    map.insert(Symbol::new("r"), p("a + r"));
    assert_eq!(p("(r - a)^2").subs(&map), p("r^2"));
    assert_eq!(p("k (r - a)^2/2 + r").subs(&map), p("k r^2/2 + a + r"));
}
