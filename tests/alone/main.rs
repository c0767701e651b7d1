//! Tests that measure the whole process: resident memory, live interned nodes, and growth
//! exponents from wall times. Tests running beside them would disturb the measure (another
//! thread interning nodes, or two busy threads on a 2-core machine doubling a time), so they
//! live apart from the `it` binary and take [`alone`] to run one at a time.

use std::sync::{Mutex, MutexGuard};

mod memory;
mod scaling;

/// Held for the whole of each test in this binary: they run one after another.
pub fn alone() -> MutexGuard<'static, ()> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    ONE_AT_A_TIME.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
