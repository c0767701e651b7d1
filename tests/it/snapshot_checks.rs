//! Independent checks of the snapshot lines that no other test checked.
//!
//! Each test reads a committed `.snap` file — the exact text a user sees, which the snapshot
//! tests pin to what the engine prints — parses every derived line and compares it at random
//! points with a route that does not go through the engine's symbolic derivations:
//!
//! * Euler–Lagrange lines against finite differences of the input Lagrangian along a
//!   quadratic path (`d/dt ∂L/∂q' − ∂L/∂q`, both derivatives by five-point differences);
//! * Hamilton's equations against finite differences of the input Hamiltonian;
//! * Hamiltonians against a numerical Legendre transform (Newton on `p = ∂L/∂v`, then
//!   `H = p·v − L`), energy functions and momenta against `v·∂L/∂v − L` and `∂L/∂v`;
//! * averaged Lagrangians against quadrature over the phase of the trial function;
//! * generating-function transformations against finite differences of the generator
//!   (`p = ∂F/∂q`, `P = −∂F1/∂Q`, `Q = ∂F2/∂P`, `K = H + ∂F/∂t`) and a forward–inverse round trip;
//! * discrete Lagrangians against the quadrature rule they name.
//!
//! Every line of each snapshot read here is either checked or named as not a derivation
//! (`wrote …`, `note: …`, section headers); a line of a new kind fails the test, so a new
//! derived line cannot slip in unchecked. `tests/README.md` maps every snapshot to its check.
//! Nothing here runs a derivation, so the whole file takes milliseconds.

use std::collections::HashMap;
use std::path::Path;

use lagrangian::eval::{eval, Env};
use lagrangian::{parse_with, Declarations, Expr};

// ----- reading snapshots ----------------------------------------------------------------------

/// The body of `snapshots/{name}.snap` (after the insta header), one entry per line.
fn snapshot(name: &str) -> Vec<String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("snapshots").join(format!("{name}.snap"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut dashes = 0;
    text.lines()
        .filter(|l| {
            if dashes < 2 && *l == "---" {
                dashes += 1;
                return false;
            }
            dashes >= 2
        })
        .map(String::from)
        .collect()
}

fn superscript(c: char) -> Option<char> {
    Some(match c {
        '⁰' => '0',
        '¹' => '1',
        '²' => '2',
        '³' => '3',
        '⁴' => '4',
        '⁵' => '5',
        '⁶' => '6',
        '⁷' => '7',
        '⁸' => '8',
        '⁹' => '9',
        _ => return None,
    })
}

/// The Unicode printing (`θ̈1`, `x²`, `√(…)`) spelled in the parser's plain syntax
/// (`θ1''`, `x^2`, `sqrt(…)`). A dot over an identifier's first letter belongs to the
/// whole identifier, so its primes go after the identifier's last character.
fn plain(s: &str) -> String {
    let mut out = String::new();
    let mut primes = 0;
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\u{307}' => primes += 1,
            '\u{308}' => primes += 2,
            _ if superscript(c).is_none() && (c.is_alphanumeric() || c == '_') => out.push(c),
            _ => {
                out.push_str(&"'".repeat(primes));
                primes = 0;
                if let Some(d) = superscript(c) {
                    out.push('^');
                    out.push(d);
                    while let Some(d) = chars.peek().copied().and_then(superscript) {
                        out.push(d);
                        chars.next();
                    }
                } else if c == '√' {
                    out.push_str("sqrt");
                } else {
                    out.push(c);
                }
            }
        }
    }
    out.push_str(&"'".repeat(primes));
    out
}

/// A snapshot line split into its left side and the expression on its right, with the
/// explanation in parentheses (`   (…)`), a `    # …` comment, a trailing ` = 0` and a restated
/// left side (`J = ∂⟨L⟩/∂ω = …`) removed.
/// `None` for lines that are not `lhs = rhs` or `lhs: rhs = 0`.
fn split(line: &str) -> Option<(String, String)> {
    let line = plain(line.trim());
    let line = line.split("   (").next().unwrap().split("    #").next().unwrap().trim();
    let (lhs, rhs) = match line.split_once(": ") {
        Some((l, r)) if !l.contains(" = ") => (l, r.trim_end_matches(" = 0")),
        _ => line.split_once(" = ")?,
    };
    // `∂⟨L⟩/∂A = … = 0` and `J = ∂⟨L⟩/∂ω = …` (the averaging lines): the expression is the
    // part between the restated name and the ` = 0`.
    let rhs = rhs.trim_end_matches(" = 0");
    let rhs = rhs.rsplit_once(" = ").map_or(rhs, |(_, r)| r);
    Some((lhs.trim().to_string(), rhs.trim().to_string()))
}

/// Lines that report files, notes or structure rather than a derived expression.
fn not_a_derivation(line: &str) -> bool {
    line.trim().is_empty()
        // `separation of a and b: …` is a measured rate, checked against the tangent flow
        // in tests/it/scene/figures.rs.
        || ["wrote ", "note: ", "# ", "$ ", "branch: ", "separation of ", "animation of "].iter().any(|p| line.starts_with(p))
        // An ensemble's summary (`low: 21 runs (low_1 … low_21) …`): its members' energies
        // are checked against the level in tests/it/scene/figures.rs.
        || line.split_once(": ").is_some_and(|(_, r)| r.contains(" runs (") && r.contains(" at the start "))
        || line.ends_with(':')
}

fn parse(text: &str) -> Expr {
    let d = Declarations::new().with_functions(["V"]);
    parse_with(text, &d).unwrap_or_else(|e| panic!("`{text}` does not parse: {e}"))
}

/// Runs `check` on every derived line of a snapshot and asserts that each was recognised:
/// `check` returns false for a line it does not know, which fails the test.
fn each_line(name: &str, mut check: impl FnMut(&str, &Expr) -> bool) -> usize {
    let mut checked = 0;
    for line in snapshot(name) {
        if not_a_derivation(&line) {
            continue;
        }
        let (lhs, rhs) = split(&line).unwrap_or_else(|| panic!("{name}: unrecognised line `{line}`"));
        assert!(check(&lhs, &parse(&rhs)), "{name}: no independent check for `{line}`");
        checked += 1;
    }
    assert!(checked > 0, "{name}: nothing checked");
    checked
}

// ----- numbers --------------------------------------------------------------------------------

/// A small xorshift generator: the points are fixed, so failures reproduce.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn at(e: &Expr, env: &Env) -> f64 {
    eval(e, env).unwrap_or_else(|err| panic!("{e} at {env:?}: {err}"))
}

fn with(env: &Env, key: &str, v: f64) -> Env {
    let mut e = env.clone();
    e.insert(key.to_string(), v);
    e
}

/// Step of the five-point differences: truncation ~h⁴ ≈ 1e-12, rounding ~ε/h ≈ 1e-13 (one
/// level) or ε/h² ≈ 1e-10 (nested), far inside the 1e-7 tolerance of [`close`].
const H: f64 = 1e-3;

fn d(f: impl Fn(f64) -> f64, x: f64) -> f64 {
    (f(x - 2.0 * H) - 8.0 * f(x - H) + 8.0 * f(x + H) - f(x + 2.0 * H)) / (12.0 * H)
}

fn partial(e: &Expr, env: &Env, key: &str) -> f64 {
    d(|v| at(e, &with(env, key, v)), env[key])
}

/// Agreement to 1e-7 relative to the size of the values: the finite differences above are
/// good to about 1e-10, and a wrong term, sign or factor is off by order one.
fn close(got: f64, want: f64, what: &str) {
    assert!((got - want).abs() <= 1e-7 * (1.0 + want.abs()), "{what}: printed {got}, independent {want}");
}

/// Random values: coordinates and velocities of either sign, parameters positive.
fn random_env(rng: &mut Rng, coords: &[&str], params: &[&str]) -> Env {
    let mut env = Env::new();
    for q in coords {
        env.insert(q.to_string(), rng.uniform(-1.5, 1.5));
        env.insert(format!("{q}'"), rng.uniform(-1.5, 1.5));
        env.insert(format!("{q}''"), rng.uniform(-1.5, 1.5));
        env.insert(format!("p_{q}"), rng.uniform(-1.5, 1.5));
    }
    for p in params {
        env.insert(p.to_string(), rng.uniform(0.5, 2.0));
    }
    env.insert("t".into(), rng.uniform(-1.0, 1.0));
    env
}

/// `d/dt ∂L/∂q_i' − ∂L/∂q_i` along the path `q(s) = q + q' s + q'' s²/2` (time `t + s`),
/// both derivatives by finite differences of `L`.
fn euler_lagrange_fd(l: &Expr, coords: &[&str], env: &Env, i: usize) -> f64 {
    let along = |s: f64| {
        let mut e = env.clone();
        for q in coords {
            let (x, v, a) = (env[*q], env[&format!("{q}'")], env[&format!("{q}''")]);
            e.insert(q.to_string(), x + v * s + a * s * s / 2.0);
            e.insert(format!("{q}'"), v + a * s);
        }
        e.insert("t".into(), env["t"] + s);
        e
    };
    let velocity = format!("{}'", coords[i]);
    d(|s| partial(l, &along(s), &velocity), 0.0) - partial(l, env, coords[i])
}

/// Solves the small dense system `a x = b` by Gaussian elimination with partial pivoting.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs())).unwrap();
        a.swap(k, p);
        b.swap(k, p);
        for i in k + 1..n {
            let f = a[i][k] / a[k][k];
            let pivot_row = a[k].clone();
            for (x, y) in a[i].iter_mut().zip(&pivot_row).skip(k) {
                *x -= f * y;
            }
            b[i] -= f * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        x[k] = (b[k] - (k + 1..n).map(|j| a[k][j] * x[j]).sum::<f64>()) / a[k][k];
    }
    x
}

/// The Legendre transform done numerically: Newton on `∂L/∂v = p` (Jacobian by finite
/// differences of the finite-difference momenta), then `H = p·v − L`.
fn legendre_fd(l: &Expr, coords: &[&str], env: &Env) -> f64 {
    let vel: Vec<String> = coords.iter().map(|q| format!("{q}'")).collect();
    let p: Vec<f64> = coords.iter().map(|q| env[&format!("p_{q}")]).collect();
    let mut e = env.clone();
    for v in &vel {
        e.insert(v.clone(), 0.0);
    }
    for _ in 0..30 {
        let residual: Vec<f64> = (0..coords.len()).map(|i| p[i] - partial(l, &e, &vel[i])).collect();
        let jac: Vec<Vec<f64>> = (0..coords.len())
            .map(|i| (0..coords.len()).map(|j| d(|x| partial(l, &with(&e, &vel[j], x), &vel[i]), e[&vel[j]])).collect())
            .collect();
        let step = solve(jac, residual);
        for (v, s) in vel.iter().zip(&step) {
            *e.get_mut(v).unwrap() += s;
        }
        if step.iter().all(|s| s.abs() < 1e-13) {
            break;
        }
    }
    (0..coords.len()).map(|i| p[i] * e[&vel[i]]).sum::<f64>() - at(l, &e)
}

/// The energy function `v·∂L/∂v − L` (PHYSICS.md (2.7)) by finite differences.
fn energy_function_fd(l: &Expr, coords: &[&str], env: &Env) -> f64 {
    coords.iter().map(|q| env[&format!("{q}'")] * partial(l, env, &format!("{q}'"))).sum::<f64>() - at(l, env)
}

// ----- scene examples -------------------------------------------------------------------------

/// The example's input text (a Lagrangian or Hamiltonian), checked to be in the scene file so
/// that the test follows the example.
fn scene_input(example: &str, text: &str) -> Expr {
    parse(scene_text(example, text))
}

/// The right side of `text`, after checking the scene file contains `text`.
fn scene_text<'a>(example: &str, text: &'a str) -> &'a str {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples").join(format!("{example}.scene"));
    let scene = std::fs::read_to_string(path).unwrap();
    let squash = |s: &str| s.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(squash(&scene).contains(&squash(text)), "{example}.scene no longer contains `{text}`");
    text.split_once(" = ").unwrap().1
}

/// Checks a Lagrangian example: `E_q` lines by finite differences of `L`, `H` by the numerical
/// Legendre transform, `h` as the energy function, `p_q` as `∂L/∂q'`. Lines whose left side
/// starts with one of `elsewhere` are checked by another test of this file.
fn lagrangian_example(example: &str, l_text: &str, coords: &[&str], params: &[&str], elsewhere: &[&str], seed: u64) {
    let l = scene_input(example, l_text);
    let mut rng = Rng(seed);
    for _ in 0..4 {
        let env = random_env(&mut rng, coords, params);
        each_line(&format!("scene_example_{example}"), |lhs, rhs| {
            if elsewhere.iter().any(|p| lhs.starts_with(p)) {
                return true;
            }
            let got = at(rhs, &env);
            let want = if let Some(q) = lhs.strip_prefix("E_") {
                let i = coords.iter().position(|c| *c == q).expect("a coordinate");
                euler_lagrange_fd(&l, coords, &env, i)
            } else if lhs == "H" {
                legendre_fd(&l, coords, &env)
            } else if lhs == "h" {
                energy_function_fd(&l, coords, &env)
            } else if let Some(q) = lhs.strip_prefix("p_") {
                partial(&l, &env, &format!("{q}'"))
            } else {
                return false;
            };
            close(got, want, &format!("{example}: {lhs}"));
            true
        });
    }
}

/// Checks a Hamiltonian example: `q' = ∂H/∂p`, `p' = −∂H/∂q` by finite differences of the input
/// `H`, and a printed `H` against the input.
fn hamiltonian_example(example: &str, h_text: &str, coords: &[&str], params: &[&str], seed: u64) {
    let h = scene_input(example, h_text);
    let mut rng = Rng(seed);
    for _ in 0..4 {
        let env = random_env(&mut rng, coords, params);
        each_line(&format!("scene_example_{example}"), |lhs, rhs| {
            let got = at(rhs, &env);
            let want = if lhs == "H" {
                at(&h, &env)
            } else if let Some(q) = lhs.strip_suffix('\'').and_then(|s| s.strip_prefix("p_")) {
                -partial(&h, &env, q)
            } else if let Some(q) = lhs.strip_suffix('\'') {
                partial(&h, &env, &format!("p_{q}"))
            } else if lhs.strip_prefix('Q').is_some_and(|k| k.parse::<u32>().is_ok()) {
                // A charge of the symmetry search: conserved, {Q, H} = 0, with both
                // brackets' derivatives by finite differences.
                let bracket: f64 = coords
                    .iter()
                    .map(|q| {
                        let p = format!("p_{q}");
                        partial(rhs, &env, q) * partial(&h, &env, &p) - partial(rhs, &env, &p) * partial(&h, &env, q)
                    })
                    .sum();
                close(bracket, 0.0, &format!("{example}: {{{lhs}, H}}"));
                return true;
            } else {
                return false;
            };
            close(got, want, &format!("{example}: {lhs}"));
            true
        });
    }
}

#[test]
fn scene_example_lagrangian_lines() {
    lagrangian_example("pendulum", "L = 1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", &["θ"], &["m", "l", "g"], &[], 11);
    lagrangian_example("atwood", "L = 1/2 (m1 + m2) x'^2 - (m1 - m2) g x", &["x"], &["m1", "m2", "g"], &[], 12);
    lagrangian_example(
        "charged_particle",
        "L = 1/2 m (x'^2 + y'^2 + z'^2) + e B/2 (x y' - y x') - e E z",
        &["x", "y", "z"],
        &["m", "e", "B", "E"],
        &[],
        13,
    );
    lagrangian_example(
        "double_pendulum",
        "L = 1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
         + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)",
        &["θ1", "θ2"],
        &["m1", "m2", "l1", "l2", "g"],
        &[],
        14,
    );
    // First-order (phase-space) Lagrangians: only E lines, which are still d/dt ∂L/∂q' − ∂L/∂q.
    lagrangian_example("phase_space_oscillator", "L = p x' - p^2/(2 m) - k x^2/2", &["x", "p"], &["m", "k"], &[], 15);
    lagrangian_example(
        "point_vortices",
        "L = Γ1 (y1 x1' - x1 y1')/2 + Γ2 (y2 x2' - x2 y2')/2 + Γ1 Γ2 log((x1 - x2)^2 + (y1 - y2)^2)/(4 π)",
        &["x1", "y1", "x2", "y2"],
        &["Γ1", "Γ2", "π"],
        &[],
        16,
    );
    lagrangian_example(
        "variational_integrator",
        "L = (x'^2 + y'^2)/2 + k/sqrt(x^2 + y^2)",
        &["x", "y"],
        &["k"],
        &[],
        19,
    );
    lagrangian_example(
        "anharmonic_oscillator",
        "L = 1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)",
        &["x"],
        &["m", "ω0", "σ", "l0"],
        &["⟨L⟩", "∂⟨L⟩", "J"],
        17,
    );
}

/// The central-potential example with `V` made concrete: `V(r) = r³/3 + cos r`, so
/// `V'(r) = r² − sin r`, substituted into the input and the printed lines alike.
#[test]
fn scene_example_central_potential_with_a_concrete_potential() {
    let concrete = |s: &str| s.replace("V'(r)", "(r^2 - sin(r))").replace("V(r)", "(r^3/3 + cos(r))");
    let l = parse(&concrete(scene_text("central_potential", "L = 1/2 m (r'^2 + r^2 φ'^2) - V(r)")));
    let coords = ["r", "φ"];
    let mut rng = Rng(21);
    for _ in 0..4 {
        let mut env = random_env(&mut rng, &coords, &["m"]);
        env.insert("r".into(), rng.uniform(0.5, 2.0));
        let mut checked = 0;
        for line in snapshot("scene_example_central_potential") {
            if not_a_derivation(&line) {
                continue;
            }
            let (lhs, rhs) = split(&line).unwrap();
            let got = at(&parse(&concrete(&rhs)), &env);
            let want = match lhs.as_str() {
                "E_r" => euler_lagrange_fd(&l, &coords, &env, 0),
                "E_φ" => euler_lagrange_fd(&l, &coords, &env, 1),
                "H" => legendre_fd(&l, &coords, &env),
                "h" => energy_function_fd(&l, &coords, &env),
                "p_φ" => partial(&l, &env, "φ'"),
                _ => panic!("central_potential: no independent check for `{line}`"),
            };
            close(got, want, &format!("central_potential: {lhs}"));
            checked += 1;
        }
        assert_eq!(checked, 5);
    }
}

#[test]
fn scene_example_hamiltonian_lines() {
    hamiltonian_example("kepler", "H = (p_x^2 + p_y^2)/2 - k/sqrt(x^2 + y^2)", &["x", "y"], &["k"], 31);
    hamiltonian_example("henon_heiles", "H = (p_x^2 + p_y^2)/2 + (x^2 + y^2)/2 + x^2 y - y^3/3", &["x", "y"], &[], 32);
    hamiltonian_example("adiabatic_oscillator", "H = p_q^2/2 + 1/2 ω0^2 (1 + ε t)^2 q^2", &["q"], &["ω0", "ε"], 33);
}

/// The trial `x = l0 (A cos θ + B cos 3θ + C sin 3θ)`, `θ = ω t`, put into `L` and averaged
/// over one period by the trapezoid rule on 64 points (exact for trigonometric polynomials of
/// degree below 64; `L` here has degree 12 in θ).
fn averaged_fd(l: &Expr, env: &Env) -> f64 {
    let n = 64;
    let (a, b, c, w, l0) = (env["A"], env["B"], env["C"], env["ω"], env["l0"]);
    (0..n)
        .map(|k| {
            let th = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            let x = l0 * (a * th.cos() + b * (3.0 * th).cos() + c * (3.0 * th).sin());
            let v = l0 * w * (-a * th.sin() - 3.0 * b * (3.0 * th).sin() + 3.0 * c * (3.0 * th).cos());
            at(l, &with(&with(env, "x", x), "x'", v))
        })
        .sum::<f64>()
        / n as f64
}

/// The averaging lines of the anharmonic example (PHYSICS.md §2.8.2): `⟨L⟩` against
/// quadrature, `∂⟨L⟩/∂A, B, C` and `J = ∂⟨L⟩/∂ω` against finite differences of the quadrature.
/// The same lines in `canonical_anharmonic_average` (spelled `w`, `w0`) get the same check.
#[test]
fn averaged_lagrangian_lines() {
    let l = scene_input("anharmonic_oscillator", "L = 1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)");
    let mut rng = Rng(41);
    for snap in ["scene_example_anharmonic_oscillator", "canonical_anharmonic_average"] {
        for _ in 0..3 {
            let mut env = random_env(&mut rng, &[], &["m", "ω0", "σ", "l0", "ω"]);
            for k in ["A", "B", "C"] {
                env.insert(k.into(), rng.uniform(-1.0, 1.0));
            }
            let mut checked = 0;
            for line in snapshot(snap) {
                if not_a_derivation(&line) {
                    continue;
                }
                let (lhs, rhs) = split(&line).unwrap();
                if lhs.starts_with("E_") || lhs == "H" {
                    continue; // checked by `scene_example_lagrangian_lines`
                }
                let rhs = parse(&rhs.replace("w0", "ω0").replace('w', "ω"));
                let got = at(&rhs, &env);
                let lhs = lhs.replace("d<L>/d", "∂⟨L⟩/∂");
                let want = match lhs.as_str() {
                    "⟨L⟩" | "<L>" => averaged_fd(&l, &env),
                    "J" => partial_of(&l, &env, "ω"),
                    _ => match lhs.strip_prefix("∂⟨L⟩/∂") {
                        Some(k) => partial_of(&l, &env, k),
                        None => panic!("{snap}: no independent check for `{line}`"),
                    },
                };
                close(got, want, &format!("{snap}: {lhs}"));
                checked += 1;
            }
            assert_eq!(checked, 5, "{snap}");
        }
    }
}

fn partial_of(l: &Expr, env: &Env, key: &str) -> f64 {
    d(|v| averaged_fd(l, &with(env, key, v)), env[key])
}

// ----- canonical transformations --------------------------------------------------------------

/// A generating-function transformation of `tests/it/canonical/transform.rs`, with its declared
/// functions made concrete (`ω(t) = 1 + t²/3`, `V(u) = cos u`) by substitution in the text.
struct Transform<'a> {
    snap: &'a str,
    f2: bool,
    generator: &'a str,
    h: &'a str,
    old: &'a [&'a str],
    new: &'a [&'a str],
    /// Draws a point (new variables, parameters, t) inside the branch the transformation took.
    point: fn(&mut Rng) -> Env,
}

fn concrete(s: &str) -> String {
    s.replace("ω'(t)", "(2 t/3)").replace("ω(t)", "(1 + t^2/3)").replace("V(", "cos(")
}

/// The sections of a transformation snapshot: relations, inverse, forward (name → expression)
/// and K.
type Sections = HashMap<String, Vec<(String, Expr)>>;

fn sections(snap: &str) -> Sections {
    let mut out: Sections = HashMap::new();
    let mut current = String::new();
    for line in snapshot(snap) {
        if line.starts_with("branch: ") || line.trim().is_empty() {
            continue;
        }
        if let Some(title) = line.strip_suffix(':') {
            current = title.split(' ').next().unwrap().to_string();
            continue;
        }
        let (lhs, rhs) = split(&line).unwrap_or_else(|| panic!("{snap}: unrecognised line `{line}`"));
        let section = if line.starts_with("  ") { current.clone() } else { lhs.clone() };
        out.entry(section).or_default().push((lhs, parse(&concrete(&rhs))));
    }
    out
}

fn check_transform(t: &Transform) {
    let s = sections(t.snap);
    let generator = parse(&concrete(t.generator));
    let h = parse(&concrete(t.h));
    let n = t.old.len();
    let (old_p, new_p): (Vec<String>, Vec<String>) = (
        t.old.iter().map(|q| format!("p_{q}")).collect(),
        if n == 1 { vec!["P".to_string()] } else { t.new.iter().map(|q| format!("P_{q}")).collect() },
    );
    let value = |sec: &str, name: &str, env: &Env| {
        let (_, e) = s[sec].iter().find(|(l, _)| l == name).unwrap_or_else(|| panic!("{}: no {sec} {name}", t.snap));
        at(e, env)
    };
    let mut rng = Rng(t.snap.len() as u64 * 7919 + 1);
    for _ in 0..6 {
        // New variables → old ones through the printed inverse.
        let mut env = (t.point)(&mut rng);
        for name in t.old.iter().map(|q| q.to_string()).chain(old_p.iter().cloned()) {
            let v = value("inverse", &name, &env);
            env.insert(name, v);
        }
        // The printed forward map returns the new variables.
        for name in t.new.iter().map(|q| q.to_string()).chain(new_p.iter().cloned()) {
            close(value("forward", &name, &env), env[&name], &format!("{}: forward {name}", t.snap));
        }
        // Relations and the inverse against derivatives of the generator: F1(q, Q):
        // p = ∂F1/∂q, P = −∂F1/∂Q; F2(q, P): p = ∂F2/∂q, Q = ∂F2/∂P.
        for (i, q) in t.old.iter().enumerate() {
            let want = partial(&generator, &env, q);
            close(env[&old_p[i]], want, &format!("{}: inverse {}", t.snap, old_p[i]));
            close(value("relations", &old_p[i], &env), want, &format!("{}: relation {}", t.snap, old_p[i]));
        }
        for (new_q, new_p) in t.new.iter().zip(&new_p) {
            let (name, want) = if t.f2 {
                (new_q.to_string(), partial(&generator, &env, new_p))
            } else {
                (new_p.clone(), -partial(&generator, &env, new_q))
            };
            close(value("relations", &name, &env), want, &format!("{}: relation {name}", t.snap));
        }
        // K = H(q, p, t) + ∂F/∂t at fixed generator arguments.
        let k = value("K", "K", &env);
        close(k, at(&h, &env) + partial(&generator, &env, "t"), &format!("{}: K", t.snap));
    }
    // Every line was one of the above.
    let lines = s.values().map(Vec::len).sum::<usize>();
    assert_eq!(lines, 2 * n + 2 * 2 * n + 1, "{}: unexpected lines {s:?}", t.snap);
}

fn point_1d(rng: &mut Rng) -> Env {
    // Q in (0, π/2) and P > 0: inside the `+` root and the n = 0 branch of atan.
    [("Q", rng.uniform(0.1, 1.4)), ("P", rng.uniform(0.2, 2.0)), ("m", rng.uniform(0.5, 2.0))]
        .into_iter()
        .chain([("w", rng.uniform(0.5, 2.0)), ("t", rng.uniform(-1.0, 1.0))])
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

fn point_2d(rng: &mut Rng) -> Env {
    // X > 0: the n = 0 branch of atan(Y/X).
    [("X", rng.uniform(0.3, 1.5)), ("Y", rng.uniform(-1.5, 1.5)), ("P_X", rng.uniform(-1.5, 1.5))]
        .into_iter()
        .chain([("P_Y", rng.uniform(-1.5, 1.5)), ("m", rng.uniform(0.5, 2.0))])
        .chain([("Ω", rng.uniform(0.5, 2.0)), ("t", rng.uniform(-1.0, 1.0))])
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

#[test]
fn canonical_transformation_lines() {
    let oscillator = "p_q^2/(2 m) + 1/2 m w^2 q^2";
    for t in [
        Transform {
            snap: "canonical_oscillator_action_angle",
            f2: false,
            generator: "1/2 m w q^2 cot(Q)",
            h: oscillator,
            old: &["q"],
            new: &["Q"],
            point: point_1d,
        },
        Transform {
            snap: "canonical_adiabatic_oscillator",
            f2: false,
            generator: "1/2 m ω(t) q^2 cot(Q)",
            h: "p_q^2/(2 m) + 1/2 m ω(t)^2 q^2",
            old: &["q"],
            new: &["Q"],
            point: point_1d,
        },
        Transform {
            snap: "canonical_exchange",
            f2: false,
            generator: "q Q",
            h: oscillator,
            old: &["q"],
            new: &["Q"],
            point: point_1d,
        },
        Transform {
            snap: "canonical_point_transformation",
            f2: true,
            generator: "P_X r cos(φ) + P_Y r sin(φ)",
            h: "p_r^2/(2 m) + p_φ^2/(2 m r^2)",
            old: &["r", "φ"],
            new: &["X", "Y"],
            point: point_2d,
        },
        Transform {
            snap: "canonical_rotating_frame",
            f2: true,
            generator: "P_X (x cos(Ω t) + y sin(Ω t)) + P_Y (-x sin(Ω t) + y cos(Ω t))",
            h: "(p_x^2 + p_y^2)/(2 m) + V(x^2 + y^2)",
            old: &["x", "y"],
            new: &["X", "Y"],
            point: point_2d,
        },
    ] {
        check_transform(&t);
    }
}

/// `{Q, P}` of the map `Q = q`, `P = p (1 + log q² − 2 log q)` by finite differences: the
/// printed bracket, and that it is 1 (for q > 0), as the snapshot's verdict says.
#[test]
fn canonical_explicit_numeric_only_bracket() {
    let lines = snapshot("canonical_explicit_numeric_only");
    let bracket = lines.iter().find_map(|l| l.strip_prefix("{Q, P} = ")).expect("the bracket line");
    let bracket = parse(bracket.split(" (expected").next().unwrap());
    let (qm, pm) = (parse("q"), parse("p_q (1 + log(q^2) - 2 log(q))"));
    let mut rng = Rng(51);
    for _ in 0..6 {
        let env: Env = [("q".to_string(), rng.uniform(0.2, 3.0)), ("p_q".to_string(), rng.uniform(-2.0, 2.0))].into();
        let want =
            partial(&qm, &env, "q") * partial(&pm, &env, "p_q") - partial(&qm, &env, "p_q") * partial(&pm, &env, "q");
        close(at(&bracket, &env), want, "{Q, P}");
        close(want, 1.0, "{Q, P} = 1");
    }
    assert!(lines[0].starts_with("canonical numerically only") && lines[0].contains("not a proof"));
}

/// The oscillator scene's action–angle lines: brackets `{Q, J}`, `{J, H}`, `{Q, H}` by finite
/// differences of `Q = atan(m ω q/p)`, `J = H/ω`; then the transformation from `F1`, printed as
/// `lagrangian canonical` prints it: the relations against derivatives of `F1`, the inverse
/// map through `p = ∂F1/∂q`, `P = −∂F1/∂Q`, the forward map back to `(Q, P)`, and `K = H`.
#[test]
fn scene_example_oscillator_action_angle_lines() {
    let name = "scene_example_oscillator_action_angle";
    let h = scene_input("oscillator_action_angle", "H = p_q^2/(2 m) + 1/2 m ω^2 q^2");
    let q_new = scene_input("oscillator_action_angle", "Q = atan(m ω q/p_q)");
    let j = parse(&format!("({h})/ω"));
    let generator = scene_input("oscillator_action_angle", "F1 = 1/2 m ω q^2 cot(Q)");
    let pb = |a: &Expr, b: &Expr, env: &Env| {
        partial(a, env, "q") * partial(b, env, "p_q") - partial(a, env, "p_q") * partial(b, env, "q")
    };
    // The printed lines by section (the title's first word; top-level lines under "").
    let mut lines: Vec<(String, String, Expr)> = Vec::new();
    let mut section = String::new();
    for line in snapshot(name) {
        if let Some(title) = line.strip_suffix(':') {
            section = title.split(' ').next().unwrap().to_string();
            continue;
        }
        if not_a_derivation(&line) {
            continue;
        }
        let (lhs, rhs) = split(&line).unwrap();
        let sec = if line.starts_with("  ") { section.clone() } else { String::new() };
        lines.push((sec, lhs, parse(&rhs)));
    }
    let get = |sec: &str, lhs: &str| {
        &lines.iter().find(|(s, l, _)| s == sec && l == lhs).unwrap_or_else(|| panic!("{name}: no {sec} {lhs}")).2
    };
    let mut rng = Rng(61);
    for _ in 0..6 {
        let mut env = random_env(&mut rng, &["q"], &["m", "ω"]);
        env.insert("p_q".into(), rng.uniform(0.3, 1.5)); // away from the pole of atan's argument
        env.insert("Q".into(), rng.uniform(0.1, 1.4));
        env.insert("P".into(), rng.uniform(0.2, 2.0));
        // The old variables at (Q, P) through the printed inverse.
        let mut old = env.clone();
        for v in ["q", "p_q"] {
            old.insert(v.into(), at(get("old", v), &env));
        }
        for (sec, lhs, e) in &lines {
            let got = at(e, &env);
            let want = match (sec.as_str(), lhs.as_str()) {
                ("", "{Q, J}") => pb(&q_new, &j, &env),
                ("", "{J, H}") => pb(&j, &h, &env),
                ("", "{Q, H}") => pb(&q_new, &h, &env),
                // The relations at (q, Q): p = ∂F1/∂q, P = −∂F1/∂Q.
                ("relations", "p_q") => partial(&generator, &env, "q"),
                ("relations", "P") => -partial(&generator, &env, "Q"),
                // The inverse satisfies the relations at (Q, P).
                ("old", "q") => {
                    close(old["p_q"], partial(&generator, &old, "q"), "p_q = ∂F1/∂q");
                    close(env["P"], -partial(&generator, &old, "Q"), "P = −∂F1/∂Q");
                    got
                }
                ("old", "p_q") => got,
                // The forward map at the inverse point returns (Q, P).
                ("new", v @ ("Q" | "P")) => {
                    close(at(e, &old), env[v], &format!("forward {v}"));
                    got
                }
                // K = H at the inverse point (F1 has no t).
                ("", "K") => at(&h, &old),
                _ => panic!("{name}: no independent check for `{sec} {lhs}`"),
            };
            close(got, want, &format!("{name}: {sec} {lhs}"));
        }
        assert_eq!(
            lines.len(),
            10,
            "{name}: {:?}",
            lines.iter().map(|(s, l, _)| format!("{s} {l}")).collect::<Vec<_>>()
        );
    }
}

// ----- the lecture-notes commands -------------------------------------------------------------

/// `lagrangian el` output (`E_q`, `W[a,b]`, `F_q` lines) against finite differences of `L`:
/// `W_ab = ∂²L/∂a'∂b'` and `F_q = −E_q` at zero accelerations.
fn el_report(snap: &str, l_text: &str, coords: &[&str], params: &[&str], seed: u64) {
    let l = parse(l_text);
    let mut rng = Rng(seed);
    for _ in 0..4 {
        let env = random_env(&mut rng, coords, params);
        let mut zero_acc = env.clone();
        for q in coords {
            zero_acc.insert(format!("{q}''"), 0.0);
        }
        let index = |q: &str| coords.iter().position(|c| *c == q).expect("a coordinate");
        each_line(snap, |lhs, rhs| {
            let (got, want) = if let Some(q) = lhs.strip_prefix("E_") {
                (at(rhs, &env), euler_lagrange_fd(&l, coords, &env, index(q)))
            } else if let Some(q) = lhs.strip_prefix("F_") {
                (at(rhs, &zero_acc), -euler_lagrange_fd(&l, coords, &zero_acc, index(q)))
            } else if let Some(pair) = lhs.strip_prefix("W[").and_then(|s| s.strip_suffix(']')) {
                let (a, b) = pair.split_once(',').unwrap();
                let (va, vb) = (format!("{a}'"), format!("{b}'"));
                (at(rhs, &env), d(|x| partial(&l, &with(&env, &vb, x), &va), env[&vb]))
            } else {
                return false;
            };
            close(got, want, &format!("{snap}: {lhs}"));
            true
        });
    }
}

#[test]
fn notes_el_lines() {
    el_report("notes_el_singular", "1/2 m x'^2 + b x^2 y' - c y^4", &["x", "y"], &["m", "b", "c"], 71);
    el_report("notes_el_phase_space_oscillator", "p x' - p^2/(2 m) - k x^2/2", &["x", "p"], &["m", "k"], 72);
}

/// `lagrangian phase-space` on `L = p x' − p²/(2m) − k x²/2`: the one-form `a_z = ∂L/∂z'`,
/// `H = a·z' − L`, the two-form `ω[x,p] = ∂a_p/∂x − ∂a_x/∂p` (with finite differences of the
/// one-form), the equations `(ω z')_z: lhs = rhs` as `Σ ω_zw w' = ∂H/∂z`, brackets and
/// velocities from `{f, g} = ∂f/∂x ∂g/∂p − ∂f/∂p ∂g/∂x` and Hamilton's equations.
#[test]
fn notes_phase_space_lines() {
    let l = parse("p x' - p^2/(2 m) - k x^2/2");
    let h = parse("p^2/(2 m) + k x^2/2"); // by hand: a·z' − L with a = (p, 0)
    let pb = |f: &Expr, g: &Expr, env: &Env| {
        partial(f, env, "x") * partial(g, env, "p") - partial(f, env, "p") * partial(g, env, "x")
    };
    let mut rng = Rng(73);
    for _ in 0..4 {
        let env = random_env(&mut rng, &["x", "p"], &["m", "k"]);
        let a = |z: &str, env: &Env| partial(&l, env, &format!("{z}'"));
        let omega_xp = d(|v| a("p", &with(&env, "x", v)), env["x"]) - d(|v| a("x", &with(&env, "p", v)), env["p"]);
        let mut checked = 0;
        for line in snapshot("notes_phase_space_oscillator") {
            if not_a_derivation(&line) {
                continue;
            }
            let line = plain(&line);
            let (lhs, rhs) = line.split_once(" = ").unwrap();
            let (got, want) = match lhs {
                "a_x" => (at(&parse(rhs), &env), a("x", &env)),
                "a_p" => (at(&parse(rhs), &env), a("p", &env)),
                "H" => (at(&parse(rhs), &env), a("x", &env) * env["x'"] + a("p", &env) * env["p'"] - at(&l, &env)),
                "ω[x,p]" => (at(&parse(rhs), &env), omega_xp),
                // `(ω z')_z: a = b` says Σ_w ω_zw w' = ∂H/∂z: ω_xp p' = ∂H/∂x, ω_px x' = ∂H/∂p.
                _ if lhs.starts_with("(ω z')_") => {
                    let (row, left) = lhs.split_once(": ").unwrap();
                    let printed = at(&parse(left), &env) - at(&parse(rhs), &env);
                    match row {
                        "(ω z')_x" => (printed, omega_xp * env["p'"] - partial(&h, &env, "x")),
                        "(ω z')_p" => (printed, -omega_xp * env["x'"] - partial(&h, &env, "p")),
                        _ => panic!("unknown row {row}"),
                    }
                }
                "{x, p}" => (at(&parse(rhs), &env), pb(&parse("x"), &parse("p"), &env)),
                "{x^2, x p}" => (at(&parse(rhs), &env), pb(&parse("x^2"), &parse("x p"), &env)),
                "x'" => (at(&parse(rhs), &env), partial(&h, &env, "p")),
                "p'" => (at(&parse(rhs), &env), -partial(&h, &env, "x")),
                _ => panic!("notes_phase_space_oscillator: no independent check for `{line}`"),
            };
            // The `(ω z')` rows are compared off-shell (random z and z'), as expressions.
            close(got, want, &format!("phase-space: {lhs}"));
            checked += 1;
        }
        assert_eq!(checked, 10);
    }
}

/// `lagrangian geodesic` on the unit sphere, and the `geodesic` statements of
/// `examples/geodesic_sphere.scene` on a sphere of radius `R`: `g` against the metric's
/// coefficients, the geodesic equations as `g⁻¹ E` with `E` by finite differences of
/// `L = ½ g v v`, `p_φ` and `h` by finite differences; `Γ` lines are checked by hand in
/// `tests/it/notes/geodesic.rs`, and here again through `q'' + Γ q' q'` (the geodesic equations
/// must equal it).
#[test]
fn notes_geodesic_lines() {
    geodesic_lines("notes_geodesic_sphere", None, 12);
    geodesic_lines("scene_example_geodesic_sphere", Some(2.0), 28);
}

/// The lines of a sphere's geodesic report; `radius` `None` is the unit sphere of the CLI
/// snapshot, `Some(R)` the scene's sphere of radius `R` (its `X` and shooting lines too).
fn geodesic_lines(snap: &str, radius: Option<f64>, expected: usize) {
    let l = parse("R^2 (θ'^2 + sin(θ)^2 φ'^2)/2");
    let coords = ["θ", "φ"];
    let mut rng = Rng(81);
    for _ in 0..4 {
        let mut env = random_env(&mut rng, &coords, &[]);
        env.insert("θ".into(), rng.uniform(0.3, 2.8)); // away from the poles
        let r = radius.unwrap_or(1.0);
        env.insert("R".into(), r);
        let r2 = r * r;
        let s2 = env["θ"].sin().powi(2);
        let mut gamma = HashMap::new();
        let mut checked = 0;
        for line in snapshot(snap) {
            if not_a_derivation(&line) {
                continue;
            }
            if let Some(v) = line.strip_prefix("shooting: q'(0) = (") {
                // The great circle from (1, 0) to (2, 1.5) in unit time (the scene's points):
                // u'(0) = Ω (u1 − cos Ω u0)/sin Ω in the coordinate basis.
                scene_text("geodesic_sphere", "geodesic ds^2 = R^2 dθ^2 + R^2 sin(θ)^2 dφ^2 from (1, 0) to (2, 1.5)");
                let v: Vec<f64> = v.split(')').next().unwrap().split(", ").map(|x| x.parse().unwrap()).collect();
                let unit = |t: f64, p: f64| [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
                let (u0, u1) = (unit(1.0, 0.0), unit(2.0, 1.5));
                let w = u0.iter().zip(&u1).map(|(a, b)| a * b).sum::<f64>().acos();
                let du: Vec<f64> = (0..3).map(|k| w * (u1[k] - w.cos() * u0[k]) / w.sin()).collect();
                let e_th = [1f64.cos(), 0.0, -1f64.sin()];
                let e_ph = [0.0, 1f64.sin(), 0.0];
                let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
                close(v[0], dot(&du, &e_th), "shooting θ'(0)");
                close(v[1], dot(&du, &e_ph) / 1f64.sin().powi(2), "shooting φ'(0)");
                checked += 1;
                continue;
            }
            let (lhs, rhs) = split(&line).unwrap();
            if lhs == "X" {
                let want = "(R sin(θ) cos(φ), R sin(θ) sin(φ), R cos(θ))";
                let scene = std::fs::read_to_string(
                    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples").join("geodesic_sphere.scene"),
                )
                .unwrap();
                assert!(scene.contains(&format!("geodesic embedding {want}")), "the scene's embedding changed");
                assert_eq!(rhs, want, "the embedding as given");
                checked += 1;
                continue;
            }
            let got = at(&parse(&rhs), &env);
            let want = match lhs.as_str() {
                "g[θ,θ]" => r2,
                "g[θ,φ]" => 0.0,
                "g[φ,φ]" => r2 * s2,
                "geodesic_θ" => euler_lagrange_fd(&l, &coords, &env, 0) / r2,
                "geodesic_φ" => euler_lagrange_fd(&l, &coords, &env, 1) / (r2 * s2),
                "p_φ" => partial(&l, &env, "φ'"),
                "h" => energy_function_fd(&l, &coords, &env),
                // Gauss curvature of an orthogonal metric R² (dθ² + G dφ²): K = −(√G)_θθ/(R² √G),
                // here by a second difference of √G = |sin θ|; then R_θφθφ = K det g and the
                // scalar curvature is 2K.
                "K" => gauss_curvature_fd(env["θ"]) / r2,
                "R_θφθφ" => gauss_curvature_fd(env["θ"]) / r2 * r2 * r2 * s2,
                "scalar_curvature" => 2.0 * gauss_curvature_fd(env["θ"]) / r2,
                _ if lhs.starts_with("Γ^") => {
                    gamma.insert(lhs.clone(), got);
                    got
                }
                // X_q · d²x/ds² with the geodesic equations substituted: here the geodesic's
                // q'' solves E(q'') = 0 (E by finite differences, linear in q'' with
                // W = R² diag(1, sin²θ)), and d²x/ds² = Σ X_ij q'_i q'_j + Σ X_k q''_k by hand.
                _ if lhs.starts_with("X_") => {
                    let (t, p, dt, dp) = (env["θ"], env["φ"], env["θ'"], env["φ'"]);
                    let att = env["θ''"] - euler_lagrange_fd(&l, &coords, &env, 0) / r2;
                    let app = env["φ''"] - euler_lagrange_fd(&l, &coords, &env, 1) / (r2 * s2);
                    let (st, ct, sp, cp) = (t.sin(), t.cos(), p.sin(), p.cos());
                    let xt = [r * ct * cp, r * ct * sp, -r * st];
                    let xp = [-r * st * sp, r * st * cp, 0.0];
                    let xtt = [-r * st * cp, -r * st * sp, -r * ct];
                    let xtp = [-r * ct * sp, r * ct * cp, 0.0];
                    let xpp = [-r * st * cp, -r * st * sp, 0.0];
                    let kappa: Vec<f64> = (0..3)
                        .map(|c| {
                            xtt[c] * dt * dt + 2.0 * xtp[c] * dt * dp + xpp[c] * dp * dp + xt[c] * att + xp[c] * app
                        })
                        .collect();
                    let tangent = if lhs.starts_with("X_θ") { xt } else { xp };
                    tangent.iter().zip(&kappa).map(|(a, b)| a * b).sum::<f64>()
                }
                _ => panic!("{snap}: no independent check for `{line}`"),
            };
            close(got, want, &format!("geodesic: {lhs}"));
            checked += 1;
        }
        assert_eq!(checked, expected, "{snap}");
        let (t1, p1) = (env["θ'"], env["φ'"]);
        close(env["θ''"] + gamma["Γ^θ_φφ"] * p1 * p1, euler_lagrange_fd(&l, &coords, &env, 0) / r2, "θ'' + Γ^θ_φφ φ'²");
        close(
            env["φ''"] + 2.0 * gamma["Γ^φ_θφ"] * t1 * p1,
            euler_lagrange_fd(&l, &coords, &env, 1) / (r2 * s2),
            "φ'' + 2 Γ^φ_θφ θ' φ'",
        );
    }
}

/// `K = −(√G)_θθ/√G` for the unit sphere's `G = sin²θ`, by a central second difference.
fn gauss_curvature_fd(theta: f64) -> f64 {
    let root_g = |x: f64| x.sin().abs();
    let second = (root_g(theta + H) - 2.0 * root_g(theta) + root_g(theta - H)) / (H * H);
    -second / root_g(theta)
}

/// `lagrangian discretize` for the pendulum: `L_d` against the rule it names (midpoint
/// `h L((θ_0 + θ_1)/2, (θ_1 − θ_0)/h)`, trapezoid `h (L(θ_0, v) + L(θ_1, v))/2`), and the discrete
/// Euler–Lagrange equation `D₂L_d(θ_0, θ_1) + D₁L_d(θ_1, θ_2)` and the discrete Legendre maps
/// `p_0 = −D₁L_d`, `p_1 = D₂L_d` by finite differences of that rule.
#[test]
fn notes_discrete_lines() {
    let l = parse("1/2 m l^2 θ'^2 - m g l (1 - cos(θ))");
    let mut rng = Rng(91);
    let mut rule = String::new();
    let mut checked = 0;
    for _ in 0..3 {
        let mut env = random_env(&mut rng, &[], &["m", "l", "g", "h"]);
        for k in ["θ_0", "θ_1", "θ_2"] {
            env.insert(k.into(), rng.uniform(-1.5, 1.5));
        }
        for line in snapshot("notes_discrete_pendulum") {
            if let Some(r) = line.strip_prefix("$ ") {
                rule = r.rsplit(' ').next().unwrap().to_string();
                continue;
            }
            if not_a_derivation(&line) {
                continue;
            }
            let ld = |a: f64, b: f64, env: &Env| {
                let h = env["h"];
                let l_at = |x: f64| at(&l, &with(&with(env, "θ", x), "θ'", (b - a) / h));
                match rule.as_str() {
                    "midpoint" => h * l_at((a + b) / 2.0),
                    "trapezoid" => h * (l_at(a) + l_at(b)) / 2.0,
                    r => panic!("unknown rule {r}"),
                }
            };
            let (t0, t1, t2) = (env["θ_0"], env["θ_1"], env["θ_2"]);
            let (lhs, rhs) = split(&line).unwrap();
            let got = at(&parse(&rhs), &env);
            let want = match lhs.as_str() {
                "L_d" => ld(t0, t1, &env),
                "DEL_θ" => d(|x| ld(t0, x, &env), t1) + d(|x| ld(x, t2, &env), t1),
                "p_θ_0" => -d(|x| ld(x, t1, &env), t0),
                "p_θ_1" => d(|x| ld(t0, x, &env), t1),
                _ => panic!("notes_discrete_pendulum: no independent check for `{line}`"),
            };
            close(got, want, &format!("discrete {rule}: {lhs}"));
            checked += 1;
        }
    }
    assert_eq!(checked, 3 * 8);
}

/// The `plain` spelling used above, on the printer's Unicode forms.
#[test]
fn unicode_lines_read_back_in_plain_syntax() {
    assert_eq!(plain("l m (g sin(θ) + l θ̈) = 0"), "l m (g sin(θ) + l θ'') = 0");
    assert_eq!(plain("θ̇2² sin(θ1 - θ2)"), "θ2'^2 sin(θ1 - θ2)");
    // The printer writes dots as combining marks after the letter (U+0307, U+0308).
    assert_eq!(plain("p\u{307}_x = -k x/(x² + y²)^(3/2)"), "p_x' = -k x/(x^2 + y^2)^(3/2)");
    assert_eq!(plain("-k/√(x² + y²)"), "-k/sqrt(x^2 + y^2)");
    assert_eq!(plain("x¹⁰"), "x^10");
}
