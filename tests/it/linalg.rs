//! Tests of `src/linalg.rs` (formerly its in-crate unit tests).

use lagrangian::linalg::{determinant, solve_in_place};

#[test]
fn solves_and_reports_the_degenerate_column() {
    // [[0, -1], [1, 0]] x = [3, 4] → x = [4, -3].
    let mut a = [0.0, -1.0, 1.0, 0.0];
    let mut b = [3.0, 4.0];
    solve_in_place(&mut a, &mut b, 2).unwrap();
    assert_eq!(b, [4.0, -3.0]);
    let mut a = [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut b = [1.0, 1.0, 1.0];
    assert_eq!(solve_in_place(&mut a, &mut b, 3), Err(2));
}

#[test]
fn determinant_by_elimination() {
    // det [[0, 2], [3, 4]] = −6 (one row exchange); a zero column gives exactly 0.
    assert_eq!(determinant(&[0.0, 2.0, 3.0, 4.0], 2), -6.0);
    assert_eq!(determinant(&[0.0, 1.0, 0.0, 1.0], 2), 0.0);
}
