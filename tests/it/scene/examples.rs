//! Every scene in `examples/` runs, and its outputs are checked: the printed derivations are
//! snapshotted and compared with the hand forms of PHYSICS.md; numbers are checked against
//! closed forms or conserved quantities computed here independently; plot files are valid
//! SVG.

use crate::support;

use std::collections::HashMap;
use std::path::Path;

use lagrangian::algebra::expand;
use lagrangian::{parse_with, Declarations, Expr};
use support::example as run;

/// `a − b` expands to zero: the printed form equals the hand form.
fn same(printed: &Expr, hand: &str, decls: &Declarations) {
    let hand = parse_with(hand, decls).unwrap();
    let diff = expand(&printed.minus(&hand)).unwrap();
    assert!(diff.is_zero(), "{printed} differs from {hand} by {diff}");
}

fn max_rel_drift(v: &[f64]) -> f64 {
    v.iter().map(|x| ((x - v[0]) / v[0]).abs()).fold(0.0, f64::max)
}

#[test]
fn pendulum() {
    let r = run("pendulum");
    let d = Declarations::new().with_positive(["m", "l", "g"]);
    // (3.20), through the plain form of the JSON-free printout: reprint in plain below.
    let h = r.line("H = ");
    assert_eq!(h, "g l m (1 - cos(θ)) + p_θ²/(2 l² m)");
    same(&parse_with("g l m (1 - cos(θ)) + p_θ^2/(2 l^2 m)", &d).unwrap(), "p_θ^2/(2 m l^2) + m g l (1 - cos(θ))", &d);
    // (2.28): E_θ = m l² θ'' + m g l sin θ.
    assert_eq!(r.line("E_θ: "), "l m (g sin(θ) + l θ̈) = 0");
    let c = r.csv("pendulum.csv");
    // Gauss–Legendre conserves H to rounding-level drift; started from rest at θ = 3, the
    // energy is m g l (1 − cos 3) = 9.81 (1 − cos 3) (by hand).
    let e0 = 9.81 * (1.0 - 3f64.cos());
    assert!((c["H"][0] - e0).abs() < 1e-12);
    assert!(max_rel_drift(&c["H"]) < 1e-12, "{}", max_rel_drift(&c["H"]));
    // A libration: |θ| never exceeds its start.
    assert!(c["θ"].iter().all(|x| x.abs() <= 3.0 + 1e-9));
    let svg = r.svg("pendulum_phase.svg");
    assert!(svg.contains(">\nseparatrix\n</text>") && svg.contains(">\nO\n</text>"));
    r.svg("pendulum_energy.svg");
}

#[test]
fn central_potential() {
    let r = run("central_potential");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(r.out.join("central_potential.json")).unwrap()).unwrap();
    let d = Declarations::new().with_positive(["m"]).with_functions(["V"]);
    let get = |i: usize, j: usize| parse_with(json[i]["value"][j]["lhs"].as_str().unwrap(), &d).unwrap();
    // (2.37) and the φ equation d/dt(m r² φ') = 0.
    same(&get(0, 0), "m r'' - m r φ'^2 + V'(r)", &d);
    same(&get(0, 1), "m r^2 φ'' + 2 m r r' φ'", &d);
    // (3.29).
    same(&parse_with(json[1]["value"].as_str().unwrap(), &d).unwrap(), "p_r^2/(2 m) + p_φ^2/(2 m r^2) + V(r)", &d);
    // (2.35): p_φ = m r² φ' is conserved.
    assert_eq!(json[2]["value"][0]["lhs"], "p_φ");
    same(&parse_with(json[2]["value"][0]["rhs"].as_str().unwrap(), &d).unwrap(), "m r^2 φ'", &d);
}

#[test]
fn atwood() {
    let r = run("atwood");
    assert_eq!(r.line("E_x: "), "g (m1 - m2) + x\u{308} (m1 + m2) = 0");
    // (2.41): constant acceleration a = −(m1 − m2) g/(m1 + m2) = −2·9.81/4; RK4 is exact
    // for a quadratic x(t) = a t²/2.
    let c = r.csv("atwood.csv");
    let a = -2.0 * 9.81 / 4.0;
    for (t, x) in c["t"].iter().zip(&c["x"]) {
        assert!((x - 0.5 * a * t * t).abs() < 1e-12, "t = {t}: {x}");
    }
}

#[test]
fn charged_particle() {
    let r = run("charged_particle");
    // (3.22): |p − e A|²/(2m) + e φ with A = B/2 (−y, x, 0), φ = E z.
    let d = Declarations::new();
    let h = r.line("H = ");
    assert_eq!(h, "E e z + p_z²/(2 m) + (p_x + B e y/2)²/(2 m) + (p_y - B e x/2)²/(2 m)");
    same(
        &parse_with("E e z + p_z^2/(2 m) + (p_x + B e y/2)^2/(2 m) + (p_y - B e x/2)^2/(2 m)", &d).unwrap(),
        "((p_x + e B y/2)^2 + (p_y - e B x/2)^2 + p_z^2)/(2 m) + e E z",
        &d,
    );
    // Gyration about the z axis with radius v/ω = 2/2 = 1 (ω = eB/m = 2); z accelerates
    // uniformly: z = −(eE/m) t²/2 (by hand).
    let c = r.csv("charged_particle.csv");
    for (i, &t) in c["t"].iter().enumerate() {
        let (x, y, z) = (c["x"][i], c["y"][i], c["z"][i]);
        assert!((x * x + y * y - 1.0).abs() < 1e-13, "radius at t = {t}");
        assert!((z + 0.05 * t * t).abs() < 1e-12, "z at t = {t}");
    }
    // The scene's comment says so: uniform acceleration, z(10) = −5, no drift promised.
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/charged_particle.scene")).unwrap();
    assert!(text.contains("z = −e E t²/(2 m) = −0.05 t², so z(10) = −5") && !text.contains("uniform drift"));
    let (t_end, z_end) = (*c["t"].last().unwrap(), *c["z"].last().unwrap());
    assert!((t_end - 10.0).abs() < 1e-9 && (z_end + 5.0).abs() < 1e-12, "z({t_end}) = {z_end}");
    r.svg("charged_particle_path.svg");
    r.svg("charged_particle_series.svg");
}

#[test]
fn double_pendulum() {
    let r = run("double_pendulum");
    let c = r.csv("double_pendulum.csv");
    // Energy T + V, written out by hand for m1 = m2 = l1 = l2 = 1, g = 9.81.
    let g = 9.81;
    let energy: Vec<f64> = (0..c["t"].len())
        .map(|i| {
            let (a, b, u, v) = (c["θ1"][i], c["θ2"][i], c["θ1'"][i], c["θ2'"][i]);
            u * u + 0.5 * v * v + u * v * (a - b).cos() - 2.0 * g * a.cos() - g * b.cos()
        })
        .collect();
    // Run `a` is gauss6 with dt = 0.004 (one fixed grid for `plot separation a, b`): a
    // symplectic method's energy error oscillates, measured at 3.7e-10; about 10× that.
    assert!(max_rel_drift(&energy) < 4e-9, "{}", max_rel_drift(&energy));
    // The reference state at t = 10 (shared/reference/double_pendulum.md). The motion
    // amplifies errors by ~1e8, so a run at this accuracy is only expected to be near it
    // (largest difference measured: 1.9e-4, in θ1').
    let last = c["t"].len() - 1;
    assert_eq!(c["t"][last], 10.0);
    let reference = [-0.7531288742949114, 1.627933082053704, -4.087368851344197, -8.869702578387533];
    for (k, want) in ["θ1", "θ2", "θ1'", "θ2'"].iter().zip(reference) {
        assert!((c[*k][last] - want).abs() < 1e-3, "{k}: {} vs {want}", c[*k][last]);
    }
    r.svg("double_pendulum_chaos.svg");
    r.svg("double_pendulum_path.svg");
    r.svg("double_pendulum_energy.svg");
}

#[test]
fn kepler() {
    let r = run("kepler");
    let sym = r.csv("kepler_symplectic.csv");
    let rk4 = r.csv("kepler_rk4.csv");
    // E = −k/(2a) = −1/2 for a = 1 (by hand, from the initial state).
    assert!((sym["H"][0] + 0.5).abs() < 1e-12);
    let err = |c: &HashMap<String, Vec<f64>>, t0: f64, t1: f64| {
        c["t"]
            .iter()
            .zip(&c["H"])
            .filter(|(t, _)| **t >= t0 && **t <= t1)
            .map(|(_, h)| (h + 0.5).abs())
            .fold(0.0, f64::max)
    };
    // Symplectic: bounded (no larger late than early). RK4: drifts (grows with time).
    assert!(err(&sym, 500.0, 1000.0) < 1.5 * err(&sym, 0.0, 500.0));
    assert!(err(&rk4, 900.0, 1000.0) > 5.0 * err(&rk4, 0.0, 100.0));
    r.svg("kepler_energy.svg");
    r.svg("kepler_orbit.svg");
    // The work-precision diagram: one marked line per method, three runs each.
    let wp = r.svg("kepler_work_precision.svg");
    for method in ["leapfrog", "yoshida4", "rk4"] {
        assert!(wp.lines().any(|l| l.trim() == method), "no `{method}` series");
    }
    assert_eq!(wp.matches("<circle").count(), 9);
}

#[test]
fn henon_heiles() {
    let r = run("henon_heiles");
    let c = r.csv("henon_heiles.csv");
    // E = 1/8 by construction of p_x.
    assert!((c["H"][0] - 0.125).abs() < 1e-14);
    assert!(max_rel_drift(&c["H"]) < 1e-12);
    let svg = r.svg("henon_heiles_section.svg");
    // One point per upward crossing of x = 0: about one per period 2π over t = 1000.
    let points = svg.matches("<circle").count();
    assert!((120..200).contains(&points), "{points} section points");
}

#[test]
fn oscillator_action_angle() {
    let r = run("oscillator_action_angle");
    // {Q, J} = 1 (canonical), {J, H} = 0, {Q, H} = ω: by hand from Q = atan(mωq/p), J = H/ω.
    assert_eq!(r.line("{Q, J} = "), "1");
    assert_eq!(r.line("{J, H} = "), "0");
    assert_eq!(r.line("{Q, H} = "), "ω");
    // F1 = ½ m ω q² cot Q (PHYSICS.md §4): q = sqrt(2P/(mω)) sin Q, p = sqrt(2mωP) cos Q,
    // K = ω P. Compared at arbitrary values.
    let d = Declarations::new().with_positive(["m", "ω"]);
    let at = |e: &str| {
        let e = parse_with(e, &d).unwrap();
        lagrangian::eval::eval_with(&e, &|s: &lagrangian::Symbol| {
            Some(match s.name() {
                "m" => 2.0,
                "ω" => 3.0,
                "P" => 0.7,
                "Q" => 0.4,
                _ => return None,
            })
        })
        .unwrap()
    };
    // The inverse map is the second `p_q` line (after the relation p = ∂F1/∂q).
    let inverse_p = r.stdout.lines().filter_map(|l| l.strip_prefix("  p_q = ")).nth(1).expect("the inverse p_q");
    assert!((at(&r.line("  q = ")) - at("sqrt(2 P/(m ω)) sin(Q)")).abs() < 1e-14);
    assert!((at(inverse_p) - at("sqrt(2 m ω P) cos(Q)")).abs() < 1e-14);
    assert_eq!(parse_with(&r.line("K = "), &d).unwrap(), parse_with("ω P", &d).unwrap());
    let c = r.csv("oscillator.csv");
    // J = E/ω = (½ m ω² q0²)/ω = ½·2·3·1 = 3.
    assert!((c["J"][0] - 3.0).abs() < 1e-12);
    assert!(max_rel_drift(&c["J"]) < 1e-6);
    r.svg("oscillator_phase.svg");
}

#[test]
fn adiabatic_oscillator() {
    let r = run("adiabatic_oscillator");
    let c = r.csv("adiabatic_oscillator.csv");
    let n = c["t"].len() - 1;
    // ω doubles over t = 100; the energy follows ω (E ∝ ω while J = E/ω is invariant).
    // J is invariant only to O(ε) = O(0.01) — physics, not integration error (measured
    // 1.2e-3) — so these bounds cannot be tightened to the integrator's accuracy.
    let (h0, h1, j0, j1) = (c["H"][0], c["H"][n], c["J"][0], c["J"][n]);
    assert!((j1 / j0 - 1.0).abs() < 0.01, "J changed by {}", j1 / j0);
    assert!((h1 / h0 - 2.0).abs() < 0.02, "H ratio {}", h1 / h0);
    r.svg("adiabatic_oscillator.svg");
}

#[test]
fn anharmonic_oscillator() {
    let r = run("anharmonic_oscillator");
    // The averaged relations (PHYSICS.md §2.8.2): C = 0 solves ∂⟨L⟩/∂C = 0, and with
    // B = C = 0, ∂⟨L⟩/∂A = 0 holds at ω² = ω0² (1 + 3/2 σ A²) (by hand from ⟨L⟩ =
    // m l0² A² (ω² − ω0²)/4 − 3 m l0² ω0² σ A⁴/16). Checked at arbitrary values.
    let d = Declarations::new().with_positive(["m", "ω0", "σ", "l0"]);
    let rel = |a: &str| parse_with(r.line(&format!("∂⟨L⟩/∂{a} = ")).trim_end_matches(" = 0"), &d).unwrap();
    let (ra, rc) = (rel("A"), rel("C"));
    let values = |amp: f64, b: f64, c: f64, w: f64| {
        move |s: &lagrangian::Symbol| -> Option<f64> {
            Some(match s.name() {
                "A" => amp,
                "B" => b,
                "C" => c,
                "ω" => w,
                "ω0" => 1.3,
                "σ" => 0.2,
                "l0" => 0.7,
                "m" => 1.9,
                _ => return None,
            })
        }
    };
    let eval = |e: &Expr, f: &dyn Fn(&lagrangian::Symbol) -> Option<f64>| lagrangian::eval::eval_with(e, f).unwrap();
    assert!(eval(&rc, &values(0.8, 0.3, 0.0, 1.1)).abs() < 1e-14);
    let w = (1.3f64 * 1.3 * (1.0 + 1.5 * 0.2 * 0.8 * 0.8)).sqrt();
    assert!(eval(&ra, &values(0.8, 0.0, 0.0, w)).abs() < 1e-13);
    assert!(eval(&ra, &values(0.8, 0.0, 0.0, 1.3)).abs() > 1e-3, "the linear frequency must not solve it");
    let c = r.csv("anharmonic.csv");
    assert!(max_rel_drift(&c["H"]) < 1e-12);
    // The period from downward zero crossings of x, against the quadrature
    // T = 4 ∫₀^{π/2} A cos u du / sqrt(2 (V(A) − V(A sin u))), V = (x² + σ x⁴)/2, A = 1, σ = 0.1.
    let v = |x: f64| 0.5 * (x * x + 0.1 * x.powi(4));
    let n = 20_000;
    let h = std::f64::consts::FRAC_PI_2 / n as f64;
    let f = |u: f64| u.cos() / (2.0 * (v(1.0) - v(u.sin()))).sqrt();
    // Midpoint rule: the integrand is finite at u = π/2 (limit 1/sqrt(V'(A)·A)).
    let period = 4.0 * (0..n).map(|i| f((i as f64 + 0.5) * h) * h).sum::<f64>();
    let (t, x) = (&c["t"], &c["x"]);
    let crossings: Vec<f64> = (1..t.len())
        .filter(|&i| x[i - 1] > 0.0 && x[i] <= 0.0)
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * x[i - 1] / (x[i - 1] - x[i]))
        .collect();
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    assert!((measured / period - 1.0).abs() < 1e-9, "{measured} vs {period}");
    // The averaged-Lagrangian estimate ω ≈ ω0 (1 + 3σA²/4) (the force is x + 2σx³) is within
    // its O(σ²) error.
    assert!((2.0 * std::f64::consts::PI / period / 1.075 - 1.0).abs() < 5e-3);
    // The scene's comment states the frequency 2π/period to four decimals, and the period.
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/anharmonic_oscillator.scene"))
            .unwrap();
    let at = text.find("period 2π/").expect("the comment states the period") + "period 2π/".len();
    let numbers: Vec<f64> = text[at..]
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter(|w| !w.is_empty())
        .take(2)
        .map(|w| w.parse().unwrap())
        .collect();
    assert!((numbers[0] - 2.0 * std::f64::consts::PI / measured).abs() < 5e-5, "{numbers:?} vs {measured}");
    assert!((numbers[1] - measured).abs() < 5e-4, "{numbers:?} vs {measured}");
    r.svg("anharmonic_phase.svg");
}

/// The damped, driven pendulum: the stroboscopic section has one point per drive period
/// (t = 3π k), the exported points are the plotted ones, and the first point agrees with a
/// hand-written RK4 integration of θ'' = −b θ' − sin θ + A cos(Ω t) (before chaos separates
/// nearby solutions).
#[test]
fn damped_driven_pendulum() {
    let r = run("damped_driven_pendulum");
    let svg = r.svg("damped_driven_section.svg");
    let c = r.csv("damped_driven_section.csv");
    let (t, wrapped, v) = (&c["t"], &c["wrapped"], &c["θ'"]);
    let period = 3.0 * std::f64::consts::PI;
    assert_eq!(t.len(), (9000.0 / period) as usize);
    for (k, tk) in t.iter().enumerate() {
        assert!((tk - period * (k + 1) as f64).abs() < 1e-9, "point {k} at t = {tk}");
    }
    assert!(wrapped.iter().all(|w| w.abs() <= std::f64::consts::PI));
    assert_eq!(svg.matches("<circle").count(), t.len(), "plotted and exported points differ in number");
    assert!(r.stdout.contains(&format!("({} points)", t.len())));
    let (b, a, w) = (0.5f64, 1.5f64, 2.0f64 / 3.0);
    let f = |t: f64, y: [f64; 2]| [y[1], -b * y[1] - y[0].sin() + a * (w * t).cos()];
    let (mut y, steps) = ([0.2f64, 0.0], 20_000);
    let h = period / steps as f64;
    for i in 0..steps {
        let t0 = i as f64 * h;
        let k1 = f(t0, y);
        let k2 = f(t0 + h / 2.0, [y[0] + h / 2.0 * k1[0], y[1] + h / 2.0 * k1[1]]);
        let k3 = f(t0 + h / 2.0, [y[0] + h / 2.0 * k2[0], y[1] + h / 2.0 * k2[1]]);
        let k4 = f(t0 + h, [y[0] + h * k3[0], y[1] + h * k3[1]]);
        y = [
            y[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            y[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        ];
    }
    let theta = y[0].sin().atan2(y[0].cos());
    assert!((wrapped[0] - theta).abs() < 5e-9 && (v[0] - y[1]).abs() < 5e-9, "({}, {}) vs {y:?}", wrapped[0], v[0]);
}

/// The outer solar system, written with indexed sums (`tests/it/parse/indexed.rs` checks that
/// it reads as the written-out Hamiltonian and integrates to the same numbers): over 10³
/// Jupiter orbits its relative energy error, computed here by hand from the exported states
/// (`Σ |p|²/2m − G Σ m_i m_j / r_ij`), stays near round-off (measured 1.7e-14; see
/// `taylor::solar_system` for the compensated library run).
#[test]
fn outer_solar_system() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let committed = std::fs::read_to_string(root.join("examples/outer_solar_system.scene")).unwrap();
    let r = run("outer_solar_system");
    r.svg("outer_solar_system_energy.svg");
    let c = r.csv("outer_solar_system.csv");
    let params: HashMap<String, f64> = crate::support::scene_parameters(&committed).into_iter().collect();
    let m: Vec<f64> = (0..5).map(|k| params[&format!("m{k}")]).collect();
    let energy = |row: usize| {
        let at = |name: String| c[&name][row];
        let mut e = 0.0;
        for i in 0..5 {
            e += (0..3).map(|a| at(format!("p_{}{i}", ["x", "y", "z"][a])).powi(2)).sum::<f64>() / (2.0 * m[i]);
            for j in i + 1..5 {
                let r2: f64 =
                    ["x", "y", "z"].iter().map(|a| (at(format!("{a}{i}")) - at(format!("{a}{j}"))).powi(2)).sum();
                e -= params["G"] * m[i] * m[j] / r2.sqrt();
            }
        }
        e
    };
    let rows = c["t"].len();
    let e0 = energy(0);
    let worst = (0..rows).map(|k| ((energy(k) - e0) / e0).abs()).fold(0.0, f64::max);
    assert!(c["t"][rows - 1] >= 1000.0 * 4332.0, "the run spans 10³ Jupiter orbits");
    assert!(worst <= 5e-14, "relative energy error {worst:.3e}");
}

/// `examples/difference_maps.scene` (§4.7.2), the last states against closed forms for
/// h = 0.3 after n = 40 steps from (1, 0): forward Euler multiplies z = q + i p by 1 − i h per
/// step, so |z| = (1 + h²)^(n/2) and arg z = −n atan h; symplectic Euler keeps
/// q² + p² − h q p = 1; the implicit midpoint rule is the rotation by 40 · 2 atan(h/2).
#[test]
fn difference_maps() {
    let r = run("difference_maps");
    let last = |k: usize| -> (f64, f64) {
        let line = r.stdout.lines().filter(|l| l.starts_with("  (1, 0) → (")).nth(k).unwrap();
        let v = crate::support::map_last_state(line);
        (v[0], v[1])
    };
    let (h, n) = (0.3f64, 40.0);
    let (q, p) = last(0);
    let radius = (1.0 + h * h).powf(n / 2.0);
    let angle = -n * h.atan();
    assert!((q - radius * angle.cos()).abs() < 1e-12 && (p - radius * angle.sin()).abs() < 1e-12, "{q} {p}");
    let (q, p) = last(1);
    assert!((q * q + p * p - h * q * p - 1.0).abs() < 1e-13, "symplectic Euler's invariant: {q} {p}");
    assert!((q * q + p * p - 1.0).abs() > 0.1, "not the circle");
    let (q, p) = last(2);
    let a = n * 2.0 * (h / 2.0).atan();
    assert!((q - a.cos()).abs() < 1e-12 && (p + a.sin()).abs() < 1e-12, "{q} {p}");
    assert!(r.stdout.matches("implicit (Newton's method per step)").count() == 3, "{}", r.stdout);
    for f in ["forward_euler.svg", "symplectic_euler.svg", "implicit_midpoint.svg", "midpoint_pendulum.svg"] {
        r.svg(f);
    }
}

/// `examples/anharmonic_relations.scene` (§2.8.2): the printed series is the second-order one of
/// `scripts/average_series_sympy.py`, and the hard spring's relations at A = 1 give
/// ω = 1.5943146199509888, B = 0.026489365310534100 (SymPy's nsolve, same script), printed to
/// six decimals; both figures are written.
#[test]
fn anharmonic_relations() {
    let r = run("anharmonic_relations");
    assert!(r.stdout.contains("  ω = ω0 + 3 A² σ ω0/4 - 15 A⁴ σ² ω0/64\n"), "{}", r.stdout);
    assert!(r.stdout.contains("  ω = ω0 - 3 A² σ ω0/4 - 15 A⁴ σ² ω0/64\n"), "{}", r.stdout);
    assert!(r.stdout.contains("  A = 1: ω = 1.594315 (series 1.515625), B = 0.026489, C = 0\n"), "{}", r.stdout);
    r.svg("anharmonic_hard.svg");
    r.svg("anharmonic_soft.svg");
}

/// The rolling coin under its velocity constraints, against SymPy's KanesMethod integrated by
/// scipy's solve_ivp (scripts/nonholonomic_simulate_sympy.py; the same numbers as
/// tests/it/simulate/nonholonomic.rs).
#[test]
#[allow(clippy::excessive_precision, clippy::needless_range_loop)] // the script's digits, as printed
fn rolling_coin() {
    let r = run("rolling_coin");
    let c = r.csv("rolling_coin.csv");
    let reference = [
        ("x", 5.820_789_944_819_793_1e-1),
        ("y", -2.909_737_286_459_251_2),
        ("θ", 8.899_999_999_999_998_6),
        ("φ", -6.075_042_467_565_174),
        ("x'", 4.132_336_236_547_359_3e-1),
        ("y'", -2.392_306_920_609_817_4e-1),
        ("θ'", 8.000_000_000_000_000_4e-1),
        ("φ'", -9.549_729_875_610_099e-1),
    ];
    for (name, want) in reference {
        let got = *c[name].last().unwrap();
        assert!((got - want).abs() < 1e-8, "{name}(10) = {got}, KanesMethod {want}");
    }
    // Rolling does no work: ½ m (x'² + y'²) + ½ I θ'² + ½ J φ'² + ½ k x² stays 1.553 (by hand
    // at the start), and the constraints hold to rounding at every kept state.
    for i in 0..c["t"].len() {
        let e = 0.5 * 2.0 * (c["x'"][i].powi(2) + c["y'"][i].powi(2))
            + 0.5 * 0.7 * c["θ'"][i].powi(2)
            + 0.5 * 1.3 * c["φ'"][i].powi(2)
            + 0.5 * 3.0 * c["x"][i].powi(2);
        assert!((e - 1.553).abs() < 1e-9, "energy {e} at t = {}", c["t"][i]);
        assert!(c["residual1"][i].abs() < 1e-14 && c["residual2"][i].abs() < 1e-14);
    }
    // The multipliers at the start: scripts/nonholonomic_sympy.py (LagrangesMethod).
    assert!((c["μ1"][0] - 1.760_528_029_587_700_2).abs() < 1e-10);
    r.svg("rolling_coin_path.svg");
}

/// The notes' ecliptic (§1.6.2) as `examples/ecliptic.scene`: held by the velocity constraint
/// `y z' − z y' = 0` against the field out of the plane, the orbit is the circle of the planar
/// problem, x = sin t, y = 3 − cos t (the closed form of the reduced coordinates x, y: radius 1,
/// speed 1 = sqrt(k/(m r))), and the multiplier balances the field, μ1 y = m g = 0.5 (by hand).
#[test]
#[allow(clippy::needless_range_loop)] // one row of several columns per step
fn ecliptic() {
    let r = run("ecliptic");
    let c = r.csv("ecliptic.csv");
    assert!(c["t"].len() > 100 && (c["t"].last().unwrap() - 20.0).abs() < 1e-12);
    for i in 0..c["t"].len() {
        let t = c["t"][i];
        assert!(
            (c["x"][i] - t.sin()).abs() < 1e-9 && (c["y"][i] - (3.0 - t.cos())).abs() < 1e-9,
            "off the circle at t = {t}"
        );
        assert!(c["z"][i].abs() < 1e-14 && c["z'"][i].abs() < 1e-14, "z = {} at t = {t}", c["z"][i]);
        assert!((c["μ1"][i] * c["y"][i] - 0.5).abs() < 1e-9, "μ1 y = {} at t = {t}", c["μ1"][i] * c["y"][i]);
        assert!(c["residual1"][i].abs() < 1e-14);
    }
    r.svg("ecliptic_path.svg");
}
