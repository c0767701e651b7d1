//! A geodesic between two points by shooting: Newton's method on the initial velocity `v₀`
//! of the geodesic equations (integrated by DOP853 on `t ∈ [0, 1]`) until `q(1)` is the end
//! point, with the Jacobian `∂q(1)/∂v₀` by central differences. The metric must be regular
//! at the start point; a start where `det g = 0` (the pole of spherical coordinates) is
//! refused, not integrated into NaN.
//!
//! Every shooting has a budget ([`ShootBudget`]: integration steps over all trial paths, and
//! wall-clock time) and keeps only the end state of a trial path, so a metric singular
//! between the points (a trial path creeping towards a pole of `g`) ends in a typed error
//! naming the budget, not in memory growing until the process is killed.

use std::time::{Duration, Instant};

use crate::eval::eval_with;
use crate::integrate::{Dop853, FailureReason, Integrate, IntegrateError, Options};
use crate::mechanics::Geodesic;

use crate::linalg::{determinant, solve_in_place};

/// Why a shooting solution was not found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShootError {
    /// `det g` vanishes (or is not finite) at the start point.
    #[error("the metric is singular at the start point {point:?} (det g = {det:e}); choose coordinates regular there")]
    SingularMetric { point: Vec<f64>, det: f64 },
    /// Newton's method on the initial velocity did not converge: no shorter step improved the
    /// miss (the last failed trial path says why, if one failed).
    #[error(
        "shooting did not converge after {iterations} Newton steps (the end point is missed by {}){}",
        crate::integrate::fmt_value(*miss),
        last_failure.as_ref().map(|w| format!("; the last trial path that failed: {w}")).unwrap_or_default()
    )]
    NoConvergence { iterations: usize, miss: f64, last_failure: Option<String> },
    /// The first trial path (the straight line's velocity) could not be integrated.
    #[error("no trial path could be integrated, from the straight line's velocity down to 2⁻⁴⁰ of it: {why}")]
    FirstTrial { why: String },
    /// The equations could not be compiled or integrated.
    #[error("{0}")]
    Numeric(String),
    /// Ctrl-C (the process-wide [`crate::cancel`] token) stopped the shooting.
    #[error("interrupted after {iterations} Newton steps")]
    Interrupted { iterations: usize },
    /// The trial paths used up the step or time budget ([`ShootBudget`]).
    #[error(
        "geodesic shooting stopped at Newton step {iteration}: the trial paths used up the budget of {limit} \
         (a trial path had reached t = {t:.6} of 1 at q = {state}); the metric may be singular or \
         degenerate between the points, so that no geodesic joins them in unit time"
    )]
    Budget {
        /// The budget that ran out, as words ("1000000 integration steps", "60 s").
        limit: String,
        /// The Newton step of the trial that used it up.
        iteration: usize,
        /// How far in the unit time that trial path got.
        t: f64,
        /// Its coordinates there, printed.
        state: String,
        /// `true` for the step budget, `false` for the time budget.
        steps: bool,
    },
}

/// What one shooting may spend: accepted DOP853 steps over all its trial paths, and
/// wall-clock time. A smooth geodesic takes a few hundred steps a trial path and about
/// ten trials; the defaults are far above that and stop a singular metric in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShootBudget {
    /// Accepted integration steps, all trial paths together.
    pub max_steps: usize,
    /// Wall-clock time of the whole shooting.
    pub time_limit: Duration,
}

impl ShootBudget {
    /// The default step budget: 10⁶ steps.
    pub const DEFAULT_STEPS: usize = 1_000_000;
    /// The default time budget: 60 s.
    pub const DEFAULT_SECONDS: f64 = 60.0;
}

impl Default for ShootBudget {
    fn default() -> Self {
        ShootBudget {
            max_steps: ShootBudget::DEFAULT_STEPS,
            time_limit: Duration::from_secs_f64(ShootBudget::DEFAULT_SECONDS),
        }
    }
}

/// A geodesic from `from` to `to` in unit time: the initial velocity and the path sampled at
/// `samples + 1` equally spaced times.
#[derive(Clone, Debug, PartialEq)]
pub struct Shot {
    /// `q'(0)`.
    pub velocity: Vec<f64>,
    /// `(t, q(t))`.
    pub path: Vec<(f64, Vec<f64>)>,
    /// Newton steps used.
    pub iterations: usize,
}

impl Shot {
    /// The printed line of `lagrangian geodesic --from … --to …` and of the scene statement
    /// `geodesic … from (…) to (…)`: the initial velocity to 12 decimals.
    pub fn report_line(&self) -> String {
        let v: Vec<String> = self.velocity.iter().map(|x| format!("{x:.12}")).collect();
        format!("shooting: q'(0) = ({}) after {} Newton steps", v.join(", "), self.iterations)
    }
}

/// Shoots from `from` to `to` within the default [`ShootBudget`]; `params` binds the
/// metric's parameters.
pub fn shoot(
    g: &Geodesic,
    from: &[f64],
    to: &[f64],
    params: &[(&str, f64)],
    samples: usize,
) -> Result<Shot, ShootError> {
    shoot_with(g, from, to, params, samples, ShootBudget::default())
}

/// [`shoot`] within `budget`.
pub fn shoot_with(
    g: &Geodesic,
    from: &[f64],
    to: &[f64],
    params: &[(&str, f64)],
    samples: usize,
    budget: ShootBudget,
) -> Result<Shot, ShootError> {
    let n = g.coords.len();
    check_metric(g, from, params)?;
    let numeric = |e: String| ShootError::Numeric(e);
    let sys =
        g.system().map_err(|e| numeric(e.to_string()))?.with_params(params).map_err(|e| numeric(e.to_string()))?;
    let rhs = sys.compile_rhs().map_err(|e| numeric(e.to_string()))?;
    let method = Dop853::new(1e-13, 1e-13);
    let started = Instant::now();
    let used = std::cell::Cell::new(0usize);
    let iteration = std::cell::Cell::new(0usize);
    // One trial path to t = 1, keeping only its end, within what is left of the budget.
    let end = |v: &[f64]| -> Result<Vec<f64>, ShootError> {
        let mut y0 = from.to_vec();
        y0.extend_from_slice(v);
        let left_steps = budget.max_steps.saturating_sub(used.get()).max(1);
        let left_time = budget.time_limit.saturating_sub(started.elapsed()).max(Duration::from_millis(1));
        let opts = Options::new().final_only().max_steps(left_steps).time_limit(left_time);
        match method.integrate_with(&rhs, 0.0..1.0, &y0, opts) {
            Ok(t) => {
                used.set(used.get() + t.stats.steps);
                Ok(t.last_state()[..n].to_vec())
            }
            Err(e) => Err(over_budget(&e, budget, iteration.get(), n).unwrap_or_else(|| numeric(e.to_string()))),
        }
    };
    // The first trial is the straight line's velocity; a failed trial later on is a step too
    // long for this metric, so the Newton step is halved until the trial path both exists
    // and misses the end point by less (a damped Newton method): only a path that cannot be
    // shot at all is reported, with the trial's own failure as the reason.
    let trial = |v: &[f64]| -> Result<Result<Vec<f64>, String>, ShootError> {
        match end(v) {
            Ok(q) => Ok(Ok(q)),
            Err(ShootError::Numeric(why)) => Ok(Err(why)),
            Err(e) => Err(e),
        }
    };
    // Damped Newton from `v` to `target`: (velocity, Newton steps).
    let newton = |target: &[f64], mut v: Vec<f64>| -> Result<(Vec<f64>, usize), ShootError> {
        let miss_of = |q1: &[f64]| (0..n).fold(0.0f64, |s, i| s.max((target[i] - q1[i]).abs()));
        iteration.set(1);
        // The straight line's velocity may be far too fast for the metric (a hyperbolic plane
        // drives a fast horizontal start to its boundary): slower starts are tried before any is
        // reported as failing.
        let mut first_failure = None;
        let mut q1 = None;
        for _ in 0..40 {
            match trial(&v)? {
                Ok(q) => {
                    q1 = Some(q);
                    break;
                }
                Err(why) => {
                    first_failure.get_or_insert(why);
                    v.iter_mut().for_each(|x| *x *= 0.5);
                }
            }
        }
        let Some(mut q1) = q1 else {
            return Err(ShootError::FirstTrial { why: first_failure.unwrap_or_default() });
        };
        let mut miss = miss_of(&q1);
        for it in 1..=MAX_NEWTON {
            if crate::cancel::interrupted() {
                return Err(ShootError::Interrupted { iterations: it - 1 });
            }
            iteration.set(it);
            if miss <= 1e-12 {
                return Ok((v, it));
            }
            let mut r: Vec<f64> = (0..n).map(|i| target[i] - q1[i]).collect();
            let mut jac = vec![0.0; n * n];
            for j in 0..n {
                let e = 1e-6 * (1.0 + v[j].abs());
                let (mut up, mut dn) = (v.clone(), v.clone());
                up[j] += e;
                dn[j] -= e;
                let (a, b) = (end(&up)?, end(&dn)?);
                for i in 0..n {
                    jac[i * n + j] = (a[i] - b[i]) / (2.0 * e);
                }
            }
            if solve_in_place(&mut jac, &mut r, n).is_err() {
                break;
            }
            let mut lambda = 1.0;
            let mut last_failure = None;
            let accepted = loop {
                let tried: Vec<f64> = (0..n).map(|i| v[i] + lambda * r[i]).collect();
                match trial(&tried)? {
                    Ok(q) if miss_of(&q) < miss => break Some((tried, q)),
                    Ok(_) => {}
                    Err(why) => last_failure = Some(why),
                }
                lambda *= 0.5;
                if lambda < 1e-9 {
                    break None;
                }
            };
            match accepted {
                Some((tried, q)) => {
                    v = tried;
                    miss = miss_of(&q);
                    q1 = q;
                }
                None => return Err(ShootError::NoConvergence { iterations: it, miss, last_failure }),
            }
        }
        Err(ShootError::NoConvergence { iterations: MAX_NEWTON, miss, last_failure: None })
    };
    // Straight at the end point first; when that fails, by continuation: end points moved
    // from the start towards `to`, each shot from the last one's velocity (the half-plane's
    // geodesic from (0, 1) to (100, 1), a tall half circle, is found this way).
    let straight: Vec<f64> = (0..n).map(|i| to[i] - from[i]).collect();
    let (v, iterations) = match newton(to, straight.clone()) {
        Ok(found) => found,
        Err(direct @ (ShootError::NoConvergence { .. } | ShootError::FirstTrial { .. })) => {
            by_continuation(&newton, from, to, &straight, direct)?
        }
        Err(e) => return Err(e),
    };
    Ok(Shot { velocity: v.clone(), path: sample(&method, &rhs, from, &v, samples)?, iterations })
}

/// The metric at the start point is evaluated (every parameter bound) and invertible before any
/// path is shot: a degenerate start is reported as such, not as a shot that did not converge.
fn check_metric(g: &Geodesic, from: &[f64], params: &[(&str, f64)]) -> Result<(), ShootError> {
    let n = g.coords.len();
    let lookup = |s: &crate::expr::Symbol| {
        g.coords
            .iter()
            .position(|q| q == s)
            .map(|i| from[i])
            .or_else(|| params.iter().find(|(k, _)| *k == s.to_string()).map(|(_, v)| *v))
    };
    let mut m = vec![0.0; n * n];
    let mut scale = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            m[i * n + j] = match eval_with(&g.metric[i][j], &lookup) {
                Ok(v) => v,
                Err(crate::eval::EvalError::Unbound(name)) => {
                    return Err(ShootError::Numeric(format!(
                        "the metric needs a value for `{name}` to shoot (give the parameter a value)"
                    )))
                }
                Err(_) => f64::NAN,
            };
            scale = scale.max(m[i * n + j].abs());
        }
    }
    let det = determinant(&m, n);
    if !det.is_finite() || det.abs() <= 1e-12 * scale.powi(n as i32) {
        return Err(ShootError::SingularMetric { point: from.to_vec(), det });
    }
    Ok(())
}

/// A damped Newton shot from a velocity to an end point: (velocity, Newton steps).
type Newton<'a> = dyn Fn(&[f64], Vec<f64>) -> Result<(Vec<f64>, usize), ShootError> + 'a;

/// Continuation when the direct shot fails: end points moved from `from` towards `to`, each shot
/// from the last one's velocity, the step doubled after a success and halved after a failure;
/// `direct` (the direct shot's failure) is the answer when the step becomes too small.
fn by_continuation(
    newton: &Newton<'_>,
    from: &[f64],
    to: &[f64],
    straight: &[f64],
    direct: ShootError,
) -> Result<(Vec<f64>, usize), ShootError> {
    let n = straight.len();
    let (mut reached, mut step) = (0.0f64, 0.25f64);
    let mut v = Vec::new();
    let mut total = 0;
    loop {
        let s = (reached + step).min(1.0);
        let target: Vec<f64> = (0..n).map(|i| from[i] + s * (to[i] - from[i])).collect();
        // The last shot's velocity, or (nothing reached yet) the straight line's.
        let guess = if reached > 0.0 { v.clone() } else { straight.iter().map(|x| x * s).collect() };
        let attempt = newton(&target, guess);
        match attempt {
            Ok((found, its)) => {
                total += its;
                v = found;
                reached = s;
                if s >= 1.0 {
                    return Ok((v, total));
                }
                step = (step * 2.0).min(0.5);
            }
            Err(ShootError::NoConvergence { .. } | ShootError::FirstTrial { .. }) => {
                step *= 0.5;
                if step < 1.0 / 4096.0 {
                    return Err(direct);
                }
            }
            Err(e) => return Err(e),
        }
    }
}

/// Newton steps before shooting gives up.
const MAX_NEWTON: usize = 30;

/// The budget error for an integration stopped by its step or time limit.
fn over_budget(e: &IntegrateError, budget: ShootBudget, iteration: usize, n: usize) -> Option<ShootError> {
    let steps = match e.reason {
        FailureReason::StepLimit { .. } => true,
        FailureReason::TimeLimit { .. } => false,
        _ => return None,
    };
    let limit = if steps {
        format!("{} integration steps", budget.max_steps)
    } else {
        format!("{} s", budget.time_limit.as_secs_f64())
    };
    let state = crate::integrate::fmt_state(&e.state[..n.min(e.state.len())]);
    Some(ShootError::Budget { limit, iteration, t: e.t, state, steps })
}

fn sample(
    method: &Dop853,
    rhs: &super::LagrangianRhs,
    from: &[f64],
    v: &[f64],
    samples: usize,
) -> Result<Vec<(f64, Vec<f64>)>, ShootError> {
    let n = from.len();
    let mut y = from.to_vec();
    y.extend_from_slice(v);
    let mut out = vec![(0.0, from.to_vec())];
    let samples = samples.max(1);
    for k in 1..=samples {
        let (t0, t1) = ((k - 1) as f64 / samples as f64, k as f64 / samples as f64);
        let opts = Options::new().final_only();
        let tr = method.integrate_with(rhs, t0..t1, &y, opts).map_err(|e| ShootError::Numeric(e.to_string()))?;
        y = tr.last_state().to_vec();
        out.push((t1, y[..n].to_vec()));
    }
    Ok(out)
}
