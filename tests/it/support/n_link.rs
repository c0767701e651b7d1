//! The planar n-link pendulum as a user (or SymPy's `LagrangesMethod`) writes it: Cartesian bob
//! velocities in terms of the absolute angles, `½ Σ_k m_k |r_k'|² − Σ_k m_k g y_k` with
//! `r_k = Σ_{i≤k} l_i (sin θ_i, −cos θ_i)`, distinct masses and lengths. Shared by the mechanics
//! tests, the mechanics, pipeline and Taylor benchmarks and the profiling example, so all of
//! them measure one system.
#![allow(dead_code)]

use lagrangian::mechanics::System;
use lagrangian::Declarations;

/// The Lagrangian's text, the coordinates `θ1…θn` and the symbols declared positive
/// (`m1…mn`, `l1…ln`, `g`).
pub fn n_link(n: usize) -> (String, Vec<String>, Vec<String>) {
    let mut terms = Vec::new();
    for k in 1..=n {
        let xs: Vec<String> = (1..=k).map(|i| format!("l{i} cos(θ{i}) θ{i}'")).collect();
        let ys: Vec<String> = (1..=k).map(|i| format!("l{i} sin(θ{i}) θ{i}'")).collect();
        let hs: Vec<String> = (1..=k).map(|i| format!("l{i} cos(θ{i})")).collect();
        terms.push(format!("1/2 m{k} (({})^2 + ({})^2) + m{k} g ({})", xs.join(" + "), ys.join(" + "), hs.join(" + ")));
    }
    let coords = (1..=n).map(|i| format!("θ{i}")).collect();
    let mut positive: Vec<String> = (1..=n).flat_map(|i| [format!("m{i}"), format!("l{i}")]).collect();
    positive.push("g".into());
    (terms.join(" + "), coords, positive)
}

/// The n-link pendulum as a [`System`], its masses, lengths and `g` symbolic (declared positive).
pub fn n_link_system(n: usize) -> System {
    let (l, coords, positive) = n_link(n);
    let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
    let d = Declarations::new().with_positive(positive.iter().map(String::as_str));
    System::from_lagrangian_with(&l, &coords, &d).expect("valid Lagrangian")
}

/// The n-link pendulum with unit masses and lengths and `g = 9.81`.
pub fn unit_n_link_system(n: usize) -> System {
    let mut params: Vec<(String, f64)> =
        (1..=n).flat_map(|i| [(format!("m{i}"), 1.0), (format!("l{i}"), 1.0)]).collect();
    params.push(("g".into(), 9.81));
    let refs: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    n_link_system(n).with_params(&refs).expect("valid parameters")
}
