//! Tests of `src/integrate/problems.rs` (formerly its in-crate unit tests).
use lagrangian::integrate::problems::*;

use lagrangian::integrate::Rhs;

use std::f64::consts::PI;
/// K(1/2) = Γ(1/4)² / (4 √π) (the lemniscate case); the value of the closed form was
/// evaluated with mpmath to 30 digits.
#[test]
fn complete_integral_matches_closed_form() {
    assert!((elliptic_k(0.5) - 1.8540746773013719).abs() < 4e-16);
    assert_eq!(elliptic_k(0.0), PI / 2.0);
    // K(m) ~ ln(4/k') as m → 1 (A&S 17.3.26), to O(k'² ln k').
    let m: f64 = 1.0 - 1e-12;
    let kp = (1.0 - m).sqrt();
    assert!((elliptic_k(m) - (4.0 / kp).ln()).abs() < 1e-9);
}

#[test]
fn jacobi_functions_satisfy_their_identities() {
    for &m in &[0.1, 0.5, 0.9, 0.999] {
        let k = elliptic_k(m);
        let (am, sn, cn, dn) = jacobi_elliptic(k, m);
        assert!((sn - 1.0).abs() < 1e-14 && cn.abs() < 1e-7, "sn(K)=1, cn(K)=0");
        assert!((am - PI / 2.0).abs() < 1e-7);
        assert!((dn - (1.0 - m).sqrt()).abs() < 1e-14);
        for i in 0..20 {
            let u = -3.0 + 0.37 * i as f64;
            let (am, sn, cn, dn) = jacobi_elliptic(u, m);
            assert!((sn * sn + cn * cn - 1.0).abs() < 1e-15);
            assert!((dn * dn + m * sn * sn - 1.0).abs() < 1e-15);
            assert!((am.sin() - sn).abs() < 1e-15);
            // d sn/du = cn dn and d am/du = dn, by central differences (error ~1e-10).
            let d = 1e-5;
            let (amp, snp, _, _) = jacobi_elliptic(u + d, m);
            let (amm, snm, _, _) = jacobi_elliptic(u - d, m);
            assert!(((snp - snm) / (2.0 * d) - cn * dn).abs() < 1e-9);
            assert!(((amp - amm) / (2.0 * d) - dn).abs() < 1e-9);
            // Periodicity 4K and the half-period shift sn(u + 2K) = −sn(u).
            let (_, sn4, _, _) = jacobi_elliptic(u + 4.0 * k, m);
            let (_, sn2, _, _) = jacobi_elliptic(u + 2.0 * k, m);
            assert!((sn4 - sn).abs() < 1e-13 && (sn2 + sn).abs() < 1e-13);
        }
    }
    // A value computed with mpmath (ellipfun, 30 digits): sn(0.7 | 0.8).
    let (_, sn, cn, dn) = jacobi_elliptic(0.7, 0.8);
    assert!((sn - 0.6123654841172453).abs() < 1e-15);
    assert!((cn - 0.7905747996627845).abs() < 1e-15);
    assert!((dn - 0.8366640969286787).abs() < 1e-15);
}

#[test]
fn exact_solutions_solve_their_equations() {
    // Check by central differences that each exact solution satisfies y' = f(y).
    let d = 1e-5;
    let mut f = [0.0; 4];
    let p = Pendulum { omega: 1.3 };
    for i in 0..10 {
        let t = 0.41 * i as f64;
        let y = p.exact_from_rest(2.5, t);
        let (yp, ym) = (p.exact_from_rest(2.5, t + d), p.exact_from_rest(2.5, t - d));
        Rhs::eval(&p, t, &y, &mut f[..2]);
        for k in 0..2 {
            assert!(((yp[k] - ym[k]) / (2.0 * d) - f[k]).abs() < 1e-8, "pendulum {t} {k}");
        }
        assert!((p.energy(&y) - p.energy(&[2.5, 0.0])).abs() < 1e-13);
        let y = p.exact_separatrix(t);
        let (yp, ym) = (p.exact_separatrix(t + d), p.exact_separatrix(t - d));
        Rhs::eval(&p, t, &y, &mut f[..2]);
        for k in 0..2 {
            assert!(((yp[k] - ym[k]) / (2.0 * d) - f[k]).abs() < 1e-8, "separatrix");
        }
    }
    assert!(p.exact_from_rest(2.5, 0.0)[1].abs() < 1e-15);
    assert!((p.exact_from_rest(2.5, 0.0)[0] - 2.5).abs() < 1e-15);
    for &e in &[0.0, 0.5, 0.9, 0.99] {
        let y0 = Kepler::pericentre(e);
        let e0 = Kepler.energy(&y0);
        assert!((e0 + 0.5).abs() < 1e-13);
        for i in 0..10 {
            let t = 0.77 * i as f64;
            let y = Kepler::exact(e, t);
            // A step scaled to the pericentre time scale keeps the truncation error small.
            let dk = d * (1.0 - e).powf(1.5);
            let (yp, ym) = (Kepler::exact(e, t + dk), Kepler::exact(e, t - dk));
            Rhs::eval(&Kepler, t, &y, &mut f);
            for k in 0..4 {
                let err = ((yp[k] - ym[k]) / (2.0 * dk) - f[k]).abs() / (1.0 + f[k].abs());
                assert!(err < 1e-6, "kepler e = {e}, t = {t}: {err}");
            }
            assert!((Kepler.energy(&y) - e0).abs() < 1e-12);
        }
    }
}

#[test]
fn double_pendulum_energy_is_conserved_by_the_rhs() {
    // dE/dt = ∇E · f must vanish; check by a directional finite difference.
    let dp = DoublePendulum::default();
    let y = [0.3, -1.2, 0.7, 2.1];
    let mut f = [0.0; 4];
    dp.eval(0.0, &y, &mut f);
    let d = 1e-6;
    let yp: Vec<f64> = (0..4).map(|i| y[i] + d * f[i]).collect();
    let ym: Vec<f64> = (0..4).map(|i| y[i] - d * f[i]).collect();
    let de = (dp.energy(&yp) - dp.energy(&ym)) / (2.0 * d);
    assert!(de.abs() < 1e-7, "dE/dt = {de}");
}
