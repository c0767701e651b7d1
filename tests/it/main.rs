//! The integration tests: one binary (linking one test binary per file dominated the CI build),
//! with modules mirroring `src/`. Run one module with `cargo test --test it canonical::` and one
//! test by its name as usual. Shared helpers live in `support` only; snapshots in the
//! repository's `snapshots/` (written through `support::snapshot`).

mod support;

mod cache;
mod cancel;
mod canonical;
mod chaos;
mod compile;
mod expr;
mod integrate;
mod linalg;
mod mechanics;
mod notes;
mod parse;
mod plot;
mod report;
mod robust;
mod scene;
mod simplify;
mod simulate;
mod snapshot_checks;
mod taylor;
