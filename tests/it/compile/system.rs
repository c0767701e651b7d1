//! `System::compile_*`: the mechanics stage's equations compiled end to end.

use crate::support::compile as compile_common;

use compile_common::Rng;
use lagrangian::compile::CompileError;
use lagrangian::integrate::{Rhs, Separable};
use lagrangian::mechanics::System;

const DOUBLE: &str = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
                      + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";

#[test]
fn double_pendulum_from_text_matches_the_hand_written_rhs() {
    let sys = System::from_lagrangian(DOUBLE, &["θ1", "θ2"])
        .unwrap()
        .with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)])
        .unwrap();
    let rhs = sys.compile_rhs().unwrap();
    let hand = compile_common::double_pendulum().hand;
    let mut rng = Rng(4);
    for _ in 0..50 {
        let y: Vec<f64> = (0..4).map(|_| rng.uniform(-3.0, 3.0)).collect();
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        rhs.eval(0.0, &y, &mut a);
        hand(0.0, &y, &mut b);
        for i in 0..4 {
            assert!((a[i] - b[i]).abs() <= 1e-12 * (1.0 + b[i].abs()), "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn unbound_parameters_are_named() {
    let sys = System::from_lagrangian(DOUBLE, &["θ1", "θ2"]).unwrap().with_params(&[("g", 9.81)]).unwrap();
    let err = sys.compile_rhs().unwrap_err();
    assert!(
        matches!(err, CompileError::Unbound { ref name } if name.starts_with('l') || name.starts_with('m')),
        "{err}"
    );
}

#[test]
fn hamiltonian_and_separable_forms_of_a_lagrangian_pendulum() {
    // H = p²/(2 m l²) − m g l cos θ (PHYSICS.md 3.20 up to a constant): drift p/(m l²),
    // kick −m g l sin θ.
    let (m, l, g) = (1.5, 0.8, 9.81);
    let sys = System::from_lagrangian("1/2 m l^2 θ'^2 + m g l cos(θ)", &["θ"])
        .unwrap()
        .with_params(&[("m", m), ("l", l), ("g", g)])
        .unwrap();
    let ham = sys.compile_hamiltonian().unwrap();
    let mut dy = [0.0; 2];
    ham.eval(0.0, &[0.3, 0.7], &mut dy);
    assert!((dy[0] - 0.7 / (m * l * l)).abs() < 1e-15);
    assert!((dy[1] + m * g * l * 0.3f64.sin()).abs() < 1e-14);
    let sep = sys.compile_separable().unwrap();
    let (mut dq, mut dp) = ([0.0], [0.0]);
    sep.drift(&[0.7], &mut dq);
    sep.kick(0.0, &[0.3], &mut dp);
    assert_eq!((dq[0], dp[0]), (dy[0], dy[1]));
    // The implicit Legendre route agrees with the closed form.
    let imp = sys.compile_implicit_legendre().unwrap();
    let mut di = [0.0; 2];
    imp.eval(0.0, &[0.3, 0.7], &mut di);
    assert!((di[0] - dy[0]).abs() < 1e-14 && (di[1] - dy[1]).abs() < 1e-14);
}

#[test]
fn a_non_separable_hamiltonian_is_refused_for_splitting() {
    // Polar Kepler: T = p_φ²/(2 m r²) mixes r and p_φ.
    let sys = System::from_lagrangian("1/2 m (r'^2 + r^2 φ'^2) + k/r", &["r", "φ"])
        .unwrap()
        .with_params(&[("m", 1.0), ("k", 1.0)])
        .unwrap();
    assert_eq!(sys.compile_separable().unwrap_err(), CompileError::NotSeparable);
    assert!(sys.compile_hamiltonian().is_ok());
}

#[test]
fn integrators_stop_with_the_reason_when_the_mass_matrix_becomes_singular() {
    // Spherical pendulum, W = diag(1, sin²θ): started at the pole θ = 0 the first evaluation
    // has a singular W; the integrator must stop with the compiler's reason, not a NaN path.
    use lagrangian::integrate::{ExplicitRk, FailureReason, Integrate};
    let sys = System::from_lagrangian("1/2 (θ'^2 + sin(θ)^2 φ'^2) + g cos(θ)", &["θ", "φ"])
        .unwrap()
        .with_params(&[("g", 9.81)])
        .unwrap();
    let rhs = sys.compile_rhs().unwrap();
    let err = ExplicitRk::rk4(0.01).integrate(&rhs, 0.0..1.0, &[0.0, 0.0, 0.1, 0.2]).unwrap_err();
    match err.reason {
        FailureReason::Rhs(e) => assert!(e.reason.contains("singular") && e.reason.contains("φ'"), "{}", e.reason),
        other => panic!("expected the right-hand side's error, got {other}"),
    }
    // Away from the pole the same system integrates, and matches the hand-written equations
    // θ'' = sinθ cosθ φ'² − g sinθ, φ'' = −2 cotθ θ' φ' integrated by the same method.
    let y0 = [0.8, 0.0, 0.1, 0.9];
    let got = ExplicitRk::rk4(0.01).integrate(&rhs, 0.0..1.0, &y0).unwrap();
    let hand = lagrangian::integrate::FnRhs {
        dim: 4,
        f: |_t: f64, y: &[f64], dy: &mut [f64]| {
            let (s, c) = y[0].sin_cos();
            dy[0] = y[2];
            dy[1] = y[3];
            dy[2] = s * c * y[3] * y[3] - 9.81 * s;
            dy[3] = -2.0 * c / s * y[2] * y[3];
        },
    };
    let want = ExplicitRk::rk4(0.01).integrate(&hand, 0.0..1.0, &y0).unwrap();
    for (a, b) in got.last_state().iter().zip(want.last_state()) {
        assert!((a - b).abs() < 1e-12, "{:?} vs {:?}", got.last_state(), want.last_state());
    }
}

/// What the compiled right-hand sides do not handle is a typed `Unsupported` error naming the
/// feature, not a panic and not a wrong right-hand side.
#[test]
fn unsupported_systems_are_refused_by_name() {
    // A bead on a circle written with a holonomic constraint: W q'' = F alone would ignore it.
    let constrained = System::from_lagrangian("1/2 m (x'^2 + y'^2) - m g y", &["x", "y"])
        .unwrap()
        .with_constraint("x^2 + y^2 = 1")
        .unwrap()
        .with_params(&[("m", 1.0), ("g", 9.81)])
        .unwrap();
    match constrained.compile_rhs().map(|_| ()) {
        Err(CompileError::Unsupported { what }) => assert!(what.contains("constraint"), "{what}"),
        other => panic!("a constrained system compiled to W q'' = F: {other:?}"),
    }
    // A Hamiltonian system has no W q'' = F and no Legendre map of a Lagrangian.
    let h = System::from_hamiltonian("p_x^2/2 + x^2/2", &["x"]).unwrap();
    for (route, result) in [
        ("compile_rhs", h.compile_rhs().map(|_| ())),
        ("compile_implicit_legendre", h.compile_implicit_legendre().map(|_| ())),
    ] {
        match result {
            Err(e @ CompileError::Unsupported { .. }) => {
                assert!(e.to_string().starts_with("compiling "), "{route}: {e}")
            }
            other => panic!("{route} of a Hamiltonian system: {other:?}"),
        }
    }
    // The supported route for it still works.
    assert!(h.compile_hamiltonian().is_ok());
}
