//! Properties of the Poisson bracket on random polynomial and trigonometric expressions:
//! antisymmetry, bilinearity, the Leibniz rule and the Jacobi identity; and canonicity of
//! every transformation the solver obtains from a random F2.
//!
//! Each identity is decided by `decide_zero`: a symbolic proof when the normal form reaches 0,
//! otherwise a numeric check at random points. Both count as passing, and a `NonZero` fails.

use lagrangian::canonical::{decide_zero, poisson, Generator, GeneratorKind, PhaseSpace, ZeroCheck};
use lagrangian::{parse, Expr};
use proptest::prelude::*;

fn space() -> PhaseSpace {
    PhaseSpace::new(["x", "y"]).expect("valid")
}

/// Random expressions in x, y, p_x, p_y: sums and products of monomials, sines and cosines.
fn expr_text() -> impl Strategy<Value = String> {
    let leaf = prop_oneof![
        Just("x".to_string()),
        Just("y".to_string()),
        Just("p_x".to_string()),
        Just("p_y".to_string()),
        (-3i32..=3).prop_map(|n| format!("({n})")),
    ];
    leaf.prop_recursive(3, 12, 3, |inner| {
        prop_oneof![
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("({a} + {b})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("({a}) ({b})")),
            inner.clone().prop_map(|a| format!("sin({a})")),
            inner.clone().prop_map(|a| format!("cos({a})")),
            inner.prop_map(|a| format!("({a})^2")),
        ]
    })
}

fn e(text: &str) -> Expr {
    parse(text).expect("generated expressions parse")
}

fn is_zero(x: &Expr) -> bool {
    let c = decide_zero(x);
    assert!(!matches!(c, ZeroCheck::Undecided), "undecided: {x}");
    c.is_zero()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    #[test]
    fn antisymmetry(f in expr_text(), g in expr_text()) {
        let ps = space();
        let (f, g) = (e(&f), e(&g));
        prop_assert!(is_zero(&poisson(&f, &g, &ps).plus(&poisson(&g, &f, &ps))));
        prop_assert!(poisson(&f, &f, &ps).is_zero() || is_zero(&poisson(&f, &f, &ps)));
    }

    #[test]
    fn bilinearity(f in expr_text(), g in expr_text(), h in expr_text(), a in -5i64..5, b in -5i64..5) {
        let ps = space();
        let (f, g, h) = (e(&f), e(&g), e(&h));
        let (a, b) = (Expr::int(a), Expr::int(b));
        let lhs = poisson(&a.times(&f).plus(&b.times(&g)), &h, &ps);
        let rhs = a.times(&poisson(&f, &h, &ps)).plus(&b.times(&poisson(&g, &h, &ps)));
        prop_assert!(is_zero(&lhs.minus(&rhs)));
    }

    #[test]
    fn leibniz(f in expr_text(), g in expr_text(), h in expr_text()) {
        let ps = space();
        let (f, g, h) = (e(&f), e(&g), e(&h));
        let lhs = poisson(&f.times(&g), &h, &ps);
        let rhs = f.times(&poisson(&g, &h, &ps)).plus(&poisson(&f, &h, &ps).times(&g));
        prop_assert!(is_zero(&lhs.minus(&rhs)));
    }

    #[test]
    fn jacobi(f in expr_text(), g in expr_text(), h in expr_text()) {
        let ps = space();
        let (f, g, h) = (e(&f), e(&g), e(&h));
        let j = Expr::add([
            poisson(&f, &poisson(&g, &h, &ps), &ps),
            poisson(&g, &poisson(&h, &f, &ps), &ps),
            poisson(&h, &poisson(&f, &g, &ps), &ps),
        ]);
        prop_assert!(is_zero(&j));
    }

    /// F2 = f(q) P + c P² + g(q) (p linear in P), or f(q) P + c q P² + g(q) (p quadratic in P,
    /// solved with an explicit branch). The solver inverts each; the forward map must satisfy
    /// {Q, P} = 1.
    #[test]
    fn solvable_f2_gives_canonical_maps(fi in 0usize..4, gi in 0usize..4, c in 0i64..3, a in 1i64..4, quad in any::<bool>()) {
        let f = ["q", "q^3", "exp(q)", "sinh(q)"][fi].replace('q', &format!("({a} q)"));
        let g = ["0", "q^2", "cos(q)", "q^4/4"][gi];
        let pp = if quad { "q P^2" } else { "P^2" };
        let f2 = e(&format!("({f}) P + {c} {pp} + {g}"));
        let old = PhaseSpace::new(["q"]).expect("valid");
        let new = PhaseSpace::with_momenta(["Q"], ["P"]).expect("valid");
        let t = Generator::new(GeneratorKind::F2, f2.clone(), old.clone(), new).expect("valid variables")
            .transform(None).expect("a non-singular generator");
        if let Ok(fwd) = &t.forward {
            let qv = &fwd[0].1;
            let pv = &fwd[1].1;
            let b = poisson(qv, pv, &old);
            prop_assert!(is_zero(&b.minus(&Expr::one())), "F2 = {f2}: {{Q, P}} = {b}");
        } else {
            prop_assert!(false, "F2 = {f2}: the solver should invert a relation linear in P");
        }
    }
}

/// One expansion for the canonical zero tests and `algebra`: `reduce::expand`
/// multiplies products and powers of sums out through `algebra::multiply_out`, so on inputs
/// without function arguments or denominators (where only `reduce` descends) both give the same
/// canonical expression, of unchanged value; past the term budget `reduce` keeps the product.
#[test]
fn reduce_expands_through_the_algebra_expansion() {
    use lagrangian::canonical::reduce::expand as reduce_expand;
    for text in ["(a + b) (a - b) c", "(x + 1)^3 - x^3", "(p - m w q)^2/2 + k (q + 1) (q - 1)", "(a + b + c)^4"] {
        let input = e(text);
        let ours = lagrangian::algebra::expand(&input).expect("small");
        assert_eq!(reduce_expand(&input), ours, "{text}");
        for k in 0..5 {
            let v = |s: &lagrangian::Symbol| Some(0.3 + 0.37 * (k as f64) + 0.11 * s.name().len() as f64);
            let (a, b) = (
                lagrangian::eval::eval_with(&input, &v).expect("finite"),
                lagrangian::eval::eval_with(&ours, &v).expect("finite"),
            );
            assert!((a - b).abs() <= 1e-12 * (1.0 + a.abs()), "{text}: {a} vs {b}");
        }
    }
    let big = e("(a1 + a2 + a3 + a4 + a5 + a6 + a7 + a8 + a9 + a10)^16");
    assert_eq!(reduce_expand(&big), big);
}
