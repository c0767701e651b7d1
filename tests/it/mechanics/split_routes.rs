//! `System::mass_matrix_split` against the plain route. `W q'' − F` must equal the raw
//! Euler–Lagrange expression `d/dt ∂L/∂q' − ∂L/∂q − Q + ∂R/∂q'` (plain memoised
//! differentiation, no polynomial form, no tidying) at random states and random accelerations.
//! Lagrangians quadratic in the velocities take the Christoffel route in `mass_matrix_split`,
//! the others (relativistic) the general one; both are checked here so neither can drift.

use crate::support::mechanics as mechanics_support;

use std::collections::BTreeSet;

use lagrangian::diff::Differentiator;
use lagrangian::expr::Expr;
use lagrangian::mechanics::System;
use mechanics_support::{random_env, system, value, Rng};

/// The n-link pendulum as a user writes it (`mechanics_support::n_link`).
fn n_link(n: usize) -> System {
    let (l, coords, positive) = mechanics_support::n_link::n_link(n);
    let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
    let positive: Vec<&str> = positive.iter().map(String::as_str).collect();
    system(&l, &coords, &positive, &[])
}

/// The raw left-hand sides `d/dt ∂L/∂q'_i − ∂L/∂q_i − Q_i + ∂R/∂q'_i`, untidied.
fn raw_equations(s: &System) -> Vec<Expr> {
    let l = s.lagrangian().expect("a Lagrangian");
    let names: BTreeSet<String> = s.coordinates().iter().map(|q| q.name().to_string()).collect();
    let mut d = Differentiator::new();
    (0..s.coordinates().len())
        .map(|i| {
            let (q, v) = (&s.coordinates()[i], &s.velocities()[i]);
            let p = d.diff(l, v);
            let mut e = d.dt(&p, &names).minus(&d.diff(l, q)).minus(&s.forces()[i]);
            if let Some(r) = s.rayleigh() {
                e = e.plus(&d.diff(r, v));
            }
            e
        })
        .collect()
}

/// Checks `Σ_j W_ij q''_j − F_i = raw_i` at `samples` random states.
fn check(s: &System, what: &str, overrides: &[(&str, f64)], slow_velocities: bool) {
    let (w, f) = s.mass_matrix_split().expect("W, F");
    let raw = raw_equations(s);
    let n = raw.len();
    let acc = s.accelerations_symbols();
    let mut rng = Rng::new(17 + n as u64);
    for sample in 0..4 {
        let mut exprs: Vec<&Expr> = raw.iter().chain(&f).collect();
        exprs.extend(w.iter().flatten());
        let mut env = random_env(&exprs, &mut rng, overrides);
        for (v, a) in s.velocities().iter().zip(&acc) {
            // Signed velocities and accelerations; below 1 (and c = 3) for the relativistic case.
            let speed = if slow_velocities { 1.0 } else { 2.0 };
            env.insert(v.to_string(), rng.range(-speed, speed));
            env.insert(a.to_string(), rng.range(-2.0, 2.0));
        }
        for q in s.coordinates() {
            env.insert(q.to_string(), rng.range(-3.0, 3.0));
        }
        for i in 0..n {
            let lhs: f64 =
                (0..n).map(|j| value(&w[i][j], &env) * env[&acc[j].to_string()]).sum::<f64>() - value(&f[i], &env);
            let rhs = value(&raw[i], &env);
            assert!(
                (lhs - rhs).abs() <= 1e-9 * (1.0 + lhs.abs() + rhs.abs()),
                "{what}, sample {sample}, equation {i}: W q'' − F = {lhs} but the raw Euler–Lagrange expression = {rhs}\nW = {w:?}\nF = {f:?}"
            );
        }
    }
}

#[test]
fn n_link_pendulums_match_plain_differentiation() {
    for n in 1..=6 {
        let s = n_link(n);
        check(&s, &format!("{n}-link pendulum"), &[], false);
        // W is symmetric.
        let (w, _) = s.mass_matrix_split().unwrap();
        for (i, row) in w.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                assert_eq!(*x, w[j][i], "W[{i}][{j}] of the {n}-link pendulum");
            }
        }
    }
}

#[test]
fn non_natural_lagrangians_match_plain_differentiation() {
    // ((L, coordinates, positive, functions), overrides, slow velocities)
    type Case = (&'static str, &'static [&'static str], &'static [&'static str], &'static [&'static str]);
    type Overrides = &'static [(&'static str, f64)];
    let cases: &[(Case, Overrides, bool)] = &[
        // Relativistic: not quadratic in the velocities, the general route.
        (("-m c^2 sqrt(1 - (x'^2 + y'^2)/c^2) - k (x^2 + y^2)", &["x", "y"], &["m", "c"], &[]), &[("c", 3.0)], true),
        // Magnetic b·q' with a position-dependent vector potential and a scalar potential.
        (("1/2 m (x'^2 + y'^2) + e (A(x, y) x' + x^2 y y') - e φ(x, y)", &["x", "y"], &["m"], &["A", "φ"]), &[], false),
        // Explicit time dependence in W, in b and in L0.
        (
            ("1/2 m exp(γ t) (x'^2 + x^2 y'^2) + t x x' + sin(ω t) y y' - k cos(t) x^2 y", &["x", "y"], &["m"], &[]),
            &[],
            false,
        ),
        // A rotating frame: b linear in the coordinates.
        (("1/2 m ((x' - Ω y)^2 + (y' + Ω x)^2) - V(x, y)", &["x", "y"], &["m"], &["V"]), &[], false),
        // A velocity inside a function: the general route.
        (("1/2 m x'^2 + log(1 + x'^2 y^2) - y^2 + 1/2 y'^2", &["x", "y"], &["m"], &[]), &[], true),
    ];
    for ((l, coords, positive, functions), overrides, slow) in cases {
        check(&system(l, coords, positive, functions), l, overrides, *slow);
    }
}

#[test]
fn forces_and_dissipation_on_both_routes() {
    let natural = system("1/2 m (r'^2 + r^2 φ'^2) - V(r)", &["r", "φ"], &["m"], &["V"])
        .with_force("φ", "τ cos(ω t) r")
        .unwrap()
        .with_rayleigh("1/2 b r'^2 + 1/2 c r^2 φ'^2 + r' φ'")
        .unwrap();
    check(&natural, "damped, driven polar particle", &[], false);
    let relativistic = system("-m c^2 sqrt(1 - x'^2/c^2)", &["x"], &["m", "c"], &[])
        .with_force("x", "F0 sin(ω t)")
        .unwrap()
        .with_rayleigh("1/2 b x'^2")
        .unwrap();
    check(&relativistic, "damped, driven relativistic particle", &[("c", 3.0)], true);
}
