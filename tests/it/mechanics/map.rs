//! Iterated maps (`mechanics::ExplicitMap`, `mechanics::ImplicitMap`): the standard map
//! p' = p + K sin q, q' = q + p' against closed forms, a hand iteration and area preservation;
//! the implicit midpoint rule (the notes' difference approximations, §4.7.2) against its closed
//! form and for area preservation; unsolvable steps and mixed forms.

use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::{ExplicitMap, ImplicitMap, MapError};
use lagrangian::{parse_with, Declarations};

fn standard_map(k: f64) -> ExplicitMap {
    let d = Declarations::new();
    let (q, p) = (Symbol::new("q"), Symbol::new("p"));
    let updates: Vec<(Symbol, Expr)> = vec![
        (p.clone(), parse_with("p + K sin(q)", &d).expect("parses")),
        (q.clone(), parse_with("q + p", &d).expect("parses")),
    ];
    ExplicitMap::new(&[q, p], &updates, &[("K", k)]).expect("compiles")
}

/// K = 0: a rigid rotation, q_n = q_0 + n p_0 and p_n = p_0 (closed form).
#[test]
fn with_k_zero_the_standard_map_is_a_rigid_rotation() {
    let m = standard_map(0.0);
    let orbits = m.orbits(&[vec![0.3, 0.7], vec![-2.0, 0.125]], 1000).expect("iterates");
    for o in &orbits {
        assert_eq!(o.len(), 1001);
        let (q0, p0) = (o[0][0], o[0][1]);
        for (n, s) in o.iter().enumerate() {
            let q = q0 + n as f64 * p0;
            assert!((s[0] - q).abs() <= 1e-12 * q.abs().max(1.0), "step {n}: {} vs {q}", s[0]);
            assert_eq!(s[1], p0);
        }
    }
}

/// Three steps from (q, p) = (1, 0.5) with K = 0.9, iterated by hand in Python (floats):
/// (5.375066801394972, 1.1643125003166652).
#[test]
fn three_steps_agree_with_a_hand_iteration() {
    let m = standard_map(0.9);
    let o = &m.orbits(&[vec![1.0, 0.5]], 3).expect("iterates")[0];
    let last = &o[3];
    assert!((last[0] - 5.375066801394972).abs() < 1e-13, "{last:?}");
    assert!((last[1] - 1.1643125003166652).abs() < 1e-13, "{last:?}");
}

/// The map is area-preserving: the determinant of its Jacobian, by central differences
/// (independent of the symbolic form), is 1 to 1e-10 at points across the cylinder.
#[test]
fn the_standard_map_preserves_area() {
    let m = standard_map(1.3);
    let at = |q: f64, p: f64| {
        let mut out = [0.0; 2];
        m.step(&[q, p], &mut out);
        out
    };
    // Central differences with one Richardson step (error O(h⁴) ≈ 1e-12 at h = 1e-3).
    let central = |q: f64, p: f64, h: f64| {
        let (a, b) = (at(q + h, p), at(q - h, p));
        let (c, d) = (at(q, p + h), at(q, p - h));
        [[(a[0] - b[0]) / (2.0 * h), (c[0] - d[0]) / (2.0 * h)], [(a[1] - b[1]) / (2.0 * h), (c[1] - d[1]) / (2.0 * h)]]
    };
    for &(q, p) in &[(0.1, 0.2), (1.7, -0.4), (3.0, 2.5), (-2.2, 0.9), (5.9, -3.1)] {
        let (j1, j2) = (central(q, p, 1e-3), central(q, p, 5e-4));
        let r = |i: usize, k: usize| (4.0 * j2[i][k] - j1[i][k]) / 3.0;
        let j = [[r(0, 0), r(0, 1)], [r(1, 0), r(1, 1)]];
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        assert!((det - 1.0).abs() < 1e-10, "det at ({q}, {p}) = {det}");
    }
}

/// An orbit that leaves the finite numbers stops there; too much work is refused.
#[test]
fn a_diverging_orbit_stops_and_too_much_work_is_refused() {
    let d = Declarations::new();
    let x = Symbol::new("x");
    let updates = [(x.clone(), parse_with("x^2", &d).expect("parses"))];
    let m = ExplicitMap::new(&[x], &updates, &[]).expect("compiles");
    let o = &m.orbits(&[vec![10.0]], 100).expect("iterates")[0];
    assert!(o.len() < 101 && !o.last().expect("states")[0].is_finite(), "{}", o.len());
    assert!(m.orbits(&vec![vec![1.0]; 100], 10_000_000).is_err());
}

fn implicit(updates: &[(&str, &str)], params: &[(&str, f64)]) -> Result<ImplicitMap, MapError> {
    let d = Declarations::new();
    let vars = [Symbol::new("q"), Symbol::new("p")];
    let updates: Vec<(Symbol, Expr)> = updates
        .iter()
        .map(|(n, v)| (Symbol::new(n.trim_end_matches('\'')).with_primes(1), parse_with(v, &d).expect("parses")))
        .collect();
    ImplicitMap::new(&vars, &updates, params)
}

/// The implicit midpoint rule on the oscillator H = (q² + p²)/2 is the Cayley transform of the
/// rotation: each step turns (q, p) clockwise by exactly θ = 2 atan(h/2) (closed form, solving the
/// 2 × 2 linear step by hand). After 1000 steps the state is the rotation by 1000 θ.
#[test]
fn the_implicit_midpoint_rule_rotates_by_the_cayley_angle() {
    let h = 0.1;
    let m = implicit(&[("q'", "q + h (p + p')/2"), ("p'", "p - h (q + q')/2")], &[("h", h)]).expect("compiles");
    let (orbits, unsolved) = m.orbits(&[vec![1.0, 0.0], vec![0.3, -0.7]], 1000).expect("iterates");
    assert_eq!(unsolved, 0);
    let theta = 2.0 * (h / 2.0).atan();
    for o in &orbits {
        let (q0, p0) = (o[0][0], o[0][1]);
        for (n, s) in o.iter().enumerate().step_by(100) {
            let a = n as f64 * theta;
            let (q, p) = (q0 * a.cos() + p0 * a.sin(), p0 * a.cos() - q0 * a.sin());
            assert!((s[0] - q).abs() < 1e-12 && (s[1] - p).abs() < 1e-12, "step {n}: {s:?} vs ({q}, {p})");
        }
    }
}

/// The implicit midpoint rule is symplectic (§4.7.2), for a nonlinear H too: on the pendulum
/// H = p²/2 − cos q the determinant of one step's Jacobian, by central differences with one
/// Richardson step, is 1 to 1e-9 at points across phase space.
#[test]
fn the_implicit_midpoint_pendulum_map_preserves_area() {
    let m = implicit(&[("q'", "q + h (p + p')/2"), ("p'", "p - h sin((q + q')/2)")], &[("h", 0.3)]).expect("compiles");
    let at = |q: f64, p: f64| {
        let mut out = [0.0; 2];
        m.step(&[q, p], &mut out).expect("solves");
        out
    };
    let central = |q: f64, p: f64, e: f64| {
        let (a, b) = (at(q + e, p), at(q - e, p));
        let (c, d) = (at(q, p + e), at(q, p - e));
        [[(a[0] - b[0]) / (2.0 * e), (c[0] - d[0]) / (2.0 * e)], [(a[1] - b[1]) / (2.0 * e), (c[1] - d[1]) / (2.0 * e)]]
    };
    for &(q, p) in &[(0.1, 0.2), (1.7, -0.4), (3.0, 1.5), (-2.2, 0.9)] {
        let (j1, j2) = (central(q, p, 1e-3), central(q, p, 5e-4));
        let r = |i: usize, k: usize| (4.0 * j2[i][k] - j1[i][k]) / 3.0;
        let det = r(0, 0) * r(1, 1) - r(0, 1) * r(1, 0);
        assert!((det - 1.0).abs() < 1e-9, "det at ({q}, {p}) = {det}");
    }
}

/// A step with no real solution (q' = q + q'² + 1 has none for q > −3/4) ends its orbit with
/// NaN and is counted, never replaced by a guess; a start that can be solved keeps going.
/// Mixed forms are refused.
#[test]
fn an_unsolvable_step_ends_its_orbit_and_mixed_forms_are_refused() {
    let m = implicit(&[("q'", "q + q'^2 + 1")], &[]).expect("compiles");
    let (orbits, unsolved) = m.orbits(&[vec![0.0, 0.0]], 5).expect("iterates");
    assert_eq!(unsolved, 1);
    assert!(orbits[0].len() == 2 && orbits[0][1][0].is_nan(), "{:?}", orbits[0]);
    // q' = q + q'² − q' has the roots q' = 1 ± √(1 − q): 3 and −1 at q = −3.
    let m = implicit(&[("q'", "q + q'^2 - q'")], &[]).expect("compiles");
    let mut out = [0.0; 2];
    assert!(m.step(&[-3.0, 0.0], &mut out).is_some());
    assert!([3.0, -1.0].iter().any(|r| (out[0] - r).abs() < 1e-12), "{out:?}");
    let d = Declarations::new();
    let (q, p) = (Symbol::new("q"), Symbol::new("p"));
    let mixed = [(q.with_primes(1), parse_with("q + p", &d).unwrap()), (p.clone(), parse_with("p", &d).unwrap())];
    assert!(matches!(ImplicitMap::new(&[q.clone(), p.clone()], &mixed, &[]), Err(MapError::Mixed(_))));
    let reads_new = [(p.clone(), parse_with("p - q'", &d).unwrap())];
    assert!(matches!(ExplicitMap::new(&[q, p], &reads_new, &[]), Err(MapError::Mixed(_))));
}
