//! The REPL driven through standard input: a session of more than fifteen statements with
//! three errors, the transcript checked line by line, and the history persisted between
//! sessions in `$LAGRANGIAN_HISTORY`.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

fn session(input: &str, history: &Path, dir: &Path) -> (i32, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .env("LAGRANGIAN_HISTORY", history)
        .env("LAGRANGIAN_CACHE_DIR", "off")
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stdout).into_owned())
}

const SESSION: &str = "\
coordinates θ
parameters m = 1, l = 1, g = 9.81 positive
T = 1/2 m l^2 θ'^2
V = m g l (1 - cos(θ))
L = T - V
print L as plain
simulat θ = 1
H = p_θ^2/(2 m l^2) + V
print H
latex
pb θ, H as plain
simulate θ = 1, p_θ = 0 for t in 0..1 with leapfrog dt = 0.01
print θ + * 2
print H + q
energy
format plain
print 2 T
help pb
plot phase to phase.svg
export energy to eqs.json
";

#[test]
fn a_session_survives_its_errors() {
    let dir = tempfile::tempdir().unwrap();
    let history = dir.path().join("hist").join("history");
    let (code, out) = session(SESSION, &history, dir.path());
    assert_eq!(code, 0, "{out}");
    // Every entry is echoed after the prompt, so the transcript reads like the session.
    assert_eq!(out.matches("lagrangian> ").count(), 20, "{out}");
    let after = |stmt: &str| -> String {
        let start = out.find(&format!("lagrangian> {stmt}\n")).unwrap_or_else(|| panic!("no `{stmt}` in {out}"));
        let rest = &out[start + "lagrangian> ".len() + stmt.len() + 1..];
        rest[..rest.find("lagrangian> ").unwrap_or(rest.len())].trim_end().to_string()
    };
    // Definitions are echoed in Unicode (the REPL's default).
    assert_eq!(after("T = 1/2 m l^2 θ'^2"), "T = l² m θ̇²/2");
    assert_eq!(after("print L as plain"), "L = l^2 m θ'^2/2 - g l m (1 - cos(θ))");
    // Error 1: an unknown statement, with a suggestion; the session goes on.
    let e1 = after("simulat θ = 1");
    assert!(e1.contains("unknown statement `simulat`") && e1.contains("did you mean `simulate`?"), "{e1}");
    assert_eq!(after("print H"), "H = g l m (1 - cos(θ)) + p_θ²/(2 l² m)");
    // `latex` reprints the last result.
    assert!(after("latex").starts_with("H = g l m \\left(1 - \\cos\\left(\\theta\\right)\\right)"), "{out}");
    // {θ, H} = ∂H/∂p_θ = p_θ/(m l²), by hand.
    assert_eq!(after("pb θ, H as plain"), "{θ, H} = p_θ/(l^2 m)");
    // The REPL runs a simulation at once and summarises it.
    let sim = after("simulate θ = 1, p_θ = 0 for t in 0..1 with leapfrog dt = 0.01");
    assert!(sim.starts_with("run1: leapfrog from t = 0 to t = 1 in 100 steps; final θ = "), "{sim}");
    // Error 2: a missing operand; error 3: an undefined symbol.
    assert!(after("print θ + * 2").contains("expected a name or an expression, found `*`"), "{out}");
    let e3 = after("print H + q");
    assert!(e3.contains("undefined symbol `q`") && e3.contains("print H + q") && e3.contains('┬'), "{e3}");
    // With L defined, `energy` is h = θ' ∂L/∂θ' − L = ½ m l² θ'² + V (by hand).
    assert_eq!(after("energy"), "E = g l m (1 - cos(θ)) + l² m θ\u{307}²/2");
    assert_eq!(after("print 2 T"), "l^2 m θ'^2");
    assert!(after("help pb").contains("example: pb θ, p_θ"));
    assert_eq!(after("plot phase to phase.svg"), "wrote ./phase.svg");
    assert!(dir.path().join("phase.svg").exists());
    assert_eq!(after("export energy to eqs.json"), "wrote ./eqs.json");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("eqs.json")).unwrap()).unwrap();
    assert_eq!(json[0]["name"], "energy");
    assert_eq!(json[0]["value"], "g l m (1 - cos(θ)) + l^2 m θ'^2/2");
}

#[test]
fn history_persists_between_sessions() {
    let dir = tempfile::tempdir().unwrap();
    let history = dir.path().join("data").join("history");
    let (code, _) = session("coordinates x\nprint (x +\n  1)\n", &history, dir.path());
    assert_eq!(code, 0);
    assert!(history.exists(), "no history file written");
    // A multi-line entry is one history item.
    let (code, out) = session("history\n", &history, dir.path());
    assert_eq!(code, 0);
    assert!(out.contains("   1  coordinates x\n"), "{out}");
    assert!(out.contains("   2  print (x +   1)\n"), "{out}");
    assert!(out.contains("   3  history\n"), "{out}");
}

#[test]
fn a_loaded_scene_runs_in_the_session() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("osc.scene"), "coordinates x\nparameters k positive\nH = p_x^2/2 + k x^2/2\n")
        .unwrap();
    let history = dir.path().join("history");
    let (code, out) = session("load osc.scene\npb x, H as plain\nload missing.scene\n", &history, dir.path());
    assert_eq!(code, 0);
    assert!(out.contains("loaded ./osc.scene"), "{out}");
    assert!(out.contains("{x, H} = p_x"), "{out}");
    assert!(out.contains("cannot read `./missing.scene`"), "{out}");
}

/// `help` with a topic of several words through the REPL binary: the row's form, and an
/// unknown topic shown as an error with a caret under its words, the session going on.
#[test]
fn help_takes_a_topic_of_several_words() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out) =
        session("help energy at\nhelp energy\nhelp foo bar\nhelp pb\n", &dir.path().join("h"), dir.path());
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("lagrangian> help energy at\nenergy at q = …, q' = … | energy at q = …, p_q = …\n"), "{out}");
    assert!(out.contains("\n  see also: `help energy at`\n"), "{out}");
    let err = &out[out.find("lagrangian> help foo bar").expect("the unknown topic")..];
    assert!(err.contains("no help for `foo bar`") && err.contains("help foo bar") && err.contains('┬'), "{err}");
    assert!(out.contains("example: pb θ, p_θ"), "{out}");
}

/// A statement continued over 100 000 piped lines is one entry, evaluated whole: the sum
/// 1 + 0 + 1 + … + 99 999 = 4 999 950 001. (The reader used to rescan the whole statement on
/// every line, so this took over a minute; it now reads each line once.)
#[test]
fn a_statement_of_a_hundred_thousand_piped_lines_is_one_entry() {
    let dir = tempfile::tempdir().unwrap();
    let mut input = String::from("print (1\n");
    for i in 0..100_000 {
        input += &format!("+ {i}\n");
    }
    input += ")\n";
    let (code, out) = session(&input, &dir.path().join("history"), dir.path());
    assert_eq!(code, 0, "{}", &out[out.len().saturating_sub(500)..]);
    assert_eq!(out.lines().last(), Some("4999950001"), "{}", &out[out.len().saturating_sub(500)..]);
}

/// A long-lived REPL keeps a bounded plan: one entry per derivation made the session grow
/// without end (38 MB after 10⁴ redefinitions of `L` with `el`, 23 MB now; 21 MB at 3000).
/// After 1500 derivations the plan holds at most its bound, and the answers stay right.
#[test]
fn a_long_repl_session_keeps_a_bounded_plan() {
    use lagrangian::scene::{Mode, Options, Session};
    let mut s = Session::new(Options::new(Mode::Repl));
    s.run_line("coordinates x").unwrap();
    let mut longest = 0;
    for i in 1..=1500 {
        s.run_line(&format!("L = 1/2 x'^2 - {i}/2 x^2")).unwrap();
        s.run_line("el").unwrap();
        longest = longest.max(s.plan().len());
    }
    assert!(longest <= 2048, "the plan reached {longest} entries");
    let out = s.take_output();
    let last = out.iter().rev().find(|l| l.starts_with("E_x")).expect("the last el");
    assert!(last.contains("1500 x"), "{last}");
}

// Formerly the unit tests of `src/scene/repl.rs`.
mod unit {
    use lagrangian::scene::repl::*;

    #[test]
    fn bounded_lines_end_at_newlines_and_skip_overlong_ones() {
        let mut input = std::io::Cursor::new(b"ab\r\n\nxxxxxxxxxx\ncd".to_vec());
        let mut next = || read_line_bounded(&mut input, 4).map_err(|e| e.kind());
        assert_eq!(next(), Ok(Some("ab".to_string())));
        assert_eq!(next(), Ok(Some(String::new())));
        assert_eq!(next(), Err(std::io::ErrorKind::InvalidData));
        assert_eq!(next(), Ok(Some("cd".to_string())));
        assert_eq!(next(), Ok(None));
    }

    #[test]
    fn an_unfinished_statement_asks_for_more_until_a_blank_line() {
        assert!(wants_more("print (x + 1"));
        assert!(wants_more("print (x + 1\n  + 2"));
        assert!(!wants_more("print (x + 1\n"));
        assert!(!wants_more("print (x + 1\n  "));
        assert!(!wants_more("print (x + 1)"));
        // A blank first line is not a blank line after an unfinished one.
        assert!(!wants_more(""));
    }

    #[test]
    fn completes_statements_methods_and_symbols() {
        let names = vec!["θ".to_string(), "θ'".to_string(), "theta0".to_string()];
        assert_eq!(complete("sim", 3, &names), (0, vec!["simulate".to_string()]));
        let line = "simulate θ = 1 for t in 0..1 with gau";
        assert_eq!(complete(line, line.len(), &names).1, ["gauss4", "gauss6"]);
        let line = "print th";
        assert_eq!(complete(line, line.len(), &names), (6, vec!["theta0".to_string()]));
        let line = "print θ";
        assert_eq!(complete(line, line.len(), &names).1, ["θ'"]);
        // Help topics word by word: `energy` and `export` begin longer topics.
        assert_eq!(complete("help ener", 9, &names).1, ["energy"]);
        assert_eq!(complete("help energy ", 12, &names).1, ["at"]);
        assert_eq!(complete("help export p", 13, &names).1, ["poincare"]);
    }
}
