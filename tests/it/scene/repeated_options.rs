//! A setting given twice in one statement (`tol = 1e-9 … tol = 1e-6`) is refused at its second
//! clause, naming the first, instead of one value silently replacing the other; clauses that add
//! to a list (several `record when …` / `stop when …` events) still add.

use lagrangian::scene::{ErrorKind, Mode, Options, SceneError, Session};

use crate::support;

/// The harmonic oscillator H = ½ p² + ½ x²: x(t) = cos t from x = 1, p = 0.
const OSC: &str = "coordinates x\nH = 1/2 p_x^2 + 1/2 x^2\n";

/// A circle of radius 1 in Cartesian coordinates (for `stabilize`).
const CIRCLE: &str = "coordinates x, y\nL = 1/2 (x'^2 + y'^2) - y\nconstraint x^2 + y^2 = 1\n";

/// A run to animate.
const RUN: &str = "simulate x = 1, p_x = 0 for t in 0..1 with rk4 dt = 0.1 as r\n";

fn refusal(scene: &str) -> SceneError {
    let mut s = Session::new(Options::new(Mode::Scene));
    match s.run_scene("test.scene", scene) {
        Ok(()) => panic!("accepted:\n{scene}"),
        Err(e) => e,
    }
}

/// Each statement with one setting twice: the refusal's message, the second clause (its span)
/// and the first (named in the hint). The second clause's value differs from the first's, so
/// its text occurs once after the first and its byte position is found by `rfind`.
#[test]
fn a_setting_given_twice_is_refused_at_its_second_clause() {
    let sim = "simulate x = 1, p_x = 0 for t in 0..1";
    let chaos = "megno x = 1, p_x = 0 for t in 0..1";
    let flow = "flow x = 1, p_x = 0 for t in 0..1";
    let map = "chaos_map megno x = -1..1, p_x = -1..1 for t in 0..1";
    #[rustfmt::skip]
    let cases: Vec<(String, &str, &str, &str)> = vec![
        // (scene, message, first clause, second clause)
        (format!("{OSC}{sim} tol = 1e-9 tol = 1e-6"), "`tol` is given twice", "tol = 1e-9", "tol = 1e-6"),
        (format!("{OSC}{sim} with rk4 dt = 0.1 with gauss6"), "`with` is given twice", "with rk4", "with gauss6"),
        (format!("{OSC}{sim} with rk4 dt = 0.1 dt = 0.01"), "`dt` is given twice", "dt = 0.1", "dt = 0.01"),
        (format!("{OSC}{sim} with rk4 steps = 10 steps = 20"), "`steps` is given twice", "steps = 10", "steps = 20"),
        // `steps = N` is the step (t1 − t0)/N: with `dt` it is a second value of one setting.
        (format!("{OSC}{sim} with rk4 dt = 0.1 steps = 20"), "`steps` and `dt` both set the step", "dt = 0.1", "steps = 20"),
        (format!("{OSC}{sim} with rk4 steps = 20 dt = 0.1"), "`dt` and `steps` both set the step", "steps = 20", "dt = 0.1"),
        (format!("{OSC}{sim} every 2 every 3"), "`every` is given twice", "every 2", "every 3"),
        (format!("{OSC}{sim} with rk4 dt = 0.01 points 10 points 20"), "`points` is given twice", "points 10", "points 20"),
        (format!("{OSC}{sim} drift = 1e-6 drift = 1e-3"), "`drift` is given twice", "drift = 1e-6", "drift = 1e-3"),
        (format!("{OSC}{sim} max_steps = 100 max_steps = 1000"), "`max_steps` is given twice", "max_steps = 100", "max_steps = 1000"),
        (
            format!("{CIRCLE}simulate x = 1, y = 0, x' = 0, y' = 1 for t in 0..1 stabilize projection stabilize baumgarte = 20"),
            "`stabilize` is given twice", "stabilize projection", "stabilize baumgarte = 20",
        ),
        // An ensemble's options are a `simulate`'s.
        (
            format!("{OSC}simulate for each x in 0..1 step 0.5 on H = 1 solve p_x > 0 for t in 0..1 tol = 1e-8 tol = 1e-7"),
            "`tol` is given twice", "tol = 1e-8", "tol = 1e-7",
        ),
        // The chaos statements read the same options.
        (format!("{OSC}{chaos} tol = 1e-9 tol = 1e-6"), "`tol` is given twice", "tol = 1e-9", "tol = 1e-6"),
        (format!("{OSC}{chaos} max_steps = 100 max_steps = 1000"), "`max_steps` is given twice", "max_steps = 100", "max_steps = 1000"),
        (format!("{OSC}{chaos} time_limit = 10 time_limit = 20"), "`time_limit` is given twice", "time_limit = 10", "time_limit = 20"),
        (format!("{OSC}{flow} tol = 1e-9 tol = 1e-6"), "`tol` is given twice", "tol = 1e-9", "tol = 1e-6"),
        (format!("{OSC}{flow} points 10 points 20 to f.csv"), "`points` is given twice", "points 10", "points 20"),
        (format!("{OSC}{flow} time_limit = 10 time_limit = 20"), "`time_limit` is given twice", "time_limit = 10", "time_limit = 20"),
        // The case that was found: the map kept the last `tol`.
        (format!("{OSC}{map} tol = 1e-9 tol = 1e-6"), "`tol` is given twice", "tol = 1e-9", "tol = 1e-6"),
        (format!("{OSC}{map} points 4 points 8 to m.csv"), "`points` is given twice", "points 4", "points 8"),
        (format!("{OSC}{map} points 4 stop megno >= 5 after 1 max_steps = 10 max_steps = 20"), "`max_steps` is given twice", "max_steps = 10", "max_steps = 20"),
        // `animate`'s frame options.
        (format!("{OSC}{RUN}animate (x, 0) to a.gif fps 10 fps 20"), "`fps` is given twice", "fps 10", "fps 20"),
        (format!("{OSC}{RUN}animate (x, 0) to a.gif duration 2 size 100 duration = 3"), "`duration` is given twice", "duration 2", "duration = 3"),
        (format!("{OSC}{RUN}animate (x, 0) to a.gif size 100 size 200"), "`size` is given twice", "size 100", "size 200"),
    ];
    let mut shown = String::new();
    for (scene, message, first, second) in &cases {
        let e = refusal(scene);
        assert_eq!(e.kind, ErrorKind::Syntax, "{scene}: {e:?}");
        assert_eq!(e.message, *message, "{scene}: {e:?}");
        let at = scene.rfind(second).expect("the second clause is in the scene");
        assert!(scene.find(first).is_some_and(|f| f < at), "{scene}: the first clause comes first");
        assert_eq!(e.span, Some((at, at + second.len())), "{scene}: {e:?}");
        let hint = e.hint.as_deref().unwrap_or_default();
        assert!(hint.contains(&format!("`{first}` (given first)")), "{scene}: {hint}");
        shown.push_str(&e.render(false));
        shown.push('\n');
    }
    support::snapshot("scene_repeated_options", &shown);
}

/// Clauses that add to a list still add: two events on one run, each doing its part. From
/// x = 1, p = 0 the oscillator is x = cos t: `record when x = 0` records t = π/2, and
/// `stop when x = -0.5` ends the run at t = 2π/3 (before x = 0 is crossed again at 3π/2);
/// the section file holds both crossings.
#[test]
fn two_events_on_one_run_both_act() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{OSC}simulate x = 1, p_x = 0 for t in 0..10 tol = 1e-12 record when x = 0 stop when x = -0.5 as r\n\
         export t, x from r to run.csv\nexport poincare t, x from r to sec.csv\n"
    );
    let (code, _, err) = support::run_scene_in(dir.path(), &scene, &[]);
    assert_eq!(code, 0, "{err}");
    let run = support::read_csv(&dir.path().join("run.csv"));
    let end = *run["t"].last().unwrap();
    assert!((end - 2.0 * std::f64::consts::PI / 3.0).abs() < 1e-8, "the run ends at {end}");
    // The events' crossings, numbered by the events in order: the record, then the stop.
    let sec = support::read_csv(&dir.path().join("sec.csv"));
    assert_eq!(sec["event"], [1.0, 2.0], "{sec:?}");
    assert!((sec["t"][0] - std::f64::consts::FRAC_PI_2).abs() < 1e-8, "{sec:?}");
    assert!((sec["t"][1] - 2.0 * std::f64::consts::PI / 3.0).abs() < 1e-8, "{sec:?}");
}

/// One name twice in a statement's list of `name = …` (or of names): refused at the second,
/// where the readers kept one of the two silently (`series L about x = 0, x = 1` expanded about
/// x = 1; `average … with x = A cos(θ), x = 2 A cos(θ)` averaged the second trial function,
/// `ritz` took the first start value). `needle` ends with the second occurrence of `name`.
#[test]
fn a_name_given_twice_in_a_list_is_refused_at_its_second_occurrence() {
    let base = "coordinates x\nparameters k = 1\nL = 1/2 x'^2 - 1/2 k x^2 - 1/4 x^4\n";
    let ritz = "ritz with x = a t (1 - t) + t";
    #[rustfmt::skip]
    let cases: Vec<(String, &str, &str, &str)> = vec![
        // (statement, name, needle, what the hint names; empty for a list of names)
        ("series L about x = 0, x = 1 order 2".into(), "x", "0, x", "expansion point"),
        ("series cos(x) in x, x order 2".into(), "x", "x, x", ""),
        (format!("{ritz}, x = b t for t in 0..1 from x = 0 to x = 1 solve a, b"), "x", "+ t, x", "trial path"),
        (format!("{ritz} for t in 0..1 from x = 0, x = 1 to x = 1 solve a"), "x", "0, x", "start value"),
        (format!("{ritz} for t in 0..1 from x = 0 to x = 1, x = 2 solve a"), "x", "1, x", "end value"),
        (format!("{ritz} for t in 0..1 from x = 0 to x = 1 solve a, a"), "a", "a, a", ""),
        ("average L with x = A cos(θ), x = 2 A cos(θ) phase θ frequency ω amplitudes A".into(), "x", "(θ), x", "trial function"),
        ("average L with x = A cos(θ) phase θ frequency ω amplitudes A, A".into(), "A", "A, A", ""),
    ];
    let mut shown = String::new();
    for (stmt, name, needle, what) in &cases {
        let scene = format!("{base}{stmt}\n");
        let e = refusal(&scene);
        assert_eq!(e.kind, ErrorKind::Syntax, "{stmt}: {e:?}");
        assert_eq!(e.message, format!("`{name}` is given twice"), "{stmt}: {e:?}");
        let at = scene.rfind(needle).expect("the needle is in the scene") + needle.len() - name.len();
        assert_eq!(e.span, Some((at, at + name.len())), "{stmt}: {e:?}");
        let hint =
            if what.is_empty() { format!("name `{name}` once") } else { format!("keep one {what} for `{name}`") };
        assert_eq!(e.hint.as_deref(), Some(hint.as_str()), "{stmt}");
        shown.push_str(&e.render(false));
        shown.push('\n');
    }
    support::snapshot("scene_repeated_names", &shown);
}

/// The command line: clap refuses a single-valued flag given twice; a `name=value` list
/// (`--set`, `--params`, `--at`) refuses a name given twice, in one flag or in two, where the
/// map kept the last value (K = 0.1 of `K=0.9,K=0.1`) and `flow` the last `k`.
#[test]
fn the_command_line_refuses_a_flag_or_a_name_given_twice() {
    let map = ["map", "p = p + K sin(q)", "q = q + p", "--vars", "q,p", "--from", "1,0.5", "--steps", "3"];
    let flow = ["flow", "1/2 p_q^2 + 1/2 k q^2", "--coords", "q", "--at", "q=1,p_q=0", "--time", "1"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            [&map[..], &["--params", "K=0.9,K=0.1"]].concat(),
            "error: --params gives `K` twice (`K=0.9` and `K=0.1`); keep one",
        ),
        (
            [&map[..], &["--params", "K=0.9", "--params", "K=0.1"]].concat(),
            "error: --params gives `K` twice (`K=0.9` and `K=0.1`); keep one",
        ),
        ([&flow[..], &["--set", "k=1,k=4"]].concat(), "error: --set gives `k` twice (`k=1` and `k=4`); keep one"),
        (
            [&flow[..], &["--set", "k=1", "--tol", "1e-9", "--tol", "1e-6"]].concat(),
            "'--tol <TOL>' cannot be used multiple times",
        ),
        ([&flow[..], &["--set", "k=1", "--time", "2"]].concat(), "'--time <TIME>' cannot be used multiple times"),
    ];
    for (args, says) in &cases {
        let (code, out, err) = support::run(args);
        assert_eq!(code, 2, "{args:?}: {out}{err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    // Each value alone is accepted, and the two differ (so keeping either silently mattered).
    let last = |args: &[&str]| {
        let (code, out, err) = support::run(args);
        assert_eq!(code, 0, "{args:?}: {err}");
        out
    };
    let a = last(&[&map[..], &["--params", "K=0.9"]].concat());
    let b = last(&[&map[..], &["--params", "K=0.1"]].concat());
    assert_ne!(a, b);
}

/// `lagrangian average`: a coordinate with two `--trial`s (the average used the last) and an
/// amplitude named twice (its condition was printed twice) are refused; one of each is accepted.
#[test]
fn the_command_line_average_refuses_a_trial_or_an_amplitude_given_twice() {
    let l = "1/2 x'^2 - 1/2 x^2 - 1/4 x^4";
    for (extra, says) in [
        (&["--trial", "x = 2 A cos(θ)"][..], "error: --trial gives `x` twice; keep one trial function for it"),
        (&["--amplitudes", "A,A"][..], "error: --amplitudes gives `A` twice; name it once"),
    ] {
        let args = [&["average", l, "--trial", "x = A cos(θ)"][..], extra].concat();
        let (code, out, err) = support::run(&args);
        assert_eq!(code, 2, "{args:?}: {out}{err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    let (code, out, err) = support::run(&["average", l, "--trial", "x = A cos(θ)", "--amplitudes", "A"]);
    assert_eq!(code, 0, "{err}");
    // ⟨½ x'² − ½ x² − ¼ x⁴⟩ for x = A cos θ, θ' = ω: A²ω²/4 − A²/4 − 3A⁴/32.
    assert!(out.contains("A^2 (ω^2/4 - 3 A^2/32 - 1/4)"), "{out}");
}
