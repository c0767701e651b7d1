//! A machine-precision long run: the outer solar system of `examples/outer_solar_system.scene`
//! (Sun and the four giant planets; Hairer, Lubich & Wanner's initial conditions) over 10³
//! Jupiter orbits with the Taylor method and compensated summation. The Hamiltonian, the
//! parameters and the starts are read from the example, so the test and the example cannot
//! drift apart; the energy is evaluated from the stored states by the interpreter
//! (`eval`), not by anything the integrator computed.

use std::collections::HashMap;
use std::path::Path;

use lagrangian::eval::eval;
use lagrangian::mechanics::System;
use lagrangian::simulate::{compile_system, integrate, MethodId, RunOptions, Sampling};
use lagrangian::{parse_with, Declarations};

/// `H`, the parameters, the starts and the end time of the example scene.
struct Scene {
    coords: Vec<String>,
    h: String,
    params: Vec<(String, f64)>,
    starts: HashMap<String, f64>,
    t_end: f64,
}

fn read_example() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/outer_solar_system.scene");
    let text = std::fs::read_to_string(path).expect("the example");
    let line = |prefix: &str| {
        text.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}` line")).to_string()
    };
    let coords = crate::support::scene_names(&line("coordinates "));
    let params = crate::support::scene_parameters(&text);
    let values: HashMap<String, f64> = params.iter().cloned().collect();
    let simulate = line("simulate ");
    let (starts, rest) = simulate.split_once(" for t in 0..").expect("a time span");
    let t_end: f64 = rest.split(' ').next().unwrap().parse().expect("the end time");
    let starts = starts
        .split(", ")
        .map(|s| {
            let (k, v) = s.split_once(" = ").expect("name = value");
            let e = lagrangian::parse(v).expect("a start value");
            (k.to_string(), eval(&e, &values).expect("a number"))
        })
        .collect();
    Scene { coords, h: line("H = "), params, starts, t_end }
}

#[test]
fn outer_solar_system_keeps_its_energy_to_round_off_over_a_thousand_jupiter_orbits() {
    let scene = read_example();
    let coords: Vec<&str> = scene.coords.iter().map(String::as_str).collect();
    let decls = Declarations::new().with_positive(scene.params.iter().map(|(k, _)| k.as_str()));
    let params: Vec<(&str, f64)> = scene.params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let sys = System::from_hamiltonian_with(&scene.h, &coords, &decls).unwrap().with_params(&params).unwrap();
    let h = parse_with(&scene.h, &decls).unwrap();
    let compiled = compile_system(&sys, MethodId::Taylor, &[]).unwrap();
    // The state in the compiled layout, from the named starts.
    let y0: Vec<f64> = compiled.state.iter().map(|name| scene.starts[&name.to_string()]).collect();
    let mut env: HashMap<String, f64> = scene.params.iter().cloned().collect();
    let mut energy = |y: &[f64]| {
        for (name, v) in compiled.state.iter().zip(y) {
            env.insert(name.to_string(), *v);
        }
        eval(&h, &env).unwrap()
    };
    let e0 = energy(&y0);
    let mut opts = RunOptions::new(MethodId::Taylor, 0.0, scene.t_end);
    opts.rtol = Some(1e-16);
    opts.compensated = true;
    opts.sampling = Sampling::Every(1);
    let run = integrate(&compiled, &y0, &opts, &mut |_| {}).unwrap();
    let errors: Vec<(f64, f64)> = run.t.iter().zip(&run.y).map(|(&t, y)| (t, ((energy(y) - e0) / e0).abs())).collect();
    let worst_until = |t: f64| errors.iter().filter(|(s, _)| *s <= t).map(|(_, e)| *e).fold(0.0, f64::max);
    let (tenth, all) = (worst_until(scene.t_end / 10.0), worst_until(scene.t_end));
    // Measured (this tree): 2.9e-15 to 10² orbits, 1.6e-14 to 10³ (15 298 steps), growing
    // like t^0.76 over the last decade: not yet Brouwer's √t (the rounding of the Taylor
    // coefficients themselves is biased; compensated summation of the update changes the
    // figure by 4 %). The bounds are about 3× the measured values, so a loss fails.
    assert!(all <= 5e-14, "relative energy error {all:.3e} over 10³ Jupiter orbits");
    let exponent = (all / tenth).log10();
    assert!(exponent < 1.0, "error grew by t^{exponent:.2} from 100 to 1000 orbits: a linear drift");
}
