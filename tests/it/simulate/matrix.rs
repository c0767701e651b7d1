//! Every method × every kind of system: the right answer against a closed-form solution, or a
//! typed refusal that names methods which do run the system (and those methods do). No cell
//! may silently drop a force, a dissipation term, a driver or a constraint.
//!
//! The closed forms are derived by hand (linear ODEs with constant coefficients):
//! * conservative `x'' = −x`, `x(0) = 1`, `x'(0) = 0`: `x = cos t`;
//! * forced by `Q = cos 2t` and driven by `L ∋ x cos 2t` (the same equation
//!   `x'' + x = cos 2t`): `x = (4/3) cos t − (1/3) cos 2t`;
//! * Rayleigh-damped, `R = ½ c x'²`: `x'' + c x' + x = 0`, `x = e^{−ct/2} (cos ω t + c/(2ω) sin ω t)`
//!   with `ω = √(1 − c²/4)`;
//! * constrained to the line `y = x` with `L = ½(x'² + y'²) − ½(x² + y²)`: on the line `s'' = −s`,
//!   so `x = y = cos t` from `(1, 1)` at rest;
//! * the same `L` under the velocity constraint `y' − x' = 0` (Lagrange–d'Alembert, multiplier
//!   μ along `a = (−1, 1)`): `x'' + x = −μ`, `y'' + y = μ`, `x'' = y''`, so from `(1, 1)` at rest
//!   `x = y` and `x'' = −x`: `x = cos t`. With `y` free of the potential instead (`½ x²` only),
//!   `x'' + x = −μ`, `y'' = μ`, `x'' = y''` give `2x'' = −x`: `x = cos(t/√2)`, which is the case
//!   below (a constraint force that is not zero);
//! * `H = ½ p² + ½ x²` given directly (Hamiltonian, separable): `x = cos t`, `p = −sin t`;
//! * `L = ½x'² − ½x² − ½(y − x)²`, where y has no velocity: eliminated (y = x), `x = cos t`;
//! * first-order `L = x y' − ½ (x² + y²)`: `y' = x`, `x' = −y`, so `x = cos t`, `y = sin t`.

use lagrangian::mechanics::System;
use lagrangian::simulate::{self, Family, MethodId, RunOptions, Sampling, SimulateError};

const T1: f64 = 2.0;

struct Case {
    name: &'static str,
    system: fn() -> System,
    /// The initial state for a layout with velocities and for one with momenta.
    y0_velocities: &'static [f64],
    y0_momenta: &'static [f64],
    /// The first coordinate at `t`.
    exact: fn(f64) -> f64,
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "conservative",
            system: || System::from_lagrangian("1/2 x'^2 - 1/2 x^2", &["x"]).unwrap(),
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, 0.0],
            exact: f64::cos,
        },
        Case {
            name: "forced",
            system: || {
                System::from_lagrangian("1/2 x'^2 - 1/2 x^2", &["x"]).unwrap().with_force("x", "cos(2 t)").unwrap()
            },
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, 0.0],
            exact: |t| 4.0 / 3.0 * t.cos() - (2.0 * t).cos() / 3.0,
        },
        Case {
            name: "rayleigh",
            system: || {
                System::from_lagrangian("1/2 x'^2 - 1/2 x^2", &["x"])
                    .unwrap()
                    .with_rayleigh("1/2 c x'^2")
                    .unwrap()
                    .with_params(&[("c", 0.5)])
                    .unwrap()
            },
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, 0.0],
            exact: |t| {
                let c = 0.5_f64;
                let w = (1.0 - c * c / 4.0).sqrt();
                (-c * t / 2.0).exp() * ((w * t).cos() + c / (2.0 * w) * (w * t).sin())
            },
        },
        Case {
            name: "driven",
            system: || System::from_lagrangian("1/2 x'^2 - 1/2 x^2 + x cos(2 t)", &["x"]).unwrap(),
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, 0.0],
            exact: |t| 4.0 / 3.0 * t.cos() - (2.0 * t).cos() / 3.0,
        },
        Case {
            name: "constrained",
            system: || {
                System::from_lagrangian("1/2 (x'^2 + y'^2) - 1/2 (x^2 + y^2)", &["x", "y"])
                    .unwrap()
                    .with_constraint("y - x")
                    .unwrap()
            },
            y0_velocities: &[1.0, 1.0, 0.0, 0.0],
            y0_momenta: &[1.0, 1.0, 0.0, 0.0],
            exact: f64::cos,
        },
        Case {
            name: "velocity-constrained",
            system: || {
                System::from_lagrangian("1/2 (x'^2 + y'^2) - 1/2 x^2", &["x", "y"])
                    .unwrap()
                    .with_velocity_constraint("y' - x'")
                    .unwrap()
            },
            y0_velocities: &[1.0, 1.0, 0.0, 0.0],
            y0_momenta: &[1.0, 1.0, 0.0, 0.0],
            exact: |t| (t / std::f64::consts::SQRT_2).cos(),
        },
        Case {
            name: "hamiltonian",
            system: || System::from_hamiltonian("1/2 p_x^2 + 1/2 x^2", &["x"]).unwrap(),
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, 0.0],
            exact: f64::cos,
        },
        Case {
            // x' = p + x, p' = −(p + x) − x, so x'' = −x: x = cos t from x = 1, p = −1.
            name: "non-separable H",
            system: || System::from_hamiltonian("1/2 (p_x + x)^2 + 1/2 x^2", &["x"]).unwrap(),
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, -1.0],
            exact: f64::cos,
        },
        Case {
            // y has no velocity (Remark 3.1): ∂L/∂y = x − y = 0 gives y = x, and the reduced
            // L = ½x'² − ½x² runs with the state (x, x'): x = cos t.
            name: "velocity-free coordinate",
            system: || System::from_lagrangian("1/2 x'^2 - 1/2 x^2 - 1/2 (y - x)^2", &["x", "y"]).unwrap(),
            y0_velocities: &[1.0, 0.0],
            y0_momenta: &[1.0, 0.0],
            exact: f64::cos,
        },
        Case {
            name: "first-order",
            system: || System::from_lagrangian("x y' - 1/2 (x^2 + y^2)", &["x", "y"]).unwrap(),
            // The state of a first-order L is z alone; the velocity slots are filled in.
            y0_velocities: &[1.0, 0.0, 0.0, 0.0],
            y0_momenta: &[1.0, 0.0, 0.0, 0.0],
            exact: f64::cos,
        },
    ]
}

/// How close a method must come at `T1` with `dt = 1e-3` (or its default tolerance):
/// a generous multiple of `C h^p` for its order, so a dropped term (an O(1) error) fails.
fn bound(m: MethodId) -> f64 {
    match m.order() {
        Some(1) => 2e-2,
        Some(2) => 1e-4,
        _ => 1e-6,
    }
}

fn options(m: MethodId) -> RunOptions {
    let mut o = RunOptions::new(m, 0.0, T1);
    if m.family() != Family::Adaptive {
        o.dt = Some(1e-3);
    }
    o.sampling = Sampling::Final;
    o
}

#[test]
fn every_method_on_every_kind_of_system_is_right_or_refused_with_working_alternatives() {
    let mut ran = 0;
    let mut refused = 0;
    for case in cases() {
        let sys = (case.system)();
        for m in MethodId::all() {
            let cell = format!("{} × {}", m.name(), case.name);
            match simulate::compile_system(&sys, m, &[]) {
                Ok(c) => {
                    let velocities = c.state.iter().any(|n| n.ends_with('\''));
                    let y0 = if velocities { case.y0_velocities } else { case.y0_momenta };
                    let tr = simulate::integrate(&c, y0, &options(m), &mut |_| {})
                        .unwrap_or_else(|e| panic!("{cell}: accepted but failed: {e}"));
                    let x = tr.last_state().unwrap()[0];
                    let err = (x - (case.exact)(T1)).abs();
                    assert!(err < bound(m), "{cell}: x({T1}) = {x}, exact {}, error {err:e}", (case.exact)(T1));
                    ran += 1;
                }
                Err(SimulateError::Refused(r)) => {
                    assert_eq!(r.method, m, "{cell}");
                    assert!(!r.alternatives.is_empty(), "{cell}: refused with no alternative");
                    assert!(r.hint().contains(r.alternatives[0].name()), "{cell}: {}", r.hint());
                    for alt in &r.alternatives {
                        assert!(
                            simulate::compile_system(&sys, *alt, &[]).is_ok(),
                            "{cell}: the alternative {} does not run it",
                            alt.name()
                        );
                    }
                    refused += 1;
                }
                Err(e) => panic!("{cell}: neither run nor a method refusal: {e}"),
            }
        }
    }
    // Refused: splitting and variational methods on the forced, damped, constrained and
    // velocity-constrained systems, on the first-order L and on the non-separable H; Taylor on
    // the first-order system; variational maps on the H-only system. Every other cell runs and
    // is checked above (Taylor on the two constrained systems through the augmented system).
    let count = |f: Family| MethodId::all().filter(|m| m.family() == f).count();
    let (splitting, variational) = (count(Family::Splitting), count(Family::Variational));
    let expected_refused = 6 * (splitting + variational) + 1 + variational;
    assert_eq!((refused, ran), (expected_refused, cases().len() * MethodId::all().count() - expected_refused));
}

/// The splitting and variational refusals of a forced system name exactly the methods that
/// integrate the equations with the force.
#[test]
fn a_refusal_names_the_methods_that_run_the_system() {
    let sys = System::from_lagrangian("1/2 x'^2 - 1/2 x^2", &["x"]).unwrap().with_force("x", "-x'").unwrap();
    let Err(SimulateError::Refused(r)) = simulate::compile_system(&sys, MethodId::Leapfrog, &[]) else {
        panic!("leapfrog ran a forced system")
    };
    let names: Vec<&str> = r.alternatives.iter().map(|m| m.name()).collect();
    assert_eq!(names, ["midpoint", "gauss4", "gauss6", "euler", "rk4", "dop853", "taylor"]);
    assert!(r.to_string().contains("forces, dissipation and constraints are not part of H"), "{r}");
}

/// Every fixed-step method of the registry shows its stated order on the pendulum
/// `H = ½ p² − cos q` (from `q = 1` at rest to `t = 4`): halving the step divides the error by
/// about `2^p` (`2^(p+2)` at most for a symmetric scheme). The reference is the Taylor method at machine precision. A scheme added to the
/// registry is measured here without touching this file.
#[test]
fn every_fixed_step_method_of_the_registry_has_its_stated_order() {
    let sys = System::from_hamiltonian("1/2 p_q^2 - cos(q)", &["q"]).unwrap();
    let t1 = 4.0;
    let reference = {
        let c = simulate::compile_system(&sys, MethodId::Taylor, &[]).unwrap();
        let mut o = RunOptions::new(MethodId::Taylor, 0.0, t1);
        o.sampling = Sampling::Final;
        simulate::integrate(&c, &[1.0, 0.0], &o, &mut |_| {}).unwrap().last_state().unwrap()[0]
    };
    for m in MethodId::all().filter(|m| !m.adaptive()) {
        let p = m.order().unwrap();
        // Steps that keep the error well above round-off and inside the asymptotic range.
        let h = match p {
            1 => 0.01,
            2 => 0.02,
            4 => 0.1,
            6 => 0.2,
            _ => 0.25,
        };
        let c = simulate::compile_system(&sys, m, &[]);
        // The variational maps discretize L: give them the Lagrangian of the same pendulum.
        let c = match c {
            Ok(c) => c,
            Err(_) => {
                let l = System::from_lagrangian("1/2 q'^2 + cos(q)", &["q"]).unwrap();
                simulate::compile_system(&l, m, &[]).unwrap()
            }
        };
        let err = |dt: f64| {
            let mut o = RunOptions::new(m, 0.0, t1);
            o.dt = Some(dt);
            o.sampling = Sampling::Final;
            let tr = simulate::integrate(&c, &[1.0, 0.0], &o, &mut |_| {}).unwrap();
            (tr.last_state().unwrap()[0] - reference).abs()
        };
        let observed = (err(h) / err(h / 2.0)).log2();
        let p = p as f64;
        // A symmetric scheme's error has only even powers of h, and one built for a small
        // leading constant shows the next power, p + 2, wherever its error is above round-off
        // (Kahan–Li 8: 9.5, 10.0, 10.0 over h = 1 … 1/8 here, Yoshida 8: 7.8, 8.0, 8.0). Its
        // order p itself is checked exactly by the order conditions (`integrate::coefficients`).
        let range = if m.symmetric() { p - 0.4..p + 2.4 } else { p - 0.4..p + 0.4 };
        assert!(range.contains(&observed), "{}: observed order {observed:.2}, stated {p}", m.name());
    }
}
