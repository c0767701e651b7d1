//! The unclear messages of the hostile run, each with the text that replaced it: what went
//! wrong, where, and what would work. Every test states the old text it guards against.

use std::io::{BufRead, BufReader, Write};
use std::process::Stdio;
use std::sync::mpsc;
use std::time::Duration;

use crate::support::{piped_repl, run, run_scene_in};

const OSCILLATOR: &str = "coordinates x\nparameters m = 1, k = 1\nL = 1/2 m x'^2 - 1/2 k x^2\n";

/// A fixed-step run that blows up: the last accepted time and state once, in short numbers,
/// and the step as the likely cause (was: the state written out as 150-digit integers, then a
/// second time and a second, internal stage state from the right-hand side).
#[test]
fn a_fixed_step_blow_up_names_one_state_briefly_and_the_step() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "coordinates x\nL = 1/2 x'^2 - 1/2 x^4\nsimulate x = 1e3, x' = 0 for t in 0..10 with rk4 dt = 0.1 as r\nexport x from r to r.csv\n";
    let (code, _, err) = run_scene_in(dir.path(), scene, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("integration stopped at t = 0.2"), "{err}");
    assert_eq!(err.matches("at t = ").count(), 1, "one time only: {err}");
    assert!(err.contains("the force became infinite or NaN"), "{err}");
    assert!(err.contains("dt = 0.1") && err.contains("halve `dt`"), "{err}");
    // No number in the message is longer than 24 characters.
    let longest = err.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-')).map(str::len).max();
    assert!(longest.unwrap_or(0) <= 24, "{err}");
}

/// The adaptive step budget: the message says how many steps the span needs and how to ask
/// for them, and asking for them works (was: "the problem is stiff" for an oscillator, with no
/// way to raise the budget).
#[test]
fn a_spent_step_budget_names_max_steps_and_the_named_budget_runs() {
    let dir = tempfile::tempdir().unwrap();
    let run_with = |budget: &str| {
        let scene = format!(
            "{OSCILLATOR}simulate x = 1, x' = 0 for t in 0..2000 with dop853 tol = 1e-9 {budget} as r\nexport x from r to r.csv\n"
        );
        run_scene_in(dir.path(), &scene, &[])
    };
    let (code, _, err) = run_with("max_steps = 1000");
    assert_eq!(code, 2, "{err}");
    let err = err.replace("\n  │ ", " ");
    assert!(!err.contains("so the problem is stiff"), "{err}");
    let ask = err.split("`max_steps = ").nth(1).and_then(|s| s.split('`').next()).expect("a budget to ask for");
    let steps: f64 = ask.parse().unwrap();
    assert!(steps > 1000.0, "{err}");
    let (code, out, err) = run_with(&format!("max_steps = {ask}"));
    assert_eq!(code, 0, "the budget the message asks for is enough: {out}{err}");
    // The run reached its end: x(2000) = cos(2000) to the tolerance's accumulated error.
    let csv = std::fs::read_to_string(dir.path().join("r.csv")).unwrap();
    let last: Vec<f64> = csv.lines().last().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    assert_eq!(last[0], 2000.0);
    assert!((last[1] - 2000f64.cos()).abs() < 1e-4, "{last:?}");
    // A malformed budget is refused at its place.
    let (code, _, err) = run_with("max_steps = 2.5");
    assert_eq!(code, 2);
    assert!(err.contains("`max_steps` is a whole number of steps"), "{err}");
}

/// Options after the run's name (was: "expected end of statement, found `r`" at `record`).
#[test]
fn options_after_the_name_say_the_name_goes_last() {
    let dir = tempfile::tempdir().unwrap();
    for scene in [
        format!("{OSCILLATOR}simulate x = 1, x' = 0 for t in 0..1 as r record when x = 0\n"),
        format!("{OSCILLATOR}simulate x = 1, x' = 0 for t in 0..1 as r\n    record when x = 0\n"),
    ] {
        let (code, _, err) = run_scene_in(dir.path(), &scene, &[]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains("`as r` ends the statement, but `record` follows it"), "{err}");
        assert!(err.contains("`… record when x = 0 as r`"), "{err}");
    }
}

/// `is-canonical "Q = , P = q"`: the caret under the empty side in the whole map (was: "empty
/// input" at column 1 of a blank snippet).
#[test]
fn an_empty_side_of_a_map_is_located_in_the_map() {
    let (code, _, err) = run(&["is-canonical", "Q = , P = q", "--coords", "q"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("`Q =` has no expression after `=` (line 1, column 5)"), "{err}");
    assert!(err.contains("  | Q = , P = q\n  |     ^"), "{err}");
    // An error inside the second side points into the whole map too.
    let (code, _, err) = run(&["is-canonical", "Q = p_q, P = -q +* 2", "--coords", "q"]);
    assert_eq!(code, 2);
    assert!(err.contains("column 18"), "{err}");
}

/// A chaos indicator of a phase-space Lagrangian (was: "no starting value for `p_x`").
#[test]
fn megno_of_a_first_order_lagrangian_says_to_write_h() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "coordinates x, y\nL = x y' - 1/2 (x^2 + y^2)\nmegno x = 1, y = 0 for t in 0..10\n";
    let (code, _, err) = run_scene_in(dir.path(), scene, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("first order in its velocities"), "{err}");
    assert!(err.contains("p_y = x"), "{err}");
    assert!(!err.contains("no starting value"), "{err}");
}

/// Carriage returns alone end lines (old Mac files; was: the whole file one line, "line 0"/1).
#[test]
fn carriage_returns_alone_end_lines() {
    let dir = tempfile::tempdir().unwrap();
    let good = format!("{OSCILLATOR}simulate x = 1, x' = 0 for t in 0..1 as r\nexport x from r to r.csv\n")
        .replace('\n', "\r");
    let (code, out, err) = run_scene_in(dir.path(), &good, &[]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(dir.path().join("r.csv").exists());
    let bad = "coordinates x\rL = 1/2 x'^2\rsimulate oops\r";
    let (code, _, err) = run_scene_in(dir.path(), bad, &[]);
    assert_eq!(code, 2);
    assert!(err.contains("test.scene:3:"), "the third line: {err}");
}

/// One degree of freedom in an ensemble: no fixed coordinates before `for each` (was:
/// "expected `'`" at `for`).
#[test]
fn a_one_dof_ensemble_needs_no_fixed_values() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{OSCILLATOR}E = 1/2 m x'^2 + 1/2 k x^2\nsimulate for each x in 0..1 step 0.5 on E = 1/2 solve x' > 0 for t in 0..1 as e\nexport x, x' from e to e.csv\n"
    );
    let (code, out, err) = run_scene_in(dir.path(), &scene, &[]);
    assert_eq!(code, 0, "{out}{err}");
    let csv = std::fs::read_to_string(dir.path().join("e.csv")).unwrap();
    // Each member starts on E = 1/2: x'(0) = sqrt(1 - x(0)^2).
    for (member, x0) in [("e_1", 0.0f64), ("e_2", 0.5), ("e_3", 1.0)] {
        let first = csv.lines().find(|l| l.starts_with(&format!("{member},"))).expect("the member's rows");
        let v: Vec<f64> = first.split(',').skip(1).map(|s| s.parse().unwrap()).collect();
        assert!((v[1] - x0).abs() < 1e-15 && (v[2] - (1.0 - x0 * x0).sqrt()).abs() < 1e-12, "{first}");
    }
}

/// `constraint 1 = 0`: the scene uses the command line's words (was: "involves no coordinate"
/// in the scene, "contradictory" on the command line).
#[test]
fn constant_constraints_read_the_same_on_both_front_ends() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, scene_err) = run_scene_in(dir.path(), &format!("{OSCILLATOR}constraint 1 = 0\n"), &[]);
    assert_eq!(code, 2);
    let (code, _, cli_err) = run(&["el", "1/2 m x'^2", "--coords", "x", "--constraint", "1 - 0"]);
    assert_eq!(code, 2);
    for err in [&scene_err, &cli_err] {
        assert!(err.contains("is contradictory: it reduces to 1 = 0, which never holds"), "{err}");
    }
}

/// An energy that is infinite at the start is said once (was: a drift warning "max |Δh|
/// (h₀ = 0) = inf" for a run that is fine).
#[test]
fn an_energy_infinite_at_the_start_is_named_not_measured() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{OSCILLATOR}simulate x = 1e200, x' = 0 for t in 0..1 with rk4 dt = 0.01 as r\nexport x from r to r.csv\n"
    );
    let (code, out, err) = run_scene_in(dir.path(), &scene, &[]);
    assert_eq!(code, 0, "{err}");
    let all = format!("{out}{err}");
    assert!(all.contains("the energy h is inf at the start, so its drift cannot be checked"), "{all}");
    assert!(!all.contains("h₀ = 0"), "{all}");
}

/// The piped REPL reads an indented line as the continuation of the statement above, as a
/// scene file does (was: "unknown statement `record`").
#[test]
fn the_piped_repl_continues_indented_lines() {
    let dir = tempfile::tempdir().unwrap();
    let input = format!(
        "{OSCILLATOR}simulate x = 1, x' = 0 for t in 0..7\n    record when x = 0 as r\nexport x from r to r.csv\n"
    );
    let out = piped_repl(dir.path())
        .spawn()
        .and_then(|mut child| {
            child.stdin.take().unwrap().write_all(input.as_bytes())?;
            child.wait_with_output()
        })
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(!text.contains("unknown statement"), "{text}");
    // x = cos t crosses zero at π/2 and 3π/2 before t = 7 (5π/2 ≈ 7.85 is after it).
    assert!(text.contains("2 events"), "{text}");
    assert!(dir.path().join("r.csv").exists(), "{text}");
}

/// …and a program that sends one statement and waits for its answer is answered before it
/// sends the next (the REPL looks ahead only at input already there).
#[test]
fn the_piped_repl_answers_before_the_next_line_arrives() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = piped_repl(dir.path()).stderr(Stdio::null()).spawn().unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            if tx.send(line.unwrap_or_default()).is_err() {
                break;
            }
        }
    });
    stdin.write_all(b"coordinates x\nL = 1/2 x'^2 - 1/2 x^2\n").unwrap();
    stdin.flush().unwrap();
    // The answer is `L = ẋ²/2 - x²/2`; the echo of the input has no `x²`.
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let answered =
        std::iter::from_fn(|| rx.recv_timeout(deadline.saturating_duration_since(std::time::Instant::now())).ok())
            .any(|l| l.starts_with("L = ") && l.contains("x²/2"));
    assert!(answered, "the definition of L was answered while the next line had not come");
    drop(stdin);
    assert!(child.wait().unwrap().success());
}

/// U11: six causes of a singular Hessian in `ritz`, each named with what would work (was, for
/// every one: "the Hessian of S(a) is singular: the trial coefficients are not independent";
/// a non-finite gradient was "Newton's method … did not converge in 50 steps"). Each case is
/// the oscillator or a one-line L on 0..1 with a trial path whose S is known in closed form.
#[test]
fn ritz_names_the_cause_of_a_singular_hessian() {
    let ritz = |l: &str, path: &str, names: &str, ends: (&str, &str), extra: &[&str]| {
        let args = ["ritz", l, "--coords", "x", "--trial", path, "--unknowns", names, "--span", "0,1"];
        let (code, out, err) = run(&[&args[..], &["--from", ends.0, "--to", ends.1], extra].concat());
        (code, out, err.replace("\n  │ ", " "))
    };
    let old = "the trial coefficients are not independent";
    let refused = |(code, out, err): (i32, String, String)| {
        assert_eq!((code, out.as_str()), (2, ""), "{err}");
        assert!(!err.contains(old), "{err}");
        err
    };
    let osc = "1/2 x'^2 - 1/2 x^2";
    // A coefficient that the trial path does not contain.
    let err = refused(ritz(osc, "t + t (1 - t) a", "a,b", ("0", "1"), &[]));
    assert!(err.contains("`b` does not appear in L(trial): the trial path does not depend on it"), "{err}");
    // Two coefficients that enter only as one combination, read off the Hessian's null
    // vector: 2a − 3b is unchanged along (1, 2/3), so S depends on a − 1.5 b.
    let err = refused(ritz(osc, "t + t (1 - t) (2 a - 3 b)", "a,b", ("0", "1"), &[]));
    assert!(err.contains("`a` and `b` enter S only as the combination a − 1.5 b"), "{err}");
    assert!(err.contains("a changes by 1 and b by 0.666667"), "{err}");
    let err = refused(ritz(osc, "t + t (1 - t) (a + b + c t)", "a,b,c", ("0", "1"), &[]));
    assert!(err.contains("`a` and `b` enter S only as the combination a + b"), "{err}");
    assert!(!err.contains("`c`"), "c is independent: {err}");
    // L = x: S = 1/2 + a/6 is linear in a, with no stationary point.
    let err = refused(ritz("x", "t + t (1 - t) a", "a", ("0", "1"), &[]));
    assert!(
        err.contains("S is linear in `a` (∂S/∂a = 0.166667 whatever a is), so it has no stationary point"),
        "{err}"
    );
    // L = x' is a total derivative: S = x(1) − x(0) = 1 whatever a.
    let err = refused(ritz("x'", "t + t (1 - t) a", "a", ("0", "1"), &[]));
    assert!(err.contains("S does not depend on `a`"), "{err}");
    // L = x^3 − 3x, x = a t(1 − t): S = a³/140 − a/2 has S'' = 0 at the guess a = 0 only.
    // The guess the message offers leads to the stationary point a = √(70/3).
    let err = refused(ritz("x^3 - 3 x", "a t (1 - t)", "a", ("0", "0"), &[]));
    assert!(err.contains("singular at a = 0 (the starting guess), though not elsewhere"), "{err}");
    let offered = err.split("e.g. a = ").nth(1).and_then(|s| s.split(',').next()).expect("a guess");
    let (code, out, err) = ritz("x^3 - 3 x", "a t (1 - t)", "a", ("0", "0"), &["--guess", offered]);
    assert_eq!(code, 0, "{err}");
    let a: f64 = out.lines().find_map(|l| l.strip_prefix("a ≈ ")).unwrap().trim().parse().unwrap();
    assert!((a - (70.0f64 / 3.0).sqrt()).abs() < 1e-12, "{out}");
    // L = √x at x = 0: ∂L/∂a = t(1 − t)/(2√x) is infinite on the whole span.
    let err = refused(ritz("sqrt(x)", "a t (1 - t)", "a", ("0", "0"), &[]));
    assert!(err.contains("∂S/∂a is inf at a = 0 (the starting guess)"), "{err}");
    assert!(err.contains("e.g. at t = 0.0005"), "{err}");
    // A Hessian below the solver's pivot floor: L scaled by 1e-305 (S'' = m/3 · … ≈ 3e-306).
    let scaled = "1/2 m x'^2 - 1/2 m x^2";
    let err = refused(ritz(scaled, "t + t (1 - t) a", "a", ("0", "1"), &["--set", "m=1e-305"]));
    assert!(err.contains("too small for double precision: its largest entry is 3e-306"), "{err}");
    // A guess that is already stationary, though degenerate (x^4: S = a⁴/630, S'' = 0 at
    // a = 0): the Newton step is zero, so a = 0 is the answer, not a refusal.
    let (code, out, err) = ritz("x^4", "a t (1 - t)", "a", ("0", "0"), &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("a ≈ 0.000000000000000e0") && out.contains("S ≈ 0.000000000000000e0"), "{out}");
}
