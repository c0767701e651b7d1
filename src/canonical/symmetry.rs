//! Point symmetries of a Lagrangian beyond ignorable coordinates (issue 15 item 3; PHYSICS.md
//! §2.6, Noether's theorem with a total-derivative term).
//!
//! A generator `ξ_i(q, t)` is a symmetry when the first-order change of `L` is a total
//! derivative, `δL = Σ (∂L/∂q_i ξ_i + ∂L/∂q'_i ξ̇_i) = dF/dt`; then
//! `Q = Σ ∂L/∂q'_i ξ_i − F` is conserved (in momenta: `Σ p_i ξ_i − F`). The search takes the
//! polynomial ansatz `ξ_i = a_i + b_i t + Σ_j c_ij q_j` (degree ≤ 1 in `q` and `t`: this holds
//! translations, rotations and Galilean boosts) and `F = Σ_j f_j q_j + g t`, so the condition is
//! linear in the unknowns `(f, g, a, b, c)`:
//!
//! 1. the condition is sampled at random points of `(q, q', t)` and of the parameters, and the
//!    null space of the sampled linear system is found by Gaussian elimination (columns of
//!    `F` first, so each null vector is fixed by its `ξ` part);
//! 2. each null vector's `ξ` coefficients are read as small rationals (they do not depend on
//!    the parameters), `δL` is formed exactly, and `F` is read off it symbolically: `f_j` is
//!    the coefficient of `q'_j` and `g` the rest, both required to be constants;
//! 3. each charge is verified: `{Q, H} + ∂Q/∂t` must be zero (proven, or said how decided).
//!
//! The search is bounded by the degree of the ansatz, and [`SymmetrySearch::bound`] says so:
//! a symmetry outside it (a non-linear generator, a time change other than the energy's) is
//! not excluded.

use num_traits::ToPrimitive;

use crate::diff::Differentiator;
use crate::eval::eval_with;
use crate::expr::{Expr, Rational, Symbol};

use super::reduce::{normalize, tidy, ZeroCheck};
use super::{is_integral, time, PhaseSpace};

/// One point symmetry and its conserved charge.
#[derive(Clone, Debug)]
pub struct PointSymmetry {
    /// `ξ_i(q, t)`, one per coordinate.
    pub generator: Vec<Expr>,
    /// `F(q, t)` with `δL = dF/dt` (zero for a strict symmetry).
    pub gauge: Expr,
    /// The charge in momenta, `Σ p_i ξ_i − F`.
    pub charge: Expr,
    /// The same charge in velocities, `Σ ∂L/∂q'_i ξ_i − F`.
    pub charge_velocities: Expr,
    /// What the generator is, in words (`rotation in (x, y)`, `Galilean boost`, …).
    pub kind: String,
    /// `{Q, H} + ∂Q/∂t`, decided.
    pub check: ZeroCheck,
}

/// The symmetries found and the bound of the search.
#[derive(Clone, Debug)]
pub struct SymmetrySearch {
    /// One per independent generator found.
    pub found: Vec<PointSymmetry>,
    /// The ansatz, in words.
    pub bound: String,
}

/// The largest system searched.
pub const MAX_COORDS: usize = 6;

/// Samples of the linear condition (more rows than unknowns, for a clean rank).
const SAMPLES_PER_UNKNOWN: usize = 3;

/// Searches `l(q, q', t)` for point symmetries of the linear ansatz; `h` is the Hamiltonian used
/// to verify each charge.
pub fn point_symmetries(l: &Expr, coords: &[Symbol], h: &Expr) -> SymmetrySearch {
    if coords.len() > MAX_COORDS {
        return SymmetrySearch {
            found: Vec::new(),
            bound: format!("not searched: {} coordinates (the search samples a linear system that grows like n³; limit {MAX_COORDS})", coords.len()),
        };
    }
    let bound =
        "ξ(q, t) of degree ≤ 1 in q and t, F(q, t) linear; symmetries outside this ansatz are not excluded".to_string();
    let n = coords.len();
    let t = time();
    let vel: Vec<Symbol> = coords.iter().map(Symbol::prime).collect();
    let mut d = Differentiator::new();
    let dl_dq: Vec<Expr> = coords.iter().map(|q| d.diff(l, q)).collect();
    let dl_dv: Vec<Expr> = vel.iter().map(|v| d.diff(l, v)).collect();
    // Basis of ξ_i: 1, t, q_1 … q_n; its time derivatives 0, 1, q'_1 … q'_n.
    let mut phi = vec![Expr::one(), Expr::sym(t.clone())];
    phi.extend(coords.iter().cloned().map(Expr::sym));
    let mut phi_dot = vec![Expr::zero(), Expr::one()];
    phi_dot.extend(vel.iter().cloned().map(Expr::sym));
    let m = phi.len();
    // Columns: F's f_1 … f_n and g, then ξ's u_{ik}.
    let mut columns: Vec<Expr> = vel.iter().map(|v| Expr::sym(v.clone()).neg()).collect();
    columns.push(Expr::int(-1));
    for i in 0..n {
        for k in 0..m {
            columns.push(dl_dq[i].times(&phi[k]).plus(&dl_dv[i].times(&phi_dot[k])));
        }
    }
    let nf = n + 1;
    let unknowns = columns.len();
    // Every other symbol (parameters) gets a random positive value per row.
    let mut others: Vec<Symbol> =
        l.free_symbols().into_iter().filter(|s| !coords.contains(s) && !vel.contains(s) && *s != t).collect();
    others.sort_by_key(|s| s.to_string());
    let mut rng = 0x5EED_u64 ^ (unknowns as u64);
    let mut next = move || {
        rng = rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let params: Vec<f64> = others.iter().map(|_| 0.5 + next()).collect();
    let mut rows = Vec::new();
    let mut attempts = 0;
    while rows.len() < SAMPLES_PER_UNKNOWN * unknowns && attempts < 20 * unknowns {
        attempts += 1;
        let point: Vec<f64> = (0..2 * n + 1).map(|_| 2.0 * next() - 1.0).collect();
        let lookup = |s: &Symbol| {
            if let Some(i) = coords.iter().position(|q| q == s) {
                return Some(point[i]);
            }
            if let Some(i) = vel.iter().position(|v| v == s) {
                return Some(point[n + i]);
            }
            if *s == t {
                return Some(point[2 * n]);
            }
            others.iter().position(|o| o == s).map(|i| params[i])
        };
        let row: Vec<f64> = columns.iter().map(|c| eval_with(c, &lookup).unwrap_or(f64::NAN)).collect();
        if row.iter().all(|x| x.is_finite()) {
            rows.push(row);
        }
    }
    if rows.len() < unknowns {
        let bound =
            "not searched: L could not be evaluated at enough sample points (a declared function has no values)"
                .to_string();
        return SymmetrySearch { found: Vec::new(), bound };
    }
    let found = null_space(rows, unknowns)
        .into_iter()
        .filter_map(|v| exact_symmetry(&v[nf..], n, &phi, &phi_dot, &dl_dq, &dl_dv, coords, &vel, h))
        .collect();
    SymmetrySearch { found, bound }
}

/// Null vectors of the sampled system, one per free column, with that column set to 1.
fn null_space(mut a: Vec<Vec<f64>>, cols: usize) -> Vec<Vec<f64>> {
    let scale = a.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs())).max(1.0);
    let tol = 1e-9 * scale;
    let mut pivots = Vec::new();
    let mut r = 0;
    for c in 0..cols {
        let Some(p) = (r..a.len()).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())) else { break };
        if a[p][c].abs() <= tol {
            continue;
        }
        a.swap(r, p);
        let pv = a[r][c];
        for x in a[r].iter_mut() {
            *x /= pv;
        }
        for i in 0..a.len() {
            if i != r && a[i][c] != 0.0 {
                let f = a[i][c];
                let row_r = a[r].clone();
                for (x, y) in a[i].iter_mut().zip(&row_r) {
                    *x -= f * y;
                }
            }
        }
        pivots.push(c);
        r += 1;
    }
    let mut out = Vec::new();
    for free in (0..cols).filter(|c| !pivots.contains(c)) {
        let mut v = vec![0.0; cols];
        v[free] = 1.0;
        for (row, &pc) in pivots.iter().enumerate() {
            v[pc] = -a[row][free];
        }
        out.push(v);
    }
    out
}

/// A float as a rational with a small denominator, if it is one.
fn small_rational(x: f64) -> Option<Rational> {
    (1..=12i64).find_map(|den| {
        let num = (x * den as f64).round();
        let close = (x - num / den as f64).abs() < 1e-7;
        let num = num.to_i64().filter(|n| n.abs() < 1 << 20)?;
        close.then(|| Rational::new(num.into(), den.into()))
    })
}

#[allow(clippy::too_many_arguments)]
fn exact_symmetry(
    xi_coeffs: &[f64],
    n: usize,
    phi: &[Expr],
    phi_dot: &[Expr],
    dl_dq: &[Expr],
    dl_dv: &[Expr],
    coords: &[Symbol],
    vel: &[Symbol],
    h: &Expr,
) -> Option<PointSymmetry> {
    let m = phi.len();
    let u: Vec<Rational> = xi_coeffs.iter().map(|&x| small_rational(x)).collect::<Option<_>>()?;
    let mut xi = Vec::new();
    let mut xi_dot = Vec::new();
    for i in 0..n {
        let row = &u[i * m..(i + 1) * m];
        xi.push(Expr::add(row.iter().zip(phi).map(|(c, f)| Expr::num(c.clone()).times(f))));
        xi_dot.push(Expr::add(row.iter().zip(phi_dot).map(|(c, f)| Expr::num(c.clone()).times(f))));
    }
    if xi.iter().all(Expr::is_zero) {
        return None;
    }
    let delta = normalize(&Expr::add((0..n).map(|i| dl_dq[i].times(&xi[i]).plus(&dl_dv[i].times(&xi_dot[i])))));
    // δL = Σ f_j q'_j + g with constant f_j, g.
    let mut d = Differentiator::new();
    let t = time();
    let constant = |e: &Expr| !coords.iter().chain(vel).any(|s| e.contains(s)) && !e.contains(&t);
    let f: Vec<Expr> = vel.iter().map(|v| normalize(&d.diff(&delta, v))).collect();
    if !f.iter().all(constant) {
        return None;
    }
    let g = normalize(&delta.minus(&Expr::add(vel.iter().zip(&f).map(|(v, fj)| Expr::sym(v.clone()).times(fj)))));
    if !constant(&g) {
        return None;
    }
    let gauge = tidy(
        &Expr::add(coords.iter().zip(&f).map(|(q, fj)| Expr::sym(q.clone()).times(fj))).plus(&g.times(&Expr::sym(t))),
    );
    let ps = PhaseSpace::new(coords.iter().map(|q| q.name())).ok()?;
    let charge = tidy(&Expr::add(ps.momenta.iter().zip(&xi).map(|(p, x)| Expr::sym(p.clone()).times(x))).minus(&gauge));
    let check = is_integral(&charge, h, &ps);
    let charge_velocities = tidy(&Expr::add(dl_dv.iter().zip(&xi).map(|(p, x)| p.times(x))).minus(&gauge));
    let kind = describe(&u, n, m, coords, &gauge);
    Some(PointSymmetry { generator: xi, gauge, charge, charge_velocities, kind, check })
}

/// The generator in words, from its coefficients `u[i·m + k]` over `1, t, q_1 … q_n`.
fn describe(u: &[Rational], n: usize, m: usize, coords: &[Symbol], gauge: &Expr) -> String {
    let c = |i: usize, k: usize| &u[i * m + k];
    let zero = |r: &Rational| num_traits::Zero::is_zero(r);
    let has_q = (0..n).any(|i| (2..m).any(|k| !zero(c(i, k))));
    let has_t = (0..n).any(|i| !zero(c(i, 1)));
    if !has_q && !has_t {
        return "translation".to_string();
    }
    if !has_q {
        return if gauge.is_zero() {
            "time-dependent translation".into()
        } else {
            "Galilean boost (δL = dF/dt)".into()
        };
    }
    // Antisymmetric c_ij: a rotation in the planes where it is non-zero.
    let antisym = (0..n).all(|i| (0..n).all(|j| *c(i, 2 + j) == -c(j, 2 + i).clone()));
    if antisym && !has_t {
        let planes: Vec<String> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .filter(|&(i, j)| !zero(c(i, 2 + j)))
            .map(|(i, j)| format!("({}, {})", coords[i], coords[j]))
            .collect();
        return format!("rotation in {}", planes.join(", "));
    }
    "linear point symmetry".to_string()
}
