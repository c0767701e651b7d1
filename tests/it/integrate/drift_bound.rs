//! Tests of `src/integrate/drift.rs` (formerly its in-crate unit tests).

use lagrangian::integrate::drift::*;

#[test]
fn records_the_largest_drift_the_first_excess_and_the_first_jump() {
    // E along the "run": 2, 2.001 (drift 5e-4), 2.004 (drift 2e-3, jump 1.5e-3), 2.0 (back).
    let values = [2.0, 2.001, 2.004, 2.0];
    let mut m = EnergyMonitor::new(|_t, y: &[f64]| y[0], 1e-3);
    for (k, v) in values.iter().enumerate() {
        m.observe(k as f64 * 0.5, &[*v]);
    }
    let r = m.report().unwrap();
    assert!(r.relative);
    assert_eq!(r.steps, 3);
    assert_eq!((r.max.step, r.max.t), (2, 1.0));
    assert!((r.max.change - 0.002).abs() < 1e-12);
    assert_eq!(r.first_exceeded.map(|e| e.step), Some(2));
    assert_eq!(r.first_jump.map(|e| e.step), Some(2), "a 1.5e-3 jump");
    assert!(r.last.abs() < 1e-12);
    assert!(r.exceeded());
}

#[test]
fn a_non_finite_energy_is_a_jump_and_zero_energy_is_absolute() {
    let mut m = EnergyMonitor::new(|_t, y: &[f64]| y[0], 1e-3);
    for (k, v) in [0.0, 1e-4, f64::NAN].iter().enumerate() {
        m.observe(k as f64, &[*v]);
    }
    let r = m.report().unwrap();
    assert!(!r.relative);
    assert_eq!(r.first_jump.map(|e| (e.step, e.change)), Some((2, f64::INFINITY)));
    let mut quiet = EnergyMonitor::new(|_t, y: &[f64]| y[0], 1e-3);
    for (k, v) in [1.0, 1.0 + 1e-9, 1.0 - 1e-9].iter().enumerate() {
        quiet.observe(k as f64, &[*v]);
    }
    assert!(!quiet.report().unwrap().exceeded());
}
