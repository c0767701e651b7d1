//! Action and frequency of a rotation (PHYSICS.md §4.5): a pendulum swinging over the top.
//!
//! A rotation has no turning points: the momentum stays real over a whole turn of an angle
//! `q`, and the orbit closes after `q` advances by 2π. On the branch moving forward,
//! `p₊ = (−b + √D)/(2a)` and `q' = ∂H/∂p = √D` (notation of [`super::action_angle`]), so
//!
//! * `J = (1/2π) ∫₀^{2π} p₊ dq`,
//! * `T = ∫₀^{2π} dq/√D`, `ω = 2π/T`.
//!
//! Both integrands are smooth and 2π-periodic, so the trapezoidal rule on uniform nodes
//! converges exponentially; nodes are doubled until two passes agree to 1e-13 (relative).
//! The period 2π is detected, not assumed: `D` must repeat after 2π and stay positive over
//! the turn, and `D` must vary with `q` (a constant `D`, the free particle, has no period);
//! else the orbit is unbounded and the caller reports that.

use std::f64::consts::TAU;

use super::action_angle::ActionFrequency;

/// Sample points used to detect periodicity and positivity of `D` over one turn.
const SAMPLES: usize = 256;

/// `J`, `T` and `ω` of the rotation through `inside`, or `None` when `D` is not 2π-periodic
/// and positive over the turn (then the orbit is not a rotation of an angle).
pub(super) fn rotation(
    disc: &dyn Fn(f64) -> f64,
    a: &dyn Fn(f64) -> f64,
    b: &dyn Fn(f64) -> f64,
    energy: f64,
    inside: f64,
) -> Option<Result<ActionFrequency, super::ActionAngleError>> {
    // A `D` that does not depend on `q` (a free particle) says nothing about a period: an
    // unbounded line, not a turning angle.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..SAMPLES {
        let x = inside + TAU * k as f64 / SAMPLES as f64;
        let (d, d_next) = (disc(x), disc(x + TAU));
        lo = lo.min(d);
        hi = hi.max(d);
        // A nearly equal difference: D repeats after a turn up to rounding of its terms.
        let periodic = (d - d_next).abs() <= 1e-9 * (1.0 + d.abs());
        if !(d > 0.0 && periodic) {
            return None;
        }
    }
    if hi - lo <= 1e-12 * hi.abs() {
        return None;
    }
    let pass = |n: usize| -> (f64, f64) {
        let (mut t_sum, mut j_sum) = (0.0, 0.0);
        for k in 0..n {
            let x = inside + TAU * k as f64 / n as f64;
            let root = disc(x).sqrt();
            t_sum += 1.0 / root;
            j_sum += (root - b(x)) / (2.0 * a(x));
        }
        let h = TAU / n as f64;
        (t_sum * h, j_sum * h / TAU)
    };
    let (t_prev, j_prev, n, change) = match super::action_angle::converged_quadrature(pass) {
        Ok(v) => v,
        Err(e) => return Some(Err(e)),
    };
    Some(Ok(ActionFrequency {
        energy,
        action: j_prev,
        period: t_prev,
        omega: TAU / t_prev,
        turning_points: (inside, inside + TAU),
        rotation: true,
        points: n,
        error_estimate: change,
    }))
}
