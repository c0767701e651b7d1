//! The REPL on a real terminal: the `lagrangian` binary is started on a
//! pseudo-terminal (rexpect), so rustyline runs in raw mode as it does for a person, keys are
//! typed as bytes (Enter is `\r`, Ctrl-C the byte 0x03 that the terminal turns into SIGINT
//! while a statement runs, Ctrl-D 0x04, the up arrow `ESC [ A`), and what the terminal shows
//! is read back with escape sequences stripped.
//!
//! Synchronisation is by what the screen shows (a result, the progress bar, the prompt),
//! never by sleeping; every wait has a generous limit (60 s) so a loaded machine is slow but
//! not flaky, and a regression fails instead of hanging. The only timed assertion is the
//! Ctrl-C latency, measured from the byte sent to the prompt shown again.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use rexpect::process::wait::WaitStatus;
use rexpect::session::{spawn_with_options, Options, PtySession};

const PROMPT: &str = "lagrangian> ";

/// The limit of every wait for the screen (a stuck REPL fails the test after this).
const WAIT_MS: u64 = 60_000;

/// The REPL on a fresh terminal, with `home` as its home and working directory and the
/// history file at `history` (`$LAGRANGIAN_HISTORY`); no derivation cache on disk.
fn start(home: &Path, history: &Path) -> PtySession {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    cmd.args(["repl", "--no-cache"])
        .current_dir(home)
        .env("HOME", home)
        .env("LAGRANGIAN_HISTORY", history)
        .env("TERM", "xterm")
        .env_remove("XDG_DATA_HOME")
        .env_remove("XDG_CACHE_HOME")
        .env_remove("LAGRANGIAN_CACHE_DIR")
        .env_remove("LAGRANGIAN_PROGRESS")
        .env_remove("NO_COLOR");
    let mut p = spawn_with_options(cmd, Options { timeout_ms: Some(WAIT_MS), strip_ansi_escape_codes: true })
        .expect("cannot start the REPL on a pseudo-terminal");
    p.exp_string("Ctrl-D quits").expect("no banner");
    p.exp_string(PROMPT).expect("no prompt");
    p
}

/// rexpect keeps each byte read as one `char` (Latin-1): a needle is searched for in that
/// form ...
fn raw(needle: &str) -> String {
    needle.bytes().map(char::from).collect()
}

/// ... and what was read is turned back into UTF-8 text.
fn text(read: &str) -> String {
    String::from_utf8_lossy(&read.chars().map(|c| c as u32 as u8).collect::<Vec<u8>>()).into_owned()
}

/// Types `keys` (a line ends with `\r`, the Enter key in raw mode).
fn type_keys(p: &mut PtySession, keys: &str) {
    p.send(keys).expect("cannot write to the terminal");
    p.flush().expect("cannot write to the terminal");
}

/// Types `line` and Enter, waits for `shows` in the output, then for the next prompt;
/// returns everything shown from the end of the typed line to the prompt.
fn enter(p: &mut PtySession, line: &str, shows: &str) -> String {
    type_keys(p, &format!("{line}\r"));
    let before = p.exp_string(&raw(shows)).unwrap_or_else(|e| panic!("`{line}` did not show `{shows}`: {e}"));
    let after = p.exp_string(PROMPT).unwrap_or_else(|e| panic!("no prompt after `{line}`: {e}"));
    text(&format!("{before}{}{after}", raw(shows)))
}

/// Types `line`, a statement that prints nothing, and Enter; waits for the next prompt and
/// checks that no error came before it. (Rustyline echoes the keys of a short line without
/// redrawing the prompt, so the next prompt is the one after the statement ran.)
fn silent(p: &mut PtySession, line: &str) {
    type_keys(p, &format!("{line}\r"));
    let shown = text(&p.exp_string(PROMPT).unwrap_or_else(|e| panic!("no prompt after `{line}`: {e}")));
    assert!(!shown.contains('×'), "`{line}`: {shown}");
}

/// Waits for the process to end after Ctrl-D and returns its exit code.
fn exit_code(p: &mut PtySession) -> i32 {
    p.exp_eof().expect("the REPL did not end");
    match p.process.wait().expect("cannot wait for the REPL") {
        WaitStatus::Exited(_, code) => code,
        other => panic!("the REPL ended with {other:?}"),
    }
}

/// Every file under `dir`, recursively.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                todo.push(path);
            } else {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn a_terminal_session_derives_recovers_is_interrupted_and_keeps_its_history() {
    let tmp = tempfile::tempdir().unwrap();
    let home = tmp.path().join("home");
    let conf = tmp.path().join("conf");
    std::fs::create_dir_all(&home).unwrap();
    let history = conf.join("history");

    // Session 1.
    let mut p = start(&home, &history);
    silent(&mut p, "coordinates x");
    silent(&mut p, "parameters m = 2, k = 3 positive");
    silent(&mut p, "L = 1/2 m x'^2 - 1/2 k x^2");
    // E_x = d/dt ∂L/∂ẋ − ∂L/∂x = m ẍ + k x = 0 (PHYSICS.md (2.28) with sin θ → x), printed
    // with ẍ as x and a combining diaeresis; the typed line has none of it.
    let shown = enter(&mut p, "el", "E_x: k x + m x\u{308} = 0");
    assert!(!shown.contains('×'), "{shown}");

    // An unclosed bracket: Enter asks for more, a blank line gives up with one error, and
    // the session goes on.
    type_keys(&mut p, "print (x + 1\r");
    let shown = enter(&mut p, "", "a `(` is never closed");
    // On a terminal a diagnostic is drawn by miette: its code, then `×` and the message.
    assert_eq!(shown.matches('×').count(), 1, "one error for the unfinished entry: {shown}");
    assert!(shown.contains("scene::syntax"), "{shown}");
    enter(&mut p, "print 20 + 22", "42");

    // Ctrl-C during a long simulation (10⁸ steps of rk4, minutes if nothing stopped it): the
    // bar appears after a second on a terminal, then the real ^C byte goes through the pty.
    type_keys(&mut p, "simulate x = 1, x' = 0 for t in 0..10000 with rk4 dt = 0.0001 as spin\r");
    p.exp_string("spin [").expect("no progress bar for the long run");
    let sent = Instant::now();
    p.send_control('c').unwrap();
    let stopped = text(&p.exp_string(PROMPT).expect("no prompt after Ctrl-C"));
    let took = sent.elapsed();
    assert!(stopped.contains("interrupted"), "{stopped}");
    assert!(took < Duration::from_secs(1), "took {took:?} from Ctrl-C to the prompt");
    // The definitions made before are intact: a short run of the same L works.
    let shown =
        enter(&mut p, "simulate x = 1, x' = 0 for t in 0..1 with rk4 dt = 0.01 as short", "from t = 0 to t = 1");
    assert!(shown.contains("short: rk4"), "{shown}");
    assert!(!shown.contains('×'), "{shown}");

    // The last line of this session, recalled in the next.
    enter(&mut p, "print 1234 + 4321", "5555");
    p.send_control('d').unwrap();
    assert_eq!(exit_code(&mut p), 0, "Ctrl-D ends the REPL cleanly");

    // Session 2: the up arrow recalls the previous session's last line; Enter runs it (the
    // sum is shown although this session never typed its digits).
    let mut p = start(&home, &history);
    let shown = enter(&mut p, "\x1b[A", "5555");
    assert!(shown.contains("1234 + 4321"), "the recalled line is shown: {shown}");
    p.send_control('d').unwrap();
    assert_eq!(exit_code(&mut p), 0);

    // The history is in the configured file, and nowhere else: nothing in the home or
    // working directory, nothing else beside the file.
    let text = std::fs::read_to_string(&history).unwrap();
    for line in ["coordinates x", "el", "print 20 + 22", "print 1234 + 4321"] {
        assert!(text.lines().any(|l| l == line), "`{line}` missing from the history file: {text}");
    }
    assert_eq!(files_under(&conf), vec![history.clone()]);
    assert_eq!(files_under(&home), Vec::<PathBuf>::new(), "files written outside the history location");
}

#[test]
fn without_the_variable_the_history_goes_to_the_data_directory_under_home() {
    let tmp = tempfile::tempdir().unwrap();
    let home = tmp.path();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    cmd.args(["repl", "--no-cache"])
        .current_dir(home)
        .env("HOME", home)
        .env("TERM", "xterm")
        .env_remove("LAGRANGIAN_HISTORY")
        .env_remove("XDG_DATA_HOME")
        .env_remove("LAGRANGIAN_PROGRESS");
    let mut p = spawn_with_options(cmd, Options { timeout_ms: Some(WAIT_MS), strip_ansi_escape_codes: true })
        .expect("cannot start the REPL on a pseudo-terminal");
    p.exp_string(PROMPT).expect("no prompt");
    enter(&mut p, "print 2 + 3", "5");
    p.send_control('d').unwrap();
    assert_eq!(exit_code(&mut p), 0);
    let expected = home.join(".local").join("share").join("lagrangian").join("history");
    assert_eq!(files_under(home), vec![expected.clone()]);
    let text = std::fs::read_to_string(&expected).unwrap();
    assert!(text.lines().any(|l| l == "print 2 + 3"), "{text}");
}
