//! Noether beyond ignorable coordinates. The point
//! symmetry search finds L_z for Kepler in Cartesian coordinates and the centre-of-mass boost
//! of two bodies, and nothing spurious for the double pendulum (only time translation); every charge is checked by its
//! Poisson bracket with H (and, independently here, against the textbook integral).

use lagrangian::canonical::symmetry::{point_symmetries, PointSymmetry};
use lagrangian::canonical::{decide_zero, ZeroCheck};
use lagrangian::scene::{Mode, Options, Session};
use lagrangian::{parse_with, Declarations, Expr, Symbol};

fn decls() -> Declarations {
    Declarations::new().with_positive(["m", "m1", "m2", "k", "g", "l"])
}

fn p(s: &str) -> Expr {
    parse_with(s, &decls()).expect("test input parses")
}

fn syms(names: &[&str]) -> Vec<Symbol> {
    names.iter().map(|n| Symbol::new(n)).collect()
}

/// The symmetries found other than time translation (whose charge, the energy, every
/// autonomous system has).
fn beyond_time_translation(found: &[PointSymmetry]) -> Vec<&PointSymmetry> {
    found.iter().filter(|f| f.kind != "time translation").collect()
}

/// `a = ±b`, proven.
fn equal_up_to_sign(a: &Expr, b: &Expr) -> bool {
    decide_zero(&a.minus(b)) == ZeroCheck::Proven || decide_zero(&a.plus(b)) == ZeroCheck::Proven
}

#[test]
fn kepler_in_cartesian_coordinates_has_lz() {
    let l = p("1/2 m (x'^2 + y'^2) + k/sqrt(x^2 + y^2)");
    let h = p("(p_x^2 + p_y^2)/(2 m) - k/sqrt(x^2 + y^2)");
    let s = point_symmetries(&l, &syms(&["x", "y"]), &h);
    let found = beyond_time_translation(&s.found);
    assert_eq!(found.len(), 1, "{:#?}", s.found);
    let rot = found[0];
    assert!(rot.kind.starts_with("rotation in (x, y)"), "{}", rot.kind);
    assert_eq!(rot.check, ZeroCheck::Proven, "{{Q, H}} = 0 proven");
    assert!(equal_up_to_sign(&rot.charge, &p("x p_y - y p_x")), "Q = {}", rot.charge);
    assert!(s.bound.contains("degree ≤ 2"), "the bound is stated: {}", s.bound);
}

#[test]
fn two_bodies_have_total_momentum_and_the_centre_of_mass_boost() {
    let l = p("1/2 m1 x1'^2 + 1/2 m2 x2'^2 - 1/2 k (x1 - x2)^2");
    let h = p("p_x1^2/(2 m1) + p_x2^2/(2 m2) + 1/2 k (x1 - x2)^2");
    let s = point_symmetries(&l, &syms(&["x1", "x2"]), &h);
    assert_eq!(beyond_time_translation(&s.found).len(), 2, "{:#?}", s.found);
    for f in &s.found {
        assert_eq!(f.check, ZeroCheck::Proven, "{}: {{Q, H}} + ∂Q/∂t = 0 proven", f.charge);
    }
    let translation = s.found.iter().find(|f| f.kind == "translation").expect("a translation");
    assert!(equal_up_to_sign(&translation.charge, &p("p_x1 + p_x2")), "{}", translation.charge);
    let boost = s.found.iter().find(|f| f.kind.starts_with("Galilean boost")).expect("a boost");
    // The centre-of-mass integral t P − M X_cm, with F = m1 x1 + m2 x2.
    assert!(equal_up_to_sign(&boost.charge, &p("t (p_x1 + p_x2) - m1 x1 - m2 x2")), "{}", boost.charge);
    assert!(equal_up_to_sign(&boost.gauge, &p("m1 x1 + m2 x2")), "F = {}", boost.gauge);
}

#[test]
fn the_double_pendulum_has_no_point_symmetry() {
    let l = p("1/2 (m1 + m2) l^2 θ1'^2 + 1/2 m2 l^2 θ2'^2 + m2 l^2 θ1' θ2' cos(θ1 - θ2) + (m1 + m2) g l cos(θ1) + m2 g l cos(θ2)");
    let sys = lagrangian::mechanics::System::from_lagrangian_expr(l.clone(), &syms(&["θ1", "θ2"])).expect("system");
    let h = sys.hamiltonian().expect("Legendre");
    let s = point_symmetries(&l, &syms(&["θ1", "θ2"]), &h);
    let spurious = beyond_time_translation(&s.found);
    assert!(spurious.is_empty(), "spurious: {:#?}", spurious.iter().map(|f| f.charge.to_string()).collect::<Vec<_>>());
    // Time translation is found, and its charge is H itself.
    assert_eq!(s.found.len(), 1);
    assert_eq!(decide_zero(&s.found[0].charge.minus(&h)), ZeroCheck::Proven, "{}", s.found[0].charge);
}

#[test]
fn scene_conserved_reports_lz_for_cartesian_kepler() {
    let mut session = Session::new(Options::new(Mode::Scene));
    session
        .run_scene(
            "kepler",
            "coordinates x, y\nparameters k positive\nH = (p_x^2 + p_y^2)/2 - k/sqrt(x^2 + y^2)\nconserved as plain",
        )
        .unwrap_or_else(|e| panic!("{e:?}"));
    let out = session.take_output();
    let q = out.iter().find(|l| l.starts_with("Q1 = ")).unwrap_or_else(|| panic!("no symmetry in {out:?}"));
    assert!(q.contains("rotation in (x, y)") && q.contains("proven"), "{q}");
    let value = q.strip_prefix("Q1 = ").and_then(|r| r.split("   ").next()).expect("Q1 = value");
    let d = Declarations::new().with_positive(["k"]);
    let got = parse_with(value, &d).expect("re-parses");
    assert!(equal_up_to_sign(&got, &parse_with("x p_y - y p_x", &d).expect("parses")), "{value}");
}

/// The ring: a particle on x² + y² = l² in Cartesian coordinates. The constraint acts
/// on x and y, so neither momentum is conserved (each is listed as broken by the constraint,
/// d/dt p = λ1 ∂f/∂q = 2 x λ1, 2 y λ1) and no boost survives; the rotation preserves the
/// constraint, so L_z is found.
#[test]
fn a_particle_on_a_ring_keeps_only_lz_and_the_energy() {
    let mut session = Session::new(Options::new(Mode::Scene));
    session
        .run_scene(
            "ring",
            "coordinates x, y\nparameters m = 1, l = 1 positive\nL = 1/2 m (x'^2 + y'^2)\n\
             constraint x^2 + y^2 = l^2\nconserved as plain",
        )
        .unwrap_or_else(|e| panic!("{e:?}"));
    let out: Vec<String> = session.take_output().into_iter().filter(|l| !l.starts_with("constraint ")).collect();
    // The momenta are listed as broken by the constraint (dp_x/dt = 2 x λ1), not as conserved.
    let conserved_momentum =
        |l: &String| (l.starts_with("p_x") || l.starts_with("p_y")) && !l.contains("not conserved");
    assert!(!out.iter().any(|l| conserved_momentum(l) || l.contains("boost")), "{out:?}");
    let broken: Vec<&String> = out.iter().filter(|l| l.contains("not conserved")).collect();
    assert_eq!(broken.len(), 2, "{out:?}");
    assert!(broken.iter().all(|l| l.contains("broken by constraint 1 (multiplier λ1)")), "{broken:?}");
    assert!(broken[0].contains("dp_x/dt = 2 x λ1") && broken[1].contains("dp_y/dt = 2 y λ1"), "{broken:?}");
    assert!(out.iter().any(|l| l.starts_with("h = ")), "{out:?}");
    let q: Vec<&String> = out.iter().filter(|l| l.starts_with('Q')).collect();
    assert_eq!(q.len(), 1, "{out:?}");
    assert!(q[0].contains("rotation in (x, y)"), "{}", q[0]);
    let d = Declarations::new().with_positive(["m", "l"]);
    let value = q[0].strip_prefix("Q1 = ").and_then(|r| r.split("   ").next()).expect("Q1 = value");
    let got = parse_with(value, &d).expect("re-parses");
    assert!(equal_up_to_sign(&got, &parse_with("m (x y' - y x')", &d).expect("parses")), "{value}");
}

/// Two free particles: each boost is found on its own, and the centre-of-mass boost integral
/// t (p1 + p2) − (m1 x1 + m2 x2) is their sum.
#[test]
fn two_free_particles_give_the_centre_of_mass_boost() {
    let l = p("1/2 m1 x1'^2 + 1/2 m2 x2'^2");
    let h = p("p_x1^2/(2 m1) + p_x2^2/(2 m2)");
    let s = point_symmetries(&l, &syms(&["x1", "x2"]), &h);
    let boosts: Vec<&Expr> =
        s.found.iter().filter(|f| f.kind.starts_with("Galilean boost")).map(|f| &f.charge).collect();
    assert_eq!(boosts.len(), 2, "{:#?}", s.found);
    let cm = p("t (p_x1 + p_x2) - m1 x1 - m2 x2");
    let combos = [boosts[0].plus(boosts[1]), boosts[0].minus(boosts[1])];
    assert!(combos.iter().any(|c| equal_up_to_sign(c, &cm)), "{} and {}", boosts[0], boosts[1]);
    assert!(s.found.iter().all(|f| f.check == ZeroCheck::Proven));
}
