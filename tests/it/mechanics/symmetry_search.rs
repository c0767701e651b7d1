//! `lagrangian conserved` reports the point
//! symmetries of the search with the same lines as scene `conserved`, and the search covers
//! generators of degree 2 with a change of time. Every charge found is checked here against a
//! hand form and, independently of the engine's bracket, by evaluating it along the exact
//! motion (which must leave it constant).

// The RK4 loop reads several state components at one index.
#![allow(clippy::needless_range_loop)]

use crate::support;

use lagrangian::canonical::symmetry::{point_symmetries, DEGREE};
use lagrangian::canonical::{decide_zero, ZeroCheck};
use lagrangian::mechanics::System;
use lagrangian::{parse_with, Declarations, Expr, Symbol};
use support::run;

fn decls(positive: &[&str]) -> Declarations {
    Declarations::new().with_positive(positive.iter().copied())
}

fn cli(args: &[&str]) -> Vec<String> {
    let (code, out, err) = run(args);
    assert_eq!(code, 0, "{args:?}: {err}");
    out.lines().map(str::to_string).collect()
}

/// `a = ±b`, proven.
fn equal_up_to_sign(a: &Expr, b: &Expr) -> bool {
    decide_zero(&a.minus(b)) == ZeroCheck::Proven || decide_zero(&a.plus(b)) == ZeroCheck::Proven
}

/// The value of a `Q… = value   (note)` line, re-parsed.
fn value_of(line: &str, d: &Declarations) -> Expr {
    let rhs = line.split_once(" = ").expect("name = value").1;
    parse_with(rhs.split("   (").next().expect("a value"), d).unwrap_or_else(|e| panic!("`{line}`: {e}"))
}

/// `f` along `q_i(t)`, `q'_i(t)` given as closures, at the times `ts`.
fn along(
    f: &Expr,
    coords: &[&str],
    path: &dyn Fn(f64) -> Vec<(f64, f64)>,
    params: &[(&str, f64)],
    ts: &[f64],
) -> Vec<f64> {
    ts.iter()
        .map(|&t| {
            let state = path(t);
            let mut env: lagrangian::eval::Env = params.iter().map(|(k, v)| (k.to_string(), *v)).collect();
            for (c, (q, v)) in coords.iter().zip(state) {
                env.insert(c.to_string(), q);
                env.insert(format!("{c}'"), v);
            }
            env.insert("t".into(), t);
            lagrangian::eval::eval(f, &env).expect("the charge evaluates")
        })
        .collect()
}

fn spread(v: &[f64]) -> f64 {
    v.iter().map(|x| (x - v[0]).abs()).fold(0.0, f64::max)
}

#[test]
fn cli_conserved_finds_lz_for_kepler_in_cartesian_coordinates() {
    let l = "1/2 m (x'^2 + y'^2) + k/sqrt(x^2 + y^2)";
    let out = cli(&["conserved", l, "--coords", "x,y", "--positive", "m,k"]);
    let q: Vec<&String> = out.iter().filter(|l| l.starts_with('Q')).collect();
    assert_eq!(q.len(), 1, "{out:#?}");
    assert!(q[0].contains("rotation in (x, y): ξ = (-y, x)"), "the generator is named: {}", q[0]);
    assert!(q[0].contains("{Q, H} + ∂Q/∂t is zero (proven symbolically)"), "{}", q[0]);
    assert!(q[0].contains(&format!("point symmetries searched: ξ(q, t) and τ(q, t) polynomials of degree ≤ {DEGREE}")));
    let d = decls(&["m", "k"]);
    let lz = value_of(q[0], &d);
    assert!(equal_up_to_sign(&lz, &parse_with("m (x y' - y x')", &d).unwrap()), "{lz}");
    // Independently: constant along a Kepler ellipse integrated here by RK4 (k = m = 1).
    let (m, k) = (1.0, 1.0);
    let mut s = [1.0f64, 0.0, 0.0, 1.2];
    let f = |s: &[f64; 4]| {
        let r3 = (s[0] * s[0] + s[1] * s[1]).powf(1.5);
        [s[2], s[3], -k * s[0] / (m * r3), -k * s[1] / (m * r3)]
    };
    let h = 1e-3;
    let mut values = Vec::new();
    for step in 0..4000 {
        if step % 500 == 0 {
            values.extend(along(
                &lz,
                &["x", "y"],
                &|_| vec![(s[0], s[2]), (s[1], s[3])],
                &[("m", m), ("k", k)],
                &[0.0],
            ));
        }
        let add =
            |a: &[f64; 4], b: &[f64; 4], c: f64| [a[0] + c * b[0], a[1] + c * b[1], a[2] + c * b[2], a[3] + c * b[3]];
        let k1 = f(&s);
        let k2 = f(&add(&s, &k1, h / 2.0));
        let k3 = f(&add(&s, &k2, h / 2.0));
        let k4 = f(&add(&s, &k3, h));
        for i in 0..4 {
            s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    assert!(spread(&values) < 1e-9, "L_z along the orbit: {values:?}");
}

#[test]
fn cli_conserved_gives_the_boost_of_two_free_particles_with_its_total_derivative_term() {
    let out = cli(&["conserved", "1/2 m1 x1'^2 + 1/2 m2 x2'^2", "--coords", "x1,x2", "--positive", "m1,m2"]);
    let boosts: Vec<&String> = out.iter().filter(|l| l.contains("Galilean boost")).collect();
    assert_eq!(boosts.len(), 2, "{out:#?}");
    let d = decls(&["m1", "m2"]);
    for (b, (x, m)) in boosts.iter().zip([("x1", "m1"), ("x2", "m2")]) {
        assert!(b.contains(&format!("F = {m} {x}")), "the total-derivative term: {b}");
        let q = value_of(b, &d);
        let hand = parse_with(&format!("t {m} {x}' - {m} {x}"), &d).unwrap();
        assert!(equal_up_to_sign(&q, &hand), "{q}");
        // x = a + v t leaves t m v − m (a + v t) = −m a.
        let (a, v) = (0.3, -1.1);
        let vals = along(&q, &[x], &|t| vec![(a + v * t, v)], &[("m1", 2.0), ("m2", 3.0)], &[0.0, 0.7, 2.5]);
        assert!(spread(&vals) < 1e-14, "{vals:?}");
    }
    // The momenta are ignorable momenta, the energy is h: no translation or time translation
    // is listed twice.
    assert!(!out.iter().any(|l| l.contains("(translation") || l.contains("time translation")), "{out:#?}");
    // Degree 2 adds the Schrödinger group's dilation and special conformal map (number
    // coefficients); the rotation mixing x1 and x2 has the mass ratio as a coefficient and is outside the ansatz.
    assert!(out.iter().any(|l| l.contains("dilation")) && out.iter().any(|l| l.contains("conformal")), "{out:#?}");
}

#[test]
fn cli_conserved_finds_nothing_spurious_for_the_double_pendulum() {
    let l = "1/2 (m1 + m2) l^2 θ1'^2 + 1/2 m2 l^2 θ2'^2 + m2 l^2 θ1' θ2' cos(θ1 - θ2) + (m1 + m2) g l cos(θ1) + m2 g l cos(θ2)";
    let out = cli(&["conserved", l, "--coords", "θ1,θ2", "--positive", "m1,m2,l,g"]);
    assert_eq!(out.len(), 1, "only the energy: {out:#?}");
    assert!(out[0].starts_with("h = "), "{}", out[0]);
    assert!(out[0].contains("point symmetries searched: "), "the bound is stated: {}", out[0]);
}

/// Atwood's machine (PHYSICS.md §2, notes §2.4.4): a uniform field. Its boost `ξ = t` needs
/// `F = (m1 + m2) x + ½ (m1 − m2) g t²`, quadratic in t (missed by a linear F).
#[test]
fn atwoods_machine_has_the_boost_of_a_uniform_field() {
    let l = "1/2 (m1 + m2) x'^2 + (m1 - m2) g x";
    let out = cli(&["conserved", l, "--coords", "x", "--positive", "m1,m2,g"]);
    let boost = out.iter().find(|l| l.contains("Galilean boost")).unwrap_or_else(|| panic!("{out:#?}"));
    let d = decls(&["m1", "m2", "g"]);
    let q = value_of(boost, &d);
    let hand = parse_with("(m1 + m2) (t x' - x) - 1/2 (m1 - m2) g t^2", &d).unwrap();
    assert!(equal_up_to_sign(&q, &hand), "{q}");
    // Along the exact motion x = x0 + v0 t + ½ a t², a = (m1 − m2) g/(m1 + m2).
    let (m1, m2, g, x0, v0) = (3.0, 1.0, 9.81, 0.4, -0.2);
    let a = (m1 - m2) * g / (m1 + m2);
    let path = |t: f64| vec![(x0 + v0 * t + 0.5 * a * t * t, v0 + a * t)];
    let vals = along(&q, &["x"], &path, &[("m1", m1), ("m2", m2), ("g", g)], &[0.0, 0.5, 1.7, 4.0]);
    assert!(spread(&vals) < 1e-12, "{vals:?}");
}

/// The degree-2 generators with a change of time, on the free particle: the dilation
/// `τ = 2t, ξ = x` and the special conformal map `τ = t², ξ = t x` (with `F = ½ m x²`), whose
/// charges `x p − 2 t H` and `t x p − t² H − ½ m x²` are constant along `x = a + v t`.
#[test]
fn the_free_particle_has_its_dilation_and_conformal_symmetry() {
    let d = decls(&["m"]);
    let l = parse_with("1/2 m x'^2", &d).unwrap();
    let x = [Symbol::new("x")];
    let h = System::from_lagrangian_expr(l.clone(), &x).unwrap().hamiltonian().unwrap();
    let s = point_symmetries(&l, &x, &h);
    let kinds: Vec<&str> = s.found.iter().map(|f| f.kind.as_str()).collect();
    assert_eq!(s.found.len(), 5, "translation, boost, time translation, dilation, conformal: {kinds:?}");
    assert!(s.found.iter().all(|f| f.check == ZeroCheck::Proven), "{kinds:?}");
    let conformal = s.found.iter().find(|f| f.kind.starts_with("conformal")).expect("conformal");
    let dilation = s.found.iter().find(|f| f.kind.starts_with("dilation")).expect("dilation");
    // Up to a constant factor: compare the ratio with the hand form at one point.
    let ratio_is_constant = |got: &Expr, hand: &str| {
        let hand = parse_with(hand, &d).unwrap();
        let vals: Vec<f64> = [(0.3, 1.2, 0.5), (-0.7, 0.4, 2.0), (1.1, -0.9, -1.3)]
            .iter()
            .map(|&(xv, pv, tv)| {
                let env: lagrangian::eval::Env =
                    [("x", xv), ("p_x", pv), ("t", tv), ("m", 1.7)].iter().map(|(k, v)| (k.to_string(), *v)).collect();
                lagrangian::eval::eval(got, &env).unwrap() / lagrangian::eval::eval(&hand, &env).unwrap()
            })
            .collect();
        spread(&vals) < 1e-12 * vals[0].abs()
    };
    assert!(ratio_is_constant(&conformal.charge, "t x p_x - t^2 p_x^2/(2 m) - 1/2 m x^2"), "{}", conformal.charge);
    assert!(ratio_is_constant(&dilation.charge, "x p_x - t p_x^2/m"), "{}", dilation.charge);
    let (a, v) = (0.8, -0.3);
    for f in [conformal, dilation] {
        let vals = along(&f.charge_velocities, &["x"], &|t| vec![(a + v * t, v)], &[("m", 1.7)], &[0.0, 1.0, 3.0]);
        assert!(spread(&vals) < 1e-13, "{}: {vals:?}", f.kind);
    }
    assert!(s.bound.contains("degree ≤ 2") && s.bound.contains("not excluded"), "{}", s.bound);
}

/// The oscillator has no polynomial symmetry but time translation at degree 2 (its other
/// generators, ξ = cos ωt, are not polynomial).
#[test]
fn the_oscillator_has_only_time_translation() {
    let d = decls(&["m", "k"]);
    let l = parse_with("1/2 m x'^2 - 1/2 k x^2", &d).unwrap();
    let x = [Symbol::new("x")];
    let h = System::from_lagrangian_expr(l.clone(), &x).unwrap().hamiltonian().unwrap();
    let s = point_symmetries(&l, &x, &h);
    let kinds: Vec<&str> = s.found.iter().map(|f| f.kind.as_str()).collect();
    assert_eq!(kinds, ["time translation"]);
    assert_eq!(decide_zero(&s.found[0].charge.minus(&h)), ZeroCheck::Proven, "Q = H: {}", s.found[0].charge);
}

/// Symmetries through declared functions: `U` stands for any function, so the search samples
/// its values at random and keeps what holds for all of them. A central potential
/// `U(√(x² + y² + z²))` gives the three rotations (charges `±(m (y z' − y' z))` …, by hand) and
/// time translation, and nothing else; `U(x)` in the plane keeps only the translation along
/// `y` and time translation (no rotation); `U` of `x − y` keeps the translation along (1, 1).
#[test]
fn declared_functions_of_invariant_combinations_keep_their_symmetries() {
    let d = decls(&["m"]).with_functions(["U"]);
    let search = |text: &str, coords: &[&str]| {
        let l = parse_with(text, &d).unwrap();
        let q: Vec<Symbol> = coords.iter().map(|c| Symbol::new(c)).collect();
        let h = System::from_lagrangian_expr(l.clone(), &q).unwrap().hamiltonian().unwrap();
        point_symmetries(&l, &q, &h)
    };
    let central = search("1/2 m (x'^2 + y'^2 + z'^2) - U(sqrt(x^2 + y^2 + z^2))", &["x", "y", "z"]);
    let mut kinds: Vec<&str> = central.found.iter().map(|f| f.kind.as_str()).collect();
    kinds.sort();
    assert_eq!(kinds.len(), 4, "{kinds:?}");
    assert_eq!(kinds.iter().filter(|k| k.starts_with("rotation")).count(), 3, "{kinds:?}");
    assert!(kinds.contains(&"time translation"), "{kinds:?}");
    assert!(central.found.iter().all(|f| f.check == ZeroCheck::Proven), "{kinds:?}");
    for hand in ["m (y z' - y' z)", "m (z x' - z' x)", "m (x y' - x' y)"] {
        let hand = parse_with(hand, &d).unwrap();
        assert!(
            central.found.iter().any(|f| equal_up_to_sign(&f.charge_velocities, &hand)),
            "{hand} not among {:?}",
            central.found.iter().map(|f| f.charge_velocities.to_string()).collect::<Vec<_>>()
        );
    }
    let wall = search("1/2 m (x'^2 + y'^2) - U(x)", &["x", "y"]);
    let kinds: Vec<&str> = wall.found.iter().map(|f| f.kind.as_str()).collect();
    assert!(!kinds.iter().any(|k| k.starts_with("rotation")), "{kinds:?}");
    let py = parse_with("m y'", &d).unwrap();
    assert!(wall.found.iter().any(|f| equal_up_to_sign(&f.charge_velocities, &py)), "{kinds:?}");
    let pair = search("1/2 m (x'^2 + y'^2) - U(x - y)", &["x", "y"]);
    let total = parse_with("m (x' + y')", &d).unwrap();
    assert!(pair.found.iter().any(|f| equal_up_to_sign(&f.charge_velocities, &total)), "{:?}", pair.found.len());
}
