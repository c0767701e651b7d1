//! Scenes and the REPL: statements, examples, diagnostics, cache, progress, figures, parity with the command line (`src/scene/`).

mod bad_input;
mod cache;
mod dynamics;
mod energy_at;
mod examples;
mod expansion;
mod figures;
mod graph;
mod parity;
mod print;
mod progress;
mod repeated_options;
mod repl;
#[cfg(unix)]
mod repl_pty;
mod run;
mod symmetry;
mod syntax;
