//! Scene files and the REPL: the statement language, its demand-driven evaluation, and
//! the outputs (printed results, plots, CSV/JSON exports).
//!
//! Three layers, each importing only the ones below it:
//! * [`syntax`]: text → statements ([`parser`] over `grammar/scene.pest`, which reuses
//!   `grammar/expr.pest`; [`ast`]; the scene file as read, `syntax::source`; errors
//!   ([`SceneError`]) with a span, a label and a hint, rendered by miette). `registry` (one
//!   row per statement: keywords, help topic, grammar rule, reader) sits above `syntax` and
//!   `statements` and joins them; the parser's statement words and [`help`] are derived from it.
//! * [`engine`]: what statements run on — the [`backend`] (the one place that calls the
//!   mechanics, canonical, compile and integrate stages, through the library's `simulate`),
//!   the plan of what was built, reused, loaded or skipped (`--explain`), [`progress`] bars
//!   and staged output files. It imports no statement.
//! * `state` (the session's data), [`session`] (running a text, `exec`, expressions,
//!   definitions demanded, derivations looked up and recorded, the plan) and `statements/`,
//!   one file per family, each with its types, readers and handlers: `declare`
//!   (`coordinates`, `parameters`, `functions`), `define` (`NAME = …`), `print` (`print`, a
//!   bare derivation, `latex`/`format`), `control` (`load`, `help`, `history`,
//!   `allow nonfinite`), `simulate`, `ensemble`, `dynamics` (`force`, `rayleigh`,
//!   `constraint`), `drift` (energy checks), `chaos`, `figures` (`plot`, `export`), `sections`
//!   (Poincaré), `animate`, `canonical` (`transform`, `lie`, `integral`, `action`, `average`),
//!   `first_order`, `variational`, `geodesic`, `ritz`. Definitions and simulations are
//!   recorded lazily; outputs demand them.
//! * [`crate::cache`]: derivations keyed by symbolic content, in memory and on disk.
//! * [`repl`]: the interactive front end.
//!
//! ```
//! use lagrangian::scene::{Mode, Options, Session};
//! let mut s = Session::new(Options::new(Mode::Scene));
//! s.run_scene("demo", "coordinates x\nparameters m, k positive\nT = 1/2 m x'^2\nprint T - 1/2 k x^2 as plain").unwrap();
//! assert_eq!(s.take_output(), ["m x'^2/2 - k x^2/2"]);
//! ```

pub mod engine;
#[doc(hidden)]
pub mod registry;
pub mod repl;
pub mod session;
mod state;
#[doc(hidden)]
pub mod statements;
pub mod syntax;

pub use engine::{backend, output, progress};
pub use statements::drift;
pub use syntax::{ast, error};

/// `help`: every statement with its form, what it does and an example, from the registry's
/// rows (the examples are parsed by a test, so they stay valid).
pub mod help {
    pub use super::registry::{help, Topic, REGISTRY as TOPICS};
}

/// Scene text → statements: the text layer's splitting (`syntax::parser`) and the registry's
/// reading of each statement.
pub mod parser {
    pub use super::registry::{parse_scene, parse_statement_at, Statement};
    pub use super::syntax::parser::{is_incomplete, split_statements, Unfinished, MAX_STATEMENT};
}

pub use backend::{Backend, BackendError, Line, NativeBackend, Trajectory};
pub use error::{ErrorKind, SceneError};
pub use session::{Cache, PlanEntry, Status, Step};
pub use state::Session;
pub use state::{Mode, Options};
pub use syntax::source::read_scene;
