//! Poisson brackets: the angular-momentum algebra, central-potential and Kepler integrals,
//! `df/dt`, integrals of motion and Poisson's theorem (PHYSICS.md §4.4).

use lagrangian::canonical::{decide_zero, is_integral, poisson, time_derivative, PhaseSpace, ZeroCheck};
use lagrangian::{parse_with, Declarations, Expr};

fn p(s: &str) -> Expr {
    parse_with(s, &Declarations::new().with_functions(["V"]).with_positive(["m", "k"])).expect("test input parses")
}

use crate::support::snapshot as snap;

fn xyz() -> PhaseSpace {
    PhaseSpace::new(["x", "y", "z"]).expect("valid phase space")
}

fn angular() -> [Expr; 3] {
    [p("y p_z - z p_y"), p("z p_x - x p_z"), p("x p_y - y p_x")]
}

#[test]
fn fundamental_brackets_are_kronecker_deltas() {
    // {q_i, p_j} = δ_ij and {q_i, q_j} = {p_i, p_j} = 0 by the definition in PHYSICS.md §4.4.
    let ps = xyz();
    for (i, q) in ps.coords.iter().enumerate() {
        for (j, pm) in ps.momenta.iter().enumerate() {
            let b = poisson(&Expr::sym(q.clone()), &Expr::sym(pm.clone()), &ps);
            assert_eq!(b, Expr::int(i64::from(i == j)), "{{{q}, {pm}}}");
            let qq = poisson(&Expr::sym(q.clone()), &Expr::sym(ps.coords[j].clone()), &ps);
            assert!(qq.is_zero());
        }
    }
    // The sign convention: {p, q} = −1.
    let ps1 = PhaseSpace::new(["q"]).expect("valid");
    assert_eq!(poisson(&p("p_q"), &p("q"), &ps1), Expr::int(-1));
}

#[test]
fn angular_momentum_algebra_is_cyclic() {
    let ps = xyz();
    let [lx, ly, lz] = angular();
    let xy = poisson(&lx, &ly, &ps);
    let yz = poisson(&ly, &lz, &ps);
    let zx = poisson(&lz, &lx, &ps);
    // {L_x, L_y} = L_z and cyclic (PHYSICS.md §4.4), exactly.
    assert_eq!(xy, lz);
    assert_eq!(yz, lx);
    assert_eq!(zx, ly);
    snap("canonical_angular_momentum", format!("{{L_x, L_y}} = {xy}\n{{L_y, L_z}} = {yz}\n{{L_z, L_x}} = {zx}"));
}

#[test]
fn central_potential_conserves_angular_momentum_and_poisson_theorem_holds() {
    let ps = xyz();
    let h = p("(p_x^2 + p_y^2 + p_z^2)/(2 m) + V(sqrt(x^2 + y^2 + z^2))");
    let [lx, ly, lz] = angular();
    let hl = poisson(&h, &lz, &ps);
    assert!(hl.is_zero(), "{{H, L_z}} = {hl}");
    snap("canonical_central_potential", format!("{{H, L_z}} = {hl}\nH = {h}"));
    for l in [&lx, &ly, &lz] {
        assert_eq!(is_integral(l, &h, &ps), ZeroCheck::Proven);
    }
    // Poisson's theorem: the bracket of two integrals is an integral.
    let b = poisson(&lx, &ly, &ps);
    assert_eq!(is_integral(&b, &h, &ps), ZeroCheck::Proven);
    // And a non-integral is reported with a point where df/dt ≠ 0.
    assert!(matches!(is_integral(&p("x"), &h, &ps), ZeroCheck::NonZero { .. }));
}

#[test]
fn runge_lenz_vector_commutes_with_the_kepler_hamiltonian() {
    let ps = xyz();
    let h = p("(p_x^2 + p_y^2 + p_z^2)/(2 m) - k/sqrt(x^2 + y^2 + z^2)");
    let [lx, ly, lz] = angular();
    let r = p("sqrt(x^2 + y^2 + z^2)");
    let (px, py, pz) = (p("p_x"), p("p_y"), p("p_z"));
    let mk = p("m k");
    // A = p × L − m k r̂.
    let ax = py.times(&lz).minus(&pz.times(&ly)).minus(&mk.times(&p("x")).over(&r));
    let ay = pz.times(&lx).minus(&px.times(&lz)).minus(&mk.times(&p("y")).over(&r));
    let az = px.times(&ly).minus(&py.times(&lx)).minus(&mk.times(&p("z")).over(&r));
    let mut lines = Vec::new();
    for (name, a) in [("A_x", &ax), ("A_y", &ay), ("A_z", &az)] {
        let b = poisson(a, &h, &ps);
        assert!(b.is_zero(), "{{{name}, H}} = {b}");
        assert_eq!(is_integral(a, &h, &ps), ZeroCheck::Proven);
        lines.push(format!("{{{name}, H}} = {b}"));
    }
    lines.push(format!("A_x = {ax}"));
    snap("canonical_runge_lenz", lines.join("\n"));
}

#[test]
fn time_derivative_includes_the_explicit_time_dependence() {
    // Galilean boost x − p_x t/m of a free particle: {f, H} = p_x/m, ∂f/∂t = −p_x/m.
    let ps = PhaseSpace::new(["x"]).expect("valid");
    let h = p("p_x^2/(2 m)");
    let f = p("x - p_x t/m");
    assert!(time_derivative(&f, &h, &ps).is_zero());
    assert_eq!(is_integral(&f, &h, &ps), ZeroCheck::Proven);
    // Without the explicit term it is not conserved: df/dt = p_x/m.
    assert_eq!(time_derivative(&p("x"), &h, &ps), p("p_x/m"));
}

#[test]
fn an_undecidable_zero_is_reported_as_numeric_evidence_only() {
    // A rational-function identity is proven over a common denominator …
    assert_eq!(decide_zero(&p("1/(1 + x) + 1/(1 - x) - 2/(1 - x^2)")), ZeroCheck::Proven);
    // … but a logarithm identity (true for the positive sample values) is beyond the normal form.
    let e = p("log(x y) - log(x) - log(y)");
    match decide_zero(&e) {
        ZeroCheck::Numeric { points, max_residual } => {
            assert!(points >= 10 && max_residual < 1e-12);
        }
        other => panic!("expected a numeric-only verdict, got {other:?}"),
    }
    assert!(decide_zero(&e).describe().contains("not a proof"));
}
