//! The driver shared by every method: stepping toward a stop time, output thinning, events
//! (zero crossings of a user function, located on the step's interpolant), guards against
//! non-finite states, and the [`Integrate`] entry points.

use std::ops::Range;
use std::time::{Duration, Instant};

use super::error::{check_finite, FailureReason, IntegrateError, StepFailure};
use super::Method;
use crate::cancel::CancelToken;

/// What a [`Solver::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// One step was taken; the stop time is not reached yet.
    Stepped,
    /// The state is at the stop time (the last step landed on it exactly).
    Finished,
}

/// Why an integration ended normally.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StopReason {
    /// The end of the time span was reached.
    ReachedEnd,
    /// An event with [`EventAction::Stop`] fired.
    Event {
        /// Index of the event in [`Options::events`].
        index: usize,
        /// When it fired.
        t: f64,
    },
}

/// Step-by-step integration of one system with one method. Fixed-step methods step on the grid
/// `t0 + k h` (times are computed from `k`, not accumulated, so they do not drift) and land
/// exactly on the stop time with a shortened last step.
pub struct Solver<'s, S: ?Sized, M: Method<S>> {
    method: &'s M,
    sys: &'s S,
    work: M::Work,
    t: f64,
    y: Vec<f64>,
    t_prev: f64,
    y_prev: Vec<f64>,
    t_stop: f64,
    anchor: f64,
    k: u64,
    steps: usize,
    /// Derivatives at both ends of the last step, for Hermite interpolation (computed lazily).
    rates: Option<(Vec<f64>, Vec<f64>)>,
    /// Checked before every step (with the process-wide token, see [`crate::cancel`]).
    cancel: Option<CancelToken>,
}

impl<'s, S: ?Sized, M: Method<S>> Solver<'s, S, M> {
    /// Starts at `(t0, y0)` heading for `t_stop` (which may be earlier than `t0`).
    pub fn new(method: &'s M, sys: &'s S, t0: f64, y0: &[f64], t_stop: f64) -> Result<Self, IntegrateError> {
        check_start(method, sys, t0, y0, t_stop)?;
        Ok(Solver {
            method,
            sys,
            work: method.work(sys),
            t: t0,
            y: y0.to_vec(),
            t_prev: t0,
            y_prev: y0.to_vec(),
            t_stop,
            anchor: t0,
            k: 0,
            steps: 0,
            rates: None,
            cancel: None,
        })
    }

    /// Stops the stepping with [`FailureReason::Interrupted`] once `token` is cancelled
    /// (Ctrl-C through the process-wide token stops every solver without this).
    pub fn set_cancel(&mut self, token: CancelToken) {
        self.cancel = Some(token);
    }

    /// Changes the stop time (the fixed-step grid restarts at the current time).
    pub fn set_stop_time(&mut self, t_stop: f64) {
        self.t_stop = t_stop;
        self.anchor = self.t;
        self.k = 0;
    }

    /// Current time.
    pub fn t(&self) -> f64 {
        self.t
    }

    /// Current state.
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// Time and state before the last step.
    pub fn previous(&self) -> (f64, &[f64]) {
        (self.t_prev, &self.y_prev)
    }

    /// The method's working storage: its dense output of the last step, for a driver that
    /// needs only some components of it ([`crate::integrate::TaylorWork::dense_component`]).
    pub fn work(&self) -> &M::Work {
        &self.work
    }

    /// Accepted steps so far.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Rejected steps so far (adaptive methods).
    pub fn rejected(&self) -> usize {
        self.method.rejected(&self.work)
    }

    /// Locates the zero of `g(t, y(t))` inside the last step, where `g` went from `g0` at its
    /// start to `g1` at its end, on the step's interpolant (the method's dense output, else
    /// Hermite), exactly as [`Integrate::integrate_with`] locates its [`Event`]s. For drivers
    /// that step a solver themselves (sampling at given times while watching events).
    pub fn locate(
        &mut self,
        g: &dyn Fn(f64, &[f64]) -> f64,
        g0: f64,
        g1: f64,
    ) -> Result<(f64, Vec<f64>), IntegrateError> {
        locate(self, g, g0, g1)
    }

    /// Replaces the state (and forgets the method's cached values).
    pub fn set_state(&mut self, t: f64, y: &[f64]) {
        self.t = t;
        self.y.copy_from_slice(y);
        self.anchor = t;
        self.k = 0;
        self.rates = None;
        self.method.reset(&mut self.work);
    }

    fn fail(&self, reason: FailureReason) -> IntegrateError {
        IntegrateError { t: self.t, state: self.y.clone(), reason, steps: self.steps }
    }

    /// Takes one step toward the stop time; fails with [`FailureReason::Interrupted`] (before
    /// stepping, so the state stays the last accepted one) once cancelled.
    pub fn step(&mut self) -> Result<Status, IntegrateError> {
        let remaining = self.t_stop - self.t;
        if remaining == 0.0 {
            return Ok(Status::Finished);
        }
        if crate::cancel::interrupted() || self.cancel.as_ref().is_some_and(CancelToken::is_cancelled) {
            return Err(self.fail(FailureReason::Interrupted));
        }
        let dir = remaining.signum();
        let h = match self.method.fixed_step() {
            Some(h) => {
                let next = self.anchor + dir * (self.k + 1) as f64 * h;
                // Land on the stop time when the next grid point reaches it (or passes it by
                // less than a rounding error's worth of the step).
                if dir * (self.t_stop - next) <= 1e-9 * h {
                    remaining
                } else {
                    next - self.t
                }
            }
            None => remaining,
        };
        self.t_prev = self.t;
        self.y_prev.copy_from_slice(&self.y);
        self.rates = None;
        let taken = self
            .method
            .step(self.sys, &mut self.work, self.t, &mut self.y, h)
            .and_then(|taken| check_finite(&self.y).map(|_| taken));
        let taken = match taken {
            Ok(taken) => taken,
            Err(StepFailure(reason)) => {
                self.y.copy_from_slice(&self.y_prev);
                self.method.reset(&mut self.work);
                return Err(self.fail(reason));
            }
        };
        self.steps += 1;
        if taken == h {
            self.t = self.t_prev + h;
            if h == remaining {
                self.t = self.t_stop;
            }
        } else {
            self.t = self.t_prev + taken;
        }
        if self.method.fixed_step().is_some() {
            self.k += 1;
        }
        Ok(if self.t == self.t_stop { Status::Finished } else { Status::Stepped })
    }

    /// The state at time `t` inside the last step, from the method's dense output or, if it
    /// has none, cubic Hermite interpolation of the step's end points and derivatives (local
    /// error `O(h^4)`).
    pub fn interpolate(&mut self, t: f64, out: &mut [f64]) -> Result<(), IntegrateError> {
        let h = self.t - self.t_prev;
        if h == 0.0 {
            out.copy_from_slice(&self.y);
            return Ok(());
        }
        let theta = (t - self.t_prev) / h;
        match self.method.dense(self.sys, &mut self.work, theta, out) {
            Ok(true) => return Ok(()),
            Ok(false) => {}
            Err(StepFailure(reason)) => return Err(self.fail(reason)),
        }
        if self.rates.is_none() {
            let n = self.y.len();
            let (mut f0, mut f1) = (vec![0.0; n], vec![0.0; n]);
            let r = self
                .method
                .rate(self.sys, self.t_prev, &self.y_prev, &mut f0)
                .and_then(|_| self.method.rate(self.sys, self.t, &self.y, &mut f1));
            if let Err(StepFailure(reason)) = r {
                return Err(self.fail(reason));
            }
            self.rates = Some((f0, f1));
        }
        let Some((f0, f1)) = &self.rates else { unreachable!("rates set above") };
        hermite(theta, h, (&self.y_prev, f0), (&self.y, f1), out);
        Ok(())
    }
}

/// Cubic Hermite interpolation at the fraction `theta` of a step of size `h` between the
/// states and derivatives `(y0, f0)` at its start and `(y1, f1)` at its end (local error
/// `O(h^4)`): the dense output of a method that has none of its own.
pub(crate) fn hermite(theta: f64, h: f64, (y0, f0): (&[f64], &[f64]), (y1, f1): (&[f64], &[f64]), out: &mut [f64]) {
    let s = theta;
    let h00 = (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s);
    let h10 = s * (1.0 - s) * (1.0 - s);
    let h01 = s * s * (3.0 - 2.0 * s);
    let h11 = s * s * (s - 1.0);
    for i in 0..out.len() {
        out[i] = h00 * y0[i] + h10 * h * f0[i] + h01 * y1[i] + h11 * h * f1[i];
    }
}

/// Which trajectory points to keep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// The initial state, every `k`-th step and the final state (`Every(1)` keeps all).
    Every(usize),
    /// Only the final state (and the initial one), to save memory on long runs.
    Final,
    /// Every step until `n` states are kept; then every other kept state is dropped and the
    /// stride doubles, as often as needed. The memory of a run is bounded by `n` states
    /// whatever its length (an adaptive run cannot know its step count in advance), and the
    /// kept states stay evenly spaced in steps. The initial and final states are always kept.
    AtMost(usize),
}

/// Which sign changes of an event function count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Crossing {
    /// From negative to positive.
    Rising,
    /// From positive to negative.
    Falling,
    /// Either way.
    Either,
}

/// What to do when an event fires.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventAction {
    /// Record the crossing (a Poincaré section) and go on.
    Record,
    /// End the integration at the crossing.
    Stop,
}

type EventFn<'a> = Box<dyn Fn(f64, &[f64]) -> f64 + 'a>;

/// A zero crossing of `g(t, y)` to detect; located by the Illinois variant of regula falsi on
/// the step's interpolant, to a few ulps of `t`.
pub struct Event<'a> {
    g: EventFn<'a>,
    crossing: Crossing,
    action: EventAction,
}

impl<'a> Event<'a> {
    /// Records every crossing of `g` in either direction.
    pub fn new(g: impl Fn(f64, &[f64]) -> f64 + 'a) -> Self {
        Event { g: Box::new(g), crossing: Crossing::Either, action: EventAction::Record }
    }
    /// Only crossings in the given direction.
    pub fn crossing(mut self, c: Crossing) -> Self {
        self.crossing = c;
        self
    }
    /// Stop at the first crossing.
    pub fn stop(mut self) -> Self {
        self.action = EventAction::Stop;
        self
    }
}

/// A located event.
#[derive(Debug, Clone, PartialEq)]
pub struct EventRecord {
    /// Index of the event in [`Options::events`].
    pub index: usize,
    /// Time of the crossing.
    pub t: f64,
    /// Interpolated state at the crossing.
    pub state: Vec<f64>,
}

/// Sorts one step's located events by time in the direction `dir` (±1) of integration.
///
/// Not generic, and not a closure inside the generic solver: a `sort_by` there is compiled
/// once per system × method pair (the standard library's stable sort is ~1,500 lines of LLVM IR
/// per instantiation, and the solver has dozens), which showed as compile time in every build.
pub(crate) fn sort_in_time(hits: &mut [EventRecord], dir: f64) {
    hits.sort_by(|a, b| (dir * a.t).total_cmp(&(dir * b.t)));
}

/// Options of [`Integrate::integrate_with`].
pub struct Options<'a> {
    /// Which points to keep.
    pub output: Output,
    /// The step budget; exceeding it is [`FailureReason::StepLimit`].
    pub max_steps: usize,
    /// Zero crossings to detect.
    pub events: Vec<Event<'a>>,
    /// Wall-clock budget; exceeding it is [`FailureReason::TimeLimit`]. Checked every 64
    /// steps, so a run overshoots it by at most 64 steps.
    pub time_limit: Option<Duration>,
    /// A token that stops the run with [`FailureReason::Interrupted`], checked before every
    /// step (the process-wide Ctrl-C token is checked whether or not one is given).
    pub cancel: Option<CancelToken>,
}

impl Default for Options<'_> {
    fn default() -> Self {
        Options { output: Output::Every(1), max_steps: 100_000_000, events: Vec::new(), time_limit: None, cancel: None }
    }
}

impl<'a> Options<'a> {
    /// Default options: keep every step, 10⁸ steps at most, no events.
    pub fn new() -> Self {
        Self::default()
    }
    /// Keep every `k`-th step.
    pub fn every(mut self, k: usize) -> Self {
        self.output = Output::Every(k.max(1));
        self
    }
    /// Keep only the initial and final states.
    pub fn final_only(mut self) -> Self {
        self.output = Output::Final;
        self
    }
    /// Sets the step budget.
    pub fn max_steps(mut self, n: usize) -> Self {
        self.max_steps = n;
        self
    }
    /// Keeps at most `n` states (at least 2), thinning evenly as the run grows (see
    /// [`Output::AtMost`]).
    pub fn at_most(mut self, n: usize) -> Self {
        self.output = Output::AtMost(n.max(2));
        self
    }
    /// Sets a wall-clock budget.
    pub fn time_limit(mut self, limit: Duration) -> Self {
        self.time_limit = Some(limit);
        self
    }
    /// Stops the run with [`FailureReason::Interrupted`] once `token` is cancelled.
    pub fn cancel(mut self, token: CancelToken) -> Self {
        self.cancel = Some(token);
        self
    }
    /// Adds an event.
    pub fn event(mut self, e: Event<'a>) -> Self {
        self.events.push(e);
        self
    }
}

/// Statistics of a finished integration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Stats {
    /// Accepted steps.
    pub steps: usize,
    /// Rejected steps (adaptive methods).
    pub rejected: usize,
}

/// The result of an integration: kept times and states (flat, `dim` entries per state),
/// recorded events and why it stopped.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Dimension of each state.
    pub dim: usize,
    /// Kept times.
    pub times: Vec<f64>,
    /// Kept states, concatenated.
    pub states: Vec<f64>,
    /// Recorded events, in time order.
    pub events: Vec<EventRecord>,
    /// Why the integration ended.
    pub stop: StopReason,
    /// Steps taken and rejected.
    pub stats: Stats,
}

impl Trajectory {
    /// Number of kept states.
    pub fn len(&self) -> usize {
        self.times.len()
    }
    /// `true` when no state is kept (never the case for a successful integration).
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }
    /// The `i`-th kept state.
    pub fn state(&self, i: usize) -> &[f64] {
        &self.states[i * self.dim..(i + 1) * self.dim]
    }
    /// The final state.
    pub fn last_state(&self) -> &[f64] {
        self.state(self.len() - 1)
    }
    /// The final time.
    pub fn last_time(&self) -> f64 {
        self.times[self.len() - 1]
    }
    /// `(t, state)` pairs.
    pub fn iter(&self) -> impl Iterator<Item = (f64, &[f64])> {
        self.times.iter().copied().zip(self.states.chunks(self.dim.max(1)))
    }
    fn push(&mut self, t: f64, y: &[f64]) {
        self.times.push(t);
        self.states.extend_from_slice(y);
    }
    /// Keeps the states at even positions (the initial state is position 0), in place.
    fn halve(&mut self) {
        let dim = self.dim;
        let kept = self.times.len().div_ceil(2);
        for j in 0..kept {
            self.times[j] = self.times[2 * j];
            self.states.copy_within(2 * j * dim..(2 * j + 1) * dim, j * dim);
        }
        self.times.truncate(kept);
        self.states.truncate(kept * dim);
    }
}

/// The one entry point of every method: `method.integrate(&system, t0..t1, &y0)`.
pub trait Integrate<S: ?Sized>: Method<S> + Sized {
    /// Integrates from `span.start` to `span.end` (backwards when `end < start`), keeping every
    /// step.
    fn integrate(&self, sys: &S, span: Range<f64>, y0: &[f64]) -> Result<Trajectory, IntegrateError> {
        self.integrate_with(sys, span, y0, Options::default())
    }

    /// Integrates with output thinning, a step budget and events.
    fn integrate_with(
        &self,
        sys: &S,
        span: Range<f64>,
        y0: &[f64],
        options: Options<'_>,
    ) -> Result<Trajectory, IntegrateError> {
        run(self, sys, span, y0, options)
    }

    /// A [`Solver`] for step-by-step control.
    fn solver<'s>(
        &'s self,
        sys: &'s S,
        t0: f64,
        y0: &[f64],
        t_stop: f64,
    ) -> Result<Solver<'s, S, Self>, IntegrateError> {
        Solver::new(self, sys, t0, y0, t_stop)
    }
}

impl<S: ?Sized, M: Method<S>> Integrate<S> for M {}

impl Crossing {
    /// Whether a step over which the event function went from `g0` to `g1` holds a crossing
    /// of this kind.
    pub fn crossed(self, g0: f64, g1: f64) -> bool {
        let rising = g0 < 0.0 && g1 >= 0.0;
        let falling = g0 > 0.0 && g1 <= 0.0;
        match self {
            Crossing::Rising => rising,
            Crossing::Falling => falling,
            Crossing::Either => rising || falling,
        }
    }
}

/// Locates the root of `g(t, y(t))` in the last step by the Illinois method.
fn locate<S: ?Sized, M: Method<S>>(
    solver: &mut Solver<'_, S, M>,
    g: &dyn Fn(f64, &[f64]) -> f64,
    g0: f64,
    g1: f64,
) -> Result<(f64, Vec<f64>), IntegrateError> {
    let (mut a, mut b) = (solver.t_prev, solver.t);
    let (mut ga, mut gb) = (g0, g1);
    let mut y = vec![0.0; solver.y.len()];
    let mut side = 0i8;
    let tol = 4.0 * f64::EPSILON * a.abs().max(b.abs()).max(1e-300);
    for _ in 0..200 {
        if (b - a).abs() <= tol {
            break;
        }
        let mut c = b - gb * (b - a) / (gb - ga);
        if !(c > a.min(b) && c < a.max(b)) {
            c = 0.5 * (a + b);
        }
        solver.interpolate(c, &mut y)?;
        let gc = g(c, &y);
        if gc == 0.0 {
            return Ok((c, y));
        }
        if (gc > 0.0) == (gb > 0.0) {
            b = c;
            gb = gc;
            if side == -1 {
                ga *= 0.5;
            }
            side = -1;
        } else {
            a = c;
            ga = gc;
            if side == 1 {
                gb *= 0.5;
            }
            side = 1;
        }
    }
    // Take the end of the bracket on the far side of the crossing, so that a restart from the
    // event does not see the same crossing again.
    let t = if gb != 0.0 { b } else { a };
    solver.interpolate(t, &mut y)?;
    Ok((t, y))
}

fn run<S: ?Sized, M: Method<S>>(
    method: &M,
    sys: &S,
    span: Range<f64>,
    y0: &[f64],
    mut options: Options<'_>,
) -> Result<Trajectory, IntegrateError> {
    let mut solver = Solver::new(method, sys, span.start, y0, span.end)?;
    solver.cancel = options.cancel.take();
    if let Some(h) = method.fixed_step() {
        // A fixed-step run knows its step count: refuse one over budget before the first step
        // instead of failing after hours.
        // (The same landing rule as `Solver::step`: a grid point within 1e-9 h of the stop
        // time is the last step.)
        let needed = ((span.end - span.start).abs() / h - 1e-9).ceil();
        if needed > options.max_steps as f64 {
            return Err(solver.fail(FailureReason::StepLimit { max_steps: options.max_steps }));
        }
    }
    let started = Instant::now();
    let dim = y0.len();
    let mut traj = Trajectory {
        dim,
        times: Vec::new(),
        states: Vec::new(),
        events: Vec::new(),
        stop: StopReason::ReachedEnd,
        stats: Stats::default(),
    };
    traj.push(span.start, y0);
    let mut g_prev: Vec<f64> = options.events.iter().map(|e| (e.g)(span.start, y0)).collect();
    let (mut every, cap) = match options.output {
        Output::Every(k) => (Some(k.max(1)), None),
        Output::Final => (None, None),
        Output::AtMost(n) => (Some(1), Some(n.max(2))),
    };
    let events = std::mem::take(&mut options.events);
    if span.start == span.end {
        return Ok(traj);
    }
    loop {
        if solver.steps >= options.max_steps {
            return Err(solver.fail(FailureReason::StepLimit { max_steps: options.max_steps }));
        }
        if let Some(limit) = options.time_limit {
            if solver.steps % 64 == 0 && started.elapsed() > limit {
                return Err(solver.fail(FailureReason::TimeLimit { seconds: limit.as_secs_f64() }));
            }
        }
        let status = solver.step()?;
        let t = solver.t;
        // Events of this step, in time order; a stopping event discards later ones.
        let mut hits = Vec::new();
        for (i, e) in events.iter().enumerate() {
            let g1 = (e.g)(t, &solver.y);
            if e.crossing.crossed(g_prev[i], g1) {
                let (te, ye) = locate(&mut solver, &*e.g, g_prev[i], g1)?;
                hits.push(EventRecord { index: i, t: te, state: ye });
            }
            g_prev[i] = g1;
        }
        sort_in_time(&mut hits, (solver.t - solver.t_prev).signum());
        for hit in hits {
            let (i, te) = (hit.index, hit.t);
            if events[i].action == EventAction::Stop {
                traj.push(te, &hit.state);
                traj.events.push(hit);
                traj.stop = StopReason::Event { index: i, t: te };
                traj.stats = Stats { steps: solver.steps, rejected: solver.rejected() };
                return Ok(traj);
            }
            traj.events.push(hit);
        }
        let keep = match every {
            Some(k) => solver.steps % k == 0 || status == Status::Finished,
            None => status == Status::Finished,
        };
        if keep {
            traj.push(solver.t, &solver.y);
            if let (Some(n), Some(k)) = (cap, every) {
                if traj.len() > n && status != Status::Finished {
                    traj.halve();
                    every = Some(2 * k);
                }
            }
        }
        if status == Status::Finished {
            break;
        }
    }
    traj.stats = Stats { steps: solver.steps, rejected: solver.rejected() };
    Ok(traj)
}

/// What [`Solver::new`] refuses: a state of the wrong length or not finite, a time span not
/// finite, a bad fixed step, the method's own check. The batch drivers start their lanes by it.
pub(crate) fn check_start<S: ?Sized, M: Method<S>>(
    method: &M,
    sys: &S,
    t0: f64,
    y0: &[f64],
    t_stop: f64,
) -> Result<(), IntegrateError> {
    let invalid =
        |msg: String| IntegrateError { t: t0, state: y0.to_vec(), reason: FailureReason::InvalidInput(msg), steps: 0 };
    let n = method.dim(sys);
    if y0.len() != n {
        return Err(invalid(format!("initial state has {} entries, the system has dimension {n}", y0.len())));
    }
    if !t0.is_finite() || !t_stop.is_finite() {
        return Err(invalid(format!("time span {t0}..{t_stop} is not finite")));
    }
    if let Some(i) = y0.iter().position(|v| !v.is_finite()) {
        return Err(invalid(format!("initial state component {i} is {}", y0[i])));
    }
    if let Some(h) = method.fixed_step() {
        if !(h.is_finite() && h > 0.0) {
            return Err(invalid(format!("step size {h} must be positive and finite")));
        }
        // A step below the spacing of f64 values near the span would leave `t` where it
        // is (or move it by a rounding error), so the grid would not be the grid asked for.
        let t_max = t0.abs().max(t_stop.abs());
        let resolution = 4.0 * f64::EPSILON * t_max;
        if t0 != t_stop && h <= resolution {
            return Err(invalid(format!(
                    "step size {h:e} is below the time resolution of f64 near t = {t_max:e} (about {resolution:e}); use a larger step"
                )));
        }
    }
    method.check().map_err(invalid)
}
