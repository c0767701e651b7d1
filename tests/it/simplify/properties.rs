//! Properties over random expressions: the algebra tools and the simplifier preserve values,
//! derivatives agree with central finite differences, plain printing re-parses to the
//! identical DAG, canonical construction does not depend on the order of operands, and the
//! native Taylor coefficients (unrolled and compact) are the interpreter's bit for bit.

use std::collections::HashMap;

use lagrangian::algebra::{
    cancel, collect_common, expand_with_limit, factor_content, numer_denom, together, trig_normalize,
};
use lagrangian::compile::{Tape, TaylorTape};
use lagrangian::diff::diff;
use lagrangian::eval::eval_with;
use lagrangian::parse::parse;
use lagrangian::simplify::simplify;
use lagrangian::{Expr, Func, Symbol};
use proptest::prelude::*;

const NAMES: [&str; 3] = ["x", "y", "z"];

/// Random expressions over `x, y, z`: small rationals, rational multiples of π, sums, products, small integer powers,
/// and the functions that are defined everywhere on the sample box (or made so: `log` and
/// `sqrt` get `1 + u²`).
fn arb_expr() -> impl Strategy<Value = Expr> {
    let leaf = prop_oneof![
        (-4i64..5, 1i64..4).prop_map(|(n, d)| Expr::frac(n, d)),
        (0usize..3).prop_map(|i| Expr::var(NAMES[i])),
        (0usize..3).prop_map(|i| Expr::var(NAMES[i])),
        // Rational multiples of the exact π, which trigonometric calls fold or shift.
        (-4i64..5, 1i64..4).prop_map(|(n, d)| Expr::frac(n, d).times(&Expr::pi())),
    ];
    leaf.prop_recursive(4, 24, 3, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 2..4).prop_map(Expr::add),
            prop::collection::vec(inner.clone(), 2..3).prop_map(Expr::mul),
            (inner.clone(), -2i64..4).prop_map(|(b, k)| {
                // Keep negative powers away from zero: (1 + b²)^k.
                if k < 0 {
                    Expr::one().plus(&b.powi(2)).powi(k)
                } else {
                    b.powi(k)
                }
            }),
            (inner.clone(), 0usize..9).prop_map(|(a, f)| match f {
                0 => Expr::call(Func::Sin, vec![a]),
                1 => Expr::call(Func::Cos, vec![a]),
                2 => Expr::call(Func::Sin, vec![a]).powi(2),
                3 => Expr::call(Func::Cos, vec![a]).powi(2),
                4 => Expr::call(Func::Log, vec![Expr::one().plus(&a.powi(2))]),
                5 => Expr::one().plus(&a.powi(2)).sqrt(),
                6 => Expr::call(Func::Exp, vec![Expr::call(Func::Sin, vec![a])]),
                7 => Expr::call(Func::Atan, vec![a]),
                _ => Expr::call(Func::Tanh, vec![a]),
            }),
        ]
    })
}

/// Sample points in the box (−1.7, 1.7)³, from the test's own seed.
fn points(seed: u64) -> Vec<HashMap<String, f64>> {
    let mut s = seed | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        -1.7 + 3.4 * ((s >> 11) as f64 / (1u64 << 53) as f64)
    };
    (0..4).map(|_| NAMES.iter().map(|n| (n.to_string(), next())).collect()).collect()
}

fn value(e: &Expr, at: &HashMap<String, f64>) -> Option<f64> {
    let v = eval_with(e, &|s: &Symbol| at.get(&s.to_string()).copied()).ok()?;
    (v.is_finite() && v.abs() < 1e8).then_some(v)
}

/// `a` and `b` agree at every sample point where `a` has a moderate finite value.
fn agree(a: &Expr, b: &Expr, seed: u64) -> Result<(), TestCaseError> {
    for at in points(seed) {
        let Some(va) = value(a, &at) else { continue };
        let vb = eval_with(b, &|s: &Symbol| at.get(&s.to_string()).copied())
            .map_err(|e| TestCaseError::fail(format!("{b} does not evaluate: {e}")))?;
        let tol = 1e-7 * (1.0 + va.abs());
        prop_assert!((va - vb).abs() <= tol, "{a} = {va} but {b} = {vb} at {at:?}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn expand_preserves_values(e in arb_expr(), seed in any::<u64>()) {
        if let Ok(x) = expand_with_limit(&e, 2_000) {
            agree(&e, &x, seed)?;
        }
    }

    #[test]
    fn together_numer_denom_and_cancel_preserve_values(e in arb_expr(), seed in any::<u64>()) {
        agree(&e, &together(&e), seed)?;
        let (n, d) = numer_denom(&e);
        agree(&e, &n.over(&d), seed)?;
        agree(&e, &cancel(&e), seed)?;
    }

    #[test]
    fn factor_content_and_trig_normalize_preserve_values(e in arb_expr(), seed in any::<u64>()) {
        agree(&e, &factor_content(&e), seed)?;
        agree(&e, &trig_normalize(&e), seed)?;
        agree(&e, &collect_common(&e), seed)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The simplifier preserves the value wherever the input is defined (at points with both
    /// signs, so a rule that needs positivity and fires without it is caught).
    #[test]
    fn simplify_preserves_values(e in arb_expr(), seed in any::<u64>()) {
        agree(&e, &simplify(&e), seed)?;
    }

    /// ∂e/∂x agrees with the central difference (e(x+h) − e(x−h))/(2h), h = 1e-5, whose error
    /// is O(h²) plus rounding O(ε/h).
    #[test]
    fn derivative_matches_central_difference(e in arb_expr(), seed in any::<u64>()) {
        let x = Symbol::new("x");
        let d = diff(&e, &x);
        let h = 1e-5;
        for at in points(seed) {
            let shifted = |dx: f64| {
                let mut p = at.clone();
                *p.entry("x".to_string()).or_insert(0.0) += dx;
                value(&e, &p)
            };
            let (Some(up), Some(down), Some(exact)) = (shifted(h), shifted(-h), value(&d, &at)) else { continue };
            let numeric = (up - down) / (2.0 * h);
            let tol = 1e-4 * (1.0 + exact.abs() + up.abs());
            prop_assert!((numeric - exact).abs() <= tol, "d/dx {e} = {d}: {exact} vs finite difference {numeric} at {at:?}");
        }
    }

    /// Plain printing re-parses to the identical node (pointer-equal, as `Expr == Expr` is).
    #[test]
    fn plain_print_reparses_to_the_same_dag(e in arb_expr()) {
        let text = e.to_string();
        let back = parse(&text).map_err(|err| TestCaseError::fail(format!("{text}: {err}")))?;
        prop_assert!(back == e, "{text} re-parsed as {back}");
        let s = simplify(&e);
        let text = s.to_string();
        let back = parse(&text).map_err(|err| TestCaseError::fail(format!("{text}: {err}")))?;
        prop_assert!(back == s, "{text} re-parsed as {back}");
    }

    /// Sums and products are one node whatever the order of their operands.
    #[test]
    fn canonical_construction_is_order_independent(xs in prop::collection::vec(arb_expr(), 1..6), k in 0usize..6) {
        let mut rotated = xs.clone();
        rotated.rotate_left(k % xs.len());
        let mut reversed = xs.clone();
        reversed.reverse();
        prop_assert!(Expr::add(xs.clone()) == Expr::add(rotated.clone()));
        prop_assert!(Expr::add(xs.clone()) == Expr::add(reversed.clone()));
        prop_assert!(Expr::mul(xs.clone()) == Expr::mul(rotated));
        prop_assert!(Expr::mul(xs.clone()) == Expr::mul(reversed));
        // Building pairwise, left to right, gives the same node as all at once.
        let folded = xs.iter().skip(1).fold(xs[0].clone(), |acc, x| acc.plus(x));
        prop_assert!(folded == Expr::add(xs));
    }
}

/// Regressions found by the table: products with a negative coefficient and a sum factor
/// (`-(a + b) c`) re-parse to the same node, a lone sum denominator prints with one pair of
/// parentheses, and a sign in an exponent stays in the exponent (`x^-2 y` is `y/x²`).
#[test]
fn printed_products_reparse_identically() {
    let (a, b, c) = (Expr::var("a"), Expr::var("b"), Expr::var("c"));
    let sum = a.plus(&b);
    for e in [
        Expr::mul([Expr::int(-1), sum.clone(), c.clone()]),
        Expr::mul([Expr::int(-1), sum.clone(), c.powi(-1)]),
        Expr::mul([Expr::frac(-3, 2), sum.clone(), c.clone()]),
        a.minus(&Expr::one()).over(&a.plus(&Expr::one())),
        Expr::mul([Expr::frac(-1, 2), a.powi(2).plus(&Expr::one()).powi(-1)]),
        // A rational times sums and nothing else distributes when re-built from `3 (a + b)`:
        Expr::mul([Expr::int(3), sum.clone(), c.powi(-1)]),
        Expr::mul([Expr::frac(3, 2), sum.clone(), c.plus(&Expr::one()).powi(-1)]),
        Expr::mul([Expr::int(-3), a.minus(&Expr::one()), Expr::call(lagrangian::Func::Sin, vec![Expr::one()])]),
    ] {
        let text = e.to_string();
        assert!(!text.contains("(("), "{text}");
        assert!(parse(&text).is_ok_and(|back| back == e), "{text}");
    }
    // Two sums under one rational coefficient are grouped so the coefficient cannot
    // distribute over the first: `3 ((a + b) (c + 1))`.
    let two_sums = Expr::mul([Expr::int(3), sum.clone(), c.plus(&Expr::one())]);
    let text = two_sums.to_string();
    assert!(parse(&text).is_ok_and(|back| back == two_sums), "{text}");
    let by_hand = Expr::var("y").over(&Expr::var("x").powi(2));
    assert!(parse("x^-2 y").is_ok_and(|e| e == by_hand));
    assert!(parse("-x^2").is_ok_and(|e| e == Expr::var("x").powi(2).neg()));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// The Taylor coefficients of `e` along a line through the sample box, to order 12: the
    /// unrolled and the compact native code give the interpreter's bits for every row and
    /// order (where the host has a JIT; the fixed cases in `taylor_native.rs` check that it does).
    #[test]
    fn native_taylor_coefficients_equal_the_interpreter(e in arb_expr(), seed in any::<u64>()) {
        let Ok(tape) = Tape::compile(std::slice::from_ref(&e), &NAMES, &[]) else { return Ok(()) };
        let tt = TaylorTape::new(&tape);
        let (p, s) = (12, 13);
        let at = &points(seed)[0];
        let start: Vec<f64> = NAMES.iter().map(|n| at[*n]).collect();
        // x_i(t) = x_i + (i + 1)/4 · t.
        let line = |k: usize, c: &mut [f64]| {
            for (i, x0) in start.iter().enumerate() {
                c[i * s + k] = match k {
                    0 => *x0,
                    1 => (i + 1) as f64 / 4.0,
                    _ => 0.0,
                };
            }
        };
        let bits = |c: &[f64]| c.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut reference = vec![f64::NAN; tt.n_rows() * s];
        tt.expand(&mut reference, s, p, line).map_err(|_| TestCaseError::fail("abs kink"))?;
        for code in [tt.compile_native(s, p), tt.compile_native_compact(s, p)].into_iter().flatten() {
            let mut c = vec![f64::NAN; tt.n_rows() * s];
            tt.expand_with(Some(&code), &mut c, s, p, line).map_err(|_| TestCaseError::fail("abs kink"))?;
            prop_assert_eq!(bits(&reference), bits(&c), "{} ({})", e, if code.is_compact() { "compact" } else { "unrolled" });
        }
    }
}

/// Every built-in's derivative (its row in the function table) agrees with the central
/// difference at points inside and outside (-1, 1), wherever the function is finite there, and
/// its call prints in plain form to text that re-parses to the same node. Iterates the table,
/// so a new function is covered without touching this test.
#[test]
fn every_builtin_derivative_matches_central_difference_and_reparses() {
    let x = Symbol::new("x");
    let y = Expr::sym(Symbol::new("y"));
    let h = 1e-6;
    for f in Func::ALL {
        let args = if f.arity() == 2 { vec![Expr::sym(x.clone()), y.clone()] } else { vec![Expr::sym(x.clone())] };
        let e = Expr::call(f, args);
        let d = diff(&e, &x);
        let mut checked = 0;
        // acosh is real only above 1, atanh only inside (−1, 1): at least three points each.
        for xv in [-2.3, -0.7, -0.2, 0.35, 0.8, 1.3, 1.6, 2.9] {
            let at = |xv: f64| HashMap::from([("x".to_string(), xv), ("y".to_string(), 0.45)]);
            let (Some(up), Some(down), Some(exact)) =
                (value(&e, &at(xv + h)), value(&e, &at(xv - h)), value(&d, &at(xv)))
            else {
                continue;
            };
            let numeric = (up - down) / (2.0 * h);
            let tol = 1e-6 * (1.0 + exact.abs() + up.abs());
            assert!(
                (numeric - exact).abs() <= tol,
                "d/dx {e} = {d}: {exact} vs finite difference {numeric} at x = {xv}"
            );
            checked += 1;
        }
        assert!(checked >= 3, "{e}: only {checked} sample points in its domain");
        let text = e.to_string();
        assert_eq!(parse(&text).unwrap(), e, "{text} re-parses");
    }
}
