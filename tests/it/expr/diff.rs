//! Tests of `src/diff.rs` (formerly its in-crate unit tests).
use lagrangian::diff::*;

use lagrangian::{Expr, Symbol};
/// A long-lived differentiator (a REPL session's) keeps at most `MAX_MEMO` entries between
/// derivatives, and still gives the same derivatives.
#[test]
fn the_memo_starts_afresh_past_its_bound_between_derivatives() {
    let x = Symbol::new("x");
    let mut d = Differentiator::new();
    for i in 0..(MAX_MEMO / 2 + 10) as i64 {
        // Three nodes each (the sum, its product, the power): past the bound by the end.
        let e = Expr::add([Expr::mul([Expr::int(i), Expr::pow(Expr::var("x"), Expr::int(i + 2))]), Expr::var("y")]);
        let want = Expr::mul([Expr::int(i * (i + 2)), Expr::pow(Expr::var("x"), Expr::int(i + 1))]);
        assert_eq!(d.diff(&e, &x), want);
        assert!(d.memo_and_depth().0 <= MAX_MEMO + 8, "{} entries", d.memo_and_depth().0);
    }
    assert_eq!(d.memo_and_depth().1, 0);
}
