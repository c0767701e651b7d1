//! Cooperative cancellation: a shared flag that long-running work polls, so that Ctrl-C
//! (or a library caller on another thread) can stop an integration, a simplification or a
//! plot between two of its steps and get a typed "interrupted" failure back, with every
//! earlier result intact.
//!
//! Why cooperative and not a signal that kills the thread: the REPL must survive an
//! interrupt with its definitions, and `lagrangian run` must remove its staged output files
//! before it exits; both need the work to return normally. The checks are one relaxed atomic
//! load each, placed where the work already loops (the integrators' step loop, the
//! simplifier's e-graph iterations, Newton iterations, figure series), so the cost is nil
//! and the latency is one step of the innermost loop that checks.
//!
//! Two kinds of token:
//! * [`CancelToken::new`] — a private token for one job, given to
//!   [`crate::integrate::Options::cancel`] or [`crate::integrate::Solver::set_cancel`];
//! * [`global`] — the process-wide token that the front ends connect to Ctrl-C
//!   ([`install_ctrlc`]). Every check also honours it, so the stages that take no token
//!   parameter (the simplifier, the scene session) stop on Ctrl-C too. A library that never
//!   installs the handler never sees it set.
//!
//! The Python binding keeps its own per-call flag (it must also poll Python's signal state
//! with the GIL held); it stops the library's integrators through the same
//! [`crate::integrate::Options`] path.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// A cancellation flag shared between the work and whoever may stop it. Cloning shares it.
#[derive(Clone, Debug, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A fresh, unset token.
    pub fn new() -> CancelToken {
        CancelToken::default()
    }

    /// Asks the work holding this token to stop at its next check.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Clears the request (before starting the next piece of work).
    pub fn reset(&self) {
        self.0.store(false, Ordering::Relaxed);
    }

    /// Whether this token (or the process-wide one) has been cancelled.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed) || interrupted()
    }

    /// `Err(Interrupted)` once cancelled.
    pub fn check(&self) -> Result<(), Interrupted> {
        if self.is_cancelled() {
            Err(Interrupted)
        } else {
            Ok(())
        }
    }
}

/// The work stopped because it was asked to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("interrupted")]
pub struct Interrupted;

static GLOBAL: OnceLock<Arc<AtomicBool>> = OnceLock::new();
static PRESSES: AtomicUsize = AtomicUsize::new(0);

fn global_flag() -> &'static Arc<AtomicBool> {
    GLOBAL.get_or_init(|| Arc::new(AtomicBool::new(false)))
}

/// The process-wide token (set by Ctrl-C once [`install_ctrlc`] has run).
pub fn global() -> CancelToken {
    CancelToken(global_flag().clone())
}

thread_local! {
    /// The token of [`with_token`] on this thread, if any.
    static SCOPED: std::cell::RefCell<Option<CancelToken>> = const { std::cell::RefCell::new(None) };
    /// Calls of [`poll`] on this thread, so that it looks at the flags once every [`POLL_EVERY`].
    static TICKS: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

/// Runs `f` with `token` as this thread's token: every check inside (the ones that take no
/// token parameter, down to the single symbolic steps — expansion, collection of terms,
/// differentiation) honours it as well as the process-wide one. A library caller stops one
/// `simplify` or `expand` from another thread this way without touching Ctrl-C's flag, which
/// would stop every other job of the process. Nests; the previous token is restored after.
pub fn with_token<R>(token: &CancelToken, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<CancelToken>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let old = self.0.take();
            SCOPED.with(|s| *s.borrow_mut() = old);
        }
    }
    let _restore = Restore(SCOPED.with(|s| s.borrow_mut().replace(token.clone())));
    f()
}

/// Whether the process-wide token (or this thread's [`with_token`] token) is set: the check
/// for code that takes no token.
#[inline]
pub fn interrupted() -> bool {
    GLOBAL.get().is_some_and(|f| f.load(Ordering::Relaxed))
        || SCOPED.with(|s| s.borrow().as_ref().is_some_and(|t| t.0.load(Ordering::Relaxed)))
}

/// [`poll`] looks at the flags on one call in this many.
pub const POLL_EVERY: u32 = 64;

/// [`check`] on one call in [`POLL_EVERY`]: for loops whose single iteration is cheap (one
/// node of an expansion or a derivative), where even a thread-local lookup per node would
/// show. The latency is at most `POLL_EVERY` nodes.
#[inline]
pub fn poll() -> Result<(), Interrupted> {
    let due = TICKS.with(|t| {
        let n = t.get().wrapping_add(1);
        t.set(n);
        n % POLL_EVERY == 0
    });
    if due {
        check()
    } else {
        Ok(())
    }
}

/// `Err(Interrupted)` when the process-wide token (or this thread's) is set.
#[inline]
pub fn check() -> Result<(), Interrupted> {
    if interrupted() {
        Err(Interrupted)
    } else {
        Ok(())
    }
}

/// Clears the process-wide token and the press count (the REPL does this before each entry).
pub fn reset_global() {
    global_flag().store(false, Ordering::Relaxed);
    PRESSES.store(0, Ordering::Relaxed);
}

/// What a second Ctrl-C does while the first is still being honoured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SecondPress {
    /// Nothing more: the REPL waits for the work to reach a check.
    Ignore,
    /// Exit at once with status 130 (`lagrangian run`: the user insists; some stage between
    /// checks is taking too long), after removing the files registered with
    /// [`remove_at_exit`] (the staged outputs), so even then no partial file is left.
    Exit,
}

/// Temporary files to delete if a second Ctrl-C ends the process before the work returns.
static DOOMED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Registers `path` (a staged output) for removal if the process is ended by a second Ctrl-C.
pub fn remove_at_exit(path: &Path) {
    let mut v = DOOMED.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    v.push(path.to_path_buf());
}

/// Withdraws `path` from [`remove_at_exit`] (it was moved into place or removed).
pub fn keep_at_exit(path: &Path) {
    let mut v = DOOMED.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    v.retain(|p| p != path);
}

/// Removes the files registered with [`remove_at_exit`] (from a thread, never in signal
/// context: it locks and allocates).
fn remove_doomed() {
    let v = DOOMED.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    for p in v.iter() {
        let _ = std::fs::remove_file(p);
    }
}

/// Ends the process on SIGTERM or SIGHUP (a service manager stopping it, its terminal
/// closing) with status 128 + the signal, after removing the staged outputs registered with
/// [`remove_at_exit`], so a `lagrangian run` ended that way leaves no partial file. Without
/// it the default action kills the process where it stands. Once per process; the signals
/// arrive on a thread of their own (signal-hook), where removing files is allowed.
#[cfg(unix)]
pub fn install_termination() -> Result<(), String> {
    use signal_hook::consts::{SIGHUP, SIGTERM};
    static INSTALLED: OnceLock<Result<(), String>> = OnceLock::new();
    INSTALLED
        .get_or_init(|| {
            let mut signals = signal_hook::iterator::Signals::new([SIGTERM, SIGHUP])
                .map_err(|e| format!("cannot install the SIGTERM handler: {e}"))?;
            std::thread::Builder::new()
                .name("lagrangian-termination".into())
                .spawn(move || {
                    if let Some(sig) = signals.forever().next() {
                        remove_doomed();
                        std::process::exit(128 + sig);
                    }
                })
                .map(|_| ())
                .map_err(|e| format!("cannot start the SIGTERM thread: {e}"))
        })
        .clone()
}

/// Connects SIGINT (Ctrl-C) to the process-wide token, once per process (later calls return
/// `Ok` and keep the first handler). On a terminal, rustyline reads keys in raw mode, so
/// Ctrl-C at the REPL prompt stays a key for the line editor; the signal arrives only while
/// a command runs.
pub fn install_ctrlc(second: SecondPress) -> Result<(), String> {
    static INSTALLED: OnceLock<Result<(), String>> = OnceLock::new();
    let flag = global_flag().clone();
    INSTALLED
        .get_or_init(|| {
            ctrlc::set_handler(move || {
                flag.store(true, Ordering::Relaxed);
                let n = PRESSES.fetch_add(1, Ordering::Relaxed) + 1;
                if n >= 2 && second == SecondPress::Exit {
                    // The handler runs on ctrlc's own thread, not in signal context, so it
                    // may lock and remove files.
                    remove_doomed();
                    std::process::exit(130);
                }
            })
            .map_err(|e| format!("cannot install the Ctrl-C handler: {e}"))
        })
        .clone()
}
