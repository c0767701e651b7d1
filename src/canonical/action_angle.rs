//! Action and frequency of a one-degree-of-freedom `H(q, p)` by quadrature (PHYSICS.md §4.5).
//!
//! `H` must be at most quadratic in `p`: `H = a(q) p² + b(q) p + c(q)` (every natural system).
//! On the level set `H = E` the two branches are `p± = (−b ± √D)/(2a)` with the discriminant
//! `D(q) = b² − 4a(c − E)`, and `q' = ∂H/∂p = ±√D`. Hence
//!
//! * `J = (1/2π) ∮ p dq = (1/2π) ∫_{q1}^{q2} √D/|a| dq`,
//! * `T = ∮ dq/q' = 2 ∫_{q1}^{q2} dq/√D`, `ω = 2π/T`,
//!
//! (for a rotation of an angle, with no turning points, see the section on rotations below),
//! with turning points `q1 < q2` the roots of `D` around a point inside the well, found by
//! bracketing outwards and bisecting to the last bit. The endpoint singularity `1/√D` is
//! removed by `q = m + h sin φ` (`m`, `h` the midpoint and half-width): `D = h² cos²φ R(q)`
//! with `R > 0` smooth, and both integrands become smooth, 2π-periodic and even about
//! `φ = π/2`, so the trapezoidal rule on a full period converges exponentially. Points are
//! doubled until two successive values agree to 1e-13 (relative); beyond that, rounding in
//! `D` near the turning points (a difference of nearly equal numbers) is the noise floor.

use std::f64::consts::TAU;

use crate::diff::Differentiator;
use crate::eval::{eval_with, Env};
use crate::expr::{Expr, Symbol};

use super::reduce::expand;

/// Terms of the Taylor series of `D` used near a turning point (within 2% of the orbit's
/// half-width and 5% of the series' estimated radius of convergence, so the remainder is
/// about 0.05^13 ≈ 1e-17 of the leading term).
const TAYLOR_ORDER: usize = 12;

/// The result at one energy.
#[derive(Clone, Debug, PartialEq)]
pub struct ActionFrequency {
    /// The energy `E`.
    pub energy: f64,
    /// `J(E) = (1/2π) ∮ p dq`.
    pub action: f64,
    /// The period `T(E)`.
    pub period: f64,
    /// `ω(E) = 2π/T(E)`.
    pub omega: f64,
    /// The turning points `(q1, q2)`; for a rotation, the ends of the turn integrated over
    /// (`q0`, `q0 + 2π`).
    pub turning_points: (f64, f64),
    /// Whether the orbit is a rotation (`J = (1/2π)∫₀^{2π} p dq` over one turn of an angle)
    /// rather than a libration between turning points.
    pub rotation: bool,
    /// Quadrature points used in the last (converged) pass.
    pub points: usize,
    /// The relative change between the last two passes: about 1e-13 normally; larger (up to
    /// 1e-6, beyond which the quadrature is refused) only very close to a separatrix, where
    /// the period diverges logarithmically.
    pub error_estimate: f64,
}

/// Why the quadrature was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ActionAngleError {
    /// `H` is not a polynomial of degree 1 or 2 in `p`.
    #[error("H must be a polynomial of degree 2 in `{momentum}` (a(q) p² + b(q) p + c(q)); here {reason}")]
    NotQuadratic {
        /// The momentum.
        momentum: String,
        /// What is wrong.
        reason: String,
    },
    /// A symbol has no numeric value.
    #[error("cannot evaluate H: {0}")]
    Eval(String),
    /// The start point is not inside an orbit of energy `E`.
    #[error("q = {inside} is not inside an orbit of energy {energy}: the momentum there is not real (D = {disc:.3e}); give a point inside the well")]
    NotInside {
        /// The start point.
        inside: f64,
        /// The energy.
        energy: f64,
        /// The discriminant there.
        disc: f64,
    },
    /// No turning point on one side, and the orbit is not a rotation of an angle: unbounded.
    #[error("no turning point on the {side} side of q = {inside} at energy {energy}: the orbit is not a libration, and not a rotation either (H is not 2π-periodic in q with real momentum over a whole turn), so it is unbounded and J and ω do not apply")]
    NoTurningPoint {
        /// `"left"` or `"right"`.
        side: &'static str,
        /// The start point.
        inside: f64,
        /// The energy.
        energy: f64,
    },
    /// The quadrature did not converge.
    #[error("the quadrature did not converge (last change {change:.2e} with {points} points); the energy may be too close to a separatrix")]
    NoConvergence {
        /// The last relative change.
        change: f64,
        /// The points used.
        points: usize,
    },
}

struct Quadratic {
    a: Expr,
    b: Expr,
    c: Expr,
}

fn split_quadratic(h: &Expr, p: &Symbol) -> Result<Quadratic, ActionAngleError> {
    let e = expand(h);
    let mut parts = [Vec::new(), Vec::new(), Vec::new()];
    for t in e.terms() {
        let mut power = 0usize;
        let mut rest = Vec::new();
        for f in t.factors() {
            let (b, x) = f.base_exp();
            if b.as_sym() == Some(p) {
                match x.as_num().and_then(super::reduce::nonneg_int) {
                    Some(n) if n <= 2 => power += n as usize,
                    _ => {
                        return Err(ActionAngleError::NotQuadratic {
                            momentum: p.to_string(),
                            reason: format!("it contains `{f}`"),
                        })
                    }
                }
            } else if f.contains(p) {
                return Err(ActionAngleError::NotQuadratic {
                    momentum: p.to_string(),
                    reason: format!("it contains `{f}`"),
                });
            } else {
                rest.push(f);
            }
        }
        if power > 2 {
            return Err(ActionAngleError::NotQuadratic {
                momentum: p.to_string(),
                reason: format!("the term `{t}` has degree {power}"),
            });
        }
        parts[power].push(Expr::mul(rest));
    }
    let [c, b, a] = parts.map(Expr::add);
    if a.is_zero() {
        return Err(ActionAngleError::NotQuadratic { momentum: p.to_string(), reason: "there is no p² term".into() });
    }
    Ok(Quadratic { a, b, c })
}

/// `J(E)`, `T(E)` and `ω(E)` for `h(q, p)` with parameters from `params`, on the orbit through
/// the point `inside` (any `q` inside the well).
pub fn action_frequency(
    h: &Expr,
    q: &Symbol,
    p: &Symbol,
    energy: f64,
    params: &Env,
    inside: f64,
) -> Result<ActionFrequency, ActionAngleError> {
    let Quadratic { a, b, c } = split_quadratic(h, p)?;
    let qname = q.to_string();
    let ev = |e: &Expr, x: f64| -> Result<f64, ActionAngleError> {
        eval_with(e, &|s: &Symbol| if s.to_string() == qname { Some(x) } else { params.get(&s.to_string()).copied() })
            .map_err(|e| ActionAngleError::Eval(e.to_string()))
    };
    // Validate evaluation once (unbound symbols are an error, not a NaN).
    ev(&a, inside)?;
    ev(&b, inside)?;
    ev(&c, inside)?;
    let disc = |x: f64| -> f64 {
        match (ev(&a, x), ev(&b, x), ev(&c, x)) {
            (Ok(a), Ok(b), Ok(c)) => b * b - 4.0 * a * (c - energy),
            _ => f64::NAN,
        }
    };
    let d0 = disc(inside);
    if d0.is_nan() || d0 <= 0.0 {
        return Err(ActionAngleError::NotInside { inside, energy, disc: d0 });
    }
    let ends = (turning_point(&disc, inside, -1.0), turning_point(&disc, inside, 1.0));
    let (q1, q2) = match ends {
        (Some(q1), Some(q2)) => (q1, q2),
        (left, _) => {
            // No turning point: a rotation when the coordinate is an angle (D periodic and
            // positive over a whole turn), else an unbounded orbit.
            let side = if left.is_none() { "left" } else { "right" };
            let a_at = |x: f64| ev(&a, x).unwrap_or(f64::NAN);
            let b_at = |x: f64| ev(&b, x).unwrap_or(f64::NAN);
            return rotation(&disc, &a_at, &b_at, energy, inside).ok_or(ActionAngleError::NoTurningPoint {
                side,
                inside,
                energy,
            })?;
        }
    };
    let half = 0.5 * (q2 - q1);
    // Near a turning point D is a difference of nearly equal numbers (E − V with V ≈ E), so
    // its relative error there grows without bound. Within `tau` of an end, D/(q − q_end) comes
    // instead from the Taylor series of D at that end, whose coefficients (symbolic
    // derivatives of D) carry no such cancellation.
    let e_sym = Symbol::new("__energy");
    let disc_expr = b.powi(2).minus(&Expr::int(4).times(&a).times(&c.minus(&Expr::sym(e_sym.clone()))));
    let ev_e = |e: &Expr, x: f64| -> f64 {
        eval_with(e, &|s: &Symbol| {
            if s.to_string() == qname {
                Some(x)
            } else if *s == e_sym {
                Some(energy)
            } else {
                params.get(&s.to_string()).copied()
            }
        })
        .unwrap_or(f64::NAN)
    };
    let mut d = Differentiator::new();
    let mut derivs = Vec::with_capacity(TAYLOR_ORDER);
    let mut cur = disc_expr;
    for _ in 0..TAYLOR_ORDER {
        cur = d.diff(&cur, q);
        derivs.push(cur.clone());
    }
    // taylor1[j] = D^(j+1)(q1)/(j+1)!, so D(q1 + s)/s = Σ taylor1[j] s^j.
    let coeffs = |at: f64| -> Vec<f64> {
        let mut fact = 1.0;
        derivs
            .iter()
            .enumerate()
            .map(|(j, e)| {
                fact *= (j + 1) as f64;
                ev_e(e, at) / fact
            })
            .collect()
    };
    let (taylor1, taylor2) = (coeffs(q1), coeffs(q2));
    let horner = |cs: &[f64], s: f64| cs.iter().rev().fold(0.0, |acc, c| acc * s + c);
    // Stay well inside the Taylor series' disc of convergence, estimated from the ratios of
    // successive coefficients (Cauchy–Hadamard); a polynomial D has no limit from this side.
    let radius = |cs: &[f64]| {
        cs.windows(2)
            .skip(1)
            .filter(|w| w[1] != 0.0 && w[0].is_finite() && w[1].is_finite())
            .map(|w| (w[0] / w[1]).abs())
            .fold(f64::INFINITY, f64::min)
    };
    let tau1 = (0.02 * half).min(0.05 * radius(&taylor1));
    let tau2 = (0.02 * half).min(0.05 * radius(&taylor2));
    // Trapezoid on a full period at offset nodes (never exactly at cos φ = 0). With
    // q = q1 + s1 = q2 − s2: s1 = h (1 + sin φ) = h (sin φ/2 + cos φ/2)², s2 = h (1 − sin φ),
    // both computed without cancellation, and (q − q1)(q2 − q) = s1 s2.
    let pass = |n: usize| -> (f64, f64) {
        let mut t_sum = 0.0;
        let mut j_sum = 0.0;
        for k in 0..n {
            let phi = std::f64::consts::TAU * (k as f64 + 0.5) / n as f64;
            let (sh, ch) = (0.5 * phi).sin_cos();
            let s1 = half * (sh + ch) * (sh + ch);
            let s2 = half * (ch - sh) * (ch - sh);
            let x = if s1 < s2 { q1 + s1 } else { q2 - s2 };
            let r = if s1 < tau1 {
                horner(&taylor1, s1) / s2
            } else if s2 < tau2 {
                -horner(&taylor2, -s2) / s1
            } else {
                disc(x) / (s1 * s2)
            };
            let av = ev(&a, x).unwrap_or(f64::NAN).abs();
            t_sum += 1.0 / r.sqrt();
            j_sum += s1 * s2 * r.sqrt() / av;
        }
        let dphi = std::f64::consts::TAU / n as f64;
        (t_sum * dphi, j_sum * dphi / (2.0 * std::f64::consts::TAU))
    };
    let (t_prev, j_prev, n, change) = converged_quadrature(pass)?;
    Ok(ActionFrequency {
        energy,
        action: j_prev,
        period: t_prev,
        omega: std::f64::consts::TAU / t_prev,
        turning_points: (q1, q2),
        rotation: false,
        points: n,
        error_estimate: change,
    })
}

/// The root of `disc` on one side of `inside`, where `disc > 0`: march outwards with steps
/// of at most 1% of the scale, shortened to 1.1× the secant prediction of the zero when `disc`
/// falls (so a narrow barrier near a separatrix, or a periodic potential's next well, is not
/// jumped over); after 20 000 steps the steps double, for far-away turning points. Then bisect
/// until the interval stops shrinking. NaN (outside the domain) counts as outside.
fn turning_point(disc: &dyn Fn(f64) -> f64, inside: f64, dir: f64) -> Option<f64> {
    let scale = inside.abs().max(1.0);
    let (max_step, min_step) = (1e-2 * scale, 1e-9 * scale);
    let mut good = inside;
    let mut d_good = disc(inside);
    let mut bad = None;
    let mut step = max_step;
    for i in 0..20_200 {
        if i >= 20_000 {
            step *= 2.0;
        }
        let x = good + dir * step;
        let d = disc(x);
        if d > 0.0 {
            if i < 20_000 {
                let slope = (d - d_good) / step;
                step = if slope < 0.0 { (1.1 * d / -slope).clamp(min_step, max_step) } else { max_step };
            }
            good = x;
            d_good = d;
        } else {
            bad = Some(x);
            break;
        }
    }
    let mut bad = bad?;
    for _ in 0..200 {
        let m = 0.5 * (good + bad);
        if m == good || m == bad {
            break;
        }
        if disc(m) > 0.0 {
            good = m;
        } else {
            bad = m;
        }
    }
    // The midpoint of the last bracket is within an ulp of the root.
    Some(0.5 * (good + bad))
}

/// The complete elliptic integral of the first kind `K(k) = π / (2 AGM(1, √(1−k²)))`.
pub fn elliptic_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..64 {
        if (a - b).abs() <= f64::EPSILON * a {
            break;
        }
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    std::f64::consts::PI / (2.0 * a)
}

/// The complete elliptic integral of the second kind, by the same AGM:
/// `E(k) = K(k) (1 − Σ_{n≥0} 2^{n−1} c_n²)`, `c_0 = k`, `c_{n+1} = (a_n − b_n)/2`.
pub fn elliptic_e(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    let mut sum = 0.5 * k * k;
    let mut pow2 = 0.5;
    for _ in 0..64 {
        let c = 0.5 * (a - b);
        pow2 *= 2.0;
        sum += pow2 * c * c;
        if c.abs() <= f64::EPSILON * a {
            break;
        }
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    std::f64::consts::PI / (2.0 * a) * (1.0 - sum)
}

/// The period and action from `pass(n)` (both by an n-point periodic rule), doubling `n` from
/// 16 until they change by less than 1e-13 relative (the rule converges geometrically for an
/// analytic integrand); an error when they still change by 1e-6 at 2¹⁷ points. Returns the
/// period, the action, the points used and the last relative change.
pub(super) fn converged_quadrature(
    mut pass: impl FnMut(usize) -> (f64, f64),
) -> Result<(f64, f64, usize, f64), ActionAngleError> {
    let mut n = 16;
    let (mut t_prev, mut j_prev) = pass(n);
    let mut change = f64::INFINITY;
    while n < 1 << 17 {
        n *= 2;
        let (t, j) = pass(n);
        change = ((t - t_prev) / t).abs().max(((j - j_prev) / j).abs());
        t_prev = t;
        j_prev = j;
        if change < 1e-13 {
            break;
        }
    }
    if change.is_nan() || change >= 1e-6 {
        return Err(ActionAngleError::NoConvergence { change, points: n });
    }
    Ok((t_prev, j_prev, n, change))
}

// ----- Rotations -------------------------------------------------------------------------
//
// Action and frequency of a rotation (PHYSICS.md §4.5): a pendulum swinging over the top.
//
// A rotation has no turning points: the momentum stays real over a whole turn of an angle
// `q`, and the orbit closes after `q` advances by 2π. On the branch moving forward,
// `p₊ = (−b + √D)/(2a)` and `q' = ∂H/∂p = √D` (notation above), so
//
// * `J = (1/2π) ∫₀^{2π} p₊ dq`,
// * `T = ∫₀^{2π} dq/√D`, `ω = 2π/T`.
//
// Both integrands are smooth and 2π-periodic, so the trapezoidal rule on uniform nodes
// converges exponentially; nodes are doubled until two passes agree to 1e-13 (relative).
// The period 2π is detected, not assumed: `D` must repeat after 2π and stay positive over
// the turn, and `D` must vary with `q` (a constant `D`, the free particle, has no period);
// else the orbit is unbounded and the caller reports that.

/// Sample points used to detect periodicity and positivity of `D` over one turn.
const ROTATION_SAMPLES: usize = 256;

/// `J`, `T` and `ω` of the rotation through `inside`, or `None` when `D` is not 2π-periodic
/// and positive over the turn (then the orbit is not a rotation of an angle).
fn rotation(
    disc: &dyn Fn(f64) -> f64,
    a: &dyn Fn(f64) -> f64,
    b: &dyn Fn(f64) -> f64,
    energy: f64,
    inside: f64,
) -> Option<Result<ActionFrequency, super::ActionAngleError>> {
    // A `D` that does not depend on `q` (a free particle) says nothing about a period: an
    // unbounded line, not a turning angle.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..ROTATION_SAMPLES {
        let x = inside + TAU * k as f64 / ROTATION_SAMPLES as f64;
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
    let (t_prev, j_prev, n, change) = match converged_quadrature(pass) {
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
