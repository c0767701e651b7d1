//! Stress tests: every method driven into hard cases must end in a correct result or in a
//! typed [`IntegrateError`] carrying a finite last state, the time and the reason; never a
//! panic and never a NaN trajectory.

use lagrangian::integrate::problems::{Kepler, Oscillator, Pendulum};
use lagrangian::integrate::{
    Dop853, ExplicitRk, FailureReason, FnJacobian, FnRhs, Gauss, ImplicitSolver, Integrate, IntegrateError, Method,
    Options, RhsError, Separable, Splitting, Trajectory, TryFnRhs,
};

fn splittings(h: f64) -> Vec<Splitting> {
    vec![
        Splitting::symplectic_euler(h),
        Splitting::leapfrog(h),
        Splitting::yoshida4(h),
        Splitting::blanes_moan4(h),
        Splitting::yoshida6(h),
        Splitting::yoshida8(h),
    ]
}

fn explicit_rk(h: f64) -> Vec<ExplicitRk> {
    vec![ExplicitRk::euler(h), ExplicitRk::rk4(h)]
}

fn gauss(h: f64) -> Vec<Gauss> {
    vec![Gauss::midpoint(h), Gauss::gauss4(h), Gauss::gauss6(h)]
}

/// The guarantees every failure must keep.
fn assert_clean_error(e: &IntegrateError, t0: f64, t1: f64) {
    assert!(e.state.iter().all(|v| v.is_finite()), "error state not finite: {e}");
    assert!(e.t.is_finite() && e.t >= t0.min(t1) && e.t <= t0.max(t1), "{e}");
    assert!(!e.to_string().is_empty());
}

fn assert_finite(tr: &Trajectory) {
    assert!(tr.states.iter().all(|v| v.is_finite()));
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Unwraps an expected failure without dumping a whole trajectory on success.
fn failure(r: Result<Trajectory, IntegrateError>, what: &str) -> IntegrateError {
    match r {
        Ok(tr) => panic!("{what}: expected a failure, got a trajectory ending at {:?}", tr.last_state()),
        Err(e) => e,
    }
}

/// Spectral radius of the one-step map of `m` on the oscillator (a 2×2 linear map, from the
/// images of the unit vectors).
fn growth<M: Method<Oscillator>>(m: &M, sys: &Oscillator, h: f64) -> f64 {
    let col = |y: [f64; 2]| {
        let tr = m.integrate_with(sys, 0.0..h, &y, Options::new().final_only()).unwrap();
        [tr.last_state()[0], tr.last_state()[1]]
    };
    let (c0, c1) = (col([1.0, 0.0]), col([0.0, 1.0]));
    let (tr, det) = (c0[0] + c1[1], c0[0] * c1[1] - c1[0] * c0[1]);
    let disc = tr * tr / 4.0 - det;
    if disc >= 0.0 {
        (tr / 2.0).abs() + disc.sqrt()
    } else {
        det.abs().sqrt()
    }
}

#[test]
fn steps_beyond_the_stability_limit_end_in_a_non_finite_error() {
    // For each explicit method, the smallest step from a list whose one-step map grows
    // vectors by ≥ 5 % per step (ω h ≥ 2.5 is beyond every explicit method's stability
    // interval, but a composition can be stable again on islands further out).
    let sys = Oscillator { omega: 1.0 };
    let (t1, y0) = (1e6, [1.0, 0.0]);
    let hs = [2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 7.0];
    let mut checked = 0;
    for make in [
        Splitting::symplectic_euler as fn(f64) -> Splitting,
        Splitting::leapfrog,
        Splitting::yoshida4,
        Splitting::blanes_moan4,
        Splitting::yoshida6,
        Splitting::yoshida8,
    ] {
        let Some(&h) = hs.iter().find(|&&h| growth(&make(h), &sys, h) > 1.05) else { continue };
        let m = make(h);
        let e = failure(m.integrate(&sys, 0.0..t1, &y0), m.info().name);
        assert!(matches!(e.reason, FailureReason::NonFinite { .. }), "{}: {e}", m.info().name);
        assert_clean_error(&e, 0.0, t1);
        checked += 1;
    }
    assert_eq!(checked, 6, "every splitting has an unstable step in the list");
    for m in explicit_rk(3.0) {
        assert!(growth(&m, &sys, 3.0) > 1.05);
        let e = failure(m.integrate(&sys, 0.0..t1, &y0), m.info().name);
        assert!(matches!(e.reason, FailureReason::NonFinite { .. }), "{e}");
        assert_clean_error(&e, 0.0, t1);
    }
    // Gauss methods are A-stable and conserve quadratic invariants: with Newton (the
    // oscillator provides its Jacobian) the result is correct in energy...
    for m in gauss(3.0) {
        let tr = m.integrate_with(&sys, 0.0..3000.0, &y0, Options::new().final_only()).unwrap();
        let de = (sys.energy(tr.last_state()) - 0.5).abs();
        assert!(de < 1e-12, "{}: energy error {de:e}", m.info().name);
    }
    // ...while fixed-point iteration converges only when h ρ(A) ω < 1 (ρ(A) = 1/2 for the
    // midpoint rule, smaller for more stages): it either converges to the same
    // energy-conserving result or says that it did not converge.
    for m in gauss(3.0) {
        let name = m.info().name;
        let m = m.solver(ImplicitSolver::FixedPoint);
        match m.integrate_with(&sys, 0.0..300.0, &y0, Options::new().final_only()) {
            Ok(tr) => {
                assert_ne!(name, "implicit midpoint", "h ω / 2 = 1.5 > 1 cannot converge");
                let de = (sys.energy(tr.last_state()) - 0.5).abs();
                assert!(de < 1e-12, "{name}: energy error {de:e}");
            }
            Err(e) => {
                assert!(matches!(e.reason, FailureReason::ImplicitSolve { newton: false, .. }), "{e}");
                assert_clean_error(&e, 0.0, 300.0);
                assert_eq!(e.t, 0.0);
            }
        }
    }
    // DOP853 adapts its step: correct result.
    let tr = Dop853::new(1e-10, 1e-12).integrate(&sys, 0.0..100.0, &y0).unwrap();
    assert!(max_diff(tr.last_state(), &sys.exact(&y0, 100.0)) < 1e-8);
}

#[test]
fn stiff_spring() {
    // k = 10⁸ (ω = 10⁴): explicit fixed steps of 10⁻³ are far beyond stability.
    let sys = Oscillator { omega: 1e4 };
    let y0 = [1e-4, 0.0];
    for m in explicit_rk(1e-3) {
        let e = failure(m.integrate(&sys, 0.0..100.0, &y0), "unstable");
        assert!(matches!(e.reason, FailureReason::NonFinite { .. }));
        assert_clean_error(&e, 0.0, 100.0);
    }
    for m in splittings(1e-3) {
        let e = failure(m.integrate(&sys, 0.0..100.0, &y0), "unstable");
        assert!(matches!(e.reason, FailureReason::NonFinite { .. }));
        assert_clean_error(&e, 0.0, 100.0);
    }
    // Gauss with Newton is stable and energy-conserving at any step.
    for m in gauss(1e-3) {
        let tr = m.integrate_with(&sys, 0.0..1.0, &y0, Options::new().final_only()).unwrap();
        let de = (sys.energy(tr.last_state()) / sys.energy(&y0) - 1.0).abs();
        assert!(de < 1e-12, "{}: relative energy error {de:e}", m.info().name);
    }
    // DOP853 resolves the oscillation (about 1600 periods): correct result.
    let tr = Dop853::new(1e-10, 1e-14).integrate_with(&sys, 0.0..1.0, &y0, Options::new().final_only()).unwrap();
    let exact = sys.exact(&y0, 1.0);
    assert!((tr.last_state()[0] - exact[0]).abs() < 1e-4 * 1e-4, "{:?} vs {exact:?}", tr.last_state());
    assert!(tr.stats.steps > 1000);
}

#[test]
fn pendulum_separatrix() {
    // Start at the bottom with exactly the energy of the separatrix: the exact motion creeps
    // up to the unstable top, θ = 4 atan(e^t) − π. Errors grow like e^t, so compare at t = 4.
    let sys = Pendulum { omega: 1.0 };
    let y0 = [0.0, 2.0];
    let exact = sys.exact_separatrix(4.0);
    let h = 0.01;
    let check = |name: &str, order: u32, tr: Result<Trajectory, IntegrateError>| {
        let tr = tr.unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_finite(&tr);
        let err = max_diff(tr.last_state(), &exact);
        let tol = if order == 1 { 0.5 } else { 1e-3 };
        assert!(err < tol, "{name}: error {err:e}");
    };
    for m in splittings(h) {
        check(m.info().name, m.info().order, m.integrate(&sys, 0.0..4.0, &y0));
    }
    for m in explicit_rk(h) {
        check(m.info().name, m.info().order, m.integrate(&sys, 0.0..4.0, &y0));
    }
    for m in gauss(h) {
        check(m.info().name, m.info().order, m.integrate(&sys, 0.0..4.0, &y0));
    }
    check("DOP853", 8, Dop853::new(1e-12, 1e-12).integrate(&sys, 0.0..4.0, &y0));
    // Long after, the exact solution sits at the top; numerically the pendulum falls to either
    // side. Symplectic methods still keep the energy near the separatrix value.
    for m in splittings(0.05).into_iter().skip(1) {
        let tr = m.integrate(&sys, 0.0..200.0, &y0).unwrap();
        let worst = tr.iter().map(|(_, y)| (sys.energy(y) - 1.0).abs()).fold(0.0, f64::max);
        let tol = if m.info().order == 2 { 5e-3 } else { 1e-4 };
        assert!(worst < tol, "{}: energy error {worst:e}", m.info().name);
    }
}

#[test]
fn close_kepler_encounters_at_e099() {
    // Pericentre distance 0.01, speed 14: one orbit (t = 2π) through the close encounter.
    let e = 0.99;
    let y0 = Kepler::pericentre(e);
    let t = 2.0 * std::f64::consts::PI;
    let exact = Kepler::exact(e, t);
    // The final state is ill-conditioned (at pericentre a time shift δt moves p by 10⁴ δt),
    // so the error is ~10⁶ times the tolerance; the energy error follows the tolerance.
    let tr = Dop853::new(1e-14, 1e-16).integrate(&Kepler, 0.0..t, &y0).unwrap();
    let err = max_diff(tr.last_state(), &exact);
    let de = (Kepler.energy(tr.last_state()) + 0.5).abs();
    assert!(err < 5e-7 && de < 1e-12, "DOP853 error {err:e}, energy error {de:e}");
    // Fixed steps small enough for the encounter (h = 2π/2¹⁷) give correct results too.
    let h = t / 131072.0;
    for m in splittings(h).into_iter().skip(1) {
        let tr = m.integrate_with(&Kepler, 0.0..t, &y0, Options::new().final_only()).unwrap();
        let err = max_diff(tr.last_state(), &exact);
        let de = (Kepler.energy(tr.last_state()) + 0.5).abs();
        println!("{:16} error {err:.2e}, energy error {de:.2e}", m.info().name);
        // Only the optimised and high-order compositions resolve the encounter at this step
        // (leapfrog would need h ~ 1e-6): their energy error is small, their phase error
        // is amplified by the pericentre passage like DOP853's.
        if ["Blanes-Moan 4", "Yoshida 6", "Yoshida 8"].contains(&m.info().name) {
            assert!(err < 0.05 && de < 1e-10, "{}: error {err:e}", m.info().name);
        } else {
            assert!(de < 0.05, "{}: energy error {de:e}", m.info().name);
        }
    }
    // Steps too coarse for the encounter: no panic and no NaN — either a finite (inaccurate)
    // state, whose energy error exposes the problem, or a clean error.
    for h in [0.05, 0.01, 0.002] {
        for m in splittings(h) {
            match m.integrate_with(&Kepler, 0.0..20.0 * t, &y0, Options::new().final_only()) {
                Ok(tr) => assert_finite(&tr),
                Err(e) => assert_clean_error(&e, 0.0, 20.0 * t),
            }
        }
        for m in explicit_rk(h) {
            match m.integrate_with(&Kepler, 0.0..20.0 * t, &y0, Options::new().final_only()) {
                Ok(tr) => assert_finite(&tr),
                Err(e) => assert_clean_error(&e, 0.0, 20.0 * t),
            }
        }
        for m in gauss(h) {
            match m.integrate_with(&Kepler, 0.0..20.0 * t, &y0, Options::new().final_only()) {
                Ok(tr) => assert_finite(&tr),
                Err(e) => {
                    assert!(
                        matches!(e.reason, FailureReason::ImplicitSolve { .. } | FailureReason::NonFinite { .. }),
                        "{e}"
                    );
                    assert_clean_error(&e, 0.0, 20.0 * t)
                }
            }
        }
    }
}

#[test]
fn collision_and_blow_up_collapse_the_adaptive_step() {
    // Radial infall from rest at r = 1 reaches r = 0 at t = π/(2√2).
    let t_c = std::f64::consts::PI / (2.0 * 2f64.sqrt());
    let e = Dop853::new(1e-10, 1e-12).integrate(&Kepler, 0.0..3.0, &[1.0, 0.0, 0.0, 0.0]).unwrap_err();
    assert!(matches!(e.reason, FailureReason::StepSizeCollapse { .. } | FailureReason::NonFinite { .. }), "{e}");
    assert_clean_error(&e, 0.0, 3.0);
    assert!((e.t - t_c).abs() < 1e-3, "stopped at {} instead of near {t_c}", e.t);
    // y' = y², y(0) = 1 blows up at t = 1.
    let sys = FnRhs { dim: 1, f: |_t: f64, y: &[f64], dy: &mut [f64]| dy[0] = y[0] * y[0] };
    let e = Dop853::new(1e-10, 1e-10).integrate(&sys, 0.0..2.0, &[1.0]).unwrap_err();
    assert!(matches!(e.reason, FailureReason::StepSizeCollapse { .. }), "{e}");
    assert!((e.t - 1.0).abs() < 1e-6 && e.state[0] > 1e5, "{e}");
}

#[test]
fn newton_failure_is_reported() {
    // y' = y² with h = 2: the midpoint equation y1 = 1 + (1 + y1)²/2 has no real solution
    // (y1² + 3 = 0), and the Gauss stage equations likewise fail; Newton cannot converge.
    let sys = FnJacobian {
        dim: 1,
        f: |_t: f64, y: &[f64], dy: &mut [f64]| dy[0] = y[0] * y[0],
        jac: |_t: f64, y: &[f64], j: &mut [f64]| j[0] = 2.0 * y[0],
    };
    for m in gauss(2.0) {
        let e = m.integrate(&sys, 0.0..4.0, &[1.0]).unwrap_err();
        assert!(matches!(e.reason, FailureReason::ImplicitSolve { newton: true, .. }), "{}: {e}", m.info().name);
        assert_clean_error(&e, 0.0, 4.0);
        assert_eq!(e.state, vec![1.0]);
    }
    // The same with finite-difference Newton (no Jacobian supplied).
    let plain = FnRhs { dim: 1, f: |_t: f64, y: &[f64], dy: &mut [f64]| dy[0] = y[0] * y[0] };
    let e = Gauss::gauss4(2.0).solver(ImplicitSolver::Newton).integrate(&plain, 0.0..4.0, &[1.0]).unwrap_err();
    assert!(matches!(e.reason, FailureReason::ImplicitSolve { newton: true, .. }), "{e}");
}

#[test]
fn a_failing_right_hand_side_stops_every_method() {
    // y' = √(1 − y²)·… defined only for |y| ≤ 1: starting at 0 with y' = 1 it leaves the
    // domain at t ≈ 1.
    let sys = TryFnRhs {
        dim: 1,
        f: |_t: f64, y: &[f64], dy: &mut [f64]| {
            if y[0] > 1.0 {
                return Err(RhsError::new(format!("y = {} outside [-1, 1]", y[0])));
            }
            dy[0] = 1.0;
            Ok(())
        },
    };
    let check = |e: IntegrateError| {
        assert!(matches!(&e.reason, FailureReason::Rhs(r) if r.reason.contains("outside")), "{e}");
        assert_clean_error(&e, 0.0, 2.0);
        // The last accepted state: inside the domain for methods that evaluate beyond the
        // step start, just past it for Euler, whose next evaluation then fails. Yoshida 8's
        // inner drifts overshoot the step by up to 5.5 h, so it stops by t = 0.5.
        assert!(e.state[0] <= 1.1 + 1e-9 && e.t >= 0.5 - 1e-9, "{e}");
    };
    for m in explicit_rk(0.1) {
        check(m.integrate(&sys, 0.0..2.0, &[0.0]).unwrap_err());
    }
    for m in gauss(0.1) {
        check(m.integrate(&sys, 0.0..2.0, &[0.0]).unwrap_err());
    }
    // DOP853 treats a failing trial stage like a failed error test and shrinks the step; the
    // failure is reported when the step collapses at the domain boundary.
    let e = Dop853::new(1e-8, 1e-8).integrate(&sys, 0.0..2.0, &[0.0]).unwrap_err();
    assert!((e.t - 1.0).abs() < 1e-9 && e.state[0] <= 1.0, "{e}");
    check(e);
    // A separable system whose force fails beyond q = 1.
    struct Wall;
    impl Separable for Wall {
        fn dof(&self) -> usize {
            1
        }
        fn drift(&self, p: &[f64], dq: &mut [f64]) {
            dq[0] = p[0];
        }
        fn kick(&self, _t: f64, _q: &[f64], dp: &mut [f64]) {
            dp[0] = 0.0;
        }
        fn try_kick(&self, _t: f64, q: &[f64], dp: &mut [f64]) -> Result<(), RhsError> {
            if q[0] > 1.0 {
                return Err(RhsError::new(format!("y = {} outside [-1, 1]", q[0])));
            }
            dp[0] = 0.0;
            Ok(())
        }
    }
    for m in splittings(0.1) {
        check(m.integrate(&Wall, 0.0..2.0, &[0.0, 1.0]).unwrap_err());
    }
}

#[test]
fn invalid_input_and_step_budget() {
    let sys = Oscillator { omega: 1.0 };
    let invalid = |e: IntegrateError| assert!(matches!(e.reason, FailureReason::InvalidInput(_)), "{e}");
    invalid(Splitting::leapfrog(0.1).integrate(&sys, 0.0..1.0, &[1.0]).unwrap_err());
    invalid(Splitting::leapfrog(0.1).integrate(&sys, 0.0..1.0, &[f64::NAN, 0.0]).unwrap_err());
    invalid(Splitting::leapfrog(0.0).integrate(&sys, 0.0..1.0, &[1.0, 0.0]).unwrap_err());
    invalid(Splitting::leapfrog(-0.1).integrate(&sys, 0.0..1.0, &[1.0, 0.0]).unwrap_err());
    invalid(ExplicitRk::rk4(0.1).integrate(&sys, 0.0..f64::INFINITY, &[1.0, 0.0]).unwrap_err());
    invalid(Gauss::gauss4(f64::NAN).integrate(&sys, 0.0..1.0, &[1.0, 0.0]).unwrap_err());
    let e =
        ExplicitRk::rk4(0.01).integrate_with(&sys, 0.0..1.0, &[1.0, 0.0], Options::new().max_steps(10)).unwrap_err();
    assert_eq!(e.reason, FailureReason::StepLimit { max_steps: 10 });
    // A fixed-step run knows it needs 100 steps: refused before the first one, at the start.
    assert_eq!((e.steps, e.t, e.state.as_slice()), (0, 0.0, &[1.0, 0.0][..]));
    let e = ExplicitRk::rk4(0.01)
        .integrate_with(&sys, 0.0..1.0, &[1.0, 0.0], Options::new().max_steps(100))
        .map(|tr| tr.stats.steps);
    assert_eq!(e, Ok(100), "exactly the budget is enough");
    // A zero-length span returns the initial state.
    let tr = ExplicitRk::rk4(0.01).integrate(&sys, 1.0..1.0, &[1.0, 0.0]).unwrap();
    assert_eq!(tr.len(), 1);
    let _ = <ExplicitRk as Method<Oscillator>>::fixed_step(&ExplicitRk::rk4(0.5));
}

#[test]
fn a_right_hand_side_that_signals_failure_with_nan_is_caught() {
    // Some right-hand sides report failure only by writing NaN (an `eval` without a
    // `try_eval`). Every method must turn that into a typed error with a finite state.
    let sys = FnRhs { dim: 1, f: |_t: f64, y: &[f64], dy: &mut [f64]| dy[0] = if y[0] > 1.0 { f64::NAN } else { 1.0 } };
    let check = |name: &str, r: Result<Trajectory, IntegrateError>| {
        let e = failure(r, name);
        assert!(
            matches!(
                e.reason,
                FailureReason::NonFinite { .. }
                    | FailureReason::StepSizeCollapse { .. }
                    | FailureReason::ImplicitSolve { .. }
            ),
            "{name}: {e}"
        );
        assert_clean_error(&e, 0.0, 2.0);
        assert!(e.t > 0.5 && e.state[0] <= 1.1 + 1e-9, "{name}: {e}");
    };
    for m in explicit_rk(0.1) {
        check(m.info().name, m.integrate(&sys, 0.0..2.0, &[0.0]));
    }
    for m in gauss(0.1) {
        check(m.info().name, m.integrate(&sys, 0.0..2.0, &[0.0]));
    }
    check("DOP853", Dop853::new(1e-8, 1e-8).integrate(&sys, 0.0..2.0, &[0.0]));
}
