//! Iterated explicit maps (`mechanics::ExplicitMap`): the standard map p' = p + K sin q,
//! q' = q + p' against closed forms, a hand iteration and area preservation.

use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::ExplicitMap;
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
