//! Geodesics (issue 11, item 5): the sphere's Christoffel symbols and geodesic equations
//! (snapshot, hand forms), a shooting solution that matches the great circle to 1e-10, and
//! bad line elements or a start where the metric is singular refused with exit code 2.

mod notes_support;

use lagrangian::compile::{shoot, ShootError};
use lagrangian::mechanics::{geodesic, MechanicsError};
use lagrangian::{parse, Symbol};
use notes_support::{run, snapshot};

const SPHERE: &str = "dθ^2 + sin(θ)^2 dφ^2";

fn line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` in\n{out}"))
}

#[test]
fn sphere_christoffel_symbols_and_geodesic_equations() {
    let (code, out, err) = run(&["geodesic", SPHERE, "--coords", "θ,φ"]);
    assert_eq!(code, 0, "{err}");
    // By hand: Γ^θ_φφ = −sin θ cos θ, Γ^φ_θφ = cot θ, all others zero (§1.6.3).
    assert_eq!(parse(line(&out, "Γ^θ_φφ = ")).unwrap(), parse("-sin(θ) cos(θ)").unwrap());
    assert_eq!(parse(line(&out, "Γ^φ_θφ = ")).unwrap(), parse("cos(θ)/sin(θ)").unwrap());
    assert_eq!(out.lines().filter(|l| l.starts_with('Γ')).count(), 2, "{out}");
    // p_φ = sin²θ φ' (the angular momentum about the axis) and the speed are conserved.
    assert_eq!(parse(line(&out, "p_φ = ").split("    #").next().unwrap()).unwrap(), parse("sin(θ)^2 φ'").unwrap());
    snapshot("notes_geodesic_sphere", &format!("# (1.19)-(1.20), §1.6.3: geodesics of the unit sphere\n$ lagrangian geodesic \"{SPHERE}\" --coords θ,φ\n{out}"));
}

fn unit(q: &[f64]) -> [f64; 3] {
    [q[0].sin() * q[1].cos(), q[0].sin() * q[1].sin(), q[0].cos()]
}

#[test]
fn shooting_matches_the_great_circle() {
    let z = [Symbol::new("θ"), Symbol::new("φ")];
    let g = geodesic(&parse(SPHERE).unwrap(), &z).unwrap();
    for (from, to) in [([1.0, 0.0], [2.0, 1.5]), ([1.2, -0.5], [1.8, 1.0])] {
        let shot = shoot(&g, &from, &to, &[], 10).unwrap();
        let (u0, u1) = (unit(&from), unit(&to));
        let omega = (u0[0] * u1[0] + u0[1] * u1[1] + u0[2] * u1[2]).acos();
        for (t, q) in &shot.path {
            // The great circle at constant speed: slerp(u0, u1, t).
            let (a, b) = (((1.0 - t) * omega).sin() / omega.sin(), (t * omega).sin() / omega.sin());
            let u = unit(q);
            for k in 0..3 {
                let exact = a * u0[k] + b * u1[k];
                assert!((u[k] - exact).abs() < 1e-10, "t = {t}: component {k}: {} vs {exact}", u[k]);
            }
        }
        // Unit time: the speed is the arc length Ω.
        let speed = (shot.velocity[0].powi(2) + from[0].sin().powi(2) * shot.velocity[1].powi(2)).sqrt();
        assert!((speed - omega).abs() < 1e-10, "speed {speed} vs arc {omega}");
    }
}

#[test]
fn bad_metrics_are_refused() {
    let z = [Symbol::new("θ"), Symbol::new("φ")];
    let g = geodesic(&parse(SPHERE).unwrap(), &z).unwrap();
    assert!(matches!(shoot(&g, &[0.0, 0.0], &[1.0, 1.0], &[], 1), Err(ShootError::SingularMetric { .. })));
    for bad in ["dθ^2 + sin(θ)^2 dφ^2 + dθ", "dθ^2 + dθ dφ^3", "θ^2", "(dθ - dφ)^2"] {
        let e = geodesic(&parse(bad).unwrap(), &z).unwrap_err();
        assert!(matches!(e, MechanicsError::BadMetric(_)), "{bad}: {e}");
    }
    let (code, out, err) = run(&["geodesic", SPHERE, "--coords", "θ,φ", "--from", "0,0", "--to", "1,1"]);
    assert_eq!(code, 2);
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("singular at the start point"), "{err}");
    let (code, _, err) = run(&["geodesic", "dθ^2 + dθ", "--coords", "θ"]);
    assert_eq!(code, 2);
    assert!(err.contains("not quadratic"), "{err}");
}

/// `K` printed by `lagrangian geodesic`, evaluated at `point`.
fn gauss_curvature(line_element: &str, coords: &str, point: &[(&str, f64)]) -> (f64, String) {
    let (code, out, err) = run(&["geodesic", line_element, "--coords", coords]);
    assert_eq!(code, 0, "{err}");
    let k = parse(line(&out, "K = ")).unwrap();
    let env: std::collections::HashMap<String, f64> = point.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    (lagrangian::eval::eval(&k, &env).unwrap(), out)
}

#[test]
fn gauss_curvature_of_sphere_plane_and_a_saddle() {
    // Sphere of radius R: K = 1/R², R_θφθφ = R² sin²θ (by hand from the Christoffel symbols
    // above: R^θ_φθφ = ∂_θ Γ^θ_φφ − Γ^θ_φφ Γ^φ_θφ = sin²θ).
    let (code, out, err) = run(&["geodesic", "R^2 dθ^2 + R^2 sin(θ)^2 dφ^2", "--coords", "θ,φ"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(parse(line(&out, "K = ")).unwrap(), parse("1/R^2").unwrap());
    assert_eq!(parse(line(&out, "R_θφθφ = ")).unwrap(), parse("R^2 sin(θ)^2").unwrap());
    assert_eq!(parse(line(&out, "scalar_curvature = ")).unwrap(), parse("2/R^2").unwrap());
    // The plane in polar coordinates: flat, no component of the Riemann tensor survives.
    let (k, out) = gauss_curvature("dr^2 + r^2 dφ^2", "r,φ", &[]);
    assert_eq!(k, 0.0);
    assert!(!out.lines().any(|l| l.starts_with("R_")), "{out}");
    // ds² = dx² + G(x) dy²: K = −(√G)''/√G (Gauss); G = cosh²x gives K = −1.
    for x in [-0.7, 0.0, 1.3] {
        let (k, _) = gauss_curvature("dx^2 + cosh(x)^2 dy^2", "x,y", &[("x", x), ("y", 0.4)]);
        assert!((k + 1.0).abs() < 1e-13, "K = {k} at x = {x}");
    }
    // A metric with a cross term: the graph z = x y, g = [[1 + y², x y], [x y, 1 + x²]], whose
    // Monge-patch curvature is K = (z_xx z_yy − z_xy²)/(1 + z_x² + z_y²)² = −1/(1 + x² + y²)².
    for (x, y) in [(0.3, -0.8), (1.1, 0.5), (0.0, 0.0)] {
        let (k, _) = gauss_curvature("(1 + y^2) dx^2 + 2 x y dx dy + (1 + x^2) dy^2", "x,y", &[("x", x), ("y", y)]);
        let exact = -1.0 / (1.0 + x * x + y * y).powi(2);
        assert!((k - exact).abs() < 1e-13, "K = {k} at ({x}, {y}), Monge patch {exact}");
    }
}
