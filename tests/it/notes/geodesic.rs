//! Geodesics: the sphere's Christoffel symbols and geodesic equations
//! (snapshot, hand forms), a shooting solution that matches the great circle to 1e-10, and
//! bad line elements or a start where the metric is singular refused with exit code 2.

use crate::support::notes as notes_support;

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
    snapshot("notes_geodesic_sphere", format!("# (1.19)-(1.20), §1.6.3: geodesics of the unit sphere\n$ lagrangian geodesic \"{SPHERE}\" --coords θ,φ\n{out}"));
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

/// Where the straight line's velocity runs into the boundary, shooting goes by continuation:
/// the Poincaré half-plane's geodesic from (0, 1) to (100, 1) is the half circle about (50, 0)
/// through both points, run at the hyperbolic distance arccosh(1 + 100²/2) per unit time, so
/// q'(0) = d (1, 50)/|(1, 50)| (the tangent at (0, 1), where the metric's scale y is 1). It
/// was refused with one failed trial path's integration error.
#[test]
fn shooting_finds_the_half_planes_tall_half_circle() {
    let z = [Symbol::new("x"), Symbol::new("y")];
    let g = geodesic(&parse("(dx^2 + dy^2)/y^2").unwrap(), &z).unwrap();
    let shot = shoot(&g, &[0.0, 1.0], &[100.0, 1.0], &[], 8).unwrap();
    let d = (1.0f64 + 100.0 * 100.0 / 2.0).acosh();
    let norm = 1.0f64.hypot(50.0);
    assert!((shot.velocity[0] - d / norm).abs() < 1e-9, "{:?}", shot.velocity);
    assert!((shot.velocity[1] - d * 50.0 / norm).abs() < 1e-9, "{:?}", shot.velocity);
    for (t, q) in &shot.path {
        let r = (q[0] - 50.0).hypot(q[1]);
        assert!((r - 1.0f64.hypot(50.0)).abs() < 1e-8, "t = {t}: off the half circle by {}", r - norm);
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
    // A parameter without a value cannot be shot through: named, not a NaN determinant.
    let radius = ["geodesic", "R^2 dθ^2 + R^2 sin(θ)^2 dφ^2", "--coords", "θ,φ", "--from", "1,0", "--to", "2,1.5"];
    let (code, out, err) = run(&radius);
    assert_eq!((code, out.as_str()), (2, ""), "{err}");
    assert!(err.contains("needs a value for `R`"), "{err}");
    let (code, out, err) = run(&[&radius[..], &["--set", "R=2"]].concat());
    assert_eq!(code, 0, "{err}");
    assert!(line(&out, "shooting: ").starts_with("q'(0) = ("), "{out}");
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

#[test]
fn curvature_of_the_cosh_metric_prints_as_minus_one() {
    // Regression: with Γ^x_yy = −sinh x cosh x and Γ^y_xy = tanh x, tidy alone left
    // K = sinh(x) tanh(x)/cosh(x) + 1/cosh(x)^2 − 2; Gauss's K = −(√G)''/√G with √G = cosh x
    // is −1 exactly, and so is the printed form now.
    let (code, out, err) = run(&["geodesic", "dx^2 + cosh(x)^2 dy^2", "--coords", "x,y"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(line(&out, "K = "), "-1", "{out}");
    assert_eq!(line(&out, "scalar_curvature = "), "-2", "{out}");
    // The same route on the sphere written with tan: ds² = dθ² + (tan θ cos θ)² dφ² is the unit
    // sphere (tan θ cos θ = sin θ), K = 1.
    let (code, out, err) = run(&["geodesic", "dθ^2 + (tan(θ) cos(θ))^2 dφ^2", "--coords", "θ,φ"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(line(&out, "K = "), "1", "{out}");
}

#[test]
fn a_metric_matrix_gives_the_line_elements_geodesics() {
    let (code, a, err) = run(&["geodesic", SPHERE, "--coords", "θ,φ"]);
    assert_eq!(code, 0, "{err}");
    let (code, b, err) = run(&["geodesic", "--metric", "1, 0; 0, sin(θ)^2", "--coords", "θ,φ"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(a, b);
    // Bad metrics: not symmetric, the wrong shape, singular everywhere; exit 2, nothing printed.
    for (metric, needle) in
        [("1, θ; 0, sin(θ)^2", "not symmetric"), ("1, 0, 0; 0, 1, 0", "2×2"), ("1, 1; 1, 1", "singular everywhere")]
    {
        let (code, out, err) = run(&["geodesic", "--metric", metric, "--coords", "θ,φ"]);
        assert_eq!((code, out.as_str()), (2, ""), "{metric}: {err}");
        assert!(err.contains(needle), "{metric}: {err}");
    }
}

/// A surface of §1.6.3's exercise: embedding, coordinates, parameters, a start point and velocity.
type Surface = (&'static str, &'static str, &'static [(&'static str, f64)], [f64; 4]);

const SURFACES: [Surface; 3] = [
    ("R sin(θ) cos(φ), R sin(θ) sin(φ), R cos(θ)", "θ,φ", &[("R", 1.7)], [1.0, 0.2, 0.3, 0.8]),
    // A torus: tube radius a around a circle of radius A.
    ("(A + a cos(v)) cos(u), (A + a cos(v)) sin(u), a sin(v)", "u,v", &[("A", 2.0), ("a", 0.7)], [0.3, 0.2, 0.5, 1.3]),
    // A graph z = f(x, y), the egg box f = sin x cos y.
    ("x, y, sin(x) cos(y)", "x,y", &[], [0.4, -0.3, 0.9, 0.5]),
];

#[test]
fn geodesic_curvature_vector_is_normal_to_an_embedded_surface() {
    for (surface, coords, _, _) in SURFACES {
        let (code, out, err) = run(&["geodesic", "--embedding", surface, "--coords", coords]);
        assert_eq!(code, 0, "{surface}: {err}");
        let names: Vec<&str> = coords.split(',').collect();
        for q in &names {
            let v = line(&out, &format!("X_{q} · d²x/ds² = "));
            assert_eq!(v.split("    #").next(), Some("0"), "{surface}: {out}");
        }
        // The induced metric g_ij = X_i · X_j, against hand forms.
        let g = |i: usize, j: usize| parse(line(&out, &format!("g[{},{}] = ", names[i], names[j]))).unwrap();
        let hand: [&str; 3] = match coords {
            "θ,φ" => ["R^2", "0", "R^2 sin(θ)^2"],
            "u,v" => ["(A + a cos(v))^2", "0", "a^2"],
            _ => ["1 + cos(x)^2 cos(y)^2", "-sin(x) cos(x) sin(y) cos(y)", "1 + sin(x)^2 sin(y)^2"],
        };
        let env: std::collections::HashMap<String, f64> = [
            ("R", 1.3),
            ("A", 2.0),
            ("a", 0.6),
            ("θ", 0.7),
            ("φ", 0.1),
            ("u", 0.4),
            ("v", -1.1),
            ("x", 0.3),
            ("y", 1.2),
        ]
        .iter()
        .map(|(k, v)| (k.to_string(), *v))
        .collect();
        if coords == "x,y" {
            // Monge patch z = f: K = (f_xx f_yy − f_xy²)/(1 + f_x² + f_y²)², and R = 2K.
            let (x, y) = (env["x"], env["y"]);
            let (fx, fy) = (x.cos() * y.cos(), -x.sin() * y.sin());
            let (fxx, fyy, fxy) = (-x.sin() * y.cos(), -x.sin() * y.cos(), -x.cos() * y.sin());
            let monge = (fxx * fyy - fxy * fxy) / (1.0 + fx * fx + fy * fy).powi(2);
            let at = |name: &str| lagrangian::eval::eval(&parse(line(&out, name)).unwrap(), &env).unwrap();
            assert!((at("K = ") - monge).abs() < 1e-14, "{surface}: K = {}, Monge {monge}", at("K = "));
            assert!((at("scalar_curvature = ") - 2.0 * monge).abs() < 1e-14, "{surface}: R ≠ 2K");
        }
        for (k, (i, j)) in [(0, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let (got, want) = (
                lagrangian::eval::eval(&g(i, j), &env).unwrap(),
                lagrangian::eval::eval(&parse(hand[k]).unwrap(), &env).unwrap(),
            );
            assert!((got - want).abs() < 1e-14, "{surface}: g[{i},{j}] = {got}, by hand {want}");
        }
    }
}

/// `X`, `X_i` and `X_ij` of the surfaces above at a point, by hand (the test's own route).
fn hand_derivatives(k: usize, q: [f64; 2], p: &[(&str, f64)]) -> ([[f64; 3]; 2], [[[f64; 3]; 2]; 2]) {
    let (s, c) = (|x: f64| x.sin(), |x: f64| x.cos());
    let (a, b) = (q[0], q[1]);
    match k {
        0 => {
            let r = p[0].1;
            let xi = [[r * c(a) * c(b), r * c(a) * s(b), -r * s(a)], [-r * s(a) * s(b), r * s(a) * c(b), 0.0]];
            let xaa = [-r * s(a) * c(b), -r * s(a) * s(b), -r * c(a)];
            let xab = [-r * c(a) * s(b), r * c(a) * c(b), 0.0];
            let xbb = [-r * s(a) * c(b), -r * s(a) * s(b), 0.0];
            (xi, [[xaa, xab], [xab, xbb]])
        }
        1 => {
            let (big, tube) = (p[0].1, p[1].1);
            let w = big + tube * c(b);
            let xi = [[-w * s(a), w * c(a), 0.0], [-tube * s(b) * c(a), -tube * s(b) * s(a), tube * c(b)]];
            let xaa = [-w * c(a), -w * s(a), 0.0];
            let xab = [tube * s(b) * s(a), -tube * s(b) * c(a), 0.0];
            let xbb = [-tube * c(b) * c(a), -tube * c(b) * s(a), -tube * s(b)];
            (xi, [[xaa, xab], [xab, xbb]])
        }
        _ => {
            let xi = [[1.0, 0.0, c(a) * c(b)], [0.0, 1.0, -s(a) * s(b)]];
            let xaa = [0.0, 0.0, -s(a) * c(b)];
            let xab = [0.0, 0.0, -c(a) * s(b)];
            let xbb = [0.0, 0.0, -s(a) * c(b)];
            (xi, [[xaa, xab], [xab, xbb]])
        }
    }
}

#[test]
fn integrated_geodesics_accelerate_along_the_normal() {
    use lagrangian::integrate::{Dop853, Integrate, Rhs};
    for (k, (surface, coords, params, start)) in SURFACES.iter().enumerate() {
        let z: Vec<Symbol> = coords.split(',').map(Symbol::new).collect();
        let x: Vec<lagrangian::Expr> = surface.split(", ").map(|c| parse(c).unwrap()).collect();
        let emb = lagrangian::mechanics::embedded(&x, &z).unwrap();
        let sys = emb.geodesic.system().unwrap().with_params(params).unwrap();
        let rhs = sys.compile_rhs().unwrap();
        let tr = Dop853::new(1e-12, 1e-12).integrate(&rhs, 0.0..4.0, start).unwrap();
        let mut worst: f64 = 0.0;
        let mut dy = [0.0; 4];
        for i in 0..tr.len() {
            let y = tr.state(i);
            rhs.eval(0.0, y, &mut dy);
            let (xi, xij) = hand_derivatives(k, [y[0], y[1]], params);
            // d²x/ds² = Σ X_ij q'_i q'_j + Σ X_k q''_k, with q'' from the engine's equations.
            let mut kappa = [0.0; 3];
            for c in 0..3 {
                for a in 0..2 {
                    kappa[c] += xi[a][c] * dy[2 + a];
                    for b in 0..2 {
                        kappa[c] += xij[a][b][c] * y[2 + a] * y[2 + b];
                    }
                }
            }
            let size = kappa.iter().map(|v| v * v).sum::<f64>().sqrt().max(1.0);
            for t in &xi {
                let tnorm = t.iter().map(|v| v * v).sum::<f64>().sqrt();
                let along = t.iter().zip(&kappa).map(|(a, b)| a * b).sum::<f64>() / tnorm;
                worst = worst.max(along.abs() / size);
            }
        }
        assert!(tr.len() > 10, "{surface}: {} states", tr.len());
        assert!(worst < 1e-10, "{surface}: tangential part of d²x/ds² up to {worst:e}");
    }
}
