//! Empirical order of every fixed-step method: the error at a fixed final time is measured at
//! step sizes h and h/2 on problems with exact solutions (oscillator: closed form; pendulum:
//! Jacobi elliptic functions; Kepler e = 0.5: Kepler's equation), and
//! `log2(err(h) / err(h/2))` must be within ±0.3 of the method's order. Step sizes are chosen
//! per method so that the error is in the asymptotic range and far above round-off.

use lagrangian::integrate::problems::{Kepler, Oscillator, Pendulum};
use lagrangian::integrate::{ExplicitRk, Gauss, Integrate, Method, Options, Rhs, Separable, Splitting};

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
}

#[test]
fn pendulum_orders() {
    let sys = Pendulum { omega: 1.0 };
    let y0 = [2.0, 0.0];
    let t = 5.0;
    let exact = sys.exact_from_rest(2.0, t);
    separable_cases("pendulum", &sys, &y0, t, &exact, &with_steps([1e-3, 0.05, 0.1, 0.05, 0.2, 0.125]));
    rhs_cases("pendulum", &sys, &y0, t, &exact, [1e-3, 0.05, 0.05, 0.2, 0.4]);
}

#[test]
fn kepler_orders() {
    let e = 0.5;
    let y0 = Kepler::pericentre(e);
    let t = 5.0; // not a whole period: at t = 2π the first-order error of symplectic Euler cancels
    let exact = Kepler::exact(e, t);
    separable_cases("kepler e=0.5", &Kepler, &y0, t, &exact, &with_steps([1e-4, 0.01, 0.02, 0.01, 0.05, 0.025]));
    rhs_cases("kepler e=0.5", &Kepler, &y0, t, &exact, [1e-4, 0.01, 0.01, 0.04, 0.08]);
}
