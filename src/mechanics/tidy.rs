//! Tidying derived expressions: expand, contract trigonometric products, pull common factors.
//!
//! Derivatives of a Lagrangian come out as sums of products with repeated factors and terms
//! that cancel only after distribution. [`tidy`] brings them to a compact, deterministic form:
//!
//! 1. **expand** products of sums and small positive integer powers of sums into monomials
//!    (so every cancellation happens), leaving denominators, roots and function arguments
//!    as they are (unlike [`crate::algebra::expand`], which also expands the bases of negative
//!    powers: here `1/(a − u t)²` must stay a power of one base so it can be collected);
//! 2. **contract** pairs of monomials by the angle-addition and Pythagorean identities:
//!    `k R cos a cos b ± k R sin a sin b = k R cos(a ∓ b)`,
//!    `k R sin a cos b ∓ k R cos a sin b = k R sin(a ∓ b)`, `k R cos² a + k R sin² a = k R`,
//!    `k R − k R cos² a = k R sin² a` (and with `sin`);
//! 3. **collect**: pull the content (rational gcd and common powers) out of the sum, then
//!    greedily factor the most frequent factor (a multivariate Horner scheme), merging terms
//!    that end up with the same sum as a cofactor (`c·S + s·S = (c + s)·S`).
//!
//! Steps 1–3 work on the sparse-polynomial form of [`crate::algebra::SparsePoly`] (atoms
//! numbered in an [`crate::algebra::Atoms`] table per run, monomials as sorted
//! `(atom, exponent)` lists, exact coefficients), not on interned
//! expressions: expanding the 30-link pendulum's forcing produces tens of thousands of
//! monomials, and building each as a canonical, interned [`Expr`] would dominate the run.
//!
//! The result goes through [`crate::simplify::simplify`], and the smallest of it, the
//! collected form and the input (by [`Expr::op_count`]) is returned: tidying never lengthens
//! an expression.

use std::rc::Rc;

use num_integer::Integer;
use num_rational::Rational64;
use num_traits::{One, Signed, Zero};

use crate::algebra::{big, merge_keys, small_exp, Atoms, Coef, FxMap, Key};
use crate::diff::Differentiator;
use crate::expr::{Expr, Func, Node, Rational, Symbol};

/// The largest number of monomials a single product is expanded into; beyond it the product
/// stays a single atom.
const MAX_EXPANDED_TERMS: usize = 200_000;

/// The largest expression (in operations) handed to the e-graph simplifier.
const MAX_SIMPLIFY_OPS: usize = 120;

/// Tidies `e`: expand, contract trigonometric products, collect common factors, simplify.
/// Never returns a longer expression than `e` (by [`Expr::op_count`]).
pub fn tidy(e: &Expr) -> Expr {
    let mut best = e.clone();
    let mut collected_best: Option<Expr> = None;
    for expand_all in [false, true] {
        let mut ctx = Ctx { expand_all, ..Ctx::default() };
        let poly = ctx.expand(e);
        let poly = ctx.contract(poly);
        let collected = ctx.collect_poly(&poly);
        if !collected_best.as_ref().is_some_and(|b| b.op_count() <= collected.op_count()) {
            collected_best = Some(collected);
        }
    }
    if let Some(collected) = collected_best {
        // The e-graph runs once, on the better collected form, and only on small expressions:
        // on large ones its budget is spent before it finds anything.
        let simplified = if collected.op_count() <= MAX_SIMPLIFY_OPS {
            crate::simplify::simplify(&collected)
        } else {
            collected.clone()
        };
        for candidate in [collected, simplified] {
            if candidate.op_count() < best.op_count() {
                best = candidate;
            }
        }
    }
    best
}

// ----- the polynomial form ----------------------------------------------------------------

/// The sparse polynomial form is [`crate::algebra`]'s, shared with the rest of the engine;
/// [`QuadraticParts`] and the mechanics routes hold it under this name.
pub(crate) use crate::algebra::SparsePoly as Poly;

/// Monomials with their coefficients.
type Terms = Vec<(Key, Rational)>;

/// A Lagrangian at most quadratic in the velocities, by degree:
/// `L = ½ Σ_ij W_ij v_i v_j + Σ_i b_i v_i + L0`.
#[doc(hidden)]
pub struct QuadraticParts {
    /// `W_ij` for `i ≤ j` (entries below the diagonal are empty).
    pub w: Vec<Vec<Poly>>,
    /// `b_i`.
    pub b: Vec<Poly>,
    /// `L0`.
    pub l0: Poly,
}

/// The trigonometric shape of a monomial (atom ids of the sin/cos factors stripped off).
#[derive(Clone, PartialEq, Eq, Hash)]
enum Trig {
    Plain,
    CC(Expr, Expr),
    SS(Expr, Expr),
    SC(Expr, Expr),
    CS(Expr, Expr),
    C2(Expr),
    S2(Expr),
}

/// Atom table and memo for one tidy run.
#[derive(Default)]
#[doc(hidden)]
pub struct Ctx {
    /// Expand every small positive power of a sum; otherwise only powers of sums that contain
    /// a velocity or a sin/cos (where cancellations and contractions happen), so that
    /// `(a − u t)²` and `(p − m ω x)²` keep their shape.
    expand_all: bool,
    /// The atom table, `algebra`'s (the numbering the shared polynomial form is read in).
    atoms: Atoms,
    /// `Some((sin or cos, argument))` for atoms that are `sin(a)` / `cos(a)`, by atom number.
    trig: Vec<Option<(Func, Expr)>>,
    /// `∂atom/∂x` as polynomials.
    dmemo: FxMap<(u32, u32), Rc<Poly>>,
    /// Variables of differentiation, numbered (so memo keys hash as integers).
    vars: FxMap<Symbol, u32>,
    /// `Σ_j ∂atom/∂q_j q'_j` as polynomials.
    dtmemo: FxMap<u32, Rc<Poly>>,
    diff: Differentiator,
    memo: FxMap<Expr, Rc<Poly>>,
    /// Tidied function arguments.
    args: FxMap<Expr, Expr>,
}

impl Ctx {
    /// A context for the mechanics pipeline (powers of velocity-free sums stay whole).
    pub fn new() -> Ctx {
        Ctx::default()
    }

    /// `e` as a contracted polynomial in its atoms.
    pub fn poly(&mut self, e: &Expr) -> Poly {
        let p = self.expand(e);
        self.contract(p)
    }

    /// `∂p/∂x`: each atom is differentiated once per variable (memoised) by the chain rule.
    pub fn diff(&mut self, p: &Poly, x: &Symbol) -> Poly {
        let next = self.vars.len() as u32;
        let xid = *self.vars.entry(x.clone()).or_insert(next);
        self.chain(p, &mut |ctx, a| ctx.atom_diff_id(a, xid, x))
    }

    /// `Σ_j (∂p/∂q_j) q'_j`: the part of `d/dt p` carried by the coordinates, in one pass
    /// (each atom's own `Σ_j ∂a/∂q_j q'_j` is memoised; one `Ctx` serves one coordinate set).
    pub fn dt_coords(&mut self, p: &Poly, coords: &[Symbol], velocities: &[Symbol]) -> Poly {
        self.chain(p, &mut |ctx, a| {
            if let Some(d) = ctx.dtmemo.get(&a) {
                return d.clone();
            }
            let mut acc = Poly::default();
            for (q, v) in coords.iter().zip(velocities) {
                let da = ctx.atom_diff(a, q);
                if !da.is_zero() {
                    let vp = Poly::atom(ctx.atom_id(&Expr::sym(v.clone())), Rational64::one());
                    acc.add(&da.mul(&vp));
                }
            }
            let rc = Rc::new(acc);
            ctx.dtmemo.insert(a, rc.clone());
            rc
        })
    }

    /// The chain rule over every atom of every monomial, with `datom` giving the derivative of
    /// one atom.
    fn chain(&mut self, p: &Poly, datom: &mut dyn FnMut(&mut Ctx, u32) -> Rc<Poly>) -> Poly {
        let mut out = Poly::default();
        for (key, c) in &p.terms {
            for (i, (a, e)) in key.iter().enumerate() {
                let da = datom(self, *a);
                if da.terms.is_empty() {
                    continue;
                }
                let mut rest: Key = key.clone();
                let e1 = *e - Rational64::one();
                if e1.is_zero() {
                    rest.remove(i);
                } else {
                    rest[i].1 = e1;
                }
                let coeff = if e.is_one() { c.clone() } else { c.mul(&Coef::Small(*e)) };
                for (k2, c2) in &da.terms {
                    out.add_term(merge_keys(&rest, k2), coeff.mul(c2));
                }
            }
        }
        out
    }

    fn atom_diff(&mut self, a: u32, x: &Symbol) -> Rc<Poly> {
        let next = self.vars.len() as u32;
        let xid = *self.vars.entry(x.clone()).or_insert(next);
        self.atom_diff_id(a, xid, x)
    }

    fn atom_diff_id(&mut self, a: u32, xid: u32, x: &Symbol) -> Rc<Poly> {
        if let Some(p) = self.dmemo.get(&(a, xid)) {
            return p.clone();
        }
        let atom = self.atoms[a].clone();
        let d = self.diff.diff(&atom, x);
        let p = Rc::new(if d.is_zero() { Poly::default() } else { self.expand(&d) });
        self.dmemo.insert((a, xid), p.clone());
        p
    }

    /// Splits a polynomial `L` that is at most quadratic in `velocities`,
    /// `L = ½ Σ_ij W_ij v_i v_j + Σ_i b_i v_i + L0`, into its coefficient polynomials, or `None`
    /// when `L` is not of that form (a velocity inside another atom, as in `sqrt(1 − v²)`, a
    /// negative or fractional velocity power, a cubic term, an acceleration).
    pub fn quadratic_split(&mut self, p: &Poly, velocities: &[Symbol]) -> Option<QuadraticParts> {
        let n = velocities.len();
        let vid: Vec<u32> = velocities.iter().map(|v| self.atom_id(&Expr::sym(v.clone()))).collect();
        let mut parts =
            QuadraticParts { w: vec![vec![Poly::default(); n]; n], b: vec![Poly::default(); n], l0: Poly::default() };
        let mut has_rate: FxMap<u32, bool> = FxMap::default();
        for (key, c) in &p.terms {
            let mut rest = Key(Vec::with_capacity(key.len()));
            let mut vel: Vec<usize> = Vec::new();
            for &(a, e) in key.iter() {
                if let Some(i) = vid.iter().position(|&v| v == a) {
                    if !e.is_integer() || !e.is_positive() || vel.len() + e.to_integer() as usize > 2 {
                        return None;
                    }
                    vel.extend(std::iter::repeat(i).take(e.to_integer() as usize));
                    continue;
                }
                // Any other atom must be free of time derivatives (velocities, accelerations).
                let atom = &self.atoms[a];
                if *has_rate.entry(a).or_insert_with(|| atom.free_symbols().iter().any(|s| s.primes() > 0)) {
                    return None;
                }
                rest.push((a, e));
            }
            match vel.as_slice() {
                [] => parts.l0.add_term(rest, c.clone()),
                [i] => parts.b[*i].add_term(rest, c.clone()),
                [i, j] if i == j => parts.w[*i][*i].add_term(rest, c.mul(&Coef::Small(Rational64::from_integer(2)))),
                [i, j] => parts.w[(*i).min(*j)][(*i).max(*j)].add_term(rest, c.clone()),
                _ => return None,
            }
        }
        Some(parts)
    }

    /// `e` as a polynomial without expanding its sums: a sum inside a product, or raised to a
    /// power, stays one atom. Used on already collected expressions (entries of `W`) so that
    /// their derivatives keep factors like `(m2 + … + m_n)` whole, and terms with the same
    /// such factor meet as one monomial. The value is unchanged.
    pub fn shallow(&mut self, e: &Expr) -> Poly {
        match e.node() {
            Node::Add(ts) => {
                let mut acc = Poly::default();
                for t in ts {
                    acc.add(&self.shallow(t));
                }
                acc
            }
            Node::Mul(fs) => {
                let mut acc = Poly::constant(Rational::one());
                for f in fs {
                    let p = self.shallow_factor(f);
                    acc = acc.mul(&p);
                }
                acc
            }
            _ => self.shallow_factor(e),
        }
    }

    fn shallow_factor(&mut self, f: &Expr) -> Poly {
        match f.node() {
            Node::Add(_) => self.leaf(f, Rational64::one()),
            Node::Pow(b, x) if matches!(b.node(), Node::Add(_)) => match x.as_num().and_then(small_exp) {
                Some(r) => self.leaf(b, r),
                None => self.leaf(f, Rational64::one()),
            },
            _ => self.expand(f),
        }
    }

    /// Contracts and collects `p` into an expression.
    pub fn finish(&mut self, p: Poly) -> Expr {
        let p = self.contract(p);
        self.collect_poly(&p)
    }

    fn atom_id(&mut self, e: &Expr) -> u32 {
        let id = self.atoms.id(e);
        if id as usize == self.trig.len() {
            // A new atom.
            self.trig.push(match e.node() {
                Node::Call(f @ (Func::Sin | Func::Cos), args) => Some((*f, args[0].clone())),
                _ => None,
            });
        }
        id
    }

    /// An atom, with the arguments of function calls tidied first (`V(x² + y²)` after a
    /// polar substitution becomes `V(r²)`).
    fn leaf(&mut self, e: &Expr, exp: Rational64) -> Poly {
        let e = match e.node() {
            Node::Call(..) | Node::Apply { .. } => {
                let mut kids = Vec::new();
                e.for_each_child(|c| kids.push(c.clone()));
                if kids.iter().all(|k| matches!(k.node(), Node::Sym(_) | Node::Num(_))) {
                    e.clone()
                } else {
                    let tidied: Vec<Expr> = kids.iter().map(|k| self.tidy_arg(k)).collect();
                    e.with_children(tidied)
                }
            }
            _ => e.clone(),
        };
        match e.node() {
            Node::Num(r) => {
                // A call that folded to a number.
                if exp.is_one() {
                    return Poly::constant(r.clone());
                }
                let v = Expr::pow(e.clone(), Expr::num(big(exp)));
                match v.as_num() {
                    Some(r) => Poly::constant(r.clone()),
                    None => {
                        let id = self.atom_id(&v);
                        Poly::atom(id, Rational64::one())
                    }
                }
            }
            _ => {
                let id = self.atom_id(&e);
                Poly::atom(id, exp)
            }
        }
    }

    fn tidy_arg(&mut self, e: &Expr) -> Expr {
        if let Some(t) = self.args.get(e) {
            return t.clone();
        }
        if is_signed_symbol_sum(e) {
            return e.clone();
        }
        let t = tidy(e);
        self.args.insert(e.clone(), t.clone());
        t
    }

    fn expand(&mut self, e: &Expr) -> Poly {
        (*self.expand_rc(e)).clone()
    }

    fn expand_rc(&mut self, e: &Expr) -> Rc<Poly> {
        if let Some(p) = self.memo.get(e) {
            return p.clone();
        }
        let p = match e.node() {
            Node::Num(r) => Poly::constant(r.clone()),
            Node::Add(ts) => {
                let mut acc = Poly::default();
                for t in ts {
                    let p = self.expand_rc(t);
                    acc.add(&p);
                }
                acc
            }
            Node::Mul(fs) => {
                let parts: Vec<Rc<Poly>> = fs.iter().map(|f| self.expand_rc(f)).collect();
                let estimate = parts.iter().fold(1usize, |a, p| a.saturating_mul(p.terms.len().max(1)));
                if estimate > MAX_EXPANDED_TERMS {
                    self.leaf(e, Rational64::one())
                } else {
                    let mut acc = Poly::constant(Rational::one());
                    for p in parts {
                        acc = acc.mul(&p);
                    }
                    acc
                }
            }
            Node::Pow(b, x) => {
                let r = x.as_num().and_then(small_exp);
                match r {
                    Some(r)
                        if r.is_integer()
                            && (2..=8).contains(r.numer())
                            && matches!(b.node(), Node::Add(_))
                            && (self.expand_all || worth_expanding(b)) =>
                    {
                        let base = self.expand_rc(b);
                        let n = *r.numer() as usize;
                        if base.terms.len().saturating_pow(n as u32) > MAX_EXPANDED_TERMS {
                            self.leaf(e, Rational64::one())
                        } else {
                            let mut acc = (*base).clone();
                            for _ in 1..n {
                                acc = acc.mul(&base);
                            }
                            acc
                        }
                    }
                    Some(r) => self.leaf(b, r),
                    None => self.leaf(e, Rational64::one()),
                }
            }
            _ => self.leaf(e, Rational64::one()),
        };
        let rc = Rc::new(p);
        self.memo.insert(e.clone(), rc.clone());
        rc
    }

    fn to_expr_key(&self, key: &[(u32, Rational64)]) -> Vec<Expr> {
        key.iter().map(|(a, r)| Expr::pow(self.atoms[*a].clone(), Expr::num(big(*r)))).collect()
    }

    // ----- contraction ----------------------------------------------------------------------

    /// Splits a key into its trigonometric shape and the remaining key.
    fn classify(&self, key: &[(u32, Rational64)]) -> Option<(Trig, Key)> {
        let trig: Vec<usize> = (0..key.len()).filter(|&i| self.trig[key[i].0 as usize].is_some()).collect();
        let rest = |skip: &[usize]| -> Key {
            key.iter().enumerate().filter(|(i, _)| !skip.contains(i)).map(|(_, x)| *x).collect()
        };
        match trig.as_slice() {
            [] => Some((Trig::Plain, Key(key.to_vec()))),
            [i] => {
                let (f, a) = self.trig[key[*i].0 as usize].clone()?;
                if key[*i].1 != Rational64::from_integer(2) {
                    return None;
                }
                let shape = if f == Func::Cos { Trig::C2(a) } else { Trig::S2(a) };
                Some((shape, rest(&[*i])))
            }
            [i, j] => {
                if !key[*i].1.is_one() || !key[*j].1.is_one() {
                    return None;
                }
                let (f1, a1) = self.trig[key[*i].0 as usize].clone()?;
                let (f2, a2) = self.trig[key[*j].0 as usize].clone()?;
                if a1 == a2 {
                    return None;
                }
                let ((f1, a1), (f2, a2)) =
                    if a1.canonical_cmp(&a2).is_le() { ((f1, a1), (f2, a2)) } else { ((f2, a2), (f1, a1)) };
                let shape = match (f1, f2) {
                    (Func::Cos, Func::Cos) => Trig::CC(a1, a2),
                    (Func::Sin, Func::Sin) => Trig::SS(a1, a2),
                    (Func::Sin, Func::Cos) => Trig::SC(a1, a2),
                    _ => Trig::CS(a1, a2),
                };
                Some((shape, rest(&[*i, *j])))
            }
            _ => None,
        }
    }

    /// Applies the angle-addition and Pythagorean identities to pairs of monomials until
    /// nothing changes (at most a few rounds).
    fn contract(&mut self, mut poly: Poly) -> Poly {
        for _ in 0..4 {
            let (next, changed) = self.contract_once(&poly);
            poly = next;
            if !changed {
                break;
            }
        }
        poly
    }

    fn contract_once(&mut self, poly: &Poly) -> (Poly, bool) {
        let terms = poly.sorted();
        let classified: Vec<Option<(Trig, Key)>> = terms.iter().map(|(k, _)| self.classify(k)).collect();
        let mut index: FxMap<(Trig, Key), usize> = FxMap::default();
        for (i, c) in classified.iter().enumerate() {
            if let Some(sk) = c {
                index.entry(sk.clone()).or_insert(i);
            }
        }
        if index.keys().all(|(s, _)| *s == Trig::Plain) {
            return (poly.clone(), false);
        }
        let mut used = vec![false; terms.len()];
        let mut out = Poly::default();
        let mut changed = false;
        let mut order: Vec<usize> = (0..terms.len()).collect();
        order.sort_by_key(|&i| matches!(classified[i], Some((Trig::Plain, _))));
        for i in order {
            if used[i] {
                continue;
            }
            used[i] = true;
            let k = &terms[i].1;
            let Some((shape, rest)) = &classified[i] else {
                out.add_term(terms[i].0.clone(), Coef::from_big(k.clone()));
                continue;
            };
            let find = |s: Trig| index.get(&(s, rest.clone())).copied();
            let neg = -k.clone();
            // (partner index, factor replacing the trig pair, coefficient)
            let mut pair: Option<(usize, Expr, Rational)> = None;
            let coeff_of = |j: usize| &terms[j].1;
            match shape {
                Trig::CC(a, b) | Trig::SS(a, b) => {
                    let other = if matches!(shape, Trig::CC(..)) {
                        Trig::SS(a.clone(), b.clone())
                    } else {
                        Trig::CC(a.clone(), b.clone())
                    };
                    if let Some(j) = find(other) {
                        if coeff_of(j) == k {
                            pair = Some((j, cos(a.minus(b)), k.clone()));
                        } else if *coeff_of(j) == neg {
                            // cc − ss = cos(a + b)
                            let c = if matches!(shape, Trig::CC(..)) { k.clone() } else { neg.clone() };
                            pair = Some((j, cos(a.plus(b)), c));
                        }
                    }
                }
                Trig::SC(a, b) | Trig::CS(a, b) => {
                    let other = if matches!(shape, Trig::SC(..)) {
                        Trig::CS(a.clone(), b.clone())
                    } else {
                        Trig::SC(a.clone(), b.clone())
                    };
                    if let Some(j) = find(other) {
                        if *coeff_of(j) == neg {
                            // k (sin a cos b − cos a sin b) = k sin(a − b)
                            let c = if matches!(shape, Trig::SC(..)) { k.clone() } else { neg.clone() };
                            pair = Some((j, sin(a.minus(b)), c));
                        } else if coeff_of(j) == k {
                            pair = Some((j, sin(a.plus(b)), k.clone()));
                        }
                    }
                }
                Trig::C2(a) | Trig::S2(a) => {
                    let other = if matches!(shape, Trig::C2(..)) { Trig::S2(a.clone()) } else { Trig::C2(a.clone()) };
                    if let Some(j) = find(other).filter(|&j| coeff_of(j) == k) {
                        pair = Some((j, Expr::one(), k.clone()));
                    } else if let Some(j) = find(Trig::Plain).filter(|&j| *coeff_of(j) == neg) {
                        // −k R + k R cos² a = −k R sin² a
                        let f = if matches!(shape, Trig::C2(..)) { sin(a.clone()) } else { cos(a.clone()) };
                        pair = Some((j, f.powi(2), neg.clone()));
                    }
                }
                Trig::Plain => {}
            }
            match pair {
                Some((j, factor, c)) if j != i && !used[j] => {
                    used[j] = true;
                    changed = true;
                    let p = self.expand(&factor);
                    let mut r = Poly::default();
                    r.add_term(rest.clone(), Coef::from_big(c));
                    out.add(&r.mul(&p));
                }
                _ => out.add_term(terms[i].0.clone(), Coef::from_big(k.clone())),
            }
        }
        (out, changed)
    }

    // ----- collection -----------------------------------------------------------------------

    fn collect_poly(&self, poly: &Poly) -> Expr {
        let terms = poly.sorted();
        if terms.is_empty() {
            return Expr::zero();
        }
        Expr::mul(self.collect_factors(terms, 0))
    }

    fn mono(&self, key: &Key, c: &Rational) -> Expr {
        let mut fs = vec![Expr::num(c.clone())];
        fs.extend(self.to_expr_key(key));
        Expr::mul(fs)
    }

    /// Content, then Horner, as a list of factors (rational content first) so that a caller
    /// multiplying in more factors keeps `g·2·(1 − cos θ)` from distributing the `2`.
    /// `depth` counts the Horner levels above this sum (see [`HORNER_LEVELS`]).
    fn collect_factors(&self, mut terms: Vec<(Key, Rational)>, depth: usize) -> Vec<Expr> {
        if terms.len() <= 1 {
            return vec![terms.first().map_or_else(Expr::zero, |(k, c)| self.mono(k, c))];
        }
        let mut g = terms[0].1.abs();
        for (_, c) in &terms[1..] {
            g = rational_gcd(&g, c);
        }
        for t in terms.iter_mut() {
            t.1 = &t.1 / &g;
        }
        let mut content: Vec<Expr> = Vec::new();
        let first: Vec<(u32, Rational64)> = terms[0].0.to_vec();
        for (a, _) in first {
            let exps: Option<Vec<Rational64>> =
                terms.iter().map(|(k, _)| k.iter().find(|(b, _)| *b == a).map(|(_, r)| *r)).collect();
            let Some(exps) = exps else { continue };
            let common = if exps.iter().all(|r| r.is_positive()) {
                exps.iter().min().copied()
            } else if exps.iter().all(|r| r.is_negative()) {
                exps.iter().max().copied()
            } else {
                None
            };
            if let Some(c) = common {
                for t in terms.iter_mut() {
                    t.0 = merge_keys(&t.0, &[(a, -c)]);
                }
                content.push(Expr::pow(self.atoms[a].clone(), Expr::num(big(c))));
            }
        }
        // Sign: more positive than negative terms inside, and on a tie a positive constant
        // (`1 − cos θ` rather than `cos θ − 1`).
        let negatives = terms.iter().filter(|t| t.1.is_negative()).count();
        let positives = terms.len() - negatives;
        let constant_negative = terms.iter().any(|t| t.0.is_empty() && t.1.is_negative());
        if negatives > positives || (negatives == positives && constant_negative) {
            g = -g;
            for t in terms.iter_mut() {
                t.1 = -t.1.clone();
            }
        }
        content.insert(0, Expr::num(g));
        content.push(self.horner(terms, depth));
        content
    }

    /// Greedy factoring of a content-free list of monomials, at most [`HORNER_LEVELS`] deep.
    fn horner(&self, terms: Vec<(Key, Rational)>, depth: usize) -> Expr {
        if terms.len() <= 1 {
            return terms.first().map_or_else(Expr::zero, |(k, c)| self.mono(k, c));
        }
        if depth >= HORNER_LEVELS {
            return merge_cofactors(terms.iter().map(|(k, c)| self.mono(k, c)).collect());
        }
        let mut counts: FxMap<(u32, bool), usize> = FxMap::default();
        for (k, _) in &terms {
            for (a, r) in k.iter() {
                *counts.entry((*a, r.is_positive())).or_default() += 1;
            }
        }
        let best = counts.into_iter().filter(|(_, n)| *n >= 2).max_by(|(ka, na), (kb, nb)| {
            na.cmp(nb).then_with(|| self.atoms[kb.0].canonical_cmp(&self.atoms[ka.0])).then(kb.1.cmp(&ka.1))
        });
        let Some(((a, positive), _)) = best else {
            return merge_cofactors(terms.iter().map(|(k, c)| self.mono(k, c)).collect());
        };
        let exp_of = |k: &Key| k.iter().find(|(b, _)| *b == a).map(|(_, r)| *r);
        let (mut with, without): (Terms, Terms) =
            terms.into_iter().partition(|(k, _)| exp_of(k).is_some_and(|r| r.is_positive() == positive));
        let exps = with.iter().filter_map(|(k, _)| exp_of(k));
        let e = if positive { exps.min() } else { exps.max() }.unwrap_or_else(Rational64::one);
        for t in with.iter_mut() {
            t.0 = merge_keys(&t.0, &[(a, -e)]);
        }
        let mut inner = self.collect_factors(with, depth + 1);
        inner.push(Expr::pow(self.atoms[a].clone(), Expr::num(big(e))));
        let mut parts = Expr::mul(inner).terms();
        if !without.is_empty() {
            parts.extend(self.horner(without, depth).terms());
        }
        merge_cofactors(parts)
    }
}

/// The deepest Horner nesting the tidy form builds; below it a sum stays a plain sum of
/// monomials. The same bound as the simplifier's ([`crate::simplify::MAX_NESTING`]): a
/// degree-1010 polynomial potential used to give `E_x` nested 1008 levels deep, past what the
/// parser reads back (`parse::MAX_DEPTH`), so an exported equation did not re-parse.
const HORNER_LEVELS: usize = crate::simplify::MAX_NESTING;

/// Whether a sum contains a time derivative or a sin/cos, so its powers should be expanded.
fn worth_expanding(b: &Expr) -> bool {
    fn walk(e: &Expr, seen: &mut std::collections::HashSet<Expr>) -> bool {
        if !seen.insert(e.clone()) {
            return false;
        }
        match e.node() {
            Node::Sym(s) => s.primes() > 0,
            Node::Call(Func::Sin | Func::Cos, _) => true,
            _ => {
                let mut found = false;
                e.for_each_child(|c| found = found || walk(c, seen));
                found
            }
        }
    }
    walk(b, &mut std::collections::HashSet::new())
}

/// Whether `e` is a sum of distinct symbols with coefficients `+1`, at most one of them `−1`
/// (`θ1 − θ2`, `θ1 + θ2`): the angle arguments that contraction creates. [`tidy`] returns
/// such a sum unchanged (nothing to expand, contract or factor, and no equal expression has
/// fewer operations: with one negation, `k` symbols need `k − 1` additions and one negation),
/// so the e-graph run inside it is skipped.
#[doc(hidden)]
pub fn is_signed_symbol_sum(e: &Expr) -> bool {
    let Node::Add(ts) = e.node() else { return false };
    let mut negatives = 0;
    for t in ts {
        match t.node() {
            Node::Sym(_) => {}
            Node::Mul(fs) if fs.len() == 2 && fs[0].is_num(-1) && matches!(fs[1].node(), Node::Sym(_)) => {
                negatives += 1;
            }
            _ => return false,
        }
    }
    negatives <= 1
}

fn cos(a: Expr) -> Expr {
    Expr::call(Func::Cos, vec![a])
}
fn sin(a: Expr) -> Expr {
    Expr::call(Func::Sin, vec![a])
}

fn rational_gcd(a: &Rational, b: &Rational) -> Rational {
    Rational::new(a.numer().gcd(b.numer()), a.denom().lcm(b.denom()))
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
            let cof = Expr::add(members);
            let mut ctx = Ctx::default();
            let p = ctx.expand(&cof);
            let mut fs = ctx.collect_factors(p.sorted(), 0);
            fs.push(s);
            out.push(Expr::mul(fs));
        }
    }
    Expr::add(out)
}
