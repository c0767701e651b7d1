//! The trial-function (Ritz) method for a fixed-end-point problem (§1.4.2, (1.21)–(1.22)):
//! a trial path `q(t; a_1 … a_K)` that meets the end conditions, the action
//! `S(a) = ∫_{t₀}^{t₁} L(q, ∂_t q, t) dt`, its stationarity conditions `∂S/∂a_k = 0`, and
//! their numeric solution by Newton's method.
//!
//! The integral is exact when the integrand is a polynomial in `t` (its `(d+1)`-th
//! derivative vanishes identically; then `∫ I dt = Σ_{j≤d} I⁽ʲ⁾(t₀) (t₁ − t₀)^{j+1}/(j+1)!`,
//! Taylor's formula, which is exact for a polynomial), and is otherwise done numerically by
//! composite Gauss–Legendre quadrature, where `∂S/∂a_k` is the integral of `∂L/∂a_k`.

use std::collections::HashMap;

use crate::algebra::expand;
use crate::diff::Differentiator;
use crate::eval::eval_with;
use crate::expr::{Expr, Symbol};

use super::system::{time, System};
use super::tidy::tidy;
use super::MechanicsError;

/// The highest polynomial degree in `t` integrated exactly.
const MAX_EXACT_DEGREE: usize = 40;
/// Composite Gauss–Legendre: panels graded geometrically towards both ends, halving until the
/// panels contribute nothing at double precision (at most `MAX_LEVELS` times, where the span
/// left is below the smallest normal float), each with `NODES` points. Stopping at a fixed
/// depth of 40 halvings lost the last `2⁻⁴⁰` of the span, `≈ 1e-6` of the brachistochrone's
/// `∫ dt/√y`.
const MAX_LEVELS: usize = 1020;
/// The depth over which `∫ e² dt` is summed for the quadrature's check.
const SQUARE_LEVELS: usize = 40;
const NODES: usize = 12;
/// The finest subdivision of every panel the quadrature tries (see `Ritz::solve`).
const MAX_SPLIT: usize = 64;

/// A Ritz problem: the action and its stationarity conditions.
#[derive(Clone, Debug, PartialEq)]
pub struct Ritz {
    /// The unknowns `a_k`.
    pub unknowns: Vec<Symbol>,
    /// The integrand `L(q(t; a), ∂_t q(t; a), t)`.
    pub integrand: Expr,
    /// `S(a)` in closed form, when the integrand is a polynomial in `t`.
    pub action: Option<Expr>,
    /// `∂S/∂a_k` in closed form (exact case), or the integrands `∂L/∂a_k` of
    /// `∂S/∂a_k = ∫ ∂L/∂a_k dt` (quadrature case).
    pub conditions: Vec<Expr>,
    /// `∂²S/∂a_k∂a_l` (or its integrands), row-major.
    hessian: Vec<Expr>,
    t0: Expr,
    t1: Expr,
    /// At each free end, the natural boundary condition (1.18) `∂L/∂q'_i = 0` along the trial
    /// path: the coordinate, the end, and `∂L/∂q'_i(t_end; a)`. The trial path is not pinned
    /// there, so stationarity of `S(a)` approximates the condition; the exact path meets it.
    pub natural: Vec<(Symbol, Expr, Expr)>,
}

/// Why a Ritz problem could not be set up or solved.
fn bad(msg: String) -> MechanicsError {
    MechanicsError::WrongKind(msg)
}

impl System {
    /// The Ritz problem of the system's `L` for the trial path `trial` (one expression in
    /// `t` and the unknowns per coordinate) between `q(t0) = from` and `q(t1) = to`. A trial
    /// path that misses an end condition is refused, naming it.
    pub fn ritz(
        &self,
        trial: &[Expr],
        unknowns: &[Symbol],
        (t0, t1): (&Expr, &Expr),
        (from, to): (&[Expr], &[Expr]),
    ) -> Result<Ritz, MechanicsError> {
        let fixed = |v: &[Expr]| v.iter().cloned().map(Some).collect::<Vec<_>>();
        self.ritz_ends(trial, unknowns, (t0, t1), (&fixed(from), &fixed(to)))
    }

    /// [`System::ritz`] where an end value may be left free (`None`): the end point varies
    /// with the path (§1.4, (1.18)), so the trial path must not be pinned there (its value at
    /// that end must depend on the unknowns), and the report adds the natural boundary
    /// condition `∂L/∂q' = 0` there, which the stationary trial path meets only approximately.
    pub fn ritz_ends(
        &self,
        trial: &[Expr],
        unknowns: &[Symbol],
        (t0, t1): (&Expr, &Expr),
        (from, to): (&[Option<Expr>], &[Option<Expr>]),
    ) -> Result<Ritz, MechanicsError> {
        let l = self.need_lagrangian("ritz")?;
        self.refuse_velocity_constraints("a Ritz solution (a stationary action)")?;
        let n = self.coords.len();
        if trial.len() != n || from.len() != n || to.len() != n {
            return Err(bad(format!(
                "ritz needs one trial path and one value at each end per coordinate ({n}); got {} paths, {} and {} end values",
                trial.len(),
                from.len(),
                to.len()
            )));
        }
        if unknowns.is_empty() {
            return Err(bad("ritz needs at least one unknown coefficient a_k in the trial path".into()));
        }
        for (q, e) in self.coords.iter().zip(trial) {
            if let Some(s) = e.free_symbols().into_iter().find(|s| s.primes() > 0 || self.coords.contains(s)) {
                return Err(bad(format!(
                    "the trial path of {q} must be a function of t and the unknowns, not of `{s}`"
                )));
            }
        }
        let t = time();
        let mut d = Differentiator::new();
        let mut natural = Vec::new();
        // End conditions: q(t_end; a) − value must vanish for every a; at a free end the
        // trial value must instead move with the unknowns.
        for (i, q) in self.coords.iter().enumerate() {
            for (end, value) in [(t0, &from[i]), (t1, &to[i])] {
                let at: HashMap<Symbol, Expr> = [(t.clone(), end.clone())].into_iter().collect();
                let Some(value) = value else {
                    let there = trial[i].subs(&at);
                    if unknowns.iter().all(|a| vanishes(&d.diff(&there, a), unknowns)) {
                        return Err(bad(format!(
                            "the trial path is pinned at the free end t = {end}: it gives {q}({end}) = {} for every value of the unknowns, \
                             so the natural boundary condition ∂L/∂{}' = 0 cannot act there; a trial path whose value at t = {end} \
                             depends on the unknowns (e.g. a term a·t) would work",
                            tidy(&there),
                            q
                        )));
                    }
                    natural.push((q.clone(), end.clone(), i));
                    continue;
                };
                let miss = trial[i].subs(&at).minus(value);
                if !vanishes(&miss, unknowns) {
                    return Err(bad(format!(
                        "the trial path misses the end condition {q}({end}) = {value}: it gives {q}({end}) = {}",
                        tidy(&trial[i].subs(&at))
                    )));
                }
            }
        }
        let mut m: HashMap<Symbol, Expr> = HashMap::new();
        for (i, q) in self.coords.iter().enumerate() {
            m.insert(q.clone(), trial[i].clone());
            m.insert(self.velocities[i].clone(), d.diff(&trial[i], &t));
        }
        let integrand = tidy(&l.subs(&m));
        let natural = natural
            .into_iter()
            .map(|(q, end, i)| {
                let at: HashMap<Symbol, Expr> = [(t.clone(), end.clone())].into_iter().collect();
                let p = d.diff(l, &self.velocities[i]).subs(&m).subs(&at);
                (q, end, tidy(&p))
            })
            .collect();
        let grad: Vec<Expr> = unknowns.iter().map(|a| tidy(&d.diff(&integrand, a))).collect();
        let hess: Vec<Expr> =
            grad.iter().flat_map(|g| unknowns.iter().map(|a| d.diff(g, a)).collect::<Vec<_>>()).collect();
        let exact = |e: &Expr, d: &mut Differentiator| exact_integral(e, &t, t0, t1, d);
        let action = exact(&integrand, &mut d);
        let (conditions, hessian) = if action.is_some() {
            let c: Option<Vec<Expr>> = grad.iter().map(|g| exact(g, &mut d)).collect();
            let h: Option<Vec<Expr>> = hess.iter().map(|g| exact(g, &mut d)).collect();
            match (c, h) {
                (Some(c), Some(h)) => (c, h),
                _ => (grad, hess),
            }
        } else {
            (grad, hess)
        };
        let exact_case = action.is_some() && conditions.iter().all(|c| !c.contains(&t));
        Ok(Ritz {
            unknowns: unknowns.to_vec(),
            integrand,
            action: if exact_case { action } else { None },
            conditions,
            hessian,
            t0: t0.clone(),
            t1: t1.clone(),
            natural,
        })
    }
}

/// Whether `e` is identically zero: by expansion, else numerically at a few values of the
/// unknowns (for trial paths with functions that expansion does not cancel).
fn vanishes(e: &Expr, unknowns: &[Symbol]) -> bool {
    if expand(e).map(|x| x.is_zero()).unwrap_or(false) || tidy(e).is_zero() {
        return true;
    }
    let free = e.free_symbols();
    if free.iter().any(|s| !unknowns.contains(s)) {
        return false;
    }
    [0.37, -1.21, 2.3].iter().all(|&base| {
        let v = eval_with(e, &|s| unknowns.iter().position(|a| a == s).map(|k| base + 0.11 * k as f64));
        v.is_ok_and(|v| v.abs() < 1e-12)
    })
}

/// `∫_{t0}^{t1} e dt` when `e` is a polynomial in `t` of degree at most [`MAX_EXACT_DEGREE`].
fn exact_integral(e: &Expr, t: &Symbol, t0: &Expr, t1: &Expr, d: &mut Differentiator) -> Option<Expr> {
    let at0: HashMap<Symbol, Expr> = [(t.clone(), t0.clone())].into_iter().collect();
    let width = t1.minus(t0);
    let mut terms = Vec::new();
    let mut der = e.clone();
    let mut factorial = 1i64;
    for j in 0..=MAX_EXACT_DEGREE {
        if expand(&der).ok()?.is_zero() {
            return Some(tidy(&expand(&Expr::add(terms)).ok()?));
        }
        factorial = factorial.checked_mul(j as i64 + 1)?;
        terms.push(der.subs(&at0).times(&width.powi(j as i64 + 1)).over(&Expr::int(factorial)));
        der = d.diff(&der, t);
    }
    None
}

/// A numeric solution of the Ritz conditions.
#[derive(Clone, Debug, PartialEq)]
pub struct RitzSolution {
    /// `a_k`.
    pub values: Vec<f64>,
    /// `S` at the solution.
    pub action: f64,
    /// Newton steps used.
    pub iterations: usize,
    /// Quadrature points the integrals took (refined until two estimates agree; 0 when `S`
    /// is exact).
    pub points: usize,
    /// `∂L/∂q'` at each free end ([`Ritz::natural`], same order) at the solution: the residual
    /// of the natural boundary condition, which tends to 0 as trial functions are added.
    pub natural: Vec<f64>,
}

impl Ritz {
    /// Solves `∂S/∂a = 0` by Newton's method from `guess`, with `params` bound.
    pub fn solve(&self, guess: &[f64], params: &[(&str, f64)]) -> Result<RitzSolution, MechanicsError> {
        let k = self.unknowns.len();
        let numeric = |e: &Expr| eval_with(e, &|s| params.iter().find(|(n, _)| *n == s.to_string()).map(|(_, v)| *v));
        let (t0, t1) =
            (numeric(&self.t0).map_err(|e| bad(e.to_string()))?, numeric(&self.t1).map_err(|e| bad(e.to_string()))?);
        let exact = self.action.is_some();
        let q = Quadrature {
            ritz: self,
            params,
            t: time(),
            span: (t0, t1),
            nodes: gauss_legendre(NODES),
            evaluations: std::cell::Cell::new(0),
        };
        let value = |e: &Expr, a: &[f64], split: usize| q.value(e, a, split);
        let mut a = guess.to_vec();
        a.resize(k, 0.0);
        // Each panel split in `split` parts; doubled (and Newton resumed from where it
        // stopped) while the check finds the quadrature unresolved, up to `MAX_SPLIT`.
        let mut split = 1;
        let mut it = 0;
        // The gradient at the first guess: once Newton has brought it down to rounding
        // (1e-13 of it), the coefficients are as good as the Hessian's condition allows, and
        // further steps only move them by rounding noise amplified by that condition (a
        // quadratic S in ten monomial coefficients: a Hessian of condition ~1e13, whose
        // Newton steps never fall below 1e-13 however long they go on).
        let mut first_gradient = None;
        while it < 50 {
            it += 1;
            crate::cancel::check().map_err(|_| bad(format!("interrupted after {} Newton steps", it - 1)))?;
            let mut g: Vec<f64> = self.conditions.iter().map(|c| value(c, &a, split)).collect::<Result<_, _>>()?;
            let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if !gmax.is_finite() {
                let i = g.iter().position(|v| !v.is_finite()).unwrap_or(0);
                let what = format!("∂S/∂{} is {}", self.unknowns[i], num(g[i]));
                return Err(self.not_finite(&what, &self.conditions[i], &a, it, (t0, t1), params));
            }
            let g0 = *first_gradient.get_or_insert(gmax);
            let at_rounding = it > 1 && gmax <= 1e-13 * g0;
            let mut step = 0.0f64;
            let mut scale = 1.0f64;
            // At rounding the step is still taken, once, as a refinement.
            let hess = |a: &[f64]| -> Result<Vec<f64>, MechanicsError> {
                self.hessian.iter().map(|c| value(c, a, split)).collect()
            };
            let mut h = hess(&a)?;
            let (h_at, g_at) = (h.clone(), g.clone());
            if solve_dense(&mut h, &mut g, k).is_none() {
                if let Some(i) = h_at.iter().position(|v| !v.is_finite()) {
                    let (r, c) = (i / k, i % k);
                    let what = format!("∂²S/∂{}∂{} is {}", self.unknowns[r], self.unknowns[c], num(h_at[i]));
                    return Err(self.not_finite(&what, &self.hessian[i], &a, it, (t0, t1), params));
                }
                // Singular here: at another point too (a structural cause, named from the
                // Hessian's rows and null vector), or only here (a degenerate point).
                let other: Vec<f64> = a.iter().enumerate().map(|(i, v)| v + 0.37 + 0.11 * i as f64).collect();
                let h_other = hess(&other)?;
                let g_other: Vec<f64> =
                    self.conditions.iter().map(|c| value(c, &other, split)).collect::<Result<_, _>>()?;
                let mut probe = (h_other.clone(), vec![0.0; k]);
                if singular(&h_other, k) || solve_dense(&mut probe.0, &mut probe.1, k).is_none() {
                    return Err(self.structural(&h_at, &h_other, (&g_at, &g_other)));
                }
                if gmax == 0.0 {
                    // Already stationary (∂S/∂a = 0 exactly), only not a strict extremum: the
                    // Newton step is zero whatever the Hessian.
                    g.iter_mut().for_each(|v| *v = 0.0);
                } else {
                    return Err(bad(format!(
                        "the Hessian of S is singular at {} ({}), though not elsewhere: S is flat to second order \
                         there, so Newton's method has no step to take. Starting from another guess \
                         (`--guess`, or `near` in a scene), e.g. {}, would work",
                        self.point(&a),
                        if it == 1 {
                            "the starting guess".to_string()
                        } else {
                            format!("after {} Newton steps", it - 1)
                        },
                        self.point(&other)
                    )));
                }
            }
            for i in 0..k {
                a[i] -= g[i];
                step = step.max(g[i].abs());
                scale = scale.max(a[i].abs());
            }
            if at_rounding || step <= 1e-13 * scale {
                if !q.check(&a, split)? {
                    split *= 2;
                    first_gradient = None;
                    continue;
                }
                q.evaluations.set(0);
                let action = match &self.action {
                    Some(s) => value(s, &a, split)?,
                    None => value(&self.integrand, &a, split)?,
                };
                let points = if exact { 0 } else { q.evaluations.get() };
                let natural = self
                    .natural
                    .iter()
                    .map(|(_, _, p)| {
                        eval_with(p, &q.bind(&a, f64::NAN))
                            .map_err(|err| bad(format!("evaluating the natural boundary condition: {err}")))
                    })
                    .collect::<Result<_, _>>()?;
                return Ok(RitzSolution { values: a, action, iterations: it, points, natural });
            }
        }
        Err(bad("Newton's method on ∂S/∂a = 0 did not converge in 50 steps (try another guess)".into()))
    }
}

/// The integrals of one [`Ritz::solve`]: each condition's integrand over the span as a function of
/// the unknowns, by graded Gauss–Legendre panels (by substitution when `S` is exact), with the
/// integrand evaluations counted for [`RitzSolution::points`]. A type of its own so the Newton
/// iteration reads as Newton's method, and the quadrature and its reliability check as one unit.
struct Quadrature<'a> {
    ritz: &'a Ritz,
    params: &'a [(&'a str, f64)],
    /// The time symbol of the trial path.
    t: Symbol,
    /// The span `(t0, t1)`, evaluated.
    span: (f64, f64),
    nodes: Vec<(f64, f64)>,
    evaluations: std::cell::Cell<usize>,
}

impl Quadrature<'_> {
    /// `S` known in closed form: every integral is the substitution at one point.
    fn exact(&self) -> bool {
        self.ritz.action.is_some()
    }

    /// The values of the time, the unknowns `a` and the parameters, for [`eval_with`].
    fn bind<'b>(&'b self, a: &'b [f64], tt: f64) -> impl Fn(&Symbol) -> Option<f64> + 'b {
        move |s: &Symbol| {
            if *s == self.t {
                return Some(tt);
            }
            if let Some(i) = self.ritz.unknowns.iter().position(|u| u == s) {
                return Some(a[i]);
            }
            self.params.iter().find(|(n, _)| *n == s.to_string()).map(|(_, v)| *v)
        }
    }

    /// ∫ e dt and ∫ e² dt over the graded panels, each panel split in `split` equal parts.
    fn integrals(&self, e: &Expr, a: &[f64], split: usize) -> Result<(f64, f64), MechanicsError> {
        let (t0, t1) = self.span;
        let ev = |tt: f64| {
            eval_with(e, &self.bind(a, tt)).map_err(|err| bad(format!("evaluating the Ritz conditions: {err}")))
        };
        if self.exact() {
            let v = ev(t0)?;
            return Ok((v, v * v));
        }
        let w = t1 - t0;
        let (mut s, mut sq, mut abs) = (0.0, 0.0, 0.0);
        let panel = |pa: f64, pb: f64| -> Result<(f64, f64, f64), MechanicsError> {
            let part = (pb - pa) / split as f64;
            let (mut ps, mut psq, mut pabs) = (0.0, 0.0, 0.0);
            self.evaluations.set(self.evaluations.get() + split * NODES);
            for j in 0..split {
                let (ja, jb) = (pa + part * j as f64, pa + part * (j + 1) as f64);
                let (mid, half) = (0.5 * (ja + jb), 0.5 * (jb - ja));
                for (x, wt) in &self.nodes {
                    let f = ev(mid + half * x)?;
                    ps += wt * half * f;
                    psq += wt * half * f * f;
                    pabs += wt * half * f.abs();
                }
            }
            Ok((ps, psq, pabs))
        };
        // The middle half, then panels [2^-(k+2), 2^-(k+1)]·w from each end inwards until
        // two in a row add nothing at double precision (an integrable end singularity
        // such as the brachistochrone's `1/√y` needs about 110 halvings for that, a smooth
        // integrand about 55), then the last sliver, whose Gauss nodes stay off the end.
        let (ps, psq, pabs) = panel(t0 + 0.25 * w, t1 - 0.25 * w)?;
        (s, sq, abs) = (s + ps, sq + psq, abs + pabs);
        for from_start in [true, false] {
            let mut quiet = 0;
            let mut k = 0;
            let sliver = loop {
                let (lo, hi) = (0.5f64.powi(k + 3), 0.5f64.powi(k + 2));
                let (a, b) = if from_start { (t0 + lo * w, t0 + hi * w) } else { (t1 - hi * w, t1 - lo * w) };
                let end = if from_start { t0 } else { t1 };
                if a == b || a == end || b == end || k as usize >= MAX_LEVELS {
                    break if from_start { (t0, a.min(b)) } else { (a.max(b), t1) };
                }
                let (ps, psq, pabs) = panel(a, b)?;
                // `∫ e²` only over a fixed depth: it detects a pole inside the span, and at an
                // integrable end singularity (`1/√t`) it diverges slowly with the depth.
                let psq = if (k as usize) < SQUARE_LEVELS { psq } else { 0.0 };
                (s, sq, abs) = (s + ps, sq + psq, abs + pabs);
                quiet = if pabs <= 1e-17 * abs { quiet + 1 } else { 0 };
                k += 1;
                if quiet >= 2 {
                    break if from_start { (t0, a) } else { (b, t1) };
                }
            };
            if sliver.1 > sliver.0 {
                s += panel(sliver.0, sliver.1)?.0;
            }
        }
        Ok((s, sq))
    }

    /// ∫ e dt.
    fn value(&self, e: &Expr, a: &[f64], split: usize) -> Result<f64, MechanicsError> {
        self.integrals(e, a, split).map(|(v, _)| v)
    }

    /// The quadrature's own error estimate at the solution: the same integrals with every
    /// panel halved, of the integrand and of its square (smooth where the integrand is, and
    /// divergent at a pole inside the span even where the signed sum is a principal value).
    /// A smooth integrand (or an integrable end singularity, which the grading resolves)
    /// agrees to rounding; one oscillating faster than the panels resolve, or not
    /// integrable inside the span, does not, and the solution is refused instead of printed
    /// as if it were right. The signed integral is compared on the scale √(T ∫ e²) ≥ ∫ |e|.
    /// `Ok(false)`: not yet reliable, but a finer split may be.
    fn check(&self, a: &[f64], split: usize) -> Result<bool, MechanicsError> {
        if self.exact() {
            return Ok(true);
        }
        for (what, e) in std::iter::once(("L(trial)".to_string(), &self.ritz.integrand))
            .chain(self.ritz.unknowns.iter().zip(&self.ritz.conditions).map(|(u, c)| (format!("∂L/∂{u}"), c)))
        {
            let ((q1, s1), (q2, s2)) = (self.integrals(e, a, split)?, self.integrals(e, a, 2 * split)?);
            let scale = ((self.span.1 - self.span.0).abs() * s2).sqrt();
            if scale == 0.0 {
                continue;
            }
            if !((q1 - q2).abs() <= 1e-6 * scale && (s1 - s2).abs() <= 1e-6 * s2) {
                if split < MAX_SPLIT {
                    return Ok(false);
                }
                return Err(bad(format!(
                    "the quadrature of ∫ {what} dt is not reliable at the solution: with each panel split in {} and {} parts \
                     it gives {q1:e} and {q2:e} (∫ ({what})² dt: {s1:e} and {s2:e}); the integrand \
                     oscillates faster than the quadrature resolves, or is not integrable inside the span \
                     (a singular point). A trial path and span on which L(trial) is smooth would work",
                    split,
                    2 * split
                )));
            }
        }
        Ok(true)
    }
}

/// A number in a message: six significant digits, scientific past a sensible width.
fn num(x: f64) -> String {
    if !x.is_finite() {
        return if x.is_nan() {
            "NaN".into()
        } else if x > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        };
    }
    let short = format!("{}", (x * 1e6).round() / 1e6);
    if x != 0.0 && (x.abs() >= 1e6 || x.abs() < 1e-4) {
        let e = format!("{x:.5e}");
        let (m, exp) = e.split_once('e').unwrap_or((&e, "0"));
        let m = if m.contains('.') { m.trim_end_matches('0').trim_end_matches('.') } else { m };
        return format!("{m}e{exp}");
    }
    short
}

/// Whether the symmetric matrix `h` (`k × k`) is singular to rounding: its smallest eigenvalue
/// below `1e-10` of its largest (or it is zero, or not finite).
fn singular(h: &[f64], k: usize) -> bool {
    let Some(eig) = eigen(h, k) else { return true };
    let big = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let small = eig.eigenvalues.iter().fold(f64::INFINITY, |m, v| m.min(v.abs()));
    big == 0.0 || small <= 1e-10 * big
}

fn eigen(h: &[f64], k: usize) -> Option<nalgebra::SymmetricEigen<f64, nalgebra::Dyn>> {
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    let m = nalgebra::DMatrix::from_fn(k, k, |i, j| 0.5 * (h[i * k + j] + h[j * k + i]));
    Some(m.symmetric_eigen())
}

impl Ritz {
    /// `a = 1, b = 2` for the coefficients `a`.
    fn point(&self, a: &[f64]) -> String {
        self.unknowns.iter().zip(a).map(|(u, v)| format!("{u} = {}", num(*v))).collect::<Vec<_>>().join(", ")
    }

    /// A gradient or Hessian entry (`what`, the integrand or closed form `e`) is not finite at
    /// `a`: where on the span its integrand is not, when it has one.
    fn not_finite(
        &self,
        what: &str,
        e: &Expr,
        a: &[f64],
        it: usize,
        (t0, t1): (f64, f64),
        params: &[(&str, f64)],
    ) -> MechanicsError {
        let when = if it == 1 { "the starting guess".to_string() } else { format!("after {} Newton steps", it - 1) };
        let t = time();
        let place = if e.contains(&t) {
            // The midpoints of 1000 equal parts (the quadrature never evaluates at the ends).
            (0..1000)
                .map(|j| t0 + (t1 - t0) * (j as f64 + 0.5) / 1000.0)
                .find(|&tt| {
                    let at = |s: &Symbol| {
                        if *s == t {
                            return Some(tt);
                        }
                        match self.unknowns.iter().position(|u| u == s) {
                            Some(i) => Some(a[i]),
                            None => params.iter().find(|(n, _)| *n == s.to_string()).map(|(_, v)| *v),
                        }
                    };
                    !eval_with(e, &at).is_ok_and(|v| v.is_finite())
                })
                .map(|tt| format!(", e.g. at t = {}", num(tt)))
                .unwrap_or_default()
        } else {
            String::new()
        };
        bad(format!(
            "{what} at {} ({when}): L(trial) is not twice differentiable in the coefficients along the span{place} \
             (the trial path reaches a point where L is singular or undefined). A guess (`--guess`, or `near` in a scene) \
             or trial path on which L(trial) stays smooth over the whole span would work",
            self.point(a)
        ))
    }

    /// The Hessian is singular at two unrelated points: name the cause from its rows, its null
    /// vector and the gradient along it (`h`, `h2`, `g`, `g2`: at the two points).
    fn structural(&self, h: &[f64], h2: &[f64], (g, g2): (&[f64], &[f64])) -> MechanicsError {
        let k = self.unknowns.len();
        let hmax = h.iter().chain(h2).fold(0.0f64, |m, v| m.max(v.abs()));
        let gmax = g.iter().chain(g2).fold(0.0f64, |m, v| m.max(v.abs()));
        let flat = |v: &[f64]| {
            let (d, d2): (f64, f64) =
                (v.iter().zip(g).map(|(x, y)| x * y).sum(), v.iter().zip(g2).map(|(x, y)| x * y).sum());
            d.abs().max(d2.abs()) <= 1e-9 * gmax
        };
        let linear = |v: &[f64]| {
            let d: f64 = v.iter().zip(g).map(|(x, y)| x * y).sum();
            num(d)
        };
        if !singular(h, k) {
            // Not singular relative to its own size: every entry is below the solver's
            // absolute pivot floor.
            return bad(format!(
                "the Hessian of S(a) is too small for double precision: its largest entry is {} \
                 (below the pivot floor 1e-300), so S varies too little to locate its stationary point. \
                 Multiplying L by a constant factor (which leaves the stationary path unchanged), or \
                 parameter values of a larger scale, would work",
                num(h.iter().fold(0.0f64, |m, v| m.max(v.abs())))
            ));
        }
        let free = self.integrand.free_symbols();
        let mut why = Vec::new();
        let mut rest = Vec::new();
        for (i, u) in self.unknowns.iter().enumerate() {
            let row = (0..k).map(|j| h[i * k + j].abs().max(h2[i * k + j].abs())).fold(0.0f64, f64::max);
            if row > 1e-12 * hmax {
                rest.push(i);
                continue;
            }
            let mut e = vec![0.0; k];
            e[i] = 1.0;
            why.push(if !free.contains(u) {
                format!(
                    "`{u}` does not appear in L(trial): the trial path does not depend on it (remove it from the unknowns, or give it a trial function of its own)"
                )
            } else if flat(&e) {
                format!(
                    "S does not depend on `{u}` (∂S/∂{u} = 0 whatever the coefficients: along this trial family L changes with {u} only by a total derivative, or not at all); remove it, or give it a trial function that changes S"
                )
            } else {
                format!(
                    "S is linear in `{u}` (∂S/∂{u} = {} whatever {u} is), so it has no stationary point in {u}; a trial path in which {u} enters L(trial) at least quadratically would work",
                    linear(&e)
                )
            });
        }
        // Among the other coefficients, a direction in which S is flat to second order.
        let n = rest.len();
        let sub =
            |h: &[f64]| -> Vec<f64> { rest.iter().flat_map(|&i| rest.iter().map(move |&j| h[i * k + j])).collect() };
        if n > 0 && singular(&sub(h), n) && singular(&sub(h2), n) {
            if let Some(eig) = eigen(&sub(h), n) {
                let j =
                    (0..n).min_by(|&x, &y| eig.eigenvalues[x].abs().total_cmp(&eig.eigenvalues[y].abs())).unwrap_or(0);
                let col = eig.eigenvectors.column(j);
                let big = col.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let mut v = vec![0.0; k];
                for (r, &i) in rest.iter().enumerate() {
                    v[i] = if col[r].abs() > 1e-6 * big { col[r] / big } else { 0.0 };
                }
                // The first coefficient involved rises.
                let sign = v.iter().copied().find(|x| *x != 0.0).unwrap_or(1.0).signum();
                v.iter_mut().for_each(|x| *x *= sign);
                let involved: Vec<usize> = (0..k).filter(|&i| v[i] != 0.0).collect();
                let names =
                    involved.iter().map(|&i| format!("`{}`", self.unknowns[i])).collect::<Vec<_>>().join(" and ");
                let direction = involved
                    .iter()
                    .enumerate()
                    .map(|(n, &i)| {
                        let by = if n == 0 { " changes by" } else { " by" };
                        format!("{}{by} {}", self.unknowns[i], num(v[i]).replace('-', "−"))
                    })
                    .collect::<Vec<_>>()
                    .join(" and ");
                let combination = if let [p, q] = involved[..] {
                    // S is unchanged along (v_p, v_q) in (a_p, a_q): it depends on
                    // v_q a_p − v_p a_q, that is on a_p − (v_p / v_q) a_q.
                    let c = -v[p] / v[q];
                    format!(
                        " only as the combination {} {} {}{}",
                        self.unknowns[p],
                        if c < 0.0 { "−" } else { "+" },
                        if (c.abs() - 1.0).abs() < 1e-9 { String::new() } else { format!("{} ", num(c.abs())) },
                        self.unknowns[q]
                    )
                } else {
                    String::new()
                };
                why.push(if flat(&v) {
                    format!(
                        "{names} enter S{combination}: S does not change when {direction} (they multiply the same function of t, \
                         or functions that L(trial) cannot tell apart); keep one of them, or give each a trial function of its own"
                    )
                } else {
                    format!(
                        "S changes only linearly when {direction} (at the rate {}), so it has no stationary point; \
                         a trial path in which {names} enter L(trial) at least quadratically would work",
                        linear(&v)
                    )
                });
            }
        }
        if why.is_empty() {
            why.push("the trial coefficients are not independent".into());
        }
        bad(format!("the Hessian of S(a) is singular whatever the coefficients: {}", why.join("; ")))
    }
}

/// Solves the Newton system `m x = b` in place (`x` into `b`); `None` if singular or not
/// finite. Elimination is the crate's one ([`crate::linalg`]), with an absolute pivot floor
/// rather than the relative one of the right-hand sides: a Hessian whose entries span many
/// orders of magnitude is still solved. Not nalgebra's LU: with its rounding, the
/// four-coefficient oscillator of the notes (`tests/it/notes/examples.rs`, `ritz_oscillator`)
/// took 4 Newton steps instead of 2, its second step staying above the `1e-13` stopping
/// threshold.
fn solve_dense(m: &mut [f64], b: &mut [f64], n: usize) -> Option<()> {
    if !m[..n * n].iter().all(|x| x.is_finite()) {
        return None;
    }
    crate::linalg::lu_in_place(m, n, 1e-300, |j, p| b.swap(j, p)).ok()?;
    crate::linalg::lu_substitute(m, n, b);
    Some(())
}

/// The `n`-point Gauss–Legendre nodes and weights on [−1, 1]: Newton on `P_n` from the
/// Chebyshev-like guesses `cos(π (i − ¼)/(n + ½))`, weights `2/((1 − x²) P_n'(x)²)`
/// (Abramowitz & Stegun 25.4.29; the three-term recurrence for `P_n`).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (1..=n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

impl Ritz {
    /// `S` as text for the machine-readable report: the closed form when the integrand is a
    /// polynomial in `t`, otherwise the integral that is evaluated numerically, so a reader of
    /// the JSON sees the action in both cases and never mistakes the integrand for it.
    pub fn action_text(&self) -> String {
        use crate::print::plain;
        match &self.action {
            Some(sa) => plain(sa),
            None => format!("∫ ({}) dt for t from {} to {}", plain(&self.integrand), plain(&self.t0), plain(&self.t1)),
        }
    }

    /// The stationarity conditions `∂S/∂a_k = 0` as text for the machine-readable report,
    /// each a whole equation: `∂S/∂a_k` itself in closed form, or the integral of `∂L/∂a_k`
    /// over the span when it is integrated numerically (the bare integrand is not `∂S/∂a_k`).
    pub fn condition_texts(&self) -> Vec<String> {
        use crate::print::plain;
        self.conditions
            .iter()
            .map(|c| match &self.action {
                Some(_) => format!("{} = 0", plain(c)),
                None => format!("∫ ({}) dt = 0 for t from {} to {}", plain(c), plain(&self.t0), plain(&self.t1)),
            })
            .collect()
    }

    /// The printed lines shared by `lagrangian ritz` and the scene statement `ritz`: the
    /// integrand, `S` and the conditions `∂S/∂a_k = 0` (or, when the integrand is not a
    /// polynomial in t, a note and the integrands of the conditions), then the solution.
    pub fn report(&self, sol: &RitzSolution, format: crate::print::Format) -> Vec<String> {
        use crate::print::{render, symbol};
        let r = |e: &Expr| render(e, format);
        let mut out = vec![format!("L(trial) = {}", r(&self.integrand))];
        match &self.action {
            Some(sa) => {
                out.push(format!("S = {}", r(sa)));
                for (u, c) in self.unknowns.iter().zip(&self.conditions) {
                    out.push(format!("∂S/∂{}: {} = 0", symbol(u, format), r(c)));
                }
            }
            None => {
                out.push(format!(
                    "note: L(trial) is not a polynomial in t; S and ∂S/∂a are integrated numerically (Gauss–Legendre, {} points graded towards the ends)",
                    sol.points
                ));
                for (u, c) in self.unknowns.iter().zip(&self.conditions) {
                    out.push(format!("∂S/∂{}: ∫ {} dt = 0", symbol(u, format), r(c)));
                }
            }
        }
        for (u, v) in self.unknowns.iter().zip(&sol.values) {
            out.push(format!("{} ≈ {v:.15e}", symbol(u, format)));
        }
        out.push(format!("S ≈ {:.15e}    # at the stationary point, {} Newton steps", sol.action, sol.iterations));
        for ((q, end, p), v) in self.natural.iter().zip(&sol.natural) {
            out.push(format!(
                "natural boundary condition at t = {}: ∂L/∂{}' = {} ≈ {v:.6e}    # 0 on the exact path (1.18)",
                r(end),
                symbol(q, format),
                r(p)
            ));
        }
        out
    }
}

/// The number of points of one graded panel of the Ritz quadrature (the points of a whole
/// integral, which adapt to the integrand, are [`RitzSolution::points`]).
pub fn ritz_quadrature_points() -> usize {
    NODES
}
