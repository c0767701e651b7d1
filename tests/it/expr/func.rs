//! Tests of `src/func.rs` (formerly its in-crate unit tests).

use lagrangian::func::*;

/// `spec` indexes by discriminant, so the rows must follow the enum; and `ALL` must list
/// every variant once.
#[test]
fn rows_follow_the_enum() {
    for (i, f) in Func::ALL.into_iter().enumerate() {
        assert_eq!(f as usize, i);
        assert_eq!(format!("{f:?}").to_lowercase(), f.name());
    }
    assert_eq!(SPECS.len(), Func::ALL.len());
}
