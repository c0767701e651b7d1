//! What statements run on: the [`backend`] over the library's `simulate` (the one place that
//! calls the mechanics, canonical, compile and integrate stages), the [`plan`] of what was
//! built, reused, loaded or skipped, [`progress`] bars and the staging of output files
//! ([`output`]).

pub mod backend;
pub mod output;
pub mod plan;
pub mod progress;
