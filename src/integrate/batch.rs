//! Many trajectories of one system by the Taylor method, several expanded at once: the
//! batch mode of ensembles, sweeps and chaos maps.
//!
//! Each trajectory keeps its own [`Solver`] (its own step size, its own end, its own
//! failure); only the expansion, the costly part of a step, is shared: the lanes' states go
//! through one [`TaylorBatchSystem::expand_batch`], and each solver then steps with its
//! lane's coefficients. Since a lane's coefficients are the bits a single expansion gives
//! (the system's promise), and the step, the dense output and the bookkeeping are the single
//! method's own code, every trajectory is bit for bit the one [`Taylor`] computes alone,
//! whatever its neighbours. A trajectory that ends loads the next unstarted one into its lane,
//! taken from a queue the drivers of all threads share.
//!
//! What a run does around each step is its [`LaneTask`]: the ensembles keep states at given
//! times and hand every failure back to be run alone (which reproduces its error exactly);
//! the chaos maps integrate MEGNO's quadrature, renormalise the tangent vectors, apply their
//! early stop and budget, and keep a failure's error, by the same per-step code as their
//! single run.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use super::error::{IntegrateError, RhsError, StepFailure};
use super::solver::{Integrate, Solver, Status};
use super::taylor::{Taylor, TaylorSystem};
use crate::cancel::CancelToken;

/// The lowest Taylor order at which the batch has been measured no slower than one start at a
/// time. On 8-lane wide code (AVX-512) the batch takes 0.83–1.06× the time of single runs on
/// the double pendulum at tol 1e-6 (order 8), 0.83× at order 9 and 0.41–0.86× from order 11 to 20
/// (`cargo bench --bench batch`, BENCHMARKS.md, "The Taylor method's batch mode"); below order 8
/// it is unmeasured, so one start at a time. Either way each start's result has the single
/// run's bits. The ensembles and the chaos maps batch from this order.
pub const BATCH_FROM_ORDER: usize = 8;

/// A [`TaylorSystem`] that can also expand several states at once.
pub trait TaylorBatchSystem: TaylorSystem {
    /// The scratch of a batch expansion.
    type Batch: Send;
    /// Scratch for expansions of `order` over about `lanes` lanes (the system chooses the
    /// width it supports nearest), or `None` when this system cannot be expanded in batches.
    fn batch(&self, order: usize, lanes: usize) -> Option<Self::Batch>;
    /// The number of lanes of `batch`.
    fn lanes(batch: &Self::Batch) -> usize;
    /// Expands lane `l`'s state `(t[l], y[l · dim ..])` into
    /// `out[l · dim · (order + 1) + i · (order + 1) + k]`, with exactly the bits
    /// [`TaylorSystem::taylor_coefficients`] gives for it; lanes the system cannot expand are
    /// marked in `failed`.
    fn expand_batch(&self, batch: &mut Self::Batch, t: &[f64], y: &[f64], out: &mut [f64], failed: &mut [bool]);
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

/// One lane's view of the system: the coefficients the batch expansion wrote for it (lane
/// `lane` of the batch's output, which all the lanes share and read in turn), handed to the
/// single method's step as if it had expanded them itself.
struct LaneSystem<'a, S> {
    sys: &'a S,
    order: usize,
    lane: usize,
    coeffs: &'a Mutex<Vec<f64>>,
}

impl<S: TaylorSystem> TaylorSystem for LaneSystem<'_, S> {
    fn dim(&self) -> usize {
        self.sys.dim()
    }
    fn scratch_len(&self, order: usize) -> usize {
        self.sys.scratch_len(order)
    }
    fn taylor_coefficients(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), RhsError> {
        if order != self.order {
            return self.sys.taylor_coefficients(t, y, order, buf);
        }
        let len = self.sys.dim() * (order + 1);
        let c = self.coeffs.lock().unwrap_or_else(|e| e.into_inner());
        buf[..len].copy_from_slice(&c[self.lane * len..(self.lane + 1) * len]);
        Ok(())
    }
    fn non_finite(&self, t: f64, y: &[f64], order: usize, at: usize) -> StepFailure {
        self.sys.non_finite(t, y, order, at)
    }
}

/// What a batch run does with each trajectory around the single method's steps: its own
/// bookkeeping between steps (an ensemble's kept states, a chaos indicator's quadrature and
/// renormalisation), its budget, and when it ends. The driver ([`Taylor::integrate_lanes`])
/// owns the lanes, the expansions and the refills; the task sees one trajectory's [`Solver`]
/// at a time, exactly as a driver stepping that trajectory alone would, so a task that does
/// the same as its single-run driver gives the same bits.
///
/// The methods are generic over the solver's system because the lanes' system is the
/// driver's own view of `S` (the batch's coefficients handed to the single method's step).
pub trait LaneTask {
    /// One trajectory's bookkeeping between steps.
    type Lane;
    /// What a trajectory gives when it ends.
    type Output;
    /// Begins trajectory `index` on its fresh solver: its bookkeeping, or at once its output
    /// when it has no step to take.
    fn begin<X: TaylorSystem>(&self, index: usize, solver: &Solver<'_, X, Taylor>) -> Result<Self::Lane, Self::Output>;
    /// Called before each step: `Some` ends the trajectory there with that output (a budget).
    fn before_step<X: TaylorSystem>(
        &self,
        lane: &mut Self::Lane,
        solver: &Solver<'_, X, Taylor>,
    ) -> Option<Self::Output>;
    /// Called with each step's result (the solver has taken it, or failed): `Some` ends the
    /// trajectory with that output.
    fn after_step<X: TaylorSystem>(
        &self,
        lane: &mut Self::Lane,
        solver: &mut Solver<'_, X, Taylor>,
        step: Result<Status, IntegrateError>,
    ) -> Option<Self::Output>;
}

/// A trajectory in a lane.
struct Running<'s, S: TaylorSystem, L> {
    index: usize,
    solver: Solver<'s, LaneSystem<'s, S>, Taylor>,
    lane: L,
}

/// The ensemble's task: the states [`BatchOutput`] asks for, a step budget, and every failure
/// handed back (`None`) to be run alone.
struct Keep<'a> {
    span: Range<f64>,
    starts: &'a [&'a [f64]],
    output: BatchOutput<'a>,
    max_steps: usize,
}

/// An ensemble trajectory's kept states, its next output time, and a buffer for the dense
/// output.
struct Kept {
    run: LaneRun,
    next: usize,
    dense: Vec<f64>,
}

impl LaneTask for Keep<'_> {
    type Lane = Kept;
    type Output = Option<LaneRun>;

    fn begin<X: TaylorSystem>(&self, index: usize, _: &Solver<'_, X, Taylor>) -> Result<Kept, Option<LaneRun>> {
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

    fn before_step<X: TaylorSystem>(&self, _: &mut Kept, solver: &Solver<'_, X, Taylor>) -> Option<Option<LaneRun>> {
        (solver.steps() >= self.max_steps).then_some(None)
    }

    fn after_step<X: TaylorSystem>(
        &self,
        kept: &mut Kept,
        solver: &mut Solver<'_, X, Taylor>,
        step: Result<Status, IntegrateError>,
    ) -> Option<Option<LaneRun>> {
        let Ok(status) = step else { return Some(None) };
        let finished = status == Status::Finished;
        let done = |kept: &mut Kept, solver: &Solver<'_, X, Taylor>| {
            let run = std::mem::replace(&mut kept.run, LaneRun { t: vec![], y: vec![], steps: 0 });
            Some(Some(LaneRun { steps: solver.steps(), ..run }))
        };
        match self.output {
            BatchOutput::Final => {
                if finished {
                    kept.run.t.push(solver.t());
                    kept.run.y.push(solver.y().to_vec());
                    return done(kept, solver);
                }
            }
            BatchOutput::Times(times) => {
                let dir = (self.span.end - self.span.start).signum();
                let until = solver.t();
                while kept.next < times.len() && dir * (times[kept.next] - until) <= 0.0 {
                    if solver.interpolate(times[kept.next], &mut kept.dense).is_err() {
                        return Some(None);
                    }
                    kept.run.t.push(times[kept.next]);
                    kept.run.y.push(kept.dense.clone());
                    kept.next += 1;
                }
                if finished || kept.next == times.len() {
                    return done(kept, solver);
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
        let task = Keep { span: span.clone(), starts, output, max_steps };
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
    /// own [`Solver`] and `task`'s bookkeeping around its steps. A lane whose trajectory ends
    /// takes the next start from `queue` (the index of the next untaken start), which several
    /// drivers, one per thread, may share: each start is taken by one of them, and their lanes
    /// idle only once no start is left. Returns `None` when the system cannot batch; else, for
    /// each start this driver took, its index and the task's output, or `None` for a start the
    /// driver hands back: its solver could not start, or its lane's expansion failed. A start
    /// running when the run is cancelled is not listed. The caller runs the starts handed back
    /// or not listed alone, which reproduces what the single run does with them.
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
        let mut batch = sys.batch(order, lanes)?;
        let width = S::lanes(&batch);
        let (dim, s) = (sys.dim(), order + 1);
        // The batch's output, each lane's coefficients read by its solver's step.
        let out = Mutex::new(vec![0.0; width * dim * s]);
        let slots: Vec<LaneSystem<S>> = (0..width).map(|lane| LaneSystem { sys, order, lane, coeffs: &out }).collect();
        let mut ended: Vec<(usize, Option<T::Output>)> = Vec::new();
        let take = || {
            let index = queue.fetch_add(1, Ordering::Relaxed);
            (index < starts.len()).then_some(index)
        };
        // Starts a trajectory in `lane`; `None` when it has nothing to step (done or refused).
        let start = |index: usize, lane: usize, ended: &mut Vec<(usize, Option<T::Output>)>| {
            let Ok(solver) = self.solver(&slots[lane], span.start, starts[index], span.end) else {
                ended.push((index, None));
                return None;
            };
            match task.begin(index, &solver) {
                Ok(lane) => Some(Running { index, solver, lane }),
                Err(out) => {
                    ended.push((index, Some(out)));
                    None
                }
            }
        };
        // Loads trajectories into `lane` until one has steps to take, or none is left.
        let fill = |lane: usize, ended: &mut Vec<(usize, Option<T::Output>)>| {
            while let Some(j) = take() {
                if let Some(r) = start(j, lane, ended) {
                    return Some(r);
                }
            }
            None
        };
        let mut active: Vec<Option<Running<S, T::Lane>>> = (0..width).map(|lane| fill(lane, &mut ended)).collect();
        let (mut ts, mut ys) = (vec![0.0; width], vec![0.0; width * dim]);
        let mut failed = vec![false; width];
        while active.iter().any(Option::is_some) {
            if cancel.is_some_and(CancelToken::is_cancelled) || crate::cancel::interrupted() {
                return Some(ended);
            }
            for (lane, r) in active.iter().enumerate() {
                // An empty lane expands its last state again, which is finite.
                if let Some(r) = r {
                    ts[lane] = r.solver.t();
                    ys[lane * dim..(lane + 1) * dim].copy_from_slice(r.solver.y());
                }
            }
            failed.fill(false);
            sys.expand_batch(&mut batch, &ts, &ys, &mut out.lock().unwrap_or_else(|e| e.into_inner()), &mut failed);
            for lane in 0..width {
                let Some(r) = active[lane].as_mut() else { continue };
                let end = if failed[lane] {
                    Some(None)
                } else if let Some(output) = task.before_step(&mut r.lane, &r.solver) {
                    Some(Some(output))
                } else {
                    let step = r.solver.step();
                    task.after_step(&mut r.lane, &mut r.solver, step).map(Some)
                };
                let Some(output) = end else { continue };
                if let Some(done) = active[lane].take() {
                    ended.push((done.index, output));
                }
                active[lane] = fill(lane, &mut ended);
            }
        }
        Some(ended)
    }
}
