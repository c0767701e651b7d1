//! Variational equations and chaos indicators: Φ against finite differences of the flow,
//! Liouville (det Φ), symplecticity, and the indicators on integrable and chaotic orbits.

use lagrangian::chaos::{chaos_map, floquet, indicators, transition_matrix, Indicator};
use lagrangian::compile::{TaylorOde, Variational};
use lagrangian::integrate::{Dop853, Gauss6, Integrate, Options, Taylor};
use lagrangian::parse;

const HH: &str = "1/2 (p_x^2 + p_y^2) + 1/2 (x^2 + y^2) + x^2 y - y^3/3";

fn henon_heiles(tangents: usize, megno: bool) -> Variational {
    Variational::hamiltonian(&parse(HH).unwrap(), &["x", "y"], &["p_x", "p_y"], &[], tangents, megno).unwrap()
}

/// A start on the energy surface `E` with `x = 0` and given `y`, `p_y` (`p_x ≥ 0` from E).
fn hh_start(e: f64, y: f64, py: f64) -> [f64; 4] {
    let px2 = 2.0 * e - py * py - y * y + 2.0 * y * y * y / 3.0;
    [0.0, y, px2.sqrt(), py]
}

fn det(a: &[f64], n: usize) -> f64 {
    let mut m = a.to_vec();
    let mut d = 1.0;
    for j in 0..n {
        let p = (j..n).max_by(|&r, &s| m[r * n + j].abs().total_cmp(&m[s * n + j].abs())).unwrap();
        if p != j {
            for k in 0..n {
                m.swap(j * n + k, p * n + k);
            }
            d = -d;
        }
        d *= m[j * n + j];
        for i in j + 1..n {
            let f = m[i * n + j] / m[j * n + j];
            for k in j..n {
                m[i * n + k] -= f * m[j * n + k];
            }
        }
    }
    d
}

#[test]
fn transition_matrix_matches_finite_differences_of_the_flow() {
    let sys = henon_heiles(4, false);
    let flow = TaylorOde::from_exprs(
        &["p_x", "p_y", "-x - 2 x y", "-y - x^2 + y^2"].map(|s| parse(s).unwrap()),
        &["x", "y", "p_x", "p_y"],
        &[],
    )
    .unwrap();
    let x0 = hh_start(0.1, 0.1, 0.05);
    let t1 = 5.0;
    let (phi, x1) = transition_matrix(&sys, &x0, t1, 1e-15).unwrap();
    let end = |x: &[f64]| {
        Taylor::new(1e-15).integrate_with(&flow, 0.0..t1, x, Options::new().final_only()).unwrap().last_state().to_vec()
    };
    assert!(end(&x0).iter().zip(&x1).all(|(a, b)| (a - b).abs() < 1e-13));
    let h = 1e-5;
    for j in 0..4 {
        let (mut xp, mut xm) = (x0, x0);
        xp[j] += h;
        xm[j] -= h;
        let (fp, fm) = (end(&xp), end(&xm));
        for i in 0..4 {
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            // Central differences: truncation O(h²) ~ 1e-10 times the third derivative.
            assert!((phi[i * 4 + j] - fd).abs() < 1e-7 * (1.0 + fd.abs()), "Φ[{i}][{j}] = {} vs {fd}", phi[i * 4 + j]);
        }
    }
}

#[test]
fn hamiltonian_flow_preserves_volume_and_the_symplectic_form() {
    let sys = henon_heiles(4, false);
    let x0 = hh_start(0.08, 0.05, 0.1);
    let (phi, _) = transition_matrix(&sys, &x0, 20.0, 1e-15).unwrap();
    assert!((det(&phi, 4) - 1.0).abs() < 1e-12, "det Φ = {}", det(&phi, 4));
    // ΦᵀJΦ = J with J = [[0, I], [−I, 0]].
    let jm = |i: usize, k: usize| -> f64 {
        match (i < 2, k < 2) {
            (true, false) if k == i + 2 => 1.0,
            (false, true) if i == k + 2 => -1.0,
            _ => 0.0,
        }
    };
    let mut defect = 0.0f64;
    for a in 0..4 {
        for b in 0..4 {
            let mut s = 0.0;
            for i in 0..4 {
                for k in 0..4 {
                    s += phi[i * 4 + a] * jm(i, k) * phi[k * 4 + b];
                }
            }
            defect = defect.max((s - jm(a, b)).abs());
        }
    }
    assert!(defect < 1e-12, "symplectic defect {defect:e}");
}

#[test]
fn damped_oscillator_contracts_volume_like_its_trace() {
    // x' = v, v' = −x − γ v: tr J = −γ, so det Φ(t) = e^{−γt} (Liouville).
    let gamma = 0.3;
    let f = [parse("v").unwrap(), parse("-x - 3/10 v").unwrap()];
    let sys = Variational::new(&f, &["x", "v"], &[], 2, false).unwrap();
    for t in [1.0, 5.0, 12.0] {
        let (phi, _) = transition_matrix(&sys, &[1.0, 0.0], t, 1e-15).unwrap();
        let want = (-gamma * t).exp();
        assert!((det(&phi, 2) - want).abs() < 1e-13 * want.max(1e-3) * 100.0, "t = {t}: {} vs {want}", det(&phi, 2));
    }
    // The same tangent flow through DOP853 (the variational system is an Rhs too).
    let y0 = sys.initial_state(&[1.0, 0.0]);
    let tr = Dop853::new(1e-13, 1e-13).integrate_with(&sys, 0.0..5.0, &y0, Options::new().final_only()).unwrap();
    let y = tr.last_state();
    let d = y[2] * y[5] - y[4] * y[3];
    assert!((d - (-gamma * 5.0f64).exp()).abs() < 1e-10, "{d}");
}

#[test]
fn integrable_orbits_have_zero_exponent_and_their_megno() {
    // Harmonic oscillator: isochronous, tangent vectors stay bounded: λ → 0, Ȳ → 0.
    let osc = Variational::hamiltonian(&parse("1/2 p^2 + 1/2 x^2").unwrap(), &["x"], &["p"], &[], 1, true).unwrap();
    let r = indicators(&osc, &[1.0, 0.0], 500.0, 1e-14).unwrap();
    assert!(r.lyapunov[0].abs() < 0.01, "{:?}", r.lyapunov);
    assert!(r.megno.abs() < 0.05, "Ȳ = {}", r.megno);
    // Pendulum libration: the period depends on the amplitude, so tangents grow linearly:
    // λ → 0 like ln t / t, Ȳ → 2.
    let pend = Variational::hamiltonian(&parse("1/2 p^2 - cos(x)").unwrap(), &["x"], &["p"], &[], 1, true).unwrap();
    let r = indicators(&pend, &[2.0, 0.0], 2000.0, 1e-14).unwrap();
    assert!(r.lyapunov[0].abs() < 0.01, "{:?}", r.lyapunov);
    assert!((r.megno - 2.0).abs() < 0.1, "Ȳ = {}", r.megno);
    // A regular Hénon–Heiles orbit at low energy: nearly isochronous (both frequencies near
    // 1), so Ȳ creeps up towards 2 only after very long times; it stays well below chaos.
    let hh = henon_heiles(1, true);
    let r = indicators(&hh, &hh_start(0.05, 0.1, 0.0), 2000.0, 1e-14).unwrap();
    assert!(r.megno < 2.2 && r.lyapunov[0] < 0.01, "Ȳ = {}, λ = {:?}", r.megno, r.lyapunov);
}

#[test]
fn chaotic_henon_heiles_orbit_at_e_one_sixth() {
    let hh = henon_heiles(1, true);
    let x0 = hh_start(1.0 / 6.0, -0.1, 0.05);
    let r = indicators(&hh, &x0, 1000.0, 1e-14).unwrap();
    assert!(r.lyapunov[0] > 0.02, "λ = {:?}", r.lyapunov);
    assert!(r.megno > 5.0, "Ȳ = {}", r.megno);
    assert!(r.fli > 10.0, "FLI = {}", r.fli);
}

#[test]
fn hamiltonian_spectrum_comes_in_opposite_pairs() {
    let hh = henon_heiles(4, false);
    let x0 = hh_start(1.0 / 6.0, -0.1, 0.05);
    let r = indicators(&hh, &x0, 1000.0, 1e-14).unwrap();
    let l = &r.lyapunov;
    assert!(l[0] > 0.02, "{l:?}");
    assert!((l[0] + l[3]).abs() < 0.02 * l[0], "{l:?}");
    assert!((l[1] + l[2]).abs() < 0.05 * l[0], "{l:?}");
    assert!(l.iter().sum::<f64>().abs() < 1e-10, "{l:?}");
}

#[test]
fn chaos_map_over_a_small_grid() {
    let hh = henon_heiles(1, true);
    let starts: Vec<Vec<f64>> =
        [(0.05, 0.1, 0.0), (1.0 / 6.0, -0.1, 0.05)].iter().map(|&(e, y, py)| hh_start(e, y, py).to_vec()).collect();
    let map = chaos_map(&hh, &starts, 300.0, 1e-12, Indicator::Megno);
    assert_eq!(map.len(), 2);
    assert!(map[0] < 3.0 && map[1] > map[0], "{map:?}");
    // Same numbers as one orbit at a time (deterministic, thread-independent).
    let one = indicators(&hh, &starts[1], 300.0, 1e-12).unwrap().megno;
    assert_eq!(map[1], one);
}

/// Mathieu's equation `x'' + (a − 2q cos 2t) x = 0` as a first-order variational system.
fn mathieu(a: f64, q: f64) -> Variational {
    let f = ["v", "-(a - 2 q cos(2 t)) x"].map(|s| parse(s).unwrap());
    Variational::new(&f, &["x", "v"], &[("a", a), ("q", q)], 2, false).unwrap()
}

#[test]
fn monodromy_of_a_constant_coefficient_oscillator_is_its_rotation() {
    // q = 0: x'' + a x = 0, so over T = π, M = [[cos ωT, sin ωT / ω], [−ω sin ωT, cos ωT]]
    // with ω = √a, and the multipliers are e^{±iωT}.
    let a: f64 = 0.3;
    let w = a.sqrt();
    let t = std::f64::consts::PI;
    let fl = floquet(&mathieu(a, 0.0), &[1.0, 0.0], t, 1e-15).unwrap();
    let want = [(w * t).cos(), (w * t).sin() / w, -w * (w * t).sin(), (w * t).cos()];
    for (got, want) in fl.monodromy.iter().zip(want) {
        assert!((got - want).abs() < 1e-13, "{:?} vs {want:?}", fl.monodromy);
    }
    assert!((fl.spectral_radius() - 1.0).abs() < 1e-13);
    let (re, im) = fl.multipliers[0];
    assert!((re - (w * t).cos()).abs() < 1e-13 && (im.abs() - (w * t).sin().abs()).abs() < 1e-13, "{fl:?}");
    assert!((fl.trace() - 2.0 * (w * t).cos()).abs() < 1e-13);
}

#[test]
fn mathieu_first_instability_tongue_matches_the_series_boundaries() {
    // Abramowitz & Stegun 20.2.25: the characteristic values bounding the first tongue are
    // a₁(q) = 1 − q − q²/8 + q³/64 − q⁴/1536 − 11q⁵/36864 + …
    // b₁(q) = 1 + q − q²/8 − q³/64 − q⁴/1536 + 11q⁵/36864 + …
    // Between them the solutions grow (|tr M| > 2 over the period π); outside, they are bounded.
    let q: f64 = 0.2;
    let a1 = 1.0 - q - q * q / 8.0 + q.powi(3) / 64.0 - q.powi(4) / 1536.0 - 11.0 * q.powi(5) / 36864.0;
    let b1 = 1.0 + q - q * q / 8.0 - q.powi(3) / 64.0 - q.powi(4) / 1536.0 + 11.0 * q.powi(5) / 36864.0;
    let t = std::f64::consts::PI;
    let excess = |a: f64| {
        let fl = floquet(&mathieu(a, q), &[1.0, 0.0], t, 1e-15).unwrap();
        // Liouville: the flow of a trace-free linear system keeps volume.
        assert!((fl.monodromy[0] * fl.monodromy[3] - fl.monodromy[1] * fl.monodromy[2] - 1.0).abs() < 1e-12);
        fl.trace().abs() - 2.0
    };
    assert!(excess(a1 - 0.02) < 0.0 && excess(1.0) > 0.0 && excess(b1 + 0.02) < 0.0);
    // Locate both boundaries by bisection on |tr M| − 2.
    let bisect = |mut lo: f64, mut hi: f64| {
        let s = excess(lo).signum();
        for _ in 0..30 {
            let mid = 0.5 * (lo + hi);
            if excess(mid).signum() == s {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let (fa, fb) = (bisect(a1 - 0.02, 1.0), bisect(1.0, b1 + 0.02));
    // The next series terms are O(q⁶) ≈ 1e-6 here.
    assert!((fa - a1).abs() < 1e-5, "a1: {fa} vs series {a1}");
    assert!((fb - b1).abs() < 1e-5, "b1: {fb} vs series {b1}");
}

#[test]
fn bad_tolerances_kinks_and_singularities_are_typed_errors() {
    use lagrangian::integrate::FailureReason;
    let osc = Variational::hamiltonian(&parse("1/2 p^2 + 1/2 x^2").unwrap(), &["x"], &["p"], &[], 1, true).unwrap();
    // A tolerance that is not positive, not a number, or below what f64 can meet: refused
    // before the first step.
    for tol in [0.0, -1e-8, f64::NAN, f64::INFINITY, 1e-25] {
        let err = indicators(&osc, &[1.0, 0.0], 10.0, tol).unwrap_err();
        assert!(matches!(err.reason, FailureReason::InvalidInput(_)), "tol {tol}: {err}");
        assert_eq!(err.steps, 0, "tol {tol}");
        // The map leaves such a start blank rather than failing the others.
        assert!(chaos_map(&osc, &[vec![1.0, 0.0]], 10.0, tol, Indicator::Megno)[0].is_nan());
    }
    // V = |x|: its force has a kink at x = 0, where no Taylor series exists. Started on the
    // kink, or crossing it inside a step, the run stops with an error naming it.
    let vee = Variational::hamiltonian(&parse("1/2 p^2 + abs(x)").unwrap(), &["x"], &["p"], &[], 1, true).unwrap();
    let err = indicators(&vee, &[0.0, 1.0], 10.0, 1e-12).unwrap_err();
    assert!(err.to_string().contains("abs"), "{err}");
    let err = indicators(&vee, &[1.0, 0.0], 10.0, 1e-12).unwrap_err();
    assert!(err.to_string().contains("kink"), "{err}");
    assert!(err.t < 1.5, "{err}");
    // L = x² x'²/2 − x has the mass matrix W = x², singular at x = 0; its H = p²/(2x²) + x
    // falls into x = 0 from rest at x = 1 (with E = 1, x' = √(2(1 − x))/x blows up there).
    // The run ends with a typed error before t = 1, in a bounded number of steps.
    let w = Variational::hamiltonian(&parse("p^2/(2 x^2) + x").unwrap(), &["x"], &["p"], &[], 2, false).unwrap();
    let err = indicators(&w, &[1.0, 0.0], 5.0, 1e-12).unwrap_err();
    assert!(
        matches!(
            err.reason,
            FailureReason::StepSizeCollapse { .. } | FailureReason::NonFinite { .. } | FailureReason::Rhs(_)
        ),
        "{err}"
    );
    assert!(err.t < 1.0 && err.steps < 100_000, "{err}");
}

#[test]
fn gauss_tangent_flow_matches_taylor_and_stays_symplectic() {
    // The variational system is an `Rhs`, so the Gauss methods integrate it too. Gauss–Legendre
    // collocation is symplectic and commutes with linearisation, so its Φ is symplectic up to
    // the stage solve, whatever the step; and it converges to the Taylor Φ at order 6.
    let sys = henon_heiles(4, false);
    let x0 = hh_start(0.1, 0.1, 0.05);
    let (want, _) = transition_matrix(&sys, &x0, 5.0, 1e-15).unwrap();
    let y0 = sys.initial_state(&x0);
    let mut errors = Vec::new();
    for h in [0.25, 0.125] {
        let y = Gauss6::new(h).integrate_with(&sys, 0.0..5.0, &y0, Options::new().final_only()).unwrap();
        let y = y.last_state();
        // Column j of Φ is tangent vector j: y[4 + 4 j + i] = Φ[i][j].
        let phi: Vec<f64> = (0..16).map(|k| y[4 + 4 * (k % 4) + k / 4]).collect();
        errors.push(phi.iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max));
        assert!((det(&phi, 4) - 1.0).abs() < 1e-11, "h = {h}: det Φ = {}", det(&phi, 4));
    }
    // Halving h divides the error by about 2⁶ = 64.
    assert!(errors[0] < 1e-5 && errors[0] / errors[1] > 40.0, "{errors:?}");
}

/// The exponent from MEGNO's slope (`Indicators::megno_lyapunov`): exact on a saddle, near zero
/// on a Kepler ellipse where the finite-time exponent still reads ~ln t / t, and the same as
/// the finite-time one on a chaotic orbit.
#[test]
fn lyapunov_exponent_from_the_slope_of_megno() {
    // H = q p: q(t) = q0 eᵗ, and a tangent started along q grows as eᵗ exactly, so
    // ẇ·w/w·w = 1, Y(s) = (2/s) ∫₀ˢ u du = s, a line of slope 1 (by hand).
    let saddle = Variational::hamiltonian(&parse("q p").unwrap(), &["q"], &["p"], &[], 1, true).unwrap();
    let r = indicators(&saddle, &[1.0, 1.0], 20.0, 1e-14).unwrap();
    assert!((r.megno_lyapunov - 1.0).abs() < 1e-9, "slope {}", r.megno_lyapunov);
    // Ȳ = (1/t) ∫ s ds = t/2 for the same line.
    assert!((r.megno - 10.0).abs() < 1e-8, "Ȳ = {}", r.megno);

    // Kepler, e = 0.5 (period 2π a^{3/2} with a = 1): regular, shear makes w grow linearly.
    let kepler = Variational::hamiltonian(
        &parse("1/2 (p_x^2 + p_y^2) - 1/sqrt(x^2 + y^2)").unwrap(),
        &["x", "y"],
        &["p_x", "p_y"],
        &[],
        1,
        true,
    )
    .unwrap();
    // Perihelion r = a (1 − e) = 0.5, speed sqrt((1 + e)/(1 − e)) = sqrt(3).
    let r = indicators(&kepler, &[0.5, 0.0, 0.0, 3f64.sqrt()], 2000.0, 1e-13).unwrap();
    assert!(r.lyapunov[0] > 2e-3, "the finite-time exponent still decays slowly: {:?}", r.lyapunov);
    assert!(r.megno_lyapunov.abs() < 1e-3, "slope {}", r.megno_lyapunov);
    assert!((r.megno - 2.0).abs() < 0.1, "Ȳ = {}", r.megno);

    // A chaotic Hénon–Heiles orbit: both estimate the same exponent.
    let hh = henon_heiles(1, true);
    let r = indicators(&hh, &hh_start(1.0 / 6.0, -0.1, 0.05), 1000.0, 1e-14).unwrap();
    let ratio = r.megno_lyapunov / r.lyapunov[0];
    assert!((0.5..2.0).contains(&ratio), "slope {} against λ {:?}", r.megno_lyapunov, r.lyapunov);
}

/// A variational system whose every expansion is written as if for the first time: it
/// forwards `taylor_coefficients` alone, so the integrator's `taylor_coefficients_again` is
/// the default, which fills the whole buffer.
struct FreshVariational<'a>(&'a Variational);

impl lagrangian::integrate::TaylorSystem for FreshVariational<'_> {
    fn dim(&self) -> usize {
        self.0.dim()
    }
    fn scratch_len(&self, order: usize) -> usize {
        lagrangian::integrate::TaylorSystem::scratch_len(self.0, order)
    }
    fn taylor_coefficients(
        &self,
        t: f64,
        y: &[f64],
        order: usize,
        buf: &mut [f64],
    ) -> Result<(), lagrangian::integrate::RhsError> {
        lagrangian::integrate::TaylorSystem::taylor_coefficients(self.0, t, y, order, buf)
    }
    fn check_step(&self, scratch: &[f64], order: usize, h: f64) -> Result<(), lagrangian::integrate::RhsError> {
        lagrangian::integrate::TaylorSystem::check_step(self.0, scratch, order, h)
    }
}

#[test]
fn variational_expansions_into_the_last_buffer_equal_fresh_ones() {
    // The Hénon–Heiles tangent flow with MEGNO (constant rows in the tape) and a driven,
    // damped oscillator (the time as an input row, whose orders past 1 a reused buffer keeps),
    // interpreted and on native code: the run that reuses the buffer has every bit of the run
    // that writes it whole at every step.
    let bits = |tr: &lagrangian::integrate::Trajectory| {
        tr.iter().map(|(t, y)| (t.to_bits(), y.iter().map(|v| v.to_bits()).collect::<Vec<_>>())).collect::<Vec<_>>()
    };
    let driven = Variational::new(
        &[parse("v").unwrap(), parse("-x - 0.1 v + 0.3 cos(1.1 t)").unwrap()],
        &["x", "v"],
        &[],
        2,
        false,
    )
    .unwrap();
    let hh = henon_heiles(2, true);
    for (sys, x0) in [(&hh, &hh_start(1.0 / 8.0, 0.1, 0.0)[..]), (&driven, &[1.0, 0.0][..])] {
        for native in [false, true] {
            let v = sys.clone().with_native(native);
            let y0 = v.initial_state(x0);
            for tol in [1e-6, 1e-12] {
                let m = Taylor::new(tol);
                let again = m.integrate(&v, 0.0..20.0, &y0).unwrap();
                let fresh = m.integrate(&FreshVariational(&v), 0.0..20.0, &y0).unwrap();
                assert!(again.stats.steps > 20, "{} steps", again.stats.steps);
                assert_eq!(bits(&again), bits(&fresh), "tol {tol:e}, native {native}");
            }
        }
    }
}
