//! Properties that tie the routes through the mechanics module together, checked numerically
//! at random states: Legendre and back, Hamilton against Euler–Lagrange, dH/dt = ∂H/∂t,
//! gauge invariance, point transformations, constraints, forces, and `tidy` soundness.

use crate::support::mechanics as mechanics_support;

use std::collections::BTreeMap;

use lagrangian::diff::Differentiator;
use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::{tidy, System};
use mechanics_support::{assert_same, expr, random_env, system, value, Rng};
use nalgebra::{DMatrix, DVector};

/// (Lagrangian, coordinates, positive, functions, overrides) of the systems the properties
/// run over: natural ones, a gauge term, magnetic and rotating (linear velocity terms), an
/// explicitly time-dependent one and the relativistic particle.
type Spec = (
    &'static str,
    &'static [&'static str],
    &'static [&'static str],
    &'static [&'static str],
    &'static [(&'static str, f64)],
);

const SYSTEMS: &[Spec] = &[
    ("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", &["θ"], &["m", "l", "g"], &[], &[]),
    ("1/2 m (r'^2 + r^2 φ'^2) - V(r)", &["r", "φ"], &["m"], &["V"], &[]),
    ("1/2 m (u^2 + (a - u t)^2 φ'^2)", &["φ"], &["m"], &[], &[]),
    ("1/2 m (x'^2 + 2 ω0 x x' - ω0^2 x^2)", &["x"], &["m"], &[], &[]),
    ("1/2 m (x'^2 + y'^2 + z'^2) - e φ(x, y, z, t) + e B/2 (-y x' + x y')", &["x", "y", "z"], &["m"], &["φ"], &[]),
    ("1/2 m ((x' - Ω y)^2 + (y' + Ω x)^2 + z'^2) - V(x, y, z)", &["x", "y", "z"], &["m"], &["V"], &[]),
    (
        "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)",
        &["θ1", "θ2"],
        &["m1", "m2", "l1", "l2", "g"],
        &[],
        &[],
    ),
    ("1/2 m l^2 (θ'^2 + sin(θ)^2 φ'^2) + m g l cos(θ)", &["θ", "φ"], &["m", "l", "g"], &[], &[]),
    ("1/2 m (r'^2 + r^2 θ'^2 + r^2 sin(θ)^2 φ'^2) + k/r", &["r", "θ", "φ"], &["m", "k"], &[], &[]),
    ("-m c^2 sqrt(1 - (x'^2 + y'^2)/c^2)", &["x", "y"], &["m", "c"], &[], &[("c", 3.0)]),
    // A triple pendulum in compact form: the 3 × 3 adjugate path.
    (
        "1/2 (m1 + m2 + m3) θ1'^2 + 1/2 (m2 + m3) θ2'^2 + 1/2 m3 θ3'^2 + (m2 + m3) θ1' θ2' cos(θ1 - θ2) + m3 θ1' θ3' cos(θ1 - θ3) + m3 θ2' θ3' cos(θ2 - θ3) + g ((m1 + m2 + m3) cos(θ1) + (m2 + m3) cos(θ2) + m3 cos(θ3))",
        &["θ1", "θ2", "θ3"],
        &["m1", "m2", "m3", "g"],
        &[],
        &[],
    ),
];

fn build(spec: &Spec) -> System {
    system(spec.0, spec.1, spec.2, spec.3)
}

#[test]
fn legendre_then_inverse_gives_back_the_lagrangian() {
    for spec in SYSTEMS {
        let s = build(spec);
        let hs = s.legendre().expect("Legendre");
        let back = hs.inverse_legendre().expect("inverse Legendre");
        let l2 = back.lagrangian().expect("a Lagrangian");
        assert_same(l2, s.lagrangian().unwrap(), &format!("L → H → L for {}", spec.0), spec.4);
    }
}

/// What the numeric properties need of one system, derived once.
struct Derived {
    s: System,
    h: Expr,
    p: Vec<Expr>,
    w: Vec<Vec<Expr>>,
    f: Vec<Expr>,
}

fn derive(spec: &Spec) -> Derived {
    let s = build(spec);
    let h = s.hamiltonian().unwrap();
    let p = s.canonical_momenta().unwrap();
    let (w, f) = s.mass_matrix_split().unwrap();
    Derived { s, h, p, w, f }
}

/// Random state `(q, q', t, parameters)` plus the momenta `p = ∂L/∂q'` at it.
fn state(d: &Derived, rng: &mut Rng, overrides: &[(&str, f64)]) -> BTreeMap<String, f64> {
    let l = d.s.lagrangian().unwrap();
    let mut env = random_env(&[l, &d.h], rng, overrides);
    for v in d.s.velocities() {
        env.entry(v.to_string()).or_insert_with(|| rng.range(0.5, 1.5));
    }
    // Keep relativistic speeds below c.
    if overrides.iter().any(|(k, _)| *k == "c") {
        for v in d.s.velocities() {
            env.insert(v.to_string(), rng.range(-1.0, 1.0));
        }
    }
    for (m, e) in d.s.momenta().iter().zip(&d.p) {
        let pv = value(e, &env);
        env.insert(m.to_string(), pv);
    }
    env
}

/// `q''` from `W q'' = F`, solved numerically.
fn el_accelerations(d: &Derived, env: &BTreeMap<String, f64>) -> DVector<f64> {
    let n = d.w.len();
    let wm = DMatrix::from_fn(n, n, |i, j| value(&d.w[i][j], env));
    let fv = DVector::from_fn(n, |i, _| value(&d.f[i], env));
    wm.lu().solve(&fv).expect("regular W")
}

#[test]
fn hamilton_and_euler_lagrange_give_the_same_motion() {
    let t = Symbol::new("t");
    for spec in SYSTEMS {
        let dv = derive(spec);
        let s = &dv.s;
        let hs = s.hamilton_equations().expect("Hamilton");
        let n = s.coordinates().len();
        let mut d = Differentiator::new();
        // d/dt ∂H/∂p along Hamilton's flow, symbolically once.
        let qdd: Vec<Expr> = (0..n)
            .map(|i| {
                let mut terms = vec![d.diff(&hs.qdot[i], &t)];
                for j in 0..n {
                    terms.push(d.diff(&hs.qdot[i], &s.coordinates()[j]).times(&hs.qdot[j]));
                    terms.push(d.diff(&hs.qdot[i], &s.momenta()[j]).times(&hs.pdot[j]));
                }
                Expr::add(terms)
            })
            .collect();
        let mut rng = Rng::new(7);
        for _ in 0..3 {
            let env = state(&dv, &mut rng, spec.4);
            // First half: q' = ∂H/∂p reproduces the velocities the momenta came from.
            for i in 0..n {
                let qd = value(&hs.qdot[i], &env);
                let v = env[&s.velocities()[i].to_string()];
                assert!((qd - v).abs() < 1e-12 * (1.0 + v.abs()), "{}: q' = ∂H/∂p ({qd} vs {v})", spec.0);
            }
            // Second half: q'' = d/dt ∂H/∂p along Hamilton's flow equals W⁻¹ F.
            let acc = el_accelerations(&dv, &env);
            for i in 0..n {
                let total = value(&qdd[i], &env);
                assert!(
                    (total - acc[i]).abs() < 1e-8 * (1.0 + acc[i].abs()),
                    "{}: q''_{i} Hamilton {total} vs Euler–Lagrange {}",
                    spec.0,
                    acc[i]
                );
            }
        }
    }
}

#[test]
fn closed_form_accelerations_match_the_numeric_solve() {
    for spec in SYSTEMS.iter().filter(|s| s.1.len() <= 3 && !s.0.contains("sqrt")) {
        let dv = derive(spec);
        let acc = dv.s.accelerations().expect("closed form");
        let mut rng = Rng::new(11);
        let env = state(&dv, &mut rng, spec.4);
        let num = el_accelerations(&dv, &env);
        for i in 0..acc.len() {
            let a = value(&acc[i], &env);
            assert!((a - num[i]).abs() < 1e-12 * (1.0 + a.abs()), "{}: {a} vs {}", spec.0, num[i]);
        }
    }
}

#[test]
fn energy_changes_only_through_explicit_time_dependence() {
    // (3.30): dH/dt = Σ ∂H/∂q q' + ∂H/∂p p' + ∂H/∂t = ∂H/∂t along Hamilton's flow.
    let t = Symbol::new("t");
    let driven = System::from_hamiltonian("p_x^2/(2 m) + 1/2 k x^2 - F0 x cos(ω t)", &["x"]).unwrap();
    let mut systems: Vec<System> = SYSTEMS.iter().map(build).collect();
    systems.push(driven);
    for s in systems {
        let eq = s.hamilton_equations().unwrap();
        let h = eq.hamiltonian.clone();
        let mut d = Differentiator::new();
        let mut terms = vec![d.diff(&h, &t)];
        for i in 0..s.coordinates().len() {
            terms.push(d.diff(&h, &s.coordinates()[i]).times(&eq.qdot[i]));
            terms.push(d.diff(&h, &s.momenta()[i]).times(&eq.pdot[i]));
        }
        let dh_dt = Expr::add(terms);
        let overrides: &[(&str, f64)] = if h.to_string().contains("c^2") { &[("c", 3.0)] } else { &[] };
        assert_same(&dh_dt, &d.diff(&h, &t), &format!("dH/dt for {h}"), overrides);
    }
}

#[test]
fn a_gauge_term_leaves_the_equations_unchanged() {
    // (2.6.2): L and L + d/dt Λ(q, t) have the same Euler–Lagrange expressions, W and F.
    let cases: [(&Spec, &str); 3] =
        [(&SYSTEMS[6], "θ1^2 t + sin(θ1 θ2)"), (&SYSTEMS[1], "r t^2 cos(φ)"), (&SYSTEMS[3], "-1/2 m ω0 x^2")];
    for (spec, lambda) in cases {
        let s = build(spec);
        let g = s.with_gauge(lambda).expect("gauge term");
        assert_ne!(g.lagrangian(), s.lagrangian());
        let (e1, e2) = (s.euler_lagrange().unwrap(), g.euler_lagrange().unwrap());
        let ((w1, f1), (w2, f2)) = (s.mass_matrix_split().unwrap(), g.mass_matrix_split().unwrap());
        for i in 0..e1.len() {
            assert_same(&e1[i], &e2[i], &format!("E with Λ = {lambda}"), spec.4);
            assert_same(&f1[i], &f2[i], &format!("F with Λ = {lambda}"), spec.4);
            for j in 0..e1.len() {
                assert_same(&w1[i][j], &w2[i][j], &format!("W with Λ = {lambda}"), spec.4);
            }
        }
    }
    // (2.75) is (2.61) plus d/dt(½ m ω0 x²): the gauge term turns one into the other.
    let plain = system("1/2 m (x'^2 - ω0^2 x^2)", &["x"], &["m"], &[]);
    let gauged = plain.with_gauge("1/2 m ω0 x^2").unwrap();
    let l275 = expr("1/2 m (x'^2 + 2 ω0 x x' - ω0^2 x^2)", &["m"], &[]);
    assert_same(gauged.lagrangian().unwrap(), &l275, "(2.61) + gauge = (2.75)", &[]);
}

#[test]
fn point_transformations() {
    // (2.6.1) Cartesian → polar: ½ m (x'² + y'²) − V(x² + y²) becomes ½ m (r'² + r² φ'²) − V(r²).
    let cart = system("1/2 m (x'^2 + y'^2) - V(x^2 + y^2)", &["x", "y"], &["m"], &["V"]);
    let polar = cart.transform(&[("x", "r cos(φ)"), ("y", "r sin(φ)")], &["r", "φ"]).unwrap();
    assert_eq!(polar.lagrangian().unwrap(), &expr("1/2 m (r'^2 + r^2 φ'^2) - V(r^2)", &["m"], &["V"]));
    // A time-dependent map, into a frame rotating at Ω: the rotating-planet Lagrangian (2.8.1).
    let free = system("1/2 m (x'^2 + y'^2)", &["x", "y"], &["m"], &[]);
    let rot =
        free.transform(&[("x", "X cos(Ω t) - Y sin(Ω t)"), ("y", "X sin(Ω t) + Y cos(Ω t)")], &["X", "Y"]).unwrap();
    let hand = expr("1/2 m ((X' - Ω Y)^2 + (Y' + Ω X)^2)", &["m"], &[]);
    assert_same(rot.lagrangian().unwrap(), &hand, "rotating frame", &[]);
}

#[test]
fn holonomic_constraint_reproduces_the_pendulum() {
    // (1.25–1.29): a particle on x² + y² = l² under gravity (y downward) moves like the pendulum
    // (2.28): x = l sin θ gives x'' = l cos θ θ'' − l sin θ θ'² with θ'' = −(g/l) sin θ.
    let s = system("1/2 m (x'^2 + y'^2) + m g y", &["x", "y"], &["m", "g", "l"], &[])
        .with_constraint("x^2 + y^2 = l^2")
        .unwrap();
    let c = s.constrained_equations().unwrap();
    assert_eq!(c.multipliers, vec![Symbol::new("λ1")]);
    assert_eq!(c.phi[0], vec![expr("2 x", &[], &[]), expr("2 y", &[], &[])]);
    assert_same(&c.c[0], &expr("-2 (x'^2 + y'^2)", &[], &[]), "c = −(d²f/dt² − Φ q'')", &[]);
    let (m, g, l, th, w): (f64, f64, f64, f64, f64) = (1.3, 9.81, 0.7, 0.4, 1.1);
    let env: BTreeMap<String, f64> = [
        ("m", m),
        ("g", g),
        ("l", l),
        ("x", l * th.sin()),
        ("y", l * th.cos()),
        ("x'", l * th.cos() * w),
        ("y'", -l * th.sin() * w),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    // [W Φᵀ; Φ 0] [q''; −λ] = [F; c]
    let mut a = DMatrix::zeros(3, 3);
    let mut b = DVector::zeros(3);
    for i in 0..2 {
        for j in 0..2 {
            a[(i, j)] = value(&c.w[i][j], &env);
        }
        a[(i, 2)] = value(&c.phi[0][i], &env);
        a[(2, i)] = value(&c.phi[0][i], &env);
        b[i] = value(&c.f[i], &env);
    }
    b[2] = value(&c.c[0], &env);
    let sol = a.lu().solve(&b).unwrap();
    let thdd = -(g / l) * th.sin();
    let xdd = l * th.cos() * thdd - l * th.sin() * w * w;
    assert!((sol[0] - xdd).abs() < 1e-9, "x'' = {} vs pendulum {xdd}", sol[0]);
    // The printed equations carry the multiplier: E − λ ∂f/∂q.
    let eqs = s.equations().unwrap();
    assert_same(&eqs[0], &expr("m x'' - 2 λ1 x", &["m"], &[]), "constrained E_x", &[]);
}

#[test]
fn forces_and_dissipation_enter_f() {
    // (2.12) E = Q and E + ∂R/∂q' = 0: a damped, driven oscillator.
    let s = system("1/2 m x'^2 - 1/2 k x^2", &["x"], &["m"], &[])
        .with_force("x", "F0 cos(ω t)")
        .unwrap()
        .with_rayleigh("1/2 b x'^2")
        .unwrap();
    let (_, f) = s.mass_matrix_split().unwrap();
    assert_same(&f[0], &expr("-k x - b x' + F0 cos(ω t)", &[], &[]), "F", &[]);
    let eq = s.equations().unwrap();
    assert_same(&eq[0], &expr("m x'' + k x + b x' - F0 cos(ω t)", &["m"], &[]), "equation", &[]);
    // Dissipation and driving break energy conservation.
    assert!(s.conserved().is_empty());
}

#[test]
fn tidy_preserves_values() {
    let cases = [
        "(a + b)^3 - a^3",
        "cos(x) cos(y) - sin(x) sin(y) + 2 sin(x)^2 + 2 cos(x)^2",
        "m1 l^2 c + m2 l^2 c + m1 l^2 s + m2 l^2 s",
        "sin(x) cos(y) + cos(x) sin(y) - k + k cos(z)^2",
        "x/(a - t u)^2 + y/(a - t u)^2 + (p - m w x)^2",
        "sqrt(1 - v^2/c^2) (1 + v^2) + 1/sqrt(1 - v^2/c^2)",
    ];
    for c in cases {
        let e = lagrangian::parse(c).unwrap();
        let t = tidy(&e);
        assert!(t.op_count() <= e.op_count());
        assert_same(&t, &e, &format!("tidy({c})"), &[("c", 3.0)]);
    }
}

#[test]
fn phase_space_lagrangian_gives_hamiltons_equations() {
    // (3.31–3.32): the Euler–Lagrange equations of p·q' − H in (q, p) are Hamilton's equations.
    let s = build(&SYSTEMS[6]).legendre().unwrap();
    let lph = s.phase_space_lagrangian().unwrap();
    let eq = s.hamilton_equations().unwrap();
    let mut d = Differentiator::new();
    for i in 0..2 {
        let q = &s.coordinates()[i];
        let p = &s.momenta()[i];
        // variation in q: d/dt ∂L/∂q' − ∂L/∂q = p' + ∂H/∂q; variation in p: −∂L/∂p = q' − ∂H/∂p.
        let by_p = d.diff(&lph, p).neg();
        let hand = eq.qdot[i].minus(&Expr::sym(s.velocities()[i].clone()));
        assert_same(&by_p, &hand, "variation in p", &[]);
        let by_q = d.diff(&lph, q);
        assert_same(&by_q, &eq.pdot[i], "variation in q: ∂L_ph/∂q = −∂H/∂q", &[]);
    }
}
