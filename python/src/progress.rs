//! Progress and Ctrl-C for a long engine call: the drive loop reports the fraction done (stored
//! in an atomic that the progress bar reads) and checks the engine's cancellation token
//! ([`lagrangian::cancel::CancelToken`]) before every step; the waiting thread sets it on
//! `KeyboardInterrupt`. The calling thread waits with the GIL released and, a few times a
//! second, takes the GIL to draw the bar and check for the signal.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError};
use pyo3::prelude::*;

/// Where an integration is, shared between the integrating thread and the one drawing the
/// progress bar.
#[derive(Default)]
pub struct Control {
    /// The fraction of the span done, as `f64` bits.
    pub fraction: AtomicU64,
    pub cancel: lagrangian::cancel::CancelToken,
}

impl Control {
    /// Stores the fraction done (what the drive loop reports).
    pub fn report(&self, f: f64) {
        self.fraction.store(f.to_bits(), Ordering::Relaxed);
    }

    pub fn fraction(&self) -> f64 {
        f64::from_bits(self.fraction.load(Ordering::Relaxed))
    }
}

/// How a progress bar is shown.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum ProgressMode {
    /// No bar (Ctrl-C is still polled).
    Off,
    /// A bar once the run has taken more than a second.
    Auto,
    /// A bar from the start.
    On,
}

pub fn progress_mode(p: Option<bool>) -> ProgressMode {
    match p {
        None => ProgressMode::Auto,
        Some(true) => ProgressMode::On,
        Some(false) => ProgressMode::Off,
    }
}

/// How often the waiting thread checks for Ctrl-C (and redraws the bar): well inside the
/// 0.2 s in which an interrupt must reach the caller.
const POLL: Duration = Duration::from_millis(40);

/// What the waiting thread does with the result of one call into Python (the bar's creation,
/// update or close). A `KeyboardInterrupt` raised inside that Python code (the interpreter
/// runs its signal handlers there) is the user's Ctrl-C: it cancels the run and is kept to be
/// raised. Any other failure of the bar only turns the bar off: a display problem must not
/// stop a computation.
pub fn bar_result<T>(
    py: Python<'_>,
    r: PyResult<T>,
    ctl: &Control,
    interrupted: &mut Option<PyErr>,
    broken: &mut bool,
) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) if e.is_instance_of::<PyKeyboardInterrupt>(py) => {
            ctl.cancel.cancel();
            interrupted.get_or_insert(e);
            None
        }
        Err(_) => {
            *broken = true;
            None
        }
    }
}

/// Runs `work` with the GIL released on a scoped thread while this one waits, checking for
/// Ctrl-C every [`POLL`] (a signal cancels the run through `ctl` and is raised once `work`
/// has stopped, leaving every object usable) and, unless `mode` is `Off`, drawing the bar
/// (`fraction()` in [0, 1]). Every path polls: with `progress=False` too, and while the bar is
/// created, updated and closed.
pub fn with_progress<R: Send>(
    py: Python<'_>,
    mode: ProgressMode,
    label: &str,
    ctl: &Control,
    fraction: impl Fn() -> f64 + Send + Sync,
    work: impl FnOnce() -> R + Send,
) -> PyResult<R> {
    let (result, interrupted) = py.allow_threads(|| {
        std::thread::scope(|s| {
            let (tx, rx) = mpsc::channel();
            s.spawn(move || {
                let _ = tx.send(work());
            });
            let start = Instant::now();
            let mut bar: Option<PyObject> = None;
            let mut broken = mode == ProgressMode::Off;
            let mut interrupted: Option<PyErr> = None;
            let delay = if mode == ProgressMode::On { Duration::ZERO } else { Duration::from_secs(1) };
            let poll = |bar: &mut Option<PyObject>, broken: &mut bool, interrupted: &mut Option<PyErr>| {
                Python::with_gil(|py| {
                    if let Err(e) = py.check_signals() {
                        ctl.cancel.cancel();
                        interrupted.get_or_insert(e);
                    }
                    if interrupted.is_some() || *broken {
                        return;
                    }
                    if bar.is_none() && start.elapsed() >= delay {
                        let made = py
                            .import("lagrangian._progress")
                            .and_then(|m| m.getattr("Bar")?.call1((label,)))
                            .map(Bound::unbind);
                        *bar = bar_result(py, made, ctl, interrupted, broken);
                    }
                    if let Some(b) = bar.as_ref() {
                        let r = b.call_method1(py, "update", (fraction().clamp(0.0, 1.0),));
                        bar_result(py, r, ctl, interrupted, broken);
                    }
                })
            };
            if mode == ProgressMode::On {
                poll(&mut bar, &mut broken, &mut interrupted);
            }
            let result = loop {
                match rx.recv_timeout(POLL) {
                    Ok(r) => break Some(r),
                    Err(mpsc::RecvTimeoutError::Disconnected) => break None,
                    Err(mpsc::RecvTimeoutError::Timeout) => poll(&mut bar, &mut broken, &mut interrupted),
                }
            };
            if let Some(b) = bar {
                Python::with_gil(|py| {
                    if interrupted.is_none() {
                        let r = b.call_method1(py, "update", (1.0,));
                        bar_result(py, r, ctl, &mut interrupted, &mut broken);
                    }
                    let r = b.call_method0(py, "close");
                    bar_result(py, r, ctl, &mut interrupted, &mut broken);
                });
            }
            (result, interrupted)
        })
    });
    // A signal that arrived after the last poll is raised now, not left for a later call.
    py.check_signals()?;
    if let Some(e) = interrupted {
        return Err(e);
    }
    result.ok_or_else(|| PyRuntimeError::new_err("the integration thread ended without a result (it panicked)"))
}
