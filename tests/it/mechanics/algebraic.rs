//! Coordinates without their velocity (§3.2.1, Remark 3.1): the algebraic equation ∂L/∂y = 0
//! solved for y when it is linear, the reduced Lagrangian, and its simulation against closed
//! forms derived by hand; nonlinear or degenerate equations refused, naming what would work.

use lagrangian::eval::eval_with;
use lagrangian::expr::Expr;
use lagrangian::mechanics::System;
use lagrangian::simulate::{self, MethodId, RunOptions, Sampling, SimulateError};

use crate::support::run_scene_in;

/// `a` and `b` agree at a few points of (x, x') (the engine's printed form is not compared).
fn same(a: &Expr, b: &str) {
    let b = lagrangian::parse::parse(b).unwrap();
    for (x, v) in [(0.3, -1.1), (1.7, 0.4), (-2.2, 2.5)] {
        let at = |s: &lagrangian::expr::Symbol| match (s.name(), s.primes()) {
            ("x", 0) => Some(x),
            ("x", 1) => Some(v),
            _ => None,
        };
        let (ea, eb) = (eval_with(a, &at).unwrap(), eval_with(&b, &at).unwrap());
        assert!((ea - eb).abs() < 1e-12, "{a} against {b} at x = {x}, x' = {v}: {ea} and {eb}");
    }
}

fn final_x(sys: &System, method: MethodId, t1: f64) -> f64 {
    let c = simulate::compile_system(sys, method, &[]).unwrap();
    assert_eq!(c.state, ["x", "x'"], "the reduced state");
    let mut o = RunOptions::new(method, 0.0, t1);
    o.dt = Some(1e-3);
    o.sampling = Sampling::Final;
    simulate::integrate(&c, &[1.0, 0.0], &o, &mut |_| {}).unwrap().last_state().unwrap()[0]
}

/// `L = ½ẋ² − ½x² − ½(y − x)²`: ∂L/∂y = x − y = 0, so y = x and `L_r = ½ẋ² − ½x²`, whose
/// solution from x = 1 at rest is cos t.
#[test]
fn a_linear_algebraic_equation_is_solved_and_the_reduced_system_runs() {
    let sys = System::from_lagrangian("1/2 x'^2 - 1/2 x^2 - 1/2 (y - x)^2", &["x", "y"]).unwrap();
    assert_eq!(sys.velocity_free_coordinates().iter().map(|s| s.name()).collect::<Vec<_>>(), ["y"]);
    let red = sys.eliminate_velocity_free().unwrap();
    assert_eq!(red.eliminated.len(), 1);
    assert_eq!(red.eliminated[0].0.name(), "y");
    same(&red.eliminated[0].1, "x");
    same(&red.lagrangian, "1/2 x'^2 - 1/2 x^2");
    let x = final_x(&sys, MethodId::Rk4, 2.0);
    assert!((x - 2f64.cos()).abs() < 1e-10, "x(2) = {x}, cos 2 = {}", 2f64.cos());
}

/// A velocity inside the algebraic equation: `L = ½ẋ² + y ẋ − ½y² − ½x²` gives ∂L/∂y = ẋ − y,
/// so y = ẋ and `L_r = ẋ² − ½x²`: `2ẍ = −x`, x = cos(t/√2) (by hand).
#[test]
fn an_eliminated_coordinate_may_depend_on_a_velocity() {
    let sys = System::from_lagrangian("1/2 x'^2 + y x' - 1/2 y^2 - 1/2 x^2", &["x", "y"]).unwrap();
    let red = sys.eliminate_velocity_free().unwrap();
    same(&red.eliminated[0].1, "x'");
    same(&red.lagrangian, "x'^2 - 1/2 x^2");
    let x = final_x(&sys, MethodId::Rk4, 3.0);
    let exact = (3.0 / 2f64.sqrt()).cos();
    assert!((x - exact).abs() < 1e-8, "x(3) = {x}, exact {exact}");
}

#[test]
fn an_equation_not_solved_for_its_coordinate_is_refused_with_what_would_work() {
    let cases: [(&str, &str); 2] =
        [("1/2 x'^2 - 1/2 x^2 - 1/4 y^4 + x y", "not linear in y"), ("1/2 x'^2 - 1/2 x^2 + x y", "does not contain y")];
    for (l, why) in cases {
        let sys = System::from_lagrangian(l, &["x", "y"]).unwrap();
        let e = sys.eliminate_velocity_free().unwrap_err().to_string();
        assert!(e.contains(why) && (e.contains("would work") || e.contains("give y a kinetic term")), "{l}: {e}");
        // The library's simulate refuses the same way instead of failing at t = 0.
        match simulate::compile_system(&sys, MethodId::Rk4, &[]) {
            Err(SimulateError::Mechanics(m)) => assert!(m.to_string().contains(why), "{l}: {m}"),
            Err(other) => panic!("{l}: not the elimination's refusal: {other}"),
            Ok(_) => panic!("{l}: compiled"),
        }
    }
    let forced =
        System::from_lagrangian("1/2 x'^2 - 1/2 (y - x)^2", &["x", "y"]).unwrap().with_force("x", "-x'").unwrap();
    let e = forced.reduced_system().unwrap_err().to_string();
    assert!(e.contains("conservative, unconstrained L"), "{e}");
}

/// A scene's `simulate` refuses before integrating (it used to stop at t = 0 with a singular
/// mass matrix) and gives the reduced system to simulate instead.
#[test]
fn a_scene_gives_the_reduced_system_of_a_coordinate_without_velocity() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "coordinates x, y\nL = 1/2 x'^2 - 1/2 x^2 - 1/2 (y - x)^2\nsimulate x = 1, x' = 0, y = 1, y' = 0 for t in 0..1 with rk4 dt = 0.01\nexport x to out.csv\n";
    let (code, out, err) = run_scene_in(dir.path(), scene, &[]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("has no velocity in L") && err.contains("y = x"), "{err}");
    assert!(err.contains("coordinates x") && err.contains("x'^2/2 - x^2/2"), "{err}");
}
