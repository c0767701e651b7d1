//! Action J(E), period T(E) and ω(E) by quadrature (PHYSICS.md §4.5), against closed forms:
//! the oscillator (J = E/ω0), the gauge-transformed oscillator (a linear p term), the pendulum
//! (T = 4 K(k)/ω0, J = (8/π) m l² ω0 [E(k) − (1−k²) K(k)], k = sin(θ_max/2)) and the radial
//! Kepler problem (J_r = κ √(m/(2|E|)) − L, T = 2π κ √m / (2|E|)^{3/2}).

use std::f64::consts::PI;

use lagrangian::canonical::{action_frequency, elliptic_e, elliptic_k, ActionAngleError};
use lagrangian::eval::Env;
use lagrangian::{parse, Expr, Symbol};

fn p(s: &str) -> Expr {
    parse(s).expect("test input parses")
}

fn env(pairs: &[(&str, f64)]) -> Env {
    pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect()
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

#[test]
fn elliptic_integrals_by_agm() {
    // K(1/√2) = Γ(1/4)²/(4√π) (the lemniscatic case), with the published constant
    // Γ(1/4) = 3.6256099082219083119… (OEIS A068466), and Legendre's relation
    // E K' + E' K − K K' = π/2, which ties the two AGM routines together.
    let g14 = 3.625_609_908_221_908_f64;
    let k = 1.0 / 2f64.sqrt();
    assert!(rel(elliptic_k(k), g14 * g14 / (4.0 * PI.sqrt())) < 1e-15);
    for &k in &[0.1f64, 0.5, 0.9, 0.999] {
        let kp = (1.0 - k * k).sqrt();
        let legendre = elliptic_e(k) * elliptic_k(kp) + elliptic_e(kp) * elliptic_k(k) - elliptic_k(k) * elliptic_k(kp);
        assert!((legendre - PI / 2.0).abs() < 1e-14, "k = {k}: {legendre}");
    }
    assert!((elliptic_k(0.0) - PI / 2.0).abs() < 1e-16 && (elliptic_e(0.0) - PI / 2.0).abs() < 1e-16);
}

#[test]
fn oscillator_action_is_energy_over_frequency() {
    let h = p("p_q^2/(2 m) + 1/2 m w^2 q^2");
    let params = env(&[("m", 2.0), ("w", 1.5)]);
    for &e in &[0.01, 1.0, 37.0] {
        let r = action_frequency(&h, &Symbol::new("q"), &Symbol::new("p_q"), e, &params, 0.0).expect("libration");
        assert!(rel(r.action, e / 1.5) < 1e-13, "J = {}", r.action);
        assert!(rel(r.omega, 1.5) < 1e-13, "ω = {}", r.omega);
        // Turning points ±sqrt(2E/(m ω²)).
        let a = (2.0 * e / (2.0 * 1.5 * 1.5)).sqrt();
        assert!(rel(r.turning_points.1, a) < 1e-14 && rel(-r.turning_points.0, a) < 1e-14);
    }
    // The gauge-transformed oscillator (PHYSICS.md (3.19)) has the same J and ω: the
    // discriminant route handles the p-linear term.
    let hg = p("(p_q - m w q)^2/(2 m) + 1/2 m w^2 q^2");
    let r = action_frequency(&hg, &Symbol::new("q"), &Symbol::new("p_q"), 1.0, &params, 0.0).expect("libration");
    assert!(rel(r.action, 1.0 / 1.5) < 1e-13 && rel(r.omega, 1.5) < 1e-13, "{r:?}");
}

#[test]
fn pendulum_librations_match_elliptic_integrals() {
    let h = p("p_θ^2/(2 m l^2) + m g l (1 - cos(θ))");
    let (m, g, l) = (1.3, 9.81, 0.7);
    let params = env(&[("m", m), ("g", g), ("l", l)]);
    let w0 = (g / l).sqrt();
    for &theta_max in &[0.1f64, 1.0, 2.0, 3.0] {
        let e = m * g * l * (1.0 - theta_max.cos());
        let k = (theta_max / 2.0).sin();
        let r = action_frequency(&h, &Symbol::new("θ"), &Symbol::new("p_θ"), e, &params, 0.0).expect("libration");
        let t_exact = 4.0 * elliptic_k(k) / w0;
        let j_exact = 8.0 / PI * m * l * l * w0 * (elliptic_e(k) - (1.0 - k * k) * elliptic_k(k));
        assert!(rel(r.period, t_exact) < 1e-13, "θmax {theta_max}: T {} vs {t_exact}", r.period);
        assert!(rel(r.omega, 2.0 * PI / t_exact) < 1e-12);
        assert!(rel(r.action, j_exact) < 1e-13, "θmax {theta_max}: J {} vs {j_exact}", r.action);
        assert!(rel(r.turning_points.1, theta_max) < 1e-13);
    }
    // Above the separatrix the pendulum rotates: no turning points, and
    // J = (1/2π)∫₀^{2π} p dθ over one turn. With E = ε m g l and k² = 2/ε,
    // p = √(2 m² g l³ ε) √(1 − k² sin²(θ/2)), so J = (2/π) √(2 m² g l³ ε) E(k) and
    // T = ∫ m l² dθ/p = 4 K(k) √(l/(2 g ε)).
    for eps in [2.5f64, 3.0, 10.0] {
        let r = action_frequency(&h, &Symbol::new("θ"), &Symbol::new("p_θ"), eps * m * g * l, &params, 0.0)
            .expect("rotation");
        let k = (2.0 / eps).sqrt();
        let j_exact = 2.0 / PI * (2.0 * m * m * g * l.powi(3) * eps).sqrt() * elliptic_e(k);
        let t_exact = 4.0 * elliptic_k(k) * (l / (2.0 * g * eps)).sqrt();
        assert!(r.rotation);
        assert!(rel(r.action, j_exact) < 1e-13, "ε {eps}: J {} vs {j_exact}", r.action);
        assert!(rel(r.period, t_exact) < 1e-13, "ε {eps}: T {} vs {t_exact}", r.period);
    }
}

#[test]
fn kepler_radial_action() {
    let h = p("p_r^2/(2 m) + L^2/(2 m r^2) - κ/r");
    let (m, ll, kappa) = (1.0, 1.2, 2.0);
    let params = env(&[("m", m), ("L", ll), ("κ", kappa)]);
    let r0 = ll * ll / (m * kappa); // the circular orbit, inside every bound orbit
                                    // E_min = −m κ²/(2 L²) ≈ −1.389: every energy below is bound and above E_min.
    for &e in &[-1.3, -0.8, -0.1] {
        let r = action_frequency(&h, &Symbol::new("r"), &Symbol::new("p_r"), e, &params, r0).expect("bound orbit");
        let j_exact = kappa * (m / (2.0 * e.abs())).sqrt() - ll;
        let t_exact = 2.0 * PI * kappa * m.sqrt() / (2.0 * e.abs()).powf(1.5);
        assert!(rel(r.action, j_exact) < 1e-13, "E {e}: J {} vs {j_exact}", r.action);
        assert!(rel(r.period, t_exact) < 1e-13, "E {e}: T {} vs {t_exact}", r.period);
    }
}

#[test]
fn bad_hamiltonians_and_start_points_are_refused() {
    let q = Symbol::new("q");
    let pm = Symbol::new("p_q");
    let e = env(&[]);
    let cubic = action_frequency(&p("p_q^3 + q^2"), &q, &pm, 1.0, &e, 0.0).expect_err("cubic in p");
    assert!(matches!(cubic, ActionAngleError::NotQuadratic { .. }), "{cubic}");
    let outside = action_frequency(&p("p_q^2/2 + q^2/2"), &q, &pm, 1.0, &e, 5.0).expect_err("outside");
    assert!(matches!(outside, ActionAngleError::NotInside { .. }), "{outside}");
    let free = action_frequency(&p("p_q^2/2"), &q, &pm, 1.0, &e, 0.0).expect_err("unbounded");
    assert!(matches!(free, ActionAngleError::NoTurningPoint { .. }), "{free}");
    let unbound = action_frequency(&p("p_q^2/(2 m) + q^2"), &q, &pm, 1.0, &e, 0.0).expect_err("no m");
    assert!(matches!(unbound, ActionAngleError::Eval(_)), "{unbound}");
}
