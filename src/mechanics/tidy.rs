//! Tidying derived expressions: expand, contract trigonometric products, pull common factors.
//!
//! Derivatives of a Lagrangian come out as sums of products with repeated factors and terms
//! that cancel only after distribution. [`tidy`] brings them to a compact, deterministic form:
//!
//! 1. **expand** products of sums and small integer powers of sums into monomials (so every
//!    cancellation happens in the canonical sum constructor);
//! 2. **contract** pairs of monomials by the angle-addition and Pythagorean identities:
//!    `k R cos a cos b ± k R sin a sin b = k R cos(a ∓ b)`,
//!    `k R sin a cos b ∓ k R cos a sin b = k R sin(a ∓ b)`, `k R cos² a + k R sin² a = k R`,
//!    `k R − k R cos² a = k R sin² a` (and with `sin`);
//! 3. **collect**: pull the content (rational gcd and common powers) out of the sum, then
//!    greedily factor the most frequent factor (a multivariate Horner scheme), merging terms
//!    that end up with the same sum as a cofactor (`c·S + s·S = (c + s)·S`).
//!
//! The result goes through [`crate::simplify::simplify`], and the smaller of it and the
//! input (by [`Expr::op_count`]) is returned: tidying never lengthens an expression.

use std::collections::HashMap;

use num_integer::Integer;
use num_traits::{One, Signed, ToPrimitive, Zero};

use crate::expr::{Expr, Func, Node, Rational};

/// The largest number of monomials a single product is expanded into; beyond it the product
/// stays factored.
const MAX_EXPANDED_TERMS: usize = 50_000;

/// Tidies `e`: expand, contract trigonometric products, collect common factors, simplify.
/// Never returns a longer expression than `e` (by [`Expr::op_count`]).
pub fn tidy(e: &Expr) -> Expr {
    let expanded = expand(e);
    let contracted = contract_trig(&expanded);
    let collected = collect_sum(&contracted);
    let simplified = crate::simplify::simplify(&collected);
    let best = if simplified.op_count() <= collected.op_count() { simplified } else { collected };
    if best.op_count() <= e.op_count() {
        best
    } else {
        e.clone()
    }
}

// ----- expansion ----------------------------------------------------------------------------

/// Distributes products over sums and expands positive integer powers of sums, bottom-up
/// with sharing. Function arguments and denominators are left as they are.
pub(crate) fn expand(e: &Expr) -> Expr {
    let mut memo = HashMap::new();
    expand_rec(e, &mut memo)
}

fn expand_rec(e: &Expr, memo: &mut HashMap<Expr, Expr>) -> Expr {
    if let Some(d) = memo.get(e) {
        return d.clone();
    }
    let out = match e.node() {
        Node::Add(ts) => Expr::add(ts.iter().map(|t| expand_rec(t, memo))),
        Node::Mul(fs) => {
            let parts: Vec<Expr> = fs.iter().map(|f| expand_rec(f, memo)).collect();
            multiply_out(&parts)
        }
        // Only small positive integer powers are expanded; the bases of other powers
        // (denominators, square roots) stay as written, so equal bases stay equal.
        Node::Pow(b, x) => match x.as_num().and_then(|r| if r.is_integer() { r.to_integer().to_i64() } else { None }) {
            Some(n) if (2..=8).contains(&n) => {
                let b2 = expand_rec(b, memo);
                if matches!(b2.node(), Node::Add(_)) {
                    multiply_out(&vec![b2; n as usize])
                } else {
                    Expr::pow(b2, x.clone())
                }
            }
            _ => e.clone(),
        },
        _ => e.clone(),
    };
    memo.insert(e.clone(), out.clone());
    out
}

fn multiply_out(parts: &[Expr]) -> Expr {
    let estimate: usize = parts.iter().map(|p| p.terms().len()).fold(1usize, |a, b| a.saturating_mul(b));
    if estimate > MAX_EXPANDED_TERMS {
        return Expr::mul(parts.iter().cloned());
    }
    let mut acc: Vec<Expr> = vec![Expr::one()];
    for p in parts {
        let ts = p.terms();
        if ts.len() == 1 {
            for a in acc.iter_mut() {
                *a = a.times(&ts[0]);
            }
            continue;
        }
        let mut next = Vec::with_capacity(acc.len() * ts.len());
        for a in &acc {
            for t in &ts {
                next.push(a.times(t));
            }
        }
        acc = next;
    }
    Expr::add(acc)
}

// ----- trigonometric contraction ------------------------------------------------------------

/// The shape of a monomial's trigonometric part.
#[derive(Clone, PartialEq, Eq, Hash)]
enum Trig {
    /// No sin/cos factor.
    Plain,
    /// `cos a cos b`, `sin a sin b`, `sin a cos b`, `cos a sin b` with `a < b`.
    CC(Expr, Expr),
    SS(Expr, Expr),
    SC(Expr, Expr),
    CS(Expr, Expr),
    /// `cos² a`, `sin² a`.
    C2(Expr),
    S2(Expr),
    /// Anything else.
    Other,
}

fn trig_factor(f: &Expr) -> Option<(Func, Expr, i64)> {
    let (b, x) = f.base_exp();
    let n = x.as_num().and_then(|r| if r.is_integer() { r.to_integer().to_i64() } else { None })?;
    match b.node() {
        Node::Call(func @ (Func::Sin | Func::Cos), args) => Some((*func, args[0].clone(), n)),
        _ => None,
    }
}

/// Splits a monomial into coefficient, trig shape and the remaining factors.
fn classify(term: &Expr) -> (Rational, Trig, Expr) {
    let (c, rest) = term.coeff_rest();
    let mut trig = Vec::new();
    let mut others = Vec::new();
    for f in rest.factors() {
        match trig_factor(&f) {
            Some(t) => trig.push(t),
            None => others.push(f),
        }
    }
    let r = Expr::mul(others);
    let shape = match trig.as_slice() {
        [] => Trig::Plain,
        [(f, a, 2)] => {
            if *f == Func::Cos {
                Trig::C2(a.clone())
            } else {
                Trig::S2(a.clone())
            }
        }
        [(f1, a1, 1), (f2, a2, 1)] if a1 != a2 => {
            let ((f1, a1), (f2, a2)) = if a1.canonical_cmp(a2).is_le() {
                ((*f1, a1.clone()), (*f2, a2.clone()))
            } else {
                ((*f2, a2.clone()), (*f1, a1.clone()))
            };
            match (f1, f2) {
                (Func::Cos, Func::Cos) => Trig::CC(a1, a2),
                (Func::Sin, Func::Sin) => Trig::SS(a1, a2),
                (Func::Sin, Func::Cos) => Trig::SC(a1, a2),
                _ => Trig::CS(a1, a2),
            }
        }
        _ => Trig::Other,
    };
    if shape == Trig::Other {
        return (c, Trig::Other, rest);
    }
    (c, shape, r)
}

fn cos(a: Expr) -> Expr {
    Expr::call(Func::Cos, vec![a])
}
fn sin(a: Expr) -> Expr {
    Expr::call(Func::Sin, vec![a])
}

/// Applies the angle-addition and Pythagorean identities to pairs of terms of a sum (and of
/// sums nested in products), until nothing changes.
pub(crate) fn contract_trig(e: &Expr) -> Expr {
    let mut cur = e.clone();
    for _ in 0..4 {
        let next = cur.map_bottom_up(&mut |x| match x.node() {
            Node::Add(_) => contract_sum(x),
            _ => None,
        });
        if next == cur {
            break;
        }
        cur = next;
    }
    cur
}

fn contract_sum(sum: &Expr) -> Option<Expr> {
    let terms = sum.terms();
    let classified: Vec<(Rational, Trig, Expr)> = terms.iter().map(classify).collect();
    // Index terms by (shape, rest).
    let mut index: HashMap<(Trig, Expr), usize> = HashMap::new();
    for (i, (_, shape, r)) in classified.iter().enumerate() {
        if *shape != Trig::Other {
            index.entry((shape.clone(), r.clone())).or_insert(i);
        }
    }
    let mut used = vec![false; terms.len()];
    let mut out: Vec<Expr> = Vec::new();
    let mut changed = false;
    // Plain terms last: they are partners of `cos²`/`sin²` terms, never the ones that look.
    let mut order: Vec<usize> = (0..terms.len()).collect();
    order.sort_by_key(|&i| classified[i].1 == Trig::Plain);
    for i in order {
        if used[i] {
            continue;
        }
        let (k, shape, r) = &classified[i];
        let partner = |s: Trig| index.get(&(s, r.clone())).copied();
        let mut pair: Option<(usize, Expr)> = None;
        let kk = Expr::num(k.clone());
        match shape {
            Trig::CC(a, b) => {
                if let Some(j) = partner(Trig::SS(a.clone(), b.clone())) {
                    let k2 = &classified[j].0;
                    if k2 == k {
                        pair = Some((j, kk.times(&cos(a.minus(b)))));
                    } else if *k2 == -k.clone() {
                        pair = Some((j, kk.times(&cos(a.plus(b)))));
                    }
                }
            }
            Trig::SS(a, b) => {
                if let Some(j) = partner(Trig::CC(a.clone(), b.clone())) {
                    let k2 = &classified[j].0;
                    if k2 == k {
                        pair = Some((j, kk.times(&cos(a.minus(b)))));
                    } else if *k2 == -k.clone() {
                        pair = Some((j, kk.neg().times(&cos(a.plus(b)))));
                    }
                }
            }
            Trig::SC(a, b) => {
                // k sin a cos b + k2 cos a sin b
                if let Some(j) = partner(Trig::CS(a.clone(), b.clone())) {
                    let k2 = &classified[j].0;
                    if *k2 == -k.clone() {
                        pair = Some((j, kk.times(&sin(a.minus(b)))));
                    } else if k2 == k {
                        pair = Some((j, kk.times(&sin(a.plus(b)))));
                    }
                }
            }
            Trig::CS(a, b) => {
                // k cos a sin b + k2 sin a cos b
                if let Some(j) = partner(Trig::SC(a.clone(), b.clone())) {
                    let k2 = &classified[j].0;
                    if *k2 == -k.clone() {
                        pair = Some((j, kk.times(&sin(b.minus(a)))));
                    } else if k2 == k {
                        pair = Some((j, kk.times(&sin(a.plus(b)))));
                    }
                }
            }
            Trig::C2(a) => {
                if let Some(j) = partner(Trig::S2(a.clone())).filter(|&j| classified[j].0 == *k) {
                    pair = Some((j, kk.clone()));
                } else if let Some(j) = partner(Trig::Plain).filter(|&j| classified[j].0 == -k.clone()) {
                    // −k R + k R cos² a = −k R sin² a
                    pair = Some((j, kk.neg().times(&sin(a.clone()).powi(2))));
                }
            }
            Trig::S2(a) => {
                if let Some(j) = partner(Trig::C2(a.clone())).filter(|&j| classified[j].0 == *k) {
                    pair = Some((j, kk.clone()));
                } else if let Some(j) = partner(Trig::Plain).filter(|&j| classified[j].0 == -k.clone()) {
                    pair = Some((j, kk.neg().times(&cos(a.clone()).powi(2))));
                }
            }
            Trig::Plain | Trig::Other => {}
        }
        match pair {
            Some((j, combined)) if j != i && !used[j] => {
                used[i] = true;
                used[j] = true;
                changed = true;
                out.push(combined.times(r));
            }
            _ => {
                used[i] = true;
                out.push(terms[i].clone());
            }
        }
    }
    if changed {
        Some(Expr::add(out))
    } else {
        None
    }
}

// ----- collection ---------------------------------------------------------------------------

/// A monomial: rational coefficient and (base, exponent) factors with distinct bases.
#[derive(Clone)]
struct Mono {
    c: Rational,
    f: Vec<(Expr, Rational)>,
}

impl Mono {
    fn from_expr(e: &Expr) -> Mono {
        let (c, rest) = e.coeff_rest();
        let mut f: Vec<(Expr, Rational)> = Vec::new();
        if !rest.is_one() {
            for x in rest.factors() {
                let (b, p) = x.base_exp();
                match p.as_num() {
                    Some(r) => f.push((b, r.clone())),
                    None => f.push((x.clone(), Rational::one())),
                }
            }
        }
        Mono { c, f }
    }

    fn exp_of(&self, b: &Expr) -> Option<&Rational> {
        self.f.iter().find(|(x, _)| x == b).map(|(_, r)| r)
    }

    fn divide(&mut self, b: &Expr, e: &Rational) {
        if let Some(pos) = self.f.iter().position(|(x, _)| x == b) {
            let r = &self.f[pos].1 - e;
            if r.is_zero() {
                self.f.remove(pos);
            } else {
                self.f[pos].1 = r;
            }
        }
    }

    fn to_expr(&self) -> Expr {
        let mut fs = vec![Expr::num(self.c.clone())];
        fs.extend(self.f.iter().map(|(b, r)| Expr::pow(b.clone(), Expr::num(r.clone()))));
        Expr::mul(fs)
    }
}

fn rational_gcd(a: &Rational, b: &Rational) -> Rational {
    Rational::new(a.numer().gcd(b.numer()), a.denom().lcm(b.denom()))
}

/// Collects common factors of a sum (and of sums nested in it, bottom-up).
pub(crate) fn collect_sum(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |x| match x.node() {
        Node::Add(ts) => Some(collect(ts.iter().map(Mono::from_expr).collect())),
        _ => None,
    })
}

fn power(b: &Expr, e: &Rational) -> Expr {
    Expr::pow(b.clone(), Expr::num(e.clone()))
}

fn collect(terms: Vec<Mono>) -> Expr {
    Expr::mul(collect_factors(terms))
}

/// [`collect`] as a list of factors (rational content first), so a caller multiplying in
/// more factors keeps `g·2·(1 − cos θ)` from distributing the `2` over the sum.
fn collect_factors(mut terms: Vec<Mono>) -> Vec<Expr> {
    if terms.len() <= 1 {
        return vec![terms.first().map_or_else(Expr::zero, Mono::to_expr)];
    }
    // Content: rational gcd and common powers.
    let mut g = terms[0].c.abs();
    for t in &terms[1..] {
        g = rational_gcd(&g, &t.c);
    }
    if !g.is_zero() {
        for t in terms.iter_mut() {
            t.c = &t.c / &g;
        }
    }
    let mut content: Vec<Expr> = Vec::new();
    let bases: Vec<Expr> = terms[0].f.iter().map(|(b, _)| b.clone()).collect();
    for b in bases {
        let exps: Option<Vec<Rational>> = terms.iter().map(|t| t.exp_of(&b).cloned()).collect();
        let Some(exps) = exps else { continue };
        let common = if exps.iter().all(Rational::is_positive) {
            exps.iter().min().cloned()
        } else if exps.iter().all(Rational::is_negative) {
            exps.iter().max().cloned()
        } else {
            None
        };
        if let Some(c) = common {
            for t in terms.iter_mut() {
                t.divide(&b, &c);
            }
            content.push(power(&b, &c));
        }
    }
    // Sign: more positive than negative terms inside, and on a tie a positive constant
    // (`1 − cos θ` rather than `cos θ − 1`).
    let negatives = terms.iter().filter(|t| t.c.is_negative()).count();
    let positives = terms.len() - negatives;
    let constant_negative = terms.iter().any(|t| t.f.is_empty() && t.c.is_negative());
    if negatives > positives || (negatives == positives && constant_negative) {
        g = -g;
        for t in terms.iter_mut() {
            t.c = -t.c.clone();
        }
    }
    content.insert(0, Expr::num(g));
    content.push(horner(terms));
    content
}

/// Greedy factoring of a content-free list of monomials.
fn horner(terms: Vec<Mono>) -> Expr {
    if terms.len() <= 1 {
        return terms.first().map_or_else(Expr::zero, Mono::to_expr);
    }
    // The most frequent (base, sign of exponent).
    let mut counts: HashMap<(Expr, bool), usize> = HashMap::new();
    for t in &terms {
        for (b, r) in &t.f {
            *counts.entry((b.clone(), r.is_positive())).or_default() += 1;
        }
    }
    let best = counts
        .into_iter()
        .filter(|(_, n)| *n >= 2)
        .max_by(|(ka, na), (kb, nb)| na.cmp(nb).then_with(|| kb.0.canonical_cmp(&ka.0)).then(kb.1.cmp(&ka.1)));
    let Some(((b, positive), _)) = best else {
        return merge_cofactors(terms.iter().map(Mono::to_expr).collect());
    };
    let (mut with, without): (Vec<Mono>, Vec<Mono>) =
        terms.into_iter().partition(|t| t.exp_of(&b).is_some_and(|r| r.is_positive() == positive));
    let exps = with.iter().filter_map(|t| t.exp_of(&b).cloned());
    let e = if positive { exps.min() } else { exps.max() }.unwrap_or_else(Rational::one);
    for t in with.iter_mut() {
        t.divide(&b, &e);
    }
    let mut inner = collect_factors(with);
    inner.push(power(&b, &e));
    let factored = Expr::mul(inner);
    let mut parts = vec![factored];
    if !without.is_empty() {
        parts.push(horner(without));
    }
    let flat: Vec<Expr> = parts.iter().flat_map(Expr::terms).collect();
    merge_cofactors(flat)
}

/// Merges terms that share a sum factor: `c·S + s·S → (c + s)·S`.
fn merge_cofactors(terms: Vec<Expr>) -> Expr {
    let mut groups: Vec<(Expr, Vec<Expr>)> = Vec::new();
    let mut rest: Vec<Expr> = Vec::new();
    for t in terms {
        let sum_factor = t.factors().into_iter().find(|f| matches!(f.node(), Node::Add(_)));
        match sum_factor {
            Some(s) => match groups.iter_mut().find(|(g, _)| *g == s) {
                Some((_, members)) => members.push(t.over(&s)),
                None => groups.push((s.clone(), vec![t.over(&s)])),
            },
            None => rest.push(t),
        }
    }
    let mut out = rest;
    for (s, members) in groups {
        if members.len() == 1 {
            out.push(members[0].times(&s));
        } else {
            let mut cof = collect_factors(Expr::add(members).terms().iter().map(Mono::from_expr).collect());
            cof.push(s);
            out.push(Expr::mul(cof));
        }
    }
    Expr::add(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::parse;

    fn p(s: &str) -> Expr {
        parse(s).unwrap()
    }

    #[test]
    fn contracts_angle_addition_and_pythagoras() {
        assert_eq!(tidy(&p("cos(a) cos(b) + sin(a) sin(b)")), p("cos(a - b)"));
        assert_eq!(tidy(&p("m cos(a)^2 + m sin(a)^2")), p("m"));
        assert_eq!(tidy(&p("k - k cos(a)^2")), p("k sin(a)^2"));
        assert_eq!(tidy(&p("sin(a) cos(b) - cos(a) sin(b)")), p("sin(a - b)"));
    }

    #[test]
    fn pulls_content_and_merges_equal_cofactors() {
        let e = p("m1 l^2 c + m2 l^2 c + m1 l^2 s + m2 l^2 s");
        assert_eq!(tidy(&e), p("l^2 (c + s) (m1 + m2)"));
    }

    #[test]
    fn never_lengthens() {
        let e = p("m (a - u t)^2 φ'");
        assert_eq!(tidy(&e), e);
    }
}
