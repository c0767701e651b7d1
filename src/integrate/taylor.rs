//! The adaptive Taylor method: each step expands the solution in its Taylor series to order
//! `p` at the current state (the coefficients come from the system, by Taylor-mode automatic
//! differentiation of its compiled tape) and sums the series at the step size.
//!
//! Order and step follow Jorba & Zou, *A software package for the numerical integration of
//! ODEs by means of high-order Taylor methods*, Experimental Mathematics 14 (2005) 99–117,
//! §3.2–3.3: for a tolerance `ε` the order is `p = ⌈−½ ln ε + 1⌉`, and the step is
//! `h = ρ / e² · exp(−0.7 / (p − 1))` with `ρ = min(ρ_{p−1}, ρ_p)`,
//! `ρ_m = (s / ‖y_[m]‖∞)^{1/m}` (an estimate of the radius of convergence from the last two
//! coefficients; `s = 1` for absolute control, `s = ‖y₀‖∞` for relative control, whichever of
//! `atol`, `rtol · ‖y₀‖∞` is larger). With `h = ρ/e²` the last term is about
//! `e^{−2p} ≤ ε`; the factor `exp(−0.7/(p − 1))` is their safety margin. The step is chosen a
//! priori, so no step is ever rejected.
//!
//! Dense output is the step's own polynomial (no extra right-hand sides), so events located
//! by the [`super::Solver`] are roots of `g` on that polynomial.

use super::error::{FailureReason, StepFailure};
use super::{add_scaled, Method, MethodInfo, RhsError};
use crate::lanes::Lane;

/// A system whose solution can be expanded in a Taylor series at any state: the integrators'
/// view of a compiled Taylor tape (`compile::TaylorOde`).
pub trait TaylorSystem: Sync {
    /// The dimension of the state.
    fn dim(&self) -> usize;
    /// The length of the buffer [`TaylorSystem::taylor_coefficients`] takes at `order`: at
    /// least `dim · (order + 1)`.
    fn scratch_len(&self, order: usize) -> usize;
    /// Writes the normalised Taylor coefficients `y_i⁽ᵏ⁾(t)/k!` of the solution through
    /// `(t, y)` into `buf[i · (order + 1) + k]`, `k = 0..=order`, `i < dim`; the rest of `buf`
    /// is the system's scratch. Must not allocate.
    ///
    /// The coefficients may be non-finite. The integrator does not scan them on every step:
    /// at a finite step `h`, a non-finite coefficient makes the step's increment `Σ c_k h^k`
    /// non-finite (NaN and ±∞ propagate through products and sums, and `∞ · 0` is NaN), so
    /// it scans only when the increment or the step size is not finite, and then asks
    /// [`TaylorSystem::non_finite`] to name the failure.
    fn taylor_coefficients(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), RhsError>;
    /// [`TaylorSystem::taylor_coefficients`] into a buffer that this system's last call of
    /// either method at the same `order` wrote, and nothing else has written since (the
    /// integrator keeps one buffer for a whole run): what every expansion writes identically
    /// (a compiled tape's constant rows, zero past order 0) may be left as it is. The
    /// default writes everything again.
    fn taylor_coefficients_again(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), RhsError> {
        self.taylor_coefficients(t, y, order, buf)
    }
    /// Checks that the expansion last written by [`TaylorSystem::taylor_coefficients`] (still
    /// in `scratch`) may be summed at the step `h`: a system with a non-smooth operation
    /// (`abs`) reports a kink inside the step as an error instead of a silently wrong step.
    /// The default accepts every step.
    fn check_step(&self, _scratch: &[f64], _order: usize, _h: f64) -> Result<(), RhsError> {
        Ok(())
    }
    /// The failure for the non-finite coefficient `buf[at]` of the expansion at `(t, y)`
    /// (component `at / (order + 1)`, order `at % (order + 1)`). The default names the
    /// component; a compiled system also names the order.
    fn non_finite(&self, _t: f64, _y: &[f64], order: usize, at: usize) -> StepFailure {
        StepFailure(FailureReason::NonFinite { component: at / (order + 1) })
    }
}

/// The smallest tolerance accepted: below it the last bits of an `f64` state are noise, and
/// the order grows with no gain.
pub const MIN_TOL: f64 = 1e-18;

/// The adaptive Taylor method (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Taylor {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance.
    pub atol: f64,
    /// The order, if not chosen from the tolerance.
    pub order: Option<usize>,
    /// Largest step size allowed (default: none).
    pub h_max: Option<f64>,
    /// Kahan-compensated summation of the state update.
    pub compensated: bool,
}

impl Default for Taylor {
    /// Machine precision: `tol = ε = 2.2e-16` (order 19).
    fn default() -> Self {
        Taylor::new(f64::EPSILON)
    }
}

impl Taylor {
    /// The Taylor method with `rtol = atol = tol`.
    pub fn new(tol: f64) -> Self {
        Taylor { rtol: tol, atol: tol, order: None, h_max: None, compensated: false }
    }

    /// Separate relative and absolute tolerances.
    pub fn with_tolerances(rtol: f64, atol: f64) -> Self {
        Taylor { rtol, atol, ..Taylor::new(rtol) }
    }

    /// Uses compensated summation for the state update.
    pub fn compensated(mut self) -> Self {
        self.compensated = true;
        self
    }

    /// Fixes the order instead of choosing it from the tolerance.
    pub fn with_order(mut self, p: usize) -> Self {
        self.order = Some(p);
        self
    }

    /// Caps the step size.
    pub fn with_h_max(mut self, h: f64) -> Self {
        self.h_max = Some(h);
        self
    }

    /// Name, order and properties.
    pub fn info(&self) -> MethodInfo {
        MethodInfo {
            name: "Taylor",
            order: self.taylor_order() as u32,
            symplectic: false,
            symmetric: false,
            adaptive: true,
        }
    }

    /// The order used: given, or `⌈−½ ln ε + 1⌉` for the smaller tolerance (at least 2).
    pub fn taylor_order(&self) -> usize {
        if let Some(p) = self.order {
            return p;
        }
        let eps = self.rtol.min(self.atol);
        if !(eps.is_finite() && eps > 0.0) {
            return 2;
        }
        ((-0.5 * eps.ln() + 1.0).ceil() as usize).max(2)
    }

    /// Checks the tolerances and order.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [("rtol", self.rtol), ("atol", self.atol)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("Taylor tolerance {name} = {v} must be positive and finite"));
            }
            if v < MIN_TOL {
                return Err(format!(
                    "Taylor tolerance {name} = {v:e} is below what f64 arithmetic can meet (the smallest accepted is {MIN_TOL:e})"
                ));
            }
        }
        if let Some(p) = self.order {
            if !(2..=100).contains(&p) {
                return Err(format!("Taylor order {p} must be between 2 and 100"));
            }
        }
        if let Some(h) = self.h_max {
            if !(h.is_finite() && h > 0.0) {
                return Err(format!("Taylor h_max = {h} must be positive and finite"));
            }
        }
        Ok(())
    }

    /// The Jorba–Zou step size from the coefficients of the last expansion (in `w`).
    fn step_size(&self, y: &[f64], w: &TaylorWork) -> f64 {
        let (x0, np1, np) = step_norms(y, &w.buf[..y.len() * (w.order + 1)], w.order);
        self.step_of_norms(x0, np1, np, w.constants)
    }

    /// The Jorba–Zou step size from the state's norm `x0 = ‖y₀‖∞` and the last two orders'
    /// `np1 = ‖y_[p−1]‖∞`, `np = ‖y_[p]‖∞` ([`step_norms`]). The roots `(s/‖y_[m]‖)^{1/m}` are taken in base-2 logarithms,
    /// `h = 2^{min_m log₂(s/‖y_[m]‖)/m + log₂ safety}`: two `log2` and one `exp2` (6 % of a
    /// Kepler step in a profile) where two `powf` were 7 %, and multiplications by `1/m`. The
    /// batch step calls this lane by lane, so each lane has the single run's step.
    #[inline]
    pub(crate) fn step_of_norms(&self, x0: f64, np1: f64, np: f64, k: StepConstants) -> f64 {
        let scale = if self.rtol * x0 <= self.atol { 1.0 } else { x0 };
        let (a, b) = (scale / np1, scale / np);
        let [inv1, inv] = k.inv_orders;
        // Only the smaller root is used. When a bracket of each `log2` from its exponent and
        // mantissa tells which one that is, only its `log2` is taken; the bits are those of
        // taking both.
        let root = match smaller_root(a, inv1, b, inv) {
            Some(true) => a.log2() * inv1,
            Some(false) => b.log2() * inv,
            // A zero norm gives `log2(∞) = ∞` (no bound from that order), an infinite one
            // `log2(0) = −∞`, so `h = 0`.
            None => (a.log2() * inv1).min(b.log2() * inv),
        };
        (root + k.safety_log2).exp2()
    }
}

/// The norms the step size needs, `(‖y₀‖∞, ‖y_[p−1]‖∞, ‖y_[p]‖∞)`, from the state `y` and its
/// coefficients (`i · (p + 1) + k`), for one run (`f64`) or lane by lane ([`Lanes`]).
/// Maxima by comparison, without `f64::max`'s handling of NaN in either operand (a NaN entry
/// is skipped alike: `v > m` is false; `m` is never NaN).
#[inline(always)]
pub(crate) fn step_norms<L: Lane>(y: &[L], coeffs: &[L], p: usize) -> (L, L, L) {
    let larger = |m: L, v: L| m.zip(v.map(f64::abs), |m, v| if v > m { v } else { m });
    let zero = L::splat(0.0);
    let x0 = y.iter().fold(zero, |m, &v| larger(m, v));
    let (mut np1, mut np) = (zero, zero);
    for row in coeffs.chunks_exact(p + 1) {
        np1 = larger(np1, row[p - 1]);
        np = larger(np, row[p]);
    }
    (x0, np1, np)
}

/// Why a step of size `h` from `(t, y)` is refused before its update, if it is: a non-finite
/// coefficient of the expansion (`first_non_finite` finds it; `∞` in the last orders makes `h`
/// zero), else a step size that collapsed to nothing (NaN, zero, or below the resolution of
/// `t`). `inc_finite`: whether the step's increments are finite; when they are and `h` has not
/// collapsed, the coefficients are not scanned. The single step and the batch step both ask.
pub(crate) fn refused_step<S: TaylorSystem + ?Sized>(
    sys: &S,
    (t, y): (f64, &[f64]),
    p: usize,
    h: f64,
    inc_finite: bool,
    first_non_finite: impl FnOnce() -> Option<usize>,
) -> Option<StepFailure> {
    let collapsed = h.is_nan() || h.abs() <= 16.0 * f64::EPSILON * t.abs() || h == 0.0;
    if !collapsed && inc_finite {
        return None;
    }
    match first_non_finite() {
        Some(at) => Some(sys.non_finite(t, y, p, at)),
        None => collapsed.then_some(StepFailure(FailureReason::StepSizeCollapse { h })),
    }
}

/// Whether `log2(a) · ia < log2(b) · ib` (`Some(true)`), `>` (`Some(false)`), or `None` when
/// the brackets below cannot tell (values within about `0.09 · max(ia, ib)` of each other in
/// `log2`, or `a`, `b` not positive normal numbers). For `x = 2^e · m`, `1 ≤ m < 2`,
/// `log2 x = e + log2 m` lies in `[e + m − 1, e + m − 1 + 0.0861]` (`log2 m − (m − 1)` is
/// concave, zero at `m = 1` and `m = 2`, largest at `m = 1/ln 2`); `0.09` leaves room for the
/// rounding of the products. Both `ia`, `ib` are positive (the reciprocals of orders).
///
/// The step size takes the smaller of two roots `2^{log2(s/‖y_[m]‖)/m}`; two `log2` calls
/// and an `exp2` were a tenth of a double-pendulum step at tol 1e-6 (BENCHMARKS.md).
#[inline]
#[doc(hidden)]
pub fn smaller_root(a: f64, ia: f64, b: f64, ib: f64) -> Option<bool> {
    const SLACK: f64 = 0.09;
    let lower = |x: f64| {
        let bits = x.to_bits();
        let e = (bits >> 52) as i64 - 1023;
        let m = f64::from_bits((bits & ((1 << 52) - 1)) | 1.0f64.to_bits());
        e as f64 + (m - 1.0)
    };
    if !(a.is_normal() && a > 0.0 && b.is_normal() && b > 0.0) {
        return None;
    }
    let (la, lb) = (lower(a), lower(b));
    if (la + SLACK) * ia < lb * ib {
        Some(true)
    } else if (lb + SLACK) * ib < la * ia {
        Some(false)
    } else {
        None
    }
}

/// What the step size needs of the order `p`, computed once per run.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StepConstants {
    /// `log₂` of Jorba & Zou's safety factor `exp(−2 − 0.7/(p − 1))` of the step size.
    safety_log2: f64,
    /// `1/(p − 1)` and `1/p`, the roots of the step size (multiplications, off the step's
    /// chain of dependent operations, where divisions were on it).
    inv_orders: [f64; 2],
}

impl StepConstants {
    pub(crate) fn new(p: usize) -> Self {
        StepConstants {
            safety_log2: (-2.0 - 0.7 / (p - 1) as f64) * std::f64::consts::LOG2_E,
            inv_orders: [1.0 / (p - 1) as f64, 1.0 / p as f64],
        }
    }
}

/// Scratch storage of a [`Taylor`] integration.
pub struct TaylorWork {
    order: usize,
    /// The system's buffer: the state's coefficients first (`i · (order + 1) + k`), then its
    /// scratch.
    buf: Vec<f64>,
    comp: Vec<f64>,
    inc: Vec<f64>,
    /// The last step's size; its polynomial is the state's rows of `buf` (dense output).
    h_last: f64,
    dense_ready: bool,
    constants: StepConstants,
    /// The system that last wrote `buf` (its address), which may then skip what it writes
    /// identically every time ([`TaylorSystem::taylor_coefficients_again`]).
    written_by: Option<usize>,
}

impl TaylorWork {
    /// The order of the expansions.
    pub fn order(&self) -> usize {
        self.order
    }

    /// The normalised Taylor coefficients of the last step (`i · (order + 1) + k`), expanded
    /// at its start.
    pub fn coefficients(&self) -> &[f64] {
        &self.buf[..self.comp.len() * (self.order + 1)]
    }

    /// The signed size of the last step.
    pub fn last_step(&self) -> f64 {
        self.h_last
    }

    /// Component `i` of the last step's dense output at the fraction `theta` of the step
    /// (`None` when there is no step to interpolate), the same bits as that component of
    /// [`super::Solver::interpolate`] at `t_prev + theta · (t − t_prev)`. A driver that reads
    /// one component at many points of each step (the MEGNO quadrature reads the accumulator
    /// at five) then sums one polynomial per point instead of one per component.
    pub fn dense_component(&self, i: usize, theta: f64) -> Option<f64> {
        (self.dense_ready && i < self.comp.len()).then(|| self.series_at(i, theta * self.h_last))
    }

    /// Component `i` of the last step's series at `x = θ h`: the one sum that dense output
    /// and [`TaylorWork::dense_component`] both read.
    fn series_at(&self, i: usize, x: f64) -> f64 {
        let s = self.order + 1;
        polynomial(&self.buf[i * s..(i + 1) * s], x, 0)
    }
}

/// `Σ_k c_k x^(k − lo)`, `k = lo..c.len()`. Horner's rule is one chain of `p` dependent
/// multiply-adds, whose latency was a tenth of a Kepler step. Here only the first
/// [`HORNER_TERMS`] coefficients are added by Horner's rule, which carries their large terms
/// with its small rounding error; the tail, whose terms are smaller by the series' decay
/// (about `e⁻²` an order at Jorba and Zou's step), is Horner's rule in `x⁴` over blocks
/// `(c₀ + c₁x) + (c₂ + c₃x)·x²` (a step of Estrin's scheme), whose blocks are independent. The
/// chain is about half as long, for the same work. Kepler e = 0.9 over 1000 orbits (tol 1e-15):
/// 37.4 → 36.6 ms in the Taylor bench, within its noise (36.8 → 32.8 ms in a program running
/// that case alone), with the energy error unchanged, 2.03e-13; blocks all the way down
/// doubled it (4.8e-13), the large terms then being added first.
///
/// The loops index from the end with the lengths known up front (a partial block is only
/// ever the last one), so that the code has no iterator adaptors or slice patterns to test
/// per block. With the update around them, the four polynomials of a double-pendulum step at
/// order 11 are the step's own 549 instructions (571 before), against 3,022 in the
/// expansion (BENCHMARKS.md).
#[inline(always)]
#[doc(hidden)]
pub fn polynomial<L: Lane>(c: &[L], x: L, lo: usize) -> L {
    let c = &c[lo.min(c.len())..];
    let (head, tail) = c.split_at(c.len().min(HORNER_TERMS));
    let x2 = x * x;
    let x4 = x2 * x2;
    let full = tail.len() / 4;
    let (blocks, last) = tail.split_at(4 * full);
    let block = |b: &[L; 4]| (b[0] + b[1] * x) + (b[2] + b[3] * x) * x2;
    let (mut acc, below) = match *last {
        [c0, c1, c2] => ((c0 + c1 * x) + c2 * x2, full),
        [c0, c1] => (c0 + c1 * x, full),
        [c0] => (c0, full),
        _ if full > 0 => (block(blocks[4 * (full - 1)..4 * full].try_into().expect("a block of 4")), full - 1),
        _ => (L::splat(0.0), 0),
    };
    for j in (0..below).rev() {
        acc = acc * x4 + block(blocks[4 * j..4 * j + 4].try_into().expect("a block of 4"));
    }
    for &ck in head.iter().rev() {
        acc = acc * x + ck;
    }
    acc
}

/// The leading coefficients [`polynomial`] adds by Horner's rule.
#[doc(hidden)]
pub const HORNER_TERMS: usize = 6;
impl<S: TaylorSystem + ?Sized> Method<S> for Taylor {
    type Work = TaylorWork;

    fn info(&self) -> MethodInfo {
        Taylor::info(self)
    }

    fn dim(&self, sys: &S) -> usize {
        sys.dim()
    }

    fn work(&self, sys: &S) -> TaylorWork {
        let n = sys.dim();
        let p = self.taylor_order().clamp(2, 100);
        TaylorWork {
            order: p,
            buf: vec![0.0; sys.scratch_len(p).max(n * (p + 1))],
            comp: vec![0.0; n],
            inc: vec![0.0; n],
            h_last: 0.0,
            dense_ready: false,
            constants: StepConstants::new(p),
            written_by: None,
        }
    }

    fn fixed_step(&self) -> Option<f64> {
        None
    }

    /// The tolerances and order, once before the first step ([`super::Solver::new`]).
    fn check(&self) -> Result<(), String> {
        self.validate()
    }

    fn step(&self, sys: &S, w: &mut TaylorWork, t: f64, y: &mut [f64], h_req: f64) -> Result<f64, StepFailure> {
        let p = w.order;
        let s = p + 1;
        let n = y.len();
        w.dense_ready = false;
        // A `TaylorWork` is made for one system, but `step` takes the system each time.
        let this = sys as *const S as *const () as usize;
        if w.written_by == Some(this) {
            sys.taylor_coefficients_again(t, y, p, &mut w.buf)?;
        } else {
            w.written_by = None;
            sys.taylor_coefficients(t, y, p, &mut w.buf)?;
            w.written_by = Some(this);
        }
        let coeffs = &w.buf[..n * s];
        let dir = h_req.signum();
        let mut h = self.step_size(y, w);
        if let Some(m) = self.h_max {
            h = h.min(m);
        }
        let h = if h >= h_req.abs() { h_req } else { dir * h };
        for (inc, row) in w.inc.iter_mut().zip(coeffs.chunks_exact(s)) {
            *inc = h * polynomial(row, h, 1);
        }
        let finite = w.inc.iter().all(|v| v.is_finite());
        if let Some(failure) = refused_step(sys, (t, y), p, h, finite, || coeffs.iter().position(|x| !x.is_finite())) {
            return Err(failure);
        }
        sys.check_step(&w.buf, p, h)?;
        add_scaled(y, self.compensated.then_some(&mut w.comp[..]), 1.0, &w.inc);
        w.h_last = h;
        w.dense_ready = true;
        Ok(h)
    }

    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure> {
        let n = sys.dim();
        let mut buf = vec![0.0; sys.scratch_len(1).max(2 * n)];
        sys.taylor_coefficients(t, y, 1, &mut buf)?;
        if let Some(at) = buf[..2 * n].iter().position(|x| !x.is_finite()) {
            return Err(sys.non_finite(t, y, 1, at));
        }
        for i in 0..n {
            dy[i] = buf[2 * i + 1];
        }
        Ok(())
    }

    fn dense(&self, _sys: &S, w: &mut TaylorWork, theta: f64, out: &mut [f64]) -> Result<bool, StepFailure> {
        if !w.dense_ready {
            return Ok(false);
        }
        let x = theta * w.h_last;
        for (i, o) in out.iter_mut().enumerate() {
            *o = w.series_at(i, x);
        }
        Ok(true)
    }

    fn reset(&self, w: &mut TaylorWork) {
        w.comp.fill(0.0);
        w.dense_ready = false;
    }
}
