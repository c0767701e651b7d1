//! The Legendre transform L → H (3.6–3.10) and back.
//!
//! Two exactly solvable shapes are recognised, in both directions (the transform of a convex
//! function is symmetric):
//!
//! * **quadratic** `f(x) = ½ xᵀ M x + bᵀ x + f₀` with `M` independent of `x` (natural systems,
//!   (3.23)–(3.27)): `g(y) = ½ (y − b)ᵀ M⁻¹ (y − b) − f₀`. `M⁻¹` is never formed with
//!   divisions inside entries: `g = (Σ adj_ij d_i d_j) / (2 det M) − f₀` with `d = y − b`, and
//!   term by term when `M` is diagonal;
//! * **square root of a quadratic** `f(x) = a + k·sqrt(c₀ + xᵀ G x)` (the relativistic particle
//!   `−m c² sqrt(1 − |r'|²/c²)`): with `Y² = yᵀ G⁻¹ y`, `y = k G x / sqrt(c₀ + xᵀGx)` inverts to
//!   `g(y) = −k c₀ sqrt((k² − Y²)/(c₀ k²)) − a` (valid where `k² > Y²`, the physical branch).
//!
//! Anything else is [`MechanicsError::NoClosedFormLegendre`].

use crate::diff::Differentiator;
use crate::expr::{Expr, Node, Symbol};

use super::euler_lagrange::check_hessian;
use super::linalg::{adjugate, determinant, is_diagonal, MAX_CLOSED_FORM};
use super::system::{contains_any, zero_out, Kind, System};
use super::tidy::tidy;
use super::MechanicsError;

impl System {
    /// The canonical momenta `p_i = ∂L/∂q'_i` (3.6), as expressions in `q, q', t`.
    pub fn canonical_momenta(&self) -> Result<Vec<Expr>, MechanicsError> {
        let l = self.need_lagrangian("canonical momenta")?;
        let mut d = Differentiator::new();
        Ok(self.velocities.iter().map(|v| tidy(&d.diff(l, v))).collect())
    }

    /// The Legendre transform: the Hamiltonian system `H(q, p, t) = p·q' − L` (3.10) with the
    /// same coordinates and parameters. A Hamiltonian system is returned unchanged. Velocity
    /// constraints are refused: no Hamiltonian system carries them, and the transform alone
    /// would be the unconstrained system.
    pub fn legendre(&self) -> Result<System, MechanicsError> {
        let l = match &self.kind {
            Kind::Hamiltonian(_) => return Ok(self.clone()),
            Kind::Lagrangian(l) => l,
        };
        self.refuse_velocity_constraints("the Legendre transform (a Hamiltonian system)")?;
        let h = transform(l, &self.velocities, &self.momenta, "L")?;
        Ok(self.with_kind(Kind::Hamiltonian(h)))
    }

    /// The Hamiltonian: the system's own, or the Legendre transform of its Lagrangian. With
    /// velocity constraints it is refused, and with it everything built on `H` (Hamilton's
    /// equations, brackets with `H`, Lie flows, chaos indicators, the canonical compiled
    /// systems): their flow would be the unconstrained one.
    pub fn hamiltonian(&self) -> Result<Expr, MechanicsError> {
        match &self.kind {
            Kind::Hamiltonian(h) => Ok(h.clone()),
            Kind::Lagrangian(l) => {
                self.refuse_velocity_constraints("the Hamiltonian (and everything derived from H)")?;
                transform(l, &self.velocities, &self.momenta, "L")
            }
        }
    }

    /// The inverse transform H → L = p·q' − H with `p` eliminated through `q' = ∂H/∂p`. A
    /// Lagrangian system is returned unchanged.
    pub fn inverse_legendre(&self) -> Result<System, MechanicsError> {
        let h = match &self.kind {
            Kind::Lagrangian(_) => return Ok(self.clone()),
            Kind::Hamiltonian(h) => h,
        };
        let l = transform(h, &self.momenta, &self.velocities, "H")?;
        Ok(self.with_kind(Kind::Lagrangian(l)))
    }
}

/// The Legendre transform of `f` in the variables `xs`, with conjugate variables `ys`.
fn transform(f: &Expr, xs: &[Symbol], ys: &[Symbol], name: &'static str) -> Result<Expr, MechanicsError> {
    let n = xs.len();
    let mut d = Differentiator::new();
    let grad: Vec<Expr> = xs.iter().map(|x| d.diff(f, x)).collect();
    let mut m = vec![vec![Expr::zero(); n]; n];
    for i in 0..n {
        for j in i..n {
            let x = tidy(&d.diff(&grad[i], &xs[j]));
            m[i][j] = x.clone();
            m[j][i] = x;
        }
    }
    if m.iter().flatten().all(|e| !contains_any(e, xs)) {
        check_hessian(&m, xs, name)?;
        let b: Vec<Expr> = grad.iter().map(|g| tidy(&zero_out(g, xs))).collect();
        // V = −f(x = 0), tidied with its sign so it reads `m g l (1 − cos θ)`.
        let v0 = tidy(&zero_out(f, xs).neg());
        let dvec: Vec<Expr> = ys.iter().zip(&b).map(|(y, b)| Expr::sym(y.clone()).minus(b)).collect();
        // The pieces are tidy already; tidying the whole would expand the quadratic form over
        // its common denominator and lose the textbook shape ½ (p − b)ᵀ W⁻¹ (p − b) + V.
        let quad = quadratic_inverse_form(&m, &dvec)?;
        return Ok(quad.plus(&v0));
    }
    if let Some(g) = sqrt_transform(f, xs, ys, name)? {
        return Ok(g);
    }
    let what = if name == "L" { "the velocities" } else { "the momenta" };
    Err(MechanicsError::NoClosedFormLegendre(format!(
        "{name} is neither quadratic in {what} nor of the form a + k·sqrt(c0 + quadratic form), so ∂{name}/∂{} = {} cannot be solved in closed form",
        xs[0],
        ys[0]
    )))
}

/// `½ dᵀ M⁻¹ d`, fraction-free: diagonal entries term by term, otherwise
/// `(Σ_i adj_ii d_i² + 2 Σ_{i<j} adj_ij d_i d_j) / (2 det M)`.
fn quadratic_inverse_form(m: &[Vec<Expr>], dvec: &[Expr]) -> Result<Expr, MechanicsError> {
    let n = m.len();
    let half = Expr::frac(1, 2);
    if is_diagonal(m) {
        return Ok(Expr::add((0..n).map(|i| Expr::mul([half.clone(), dvec[i].powi(2), m[i][i].powi(-1)]))));
    }
    if n > MAX_CLOSED_FORM {
        return Err(MechanicsError::TooLarge { n, limit: MAX_CLOSED_FORM });
    }
    let adj = adjugate(m);
    let det = determinant(m);
    let mut terms = Vec::new();
    for i in 0..n {
        terms.push(adj[i][i].times(&dvec[i].powi(2)));
        for j in i + 1..n {
            terms.push(Expr::mul([Expr::int(2), adj[i][j].clone(), dvec[i].clone(), dvec[j].clone()]));
        }
    }
    Ok(Expr::mul([half, Expr::add(terms), det.powi(-1)]))
}

/// The transform of `f = a + k·sqrt(u)` with `u = c₀ + xᵀ G x` (no linear terms), if `f` has
/// that shape.
fn sqrt_transform(f: &Expr, xs: &[Symbol], ys: &[Symbol], name: &'static str) -> Result<Option<Expr>, MechanicsError> {
    let (with, without): (Vec<Expr>, Vec<Expr>) = f.terms().into_iter().partition(|t| contains_any(t, xs));
    let [term] = with.as_slice() else { return Ok(None) };
    let a = Expr::add(without);
    let (k, u) = {
        let mut k = Vec::new();
        let mut u = None;
        for fac in term.factors() {
            match fac.node() {
                Node::Pow(b, e)
                    if e.as_num().is_some_and(|r| *r == num_rational::BigRational::new(1.into(), 2.into()))
                        && contains_any(b, xs) =>
                {
                    if u.is_some() {
                        return Ok(None);
                    }
                    u = Some(b.clone());
                }
                _ if contains_any(&fac, xs) => return Ok(None),
                _ => k.push(fac),
            }
        }
        match u {
            Some(u) => (Expr::mul(k), u),
            None => return Ok(None),
        }
    };
    let n = xs.len();
    let mut d = Differentiator::new();
    let grad: Vec<Expr> = xs.iter().map(|x| d.diff(&u, x)).collect();
    if grad.iter().any(|g| !tidy(&zero_out(g, xs)).is_zero()) {
        return Ok(None);
    }
    // G = ½ ∂²u/∂x∂x.
    let mut g = vec![vec![Expr::zero(); n]; n];
    for i in 0..n {
        for j in i..n {
            let x = tidy(&d.diff(&grad[i], &xs[j]).times(&Expr::frac(1, 2)));
            if contains_any(&x, xs) {
                return Ok(None);
            }
            g[i][j] = x.clone();
            g[j][i] = x;
        }
    }
    let c0 = tidy(&zero_out(&u, xs));
    if c0.is_zero() {
        return Err(MechanicsError::SingularHessianDirection {
            function: name,
            direction: format!(
                "of the velocities themselves ({name} is homogeneous of degree one in {}, like the length functional (1.19))",
                xs.iter().map(Symbol::to_string).collect::<Vec<_>>().join(", ")
            ),
        });
    }
    check_hessian(&g, xs, name)?;
    // Y² = yᵀ G⁻¹ y = 2 · (½ yᵀ G⁻¹ y).
    let ysyms: Vec<Expr> = ys.iter().map(|y| Expr::sym(y.clone())).collect();
    let y2 = tidy(&quadratic_inverse_form(&g, &ysyms)?.times(&Expr::int(2)));
    let k2 = k.powi(2);
    let inner = tidy(&k2.minus(&y2)).times(&c0.times(&k2).powi(-1));
    let out = Expr::mul([Expr::int(-1), k, c0, inner.sqrt()]).minus(&a);
    Ok(Some(tidy(&out)))
}
