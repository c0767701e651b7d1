//! Tests that measure the whole process: resident memory, live interned nodes, and growth
//! exponents from the CPU time of the thread that does the work. Tests running beside them in
//! the same process would disturb the measure (another thread interning nodes or allocating, or
//! competing for the thread's cache), so they live apart from the `it` binary and take [`alone`]
//! to run one at a time. Other processes may run meanwhile (CI runs the Python tests beside
//! `cargo test`): they change neither a thread's CPU time nor this process's memory.

use std::sync::{Mutex, MutexGuard};

mod memory;
mod scaling;

/// Held for the whole of each test in this binary: they run one after another.
pub fn alone() -> MutexGuard<'static, ()> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    ONE_AT_A_TIME.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
