//! Discrete mechanics: the discrete Euler–Lagrange equations and Legendre
//! maps of the pendulum for the midpoint and trapezoid rules (snapshotted and compared with
//! hand derivations), and the variational integrator's properties measured: order 2 against a
//! DOP853 reference, energy error bounded over 10⁵ steps, the discrete Noether momentum of a
//! central force conserved to rounding, the map canonical (numerically, by finite
//! differences), and a step too large for Newton refused with a typed error. The `gauss2`
//! (Galerkin, 2-point Gauss–Legendre) rule: its `L̃` against a hand-coded quadrature, its
//! order 4 measured, and the same conservation and canonicity checks.

use crate::support::notes as notes_support;

use lagrangian::algebra::expand;
use lagrangian::compile::{VariationalError, VariationalMap};
use lagrangian::eval::eval;
use lagrangian::integrate::{Dop853, Integrate};
use lagrangian::mechanics::{Rule, System};
use lagrangian::{parse, Expr};
use notes_support::{run, snapshot};
use std::collections::HashMap;

const PENDULUM: &str = "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))";
const KEPLER: &str = "1/2 (x'^2 + y'^2) + 1/sqrt(x^2 + y^2)";

fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in\n{out}"))
}

fn same(printed: &str, hand: &str) {
    let d = expand(&parse(printed).unwrap().minus(&parse(hand).unwrap())).unwrap();
    assert!(d.is_zero(), "{printed} differs from {hand} by {d}");
}

#[test]
fn pendulum_discrete_euler_lagrange_for_midpoint_and_trapezoid() {
    // By hand (Marsden & West 2001, §1.2): midpoint
    //   L_d = h [½ m l² ((θ_1 − θ_0)/h)² − m g l (1 − cos((θ_0 + θ_1)/2))],
    //   DEL: m l² (2 θ_1 − θ_0 − θ_2)/h − (h m g l/2) (sin((θ_0+θ_1)/2) + sin((θ_1+θ_2)/2)) = 0;
    // trapezoid: Störmer–Verlet, m l² (θ_0 − 2 θ_1 + θ_2)/h + h m g l sin θ_1 = 0 (times −1).
    let mut snap = String::from("# (2.27) pendulum, discrete Euler–Lagrange equations (§4.7.2; Marsden & West 2001)\n");
    for (rule, del) in [
        ("midpoint", "m l^2 (2 θ_1 - θ_0 - θ_2)/h - h m g l (sin((θ_0 + θ_1)/2) + sin((θ_1 + θ_2)/2))/2"),
        ("trapezoid", "m l^2 (2 θ_1 - θ_0 - θ_2)/h - h m g l sin(θ_1)"),
    ] {
        let (code, out, err) = run(&["discretize", PENDULUM, "--coords", "θ", "--rule", rule, "--step", "h"]);
        assert_eq!(code, 0, "{err}");
        same(line(&out, "DEL_θ: ").trim_end_matches(" = 0"), del);
        snap += &format!("$ lagrangian discretize \"{PENDULUM}\" --coords θ --rule {rule}\n{out}");
    }
    // The midpoint Legendre maps.
    let (_, out, _) = run(&["discretize", PENDULUM, "--coords", "θ", "--rule", "midpoint"]);
    same(line(&out, "p_θ_0 = "), "m l^2 (θ_1 - θ_0)/h + h m g l sin((θ_0 + θ_1)/2)/2");
    same(line(&out, "p_θ_1 = "), "m l^2 (θ_1 - θ_0)/h - h m g l sin((θ_0 + θ_1)/2)/2");
    snapshot("notes_discrete_pendulum", &snap);
}

fn pendulum_map(rule: Rule, h: f64) -> VariationalMap {
    let s = System::from_lagrangian(PENDULUM, &["θ"]).unwrap();
    let d = s.discretize(rule, &Expr::var("h")).unwrap();
    VariationalMap::new(&d, &[("m", 1.0), ("l", 1.0), ("g", 1.0), ("h", h)]).unwrap()
}

#[test]
fn order_two_for_midpoint_and_trapezoid() {
    // Reference: W q'' = F of the same L by DOP853 at tolerance 1e-13.
    let sys =
        System::from_lagrangian(PENDULUM, &["θ"]).unwrap().with_params(&[("m", 1.0), ("l", 1.0), ("g", 1.0)]).unwrap();
    let rhs = sys.compile_rhs().unwrap();
    let t1 = 2.0;
    let exact = Dop853::new(1e-13, 1e-13).integrate(&rhs, 0.0..t1, &[1.2, 0.0]).unwrap().last_state().to_vec();
    for rule in [Rule::Midpoint, Rule::Trapezoid] {
        let errors: Vec<f64> = [0.04, 0.02, 0.01]
            .iter()
            .map(|&h| {
                let m = pendulum_map(rule, h);
                let steps = (t1 / h).round() as usize;
                let path = m.integrate(0.0, &[1.2], &[0.0], steps, steps).unwrap();
                let last = path.last().unwrap();
                // p_k = m l² θ' at the nodes up to O(h²) as well.
                (last.q[0] - exact[0]).abs().max((last.p[0] - exact[1]).abs())
            })
            .collect();
        for w in errors.windows(2) {
            let order = (w[0] / w[1]).log2();
            eprintln!("{rule:?}: errors {errors:?}, observed order {order:.3}");
            assert!((order - 2.0).abs() < 0.15, "{rule:?}: observed order {order} from {errors:?}");
        }
    }
}

#[test]
fn energy_error_stays_bounded_over_1e5_steps() {
    let h = 0.05;
    for rule in [Rule::Midpoint, Rule::Trapezoid, Rule::Gauss2] {
        let m = pendulum_map(rule, h);
        let path = m.integrate(0.0, &[2.0], &[0.0], 100_000, 1).unwrap();
        let energy = |q: f64, p: f64| p * p / 2.0 + (1.0 - q.cos());
        let e0 = energy(2.0, 0.0);
        let err: Vec<f64> = path.iter().map(|pt| (energy(pt.q[0], pt.p[0]) - e0).abs()).collect();
        let first = err[..10_000].iter().cloned().fold(0.0, f64::max);
        let last = err[90_000..].iter().cloned().fold(0.0, f64::max);
        eprintln!("{rule:?}: max |ΔE| first tenth {first:e}, last tenth {last:e}");
        // Bounded: O(h²) and no secular growth between the first and the last tenth.
        assert!(first < 0.01 && last < 1.5 * first, "{rule:?}: max |ΔE| first tenth {first:e}, last tenth {last:e}");
    }
}

#[test]
fn angular_momentum_of_a_central_force_is_conserved_to_rounding() {
    let s = System::from_lagrangian(KEPLER, &["x", "y"]).unwrap();
    for rule in [Rule::Midpoint, Rule::Trapezoid, Rule::Gauss2] {
        let d = s.discretize(rule, &Expr::var("h")).unwrap();
        let m = VariationalMap::new(&d, &[("h", 0.01)]).unwrap();
        // e ≈ 0.5 orbit: r = 1 at pericentre with speed sqrt(1.5).
        let (q0, p0) = ([1.0, 0.0], [0.0, 1.5f64.sqrt()]);
        // 2·10⁴ steps, 11 orbits.
        let path = m.integrate(0.0, &q0, &p0, 20_000, 1).unwrap();
        let lz = |q: &[f64], p: &[f64]| q[0] * p[1] - q[1] * p[0];
        let l0 = lz(&q0, &p0);
        let worst = path.iter().map(|pt| (lz(&pt.q, &pt.p) - l0).abs() / l0).fold(0.0, f64::max);
        eprintln!("{rule:?}: max relative drift of x p_y − y p_x over 2·10⁴ steps: {worst:e}");
        assert!(worst <= 2e-13, "{rule:?}: relative drift of x p_y − y p_x {worst:e}");
    }
}

#[test]
fn the_map_is_canonical_numerically() {
    // Numerical check (finite differences, not a proof): the Jacobian M of
    // (q_k, p_k) → (q_{k+1}, p_{k+1}) satisfies Mᵀ J M = J (4.6.2).
    let s = System::from_lagrangian(KEPLER, &["x", "y"]).unwrap();
    for rule in [Rule::Midpoint, Rule::Trapezoid, Rule::Gauss2] {
        let d = s.discretize(rule, &Expr::var("h")).unwrap();
        let m = VariationalMap::new(&d, &[("h", 0.1)]).unwrap();
        let map = |z: &[f64; 4]| -> [f64; 4] {
            let (mut dq, mut p1) = ([0.0; 2], [0.0; 2]);
            m.step(0.0, &z[..2], &z[2..], &mut dq, &mut p1).unwrap();
            [z[0] + dq[0], z[1] + dq[1], p1[0], p1[1]]
        };
        let z0 = [0.9, 0.3, -0.2, 1.1];
        let eps = 1e-6;
        let mut jac = [[0.0; 4]; 4];
        for j in 0..4 {
            let (mut up, mut dn) = (z0, z0);
            up[j] += eps;
            dn[j] -= eps;
            let (a, b) = (map(&up), map(&dn));
            for i in 0..4 {
                jac[i][j] = (a[i] - b[i]) / (2.0 * eps);
            }
        }
        let jmat = [[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0]];
        for a in 0..4 {
            for b in 0..4 {
                let mut s = 0.0;
                for i in 0..4 {
                    for j in 0..4 {
                        s += jac[i][a] * jmat[i][j] * jac[j][b];
                    }
                }
                assert!((s - jmat[a][b]).abs() < 2e-9, "{rule:?}: (MᵀJM)[{a}][{b}] = {s}");
            }
        }
    }
}

#[test]
fn newton_that_does_not_converge_is_a_typed_error() {
    // L = cos(x'): p_k = −D₁L_d = −sin((x_1 − x_0)/h) lies in [−1, 1], so p_k = 3 has no
    // q_{k+1} at all and Newton cannot converge.
    let s = System::from_lagrangian("cos(x')", &["x"]).unwrap();
    let d = s.discretize(Rule::Midpoint, &Expr::var("h")).unwrap();
    let m = VariationalMap::new(&d, &[("h", 0.1)]).unwrap();
    let e = m.integrate(0.0, &[0.0], &[3.0], 5, 1).unwrap_err();
    assert!(matches!(e, VariationalError::Newton { .. } | VariationalError::Singular { .. }), "{e}");
    assert!(e.to_string().contains("t = "), "{e}");
    // Bad rules and steps from the CLI: exit 2, nothing printed.
    let (code, out, err) = run(&["discretize", PENDULUM, "--coords", "θ", "--rule", "simpson"]);
    assert_eq!((code, out.as_str()), (2, ""));
    assert!(err.contains("simpson"), "{err}");
    let (code, _, err) = run(&["discretize", PENDULUM, "--coords", "θ", "--step", "0"]);
    assert_eq!(code, 2);
    assert!(err.contains("step"), "{err}");
}

#[test]
fn gauss2_discrete_lagrangian_is_the_two_point_gauss_rule_on_a_quadratic() {
    // Second route, by hand in f64: the quadratic through θ_0 (τ = 0), θ_m (τ = ½), θ_1
    // (τ = 1) in the Lagrange basis ℓ_0 = 2(τ − ½)(τ − 1), ℓ_m = 4τ(1 − τ), ℓ_1 = 2τ(τ − ½),
    // and ∫_0^h L dt ≈ h/2 [L(τ_−) + L(τ_+)] at the Gauss–Legendre nodes τ_± = ½ ± 1/(2√3)
    // (Abramowitz & Stegun 25.4.29).
    let (code, out, err) = run(&["discretize", PENDULUM, "--coords", "θ", "--rule", "gauss2"]);
    assert_eq!(code, 0, "{err}");
    let ld = parse(line(&out, "L_d = ")).unwrap();
    let (m, l, g) = (1.3, 0.7, 9.81);
    let lag = |q: f64, v: f64| 0.5 * m * l * l * v * v - m * g * l * (1.0 - q.cos());
    for (a, mid, b, h) in [(0.1, 0.4, 0.9, 0.3), (-1.2, -0.5, 0.2, 0.05), (2.0, 2.1, 1.7, 0.8)] {
        let mut sum = 0.0;
        for tau in [0.5 - 0.5 / 3f64.sqrt(), 0.5 + 0.5 / 3f64.sqrt()] {
            let q = a * 2.0 * (tau - 0.5) * (tau - 1.0) + mid * 4.0 * tau * (1.0 - tau) + b * 2.0 * tau * (tau - 0.5);
            let dq = (a * (4.0 * tau - 3.0) + mid * (4.0 - 8.0 * tau) + b * (4.0 * tau - 1.0)) / h;
            sum += 0.5 * h * lag(q, dq);
        }
        let env: HashMap<String, f64> = [("θ_0", a), ("θ_m", mid), ("θ_1", b), ("h", h), ("m", m), ("l", l), ("g", g)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
        let printed = eval(&ld, &env).unwrap();
        assert!((printed - sum).abs() <= 1e-12 * sum.abs().max(1.0), "L_d = {printed}, by hand {sum}");
    }
    // The free particle: stationarity in θ_m puts it at the midpoint, and L_d = (θ_1 − θ_0)²/(2h)
    // (the 2-point rule is exact for the quadratic q'²).
    let (_, out, _) = run(&["discretize", "1/2 x'^2", "--coords", "x", "--rule", "gauss2"]);
    same(line(&out, "∂L_d/∂x_m: ").trim_end_matches(" = 0"), "8 (2 x_m - x_0 - x_1)/(3 h)");
    let (code, _, err) = run(&["discretize", PENDULUM, "--coords", "θ", "--rule", "gauss3"]);
    assert_eq!(code, 2);
    assert!(err.contains("gauss2"), "{err}");
}

#[test]
fn order_four_for_gauss2() {
    let sys =
        System::from_lagrangian(PENDULUM, &["θ"]).unwrap().with_params(&[("m", 1.0), ("l", 1.0), ("g", 1.0)]).unwrap();
    let rhs = sys.compile_rhs().unwrap();
    let t1 = 2.0;
    let exact = Dop853::new(1e-14, 1e-14).integrate(&rhs, 0.0..t1, &[1.2, 0.0]).unwrap().last_state().to_vec();
    let errors: Vec<f64> = [0.2, 0.1, 0.05]
        .iter()
        .map(|&h| {
            let m = pendulum_map(Rule::Gauss2, h);
            let steps = (t1 / h).round() as usize;
            let path = m.integrate(0.0, &[1.2], &[0.0], steps, steps).unwrap();
            let last = path.last().unwrap();
            (last.q[0] - exact[0]).abs().max((last.p[0] - exact[1]).abs())
        })
        .collect();
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        eprintln!("Gauss2: errors {errors:?}, observed order {order:.3}");
        assert!((order - 4.0).abs() < 0.2, "Gauss2: observed order {order} from {errors:?}");
    }
}
