//! `series` and `jacobian` in a scene (the byte-for-byte agreement with the command line is in
//! `parity.rs`): the example scene's lines against hand expansions, and the refusals.

use lagrangian::scene::{ErrorKind, Mode, Options, Session};

fn run(scene: &str) -> Result<Vec<String>, lagrangian::scene::SceneError> {
    let mut s = Session::new(Options::new(Mode::Scene));
    s.run_scene("test", scene).map(|()| s.take_output())
}

/// `examples/small_oscillations.scene`: the double pendulum about θ1 = θ2 = 0 to second order
/// is, by hand (cos(θ1 − θ2) → 1, cos θ → 1 − θ²/2), 3mgl − mgl θ1² − ½ mgl θ2² +
/// m l² θ̇1² + ½ m l² θ̇2² + m l² θ̇1 θ̇2; the bob's map (l sin θ, −l cos θ) has det = l; sin ε
/// to fifth order is ε − ε³/6 + ε⁵/120.
#[test]
fn the_small_oscillations_example_prints_the_hand_expansions() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/small_oscillations.scene"))
        .expect("example exists");
    let text = text.replace("\njacobian", "\nformat plain\njacobian");
    let out = run(&text.replace("order 2\n", "order 2 as plain\n")).unwrap_or_else(|e| panic!("{e:?}"));
    let d = lagrangian::Declarations::new();
    let hand = lagrangian::parse_with(
        "3 m g l - m g l θ1^2 - 1/2 m g l θ2^2 + m l^2 θ1'^2 + 1/2 m l^2 θ2'^2 + m l^2 θ1' θ2'",
        &d,
    )
    .expect("parses");
    let got = lagrangian::parse_with(&out[0], &d).expect("re-parses");
    let diff = got.minus(&hand);
    assert_eq!(lagrangian::canonical::decide_zero(&diff), lagrangian::canonical::ZeroCheck::Proven, "{out:?}");
    assert!(out.contains(&"det = l".to_string()), "{out:?}");
    assert_eq!(out.last().map(String::as_str), Some("ε - ε^3/6 + ε^5/120"), "{out:?}");
}

/// Inputs that have no answer are refused with what would work, at the statement.
#[test]
fn series_and_jacobian_refuse_what_has_no_answer() {
    // 1/x has no power series about x = 0.
    let e = run("series 1/x in x order 3").expect_err("refused");
    assert_eq!(e.kind, ErrorKind::Derivation);
    assert!(e.message.contains("no power series"), "{}", e.message);
    // An order that is not a whole number, and one above the limit.
    let e = run("series sin(x) in x order 1.5").expect_err("refused");
    assert_eq!(e.kind, ErrorKind::BadNumber);
    let e = run("series sin(x) in x order 40").expect_err("refused");
    assert_eq!(e.kind, ErrorKind::BadNumber);
    // Two components, three variables.
    let e = run("jacobian (r cos(φ), r sin(φ)) in r, φ, z").expect_err("refused");
    assert!(e.message.contains("as many of each"), "{}", e.message);
    // A small quantity that is an expression.
    let e = run("series sin(x) in 2 x").expect_err("refused");
    assert_eq!(e.kind, ErrorKind::Syntax);
    assert!(e.span.is_some(), "{e:?}");
}

/// `map`: three steps of the standard map from (1, 0.5) with K = 0.9 print the state a hand
/// iteration gives (Python floats: 5.375066801394972, 1.1643125003166652); the same map
/// written implicitly (`p' = …, q' = q + p'`) gives the same state; mixing primed and plain
/// assignments, a new value in an explicit map and an assignment without a start are refused.
#[test]
fn map_iterates_the_standard_map_and_refuses_what_it_cannot() {
    let out = run("parameters K = 0.9\nmap p = p + K sin(q), q = q + p for 3 steps from q = 1, p = 0.5")
        .unwrap_or_else(|e| panic!("{e:?}"));
    assert_eq!(out, ["map: 1 orbit(s) of 3 step(s)", "  (1, 0.5) → (5.375066801394972, 1.1643125003166652)"]);
    let out = run("parameters K = 0.9\nmap p' = p + K sin(q), q' = q + p' for 3 steps from q = 1, p = 0.5")
        .unwrap_or_else(|e| panic!("{e:?}"));
    assert_eq!(out[0], "map: 1 orbit(s) of 3 step(s), implicit (Newton's method per step)");
    let last = crate::support::map_last_state(&out[1]);
    assert!((last[0] - 5.375066801394972).abs() < 1e-13 && (last[1] - 1.1643125003166652).abs() < 1e-13, "{out:?}");
    let e = run("map p' = p + sin(q), q = q + p' for 3 steps from q = 1, p = 0.5").expect_err("refused");
    assert!(e.message.contains("implicit map writes every new value primed") && e.span.is_some(), "{e:?}");
    let e = run("map p = p + sin(q'), q = q + p for 3 steps from q = 1, p = 0.5").expect_err("refused");
    assert!(e.message.contains("appears in an explicit map"), "{e:?}");
    let e = run("map p = p + sin(q), q = q + p for 3 steps from q = 1").expect_err("refused");
    assert!(e.message.contains("no start"), "{}", e.message);
    let e = run("map p = p + sin(q), q = q + p for 2.5 steps from q = 1, p = 0").expect_err("refused");
    assert_eq!(e.kind, ErrorKind::BadNumber);
}
