//! The compiler: tapes, the native back end, compiled right-hand sides and systems (`src/compile/`).

mod native;
mod rhs;
mod system;
mod tape;
