//! Dense linear algebra on small row-major `f64` matrices: Gaussian elimination with partial
//! pivoting (LU), Cholesky, and the determinant, written once for every caller.
//!
//! Why not nalgebra here: these run inside right-hand sides on stack or per-thread scratch
//! buffers (no allocation per call), the bit-for-bit native back ends reproduce the exact
//! operation order of the Cholesky factorisation, and a rounding change moves Newton's step
//! counts (the Ritz solver took 4 steps instead of 2 with nalgebra's LU on the notes'
//! four-coefficient oscillator). nalgebra stays where a caller wants what it has and this
//! does not (eigenvalues, SVD, symmetric eigen-decompositions: `integrate/gauss.rs`,
//! `chaos.rs`, `canonical/generating.rs`).

/// How a matrix was factorised in place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Factor {
    /// `A = L Lᵀ`, `L` in the lower triangle.
    Cholesky,
    /// `P A = L U` with unit `L` below the diagonal, `U` on and above, `perm` the row order.
    Lu,
}

/// The pivot at or below which an `n × n` matrix counts as singular to working precision:
/// `n·ε·max|a_ij|`.
pub fn singular_below(a: &[f64], n: usize) -> f64 {
    let scale = a[..n * n].iter().fold(0.0f64, |s, x| s.max(x.abs()));
    n as f64 * f64::EPSILON * scale
}

/// `P A = L U` in place by Gaussian elimination with partial pivoting (the first row of
/// largest magnitude): the multipliers of the unit `L` below the diagonal, `U` on and above.
/// `swapped(j, p)` is told of each row exchange, for the caller to apply to what goes with
/// the rows (a permutation, a right-hand side, a sign). A pivot no larger than `tol` stops it:
/// the error is its column.
pub fn lu_in_place(m: &mut [f64], n: usize, tol: f64, mut swapped: impl FnMut(usize, usize)) -> Result<(), usize> {
    for j in 0..n {
        let mut piv = j;
        for i in j + 1..n {
            if m[i * n + j].abs() > m[piv * n + j].abs() {
                piv = i;
            }
        }
        if m[piv * n + j].abs() <= tol {
            return Err(j);
        }
        if piv != j {
            for k in 0..n {
                m.swap(j * n + k, piv * n + k);
            }
            swapped(j, piv);
        }
        let d = m[j * n + j];
        for i in j + 1..n {
            let f = m[i * n + j] / d;
            m[i * n + j] = f;
            for k in j + 1..n {
                m[i * n + k] -= f * m[j * n + k];
            }
        }
    }
    Ok(())
}

/// Solves `L U x = b` with the factors of [`lu_in_place`] (`b` already in the pivots' row
/// order): `x` holds `b` on entry and the solution on exit.
pub fn lu_substitute(m: &[f64], n: usize, x: &mut [f64]) {
    for i in 0..n {
        let mut v = x[i];
        for k in 0..i {
            v -= m[i * n + k] * x[k];
        }
        x[i] = v;
    }
    for i in (0..n).rev() {
        let mut v = x[i];
        for k in i + 1..n {
            v -= m[i * n + k] * x[k];
        }
        x[i] = v / m[i * n + i];
    }
}

/// Solves `a x = b` in place (`a` overwritten by its factors, `x` into `b`). A pivot no larger
/// than [`singular_below`] is a degenerate matrix; the error is its column. A matrix with no
/// finite non-zero entry (all zeros or NaN, as a Newton Jacobian evaluated past its domain) is
/// degenerate at column 0 rather than solved into NaN: the callers report a degenerate
/// Jacobian or two-form there, not a non-finite state later.
pub fn solve_in_place(a: &mut [f64], b: &mut [f64], n: usize) -> Result<(), usize> {
    let tol = singular_below(a, n);
    if n > 0 && tol == 0.0 {
        return Err(0);
    }
    lu_in_place(a, n, tol, |j, p| b.swap(j, p))?;
    lu_substitute(a, n, b);
    Ok(())
}

/// `A = L Lᵀ` in place (`L` in the lower triangle; the upper is left as it was); `false` when
/// a pivot is not above `tol` (not positive definite to working precision).
pub fn cholesky_in_place(m: &mut [f64], n: usize, tol: f64) -> bool {
    for j in 0..n {
        let mut d = m[j * n + j];
        for k in 0..j {
            d -= m[j * n + k] * m[j * n + k];
        }
        if d <= tol {
            return false;
        }
        let l = d.sqrt();
        m[j * n + j] = l;
        for i in j + 1..n {
            let mut x = m[i * n + j];
            for k in 0..j {
                x -= m[i * n + k] * m[j * n + k];
            }
            m[i * n + j] = x / l;
        }
    }
    true
}

/// Factorises the `n × n` row-major matrix `a` into `m`: Cholesky when `try_cholesky` and the
/// matrix is positive definite, otherwise LU with partial pivoting. `perm` receives the row
/// order (as `f64`, exact for any realistic `n`). A pivot no larger than [`singular_below`]
/// means singular to working precision; the error carries the column of the failing pivot.
pub fn factor(a: &[f64], m: &mut [f64], perm: &mut [f64], n: usize, try_cholesky: bool) -> Result<Factor, usize> {
    let tol = singular_below(a, n);
    if try_cholesky {
        m[..n * n].copy_from_slice(&a[..n * n]);
        if cholesky_in_place(m, n, tol) {
            return Ok(Factor::Cholesky);
        }
    }
    m[..n * n].copy_from_slice(&a[..n * n]);
    for (i, p) in perm.iter_mut().enumerate().take(n) {
        *p = i as f64;
    }
    lu_in_place(m, n, tol, |j, p| perm.swap(j, p))?;
    Ok(Factor::Lu)
}

/// Solves with a factorisation from [`factor`]: `x` holds the right-hand side on entry and the
/// solution on exit; `tmp` is `n` values of workspace.
pub fn solve(kind: Factor, m: &[f64], perm: &[f64], n: usize, x: &mut [f64], tmp: &mut [f64]) {
    match kind {
        Factor::Cholesky => {
            for i in 0..n {
                let mut v = x[i];
                for k in 0..i {
                    v -= m[i * n + k] * x[k];
                }
                x[i] = v / m[i * n + i];
            }
            for i in (0..n).rev() {
                let mut v = x[i];
                for k in i + 1..n {
                    v -= m[k * n + i] * x[k];
                }
                x[i] = v / m[i * n + i];
            }
        }
        Factor::Lu => {
            for i in 0..n {
                tmp[i] = x[perm[i] as usize];
            }
            lu_substitute(m, n, &mut tmp[..n]);
            x[..n].copy_from_slice(&tmp[..n]);
        }
    }
}

/// The determinant of a small row-major matrix (exactly 0 when a pivot is exactly 0).
pub fn determinant(m: &[f64], n: usize) -> f64 {
    let mut a = m[..n * n].to_vec();
    let mut sign = 1.0;
    if lu_in_place(&mut a, n, 0.0, |_, _| sign = -sign).is_err() {
        return 0.0;
    }
    // Negation is exact, so the sign applied last gives the bits of flipping it between the
    // products.
    sign * (0..n).fold(1.0, |d, j| d * a[j * n + j])
}
