//! Lie series (PHYSICS.md §4.4.2): exact series of simple flows, and the pendulum flow as a
//! Taylor series in t checked against a fine RK4 integration, with the truncation error
//! falling like t^(N+1) for order N.

use lagrangian::canonical::{lie_flow, lie_series, lie_terms, LieError, PhaseSpace};
use lagrangian::eval::eval_with;
use lagrangian::{parse, Expr, Symbol};

fn p(s: &str) -> Expr {
    parse(s).expect("test input parses")
}

use crate::support::snapshot as snap;

#[test]
fn translation_and_rotation_series_are_exact() {
    // exp(ε{·, p}) q = q + ε: the momentum generates translations; the series stops.
    let ps = PhaseSpace::new(["q"]).expect("valid");
    let eps = Symbol::new("ε");
    assert_eq!(lie_series(&p("q"), &p("p_q"), &eps, 5, &ps), p("q + ε"));
    // exp(ε{·, L_z}) x = x cos ε − y sin ε, term by term: {x, L_z} = −y, {−y, L_z} = −x, …
    let ps2 = PhaseSpace::new(["x", "y"]).expect("valid");
    let terms = lie_terms(&p("x"), &p("x p_y - y p_x"), 6, &ps2);
    let hand = ["x", "-y", "-x/2", "y/6", "x/24", "-y/120", "-x/720"];
    for (k, (t, h)) in terms.iter().zip(hand).enumerate() {
        assert_eq!(*t, p(h), "order {k}");
    }
}

/// The pendulum H = p²/2 − cos q integrated by classical RK4 with `n` steps to time `t`.
fn rk4(q0: f64, p0: f64, t: f64, n: usize) -> f64 {
    let f = |q: f64, pm: f64| (pm, -q.sin());
    let h = t / n as f64;
    let (mut q, mut pm) = (q0, p0);
    for _ in 0..n {
        let k1 = f(q, pm);
        let k2 = f(q + 0.5 * h * k1.0, pm + 0.5 * h * k1.1);
        let k3 = f(q + 0.5 * h * k2.0, pm + 0.5 * h * k2.1);
        let k4 = f(q + h * k3.0, pm + h * k3.1);
        q += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
        pm += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
    }
    q
}

#[test]
fn pendulum_flow_matches_rk4_with_the_predicted_order() {
    let ps = PhaseSpace::new(["q"]).expect("valid");
    let h = p("p_q^2/2 - cos(q)");
    let (q0, p0) = (0.7, 0.4);
    let at = |e: &Expr, t: f64| {
        eval_with(e, &|s: &Symbol| match s.name() {
            "q" => Some(q0),
            "p_q" => Some(p0),
            "t" => Some(t),
            _ => None,
        })
        .expect("evaluates")
    };
    // Reference: RK4 with 4000 steps (error ~ (t/4000)^4, far below the series errors).
    let (t1, t2) = (0.2, 0.1);
    let (r1, r2) = (rk4(q0, p0, t1, 4000), rk4(q0, p0, t2, 4000));
    // Richardson-style check of the reference itself: halving the steps changes it by < 1e-14.
    assert!((rk4(q0, p0, t1, 2000) - r1).abs() < 1e-14);
    let mut last = f64::INFINITY;
    for order in 1..=5usize {
        let series = lie_flow(&p("q"), &h, order, &ps).expect("autonomous");
        let (e1, e2) = ((at(&series, t1) - r1).abs(), (at(&series, t2) - r2).abs());
        // The error of a truncated Taylor series is O(t^(N+1)): halving t divides it by 2^(N+1).
        let slope = (e1 / e2).log2();
        assert!((slope - (order as f64 + 1.0)).abs() < 0.35, "order {order}: slope {slope}, errors {e1:e} {e2:e}");
        assert!(e1 < last, "order {order}: error {e1:e} did not fall (previous {last:e})");
        last = e1;
    }
    snap("canonical_pendulum_flow", lie_flow(&p("q"), &h, 4, &ps).expect("autonomous").to_string());
}

#[test]
fn time_dependent_hamiltonian_is_refused_for_the_flow() {
    let ps = PhaseSpace::new(["q"]).expect("valid");
    assert_eq!(lie_flow(&p("q"), &p("p_q^2/2 + q t"), 3, &ps), Err(LieError::TimeDependent));
}

#[test]
fn a_generator_or_function_containing_epsilon_is_truncated_consistently_in_epsilon() {
    // f = p²/2 + ε q⁴, G = q³ p: the first bracket ε{f, G} = ε(4ε q⁶ − 3 q² p²) has an ε² part,
    // and the ε² coefficient also gets ε²/2 {{p²/2, G}, G} = 6 ε² q⁴ p² from the next bracket.
    // At order 1 no ε² term may be kept; at orders 2 and 3 every power up to the order is
    // complete. Expected series from SymPy, brackets summed to order + 2 then truncated
    // (scripts/notes_gaps_reference.py).
    let ps = PhaseSpace::new(["q"]).expect("valid");
    let eps = Symbol::new("ε");
    let f = p("p_q^2/2 + ε q^4");
    let g = p("q^3 p_q");
    let sympy = [
        "-3 ε p_q^2 q^2 + ε q^4 + p_q^2/2",
        "6 ε^2 p_q^2 q^4 + 4 ε^2 q^6 - 3 ε p_q^2 q^2 + ε q^4 + p_q^2/2",
        "-4 ε^3 p_q^2 q^6 + 12 ε^3 q^8 + 6 ε^2 p_q^2 q^4 + 4 ε^2 q^6 - 3 ε p_q^2 q^2 + ε q^4 + p_q^2/2",
    ];
    for (order, expected) in (1..=3).zip(sympy) {
        let got = lie_series(&f, &g, &eps, order, &ps);
        let diff = lagrangian::canonical::normalize(&got.minus(&p(expected)));
        assert!(diff.is_zero(), "order {order}: {got} − SymPy = {diff}");
    }
    // A generator of order ε: exp(ε{·, ε p²/2 + ε² q}) q = q + ε² p + O(ε⁴) ({q, G} = ε p,
    // {ε p, G} = −ε³), so order 2 and order 3 are both q + ε² p.
    for order in [2, 3] {
        assert_eq!(lie_series(&p("q"), &p("ε p_q^2/2 + ε^2 q"), &eps, order, &ps), p("q + ε^2 p_q"), "order {order}");
    }
}
