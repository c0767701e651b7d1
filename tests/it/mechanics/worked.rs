//! Every worked system of PHYSICS.md §2–3 (and the double and spherical pendulums, Kepler in
//! spherical coordinates, three-body gravity): equations, W, F, H and conserved quantities are
//! snapshotted (`snapshots/mechanics_*.snap`) AND checked numerically at random states against
//! the hand forms written below, each from the equation of the notes named in its comment.
//! `W` and `F` are checked against the hand Euler–Lagrange expression: `W_ij = ∂E_i/∂q''_j` and
//! `F_i = −E_i` at `q'' = 0`.

use crate::support::mechanics as mechanics_support;

use std::collections::{BTreeSet, HashMap};

use lagrangian::diff::diff;
use lagrangian::expr::{Expr, Symbol};
use mechanics_support::{assert_same, expr, report, snapshot, system};

struct Case<'a> {
    snap: &'a str,
    title: &'a str,
    l: &'a str,
    coords: &'a [&'a str],
    positive: &'a [&'a str],
    functions: &'a [&'a str],
    /// Hand Euler–Lagrange expressions `E_i`, one per coordinate.
    el: &'a [&'a str],
    /// Hand Hamiltonian.
    h: Option<&'a str>,
    /// Exactly the conserved quantities expected, by name, with hand forms.
    conserved: &'a [(&'a str, &'a str)],
    /// Fixed values for some symbols at the random states (e.g. `c` for the relativistic case).
    overrides: &'a [(&'a str, f64)],
}

fn check(c: &Case) {
    let s = system(c.l, c.coords, c.positive, c.functions);
    let p = |t: &str| expr(t, c.positive, c.functions);
    let el = s.euler_lagrange().expect("EL");
    let (w, f) = s.mass_matrix_split().expect("W, F");
    let acc: Vec<Symbol> = s.accelerations_symbols();
    let zero_acc: HashMap<Symbol, Expr> = acc.iter().map(|a| (a.clone(), Expr::zero())).collect();
    for (i, hand) in c.el.iter().enumerate() {
        let hand = p(hand);
        assert_same(&el[i], &hand, &format!("{}: E_{}", c.title, c.coords[i]), c.overrides);
        for (j, a) in acc.iter().enumerate() {
            let hand_w = diff(&hand, a);
            assert_same(&w[i][j], &hand_w, &format!("{}: W[{i},{j}]", c.title), c.overrides);
        }
        let hand_f = hand.subs(&zero_acc).neg();
        assert_same(&f[i], &hand_f, &format!("{}: F_{}", c.title, c.coords[i]), c.overrides);
    }
    if let Some(h) = c.h {
        let got = s.hamiltonian().expect("H");
        assert_same(&got, &p(h), &format!("{}: H", c.title), c.overrides);
    }
    let found = s.conserved();
    let names: BTreeSet<&str> = found.iter().map(|k| k.name.as_str()).collect();
    let expected: BTreeSet<&str> = c.conserved.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, expected, "{}: conserved quantities", c.title);
    for (name, hand) in c.conserved {
        let k = found.iter().find(|k| k.name == *name).expect("listed");
        assert_same(&k.expr, &p(hand), &format!("{}: conserved {name}", c.title), c.overrides);
    }
    snapshot(c.snap, report(c.title, &s));
}

#[test]
fn physical_pendulum() {
    // (2.27) L, (2.28) m l² θ'' = −m g l sin θ, (3.20) H, (2.7) energy.
    check(&Case {
        snap: "mechanics_pendulum",
        title: "physical pendulum (2.27), (2.28), (3.20)",
        l: "1/2 m l^2 θ'^2 - m g l (1 - cos(θ))",
        coords: &["θ"],
        positive: &["m", "l", "g"],
        functions: &[],
        el: &["m l^2 θ'' + m g l sin(θ)"],
        h: Some("p_θ^2/(2 m l^2) + m g l (1 - cos(θ))"),
        conserved: &[("h", "1/2 m l^2 θ'^2 + m g l (1 - cos(θ))")],
        overrides: &[],
    });
}

#[test]
fn small_angle_pendulum() {
    // (2.29): θ'' + ω0² θ = 0 with ω0² = g/l, i.e. E = m l² (θ'' + (g/l) θ).
    check(&Case {
        snap: "mechanics_small_angle_pendulum",
        title: "small-angle pendulum (2.29)",
        l: "1/2 m l^2 θ'^2 - 1/2 m g l θ^2",
        coords: &["θ"],
        positive: &["m", "l", "g"],
        functions: &[],
        el: &["m l^2 (θ'' + g/l θ)"],
        h: Some("p_θ^2/(2 m l^2) + 1/2 m g l θ^2"),
        conserved: &[("h", "1/2 m l^2 θ'^2 + 1/2 m g l θ^2")],
        overrides: &[],
    });
    let s = system("1/2 m l^2 θ'^2 - 1/2 m g l θ^2", &["θ"], &["m", "l", "g"], &[]);
    let acc = s.accelerations().expect("diagonal W");
    assert_same(&acc[0], &expr("-(g/l) θ", &["g", "l"], &[]), "θ'' = −ω0² θ", &[]);
}

#[test]
fn central_potential_polar() {
    // (2.33) L, (2.37) m r'' − m r φ'² = −V'(r), (2.35) m r² φ' conserved, (3.29) H.
    check(&Case {
        snap: "mechanics_central_potential",
        title: "central potential in polar coordinates (2.33), (2.35), (2.37), (3.29)",
        l: "1/2 m (r'^2 + r^2 φ'^2) - V(r)",
        coords: &["r", "φ"],
        positive: &["m"],
        functions: &["V"],
        el: &["m r'' - m r φ'^2 + V'(r)", "m r^2 φ'' + 2 m r r' φ'"],
        h: Some("p_r^2/(2 m) + p_φ^2/(2 m r^2) + V(r)"),
        conserved: &[("p_φ", "m r^2 φ'"), ("h", "1/2 m (r'^2 + r^2 φ'^2) + V(r)")],
        overrides: &[],
    });
}

#[test]
fn thread_through_a_hole() {
    // (2.38) L with r = a − u t, (2.39) m (a − u t)² φ' conserved; L depends on t, so no energy.
    check(&Case {
        snap: "mechanics_thread_through_hole",
        title: "thread pulled through a hole (2.38), (2.39)",
        l: "1/2 m (u^2 + (a - u t)^2 φ'^2)",
        coords: &["φ"],
        positive: &["m"],
        functions: &[],
        el: &["m (a - u t)^2 φ'' - 2 m u (a - u t) φ'"],
        h: Some("p_φ^2/(2 m (a - u t)^2) - 1/2 m u^2"),
        conserved: &[("p_φ", "m (a - u t)^2 φ'")],
        overrides: &[],
    });
}

#[test]
fn atwood_machine() {
    // (2.40) L, (2.41) x'' = −(m1 − m2) g/(m1 + m2).
    check(&Case {
        snap: "mechanics_atwood",
        title: "Atwood's machine (2.40), (2.41)",
        l: "1/2 (m1 + m2) x'^2 - (m1 - m2) g x",
        coords: &["x"],
        positive: &["m1", "m2", "g"],
        functions: &[],
        el: &["(m1 + m2) x'' + (m1 - m2) g"],
        h: Some("p_x^2/(2 (m1 + m2)) + (m1 - m2) g x"),
        conserved: &[("h", "1/2 (m1 + m2) x'^2 + (m1 - m2) g x")],
        overrides: &[],
    });
    let s = system("1/2 (m1 + m2) x'^2 - (m1 - m2) g x", &["x"], &["m1", "m2", "g"], &[]);
    let acc = s.accelerations().expect("diagonal W");
    assert_same(&acc[0], &expr("-(m1 - m2) g/(m1 + m2)", &["m1", "m2", "g"], &[]), "(2.41)", &[]);
}

#[test]
fn charged_particle() {
    // (2.44) with A = B/2 (−y, x, 0) (uniform B along z) and a scalar potential φ(r, t):
    // Lorentz force (2.47) m r'' = e (−∇φ + r' × B), B × components: r' × B = (B y', −B x', 0).
    // (3.22) H = |p − e A|²/2m + e φ. φ depends on every coordinate and on t: nothing conserved.
    check(&Case {
        snap: "mechanics_charged_particle",
        title: "charged particle in A = B/2 (−y, x, 0) and φ(r, t) (2.44), (2.47), (3.22)",
        l: "1/2 m (x'^2 + y'^2 + z'^2) - e φ(x, y, z, t) + e B/2 (-y x' + x y')",
        coords: &["x", "y", "z"],
        positive: &["m"],
        functions: &["φ"],
        el: &["m x'' + e ∂₁φ(x, y, z, t) - e B y'", "m y'' + e ∂₂φ(x, y, z, t) + e B x'", "m z'' + e ∂₃φ(x, y, z, t)"],
        h: Some("((p_x + e B y/2)^2 + (p_y - e B x/2)^2 + p_z^2)/(2 m) + e φ(x, y, z, t)"),
        conserved: &[],
        overrides: &[],
    });
}

#[test]
fn fluid_element() {
    // (2.52) L = ½|r'|² − h(r, t) − V(r, t): r'' = −∇h − ∇V.
    check(&Case {
        snap: "mechanics_fluid_element",
        title: "fluid element (2.51), (2.52)",
        l: "1/2 (x'^2 + y'^2 + z'^2) - h(x, y, z, t) - V(x, y, z, t)",
        coords: &["x", "y", "z"],
        positive: &[],
        functions: &["h", "V"],
        el: &[
            "x'' + ∂₁h(x, y, z, t) + ∂₁V(x, y, z, t)",
            "y'' + ∂₂h(x, y, z, t) + ∂₂V(x, y, z, t)",
            "z'' + ∂₃h(x, y, z, t) + ∂₃V(x, y, z, t)",
        ],
        h: Some("(p_x^2 + p_y^2 + p_z^2)/2 + h(x, y, z, t) + V(x, y, z, t)"),
        conserved: &[],
        overrides: &[],
    });
}

#[test]
fn harmonic_oscillator() {
    // (2.61) L, m x'' + m ω0² x = 0, (3.16) H.
    check(&Case {
        snap: "mechanics_harmonic_oscillator",
        title: "harmonic oscillator (2.61), (3.16)",
        l: "1/2 m (x'^2 - ω0^2 x^2)",
        coords: &["x"],
        positive: &["m"],
        functions: &[],
        el: &["m x'' + m ω0^2 x"],
        h: Some("p_x^2/(2 m) + m ω0^2 x^2/2"),
        conserved: &[("h", "1/2 m (x'^2 + ω0^2 x^2)")],
        overrides: &[],
    });
}

#[test]
fn gauge_transformed_oscillator() {
    // (2.75) L = (2.61) + d/dt(½ m ω0 x²): same equation; (3.18) p = m (x' + ω0 x); (3.19) H.
    check(&Case {
        snap: "mechanics_gauge_oscillator",
        title: "gauge-transformed oscillator (2.75), (3.18), (3.19)",
        l: "1/2 m (x'^2 + 2 ω0 x x' - ω0^2 x^2)",
        coords: &["x"],
        positive: &["m"],
        functions: &[],
        el: &["m x'' + m ω0^2 x"],
        h: Some("(p_x - m ω0 x)^2/(2 m) + 1/2 m ω0^2 x^2"),
        conserved: &[("h", "1/2 m (x'^2 + ω0^2 x^2)")],
        overrides: &[],
    });
    let s = system("1/2 m (x'^2 + 2 ω0 x x' - ω0^2 x^2)", &["x"], &["m"], &[]);
    let p = s.canonical_momenta().expect("p");
    assert_same(&p[0], &expr("m (x' + ω0 x)", &["m"], &[]), "(3.18)", &[]);
}

#[test]
fn anharmonic_oscillator() {
    // (2.8.2) L; E = m x'' + m ω0² (x + 2 σ x³/l0²); H = p²/2m + V. (The averaged-Lagrangian
    // part of (2.8.2) is the canonical module's `average`.)
    check(&Case {
        snap: "mechanics_anharmonic_oscillator",
        title: "anharmonic oscillator (2.8.2)",
        l: "1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)",
        coords: &["x"],
        positive: &["m", "l0"],
        functions: &[],
        el: &["m x'' + m ω0^2 (x + 2 σ x^3/l0^2)"],
        h: Some("p_x^2/(2 m) + 1/2 m ω0^2 (x^2 + σ x^4/l0^2)"),
        conserved: &[("h", "1/2 m x'^2 + 1/2 m ω0^2 (x^2 + σ x^4/l0^2)")],
        overrides: &[],
    });
}

#[test]
fn rotating_planet() {
    // (2.8.1) L = ½ m |r' + Ω × r|² − V(r), Ω = Ω ẑ: m (r'' + 2 Ω × r' + Ω × (Ω × r)) = −∇V
    // (Coriolis and centrifugal); H = |p|²/2m − Ω·(r × p) + V; the Jacobi integral h.
    check(&Case {
        snap: "mechanics_rotating_planet",
        title: "rotating planet (2.8.1)",
        l: "1/2 m ((x' - Ω y)^2 + (y' + Ω x)^2 + z'^2) - V(x, y, z)",
        coords: &["x", "y", "z"],
        positive: &["m"],
        functions: &["V"],
        el: &[
            "m (x'' - 2 Ω y' - Ω^2 x) + ∂₁V(x, y, z)",
            "m (y'' + 2 Ω x' - Ω^2 y) + ∂₂V(x, y, z)",
            "m z'' + ∂₃V(x, y, z)",
        ],
        h: Some("(p_x^2 + p_y^2 + p_z^2)/(2 m) + Ω (y p_x - x p_y) + V(x, y, z)"),
        conserved: &[("h", "1/2 m (x'^2 + y'^2 + z'^2) - 1/2 m Ω^2 (x^2 + y^2) + V(x, y, z)")],
        overrides: &[],
    });
}

#[test]
fn relativistic_particle() {
    // §3: L = −m c² sqrt(1 − |r'|²/c²) needs the general inversion of (3.6); p = γ m r',
    // H = sqrt(m² c⁴ + c² |p|²), E_i = d/dt(γ m x_i') = γ m x_i'' + γ³ m x_i' (r'·r'')/c².
    let g = "1/sqrt(1 - (x'^2 + y'^2 + z'^2)/c^2)";
    let el: Vec<String> = ["x", "y", "z"]
        .iter()
        .map(|q| format!("m ({g}) {q}'' + m ({g})^3 {q}' (x' x'' + y' y'' + z' z'')/c^2"))
        .collect();
    let el: Vec<&str> = el.iter().map(String::as_str).collect();
    let px = format!("m x' ({g})");
    let py = format!("m y' ({g})");
    let pz = format!("m z' ({g})");
    let h = format!("m c^2 ({g})");
    check(&Case {
        snap: "mechanics_relativistic_particle",
        title: "relativistic free particle (§3, general inversion of (3.6))",
        l: "-m c^2 sqrt(1 - (x'^2 + y'^2 + z'^2)/c^2)",
        coords: &["x", "y", "z"],
        positive: &["m", "c"],
        functions: &[],
        el: &el,
        h: Some("sqrt(m^2 c^4 + c^2 (p_x^2 + p_y^2 + p_z^2))"),
        conserved: &[("p_x", &px), ("p_y", &py), ("p_z", &pz), ("h", &h)],
        // |r'|² < 3 · 1.5² < c² = 9.
        overrides: &[("c", 3.0)],
    });
}

const DOUBLE_PENDULUM: &str = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
const DP_POSITIVE: &[&str] = &["m1", "m2", "l1", "l2", "g"];

#[test]
fn double_pendulum() {
    // Natural system (3.23–3.27); the compact H of the issue (textbook form).
    check(&Case {
        snap: "mechanics_double_pendulum",
        title: "double pendulum (natural system (3.23)–(3.27))",
        l: DOUBLE_PENDULUM,
        coords: &["θ1", "θ2"],
        positive: DP_POSITIVE,
        functions: &[],
        el: &[
            "(m1 + m2) l1^2 θ1'' + m2 l1 l2 θ2'' cos(θ1 - θ2) + m2 l1 l2 θ2'^2 sin(θ1 - θ2) + (m1 + m2) g l1 sin(θ1)",
            "m2 l2^2 θ2'' + m2 l1 l2 θ1'' cos(θ1 - θ2) - m2 l1 l2 θ1'^2 sin(θ1 - θ2) + m2 g l2 sin(θ2)",
        ],
        h: Some(
            "(m2 l2^2 p_θ1^2 + (m1 + m2) l1^2 p_θ2^2 - 2 m2 l1 l2 p_θ1 p_θ2 cos(θ1 - θ2)) / (2 m2 l1^2 l2^2 (m1 + m2 sin(θ1 - θ2)^2)) - (m1 + m2) g l1 cos(θ1) - m2 g l2 cos(θ2)",
        ),
        conserved: &[(
            "h",
            "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) - (m1 + m2) g l1 cos(θ1) - m2 g l2 cos(θ2)",
        )],
        overrides: &[],
    });
}

#[test]
fn double_pendulum_from_cartesian_positions_gives_the_same_w_f_and_h() {
    // The same pendulum written as ½ Σ m_k |r_k'|² − V with r_k in terms of the angles: the
    // angle-addition and Pythagorean contractions must give structurally identical results.
    let cartesian = "1/2 m1 ((l1 cos(θ1) θ1')^2 + (l1 sin(θ1) θ1')^2) + 1/2 m2 ((l1 cos(θ1) θ1' + l2 cos(θ2) θ2')^2 + (l1 sin(θ1) θ1' + l2 sin(θ2) θ2')^2) + m1 g l1 cos(θ1) + m2 g (l1 cos(θ1) + l2 cos(θ2))";
    let a = system(DOUBLE_PENDULUM, &["θ1", "θ2"], DP_POSITIVE, &[]);
    let b = system(cartesian, &["θ1", "θ2"], DP_POSITIVE, &[]);
    assert_eq!(a.mass_matrix_split().unwrap(), b.mass_matrix_split().unwrap());
    assert_eq!(a.hamiltonian().unwrap(), b.hamiltonian().unwrap());
    // The issue's target: H in at most 60 operations.
    assert!(a.hamiltonian().unwrap().op_count() <= 60);
}

#[test]
fn spherical_pendulum() {
    // L = ½ m l² (θ'² + sin²θ φ'²) + m g l cos θ; φ ignorable (2.7); natural H (3.23).
    check(&Case {
        snap: "mechanics_spherical_pendulum",
        title: "spherical pendulum",
        l: "1/2 m l^2 (θ'^2 + sin(θ)^2 φ'^2) + m g l cos(θ)",
        coords: &["θ", "φ"],
        positive: &["m", "l", "g"],
        functions: &[],
        el: &[
            "m l^2 θ'' - m l^2 sin(θ) cos(θ) φ'^2 + m g l sin(θ)",
            "m l^2 sin(θ)^2 φ'' + 2 m l^2 sin(θ) cos(θ) θ' φ'",
        ],
        h: Some("p_θ^2/(2 m l^2) + p_φ^2/(2 m l^2 sin(θ)^2) - m g l cos(θ)"),
        conserved: &[("p_φ", "m l^2 sin(θ)^2 φ'"), ("h", "1/2 m l^2 (θ'^2 + sin(θ)^2 φ'^2) - m g l cos(θ)")],
        overrides: &[],
    });
}

#[test]
fn kepler_spherical() {
    // Kepler problem in spherical coordinates, V = −k/r; φ ignorable; natural H (3.23).
    check(&Case {
        snap: "mechanics_kepler_spherical",
        title: "Kepler problem in spherical coordinates",
        l: "1/2 m (r'^2 + r^2 θ'^2 + r^2 sin(θ)^2 φ'^2) + k/r",
        coords: &["r", "θ", "φ"],
        positive: &["m", "k"],
        functions: &[],
        el: &[
            "m r'' - m r θ'^2 - m r sin(θ)^2 φ'^2 + k/r^2",
            "m r^2 θ'' + 2 m r r' θ' - m r^2 sin(θ) cos(θ) φ'^2",
            "m r^2 sin(θ)^2 φ'' + 2 m r r' sin(θ)^2 φ' + 2 m r^2 sin(θ) cos(θ) θ' φ'",
        ],
        h: Some("p_r^2/(2 m) + p_θ^2/(2 m r^2) + p_φ^2/(2 m r^2 sin(θ)^2) - k/r"),
        conserved: &[("p_φ", "m r^2 sin(θ)^2 φ'"), ("h", "1/2 m (r'^2 + r^2 θ'^2 + r^2 sin(θ)^2 φ'^2) - k/r")],
        overrides: &[],
    });
}

#[test]
fn three_body_gravity_cartesian() {
    // N-body natural form (3.27) for N = 3: H = Σ |p_i|²/2m_i + V,
    // V = −Σ_{i<j} G m_i m_j / r_ij; E for x_i: m_i x_i'' + Σ_j G m_i m_j (x_i − x_j)/r_ij³.
    let r = |i: usize, j: usize| format!("((x{i} - x{j})^2 + (y{i} - y{j})^2 + (z{i} - z{j})^2)");
    let pairs = [(1, 2), (1, 3), (2, 3)];
    let kinetic: Vec<String> = (1..=3).map(|i| format!("1/2 m{i} (x{i}'^2 + y{i}'^2 + z{i}'^2)")).collect();
    let potential: Vec<String> = pairs.iter().map(|&(i, j)| format!("G m{i} m{j}/sqrt{}", r(i, j))).collect();
    let l = format!("{} + {}", kinetic.join(" + "), potential.join(" + "));
    let mut coords = Vec::new();
    let mut el = Vec::new();
    for i in 1..=3usize {
        for c in ["x", "y", "z"] {
            coords.push(format!("{c}{i}"));
            let mut e = format!("m{i} {c}{i}''");
            for j in (1..=3usize).filter(|&j| j != i) {
                e += &format!(" + G m{i} m{j} ({c}{i} - {c}{j})/{}^(3/2)", r(i, j));
            }
            el.push(e);
        }
    }
    let kinetic_h: Vec<String> = (1..=3).map(|i| format!("(p_x{i}^2 + p_y{i}^2 + p_z{i}^2)/(2 m{i})")).collect();
    let h = format!("{} - {}", kinetic_h.join(" + "), potential.join(" - "));
    let energy = format!("{} - {}", kinetic.join(" + "), potential.join(" - "));
    let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
    let el: Vec<&str> = el.iter().map(String::as_str).collect();
    check(&Case {
        snap: "mechanics_three_body",
        title: "three-body gravity in Cartesian coordinates ((3.27), N = 3)",
        l: &l,
        coords: &coords,
        positive: &["m1", "m2", "m3", "G"],
        functions: &[],
        el: &el,
        h: Some(&h),
        conserved: &[("h", &energy)],
        overrides: &[],
    });
}
