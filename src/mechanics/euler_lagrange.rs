//! Euler–Lagrange expressions and the split `W q'' = F` (PHYSICS.md §1–2, (3.4)–(3.5)).

use nalgebra::DMatrix;

use crate::diff::Differentiator;
use crate::eval::eval_with;
use crate::expr::{Expr, Symbol};

use super::linalg::{adjugate, determinant, inverse_by_blocks, is_diagonal, MAX_CLOSED_FORM};
use super::system::{time, System};
use super::tidy::{tidy, Ctx, Poly, QuadraticParts};
use super::MechanicsError;
use crate::expr::Rational;

impl System {
    /// The Euler–Lagrange expressions `E_i = d/dt(∂L/∂q'_i) − ∂L/∂q_i`, one per coordinate
    /// (the equation of motion is `E_i = 0`; forces are not included, see
    /// [`System::equations`]). Accelerations appear as `q''`.
    pub fn euler_lagrange(&self) -> Result<Vec<Expr>, MechanicsError> {
        let l = self.need_lagrangian("Euler–Lagrange")?;
        let names = self.coord_names();
        let mut d = Differentiator::new();
        Ok(self
            .coords
            .iter()
            .zip(&self.velocities)
            .map(|(q, v)| {
                let dv = d.diff(l, v);
                let e = d.dt(&dv, &names).minus(&d.diff(l, q));
                tidy(&e)
            })
            .collect())
    }

    /// What drives each coordinate besides `L`: `Q_i − ∂R/∂q'_i + Σ_j λ_j ∂f_j/∂q_i +
    /// Σ_k μ_k ∂g_k/∂q'_i` (the forces (2.12), the Rayleigh dissipation, the constraint forces
    /// with multipliers `λ1, λ2, …` (1.25–1.29), and those of the velocity constraints with
    /// multipliers `μ1, μ2, …` (Lagrange–d'Alembert, §1.5)), in `q, q', t` and the
    /// multipliers; zero for a closed system. The equations of motion are `E_i = ` this.
    pub fn driving_forces(&self) -> Vec<Expr> {
        let mut d = Differentiator::new();
        let lambdas = self.multipliers();
        let mus = self.velocity_multipliers(self.velocity_constraints.len());
        (0..self.coords.len())
            .map(|i| {
                let mut terms = vec![self.forces[i].clone()];
                if let Some(r) = &self.rayleigh {
                    terms.push(d.diff(r, &self.velocities[i]).neg());
                }
                for (f, lam) in self.constraints.iter().zip(&lambdas) {
                    terms.push(Expr::sym(lam.clone()).times(&d.diff(f, &self.coords[i])));
                }
                for (g, mu) in self.velocity_constraints.iter().zip(&mus) {
                    terms.push(Expr::sym(mu.clone()).times(&d.diff(g, &self.velocities[i])));
                }
                tidy(&Expr::add(terms))
            })
            .collect()
    }

    /// Whether forces, a Rayleigh function or constraints (of either kind) are declared.
    pub fn has_driving_forces(&self) -> bool {
        self.forces.iter().any(|f| !f.is_zero())
            || self.rayleigh.is_some()
            || !self.constraints.is_empty()
            || !self.velocity_constraints.is_empty()
    }

    /// The full left-hand sides of the equations of motion, each `= 0`:
    /// `E_i − Q_i + ∂R/∂q'_i − Σ_j λ_j ∂f_j/∂q_i − Σ_k μ_k ∂g_k/∂q'_i` (forces (2.12), Rayleigh
    /// dissipation, constraint multipliers `λ1, λ2, …` (1.25–1.29), and with velocity
    /// constraints `g_k = 0` the Lagrange–d'Alembert multipliers `μ1, μ2, …`): with either kind
    /// of constraint these are the equations of the constrained motion, which the constraints
    /// themselves complete.
    pub fn equations(&self) -> Result<Vec<Expr>, MechanicsError> {
        if !self.velocity_constraints.is_empty() {
            return Ok(self.lagrange_dalembert(&[])?.equations);
        }
        let el = self.euler_lagrange()?;
        let mut d = Differentiator::new();
        let lambdas = self.multipliers();
        Ok(el
            .into_iter()
            .enumerate()
            .map(|(i, e)| {
                let mut terms = vec![e, self.forces[i].neg()];
                if let Some(r) = &self.rayleigh {
                    terms.push(d.diff(r, &self.velocities[i]));
                }
                for (f, lam) in self.constraints.iter().zip(&lambdas) {
                    terms.push(Expr::sym(lam.clone()).times(&d.diff(f, &self.coords[i])).neg());
                }
                tidy(&Expr::add(terms))
            })
            .collect())
    }

    /// The generalized mass matrix `W_ij = ∂²L/∂q'_i∂q'_j` (3.4) and the forcing
    /// `F = ∂L/∂q − ∂²L/∂q'∂t − (∂²L/∂q'∂q) q' + Q − ∂R/∂q'` (3.5), so that the equations of
    /// motion read `W q'' = F`. Both tidied; `W` is symmetric.
    ///
    /// Everything happens on one contracted polynomial form of L: its derivatives are formed
    /// monomial by monomial, and each atom (cos(θ1 − θ2), 1/r, …) is differentiated once per
    /// variable. When L is at most quadratic in the velocities (every natural system, magnetic
    /// and rotating frames), `W` is read off the velocity monomials and `F` is built from the
    /// collected entries of `W` by the Christoffel symbols; otherwise (the relativistic
    /// particle, …) from the derivatives of L directly.
    pub fn mass_matrix_split(&self) -> Result<(Vec<Vec<Expr>>, Vec<Expr>), MechanicsError> {
        let l = self.need_lagrangian("the mass matrix")?;
        let mut ctx = Ctx::new();
        let lp = ctx.poly(l);
        if let Some(parts) = ctx.quadratic_split(&lp, &self.velocities) {
            return Ok(self.quadratic_forcing(&mut ctx, parts));
        }
        Ok(self.general_forcing(&mut ctx, &lp))
    }

    /// `W` and `F` by differentiating the polynomial form `lp` of any Lagrangian.
    fn general_forcing(&self, ctx: &mut Ctx, lp: &Poly) -> (Vec<Vec<Expr>>, Vec<Expr>) {
        let n = self.coords.len();
        let t = time();
        let pv: Vec<Poly> = self.velocities.iter().map(|v| ctx.diff(lp, v)).collect();
        let mut w = vec![vec![Expr::zero(); n]; n];
        for i in 0..n {
            for j in i..n {
                let x = ctx.diff(&pv[i], &self.velocities[j]);
                let x = ctx.finish(x);
                w[i][j] = x.clone();
                w[j][i] = x;
            }
        }
        let mut f = Vec::with_capacity(n);
        for i in 0..n {
            let mut acc = ctx.diff(lp, &self.coords[i]);
            acc.add(&ctx.diff(&pv[i], &t).scale(&minus_one()));
            acc.add(&ctx.dt_coords(&pv[i], &self.coords, &self.velocities).scale(&minus_one()));
            self.add_forces(ctx, i, &mut acc);
            f.push(ctx.finish(acc));
        }
        (w, f)
    }

    /// `W` and `F` for `L = ½ q'ᵀ W q' + bᵀ q' + L0` (W, b, L0 functions of q and t).
    /// Substituting this L into (3.5) gives
    /// `F_i = Σ_jk (½ ∂_i W_jk − ∂_k W_ij) q'_j q'_k + Σ_j (∂_i b_j − ∂_j b_i − ∂_t W_ij) q'_j
    /// − ∂_t b_i + ∂_i L0 + Q_i − ∂R/∂q'_i`
    /// (the first sum is minus the Christoffel symbols of the first kind). The entries of `W`
    /// are collected first and differentiated in that form ([`Ctx::shallow`]), so `F` comes
    /// out grouped by velocity monomial with factors such as `(m2 + … + m_n)` kept whole, and
    /// the work grows with the size of the collected `W`, not of the expanded `L`.
    fn quadratic_forcing(&self, ctx: &mut Ctx, parts: QuadraticParts) -> (Vec<Vec<Expr>>, Vec<Expr>) {
        let n = self.coords.len();
        let t = time();
        let half = Rational::new(1.into(), 2.into());
        let mut w = vec![vec![Expr::zero(); n]; n];
        let mut ws: Vec<Vec<Poly>> = vec![vec![Poly::default(); n]; n];
        for (i, row) in parts.w.into_iter().enumerate() {
            for (j, p) in row.into_iter().enumerate().skip(i) {
                let x = ctx.finish(p);
                ws[i][j] = ctx.shallow(&x);
                w[i][j] = x.clone();
                w[j][i] = x;
            }
        }
        let wp = |i: usize, j: usize| if i <= j { &ws[i][j] } else { &ws[j][i] };
        // ∂_k W_ij for i ≤ j, every k (most are zero).
        let mut dw: Vec<Vec<Vec<Poly>>> = vec![vec![Vec::new(); n]; n];
        for i in 0..n {
            for j in i..n {
                dw[i][j] = self.coords.iter().map(|q| ctx.diff(wp(i, j), q)).collect();
            }
        }
        let dwk = |i: usize, j: usize, k: usize| if i <= j { &dw[i][j][k] } else { &dw[j][i][k] };
        let v: Vec<Poly> = self.velocities.iter().map(|v| ctx.shallow(&Expr::sym(v.clone()))).collect();
        let mut f = Vec::with_capacity(n);
        for i in 0..n {
            // The terms of degree 0 and 1 in the velocities, collected on their own.
            let mut low = ctx.diff(&parts.l0, &self.coords[i]);
            low.add(&ctx.diff(&parts.b[i], &t).scale(&minus_one()));
            for j in 0..n {
                let mut c = ctx.diff(&parts.b[j], &self.coords[i]);
                c.add(&ctx.diff(&parts.b[i], &self.coords[j]).scale(&minus_one()));
                c.add(&ctx.diff(wp(i, j), &t).scale(&minus_one()));
                if !c.is_zero() {
                    low.add(&c.mul(&v[j]));
                }
            }
            self.add_forces(ctx, i, &mut low);
            let low = ctx.finish(low);
            let mut acc = ctx.shallow(&low);
            // The quadratic terms, one coefficient per unordered pair j ≤ k (for j < k it gathers
            // the (j, k) and (k, j) terms of the double sum).
            for j in 0..n {
                for k in j..n {
                    let mut c = Poly::default();
                    if j == k {
                        c.add(&dwk(j, j, i).scale(&half));
                        c.add(&dwk(i, j, j).scale(&minus_one()));
                    } else {
                        c.add(dwk(j, k, i));
                        c.add(&dwk(i, j, k).scale(&minus_one()));
                        c.add(&dwk(i, k, j).scale(&minus_one()));
                    }
                    if !c.is_zero() {
                        acc.add(&c.mul(&v[j].mul(&v[k])));
                    }
                }
            }
            f.push(ctx.finish(acc));
        }
        (w, f)
    }

    /// Adds the generalized force `Q_i` and the dissipation `−∂R/∂q'_i` to `acc`.
    fn add_forces(&self, ctx: &mut Ctx, i: usize, acc: &mut Poly) {
        if !self.forces[i].is_zero() {
            acc.add(&ctx.poly(&self.forces[i]));
        }
        if let Some(r) = &self.rayleigh {
            let rp = ctx.poly(r);
            acc.add(&ctx.diff(&rp, &self.velocities[i]).scale(&minus_one()));
        }
    }

    /// Checks that the mass matrix `W` is regular, so that `W q'' = F` determines the
    /// accelerations; otherwise the error names the velocity or null direction (Remark 3.1).
    pub fn check_regular(&self) -> Result<(), MechanicsError> {
        let (w, _) = self.mass_matrix_split()?;
        check_hessian(&w, &self.velocities, "L")
    }

    /// Why the accelerations are not determined, as one printable note line, or `None` when
    /// `W` is regular. The Euler–Lagrange expressions exist for every Lagrangian; only `W⁻¹`
    /// may not (Remark 3.1), so `el` prints `E_i` and this note instead of refusing. A
    /// Lagrangian with `W ≡ 0` (first order in the velocities, such as the phase-space
    /// Lagrangian (3.31)) is named as such: its equations are first order.
    pub fn hessian_note(&self) -> Result<Option<String>, MechanicsError> {
        let (w, _) = self.mass_matrix_split()?;
        let first_order = w.iter().flatten().all(Expr::is_zero);
        match check_hessian(&w, &self.velocities, "L") {
            Ok(()) => Ok(None),
            Err(_) if first_order => Ok(Some(
                "note: W = ∂²L/∂q'∂q' is zero: L is linear in every velocity (a first-order, phase-space Lagrangian), \
                 so E = 0 are first-order equations ω z' = ∂H/∂z + ∂a/∂t (see `phase-space`); no accelerations, \
                 no Legendre transform"
                    .to_string(),
            )),
            Err(MechanicsError::SingularHessian { var, .. }) => Ok(Some(format!(
                "note: W = ∂²L/∂q'∂q' is singular: its row for `{var}` is zero (L is at most linear in {var}), \
                 so E = 0 does not determine every acceleration (Remark 3.1: no Legendre transform)"
            ))),
            Err(MechanicsError::SingularHessianDirection { direction, .. }) => Ok(Some(format!(
                "note: W = ∂²L/∂q'∂q' is singular along the direction {direction}, \
                 so E = 0 does not determine every acceleration (Remark 3.1: no Legendre transform)"
            ))),
            Err(e) => Err(e),
        }
    }

    /// The accelerations `q'' = W⁻¹ F` in closed form: directly when `W` is diagonal, through
    /// the fraction-free adjugate `adj(W) F / det(W)` for up to four coupled coordinates.
    /// A singular `W` is an error naming the velocity or the null direction (Remark 3.1).
    /// With constraints (holonomic or velocity ones) these are the constrained accelerations,
    /// the multipliers eliminated ([`System::constrained_accelerations`]): `W⁻¹ F` alone would
    /// ignore the constraint forces.
    pub fn accelerations(&self) -> Result<Vec<Expr>, MechanicsError> {
        if !self.constraints.is_empty() || !self.velocity_constraints.is_empty() {
            return self.constrained_accelerations().map(|(acc, _)| acc);
        }
        let (w, f) = self.mass_matrix_split()?;
        check_hessian(&w, &self.velocities, "L")?;
        let n = w.len();
        if is_diagonal(&w) {
            return Ok((0..n).map(|i| tidy(&f[i].over(&w[i][i]))).collect());
        }
        if n > MAX_CLOSED_FORM {
            // Block by block (two uncoupled double pendulums), or refused.
            let inv = inverse_by_blocks(&w).map_err(|n| MechanicsError::TooLarge { n, limit: MAX_CLOSED_FORM })?;
            return Ok((0..n).map(|i| tidy(&Expr::add((0..n).map(|j| inv[i][j].times(&f[j]))))).collect());
        }
        let adj = adjugate(&w);
        let det = determinant(&w);
        Ok((0..n)
            .map(|i| {
                let num = tidy(&Expr::add((0..n).map(|j| adj[i][j].times(&f[j]))));
                num.over(&det)
            })
            .collect())
    }
}

fn minus_one() -> Rational {
    Rational::from_integer((-1).into())
}

/// A deterministic pseudo-random value in `[0.5, 1.5)` for a symbol at sample `k`: numeric
/// probes of symbolic identities.
pub(crate) fn probe_value(s: &Symbol, k: u64) -> f64 {
    let mut h: u64 = 0x9E37_79B9_7F4A_7C15 ^ k.wrapping_mul(0xD1B5_4A32_D192_ED03);
    for b in s.to_string().bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01B3);
    }
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    0.5 + (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Checks that a Hessian is regular: a zero row names its variable; otherwise
/// [`null_direction`] detects a singular matrix and the error names a null direction.
pub(crate) fn check_hessian(m: &[Vec<Expr>], vars: &[Symbol], function: &'static str) -> Result<(), MechanicsError> {
    for (i, row) in m.iter().enumerate() {
        if row.iter().all(Expr::is_zero) {
            return Err(MechanicsError::SingularHessian { function, var: vars[i].to_string() });
        }
    }
    match null_direction(m, vars) {
        None => Ok(()),
        Some(direction) => Err(MechanicsError::SingularHessianDirection { function, direction }),
    }
}

/// A null direction of a square symbolic matrix, printed as `(1, -1) in (x', y')`, or `None`
/// when it is regular: a numeric rank test at two probe points (when every entry evaluates),
/// otherwise the symbolic determinant (up to four variables) and a column of the adjugate.
pub(crate) fn null_direction(m: &[Vec<Expr>], vars: &[Symbol]) -> Option<String> {
    let n = m.len();
    let mut numeric_null: Option<Vec<f64>> = None;
    let mut evaluated = true;
    for k in 0..2u64 {
        let mut mat = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..n {
                match eval_with(&m[i][j], &|s: &Symbol| Some(probe_value(s, k))) {
                    Ok(v) if v.is_finite() => mat[(i, j)] = v,
                    _ => evaluated = false,
                }
            }
        }
        if !evaluated {
            break;
        }
        let svd = mat.svd(false, true);
        let sv = &svd.singular_values;
        let max = sv.iter().cloned().fold(0.0, f64::max);
        let (imin, min) =
            sv.iter().cloned().enumerate().fold((0, f64::INFINITY), |a, (i, v)| if v < a.1 { (i, v) } else { a });
        if min > 1e-9 * max.max(1e-300) {
            return None;
        }
        if let Some(vt) = &svd.v_t {
            numeric_null = Some(vt.row(imin).iter().cloned().collect());
        }
    }
    if evaluated {
        let dir = numeric_null.unwrap_or_default();
        return Some(describe_direction(&dir, vars));
    }
    if n <= MAX_CLOSED_FORM && determinant(m).is_zero() {
        let adj = adjugate(m);
        let col = (0..n).find(|&j| (0..n).any(|i| !adj[i][j].is_zero()));
        return Some(match col {
            Some(j) => {
                let parts: Vec<String> = (0..n).map(|i| adj[i][j].to_string()).collect();
                let names: Vec<String> = vars.iter().map(Symbol::to_string).collect();
                format!("({}) in ({})", parts.join(", "), names.join(", "))
            }
            None => "of more than one velocity".to_string(),
        });
    }
    None
}

fn describe_direction(v: &[f64], vars: &[Symbol]) -> String {
    let big = v.iter().cloned().fold(0.0f64, |a, x| if x.abs() > a.abs() { x } else { a });
    let scaled: Vec<String> = v
        .iter()
        .map(|x| {
            let r = x / if big == 0.0 { 1.0 } else { big };
            let rounded = (r * 1e6).round() / 1e6;
            if rounded == rounded.trunc() {
                format!("{}", rounded as i64)
            } else {
                format!("{rounded}")
            }
        })
        .collect();
    let names: Vec<String> = vars.iter().map(Symbol::to_string).collect();
    format!("({}) in ({})", scaled.join(", "), names.join(", "))
}
