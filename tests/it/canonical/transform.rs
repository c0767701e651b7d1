//! Generating functions F1–F4 and explicit maps (PHYSICS.md §4): the oscillator's
//! action-angle variables, the adiabatic oscillator, a point transformation, the exchange
//! transformation, a rotating frame, and the refusals (singular generator, non-canonical map).

use lagrangian::canonical::{
    check_map, decide_zero, poisson, Canonicity, ExplicitMap, GeneratedTransform, Generator, GeneratorKind, PhaseSpace,
    TransformError, ZeroCheck,
};
use lagrangian::{parse_with, Declarations, Expr, Symbol};

fn p(s: &str) -> Expr {
    parse_with(s, &Declarations::new().with_functions(["V", "ω"]).with_positive(["m", "w", "Ω"]))
        .expect("test input parses")
}

use crate::support::snapshot as snap;

fn ps(coords: &[&str]) -> PhaseSpace {
    PhaseSpace::new(coords).expect("valid phase space")
}

fn new_ps(coords: &[&str], momenta: &[&str]) -> PhaseSpace {
    PhaseSpace::with_momenta(coords, momenta).expect("valid phase space")
}

fn render(t: &GeneratedTransform) -> String {
    let mut out = vec![format!("relations ({}):", t.kind)];
    out.extend(t.relations.iter().map(|(s, e)| format!("  {s} = {e}")));
    for (title, r) in [("inverse", &t.inverse), ("forward", &t.forward)] {
        match r {
            Ok(v) => {
                out.push(format!("{title}:"));
                out.extend(v.iter().map(|(s, e)| format!("  {s} = {e}")));
            }
            Err(e) => out.push(format!("{title}: {e}")),
        }
    }
    out.extend(t.branches.iter().map(|b| format!("branch: {b}")));
    match &t.hamiltonian {
        Some(Ok(k)) => out.push(format!("K = {k}")),
        Some(Err(e)) => out.push(format!("K: {e}")),
        None => {}
    }
    out.join("\n")
}

fn value(rel: &[(Symbol, Expr)], name: &str) -> Expr {
    rel.iter().find(|(s, _)| s.name() == name).map(|(_, e)| e.clone()).expect("relation present")
}

/// The forward map (Q, P)(q, p) must satisfy every fundamental bracket over the old
/// variables (PHYSICS.md §4.4): {Q_i, P_j} = δ_ij, {Q_i, Q_j} = {P_i, P_j} = 0.
fn assert_forward_canonical(t: &GeneratedTransform, old: &PhaseSpace, new: &PhaseSpace) {
    let fwd = t.forward.as_ref().expect("forward map in closed form");
    let names = |v: &[Symbol]| v.iter().map(|s| s.name().to_string()).collect::<Vec<_>>();
    let (qs, ps) = (names(&new.coords), names(&new.momenta));
    let mut checked = 0;
    for (i, qi) in qs.iter().enumerate() {
        for (j, pj) in ps.iter().enumerate() {
            let b = poisson(&value(fwd, qi), &value(fwd, pj), old);
            let expected = Expr::int(i64::from(i == j));
            assert!(decide_zero(&b.minus(&expected)).is_zero(), "{{{qi}, {pj}}} = {b}, expected {expected}");
            checked += 1;
        }
        for (a, b_name) in [(&qs, &qs), (&ps, &ps)] {
            for other in &b_name[i + 1..] {
                let b = poisson(&value(fwd, &a[i]), &value(fwd, other), old);
                assert!(decide_zero(&b).is_zero(), "{{{}, {other}}} = {b}, expected 0", a[i]);
                checked += 1;
            }
        }
    }
    // n² mixed brackets and n(n − 1) pure ones.
    let n = qs.len();
    assert_eq!(checked, n * n + n * (n - 1));
}

#[test]
fn oscillator_action_angle_variables() {
    let old = ps(&["q"]);
    let new = new_ps(&["Q"], &["P"]);
    let g =
        Generator::new(GeneratorKind::F1, p("1/2 m w q^2 cot(Q)"), old.clone(), new.clone()).expect("valid generator");
    let t = g.transform(Some(&p("p_q^2/(2 m) + 1/2 m w^2 q^2"))).expect("transform");
    // K = ω P exactly (PHYSICS.md §4).
    assert_eq!(t.hamiltonian.clone().expect("asked").expect("closed form"), p("w P"));
    // The maps of PHYSICS.md: q = sqrt(2P/(m ω)) sin Q, p = sqrt(2 m ω P) cos Q.
    let inv = t.inverse.as_ref().expect("inverse");
    assert!(decide_zero(&value(inv, "q").minus(&p("sqrt(2 P/(m w)) sin(Q)"))).is_zero());
    assert!(decide_zero(&value(inv, "p_q").minus(&p("sqrt(2 m w P) cos(Q)"))).is_zero());
    // Forward: P = H/ω (the action), tan Q = m ω q/p.
    let fwd = t.forward.as_ref().expect("forward");
    assert_eq!(decide_zero(&value(fwd, "P").minus(&p("(p_q^2/(2 m) + 1/2 m w^2 q^2)/w"))), ZeroCheck::Proven);
    assert_forward_canonical(&t, &old, &new);
    // Second route: Newton on the implicit relation agrees with the closed-form inverse.
    let params: lagrangian::eval::Env = [("m".to_string(), 1.3), ("w".to_string(), 0.7)].into_iter().collect();
    let (qv, pv) = (0.6, 2.1);
    let mut env = params.clone();
    env.extend([("Q".to_string(), qv), ("P".to_string(), pv)]);
    let closed_q = lagrangian::eval::eval(&value(inv, "q"), &env).expect("evaluates");
    let closed_p = lagrangian::eval::eval(&value(inv, "p_q"), &env).expect("evaluates");
    let num = g.numeric_inverse(&[qv, pv], &params, &[1.0]).expect("converges");
    assert!(
        (num[0] - closed_q).abs() < 1e-13 && (num[1] - closed_p).abs() < 1e-13,
        "{num:?} vs {closed_q}, {closed_p}"
    );
    snap("canonical_oscillator_action_angle", render(&t));
}

#[test]
fn adiabatic_oscillator_gains_the_sin_2q_term() {
    let g = Generator::new(GeneratorKind::F1, p("1/2 m ω(t) q^2 cot(Q)"), ps(&["q"]), new_ps(&["Q"], &["P"]))
        .expect("valid generator");
    let t = g.transform(Some(&p("p_q^2/(2 m) + 1/2 m ω(t)^2 q^2"))).expect("transform");
    let k = t.hamiltonian.clone().expect("asked").expect("closed form");
    // PHYSICS.md §4 (4.2.1): K = ω P + (ω'/(2ω)) P sin 2Q.
    let hand = p("ω(t) P + ω'(t)/(2 ω(t)) P sin(2 Q)");
    assert_eq!(decide_zero(&k.minus(&hand)), ZeroCheck::Proven, "K = {k}");
    snap("canonical_adiabatic_oscillator", render(&t));
}

#[test]
fn point_transformation_polar_to_cartesian() {
    // F2 = Σ f_i(q) P_i with Q = f(q): X = r cos φ, Y = r sin φ; then p = (∂f/∂q)ᵀ P.
    let old = ps(&["r", "φ"]);
    let new = new_ps(&["X", "Y"], &["P_X", "P_Y"]);
    let g = Generator::new(GeneratorKind::F2, p("P_X r cos(φ) + P_Y r sin(φ)"), old.clone(), new.clone())
        .expect("valid generator");
    let t = g.transform(Some(&p("p_r^2/(2 m) + p_φ^2/(2 m r^2)"))).expect("transform");
    let rel = &t.relations;
    assert_eq!(value(rel, "X"), p("r cos(φ)"));
    assert_eq!(value(rel, "p_r"), p("P_X cos(φ) + P_Y sin(φ)"));
    assert_eq!(value(rel, "p_φ"), p("-P_X r sin(φ) + P_Y r cos(φ)"));
    // The free particle is free in Cartesian variables.
    let k = t.hamiltonian.clone().expect("asked").expect("closed form");
    assert_eq!(decide_zero(&k.minus(&p("(P_X^2 + P_Y^2)/(2 m)"))), ZeroCheck::Proven);
    // The inverse (with its atan branch) maps back: r² = X² + Y², tan φ = Y/X.
    let inv = t.inverse.as_ref().expect("inverse");
    assert!(decide_zero(&value(inv, "r").powi(2).minus(&p("X^2 + Y^2"))).is_zero());
    assert!(decide_zero(&value(inv, "φ").minus(&p("atan(Y/X)"))).is_zero());
    assert!(t.branches.iter().any(|b| b.contains("atan")));
    assert_forward_canonical(&t, &old, &new);
    snap("canonical_point_transformation", render(&t));
}

#[test]
fn exchange_transformation() {
    // F1 = q Q gives Q = p, P = −q (PHYSICS.md §4).
    let old = ps(&["q"]);
    let new = new_ps(&["Q"], &["P"]);
    let g = Generator::new(GeneratorKind::F1, p("q Q"), old.clone(), new.clone()).expect("valid");
    let t = g.transform(Some(&p("p_q^2/(2 m) + 1/2 m w^2 q^2"))).expect("transform");
    let fwd = t.forward.as_ref().expect("forward");
    assert_eq!(value(fwd, "Q"), p("p_q"));
    assert_eq!(value(fwd, "P"), p("-q"));
    // The oscillator swaps the roles of mass and stiffness.
    assert_eq!(t.hamiltonian.clone().expect("asked").expect("closed form"), p("Q^2/(2 m) + 1/2 m w^2 P^2"));
    assert_forward_canonical(&t, &old, &new);
    snap("canonical_exchange", render(&t));
}

#[test]
fn rotating_frame() {
    // X = x cos Ωt + y sin Ωt, Y = −x sin Ωt + y cos Ωt from F2; K = H + ∂F2/∂t = H − Ω L_Z.
    let old = ps(&["x", "y"]);
    let f2 = p("P_X (x cos(Ω t) + y sin(Ω t)) + P_Y (-x sin(Ω t) + y cos(Ω t))");
    let new = new_ps(&["X", "Y"], &["P_X", "P_Y"]);
    let g = Generator::new(GeneratorKind::F2, f2, old.clone(), new.clone()).expect("valid");
    let t = g.transform(Some(&p("(p_x^2 + p_y^2)/(2 m) + V(x^2 + y^2)"))).expect("transform");
    let k = t.hamiltonian.clone().expect("asked").expect("closed form");
    let hand = p("(P_X^2 + P_Y^2)/(2 m) + V(X^2 + Y^2) - Ω (X P_Y - Y P_X)");
    assert_eq!(decide_zero(&k.minus(&hand)), ZeroCheck::Proven, "K = {k}");
    assert_forward_canonical(&t, &old, &new);
    snap("canonical_rotating_frame", render(&t));
}

#[test]
fn identity_and_f3_f4_generators() {
    // F2 = q P is the identity; F3 = −p Q and F4 = p P follow the table's signs.
    let old = ps(&["q"]);
    let new = new_ps(&["Q"], &["P"]);
    let t = Generator::new(GeneratorKind::F2, p("q P"), old.clone(), new.clone())
        .expect("valid")
        .transform(None)
        .expect("ok");
    let fwd = t.forward.expect("forward");
    assert_eq!((value(&fwd, "Q"), value(&fwd, "P")), (p("q"), p("p_q")));
    // F3(p, Q) = −p Q: q = −∂F3/∂p = Q, P = −∂F3/∂Q = p: the identity.
    let t = Generator::new(GeneratorKind::F3, p("-p_q Q"), old.clone(), new.clone())
        .expect("valid")
        .transform(None)
        .expect("ok");
    let fwd = t.forward.expect("forward");
    assert_eq!((value(&fwd, "Q"), value(&fwd, "P")), (p("q"), p("p_q")));
    // F4(p, P) = p P: q = −∂F4/∂p = −P, Q = ∂F4/∂P = p: the exchange again.
    let t = Generator::new(GeneratorKind::F4, p("p_q P"), old, new).expect("valid").transform(None).expect("ok");
    let fwd = t.forward.expect("forward");
    assert_eq!((value(&fwd, "Q"), value(&fwd, "P")), (p("p_q"), p("-q")));
}

#[test]
fn singular_generator_is_refused() {
    // ∂²F1/∂q∂Q = 0: F1 = q² + Q² does not couple old and new variables.
    let g = Generator::new(GeneratorKind::F1, p("q^2 + Q^2"), ps(&["q"]), new_ps(&["Q"], &["P"])).expect("valid vars");
    let err = g.transform(None).expect_err("singular");
    assert!(matches!(err, TransformError::SingularGenerator { .. }));
    assert!(err.to_string().contains("not a valid generating function"), "{err}");
    // Two degrees of freedom, singular only as a matrix: F2 = (x + y)(P_X + P_Y).
    let g = Generator::new(
        GeneratorKind::F2,
        p("(x + y) (P_X + P_Y)"),
        ps(&["x", "y"]),
        new_ps(&["X", "Y"], &["P_X", "P_Y"]),
    )
    .expect("valid vars");
    assert!(matches!(g.transform(None), Err(TransformError::SingularGenerator { .. })));
    // A variable the type excludes.
    let e = Generator::new(GeneratorKind::F1, p("q Q + p_q"), ps(&["q"]), new_ps(&["Q"], &["P"])).expect_err("p in F1");
    assert!(matches!(e, TransformError::WrongVariable { .. }), "{e}");
}

#[test]
fn no_closed_form_leaves_the_relations_implicit() {
    // Q = ∂F2/∂P = q + q^5 P^4/… : a quintic in q has no closed-form inverse here.
    let g =
        Generator::new(GeneratorKind::F2, p("q P + q^5 + q^3 P^2"), ps(&["q"]), new_ps(&["Q"], &["P"])).expect("valid");
    let t = g.transform(Some(&p("p_q^2/2"))).expect("valid generator");
    let err = t.inverse.as_ref().expect_err("no closed form");
    assert!(err.to_string().contains("no closed form"), "{err}");
    // K stays available in the generator's own variables.
    assert!(t.k_mixed.is_some());
    assert!(matches!(t.hamiltonian, Some(Err(_))));
    // The numeric map instead: at (Q, P) = (1.7, 0.4), Newton solves Q = q + 2 q³ P for q, and
    // p = P + 5 q⁴ + 3 q² P² follows; both relations hold at the result.
    let (big_q, big_p) = (1.7, 0.4);
    let qp = g.numeric_inverse(&[big_q, big_p], &Default::default(), &[1.0]).expect("converges");
    let (q, pm) = (qp[0], qp[1]);
    assert!((q + 2.0 * q.powi(3) * big_p - big_q).abs() < 1e-14, "q = {q}");
    assert!((pm - (big_p + 5.0 * q.powi(4) + 3.0 * q * q * big_p * big_p)).abs() < 1e-13, "p = {pm}");
    assert!(matches!(
        g.numeric_inverse(&[big_q], &Default::default(), &[1.0]),
        Err(lagrangian::canonical::NumericMapError::Length { .. })
    ));
}

fn map(q: &str, pm: &str) -> ExplicitMap {
    ExplicitMap { old: ps(&["q"]), new: new_ps(&["Q"], &["P"]), q_new: vec![p(q)], p_new: vec![p(pm)] }
}

#[test]
fn explicit_map_canonicity() {
    // The issue's example: canonical, with {Q, P} = 1 proven; K for the oscillator follows.
    let r = check_map(&map("log(sin(p_q)/q)", "q cot(p_q)"), Some(&p("p_q^2/2 + q^2/2")));
    assert_eq!(r.canonicity, Canonicity::Proven);
    assert_eq!(r.brackets[0].value, Expr::one());
    let k = r.hamiltonian.clone().expect("asked").expect("canonical");
    // Hand route: q = sqrt(1 − P² e^{2Q}) e^{−Q}, p = acos(P e^Q).
    let hand = p("acos(P exp(Q))^2/2 + (1 - P^2 exp(2 Q)) exp(-2 Q)/2");
    assert!(decide_zero(&k.minus(&hand)).is_zero(), "K = {k}");
    // A scaling of p alone is not canonical: {Q, P} = 2.
    let r = check_map(&map("q", "2 p_q"), Some(&p("p_q^2/2")));
    assert!(matches!(r.canonicity, Canonicity::NotCanonical { .. }));
    assert!(r.canonicity.describe().starts_with("not canonical"), "{}", r.canonicity.describe());
    assert!(r.hamiltonian.expect("asked").is_err());
    // Canonical (for q > 0), but only a numeric check can tell: {Q, P} = 1 + log(q²) − 2 log q.
    let r = check_map(&map("q", "p_q (1 + log(q^2) - 2 log(q))"), None);
    assert!(matches!(r.canonicity, Canonicity::NumericOnly { .. }), "{:?}", r.canonicity);
    assert!(r.canonicity.describe().contains("not a proof"));
    let lines: Vec<String> = r
        .brackets
        .iter()
        .map(|b| {
            format!("{} = {} (expected {}; the difference is {})", b.name, b.value, b.expected, b.check.describe())
        })
        .collect();
    snap("canonical_explicit_numeric_only", format!("{}\n{}", r.canonicity.describe(), lines.join("\n")));
}
