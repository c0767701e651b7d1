//! Budgets of long computations (issue 31, D1 and D2): geodesic shooting and the chaos
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
