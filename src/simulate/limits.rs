//! The budgets a run has when it sets none: what is kept, and how many steps it may take.

/// The most states a run keeps by default ([`super::run::Sampling::Auto`]): fixed-step runs keep every
/// k-th step for a k chosen up front, adaptive runs thin as they go, so the memory of a run is
/// bounded whatever its length.
pub const MAX_POINTS: usize = 20_000;

/// The step budget of an adaptive run that sets none: it cannot know its count in advance, so
/// it stops here with an error that says where it got to and why (typically stiffness).
pub const MAX_ADAPTIVE_STEPS: usize = 1_000_000;

/// The most fixed steps a run that sets no budget may take; more is refused before the
/// first step.
pub const MAX_FIXED_STEPS: f64 = 1e9;

/// The most states a run may keep when it asks for them (`every N`, `points N`, sample times).
/// A kept state costs about 230 bytes for a small system (its vector and the time), so this
/// is about half a gigabyte; more is refused before the first step with the smallest `every`
/// that fits, where it used to run until the process was killed (10⁸ RK4 steps with
/// `every 1`: 2.46 GB, then an abort).
pub const MAX_STORED_STATES: usize = 2_000_000;
