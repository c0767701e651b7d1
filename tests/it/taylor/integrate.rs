//! The adaptive Taylor integrator on compiled systems: closed forms, the 50-digit
//! double-pendulum reference, events on the step polynomial, and bad input.

use std::f64::consts::PI;

use lagrangian::compile::TaylorOde;
use lagrangian::integrate::problems::{elliptic_k, DoublePendulum, Kepler, Pendulum};
use lagrangian::integrate::{
    Crossing, Dop853, Event, FailureReason, Integrate, Options, RhsError, Taylor, TaylorSystem,
};
use lagrangian::mechanics::System;
use lagrangian::parse;

fn lagrangian(l: &str, coords: &[&str], params: &[(&str, f64)]) -> TaylorOde {
    System::from_lagrangian(l, coords).unwrap().with_params(params).unwrap().compile_taylor().unwrap()
}

#[test]
fn order_follows_jorba_zou() {
    // p = ⌈−½ ln ε + 1⌉.
    assert_eq!(Taylor::new(1e-16).taylor_order(), (0.5 * 16.0 * 10f64.ln() + 1.0).ceil() as usize);
    assert_eq!(Taylor::new(1e-16).taylor_order(), 20);
    assert_eq!(Taylor::new(1e-6).taylor_order(), 8);
    assert_eq!(Taylor::default().taylor_order(), 20);
}

#[test]
fn harmonic_oscillator_matches_the_closed_form_with_dense_output() {
    let w = 1.7;
    let sys = lagrangian("1/2 m x'^2 - 1/2 k x^2", &["x"], &[("m", 2.0), ("k", 2.0 * w * w)]);
    let y0 = [0.3, 0.5];
    let exact = |t: f64| {
        [y0[0] * (w * t).cos() + y0[1] / w * (w * t).sin(), -y0[0] * w * (w * t).sin() + y0[1] * (w * t).cos()]
    };
    let traj = Taylor::new(1e-15).integrate(&sys, 0.0..100.0, &y0).unwrap();
    let mut worst = 0.0f64;
    for (t, y) in traj.iter() {
        let e = exact(t);
        worst = worst.max((y[0] - e[0]).abs()).max((y[1] - e[1]).abs());
    }
    assert!(worst < 1e-12, "max error over 100 time units: {worst:e}");
    // Steps are long (a Taylor polynomial of order 20 covers a good part of a period) ...
    assert!(traj.stats.steps < 400, "{} steps", traj.stats.steps);
    assert_eq!(traj.stats.rejected, 0);
    // ... and dense output inside them is the step polynomial, as accurate as the steps.
    let method = Taylor::new(1e-15);
    let mut solver = method.solver(&sys, 0.0, &y0, 10.0).unwrap();
    solver.step().unwrap();
    let (t0, t1) = (solver.previous().0, solver.t());
    assert!(t1 - t0 > 0.2, "first step {}", t1 - t0);
    let mut y = [0.0; 2];
    for j in 1..10 {
        let t = t0 + (t1 - t0) * j as f64 / 10.0;
        solver.interpolate(t, &mut y).unwrap();
        let e = exact(t);
        assert!((y[0] - e[0]).abs() < 1e-14 && (y[1] - e[1]).abs() < 1e-14, "dense at {t}: {y:?} vs {e:?}");
    }
}

#[test]
fn kepler_eccentric_orbit_over_1000_periods() {
    // e = 0.9, period 2π, energy −1/2: Hamiltonian form, state sampled once per orbit.
    let sys = System::from_hamiltonian("1/2 (p_x^2 + p_y^2) - 1/sqrt(x^2 + y^2)", &["x", "y"])
        .unwrap()
        .compile_taylor()
        .unwrap();
    let e = 0.9;
    let y0 = Kepler::pericentre(e);
    let orbits = 1000;
    let method = Taylor::new(1e-15);
    let mut solver = method.solver(&sys, 0.0, &y0, 2.0 * PI).unwrap();
    let mut worst_energy = 0.0f64;
    for k in 1..=orbits {
        solver.set_stop_time(2.0 * PI * k as f64);
        while solver.step().unwrap() == lagrangian::integrate::Status::Stepped {}
        let h = Kepler.energy(solver.y());
        worst_energy = worst_energy.max((h + 0.5).abs() / 0.5);
    }
    let y = solver.y();
    let exact = Kepler::exact(e, 2.0 * PI * orbits as f64);
    let pos = ((y[0] - exact[0]).powi(2) + (y[1] - exact[1]).powi(2)).sqrt();
    assert!(worst_energy < 1e-12, "max relative energy error {worst_energy:e}");
    assert!(pos < 1e-8, "position error after {orbits} orbits: {pos:e}");
    let steps = solver.steps();
    assert!(steps < 200 * orbits, "{steps} steps");
}

#[test]
fn double_pendulum_against_the_50_digit_reference() {
    let l = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
             + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
    let params = [("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)];
    let sys = lagrangian(l, &["θ1", "θ2"], &params);
    let reference = DoublePendulum::REFERENCE_T10;
    let mut errors = Vec::new();
    for tol in [1e-8, 1e-11, 1e-14] {
        let traj =
            Taylor::new(tol).integrate_with(&sys, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only()).unwrap();
        let y = traj.last_state();
        let err = (0..4).map(|i| (y[i] - reference[i]).abs()).fold(0.0, f64::max);
        errors.push(err);
    }
    // Chaos amplifies local errors by about 1e8 by t = 10; the error still falls with tol.
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    assert!(errors[2] < 1e-5, "{errors:?}");
    // The energy is conserved along the way at the tight tolerance.
    let dp = DoublePendulum::default();
    let traj = Taylor::new(1e-15).integrate(&sys, 0.0..10.0, &DoublePendulum::Y0).unwrap();
    let e0 = dp.energy(&DoublePendulum::Y0);
    let drift = traj.iter().map(|(_, y)| (dp.energy(y) - e0).abs() / e0.abs()).fold(0.0, f64::max);
    assert!(drift < 1e-12, "energy drift {drift:e}");
}

/// One component of the dense output (what the MEGNO quadrature reads) is that component of
/// `Solver::interpolate`, bit for bit, at every point of every step; before the first step and
/// after `set_state` there is none.
#[test]
fn one_component_of_the_dense_output_is_interpolate_s() {
    use lagrangian::integrate::Status;
    let l = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
             + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
    let params = [("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)];
    let sys = lagrangian(l, &["θ1", "θ2"], &params);
    let method = Taylor::new(1e-9);
    let mut solver = method.solver(&sys, 0.0, &DoublePendulum::Y0, 3.0).unwrap();
    assert_eq!(solver.work().dense_component(0, 0.5), None);
    let mut y = [0.0; 4];
    let mut points = 0;
    loop {
        let status = solver.step().unwrap();
        let (t0, t1) = (solver.previous().0, solver.t());
        for x in [-0.9, -0.5, 0.0, 0.3, 0.9, 1.0] {
            let t = 0.5 * (t0 + t1) + 0.5 * (t1 - t0) * x;
            solver.interpolate(t, &mut y).unwrap();
            for (i, yi) in y.iter().enumerate() {
                let one = solver.work().dense_component(i, (t - t0) / (t1 - t0)).unwrap();
                assert_eq!(one.to_bits(), yi.to_bits(), "component {i} at t = {t}");
                points += 1;
            }
        }
        assert_eq!(solver.work().dense_component(4, 0.5), None, "no fifth component");
        if status == Status::Finished {
            break;
        }
    }
    assert!(points > 100, "{points} points");
    let end = solver.y().to_vec();
    solver.set_state(3.0, &end);
    assert_eq!(solver.work().dense_component(0, 0.5), None);
}

#[test]
fn pendulum_turning_points_are_half_periods_apart() {
    // θ'' = −sin θ released from rest at θ0 = 2.5: turning points (θ' = 0) every T/2 with
    // T = 4 K(sin²(θ0/2)), located on the step polynomial.
    let sys = lagrangian("1/2 θ'^2 + cos(θ)", &["θ"], &[]);
    let theta0: f64 = 2.5;
    let period = 4.0 * elliptic_k((0.5 * theta0).sin().powi(2));
    assert!((period - Pendulum { omega: 1.0 }.period(theta0)).abs() < 1e-14);
    let opts = Options::new().final_only().event(Event::new(|_, y: &[f64]| y[1]).crossing(Crossing::Either));
    let traj = Taylor::new(1e-15).integrate_with(&sys, 0.0..20.0 * period + 0.1, &[theta0, 0.0], opts).unwrap();
    // The start itself (θ' = 0 at t = 0) is not a crossing; then one every half period.
    assert_eq!(traj.events.len(), 40, "{:?}", traj.events.iter().map(|e| e.t).collect::<Vec<_>>());
    for (j, ev) in traj.events.iter().enumerate() {
        let expected = (j + 1) as f64 * period / 2.0;
        assert!((ev.t - expected).abs() < 1e-11, "turning point {j}: {} vs {expected}", ev.t);
        assert!((ev.state[0].abs() - theta0).abs() < 1e-12);
    }
}

#[test]
fn first_order_system_from_expressions() {
    // Logistic growth y' = y (1 − y): y = 1 / (1 + 9 e^{−t}) from y(0) = 0.1, with an explicit
    // time dependence in a second component z' = cos(t) (z = sin t).
    let f = [parse("y (1 - y)").unwrap(), parse("cos(t)").unwrap()];
    let sys = TaylorOde::from_exprs(&f, &["y", "z"], &[]).unwrap();
    let traj = Taylor::new(1e-14).integrate(&sys, 0.0..8.0, &[0.1, 0.0]).unwrap();
    for (t, y) in traj.iter() {
        assert!((y[0] - 1.0 / (1.0 + 9.0 * (-t).exp())).abs() < 1e-13, "t = {t}");
        assert!((y[1] - t.sin()).abs() < 1e-13, "t = {t}");
    }
    // Backwards in time too.
    let back = Taylor::new(1e-14).integrate(&sys, 8.0..0.0, traj.last_state()).unwrap();
    assert!((back.last_state()[0] - 0.1).abs() < 1e-12);
}

#[test]
fn compensated_summation_keeps_long_runs_closer() {
    let sys = lagrangian("1/2 x'^2 - 1/2 x^2", &["x"], &[]);
    let t1 = 2000.0 * PI;
    let plain = Taylor::new(1e-16).integrate_with(&sys, 0.0..t1, &[1.0, 0.0], Options::new().final_only()).unwrap();
    let comp = Taylor::new(1e-16)
        .compensated()
        .integrate_with(&sys, 0.0..t1, &[1.0, 0.0], Options::new().final_only())
        .unwrap();
    let err = |y: &[f64]| (y[0] - 1.0).abs().max(y[1].abs());
    assert!(err(comp.last_state()) < 1e-11, "{:e}", err(comp.last_state()));
    assert!(err(comp.last_state()) <= err(plain.last_state()) * 1.5);
}

#[test]
fn bad_tolerances_are_typed_errors() {
    let sys = lagrangian("1/2 x'^2 - 1/2 x^2", &["x"], &[]);
    for tol in [0.0, -1e-8, f64::NAN, f64::INFINITY, 1e-25] {
        let err = Taylor::new(tol).integrate(&sys, 0.0..1.0, &[1.0, 0.0]).unwrap_err();
        assert!(matches!(err.reason, FailureReason::InvalidInput(_)), "tol {tol}: {err}");
        assert_eq!(err.steps, 0);
    }
}

#[test]
fn a_blow_up_ends_with_a_typed_error_not_a_hang() {
    // y' = y² from y(0) = 1 blows up at t = 1.
    let sys = TaylorOde::from_exprs(&[parse("y^2").unwrap()], &["y"], &[]).unwrap();
    let err = Taylor::new(1e-12).integrate(&sys, 0.0..2.0, &[1.0]).unwrap_err();
    assert!(
        matches!(
            err.reason,
            FailureReason::StepSizeCollapse { .. } | FailureReason::NonFinite { .. } | FailureReason::Rhs(_)
        ),
        "{err}"
    );
    assert!(err.t > 0.99 && err.t < 1.0 + 1e-12, "{err}");
    assert!(err.steps < 10_000, "{} steps", err.steps);
}

/// `y(t) = y₀ + t`, except that every coefficient from order 2 on is the given non-finite
/// value, and this system names no order (`TaylorSystem::non_finite` left at its default).
struct BadSeries(f64);

impl TaylorSystem for BadSeries {
    fn dim(&self) -> usize {
        1
    }
    fn scratch_len(&self, order: usize) -> usize {
        order + 1
    }
    fn taylor_coefficients(&self, _t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), RhsError> {
        buf[0] = y[0];
        buf[1] = 1.0;
        buf[2..=order].fill(self.0);
        Ok(())
    }
}

#[test]
fn non_finite_coefficients_are_typed_failures_named_by_the_system() {
    // The integrator's default failure, before any step: NaN (ignored by the norms, so the
    // step size is finite) and ∞ (which makes the step size zero, still reported as the
    // non-finite coefficient it is, not as a collapse).
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let err = Taylor::new(1e-12).integrate(&BadSeries(bad), 0.0..1.0, &[0.0]).unwrap_err();
        assert!(matches!(err.reason, FailureReason::NonFinite { component: 0 }), "{bad}: {err}");
        assert_eq!(err.steps, 0);
    }
    // A compiled system names the order and the state:
    // y' = exp(y) at y = 800 overflows at order 1.
    let sys = TaylorOde::from_exprs(&[parse("exp(y)").unwrap()], &["y"], &[]).unwrap();
    let err = Taylor::new(1e-12).integrate(&sys, 0.0..1.0, &[800.0]).unwrap_err();
    assert!(matches!(err.reason, FailureReason::Rhs(_)), "{err}");
    assert!(err.to_string().contains("non-finite Taylor coefficient of order 1"), "{err}");
}

#[test]
fn singular_mass_matrix_and_abs_kink_are_typed_errors() {
    // W = x², singular at x = 0.
    let sys = lagrangian("1/2 x^2 x'^2 - x", &["x"], &[]);
    let err = Taylor::new(1e-12).integrate(&sys, 0.0..1.0, &[0.0, 1.0]).unwrap_err();
    assert!(err.to_string().contains("singular"), "{err}");
    // A force with |x| at its kink x = 0.
    let f = [parse("v").unwrap(), parse("-abs(y)").unwrap()];
    let sys = TaylorOde::from_exprs(&f, &["y", "v"], &[]).unwrap();
    let err = Taylor::new(1e-12).integrate(&sys, 0.0..1.0, &[0.0, 1.0]).unwrap_err();
    assert!(err.to_string().contains("abs"), "{err}");
    // A kink crossed inside a step (y' = v, v' = −|y| from y = 0.5 falling through 0) is
    // reported, not summed over with the series of the wrong branch.
    let err = Taylor::new(1e-12).integrate(&sys, 0.0..5.0, &[0.5, -1.0]).unwrap_err();
    assert!(err.to_string().contains("kink"), "{err}");
    assert!(err.t < 0.5, "{err}");
}

/// Each of the later built-ins in a position-dependent mass, so the right-hand side holds both
/// the function and its derivative: the Taylor method against DOP853 on the same system
/// (compiled by the tape route the other methods use), from the same state.
#[test]
fn later_builtins_in_a_mass_agree_with_dop853() {
    let masses = [
        "2 + asinh(x/2)",
        "acosh(2 + x^2)",
        "2 + atanh(x/2)",
        "sec(x/2)",
        "csc(1 + x/4)",
        "coth(2 + x/4)",
        "2 + erf(x)",
    ];
    for m in masses {
        let sys = System::from_lagrangian(&format!("1/2 ({m}) x'^2 - 1/2 x^2"), &["x"]).unwrap();
        let y0 = [0.8, 0.3];
        let taylor = sys.compile_taylor().unwrap();
        let tr = Taylor::new(1e-15).integrate_with(&taylor, 0.0..6.0, &y0, Options::new().final_only()).unwrap();
        let rhs = sys.compile_rhs().unwrap();
        let dp = Dop853::new(1e-13, 1e-13).integrate_with(&rhs, 0.0..6.0, &y0, Options::new().final_only()).unwrap();
        let (a, b) = (tr.last_state(), dp.last_state());
        for i in 0..2 {
            assert!((a[i] - b[i]).abs() < 1e-9, "mass {m}: Taylor {a:?} vs DOP853 {b:?}");
        }
        // The function reached the Taylor tape itself, not only through its derivative.
        let name = m.split('(').next().unwrap().rsplit(' ').next().unwrap();
        assert!(
            format!("{}", taylor.tape()).contains(&format!("= {name}(")),
            "mass {m}: no `{name}` in\n{}",
            taylor.tape()
        );
    }
}

/// acosh is real only from 1 up and atanh only inside (−1, 1): outside, their float value is
/// NaN (or ±∞ at atanh(±1)), and the Taylor method refuses the series with a typed failure,
/// as DOP853 refuses the same right-hand side, never a finite trajectory. Below −1 the acosh
/// recurrence's root `√(x² − 1)` would be real, so its order-0 value is taken as
/// `√(x − 1) √(x + 1)`, NaN there too.
#[test]
fn acosh_and_atanh_outside_their_domain_are_typed_failures() {
    for (f, y0) in [("acosh(y)", 0.5), ("acosh(y)", -2.0), ("atanh(y)", 1.5), ("atanh(y)", -1.0)] {
        let sys = TaylorOde::from_exprs(&[parse(f).unwrap()], &["y"], &[]).unwrap();
        let err = Taylor::new(1e-12).integrate(&sys, 0.0..1.0, &[y0]).unwrap_err();
        assert!(err.to_string().contains("non-finite Taylor coefficient of order 1"), "y' = {f}, y = {y0}: {err}");
        // The same function as a mass, x'' from (f(x) x')' = …: both methods refuse.
        let sys = System::from_lagrangian(&format!("1/2 {} x'^2 - 1/2 x^2", f.replace('y', "x")), &["x"]).unwrap();
        let y0 = [y0, 0.5];
        let taylor = sys.compile_taylor().unwrap();
        assert!(Taylor::new(1e-12).integrate(&taylor, 0.0..1.0, &y0).is_err(), "Taylor, mass {f} at {y0:?}");
        let rhs = sys.compile_rhs().unwrap();
        assert!(Dop853::new(1e-10, 1e-10).integrate(&rhs, 0.0..1.0, &y0).is_err(), "DOP853, mass {f} at {y0:?}");
    }
    // Every coefficient of acosh(t) at t = −2 is NaN, not only the value.
    let tape = lagrangian::compile::Tape::compile(&[parse("acosh(t)").unwrap()], &["t"], &[]).unwrap();
    let tt = lagrangian::compile::TaylorTape::new(&tape);
    let s = 6;
    let mut c = vec![0.0; tt.n_rows() * s];
    tt.expand(&mut c, s, 5, |k, c| c[k] = [-2.0, 1.0, 0.0, 0.0, 0.0, 0.0][k]).unwrap();
    let row = tt.output_row(0);
    assert!(c[row * s..(row + 1) * s].iter().all(|v| v.is_nan()), "{:?}", &c[row * s..(row + 1) * s]);
}

/// A compiled system whose every expansion is written as if for the first time: it forwards
/// `taylor_coefficients` alone, so the integrator's `taylor_coefficients_again` is the
/// default, which fills the whole buffer.
struct Fresh<'a>(&'a TaylorOde);

impl TaylorSystem for Fresh<'_> {
    fn dim(&self) -> usize {
        TaylorSystem::dim(self.0)
    }
    fn scratch_len(&self, order: usize) -> usize {
        TaylorSystem::scratch_len(self.0, order)
    }
    fn taylor_coefficients(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), RhsError> {
        self.0.taylor_coefficients(t, y, order, buf)
    }
    fn check_step(&self, scratch: &[f64], order: usize, h: f64) -> Result<(), RhsError> {
        self.0.check_step(scratch, order, h)
    }
}

#[test]
fn expansions_into_the_last_buffer_equal_fresh_ones() {
    // A driven, damped pendulum (constants in the tape, and the time as an input row whose
    // higher orders a reused buffer keeps) and the double pendulum (`W q'' = F`, whose solve
    // has its own scratch in the buffer), interpreted and on native code (from the 64th
    // expansion on).
    let driven = TaylorOde::from_exprs(
        &[parse("v").unwrap(), parse("-9.81 sin(x) + 0.3 cos(1.1 t) - 0.05 v").unwrap()],
        &["x", "v"],
        &[],
    )
    .unwrap();
    let double = lagrangian(
        "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)",
        &["θ1", "θ2"],
        &[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)],
    );
    let bits = |tr: &lagrangian::integrate::Trajectory| {
        tr.iter().map(|(t, y)| (t.to_bits(), y.iter().map(|v| v.to_bits()).collect::<Vec<_>>())).collect::<Vec<_>>()
    };
    for (sys, y0) in [(&driven, &[1.0, 0.0][..]), (&double, &DoublePendulum::Y0[..])] {
        for native in [false, true] {
            let ode = sys.clone().with_native(native);
            for tol in [1e-6, 1e-12] {
                let m = Taylor::new(tol).compensated();
                let again = m.integrate(&ode, 0.0..10.0, y0).unwrap();
                let fresh = m.integrate(&Fresh(&ode), 0.0..10.0, y0).unwrap();
                assert!(again.stats.steps > 100, "{} steps", again.stats.steps);
                assert_eq!(bits(&again), bits(&fresh), "tol {tol:e}, native {native}");
            }
        }
    }
}
