//! First-order (phase-space) Lagrangians: the two-form, the equations
//! ω z' = ∂H/∂z + ∂a/∂t, the Poisson tensor, the compiled right-hand side, and a degenerate
//! two-form named by its null direction. Checked against Hamilton's equations of the same H
//! (a second route through the engine) at random points, and point vortices against their
//! closed-form rotation.

use crate::support::notes as notes_support;

use std::collections::HashMap;

use lagrangian::eval::eval;
use lagrangian::integrate::{Dop853, Gauss4, Integrate, Rhs};
use lagrangian::mechanics::{MechanicsError, System};
use lagrangian::parse;
use notes_support::{run, snapshot, Rng};

const PHASE_SPACE: &str = "p x' - p^2/(2 m) - k x^2/2";

/// Two point vortices in Kirchhoff's orientation, Γ_i x_i' = ∂H/∂y_i, Γ_i y_i' = −∂H/∂x_i
/// (P. K. Newton, *The N-Vortex Problem*, 2001, §2.1), with
/// H = −Γ1 Γ2 log(r²)/(4π).
const VORTICES: &str = "Γ1 (y1 x1' - x1 y1')/2 + Γ2 (y2 x2' - x2 y2')/2 \
                        + Γ1 Γ2 log((x1 - x2)^2 + (y1 - y2)^2)/(4 π)";

fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in\n{out}"))
}

#[test]
fn phase_space_oscillator_two_form_bracket_and_velocities() {
    let (code, out, err) =
        run(&["phase-space", PHASE_SPACE, "--coords", "x,p", "--bracket", "x^2", "--bracket", "x p"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(parse(line(&out, "{x, p} = ")).unwrap(), parse("1").unwrap());
    // {x², x p} = ∂(x²)/∂x · P_xp · ∂(x p)/∂p = 2x · 1 · x.
    assert_eq!(parse(line(&out, "{x^2, x p} = ")).unwrap(), parse("2 x^2").unwrap());
    assert_eq!(parse(line(&out, "x' = ")).unwrap(), parse("p/m").unwrap());
    assert_eq!(parse(line(&out, "p' = ")).unwrap(), parse("-k x").unwrap());
    assert_eq!(parse(line(&out, "ω[x,p] = ")).unwrap(), parse("-1").unwrap());
    snapshot("notes_phase_space_oscillator", format!("# (3.31)-(3.32) with (3.16): ω, Hamilton's equations, {{x, p}} = 1 (4.4)\n$ lagrangian phase-space \"{PHASE_SPACE}\" --coords x,p --bracket x^2 --bracket \"x p\"\n{out}"));
}

/// At random points, the velocities z' = ω⁻¹ (∂H/∂z + ∂a/∂t) of L = Σ p_i q_i' − H equal
/// Hamilton's equations of H, symbolically evaluated and compiled (two separate routes).
#[test]
fn first_order_equations_match_hamiltons_equations_at_random_points() {
    // Hénon–Heiles plus a momentum coupling: not separable, so nothing is trivial.
    let h = "(u^2 + v^2)/2 + (x^2 + y^2)/2 + x^2 y - y^3/3 + a u x y";
    let l = format!("u x' + v y' - ({h})");
    let sys = System::from_lagrangian(&l, &["x", "y", "u", "v"]).unwrap().with_params(&[("a", 0.3)]).unwrap();
    let f = sys.first_order().unwrap();
    let vel = f.velocities().unwrap();
    let ham = System::from_hamiltonian(&h.replace('u', "p_x").replace('v', "p_y"), &["x", "y"])
        .unwrap()
        .with_params(&[("a", 0.3)])
        .unwrap();
    let eqs = ham.hamilton_equations().unwrap();
    let hand = [&eqs.qdot[0], &eqs.qdot[1], &eqs.pdot[0], &eqs.pdot[1]];
    let compiled = sys.compile_first_order().unwrap();
    let reference = ham.compile_hamiltonian().unwrap();
    let mut rng = Rng::new(7);
    for _ in 0..20 {
        let z: Vec<f64> = (0..4).map(|_| rng.uniform(-1.5, 1.5)).collect();
        let env: HashMap<String, f64> = [("x", z[0]), ("y", z[1]), ("u", z[2]), ("v", z[3]), ("a", 0.3)]
            .iter()
            .map(|(k, v)| (k.to_string(), *v))
            .collect();
        let henv: HashMap<String, f64> = [("x", z[0]), ("y", z[1]), ("p_x", z[2]), ("p_y", z[3]), ("a", 0.3)]
            .iter()
            .map(|(k, v)| (k.to_string(), *v))
            .collect();
        let (mut dz, mut dh) = ([0.0; 4], [0.0; 4]);
        compiled.eval(0.0, &z, &mut dz);
        reference.eval(0.0, &z, &mut dh);
        for i in 0..4 {
            let a = eval(&vel[i], &env).unwrap();
            let b = eval(hand[i], &henv).unwrap();
            assert!((a - b).abs() < 1e-12 * (1.0 + b.abs()), "component {i}: {a} vs {b}");
            assert!(
                (dz[i] - dh[i]).abs() < 1e-12 * (1.0 + dh[i].abs()),
                "compiled component {i}: {} vs {}",
                dz[i],
                dh[i]
            );
        }
    }
}

#[test]
fn two_point_vortices_conserve_centre_and_distance_and_rotate_at_the_known_rate() {
    let (g1, g2) = (1.0, 0.5);
    let sys = System::from_lagrangian(VORTICES, &["x1", "y1", "x2", "y2"])
        .unwrap()
        .with_params(&[("Γ1", g1), ("Γ2", g2)])
        .unwrap();
    let f = sys.first_order().unwrap();
    // ω is constant: diag blocks [[0, −Γ_i], [Γ_i, 0]] (ω_{x y} = ∂a_y/∂x − ∂a_x/∂y = −Γ).
    assert_eq!(f.omega[0][1], parse("-Γ1").unwrap());
    assert_eq!(f.omega[2][3], parse("-Γ2").unwrap());
    assert!(f.omega[0][2].is_zero() && f.omega[1][3].is_zero());
    // The centre of vorticity Σ Γ_i z_i commutes with H: {Γ1 x1 + Γ2 x2, H} = 0.
    let hx = f.bracket(&parse("Γ1 x1 + Γ2 x2").unwrap(), &f.h).unwrap();
    assert!(hx.is_zero(), "{hx}");
    let rhs = sys.compile_first_order().unwrap();
    let z0: [f64; 4] = [1.0, 0.0, -0.5, 0.25];
    let d0 = ((z0[0] - z0[2]).powi(2) + (z0[1] - z0[3]).powi(2)).sqrt();
    let t1 = 20.0;
    for traj in [
        Gauss4::new(0.01).integrate(&rhs, 0.0..t1, &z0).unwrap(),
        Dop853::new(1e-12, 1e-12).integrate(&rhs, 0.0..t1, &z0).unwrap(),
    ] {
        let mut worst: f64 = 0.0;
        for (_, y) in traj.iter() {
            let cx = g1 * y[0] + g2 * y[2] - (g1 * z0[0] + g2 * z0[2]);
            let cy = g1 * y[1] + g2 * y[3] - (g1 * z0[1] + g2 * z0[3]);
            let d = ((y[0] - y[2]).powi(2) + (y[1] - y[3]).powi(2)).sqrt();
            worst = worst.max(cx.abs()).max(cy.abs()).max((d - d0).abs());
        }
        assert!(worst < 1e-10, "centre of vorticity and distance drift by {worst:e}");
        // The pair rotates rigidly at Ω = (Γ1 + Γ2)/(2π d²) (Newton 2001, §2.2.1).
        let y = traj.last_state();
        let omega = (g1 + g2) / (2.0 * std::f64::consts::PI * d0 * d0);
        let a0 = (z0[1] - z0[3]).atan2(z0[0] - z0[2]);
        let a1 = (y[1] - y[3]).atan2(y[0] - y[2]);
        let expected = (a0 + omega * t1).rem_euclid(2.0 * std::f64::consts::PI);
        let got = a1.rem_euclid(2.0 * std::f64::consts::PI);
        assert!((got - expected).abs() < 1e-8, "angle {got} vs {expected}");
    }
}

#[test]
fn degenerate_two_form_names_its_null_direction() {
    // L = p x' − H(x, p, y): y has no one-form term, a constraint direction.
    let s = System::from_lagrangian("p x' - p^2/2 - x^2/2 - y^2", &["x", "p", "y"]).unwrap();
    let f = s.first_order().unwrap();
    match f.check_nondegenerate().unwrap_err() {
        MechanicsError::DegenerateTwoForm { direction } => {
            assert!(direction.contains("(0, 0, 1) in (x, p, y)"), "{direction}")
        }
        other => panic!("wrong error {other}"),
    }
    // A gauge direction: a depends on x + y only, so ω has the null vector (1, −1, 0).
    let s = System::from_lagrangian("(x + y) p' - p^2 - (x + y)^2", &["x", "y", "p"]).unwrap();
    let f = s.first_order().unwrap();
    match f.check_nondegenerate().unwrap_err() {
        MechanicsError::DegenerateTwoForm { direction } => {
            assert!(direction.contains("(1, -1, 0) in (x, y, p)"), "{direction}")
        }
        other => panic!("wrong error {other}"),
    }
    let e = s.compile_first_order().unwrap_err();
    assert!(e.to_string().contains("degenerate"), "{e}");
    // CLI: exit 2, the direction in the message, nothing on stdout.
    let (code, out, err) = run(&["phase-space", "p x' - p^2/2 - x^2/2 - y^2", "--coords", "x,p,y"]);
    assert_eq!(code, 2);
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("degenerate") && err.contains("(0, 0, 1)"), "{err}");
    // Not first order at all.
    let (code, _, err) = run(&["phase-space", "1/2 x'^2 - x^2", "--coords", "x"]);
    assert_eq!(code, 2);
    assert!(err.contains("not first order") && err.contains("x'"), "{err}");
}
