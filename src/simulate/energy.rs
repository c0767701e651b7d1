//! The energy ledger of a run: a conserved energy compiled once, observed after every step
//! ([`crate::integrate::drift`]), and what it saw.

use std::sync::Arc;

use crate::compile::Tape;
use crate::integrate::drift::{DriftReport, EnergyMonitor};

/// The energy a run is checked against, compiled once per run.
#[derive(Clone, Debug)]
pub struct EnergyCheck {
    /// `energy(state…, t)`, inputs in the state's order then `t`.
    pub tape: Arc<Tape>,
    /// Relative drift above which the run is reported.
    pub threshold: f64,
}

impl EnergyCheck {
    /// A monitor evaluating the tape on `(y, t)`.
    pub fn monitor(&self) -> EnergyMonitor<impl FnMut(f64, &[f64]) -> f64 + '_> {
        let mut x = vec![0.0; self.tape.n_inputs()];
        let mut out = [0.0];
        let tape = &self.tape;
        EnergyMonitor::new(
            move |t: f64, y: &[f64]| {
                let n = x.len() - 1;
                x[..n].copy_from_slice(&y[..n]);
                x[n] = t;
                tape.eval(&x, &mut out);
                out[0]
            },
            self.threshold,
        )
    }
}

/// What a run's energy check saw.
#[derive(Clone, Debug, Default)]
pub enum Ledger {
    /// Not checked (no energy was given, or nothing to say).
    #[default]
    Unchecked,
    /// Not checked, with the reason a summary gives.
    Skipped(String),
    /// Checked: the energy's name (`H` or `h`, set by the front end) and what the monitor saw.
    Checked {
        /// `H` or `h`.
        symbol: &'static str,
        /// The ledger.
        report: DriftReport,
    },
}

impl Ledger {
    /// The ledger of a run that was given `check` and whose monitor reported `report`.
    pub(super) fn from_report(check: Option<&EnergyCheck>, report: Option<DriftReport>) -> Ledger {
        match (check, report) {
            (Some(_), Some(report)) => Ledger::Checked { symbol: "", report },
            _ => Ledger::Unchecked,
        }
    }
}
