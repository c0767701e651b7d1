//! Velocity constraints (§1.5, §1.6.2): the Lagrange–d'Alembert equations with multipliers of
//! the upright rolling coin with a spring on x, against SymPy's KanesMethod and
//! LagrangesMethod (scripts/nonholonomic_sympy.py), and refusals of what is not handled.

use lagrangian::eval::eval_with;
use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::System;
use lagrangian::parse::parse;

use crate::support::run;

const L: &str = "1/2 m (x'^2 + y'^2) + 1/2 I θ'^2 + 1/2 J φ'^2 - 1/2 k x^2";
const ROLL: [&str; 2] = ["x' - R φ' cos(θ)", "y' - R φ' sin(θ)"];

/// From scripts/nonholonomic_sympy.py at x = 0.4, y = −0.3, θ = 0.9, φ = 0.2, θ' = 0.8,
/// φ' = −1.1 (x', y' from the constraints), m = 2, I = 0.7, J = 1.3, R = 0.5, k = 3.
const KANE: [f64; 4] = [0.280_264_014_793_85, -0.354_662_355_278_941_9, 0.0, -0.207_203_322_756_888_1];
const MULTIPLIERS: [f64; 2] = [1.760_528_029_587_700_2, -0.709_324_710_557_883_9];

fn value(s: &Symbol) -> Option<f64> {
    let (r, ph) = (0.5f64, -1.1f64);
    let th = 0.9f64;
    Some(match (s.name(), s.primes()) {
        ("x", 0) => 0.4,
        ("y", 0) => -0.3,
        ("θ", 0) => th,
        ("φ", 0) => 0.2,
        ("θ", 1) => 0.8,
        ("φ", 1) => ph,
        ("x", 1) => r * ph * th.cos(),
        ("y", 1) => r * ph * th.sin(),
        ("m", 0) => 2.0,
        ("I", 0) => 0.7,
        ("J", 0) => 1.3,
        ("R", 0) => r,
        ("k", 0) => 3.0,
        _ => return None,
    })
}

/// Gaussian elimination with partial pivoting (the test's own, not the engine's).
#[allow(clippy::needless_range_loop)]
fn solve(mut m: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| m[i][c].abs().total_cmp(&m[j][c].abs())).unwrap();
        m.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = m[r][c] / m[c][c];
            for k in c..n {
                m[r][k] -= f * m[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        x[r] = (b[r] - (r + 1..n).map(|k| m[r][k] * x[k]).sum::<f64>()) / m[r][r];
    }
    x
}

#[test]
#[allow(clippy::needless_range_loop)]
fn rolling_coin_lagrange_dalembert_matches_kanes_method() {
    let sys = System::from_lagrangian(L, &["x", "y", "θ", "φ"]).unwrap();
    let gs: Vec<Expr> = ROLL.iter().map(|g| parse(g).unwrap()).collect();
    let c = sys.lagrange_dalembert(&gs).unwrap();
    let ev = |e: &Expr| eval_with(e, &value).unwrap_or_else(|err| panic!("{e}: {err}"));
    // [W −aᵀ; a 0] [q''; μ] = [F; c]
    let (n, k) = (4, 2);
    let mut m = vec![vec![0.0; n + k]; n + k];
    let mut b = vec![0.0; n + k];
    for i in 0..n {
        for j in 0..n {
            m[i][j] = ev(&c.w[i][j]);
        }
        b[i] = ev(&c.f[i]);
    }
    for (j, row) in c.phi.iter().enumerate() {
        for (i, a) in row.iter().enumerate() {
            m[i][n + j] = -ev(a);
            m[n + j][i] = ev(a);
        }
        b[n + j] = ev(&c.c[j]);
    }
    let sol = solve(m, b);
    for i in 0..n {
        assert!((sol[i] - KANE[i]).abs() < 1e-12, "q''[{i}] = {}, KanesMethod {}", sol[i], KANE[i]);
    }
    for j in 0..k {
        assert!((sol[n + j] - MULTIPLIERS[j]).abs() < 1e-12, "μ{} = {}, SymPy {}", j + 1, sol[n + j], MULTIPLIERS[j]);
    }
    // The printed equations themselves: substituting the solution makes each vanish.
    let with_solution = |s: &Symbol| match (s.name(), s.primes()) {
        ("x", 2) => Some(sol[0]),
        ("y", 2) => Some(sol[1]),
        ("θ", 2) => Some(sol[2]),
        ("φ", 2) => Some(sol[3]),
        ("μ1", 0) => Some(sol[4]),
        ("μ2", 0) => Some(sol[5]),
        _ => value(s),
    };
    for e in &c.equations {
        let r = eval_with(e, &with_solution).unwrap();
        assert!(r.abs() < 1e-12, "{e} = {r}");
    }
}

#[test]
fn el_prints_the_lagrange_dalembert_equations() {
    let (code, out, err) = run(&[
        "el",
        L,
        "--coords",
        "x,y,θ,φ",
        "--velocity-constraint",
        "x' = R φ' cos(θ)",
        "--velocity-constraint",
        "y' = R φ' sin(θ)",
    ]);
    assert_eq!(code, 0, "{err}");
    for line in [
        "Lagrange–d'Alembert x: k x - μ1 + m x'' = 0",
        "Lagrange–d'Alembert y: m y'' - μ2 = 0",
        "Lagrange–d'Alembert θ: I θ'' = 0",
        "Lagrange–d'Alembert φ: J φ'' + R (μ1 cos(θ) + μ2 sin(θ)) = 0",
        "d/dt of velocity constraint 1: x'' - R φ'' cos(θ) = -R θ' φ' sin(θ)",
        "d/dt of velocity constraint 2: y'' - R φ'' sin(θ) = R θ' φ' cos(θ)",
    ] {
        assert!(out.lines().any(|l| l == line), "no `{line}` in\n{out}");
    }
}

#[test]
fn velocity_constraints_that_are_not_linear_or_have_no_velocity_are_refused() {
    for (g, why) in
        [("x'^2 - 1", "not linear in the velocities"), ("x - 1", "contains no velocity"), ("x'' - 1", "acceleration")]
    {
        let (code, out, err) = run(&["el", "1/2 x'^2", "--coords", "x", "--velocity-constraint", g]);
        assert_eq!((code, out.as_str()), (2, ""), "{g}");
        assert!(err.contains(why), "{g}: {err}");
    }
}
