//! Adaptive Dormand–Prince 8(5,3) with Hairer's error estimator, step-size control and
//! 7th-order dense output (the algorithm of `dop853.f`; coefficients in
//! [`super::coefficients::dop853`]).

use super::coefficients::dop853::{A, BHH, C, D, ER};
use super::error::{check_finite, FailureReason, StepFailure};
use super::{add_scaled, Method, MethodInfo, Rhs};

/// DOP853 with relative and absolute tolerances (per component:
/// `|err_i| ≲ atol + rtol · max(|y_i|, |y_new,i|)`).
#[derive(Debug, Clone, PartialEq)]
pub struct Dop853 {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance.
    pub atol: f64,
    /// Largest step size allowed (default: the whole span).
    pub h_max: Option<f64>,
    /// Initial step size (default: Hairer's estimate).
    pub h0: Option<f64>,
    /// Kahan-compensated summation of the state update (the stages still see `y_{n+1}`
    /// rounded once; only the accumulated state keeps the lost low-order bits).
    pub compensated: bool,
}

impl Dop853 {
    /// The smallest relative tolerance DOP853 accepts: ten units of rounding, the floor of
    /// Hairer's `dop853.f` (it stops with "tolerances are too small" when `rtol ≤ 10·uround`).
    /// Below it the error
    /// estimate is rounding noise, steps shrink until they are accepted by chance, and a run
    /// of unit length takes ~10⁹ steps: the reported "hang". Smaller values are refused
    /// (not raised silently), so what was asked is never quietly changed.
    pub const MIN_RTOL: f64 = 10.0 * f64::EPSILON;

    /// DOP853 with the given tolerances.
    pub fn new(rtol: f64, atol: f64) -> Self {
        Dop853 { rtol, atol, h_max: None, h0: None, compensated: false }
    }
    /// Uses compensated summation for the state update.
    pub fn compensated(mut self) -> Self {
        self.compensated = true;
        self
    }
    /// Name, order and properties.
    pub fn info(&self) -> MethodInfo {
        MethodInfo { name: "DOP853", order: 8, symplectic: false, symmetric: false, adaptive: true }
    }
    /// Caps the step size.
    pub fn with_h_max(mut self, h: f64) -> Self {
        self.h_max = Some(h);
        self
    }
    /// Sets the first step size.
    pub fn with_h0(mut self, h: f64) -> Self {
        self.h0 = Some(h);
        self
    }
}

/// Scratch storage of a [`Dop853`] integration.
pub struct Dop853Work {
    k: Vec<Vec<f64>>,
    stage: Vec<f64>,
    y_new: Vec<f64>,
    y_old: Vec<f64>,
    err5: Vec<f64>,
    err3: Vec<f64>,
    inc: Vec<f64>,
    comp: Vec<f64>,
    rcont: Vec<Vec<f64>>,
    /// `k[0]` holds `f(t, y)` of the current state (after an accepted step it is still in
    /// `k[12]` until the next step starts).
    fsal: Fsal,
    h: f64,
    facold: f64,
    reject: bool,
    rejected: usize,
    t_old: f64,
    h_last: f64,
    dense_ready: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fsal {
    None,
    InK0,
    InK12,
}

const SAFE: f64 = 0.9;
const FAC_MIN: f64 = 0.333; // the step shrinks by at most 1/0.333 ...
const FAC_MAX: f64 = 6.0; // ... and grows by at most 6 per step (Hairer's fac1, fac2)

impl Dop853 {
    fn scale(&self, y: f64, y_new: f64) -> f64 {
        self.atol + self.rtol * y.abs().max(y_new.abs())
    }

    /// Hairer's initial step estimate (`hinit` in `dop853.f`).
    fn initial_step<S: Rhs + ?Sized>(
        &self,
        sys: &S,
        w: &mut Dop853Work,
        t: f64,
        y: &[f64],
        h_max: f64,
        dir: f64,
    ) -> Result<f64, StepFailure> {
        let n = y.len();
        let (mut dnf, mut dny) = (0.0, 0.0);
        for i in 0..n {
            let sk = self.scale(y[i], y[i]);
            dnf += (w.k[0][i] / sk).powi(2);
            dny += (y[i] / sk).powi(2);
        }
        let mut h = if dnf <= 1e-10 || dny <= 1e-10 { 1e-6 } else { (dny / dnf).sqrt() * 0.01 };
        h = h.min(h_max);
        for i in 0..n {
            w.stage[i] = y[i] + dir * h * w.k[0][i];
        }
        sys.try_eval(t + dir * h, &w.stage, &mut w.k[1])?;
        let mut der2: f64 = 0.0;
        for i in 0..n {
            let sk = self.scale(y[i], y[i]);
            der2 += ((w.k[1][i] - w.k[0][i]) / sk).powi(2);
        }
        let der2 = der2.sqrt() / h;
        let der12 = der2.abs().max(dnf.sqrt());
        let h1 = if der12 <= 1e-15 { (h * 1e-3).max(1e-6) } else { (0.01 / der12).powf(1.0 / 8.0) };
        let h = (100.0 * h).min(h1).min(h_max);
        Ok(if h.is_finite() && h > 0.0 { h } else { 1e-6f64.min(h_max) })
    }
}

impl<S: Rhs + ?Sized> Method<S> for Dop853 {
    type Work = Dop853Work;

    fn info(&self) -> MethodInfo {
        Dop853::info(self)
    }

    fn dim(&self, sys: &S) -> usize {
        sys.dim()
    }

    fn work(&self, sys: &S) -> Dop853Work {
        let n = sys.dim();
        Dop853Work {
            k: vec![vec![0.0; n]; 16],
            stage: vec![0.0; n],
            y_new: vec![0.0; n],
            y_old: vec![0.0; n],
            err5: vec![0.0; n],
            err3: vec![0.0; n],
            inc: vec![0.0; n],
            comp: vec![0.0; n],
            rcont: vec![vec![0.0; n]; 8],
            fsal: Fsal::None,
            h: 0.0,
            facold: 1e-4,
            reject: false,
            rejected: 0,
            t_old: 0.0,
            h_last: 0.0,
            dense_ready: false,
        }
    }

    fn fixed_step(&self) -> Option<f64> {
        None
    }

    fn check(&self) -> Result<(), String> {
        // `atol > 0` as in `dop853.f`: with `atol = 0` a component passing through zero has a
        // zero error scale, and 0/0 makes every trial step fail.
        if !(self.rtol.is_finite() && self.atol.is_finite() && self.atol > 0.0) {
            return Err(format!(
                "tolerances must be finite, with atol positive; found rtol = {}, atol = {}",
                self.rtol, self.atol
            ));
        }
        if self.rtol < Self::MIN_RTOL {
            return Err(format!(
                "relative tolerance {:e} is below what f64 arithmetic can meet; the smallest usable value is {:e}",
                self.rtol,
                Self::MIN_RTOL
            ));
        }
        for (what, h) in [("h_max", self.h_max), ("h0", self.h0)] {
            if let Some(h) = h {
                if !(h.is_finite() && h > 0.0) {
                    return Err(format!("{what} = {h} must be positive and finite"));
                }
            }
        }
        Ok(())
    }

    fn step(&self, sys: &S, w: &mut Dop853Work, t: f64, y: &mut [f64], h_req: f64) -> Result<f64, StepFailure> {
        let n = y.len();
        let dir = h_req.signum();
        let h_max = self.h_max.map_or(h_req.abs(), |m| m.abs().min(h_req.abs()));
        match w.fsal {
            Fsal::InK0 => {}
            Fsal::InK12 => w.k.swap(0, 12),
            Fsal::None => {
                sys.try_eval(t, y, &mut w.k[0])?;
                check_finite(&w.k[0])?;
            }
        }
        w.fsal = Fsal::InK0;
        w.dense_ready = false;
        if w.h == 0.0 {
            w.h = match self.h0 {
                Some(h0) => h0.abs(),
                None => self.initial_step(sys, w, t, y, h_max, dir)?,
            };
        }
        // A right-hand side that fails at a trial stage (the stage left its domain) makes the
        // step shrink like an error-test failure; it is reported only if the step collapses.
        let mut stage_failure = None;
        'trial: loop {
            let h = dir * w.h.abs().min(h_max);
            if h.abs() <= 16.0 * f64::EPSILON * t.abs().max(f64::MIN_POSITIVE) || h == 0.0 {
                return Err(match stage_failure {
                    Some(e) => StepFailure(FailureReason::Rhs(e)),
                    None => StepFailure(FailureReason::StepSizeCollapse { h }),
                });
            }
            for i in 1..12 {
                w.stage.copy_from_slice(y);
                for &(j, a) in A[i] {
                    for (st, kj) in w.stage.iter_mut().zip(&w.k[j]) {
                        *st += h * a * kj;
                    }
                }
                if let Err(e) = sys.try_eval(t + C[i] * h, &w.stage, &mut w.k[i]) {
                    stage_failure = Some(e);
                    w.h = h.abs() * 0.1;
                    w.reject = true;
                    w.rejected += 1;
                    continue 'trial;
                }
            }
            // inc = Σ b_j k_j, y_new = y + h inc.
            w.inc.fill(0.0);
            for &(j, b) in A[12] {
                for (e, kj) in w.inc.iter_mut().zip(&w.k[j]) {
                    *e += b * kj;
                }
            }
            for i in 0..n {
                w.y_new[i] = y[i] + h * w.inc[i];
            }
            w.err3.copy_from_slice(&w.inc);
            for &(j, b) in &BHH {
                for (e, kj) in w.err3.iter_mut().zip(&w.k[j]) {
                    *e -= b * kj;
                }
            }
            w.err5.fill(0.0);
            for &(j, e) in &ER {
                for (er, kj) in w.err5.iter_mut().zip(&w.k[j]) {
                    *er += e * kj;
                }
            }
            let (mut e5, mut e3) = (0.0, 0.0);
            for i in 0..n {
                let sk = self.scale(y[i], w.y_new[i]);
                e5 += (w.err5[i] / sk).powi(2);
                e3 += (w.err3[i] / sk).powi(2);
            }
            let mut deno = e5 + 0.01 * e3;
            if deno <= 0.0 {
                deno = 1.0;
            }
            let err = h.abs() * e5 * (1.0 / (n as f64 * deno)).sqrt();
            if !err.is_finite() {
                // Overflow or NaN inside the stages: retry with a much smaller step.
                w.h = h.abs() * 0.1;
                w.reject = true;
                w.rejected += 1;
                continue;
            }
            let fac11 = err.powf(1.0 / 8.0);
            let fac = (fac11 / SAFE).clamp(1.0 / FAC_MAX, 1.0 / FAC_MIN);
            let mut h_new = h.abs() / fac;
            if err <= 1.0 {
                w.facold = err.max(1e-4);
                if let Err(e) = sys.try_eval(t + h, &w.y_new, &mut w.k[12]) {
                    stage_failure = Some(e);
                    w.h = h.abs() * 0.1;
                    w.reject = true;
                    w.rejected += 1;
                    continue;
                }
                check_finite(&w.y_new)?;
                check_finite(&w.k[12])?;
                if w.reject {
                    h_new = h_new.min(h.abs());
                }
                w.reject = false;
                w.y_old.copy_from_slice(y);
                if self.compensated {
                    add_scaled(y, Some(&mut w.comp), h, &w.inc);
                    w.y_new.copy_from_slice(y);
                } else {
                    y.copy_from_slice(&w.y_new);
                }
                w.t_old = t;
                w.h_last = h;
                w.fsal = Fsal::InK12;
                // Keep the proposal when this step was cut short to land on the stop time.
                if h.abs() < w.h.abs() && h.abs() == h_max {
                    h_new = h_new.max(w.h.abs());
                }
                w.h = h_new;
                return Ok(h);
            }
            w.h = h.abs() / (1.0 / FAC_MIN).min(fac11 / SAFE);
            w.reject = true;
            w.rejected += 1;
        }
    }

    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure> {
        Ok(sys.try_eval(t, y, dy)?)
    }

    fn dense(&self, sys: &S, w: &mut Dop853Work, theta: f64, out: &mut [f64]) -> Result<bool, StepFailure> {
        if w.fsal != Fsal::InK12 {
            return Ok(false);
        }
        let h = w.h_last;
        let n = out.len();
        if !w.dense_ready {
            // The three extra stages of the dense output (evaluated only when asked for).
            for i in 13..16 {
                w.stage.copy_from_slice(&w.y_old);
                for &(j, a) in A[i] {
                    for (st, kj) in w.stage.iter_mut().zip(&w.k[j]) {
                        *st += h * a * kj;
                    }
                }
                sys.try_eval(w.t_old + C[i] * h, &w.stage, &mut w.k[i])?;
            }
            for i in 0..n {
                let ydiff = w.y_new[i] - w.y_old[i];
                let bspl = h * w.k[0][i] - ydiff;
                w.rcont[0][i] = w.y_old[i];
                w.rcont[1][i] = ydiff;
                w.rcont[2][i] = bspl;
                w.rcont[3][i] = ydiff - h * w.k[12][i] - bspl;
                for (r, d) in D.iter().enumerate() {
                    let mut acc = 0.0;
                    for (j, dj) in d.iter().enumerate() {
                        if *dj != 0.0 {
                            acc += dj * w.k[j][i];
                        }
                    }
                    w.rcont[4 + r][i] = h * acc;
                }
            }
            w.dense_ready = true;
        }
        let s = theta;
        let s1 = 1.0 - s;
        for (i, o) in out.iter_mut().enumerate() {
            let r = |m: usize| w.rcont[m][i];
            let conpar = r(4) + s * (r(5) + s1 * (r(6) + s * r(7)));
            *o = r(0) + s * (r(1) + s1 * (r(2) + s * (r(3) + s1 * conpar)));
        }
        Ok(true)
    }

    fn reset(&self, w: &mut Dop853Work) {
        w.comp.fill(0.0);
        w.fsal = Fsal::None;
        w.dense_ready = false;
    }

    fn rejected(&self, w: &Dop853Work) -> usize {
        w.rejected
    }
}
