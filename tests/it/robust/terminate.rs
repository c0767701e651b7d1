//! Every method terminates: extreme settings — a tolerance below f64's
//! reach, a step of 1e-300, a time span of 1e300 — end each method quickly with a typed
//! failure that names the time, the state and the reason, or a refusal before the first
//! step. Each case runs on its own thread under a timeout, so a regression fails the test
//! instead of hanging CI. Through the library and through `lagrangian run`.

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use lagrangian::integrate::problems::Oscillator;
use lagrangian::integrate::{
    Dop853, ExplicitRk, FailureReason, Gauss, Integrate, IntegrateError, Options, Splitting, Trajectory,
};

/// Runs `f` on a thread and fails the test if it has not returned after `limit`.
fn within<T: Send + 'static>(limit: Duration, what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(limit).unwrap_or_else(|_| panic!("{what} did not finish within {limit:?}"))
}

const LIMIT: Duration = Duration::from_secs(20);

/// The oscillator `x'' = −x` as a separable system and as a right-hand side.
fn osc() -> Oscillator {
    Oscillator { omega: 1.0 }
}

type Run = Box<dyn Fn(std::ops::Range<f64>, Options<'static>) -> Result<Trajectory, IntegrateError> + Send>;

/// Every fixed-step method with step `h`, by name.
fn fixed_step_methods(h: f64) -> Vec<(&'static str, Run)> {
    let y0 = [1.0, 0.0];
    let split = |m: Splitting| -> Run { Box::new(move |span, o| m.integrate_with(&osc(), span, &y0, o)) };
    let rk = |m: ExplicitRk| -> Run { Box::new(move |span, o| m.integrate_with(&osc(), span, &y0, o)) };
    let gauss = |m: Gauss| -> Run { Box::new(move |span, o| m.integrate_with(&osc(), span, &y0, o)) };
    vec![
        ("symplectic_euler", split(Splitting::symplectic_euler(h))),
        ("leapfrog", split(Splitting::leapfrog(h))),
        ("yoshida4", split(Splitting::yoshida4(h))),
        ("yoshida6", split(Splitting::yoshida6(h))),
        ("yoshida8", split(Splitting::yoshida8(h))),
        ("blanes_moan4", split(Splitting::blanes_moan4(h))),
        ("euler", rk(ExplicitRk::euler(h))),
        ("rk4", rk(ExplicitRk::rk4(h))),
        ("midpoint", gauss(Gauss::midpoint(h))),
        ("gauss4", gauss(Gauss::gauss4(h))),
        ("gauss6", gauss(Gauss::gauss6(h))),
    ]
}

fn invalid_input(e: &IntegrateError) -> &str {
    match &e.reason {
        FailureReason::InvalidInput(m) => m,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn a_step_of_1e_300_is_refused_by_every_fixed_step_method() {
    for (name, run) in fixed_step_methods(1e-300) {
        let start = Instant::now();
        let e = within(LIMIT, name, move || run(0.0..1.0, Options::new())).unwrap_err();
        assert!(invalid_input(&e).contains("below the time resolution"), "{name}: {e}");
        assert_eq!((e.t, e.steps), (0.0, 0), "{name}: refused before the first step");
        assert!(start.elapsed() < Duration::from_secs(1), "{name} took {:?}", start.elapsed());
    }
}

#[test]
fn a_span_of_1e300_is_refused_or_bounded_by_every_fixed_step_method() {
    // dt = 0.01 cannot even move t near 1e300 (the spacing of f64 there is ~1e284).
    for (name, run) in fixed_step_methods(0.01) {
        let e = within(LIMIT, name, move || run(0.0..1e300, Options::new())).unwrap_err();
        assert!(invalid_input(&e).contains("time resolution"), "{name}: {e}");
    }
    // A step the grid can resolve still needs 1e10 steps: over the default budget of 10⁸,
    // refused before the first step.
    for (name, run) in fixed_step_methods(1e290) {
        let e = within(LIMIT, name, move || run(0.0..1e300, Options::new())).unwrap_err();
        assert!(matches!(e.reason, FailureReason::StepLimit { max_steps: 100_000_000 }), "{name}: {e}");
        assert_eq!(e.steps, 0, "{name}");
    }
}

#[test]
fn dop853_refuses_a_tolerance_below_rounding_and_names_the_floor() {
    for (rtol, atol) in [(1e-30, 1e-30), (1e-25, 1e-10), (1e-16, 1e-16)] {
        let e = within(LIMIT, "dop853", move || Dop853::new(rtol, atol).integrate(&osc(), 0.0..1.0, &[1.0, 0.0]))
            .unwrap_err();
        let msg = invalid_input(&e);
        assert!(msg.contains("smallest usable value is 2.220446049250313e-15"), "{msg}");
        assert_eq!(Dop853::MIN_RTOL, 10.0 * f64::EPSILON);
    }
    // At the floor itself the run works, and it is accurate to near rounding.
    let tr = Dop853::new(Dop853::MIN_RTOL, 1e-300).integrate(&osc(), 0.0..1.0, &[1.0, 0.0]).unwrap();
    assert!((tr.last_state()[0] - 1f64.cos()).abs() < 1e-13, "{:?}", tr.last_state());
    for (rtol, atol) in [(f64::NAN, 1e-10), (1e-10, 0.0), (1e-10, f64::INFINITY)] {
        let e = Dop853::new(rtol, atol).integrate(&osc(), 0.0..1.0, &[1.0, 0.0]).unwrap_err();
        assert!(invalid_input(&e).contains("tolerances must be finite"), "{e}");
    }
}

#[test]
fn dop853_over_a_span_of_1e300_stops_at_its_step_or_time_budget_with_the_state() {
    let e = within(LIMIT, "dop853 step budget", || {
        Dop853::new(1e-8, 1e-8).integrate_with(&osc(), 0.0..1e300, &[1.0, 0.0], Options::new().max_steps(5_000))
    })
    .unwrap_err();
    assert!(matches!(e.reason, FailureReason::StepLimit { max_steps: 5_000 }), "{e}");
    assert_eq!(e.steps, 5_000);
    // The reported state is the accepted one at the reported time: on the unit circle.
    assert!(e.t > 0.0 && e.t < 1e300);
    let r = e.state[0].hypot(e.state[1]);
    assert!((r - 1.0).abs() < 1e-3, "{e}");
    let msg = e.to_string();
    assert!(msg.starts_with(&format!("integration stopped at t = {} with state [", e.t)), "{msg}");
    assert!(msg.contains("step limit of 5000 steps"), "{msg}");

    // The wall-clock budget: a 50 ms limit ends an unbounded run within a fraction of a second.
    let start = Instant::now();
    let e = within(LIMIT, "dop853 time limit", || {
        Dop853::new(1e-8, 1e-8).integrate_with(
            &osc(),
            0.0..1e300,
            &[1.0, 0.0],
            Options::new().max_steps(usize::MAX).time_limit(Duration::from_millis(50)),
        )
    })
    .unwrap_err();
    assert!(matches!(e.reason, FailureReason::TimeLimit { .. }), "{e}");
    assert!(start.elapsed() < Duration::from_secs(5), "{:?}", start.elapsed());
    assert!(e.to_string().contains("time limit of 0.05 s"), "{e}");
}

#[test]
fn thinned_output_keeps_at_most_n_evenly_spaced_states_and_both_ends() {
    // 10⁴ steps of a fixed-step method kept through `at_most(100)`: the same states as
    // keeping every 2^k-th step for the smallest k that fits, plus the final state.
    let m = Splitting::leapfrog(1e-3);
    let all = m.integrate(&osc(), 0.0..10.0, &[1.0, 0.0]).unwrap();
    let thin = m.integrate_with(&osc(), 0.0..10.0, &[1.0, 0.0], Options::new().at_most(100)).unwrap();
    assert!(thin.len() <= 101, "{} states kept", thin.len());
    assert_eq!(thin.times[0], 0.0);
    assert_eq!(thin.last_time(), 10.0);
    assert_eq!(thin.last_state(), all.last_state());
    let stride = (0..).map(|k| 1usize << k).find(|s| 10_000 / s <= 100).unwrap();
    for (i, &t) in thin.times[..thin.len() - 1].iter().enumerate() {
        assert_eq!(t, all.times[i * stride], "kept state {i}");
        assert_eq!(thin.state(i), all.state(i * stride));
    }
}

// ----- through the scene language -------------------------------------------------------

/// Runs a scene with `lagrangian run` under a hang guard: (exit code, stderr, elapsed).
fn run_scene(dir: &Path, scene: &str) -> (Option<i32>, String, Duration) {
    let path = dir.join("extreme.scene");
    std::fs::write(&path, scene).unwrap();
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .arg("run")
        .arg(&path)
        .env("LAGRANGIAN_CACHE_DIR", "off")
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
        s
    });
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return (status.code(), reader.join().unwrap(), start.elapsed());
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("`lagrangian run` did not finish in 60 s:\n{scene}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

const OSC: &str = "coordinates x\nparameters k = 1\nH = p_x^2/2 + k x^2/2\n";

const SCENE_METHODS: &[&str] = &[
    "leapfrog",
    "verlet",
    "yoshida4",
    "yoshida6",
    "yoshida8",
    "blanes_moan",
    "symplectic_euler",
    "midpoint",
    "gauss4",
    "gauss6",
    "euler",
    "rk4",
];

#[test]
fn scene_extremes_end_at_once_with_a_clear_error_for_every_method() {
    let dir = tempfile::tempdir().unwrap();
    let mut cases: Vec<(String, Vec<&str>)> = Vec::new();
    for m in SCENE_METHODS {
        cases.push((
            format!("simulate x = 1, p_x = 0 for t in 0..1 with {m} dt = 1e-300\nexport to a.csv\n"),
            vec!["1.000e300 steps is more than the limit of 10⁹"],
        ));
        cases.push((
            format!("simulate x = 1, p_x = 0 for t in 0..1e300 with {m} dt = 0.01\nexport to a.csv\n"),
            vec!["1.000e302 steps is more than the limit of 10⁹"],
        ));
    }
    cases.push((
        "simulate x = 1, p_x = 0 for t in 0..1 with dop853 tol = 1e-30\nexport to a.csv\n".into(),
        vec!["tol = 1e-30 is below what f64 can meet", "the smallest usable tol is 2.22e-15"],
    ));
    cases.push((
        "simulate x = 1, p_x = 0 for t in 0..1 with dop853 tol = 1e-25\nexport to a.csv\n".into(),
        vec!["the smallest usable tol"],
    ));
    for (sim, pieces) in cases {
        let (code, err, took) = run_scene(dir.path(), &format!("{OSC}{sim}"));
        assert_eq!(code, Some(2), "{sim}{err}");
        for p in pieces {
            assert!(err.contains(p), "expected `{p}` for {sim}in:\n{err}");
        }
        assert!(!err.contains("panicked"), "{err}");
        assert!(took < Duration::from_secs(10), "{sim} took {took:?}");
    }
}

#[test]
fn scene_dop853_over_1e300_stops_at_the_step_budget_naming_time_state_and_stiffness() {
    let dir = tempfile::tempdir().unwrap();
    let (code, err, _) = run_scene(
        dir.path(),
        &format!("{OSC}simulate x = 1, p_x = 0 for t in 0..1e300 with dop853 tol = 1e-6\nexport to a.csv\n"),
    );
    assert_eq!(code, Some(2), "{err}");
    for p in ["integration stopped at t = ", "(state x = ", ", p_x = ", "step limit of 1000000 steps", "stiff"] {
        assert!(err.contains(p), "expected `{p}` in:\n{err}");
    }
}
