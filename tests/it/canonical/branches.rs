//! The inverse map of a generating function keeps the sign information of
//! the forward map, and `K` comes out short.
//!
//! The adiabatic oscillator with an explicit `ω(t) = ω0 (1 + ε t)` (notes 4.2.1) used to
//! print its inverse map through `√(−1)`, and the map equalled `√(2P/ω)·|sin Q|`, so `q` had
//! the wrong sign whenever `sin Q < 0`. Here the map is checked as a true inverse of the
//! forward map on all four quadrants of `Q`: random `(q, p)` of every sign give
//! `Q = atan2(ω q, p)` (the angle the forward relation `tan Q = ω q/p` defines on the whole
//! circle) and `P = H/ω`; the printed inverse map must return the same `(q, p)`.

use lagrangian::canonical::{decide_zero, Generator, GeneratorKind, PhaseSpace, ZeroCheck};
use lagrangian::eval::{eval, Env};
use lagrangian::{parse_with, Declarations, Expr, Symbol};

fn p(s: &str) -> Expr {
    parse_with(s, &Declarations::new().with_positive(["ω0", "ε"])).expect("test input parses")
}

fn value(rel: &[(Symbol, Expr)], name: &str) -> Expr {
    rel.iter().find(|(s, _)| s.name() == name).map(|(_, e)| e.clone()).expect("relation present")
}

/// A small deterministic generator (SplitMix64) so the random points repeat exactly.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
}

#[test]
fn adiabatic_oscillator_inverse_map_is_real_and_keeps_the_sign_of_sin_q() {
    let old = PhaseSpace::new(["q"]).expect("phase space");
    let new = PhaseSpace::with_momenta(["Q"], ["P"]).expect("phase space");
    let g = Generator::new(GeneratorKind::F1, p("1/2 ω0 (1 + ε t) q^2 cot(Q)"), old, new).expect("generator");
    let t = g.transform(Some(&p("p_q^2/2 + 1/2 ω0^2 (1 + ε t)^2 q^2"))).expect("transform");
    let inv = t.inverse.as_ref().expect("inverse map in closed form");
    let (qe, pe) = (value(inv, "q"), value(inv, "p_q"));
    for e in [&qe, &pe] {
        let s = e.to_string();
        assert!(!s.contains("sqrt(-") && !s.contains("(-1)^"), "an imaginary unit in a real map: {s}");
        assert!(!s.contains("abs("), "an absolute value where the sign is meant: {s}");
    }
    assert!(t.branches.iter().any(|b| b.contains("+ root taken")), "the branch is named: {:?}", t.branches);

    let mut rng = Rng(15);
    let mut quadrants = [0usize; 4];
    for _ in 0..200 {
        let (w0, eps, time) = (rng.range(0.5, 2.0), rng.range(0.0, 0.1), rng.range(0.0, 10.0));
        let (q, pq) = (rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
        let w = w0 * (1.0 + eps * time);
        let angle = (w * q).atan2(pq);
        let action = (pq * pq / w + w * q * q) / 2.0;
        quadrants[((angle + std::f64::consts::PI) / std::f64::consts::FRAC_PI_2).floor().min(3.0) as usize] += 1;
        let env: Env = [("ω0", w0), ("ε", eps), ("t", time), ("Q", angle), ("P", action)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
        let (q2, p2) = (eval(&qe, &env).expect("q evaluates"), eval(&pe, &env).expect("p evaluates"));
        assert!(
            (q2 - q).abs() < 1e-12 * (1.0 + q.abs()) && (p2 - pq).abs() < 1e-12 * (1.0 + pq.abs()),
            "Q = {angle}, P = {action}: the inverse map gives ({q2}, {p2}), the point was ({q}, {pq})"
        );
    }
    assert!(quadrants.iter().all(|&n| n > 20), "every quadrant of Q is sampled: {quadrants:?}");
}

#[test]
fn adiabatic_oscillator_k_is_short() {
    let old = PhaseSpace::new(["q"]).expect("phase space");
    let new = PhaseSpace::with_momenta(["Q"], ["P"]).expect("phase space");
    let g = Generator::new(GeneratorKind::F1, p("1/2 ω0 (1 + ε t) q^2 cot(Q)"), old, new).expect("generator");
    let t = g.transform(Some(&p("p_q^2/2 + 1/2 ω0^2 (1 + ε t)^2 q^2"))).expect("transform");
    let k = t.hamiltonian.clone().expect("asked").expect("closed form");
    // PHYSICS.md (4.2.1): K = ω P + (ω'/(2ω)) P sin 2Q, with ω = ω0 (1 + ε t), ω' = ω0 ε.
    let hand = p("ω0 (1 + ε t) P + ε/(2 (1 + ε t)) P sin(2 Q)");
    assert_eq!(decide_zero(&k.minus(&hand)), ZeroCheck::Proven, "K = {k}");
    // The four-term fraction over `t ε + 1` is gone: the polynomial part cancels to ω P.
    assert!(k.terms().len() <= 2 && k.op_count() <= hand.op_count() + 2, "K is not compact: {k}");
}
