//! Tests of `src/canonical/reduce.rs` (formerly its in-crate unit tests).
use lagrangian::canonical::reduce::*;
use lagrangian::parse::parse;

#[test]
fn hyperbolic_functions_of_the_log_forms_of_their_inverses() {
    // sinh(asinh q) with asinh q = log(q + sqrt(q² + 1)), and cosh(acosh q) likewise.
    let e = parse("sinh(log(q + sqrt(q^2 + 1)))^2").expect("parses");
    assert_eq!(tidy(&e), parse("q^2").expect("parses"));
    let e = parse("cosh(log(q + sqrt(q^2 - 1)))").expect("parses");
    assert_eq!(tidy(&e), parse("q").expect("parses"));
    // Any other logarithm is left alone.
    let e = parse("sinh(log(u))").expect("parses");
    assert_eq!(tidy(&e), e);
}

#[test]
fn radical_reduction_sees_sum_of_squares() {
    let e = parse("x^2/(x^2 + y^2)^(3/2) + y^2/(x^2 + y^2)^(3/2) - 1/sqrt(x^2 + y^2)").expect("parses");
    assert!(reduce_radicals(&e).is_zero(), "{}", reduce_radicals(&e));
}
