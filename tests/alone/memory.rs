//! Bounded memory in a long-running process: interned nodes that nothing references are freed.
//!
//! A REPL, a notebook kernel or a server derives one system after another. Before weak
//! interning every node lived for the process (about 50 kB per derivation, 164 MB after 3000).
//! This test derives 10⁴ different Lagrangians in one process and checks both the exact
//! measure (the count of live interned nodes returns to where it was after a warm-up) and
//! the one a user sees (resident memory grows by less than a fixed bound).
//!
//! It runs in the `alone` binary, one test at a time, so no other thread interns nodes or
//! allocates meanwhile.

use lagrangian::mechanics::System;

/// A derivation a REPL user would run: the Euler–Lagrange equations, `W` and `F`, and `H`, of a
/// Lagrangian that differs from every other one in the run (its coefficients carry `i`).
fn derive(i: usize) -> usize {
    let text = format!("1/2 m (x'^2 + y'^2) - {i}/7 x^2 y - {}/3 k y^4 + {i} x y'", i + 1);
    let s = System::from_lagrangian(&text, &["x", "y"]).expect("a valid Lagrangian");
    let el = s.euler_lagrange().expect("Euler–Lagrange");
    let (w, f) = s.mass_matrix_split().expect("W, F");
    let h = s.hamiltonian().expect("H");
    el.len() + w.len() + f.len() + h.op_count()
}

/// Resident set size in bytes (Linux `/proc`; elsewhere the RSS half of the test is skipped).
fn resident_bytes() -> Option<usize> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: usize = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

#[test]
fn ten_thousand_derivations_hold_no_memory_once_dropped() {
    let _alone = crate::alone();
    // Warm-up: the rule table, small numbers and allocator pools reach their steady size.
    for i in 0..200 {
        assert!(derive(i) > 0);
    }
    let nodes_before = lagrangian::live_nodes();
    let rss_before = resident_bytes();
    for i in 200..10_000 {
        assert!(derive(i) > 0);
    }
    let nodes_after = lagrangian::live_nodes();
    // Each derivation interns hundreds of nodes; had any been kept, 9800 derivations would
    // leave hundreds of thousands alive. A handful of nodes may stay in flight in caches that
    // are per call; none may accumulate.
    assert!(
        nodes_after <= nodes_before + 100,
        "live interned nodes grew from {nodes_before} to {nodes_after} over 9800 derivations"
    );
    if let (Some(before), Some(after)) = (rss_before, resident_bytes()) {
        let grown = after.saturating_sub(before);
        // Without freeing, 9800 derivations at ~50 kB each would add ~490 MB.
        assert!(grown < 32 << 20, "resident memory grew by {} MB over 9800 derivations", grown >> 20);
    }
}
