//! Round trip at depth and size: what the printer emits, the parser
//! accepts, and it reads back as the identical (pointer-equal, hash-consed) node. Covers
//! degree-400 polynomials before and after `simplify` (whose Horner forms used to nest 399
//! levels, past the parser's old limit of 200) and towers of calls and powers 300 deep.
//! Each test runs on the test harness's 2 MB worker thread, the smallest stack a caller has.

use lagrangian::print::plain;
use lagrangian::simplify::simplify;
use lagrangian::{parse, Expr, Func};
use proptest::prelude::*;

/// The deepest parenthesis nesting in printed text.
fn paren_depth(s: &str) -> usize {
    let (mut depth, mut deepest) = (0usize, 0usize);
    for c in s.chars() {
        match c {
            '(' => {
                depth += 1;
                deepest = deepest.max(depth);
            }
            ')' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    deepest
}

/// Prints `e`, re-parses the text and asserts the same node comes back.
fn round_trip(e: &Expr) -> String {
    let text = plain(e);
    assert!(paren_depth(&text) <= lagrangian::parse::MAX_DEPTH, "printed deeper than the parser accepts");
    let back = parse(&text).unwrap_or_else(|err| panic!("printed text does not re-parse: {err}"));
    assert!(back == *e, "re-parsed to a different node:\n{}\n{}", text, plain(&back));
    text
}

/// `Σ c_k x^k` for k = 0..=degree, written out.
fn polynomial(coeffs: &[i64]) -> String {
    coeffs.iter().enumerate().map(|(k, c)| format!("({c}) x^{k}")).collect::<Vec<_>>().join(" + ")
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3, ..ProptestConfig::default() })]

    #[test]
    fn degree_400_polynomials_round_trip_before_and_after_simplify(
        coeffs in prop::collection::vec(-9i64..=9, 401),
        lead in 1i64..=9,
    ) {
        let mut coeffs = coeffs;
        coeffs[400] = lead;
        let e = parse(&polynomial(&coeffs)).unwrap();
        round_trip(&e);
        let s = simplify(&e);
        let text = round_trip(&s);
        // The simplifier keeps nesting shallow (Horner forms at most 64 levels), so its
        // output is also readable, not only re-parseable.
        prop_assert!(paren_depth(&text) <= 64, "simplified output nests {} levels", paren_depth(&text));
    }

    /// A tower 300 deep of functions and powers chosen at random, built by the library.
    #[test]
    fn towers_300_deep_round_trip(kinds in prop::collection::vec(0u8..5, 300)) {
        let x = Expr::var("x");
        let mut e = x.clone();
        for k in kinds {
            e = match k {
                0 => Expr::call(Func::Sin, vec![e]),
                1 => Expr::call(Func::Exp, vec![e]),
                2 => Expr::pow(e, Expr::int(3)),
                3 => Expr::pow(x.clone(), e),
                _ => Expr::add([Expr::call(Func::Cos, vec![e]), x.clone()]),
            };
        }
        round_trip(&e);
    }
}

#[test]
fn pure_towers_of_sin_exp_and_powers_round_trip() {
    let x = Expr::var("x");
    let (mut sin, mut exp, mut pow) = (x.clone(), x.clone(), x.clone());
    for _ in 0..300 {
        sin = Expr::call(Func::Sin, vec![sin]);
        exp = Expr::call(Func::Exp, vec![exp]);
        pow = Expr::pow(x.clone(), pow);
    }
    assert_eq!(paren_depth(&round_trip(&sin)), 300);
    round_trip(&exp);
    // `x^x^…^x` prints as one right-associative chain of 300 `^`.
    assert_eq!(round_trip(&pow).matches('^').count(), 300);
}

#[test]
fn nesting_past_the_limit_is_refused_with_its_location() {
    let limit = lagrangian::parse::MAX_DEPTH;
    let at = format!("{}x{}", "sin(".repeat(limit), ")".repeat(limit));
    assert!(parse(&at).is_ok());
    let past = format!("{}x{}", "sin(".repeat(limit + 1), ")".repeat(limit + 1));
    let err = parse(&past).unwrap_err().to_string();
    assert!(err.contains(&format!("nesting deeper than {limit} levels")), "{err}");
}

#[test]
fn binomial_power_minus_its_expansion_is_zero() {
    // Coefficients from Pascal's rule, independently of the engine's binomial expansion.
    let n = 400;
    let mut row = vec![num_bigint::BigInt::from(1)];
    for _ in 0..n {
        let mut next = vec![num_bigint::BigInt::from(1)];
        next.extend(row.windows(2).map(|w| &w[0] + &w[1]));
        next.push(num_bigint::BigInt::from(1));
        row = next;
    }
    let expansion: Vec<String> = row.iter().enumerate().map(|(k, c)| format!("{c} x^{k}")).collect();
    let text = format!("(x + 1)^{n} - ({})", expansion.join(" + "));
    let e = parse(&text).unwrap();
    assert!(simplify(&e).is_zero(), "(x+1)^{n} minus its expansion did not simplify to 0");
    // One coefficient off by one must not simplify to 0 (the numeric guard must not hide it).
    let wrong = text.replacen(" + 400 x^1 ", " + 401 x^1 ", 1);
    assert_ne!(wrong, text);
    assert!(!simplify(&parse(&wrong).unwrap()).is_zero());
}

/// The Euler–Lagrange expression of a degree-1010 polynomial potential: the mechanics stage's
/// tidy form factors sums Horner-style, and used to nest `E_x` 1008 levels deep, so the
/// exported "plain form, which re-parses" did not (the parser stops at 1000 levels). Now its
/// Horner nesting stops at 64 levels and the text reads back as the same node.
#[test]
fn euler_lagrange_of_a_degree_1010_potential_round_trips() {
    let potential: Vec<String> = (1..=1010).map(|k| format!("{} x^{k}", k + 1)).collect();
    let text = format!("1/2 x'^2 - ({})", potential.join(" + "));
    let system = lagrangian::mechanics::System::from_lagrangian(&text, &["x"]).expect("a valid Lagrangian");
    let el = system.euler_lagrange().expect("Euler–Lagrange");
    let printed = round_trip(&el[0]);
    assert!(paren_depth(&printed) <= 66, "E_x nests {} levels", paren_depth(&printed));
    // The value: x'' + Σ k (k + 1) x^(k−1) at x = 0.9, x'' = 0.
    let at = |x: f64| -> f64 { (1..=1010).map(|k| (k * (k + 1)) as f64 * x.powi(k - 1)).sum() };
    let vars = std::collections::HashMap::from([("x".to_string(), 0.9), ("x''".to_string(), 0.0)]);
    let value = lagrangian::eval::eval(&el[0], &vars).expect("a number");
    assert!((value - at(0.9)).abs() <= 1e-12 * at(0.9), "{value} against {}", at(0.9));
}
