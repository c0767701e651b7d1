//! Input and output at the edges: a reader that
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

/// Runs the binary with `args` in `dir` (stdin from `input`): (exit code, stdout, stderr).
fn run_in(dir: &Path, args: &[&str], input: &[u8]) -> (Option<i32>, String, String) {
    let mut child = bin()
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let data = input.to_vec();
    let writer = std::thread::spawn(move || {
        use std::io::Write;
        let _ = stdin.write_all(&data);
    });
    let mut stdout = child.stdout.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stdout, &mut s);
        s
    });
    let (status, err) = finish(child, &args.join(" "));
    let _ = writer.join();
    (status.code(), out.join().unwrap(), err)
}

#[cfg(unix)]
#[test]
fn reads_of_devices_are_bounded_and_name_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let start = Instant::now();
    let (code, _, err) = run_in(dir.path(), &["run", "/dev/zero"], b"");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("`/dev/zero` is not a regular file and longer than the limit"), "{err}");
    assert!(err.contains("limited to 4 MB"), "{err}");
    std::fs::write(dir.path().join("s.scene"), "coordinates x\nload \"/dev/zero\"\n").unwrap();
    let (code, _, err) = run_in(dir.path(), &["run", "s.scene"], b"");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("limited to 4 MB"), "{err}");
    let (code, _, err) = run_in(dir.path(), &["run", "."], b"");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("it is a directory"), "{err}");
    // Standard input: 64 MB + 1 byte of zeros is refused (one read of the limit, no more).
    let (code, _, err) = run_in(dir.path(), &["simplify", "-"], &vec![b'0'; (64 << 20) + 1]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("standard input is longer than the limit of 64 MB"), "{err}");
    assert!(start.elapsed() < Duration::from_secs(20), "{:?}", start.elapsed());
}

#[test]
fn the_piped_repl_recovers_from_an_unclosed_parenthesis_at_a_blank_line() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, _) =
        run_in(dir.path(), &[], b"coordinates x\nprint (x + 1\n\nprint 1 + 1\nprint sin(x)^2 + cos(x)^2\n");
    assert_eq!(code, Some(0), "{out}");
    // One error for the unfinished entry, then both later statements run.
    assert!(out.contains("error") || out.contains("×"), "{out}");
    let after: Vec<&str> = out.lines().skip_while(|l| !l.contains("print 1 + 1")).collect();
    assert!(after.iter().any(|l| l.trim() == "2"), "{out}");
    // `print` simplifies as `lagrangian simplify` does: sin² + cos² is 1.
    assert!(after.iter().any(|l| l.trim() == "1"), "{out}");
}

const SCENE: &str = "coordinates x\nH = p_x^2/2 + x^2/2\nsimulate x = 1, p_x = 0 for t in 0..1 with rk4 dt = 0.1\n";

/// Runs `scene` with `extra` arguments in a fresh directory holding `out/`.
fn scene_in(scene: &str, extra: &[&str]) -> (tempfile::TempDir, Option<i32>, String, String) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("out")).unwrap();
    std::fs::write(dir.path().join("s.scene"), scene).unwrap();
    let mut args = vec!["run", "s.scene", "--out-dir", "out"];
    args.extend_from_slice(extra);
    let (code, out, err) = run_in(dir.path(), &args, b"");
    (dir, code, out, err)
}

#[test]
fn outputs_stay_inside_the_output_directory_unless_allowed() {
    let outside = tempfile::tempdir().unwrap();
    let abs = outside.path().join("abs.csv");
    for (path, piece) in [
        ("../escape.csv".to_string(), "leaves the output directory"),
        ("a/../../escape.csv".to_string(), "leaves the output directory"),
        (abs.display().to_string(), "is an absolute path"),
    ] {
        // The escape is the second output: refused before the first is written or anything runs.
        let scene = format!("{SCENE}export to fine.csv\nexport to \"{path}\"\n");
        let (dir, code, out, err) = scene_in(&scene, &[]);
        assert_eq!(code, Some(2), "{path}: {err}");
        assert!(err.contains(piece) && err.contains("--allow-outside"), "{path}: {err}");
        assert!(!out.contains("wrote"), "{out}");
        assert_eq!(files_in(&dir.path().join("out")), Vec::<String>::new());
        assert_eq!(files_in(dir.path()), ["out", "s.scene"]);
        assert!(!abs.exists());
    }
    // With --allow-outside both are written.
    let scene = format!("{SCENE}export to \"../escape.csv\"\nexport to \"{}\"\n", abs.display());
    let (dir, code, _, err) = scene_in(&scene, &["--allow-outside"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(dir.path().join("escape.csv").is_file() && abs.is_file());
    // `sub/../x.csv` stays inside and is fine.
    let (dir, code, _, err) = scene_in(&format!("{SCENE}export to \"sub/../x.csv\"\n"), &[]);
    assert_eq!(code, Some(0), "{err}");
    assert!(dir.path().join("out/x.csv").is_file());
}

#[cfg(unix)]
#[test]
fn a_symbolic_link_out_of_the_output_directory_is_refused() {
    let outside = tempfile::tempdir().unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("out")).unwrap();
    std::os::unix::fs::symlink(outside.path(), dir.path().join("out/link")).unwrap();
    std::fs::write(dir.path().join("s.scene"), format!("{SCENE}export to \"link/x.csv\"\n")).unwrap();
    let (code, _, err) = run_in(dir.path(), &["run", "s.scene", "--out-dir", "out"], b"");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("leads through a symbolic link"), "{err}");
    assert_eq!(files_in(outside.path()), Vec::<String>::new());
}

#[test]
fn two_outputs_to_one_path_are_an_error_before_anything_runs() {
    let scene = format!("{SCENE}export to a.csv\nplot energy\nexport x to \"./a.csv\"\n");
    let (dir, code, out, err) = scene_in(&scene, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("two outputs write") && err.contains("a.csv"), "{err}");
    assert!(!out.contains("wrote"), "{out}");
    assert_eq!(files_in(&dir.path().join("out")), Vec::<String>::new());
    // Two default-named plots of one kind collide too.
    let (_, code, _, err) = scene_in(&format!("{SCENE}plot energy\nplot energy\n"), &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("s_energy.svg"), "{err}");
}

#[test]
fn wrote_is_printed_only_for_files_that_exist() {
    // The export succeeds, a later statement fails: nothing is written and nothing claims so.
    let (dir, code, out, err) = scene_in(&format!("{SCENE}export to a.csv\nprint nosuch + 1\n"), &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(!out.contains("wrote"), "{out}");
    assert_eq!(files_in(&dir.path().join("out")), Vec::<String>::new());
    // On success every announced file exists, and an existing file is replaced whole.
    let (dir, code, out, err) = scene_in(&format!("{SCENE}export to a.csv\n"), &[]);
    assert_eq!(code, Some(0), "{err}");
    for line in out.lines().filter(|l| l.starts_with("wrote ")) {
        assert!(dir.path().join(&line["wrote ".len()..]).is_file(), "{line}");
    }
    let first = std::fs::read_to_string(dir.path().join("out/a.csv")).unwrap();
    std::fs::write(dir.path().join("s.scene"), format!("{SCENE}export x to a.csv\n")).unwrap();
    let (code, _, err) = run_in(dir.path(), &["run", "s.scene", "--out-dir", "out"], b"");
    assert_eq!(code, Some(0), "{err}");
    let second = std::fs::read_to_string(dir.path().join("out/a.csv")).unwrap();
    assert_ne!(first, second);
    assert!(second.lines().next().is_some_and(|h| !h.contains("p_x")), "{second}");
    assert_eq!(files_in(&dir.path().join("out")), ["a.csv"], "no temporary file left");
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn a_failed_simulate_in_the_repl_does_not_consume_its_run_name() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, _) = run_in(
        dir.path(),
        &[],
        b"coordinates x\nH = p_x^2/2 + x^2/2\nsimulate x = 1, p_x = 0 for t in 0..0\n\
          simulate x = 1, p_x = 0 for t in 0..1 with rk4 dt = 0.1\n",
    );
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("the time span is empty"), "{out}");
    assert!(out.lines().any(|l| l.starts_with("run1: rk4")), "{out}");
    assert!(!out.contains("run2"), "{out}");
}

#[test]
fn numbers_that_underflow_or_overflow_f64_say_so() {
    let dir = tempfile::tempdir().unwrap();
    for (value, piece) in [("1e-400", "underflows to 0 in f64"), ("1e400", "overflows f64")] {
        std::fs::write(
            dir.path().join("s.scene"),
            format!("coordinates x\nparameters m = {value}\nH = p_x^2/(2 m) + x^2/2\nsimulate x = 1, p_x = 0 for t in 0..1 with rk4 dt = 0.1\nexport to a.csv\n"),
        )
        .unwrap();
        let (code, _, err) = run_in(dir.path(), &["run", "s.scene"], b"");
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(piece), "{value}: {err}");
    }
}

/// D15 of the hostile run: `export from ENSEMBLE` writes every member, as the docs say (before, only
/// the first member was written, with no note). Each member's rows are the rows the member
/// exported alone gives, after a `run` column naming it; JSON holds one object per member;
/// `export poincare` does the same.
#[test]
fn exports_of_an_ensemble_write_every_member() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "coordinates x, y\nH = (p_x^2 + p_y^2)/2 + (x^2 + y^2)/2\n\
        simulate x = 0, p_y = 0 for each y in 0..0.2 step 0.1 on H = 1/8 solve p_x > 0 for t in 0..10 \
        with rk4 dt = 0.1 record when x = 0 rising as e\n\
        export from e to e.csv\nexport from e_1 to e1.csv\nexport from e_2 to e2.csv\nexport from e_3 to e3.csv\n\
        export x, y from e to e.json\nexport poincare from e to p.csv\nexport poincare from e_3 to p3.csv\n";
    std::fs::write(dir.path().join("e.scene"), scene).unwrap();
    let out = bin().args(["run", "e.scene"]).current_dir(dir.path()).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let read = |f: &str| std::fs::read_to_string(dir.path().join(f)).unwrap();
    let all = read("e.csv");
    let mut lines = all.lines();
    assert_eq!(lines.next(), Some("run,t,x,y,p_x,p_y"));
    let rows: Vec<&str> = lines.collect();
    let mut expected = Vec::new();
    for k in 1..=3 {
        let alone = read(&format!("e{k}.csv"));
        assert_eq!(alone.lines().next(), Some("t,x,y,p_x,p_y"));
        expected.extend(alone.lines().skip(1).map(|l| format!("e_{k},{l}")));
    }
    assert_eq!(expected.len(), 3 * 101);
    assert_eq!(rows, expected);
    let json: serde_json::Value = serde_json::from_str(&read("e.json")).unwrap();
    let runs = json["runs"].as_array().expect("one object per member");
    let names: Vec<&str> = runs.iter().map(|r| r["run"].as_str().unwrap()).collect();
    assert_eq!(names, ["e_1", "e_2", "e_3"]);
    for (k, r) in runs.iter().enumerate() {
        // Each member starts at its own y: 0, 0.1, 0.2.
        let ys = r["columns"][2]["values"].as_array().unwrap();
        assert_eq!((r["columns"][2]["name"].as_str(), ys.len()), (Some("y"), 101));
        assert!((ys[0].as_f64().unwrap() - 0.1 * k as f64).abs() < 1e-15, "{k}");
    }
    let section = read("p.csv");
    let members: Vec<&str> = section.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(members, ["e_1", "e_2", "e_3"], "{section}");
    assert_eq!(section.lines().nth(3).unwrap(), format!("e_3,{}", read("p3.csv").lines().nth(1).unwrap()));
}
