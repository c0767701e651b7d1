//! Tests of `src/cancel.rs` (formerly its in-crate unit tests).
use lagrangian::cancel::*;

#[test]
fn a_private_token_is_shared_by_its_clones_and_reset() {
    let t = CancelToken::new();
    let u = t.clone();
    assert!(!u.is_cancelled());
    t.cancel();
    assert!(u.is_cancelled());
    assert_eq!(u.check(), Err(Interrupted));
    u.reset();
    assert!(!t.is_cancelled());
}
