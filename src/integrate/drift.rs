//! The energy ledger of a run: the conserved energy (`H`, or the energy function `h` of a
//! Lagrangian without explicit time) evaluated after every accepted step, so that a run that
//! went wrong — a fixed step jumping through a collision, a tolerance too loose for a long
//! run — says so instead of returning confident wrong numbers.
//!
//! Why every step and not the kept states: a thinned run keeps one state in thousands, and a
//! jump through a singularity can happen (and partly undo itself) between two of them. The
//! energy is one compiled tape call per step, small next to the step itself (which evaluates
//! the right-hand side at least once, and usually 4–13 times).
//!
//! What is recorded (all relative to `|E₀|`, or absolute when `E₀ = 0`):
//! * the largest drift `max |E_k − E₀|` and the time where it occurred;
//! * the first step where the drift exceeded the threshold (the warning names its time);
//! * the first step whose own energy change `|E_k − E_{k−1}|` exceeded the threshold, or
//!   whose energy is not finite: the signature of a fixed step crossing a singularity.

/// The default threshold on the relative energy drift: 10⁻³.
pub const DEFAULT_THRESHOLD: f64 = 1e-3;

/// One step where something happened: its number (1 = the first step), time and the
/// relative change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriftEvent {
    /// Accepted step number (1-based).
    pub step: usize,
    /// Time at the end of that step.
    pub t: f64,
    /// The relative (or absolute, see [`DriftReport::relative`]) change; infinite when the
    /// energy was not finite.
    pub change: f64,
}

/// What an [`EnergyMonitor`] saw over a run.
#[derive(Clone, Debug, PartialEq)]
pub struct DriftReport {
    /// The energy at the initial state.
    pub e0: f64,
    /// Whether the changes are relative to `|E₀|` (`false` when `E₀ = 0`: absolute).
    pub relative: bool,
    /// The threshold the run was checked against.
    pub threshold: f64,
    /// The largest drift `|E − E₀|` (relative when [`DriftReport::relative`]) and where.
    pub max: DriftEvent,
    /// The drift at the last step.
    pub last: f64,
    /// The first step where the drift exceeded the threshold.
    pub first_exceeded: Option<DriftEvent>,
    /// The first step whose own energy change exceeded the threshold (or was not finite).
    pub first_jump: Option<DriftEvent>,
    /// Steps observed.
    pub steps: usize,
}

impl DriftReport {
    /// Whether the run should be reported: its drift exceeded the threshold or one step
    /// jumped by more than it.
    pub fn exceeded(&self) -> bool {
        self.first_exceeded.is_some() || self.first_jump.is_some()
    }
}

/// Watches the energy along a run; feed it every accepted `(t, y)` with
/// [`EnergyMonitor::observe`], the initial state first.
pub struct EnergyMonitor<F> {
    energy: F,
    threshold: f64,
    e0: f64,
    scale: f64,
    prev: f64,
    seen: usize,
    max: DriftEvent,
    last: f64,
    first_exceeded: Option<DriftEvent>,
    first_jump: Option<DriftEvent>,
}

impl<F: FnMut(f64, &[f64]) -> f64> EnergyMonitor<F> {
    /// A monitor of `energy(t, y)` against a relative `threshold`.
    pub fn new(energy: F, threshold: f64) -> Self {
        EnergyMonitor {
            energy,
            threshold,
            e0: f64::NAN,
            scale: 1.0,
            prev: f64::NAN,
            seen: 0,
            max: DriftEvent { step: 0, t: 0.0, change: 0.0 },
            last: 0.0,
            first_exceeded: None,
            first_jump: None,
        }
    }

    /// Records the state after one more accepted step (the first call is the initial state).
    pub fn observe(&mut self, t: f64, y: &[f64]) {
        let e = (self.energy)(t, y);
        if self.seen == 0 {
            self.e0 = e;
            self.prev = e;
            self.scale = if e.is_finite() && e != 0.0 { e.abs() } else { 1.0 };
            self.max = DriftEvent { step: 0, t, change: 0.0 };
            self.seen = 1;
            return;
        }
        let step = self.seen;
        self.seen += 1;
        // Non-finite values count as infinite changes, so every comparison below is ordered.
        let drift = if e.is_finite() && self.e0.is_finite() { (e - self.e0).abs() / self.scale } else { f64::INFINITY };
        let jump =
            if e.is_finite() && self.prev.is_finite() { (e - self.prev).abs() / self.scale } else { f64::INFINITY };
        self.prev = e;
        self.last = drift;
        if drift > self.max.change {
            self.max = DriftEvent { step, t, change: drift };
        }
        if self.first_exceeded.is_none() && drift > self.threshold {
            self.first_exceeded = Some(DriftEvent { step, t, change: drift });
        }
        if self.first_jump.is_none() && jump > self.threshold {
            self.first_jump = Some(DriftEvent { step, t, change: jump });
        }
    }

    /// The ledger so far (`None` before the initial state was observed).
    pub fn report(&self) -> Option<DriftReport> {
        (self.seen > 0).then(|| DriftReport {
            e0: self.e0,
            relative: self.e0.is_finite() && self.e0 != 0.0,
            threshold: self.threshold,
            max: self.max,
            last: self.last,
            first_exceeded: self.first_exceeded,
            first_jump: self.first_jump,
            steps: self.seen - 1,
        })
    }
}
