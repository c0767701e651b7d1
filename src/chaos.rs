//! Chaos indicators from the variational equations ([`crate::compile::Variational`]),
//! integrated by the Taylor method:
//!
//! * the Lyapunov exponents by Benettin's algorithm (Benettin, Galgani, Giorgilli & Strelcyn,
//!   Meccanica 15, 1980): after every step the tangent vectors are re-orthonormalised by
//!   Gram–Schmidt (a QR factorisation), and `λ_j(t) = (1/t) Σ ln R_jj`; with one vector this
//!   is the maximal exponent with periodic renormalisation;
//! * the fast Lyapunov indicator `FLI(t) = sup_{s ≤ t} ln ‖w(s)‖` of the first tangent vector
//!   from a unit vector (Froeschlé, Lega & Gonczi 1997);
//! * MEGNO, `Y(t) = (2/t) ∫₀ᵗ s (ẇ·w / w·w) ds` and its running mean
//!   `Ȳ(t) = (1/t) ∫₀ᵗ Y(s) ds` (Cincotta & Simó 2000): `Ȳ → 0` for stable isochronous
//!   motion (a harmonic oscillator), `Ȳ → 2` for quasi-periodic motion, `Ȳ ≈ λ t / 2` for
//!   chaotic motion. The inner integral is a state of the variational system (integrated
//!   by the Taylor method with everything else); the outer one is a 5-point Gauss–Legendre
//!   quadrature of `2 y(s)/s` on each step's own polynomial (no extra right-hand sides).
//!
//! A chaos map evaluates an indicator over many initial conditions in parallel (rayon).
//!
//! [`floquet`] gives the monodromy matrix `M = Φ(T)` over a period and its eigenvalues, the
//! Floquet multipliers: the linear stability of a periodic orbit, or of a periodically
//! forced linear system such as Mathieu's equation.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::compile::Variational;
use crate::integrate::{
    FailureReason, Integrate, IntegrateError, LaneTask, RunState, Status, Taylor, BATCH_FROM_ORDER,
};

/// What a chaos statement may spend: Taylor steps per orbit, wall-clock time for all its
/// orbits together, and samples kept along an orbit. An indicator over `0..1e9` would
/// otherwise step for hours and keep every step's sample (31 MB/s); past the step or time
/// budget the orbit ends with [`FailureReason::StepLimit`] or [`FailureReason::TimeLimit`],
/// and past `max_samples` the kept samples are thinned evenly (every other one dropped and
/// the stride doubled, as [`crate::integrate::Output::AtMost`] does), so memory is bounded
/// whatever the span.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Taylor steps of one orbit.
    pub max_steps: usize,
    /// When every orbit of the statement must have ended (`None`: no time budget).
    pub deadline: Option<Instant>,
    /// The time budget the deadline came from, for the error message.
    pub time_limit: Option<Duration>,
    /// Samples kept along one orbit (at least 2).
    pub max_samples: usize,
    /// Stop an orbit early once its mean MEGNO has clearly diverged (`None`: run every orbit
    /// to its end). Opt-in because it changes what is reported: see [`MegnoStop`].
    pub megno_stop: Option<MegnoStop>,
}

/// An early stop for orbits whose running mean MEGNO `Ȳ(t)` has left the regular range: once
/// `t ≥ after`, the first step ending with `Ȳ(t) ≥ above` ends the orbit there, and its
/// [`Indicators::stopped_at`] says when. The indicators are then those at that time, so a map
/// reports the cell as "`Ȳ ≥ above`", never as a value at the end time. A chaotic orbit's `Ȳ`
/// grows like `λ t / 2`, so in a chaos map most of the time goes to orbits whose class is
/// already settled; a regular one stays near 2 (quasi-periodic) or 0 (isochronous). Whether a
/// stopped orbit could have come back below a threshold by the end time is not decided here:
/// `Ȳ(T) ≥ (after / T) · above` holds only when `Y ≥ 0` afterwards, so the choice of `above`
/// and `after` is the caller's, checked on the map it is used for (BENCHMARKS.md, the double
/// pendulum's 200 × 200 map). Without the MEGNO accumulator it never stops an orbit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MegnoStop {
    /// The mean MEGNO at or above which an orbit stops (finite, above 2: the quasi-periodic
    /// value).
    pub above: f64,
    /// The time before which no orbit stops (finite, at least 0).
    pub after: f64,
}

impl MegnoStop {
    /// The stop, or why it is refused.
    pub fn new(above: f64, after: f64) -> Result<MegnoStop, String> {
        if !(above.is_finite() && above > 2.0) {
            return Err(format!(
                "the MEGNO stop level {above} must be finite and above 2 (a quasi-periodic orbit's mean MEGNO tends to 2)"
            ));
        }
        if !(after.is_finite() && after >= 0.0) {
            return Err(format!("the MEGNO stop time {after} must be finite and at least 0"));
        }
        Ok(MegnoStop { above, after })
    }
}

impl Budget {
    /// The default step budget of an orbit: 10⁷ Taylor steps (seconds for a small system).
    pub const DEFAULT_STEPS: usize = 10_000_000;
    /// The default time budget of a statement: 600 s.
    pub const DEFAULT_SECONDS: f64 = 600.0;
    /// The default number of samples kept along an orbit.
    pub const DEFAULT_SAMPLES: usize = 20_000;

    /// A budget of `max_steps` steps per orbit and `time_limit` from now.
    pub fn new(max_steps: usize, time_limit: Duration) -> Budget {
        Budget {
            max_steps,
            deadline: Instant::now().checked_add(time_limit),
            time_limit: Some(time_limit),
            max_samples: Budget::DEFAULT_SAMPLES,
            megno_stop: None,
        }
    }
}

impl Default for Budget {
    /// The default budgets, the time counted from now.
    fn default() -> Budget {
        Budget::new(Budget::DEFAULT_STEPS, Duration::from_secs_f64(Budget::DEFAULT_SECONDS))
    }
}

/// Gauss–Legendre nodes and weights on `[−1, 1]`, 5 points (exact for degree 9; Abramowitz &
/// Stegun, Table 25.4).
const GL5: [(f64, f64); 5] = [
    (0.0, 0.568_888_888_888_888_9),
    (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
    (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
    (0.906_179_845_938_664, 0.236_926_885_056_189_1),
];

/// The least-squares slope of `Y(s)` against `s` on `[0, t]`, from `∫ Y ds` and `∫ s Y ds`:
/// `cov(s, Y) / var(s)` with the uniform weight over time, where `var(s) = t²/12` and
/// `cov(s, Y) = (1/t) ∫ s Y ds − (t/2) (1/t) ∫ Y ds`.
fn megno_slope(t: f64, y_int: f64, sy_int: f64) -> f64 {
    let cov = sy_int / t - 0.5 * y_int;
    cov / (t * t / 12.0)
}

/// One sample of a run's indicators (at the end of a step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time.
    pub t: f64,
    /// The finite-time maximal Lyapunov exponent `λ₀(t)`.
    pub lyapunov: f64,
    /// `ln ‖w₀(t)‖` (its running maximum is the FLI).
    pub log_norm: f64,
    /// The mean MEGNO `Ȳ(t)` (NaN without the accumulator).
    pub megno: f64,
}

/// The indicators of one orbit.
#[derive(Clone, Debug, PartialEq)]
pub struct Indicators {
    /// The finite-time Lyapunov exponents at the end time, one per tangent vector (largest
    /// first for a generic start).
    pub lyapunov: Vec<f64>,
    /// The fast Lyapunov indicator at the end time.
    pub fli: f64,
    /// The mean MEGNO `Ȳ` at the end time (NaN without the accumulator).
    pub megno: f64,
    /// The maximal Lyapunov exponent from MEGNO: the least-squares slope of `Y(s)` against `s`
    /// over the run (`Y ≈ λ s` for chaotic motion; Cincotta & Simó 2000, eq. 24; what
    /// REBOUND's `lyapunov()` reports). On a regular orbit `Y` levels off, so this falls like
    /// 1/t², where the finite-time `lyapunov[0]` falls only like ln t / t (0.0077 for a Kepler
    /// orbit that this gives as ~1e-5). NaN without the accumulator.
    pub megno_lyapunov: f64,
    /// The indicators along the run: one sample per step, thinned evenly to at most
    /// [`Budget::max_samples`] (the last step's sample is always kept).
    pub samples: Vec<Sample>,
    /// Taylor steps taken.
    pub steps: usize,
    /// The time at which the orbit stopped because its mean MEGNO reached the budget's
    /// [`MegnoStop::above`] (`None`: it ran to the end time). The indicators are those at
    /// that time.
    pub stopped_at: Option<f64>,
}

/// Integrates the variational system from `x0` (tangents start as unit vectors) over
/// `0..t_end` with the Taylor method at `tol`, re-orthonormalising the tangent vectors after
/// every step, within the default [`Budget`].
pub fn indicators(sys: &Variational, x0: &[f64], t_end: f64, tol: f64) -> Result<Indicators, IntegrateError> {
    indicators_with(sys, x0, t_end, tol, &Budget::default())
}

/// [`indicators`] within `budget`.
pub fn indicators_with(
    sys: &Variational,
    x0: &[f64],
    t_end: f64,
    tol: f64,
    budget: &Budget,
) -> Result<Indicators, IntegrateError> {
    indicators_from(sys, &sys.initial_state(x0), t_end, tol, budget)
}

/// The initial state of `sys` from `x0` with the first tangent vector along `w0` (normalised)
/// and the others the unit vectors made orthonormal to it and to each other by Gram–Schmidt
/// (a unit vector dependent on those before it is skipped for the next one). MEGNO and the FLI
/// follow the first tangent vector, so `w0` chooses the direction they measure; `None` when
/// `w0` has the wrong length, is not finite or is zero.
pub fn initial_state_along(sys: &Variational, x0: &[f64], w0: &[f64]) -> Option<Vec<f64>> {
    let (n, m) = (sys.n(), sys.tangents());
    let norm = w0.iter().map(|a| a * a).sum::<f64>().sqrt();
    if w0.len() != n || !norm.is_finite() || norm == 0.0 {
        return None;
    }
    let mut basis: Vec<Vec<f64>> = vec![w0.iter().map(|a| a / norm).collect()];
    let mut k = 0;
    while basis.len() < m && k < n {
        let mut v: Vec<f64> = (0..n).map(|i| if i == k { 1.0 } else { 0.0 }).collect();
        k += 1;
        for b in &basis {
            let r: f64 = v.iter().zip(b).map(|(a, c)| a * c).sum();
            v.iter_mut().zip(b).for_each(|(a, c)| *a -= r * c);
        }
        let len = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        if len > 1e-8 {
            basis.push(v.iter().map(|a| a / len).collect());
        }
    }
    let mut y = sys.initial_state(x0);
    for (j, b) in basis.iter().take(m).enumerate() {
        y[n + j * n..n + (j + 1) * n].copy_from_slice(b);
    }
    Some(y)
}

/// [`indicators_with`] from the whole initial state `y0` of `sys` (the state, its tangent
/// vectors, orthonormal, and the MEGNO accumulator, as [`Variational::initial_state`] or
/// [`initial_state_along`] build it).
pub fn indicators_from(
    sys: &Variational,
    y0: &[f64],
    t_end: f64,
    tol: f64,
    budget: &Budget,
) -> Result<Indicators, IntegrateError> {
    let method = Taylor::new(tol);
    let mut solver = method.solver(sys, 0.0, y0, t_end)?;
    let mut orbit = Orbit::new(sys, budget, budget.deadline);
    loop {
        orbit.check_budget(&solver)?;
        let status = solver.step()?;
        if orbit.after_step(&mut solver, status)? {
            return Ok(orbit.finish(&solver));
        }
    }
}

/// One orbit's indicators between steps: the single run's loop ([`indicators_from`]) and a
/// lane of the batch ([`chaos_map_with`]) both step a solver and hand each step to
/// [`Orbit::after_step`], so an orbit's numbers are the same bits whichever ran it.
struct Orbit<'a> {
    sys: &'a Variational,
    budget: &'a Budget,
    /// When this orbit must have ended: the map's deadline, or one of its own.
    deadline: Option<Instant>,
    logs: Vec<f64>,
    fli: f64,
    /// `∫ Y ds` and `∫ s Y ds` over the run, for `Ȳ` and for the slope of `Y` against `s`.
    ybar_int: f64,
    sy_int: f64,
    y: Vec<f64>,
    buf: Vec<f64>,
    samples: Vec<Sample>,
    stride: usize,
    taken: usize,
    stopped_at: Option<f64>,
}

impl<'a> Orbit<'a> {
    fn new(sys: &'a Variational, budget: &'a Budget, deadline: Option<Instant>) -> Orbit<'a> {
        let dim = sys.dim();
        Orbit {
            sys,
            budget,
            deadline,
            logs: vec![0.0; sys.tangents()],
            fli: 0.0,
            ybar_int: 0.0,
            sy_int: 0.0,
            y: vec![0.0; dim],
            buf: vec![0.0; dim],
            samples: Vec::new(),
            stride: 1,
            taken: 0,
            stopped_at: None,
        }
    }

    /// The budget before a step: the orbit's steps and the deadline (read every 64 steps).
    fn check_budget<V: RunState>(&self, solver: &V) -> Result<(), IntegrateError> {
        let budget = self.budget;
        let stop = |reason: FailureReason| IntegrateError {
            t: solver.t(),
            state: solver.y()[..self.sys.n()].to_vec(),
            reason,
            steps: solver.steps(),
        };
        if solver.steps() >= budget.max_steps {
            return Err(stop(FailureReason::StepLimit { max_steps: budget.max_steps }));
        }
        if solver.steps() % 64 == 0 && self.deadline.is_some_and(|d| Instant::now() >= d) {
            let seconds = budget.time_limit.map_or(0.0, |l| l.as_secs_f64());
            return Err(stop(FailureReason::TimeLimit { seconds }));
        }
        Ok(())
    }

    /// Takes in the step `solver` has just taken (with `status`): the MEGNO quadrature on its
    /// polynomial, the tangent vectors' renormalisation (written back into the solver), the
    /// sample, the early stop. Whether the orbit has ended.
    fn after_step<V: RunState>(&mut self, solver: &mut V, status: Status) -> Result<bool, IntegrateError> {
        let sys = self.sys;
        let (n, m, dim) = (sys.n(), sys.tangents(), sys.dim());
        let (t0, t1) = (solver.previous().0, solver.t());
        if sys.has_megno() {
            let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
            let (mut acc, mut acc_s) = (0.0, 0.0);
            for (x, w) in GL5 {
                let s = mid + half * x;
                // Only the accumulator's polynomial (the last of `dim`): the other components'
                // were a tenth of a chaos map's time. Same bits as `interpolate`'s.
                let theta = (s - t0) / (t1 - t0);
                let integral = match solver.dense_component(dim - 1, theta) {
                    Some(v) if t1 != t0 => v,
                    _ => {
                        solver.interpolate(s, &mut self.buf)?;
                        self.buf[dim - 1]
                    }
                };
                let y_s = 2.0 * integral / s;
                acc += w * y_s;
                acc_s += w * s * y_s;
            }
            self.ybar_int += acc * half;
            self.sy_int += acc_s * half;
        }
        let y = &mut self.y;
        y.copy_from_slice(solver.y());
        // Modified Gram–Schmidt on the tangent vectors: w_j ← (w_j − Σ_{k<j} (w_j·q_k) q_k) / R_jj.
        for (j, log) in self.logs.iter_mut().enumerate() {
            let (done, rest) = y[n..n + m * n].split_at_mut(j * n);
            let wj = &mut rest[..n];
            for k in 0..j {
                let qk = &done[k * n..(k + 1) * n];
                let r: f64 = wj.iter().zip(qk).map(|(a, b)| a * b).sum();
                wj.iter_mut().zip(qk).for_each(|(a, b)| *a -= r * b);
            }
            let norm = wj.iter().map(|a| a * a).sum::<f64>().sqrt();
            *log += norm.ln();
            wj.iter_mut().for_each(|a| *a /= norm);
        }
        self.fli = self.fli.max(self.logs[0]);
        solver.set_state(t1, y);
        // The budget's early stop: this step's end is the orbit's end.
        let ybar_int = self.ybar_int;
        let diverged = self
            .budget
            .megno_stop
            .is_some_and(|stop| sys.has_megno() && t1 >= stop.after && t1 > 0.0 && ybar_int / t1 >= stop.above);
        if diverged && status != Status::Finished {
            self.stopped_at = Some(t1);
        }
        let finished = status == Status::Finished || diverged;
        self.taken += 1;
        if self.taken % self.stride == 0 || finished {
            self.samples.push(Sample {
                t: t1,
                lyapunov: self.logs[0] / t1,
                log_norm: self.logs[0],
                megno: if sys.has_megno() { ybar_int / t1 } else { f64::NAN },
            });
            if self.samples.len() > self.budget.max_samples.max(2) && !finished {
                // Keep the 2nd, 4th, … sample: those are the steps that are multiples of the
                // doubled stride, so the kept ones stay evenly spaced in steps.
                let mut k = 0;
                self.samples.retain(|_| {
                    k += 1;
                    k % 2 == 0
                });
                self.stride *= 2;
            }
        }
        Ok(finished)
    }

    /// The indicators of the ended orbit.
    fn finish<V: RunState>(&mut self, solver: &V) -> Indicators {
        let sys = self.sys;
        let t = solver.t();
        let (ybar_int, sy_int) = (self.ybar_int, self.sy_int);
        Indicators {
            lyapunov: self.logs.iter().map(|l| l / t).collect(),
            fli: self.fli,
            megno: if sys.has_megno() { ybar_int / t } else { f64::NAN },
            megno_lyapunov: if sys.has_megno() { megno_slope(t, ybar_int, sy_int) } else { f64::NAN },
            samples: std::mem::take(&mut self.samples),
            steps: solver.steps(),
            stopped_at: self.stopped_at,
        }
    }
}

impl Indicators {
    /// This orbit as a chaos map's cell: the indicator's value and when the early stop ended
    /// it.
    pub fn cell(&self, which: Indicator) -> Cell {
        Cell { value: self.value(which), stopped_at: self.stopped_at }
    }

    /// The number a chaos map shows for this orbit.
    pub fn value(&self, which: Indicator) -> f64 {
        match which {
            Indicator::Lyapunov => self.lyapunov[0],
            Indicator::Fli => self.fli,
            Indicator::Megno => self.megno,
        }
    }
}

/// Which number a chaos map shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Indicator {
    /// The maximal Lyapunov exponent.
    Lyapunov,
    /// The fast Lyapunov indicator.
    Fli,
    /// The mean MEGNO.
    Megno,
}

impl Indicator {
    /// Every indicator, in the order an error message lists them.
    pub const ALL: [Indicator; 3] = [Indicator::Megno, Indicator::Fli, Indicator::Lyapunov];

    /// The indicator's name in scenes and in Python (`megno`, `fli`, `lyapunov`).
    pub fn name(self) -> &'static str {
        match self {
            Indicator::Lyapunov => "lyapunov",
            Indicator::Fli => "fli",
            Indicator::Megno => "megno",
        }
    }

    /// The indicator of that name; `None` for any other word (the front ends say which names
    /// exist: [`Indicator::ALL`]).
    pub fn named(name: &str) -> Option<Indicator> {
        Indicator::ALL.into_iter().find(|i| i.name() == name)
    }
}

/// An indicator over many initial conditions, in parallel (rayon), within the default
/// [`Budget`] for each orbit (its time budget counted from the orbit's start). A start whose
/// integration fails (escapes to infinity, hits a singularity, runs out of the budget) gets
/// NaN; the scene's `chaos_map` goes through [`indicators_with`] and refuses a map whose starts
/// ran out of the budget ([`is_budget`]). The orbits run in lane groups of the Taylor method's
/// batch mode where it pays, each with the bits of its run alone (see [`indicators_map`]).
pub fn chaos_map(sys: &Variational, starts: &[Vec<f64>], t_end: f64, tol: f64, which: Indicator) -> Vec<f64> {
    chaos_map_each(sys, starts, t_end, tol, which, &Budget::default()).into_iter().map(|c| c.value).collect()
}

/// One cell of a chaos map from [`chaos_map_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// The indicator (NaN for a start whose integration failed).
    pub value: f64,
    /// When the orbit stopped early by the budget's [`MegnoStop`]: its `value` is then the
    /// mean MEGNO at that time, at least [`MegnoStop::above`], and stands for "`Ȳ ≥ above`",
    /// not for a value at the end time.
    pub stopped_at: Option<f64>,
}

impl Cell {
    /// A cell without an orbit (its start failed, or lies off the map's level set).
    pub const BLANK: Cell = Cell { value: f64::NAN, stopped_at: None };
}

/// [`chaos_map`] within `budget` (its deadline is for the whole map), with each cell marked
/// when the budget's [`MegnoStop`] ended its orbit early. A start whose integration fails or
/// runs out of the budget gets NaN, as in [`chaos_map`].
pub fn chaos_map_with(
    sys: &Variational,
    starts: &[Vec<f64>],
    t_end: f64,
    tol: f64,
    which: Indicator,
    budget: &Budget,
) -> Vec<Cell> {
    cells(indicators_map(sys, starts, t_end, tol, budget), which)
}

/// [`chaos_map_with`] with each orbit within a budget of its own: `budget`'s steps, samples and
/// early stop, and its time limit counted from the orbit's start (as one [`indicators_with`]
/// per start with a fresh [`Budget`]), so the map's size does not eat into its orbits' time.
pub fn chaos_map_each(
    sys: &Variational,
    starts: &[Vec<f64>],
    t_end: f64,
    tol: f64,
    which: Indicator,
    budget: &Budget,
) -> Vec<Cell> {
    cells(orbits(sys, starts, t_end, tol, budget, Deadline::PerOrbit, &AtomicUsize::new(0)), which)
}

/// A map's cells from its orbits (NaN for one that failed).
fn cells(orbits: Vec<Result<Indicators, IntegrateError>>, which: Indicator) -> Vec<Cell> {
    orbits
        .into_iter()
        .map(|r| match r {
            Ok(r) => r.cell(which),
            Err(_) => Cell::BLANK,
        })
        .collect()
}

/// [`indicators_with`] for every start of `starts`, in parallel, within `budget` (its deadline
/// is for all of them): per start the orbit's indicators or its error, bit for bit what
/// [`indicators_with`] gives for that start alone. Where the Taylor method's batch mode pays
/// (from [`BATCH_FROM_ORDER`], as the ensembles) the orbits run in lane groups of batch
/// expansions ([`Taylor::integrate_lanes`]), each lane with its own step sizes, quadrature,
/// renormalisation, early stop, budget and failure, by the same per-step code as the single
/// run; the lane groups spread over rayon's threads. A start the batch hands back
/// (its lane's expansion failed, or the run was interrupted) runs alone.
pub fn indicators_map(
    sys: &Variational,
    starts: &[Vec<f64>],
    t_end: f64,
    tol: f64,
    budget: &Budget,
) -> Vec<Result<Indicators, IntegrateError>> {
    indicators_map_counting(sys, starts, t_end, tol, budget, &AtomicUsize::new(0))
}

/// [`indicators_map`], adding one to `done` as each orbit ends, so that another thread can
/// report the map's progress while it runs (the scene's progress bar).
pub fn indicators_map_counting(
    sys: &Variational,
    starts: &[Vec<f64>],
    t_end: f64,
    tol: f64,
    budget: &Budget,
    done: &AtomicUsize,
) -> Vec<Result<Indicators, IntegrateError>> {
    orbits(sys, starts, t_end, tol, budget, Deadline::Shared, done)
}

/// Whose deadline an orbit of a map keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Deadline {
    /// The budget's, for the whole map.
    Shared,
    /// Its own: the budget's time limit from the orbit's start (as one [`indicators`] call
    /// per start).
    PerOrbit,
}

impl Deadline {
    fn of(self, budget: &Budget) -> Option<Instant> {
        match self {
            Deadline::Shared => budget.deadline,
            Deadline::PerOrbit => budget.time_limit.and_then(|l| Instant::now().checked_add(l)),
        }
    }
}

/// The orbits of a map: batched where the batch pays, else one at a time (see
/// [`indicators_map`]). One batch driver per thread of rayon's pool, all taking starts from
/// one queue, so a lane idles only once no start is left: with a fixed group of starts per
/// driver, its lanes would expand for nothing while the group's longest orbits finish (a
/// map's orbits differ in length by the early stop and by their step sizes).
fn orbits(
    sys: &Variational,
    starts: &[Vec<f64>],
    t_end: f64,
    tol: f64,
    budget: &Budget,
    deadline: Deadline,
    done: &AtomicUsize,
) -> Vec<Result<Indicators, IntegrateError>> {
    let alone = |x0: &Vec<f64>| {
        let own = Budget { deadline: deadline.of(budget), ..*budget };
        let r = indicators_with(sys, x0, t_end, tol, &own);
        done.fetch_add(1, Ordering::Relaxed);
        r
    };
    let method = Taylor::new(tol);
    let n = sys.n();
    let batch = method.taylor_order() >= BATCH_FROM_ORDER
        && sys.taylor().batchable()
        && method.validate().is_ok()
        && starts.iter().all(|x0| x0.len() >= n);
    let mut results: Vec<Option<Result<Indicators, IntegrateError>>> = (0..starts.len()).map(|_| None).collect();
    if batch {
        let lanes = crate::compile::simd_lanes();
        let y0: Vec<Vec<f64>> = starts.iter().map(|x0| sys.initial_state(x0)).collect();
        let refs: Vec<&[f64]> = y0.iter().map(Vec::as_slice).collect();
        let queue = AtomicUsize::new(0);
        let task = Orbits { sys, budget, deadline, done };
        let drivers = rayon::broadcast(|_| method.integrate_lanes(sys, lanes, 0.0..t_end, &refs, &queue, &task, None));
        for (index, r) in drivers.into_iter().flatten().flatten() {
            results[index] = r;
        }
    }
    // What the batch did not run (or handed back) runs alone.
    results.into_par_iter().zip(starts).map(|(r, x0)| r.unwrap_or_else(|| alone(x0))).collect()
}

/// The chaos maps' lane task: each lane an [`Orbit`], ended by its budget, its failure, its
/// end time or its early stop, exactly as [`indicators_from`] ends it.
struct Orbits<'a> {
    sys: &'a Variational,
    budget: &'a Budget,
    deadline: Deadline,
    /// Orbits ended so far (the progress report's count).
    done: &'a AtomicUsize,
}

impl Orbits<'_> {
    /// Counts an orbit that ends with `out`.
    fn ended<T>(&self, out: Option<T>) -> Option<T> {
        if out.is_some() {
            self.done.fetch_add(1, Ordering::Relaxed);
        }
        out
    }
}

impl<'a> LaneTask for Orbits<'a> {
    type Lane = Orbit<'a>;
    type Output = Result<Indicators, IntegrateError>;

    fn begin<V: RunState>(&self, _: usize, _: &V) -> Result<Orbit<'a>, Self::Output> {
        Ok(Orbit::new(self.sys, self.budget, self.deadline.of(self.budget)))
    }

    fn before_step<V: RunState>(&self, orbit: &mut Orbit<'a>, solver: &V) -> Option<Self::Output> {
        self.ended(orbit.check_budget(solver).err().map(Err))
    }

    fn after_step<V: RunState>(
        &self,
        orbit: &mut Orbit<'a>,
        solver: &mut V,
        step: Result<Status, IntegrateError>,
    ) -> Option<Self::Output> {
        self.ended(match step.and_then(|status| orbit.after_step(solver, status)) {
            Err(e) => Some(Err(e)),
            Ok(true) => Some(Ok(orbit.finish(solver))),
            Ok(false) => None,
        })
    }
}

/// Whether `e` is an orbit stopped by its [`Budget`] (steps or time), not by its dynamics.
pub fn is_budget(e: &IntegrateError) -> bool {
    matches!(e.reason, FailureReason::StepLimit { .. } | FailureReason::TimeLimit { .. })
}

/// The state transition matrix `Φ(t_end)` (row-major, `n × n`) and the state at `t_end`, by
/// the Taylor method on a variational system with `n` tangent vectors (no renormalisation).
pub fn transition_matrix(
    sys: &Variational,
    x0: &[f64],
    t_end: f64,
    tol: f64,
) -> Result<(Vec<f64>, Vec<f64>), IntegrateError> {
    let n = sys.n();
    assert_eq!(sys.tangents(), n, "Φ needs n tangent vectors");
    let y0 = sys.initial_state(x0);
    let traj = Taylor::new(tol).integrate_with(sys, 0.0..t_end, &y0, crate::integrate::Options::new().final_only())?;
    let y = traj.last_state();
    let mut phi = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            phi[i * n + j] = y[n + j * n + i];
        }
    }
    Ok((phi, y[..n].to_vec()))
}

/// The flow over `0..T` and the two structural checks of notes §4.6.1: Liouville's theorem
/// (`det Φ = 1`, phase-space volume is kept) and symplecticity (`ΦᵀJΦ = J` with
/// `J = [[0, I], [−I, 0]]` in the order `(q, p)`). Both hold exactly for the true flow of a
/// Hamiltonian system, so the residuals measure the integration error of `Φ`. A dissipative
/// or driven system keeps neither: `det Φ(t) = exp(∫₀ᵗ tr ∂f/∂x ds)` (Liouville's formula;
/// `e^{−γt}` for `x'' = −γx' − ω²x`), and its flow has no symplectic defect to report.
#[derive(Clone, Debug, PartialEq)]
pub struct Flow {
    /// `Φ(T) = ∂x(T)/∂x(0)`, row-major `n × n`.
    pub phi: Vec<f64>,
    /// The state at `T`.
    pub end: Vec<f64>,
    /// `det Φ − 1`.
    pub det_minus_one: f64,
    /// `max_ij |(ΦᵀJΦ − J)_ij|`, for a Hamiltonian flow only ([`Variational::is_hamiltonian`]).
    pub symplectic_defect: Option<f64>,
    /// The same checks along the run, at the end of the kept steps (the first at `t = 0`, the
    /// last at `T`).
    pub samples: Vec<FlowSample>,
    /// Taylor steps taken.
    pub steps: usize,
}

/// The flow's checks at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlowSample {
    /// Time.
    pub t: f64,
    /// `det Φ(t) − 1`.
    pub det_minus_one: f64,
    /// `max_ij |(Φ(t)ᵀJΦ(t) − J)_ij|` (Hamiltonian flows only).
    pub symplectic_defect: Option<f64>,
}

/// [`Flow`] from `x0 = (q, p)` with the Taylor method at `tol`, keeping only the end, within
/// the default [`Budget`]. `sys` needs `n` tangent vectors (`n = 2 × degrees of freedom`).
pub fn flow(sys: &Variational, x0: &[f64], t_end: f64, tol: f64) -> Result<Flow, IntegrateError> {
    flow_with(sys, x0, t_end, tol, 2, &Budget::default())
}

/// [`flow`] keeping the checks at about `points` steps (evenly spaced in steps, as
/// [`crate::integrate::Output::AtMost`] keeps them), within `budget`'s steps and deadline
/// (its sample limit is `points`). What is kept does not change the steps taken, so `Φ(T)` is
/// the same whatever `points` is.
pub fn flow_with(
    sys: &Variational,
    x0: &[f64],
    t_end: f64,
    tol: f64,
    points: usize,
    budget: &Budget,
) -> Result<Flow, IntegrateError> {
    let n = sys.n();
    assert_eq!(sys.tangents(), n, "Φ needs n tangent vectors");
    let y0 = sys.initial_state(x0);
    let mut options = crate::integrate::Options::new().at_most(points).max_steps(budget.max_steps);
    options.time_limit = budget.deadline.map(|d| d.saturating_duration_since(Instant::now()));
    // A stopped run reports the state `x` (not its tangents) and the time budget it was given
    // (not what was left of it when the run started).
    let traj = Taylor::new(tol).integrate_with(sys, 0.0..t_end, &y0, options).map_err(|mut e| {
        e.state.truncate(n);
        if let (FailureReason::TimeLimit { seconds }, Some(limit)) = (&mut e.reason, budget.time_limit) {
            *seconds = limit.as_secs_f64();
        }
        e
    })?;
    let hamiltonian = sys.is_hamiltonian();
    let checks = |y: &[f64]| {
        let phi = phi_of(y, n);
        let det_minus_one = crate::linalg::determinant(&phi, n) - 1.0;
        let defect = hamiltonian.then(|| symplectic_defect(&phi, n));
        (phi, det_minus_one, defect)
    };
    let samples = (0..traj.len())
        .map(|i| {
            let (_, det_minus_one, symplectic_defect) = checks(traj.state(i));
            FlowSample { t: traj.times[i], det_minus_one, symplectic_defect }
        })
        .collect();
    let y = traj.last_state();
    let (phi, det_minus_one, symplectic_defect) = checks(y);
    Ok(Flow { phi, end: y[..n].to_vec(), det_minus_one, symplectic_defect, samples, steps: traj.stats.steps })
}

/// `Φ` (row-major) from a variational state: column `j` is tangent vector `j`.
fn phi_of(y: &[f64], n: usize) -> Vec<f64> {
    let mut phi = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            phi[i * n + j] = y[n + j * n + i];
        }
    }
    phi
}

/// `max_ij |(ΦᵀJΦ − J)_ij|` for the canonical `J` of `n = 2d` variables ordered `(q, p)`.
fn symplectic_defect(phi: &[f64], n: usize) -> f64 {
    let d = n / 2;
    let j = |r: usize, c: usize| match (r < d, c < d) {
        (true, false) if c - d == r => 1.0,
        (false, true) if r - d == c => -1.0,
        _ => 0.0,
    };
    // (JΦ)_kc = Σ_l J_kl Φ_lc; (ΦᵀJΦ)_rc = Σ_k Φ_kr (JΦ)_kc.
    let jphi: Vec<f64> = (0..n * n).map(|i| (0..n).map(|l| j(i / n, l) * phi[l * n + i % n]).sum()).collect();
    let mut worst = 0.0f64;
    for r in 0..n {
        for c in 0..n {
            let v: f64 = (0..n).map(|k| phi[k * n + r] * jphi[k * n + c]).sum();
            worst = worst.max((v - j(r, c)).abs());
        }
    }
    worst
}

/// The monodromy matrix of a periodic orbit (or of a `T`-periodic linear system) and its
/// Floquet multipliers.
#[derive(Clone, Debug, PartialEq)]
pub struct Floquet {
    /// `M = Φ(T)`, row-major `n × n`.
    pub monodromy: Vec<f64>,
    /// The state at `T`.
    pub end: Vec<f64>,
    /// `‖x(T) − x(0)‖∞`: how far the orbit is from closing (a true periodic orbit has 0;
    /// for a periodic linear system any start is fine and this is not a test).
    pub closure: f64,
    /// The eigenvalues of `M` as `(re, im)`, largest modulus first (ties: larger real part,
    /// then larger imaginary part, so the order is deterministic). An orbit is linearly
    /// stable when all have modulus ≤ 1; an autonomous flow always has one multiplier 1
    /// (along the orbit), a Hamiltonian one has them in pairs `μ, 1/μ` with `Π μ = 1`.
    pub multipliers: Vec<(f64, f64)>,
}

impl Floquet {
    /// The largest modulus of a multiplier.
    pub fn spectral_radius(&self) -> f64 {
        self.multipliers.iter().map(|&(re, im)| re.hypot(im)).fold(0.0, f64::max)
    }

    /// The trace of `M` (for a one-degree-of-freedom Hamiltonian system, `|tr M| < 2` is
    /// stability and `|tr M| = 2` the boundary).
    pub fn trace(&self) -> f64 {
        let n = self.end.len();
        (0..n).map(|i| self.monodromy[i * n + i]).sum()
    }
}

/// The monodromy matrix `Φ(period)` from `x0` with the Taylor method at `tol`, and its Floquet
/// multipliers (eigenvalues by nalgebra's real Schur decomposition). `sys` needs `n` tangent
/// vectors and no MEGNO accumulator.
pub fn floquet(sys: &Variational, x0: &[f64], period: f64, tol: f64) -> Result<Floquet, IntegrateError> {
    let n = sys.n();
    assert!(!sys.has_megno(), "the monodromy matrix needs a system without the MEGNO accumulator");
    let (monodromy, end) = transition_matrix(sys, x0, period, tol)?;
    let closure = end.iter().zip(x0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let m = nalgebra::DMatrix::from_row_slice(n, n, &monodromy);
    let mut multipliers: Vec<(f64, f64)> = m.complex_eigenvalues().iter().map(|z| (z.re, z.im)).collect();
    multipliers
        .sort_by(|a, b| b.0.hypot(b.1).total_cmp(&a.0.hypot(a.1)).then(b.0.total_cmp(&a.0)).then(b.1.total_cmp(&a.1)));
    Ok(Floquet { monodromy, end, closure, multipliers })
}
