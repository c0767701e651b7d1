//! Empirical order of every fixed-step method: the error at a fixed final time is measured at
//! step sizes h and h/2 on problems with exact solutions (oscillator: closed form; pendulum:
//! Jacobi elliptic functions; Kepler e = 0.5: Kepler's equation), and
//! `log2(err(h) / err(h/2))` must be within ±0.3 of the method's order. Step sizes are chosen
//! per method so that the error is in the asymptotic range and far above round-off.
//!
//! DOP853 is adaptive; its order is measured the same way by pinning its step: the first step
//! (`with_h0`) and the largest step (`with_h_max`) are both `h`, and the tolerances are so loose
//! that no step is rejected or shortened, so it takes exactly `t/h` steps of size `h` (checked).
//! The same file exercises the rest of the adaptive and stepping API: `with_h0`, `with_h_max`,
//! and `Solver::set_state`.

use lagrangian::integrate::problems::{Kepler, Oscillator, Pendulum};
use lagrangian::integrate::{Dop853, ExplicitRk, Gauss, Integrate, Method, Options, Rhs, Separable, Splitting, Status};

fn final_error<S: ?Sized, M: Method<S>>(m: &M, sys: &S, y0: &[f64], t: f64, exact: &[f64]) -> f64 {
    let traj = m.integrate_with(sys, 0.0..t, y0, Options::new().final_only()).expect("integrates");
    assert_eq!(traj.last_time(), t);
    traj.last_state().iter().zip(exact).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
}

/// Empirical order from step halving, and the errors, for `make(h)`.
fn order<S: ?Sized, M: Method<S>>(
    make: &dyn Fn(f64) -> M,
    sys: &S,
    y0: &[f64],
    t: f64,
    exact: &[f64],
    h: f64,
) -> (f64, f64, f64) {
    let e1 = final_error(&make(h), sys, y0, t, exact);
    let e2 = final_error(&make(h / 2.0), sys, y0, t, exact);
    ((e1 / e2).log2(), e1, e2)
}

fn check(name: &str, expected: u32, got: (f64, f64, f64)) {
    let (p, e1, e2) = got;
    println!("{name:40} order {p:6.3} (expected {expected}); errors {e1:.3e} -> {e2:.3e}");
    assert!(e2 > 1e-13, "{name}: error {e2:e} too close to round-off to measure an order");
    assert!(
        (p - expected as f64).abs() <= 0.3,
        "{name}: empirical order {p} is not within 0.3 of {expected} (errors {e1:e}, {e2:e})"
    );
}

fn separable_cases<S: Separable + ?Sized>(
    label: &str,
    sys: &S,
    y0: &[f64],
    t: f64,
    exact: &[f64],
    steps: &[(&str, Make, f64)],
) {
    for (name, make, h) in steps {
        let m = make(1.0);
        let ord = m.info().order;
        check(&format!("{label} / {name}"), ord, order(&|h| make(h).compensated(), sys, y0, t, exact, *h));
    }
}

/// DOP853 pinned to the constant step `h` (see the module docs).
fn dop853_fixed(h: f64) -> Dop853 {
    Dop853::new(1e6, 1e6).with_h0(h).with_h_max(h)
}

/// DOP853's empirical order, after checking that the pinned runs took exactly `t/h` steps.
/// The final times are chosen like the step sizes, where the order-8 term dominates: on the
/// pendulum at most final times the measured order is about 9 over h = 1 … 1/8 (the order-8
/// error constant is small there), which is higher, not lower, than promised.
fn dop853_case<S: Rhs + ?Sized>(label: &str, sys: &S, y0: &[f64], t: f64, h: f64, exact: &[f64]) {
    for hh in [h, h / 2.0] {
        let traj = dop853_fixed(hh).integrate_with(sys, 0.0..t, y0, Options::new().final_only()).expect("integrates");
        assert_eq!(traj.stats.steps, (t / hh).round() as usize, "{label}: DOP853 was not pinned to h = {hh}");
        assert_eq!(traj.stats.rejected, 0, "{label}: DOP853 rejected a step at h = {hh}");
    }
    check(&format!("{label} / DOP853"), 8, order(&dop853_fixed, sys, y0, t, exact, h));
}

fn rhs_cases<S: Rhs + ?Sized>(label: &str, sys: &S, y0: &[f64], t: f64, exact: &[f64], hs: [f64; 5]) {
    check(&format!("{label} / Euler"), 1, order(&|h| ExplicitRk::euler(h), sys, y0, t, exact, hs[0]));
    check(&format!("{label} / RK4"), 4, order(&|h| ExplicitRk::rk4(h), sys, y0, t, exact, hs[1]));
    check(&format!("{label} / midpoint"), 2, order(&|h| Gauss::midpoint(h), sys, y0, t, exact, hs[2]));
    check(&format!("{label} / Gauss 4"), 4, order(&|h| Gauss::gauss4(h).compensated(), sys, y0, t, exact, hs[3]));
    check(&format!("{label} / Gauss 6"), 6, order(&|h| Gauss::gauss6(h).compensated(), sys, y0, t, exact, hs[4]));
}

type Make = fn(f64) -> Splitting;
const SPLITTINGS: [(&str, Make); 6] = [
    ("symplectic Euler", Splitting::symplectic_euler),
    ("leapfrog", Splitting::leapfrog),
    ("Yoshida 4", Splitting::yoshida4),
    ("Blanes-Moan 4", Splitting::blanes_moan4),
    ("Yoshida 6", Splitting::yoshida6),
    ("Yoshida 8", Splitting::yoshida8),
];

fn with_steps(hs: [f64; 6]) -> Vec<(&'static str, Make, f64)> {
    SPLITTINGS.iter().zip(hs).map(|((n, m), h)| (*n, *m, h)).collect()
}

#[test]
fn oscillator_orders() {
    let sys = Oscillator { omega: 1.0 };
    let y0 = [1.0, 0.5];
    let t = 50.0; // long enough that Yoshida 8's tiny error stays well above round-off
    let exact = sys.exact(&y0, t);
    separable_cases("oscillator", &sys, &y0, t, &exact, &with_steps([1e-3, 0.05, 0.1, 0.2, 0.2, 0.125]));
    rhs_cases("oscillator", &sys, &y0, t, &exact, [1e-3, 0.05, 0.05, 0.2, 0.4]);
    dop853_case("oscillator", &sys, &y0, t, 0.5, &exact);
}

#[test]
fn pendulum_orders() {
    let sys = Pendulum { omega: 1.0 };
    let y0 = [2.0, 0.0];
    let t = 5.0;
    let exact = sys.exact_from_rest(2.0, t);
    separable_cases("pendulum", &sys, &y0, t, &exact, &with_steps([1e-3, 0.05, 0.1, 0.05, 0.2, 0.125]));
    rhs_cases("pendulum", &sys, &y0, t, &exact, [1e-3, 0.05, 0.05, 0.2, 0.4]);
    dop853_case("pendulum", &sys, &y0, 3.0, 0.5, &sys.exact_from_rest(2.0, 3.0));
}

#[test]
fn kepler_orders() {
    let e = 0.5;
    let y0 = Kepler::pericentre(e);
    let t = 5.0; // not a whole period: at t = 2π the first-order error of symplectic Euler cancels
    let exact = Kepler::exact(e, t);
    separable_cases("kepler e=0.5", &Kepler, &y0, t, &exact, &with_steps([1e-4, 0.01, 0.02, 0.01, 0.05, 0.025]));
    rhs_cases("kepler e=0.5", &Kepler, &y0, t, &exact, [1e-4, 0.01, 0.01, 0.04, 0.08]);
    dop853_case("kepler e=0.5", &Kepler, &y0, 3.0, 0.125, &Kepler::exact(e, 3.0));
}

/// `with_h0` sets the first step exactly; without it Hairer's estimate is used; `with_h_max`
/// caps every step of an ordinary tolerance-driven run (which without the cap takes longer ones).
#[test]
fn dop853_first_and_largest_step() {
    let sys = Pendulum { omega: 1.0 };
    let y0 = [2.0, 0.0];
    let first_step = |m: &Dop853| {
        let mut s = m.solver(&sys, 0.0, &y0, 10.0).expect("valid");
        assert_eq!(s.step().expect("steps"), Status::Stepped);
        s.t()
    };
    let m = Dop853::new(1e-10, 1e-10);
    let estimated = first_step(&m);
    assert_eq!(first_step(&m.clone().with_h0(1.0e-3)), 1.0e-3);
    assert_ne!(estimated, 1.0e-3, "the estimate happened to equal the requested step; pick another");
    let steps = |m: &Dop853| {
        let traj = m.integrate(&sys, 0.0..10.0, &y0).expect("integrates");
        traj.times.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max)
    };
    let free = steps(&m);
    let capped = steps(&m.clone().with_h_max(0.05));
    assert!(free > 0.1, "the uncapped run's largest step {free} is already small; the cap would prove nothing");
    assert!(capped <= 0.05 * (1.0 + 1e-12), "largest step {capped} exceeds h_max = 0.05");
}

/// `Solver::set_state` forgets what the method cached from the old state (DOP853 reuses
/// `f(t, y)` of the last stage as the next step's first, "FSAL"). With the step pinned to `h`
/// (so the step size, which DOP853 carries over, is the same either way), the steps after
/// `set_state` are bit for bit those of a fresh start from the new state; a stale `f(t, y)`
/// would change every one of them.
#[test]
fn set_state_is_a_fresh_start() {
    let sys = Pendulum { omega: 1.0 };
    let m = dop853_fixed(0.125);
    let mut s = m.solver(&sys, 0.0, &[2.0, 0.0], 10.0).expect("valid");
    for _ in 0..5 {
        s.step().expect("steps");
    }
    let (t1, y1) = (1.5, [-0.7, 0.3]);
    s.set_state(t1, &y1);
    assert_eq!((s.t(), s.y()), (t1, &y1[..]));
    let mut fresh = m.solver(&sys, t1, &y1, 10.0).expect("valid");
    for k in 0..20 {
        let (a, b) = (s.step().expect("steps"), fresh.step().expect("steps"));
        assert_eq!(a, b);
        assert_eq!((s.t(), s.y()), (fresh.t(), fresh.y()), "step {k} after set_state differs from a fresh start");
    }
    // A fixed-step method's grid restarts at the new time.
    let g = ExplicitRk::rk4(0.1);
    let mut s = g.solver(&sys, 0.0, &[2.0, 0.0], 10.0).expect("valid");
    for _ in 0..3 {
        s.step().expect("steps");
    }
    s.set_state(0.05, &y1);
    s.step().expect("steps");
    assert!((s.t() - 0.15).abs() < 1e-15, "after set_state at 0.05 the grid should restart there: t = {}", s.t());
}
