//! Honest long runs in scenes: which energy a run conserves (if any), its compiled tape for
//! the backend's per-step ledger ([`crate::integrate::drift`]), the drift in the run summary,
//! and the warning — or, under `--strict`, the error — when it exceeds the threshold.
//!
//! The conserved energy is `H` for runs that integrate Hamilton's equations (or a drift/kick
//! split of `H`), and the energy function `h = Σ q' ∂L/∂q' − L` for runs of `W q'' = F`,
//! provided the function has no explicit `t` (PHYSICS.md (2.7)): then `dH/dt = ∂H/∂t = 0`.
//! Runs with forces, dissipation or constraints, first-order Lagrangians and explicitly
//! time-dependent systems are not checked, and their summary says why.

use std::sync::Arc;

use crate::cache::Value;
use crate::compile::Tape;
use crate::expr::{Expr, Symbol};
use crate::print::fmt_num;
use crate::scene::engine::backend::{Formulation, Trajectory};
use crate::scene::state::{At, Layout, Session};
use crate::scene::syntax::ast::{DerivKind, SimSpec};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};

fn has_t(e: &Expr) -> bool {
    e.free_symbols().iter().any(Symbol::is_time)
}
use crate::integrate::drift::DriftReport;
pub use crate::simulate::{EnergyCheck, Ledger};

/// The energy a run is checked against (`H` or `h`, and its check), or why none is.
pub type EnergyChoice = Result<(&'static str, EnergyCheck), String>;

/// Which energy a prepared run checks (`H` or `h`), or why it checks none.
pub type EnergyPlan = Result<&'static str, String>;

/// How a drift or jump is written: relative `|ΔH/H₀|` or absolute `|ΔH|` when `H₀ = 0`.
fn measure(symbol: &str, r: &DriftReport) -> String {
    if r.relative {
        format!("|Δ{symbol}/{symbol}₀|")
    } else {
        format!("|Δ{symbol}| ({symbol}₀ = 0)")
    }
}

/// The summary's clause, e.g. `; energy drift max |ΔH/H₀| = 2.1e-9`.
pub fn summary_clause(ledger: &Ledger) -> String {
    match ledger {
        Ledger::Unchecked => String::new(),
        Ledger::Skipped(why) => format!("; energy not checked ({why})"),
        Ledger::Checked { symbol, report } if !report.e0.is_finite() => {
            format!("; energy not checked ({symbol}₀ = {} at the start: no change can be measured from it)", report.e0)
        }
        Ledger::Checked { symbol, report } => {
            format!("; energy drift max {} = {:.1e}", measure(symbol, report), report.max.change)
        }
    }
}

impl Session {
    /// The energy check of a run, or why there is none. `l`/`h` are the run's Lagrangian or
    /// Hamiltonian; `names` the state's input names in order.
    pub(in crate::scene) fn energy_check(
        &mut self,
        at: At,
        spec: &SimSpec,
        formulation: &Formulation,
        names: &[String],
        params: &[(String, f64)],
    ) -> Result<EnergyChoice, SceneError> {
        let threshold = match &spec.drift {
            Some(src) => {
                let e = self.resolved(at, src)?;
                let x = self.number(&e, src.span)?;
                if !(x > 0.0 && x.is_finite()) {
                    return Err(SceneError::new(
                        ErrorKind::BadNumber,
                        format!("the drift threshold must be positive and finite, found {x}"),
                    )
                    .at(src.span)
                    .hint("write `drift = 1e-6` (a relative change of the energy)"));
                }
                x
            }
            None => self.opts.drift_threshold,
        };
        let (symbol, energy) = match formulation {
            Formulation::Extended(_) => {
                return Ok(Err("forces, dissipation or constraints: no conserved energy".into()))
            }
            Formulation::FirstOrder(_) => return Ok(Err("first-order Lagrangian: not implemented".into())),
            // Scenes pass L, never its derived equations.
            Formulation::Equations { .. } => return Ok(Err("no Lagrangian to take the energy of".into())),
            Formulation::Separable { t: kinetic, v } => ("H", kinetic.plus(v)),
            Formulation::Hamiltonian(h) => ("H", h.clone()),
            // The map's state is (q, p) with the discrete momenta, which approach ∂L/∂q' at
            // the method's order: the Legendre transform's H measures its energy error.
            Formulation::Variational(l) => {
                if has_t(l) {
                    return Ok(Err("L depends on t explicitly: H is not conserved".into()));
                }
                match self.derive(at, DerivKind::Legendre, vec![l.clone()], at.span)? {
                    Value::Expr(e) => ("H", e),
                    _ => return Ok(Err("no Hamiltonian".into())),
                }
            }
            Formulation::Lagrangian(l) => {
                if has_t(l) {
                    return Ok(Err("L depends on t explicitly: h is not conserved".into()));
                }
                match self.derive(at, DerivKind::Energy, vec![l.clone()], at.span)? {
                    Value::Expr(e) => ("h", e),
                    _ => return Ok(Err("no energy function".into())),
                }
            }
        };
        if has_t(&energy) {
            return Ok(Err(format!("{symbol} depends on t explicitly: it is not conserved")));
        }
        let mut inputs: Vec<&str> = names.iter().map(String::as_str).collect();
        inputs.push("t");
        let params: Vec<(&str, f64)> = params.iter().map(|(n, v)| (n.as_str(), *v)).collect();
        Ok(match Tape::compile(&[energy], &inputs, &params) {
            Ok(tape) => Ok((symbol, EnergyCheck { tape: Arc::new(tape), threshold })),
            Err(e) => Err(format!("the energy does not compile: {e}")),
        })
    }

    /// Names the ledger the backend filled for `traj` after the plan, then judges it.
    pub(in crate::scene) fn settle_energy(
        &mut self,
        name: &str,
        plan: &EnergyPlan,
        traj: &mut Trajectory,
        span: Span,
    ) -> Result<(), SceneError> {
        traj.energy = match (plan, std::mem::take(&mut traj.energy)) {
            (Ok(symbol), Ledger::Checked { report, .. }) => Ledger::Checked { symbol, report },
            (Err(why), _) => Ledger::Skipped(why.clone()),
            (Ok(_), other) => other,
        };
        self.judge_drift(name, traj, span)
    }

    /// Reports a run whose energy drifted or jumped beyond its threshold: a warning for
    /// standard error naming the run and the time, or under `--strict` an error.
    pub(in crate::scene) fn judge_drift(
        &mut self,
        name: &str,
        traj: &Trajectory,
        span: Span,
    ) -> Result<(), SceneError> {
        let Ledger::Checked { symbol, report } = &traj.energy else { return Ok(()) };
        // An energy that is infinite or NaN at the start measures nothing: say so, once.
        if !report.e0.is_finite() {
            self.warnings.push(format!(
                "warning: {name}: the energy {symbol} is {} at the start, so its drift cannot be checked",
                report.e0
            ));
            return Ok(());
        }
        if !report.exceeded() {
            return Ok(());
        }
        let m = measure(symbol, report);
        let mut msg = match report.first_exceeded {
            Some(e) => format!(
                "{name}: the energy {symbol} drifted beyond the threshold {:.0e} at t = {} (step {}); max {m} = {:.1e} at t = {}",
                report.threshold,
                fmt_num(e.t),
                e.step,
                report.max.change,
                fmt_num(report.max.t)
            ),
            None => format!("{name}: the energy {symbol} jumped in one step although its drift stayed below the threshold {:.0e}", report.threshold),
        };
        if let Some(j) = report.first_jump {
            if j.change.is_finite() {
                msg.push_str(&format!(
                    "; the first jump above the threshold was step {} ending at t = {} ({m} changed by {:.1e} in one step)",
                    j.step,
                    fmt_num(j.t),
                    j.change
                ));
            } else {
                msg.push_str(&format!(
                    "; the energy became non-finite at step {} ending at t = {}",
                    j.step,
                    fmt_num(j.t)
                ));
            }
        }
        let hint = "a smaller `dt`, an adaptive method (`with dop853 tol = 1e-12`), or `drift = …` to accept more";
        if self.opts.strict {
            return Err(SceneError::new(ErrorKind::Numeric, msg).at(span).label("this run").hint(hint));
        }
        self.warnings.push(format!("warning: {msg} ({hint})"));
        Ok(())
    }
}

/// The state's plain input names for a layout (`x`, `x'` or `p_x`), as the backend compiles them.
pub(in crate::scene) fn input_names(coords: &[Symbol], layout: Layout) -> Vec<String> {
    let mut v: Vec<String> = coords.iter().map(|q| q.to_string()).collect();
    v.extend(coords.iter().map(|q| match layout {
        Layout::Velocities => format!("{q}'"),
        Layout::Momenta => format!("p_{q}"),
    }));
    v
}
