//! Many trajectories of one system by the Taylor method, several expanded at once: the
//! batch mode of ensembles, sweeps and chaos maps.
//!
//! Each trajectory keeps its own [`Solver`] (its own step size, its own end, its own
//! failure); only the expansion, the costly part of a step, is shared: the lanes' states go
//! through one [`TaylorBatchSystem::expand_batch`], and each solver then steps with its
//! lane's coefficients. Since a lane's coefficients are the bits a single expansion gives
//! (the system's promise), and the step, the dense output and the bookkeeping are the single
//! method's own code, every trajectory is bit for bit the one [`Taylor`] computes alone,
//! whatever its neighbours. A trajectory that ends loads the next one into its lane
//! ([`LaneRefill`]); one that fails is handed back to be run alone, which reproduces its
//! error exactly.

use std::ops::Range;
use std::sync::Mutex;

use super::error::{RhsError, StepFailure};
use super::solver::{Integrate, Solver, Status};
use super::taylor::{Taylor, TaylorSystem};
use crate::cancel::CancelToken;

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

/// Which trajectory each lane of a batch holds. When a lane's trajectory ends (finished or
/// failed), [`LaneRefill::finish`] loads the next unstarted one into that lane, so a batch
/// never idles while trajectories remain; one lane's end never touches the others.
#[derive(Debug, Clone)]
pub struct LaneRefill {
    lanes: Vec<Option<usize>>,
    next: usize,
    total: usize,
}

impl LaneRefill {
    /// `lanes` lanes over trajectories `0..total`, the first `min(lanes, total)` loaded.
    pub fn new(lanes: usize, total: usize) -> Self {
        let loaded = lanes.min(total);
        let slots = (0..lanes).map(|i| (i < loaded).then_some(i)).collect();
        LaneRefill { lanes: slots, next: loaded, total }
    }

    /// The trajectory lane `lane` holds, or `None` if it is empty (nothing left to load).
    pub fn lane(&self, lane: usize) -> Option<usize> {
        self.lanes[lane]
    }

    /// Ends lane `lane`'s trajectory and loads the next unstarted one, which it returns (the
    /// caller copies that initial condition into the lane); `None` leaves the lane empty.
    pub fn finish(&mut self, lane: usize) -> Option<usize> {
        let refill = (self.next < self.total).then_some(self.next);
        self.next += usize::from(refill.is_some());
        self.lanes[lane] = refill;
        refill
    }

    /// Whether every lane is empty: all trajectories have ended.
    pub fn done(&self) -> bool {
        self.lanes.iter().all(Option::is_none)
    }
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

/// One lane's view of the system: the coefficients the batch expansion wrote for it, handed
/// to the single method's step as if it had expanded them itself.
struct LaneSystem<'a, S> {
    sys: &'a S,
    order: usize,
    coeffs: Mutex<Vec<f64>>,
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
        let c = self.coeffs.lock().unwrap_or_else(|e| e.into_inner());
        buf[..c.len()].copy_from_slice(&c);
        Ok(())
    }
    fn non_finite(&self, t: f64, y: &[f64], order: usize, at: usize) -> StepFailure {
        self.sys.non_finite(t, y, order, at)
    }
}

/// A trajectory in a lane.
struct Running<'s, S: TaylorSystem> {
    index: usize,
    solver: Solver<'s, LaneSystem<'s, S>, Taylor>,
    run: LaneRun,
    /// The next output time (for [`BatchOutput::Times`]).
    next: usize,
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
        self.validate().ok()?;
        let order = self.taylor_order().clamp(2, 100);
        let mut batch = sys.batch(order, lanes)?;
        let width = S::lanes(&batch);
        let (dim, s) = (sys.dim(), order + 1);
        let slots: Vec<LaneSystem<S>> =
            (0..width).map(|_| LaneSystem { sys, order, coeffs: Mutex::new(vec![0.0; dim * s]) }).collect();
        let mut results: Vec<Option<LaneRun>> = vec![None; starts.len()];
        let mut refill = LaneRefill::new(width, starts.len());
        let dir = (span.end - span.start).signum();
        // Starts a trajectory in `lane`; `None` when it has nothing to step (done or refused).
        let start = |index: usize, lane: usize, results: &mut Vec<Option<LaneRun>>| -> Option<Running<S>> {
            let y0 = starts[index];
            let solver = self.solver(&slots[lane], span.start, y0, span.end).ok()?;
            let mut run = LaneRun { t: vec![], y: vec![], steps: 0 };
            let mut next = 0;
            match output {
                BatchOutput::Final => {
                    run.t.push(span.start);
                    run.y.push(y0.to_vec());
                    if span.start == span.end {
                        results[index] = Some(run);
                        return None;
                    }
                }
                BatchOutput::Times(times) => {
                    while next < times.len() && times[next] == span.start {
                        run.t.push(span.start);
                        run.y.push(y0.to_vec());
                        next += 1;
                    }
                    if next == times.len() {
                        results[index] = Some(run);
                        return None;
                    }
                }
            }
            Some(Running { index, solver, run, next })
        };
        // Loads trajectories into `lane` until one has steps to take, or none is left.
        let fill = |lane: usize, first: Option<usize>, refill: &mut LaneRefill, results: &mut Vec<Option<LaneRun>>| {
            let mut candidate = first;
            while let Some(j) = candidate {
                if let Some(r) = start(j, lane, results) {
                    return Some(r);
                }
                candidate = refill.finish(lane);
            }
            None
        };
        let mut active: Vec<Option<Running<S>>> = Vec::with_capacity(width);
        for lane in 0..width {
            let first = refill.lane(lane);
            active.push(fill(lane, first, &mut refill, &mut results));
        }
        let (mut ts, mut ys) = (vec![0.0; width], vec![0.0; width * dim]);
        let mut out = vec![0.0; width * dim * s];
        let mut failed = vec![false; width];
        let mut dense = vec![0.0; dim];
        while active.iter().any(Option::is_some) {
            if cancel.is_some_and(CancelToken::is_cancelled) || crate::cancel::interrupted() {
                return Some(results);
            }
            for (lane, r) in active.iter().enumerate() {
                // An empty lane expands its last state again, which is finite.
                if let Some(r) = r {
                    ts[lane] = r.solver.t();
                    ys[lane * dim..(lane + 1) * dim].copy_from_slice(r.solver.y());
                }
            }
            failed.fill(false);
            sys.expand_batch(&mut batch, &ts, &ys, &mut out, &mut failed);
            for lane in 0..width {
                let Some(r) = active[lane].as_mut() else { continue };
                let ended = if failed[lane] || r.solver.steps() >= max_steps {
                    Some(false)
                } else {
                    let coeffs = &out[lane * dim * s..(lane + 1) * dim * s];
                    slots[lane].coeffs.lock().unwrap_or_else(|e| e.into_inner()).copy_from_slice(coeffs);
                    match r.solver.step() {
                        Err(_) => Some(false),
                        Ok(status) => {
                            let finished = status == Status::Finished;
                            let mut ok = true;
                            match output {
                                BatchOutput::Final => {
                                    if finished {
                                        r.run.t.push(r.solver.t());
                                        r.run.y.push(r.solver.y().to_vec());
                                    }
                                }
                                BatchOutput::Times(times) => {
                                    let until = r.solver.t();
                                    while r.next < times.len() && dir * (times[r.next] - until) <= 0.0 {
                                        if r.solver.interpolate(times[r.next], &mut dense).is_err() {
                                            ok = false;
                                            break;
                                        }
                                        r.run.t.push(times[r.next]);
                                        r.run.y.push(dense.clone());
                                        r.next += 1;
                                    }
                                }
                            }
                            let all_out = matches!(output, BatchOutput::Times(times) if r.next == times.len());
                            (!ok || finished || all_out).then_some(ok)
                        }
                    }
                };
                let Some(ok) = ended else { continue };
                if let Some(done) = active[lane].take().filter(|_| ok) {
                    results[done.index] = Some(LaneRun { steps: done.solver.steps(), ..done.run });
                }
                let next = refill.finish(lane);
                active[lane] = fill(lane, next, &mut refill, &mut results);
            }
        }
        Some(results)
    }
}
