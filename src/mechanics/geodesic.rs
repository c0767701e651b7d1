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

use crate::algebra::{cancel, expand, numer_denom, together, trig_normalize};
use crate::diff::Differentiator;
use crate::expr::{Expr, Func, Node, Symbol};
use crate::print::{render, symbol, Format};

use super::linalg::{adjugate, determinant, inverse_by_blocks, MAX_CLOSED_FORM};
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
    geodesic_from_metric(metric, coords)
}

/// The geodesic equations of a metric given as a matrix `g_ij(q)` (rows in coordinate
/// order). The matrix must be square, symmetric (`g_ij − g_ji` tidies to zero) and not
/// singular everywhere, and its entries must not contain velocities.
pub fn geodesic_from_metric(metric: Vec<Vec<Expr>>, coords: &[Symbol]) -> Result<Geodesic, MechanicsError> {
    let n = coords.len();
    if n == 0 {
        return Err(MechanicsError::NoCoordinates);
    }
    if metric.len() != n || metric.iter().any(|row| row.len() != n) {
        return Err(MechanicsError::BadMetric(format!(
            "the metric must be a {n}×{n} matrix for the {n} coordinates; its rows have {:?} entries",
            metric.iter().map(Vec::len).collect::<Vec<_>>()
        )));
    }
    for (i, row) in metric.iter().enumerate() {
        for (j, g) in row.iter().enumerate() {
            if let Some(v) = g.free_symbols().iter().find(|s| s.primes() > 0) {
                return Err(MechanicsError::BadMetric(format!(
                    "g[{},{}] contains the velocity `{v}`; a metric depends on the coordinates only",
                    coords[i], coords[j]
                )));
            }
            if j > i && !tidy(&g.minus(&metric[j][i])).is_zero() {
                return Err(MechanicsError::BadMetric(format!(
                    "the metric is not symmetric: g[{a},{b}] = {g} but g[{b},{a}] = {h}",
                    a = coords[i],
                    b = coords[j],
                    h = metric[j][i]
                )));
            }
        }
    }
    let metric: Vec<Vec<Expr>> = metric.into_iter().map(|row| row.iter().map(tidy).collect()).collect();
    let mut d = Differentiator::new();
    // Christoffel symbols of the first kind Γ_lij = ½ (∂_i g_jl + ∂_j g_il − ∂_l g_ij).
    let first = first_kind(&metric, coords, &mut d);
    let mut christoffel = vec![vec![vec![Expr::zero(); n]; n]; n];
    // Raised with g⁻¹: up to four coordinates as adj(g)/det g, beyond that block by block
    // (a diagonal metric in any dimension).
    let first = &first;
    let raise: Box<dyn Fn(usize, usize, usize) -> Expr + '_> = if n <= MAX_CLOSED_FORM {
        let det = determinant(&metric);
        if tidy(&det).is_zero() {
            return Err(MechanicsError::BadMetric("the metric is singular everywhere (det g = 0)".into()));
        }
        let adj = adjugate(&metric);
        Box::new(move |k, i, j| tidy(&Expr::add((0..n).map(|l| adj[k][l].times(&first[l][i][j]))).over(&det)))
    } else {
        let inv = inverse_of_metric(&metric)?;
        Box::new(move |k, i, j| tidy(&Expr::add((0..n).map(|l| inv[k][l].times(&first[l][i][j])))))
    };
    for k in 0..n {
        for i in 0..n {
            for j in i..n {
                let c = raise(k, i, j);
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
    let mut quad = Vec::new();
    for i in 0..n {
        for j in 0..n {
            quad.push(Expr::mul([metric[i][j].clone(), v[i].clone(), v[j].clone()]));
        }
    }
    let lagrangian = tidy(&Expr::add(quad).times(&Expr::frac(1, 2)));
    Ok(Geodesic { coords: coords.to_vec(), metric, christoffel, equations, lagrangian })
}

/// `g⁻¹` of a metric of more than [`MAX_CLOSED_FORM`] coordinates, block by block; a block
/// that couples more of them, or one singular everywhere, is refused.
fn inverse_of_metric(metric: &[Vec<Expr>]) -> Result<Vec<Vec<Expr>>, MechanicsError> {
    let inv = inverse_by_blocks(metric).map_err(|n| MechanicsError::TooLarge { n, limit: MAX_CLOSED_FORM })?;
    if inv.iter().flatten().any(Expr::is_undefined) {
        return Err(MechanicsError::BadMetric("the metric is singular everywhere (det g = 0)".into()));
    }
    Ok(inv)
}

/// `Γ_lij = ½ (∂_i g_jl + ∂_j g_il − ∂_l g_ij)` as `first[l][i][j]`.
fn first_kind(metric: &[Vec<Expr>], coords: &[Symbol], d: &mut Differentiator) -> Vec<Vec<Vec<Expr>>> {
    let n = coords.len();
    let dg: Vec<Vec<Vec<Expr>>> =
        (0..n).map(|i| (0..n).map(|j| coords.iter().map(|q| d.diff(&metric[i][j], q)).collect()).collect()).collect();
    (0..n)
        .map(|l| {
            (0..n)
                .map(|i| {
                    (0..n)
                        .map(|j| dg[j][l][i].plus(&dg[i][l][j]).minus(&dg[i][j][l]).times(&Expr::frac(1, 2)))
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// A surface (or any submanifold) `x = X(q)` embedded in Euclidean space, §1.6.3: the
/// induced metric `g_ij = X_i · X_j` (`X_i = ∂X/∂q_i`), its geodesics, and the components
/// of a geodesic's curvature vector `κ = d²x/ds²` along the tangent vectors `X_l`.
///
/// Along a curve `q(s)`, `κ = Σ_ij X_ij q'_i q'_j + Σ_k X_k q''_k`; substituting the geodesic
/// equations `q''_k = −Σ Γ^k_ij q'_i q'_j` gives
/// `X_l · κ = Σ_ij (X_l · X_ij − Σ_k g_lk Γ^k_ij) q'_i q'_j`, and since
/// `X_l · X_ij = Γ_lij` (differentiate `g_jl = X_j · X_l`) every component vanishes: the
/// geodesic bends only along the normal. [`Embedding::tangential`] holds these components
/// as derived, each multiplied by `det g` (so no division is left) and expanded, which is
/// how their vanishing is shown rather than assumed.
#[derive(Clone, Debug, PartialEq)]
pub struct Embedding {
    /// `X(q)`, one component per Euclidean axis.
    pub surface: Vec<Expr>,
    /// The induced metric's geometry.
    pub geodesic: Geodesic,
    /// `det g · (X_l · κ)` after substituting the geodesic equations, expanded, per
    /// coordinate `l`; zero when the curvature vector is normal to the surface.
    pub tangential: Vec<Expr>,
    /// `X_l · κ` as derived (before the expansion), tidied: what the zero above comes from.
    pub tangential_raw: Vec<Expr>,
}

/// The induced metric of the embedding `x = X(q)` (components `surface`) and its geodesics.
pub fn embedded(surface: &[Expr], coords: &[Symbol]) -> Result<Embedding, MechanicsError> {
    let n = coords.len();
    if surface.len() < n {
        return Err(MechanicsError::BadMetric(format!(
            "an embedding of {n} coordinates needs at least {n} components X_1 … X_{n}; {} given",
            surface.len()
        )));
    }
    for x in surface {
        if let Some(v) = x.free_symbols().iter().find(|s| s.primes() > 0 || s.is_time()) {
            return Err(MechanicsError::BadMetric(format!(
                "the embedding contains `{v}`; X is a function of the coordinates {} and parameters",
                coords.iter().map(Symbol::to_string).collect::<Vec<_>>().join(", ")
            )));
        }
    }
    let mut d = Differentiator::new();
    // X_i (tangent vectors) and X_ij, each a list of Euclidean components.
    let xi: Vec<Vec<Expr>> = coords.iter().map(|q| surface.iter().map(|x| d.diff(x, q)).collect()).collect();
    let xij: Vec<Vec<Vec<Expr>>> =
        (0..n).map(|i| coords.iter().map(|q| xi[i].iter().map(|x| d.diff(x, q)).collect()).collect()).collect();
    let dot = |a: &[Expr], b: &[Expr]| Expr::add(a.iter().zip(b).map(|(x, y)| x.times(y)));
    let metric: Vec<Vec<Expr>> = (0..n).map(|i| (0..n).map(|j| dot(&xi[i], &xi[j])).collect()).collect();
    let metric_exact = metric.clone();
    let geodesic = geodesic_from_metric(metric, coords).map_err(|e| match e {
        MechanicsError::BadMetric(m) => MechanicsError::BadMetric(format!("the induced metric X_i · X_j: {m}")),
        e => e,
    })?;
    // Built from the unsimplified pieces with det g multiplied through, so the check is an
    // identity of polynomials in the entries: det g (X_l · X_ij) − Σ_k g_lk Σ_m adj_km Γ_mij.
    let det = determinant(&metric_exact);
    let adj = adjugate(&metric_exact);
    let first = first_kind(&metric_exact, coords, &mut d);
    let v: Vec<Expr> = coords.iter().map(|q| Expr::sym(q.prime())).collect();
    let mut tangential = Vec::new();
    let mut tangential_raw = Vec::new();
    for l in 0..n {
        let mut cleared = Vec::new();
        let mut raw = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let vv = v[i].times(&v[j]);
                let along = dot(&xi[l], &xij[i][j]);
                let mut gamma = Vec::new();
                for k in 0..n {
                    for m in 0..n {
                        gamma.push(Expr::mul([metric_exact[l][k].clone(), adj[k][m].clone(), first[m][i][j].clone()]));
                    }
                }
                cleared.push(det.times(&along).minus(&Expr::add(gamma)).times(&vv));
                let christ = Expr::add((0..n).map(|k| metric_exact[l][k].times(&geodesic.christoffel[k][i][j])));
                raw.push(along.minus(&christ).times(&vv));
            }
        }
        let e = Expr::add(cleared);
        let zero = expand(&e).map_err(|err| MechanicsError::BadMetric(format!("X_l · κ: {err}")))?;
        let zero = if zero.is_zero() { zero } else { crate::algebra::trig_normalize(&zero) };
        tangential.push(if zero.is_zero() { zero } else { tidy(&zero) });
        tangential_raw.push(tidy(&Expr::add(raw)));
    }
    Ok(Embedding { surface: surface.to_vec(), geodesic, tangential, tangential_raw })
}

impl Embedding {
    /// The printed lines of the embedding: `X = (…)`, then each `X_l · d²x/ds² = …` after the
    /// geodesic equations are substituted (`0` when shown to vanish).
    pub fn report(&self, format: Format) -> Vec<String> {
        let comps: Vec<String> = self.surface.iter().map(|x| render(x, format)).collect();
        let mut out = vec![format!("X = ({})", comps.join(", "))];
        for (l, q) in self.geodesic.coords.iter().enumerate() {
            let value =
                if self.tangential[l].is_zero() { "0".to_string() } else { render(&self.tangential_raw[l], format) };
            out.push(format!("X_{} · d²x/ds² = {value}    # geodesic equations substituted", symbol(q, format)));
        }
        out
    }
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
                        lowered[a][b][c][e] = curvature_form(&s);
                    }
                }
            }
        }
        let det = determinant(&self.metric);
        let contracted = |inv: &[Vec<Expr>]| {
            let mut terms = Vec::new();
            for a in 0..n {
                for b in 0..n {
                    for e in 0..n {
                        terms.push(inv[b][e].times(&riemann[a][b][a][e]));
                    }
                }
            }
            Expr::add(terms)
        };
        let mut scalar = if n <= MAX_CLOSED_FORM {
            curvature_form(&contracted(&adjugate(&self.metric)).over(&det))
        } else {
            // Block by block, as when the symbols were formed (which refused a larger block);
            // a hand-built `Geodesic` with one gets an undefined scalar, never a wrong 0.
            let inv = inverse_by_blocks(&self.metric).unwrap_or_else(|_| vec![vec![Expr::undefined(); n]; n]);
            curvature_form(&contracted(&inv))
        };
        let gauss = (n == 2).then(|| curvature_form(&lowered[0][1][0][1].over(&det)));
        // On a surface R = 2K identically; print whichever form of the two is shorter (the
        // contraction can leave a long sum that K's single component does not).
        if let Some(k) = &gauss {
            let twice = tidy(&k.times(&Expr::int(2)));
            if twice.op_count() < scalar.op_count() {
                scalar = twice;
            }
        }
        Curvature { riemann, lowered, scalar, gauss }
    }
}

/// The printed form of a curvature component: the shorter (by operation count) of
/// [`tidy`]'s and a rational normal form in which `tan`/`tanh` are written as quotients of
/// `sin`/`cos` (`sinh`/`cosh`), the terms are put over one denominator, numerator and
/// denominator are expanded and reduced by the Pythagorean identities (`sin² = 1 − cos²`,
/// `sinh² = cosh² − 1`, [`trig_normalize`]) and common factors cancelled. A Christoffel
/// symbol such as `tanh x` makes the Riemann tensor a sum of quotients that only this
/// second route sees cancel: for `ds² = dx² + cosh²x dy²`, tidy keeps
/// `sinh x tanh x / cosh x + 1/cosh² x − 2`, which the normal form shows to be `−1`.
pub(crate) fn curvature_form(e: &Expr) -> Expr {
    let tidied = tidy(e);
    if tidied.as_num().is_some() {
        return tidied;
    }
    let quotients = e.map_bottom_up(&mut |x| match x.node() {
        Node::Call(Func::Tan, a) => Some(Expr::call(Func::Sin, a.clone()).over(&Expr::call(Func::Cos, a.clone()))),
        Node::Call(Func::Tanh, a) => Some(Expr::call(Func::Sinh, a.clone()).over(&Expr::call(Func::Cosh, a.clone()))),
        _ => None,
    });
    let (n, d) = numer_denom(&together(&quotients));
    let reduce = |x: &Expr| expand(x).ok().map(|x| trig_normalize(&x)).and_then(|x| expand(&x).ok());
    let candidate = match (reduce(&n), reduce(&d)) {
        (Some(n), Some(_)) if n.is_zero() => n,
        (Some(n), Some(d)) => tidy(&cancel(&n.over(&d))),
        _ => return tidied,
    };
    if candidate.op_count() < tidied.op_count() {
        candidate
    } else {
        tidied
    }
}

impl Geodesic {
    /// The printed lines shared by `lagrangian geodesic` and the scene statement `geodesic`:
    /// the metric `g[q_i,q_j]`, the Christoffel symbols `Γ^k_ij` that are not zero, the
    /// geodesic equations, the independent non-zero components `R_abcd` (`a < b`, `c < d`,
    /// `(a, b) ≤ (c, d)`), the scalar curvature, for a surface `K`, and the conserved
    /// quantities of the energy Lagrangian with their reasons.
    pub fn report(&self, curv: &Curvature, conserved: &[super::Conserved], format: Format) -> Vec<String> {
        let z = &self.coords;
        let n = z.len();
        let s = |q: &Symbol| symbol(q, format);
        let r = |e: &Expr| render(e, format);
        let mut out = Vec::new();
        for i in 0..n {
            for j in i..n {
                out.push(format!("g[{},{}] = {}", s(&z[i]), s(&z[j]), r(&self.metric[i][j])));
            }
        }
        for k in 0..n {
            for i in 0..n {
                for j in i..n {
                    if !self.christoffel[k][i][j].is_zero() {
                        out.push(format!(
                            "Γ^{}_{}{} = {}",
                            s(&z[k]),
                            s(&z[i]),
                            s(&z[j]),
                            r(&self.christoffel[k][i][j])
                        ));
                    }
                }
            }
        }
        for (q, e) in z.iter().zip(&self.equations) {
            out.push(format!("geodesic_{}: {} = 0", s(q), r(e)));
        }
        for a in 0..n {
            for b in a + 1..n {
                for c in a..n {
                    for e in c + 1..n {
                        if (c, e) < (a, b) || curv.lowered[a][b][c][e].is_zero() {
                            continue;
                        }
                        let label = format!("R_{}{}{}{}", s(&z[a]), s(&z[b]), s(&z[c]), s(&z[e]));
                        out.push(format!("{label} = {}", r(&curv.lowered[a][b][c][e])));
                    }
                }
            }
        }
        out.push(format!("scalar_curvature = {}", r(&curv.scalar)));
        if let Some(k) = &curv.gauss {
            out.push(format!("K = {}", r(k)));
        }
        for c in conserved {
            out.push(format!("{} = {}    # {}", c.name, r(&c.expr), c.reason));
        }
        out
    }
}
