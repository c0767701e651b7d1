//! One file per family of statements, each an `impl Session` block with the handlers, and the
//! `Stmt` impls that tie each statement's type to its handler. The registry
//! (`scene/registry.rs`) says which grammar rule reads into which type; the session runs the
//! result through `Stmt::run`.

use std::fmt::Debug;

use super::state::{At, Session};
use super::syntax::ast::Src;
use super::syntax::error::SceneError;

pub(super) mod animate;
pub mod canonical;
pub(super) mod chaos;
pub(super) mod control;
pub mod declare;
pub mod define;
pub mod drift;
pub(super) mod dynamics;
pub(super) mod energy_at;
pub(super) mod ensemble;
pub(super) mod expansion;
pub(super) mod figures;
pub(super) mod first_order;
pub mod flow;
pub(super) mod geodesic;
pub(super) mod map;
pub mod print;
pub(super) mod ritz;
pub(super) mod sections;
pub(super) mod simulate;
pub(super) mod variational;

/// A parsed statement: what it does when run, and which file it writes. A trait rather than
/// a table of handlers because each statement has its own type; the compiler checks that the
/// handler gets the type the reader made.
pub(in crate::scene) trait Stmt: Debug {
    /// Runs the statement at `at` (its line and span) in the session.
    fn run(&self, s: &mut Session, at: At) -> Result<(), SceneError>;

    /// The file this statement writes, claimed for the whole scene before any statement runs
    /// (so two statements never write one file, and a bad name fails before the work).
    fn output(&self) -> Option<Output<'_>> {
        None
    }
}

/// A file a statement writes: where (or a default name) and which formats it may have.
pub(in crate::scene) struct Output<'a> {
    /// `to FILE`, if given.
    pub path: Option<&'a Src>,
    /// The file's stem when no path is given.
    pub default: &'static str,
    /// What is written (`image`, `chaos map`), for the error about an unknown format.
    pub what: &'static str,
    /// The extensions accepted.
    pub formats: &'static [&'static str],
    /// The hint naming them.
    pub hint: &'static str,
}
