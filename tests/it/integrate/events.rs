//! Events (zero crossings located on the step interpolant), dense output, DOP853's tolerance
//! behaviour and the step-by-step solver.

use std::f64::consts::PI;

use lagrangian::integrate::problems::{elliptic_k, DoublePendulum, HenonHeiles, Kepler, Oscillator, Pendulum};
use lagrangian::integrate::{
    Crossing, Dop853, Event, Gauss, Integrate, Options, Separable, SeparableRhs, Splitting, Status, StopReason,
};

#[test]
fn oscillator_zero_crossings_are_located() {
    // q = cos t crosses zero at t = π/2 + kπ (falling for even k).
    let sys = Oscillator { omega: 1.0 };
    let y0 = [1.0, 0.0];
    let opts = || Options::new().event(Event::new(|_t, y: &[f64]| y[0]).crossing(Crossing::Falling));
    let expect = |k: usize| PI / 2.0 + 2.0 * PI * k as f64;
    let tr = Dop853::new(1e-12, 1e-14).integrate_with(&sys, 0.0..20.0, &y0, opts()).unwrap();
    assert_eq!(tr.events.len(), 3); // π/2, 5π/2, 9π/2 < 20 < 13π/2
    for (k, ev) in tr.events.iter().enumerate() {
        assert!((ev.t - expect(k)).abs() < 1e-10, "DOP853 event {k} at {}", ev.t);
        assert!(ev.state[0].abs() < 1e-10 && ev.state[1] < 0.0);
    }
    // Fixed-step methods interpolate with cubic Hermite polynomials (error O(h⁴)).
    let tr = Gauss::gauss6(0.05).integrate_with(&sys, 0.0..20.0, &y0, opts()).unwrap();
    assert_eq!(tr.events.len(), 3);
    for (k, ev) in tr.events.iter().enumerate() {
        assert!((ev.t - expect(k)).abs() < 1e-9, "Gauss 6 event {k} at {}", ev.t);
    }
    let tr = Splitting::yoshida8(0.05).integrate_with(&sys, 0.0..20.0, &y0, opts()).unwrap();
    assert_eq!(tr.events.len(), 3);
    for (k, ev) in tr.events.iter().enumerate() {
        assert!((ev.t - expect(k)).abs() < 1e-9, "Yoshida 8 event {k} at {}", ev.t);
    }
    // Rising crossings only: 3π/2 + 2kπ.
    let tr = Dop853::new(1e-12, 1e-14)
        .integrate_with(
            &sys,
            0.0..20.0,
            &y0,
            Options::new().event(Event::new(|_t, y: &[f64]| y[0]).crossing(Crossing::Rising)),
        )
        .unwrap();
    let times: Vec<f64> = tr.events.iter().map(|e| e.t).collect();
    assert_eq!(times.len(), 3);
    assert!((times[0] - 1.5 * PI).abs() < 1e-10);
}

#[test]
fn stop_event_ends_at_the_quarter_period_of_the_pendulum() {
    // Released from rest at θ0 = 2, the pendulum first passes θ = 0 at a quarter period K(k).
    let sys = Pendulum { omega: 1.0 };
    let quarter = elliptic_k((1.0f64).sin().powi(2));
    let opts = || Options::new().event(Event::new(|_t, y: &[f64]| y[0]).stop());
    let tr = Dop853::new(1e-13, 1e-15).integrate_with(&sys, 0.0..100.0, &[2.0, 0.0], opts()).unwrap();
    match tr.stop {
        StopReason::Event { index: 0, t } => assert!((t - quarter).abs() < 1e-10, "{t} vs {quarter}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(tr.last_time(), tr.events[0].t);
    assert!(tr.last_state()[0].abs() < 1e-12);
    let tr = Splitting::yoshida8(0.02).integrate_with(&sys, 0.0..100.0, &[2.0, 0.0], opts()).unwrap();
    assert!((tr.last_time() - quarter).abs() < 1e-7);
    // Backwards in time the first crossing is at −K.
    let tr = Dop853::new(1e-13, 1e-15).integrate_with(&sys, 0.0..-100.0, &[2.0, 0.0], opts()).unwrap();
    assert!((tr.last_time() + quarter).abs() < 1e-10);
}

#[test]
fn henon_heiles_poincare_section() {
    // Section x = 0 with p_x > 0 (x rising). Every recorded point lies on the section and on
    // the energy surface.
    let y0 = [0.0, 0.1, 0.4, 0.05];
    let e0 = HenonHeiles.energy(&y0);
    let opts = || Options::new().final_only().event(Event::new(|_t, y: &[f64]| y[0]).crossing(Crossing::Rising));
    let tr = Dop853::new(1e-12, 1e-14).integrate_with(&HenonHeiles, 0.0..300.0, &y0, opts()).unwrap();
    assert!(tr.events.len() > 30, "{} section points", tr.events.len());
    for ev in &tr.events {
        assert!(ev.state[0].abs() < 1e-12 && ev.state[2] > 0.0);
        assert!((HenonHeiles.energy(&ev.state) - e0).abs() < 1e-11);
    }
    assert_eq!(tr.len(), 2, "final_only keeps the initial and final states");
    // The same section from Yoshida 8: same number of crossings, the first points agree.
    let ys = Splitting::yoshida8(0.01).integrate_with(&HenonHeiles, 0.0..300.0, &y0, opts()).unwrap();
    assert_eq!(ys.events.len(), tr.events.len());
    for (a, b) in ys.events.iter().zip(&tr.events).take(10) {
        assert!((a.t - b.t).abs() < 1e-10 && (a.state[1] - b.state[1]).abs() < 1e-10);
    }
}

#[test]
fn dop853_tolerance_and_dense_output() {
    // Error at t = 2π on Kepler e = 0.5 follows the tolerance.
    let y0 = Kepler::pericentre(0.5);
    let exact = Kepler::exact(0.5, 2.0 * PI);
    let mut last = f64::INFINITY;
    for tol in [1e-6, 1e-9, 1e-12] {
        let tr = Dop853::new(tol, tol * 1e-2).integrate(&Kepler, 0.0..2.0 * PI, &y0).unwrap();
        let err = tr.last_state().iter().zip(&exact).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 100.0 * tol && err < last / 10.0, "tol {tol:e}: error {err:e}");
        last = err;
        // Compensated summation changes only the rounding of the state update.
        let tc = Dop853::new(tol, tol * 1e-2).compensated().integrate(&Kepler, 0.0..2.0 * PI, &y0).unwrap();
        let errc = tc.last_state().iter().zip(&exact).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(errc < 100.0 * tol, "compensated, tol {tol:e}: error {errc:e}");
    }
    // Dense output between steps is accurate to the tolerance (7th-order interpolant).
    let sys = Oscillator { omega: 1.0 };
    let m = Dop853::new(1e-12, 1e-14);
    let mut s = m.solver(&sys, 0.0, &[1.0, 0.0], 10.0).unwrap();
    let mut worst: f64 = 0.0;
    let mut out = [0.0; 2];
    loop {
        let status = s.step().unwrap();
        let (t0, _) = s.previous();
        let t1 = s.t();
        for k in 1..8 {
            let t = t0 + (t1 - t0) * k as f64 / 8.0;
            s.interpolate(t, &mut out).unwrap();
            worst = worst.max((out[0] - t.cos()).abs()).max((out[1] + t.sin()).abs());
        }
        if status == Status::Finished {
            break;
        }
    }
    assert!(worst < 2e-11, "dense output error {worst:e}");
    assert!(s.steps() > 10);
}

#[test]
fn double_pendulum_against_the_reference() {
    // The 50-digit reference at t = 10; chaos amplifies errors ~1e8, so a tolerance of 1e-13
    // still leaves ~1e-5 at t = 10. The energy is conserved to near the tolerance.
    let dp = DoublePendulum::default();
    let tr = Dop853::new(1e-13, 1e-15)
        .integrate_with(&dp, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only())
        .unwrap();
    let err =
        tr.last_state().iter().zip(&DoublePendulum::REFERENCE_T10).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let de = (dp.energy(tr.last_state()) - dp.energy(&DoublePendulum::Y0)).abs();
    println!("DOP853 double pendulum error {err:.2e}, energy error {de:.2e}, steps {}", tr.stats.steps);
    assert!(err < 3e-4, "error {err:e}");
    assert!(de < 1e-10, "energy error {de:e}");
    let tr =
        Gauss::gauss6(2e-3).integrate_with(&dp, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only()).unwrap();
    let err =
        tr.last_state().iter().zip(&DoublePendulum::REFERENCE_T10).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    println!("Gauss 6 (h = 2e-3) double pendulum error {err:.2e}");
    assert!(err < 5e-5, "error {err:e}");
}

#[test]
fn runge_kutta_on_a_separable_system_matches_splitting() {
    // The adapter SeparableRhs makes a separable system an Rhs; both routes converge to the
    // exact pendulum solution.
    let sys = Pendulum { omega: 1.0 };
    let exact = sys.exact_from_rest(1.0, 3.0);
    let a = Dop853::new(1e-12, 1e-14).integrate(&SeparableRhs(&sys), 0.0..3.0, &[1.0, 0.0]).unwrap();
    let b = Splitting::yoshida6(0.01).integrate(&sys, 0.0..3.0, &[1.0, 0.0]).unwrap();
    assert!((a.last_state()[0] - exact[0]).abs() < 1e-10);
    assert!((b.last_state()[0] - exact[0]).abs() < 1e-10);
    assert_eq!(sys.dof(), 1);
    // Output thinning: every 10th of 300 steps plus the endpoints.
    let c = Splitting::leapfrog(0.01).integrate_with(&sys, 0.0..3.0, &[1.0, 0.0], Options::new().every(10)).unwrap();
    assert_eq!(c.len(), 31);
    assert!((c.times[1] - 0.1).abs() < 1e-12 && c.last_time() == 3.0);
}
