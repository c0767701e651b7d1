//! Progress bars for long simulations (indicatif).
//!
//! A bar appears only on a terminal and only once a simulation has run for about a second, so
//! short runs, pipes and log files stay quiet. Where the bar is drawn is decided by one
//! function of "is stderr a terminal" and the `LAGRANGIAN_PROGRESS` variable, so that tests
//! can force it: `never` hides it, `always` draws it at once and, when stderr is not a
//! terminal, as plain lines (one per redraw, the last at 100 %), which a test can read.

use std::io::Write;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};

/// Where and when a bar is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Draw {
    /// Never.
    Hidden,
    /// On the terminal, for simulations longer than [`Draw::DELAY`].
    Terminal,
    /// As plain lines on stderr, from the start (forced with `LAGRANGIAN_PROGRESS=always`
    /// when stderr is not a terminal).
    Lines,
}

impl Draw {
    /// How long a simulation runs before its bar appears on a terminal.
    pub const DELAY: Duration = Duration::from_secs(1);

    /// The draw target for a process whose stderr is (or is not) a terminal, given the
    /// value of `LAGRANGIAN_PROGRESS` (`always`, `never`, or unset for automatic).
    pub fn choose(stderr_is_terminal: bool, setting: Option<&str>) -> Draw {
        match (setting, stderr_is_terminal) {
            (Some("never"), _) => Draw::Hidden,
            (Some("always"), false) => Draw::Lines,
            (_, true) => Draw::Terminal,
            (_, false) => Draw::Hidden,
        }
    }

    /// [`Draw::choose`] for this process.
    pub fn from_env() -> Draw {
        let setting = std::env::var("LAGRANGIAN_PROGRESS").ok();
        Draw::choose(std::io::IsTerminal::is_terminal(&std::io::stderr()), setting.as_deref())
    }
}

/// The bar of one simulation, created when it is first due.
pub struct Progress {
    draw: Draw,
    name: String,
    started: Instant,
    bar: Option<ProgressBar>,
    /// The largest fraction reported so far.
    done: f64,
}

/// Bar positions per unit of progress.
const TICKS: u64 = 1000;

impl Progress {
    /// A progress report for the simulation `name`.
    pub fn new(name: &str, draw: Draw) -> Progress {
        Progress { draw, name: name.to_string(), started: Instant::now(), bar: None, done: 0.0 }
    }

    /// Moves the start `ago` into the past, so a test of the bar's delay does not depend on
    /// how fast its host runs.
    #[doc(hidden)]
    pub fn backdate(&mut self, ago: std::time::Duration) {
        if let Some(then) = Instant::now().checked_sub(ago) {
            self.started = then;
        }
    }

    /// Reports the fraction of the time span done (clamped to `[0, 1]`, never moving back).
    pub fn update(&mut self, fraction: f64) {
        if fraction.is_nan() {
            return;
        }
        self.done = self.done.max(fraction.clamp(0.0, 1.0));
        if self.bar.is_none() {
            let due = match self.draw {
                Draw::Hidden => false,
                // A run that is nearly done when the second passes gets no bar.
                Draw::Terminal => self.started.elapsed() > Draw::DELAY && self.done < 0.9,
                Draw::Lines => true,
            };
            if due {
                self.bar = Some(self.make_bar());
            }
        }
        if let Some(b) = &self.bar {
            b.set_position((self.done * TICKS as f64).round() as u64);
        }
    }

    fn make_bar(&self) -> ProgressBar {
        let target = match self.draw {
            Draw::Lines => ProgressDrawTarget::term_like(Box::new(PlainLines::default())),
            _ => ProgressDrawTarget::stderr(),
        };
        let b = ProgressBar::with_draw_target(Some(TICKS), target);
        if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ETA {eta}") {
            b.set_style(style);
        }
        b.set_message(self.name.clone());
        b
    }

    /// The largest fraction reported.
    pub fn fraction(&self) -> f64 {
        self.done
    }

    /// Whether a bar was shown.
    pub fn shown(&self) -> bool {
        self.bar.is_some()
    }

    /// Ends a report whose run failed or was interrupted: a terminal bar is cleared, a plain
    /// one is left where the run stopped (not drawn at 100 %).
    pub fn abandon(self) {
        if let Some(b) = self.bar {
            match self.draw {
                Draw::Lines => b.abandon(),
                _ => b.finish_and_clear(),
            }
        }
    }

    /// Ends the report: a terminal bar is cleared, a plain one drawn a last time.
    pub fn finish(self) {
        if let Some(b) = self.bar {
            match self.draw {
                Draw::Lines => b.finish(),
                _ => b.finish_and_clear(),
            }
        }
    }
}

/// A "terminal" that writes each frame that differs from the last as a line on stderr and
/// ignores cursor motion.
#[derive(Debug, Default)]
struct PlainLines {
    last: std::sync::Mutex<String>,
}

impl TermLike for PlainLines {
    fn width(&self) -> u16 {
        80
    }
    fn move_cursor_up(&self, _n: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _n: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _n: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _n: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.write_str(s)
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        let mut last = self.last.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if s.trim().is_empty() || *last == s {
            return Ok(());
        }
        s.clone_into(&mut last);
        writeln!(std::io::stderr().lock(), "{s}")
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}
