//! Fraction-free symbolic linear algebra on small symmetric matrices: the determinant and the
//! adjugate by cofactor expansion, so `W⁻¹ = adj(W) / det(W)` never divides inside an entry.
//!
//! Cofactor expansion costs `n!` terms; the mechanics module uses it only up to
//! [`MAX_CLOSED_FORM`] coupled velocities, and on diagonal matrices directly.

use crate::expr::Expr;

use super::tidy::tidy;

/// The largest `n` for which a closed-form inverse of a full `n × n` matrix is formed.
pub const MAX_CLOSED_FORM: usize = 4;

fn minor(m: &[Vec<Expr>], row: usize, col: usize) -> Vec<Vec<Expr>> {
    m.iter()
        .enumerate()
        .filter(|(i, _)| *i != row)
        .map(|(_, r)| r.iter().enumerate().filter(|(j, _)| *j != col).map(|(_, x)| x.clone()).collect())
        .collect()
}

fn det_raw(m: &[Vec<Expr>]) -> Expr {
    match m.len() {
        0 => Expr::one(),
        1 => m[0][0].clone(),
        2 => m[0][0].times(&m[1][1]).minus(&m[0][1].times(&m[1][0])),
        n => {
            // Expand along the row with the most zeros.
            let row = (0..n).max_by_key(|&i| (m[i].iter().filter(|x| x.is_zero()).count(), n - i)).unwrap_or(0);
            let mut terms = Vec::new();
            for j in 0..n {
                if m[row][j].is_zero() {
                    continue;
                }
                let sign = if (row + j) % 2 == 0 { Expr::one() } else { Expr::int(-1) };
                terms.push(Expr::mul([sign, m[row][j].clone(), det_raw(&minor(m, row, j))]));
            }
            Expr::add(terms)
        }
    }
}

/// The determinant of a square matrix, tidied.
pub fn determinant(m: &[Vec<Expr>]) -> Expr {
    tidy(&det_raw(m))
}

/// The adjugate (transposed cofactor matrix), entries tidied: `m · adj(m) = det(m) · I`.
pub fn adjugate(m: &[Vec<Expr>]) -> Vec<Vec<Expr>> {
    let n = m.len();
    if n == 1 {
        return vec![vec![Expr::one()]];
    }
    let mut adj = vec![vec![Expr::zero(); n]; n];
    for i in 0..n {
        for j in 0..n {
            let sign = if (i + j) % 2 == 0 { Expr::one() } else { Expr::int(-1) };
            adj[j][i] = tidy(&sign.times(&det_raw(&minor(m, i, j))));
        }
    }
    adj
}

/// The inverse of a matrix that decouples into blocks (coordinates linked by nonzero
/// off-diagonal entries, in either triangle), each inverted in closed form: `1/m_ii` for a
/// block of one, `adj/det` of the block up to [`MAX_CLOSED_FORM`]. A diagonal 8 × 8 metric or
/// mass matrix is then as easy as a 1 × 1 one; a block coupling more than
/// [`MAX_CLOSED_FORM`] coordinates is `Err` with its size.
pub fn inverse_by_blocks(m: &[Vec<Expr>]) -> Result<Vec<Vec<Expr>>, usize> {
    let n = m.len();
    // Union–find over the nonzero couplings.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in 0..n {
            if i != j && !m[i][j].is_zero() {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    for i in 0..n {
        let r = root(&mut parent, i);
        match blocks.iter_mut().find(|b| root(&mut parent, b[0]) == r) {
            Some(b) => b.push(i),
            None => blocks.push(vec![i]),
        }
    }
    let mut inv = vec![vec![Expr::zero(); n]; n];
    for block in &blocks {
        if block.len() > MAX_CLOSED_FORM {
            return Err(block.len());
        }
        let sub: Vec<Vec<Expr>> = block.iter().map(|&i| block.iter().map(|&j| m[i][j].clone()).collect()).collect();
        let det = determinant(&sub);
        let adj = adjugate(&sub);
        for (a, &i) in block.iter().enumerate() {
            for (b, &j) in block.iter().enumerate() {
                inv[i][j] = tidy(&adj[a][b].over(&det));
            }
        }
    }
    Ok(inv)
}

/// Whether every off-diagonal entry is zero.
pub fn is_diagonal(m: &[Vec<Expr>]) -> bool {
    m.iter().enumerate().all(|(i, r)| r.iter().enumerate().all(|(j, x)| i == j || x.is_zero()))
}
