//! Splitting methods for separable Hamiltonians `H = T(p) + V(q, t)`: compositions of the
//! exact flows of `T` (the drift `q ← q + a h ∂T/∂p`) and of `V` (the kick
//! `p ← p − b h ∂V/∂q`). Each flow is a canonical map, so every composition is symplectic;
//! palindromic compositions are also symmetric (time-reversible).

use super::coefficients::{
    SplittingKind, SplittingScheme, BLANES_MOAN4, LEAPFROG, SYMPLECTIC_EULER, YOSHIDA4, YOSHIDA6, YOSHIDA8,
};
use super::error::StepFailure;
use super::{add_scaled, Method, MethodInfo, Separable};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Flow {
    Kick(f64),
    Drift(f64),
}

/// A splitting method with a fixed step size: a [`SplittingScheme`] (coefficient data) plus
/// the step and whether to use compensated summation.
#[derive(Debug, Clone, PartialEq)]
pub struct Splitting {
    scheme: &'static SplittingScheme,
    h: f64,
    compensated: bool,
    flows: Vec<Flow>,
}

impl Splitting {
    /// The scheme `scheme` with step `h`. Adjacent kicks of a Verlet composition are merged,
    /// so an `s`-stage composition costs `s` force evaluations per step (the last kick's force
    /// is reused by the first kick of the next step).
    pub fn new(scheme: &'static SplittingScheme, h: f64) -> Self {
        let mut flows: Vec<Flow> = Vec::new();
        let mut push = |f: Flow| match (flows.last_mut(), f) {
            (Some(Flow::Kick(b0)), Flow::Kick(b1)) => *b0 += b1,
            (Some(Flow::Drift(a0)), Flow::Drift(a1)) => *a0 += a1,
            _ => flows.push(f),
        };
        match scheme.kind {
            SplittingKind::VerletComposition { weights } => {
                for &w in weights {
                    push(Flow::Kick(0.5 * w));
                    push(Flow::Drift(w));
                    push(Flow::Kick(0.5 * w));
                }
            }
            SplittingKind::KickDrift { kicks, drifts } => {
                for (i, &b) in kicks.iter().enumerate() {
                    push(Flow::Kick(b));
                    if let Some(&a) = drifts.get(i) {
                        push(Flow::Drift(a));
                    }
                }
            }
        }
        Splitting { scheme, h, compensated: false, flows }
    }
    /// Symplectic Euler (order 1).
    pub fn symplectic_euler(h: f64) -> Self {
        Self::new(&SYMPLECTIC_EULER, h)
    }
    /// Störmer–Verlet / leapfrog (order 2).
    pub fn leapfrog(h: f64) -> Self {
        Self::new(&LEAPFROG, h)
    }
    /// Yoshida's triple jump (order 4).
    pub fn yoshida4(h: f64) -> Self {
        Self::new(&YOSHIDA4, h)
    }
    /// Yoshida's 7-stage composition (order 6).
    pub fn yoshida6(h: f64) -> Self {
        Self::new(&YOSHIDA6, h)
    }
    /// Yoshida's 15-stage composition (order 8).
    pub fn yoshida8(h: f64) -> Self {
        Self::new(&YOSHIDA8, h)
    }
    /// Blanes & Moan's optimised 4th-order splitting.
    pub fn blanes_moan4(h: f64) -> Self {
        Self::new(&BLANES_MOAN4, h)
    }
    /// Uses Kahan-compensated summation for the state updates.
    pub fn compensated(mut self) -> Self {
        self.compensated = true;
        self
    }
    /// Name, order and properties (every splitting is symplectic).
    pub fn info(&self) -> MethodInfo {
        MethodInfo {
            name: self.scheme.name,
            order: self.scheme.order,
            symplectic: true,
            symmetric: self.scheme.symmetric,
            adaptive: false,
        }
    }
    /// The coefficient data.
    pub fn scheme(&self) -> &'static SplittingScheme {
        self.scheme
    }
    /// Force evaluations per step (after merging adjacent kicks and reusing the last force).
    pub fn force_evaluations(&self) -> usize {
        let kicks = self.flows.iter().filter(|f| matches!(f, Flow::Kick(_))).count();
        match (self.flows.first(), self.flows.last()) {
            (Some(Flow::Kick(_)), Some(Flow::Kick(_))) => kicks - 1,
            _ => kicks,
        }
    }
}

/// Scratch storage of a [`Splitting`] integration.
pub struct SplittingWork {
    force: Vec<f64>,
    force_q: Vec<f64>,
    force_t: f64,
    force_valid: bool,
    velocity: Vec<f64>,
    comp: Vec<f64>,
}

impl<S: Separable + ?Sized> Method<S> for Splitting {
    type Work = SplittingWork;

    fn info(&self) -> MethodInfo {
        Splitting::info(self)
    }

    fn dim(&self, sys: &S) -> usize {
        2 * sys.dof()
    }

    fn work(&self, sys: &S) -> SplittingWork {
        let n = sys.dof();
        SplittingWork {
            force: vec![0.0; n],
            force_q: vec![0.0; n],
            force_t: f64::NAN,
            force_valid: false,
            velocity: vec![0.0; n],
            comp: vec![0.0; 2 * n],
        }
    }

    fn fixed_step(&self) -> Option<f64> {
        Some(self.h)
    }

    fn step(&self, sys: &S, w: &mut SplittingWork, t: f64, y: &mut [f64], h: f64) -> Result<f64, StepFailure> {
        let n = sys.dof();
        let (q, p) = y.split_at_mut(n);
        let (cq, cp) = w.comp.split_at_mut(n);
        let mut tau = t;
        for flow in &self.flows {
            match *flow {
                Flow::Kick(b) => {
                    let cached = w.force_valid && w.force_t == tau && w.force_q[..] == q[..];
                    if !cached {
                        sys.try_kick(tau, q, &mut w.force)?;
                        w.force_q.copy_from_slice(q);
                        w.force_t = tau;
                        w.force_valid = true;
                    }
                    add_scaled(p, self.compensated.then_some(&mut *cp), b * h, &w.force);
                }
                Flow::Drift(a) => {
                    sys.try_drift(p, &mut w.velocity)?;
                    add_scaled(q, self.compensated.then_some(&mut *cq), a * h, &w.velocity);
                    tau += a * h;
                }
            }
        }
        Ok(h)
    }

    fn rate(&self, sys: &S, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), StepFailure> {
        let n = sys.dof();
        let (dq, dp) = dy.split_at_mut(n);
        sys.try_drift(&y[n..], dq)?;
        sys.try_kick(t, &y[..n], dp)?;
        Ok(())
    }

    fn reset(&self, w: &mut SplittingWork) {
        w.force_valid = false;
        w.comp.fill(0.0);
    }
}
