//! A small equation solver: enough to invert generating-function relations.
//!
//! It solves `e = 0` for one unknown `u` when `u` enters through a single "kernel" `k(u)`
//! (the unknown itself, a root `u^(1/d)`, or one function call such as `sin(a(u))`, `exp(..)`):
//! the equation is then a Laurent polynomial in `k`, solved when linear, quadratic or a
//! binomial `a kⁿ + b`; the kernel is then inverted (`asin`, `acos`, `atan`, `log`, `exp`,
//! roots), recursively. An equation in both `sin a` and `cos a` is tried as an equation in
//! `tan a` (substituting `sin a = T cos a`), which is how `p = m ω q cot Q` inverts.
//!
//! Every multi-valued inverse names the branch it took in [`Solution::branches`], e.g.
//! `q = ±√…; the + root taken`, `Q = atan(…) + nπ; n = 0 taken`. Where no closed form exists
//! the error says why, and callers keep the relations implicit.

use std::collections::BTreeSet;

use num_traits::ToPrimitive;

use crate::diff::diff;
use crate::expr::{Expr, Func, Node, Rational, Symbol};

use super::reduce::{decide_zero, expand, normalize, tidy};

/// One solution and the branch chosen to get it.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// The value of the unknown.
    pub value: Expr,
    /// The branches taken, in plain words (empty when the solution is unique).
    pub branches: Vec<String>,
}

/// Why an equation was not solved.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The unknown does not occur.
    #[error("`{unknown}` does not occur in `{equation} = 0`")]
    Absent {
        /// The unknown.
        unknown: String,
        /// The equation's left side.
        equation: String,
    },
    /// The solver knows no closed form.
    #[error("no closed form for `{unknown}` from `{equation} = 0`: {reason}")]
    NoClosedForm {
        /// The unknown.
        unknown: String,
        /// The equation's left side.
        equation: String,
        /// What stopped the solver.
        reason: String,
    },
    /// A linear system whose determinant vanishes.
    #[error("the linear system for {unknowns} is singular (determinant {determinant})")]
    Singular {
        /// The unknowns, comma-separated.
        unknowns: String,
        /// The determinant that vanished.
        determinant: String,
    },
}

fn no_closed_form(u: &Symbol, e: &Expr, reason: impl Into<String>) -> SolveError {
    SolveError::NoClosedForm { unknown: u.to_string(), equation: e.to_string(), reason: reason.into() }
}

/// Solves `eq = 0` for `u`.
pub fn solve(eq: &Expr, u: &Symbol) -> Result<Solution, SolveError> {
    solve_depth(eq, u, 0)
}

const MAX_DEPTH: usize = 8;

fn solve_depth(eq: &Expr, u: &Symbol, depth: usize) -> Result<Solution, SolveError> {
    let e = expand(&tidy(eq));
    if !e.contains(u) {
        return Err(SolveError::Absent { unknown: u.to_string(), equation: eq.to_string() });
    }
    if depth > MAX_DEPTH {
        return Err(no_closed_form(u, eq, "the inversion nests too deeply"));
    }
    let mut ks = BTreeSet::new();
    kernels(&e, u, &mut ks);
    let ks: Vec<Expr> = sort_exprs(ks);
    if ks.len() == 1 {
        let k = &ks[0];
        let (kv, mut branches) = solve_polynomial(&e, k, u, eq)?;
        let mut sol = invert(k, &kv, u, eq, depth)?;
        branches.append(&mut sol.branches);
        return Ok(Solution { value: tidy(&sol.value), branches });
    }
    // sin(a) and cos(a) of one argument: try tan(a).
    if ks.len() == 2 {
        if let (Node::Call(f1, a1), Node::Call(f2, a2)) = (ks[0].node(), ks[1].node()) {
            let pair = matches!((f1, f2), (Func::Sin, Func::Cos) | (Func::Cos, Func::Sin));
            if pair && a1 == a2 {
                let a = &a1[0];
                let sin = Expr::call(Func::Sin, vec![a.clone()]);
                let cos = Expr::call(Func::Cos, vec![a.clone()]);
                let t = Expr::var("__tan");
                let sub = expand(&replace(&e, &sin, &t.times(&cos)));
                if !sub.contains(u) {
                    let tsym = Symbol::new("__tan");
                    let (tv, mut branches) = solve_polynomial(&sub, &t, &tsym, eq)?;
                    let at = Expr::call(Func::Atan, vec![tv]);
                    branches.push(format!("tan({a}) inverted by atan: + nπ, n = 0 taken"));
                    let mut inner = solve_depth(&a.minus(&at), u, depth + 1)?;
                    branches.append(&mut inner.branches);
                    return Ok(Solution { value: tidy(&inner.value), branches });
                }
            }
        }
    }
    let names: Vec<String> = ks.iter().map(|k| format!("`{k}`")).collect();
    Err(no_closed_form(u, eq, format!("`{u}` enters through several independent subexpressions {}", names.join(", "))))
}

fn sort_exprs(set: BTreeSet<SortKey>) -> Vec<Expr> {
    set.into_iter().map(|k| k.0).collect()
}

/// An `Expr` ordered by the canonical order, for deterministic kernel sets.
#[derive(Clone, PartialEq, Eq)]
struct SortKey(Expr);
impl PartialOrd for SortKey {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for SortKey {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.canonical_cmp(&other.0)
    }
}

/// The maximal subexpressions through which `u` enters `e`, with sums, products and
/// integer powers looked through.
fn kernels(e: &Expr, u: &Symbol, out: &mut BTreeSet<SortKey>) {
    if !e.contains(u) {
        return;
    }
    match e.node() {
        Node::Sym(_) => {
            out.insert(SortKey(e.clone()));
        }
        Node::Add(xs) | Node::Mul(xs) => xs.iter().for_each(|x| kernels(x, u, out)),
        Node::Pow(b, x) => {
            if x.contains(u) {
                out.insert(SortKey(e.clone()));
                return;
            }
            match x.as_num() {
                Some(r) if r.is_integer() => kernels(b, u, out),
                Some(r) => {
                    let d = Rational::from_integer(r.denom().clone()).recip();
                    out.insert(SortKey(Expr::pow(b.clone(), Expr::num(d))));
                }
                None => {
                    out.insert(SortKey(e.clone()));
                }
            }
        }
        _ => {
            out.insert(SortKey(e.clone()));
        }
    }
}

/// Replaces the kernel `k` by `by` in `e`, including fractional powers of a root kernel
/// (`b^(3/2)` with kernel `b^(1/2)` becomes `by^3`).
fn replace(e: &Expr, k: &Expr, by: &Expr) -> Expr {
    let (kb, ke) = k.base_exp();
    let root = ke.as_num().cloned();
    e.map_bottom_up(&mut |n| {
        if n == k {
            return Some(by.clone());
        }
        if let (Node::Pow(b, x), Some(kr)) = (n.node(), &root) {
            if *b == kb {
                if let Some(r) = x.as_num() {
                    let m = r / kr;
                    if m.is_integer() {
                        return Some(Expr::pow(by.clone(), Expr::num(m)));
                    }
                }
            }
        }
        None
    })
}

/// Treats `e` as a Laurent polynomial in the kernel `k` and solves it for `k`.
fn solve_polynomial(e: &Expr, k: &Expr, u: &Symbol, eq: &Expr) -> Result<(Expr, Vec<String>), SolveError> {
    let kv = Symbol::new("__kernel");
    let ke = Expr::sym(kv.clone());
    let p = expand(&replace(e, k, &ke));
    if p.contains(u) {
        return Err(no_closed_form(u, eq, format!("`{u}` is not isolated by the kernel `{k}`")));
    }
    // Collect coefficients by integer power of the kernel.
    let mut coeffs: std::collections::BTreeMap<i64, Vec<Expr>> = Default::default();
    for t in p.terms() {
        let mut power = 0i64;
        let mut rest = Vec::new();
        for f in t.factors() {
            let (b, x) = f.base_exp();
            if b == ke {
                match x.as_num().filter(|r| r.is_integer()).and_then(|r| r.to_integer().to_i64()) {
                    Some(n) => power += n,
                    None => return Err(no_closed_form(u, eq, format!("a non-integer power of `{k}`"))),
                }
            } else if f.contains(&kv) {
                return Err(no_closed_form(u, eq, format!("`{k}` occurs inside `{f}`")));
            } else {
                rest.push(f);
            }
        }
        coeffs.entry(power).or_default().push(Expr::mul(rest));
    }
    let mut cs: std::collections::BTreeMap<i64, Expr> = Default::default();
    for (n, ts) in coeffs {
        let c = normalize(&Expr::add(ts));
        if !c.is_zero() {
            cs.insert(n, c);
        }
    }
    let lo = cs.keys().next().copied().unwrap_or(0);
    let hi = cs.keys().last().copied().unwrap_or(0);
    // Multiply through by k^(-lo) and drop a common factor k^j (its root k = 0 is discarded).
    let c = |n: i64| cs.get(&(n + lo)).cloned().unwrap_or_else(Expr::zero);
    let deg = hi - lo;
    let mut branches = Vec::new();
    let value = match deg {
        0 => return Err(no_closed_form(u, eq, format!("the equation does not depend on `{k}` after simplification"))),
        1 if c(1).is_negative_form() => c(0).over(&c(1).neg()),
        1 => c(0).neg().over(&c(1)),
        2 if c(1).is_zero() => {
            branches.push(format!("{k} = ±√(…): the + root taken"));
            root(&normalize(&c(0).neg().over(&c(2))), 2)
        }
        2 => {
            let (a, b, c0) = (c(2), c(1), c(0));
            let disc = normalize(&b.powi(2).minus(&Expr::int(4).times(&a).times(&c0)));
            // Of the two roots, take the one that tends to the linear solution −c/b as c → 0:
            // (−b + √D)/(2a) when b is positive, 2c/(−b + √D) (the same root written without
            // cancellation) when b is negative.
            branches.push(format!(
                "{k} from a quadratic: of the two roots (−b ± √(b² − 4ac))/(2a), the one tending to −c/b as c → 0 taken"
            ));
            if b.is_negative_form() {
                Expr::int(2).times(&c0).over(&b.neg().plus(&disc.sqrt()))
            } else {
                b.neg().plus(&disc.sqrt()).over(&Expr::int(2).times(&a))
            }
        }
        n if (1..n).all(|j| c(j).is_zero()) => {
            if n % 2 == 0 {
                branches.push(format!("{k} = ±({})^(1/{n}): the + root taken", c(0).neg().over(&c(n))));
            }
            root(&normalize(&c(0).neg().over(&c(n))), n as u32)
        }
        n => return Err(no_closed_form(u, eq, format!("a polynomial of degree {n} in `{k}`"))),
    };
    Ok((value, branches))
}

/// An `n`-th root taken factor by factor (`(a² b)^(1/2) = a b^(1/2)`): one of the roots, the
/// branch stated by the caller, with no absolute values introduced.
///
/// The common content of every sum is pulled out first and, for an even root, a negative
/// coefficient is paired with a sum led by a minus sign (`−P/(−a − b)` is `P/(a + b)`), so a
/// real value is never written through `√(−1)`: `(2 P sin²Q/ω)^(1/2)` becomes
/// `√2 √P sin Q/√ω`, which keeps the sign of `sin Q` that the forward map `tan Q = ω q/p` needs.
pub fn root(v: &Expr, n: u32) -> Expr {
    let inv = Expr::frac(1, i64::from(n));
    let per_factor = |f: &Expr| {
        let (b, x) = f.base_exp();
        match b.node() {
            Node::Num(_) => Expr::pow(f.clone(), inv.clone()),
            _ => Expr::pow(b, x.times(&inv)),
        }
    };
    let v = real_sign(&crate::algebra::factor_content(v), n);
    match v.node() {
        Node::Mul(fs) => Expr::mul(fs.iter().map(per_factor)),
        _ => per_factor(&v),
    }
}

/// For an even `n`: a product with a negative coefficient and a factor `S^k` (`k` an odd
/// integer, `S` a sum led by a minus sign) is rewritten with both signs flipped, so the
/// coefficient under the root is positive. Anything else is returned unchanged.
fn real_sign(v: &Expr, n: u32) -> Expr {
    if n % 2 == 1 {
        return v.clone();
    }
    let fs = v.factors();
    let negative = fs.first().and_then(Expr::as_num).is_some_and(|r| r < &Rational::from_integer(0.into()));
    if !negative {
        return v.clone();
    }
    let odd = |x: &Expr| x.as_num().is_some_and(|r| r.is_integer() && r.numer() % 2 != 0.into());
    let flip = fs.iter().position(|f| {
        let (b, x) = f.base_exp();
        matches!(b.node(), Node::Add(_)) && b.is_negative_form() && odd(&x)
    });
    let Some(i) = flip else { return v.clone() };
    let mut out = fs.clone();
    out[0] = out[0].neg();
    let (b, x) = fs[i].base_exp();
    out[i] = Expr::pow(b.neg(), x);
    Expr::mul(out)
}

/// Inverts `k(u) = value` for `u`.
fn invert(k: &Expr, value: &Expr, u: &Symbol, eq: &Expr, depth: usize) -> Result<Solution, SolveError> {
    let recurse = |inner: &Expr, target: Expr, note: Option<String>| -> Result<Solution, SolveError> {
        let mut s = solve_depth(&inner.minus(&target), u, depth + 1)?;
        if let Some(n) = note {
            s.branches.insert(0, n);
        }
        Ok(s)
    };
    match k.node() {
        Node::Sym(s) if s == u => Ok(Solution { value: value.clone(), branches: vec![] }),
        Node::Pow(b, x) if !x.contains(u) => {
            // b^x = v  ⇒  b = v^(1/x).
            let inv = match x.as_num() {
                Some(r) => Expr::num(r.recip()),
                None => x.powi(-1),
            };
            let target = if inv.as_num().is_some_and(|r| r.is_integer()) {
                Expr::pow(value.clone(), inv)
            } else {
                let d = inv.as_num().and_then(|r| r.denom().to_u32());
                match d {
                    Some(d) if inv.as_num().is_some_and(|r| r.numer() == &1.into()) => root(value, d),
                    _ => Expr::pow(value.clone(), inv),
                }
            };
            recurse(b, target, None)
        }
        Node::Pow(b, x) if !b.contains(u) => {
            recurse(x, Expr::call(Func::Log, vec![value.clone()]).over(&Expr::call(Func::Log, vec![b.clone()])), None)
        }
        Node::Call(f, args) if args.len() == 1 => {
            let a = &args[0];
            let v = value.clone();
            let one = Expr::one();
            let (target, note) = match f {
                Func::Sin => {
                    (Expr::call(Func::Asin, vec![v]), Some(format!("{k} = …: asin taken (also π − asin; + 2πn)")))
                }
                Func::Cos => {
                    (Expr::call(Func::Acos, vec![v]), Some(format!("{k} = …: acos taken (also −acos; + 2πn)")))
                }
                Func::Tan => (Expr::call(Func::Atan, vec![v]), Some(format!("{k} = …: atan taken (+ nπ)"))),
                Func::Exp => (Expr::call(Func::Log, vec![v]), None),
                Func::Log => (Expr::call(Func::Exp, vec![v]), None),
                Func::Asin => (Expr::call(Func::Sin, vec![v]), None),
                Func::Acos => (Expr::call(Func::Cos, vec![v]), None),
                Func::Atan => (Expr::call(Func::Tan, vec![v]), None),
                Func::Sinh => (Expr::call(Func::Log, vec![v.plus(&v.powi(2).plus(&one).sqrt())]), None),
                Func::Cosh => (
                    Expr::call(Func::Log, vec![v.plus(&v.powi(2).minus(&one).sqrt())]),
                    Some(format!("{k} = …: the non-negative acosh taken")),
                ),
                Func::Tanh => {
                    (Expr::frac(1, 2).times(&Expr::call(Func::Log, vec![one.plus(&v).over(&one.minus(&v))])), None)
                }
                Func::Abs => (v, Some(format!("{k} = …: the non-negative sign taken"))),
                Func::Asinh => (Expr::call(Func::Sinh, vec![v]), None),
                Func::Acosh => (Expr::call(Func::Cosh, vec![v]), None),
                Func::Atanh => (Expr::call(Func::Tanh, vec![v]), None),
                Func::Sec => (
                    Expr::call(Func::Acos, vec![v.powi(-1)]),
                    Some(format!("{k} = …: acos of the reciprocal taken (also −acos; + 2πn)")),
                ),
                Func::Csc => (
                    Expr::call(Func::Asin, vec![v.powi(-1)]),
                    Some(format!("{k} = …: asin of the reciprocal taken (also π − asin; + 2πn)")),
                ),
                Func::Coth => (Expr::call(Func::Atanh, vec![v.powi(-1)]), None),
                Func::Atan2 => return Err(no_closed_form(u, eq, "atan2 is not inverted")),
                Func::Erf => return Err(no_closed_form(u, eq, "erf has no elementary inverse")),
            };
            recurse(a, target, note)
        }
        _ => Err(no_closed_form(u, eq, format!("cannot invert `{k}`"))),
    }
}

/// Values for the unknowns (in the order asked) and the branches taken.
pub type SystemSolution = (Vec<(Symbol, Expr)>, Vec<String>);

/// Solves `eqs = 0` for `unknowns`: linear systems by Cramer's rule (the determinant in
/// normal form), otherwise one equation and one unknown at a time, substituting as it goes.
/// Returns the solution in the order of `unknowns` and the branches taken.
pub fn solve_system(eqs: &[Expr], unknowns: &[Symbol]) -> Result<SystemSolution, SolveError> {
    if let Some(res) = solve_linear(eqs, unknowns)? {
        return Ok((res, Vec::new()));
    }
    let mut pending: Vec<Expr> = eqs.to_vec();
    let mut left: Vec<Symbol> = unknowns.to_vec();
    let mut solved: Vec<(Symbol, Expr)> = Vec::new();
    let mut branches = Vec::new();
    while !left.is_empty() {
        // Prefer an equation with a single remaining unknown.
        let mut order: Vec<(usize, usize)> = Vec::new();
        for (i, e) in pending.iter().enumerate() {
            let n = left.iter().filter(|u| e.contains(u)).count();
            order.push((n, i));
        }
        order.sort();
        let mut progress = None;
        let mut last_err = None;
        'outer: for &(n, i) in &order {
            if n == 0 {
                continue;
            }
            for (j, u) in left.iter().enumerate() {
                if !pending[i].contains(u) {
                    continue;
                }
                match solve(&pending[i], u) {
                    Ok(s) => {
                        progress = Some((i, j, s));
                        break 'outer;
                    }
                    Err(e) => last_err = Some(e),
                }
            }
        }
        let Some((i, j, s)) = progress else {
            return Err(last_err.unwrap_or_else(|| SolveError::NoClosedForm {
                unknown: left.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", "),
                equation: pending.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("; "),
                reason: "the equations do not involve the unknowns".into(),
            }));
        };
        let u = left.remove(j);
        pending.remove(i);
        pending = pending.iter().map(|e| e.subs1(&u, &s.value)).collect();
        branches.extend(s.branches);
        solved.push((u, s.value));
    }
    // Back-substitute: later solutions are free of earlier unknowns.
    for idx in (0..solved.len()).rev() {
        let (u, v) = solved[idx].clone();
        for item in solved.iter_mut().take(idx) {
            item.1 = tidy(&item.1.subs1(&u, &v));
        }
    }
    let mut out = Vec::new();
    for u in unknowns {
        if let Some((_, v)) = solved.iter().find(|(s, _)| s == u) {
            out.push((u.clone(), v.clone()));
        }
    }
    Ok((out, branches))
}

/// Cramer's rule when every equation is linear in every unknown; `None` when not linear.
fn solve_linear(eqs: &[Expr], unknowns: &[Symbol]) -> Result<Option<Vec<(Symbol, Expr)>>, SolveError> {
    let n = unknowns.len();
    if eqs.len() != n || n == 0 || n > 4 {
        return Ok(None);
    }
    let mut a = vec![vec![Expr::zero(); n]; n];
    let mut b = vec![Expr::zero(); n];
    for (i, e) in eqs.iter().enumerate() {
        let e = expand(e);
        for (j, u) in unknowns.iter().enumerate() {
            let c = normalize(&diff(&e, u));
            if unknowns.iter().any(|v| c.contains(v)) {
                return Ok(None);
            }
            a[i][j] = c;
        }
        let zero: std::collections::HashMap<Symbol, Expr> =
            unknowns.iter().map(|u| (u.clone(), Expr::zero())).collect();
        b[i] = normalize(&e.subs(&zero)).neg();
    }
    let det = normalize(&determinant(&a));
    if decide_zero(&det).is_zero() {
        return Err(SolveError::Singular {
            unknowns: unknowns.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", "),
            determinant: det.to_string(),
        });
    }
    let mut out = Vec::new();
    for (j, u) in unknowns.iter().enumerate() {
        let mut aj = a.clone();
        for i in 0..n {
            aj[i][j] = b[i].clone();
        }
        let num = normalize(&determinant(&aj));
        // Keep the printed denominator's sign positive: Q/(4P + 1), not −Q/(−4P − 1).
        let (num, den) = if det.is_negative_form() { (num.neg(), det.neg()) } else { (num, det.clone()) };
        out.push((u.clone(), normalize(&num.over(&den))));
    }
    Ok(Some(out))
}

/// The determinant by cofactor expansion (n ≤ 4).
pub fn determinant(m: &[Vec<Expr>]) -> Expr {
    let n = m.len();
    match n {
        0 => Expr::one(),
        1 => m[0][0].clone(),
        _ => {
            let mut terms = Vec::new();
            for j in 0..n {
                if m[0][j].is_zero() {
                    continue;
                }
                let minor: Vec<Vec<Expr>> = m[1..]
                    .iter()
                    .map(|row| row.iter().enumerate().filter(|(c, _)| *c != j).map(|(_, x)| x.clone()).collect())
                    .collect();
                let sign = if j % 2 == 0 { Expr::one() } else { Expr::int(-1) };
                terms.push(Expr::mul([sign, m[0][j].clone(), determinant(&minor)]));
            }
            Expr::add(terms)
        }
    }
}
