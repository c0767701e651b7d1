//! Tests of `src/parse.rs` (formerly its in-crate unit tests).
use lagrangian::parse::*;

use lagrangian::Expr;
fn p(s: &str) -> Expr {
    match parse(s) {
        Ok(e) => e,
        Err(e) => panic!("{s}: {e}"),
    }
}

#[test]
fn precedence_and_juxtaposition() {
    assert_eq!(p("-x^2"), p("-(x^2)"));
    assert_eq!(p("2^3^2"), Expr::int(512));
    assert_eq!(p("1/2 m l^2"), p("(1/2)*m*(l^2)"));
    assert_eq!(p("a/b c"), p("(a/b)*c"));
    assert_eq!(p("m (x+1)"), p("m*(x+1)"));
}

/// Python's `**` is the power operator, as `^` (the grammar lists both; the power rule
/// is tried before `*`, which would otherwise take the first star and fail on the second).
#[test]
fn double_star_is_a_power() {
    assert_eq!(p("x**2"), p("x^2"));
    assert_eq!(p("2*x**3*y"), p("2 x^3 y"));
    assert_eq!(p("2**3**2"), Expr::int(512));
    assert_eq!(p("-x**2"), p("-(x^2)"));
}

#[test]
fn decimals_are_exact() {
    assert_eq!(p("0.5"), Expr::frac(1, 2));
    assert_eq!(p("1e-3"), Expr::frac(1, 1000));
    assert_eq!(p("2.5E2"), Expr::int(250));
}

#[test]
fn chains_build_the_same_node_as_a_left_fold() {
    // Sums: one n-ary construction equals the pairwise fold it replaces.
    let terms: Vec<Expr> = (0..300).map(|i| p(&format!("{} x{} y^{}", i % 7 - 3, i % 50, i % 3))).collect();
    let folded = terms.iter().skip(1).fold(terms[0].clone(), |acc, t| acc.plus(t));
    let text: Vec<String> = (0..300).map(|i| format!("({} x{} y^{})", i % 7 - 3, i % 50, i % 3)).collect();
    assert_eq!(p(&text.join(" + ")), folded);
    assert_eq!(p("a - b + c - (a - b)"), p("c"));
    // Products: a coefficient meeting a lone sum distributes mid-chain, exactly as the fold
    // did, so `2 (a + b) c` is `(2a + 2b) c`, not `2 c (a + b)`.
    let (a, b, c) = (Expr::var("a"), Expr::var("b"), Expr::var("c"));
    let fold = Expr::int(2).times(&a.plus(&b)).times(&c);
    assert_eq!(p("2 (a + b) c"), fold);
    assert_eq!(p("-2 (a + b) / c x"), fold.over(&c).over(&c).times(&Expr::var("x")).neg());
    assert_eq!(p("x y z / x / y"), Expr::var("z"));
}

#[test]
fn calls_need_declarations() {
    let err = parse("m(x+1)").unwrap_err();
    assert!(err.message.contains("unknown function `m`"), "{err}");
    assert!(err.hint.as_deref().is_some_and(|h| h.contains("m (…)")));
    let d = Declarations::new().with_functions(["V"]);
    assert!(parse_with("V(r) + V'(r)", &d).is_ok());
}
