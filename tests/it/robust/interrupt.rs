//! Interruptible work: a real SIGINT to a child `lagrangian run` ends it
//! within a second with status 130 and no output file — during a simulation, an animation
//! being encoded and a long plot; the piped REPL survives one with its definitions; and the
//! library's token stops an integration and the simplifier.
//!
//! The child-process tests start a simulation of ~10⁸ steps (minutes if nothing stopped it),
//! wait until its progress line appears on stderr (`LAGRANGIAN_PROGRESS=always`), then send
//! the signal; a watchdog kills the child after 20 s so a regression fails instead of hanging.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use lagrangian::cancel::CancelToken;
use lagrangian::integrate::{ExplicitRk, FailureReason, FnRhs, Integrate, Options};

/// A harmonic oscillator run of 10⁸ steps.
const LONG: &str = "\
coordinates x
H = p_x^2/2 + x^2/2
simulate x = 1, p_x = 0 for t in 0..10000 with rk4 dt = 0.0001 as spin
";

fn sigint(child: &Child) {
    // SAFETY: `kill` with a valid pid and signal number has no memory effects here.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    assert_eq!(r, 0, "kill failed");
}

/// Lines of a child's stream, as they arrive, on a channel.
fn lines(stream: impl Read + Send + 'static) -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// Waits (at most 20 s) for a line containing `needle`, returning everything seen.
fn wait_for(rx: &mpsc::Receiver<String>, needle: &str) -> Vec<String> {
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut seen = Vec::new();
    while Instant::now() < deadline {
        if let Ok(l) = rx.recv_timeout(Duration::from_millis(50)) {
            let hit = l.contains(needle);
            seen.push(l);
            if hit {
                return seen;
            }
        }
    }
    panic!("no line containing `{needle}` within 20 s; seen {seen:?}");
}

fn wait_exit(child: &mut Child, limit: Duration) -> Option<std::process::ExitStatus> {
    let start = Instant::now();
    while start.elapsed() < limit {
        if let Some(s) = child.try_wait().unwrap() {
            return Some(s);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

#[test]
fn ctrl_c_ends_a_scene_run_with_status_130_and_no_output_file() {
    let (_dir, child, err, out) = start_run(&format!("{LONG}export t, x from spin to spin.csv\n"));
    wait_for(&err, "spin");
    interrupt_and_check(child, &out);
}

/// `lagrangian run` of `scene` in a fresh directory with an empty `out/`, progress lines
/// forced on stderr: the child, its stderr lines and the output directory.
fn start_run(scene: &str) -> (tempfile::TempDir, Child, mpsc::Receiver<String>, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.scene");
    std::fs::write(&path, scene).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .args(["run", path.to_str().unwrap(), "--no-cache", "--out-dir", out.to_str().unwrap()])
        .env("LAGRANGIAN_PROGRESS", "always")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = lines(child.stderr.take().unwrap());
    (dir, child, err, out)
}

/// SIGINT to `child`; asserts it exits 130 within a second, leaving `out` empty and
/// announcing no file.
fn interrupt_and_check(mut child: Child, out: &std::path::Path) {
    let sent = Instant::now();
    sigint(&child);
    let status = wait_exit(&mut child, Duration::from_secs(20)).expect("the run did not stop within 20 s");
    let took = sent.elapsed();
    assert_eq!(status.code(), Some(130), "exit status");
    assert!(took < Duration::from_secs(1), "took {took:?} to exit after SIGINT");
    let left: Vec<_> = std::fs::read_dir(out).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
    let mut stdout = String::new();
    child.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
    assert!(!stdout.contains("wrote"), "no file is announced: {stdout}");
}

/// Starts a scene whose animation takes about 100 s uninterrupted (1500 frames of 512²
/// pixels, 65 ms a frame in the dev profile; RELIABILITY.md) and returns once the GIF back
/// end has created its staged file, that is once drawing has started.
fn start_long_animation() -> (tempfile::TempDir, Child, mpsc::Receiver<String>, std::path::PathBuf) {
    // (The stderr receiver is kept: a closed pipe would end the child by SIGPIPE.)
    let (dir, mut child, err, out) = start_run(
        "coordinates x\nH = p_x^2/2 + x^2/2\n\
         simulate x = 1, p_x = 0 for t in 0..10 with leapfrog dt = 0.01 as a\n\
         animate path (0, 0), (x, p_x) from a to motion.gif fps 50 duration 30 size 512\n",
    );
    // The GIF back end creates its (staged) file when drawing starts: wait for it.
    let deadline = Instant::now() + Duration::from_secs(60);
    let staged = loop {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended before the animation started: {status}");
        }
        let names: Vec<String> =
            std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        if let Some(n) = names.into_iter().find(|n| n.contains("partial")) {
            break n;
        }
        assert!(Instant::now() < deadline, "the animation was not started within 60 s");
        std::thread::sleep(Duration::from_millis(5));
    };
    assert!(staged.ends_with(".gif"), "{staged}");
    (dir, child, err, out)
}

#[test]
fn ctrl_c_during_an_animation_stops_it_mid_draw_with_no_file() {
    let (_dir, child, _err, out) = start_long_animation();
    interrupt_and_check(child, &out);
}

/// Waits until no SIGINT is pending for `child` (read from `/proc`), so that a second signal
/// is a second press and not merged with the first by the kernel.
#[cfg(target_os = "linux")]
fn wait_delivered(child: &Child) {
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = format!("/proc/{}/status", child.id());
    loop {
        let text = std::fs::read_to_string(&status).unwrap_or_default();
        let pending = text
            .lines()
            .filter(|l| l.starts_with("SigPnd:") || l.starts_with("ShdPnd:"))
            .any(|l| u64::from_str_radix(l[7..].trim(), 16).unwrap_or(0) & (1 << (libc::SIGINT - 1)) != 0);
        if !pending {
            return;
        }
        assert!(Instant::now() < deadline, "SIGINT still pending after 20 s");
        std::thread::yield_now();
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_second_ctrl_c_exits_at_once_and_still_removes_the_staged_file() {
    // The second press ends the process from the handler's thread while the main thread is
    // still inside a frame (65 ms each): the staged GIF is removed there, before the exit.
    let (_dir, child, _err, out) = start_long_animation();
    sigint(&child);
    wait_delivered(&child);
    interrupt_and_check(child, &out);
}

#[cfg(unix)]
#[test]
fn sigterm_ends_a_run_with_status_143_and_removes_the_staged_file() {
    // Killed where it stands by the default action, the run would leave its staged GIF.
    let (_dir, mut child, _err, out) = start_long_animation();
    // SAFETY: `kill` with a valid pid and signal number has no memory effects here.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    assert_eq!(r, 0, "kill failed");
    let status = wait_exit(&mut child, Duration::from_secs(20)).expect("the run did not stop within 20 s");
    assert_eq!(status.code(), Some(143), "exit status {status}");
    let left: Vec<_> = std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
}

#[test]
fn ctrl_c_during_a_long_plot_stops_it_with_no_file() {
    // A run of 10⁶ stored states (`every 1`), then a plot of five expressions along it: about
    // 10 s of evaluation and drawing uninterrupted in the dev profile (RELIABILITY.md), against
    // 0.3 s for the run. The signal goes when the run's progress line reaches 100 %, that is
    // as the plot starts.
    let (_dir, child, err, out) = start_run(
        "coordinates x\nH = p_x^2/2 + x^2/2\n\
         simulate x = 1, p_x = 0 for t in 0..10000 with leapfrog dt = 0.01 every 1 as long\n\
         plot x, p_x, x^2 - p_x^2, x p_x, sin(x) cos(p_x) vs t from long to long.png\n",
    );
    wait_for(&err, "100%");
    interrupt_and_check(child, &out);
}

#[test]
fn ctrl_c_in_the_piped_repl_returns_to_the_prompt_with_earlier_definitions() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .arg("repl")
        .arg("--no-cache")
        .env("LAGRANGIAN_PROGRESS", "always")
        .env("LAGRANGIAN_HISTORY", dir.path().join("history"))
        .current_dir(dir.path())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let out = lines(child.stdout.take().unwrap());
    let err = lines(child.stderr.take().unwrap());
    stdin.write_all(LONG.as_bytes()).unwrap();
    stdin.flush().unwrap();
    wait_for(&err, "spin");
    let sent = Instant::now();
    sigint(&child);
    let before = wait_for(&out, "interrupted");
    let took = sent.elapsed();
    assert!(took < Duration::from_secs(1), "took {took:?} to stop after SIGINT");
    // The definitions before the interrupted statement are intact, and the REPL goes on: a
    // short run of the same H, then the Hamiltonian printed.
    stdin
        .write_all(b"simulate x = 1, p_x = 0 for t in 0..1 with leapfrog dt = 0.01 as short\nprint H\nquit\n")
        .unwrap();
    drop(stdin);
    let status = wait_exit(&mut child, Duration::from_secs(20)).expect("the REPL did not end");
    assert_eq!(status.code(), Some(0));
    let rest: Vec<String> = out.try_iter().collect();
    let transcript = before.into_iter().chain(rest).collect::<Vec<_>>().join("\n");
    assert!(transcript.contains("short: leapfrog from t = 0 to t = 1 in 100 steps"), "{transcript}");
    assert!(transcript.contains("H = p_x²/2 + x²/2"), "{transcript}");
    // The interrupted run was not kept: its name is unknown afterwards.
    assert!(!transcript.contains("spin: rk4"), "{transcript}");
}

#[test]
fn a_token_stops_an_integration_at_its_next_step_with_the_last_good_state() {
    let token = CancelToken::new();
    let canceller = token.clone();
    let rhs = FnRhs {
        dim: 2,
        f: |_t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1];
            dy[1] = -y[0];
        },
    };
    // Cancel from another thread after 50 ms; the run (5·10⁷ steps) would take seconds to minutes.
    let stopper = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(50));
        canceller.cancel();
    });
    let start = Instant::now();
    let e = ExplicitRk::rk4(1e-6)
        .integrate_with(&rhs, 0.0..50.0, &[1.0, 0.0], Options::new().final_only().cancel(token))
        .unwrap_err();
    stopper.join().unwrap();
    assert_eq!(e.reason, FailureReason::Interrupted);
    assert!(start.elapsed() < Duration::from_secs(5));
    assert!(e.t > 0.0 && e.t < 50.0 && e.steps > 0, "{e}");
    // The state is the last accepted one: on the unit circle of the oscillator.
    let r2 = e.state[0] * e.state[0] + e.state[1] * e.state[1];
    assert!((r2 - 1.0).abs() < 1e-9, "{e}");
}

/// `1 + x (2 + x (3 + …))`, `n` deep, built directly (the parser stops at 1000 levels).
fn horner(n: i64) -> lagrangian::Expr {
    use lagrangian::{Expr, Symbol};
    let x = Expr::sym(Symbol::new("x"));
    (1..n).rev().fold(Expr::int(n), |inner, k| Expr::int(k).plus(&x.times(&inner)))
}

/// Runs `f` on a thread with a stack for 6400-deep recursion (the symbolic steps recurse).
fn deep<R: Send + 'static>(f: impl FnOnce() -> R + Send + 'static) -> R {
    std::thread::Builder::new().stack_size(512 << 20).spawn(f).unwrap().join().unwrap()
}

/// The single symbolic steps poll the token (a library caller's, through
/// `cancel::with_token`, or Ctrl-C's): an expansion, a collection of terms and a derivative
/// return `Interrupted` when it is set, and the same calls without it give the uninterrupted
/// result (before, each ran to its end whatever was set).
#[test]
fn a_token_set_before_the_call_stops_expansion_collection_and_differentiation() {
    use lagrangian::algebra::{expand, try_collect_common, AlgebraError};
    use lagrangian::cancel::{with_token, Interrupted};
    use lagrangian::diff::{diff, Differentiator};
    use lagrangian::Symbol;
    deep(|| {
        let e = horner(200);
        let x = Symbol::new("x");
        let set = CancelToken::new();
        set.cancel();
        let unset = CancelToken::new();
        assert_eq!(with_token(&set, || expand(&e)), Err(AlgebraError::Interrupted));
        let full = with_token(&unset, || expand(&e)).unwrap();
        assert_eq!(full.terms().len(), 200, "the degree-199 polynomial, one term per power");
        assert_eq!(with_token(&set, || try_collect_common(&full)), Err(Interrupted));
        assert!(with_token(&unset, || try_collect_common(&full)).is_ok());
        let mut d = Differentiator::new();
        assert_eq!(with_token(&set, || d.try_diff(&e, &x)), Err(Interrupted));
        // The abandoned derivative left nothing wrong in the memo.
        assert_eq!(with_token(&unset, || d.try_diff(&e, &x)), Ok(diff(&e, &x)));
        // The simplifier sees the same token: it stops with the input unchanged.
        let s = with_token(&set, || lagrangian::simplify::simplify_with(&e, &Default::default()));
        assert_eq!(s.stop, lagrangian::simplify::StopReason::Interrupted);
        // Outside `with_token` nothing is set: the token does not leak to later work.
        assert!(expand(&horner(100)).is_ok());
    });
}

/// One expansion of a deep Horner form (the degree-n polynomial, about n²/2 term products),
/// cancelled from another thread 50 ms in, returns `Interrupted` in well under the time the
/// same expansion takes uninterrupted, measured first in this test (n doubles from 800 until
/// that is at least 0.3 s, so a fast machine still has something to interrupt).
#[test]
fn a_single_expansion_is_cancelled_from_another_thread() {
    use lagrangian::algebra::{expand_with_limit, AlgebraError};
    use lagrangian::cancel::with_token;
    deep(|| {
        let mut n = 800;
        let (e, full) = loop {
            let e = horner(n);
            let start = Instant::now();
            let out = expand_with_limit(&e, 1 << 30).unwrap();
            let full = start.elapsed();
            assert_eq!(out.terms().len(), n as usize);
            if full >= Duration::from_millis(300) || n >= 12_800 {
                break (e, full);
            }
            n *= 2;
        };
        let token = CancelToken::new();
        let setter = {
            let token = token.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(50));
                token.cancel();
            })
        };
        let start = Instant::now();
        let out = with_token(&token, || expand_with_limit(&e, 1 << 30));
        let interrupted = start.elapsed();
        setter.join().unwrap();
        assert_eq!(out, Err(AlgebraError::Interrupted), "n = {n}, uninterrupted {full:?}");
        assert!(interrupted < full / 2, "n = {n}: interrupted after {interrupted:?}, uninterrupted {full:?}");
    });
}
