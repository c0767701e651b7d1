//! Input and output at the edges (issue 16 items 1–2, 6; issue 13 item 5): a reader that
//! closes the pipe early, unbounded or non-regular inputs, outputs that would leave the
//! output directory, two outputs to one path. Never a panic, a hang or a quietly wrong file.

use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    c.env("LAGRANGIAN_CACHE_DIR", "off");
    c
}

/// Waits for `child` with a hang guard, reading stderr meanwhile.
fn finish(mut child: std::process::Child, what: &str) -> (ExitStatus, String) {
    let mut stderr = child.stderr.take().expect("stderr is piped");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
        s
    });
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return (status, reader.join().unwrap());
        }
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            panic!("{what} did not finish in 30 s");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Quiet end on a closed pipe: success, or killed by SIGPIPE (status 141 in a shell), the
/// convention of `cat` and `grep`; never a panic (exit 101) or an error message.
fn assert_quiet_end(status: ExitStatus, stderr: &str, what: &str) {
    #[cfg(unix)]
    let by_sigpipe = std::os::unix::process::ExitStatusExt::signal(&status) == Some(13);
    #[cfg(not(unix))]
    let by_sigpipe = false;
    assert!(status.success() || by_sigpipe, "{what}: {status:?}\n{stderr}");
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    assert!(!stderr.contains("failed printing"), "{what}: {stderr}");
}

/// Every subcommand, its output piped into a reader that has already gone away.
#[test]
fn every_subcommand_ends_quietly_when_its_reader_closes_the_pipe() {
    let long = "a".repeat(100_000);
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.scene");
    std::fs::write(&scene, "coordinates x\nH = p_x^2/2 + x^2/2\nprint hamilton\nprint H\n").unwrap();
    let scene = scene.to_str().unwrap().to_string();
    let cases: Vec<Vec<&str>> = vec![
        vec!["simplify", &long],
        vec!["simplify", "sin(x)^2 + cos(x)^2", "--format", "json"],
        vec!["diff", &long, "a"],
        vec!["dt", "1/2 m x'^2"],
        vec!["el", "1/2 m x'^2 - k x^2/2", "--coords", "x"],
        vec!["legendre", "1/2 m x'^2 - k x^2/2", "--coords", "x", "--positive", "m"],
        vec!["hamilton", "p_x^2/2 + x^2/2", "--coords", "x"],
        vec!["conserved", "1/2 m x'^2", "--coords", "x"],
        vec!["pb", "x", "p_x", "--coords", "x"],
        vec!["integral", "p_x", "--hamiltonian", "p_x^2/2", "--coords", "x"],
        vec!["is-canonical", "Q = p_q, P = -q", "--coords", "q"],
        vec!["canonical", "--hamiltonian", "p_q^2/2 + q^2/2", "--coords", "q", "--f1", "q Q", "--new", "Q,P"],
        vec!["lie", "q", "--generator", "p_q^2/2", "--coords", "q"],
        vec!["action", "--hamiltonian", "p^2/2 + q^2/2", "--coord", "q", "--momentum", "p", "--energy", "1,2"],
        vec!["average", "1/2 x'^2 - 1/2 x^2", "--trial", "x = A cos(θ)", "--phase", "θ", "--frequency", "ω"],
        vec!["run", &scene],
        vec!["--help"],
    ];
    for args in cases {
        let what = format!("lagrangian {}", args.iter().map(|a| &a[..a.len().min(30)]).collect::<Vec<_>>().join(" "));
        let mut child = bin()
            .args(&args)
            .current_dir(dir.path())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The reader goes away before the first byte is written.
        drop(child.stdout.take());
        let (status, stderr) = finish(child, &what);
        assert_quiet_end(status, &stderr, &what);
    }
}

/// The REPL on a pipe whose reader has gone.
#[test]
fn the_piped_repl_ends_quietly_when_its_reader_closes_the_pipe() {
    let mut child = bin().stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    drop(child.stdout.take());
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        let _ = stdin.write_all(b"coordinates x\nH = p_x^2/2 + x^2/2\nprint hamilton\n");
    }
    let (status, stderr) = finish(child, "the REPL");
    assert_quiet_end(status, &stderr, "the REPL");
}

#[allow(dead_code)]
fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}
