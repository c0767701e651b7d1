//! Geodesics from a line element `ds² = Σ g_ij(q) dq_i dq_j` (PHYSICS.md §1, (1.19)–(1.20)):
//! the metric, the Christoffel symbols of the second kind
//! `Γ^k_ij = ½ Σ_l g^{kl} (∂_i g_jl + ∂_j g_il − ∂_l g_ij)`, the geodesic equations
//! `q''_k + Σ_ij Γ^k_ij q'_i q'_j = 0`, and the energy Lagrangian `½ q'ᵀ g q'` whose
//! Euler–Lagrange equations they are (constant-speed parametrisation), so its Noether
//! quantities are the geodesics' conserved quantities.
//!
//! A line element names the differential of coordinate `x` as `dx` (`dθ^2 + sin(θ)^2 dφ^2`).
//!
//! [`Geodesic::curvature`] gives the Riemann tensor, the scalar curvature and, for a
//! surface, the Gauss curvature `K` (§1.6.3 "curvature of geodesics": on a surface the
//! geodesics' spreading is governed by `K`; the unit sphere has `K = 1`, a plane in polar
//! coordinates `K = 0`).

use std::collections::HashMap;

use crate::algebra::expand;
use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::linalg::{adjugate, determinant, MAX_CLOSED_FORM};
use super::system::{contains_any, System};
use super::tidy::tidy;
use super::MechanicsError;

/// The geometry of a metric and its geodesic equations.
#[derive(Clone, Debug, PartialEq)]
pub struct Geodesic {
    /// The coordinates.
    pub coords: Vec<Symbol>,
    /// `g_ij`, symmetric.
    pub metric: Vec<Vec<Expr>>,
    /// `Γ^k_ij` as `christoffel[k][i][j]`.
    pub christoffel: Vec<Vec<Vec<Expr>>>,
    /// `q''_k + Σ Γ^k_ij q'_i q'_j`, each `= 0`.
    pub equations: Vec<Expr>,
    /// The energy Lagrangian `½ Σ g_ij q'_i q'_j`.
    pub lagrangian: Expr,
}

/// Reads the metric off a line element and derives the geodesic equations.
pub fn geodesic(ds2: &Expr, coords: &[Symbol]) -> Result<Geodesic, MechanicsError> {
    let n = coords.len();
    if n == 0 {
        return Err(MechanicsError::NoCoordinates);
    }
    if n > MAX_CLOSED_FORM {
        return Err(MechanicsError::TooLarge { n, limit: MAX_CLOSED_FORM });
    }
    let diffs: Vec<Symbol> = coords.iter().map(|q| Symbol::new(&format!("d{}", q.name()))).collect();
    let free = ds2.free_symbols();
    if !diffs.iter().any(|d| free.contains(d)) {
        return Err(MechanicsError::BadMetric(format!(
            "the line element contains none of the differentials {}",
            diffs.iter().map(Symbol::to_string).collect::<Vec<_>>().join(", ")
        )));
    }
    if let Some(v) = free.iter().find(|s| s.primes() > 0) {
        return Err(MechanicsError::BadMetric(format!(
            "the line element contains the velocity `{v}`; write differentials `d{}`",
            v.name()
        )));
    }
    let mut d = Differentiator::new();
    let mut metric = vec![vec![Expr::zero(); n]; n];
    for i in 0..n {
        for j in i..n {
            let di = d.diff(ds2, &diffs[i]);
            let g = tidy(&d.diff(&di, &diffs[j]).times(&Expr::frac(1, 2)));
            if contains_any(&g, &diffs) {
                return Err(MechanicsError::BadMetric(format!(
                    "ds² is not quadratic in the differentials: ∂²ds²/∂{}∂{} still contains one",
                    diffs[i], diffs[j]
                )));
            }
            metric[i][j] = g.clone();
            metric[j][i] = g;
        }
    }
    // ds² must be exactly the quadratic form (no linear or constant terms in the dq).
    let mut quad = Vec::new();
    for i in 0..n {
        for j in 0..n {
            quad.push(Expr::mul([metric[i][j].clone(), Expr::sym(diffs[i].clone()), Expr::sym(diffs[j].clone())]));
        }
    }
    let rest = expand(&ds2.minus(&Expr::add(quad))).map_err(|e| MechanicsError::BadMetric(e.to_string()))?;
    if !rest.is_zero() {
        return Err(MechanicsError::BadMetric(format!(
            "ds² has terms that are not quadratic in the differentials: {rest}"
        )));
    }
    let det = determinant(&metric);
    if det.is_zero() {
        return Err(MechanicsError::BadMetric("the metric is singular everywhere (det g = 0)".into()));
    }
    let adj = adjugate(&metric);
    // Christoffel symbols of the first kind Γ_lij = ½ (∂_i g_jl + ∂_j g_il − ∂_l g_ij).
    let dg: Vec<Vec<Vec<Expr>>> =
        (0..n).map(|i| (0..n).map(|j| coords.iter().map(|q| d.diff(&metric[i][j], q)).collect()).collect()).collect();
    let first =
        |l: usize, i: usize, j: usize| dg[j][l][i].plus(&dg[i][l][j]).minus(&dg[i][j][l]).times(&Expr::frac(1, 2));
    let mut christoffel = vec![vec![vec![Expr::zero(); n]; n]; n];
    for k in 0..n {
        for i in 0..n {
            for j in i..n {
                let s = Expr::add((0..n).map(|l| adj[k][l].times(&first(l, i, j))));
                let c = tidy(&s.over(&det));
                christoffel[k][i][j] = c.clone();
                christoffel[k][j][i] = c;
            }
        }
    }
    let v: Vec<Expr> = coords.iter().map(|q| Expr::sym(q.prime())).collect();
    let equations = (0..n)
        .map(|k| {
            let mut terms = vec![Expr::sym(coords[k].with_primes(2))];
            for i in 0..n {
                for j in 0..n {
                    terms.push(Expr::mul([christoffel[k][i][j].clone(), v[i].clone(), v[j].clone()]));
                }
            }
            tidy(&Expr::add(terms))
        })
        .collect();
    let to_vel: HashMap<Symbol, Expr> = diffs.iter().cloned().zip(v.iter().cloned()).collect();
    let lagrangian = tidy(&ds2.subs(&to_vel).times(&Expr::frac(1, 2)));
    Ok(Geodesic { coords: coords.to_vec(), metric, christoffel, equations, lagrangian })
}

impl Geodesic {
    /// The energy Lagrangian as a [`System`] (its `conserved()` are the geodesics' integrals,
    /// its compiled right-hand side integrates them).
    pub fn system(&self) -> Result<System, MechanicsError> {
        System::from_lagrangian_expr(self.lagrangian.clone(), &self.coords)
    }
}

/// The curvature of a metric (§1.6.3): the Riemann tensor, its scalar, and for a surface
/// the Gauss curvature.
#[derive(Clone, Debug, PartialEq)]
pub struct Curvature {
    /// `R^a_bcd = ∂_c Γ^a_db − ∂_d Γ^a_cb + Σ_e (Γ^a_ce Γ^e_db − Γ^a_de Γ^e_cb)` as
    /// `riemann[a][b][c][d]` (the sign convention of Misner, Thorne & Wheeler (11.12), in
    /// which the unit sphere has `R_θφθφ = sin²θ > 0`).
    pub riemann: Vec<Vec<Vec<Vec<Expr>>>>,
    /// `R_abcd = Σ_e g_ae R^e_bcd`.
    pub lowered: Vec<Vec<Vec<Vec<Expr>>>>,
    /// The scalar curvature `R = Σ g^bd R^a_bad`.
    pub scalar: Expr,
    /// For two coordinates, the Gauss curvature `K = R_1212 / det g` (`R = 2K`).
    pub gauss: Option<Expr>,
}

impl Geodesic {
    /// The curvature of the metric, from the Christoffel symbols.
    pub fn curvature(&self) -> Curvature {
        let n = self.coords.len();
        let mut d = Differentiator::new();
        let g = &self.christoffel;
        // ∂_c Γ^a_db, as dg[c][a][d][b].
        let dg: Vec<Vec<Vec<Vec<Expr>>>> = self
            .coords
            .iter()
            .map(|q| {
                (0..n).map(|a| (0..n).map(|x| (0..n).map(|y| d.diff(&g[a][x][y], q)).collect()).collect()).collect()
            })
            .collect();
        let mut riemann = vec![vec![vec![vec![Expr::zero(); n]; n]; n]; n];
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    for e in c + 1..n {
                        let mut terms = vec![dg[c][a][e][b].clone(), dg[e][a][c][b].neg()];
                        for k in 0..n {
                            terms.push(g[a][c][k].times(&g[k][e][b]));
                            terms.push(g[a][e][k].times(&g[k][c][b]).neg());
                        }
                        let r = tidy(&Expr::add(terms));
                        riemann[a][b][e][c] = tidy(&r.neg());
                        riemann[a][b][c][e] = r;
                    }
                }
            }
        }
        let mut lowered = vec![vec![vec![vec![Expr::zero(); n]; n]; n]; n];
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    for e in 0..n {
                        let s = Expr::add((0..n).map(|k| self.metric[a][k].times(&riemann[k][b][c][e])));
                        lowered[a][b][c][e] = tidy(&s);
                    }
                }
            }
        }
        let det = determinant(&self.metric);
        let adj = adjugate(&self.metric);
        let mut terms = Vec::new();
        for a in 0..n {
            for b in 0..n {
                for e in 0..n {
                    terms.push(adj[b][e].times(&riemann[a][b][a][e]));
                }
            }
        }
        let scalar = tidy(&Expr::add(terms).over(&det));
        let gauss = (n == 2).then(|| tidy(&lowered[0][1][0][1].over(&det)));
        Curvature { riemann, lowered, scalar, gauss }
    }
}
