//! Printed forms the notes write, from general rules: a Poisson bracket
//! proven equal to its expected value prints as that value; a gauge-transformed Lagrangian is
//! tidied so the terms of dΛ/dt cancel; `conserved` prints the energy function h in the
//! grouping of L's terms when they do not interact (the scene's `energy` form). Each printed
//! line is re-parsed and checked against an independent expression at random points.

use lagrangian::eval::eval;
use lagrangian::{parse_with, Declarations, Expr};

use crate::support::notes::run;

fn p(s: &str) -> Expr {
    parse_with(s, &Declarations::new()).expect("test input parses")
}

/// `a − b` at a few deterministic points of every free symbol (values in 0.3 .. 1.7).
fn assert_equal_numerically(a: &Expr, b: &Expr, what: &str) {
    let diff = a.minus(b);
    for k in 0..5 {
        let env = diff
            .free_symbols()
            .into_iter()
            .enumerate()
            .map(|(i, s)| (s.to_string(), 0.3 + 1.4 * (((i * 7 + k * 13) % 17) as f64) / 17.0))
            .collect();
        let v = eval(&diff, &env).expect("evaluates");
        assert!(v.abs() < 1e-12, "{what}: {a} − {b} = {v} at {env:?}");
    }
}

fn line_after<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines().find_map(|l| l.trim_start().strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in\n{out}"))
}

#[test]
fn implicit_midpoint_bracket_prints_one() {
    // The implicit midpoint map of the oscillator (§4.7.2), solved for (Q, P): {Q, P} is
    // h²/(2 (h²/4 + 1)²) + h⁴/(16 (h²/4 + 1)²) + 1/(h²/4 + 1)² = (1 + h²/4)²/(1 + h²/4)² = 1.
    let (code, out, err) = run(&[
        "is-canonical",
        "Q = q + h (p_q - h q/2)/(1 + h^2/4), P = (p_q - h q - h^2 p_q/4)/(1 + h^2/4)",
        "--coords",
        "q",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("  {Q, P} = 1 (expected 1;"), "{out}");
}

#[test]
fn gauge_change_from_symmetric_to_landau_cancels() {
    // ½ m (ẋ² + ẏ²) + ½ e B (x ẏ − ẋ y) + d/dt(−½ e B x y) = ½ m (ẋ² + ẏ²) − e B ẋ y.
    let (code, out, err) =
        run(&["transform", "1/2 m (x'^2 + y'^2) + e B (x y' - x' y)/2", "--coords", "x,y", "--gauge=-e B x y/2"]);
    assert_eq!(code, 0, "{err}");
    let l = line_after(&out, "L = ");
    assert_eq!(l, "m (x'^2 + y'^2)/2 - B e x' y", "{out}");
    assert_equal_numerically(&p(l), &p("1/2 m (x'^2 + y'^2) - e B y x'"), "Landau-gauge L");
}

#[test]
fn pendulum_energy_function_prints_as_the_notes_energy() {
    // h = θ' ∂L/∂θ' − L = ½ m l² θ'² + m g l (1 − cos θ) (3.20 with p = m l² θ'), the form the
    // scene's `energy` prints; before, `conserved` printed l m (g (2 − 2 cos θ) + l θ'²)/2.
    let (code, out, err) = run(&["conserved", "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", "--coords", "θ"]);
    assert_eq!(code, 0, "{err}");
    let h = line_after(&out, "h = ").split("   (").next().expect("a form");
    assert_eq!(h, "g l m (1 - cos(θ)) + l^2 m θ'^2/2", "{out}");
    assert_equal_numerically(&p(h), &p("1/2 m l^2 θ'^2 + m g l (1 - cos(θ))"), "h");
    assert_equal_numerically(&p(h), &p("l m (g (2 - 2 cos(θ)) + l θ'^2)/2"), "the old printed h");
}
