//! One file per family of statements, each an `impl Session` block with the handlers the
//! session's `exec` dispatches to.

pub(super) mod animate;
pub(super) mod canonical;
pub(super) mod chaos;
pub mod drift;
pub(super) mod dynamics;
pub(super) mod ensemble;
pub(super) mod expansion;
pub(super) mod figures;
pub(super) mod first_order;
pub(super) mod flow;
pub(super) mod geodesic;
pub(super) mod map;
pub(super) mod ritz;
pub(super) mod sections;
pub(super) mod simulate;
pub(super) mod variational;
