//! Budgets of long computations (D1 and D2): geodesic shooting and the chaos
//! indicators stop at a step or time budget with an error that names the budget and how to
//! raise it, in bounded memory. Each case runs the binary under an address-space cap of 1 GB
//! and a watchdog; before the budgets, the geodesic case grew about 22 MB/s and the MEGNO
//! case about 31 MB/s until the cap aborted them.

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use lagrangian::compile::{shoot_with, ShootBudget, ShootError};
use lagrangian::mechanics::geodesic;
use lagrangian::{parse, Symbol};

/// The address-space cap of every run, as in the hostile run that found the defects.
const CAP_BYTES: u64 = 1 << 30;

/// What a capped run produced.
struct Capped {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    seconds: f64,
}

/// Runs the binary with `args` (and `dir` as its working directory) under [`CAP_BYTES`] of
/// address space, killed (and the test failed) after `limit`.
fn run_capped(args: &[&str], dir: Option<&std::path::Path>, limit: Duration) -> Capped {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    cmd.args(args).env("LAGRANGIAN_CACHE_DIR", "off").stdout(Stdio::piped()).stderr(Stdio::piped());
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    // SAFETY: `setrlimit` is async-signal-safe and touches nothing of the parent.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit { rlim_cur: CAP_BYTES, rlim_max: CAP_BYTES };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let start = Instant::now();
    let mut child = cmd.spawn().expect("the binary starts");
    let read = |mut pipe: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            let _ = pipe.read_to_string(&mut s);
            s
        })
    };
    let out = read(Box::new(child.stdout.take().expect("stdout is piped")));
    let err = read(Box::new(child.stderr.take().expect("stderr is piped")));
    let status = loop {
        if let Some(s) = child.try_wait().expect("the child can be polled") {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("`lagrangian {args:?}` ran for more than {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Capped {
        code: status.code(),
        stdout: out.join().expect("stdout reader"),
        stderr: err.join().expect("stderr reader"),
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// `ds² = dx²/(x − 1/2)² + dy²`: the line x = 1/2 is infinitely far from both sides, so no
/// geodesic joins (0, 0) to (1, 0), and every trial path creeps towards x = 1/2.
const WALL: &str = "dx^2/(x-1/2)^2 + dy^2";

#[test]
fn geodesic_shooting_through_a_singular_metric_stops_at_its_budget() {
    let args = ["geodesic", WALL, "--coords", "x,y", "--from", "0,0", "--to", "1,0"];
    let r = run_capped(&args, None, Duration::from_secs(120));
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stdout.is_empty(), "{}", r.stdout);
    assert!(r.stderr.contains("budget of 1000000 integration steps"), "{}", r.stderr);
    assert!(r.stderr.contains("raise --max-steps"), "{}", r.stderr);
    assert!(r.stderr.contains("singular"), "{}", r.stderr);
    // The time budget, with a step budget too large to matter.
    let timed = [&args[..], &["--max-steps", "1000000000000", "--time-limit", "0.5"]].concat();
    let r = run_capped(&timed, None, Duration::from_secs(60));
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stderr.contains("budget of 0.5 s") && r.stderr.contains("raise --time-limit"), "{}", r.stderr);
    assert!(r.seconds < 30.0, "the 0.5 s budget took {} s", r.seconds);
    let r = run_capped(&[&args[..], &["--max-steps", "0"]].concat(), None, Duration::from_secs(60));
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stderr.contains("must be positive"), "{}", r.stderr);
}

#[test]
fn the_shooting_budget_counts_steps_of_every_trial_path() {
    let z = [Symbol::new("x"), Symbol::new("y")];
    let wall = geodesic(&parse(WALL).unwrap(), &z).unwrap();
    let budget = ShootBudget { max_steps: 5_000, ..ShootBudget::default() };
    match shoot_with(&wall, &[0.0, 0.0], &[1.0, 0.0], &[], 1, budget) {
        Err(ShootError::Budget { steps: true, limit, t, .. }) => {
            assert_eq!(limit, "5000 integration steps");
            assert!((0.0..1.0).contains(&t), "t = {t}");
        }
        other => panic!("expected the step budget, got {other:?}"),
    }
    // A smooth geodesic (a great circle) is found well inside a small budget, and its
    // end velocity does not depend on the budget.
    let sphere = geodesic(&parse("dθ^2 + sin(θ)^2 dφ^2").unwrap(), &[Symbol::new("θ"), Symbol::new("φ")]).unwrap();
    let small = ShootBudget { max_steps: 20_000, ..ShootBudget::default() };
    let a = shoot_with(&sphere, &[1.0, 0.0], &[1.2, 0.5], &[], 1, small).expect("found within 20 000 steps");
    let b = shoot_with(&sphere, &[1.0, 0.0], &[1.2, 0.5], &[], 1, ShootBudget::default()).expect("found");
    assert_eq!(a.velocity, b.velocity);
}

/// A pendulum, `H = p²/2 − cos θ`.
const PENDULUM_SCENE: &str = "coordinates θ\nparameters g = 1, l = 1\nL = 1/2 l^2 θ'^2 + g l cos(θ)\n";

/// Runs `scene` (a pendulum and one more statement) in a fresh directory under the cap.
fn run_scene(statement: &str, limit: Duration) -> Capped {
    let dir = std::env::temp_dir().join(format!("lagrangian-budget-{}-{}", std::process::id(), statement.len()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    std::fs::write(dir.join("s.scene"), format!("{PENDULUM_SCENE}{statement}\n")).expect("scene written");
    let r = run_capped(&["run", "s.scene"], Some(&dir), limit);
    std::fs::remove_dir_all(&dir).expect("temporary directory removed");
    r
}

#[test]
fn chaos_indicators_stop_at_their_step_budget_in_bounded_memory() {
    // The hostile case itself, to t = 1e9: 10⁷ Taylor steps (about 14 s in the dev profile),
    // then an error naming the budget. Before, it grew 31 MB/s until the cap aborted it.
    let r = run_scene("megno θ = 1, θ' = 0 for t in 0..1e9", Duration::from_secs(300));
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stderr.contains("step limit of 10000000 steps"), "{}", r.stderr);
    assert!(r.stderr.contains("`max_steps = N` (now 10000000)"), "{}", r.stderr);
    for (stmt, needle) in [
        ("lyapunov θ = 1, θ' = 0 for t in 0..1e9 max_steps = 1000", "step limit of 1000 steps"),
        ("fli θ = 1, θ' = 0 for t in 0..1e9 max_steps = 1000", "step limit of 1000 steps"),
        ("megno θ = 1, θ' = 0 for t in 0..1e9 max_steps = 1e12 time_limit = 0.5", "time limit of 0.5 s"),
        // A map whose starts run out of the budget is refused, not drawn with blank cells.
        (
            "chaos_map megno θ = -1..1, θ' = -1..1 for t in 0..1e7 points 2 max_steps = 1000 to m.csv",
            "step limit of 1000",
        ),
        (
            "chaos_map megno θ = -1..1, θ' = -1..1 for t in 0..1e7 points 2 time_limit = 0.5 to m.csv",
            "time limit of 0.5 s",
        ),
    ] {
        let r = run_scene(stmt, Duration::from_secs(120));
        assert_eq!(r.code, Some(2), "{stmt}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{stmt}: {}", r.stderr);
        let raise = if needle.starts_with("time") { "`time_limit = SECONDS`" } else { "`max_steps = N`" };
        assert!(r.stderr.contains(raise), "{stmt}: {}", r.stderr);
        assert!(!r.stdout.contains("wrote"), "{stmt}: {}", r.stdout);
    }
    for (stmt, needle) in [
        ("megno θ = 1, θ' = 0 for t in 0..10 max_steps = 2.5", "whole number of steps"),
        ("megno θ = 1, θ' = 0 for t in 0..10 max_steps = 0", "whole number of steps"),
        ("megno θ = 1, θ' = 0 for t in 0..10 time_limit = -1", "positive number of seconds"),
    ] {
        let r = run_scene(stmt, Duration::from_secs(60));
        assert_eq!(r.code, Some(2), "{stmt}: {}", r.stderr);
        assert!(r.stderr.contains(needle), "{stmt}: {}", r.stderr);
    }
    // Within its budget the statement prints what it printed without one (the budget only
    // bounds; here 1096 Taylor steps).
    let with = run_scene("megno θ = 1, θ' = 0 for t in 0..200 max_steps = 100000", Duration::from_secs(60));
    let without = run_scene("megno θ = 1, θ' = 0 for t in 0..200", Duration::from_secs(60));
    assert_eq!((with.code, without.code), (Some(0), Some(0)), "{} {}", with.stderr, without.stderr);
    assert!(with.stdout.contains("MEGNO ⟨Y⟩ = "), "{}", with.stdout);
    assert_eq!(with.stdout, without.stdout);
}

#[test]
fn chaos_samples_are_thinned_evenly_to_their_budget() {
    use lagrangian::chaos::{indicators, indicators_with, Budget};
    let h = parse("p^2/2 - cos(q)").unwrap();
    let var = lagrangian::compile::Variational::hamiltonian(&h, &["q"], &["p"], &[], 1, true).unwrap();
    let full = indicators(&var, &[1.0, 0.0], 2000.0, 1e-12).unwrap();
    let budget = Budget { max_samples: 100, ..Budget::default() };
    let thin = indicators_with(&var, &[1.0, 0.0], 2000.0, 1e-12, &budget).unwrap();
    // The same orbit and the same indicators at the end; only the kept samples differ.
    assert_eq!((thin.steps, thin.megno, thin.fli), (full.steps, full.megno, full.fli));
    assert!(full.samples.len() == full.steps && full.steps > 400, "{} steps", full.steps);
    assert!((50..=101).contains(&thin.samples.len()), "{} samples", thin.samples.len());
    // Every kept sample is one of the full run's, at an even stride, and the last is the end.
    let stride = full.samples.iter().position(|s| *s == thin.samples[0]).unwrap() + 1;
    assert!(stride.is_power_of_two() && stride >= full.steps / 101, "stride {stride}");
    for (k, s) in thin.samples.iter().enumerate().take(thin.samples.len() - 1) {
        assert_eq!(*s, full.samples[(k + 1) * stride - 1], "sample {k}");
    }
    assert_eq!(thin.samples.last(), full.samples.last());
    assert_eq!(thin.samples.last().unwrap().t, 2000.0);
}

/// `every 1` over 10⁸ fixed steps would keep 10⁸ states (it used to run until the address
/// space ran out): refused before the first step, at `every`, with the smallest `every` that
/// fits (10⁸ / 2·10⁶ = 50). Within the limit the same run is accepted and keeps every state.
#[test]
fn keeping_more_states_than_memory_allows_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |span: &str| {
        format!(
            "coordinates x\nL = 1/2 x'^2 - 1/2 x^2\nsimulate x = 1, x' = 0 for t in 0..{span} with rk4 dt = 1 every 1 as r\nexport from r to r.csv\n"
        )
    };
    let path = dir.path().join("every.scene");
    std::fs::write(&path, scene("1e8")).unwrap();
    let r = run_capped(&["run", path.to_str().unwrap()], Some(dir.path()), Duration::from_secs(20));
    assert_eq!(r.code, Some(2), "{}{}", r.stdout, r.stderr);
    assert!(r.stderr.contains("would keep 1.000e8 states") && r.stderr.contains("`every 50`"), "{}", r.stderr);
    assert!(!dir.path().join("r.csv").exists());
    std::fs::write(&path, scene("1000")).unwrap();
    let r = run_capped(&["run", path.to_str().unwrap()], Some(dir.path()), Duration::from_secs(20));
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    let rows = std::fs::read_to_string(dir.path().join("r.csv")).unwrap().lines().count();
    assert_eq!(rows, 1 + 1001, "a header and every step from t = 0 to 1000");
}
