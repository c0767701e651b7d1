//! `energy at`: the energy function h at one state, against its closed form and the H route.

use lagrangian::scene::{ErrorKind, Mode, Options, SceneError, Session};

fn run(scene: &str) -> Result<Vec<String>, SceneError> {
    let mut s = Session::new(Options::new(Mode::Scene));
    s.run_scene("test", scene)?;
    Ok(s.take_output())
}

/// The number printed by the scene's last line `E = …`.
fn energy(scene: &str) -> f64 {
    let out = run(scene).unwrap_or_else(|e| panic!("{e:?}"));
    let last = out.last().expect("a printed line");
    last.strip_prefix("E = ").unwrap_or_else(|| panic!("{last}")).parse().unwrap()
}

/// The pendulum's h = ½ m l² θ'² − m g l cos θ, evaluated here by hand in f64.
#[test]
fn the_pendulum_energy_at_a_state_is_its_closed_form() {
    let (m, l, g, th, w) = (2.0_f64, 1.5_f64, 9.81_f64, 0.7_f64, 1.3_f64);
    let expected = 0.5 * m * l * l * w * w - m * g * l * th.cos();
    let got = energy(
        "coordinates θ\nparameters m = 2, l = 1.5, g = 9.81\nL = 1/2 m l^2 θ'^2 + m g l cos(θ)\nenergy at θ = 0.7, θ' = 1.3",
    );
    assert!((got - expected).abs() <= 1e-14 * expected.abs(), "{got} vs {expected}");
}

/// The same oscillator through L with a velocity and through H with the momentum p = m x'
/// gives the same number, and it is the exact ½ m x'² + ½ k x² = 2.625.
#[test]
fn velocities_through_l_and_momenta_through_h_agree() {
    let through_l =
        energy("coordinates x\nparameters m = 2, k = 3\nL = 1/2 m x'^2 - 1/2 k x^2\nenergy at x = 0.5, x' = 1.5");
    let through_h =
        energy("coordinates x\nparameters m = 2, k = 3\nH = p_x^2/(2 m) + 1/2 k x^2\nenergy at x = 0.5, p_x = 3");
    assert_eq!(through_l, 2.625);
    assert_eq!(through_h, 2.625);
}

/// A state variable the energy needs and was not given is an error naming it, at the
/// statement's words; so is an unknown name in the state, at that name.
#[test]
fn missing_and_foreign_state_values_are_refused_with_their_place() {
    let scene = "coordinates θ\nparameters m = 1, l = 1, g = 9.81\nL = 1/2 m l^2 θ'^2 + m g l cos(θ)\nenergy at θ = 1";
    let err = run(scene).unwrap_err();
    assert_eq!(err.kind, ErrorKind::MissingValue, "{err:?}");
    assert!(err.message.contains("`θ'`"), "{err:?}");
    let at = scene.find("energy at").unwrap();
    assert_eq!(err.span, Some((at, at + "energy at".len())));

    let scene = "coordinates x\nparameters m = 1\nL = 1/2 m x'^2\nenergy at x = 1, y = 2";
    let err = run(scene).unwrap_err();
    assert_eq!(err.kind, ErrorKind::UndefinedSymbol, "{err:?}");
    let y = scene.find("y = 2").unwrap();
    assert_eq!(err.span, Some((y, y + 1)));

    let scene = "coordinates x\nparameters m, k = 1\nL = 1/2 m x'^2 - 1/2 k x^2\nenergy at x = 1, x' = 2";
    let err = run(scene).unwrap_err();
    assert_eq!(err.kind, ErrorKind::MissingValue, "{err:?}");
    assert!(err.hint.as_deref().is_some_and(|h| h.contains("parameters m = ")), "{err:?}");
}
