//! Normal forms and zero tests for the expressions this module produces.
//!
//! Brackets, transformed Hamiltonians and canonicity conditions are only useful if we can
//! tell when they vanish. The canonical core collects like terms but never distributes
//! products over sums, and it knows no trigonometric identities. This file adds the two
//! steps that decide most of our cases: full expansion (products of sums, positive integer
//! powers of sums) and a trigonometric normal form (`cos²x → 1 − sin²x`, multiple angles
//! `sin(n x)` written through `sin x`, `cos x`, compositions like `sin(asin x) = x` removed).
//! That normal form is complete for trigonometric polynomials, so a trigonometric-polynomial
//! identity reduces to `0` exactly. [`decide_zero`] also tries roots of sums
//! ([`reduce_radicals`]) and a common denominator (`crate::algebra::numer_denom`). When all of
//! that leaves a non-zero form, it falls
//! back to evaluation at seeded pseudo-random points and says so: a numeric check is reported
//! as evidence, never as a proof.

use std::collections::HashMap;

use num_traits::{Signed, ToPrimitive};

use crate::diff::diff;
use crate::eval::eval_with;
use crate::expr::{Expr, Func, Node, Rational, Symbol};

/// Expansion stops (returning the partly expanded form) beyond this many terms.
const MAX_TERMS: usize = 20_000;
/// The largest integer power of a sum that is multiplied out.
const MAX_EXPAND_POWER: i64 = 16;

/// Multiplies out products of sums and positive integer powers of sums, everywhere in `e`
/// (function arguments and denominators included).
pub fn expand(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |n| match n.node() {
        Node::Mul(fs) if fs.iter().any(|f| matches!(f.node(), Node::Add(_))) => Some(distribute(fs)),
        Node::Pow(b, x) => {
            let k = x.as_num().filter(|r| r.is_integer()).and_then(|r| r.to_integer().to_i64())?;
            if !(2..=MAX_EXPAND_POWER).contains(&k) || !matches!(b.node(), Node::Add(_)) {
                return None;
            }
            let fs = vec![b.clone(); k as usize];
            Some(distribute(&fs))
        }
        _ => None,
    })
}

/// The product multiplied out by [`crate::algebra`]'s expansion, or left whole beyond
/// [`MAX_TERMS`] terms.
fn distribute(fs: &[Expr]) -> Expr {
    crate::algebra::multiply_out(fs, MAX_TERMS).unwrap_or_else(|_| Expr::mul(fs.iter().cloned()))
}

/// The integer `n` when `e` is `n·x` with `|n| ≥ 2`, and `x`.
fn integer_multiple(e: &Expr) -> Option<(i64, Expr)> {
    let (c, rest) = e.coeff_rest();
    if !c.is_integer() || rest.is_one() {
        return None;
    }
    let n = c.to_integer().to_i64()?;
    if n.abs() < 2 || n.abs() > 12 {
        return None;
    }
    Some((n, rest))
}

/// `(sin(n x), cos(n x))` as polynomials in `sin x`, `cos x`, for `n ≥ 1`.
fn multiple_angle(n: i64, x: &Expr) -> (Expr, Expr) {
    let s = Expr::call(Func::Sin, vec![x.clone()]);
    let c = Expr::call(Func::Cos, vec![x.clone()]);
    let (mut sn, mut cn) = (s.clone(), c.clone());
    for _ in 1..n {
        let sn1 = sn.times(&c).plus(&cn.times(&s));
        let cn1 = cn.times(&c).minus(&sn.times(&s));
        sn = sn1;
        cn = cn1;
    }
    (sn, cn)
}

/// One bottom-up pass of trigonometric and inverse-function rewrites.
fn trig_pass(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |n| match n.node() {
        Node::Call(f, args) => {
            let a = &args[0];
            if let Some((k, x)) = integer_multiple(a) {
                let sign = if k < 0 { -1 } else { 1 };
                let (s, c) = multiple_angle(k.abs(), &x);
                match f {
                    Func::Sin => return Some(Expr::int(sign).times(&s)),
                    Func::Cos => return Some(c),
                    _ => {}
                }
            }
            if let Some(x) = compose_inverse(*f, a) {
                return Some(x);
            }
            match f {
                Func::Tan => Some(Expr::call(Func::Sin, vec![a.clone()]).over(&Expr::call(Func::Cos, vec![a.clone()]))),
                _ => None,
            }
        }
        Node::Pow(b, x) => {
            let k = x.as_num().filter(|r| r.is_integer()).and_then(|r| r.to_integer().to_i64())?;
            if k < 2 {
                return None;
            }
            let rest = Expr::pow(b.clone(), Expr::int(k - 2));
            match b.node() {
                Node::Call(Func::Cos, a) => {
                    let s2 = Expr::call(Func::Sin, a.clone()).powi(2);
                    Some(rest.times(&Expr::one().minus(&s2)))
                }
                Node::Call(Func::Cosh, a) => {
                    let s2 = Expr::call(Func::Sinh, a.clone()).powi(2);
                    Some(rest.times(&Expr::one().plus(&s2)))
                }
                _ => None,
            }
        }
        _ => None,
    })
}

/// The normal form used to compare results: expansion and trigonometric rewrites to a fixed
/// point (at most a few rounds).
pub fn normalize(e: &Expr) -> Expr {
    let mut cur = expand(e);
    for _ in 0..6 {
        let next = expand(&trig_pass(&cur));
        if next == cur {
            break;
        }
        cur = next;
    }
    cur
}

/// Roots of sums: `Σ x_i² · S^(-3/2) − S^(-1/2)` with `S = Σ x_i²` is zero, but expansion
/// alone cannot see it. For each power of a sum `S^(n/d)` this introduces `u = S^(1/d)`,
/// eliminates one variable's leading power by `c v^k = u^d − (S − c v^k)` (a reduction modulo
/// the defining relation), expands, and substitutes `u` back. Returns the shorter of the input
/// and the reduced form (by operation count); a zero comes out as `0`.
pub fn reduce_radicals(e: &Expr) -> Expr {
    let mut cur = e.clone();
    for round in 0..4 {
        let Some((base, d)) = find_radical(&cur) else { break };
        let Some(reduced) = reduce_one_radical(&cur, &base, d, round) else { break };
        if reduced.is_zero() {
            return reduced;
        }
        if reduced.op_count() < cur.op_count() {
            cur = reduced;
        } else {
            break;
        }
    }
    cur
}

/// The first power of a sum with a non-integer exponent, and the lcm of the denominators of
/// all exponents on that base.
fn find_radical(e: &Expr) -> Option<(Expr, i64)> {
    let mut found: Option<Expr> = None;
    let mut seen = std::collections::HashSet::new();
    fn walk(e: &Expr, found: &mut Option<Expr>, seen: &mut std::collections::HashSet<Expr>) {
        if found.is_some() || !seen.insert(e.clone()) {
            return;
        }
        if let Node::Pow(b, x) = e.node() {
            if matches!(b.node(), Node::Add(_)) && x.as_num().is_some_and(|r| !r.is_integer()) {
                *found = Some(b.clone());
                return;
            }
        }
        e.for_each_child(|c| walk(c, found, seen));
    }
    walk(e, &mut found, &mut seen);
    let base = found?;
    let mut d: i64 = 1;
    let mut seen = std::collections::HashSet::new();
    fn denoms(e: &Expr, base: &Expr, d: &mut i64, seen: &mut std::collections::HashSet<Expr>) {
        if !seen.insert(e.clone()) {
            return;
        }
        if let Node::Pow(b, x) = e.node() {
            if b == base {
                if let Some(den) = x.as_num().and_then(|r| r.denom().to_i64()) {
                    *d = num_integer::lcm(*d, den);
                }
            }
        }
        e.for_each_child(|c| denoms(c, base, d, seen));
    }
    denoms(e, &base, &mut d, &mut seen);
    (d <= 12).then_some((base, d))
}

fn reduce_one_radical(e: &Expr, base: &Expr, d: i64, round: usize) -> Option<Expr> {
    // A variable v with base = c v^k + rest, rest free of v.
    let mut pick = None;
    for v in base.free_symbols() {
        let with: Vec<Expr> = base.terms().into_iter().filter(|t| t.contains(&v)).collect();
        if with.len() != 1 {
            continue;
        }
        let (c, mono) = with[0].coeff_rest();
        let (b, k) = mono.base_exp();
        if b.as_sym() == Some(&v) {
            if let Some(k) = k.as_num().and_then(nonneg_int).filter(|k| *k >= 1) {
                pick = Some((v, Expr::num(c), i64::from(k), with[0].clone()));
                break;
            }
        }
    }
    let (v, c, k, lead) = pick?;
    let u = Expr::sym(Symbol::new(&format!("__radical{round}")));
    let ud = u.powi(d);
    let rest = base.minus(&lead);
    let vk = ud.minus(&rest).over(&c);
    let dd = Rational::from_integer(d.into());
    // First the powers of the base (their children are untouched by this pass), then v^j.
    let with_u = map_top_down(e, &mut |n| {
        if n == base {
            return Some(ud.clone());
        }
        match n.node() {
            Node::Pow(b, x) if b == base => {
                let r = x.as_num()? * &dd;
                r.is_integer().then(|| Expr::pow(u.clone(), Expr::num(r)))
            }
            _ => None,
        }
    });
    let replaced = with_u.map_bottom_up(&mut |n| match n.node() {
        Node::Pow(b, x) if b.as_sym() == Some(&v) => {
            let j = x.as_num().filter(|r| r.is_integer()).and_then(|r| r.to_integer().to_i64())?;
            (j >= k).then(|| Expr::sym(v.clone()).powi(j % k).times(&vk.powi(j / k)))
        }
        Node::Sym(s) if *s == v && k == 1 => Some(vk.clone()),
        _ => None,
    });
    let reduced = normalize(&replaced);
    let back = Expr::pow(base.clone(), Expr::frac(1, d));
    let usym = Symbol::new(&format!("__radical{round}"));
    Some(normalize(&reduced.subs1(&usym, &back)).pipe_zero_if(reduced.is_zero()))
}

/// Rewrites top-down: where `f` replaces a node, its children are not visited.
fn map_top_down(e: &Expr, f: &mut impl FnMut(&Expr) -> Option<Expr>) -> Expr {
    fn rec(e: &Expr, f: &mut impl FnMut(&Expr) -> Option<Expr>, memo: &mut HashMap<Expr, Expr>) -> Expr {
        if let Some(done) = memo.get(e) {
            return done.clone();
        }
        let out = match f(e) {
            Some(r) => r,
            None => {
                let mut kids = Vec::new();
                e.for_each_child(|c| kids.push(c.clone()));
                if kids.is_empty() {
                    e.clone()
                } else {
                    let new: Vec<Expr> = kids.iter().map(|c| rec(c, f, memo)).collect();
                    if new == kids {
                        e.clone()
                    } else {
                        e.with_children(new)
                    }
                }
            }
        };
        memo.insert(e.clone(), out.clone());
        out
    }
    rec(e, f, &mut HashMap::new())
}

trait ZeroIf {
    fn pipe_zero_if(self, zero: bool) -> Expr;
}
impl ZeroIf for Expr {
    fn pipe_zero_if(self, zero: bool) -> Expr {
        if zero {
            Expr::zero()
        } else {
            self
        }
    }
}

/// Only the inverse-function compositions and `tan = sin/cos`; no expansion. Used to tidy
/// solutions without destroying their factored shape.
pub fn tidy(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |n| match n.node() {
        Node::Call(f, args) => compose_inverse(*f, &args[0]),
        _ => None,
    })
}

/// The outcome of asking whether an expression is identically zero.
#[derive(Clone, Debug, PartialEq)]
pub enum ZeroCheck {
    /// The normal form is exactly `0`: a symbolic proof.
    Proven,
    /// The normal form is not `0`, but the expression vanished (to rounding) at every one of
    /// `points` random points: evidence, not a proof.
    Numeric {
        /// How many points were evaluated.
        points: usize,
        /// The largest absolute value seen.
        max_residual: f64,
    },
    /// The expression is not zero: its value at one point.
    NonZero {
        /// The point, as (symbol, value) pairs in canonical symbol order.
        at: Vec<(String, f64)>,
        /// The value there.
        value: f64,
    },
    /// Neither route could decide (no point where the expression evaluates).
    Undecided,
}

impl ZeroCheck {
    /// Whether the expression is zero, proven or by numeric evidence.
    pub fn is_zero(&self) -> bool {
        matches!(self, ZeroCheck::Proven | ZeroCheck::Numeric { .. })
    }

    /// A one-line human description.
    pub fn describe(&self) -> String {
        match self {
            ZeroCheck::Proven => "zero (proven symbolically)".to_string(),
            ZeroCheck::Numeric { points, max_residual } => format!(
                "zero numerically only: simplification could not decide; |value| ≤ {max_residual:.1e} at {points} random points (not a proof)"
            ),
            ZeroCheck::NonZero { at, value } => {
                // A constant residual has no point to name ("value -1.000000e0 at )" before).
                if at.is_empty() {
                    return format!("not zero: it is the constant {value}");
                }
                let pt: Vec<String> = at.iter().map(|(s, v)| format!("{s} = {v:.4}")).collect();
                format!("not zero: value {value:.6} at {}", pt.join(", "))
            }
            ZeroCheck::Undecided => "undecided: no point where the expression evaluates".to_string(),
        }
    }
}

/// A small deterministic generator (SplitMix64) so numeric checks repeat exactly.
pub(crate) struct Rng(u64);

impl Rng {
    /// A generator with a fixed seed.
    pub(crate) fn new(seed: u64) -> Rng {
        Rng(seed)
    }
    /// The next value in `[0, 1)`.
    pub(crate) fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A value in `[lo, hi)`.
    pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

/// Replaces every declared function (`V(r)`, `V'(r)`) by the matching derivative of one fixed
/// smooth concrete function, so expressions with declared functions can be evaluated and the
/// derivatives stay consistent with each other (`V'` really is the derivative of `V`).
pub(crate) fn concretize_functions(e: &Expr) -> Expr {
    let mut cache: HashMap<(String, usize), Expr> = HashMap::new();
    e.map_bottom_up(&mut |n| match n.node() {
        Node::Apply { name, orders, args } => {
            let vars: Vec<Symbol> = (0..args.len()).map(|i| Symbol::new(&format!("__z{i}"))).collect();
            let base =
                cache.entry((name.to_string(), args.len())).or_insert_with(|| concrete_function(name, &vars)).clone();
            let mut d = base;
            for (v, &k) in vars.iter().zip(orders) {
                for _ in 0..k {
                    d = diff(&d, v);
                }
            }
            let map: HashMap<Symbol, Expr> = vars.into_iter().zip(args.iter().cloned()).collect();
            Some(d.subs(&map))
        }
        _ => None,
    })
}

fn concrete_function(name: &str, vars: &[Symbol]) -> Expr {
    // Coefficients depend on the name only, so two functions differ and runs repeat.
    let seed = name.bytes().fold(17u64, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b)));
    let mut rng = Rng::new(seed);
    let mut lin = Vec::new();
    let mut quad = Vec::new();
    for v in vars {
        let a = Expr::frac((rng.range(3.0, 13.0)) as i64, 10);
        let b = Expr::frac((rng.range(2.0, 9.0)) as i64, 10);
        lin.push(a.times(&Expr::sym(v.clone())));
        quad.push(b.times(&Expr::sym(v.clone())));
    }
    let s = Expr::call(Func::Sin, vec![Expr::add(lin).plus(&Expr::frac(1, 2))]);
    let q = Expr::add(quad).powi(2);
    let ex = Expr::call(Func::Exp, vec![Expr::add(vars.iter().map(|v| Expr::frac(1, 5).times(&Expr::sym(v.clone()))))]);
    Expr::add([s, q, ex])
}

/// Decides whether `e` is identically zero: first by [`normalize`], then numerically at
/// `points` seeded random points (symbols drawn from `[0.3, 1.7]`, so square roots and
/// logarithms of positive combinations stay real).
pub fn decide_zero(e: &Expr) -> ZeroCheck {
    let n = normalize(e);
    if n.is_zero() || reduce_radicals(&n).is_zero() {
        return ZeroCheck::Proven;
    }
    // Sums of fractions: over a common denominator the numerator alone must vanish.
    let (num, _) = crate::algebra::numer_denom(&n);
    let num = normalize(&num);
    if num.is_zero() || reduce_radicals(&num).is_zero() {
        return ZeroCheck::Proven;
    }
    numeric_zero(&n, 12, 0x5EED)
}

/// The numeric half of [`decide_zero`].
pub fn numeric_zero(e: &Expr, points: usize, seed: u64) -> ZeroCheck {
    let concrete = concretize_functions(e);
    let syms: Vec<Symbol> = concrete.free_symbols().into_iter().collect();
    let terms = concrete.terms();
    let mut rng = Rng::new(seed);
    let mut good = 0;
    let mut max_residual: f64 = 0.0;
    for _ in 0..points * 4 {
        if good == points {
            break;
        }
        let vals: Vec<f64> = syms.iter().map(|_| rng.range(0.3, 1.7)).collect();
        let lookup = |s: &Symbol| syms.iter().position(|x| x == s).map(|i| vals[i]);
        let Ok(v) = eval_with(&concrete, &lookup) else { continue };
        if !v.is_finite() {
            continue;
        }
        let scale = terms.iter().filter_map(|t| eval_with(t, &lookup).ok()).fold(1.0f64, |m, x| {
            if x.is_finite() {
                m.max(x.abs())
            } else {
                m
            }
        });
        if v.abs() > 1e-9 * scale {
            let at = syms.iter().zip(&vals).map(|(s, v)| (s.to_string(), *v)).collect();
            return ZeroCheck::NonZero { at, value: v };
        }
        max_residual = max_residual.max(v.abs());
        good += 1;
    }
    if good == 0 {
        ZeroCheck::Undecided
    } else {
        ZeroCheck::Numeric { points: good, max_residual }
    }
}

/// Whether a rational is a non-negative integer.
pub(crate) fn nonneg_int(r: &Rational) -> Option<u32> {
    if r.is_integer() && !r.is_negative() {
        r.to_integer().to_u32()
    } else {
        None
    }
}

/// A function of an inverse function, resolved on the principal branch: `sin(asin x) = x`,
/// `cos(asin x) = sqrt(1 − x²)`, `sin(atan x) = x/sqrt(1 + x²)`, … `None` when `f(arg)` is not
/// such a composition.
fn compose_inverse(f: Func, arg: &Expr) -> Option<Expr> {
    let Node::Call(g, b) = arg.node() else { return None };
    if b.len() != 1 {
        return None;
    }
    let (x, one) = (b[0].clone(), Expr::one());
    match (f, *g) {
        (Func::Sin, Func::Asin)
        | (Func::Cos, Func::Acos)
        | (Func::Exp, Func::Log)
        | (Func::Log, Func::Exp)
        | (Func::Tan, Func::Atan) => Some(x),
        (Func::Sin, Func::Acos) | (Func::Cos, Func::Asin) => Some(one.minus(&x.powi(2)).sqrt()),
        (Func::Sin, Func::Atan) => Some(x.times(&Expr::pow(one.plus(&x.powi(2)), Expr::frac(-1, 2)))),
        (Func::Cos, Func::Atan) => Some(Expr::pow(one.plus(&x.powi(2)), Expr::frac(-1, 2))),
        // sinh(log u) = (u − 1/u)/2 and cosh(log u) = (u + 1/u)/2 on the logarithm's domain
        // u > 0; for the log forms of the inverse functions, u = a + sqrt(a² ± 1), 1/u is
        // ±(sqrt(a² ± 1) − a) and both give back a exactly (cosh for a ≥ 1, its domain).
        (Func::Sinh, Func::Log) => log_form_argument(&x, 1),
        (Func::Cosh, Func::Log) => log_form_argument(&x, -1),
        _ => None,
    }
}

/// `a` when `u = a + sqrt(a² + sign)` (the logarithmic form of asinh for `sign = 1`, of acosh
/// for `sign = −1`).
fn log_form_argument(u: &Expr, sign: i64) -> Option<Expr> {
    let Node::Add(terms) = u.node() else { return None };
    for t in terms {
        let Node::Pow(base, exp) = t.node() else { continue };
        if *exp != Expr::frac(1, 2) {
            continue;
        }
        let a = u.minus(t);
        if crate::algebra::expand(&base.minus(&a.powi(2)).minus(&Expr::frac(sign, 1))).is_ok_and(|d| d.is_zero()) {
            return Some(a);
        }
    }
    None
}
