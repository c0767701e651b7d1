//! Demand-driven evaluation and the derivation cache, proved by counting what a backend is
//! asked to build. The backend here is a stand-in that records every call (the real stages
//! are exercised by the example tests); what is under test is the session's demand logic.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use lagrangian::expr::Expr;
use lagrangian::scene::backend::{CompileRequest, Compiled, Formulation, RunRequest, SystemRef};
use lagrangian::scene::{Backend, BackendError, Cache, Line, Mode, Options, Session, Status, Step, Trajectory};

#[derive(Clone, Default)]
struct Counts(Arc<Mutex<BTreeMap<&'static str, usize>>>);

impl Counts {
    fn bump(&self, what: &'static str) {
        *self.0.lock().unwrap().entry(what).or_default() += 1;
    }
    fn get(&self, what: &str) -> usize {
        self.0.lock().unwrap().get(what).copied().unwrap_or(0)
    }
}

/// Records calls; returns simple but well-formed results. Its `legendre` is exact for
/// `L = Σ q'²/2 − V(q)` (unit masses): `H = Σ p²/2 + V`.
struct Counting(Counts);

impl Backend for Counting {
    fn euler_lagrange(&self, _sys: &SystemRef, l: &Expr) -> Result<Vec<Line>, BackendError> {
        self.0.bump("el");
        Ok(vec![Line::new(l.clone(), Expr::zero())])
    }
    fn legendre(&self, sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
        self.0.bump("legendre");
        let mut at_rest = l.clone();
        let mut kinetic = Vec::new();
        for q in sys.coords {
            at_rest = at_rest.subs1(&q.prime(), &Expr::zero());
            kinetic.push(Expr::var(&format!("p_{}", q.name())).powi(2).times(&Expr::frac(1, 2)));
        }
        Ok(Expr::add(kinetic).minus(&at_rest))
    }
    fn hamilton(&self, _sys: &SystemRef, h: &Expr) -> Result<Vec<Line>, BackendError> {
        self.0.bump("hamilton");
        Ok(vec![Line::new(h.clone(), Expr::zero())])
    }
    fn conserved(&self, _sys: &SystemRef, f: &Expr, _h: bool) -> Result<Vec<Line>, BackendError> {
        self.0.bump("conserved");
        Ok(vec![Line::new(f.clone(), Expr::zero())])
    }
    fn energy(&self, _sys: &SystemRef, l: &Expr) -> Result<Expr, BackendError> {
        self.0.bump("energy");
        Ok(l.clone())
    }
    fn bracket(&self, _sys: &SystemRef, _f: &Expr, _g: &Expr) -> Result<Expr, BackendError> {
        self.0.bump("bracket");
        Ok(Expr::zero())
    }
    fn compile(&self, req: &CompileRequest) -> Result<Compiled, BackendError> {
        self.0.bump(match req.formulation {
            Formulation::Lagrangian(_) | Formulation::Equations { .. } | Formulation::Extended(_) => {
                "compile_lagrangian"
            }
            Formulation::FirstOrder(_) => "compile_first_order",
            Formulation::Hamiltonian(_) => "compile_hamiltonian",
            Formulation::Separable { .. } => "compile_separable",
            Formulation::Variational(_) => "compile_variational",
        });
        // A real compilation: the compiled system is a typed value, not a stand-in.
        lagrangian::scene::NativeBackend.compile(req)
    }
    fn integrate(
        &self,
        _c: &Compiled,
        run: &RunRequest,
        progress: &mut dyn FnMut(f64),
    ) -> Result<Trajectory, BackendError> {
        self.0.bump("integrate");
        progress(1.0);
        // A constant trajectory: enough for plots and exports to have data.
        let t: Vec<f64> =
            (0..=10).map(|i| run.options.t0 + (run.options.t1 - run.options.t0) * i as f64 / 10.0).collect();
        let y = vec![run.y0.clone(); t.len()];
        Ok(Trajectory { t, y, events: vec![], steps: 10, evaluations: 10, aux: vec![], ..Default::default() })
    }
}

fn session(counts: &Counts, out: &std::path::Path) -> Session {
    let mut opts = Options::new(Mode::Scene);
    opts.out_dir = out.to_path_buf();
    Session::with_backend(opts, Box::new(Counting(counts.clone())))
}

const OSCILLATOR: &str = "\
coordinates x
parameters k = 2 positive
L = 1/2 x'^2 - 1/2 k x^2
E = el(L)
K = conserved(L)
simulate x = 1, x' = 0 for t in 0..1 with leapfrog dt = 0.1
export to run.csv
";

#[test]
fn splitting_simulation_builds_only_the_hamiltonian_split() {
    let dir = tempfile::tempdir().unwrap();
    let counts = Counts::default();
    let mut s = session(&counts, dir.path());
    s.run_scene("osc", OSCILLATOR).unwrap();
    // Demanded: H by the Legendre transform, its split, one compile, one integration.
    assert_eq!(counts.get("legendre"), 1);
    assert_eq!(counts.get("compile_separable"), 1);
    assert_eq!(counts.get("integrate"), 1);
    // Never demanded: Euler–Lagrange, conserved quantities, brackets, Hamilton's equations,
    // a Lagrangian right-hand side.
    for never in ["el", "conserved", "bracket", "hamilton", "compile_lagrangian"] {
        assert_eq!(counts.get(never), 0, "{never} was built");
    }
    let plan = s.plan();
    let built = |step: Step| plan.iter().filter(|e| e.step == step && e.status == Status::Built).count();
    assert_eq!(built(Step::Legendre), 1);
    assert_eq!(built(Step::Split), 1);
    assert_eq!(built(Step::EulerLagrange), 0);
    assert_eq!(built(Step::Energy), 0);
    assert_eq!(built(Step::Bracket), 0);
    // The plan names what it skipped and why.
    let skipped = |step: Step| plan.iter().any(|e| e.step == step && matches!(e.status, Status::Skipped(_)));
    assert!(
        skipped(Step::EulerLagrange) && skipped(Step::Conserved) && skipped(Step::Energy) && skipped(Step::Bracket)
    );
    let explain = s.explain();
    assert!(explain.contains("skipped line 4   Euler–Lagrange equations `E` (el) — no output uses `E`"), "{explain}");
    assert!(explain.contains("built   line 6   Legendre transform"), "{explain}");
    // The export has the state's columns: with a splitting method the state is (x, p_x),
    // and p_x = ∂L/∂x' = x' = 0 initially.
    let csv = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
    assert!(csv.starts_with("t,x,p_x\n0e0,1e0,0e0\n"), "{csv}");
}

#[test]
fn a_simulation_nothing_uses_is_not_run() {
    let dir = tempfile::tempdir().unwrap();
    let counts = Counts::default();
    let mut s = session(&counts, dir.path());
    let scene = OSCILLATOR.replace("export to run.csv\n", "print E\n");
    s.run_scene("osc", &scene).unwrap();
    assert_eq!(counts.get("el"), 1);
    assert_eq!(counts.get("legendre") + counts.get("integrate") + counts.get("compile_separable"), 0);
    assert!(s
        .plan()
        .iter()
        .any(|e| e.step == Step::Integrate && e.status == Status::Skipped("no plot or export uses `run1`".into())));
}

#[test]
fn rerunning_with_other_numbers_reuses_the_derivations() {
    let dir = tempfile::tempdir().unwrap();
    let counts = Counts::default();
    let mut first = session(&counts, dir.path());
    first.run_scene("osc", OSCILLATOR).unwrap();
    let cache: Cache = first.into_cache();
    assert_eq!(counts.get("legendre"), 1);

    // Other parameter value and initial state: same symbolic content.
    let changed = OSCILLATOR.replace("k = 2", "k = 3").replace("x = 1,", "x = 0.5,");
    let mut second = session(&counts, dir.path()).with_cache(cache);
    second.run_scene("osc", &changed).unwrap();
    assert_eq!(counts.get("legendre"), 1, "the Legendre transform was redone");
    assert_eq!(counts.get("integrate"), 2);
    // Compiled code binds the parameter values, so a new `k` compiles again.
    assert_eq!(counts.get("compile_separable"), 2);
    let reused: Vec<Step> = second.plan().iter().filter(|e| e.status == Status::Reused).map(|e| e.step).collect();
    assert_eq!(reused, [Step::Legendre, Step::Split, Step::Momenta]);

    // Same numbers again: the compiled code is reused too.
    let cache = second.into_cache();
    let mut third = session(&counts, dir.path()).with_cache(cache);
    third.run_scene("osc", &changed).unwrap();
    assert_eq!(counts.get("compile_separable"), 2);
    assert_eq!(counts.get("integrate"), 3);

    // A different Lagrangian is different content: derived again.
    let cache = third.into_cache();
    let mut fourth = session(&counts, dir.path()).with_cache(cache);
    fourth.run_scene("osc", &changed.replace("1/2 k x^2", "1/4 k x^4")).unwrap();
    assert_eq!(counts.get("legendre"), 2);
}

#[test]
fn a_new_process_loads_the_derivations_from_the_disk_cache() {
    // Two sessions sharing only a cache directory stand for two `lagrangian run` processes.
    let dir = tempfile::tempdir().unwrap();
    let cache_dir = tempfile::tempdir().unwrap();
    let counts = Counts::default();
    let mut first = session(&counts, dir.path()).with_cache(Cache::with_dir(cache_dir.path()));
    first.run_scene("osc", OSCILLATOR).unwrap();
    assert_eq!(counts.get("legendre"), 1);
    let first_out = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();

    let changed = OSCILLATOR.replace("x = 1,", "x = 0.5,");
    let mut second = session(&counts, dir.path()).with_cache(Cache::with_dir(cache_dir.path()));
    second.run_scene("osc", &changed).unwrap();
    assert_eq!(counts.get("legendre"), 1, "the Legendre transform was redone");
    let loaded: Vec<Step> = second.plan().iter().filter(|e| e.status == Status::Loaded).map(|e| e.step).collect();
    assert_eq!(loaded, [Step::Legendre, Step::Split, Step::Momenta]);
    assert!(second.explain().contains("3 loaded from the disk cache"), "{}", second.explain());
    assert_ne!(std::fs::read_to_string(dir.path().join("run.csv")).unwrap(), first_out, "the new numbers were used");

    // Every entry damaged in a different way: each is a miss, rebuilt and rewritten.
    let mut files: Vec<_> = std::fs::read_dir(cache_dir.path()).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    assert_eq!(files.len(), 3, "{files:?}");
    let text = std::fs::read_to_string(&files[0]).unwrap();
    std::fs::write(&files[0], &text[..text.len() / 3]).unwrap();
    std::fs::write(&files[1], text.replace("\"format\":1", "\"format\":99")).unwrap();
    std::fs::write(&files[2], [0xff, 0xfe, 0x00]).unwrap();
    let mut third = session(&counts, dir.path()).with_cache(Cache::with_dir(cache_dir.path()));
    third.run_scene("osc", &changed).unwrap();
    assert_eq!(counts.get("legendre"), 2);
    assert!(third.plan().iter().all(|e| e.status != Status::Loaded));
    let mut fourth = session(&counts, dir.path()).with_cache(Cache::with_dir(cache_dir.path()));
    fourth.run_scene("osc", &changed).unwrap();
    assert_eq!(counts.get("legendre"), 2, "the rewritten entries were not used");
}

#[test]
fn definitions_are_derived_once_however_often_they_are_used() {
    let dir = tempfile::tempdir().unwrap();
    let counts = Counts::default();
    let mut s = session(&counts, dir.path());
    s.run_scene("osc", "coordinates x\nL = 1/2 x'^2 - x^4\nH = legendre(L)\nprint H\nprint H + 1\nhamilton\nlegendre")
        .unwrap();
    assert_eq!(counts.get("legendre"), 1);
    assert_eq!(counts.get("hamilton"), 1);
    let out = s.take_output();
    // H = p_x²/2 + x⁴ by hand (unit mass).
    assert_eq!(out[0], "H = p_x²/2 + x⁴");
    assert_eq!(out[1], "p_x²/2 + x⁴ + 1");
}

#[test]
fn velocities_become_momenta_through_the_lagrangian() {
    // L = m x'²/2 − k x²/2: p = m x', so x' = 2 with m = 3 starts at p_x = 6 (by hand).
    let dir = tempfile::tempdir().unwrap();
    let counts = Counts::default();
    let mut s = session(&counts, dir.path());
    let scene = "coordinates x\nparameters m = 3, k = 1\nL = 1/2 m x'^2 - 1/2 k x^2\nH = p_x^2/(2 m) + 1/2 k x^2\n\
                 simulate x = 0, x' = 2 for t in 0..1 with yoshida4 dt = 0.1\nexport x, p_x, H to a.csv";
    s.run_scene("osc", scene).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("a.csv")).unwrap();
    // H = 36/6 + 0 = 6.
    assert!(csv.starts_with("t,x,p_x,H\n0e0,0e0,6e0,6e0\n"), "{csv}");
    assert_eq!(counts.get("legendre"), 0, "H was given; no transform needed");
}
