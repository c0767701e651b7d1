//! Progress of long simulations: the library reports the fraction done up to the end of the
//! time span, with and without events; a piped run stays quiet; a forced bar
//! (`LAGRANGIAN_PROGRESS=always`) is driven to 100 %.

use std::process::Command;

use lagrangian::integrate::Crossing;
use lagrangian::simulate::{self, CompileRequest, EventSpec, Family, Formulation, MethodId, RunOptions};
use lagrangian::{parse_with, Declarations, Symbol};

/// Integrates the pendulum `H = p²/2 − cos θ` over `0..t1` with `name`, recording every
/// progress report.
fn reports(name: &str, t1: f64, with_event: bool) -> (Vec<f64>, usize) {
    let decls = Declarations::new();
    let h = parse_with("p_θ^2/2 - cos(θ)", &decls).unwrap();
    let m = MethodId::from_name(name).unwrap();
    let formulation = match m.family() {
        Family::Splitting => Formulation::Separable {
            t: parse_with("p_θ^2/2", &decls).unwrap(),
            v: parse_with("-cos(θ)", &decls).unwrap(),
        },
        _ => Formulation::Hamiltonian(h),
    };
    let events = if with_event { vec![parse_with("θ", &decls).unwrap()] } else { vec![] };
    let req = CompileRequest { coords: vec![Symbol::new("θ")], formulation, params: vec![], form: m.form(), events };
    let compiled = simulate::compile(&req).unwrap();
    let mut run = RunOptions::new(m, 0.0, t1);
    run.dt = Some(0.001);
    if with_event {
        run.events = vec![EventSpec { index: 0, crossing: Crossing::Rising, terminal: false }];
    }
    let mut seen = Vec::new();
    let tr = simulate::integrate(&compiled, &[1.0, 0.0], &run, &mut |f| seen.push(f)).unwrap();
    (seen, tr.events.len())
}

#[test]
fn a_long_simulation_reports_progress_up_to_its_end() {
    // 10⁵ steps: reports every 256 steps, then the end.
    for (name, with_event) in [("leapfrog", false), ("rk4", false), ("leapfrog", true), ("gauss4", true)] {
        let (seen, events) = reports(name, 100.0, with_event);
        assert!(seen.len() > 100, "{name}: only {} reports", seen.len());
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{name}: progress went back");
        assert_eq!(*seen.last().unwrap(), 1.0, "{name}");
        // Halfway through the run the reports had passed the middle of the span.
        let mid = seen[seen.len() / 2];
        assert!((0.3..0.7).contains(&mid), "{name}: {mid}");
        if with_event {
            // θ rises through 0 once per period 2π/ω₀·(1 + …) ≈ 6.7 (amplitude 1): about 15 times.
            assert!((10..20).contains(&events), "{name}: {events} events");
        }
    }
}

const LONG: &str = "coordinates θ\nparameters g = 9.81 positive\nH = p_θ^2/2 - g cos(θ)\n\
                    simulate θ = 1, p_θ = 0 for t in 0..T with yoshida8 dt = 0.001 record when θ = 0 as long\n\
                    export from long to long.csv\n";

fn run(t1: &str, progress: Option<&str>) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.scene");
    std::fs::write(&path, LONG.replace("..T", &format!("..{t1}"))).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    cmd.arg("run").arg(&path).arg("--no-cache").current_dir(dir.path()).env_remove("LAGRANGIAN_PROGRESS");
    if let Some(p) = progress {
        cmd.env("LAGRANGIAN_PROGRESS", p);
    }
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Whether the bar shows is decided by a condition (stderr is a pipe, `LAGRANGIAN_PROGRESS`),
/// not by how long the run took: the same run that draws a bar when forced draws nothing when
/// piped. (That a terminal bar waits for its delay is tested in `scene::progress` with a
/// start time set in the past, so no test depends on this host's speed.)
#[test]
fn a_piped_run_shows_no_bar_however_long() {
    let forced = run("100", Some("always"));
    assert!(forced.lines().count() > 1, "the run reported no progress to draw: {forced}");
    assert_eq!(run("100", None), "");
}

#[test]
fn a_forced_bar_is_driven_to_completion() {
    let stderr = run("100", Some("always"));
    let lines: Vec<&str> = stderr.lines().collect();
    assert!(!lines.is_empty(), "{stderr}");
    assert!(lines.iter().all(|l| l.starts_with("long [")), "{stderr}");
    assert!(lines.last().unwrap().contains("100%"), "{stderr}");
    // `never` wins over everything.
    assert_eq!(run("100", Some("never")), "");
}

// Formerly the unit tests of `src/scene/engine/progress.rs`.
mod unit {
    use lagrangian::scene::engine::progress::*;
    use std::time::Duration;

    #[test]
    fn a_bar_is_drawn_only_on_a_terminal_unless_forced() {
        assert_eq!(Draw::choose(false, None), Draw::Hidden);
        assert_eq!(Draw::choose(true, None), Draw::Terminal);
        assert_eq!(Draw::choose(true, Some("never")), Draw::Hidden);
        assert_eq!(Draw::choose(false, Some("always")), Draw::Lines);
    }

    /// A progress report that started `ago` before now.
    fn started(draw: Draw, ago: Duration) -> Progress {
        let mut p = Progress::new("run", draw);
        p.backdate(ago);
        p
    }

    /// The terminal bar appears once the run has lasted [`Draw::DELAY`], and not if it is
    /// nearly done by then; a hidden one never does however long the run. The start time is
    /// set in the past, so the test does not depend on how fast this host runs.
    #[test]
    fn a_terminal_bar_waits_for_its_delay() {
        let mut fresh = started(Draw::Terminal, Duration::ZERO);
        fresh.update(0.5);
        assert!(!fresh.shown(), "a bar appeared before the delay");
        let mut late = started(Draw::Terminal, 2 * Draw::DELAY);
        late.update(0.5);
        assert!(late.shown(), "no bar after twice the delay");
        late.finish();
        let mut nearly_done = started(Draw::Terminal, 2 * Draw::DELAY);
        nearly_done.update(0.95);
        assert!(!nearly_done.shown(), "a bar appeared for a run that was nearly done");
        let mut hidden = started(Draw::Hidden, 100 * Draw::DELAY);
        hidden.update(0.5);
        assert!(!hidden.shown());
    }

    #[test]
    fn progress_never_moves_back_and_a_hidden_one_draws_nothing() {
        let mut p = Progress::new("run", Draw::Hidden);
        for f in [0.2, 0.1, f64::NAN, 0.7, 1.5] {
            p.update(f);
        }
        assert_eq!(p.fraction(), 1.0);
        assert!(!p.shown());
    }
}
