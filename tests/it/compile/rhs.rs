//! Compiled right-hand sides against hand-written ones, finite differences and failure cases.

use crate::support::compile as compile_common;

use compile_common::{benchmark_systems, kepler_polar, mass_matrix_split, Rng};
use lagrangian::compile::{
    ensemble, ensemble_with_threads, split_separable, CompileError, HamiltonianRhs, ImplicitLegendreRhs, LagrangianRhs,
    RhsError, SeparableHamiltonian,
};
use lagrangian::integrate::{Jacobian, Rhs, Separable};
use lagrangian::parse;

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
}

#[test]
fn lagrangian_accelerations_match_hand_written_systems() {
    let mut systems = benchmark_systems();
    systems.push(kepler_polar());
    let mut rng = Rng(42);
    for sys in &systems {
        let rhs = sys.compile();
        let d = sys.dim();
        assert_eq!(rhs.dim(), d);
        for _ in 0..50 {
            let mut y: Vec<f64> = (0..d).map(|_| rng.uniform(-2.0, 2.0)).collect();
            if sys.name.starts_with("Kepler") {
                y[0] = rng.uniform(0.5, 2.0); // keep r (or x) away from the singularity
            }
            let (mut got, mut want) = (vec![0.0; d], vec![0.0; d]);
            rhs.try_eval(0.0, &y, &mut got).unwrap();
            (sys.hand)(0.0, &y, &mut want);
            assert!(close(&got, &want, 1e-11), "{}: {got:?} vs {want:?}", sys.name);
        }
    }
}

#[test]
fn batch_rhs_equals_scalar_rhs() {
    let sys = compile_common::double_pendulum();
    let rhs = sys.compile();
    let points = 21;
    let mut rng = Rng(5);
    let y: Vec<f64> = (0..4 * points).map(|_| rng.uniform(-2.0, 2.0)).collect();
    let mut dy = vec![0.0; 4 * points];
    rhs.eval_batch(0.0, &y, &mut dy, points).unwrap();
    for k in 0..points {
        let yk: Vec<f64> = (0..4).map(|i| y[i * points + k]).collect();
        let mut d = [0.0; 4];
        rhs.try_eval(0.0, &yk, &mut d).unwrap();
        for i in 0..4 {
            assert_eq!(dy[i * points + k].to_bits(), d[i].to_bits());
        }
    }
}

/// Central differences of `f` at `y`, column `j` of the Jacobian.
fn fd_jacobian(f: &dyn Fn(&[f64], &mut [f64]), y: &[f64]) -> Vec<f64> {
    let d = y.len();
    let mut jac = vec![0.0; d * d];
    for j in 0..d {
        let h = 1e-6 * (1.0 + y[j].abs());
        let (mut yp, mut ym) = (y.to_vec(), y.to_vec());
        yp[j] += h;
        ym[j] -= h;
        let (mut fp, mut fm) = (vec![0.0; d], vec![0.0; d]);
        f(&yp, &mut fp);
        f(&ym, &mut fm);
        for i in 0..d {
            jac[i * d + j] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    jac
}

#[test]
fn lagrangian_jacobian_matches_finite_differences() {
    for sys in [compile_common::double_pendulum(), kepler_polar(), compile_common::chain(3)] {
        let jr = sys.compile().with_jacobian().unwrap();
        let d = sys.dim();
        let mut rng = Rng(9);
        for _ in 0..10 {
            let mut y: Vec<f64> = (0..d).map(|_| rng.uniform(-1.5, 1.5)).collect();
            y[0] = y[0].abs() + 0.5;
            let mut jac = vec![0.0; d * d];
            jr.jacobian(0.0, &y, &mut jac);
            let fd = fd_jacobian(&|y, dy| jr.eval(0.0, y, dy), &y);
            assert!(close(&jac, &fd, 1e-7), "{}:\n{jac:?}\n{fd:?}", sys.name);
        }
    }
}

#[test]
fn hamiltonian_rhs_and_jacobian() {
    // Central potential (PHYSICS.md 3.29) with V = −μ/r: H = p_r²/2m + p_φ²/(2 m r²) − μ/r.
    // By hand: r' = p_r/m, φ' = p_φ/(m r²), p_r' = p_φ²/(m r³) − μ/r², p_φ' = 0.
    let h = parse("p_r^2/(2 m) + p_φ^2/(2 m r^2) - mu/r").unwrap();
    let (m, mu) = (2.0, 1.5);
    let rhs = HamiltonianRhs::new(&h, &["r", "φ"], &["p_r", "p_φ"], &[("m", m), ("mu", mu)]).unwrap();
    let mut rng = Rng(2);
    for _ in 0..20 {
        let y = [rng.uniform(0.5, 2.0), rng.uniform(-3.0, 3.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)];
        let (r, pr, pf) = (y[0], y[2], y[3]);
        let want = [pr / m, pf / (m * r * r), pf * pf / (m * r * r * r) - mu / (r * r), 0.0];
        let mut got = [0.0; 4];
        rhs.try_eval(0.0, &y, &mut got).unwrap();
        assert!(close(&got, &want, 1e-13), "{got:?} vs {want:?}");
        let mut jac = [0.0; 16];
        rhs.jacobian(0.0, &y, &mut jac);
        let fd = fd_jacobian(&|y, dy| rhs.eval(0.0, y, dy), &y);
        assert!(close(&jac, &fd, 1e-7), "{jac:?}\n{fd:?}");
    }
    // Not separable: the kinetic term mixes p_φ and r.
    assert!(split_separable(&h, &["r", "φ"], &["p_r", "p_φ"]).is_none());
    assert_eq!(
        SeparableHamiltonian::new(&h, &["r", "φ"], &["p_r", "p_φ"], &[("m", m), ("mu", mu)]).unwrap_err(),
        CompileError::NotSeparable
    );
}

#[test]
fn separable_hamiltonians_are_detected_and_split() {
    // Pendulum (PHYSICS.md 3.20): H = p²/(2 m l²) + m g l (1 − cos θ), so drift p/(m l²),
    // kick −m g l sin θ.
    let h = parse("p^2/(2 m l^2) + m g l (1 - cos(θ))").unwrap();
    let params = [("m", 1.5), ("l", 0.8), ("g", 9.81)];
    let (t, v) = split_separable(&h, &["θ"], &["p"]).unwrap();
    assert_eq!(t.plus(&v), h, "T + V is H");
    assert!(!t.free_symbols().iter().any(|s| s.name() == "θ"));
    assert!(!v.free_symbols().iter().any(|s| s.name() == "p"));
    let sep = SeparableHamiltonian::new(&h, &["θ"], &["p"], &params).unwrap();
    let (mut dq, mut dp) = ([0.0], [0.0]);
    sep.drift(&[0.7], &mut dq);
    sep.kick(0.0, &[0.3], &mut dp);
    assert!((dq[0] - 0.7 / (1.5 * 0.64)).abs() < 1e-15);
    assert!((dp[0] + 1.5 * 9.81 * 0.8 * 0.3f64.sin()).abs() < 1e-14);
    // A parameter times a separable sum distributes; a time-dependent potential is allowed.
    let h2 = parse("k (p^2 + q^2) + q cos(t)").unwrap();
    let (t2, v2) = split_separable(&h2, &["q"], &["p"]).unwrap();
    assert_eq!(t2, parse("k p^2").unwrap());
    assert_eq!(v2, parse("k q^2 + q cos(t)").unwrap());
    // Negative cases: a product of p and q, and p in a time-dependent term.
    assert!(split_separable(&parse("p^2 + p q").unwrap(), &["q"], &["p"]).is_none());
    assert!(split_separable(&parse("p^2 t + q^2").unwrap(), &["q"], &["p"]).is_none());
    assert!(split_separable(&parse("sin(p + q)").unwrap(), &["q"], &["p"]).is_none());
}

#[test]
fn a_singular_mass_matrix_is_an_error_not_nan() {
    // L independent of y' (PHYSICS.md Remark 3.1): W = [[1, 0], [0, 0]] everywhere.
    let l = parse("1/2 x'^2 - x^2 + y").unwrap();
    let (w, f) = mass_matrix_split(&l, &["x", "y"]);
    let rhs = LagrangianRhs::new(&w, &f, &["x", "y"], &[]).unwrap();
    let mut dy = [0.0; 4];
    let err = rhs.try_eval(0.5, &[1.0, 2.0, 3.0, 4.0], &mut dy).unwrap_err();
    assert_eq!(err, RhsError::SingularMassMatrix { t: 0.5, state: vec![1.0, 2.0, 3.0, 4.0], velocity: "y'".into() });
    // Through the infallible trait method: NaN output and the reason kept.
    rhs.eval(0.5, &[1.0, 2.0, 3.0, 4.0], &mut dy);
    assert!(dy.iter().all(|x| x.is_nan()));
    assert_eq!(rhs.take_error(), Some(err));
    assert_eq!(rhs.last_error(), None);

    // Spherical pendulum, W = diag(m l², m l² sin²θ): singular at the pole θ = 0, fine elsewhere.
    let l = parse("1/2 (θ'^2 + sin(θ)^2 φ'^2) + g cos(θ)").unwrap();
    let (w, f) = mass_matrix_split(&l, &["θ", "φ"]);
    let rhs = LagrangianRhs::new(&w, &f, &["θ", "φ"], &[("g", 9.81)]).unwrap();
    assert!(rhs.try_eval(0.0, &[0.5, 0.0, 0.1, 0.2], &mut dy).is_ok());
    let err = rhs.try_eval(0.0, &[0.0, 0.0, 0.1, 0.2], &mut dy).unwrap_err();
    assert!(matches!(err, RhsError::SingularMassMatrix { ref velocity, .. } if velocity == "φ'"), "{err}");
    // Non-finite state.
    let err = rhs.try_eval(0.0, &[f64::NAN, 0.0, 0.1, 0.2], &mut dy).unwrap_err();
    assert!(matches!(err, RhsError::NonFinite { .. }));
    // The batch path reports the failing state too.
    let y = [0.5, 0.0, 0.0, 0.0, 0.1, 0.1, 0.2, 0.2]; // SoA, second state at the pole
    let mut dyb = [0.0; 8];
    let err = rhs.eval_batch(0.0, &y, &mut dyb, 2).unwrap_err();
    assert!(matches!(err, RhsError::SingularMassMatrix { ref state, .. } if state == &vec![0.0, 0.0, 0.1, 0.2]));
}

#[test]
fn an_indefinite_mass_matrix_is_solved_by_lu() {
    // L = ½ x'² − ½ y'² + x y: W = diag(1, −1) is not positive definite; x'' = y, y'' = −x.
    let l = parse("1/2 x'^2 - 1/2 y'^2 + x y").unwrap();
    let (w, f) = mass_matrix_split(&l, &["x", "y"]);
    let rhs = LagrangianRhs::new(&w, &f, &["x", "y"], &[]).unwrap();
    let mut dy = [0.0; 4];
    rhs.try_eval(0.0, &[2.0, 3.0, 0.5, 0.25], &mut dy).unwrap();
    assert_eq!(dy, [0.5, 0.25, 3.0, -2.0]);
}

#[test]
fn implicit_legendre_map_inverts_a_relativistic_lagrangian() {
    // L = −m c² sqrt(1 − x'²/c²) − ½ k x²: p = m x' γ, so by hand x' = p / sqrt(m² + p²/c²)
    // and p' = −k x.
    let l = parse("-m c^2 sqrt(1 - x'^2/c^2) - 1/2 k x^2").unwrap();
    let (m, c, k) = (1.5, 2.0, 3.0);
    let rhs = ImplicitLegendreRhs::new(&l, &["x"], &[("m", m), ("c", c), ("k", k)]).unwrap();
    for (x, p) in [(0.3, 0.1), (-1.0, 5.0), (2.0, -40.0)] {
        let mut dy = [0.0; 2];
        rhs.try_eval(0.0, &[x, p], &mut dy).unwrap();
        let want = [p / (m * m + p * p / (c * c)).sqrt(), -k * x];
        assert!(close(&dy, &want, 1e-13), "{dy:?} vs {want:?}");
    }
    // A quadratic Lagrangian agrees with its Hamiltonian: pendulum, p = m l² θ'.
    let l = parse("1/2 m l^2 θ'^2 + m g l cos(θ)").unwrap();
    let params = [("m", 1.5), ("l", 0.8), ("g", 9.81)];
    let rhs = ImplicitLegendreRhs::new(&l, &["θ"], &params).unwrap();
    let h = parse("p^2/(2 m l^2) - m g l cos(θ)").unwrap();
    let ham = HamiltonianRhs::new(&h, &["θ"], &["p"], &params).unwrap();
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    rhs.try_eval(0.0, &[0.4, 1.1], &mut a).unwrap();
    ham.try_eval(0.0, &[0.4, 1.1], &mut b).unwrap();
    assert!(close(&a, &b, 1e-14));
    // A Lagrangian with no velocity dependence has no Legendre map: an error, not a panic.
    let rhs = ImplicitLegendreRhs::new(&parse("x^2").unwrap(), &["x"], &[]).unwrap();
    let mut dy = [0.0; 2];
    assert!(rhs.try_eval(0.0, &[1.0, 1.0], &mut dy).is_err());
    rhs.eval(0.0, &[1.0, 1.0], &mut dy);
    assert!(dy[0].is_nan() && rhs.last_error().is_some());
}

#[test]
fn ensembles_match_serial_runs_in_order() {
    // 1000 pendulum states, each advanced by 100 RK4 steps of the compiled RHS.
    let rhs = compile_common::pendulum().compile();
    let integrate = |y0: &[f64]| -> Result<Vec<f64>, RhsError> {
        let mut y = y0.to_vec();
        let h = 0.01;
        let (mut k1, mut k2, mut k3, mut k4, mut tmp) = ([0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2]);
        for _ in 0..100 {
            rhs.try_eval(0.0, &y, &mut k1)?;
            (0..2).for_each(|i| tmp[i] = y[i] + 0.5 * h * k1[i]);
            rhs.try_eval(0.0, &tmp, &mut k2)?;
            (0..2).for_each(|i| tmp[i] = y[i] + 0.5 * h * k2[i]);
            rhs.try_eval(0.0, &tmp, &mut k3)?;
            (0..2).for_each(|i| tmp[i] = y[i] + h * k3[i]);
            rhs.try_eval(0.0, &tmp, &mut k4)?;
            (0..2).for_each(|i| y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        }
        Ok(y)
    };
    let mut rng = Rng(8);
    let init: Vec<f64> = (0..2000).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let par = ensemble(&init, 2, integrate).unwrap();
    let two = ensemble_with_threads(2, &init, 2, integrate).unwrap();
    for (k, y0) in init.chunks(2).enumerate() {
        let serial = integrate(y0).unwrap();
        assert_eq!(par[k].as_ref().unwrap(), &serial);
        assert_eq!(two[k].as_ref().unwrap(), &serial);
    }
    assert!(ensemble(&init[..3], 2, integrate).is_err());
}

#[test]
fn a_diagonal_mass_matrix_is_divided_out_symbolically() {
    // W = m, F = −m ω² x: the quotient cancels m before any code exists, so the solve tape is
    // the one product −ω² x (the unrolled factorisation would spend a root and two products).
    let l = parse("1/2 m x'^2 - 1/2 m ω^2 x^2").unwrap();
    let (w, f) = mass_matrix_split(&l, &["x"]);
    let rhs = LagrangianRhs::new(&w, &f, &["x"], &[("m", 1.3), ("ω", 2.0)]).unwrap();
    assert_eq!(rhs.solve_tape().unwrap().op_count(), 1);
    let mut dy = [0.0; 2];
    rhs.try_eval(0.0, &[0.7, 0.2], &mut dy).unwrap();
    assert_eq!(dy, [0.2, -4.0 * 0.7]);
}

#[test]
fn a_negative_constant_mass_is_divided_out() {
    // W = −m < 0 is diagonal, not positive definite: the quotient F/W is still the answer.
    // By hand: −m x'' + k x = 0, x'' = k x / m.
    let l = parse("-1/2 m x'^2 - 1/2 k x^2").unwrap();
    let (w, f) = mass_matrix_split(&l, &["x"]);
    let (m, k) = (1.3, 2.5);
    let rhs = LagrangianRhs::new(&w, &f, &["x"], &[("m", m), ("k", k)]).unwrap();
    let mut dy = [0.0; 2];
    rhs.try_eval(0.0, &[0.7, 0.2], &mut dy).unwrap();
    assert_eq!(dy[0], 0.2);
    assert!((dy[1] - k * 0.7 / m).abs() <= 1e-15 * (k * 0.7 / m), "{}", dy[1]);
}

#[test]
fn a_nearly_singular_constant_mass_matrix_keeps_its_pivot_test() {
    // W = [[1, 1], [1, 1 + e]] with e = f64::EPSILON: the second Cholesky pivot is e, below
    // the threshold 2·ε·max W_jj, so the compile-time test fails and the run-time test stays:
    // the state is refused as singular rather than solved into values of size 1/e.
    let l = parse("1/2 x'^2 + x' y' + 1/2 (1 + e) y'^2 - 1/2 (x^2 + y^2)").unwrap();
    let (w, f) = mass_matrix_split(&l, &["x", "y"]);
    let rhs = LagrangianRhs::new(&w, &f, &["x", "y"], &[("e", f64::EPSILON)]).unwrap();
    let mut dy = [0.0; 4];
    let err = rhs.try_eval(0.0, &[0.3, 0.4, 0.0, 0.0], &mut dy).unwrap_err();
    assert!(matches!(err, RhsError::SingularMassMatrix { .. }), "{err:?}");
}

#[test]
fn keplers_accelerations_share_one_signed_reciprocal() {
    // q'' = −μ q / r³ (μ = 1): the sign goes into the reciprocal −1/r³, shared by both
    // accelerations, so the solve tape has one division, one root and no negation; its values
    // are the hand-written ones to rounding.
    let sys = compile_common::kepler();
    let rhs = sys.compile();
    let counts = rhs.solve_tape().unwrap().op_counts();
    assert_eq!((counts.div, counts.sqrt, counts.neg), (1, 1, 0), "{counts:?}");
    let mut rng = Rng(7);
    for _ in 0..100 {
        let y: Vec<f64> = (0..4).map(|_| rng.uniform(-2.0, 2.0)).collect();
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        rhs.eval(0.0, &y, &mut a);
        (sys.hand)(0.0, &y, &mut b);
        for i in 0..4 {
            assert!((a[i] - b[i]).abs() <= 4.0 * f64::EPSILON * b[i].abs(), "{a:?} vs {b:?}");
        }
    }
}
