//! Scene files and the REPL: the statement language, its demand-driven evaluation, and
//! the outputs (printed results, plots, CSV/JSON exports).
//!
//! * [`parser`]: text → statements (`grammar/scene.pest`, which reuses `grammar/expr.pest`).
//! * [`session`]: executes statements. Definitions and simulations are recorded lazily in a
//!   scene; outputs demand them. Its work is split by job: `simulate` (one run), `figures`
//!   (`plot`, `export`), `plan` (what was built, reused, loaded or skipped: what
//!   `lagrangian run --explain` prints).
//! * `dynamics`: `force`, `rayleigh` and `constraint` statements, resolved into the
//!   extended Lagrangian a run compiles.
//! * `ensemble`: `simulate … for each y in A..B step H on E = VALUE solve p > 0`: many runs
//!   started on one level set, integrated in parallel, named as one group.
//! * `animate`: `animate path (x, y), … to FILE.gif`, the motion as frames of bodies and arms.
//! * `chaos`: `lyapunov`, `megno`, `fli` and `chaos_map` (chaos indicators of the
//!   Hamiltonian flow, through [`crate::chaos`]).
//! * `sections`: Poincaré sections (`record when …` points) as data for plots and exports.
//! * [`crate::cache`]: derivations keyed by symbolic content, in memory and on disk.
//! * [`progress`]: progress bars of long simulations, only on a terminal.
//! * [`backend`]: the one place that calls the mechanics, canonical, compile and integrate
//!   stages.
//! * [`repl`]: the interactive front end.
//! * Errors ([`SceneError`]) carry a span, a label and a hint, rendered by miette.
//!
//! ```
//! use lagrangian::scene::{Mode, Options, Session};
//! let mut s = Session::new(Options::new(Mode::Scene));
//! s.run_scene("demo", "coordinates x\nparameters m, k positive\nT = 1/2 m x'^2\nprint T - 1/2 k x^2 as plain").unwrap();
//! assert_eq!(s.take_output(), ["m x'^2/2 - k x^2/2"]);
//! ```

pub mod engine;
pub mod repl;
pub mod session;
mod statements;
pub mod syntax;

pub use engine::{backend, output, progress};
pub use statements::drift;
pub use syntax::{ast, error, help, parser};

pub use backend::{Backend, BackendError, Line, NativeBackend, Trajectory};
pub use error::{ErrorKind, SceneError};
pub use session::{read_scene, Cache, Mode, Options, PlanEntry, Session, Status, Step};
