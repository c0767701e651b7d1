//! A system that carries velocity (nonholonomic) constraints never yields the unconstrained
//! system's result: each public derivation either includes the constraints (the
//! Lagrange–d'Alembert equations with multipliers μ, the accelerations with μ eliminated, the
//! compiled augmented system, a point transformation) or is refused with
//! `MechanicsError::DropsVelocityConstraints` naming what keeps them. Expected numbers are the
//! rolling coin's from SymPy's KanesMethod (scripts/nonholonomic_sympy.py, the same point as
//! `mechanics::nonholonomic`).

use lagrangian::compile::{CompileError, Stabilization, Variational};
use lagrangian::eval::eval_with;
use lagrangian::expr::{Expr, Symbol};
use lagrangian::integrate::Rhs;
use lagrangian::mechanics::{MechanicsError, Rule, System};
use lagrangian::print::Format;
use lagrangian::report;

const L: &str = "1/2 m (x'^2 + y'^2) + 1/2 I θ'^2 + 1/2 J φ'^2 - 1/2 k x^2";
const ROLL: [&str; 2] = ["x' = R φ' cos(θ)", "y' = R φ' sin(θ)"];

/// KanesMethod's accelerations (x'', y'', θ'', φ'') and the multipliers at the state of [`value`].
const KANE: [f64; 4] = [0.280_264_014_793_85, -0.354_662_355_278_941_9, 0.0, -0.207_203_322_756_888_1];
const MULTIPLIERS: [f64; 2] = [1.760_528_029_587_700_2, -0.709_324_710_557_883_9];
const PARAMS: [(&str, f64); 5] = [("m", 2.0), ("I", 0.7), ("J", 1.3), ("R", 0.5), ("k", 3.0)];

fn value(s: &Symbol) -> Option<f64> {
    let (r, ph, th) = (0.5f64, -1.1f64, 0.9f64);
    Some(match (s.name(), s.primes()) {
        ("x", 0) => 0.4,
        ("y", 0) => -0.3,
        ("θ", 0) => th,
        ("φ", 0) => 0.2,
        ("θ", 1) => 0.8,
        ("φ", 1) => ph,
        ("x", 1) => r * ph * th.cos(),
        ("y", 1) => r * ph * th.sin(),
        (name, 0) => PARAMS.iter().find(|(p, _)| *p == name)?.1,
        _ => return None,
    })
}

/// The state `(x, y, θ, φ, x', y', θ', φ')` of [`value`].
fn state() -> Vec<f64> {
    let names = ["x", "y", "θ", "φ"];
    let q = names.iter().map(|n| value(&Symbol::new(n)).unwrap());
    let v = names.iter().map(|n| value(&Symbol::new(n).with_primes(1)).unwrap());
    q.chain(v).collect()
}

fn coin() -> System {
    let mut s = System::from_lagrangian(L, &["x", "y", "θ", "φ"]).unwrap();
    for g in ROLL {
        s = s.with_velocity_constraint(g).unwrap();
    }
    s
}

fn refused<T: std::fmt::Debug>(what: &str, r: Result<T, MechanicsError>) {
    match r {
        Err(e @ MechanicsError::DropsVelocityConstraints { .. }) => {
            let text = e.to_string();
            assert!(text.contains("lagrange_dalembert") && text.contains("simulation"), "{what}: {text}");
            assert!(text.contains("nonholonomic") && text.contains("= 0"), "{what}: {text}");
        }
        other => panic!("{what}: expected the velocity-constraint refusal, got {other:?}"),
    }
}

#[test]
fn equations_carry_the_multipliers_and_vanish_on_kanes_solution() {
    let s = coin();
    let eqs = s.equations().unwrap();
    assert_eq!(eqs, s.lagrange_dalembert(&[]).unwrap().equations);
    let mu: Vec<Symbol> = ["μ1", "μ2"].iter().map(|m| Symbol::new(m)).collect();
    assert!(eqs[0].free_symbols().contains(&mu[0]) && eqs[3].free_symbols().contains(&mu[1]), "{eqs:?}");
    let solved = |sym: &Symbol| match (sym.name(), sym.primes()) {
        ("x", 2) => Some(KANE[0]),
        ("y", 2) => Some(KANE[1]),
        ("θ", 2) => Some(KANE[2]),
        ("φ", 2) => Some(KANE[3]),
        ("μ1", 0) => Some(MULTIPLIERS[0]),
        ("μ2", 0) => Some(MULTIPLIERS[1]),
        _ => value(sym),
    };
    for e in &eqs {
        let r = eval_with(e, &solved).unwrap();
        assert!(r.abs() < 1e-12, "{e} = {r}");
    }
    // The system's own constraints and extra ones given to lagrange_dalembert are numbered on.
    let one = System::from_lagrangian(L, &["x", "y", "θ", "φ"]).unwrap().with_velocity_constraint(ROLL[0]).unwrap();
    let extra = one.lagrange_dalembert(&[lagrangian::parse("y' - R φ' sin(θ)").unwrap()]).unwrap();
    assert_eq!(extra.multipliers, mu);
    for (a, b) in extra.equations.iter().zip(&eqs) {
        assert!((eval_with(a, &solved).unwrap() - eval_with(b, &solved).unwrap()).abs() < 1e-12);
    }
}

/// The skate (a knife edge, Chaplygin) on a spring: `L = ½ m (x'² + y'²) + ½ I θ'² − ½ k x²`
/// with `y' cos θ − x' sin θ = 0`. By hand: `m x'' = −k x − μ sin θ`, `m y'' = μ cos θ`,
/// `I θ'' = 0`, and the constraint differentiated, `−x'' sin θ + y'' cos θ = θ' v` with
/// `v = x' cos θ + y' sin θ`, gives `μ = m θ' v − k x sin θ`.
#[test]
fn accelerations_eliminate_the_multipliers() {
    let s = System::from_lagrangian("1/2 m (x'^2 + y'^2) + 1/2 I θ'^2 - 1/2 k x^2", &["x", "y", "θ"])
        .unwrap()
        .with_velocity_constraint("y' cos(θ) = x' sin(θ)")
        .unwrap();
    let (m, i, k, x, th, thd, v) = (2.0f64, 0.7f64, 3.0f64, 0.4f64, 0.9f64, 0.8f64, -0.6f64);
    let at = |sym: &Symbol| {
        Some(match (sym.name(), sym.primes()) {
            ("m", 0) => m,
            ("I", 0) => i,
            ("k", 0) => k,
            ("x", 0) => x,
            ("y", 0) => -0.3,
            ("θ", 0) => th,
            ("θ", 1) => thd,
            ("x", 1) => v * th.cos(),
            ("y", 1) => v * th.sin(),
            _ => return None,
        })
    };
    let mu = m * thd * v - k * x * th.sin();
    let want = [(-k * x - mu * th.sin()) / m, mu * th.cos() / m, 0.0];
    let acc = s.accelerations().unwrap();
    for (a, w) in acc.iter().zip(want) {
        let got = eval_with(a, &at).unwrap();
        assert!((got - w).abs() < 1e-12, "{a} = {got}, by hand {w}");
    }
    let lines = report::accelerations(&s).unwrap();
    let printed = report::render_lines(&lines, Format::Plain);
    assert_eq!(lines.len(), 4, "{printed:?}");
    assert!(printed[3].starts_with("μ1 = "), "{printed:?}");
    let got = eval_with(lines[3].rhs().unwrap(), &at).unwrap();
    assert!((got - mu).abs() < 1e-12, "{printed:?}: μ1 = {got}, by hand {mu}");
    // The coin's six unknowns exceed the closed form: refused, never W⁻¹ F.
    assert!(matches!(coin().accelerations(), Err(MechanicsError::TooLarge { n: 6, .. })));
}

#[test]
fn el_and_constraints_reports_include_the_velocity_constraints() {
    let s = coin();
    let el = report::render_lines(&report::euler_lagrange(&s).unwrap(), Format::Plain);
    assert_eq!(el[0], "E_x: k x + m x'' = μ1");
    assert_eq!(el[3], "E_φ: J φ'' = -R (μ1 cos(θ) + μ2 sin(θ))");
    let c = report::render_lines(&report::constraints(&s).unwrap(), Format::Plain);
    assert!(c.contains(&"Φ[1,φ] = -R cos(θ)".to_string()) && c.contains(&"c_2 = R θ' φ' cos(θ)".to_string()), "{c:?}");
}

#[test]
fn conserved_report_names_the_velocity_constraint_that_breaks_a_momentum() {
    let s = coin();
    let lines = report::render_lines(&report::conserved(&s), Format::Plain);
    let py = lines.iter().find(|l| l.starts_with("p_y = ")).unwrap_or_else(|| panic!("{lines:?}"));
    assert!(py.contains("not conserved: dp_y/dt = μ2") && py.contains("velocity constraint 2 (multiplier μ2)"), "{py}");
    // θ is ignorable and no constraint force acts on it: p_θ = I θ' stays.
    assert!(lines.iter().any(|l| l.starts_with("p_θ = I θ'")), "{lines:?}");
}

#[test]
fn hamiltonian_derivations_are_refused() {
    let s = coin();
    refused("hamiltonian", s.hamiltonian());
    refused("legendre", s.legendre());
    refused("hamilton_equations", s.hamilton_equations());
    refused("phase_space_lagrangian", s.phase_space_lagrangian());
    refused("report::legendre", report::legendre(&s));
    refused("report::hamilton", report::hamilton(&s));
    refused("discretize", s.discretize(Rule::Midpoint, &Expr::var("h")));
    let first = System::from_lagrangian("p x' - p^2/2 - x^2/2 + y' x", &["x", "p", "y"])
        .unwrap()
        .with_velocity_constraint("y' = x'")
        .unwrap();
    refused("first_order", first.first_order());
}

#[test]
fn compiled_systems_keep_or_refuse_the_velocity_constraints() {
    let s = coin().with_params(&PARAMS).unwrap();
    let mech = |what: &str, r: Result<(), CompileError>| match r {
        Err(CompileError::Mechanics(e)) => refused(what, Err::<(), _>(e)),
        other => panic!("{what}: {other:?}"),
    };
    mech("compile_hamiltonian", s.compile_hamiltonian().map(|_| ()));
    mech("compile_separable", s.compile_separable().map(|_| ()));
    mech("compile_implicit_legendre", s.compile_implicit_legendre().map(|_| ()));
    mech("compile_taylor", s.compile_taylor().map(|_| ()));
    mech("compile_first_order", s.compile_first_order().map(|_| ()));
    mech("Variational::of_system", Variational::of_system(&s, 1, true).map(|_| ()));
    match s.compile_rhs() {
        Err(CompileError::Unsupported { what }) => assert!(what.contains("compile_constrained"), "{what}"),
        other => panic!("compile_rhs: {:?}", other.map(|_| ())),
    }
    let rhs = s.compile_constrained(Stabilization::None).unwrap();
    let y = state();
    let mut dy = vec![0.0; 8];
    rhs.eval(0.0, &y, &mut dy);
    for i in 0..4 {
        assert!((dy[4 + i] - KANE[i]).abs() < 1e-12, "q''[{i}] = {}, KanesMethod {}", dy[4 + i], KANE[i]);
    }
}

#[test]
fn a_point_transformation_carries_the_velocity_constraints() {
    // The coin's centre in polar coordinates: x = r cos(α), y = r sin(α).
    let s = coin();
    let t = s.transform(&[("x", "r cos(α)"), ("y", "r sin(α)")], &["r", "α", "θ", "φ"]).unwrap();
    assert_eq!(t.velocity_constraints().len(), 2);
    // At a point, each new constraint equals the old one with x, y, x', y' from r, α, r', α'.
    let (r, al, rd, ald) = (1.3f64, 0.4f64, -0.2f64, 0.7f64);
    let polar = |sym: &Symbol| match (sym.name(), sym.primes()) {
        ("r", 0) => Some(r),
        ("α", 0) => Some(al),
        ("r", 1) => Some(rd),
        ("α", 1) => Some(ald),
        _ => value(sym),
    };
    let cartesian = |sym: &Symbol| match (sym.name(), sym.primes()) {
        ("x", 0) => Some(r * al.cos()),
        ("y", 0) => Some(r * al.sin()),
        ("x", 1) => Some(rd * al.cos() - r * ald * al.sin()),
        ("y", 1) => Some(rd * al.sin() + r * ald * al.cos()),
        _ => value(sym),
    };
    for (new, old) in t.velocity_constraints().iter().zip(s.velocity_constraints()) {
        let (a, b) = (eval_with(new, &polar).unwrap(), eval_with(old, &cartesian).unwrap());
        assert!((a - b).abs() < 1e-12 && b.abs() > 1e-3, "{new}: {a} against {old}: {b}");
    }
}

/// The command line's `--velocity-constraint` is on the system for every command: `hamilton`
/// and `legendre` refuse it, and `conserved` no longer lists the momenta it breaks (they were
/// printed as conserved for the unconstrained system).
#[test]
fn the_command_line_keeps_or_refuses_velocity_constraints_on_every_command() {
    let base = ["--coords", "x,y", "--velocity-constraint", "x' = y"];
    for cmd in [&["hamilton", "1/2 x'^2 + 1/2 y'^2", "--lagrangian"][..], &["legendre", "1/2 x'^2 + 1/2 y'^2"][..]] {
        let args: Vec<&str> = cmd.iter().chain(&base).copied().collect();
        let (code, out, err) = crate::support::run(&args);
        assert_eq!((code, out.as_str()), (2, ""), "{args:?}: {err}");
        assert!(err.contains("nonholonomic") && err.contains("lagrange_dalembert"), "{args:?}: {err}");
    }
    let args: Vec<&str> = ["conserved", "1/2 x'^2 + 1/2 y'^2"].iter().chain(&base).copied().collect();
    let (code, out, err) = crate::support::run(&args);
    assert_eq!(code, 0, "{err}");
    // Its force μ1 acts on x alone, and b = −y does work: p_y stays, p_x and h do not.
    assert!(out.lines().any(|l| l.starts_with("p_y = y'   (y is ignorable")), "{out}");
    assert!(out.lines().any(|l| l.starts_with("p_x = x'   (not conserved: dp_x/dt = μ1")), "{out}");
    assert!(!out.lines().any(|l| l.starts_with("h = ") && !l.contains("not conserved")), "{out}");
}
