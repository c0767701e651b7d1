//! `jacobian` (§1.3): the Jacobian matrix and determinant of a map of
//! coordinates. Spherical coordinates by hand (J = r² sin θ); the ideal fluid's Lagrangian map
//! x(r₀, t) of §1.3 for a shear (volume-preserving, J = 1) and a rotation-with-dilation
//! (J = e^{3t}, by hand), and every entry of a nonlinear map against central differences.

use lagrangian::eval::eval;
use lagrangian::mechanics::jacobian;
use lagrangian::{parse, Expr, Symbol};

use crate::support::notes::run;

fn p(s: &str) -> Expr {
    parse(s).expect("test input parses")
}

fn syms(names: &[&str]) -> Vec<Symbol> {
    names.iter().map(|n| Symbol::new(n)).collect()
}

#[test]
fn spherical_and_fluid_jacobians() {
    let (code, out, err) = run(&["jacobian", "r sin(θ) cos(φ), r sin(θ) sin(φ), r cos(θ)", "--in", "r,θ,φ"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.lines().any(|l| l == "det = r^2 sin(θ)"), "{out}");
    // §1.3: x(r₀, t) for a shear flow, x = x0 + t y0: incompressible, J = 1.
    let (_, det) = jacobian(&[p("x0 + t y0"), p("y0"), p("z0")], &syms(&["x0", "y0", "z0"])).expect("square");
    assert_eq!(det, Expr::one());
    // A rotation by t about z with the uniform dilation e^t: J = e^{3t}.
    let map = [p("exp(t) (x0 cos(t) - y0 sin(t))"), p("exp(t) (x0 sin(t) + y0 cos(t))"), p("exp(t) z0")];
    let (_, det) = jacobian(&map, &syms(&["x0", "y0", "z0"])).expect("square");
    assert!(lagrangian::canonical::decide_zero(&det.minus(&p("exp(3 t)"))).is_zero(), "{det}");
}

#[test]
fn entries_match_central_differences_and_mismatch_is_refused() {
    let vars = syms(&["u", "v"]);
    let map = [p("u^2 sin(v) + exp(u v)"), p("log(1 + u^2) v^3")];
    let (m, det) = jacobian(&map, &vars).expect("square");
    let (u0, v0, h) = (0.7, 1.3, 1e-5);
    let at = |e: &Expr, u: f64, v: f64| {
        let env = [("u".to_string(), u), ("v".to_string(), v)].into_iter().collect();
        eval(e, &env).expect("evaluates")
    };
    let mut num = [[0.0; 2]; 2];
    for i in 0..2 {
        num[i][0] = (at(&map[i], u0 + h, v0) - at(&map[i], u0 - h, v0)) / (2.0 * h);
        num[i][1] = (at(&map[i], u0, v0 + h) - at(&map[i], u0, v0 - h)) / (2.0 * h);
        for j in 0..2 {
            let sym = at(&m[i][j], u0, v0);
            assert!((sym - num[i][j]).abs() < 1e-8 * (1.0 + sym.abs()), "J[{i}][{j}] = {sym} vs {}", num[i][j]);
        }
    }
    let det_num = num[0][0] * num[1][1] - num[0][1] * num[1][0];
    assert!((at(&det, u0, v0) - det_num).abs() < 1e-7 * (1.0 + det_num.abs()));
    let (code, out, err) = run(&["jacobian", "r cos(φ), r sin(φ)", "--in", "r"]);
    assert_eq!((code, out.as_str()), (2, ""));
    assert!(err.contains("2 component(s) but --in names 1"), "{err}");
}
