//! Explicit Runge–Kutta methods with a fixed step, from a Butcher [`Tableau`].

use super::coefficients::Tableau;
use super::error::StepFailure;
use super::{add_scaled, Method, MethodInfo, Rhs};

/// An explicit Runge–Kutta method (strictly lower-triangular `A`) with fixed step `h`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExplicitRk {
    tableau: Tableau,
    h: f64,
    compensated: bool,
}

impl ExplicitRk {
    /// The method of `tableau` (whose `A` must be strictly lower triangular) with step `h`.
    pub fn new(tableau: Tableau, h: f64) -> Self {
        ExplicitRk { tableau, h, compensated: false }
    }
    /// Forward Euler (order 1), the teaching baseline.
    pub fn euler(h: f64) -> Self {
        Self::new(Tableau::euler(), h)
    }
    /// The classical Runge–Kutta method (order 4).
    pub fn rk4(h: f64) -> Self {
        Self::new(Tableau::rk4(), h)
    }
    /// Uses Kahan-compensated summation for the state update.
    pub fn compensated(mut self) -> Self {
        self.compensated = true;
        self
    }
    /// Name, order and properties.
    pub fn info(&self) -> MethodInfo {
        self.tableau.info()
    }
    /// The tableau.
    pub fn tableau(&self) -> &Tableau {
        &self.tableau
    }
}

/// Scratch storage of an [`ExplicitRk`] integration.
pub struct RkWork {
    k: Vec<Vec<f64>>,
    stage: Vec<f64>,
    inc: Vec<f64>,
    comp: Vec<f64>,
}

impl<S: Rhs + ?Sized> Method<S> for ExplicitRk {
    type Work = RkWork;

    fn info(&self) -> MethodInfo {
        ExplicitRk::info(self)
    }

    fn dim(&self, sys: &S) -> usize {
        sys.dim()
    }

    fn work(&self, sys: &S) -> RkWork {
        let n = sys.dim();
        RkWork {
            k: vec![vec![0.0; n]; self.tableau.stages],
            stage: vec![0.0; n],
            inc: vec![0.0; n],
            comp: vec![0.0; n],
        }
    }

    fn fixed_step(&self) -> Option<f64> {
        Some(self.h)
    }

    fn step(&self, sys: &S, w: &mut RkWork, t: f64, y: &mut [f64], h: f64) -> Result<f64, StepFailure> {
        let tab = &self.tableau;
        let s = tab.stages;
        for i in 0..s {
            w.stage.copy_from_slice(y);
            for j in 0..i {
                let a = tab.a(i, j);
                if a != 0.0 {
                    for (st, kj) in w.stage.iter_mut().zip(&w.k[j]) {
                        *st += h * a * kj;
                    }
                }
            }
            sys.try_eval(t + tab.c[i] * h, &w.stage, &mut w.k[i])?;
        }
        w.inc.fill(0.0);
        for (i, ki) in w.k.iter().enumerate() {
            let b = tab.b[i];
            for (d, kv) in w.inc.iter_mut().zip(ki) {
                *d += b * kv;
            }
        }
        add_scaled(y, self.compensated.then_some(&mut w.comp[..]), h, &w.inc);
        Ok(h)
    }

    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure> {
        Ok(sys.try_eval(t, y, dy)?)
    }

    fn reset(&self, w: &mut RkWork) {
        w.comp.fill(0.0);
    }
}
