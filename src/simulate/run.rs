//! The one drive loop: a compiled system, an initial state and [`RunOptions`] in, a
//! [`Trajectory`] out. Every front end integrates through [`integrate`] (and many starts
//! through [`ensemble`]), so sampling, events, budgets, cancellation, the energy ledger and the
//! method dispatch are written once.

use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use super::compiled::{check_constrained_start, Compiled, CompiledSystem};
use super::energy::{EnergyCheck, Ledger};
use super::error::SimulateError;
pub use super::limits::{MAX_ADAPTIVE_STEPS, MAX_FIXED_STEPS, MAX_POINTS, MAX_STORED_STATES};
use super::method::{Family, MethodId, Needs, Scheme};
use crate::cancel::CancelToken;
use crate::compile::{ConstrainedRhs, Projected, Stabilization, Tape, VariationalStepper};
use crate::integrate::{
    fmt_value, BatchOutput, Crossing, Dop853, Event, EventRecord, ExplicitRk, FailureReason, Gauss, Integrate,
    IntegrateError, Jacobian, KeepStates, Method, Options, Rhs, RhsError, Separable, Splitting, Status, StopReason,
    Taylor, BATCH_FROM_ORDER,
};

/// Which states a run keeps.
#[derive(Clone, Debug, PartialEq)]
pub enum Sampling {
    /// At most [`MAX_POINTS`] states: every k-th step of a fixed-step run (k from the span), an
    /// evenly thinned subset of an adaptive one.
    Auto,
    /// The initial state, every `k`-th step and the final state.
    Every(usize),
    /// At most `n` states, thinned evenly as the run grows.
    AtMost(usize),
    /// The initial and final states only.
    Final,
    /// The states at these times (sorted in the direction of integration, inside the span),
    /// by the method's dense output or Hermite interpolation. As in SciPy's `solve_ivp`, events
    /// are watched over the whole span and a terminal one ends the output before it.
    Times(Vec<f64>),
}

/// A zero crossing to watch: one of the compiled system's event functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EventSpec {
    /// Index into [`Compiled::events`].
    pub index: usize,
    /// Which sign changes count.
    pub crossing: Crossing,
    /// Whether the run stops at the first crossing.
    pub terminal: bool,
}

/// One integration request.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// The method.
    pub method: MethodId,
    /// Start time.
    pub t0: f64,
    /// End time (after `t0`; before it integrates backwards where the method allows).
    pub t1: f64,
    /// The fixed step (fixed-step methods).
    pub dt: Option<f64>,
    /// Relative tolerance (adaptive methods); the method's default when `None`.
    pub rtol: Option<f64>,
    /// Absolute tolerance; `rtol` when `None`.
    pub atol: Option<f64>,
    /// Events to watch.
    pub events: Vec<EventSpec>,
    /// Which states to keep.
    pub sampling: Sampling,
    /// Kahan-compensated state updates (round-off grows like √N instead of N).
    pub compensated: bool,
    /// The step budget; [`MAX_ADAPTIVE_STEPS`] (adaptive) or [`MAX_FIXED_STEPS`] when `None`.
    pub max_steps: Option<usize>,
    /// The conserved energy to check after every step.
    pub energy: Option<EnergyCheck>,
    /// A token that stops the run (the process-wide Ctrl-C token is always checked).
    pub cancel: Option<CancelToken>,
}

impl RunOptions {
    /// `method` from `t0` to `t1`, everything else at its default.
    pub fn new(method: MethodId, t0: f64, t1: f64) -> RunOptions {
        RunOptions {
            method,
            t0,
            t1,
            dt: None,
            rtol: None,
            atol: None,
            events: Vec::new(),
            sampling: Sampling::Auto,
            compensated: false,
            max_steps: None,
            energy: None,
            cancel: None,
        }
    }

    /// The relative tolerance the run uses.
    pub fn tolerance(&self) -> f64 {
        self.rtol.or(self.method.default_tolerance()).unwrap_or(super::method::DEFAULT_TOL)
    }

    /// Refuses what the method cannot honour, before anything is compiled: a missing or
    /// superfluous `dt`, a tolerance below the method's floor, an empty span, too many steps.
    pub fn check(&self) -> Result<(), SimulateError> {
        if !(self.t0.is_finite() && self.t1.is_finite()) {
            return Err(SimulateError::InvalidRun(format!("the time span {}..{} is not finite", self.t0, self.t1)));
        }
        if self.t0 == self.t1 {
            return Err(SimulateError::InvalidRun(format!(
                "the time span is empty: it starts and ends at {}",
                self.t0
            )));
        }
        let m = self.method;
        match (m.needs(), self.dt) {
            (Needs::Tolerance, Some(_)) => return Err(SimulateError::NeedsTolerance { method: m }),
            (Needs::Step, None) => return Err(SimulateError::NeedsStep { method: m }),
            (Needs::Step, Some(h)) => {
                if !(h.is_finite() && h > 0.0) {
                    return Err(SimulateError::NotPositive { what: "the step `dt`", value: h });
                }
                let steps = ((self.t1 - self.t0) / h).abs();
                let limit = self.max_steps.map_or(MAX_FIXED_STEPS, |n| n as f64);
                if steps > limit {
                    return Err(SimulateError::TooManySteps { steps, limit });
                }
            }
            (Needs::Tolerance, None) => {}
        }
        for (what, tol) in [("the tolerance `tol`", self.rtol), ("the absolute tolerance `atol`", self.atol)] {
            let Some(tol) = tol else { continue };
            if !(tol.is_finite() && tol > 0.0) {
                return Err(SimulateError::NotPositive { what, value: tol });
            }
        }
        if let (Some(tol), Some(floor)) = (self.rtol, m.tolerance_floor()) {
            if tol < floor {
                return Err(SimulateError::ToleranceBelowFloor { method: m, tol, floor });
            }
        }
        if let Sampling::Times(times) = &self.sampling {
            let dir = (self.t1 - self.t0).signum();
            if let Some(x) = times.iter().find(|x| !(dir * (**x - self.t0) >= 0.0 && dir * (self.t1 - **x) >= 0.0)) {
                return Err(SimulateError::InvalidRun(format!(
                    "the sample time {x} is outside the span {}..{}",
                    self.t0, self.t1
                )));
            }
            if times.windows(2).any(|w| dir * (w[1] - w[0]) < 0.0) {
                return Err(SimulateError::InvalidRun(
                    "sample times must be sorted in the direction of integration".into(),
                ));
            }
        }
        if let Sampling::Every(0) | Sampling::AtMost(0) = self.sampling {
            return Err(SimulateError::InvalidRun("keep at least every step (every ≥ 1, at most ≥ 2 states)".into()));
        }
        self.check_stored_states()
    }

    /// Refuses a run that would keep more than [`MAX_STORED_STATES`] states, before the first
    /// step: a fixed-step run's count is known from its span, an adaptive run's is bounded by
    /// its step budget.
    fn check_stored_states(&self) -> Result<(), SimulateError> {
        let limit = MAX_STORED_STATES;
        let too_many = |states: f64, every: Option<u64>| Err(SimulateError::TooManyStates { states, limit, every });
        match &self.sampling {
            Sampling::Times(times) if times.len() > limit => too_many(times.len() as f64, None),
            Sampling::AtMost(n) if *n > limit => too_many(*n as f64, None),
            Sampling::Every(k) => {
                let steps = match self.dt {
                    Some(h) => ((self.t1 - self.t0) / h).abs().ceil(),
                    None => self.budget() as f64,
                };
                let states = steps / *k as f64;
                if states > limit as f64 {
                    too_many(states, Some((steps / limit as f64).ceil() as u64))
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    fn budget(&self) -> usize {
        match self.max_steps {
            Some(n) => n,
            None if self.method.adaptive() => MAX_ADAPTIVE_STEPS,
            None => usize::MAX,
        }
    }
}

/// A computed trajectory.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    /// Times of the kept states.
    pub t: Vec<f64>,
    /// The kept states, one per time, in the compiled system's layout ([`Compiled::state`]).
    pub y: Vec<Vec<f64>>,
    /// Recorded events (index into [`RunOptions::events`], time, state).
    pub events: Vec<EventRecord>,
    /// Which event stopped the run, and when; `None` when it reached the end of the span.
    pub stopped_by: Option<(usize, f64)>,
    /// Accepted steps.
    pub steps: usize,
    /// Rejected steps (adaptive methods).
    pub rejected: usize,
    /// Right-hand-side evaluations (for splitting methods, kicks: the force evaluations; for
    /// the Taylor method, series expansions), counted during the run: the work axis of a
    /// work-precision diagram, deterministic where wall time is not.
    pub evaluations: usize,
    /// Further named values at each kept state (the multipliers `λ1, …` and the constraint
    /// residuals `residual1, …` of a constrained run).
    pub aux: Vec<(String, Vec<f64>)>,
    /// What the energy check saw.
    pub energy: Ledger,
}

impl Trajectory {
    /// The final state.
    pub fn last_state(&self) -> Option<&[f64]> {
        self.y.last().map(Vec::as_slice)
    }
}

/// Integrates `c` from `y0` as `opts` asks; `progress` receives the fraction of the span done.
pub fn integrate(
    c: &Compiled,
    y0: &[f64],
    opts: &RunOptions,
    progress: &mut dyn FnMut(f64),
) -> Result<Trajectory, SimulateError> {
    opts.check()?;
    if !c.serves(opts.method) {
        return Err(SimulateError::Internal("the system was compiled for another kind of method"));
    }
    if y0.len() != c.state.len() {
        return Err(SimulateError::InvalidRun(format!(
            "the initial state has {} values; the state is ({})",
            y0.len(),
            c.state.join(", ")
        )));
    }
    if let Some(i) = opts.events.iter().position(|e| e.index >= c.events.len()) {
        return Err(SimulateError::InvalidRun(format!("event {i} names no compiled event function")));
    }
    let d = Drive { opts, names: &c.state, events: &c.events, y0, progress: RefCell::new(progress) };
    let count = AtomicUsize::new(0);
    let dt = opts.dt.unwrap_or(f64::NAN);
    let mut traj = match &*c.system {
        CompiledSystem::Taylor(ode, inner) => {
            let m = taylor_method(opts);
            m.validate().map_err(SimulateError::InvalidRun)?;
            let mut t = match &**inner {
                CompiledSystem::Constrained(r) => {
                    check_constrained_start(r, opts.t0, y0)?;
                    let mut t = match r.stabilization() {
                        Stabilization::Projection => d.run(&Projected { method: &m, constraints: r }, ode)?,
                        _ => d.run(&m, ode)?,
                    };
                    t.aux = constrained_aux(r, &t);
                    t
                }
                _ => d.run(&m, ode)?,
            };
            t.evaluations = t.steps;
            t
        }
        CompiledSystem::Separable(s) => {
            let Scheme::Splitting(scheme) = opts.method.spec().scheme else {
                return Err(SimulateError::Internal("a drift/kick split run by a method that does not split"));
            };
            let mut m = Splitting::new(scheme, dt);
            if opts.compensated {
                m = m.compensated();
            }
            d.run(&m, &Counted::new(s, &count))?
        }
        CompiledSystem::Variational(map, rule) => {
            if opts.compensated {
                return Err(SimulateError::InvalidRun(format!(
                    "`{}` has no compensated form; drop `compensated`, or use `gauss6` with it",
                    opts.method.name()
                )));
            }
            let before = map.evaluations();
            let stepper = VariationalStepper { h: dt, order: rule.order() };
            let mut t = d.run(&stepper, map)?;
            t.evaluations = map.evaluations() - before;
            t
        }
        CompiledSystem::Constrained(r) => {
            check_constrained_start(r, opts.t0, y0)?;
            let project = (r.stabilization() == Stabilization::Projection).then_some(r);
            let mut t = by_rhs(&d, &Counted::new(r, &count), project)?;
            t.aux = constrained_aux(r, &t);
            t
        }
        CompiledSystem::FirstOrder(r) => {
            let mut t = by_rhs(&d, &Counted::new(r, &count), None)?;
            let fill = |t: f64, y: &mut Vec<f64>| {
                r.0.fill_velocities(t, y).map_err(|e| SimulateError::InvalidRun(e.to_string()))
            };
            for (tk, y) in t.t.iter().zip(t.y.iter_mut()) {
                fill(*tk, y)?;
            }
            for e in t.events.iter_mut() {
                let mut y = std::mem::take(&mut e.state);
                fill(e.t, &mut y)?;
                e.state = y;
            }
            t
        }
        CompiledSystem::Lagrangian(r) => by_rhs(&d, &Counted::new(r, &count), None)?,
        CompiledSystem::LagrangianJacobian(r) => by_rhs(&d, &Counted::new(r, &count), None)?,
        CompiledSystem::Hamiltonian(r) => by_rhs(&d, &Counted::new(r, &count), None)?,
    };
    if traj.evaluations == 0 {
        traj.evaluations = count.load(Ordering::Relaxed);
    }
    Ok(traj)
}

/// Many starts of one compiled system in parallel (rayon; `threads` workers, all cores when
/// `None`); each start on one thread, so the results do not depend on the number of threads.
/// One start's failure does not stop the others. `progress` receives the fraction of starts
/// finished (every 50 ms, from the calling thread).
pub fn ensemble(
    c: &Compiled,
    starts: &[Vec<f64>],
    opts: &RunOptions,
    threads: Option<usize>,
    progress: &mut dyn FnMut(f64),
) -> Vec<Result<Trajectory, SimulateError>> {
    if let Err(e) = opts.check() {
        return starts.iter().map(|_| Err(e.clone())).collect();
    }
    // What the batch ran, then every start it did not run (all of them when it does not
    // apply; the ones it handed back otherwise) one at a time, in parallel.
    let mut out: Vec<Option<Result<Trajectory, SimulateError>>> = match taylor_batch(c, starts, opts, threads, progress)
    {
        Some(runs) => runs.into_iter().map(|r| r.map(Ok)).collect(),
        None => starts.iter().map(|_| None).collect(),
    };
    let rest: Vec<usize> = (0..starts.len()).filter(|&i| out[i].is_none()).collect();
    let rest_starts: Vec<&Vec<f64>> = rest.iter().map(|&i| &starts[i]).collect();
    let cancel = opts.cancel.clone();
    let alone = par_map_with_progress(&rest_starts, threads, progress, |y0| {
        if cancel.as_ref().is_some_and(CancelToken::is_cancelled) || crate::cancel::interrupted() {
            return Err(SimulateError::Cancelled);
        }
        integrate(c, y0, opts, &mut |_| {})
    })
    .unwrap_or_else(|_| rest.iter().map(|_| Err(SimulateError::Internal("an ensemble worker panicked"))).collect());
    for (i, r) in rest.into_iter().zip(alone) {
        out[i] = Some(r);
    }
    out.into_iter().map(|r| r.unwrap_or(Err(SimulateError::Internal("an ensemble start ran nowhere")))).collect()
}

/// [`ensemble`] by the Taylor method's batch mode ([`Taylor::integrate_batch`]), when the run
/// asks for nothing it lacks: final states or states at given times, no events, no energy
/// check. `None`: the run goes one start at a time. Each trajectory is bit for bit the one
/// [`integrate`] gives (the batch's promise); a start the batch hands back (`None` in its
/// place: a failure, a budget, a cancellation) the caller runs alone, so its error is the
/// single run's.
fn taylor_batch(
    c: &Compiled,
    starts: &[Vec<f64>],
    opts: &RunOptions,
    threads: Option<usize>,
    progress: &mut dyn FnMut(f64),
) -> Option<Vec<Option<Trajectory>>> {
    // A constrained system's trajectories carry multipliers and residuals, and projection
    // steps, which the batch does not: they run one at a time.
    let CompiledSystem::Taylor(ode, inner) = &*c.system else { return None };
    if matches!(**inner, CompiledSystem::Constrained(_)) {
        return None;
    }
    let output = match &opts.sampling {
        Sampling::Final => BatchOutput::Final,
        Sampling::Times(times) => BatchOutput::Times(times),
        _ => return None,
    };
    let plain = opts.events.is_empty() && opts.energy.is_none() && c.serves(opts.method);
    if !plain || !ode.batchable() || starts.iter().any(|y| y.len() != c.state.len()) {
        return None;
    }
    let method = taylor_method(opts);
    if method.taylor_order() < BATCH_FROM_ORDER {
        return None;
    }
    // One batch driver per worker thread, all taking starts from one queue: a lane idles only
    // once no start is left (chunks of starts, one driver each, idled lanes at every chunk's
    // end), as the chaos maps do.
    let lanes = crate::compile::simd_lanes();
    let refs: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
    let (queue, done) = (AtomicUsize::new(0), AtomicUsize::new(0));
    let task = KeepStates::new(opts.t0..opts.t1, &refs, output, opts.budget()).counting(&done);
    let drive = || {
        rayon::broadcast(|_| {
            method.integrate_lanes(ode, lanes, opts.t0..opts.t1, &refs, &queue, &task, opts.cancel.as_ref())
        })
    };
    let drivers = with_progress(&done, starts.len(), progress, || in_pool(threads, drive)).ok()?;
    let mut out: Vec<Option<Trajectory>> = vec![None; starts.len()];
    for (index, run) in drivers.into_iter().collect::<Option<Vec<_>>>()?.into_iter().flatten() {
        out[index] = run.flatten().map(|r| Trajectory {
            t: r.t,
            y: r.y,
            steps: r.steps,
            evaluations: r.steps,
            energy: Ledger::from_report(None, None),
            ..Trajectory::default()
        });
    }
    Some(out)
}

/// The Taylor method with the run's tolerances.
fn taylor_method(opts: &RunOptions) -> Taylor {
    let tol = opts.tolerance();
    let m = Taylor::with_tolerances(tol, opts.atol.unwrap_or(tol));
    if opts.compensated {
        m.compensated()
    } else {
        m
    }
}

/// A worker thread of [`par_map_with_progress`] panicked (the panic hook has printed it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WorkerPanicked;

/// `f` over `items` on rayon's pool (`threads` workers, all cores when `None`), while this
/// thread reports the fraction finished every 50 ms.
pub fn par_map_with_progress<T: Sync, R: Send>(
    items: &[T],
    threads: Option<usize>,
    progress: &mut dyn FnMut(f64),
    f: impl Fn(&T) -> R + Sync,
) -> Result<Vec<R>, WorkerPanicked> {
    use rayon::prelude::*;
    let done = AtomicUsize::new(0);
    let work = || {
        items
            .par_iter()
            .map(|x| {
                let out = f(x);
                done.fetch_add(1, Ordering::Relaxed);
                out
            })
            .collect::<Vec<_>>()
    };
    with_progress(&done, items.len(), progress, || in_pool(threads, work))
}

/// `work` on a pool of `threads` worker threads, or on rayon's global pool.
fn in_pool<R: Send>(threads: Option<usize>, work: impl FnOnce() -> R + Send) -> R {
    match threads.map(|k| rayon::ThreadPoolBuilder::new().num_threads(k.max(1)).build()) {
        Some(Ok(pool)) => pool.install(work),
        _ => work(),
    }
}

/// `work` on a thread of its own, while this thread reports `done / n` every 50 ms (`work`
/// counts its finished items in `done`) and `1` at its end. The wait ends as soon as `work`
/// does (it signals its end; a fixed sleep made every run last a multiple of 50 ms).
pub fn with_progress<R: Send>(
    done: &AtomicUsize,
    n: usize,
    progress: &mut dyn FnMut(f64),
    work: impl FnOnce() -> R + Send,
) -> Result<R, WorkerPanicked> {
    let n = n.max(1) as f64;
    let (finished, wait) = std::sync::mpsc::channel::<()>();
    std::thread::scope(|scope| {
        let handle = scope.spawn(move || {
            // Dropped at the end of `work`, or as it unwinds: either ends the wait.
            let _finished = finished;
            work()
        });
        progress(done.load(Ordering::Relaxed) as f64 / n);
        while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) =
            wait.recv_timeout(std::time::Duration::from_millis(50))
        {
            progress(done.load(Ordering::Relaxed) as f64 / n);
        }
        progress(1.0);
        handle.join().map_err(|_| WorkerPanicked)
    })
}

/// One run's fixed inputs, shared by every method's drive.
struct Drive<'a, 'p> {
    opts: &'a RunOptions,
    names: &'a [String],
    events: &'a [Arc<Tape>],
    y0: &'a [f64],
    progress: RefCell<&'p mut dyn FnMut(f64)>,
}

/// Integrates a first-order right-hand side with the method `d.opts` names; with `project`,
/// every step is followed by a projection onto those constraints.
fn by_rhs<S: Rhs + ?Sized>(d: &Drive, sys: &S, project: Option<&ConstrainedRhs>) -> Result<Trajectory, SimulateError> {
    let (dt, tol) = (d.opts.dt.unwrap_or(f64::NAN), d.opts.tolerance());
    let atol = d.opts.atol.unwrap_or(tol);
    let comp = d.opts.compensated;
    macro_rules! go {
        ($m:expr) => {{
            let m = $m;
            match project {
                Some(c) => d.run(&Projected { method: &m, constraints: c }, sys),
                None => d.run(&m, sys),
            }
        }};
    }
    match d.opts.method.spec().scheme {
        Scheme::Implicit(tableau) => {
            let m = Gauss::new(tableau(), dt);
            go!(if comp { m.compensated() } else { m })
        }
        Scheme::Explicit(tableau) => {
            let m = ExplicitRk::new(tableau(), dt);
            go!(if comp { m.compensated() } else { m })
        }
        Scheme::Dop853 => {
            let m = Dop853::new(tol, atol);
            go!(if comp { m.compensated() } else { m })
        }
        Scheme::Splitting(_) | Scheme::Taylor | Scheme::Variational(_) => {
            Err(SimulateError::Internal("a right-hand side run by a method that needs another form"))
        }
    }
}

/// A measured figure in a hint, to four significant digits: `0.4751`, `4.751e5`.
fn approx(x: f64) -> String {
    if x != 0.0 && !(1e-3..1e5).contains(&x.abs()) {
        format!("{x:.3e}").replace("e0", "").replace(".000e", "e")
    } else {
        let digits = 3 - x.abs().log10().floor().clamp(-3.0, 4.0) as i32;
        let s = format!("{x:.*}", digits.max(0) as usize);
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    }
}

/// An event tape evaluated on `(y, t)`.
fn event_fn(tape: &Tape) -> impl Fn(f64, &[f64]) -> f64 + '_ {
    move |t, y| {
        let mut x = Vec::with_capacity(y.len() + 1);
        x.extend_from_slice(y);
        x.push(t);
        let mut o = [0.0];
        tape.eval(&x, &mut o);
        o[0]
    }
}

impl Drive<'_, '_> {
    fn fail(&self, e: IntegrateError) -> SimulateError {
        let span = self.opts.t1 - self.opts.t0;
        let done = e.t - self.opts.t0;
        let hint = match &e.reason {
            FailureReason::StepLimit { max_steps } if self.opts.method.family() == Family::Adaptive => {
                let avg = done / e.steps.max(1) as f64;
                // At the average step so far, how many steps the whole span would take: a
                // budget a user can ask for, rounded up to one significant digit.
                let needed = (span / avg.max(f64::MIN_POSITIVE)).min(1e18);
                let ask = {
                    let p = 10f64.powf(needed.log10().floor());
                    (needed / p).ceil() * p
                };
                Some(format!(
                    "; the average step was {} over {} of the {} span, so the whole span needs about {} steps at this tolerance: raise the budget of {} with `max_steps = {ask:e}`, loosen `tol`, or shorten the span (if the steps are small because the problem is stiff, an implicit method with a fixed step, `with gauss6 dt = …`, is cheaper)",
                    approx(avg),
                    approx(done),
                    approx(span),
                    approx(needed),
                    approx(*max_steps as f64),
                ))
            }
            FailureReason::NonFinite { .. } | FailureReason::Rhs(_) => self
                .opts
                .dt
                .filter(|_| matches!(self.opts.method.family(), Family::Explicit | Family::Splitting | Family::Implicit))
                .map(|dt| {
                    format!(
                        "; with the fixed step dt = {} the step may be too large for this motion: halve `dt`, or use an adaptive method (`with dop853 tol = 1e-10` or `with taylor`), which would report where the solution itself blows up",
                        fmt_value(dt)
                    )
                }),
            _ => None,
        };
        SimulateError::integration(e, self.names, hint)
    }

    fn report(&self, fraction: f64) {
        if let Ok(mut p) = self.progress.try_borrow_mut() {
            p(fraction.clamp(0.0, 1.0));
        }
    }

    fn run<S: ?Sized, M: Method<S>>(&self, method: &M, sys: &S) -> Result<Trajectory, SimulateError> {
        let out = match &self.opts.sampling {
            Sampling::Times(times) => self.sampled(method, sys, times),
            _ => self.stepped(method, sys),
        };
        self.report(1.0);
        out
    }

    /// Keeps steps (every k-th, at most n, or the final state), watching events on the way.
    fn stepped<S: ?Sized, M: Method<S>>(&self, method: &M, sys: &S) -> Result<Trajectory, SimulateError> {
        let o = self.opts;
        let span = o.t1 - o.t0;
        let calls = Cell::new(0usize);
        // The same per-step hook feeds the energy ledger (every accepted step, the initial
        // state first), so a step that jumps is seen even when the output is thinned, and
        // reports progress every 256 steps. It never changes sign, so it never fires.
        let monitor = o.energy.as_ref().map(|c| RefCell::new(c.monitor()));
        let watch = Event::new(|t, y: &[f64]| {
            if let Some(m) = &monitor {
                m.borrow_mut().observe(t, y);
            }
            calls.set(calls.get() + 1);
            if calls.get() % 256 == 0 {
                self.report((t - o.t0) / span);
            }
            1.0
        });
        let gs: Vec<_> = self.events.iter().map(|t| event_fn(t)).collect();
        let mut opts = match o.sampling {
            Sampling::Every(k) => Options::new().every(k),
            Sampling::AtMost(n) => Options::new().at_most(n),
            Sampling::Final => Options::new().final_only(),
            Sampling::Auto => match o.dt {
                Some(h) => Options::new().every(default_every(h, o.t0, o.t1)),
                None => Options::new().at_most(MAX_POINTS),
            },
            Sampling::Times(_) => unreachable!("sampled runs go through `sampled`"),
        }
        .max_steps(self.budget_for_options())
        .event(watch);
        if let Some(token) = &o.cancel {
            opts = opts.cancel(token.clone());
        }
        for spec in &o.events {
            let g = &gs[spec.index];
            let mut e = Event::new(move |t, y: &[f64]| g(t, y)).crossing(spec.crossing);
            if spec.terminal {
                e = e.stop();
            }
            opts = opts.event(e);
        }
        let tr = method.integrate_with(sys, o.t0..o.t1, self.y0, opts).map_err(|e| self.fail(e))?;
        let energy = monitor.and_then(|m| m.into_inner().report());
        let dim = tr.dim.max(1);
        Ok(Trajectory {
            t: tr.times.clone(),
            y: tr.states.chunks(dim).map(<[f64]>::to_vec).collect(),
            // The watch is event 0 and never fires; the run's events are numbered from 0.
            events: tr
                .events
                .into_iter()
                .filter(|e| e.index > 0)
                .map(|e| EventRecord { index: e.index - 1, ..e })
                .collect(),
            stopped_by: match tr.stop {
                StopReason::ReachedEnd => None,
                StopReason::Event { index, t } => Some((index.saturating_sub(1), t)),
            },
            steps: tr.stats.steps,
            rejected: tr.stats.rejected,
            evaluations: 0,
            aux: Vec::new(),
            energy: Ledger::from_report(o.energy.as_ref(), energy),
        })
    }

    fn budget_for_options(&self) -> usize {
        self.opts.budget()
    }

    /// Steps a [`crate::integrate::Solver`] and interpolates at the requested times (the
    /// method's dense output, or Hermite interpolation). Events are located on the same
    /// interpolant; the run covers the whole span while events are watched.
    fn sampled<S: ?Sized, M: Method<S>>(
        &self,
        method: &M,
        sys: &S,
        times: &[f64],
    ) -> Result<Trajectory, SimulateError> {
        let o = self.opts;
        let y0 = self.y0;
        let n = y0.len();
        let mut solver = method.solver(sys, o.t0, y0, o.t1).map_err(|e| self.fail(e))?;
        if let Some(token) = &o.cancel {
            solver.set_cancel(token.clone());
        }
        let mut monitor = o.energy.as_ref().map(EnergyCheck::monitor);
        if let Some(m) = monitor.as_mut() {
            m.observe(o.t0, y0);
        }
        let dir = (o.t1 - o.t0).signum();
        let budget = self.budget_for_options();
        let mut traj = Trajectory::default();
        let mut next = 0;
        while next < times.len() && times[next] == o.t0 {
            traj.t.push(o.t0);
            traj.y.push(y0.to_vec());
            next += 1;
        }
        let gs: Vec<_> = o.events.iter().map(|s| event_fn(&self.events[s.index])).collect();
        let mut g_prev: Vec<f64> = gs.iter().map(|g| g(o.t0, y0)).collect();
        let mut out = vec![0.0; n];
        while next < times.len() || !gs.is_empty() {
            if solver.steps() >= budget {
                return Err(self.fail(IntegrateError {
                    t: solver.t(),
                    state: solver.y().to_vec(),
                    reason: FailureReason::StepLimit { max_steps: budget },
                    steps: solver.steps(),
                }));
            }
            let status = solver.step().map_err(|e| self.fail(e))?;
            let t = solver.t();
            if let Some(m) = monitor.as_mut() {
                m.observe(t, solver.y());
            }
            if solver.steps() % 256 == 0 {
                self.report((t - o.t0) / (o.t1 - o.t0));
            }
            // This step's crossings in time order; a terminal one ends the output there.
            let mut hits = Vec::new();
            for (i, g) in gs.iter().enumerate() {
                let g1 = g(t, solver.y());
                if o.events[i].crossing.crossed(g_prev[i], g1) {
                    let (te, ye) = solver.locate(g, g_prev[i], g1).map_err(|e| self.fail(e))?;
                    hits.push(EventRecord { index: i, t: te, state: ye });
                }
                g_prev[i] = g1;
            }
            crate::integrate::sort_in_time(&mut hits, dir);
            let mut until = t;
            for h in hits {
                let (i, te) = (h.index, h.t);
                traj.events.push(h);
                if o.events[i].terminal {
                    traj.stopped_by = Some((i, te));
                    until = te;
                    break;
                }
            }
            while next < times.len() && dir * (times[next] - until) <= 0.0 {
                solver.interpolate(times[next], &mut out).map_err(|e| self.fail(e))?;
                traj.t.push(times[next]);
                traj.y.push(out.clone());
                next += 1;
            }
            if traj.stopped_by.is_some() || status == Status::Finished {
                break;
            }
        }
        traj.steps = solver.steps();
        traj.rejected = solver.rejected();
        traj.energy = Ledger::from_report(o.energy.as_ref(), monitor.and_then(|m| m.report()));
        Ok(traj)
    }
}

/// The thinning of a fixed-step run that keeps at most [`MAX_POINTS`] states.
pub fn default_every(dt: f64, t0: f64, t1: f64) -> usize {
    let expected_steps = ((t1 - t0).abs() / dt).ceil() as usize;
    expected_steps.div_ceil(MAX_POINTS).max(1)
}

/// The multipliers and residuals of a constrained run at each kept state.
fn constrained_aux(r: &ConstrainedRhs, tr: &Trajectory) -> Vec<(String, Vec<f64>)> {
    let m = r.constraints();
    let mut lambda = vec![vec![0.0; tr.t.len()]; m];
    let mut resid = vec![vec![0.0; tr.t.len()]; m];
    let (mut l, mut f) = (vec![0.0; m], vec![0.0; m]);
    for (k, (t, y)) in tr.t.iter().zip(&tr.y).enumerate() {
        if r.multipliers(*t, y, &mut l).is_err() {
            l.fill(f64::NAN);
        }
        r.residuals(*t, y, &mut f);
        for (column, value) in lambda.iter_mut().zip(&l).chain(resid.iter_mut().zip(&f)) {
            column[k] = *value;
        }
    }
    let mut out = Vec::new();
    // The velocity constraints' multipliers are `μ1, …`, as the printed Lagrange–d'Alembert
    // equations name them.
    let mh = r.holonomic();
    for (j, v) in lambda.into_iter().enumerate() {
        out.push((if j < mh { format!("λ{}", j + 1) } else { format!("μ{}", j - mh + 1) }, v));
    }
    for (j, v) in resid.into_iter().enumerate() {
        out.push((format!("residual{}", j + 1), v));
    }
    out
}

/// A compiled system that counts its evaluations (see [`Trajectory::evaluations`]). One run
/// is integrated on one thread, so the count is a relaxed load and store, not a locked
/// read-modify-write: plain moves on common targets, small next to an evaluation.
struct Counted<'a, S: ?Sized> {
    inner: &'a S,
    count: &'a AtomicUsize,
}

impl<'a, S: ?Sized> Counted<'a, S> {
    fn new(inner: &'a S, count: &'a AtomicUsize) -> Self {
        Counted { inner, count }
    }
    fn bump(&self) {
        self.count.store(self.count.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
    }
}

impl<S: Rhs + ?Sized> Rhs for Counted<'_, S> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        self.bump();
        self.inner.eval(t, y, dy);
    }
    fn try_eval(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), RhsError> {
        self.bump();
        self.inner.try_eval(t, y, dy)
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        self.inner.as_jacobian()
    }
}

impl<S: Separable + ?Sized> Separable for Counted<'_, S> {
    fn dof(&self) -> usize {
        self.inner.dof()
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        self.inner.drift(p, dq);
    }
    fn kick(&self, t: f64, q: &[f64], dp: &mut [f64]) {
        self.bump();
        self.inner.kick(t, q, dp);
    }
    fn try_drift(&self, p: &[f64], dq: &mut [f64]) -> Result<(), RhsError> {
        self.inner.try_drift(p, dq)
    }
    fn try_kick(&self, t: f64, q: &[f64], dp: &mut [f64]) -> Result<(), RhsError> {
        self.bump();
        self.inner.try_kick(t, q, dp)
    }
}
