//! Simulating velocity (nonholonomic) constraints: the upright rolling coin with a spring on x
//! (§1.5, §1.6.2; the model of scripts/nonholonomic_sympy.py) integrated through the library
//! simulate layer, against SymPy's KanesMethod integrated by scipy's solve_ivp
//! (scripts/nonholonomic_simulate_sympy.py); the constraints held to the projection's bound
//! over a long run; the energy conserved (ideal rolling does no work); the refusals.

use lagrangian::mechanics::System;
use lagrangian::simulate::{self, MethodId, RunOptions, SimulateError};

const L: &str = "1/2 m (x'^2 + y'^2) + 1/2 I θ'^2 + 1/2 J φ'^2 - 1/2 k x^2";
const PARAMS: [(&str, f64); 5] = [("m", 2.0), ("I", 0.7), ("J", 1.3), ("R", 0.5), ("k", 3.0)];

fn coin() -> System {
    System::from_lagrangian(L, &["x", "y", "θ", "φ"])
        .unwrap()
        .with_velocity_constraint("x' = R φ' cos(θ)")
        .unwrap()
        .with_velocity_constraint("y' = R φ' sin(θ)")
        .unwrap()
        .with_params(&PARAMS)
        .unwrap()
}

/// x = 0.4, y = −0.3, θ = 0.9, φ = 0.2, θ' = 0.8, φ' = −1.1, with x', y' from the constraints.
fn start() -> Vec<f64> {
    let (th, ph) = (0.9f64, -1.1f64);
    vec![0.4, -0.3, th, 0.2, 0.5 * ph * th.cos(), 0.5 * ph * th.sin(), 0.8, ph]
}

/// ½ m (x'² + y'²) + ½ I θ'² + ½ J φ'² + ½ k x².
fn energy(y: &[f64]) -> f64 {
    0.5 * 2.0 * (y[4] * y[4] + y[5] * y[5])
        + 0.5 * 0.7 * y[6] * y[6]
        + 0.5 * 1.3 * y[7] * y[7]
        + 0.5 * 3.0 * y[0] * y[0]
}

fn aux<'a>(tr: &'a simulate::Trajectory, name: &str) -> &'a [f64] {
    &tr.aux.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no `{name}` in {:?}", tr.aux)).1
}

/// From scripts/nonholonomic_simulate_sympy.py: the state at t = 10 (KanesMethod equations,
/// solve_ivp DOP853 at rtol = atol = 1e-13), in the order x, y, θ, φ, x', y', θ', φ' (the
/// script's digits, as printed).
#[allow(clippy::excessive_precision)]
const AT_10: [f64; 8] = [
    5.820_789_944_819_793_1e-1,
    -2.909_737_286_459_251_2,
    8.899_999_999_999_998_6,
    -6.075_042_467_565_174,
    4.132_336_236_547_359_3e-1,
    -2.392_306_920_609_817_4e-1,
    8.000_000_000_000_000_4e-1,
    -9.549_729_875_610_099e-1,
];

#[test]
fn rolling_coin_simulated_matches_kanes_method_with_solve_ivp() {
    let c = simulate::compile_system(&coin(), MethodId::Dop853, &[]).unwrap();
    assert_eq!(c.state, ["x", "y", "θ", "φ", "x'", "y'", "θ'", "φ'"]);
    let mut o = RunOptions::new(MethodId::Dop853, 0.0, 10.0);
    o.rtol = Some(1e-12);
    let tr = simulate::integrate(&c, &start(), &o, &mut |_| {}).unwrap();
    let end = tr.last_state().unwrap();
    for (i, (got, want)) in end.iter().zip(AT_10).enumerate() {
        assert!((got - want).abs() < 1e-8, "{}: {got} against KanesMethod {want}", c.state[i]);
    }
    // The multipliers at the start are the Lagrange–d'Alembert ones of
    // tests/it/mechanics/nonholonomic.rs (scripts/nonholonomic_sympy.py, LagrangesMethod).
    assert!((aux(&tr, "μ1")[0] - 1.760_528_029_587_700_2).abs() < 1e-10, "{:?}", aux(&tr, "μ1")[0]);
    assert!((aux(&tr, "μ2")[0] + 0.709_324_710_557_883_9).abs() < 1e-10, "{:?}", aux(&tr, "μ2")[0]);
}

/// Over 10⁴ steps of RK4 the projection holds g = 0 to rounding at every kept state, and the
/// energy (no work done by the rolling constraint) drifts only by the method's truncation.
#[test]
fn rolling_coin_holds_its_constraints_and_energy_over_a_long_run() {
    let c = simulate::compile_system(&coin(), MethodId::Rk4, &[]).unwrap();
    let mut o = RunOptions::new(MethodId::Rk4, 0.0, 200.0);
    o.dt = Some(0.02);
    let tr = simulate::integrate(&c, &start(), &o, &mut |_| {}).unwrap();
    assert!(tr.y.len() > 100);
    for name in ["residual1", "residual2"] {
        let worst = aux(&tr, name).iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(worst < 1e-13, "{name}: worst {worst:e}");
    }
    let e0 = energy(&start());
    let worst = tr.y.iter().map(|y| (energy(y) - e0).abs() / e0).fold(0.0f64, f64::max);
    assert!(worst < 1e-6, "relative energy drift {worst:e}");
    // Without the constraint forces the spring would pull x' off R φ' cos θ: the run is not
    // the unconstrained one (whose θ' and φ' would stay constant).
    let last = tr.last_state().unwrap();
    assert!((last[7] + 1.1).abs() > 1e-3, "φ' = {}", last[7]);
}

/// Rolling breaks the momenta of x, y and φ (the constraint force acts on them) but not p_θ
/// (no row has θ'), and does no work, so h stays conserved: θ' is constant in the reference
/// run (AT_10) and the energy is checked above.
#[test]
fn conserved_quantities_respect_the_velocity_constraints() {
    let names: Vec<String> = coin().conserved().into_iter().map(|c| c.name).collect();
    assert_eq!(names, ["p_θ", "h"]);
    // A moving belt along x under the coin (x' = R φ' cos θ + v, y left free) does work: h is
    // not reported; p_y, on which no constraint force acts, is.
    let belt = System::from_lagrangian(L, &["x", "y", "θ", "φ"])
        .unwrap()
        .with_velocity_constraint("x' = R φ' cos(θ) + v")
        .unwrap();
    let names: Vec<String> = belt.conserved().into_iter().map(|c| c.name).collect();
    assert_eq!(names, ["p_y", "p_θ"]);
}

#[test]
fn a_start_off_a_velocity_constraint_is_refused() {
    let c = simulate::compile_system(&coin(), MethodId::Dop853, &[]).unwrap();
    let mut y0 = start();
    y0[4] += 0.1;
    let err = simulate::integrate(&c, &y0, &RunOptions::new(MethodId::Dop853, 0.0, 1.0), &mut |_| {}).unwrap_err();
    assert!(matches!(err, SimulateError::InitialState(_)), "{err:?}");
    assert!(err.to_string().contains("velocity constraint 1"), "{err}");
}

#[test]
fn splitting_and_variational_methods_refuse_velocity_constraints() {
    for m in [MethodId::Leapfrog, MethodId::Variational] {
        let Err(SimulateError::Refused(r)) = simulate::compile_system(&coin(), m, &[]) else {
            panic!("{} ran a velocity-constrained system", m.name())
        };
        assert!(r.alternatives.contains(&MethodId::Dop853), "{}: {:?}", m.name(), r.alternatives);
        assert!(r.alternatives.contains(&MethodId::Taylor), "{}: {:?}", m.name(), r.alternatives);
    }
}

/// The Taylor method runs the coin through the Taylor form of the augmented system (one LU
/// factorisation per expansion, projection after each step): the state at t = 10 is
/// KanesMethod's and solve_ivp's (the reference above), the constraints hold to rounding and
/// the energy is kept.
#[test]
fn the_taylor_method_runs_the_rolling_coin() {
    let c = simulate::compile_system(&coin(), MethodId::Taylor, &[]).unwrap();
    let mut o = RunOptions::new(MethodId::Taylor, 0.0, 10.0);
    o.rtol = Some(1e-13);
    let tr = simulate::integrate(&c, &start(), &o, &mut |_| {}).unwrap();
    let y = tr.last_state().unwrap();
    for (i, (got, want)) in y.iter().zip(AT_10).enumerate() {
        assert!((got - want).abs() < 1e-9, "component {i}: {got} against {want}");
    }
    for r in ["residual1", "residual2"] {
        let worst = aux(&tr, r).iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst < 1e-13, "{r}: {worst:e}");
    }
    let e0 = energy(&start());
    assert!((energy(y) - e0).abs() < 1e-10 * e0, "energy {} against {e0}", energy(y));
}

#[test]
fn a_velocity_constraint_that_is_not_linear_or_has_no_velocity_is_refused() {
    let sys = System::from_lagrangian(L, &["x", "y", "θ", "φ"]).unwrap();
    let e = sys.clone().with_velocity_constraint("x'^2 - y'").unwrap_err().to_string();
    assert!(e.contains("not linear in the velocities"), "{e}");
    let e = sys.with_velocity_constraint("x - y").unwrap_err().to_string();
    assert!(e.contains("holonomic"), "{e}");
}
