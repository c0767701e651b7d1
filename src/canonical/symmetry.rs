//! Point symmetries of a Lagrangian beyond ignorable coordinates (PHYSICS.md
//! §2.6, Noether's theorem with a total-derivative term).
//!
//! A generator moves `q_i → q_i + ε ξ_i(q, t)` and `t → t + ε τ(q, t)`. It is a symmetry when
//! the first-order change of the action density is a total derivative,
//!
//! `Σ_i [∂L/∂q_i ξ_i + ∂L/∂q'_i (ξ̇_i − q'_i τ̇)] + ∂L/∂t τ + L τ̇ = dF/dt`,
//!
//! and then `Q = Σ_i ∂L/∂q'_i ξ_i − h τ − F` is conserved (`h` the energy function; in
//! momenta `Σ p_i ξ_i − H τ − F`). The search takes the polynomial ansatz: `ξ_i` and `τ` of
//! total degree ≤ [`DEGREE`] in `(q, t)` with pure-number coefficients, `F` of degree ≤
//! [`F_DEGREE`]. Degree 2 holds translations, rotations, Galilean boosts (also in a uniform
//! field, whose `F` is quadratic in `t`), time translation, and the free particle's dilation
//! (`τ = 2t, ξ = q`) and special conformal map (`τ = t², ξ = t q`). The condition is linear in
//! the unknown coefficients:
//!
//! 1. it is sampled at random points of `(q, q', t)` (parameters fixed at random values), and
//!    the null space of the sampled system is found by Gaussian elimination (columns of `F`
//!    first, so each null vector is fixed by its `ξ, τ` part);
//! 2. each null vector's `ξ, τ` coefficients are read as small rationals, `δL` is formed
//!    exactly, and `F` is read off it symbolically: `δL = Σ A_j q'_j + B` with `A`, `B`
//!    polynomial in `(q, t)`, and `F = Σ_terms term/degree(term)` of `t B + Σ q_j A_j` (Euler's
//!    formula for homogeneous parts), accepted only when `dF/dt − δL` is proven zero;
//! 3. each charge is verified: `{Q, H} + ∂Q/∂t` must be zero (proven, or said how decided).
//!
//! The search is bounded, and [`SymmetrySearch::bound`] says how: a generator of higher degree,
//! not polynomial, or with a coefficient that involves a parameter (such as the mass-weighted
//! rotation of two unequal masses) is not excluded by finding nothing.

use num_traits::ToPrimitive;

use crate::diff::Differentiator;
use crate::eval::eval_with;
use crate::expr::{Expr, Node, Rational, Symbol};

use super::reduce::{decide_zero, normalize, tidy, ZeroCheck};
use super::{is_integral, time, PhaseSpace};

/// One point symmetry and its conserved charge.
#[derive(Clone, Debug)]
pub struct PointSymmetry {
    /// `ξ_i(q, t)`, one per coordinate.
    pub generator: Vec<Expr>,
    /// `τ(q, t)`, the change of time (zero for a symmetry at fixed time).
    pub time_change: Expr,
    /// `F(q, t)` with `δL = dF/dt` (zero for a strict symmetry).
    pub gauge: Expr,
    /// The charge in momenta, `Σ p_i ξ_i − H τ − F`.
    pub charge: Expr,
    /// The same charge in velocities, `Σ ∂L/∂q'_i ξ_i − h τ − F`.
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

/// The total degree of `ξ_i` and `τ` in `(q, t)`.
pub const DEGREE: u32 = 2;

/// The total degree of `F` in `(q, t)` in the sampled system.
pub const F_DEGREE: u32 = DEGREE + 1;

/// Samples of the linear condition (more rows than unknowns, for a clean rank).
const SAMPLES_PER_UNKNOWN: usize = 3;

/// The ansatz in words, as [`SymmetrySearch::bound`] states it.
pub fn ansatz() -> String {
    format!(
        "ξ(q, t) and τ(q, t) polynomials of degree ≤ {DEGREE} in q and t with number coefficients, \
         F(q, t) of degree ≤ {F_DEGREE}; symmetries outside this ansatz are not excluded"
    )
}

/// A monomial `t^e_0 q_1^e_1 … q_n^e_n`, as its exponents.
type Mono = Vec<u32>;

/// Every monomial in `vars` variables of total degree `lo..=hi`, by degree and then
/// lexicographically (so the columns, and with them the null vectors, are deterministic).
fn monomials(vars: usize, lo: u32, hi: u32) -> Vec<Mono> {
    fn rec(vars: usize, left: u32, cur: &mut Mono, out: &mut Vec<Mono>) {
        if cur.len() == vars - 1 {
            cur.push(left);
            out.push(cur.clone());
            cur.pop();
            return;
        }
        for e in (0..=left).rev() {
            cur.push(e);
            rec(vars, left - e, cur, out);
            cur.pop();
        }
    }
    let mut out = Vec::new();
    for d in lo..=hi {
        rec(vars, d, &mut Vec::new(), &mut out);
    }
    out
}

/// The monomial's value and its total time derivative at `x = (t, q)`, `ẋ = (1, q')`.
fn mono_values(m: &Mono, x: &[f64], xdot: &[f64]) -> (f64, f64) {
    let value = m.iter().zip(x).map(|(&e, &v)| v.powi(e as i32)).product();
    let mut dot = 0.0;
    for k in 0..m.len() {
        if m[k] == 0 {
            continue;
        }
        let rest: f64 = (0..m.len()).filter(|&j| j != k).map(|j| x[j].powi(m[j] as i32)).product();
        dot += m[k] as f64 * x[k].powi(m[k] as i32 - 1) * rest * xdot[k];
    }
    (value, dot)
}

/// The monomial as an expression in `x = (t, q)`.
fn mono_expr(m: &Mono, x: &[Expr]) -> Expr {
    Expr::mul(m.iter().zip(x).filter(|(&e, _)| e > 0).map(|(&e, v)| v.powi(e as i64)))
}

/// `Σ c_k φ_k` and its total time derivative, exactly.
fn combination(c: &[Rational], monos: &[Mono], x: &[Expr], xdot: &[Expr]) -> (Expr, Expr) {
    let mut value = Vec::new();
    let mut dot = Vec::new();
    for (ck, m) in c.iter().zip(monos) {
        if num_traits::Zero::is_zero(ck) {
            continue;
        }
        let k = Expr::num(ck.clone());
        value.push(k.times(&mono_expr(m, x)));
        for j in 0..m.len() {
            if m[j] > 0 {
                let mut lower = m.clone();
                lower[j] -= 1;
                dot.push(k.times(&Expr::int(m[j] as i64)).times(&mono_expr(&lower, x)).times(&xdot[j]));
            }
        }
    }
    (Expr::add(value), Expr::add(dot))
}

/// What the exact stage needs besides one null vector.
struct Context<'a> {
    l: &'a Expr,
    h: &'a Expr,
    coords: &'a [Symbol],
    vel: Vec<Symbol>,
    /// `(t, q_1 … q_n)` and their time derivatives `(1, q'_1 … q'_n)`.
    x: Vec<Expr>,
    xdot: Vec<Expr>,
    dl_dq: Vec<Expr>,
    dl_dv: Vec<Expr>,
    dl_dt: Expr,
    /// The energy function `h = Σ q' ∂L/∂q' − L`.
    energy: Expr,
    /// The basis of `ξ_i` and `τ`.
    basis: Vec<Mono>,
}

/// Searches `l(q, q', t)` for point symmetries of the polynomial ansatz ([`ansatz`]); `h` is
/// the Hamiltonian used to verify each charge.
pub fn point_symmetries(l: &Expr, coords: &[Symbol], h: &Expr) -> SymmetrySearch {
    if coords.len() > MAX_COORDS {
        return SymmetrySearch {
            found: Vec::new(),
            bound: format!(
                "not searched: {} coordinates (the sampled linear system has O(n³) unknowns; limit {MAX_COORDS})",
                coords.len()
            ),
        };
    }
    let n = coords.len();
    let t = time();
    let vel: Vec<Symbol> = coords.iter().map(Symbol::prime).collect();
    let mut d = Differentiator::new();
    let dl_dq: Vec<Expr> = coords.iter().map(|q| d.diff(l, q)).collect();
    let dl_dv: Vec<Expr> = vel.iter().map(|v| d.diff(l, v)).collect();
    let dl_dt = d.diff(l, &t);
    let energy = Expr::add(vel.iter().zip(&dl_dv).map(|(v, p)| Expr::sym(v.clone()).times(p))).minus(l);
    let mut x = vec![Expr::sym(t.clone())];
    x.extend(coords.iter().cloned().map(Expr::sym));
    let mut xdot = vec![Expr::one()];
    xdot.extend(vel.iter().cloned().map(Expr::sym));
    let basis = monomials(n + 1, 0, DEGREE);
    let f_basis = monomials(n + 1, 1, F_DEGREE);
    let m = basis.len();
    let nf = f_basis.len();
    // Columns: F's coefficients, then ξ_i's (i = 1 … n), then τ's, each over its basis.
    let unknowns = nf + (n + 1) * m;
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
    // Per sample: L, ∂L/∂t, ∂L/∂q_i, ∂L/∂q'_i; the row is formed from them and the monomials.
    let mut sampled = vec![l.clone(), dl_dt.clone()];
    sampled.extend(dl_dq.iter().cloned());
    sampled.extend(dl_dv.iter().cloned());
    let applications = opaque_applications(&mut sampled);
    let mut rows = Vec::new();
    let mut attempts = 0;
    while rows.len() < SAMPLES_PER_UNKNOWN * unknowns && attempts < 20 * unknowns {
        attempts += 1;
        let point: Vec<f64> = (0..2 * n + 1).map(|_| 2.0 * next() - 1.0).collect();
        let applied: Vec<f64> = applications.iter().map(|_| 2.0 * next() - 1.0).collect();
        let lookup = |s: &Symbol| {
            if let Some(i) = applications.iter().position(|a| a == s) {
                return Some(applied[i]);
            }
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
        let vals: Vec<f64> = sampled.iter().map(|c| eval_with(c, &lookup).unwrap_or(f64::NAN)).collect();
        if !vals.iter().all(|v| v.is_finite()) {
            continue;
        }
        let (lv, lt, lq, lp) = (vals[0], vals[1], &vals[2..2 + n], &vals[2 + n..]);
        let xs: Vec<f64> = std::iter::once(point[2 * n]).chain(point[..n].iter().copied()).collect();
        let xd: Vec<f64> = std::iter::once(1.0).chain(point[n..2 * n].iter().copied()).collect();
        let h_val = (0..n).map(|i| xd[i + 1] * lp[i]).sum::<f64>() - lv;
        let phis: Vec<(f64, f64)> = basis.iter().map(|b| mono_values(b, &xs, &xd)).collect();
        let mut row = Vec::with_capacity(unknowns);
        row.extend(f_basis.iter().map(|b| -mono_values(b, &xs, &xd).1));
        for i in 0..n {
            row.extend(phis.iter().map(|&(v, dv)| lq[i] * v + lp[i] * dv));
        }
        row.extend(phis.iter().map(|&(v, dv)| lt * v - h_val * dv));
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
    let ctx = Context { l, h, coords, vel, x, xdot, dl_dq, dl_dv, dl_dt, energy, basis };
    let found = null_space(rows, unknowns).into_iter().filter_map(|v| exact_symmetry(&ctx, &v[nf..])).collect();
    SymmetrySearch { found, bound: ansatz() }
}

/// Replaces every application of a declared function in `exprs` (`U(r)`, `U'(r)`, innermost
/// first) by a fresh symbol, and returns those symbols. Why: a declared `U` stands for any
/// function, so a symmetry must hold whatever values `U` and its derivatives take. At sample
/// points where the arguments differ, any values are those of some smooth `U` (Hermite
/// interpolation), so drawing them at random, independently at each point, samples the
/// condition for all `U` at once, and a generator found this way holds for every `U` (the
/// exact stage then proves it with `U` left symbolic). A central potential `U(√(x² + y²))`
/// yields its rotation this way.
fn opaque_applications(exprs: &mut [Expr]) -> Vec<Symbol> {
    let mut fresh: Vec<(Expr, Symbol)> = Vec::new();
    for e in exprs.iter_mut() {
        *e = e.map_bottom_up(&mut |x| {
            if !matches!(x.node(), Node::Apply { .. }) {
                return None;
            }
            if let Some((_, s)) = fresh.iter().find(|(a, _)| a == x) {
                return Some(Expr::sym(s.clone()));
            }
            let s = Symbol::new(&format!("⟪applied {}⟫", fresh.len()));
            fresh.push((x.clone(), s.clone()));
            Some(Expr::sym(s))
        });
    }
    fresh.into_iter().map(|(_, s)| s).collect()
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
        let row_r = a[r].clone();
        for (i, row) in a.iter_mut().enumerate() {
            if i != r && row[c] != 0.0 {
                let f = row[c];
                for (x, y) in row.iter_mut().zip(&row_r) {
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

/// The total degree of a term in `vars` when it is a monomial in them (times factors free of
/// them); `None` otherwise.
fn term_degree(term: &Expr, vars: &[Symbol]) -> Option<u32> {
    let mut deg = 0u32;
    for f in term.factors() {
        if !vars.iter().any(|v| f.contains(v)) {
            continue;
        }
        match f.node() {
            Node::Sym(s) if vars.contains(s) => deg += 1,
            Node::Pow(b, e) => {
                if !b.as_sym().is_some_and(|s| vars.contains(s)) {
                    return None;
                }
                let k = e.as_num().filter(|r| r.is_integer())?.to_integer().to_u32()?;
                deg += k;
            }
            _ => return None,
        }
    }
    Some(deg)
}

/// The printed form of a charge or gauge term: the shortest (in plain text, the first on a
/// tie) of its tidied form, its expanded form and that form grouped over common factors, so
/// `2 x' (m1/2 + m2/2)` from a derivative prints as `m1 x' + m2 x'`.
fn shortest(e: &Expr) -> Expr {
    let expanded = normalize(e);
    let candidates = [tidy(e), tidy(&expanded), super::compact::compact(&expanded)];
    candidates.into_iter().min_by_key(|c| crate::print::plain(c).chars().count()).unwrap_or_else(|| e.clone())
}

/// The exact symmetry behind one null vector's `ξ, τ` coefficients, if it is one.
fn exact_symmetry(ctx: &Context, coeffs: &[f64]) -> Option<PointSymmetry> {
    let n = ctx.coords.len();
    let m = ctx.basis.len();
    let mut u: Vec<Rational> = coeffs.iter().map(|&x| small_rational(x)).collect::<Option<_>>()?;
    let zero = |r: &Rational| num_traits::Zero::is_zero(r);
    if u.iter().all(zero) {
        return None;
    }
    // A pure time translation is scaled to τ = −1, so that its charge is the energy itself.
    let tau_part = &u[n * m..];
    let only_time = u[..n * m].iter().all(zero) && tau_part[1..].iter().all(zero);
    if only_time {
        let scale = -tau_part[0].clone();
        u = u.iter().map(|c| c / &scale).collect();
    }
    let block = |k: usize| combination(&u[k * m..(k + 1) * m], &ctx.basis, &ctx.x, &ctx.xdot);
    let (xi, xi_dot): (Vec<Expr>, Vec<Expr>) = (0..n).map(&block).unzip();
    let (tau, tau_dot) = block(n);
    let mut terms = Vec::new();
    for i in 0..n {
        terms.push(ctx.dl_dq[i].times(&xi[i]));
        let v = Expr::sym(ctx.vel[i].clone());
        terms.push(ctx.dl_dv[i].times(&xi_dot[i].minus(&v.times(&tau_dot))));
    }
    terms.push(ctx.dl_dt.times(&tau));
    terms.push(ctx.l.times(&tau_dot));
    let delta = normalize(&Expr::add(terms));
    // δL = Σ A_j q'_j + B with A, B free of velocities, and F from Euler's formula.
    let mut d = Differentiator::new();
    let t = time();
    let moving = |e: &Expr| ctx.vel.iter().any(|v| e.contains(v));
    let a: Vec<Expr> = ctx.vel.iter().map(|v| normalize(&d.diff(&delta, v))).collect();
    if a.iter().any(&moving) {
        return None;
    }
    let b = normalize(&delta.minus(&Expr::add(ctx.vel.iter().zip(&a).map(|(v, aj)| Expr::sym(v.clone()).times(aj)))));
    if moving(&b) {
        return None;
    }
    let mut vars = vec![t.clone()];
    vars.extend(ctx.coords.iter().cloned());
    let euler = Expr::add(
        std::iter::once(Expr::sym(t.clone()).times(&b))
            .chain(ctx.coords.iter().zip(&a).map(|(q, aj)| Expr::sym(q.clone()).times(aj))),
    );
    let euler = crate::algebra::expand(&euler).ok()?;
    let mut f_terms = Vec::new();
    for term in euler.terms().into_iter().filter(|t| !t.is_zero()) {
        let deg = term_degree(&term, &vars).filter(|&k| k > 0)?;
        f_terms.push(term.over(&Expr::int(deg as i64)));
    }
    let gauge = shortest(&Expr::add(f_terms));
    let df_dt = Expr::add(vars.iter().zip(&ctx.xdot).map(|(v, vd)| d.diff(&gauge, v).times(vd)).collect::<Vec<_>>());
    if decide_zero(&df_dt.minus(&delta)) != ZeroCheck::Proven {
        return None;
    }
    let ps = PhaseSpace::new(ctx.coords.iter().map(|q| q.name())).ok()?;
    let charge = shortest(
        &Expr::add(ps.momenta.iter().zip(&xi).map(|(p, x)| Expr::sym(p.clone()).times(x)))
            .minus(&ctx.h.times(&tau))
            .minus(&gauge),
    );
    let check = is_integral(&charge, ctx.h, &ps);
    let charge_velocities = shortest(
        &Expr::add(ctx.dl_dv.iter().zip(&xi).map(|(p, x)| p.times(x))).minus(&ctx.energy.times(&tau)).minus(&gauge),
    );
    let kind = describe(&u, &ctx.basis, ctx.coords, &gauge, &tau);
    Some(PointSymmetry { generator: xi, time_change: tau, gauge, charge, charge_velocities, kind, check })
}

/// The generator in words, from its coefficients `u[i·m + k]` over the basis (`i = n`: `τ`).
fn describe(u: &[Rational], basis: &[Mono], coords: &[Symbol], gauge: &Expr, tau: &Expr) -> String {
    let n = coords.len();
    let m = basis.len();
    let zero = |r: &Rational| num_traits::Zero::is_zero(r);
    let c = |i: usize, k: usize| &u[i * m + k];
    let xi_zero = (0..n).all(|i| (0..m).all(|k| zero(c(i, k))));
    let t_deg = |k: usize| basis[k][0];
    let q_deg = |k: usize| basis[k][1..].iter().sum::<u32>();
    if !tau.is_zero() {
        let tau_uses = |pred: &dyn Fn(usize) -> bool| (0..m).any(|k| !zero(c(n, k)) && pred(k));
        let shown = crate::print::plain(tau);
        if xi_zero && !tau_uses(&|k| t_deg(k) + q_deg(k) > 0) {
            return "time translation".into();
        }
        if tau_uses(&|k| q_deg(k) > 0) {
            return format!("point symmetry with a time change τ = {shown}");
        }
        if tau_uses(&|k| t_deg(k) == 2) {
            return format!("conformal transformation (τ = {shown})");
        }
        if tau_uses(&|k| t_deg(k) == 1) {
            return format!("dilation (τ = {shown})");
        }
        return format!("point symmetry with a time change τ = {shown}");
    }
    let used = |pred: &dyn Fn(usize) -> bool| (0..n).any(|i| (0..m).any(|k| !zero(c(i, k)) && pred(k)));
    let has_q = used(&|k| q_deg(k) > 0);
    let has_t = used(&|k| t_deg(k) > 0);
    let nonlinear = used(&|k| t_deg(k) + q_deg(k) > 1);
    if nonlinear {
        return "point symmetry".into();
    }
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
    // ξ_i = Σ_j c_ij q_j with c antisymmetric: a rotation in the planes where it is non-zero.
    let lin = |i: usize, j: usize| -> Rational {
        let k = basis.iter().position(|b| b[0] == 0 && b[1 + j] == 1 && q_deg_of(b) == 1).unwrap_or(0);
        c(i, k).clone()
    };
    let antisym = (0..n).all(|i| (0..n).all(|j| lin(i, j) == -lin(j, i)));
    if antisym && !has_t {
        let planes: Vec<String> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .filter(|&(i, j)| !zero(&lin(i, j)))
            .map(|(i, j)| format!("({}, {})", coords[i], coords[j]))
            .collect();
        return format!("rotation in {}", planes.join(", "));
    }
    "linear point symmetry".to_string()
}

fn q_deg_of(b: &Mono) -> u32 {
    b[1..].iter().sum()
}
