//! Many trajectories of one system by the Taylor method, several expanded and stepped at
//! once: the batch mode of ensembles, sweeps and chaos maps.
//!
//! Each trajectory keeps its own state, step size, end and failure (a [`Track`]); the lanes'
//! states go through one [`TaylorBatchSystem::expand_batch`], whose coefficients come back
//! lane beside lane ([`Lanes<B>`]), and one step of all lanes then reads them there: the
//! norms of the step size and the series sums of the state update are lane-wise operations,
//! the step size's roots are taken lane by lane by the single method's own function, and the
//! update and the bookkeeping are the single method's, lane by lane. Since a lane's
//! coefficients are the bits a single expansion gives (the system's promise), and every
//! operation of a step is the single run's in the single run's order ([`Lanes`] operates lane
//! by lane, never fusing a multiply and an add), every trajectory is bit for bit the one
//! [`Taylor`] computes alone, whatever its neighbours. A trajectory that ends loads the next
//! unstarted one into its lane, taken from a queue the drivers of all threads share.
//!
//! What a run does around each step is its [`LaneTask`]: the ensembles keep states at given
//! times and hand every failure back to be run alone (which reproduces its error exactly);
//! the chaos maps integrate MEGNO's quadrature, renormalise the tangent vectors, apply their
//! early stop and budget, and keep a failure's error, by the same per-step code as their
//! single run, which sees one trajectory through [`RunState`] as its single run sees a
//! [`Solver`].

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::error::{check_finite, FailureReason, IntegrateError, StepFailure};
use super::solver::{check_start, hermite, Solver, Status};
use super::taylor::{polynomial, refused_step, step_norms, StepConstants, Taylor, TaylorSystem};
use super::{add_scaled, Method};
use crate::cancel::CancelToken;
use crate::lanes::{Lane, Lanes};

/// The lowest Taylor order at which the batch has been measured no slower than one start at a
/// time. On 8-lane wide code (AVX-512), with the step on whole lanes, the batch takes 0.65× the
/// time of single runs on the double pendulum at tol 1e-6 (order 8) and 0.35–0.61× from order 11
/// to 20 (`cargo bench --bench batch`, BENCHMARKS.md, "The Taylor method's batch mode"); below
/// order 8 it is unmeasured, so one start at a time. Either way each start's result has the
/// single run's bits. The ensembles and the chaos maps batch from this order.
pub const BATCH_FROM_ORDER: usize = 8;

/// A [`TaylorSystem`] that can also expand several states at once.
pub trait TaylorBatchSystem: TaylorSystem {
    /// The scratch of a batch expansion.
    type Batch: Send;
    /// Scratch for expansions of `order` over about `lanes` lanes (the system chooses the
    /// width it supports nearest), or `None` when this system cannot be expanded in batches.
    fn batch(&self, order: usize, lanes: usize) -> Option<Self::Batch>;
    /// The number of lanes of `batch`: 2, 4 or 8.
    fn lanes(batch: &Self::Batch) -> usize;
    /// Expands lane `l`'s state `(t[l], y[l · dim ..])` into lane `l` of
    /// `out[i · (order + 1) + k]`, with exactly the bits [`TaylorSystem::taylor_coefficients`]
    /// gives for it; lanes the system cannot expand are marked in `failed`. `B` is
    /// [`TaylorBatchSystem::lanes`] of `batch`.
    fn expand_batch<const B: usize>(
        &self,
        batch: &mut Self::Batch,
        t: &[f64],
        y: &[f64],
        out: &mut [Lanes<B>],
        failed: &mut [bool],
    );
}

/// Which states a batch run keeps of each trajectory.
#[derive(Debug, Clone, Copy)]
pub enum BatchOutput<'a> {
    /// The initial and the final state (an adaptive run's `Output::Final`).
    Final,
    /// The states at these times, in the direction of the run, from the dense output; the
    /// stepping stops once the last is passed.
    Times(&'a [f64]),
}

/// What a batch run kept of one trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct LaneRun {
    /// Times of the kept states.
    pub t: Vec<f64>,
    /// The kept states.
    pub y: Vec<Vec<f64>>,
    /// Accepted steps.
    pub steps: usize,
}

/// One trajectory between steps, as a driver's per-step code sees it: a single run's
/// [`Solver`], or a lane of the batch. The chaos indicators' bookkeeping and the ensembles'
/// kept states are written once against this, so the batch runs the single run's code.
pub trait RunState {
    /// Current time.
    fn t(&self) -> f64;
    /// Current state.
    fn y(&self) -> &[f64];
    /// Time and state before the last step.
    fn previous(&self) -> (f64, &[f64]);
    /// Accepted steps so far.
    fn steps(&self) -> usize;
    /// The state at `t` inside the last step ([`Solver::interpolate`]).
    fn interpolate(&mut self, t: f64, out: &mut [f64]) -> Result<(), IntegrateError>;
    /// Component `i` of the last step's dense output at the fraction `theta` of the step
    /// ([`super::TaylorWork::dense_component`]).
    fn dense_component(&self, i: usize, theta: f64) -> Option<f64>;
    /// Replaces the state ([`Solver::set_state`]).
    fn set_state(&mut self, t: f64, y: &[f64]);
}

impl<S: TaylorSystem + ?Sized> RunState for Solver<'_, S, Taylor> {
    fn t(&self) -> f64 {
        Solver::t(self)
    }
    fn y(&self) -> &[f64] {
        Solver::y(self)
    }
    fn previous(&self) -> (f64, &[f64]) {
        Solver::previous(self)
    }
    fn steps(&self) -> usize {
        Solver::steps(self)
    }
    fn interpolate(&mut self, t: f64, out: &mut [f64]) -> Result<(), IntegrateError> {
        Solver::interpolate(self, t, out)
    }
    fn dense_component(&self, i: usize, theta: f64) -> Option<f64> {
        self.work().dense_component(i, theta)
    }
    fn set_state(&mut self, t: f64, y: &[f64]) {
        Solver::set_state(self, t, y)
    }
}

/// What a batch run does with each trajectory around the single method's steps: its own
/// bookkeeping between steps (an ensemble's kept states, a chaos indicator's quadrature and
/// renormalisation), its budget, and when it ends. The driver ([`Taylor::integrate_lanes`])
/// owns the lanes, the expansions, the steps and the refills; the task sees one trajectory at
/// a time through [`RunState`], exactly as a driver stepping that trajectory alone sees its
/// [`Solver`], so a task that does the same as its single-run driver gives the same bits.
pub trait LaneTask {
    /// One trajectory's bookkeeping between steps.
    type Lane;
    /// What a trajectory gives when it ends.
    type Output;
    /// Begins trajectory `index` at its start: its bookkeeping, or at once its output when it
    /// has no step to take.
    fn begin<V: RunState>(&self, index: usize, run: &V) -> Result<Self::Lane, Self::Output>;
    /// Called before each step: `Some` ends the trajectory there with that output (a budget).
    fn before_step<V: RunState>(&self, lane: &mut Self::Lane, run: &V) -> Option<Self::Output>;
    /// Called with each step's result (the step was taken, or failed): `Some` ends the
    /// trajectory with that output.
    fn after_step<V: RunState>(
        &self,
        lane: &mut Self::Lane,
        run: &mut V,
        step: Result<Status, IntegrateError>,
    ) -> Option<Self::Output>;
}

/// One trajectory of a batch run: what its [`Solver`] and [`super::TaylorWork`] would hold
/// (the coefficients of its last step stay in its lane of the batch's output until the next
/// expansion).
struct Track {
    t: f64,
    y: Vec<f64>,
    t_prev: f64,
    y_prev: Vec<f64>,
    /// The compensated update's running error.
    comp: Vec<f64>,
    /// The last step's size, whose polynomial is the lane's coefficients.
    h_last: f64,
    dense_ready: bool,
    steps: usize,
    /// Derivatives at both ends of the last step, for Hermite interpolation (computed lazily).
    rates: Option<(Vec<f64>, Vec<f64>)>,
}

impl Track {
    fn error(&self, reason: FailureReason) -> IntegrateError {
        IntegrateError { t: self.t, state: self.y.clone(), reason, steps: self.steps }
    }

    /// The method's reset ([`Method::reset`]): no compensation carried, no dense output.
    fn reset(&mut self) {
        self.comp.fill(0.0);
        self.dense_ready = false;
    }
}

/// A lane's trajectory seen by its [`LaneTask`]: its [`Track`] and the batch's coefficients.
struct LaneView<'a, S: ?Sized, const B: usize> {
    track: &'a mut Track,
    coeffs: &'a [Lanes<B>],
    lane: usize,
    order: usize,
    sys: &'a S,
    method: &'a Taylor,
}

impl<S: TaylorSystem + ?Sized, const B: usize> LaneView<'_, S, B> {
    /// Component `i` of the last step's series at `x = θ h` (`TaylorWork::series_at`): the
    /// sum on whole lanes, of which this lane's is the single run's (gathering the lane's
    /// coefficients first cost a store-forwarding stall per call: a fifth of a chaos map).
    fn series_at(&self, i: usize, x: f64) -> f64 {
        let s = self.order + 1;
        polynomial(&self.coeffs[i * s..(i + 1) * s], Lanes::splat(x), 0).lane(self.lane)
    }
}

impl<S: TaylorSystem + ?Sized, const B: usize> RunState for LaneView<'_, S, B> {
    fn t(&self) -> f64 {
        self.track.t
    }
    fn y(&self) -> &[f64] {
        &self.track.y
    }
    fn previous(&self) -> (f64, &[f64]) {
        (self.track.t_prev, &self.track.y_prev)
    }
    fn steps(&self) -> usize {
        self.track.steps
    }
    fn interpolate(&mut self, t: f64, out: &mut [f64]) -> Result<(), IntegrateError> {
        let tr = &*self.track;
        let h = tr.t - tr.t_prev;
        if h == 0.0 {
            out.copy_from_slice(&tr.y);
            return Ok(());
        }
        let theta = (t - tr.t_prev) / h;
        if tr.dense_ready {
            let x = theta * tr.h_last;
            for (i, o) in out.iter_mut().enumerate() {
                *o = self.series_at(i, x);
            }
            return Ok(());
        }
        if self.track.rates.is_none() {
            let (tr, n) = (&*self.track, self.track.y.len());
            let (mut f0, mut f1) = (vec![0.0; n], vec![0.0; n]);
            let r = Method::<S>::rate(self.method, self.sys, tr.t_prev, &tr.y_prev, &mut f0)
                .and_then(|_| Method::<S>::rate(self.method, self.sys, tr.t, &tr.y, &mut f1));
            if let Err(StepFailure(reason)) = r {
                return Err(tr.error(reason));
            }
            self.track.rates = Some((f0, f1));
        }
        let tr = &*self.track;
        if let Some((f0, f1)) = &tr.rates {
            hermite(theta, h, (&tr.y_prev, f0), (&tr.y, f1), out);
        }
        Ok(())
    }
    fn dense_component(&self, i: usize, theta: f64) -> Option<f64> {
        let tr = &*self.track;
        (tr.dense_ready && i < tr.y.len()).then(|| self.series_at(i, theta * tr.h_last))
    }
    fn set_state(&mut self, t: f64, y: &[f64]) {
        let tr = &mut *self.track;
        tr.t = t;
        tr.y.copy_from_slice(y);
        tr.rates = None;
        tr.reset();
    }
}

/// A trajectory in a lane.
struct Running<L> {
    index: usize,
    track: Track,
    lane: L,
}

/// The ensemble's task: the states [`BatchOutput`] asks for, a step budget, and every failure
/// handed back (`None`) to be run alone; ended trajectories are counted in `done` (a progress
/// report's count) when given.
pub struct KeepStates<'a> {
    span: Range<f64>,
    starts: &'a [&'a [f64]],
    output: BatchOutput<'a>,
    max_steps: usize,
    done: Option<&'a AtomicUsize>,
}

impl<'a> KeepStates<'a> {
    /// The task of [`Taylor::integrate_batch`]: `starts` over `span`, keeping `output`, each
    /// trajectory at most `max_steps` steps.
    pub fn new(span: Range<f64>, starts: &'a [&'a [f64]], output: BatchOutput<'a>, max_steps: usize) -> Self {
        KeepStates { span, starts, output, max_steps, done: None }
    }

    /// Counts every trajectory that ends in `done`.
    pub fn counting(self, done: &'a AtomicUsize) -> Self {
        KeepStates { done: Some(done), ..self }
    }

    fn ended(&self, out: Option<Option<LaneRun>>) -> Option<Option<LaneRun>> {
        if let (Some(_), Some(done)) = (&out, self.done) {
            done.fetch_add(1, Ordering::Relaxed);
        }
        out
    }
}

/// A [`KeepStates`] trajectory's kept states, its next output time, and a buffer for the dense
/// output.
pub struct Kept {
    run: LaneRun,
    next: usize,
    dense: Vec<f64>,
}

impl LaneTask for KeepStates<'_> {
    type Lane = Kept;
    type Output = Option<LaneRun>;

    fn begin<V: RunState>(&self, index: usize, _: &V) -> Result<Kept, Option<LaneRun>> {
        let (y0, t0) = (self.starts[index], self.span.start);
        let mut run = LaneRun { t: vec![], y: vec![], steps: 0 };
        let mut next = 0;
        match self.output {
            BatchOutput::Final => {
                run.t.push(t0);
                run.y.push(y0.to_vec());
                if t0 == self.span.end {
                    return Err(Some(run));
                }
            }
            BatchOutput::Times(times) => {
                while next < times.len() && times[next] == t0 {
                    run.t.push(t0);
                    run.y.push(y0.to_vec());
                    next += 1;
                }
                if next == times.len() {
                    return Err(Some(run));
                }
            }
        }
        Ok(Kept { run, next, dense: vec![0.0; y0.len()] })
    }

    fn before_step<V: RunState>(&self, _: &mut Kept, run: &V) -> Option<Option<LaneRun>> {
        self.ended((run.steps() >= self.max_steps).then_some(None))
    }

    fn after_step<V: RunState>(
        &self,
        kept: &mut Kept,
        run: &mut V,
        step: Result<Status, IntegrateError>,
    ) -> Option<Option<LaneRun>> {
        let out = self.keep(kept, run, step);
        self.ended(out)
    }
}

impl KeepStates<'_> {
    /// [`LaneTask::after_step`], uncounted.
    fn keep<V: RunState>(
        &self,
        kept: &mut Kept,
        run: &mut V,
        step: Result<Status, IntegrateError>,
    ) -> Option<Option<LaneRun>> {
        let Ok(status) = step else { return Some(None) };
        let finished = status == Status::Finished;
        let done = |kept: &mut Kept, run: &V| {
            let kept_run = std::mem::replace(&mut kept.run, LaneRun { t: vec![], y: vec![], steps: 0 });
            Some(Some(LaneRun { steps: run.steps(), ..kept_run }))
        };
        match self.output {
            BatchOutput::Final => {
                if finished {
                    kept.run.t.push(run.t());
                    kept.run.y.push(run.y().to_vec());
                    return done(kept, run);
                }
            }
            BatchOutput::Times(times) => {
                let dir = (self.span.end - self.span.start).signum();
                let until = run.t();
                while kept.next < times.len() && dir * (times[kept.next] - until) <= 0.0 {
                    if run.interpolate(times[kept.next], &mut kept.dense).is_err() {
                        return Some(None);
                    }
                    kept.run.t.push(times[kept.next]);
                    kept.run.y.push(kept.dense.clone());
                    kept.next += 1;
                }
                if finished || kept.next == times.len() {
                    return done(kept, run);
                }
            }
        }
        None
    }
}

impl Taylor {
    /// Integrates every start in `starts` over `span`, several at once in lanes of batch
    /// expansions (about `lanes` wide), each trajectory bit for bit as [`Taylor`] alone
    /// would. Returns `None` when the system cannot batch; else per start its run, or `None`
    /// for one that failed, ran out of its `max_steps` budget or was cancelled (the caller
    /// runs those alone, to report their errors as a single run does).
    #[allow(clippy::too_many_arguments)] // a single run's inputs, plus the lane count
    pub fn integrate_batch<S: TaylorBatchSystem>(
        &self,
        sys: &S,
        lanes: usize,
        span: Range<f64>,
        starts: &[&[f64]],
        output: BatchOutput<'_>,
        max_steps: usize,
        cancel: Option<&CancelToken>,
    ) -> Option<Vec<Option<LaneRun>>> {
        let task = KeepStates::new(span.clone(), starts, output, max_steps);
        let queue = AtomicUsize::new(0);
        let ran = self.integrate_lanes(sys, lanes, span, starts, &queue, &task, cancel)?;
        let mut runs: Vec<Option<LaneRun>> = vec![None; starts.len()];
        for (index, run) in ran {
            runs[index] = run.flatten();
        }
        Some(runs)
    }

    /// The batch driver under [`Taylor::integrate_batch`] and the chaos maps: the starts of
    /// `starts` over `span` in lanes of batch expansions (about `lanes` wide), each with its
    /// own state and step size and `task`'s bookkeeping around its steps. A lane whose
    /// trajectory ends takes the next start from `queue` (the index of the next untaken
    /// start), which several drivers, one per thread, may share: each start is taken by one of
    /// them, and their lanes idle only once no start is left. Returns `None` when the system
    /// cannot batch; else, for each start this driver took, its index and the task's output,
    /// or `None` for a start the driver hands back: it could not start (its state or span is
    /// not finite, or of the wrong length), or its lane's expansion failed. A start running
    /// when the run is cancelled is not listed. The caller runs the starts handed back or not
    /// listed alone, which reproduces what the single run does with them.
    #[allow(clippy::too_many_arguments)] // a single run's inputs, the lanes and their queue
    pub fn integrate_lanes<S: TaylorBatchSystem, T: LaneTask>(
        &self,
        sys: &S,
        lanes: usize,
        span: Range<f64>,
        starts: &[&[f64]],
        queue: &AtomicUsize,
        task: &T,
        cancel: Option<&CancelToken>,
    ) -> Option<Vec<(usize, Option<T::Output>)>> {
        self.validate().ok()?;
        let order = self.taylor_order().clamp(2, 100);
        let batch = sys.batch(order, lanes)?;
        let run = Starts { sys, order, span, starts, queue };
        match S::lanes(&batch) {
            2 => Some(self.drive::<S, T, 2>(run, batch, task, cancel)),
            4 => Some(self.drive::<S, T, 4>(run, batch, task, cancel)),
            8 => Some(self.drive::<S, T, 8>(run, batch, task, cancel)),
            _ => None,
        }
    }
}

/// What a batch driver runs: `starts` of `sys` over `span` at `order`, taken from `queue`.
struct Starts<'a, S> {
    sys: &'a S,
    order: usize,
    span: Range<f64>,
    starts: &'a [&'a [f64]],
    queue: &'a AtomicUsize,
}

impl<S: TaylorSystem> Starts<'_, S> {
    /// The next untaken start, if any.
    fn take(&self) -> Option<usize> {
        let index = self.queue.fetch_add(1, Ordering::Relaxed);
        (index < self.starts.len()).then_some(index)
    }

    /// Start `index`'s track, or `None` when a single run would refuse it ([`Solver::new`]'s
    /// checks, `check_start`).
    fn track(&self, method: &Taylor, index: usize) -> Option<Track> {
        let (y0, t0) = (self.starts[index], self.span.start);
        check_start(method, self.sys, t0, y0, self.span.end).ok().map(|_| Track {
            t: t0,
            y: y0.to_vec(),
            t_prev: t0,
            y_prev: y0.to_vec(),
            comp: vec![0.0; y0.len()],
            h_last: 0.0,
            dense_ready: false,
            steps: 0,
            rates: None,
        })
    }
}

impl Taylor {
    /// [`Taylor::integrate_lanes`] on `B` lanes.
    fn drive<S: TaylorBatchSystem, T: LaneTask, const B: usize>(
        &self,
        run: Starts<'_, S>,
        mut batch: S::Batch,
        task: &T,
        cancel: Option<&CancelToken>,
    ) -> Vec<(usize, Option<T::Output>)> {
        let (sys, order) = (run.sys, run.order);
        let (dim, s) = (sys.dim(), order + 1);
        let mut coeffs = vec![Lanes::<B>::splat(0.0); dim * s];
        let mut ended: Vec<(usize, Option<T::Output>)> = Vec::new();
        // Loads trajectories into a lane until one has steps to take, or none is left.
        let fill = |ended: &mut Vec<(usize, Option<T::Output>)>, coeffs: &[Lanes<B>], lane: usize| {
            while let Some(index) = run.take() {
                let Some(mut track) = run.track(self, index) else {
                    ended.push((index, None));
                    continue;
                };
                let view = LaneView { track: &mut track, coeffs, lane, order, sys, method: self };
                match task.begin(index, &view) {
                    Ok(l) => return Some(Running { index, track, lane: l }),
                    Err(out) => ended.push((index, Some(out))),
                }
            }
            None
        };
        let mut active: Vec<Option<Running<T::Lane>>> = (0..B).map(|l| fill(&mut ended, &coeffs, l)).collect();
        let (mut ts, mut ys) = (vec![0.0; B], vec![0.0; B * dim]);
        let mut failed = vec![false; B];
        let zero = Lanes::<B>::splat(0.0);
        let mut scratch = LaneScratch {
            y: vec![zero; dim],
            comp: vec![zero; dim],
            inc: vec![zero; dim],
            stepping: [false; B],
            steps: std::array::from_fn(|_| None),
        };
        let plan = StepPlan { sys, order, t_end: run.span.end, constants: StepConstants::new(order) };
        while active.iter().any(Option::is_some) {
            if cancel.is_some_and(CancelToken::is_cancelled) || crate::cancel::interrupted() {
                return ended;
            }
            for (lane, r) in active.iter().enumerate() {
                // An empty lane expands its last state again, which is finite.
                if let Some(r) = r {
                    ts[lane] = r.track.t;
                    ys[lane * dim..(lane + 1) * dim].copy_from_slice(&r.track.y);
                }
            }
            failed.fill(false);
            sys.expand_batch(&mut batch, &ts, &ys, &mut coeffs, &mut failed);
            // Which lanes step: a failed expansion hands its start back, a task may end one.
            let mut stepping = [false; B];
            for lane in 0..B {
                let Some(r) = active[lane].as_mut() else { continue };
                let end = if failed[lane] {
                    Some(None)
                } else {
                    let view = LaneView { track: &mut r.track, coeffs: &coeffs, lane, order, sys, method: self };
                    task.before_step(&mut r.lane, &view).map(Some)
                };
                match end {
                    None => stepping[lane] = true,
                    Some(output) => {
                        if let Some(done) = active[lane].take() {
                            ended.push((done.index, output));
                        }
                        active[lane] = fill(&mut ended, &coeffs, lane);
                    }
                }
            }
            scratch.stepping = stepping;
            self.step_lanes_at_width(&plan, &coeffs, &mut active, &mut scratch);
            for lane in 0..B {
                let (Some(step), Some(r)) = (scratch.steps[lane].take(), active[lane].as_mut()) else { continue };
                let step = step.map_err(|e| *e);
                let mut view = LaneView { track: &mut r.track, coeffs: &coeffs, lane, order, sys, method: self };
                let Some(output) = task.after_step(&mut r.lane, &mut view, step) else { continue };
                if let Some(done) = active[lane].take() {
                    ended.push((done.index, Some(output)));
                }
                active[lane] = fill(&mut ended, &coeffs, lane);
            }
        }
        ended
    }

    /// One step of every lane marked in `stepping`, from the batch's coefficients: what
    /// [`Solver::step`] and the single method's step do, the norms and the series sums on
    /// whole lanes, the rest lane by lane, each lane with its single run's bits. Each stepped
    /// lane's result goes to `steps`.
    #[inline(always)]
    fn step_lanes<S: TaylorSystem, L, const B: usize>(
        &self,
        plan: &StepPlan<'_, S>,
        coeffs: &[Lanes<B>],
        active: &mut [Option<Running<L>>],
        scratch: &mut LaneScratch<B>,
    ) {
        let StepPlan { sys, order, t_end, constants } = *plan;
        let (p, s) = (order, order + 1);
        let steps = &mut scratch.steps;
        let mut go = scratch.stepping;
        let mut remaining = [0.0; B];
        for lane in 0..B {
            let Some(r) = active[lane].as_mut().filter(|_| go[lane]) else { continue };
            let tr = &r.track;
            remaining[lane] = t_end - tr.t;
            if remaining[lane] == 0.0 {
                steps[lane] = Some(Ok(Status::Finished));
                go[lane] = false;
                continue;
            }
            for (y, &v) in scratch.y.iter_mut().zip(&tr.y) {
                y.set_lane(lane, v);
            }
        }
        // The step sizes: norms on whole lanes, the roots lane by lane (`Taylor::step`).
        let (x0, np1, np) = step_norms(&scratch.y, coeffs, p);
        let mut h = Lanes::<B>::splat(0.0);
        for lane in (0..B).filter(|&l| go[l]) {
            let mut hl = self.step_of_norms(x0.lane(lane), np1.lane(lane), np.lane(lane), constants);
            if let Some(m) = self.h_max {
                hl = hl.min(m);
            }
            let req = remaining[lane];
            h.set_lane(lane, if hl >= req.abs() { req } else { req.signum() * hl });
        }
        // The increments `h Σ_{k≥1} c_k h^{k−1}` on whole lanes, which lanes' are not finite,
        // and the updated states (the single step's `add_scaled`, on whole lanes; a lane that
        // fails keeps its state).
        let mut finite = [true; B];
        for (inc, row) in scratch.inc.iter_mut().zip(coeffs.chunks_exact(s)) {
            *inc = h * polynomial(row, h, 1);
            for l in 0..B {
                finite[l] &= inc.0[l].is_finite();
            }
        }
        if self.compensated {
            for lane in (0..B).filter(|&l| go[l]) {
                let Some(r) = active[lane].as_ref() else { continue };
                for (c, &v) in scratch.comp.iter_mut().zip(&r.track.comp) {
                    c.set_lane(lane, v);
                }
            }
        }
        let comp = self.compensated.then_some(&mut scratch.comp[..]);
        add_scaled(&mut scratch.y, comp, Lanes::splat(1.0), &scratch.inc);
        for lane in (0..B).filter(|&l| go[l]) {
            let Some(r) = active[lane].as_mut() else { continue };
            let step = LaneStep { lane, h: h.lane(lane), finite: finite[lane], remaining: remaining[lane], t_end };
            let taken = self.finish_step(sys, p, coeffs, step, &mut r.track, scratch);
            scratch.steps[lane] = Some(taken.map_err(Box::new));
        }
    }

    /// The rest of one lane's step once its size, its increment's finiteness and its updated
    /// state (lane `lane` of `scratch.y`, `scratch.comp`) are known, as [`Solver::step`] and
    /// the single method's step do it: the failures, the update and the bookkeeping.
    fn finish_step<S: TaylorSystem, const B: usize>(
        &self,
        sys: &S,
        p: usize,
        coeffs: &[Lanes<B>],
        LaneStep { lane, h, finite, remaining, t_end }: LaneStep,
        tr: &mut Track,
        scratch: &LaneScratch<B>,
    ) -> Result<Status, IntegrateError> {
        tr.t_prev = tr.t;
        tr.rates = None;
        tr.dense_ready = false;
        let first = || coeffs.iter().position(|c| !c.lane(lane).is_finite());
        if let Some(StepFailure(reason)) = refused_step(sys, (tr.t, &tr.y), p, h, finite, first) {
            tr.y_prev.copy_from_slice(&tr.y);
            tr.reset();
            return Err(tr.error(reason));
        }
        // The state before the step becomes the previous one; the lane's update the current.
        std::mem::swap(&mut tr.y, &mut tr.y_prev);
        for (y, v) in tr.y.iter_mut().zip(&scratch.y) {
            *y = v.lane(lane);
        }
        if self.compensated {
            for (c, v) in tr.comp.iter_mut().zip(&scratch.comp) {
                *c = v.lane(lane);
            }
        }
        tr.h_last = h;
        tr.dense_ready = true;
        if let Err(StepFailure(reason)) = check_finite(&tr.y) {
            tr.y.copy_from_slice(&tr.y_prev);
            tr.reset();
            return Err(tr.error(reason));
        }
        tr.steps += 1;
        tr.t = if h == remaining { t_end } else { tr.t_prev + h };
        Ok(if tr.t == t_end { Status::Finished } else { Status::Stepped })
    }
}

/// One lane's step: its size, whether its increment is finite, what was left of the span before it, and the span's end.
struct LaneStep {
    lane: usize,
    h: f64,
    /// Whether its increment is finite.
    finite: bool,
    remaining: f64,
    t_end: f64,
}

/// The batch step's scratch: the lanes' states, compensations and increments, which lanes
/// step, and their steps' results.
struct LaneScratch<const B: usize> {
    y: Vec<Lanes<B>>,
    comp: Vec<Lanes<B>>,
    inc: Vec<Lanes<B>>,
    stepping: [bool; B],
    /// (An error is boxed: the lanes' results are moved on every step, and failures are rare.)
    steps: [Option<Result<Status, Box<IntegrateError>>>; B],
}

/// What every step of a batch run shares: the system, the order, the span's end and the step
/// size's constants.
struct StepPlan<'a, S> {
    sys: &'a S,
    order: usize,
    t_end: f64,
    constants: StepConstants,
}

impl<S> Clone for StepPlan<'_, S> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<S> Copy for StepPlan<'_, S> {}

impl Taylor {
    /// [`Taylor::step_lanes`] compiled for the vector registers `B` lanes fill, as the batch
    /// expansion is: the same IEEE operations in the same order (no fused multiply-add is
    /// enabled), so the bits do not change.
    fn step_lanes_at_width<S: TaylorSystem, L, const B: usize>(
        &self,
        plan: &StepPlan<'_, S>,
        coeffs: &[Lanes<B>],
        active: &mut [Option<Running<L>>],
        scratch: &mut LaneScratch<B>,
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            if B == 8 && std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                return unsafe { self.step_lanes_avx512(plan, coeffs, active, scratch) };
            }
            if B >= 4 && std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                return unsafe { self.step_lanes_avx2(plan, coeffs, active, scratch) };
            }
        }
        self.step_lanes(plan, coeffs, active, scratch)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn step_lanes_avx512<S: TaylorSystem, L, const B: usize>(
        &self,
        plan: &StepPlan<'_, S>,
        coeffs: &[Lanes<B>],
        active: &mut [Option<Running<L>>],
        scratch: &mut LaneScratch<B>,
    ) {
        self.step_lanes(plan, coeffs, active, scratch)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn step_lanes_avx2<S: TaylorSystem, L, const B: usize>(
        &self,
        plan: &StepPlan<'_, S>,
        coeffs: &[Lanes<B>],
        active: &mut [Option<Running<L>>],
        scratch: &mut LaneScratch<B>,
    ) {
        self.step_lanes(plan, coeffs, active, scratch)
    }
}
