//! The compiler: tapes, the native back end, compiled right-hand sides and systems (`src/compile/`).

mod lanes;
mod native;
mod rhs;
mod system;
mod tape;
