//! Polynomial and rational-function tools over canonical expressions.
//!
//! The canonical form of [`crate::expr`] collects like terms but never multiplies out or
//! combines fractions, because either can make an expression much larger. The tools here do
//! those global rewrites on request, and the simplifier offers their results as candidate
//! forms (the cost function decides which one wins):
//!
//! * [`expand`] distributes products and positive integer powers of sums, refusing
//!   expansions that would exceed a term budget ([`AlgebraError::TooManyTerms`]) before doing
//!   the work, so `(a+b)^100000` is answered at once;
//! * [`numer_denom`] and [`together`] put a rational expression over one common denominator;
//! * [`cancel`] removes common factors between numerator and denominator: rational and
//!   monomial content, factors that divide exactly (multivariate exact division), and the
//!   greatest common divisor of univariate numerators and denominators (Euclid over ℚ), all
//!   in the sparse polynomial form below, the one the derivation stages use;
//! * [`factor_content`] pulls the common rational and monomial content out of every sum:
//!   `2 a x + 4 a y` → `2 a (x + 2 y)`;
//! * [`trig_normalize`] applies `sin²u + cos²u = 1` (and `cosh²u − sinh²u = 1`) inside sums
//!   of any length, choosing per argument `u` whichever of `cos² → 1 − sin²`,
//!   `sin² → 1 − cos²` or neither gives the fewest operations. Rewriting even powers of one
//!   of the two functions into the other is complete for trigonometric polynomials, so scaled
//!   and split forms (`m1 + m2 − m2 cos²u` → `m1 + m2 sin²u`) need no separate rules.
//!
//! Everything here preserves the value wherever the input is defined; all of it is tested by
//! evaluation at random points.

use std::collections::{BTreeMap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};

use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::Rational64;
use num_traits::{CheckedAdd, CheckedMul, One, Signed, ToPrimitive, Zero};
use thiserror::Error;

use crate::expr::{rat_add, rat_mul, Expr, Func, Node, Rational, MAX_FOLD_BITS};

/// The default largest number of terms [`expand`] produces (or multiplies through).
pub const MAX_EXPAND_TERMS: usize = 20_000;

/// Why an algebraic rewrite was refused.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum AlgebraError {
    /// Expanding would produce (or pass through) more terms than the budget allows.
    #[error("resource limit: expanding `{what}` would produce about {estimate} terms (the limit is {limit})")]
    TooManyTerms {
        /// The plain form of the sub-expression that was refused (shortened).
        what: String,
        /// An upper estimate of the number of terms, saturating.
        estimate: u128,
        /// The budget in force.
        limit: usize,
    },
    /// Expanding would form coefficients larger than [`crate::expr::MAX_FOLD_BITS`] bits
    /// (the same bound that keeps `2^(10^10)` unevaluated).
    #[error("resource limit: expanding `{what}` would form coefficients of about {bits} bits (the limit is {limit})")]
    HugeCoefficients {
        /// The plain form of the sub-expression that was refused (shortened).
        what: String,
        /// An estimate of the largest coefficient's size in bits, saturating.
        bits: u64,
        /// The bound in force, in bits.
        limit: u64,
    },
    /// The cancellation token ([`crate::cancel`]) was set while expanding.
    #[error("interrupted")]
    Interrupted,
}

impl From<crate::cancel::Interrupted> for AlgebraError {
    fn from(_: crate::cancel::Interrupted) -> AlgebraError {
        AlgebraError::Interrupted
    }
}

fn short(e: &Expr) -> String {
    let s = e.to_string();
    if s.chars().count() > 60 {
        let head: String = s.chars().take(57).collect();
        format!("{head}...")
    } else {
        s
    }
}

// ----- expand --------------------------------------------------------------------------------

/// Distributes products over sums and multiplies out integer powers of sums, everywhere in
/// `e` (function arguments included), with the default term budget [`MAX_EXPAND_TERMS`].
///
/// Negative integer powers of sums expand their base: `(x+1)^-2` → `1/(x^2 + 2 x + 1)`.
pub fn expand(e: &Expr) -> Result<Expr, AlgebraError> {
    expand_with_limit(e, MAX_EXPAND_TERMS)
}

/// [`expand`] with an explicit term budget.
pub fn expand_with_limit(e: &Expr, limit: usize) -> Result<Expr, AlgebraError> {
    expand_with_memo(e, limit, &mut ExpandMemo::default())
}

/// Expansions already computed, kept across calls by a caller that expands many nested
/// subexpressions of one expression (the simplifier's bottom-up pass): each call then pays
/// only for the nodes not seen before. Without it, expanding every level of a Horner form
/// `1 + x (2 + x (…))` re-expanded all the levels below, cubic in the depth.
/// Valid for one `limit`: results depend on it.
#[derive(Default)]
pub struct ExpandMemo(HashMap<Expr, Expr>);

/// [`expand_with_limit`] with a memo shared between calls (see [`ExpandMemo`]).
pub fn expand_with_memo(e: &Expr, limit: usize, memo: &mut ExpandMemo) -> Result<Expr, AlgebraError> {
    expand_rec(e, limit, &mut memo.0)
}

fn expand_rec(e: &Expr, limit: usize, memo: &mut HashMap<Expr, Expr>) -> Result<Expr, AlgebraError> {
    if let Some(done) = memo.get(e) {
        return Ok(done.clone());
    }
    crate::cancel::poll()?;
    let mut children = Vec::new();
    e.for_each_child(|c| children.push(c.clone()));
    let mut new_children = Vec::with_capacity(children.len());
    for c in &children {
        new_children.push(expand_rec(c, limit, memo)?);
    }
    let rebuilt = if new_children == children { e.clone() } else { e.with_children(new_children) };
    let out = match rebuilt.node() {
        Node::Mul(fs) => multiply_out(fs, limit)?,
        Node::Pow(b, x) => match (b.node(), x.as_num()) {
            (Node::Add(ts), Some(n)) if n.is_integer() && !n.is_zero() => {
                let k = n.to_integer().abs();
                let estimate = multinomial_terms(ts.len(), &k);
                // Repeated multiplication does about k · terms · m products: (x+1)^1999 has
                // few terms for its power but needs thousands of steps with huge coefficients.
                let steps = k.to_u128().unwrap_or(u128::MAX);
                // The k-th power of a coefficient of B bits has about k·B bits, and exact
                // rational arithmetic on such numbers costs their size squared: (x + 10^-3201)^19
                // took minutes, and (x^2 + 10^20)^100 half a minute (found by tests/it/robust/fuzz.rs), so
                // the work counts machine words of coefficient as well as terms.
                let base_bits = ts.iter().map(numeric_bits).max().unwrap_or(0);
                let bits = base_bits.saturating_mul(k.to_u64().unwrap_or(u64::MAX));
                let words = 1 + u128::from(bits / 64);
                // A binomial is written out term by term (`binomial_power`), so its work is
                // its k + 1 terms at the squared coefficient size that the rest of `simplify`
                // pays for them ((x+1)^400 passes; (x+1)^1999, 2000 terms of 2000 bits, does
                // not); other sums are multiplied out k times.
                let rounds = if ts.len() == 2 { words } else { (ts.len() as u128).saturating_mul(steps) };
                let work = estimate.saturating_mul(rounds).saturating_mul(words);
                if estimate > limit as u128 || work > 64 * limit as u128 {
                    return Err(AlgebraError::TooManyTerms { what: short(&rebuilt), estimate, limit });
                }
                if bits > MAX_FOLD_BITS {
                    return Err(AlgebraError::HugeCoefficients { what: short(&rebuilt), bits, limit: MAX_FOLD_BITS });
                }
                let k = k.to_u32().unwrap_or(u32::MAX);
                let p = if let [a, c] = &ts[..] { binomial_power(a, c, k) } else { power_of_sum(b, k, limit)? };
                if n.is_negative() {
                    Expr::pow(p, Expr::int(-1))
                } else {
                    p
                }
            }
            _ => rebuilt,
        },
        _ => rebuilt,
    };
    memo.insert(e.clone(), out.clone());
    Ok(out)
}

/// The bits of exact number a term carries: its rational coefficient and its surds
/// (`sqrt(99999999999)` has a coefficient of 1, but its 50th power folds to a 1,800-bit
/// integer: `(x^2 + sqrt(99999999999) a)^100` took 8 s before surds were counted; found by
/// tests/it/robust/fuzz.rs).
fn numeric_bits(t: &Expr) -> u64 {
    let surd_bits = |f: &Expr| match f.node() {
        Node::Pow(b, x) => match (b.as_num(), x.as_num()) {
            (Some(b), Some(x)) => {
                let power = x.abs().ceil().to_integer().to_u64().unwrap_or(u64::MAX);
                rational_bits(b).saturating_mul(power)
            }
            _ => 0,
        },
        _ => 0,
    };
    t.factors().iter().map(surd_bits).fold(rational_bits(&t.coeff_rest().0), u64::saturating_add)
}

/// The number of monomials of degree `k` in `m` variables, `C(k+m−1, m−1)`, saturating.
fn multinomial_terms(m: usize, k: &BigInt) -> u128 {
    let Some(k) = k.to_u128() else { return u128::MAX };
    let mut acc: u128 = 1;
    // C(k+m-1, m-1) = Π_{i=1}^{m-1} (k+i)/i, exact at every step.
    for i in 1..m as u128 {
        acc = match acc.checked_mul(k.saturating_add(i)) {
            Some(v) => v / i,
            None => return u128::MAX,
        };
    }
    acc
}

/// `(a + b)^k` by the binomial theorem, `Σ C(k, j) a^j b^(k−j)`, in O(k) monomial products
/// (repeated multiplication would form k partial sums, O(k²) products: `(x+1)^400` was refused
/// by the work estimate). The binomial coefficients come from `C(k, j+1) = C(k, j)(k−j)/(j+1)`.
/// `a` and `b` are terms of a canonical sum, so no product here is a sum.
fn binomial_power(a: &Expr, b: &Expr, k: u32) -> Expr {
    let powers = |x: &Expr| {
        let mut out = vec![Expr::one()];
        for _ in 0..k {
            let next = out[out.len() - 1].times(x);
            out.push(next);
        }
        out
    };
    let (pa, pb) = (powers(a), powers(b));
    let mut c = BigInt::from(1);
    let mut terms = Vec::with_capacity(k as usize + 1);
    for j in 0..=k {
        let coeff = Expr::num(Rational::from_integer(c.clone()));
        terms.push(coeff.times(&pa[j as usize]).times(&pb[(k - j) as usize]));
        c = c * BigInt::from(k - j) / BigInt::from(j + 1);
    }
    Expr::add(terms)
}

/// `base^k` for a sum `base`, by repeated multiplication.
fn power_of_sum(base: &Expr, k: u32, limit: usize) -> Result<Expr, AlgebraError> {
    let mut acc = Expr::one();
    for _ in 0..k {
        acc = multiply_out(&[acc, base.clone()], limit)?;
    }
    Ok(acc)
}

/// Multiplies a list of (already expanded) factors out into one sum, collecting like terms
/// after each factor; refuses (before the work) a product of more than `limit` terms. Also
/// `canonical::reduce`'s expansion.
pub(crate) fn multiply_out(fs: &[Expr], limit: usize) -> Result<Expr, AlgebraError> {
    let mut plain = Vec::new();
    let mut sums = Vec::new();
    for f in fs {
        match f.node() {
            Node::Add(_) => sums.push(f.clone()),
            _ => plain.push(f.clone()),
        }
    }
    if sums.is_empty() {
        return Ok(Expr::mul(plain));
    }
    let mut terms = vec![Expr::mul(plain)];
    for s in &sums {
        let st = s.terms();
        let estimate = (terms.len() as u128).saturating_mul(st.len() as u128);
        if estimate > limit as u128 {
            return Err(AlgebraError::TooManyTerms { what: short(&Expr::mul(fs.iter().cloned())), estimate, limit });
        }
        let mut next = Vec::with_capacity(terms.len() * st.len());
        for t in &terms {
            crate::cancel::poll()?;
            for u in &st {
                next.push(t.times(u));
            }
        }
        terms = Expr::add(next).terms();
    }
    Ok(Expr::add(terms))
}

// ----- numerator and denominator ---------------------------------------------------------------

/// Splits `e` into a numerator and a denominator with `e = n / d`, combining sums of
/// fractions over a common denominator (the product of the distinct denominator factors, each
/// to its largest power, and the least common multiple of the numeric denominators). Neither
/// part is expanded.
pub fn numer_denom(e: &Expr) -> (Expr, Expr) {
    let mut memo = HashMap::new();
    nd(e, &mut memo)
}

/// `e` as one fraction over a common denominator: `1/x + 1/y` → `(x + y)/(x y)`.
///
/// Numeric denominators may be redistributed by the canonical form (`x/2 + y/3` stays as it
/// is, since a rational coefficient of a single sum is always distributed).
pub fn together(e: &Expr) -> Expr {
    let (n, d) = numer_denom(e);
    if d.is_one() {
        return n;
    }
    n.over(&d)
}

fn nd(e: &Expr, memo: &mut HashMap<Expr, (Expr, Expr)>) -> (Expr, Expr) {
    if let Some(done) = memo.get(e) {
        return done.clone();
    }
    let out = match e.node() {
        Node::Num(r) => {
            (Expr::num(Rational::from_integer(r.numer().clone())), Expr::num(Rational::from_integer(r.denom().clone())))
        }
        Node::Sym(_) | Node::Pi | Node::Undefined => (e.clone(), Expr::one()),
        Node::Mul(fs) => {
            let mut ns = Vec::with_capacity(fs.len());
            let mut ds = Vec::new();
            for f in fs {
                let (n, d) = nd(f, memo);
                ns.push(n);
                ds.push(d);
            }
            (Expr::mul(ns), Expr::mul(ds))
        }
        Node::Pow(b, x) => match x.as_num() {
            Some(r) if r.is_integer() => {
                let (bn, bd) = nd(b, memo);
                let k = Expr::num(r.abs());
                let (pn, pd) = (Expr::pow(bn, k.clone()), Expr::pow(bd, k));
                if r.is_negative() {
                    (pd, pn)
                } else {
                    (pn, pd)
                }
            }
            Some(r) if r.is_negative() => (Expr::one(), Expr::pow(together(b), Expr::num(-r))),
            _ => (Expr::pow(together(b), together(x)), Expr::one()),
        },
        Node::Add(ts) => {
            let parts: Vec<(Expr, Expr)> = ts.iter().map(|t| nd(t, memo)).collect();
            if parts.iter().all(|(_, d)| d.is_one()) {
                (Expr::add(parts.into_iter().map(|(n, _)| n)), Expr::one())
            } else {
                let common = common_denominator(parts.iter().map(|(_, d)| d));
                let num = Expr::add(parts.iter().map(|(n, d)| n.times(&common.over(d))));
                (num, common)
            }
        }
        Node::Call(..) | Node::Apply { .. } => {
            let mut args = Vec::new();
            e.for_each_child(|c| args.push(together(c)));
            (e.with_children(args), Expr::one())
        }
    };
    memo.insert(e.clone(), out.clone());
    out
}

/// The least common multiple of denominators given as products of powers: the lcm of their
/// numeric parts times every base to its largest exponent.
fn common_denominator<'a>(ds: impl Iterator<Item = &'a Expr>) -> Expr {
    let mut numeric = BigInt::one();
    let mut bases: Vec<(Expr, Rational)> = Vec::new();
    for d in ds {
        let (c, rest) = d.coeff_rest();
        if c.is_integer() {
            numeric = numeric.lcm(&c.to_integer().abs());
        }
        if rest.is_one() {
            continue;
        }
        for f in rest.factors() {
            let (b, x) = f.base_exp();
            let (b, k) = match x.as_num() {
                Some(r) => (b, r.clone()),
                None => (f.clone(), Rational::one()),
            };
            match bases.iter_mut().find(|(b2, _)| *b2 == b) {
                Some((_, k2)) => {
                    if k > *k2 {
                        *k2 = k;
                    }
                }
                None => bases.push((b, k)),
            }
        }
    }
    let mut fs = vec![Expr::num(Rational::from_integer(numeric))];
    fs.extend(bases.into_iter().map(|(b, k)| Expr::pow(b, Expr::num(k))));
    Expr::mul(fs)
}

// ----- polynomials: reading, the univariate gcd, cancellation -----------------------------------

/// The largest exponent read as a polynomial degree (larger powers are opaque atoms), and the
/// largest degree the univariate gcd works on (it is quadratic in the degree).
const MAX_POLY_DEGREE: u32 = 10_000;
const MAX_GCD_DEGREE: usize = 200;

/// The atoms of a family of polynomials, numbered from 0 in order of first appearance.
///
/// One table serves every polynomial that takes part in one computation (a `cancel`, a tidy
/// run), so that equal atoms get equal numbers; the numbering also fixes the lexicographic
/// monomial order of exact division (atom 0 most significant).
#[derive(Default)]
#[doc(hidden)]
pub struct Atoms {
    list: Vec<Expr>,
    index: FxMap<Expr, u32>,
}

impl Atoms {
    /// The number of `a`, numbering it if it is new.
    pub fn id(&mut self, a: &Expr) -> u32 {
        if let Some(&i) = self.index.get(a) {
            return i;
        }
        let i = self.list.len() as u32;
        self.list.push(a.clone());
        self.index.insert(a.clone(), i);
        i
    }
}

impl std::ops::Index<u32> for Atoms {
    type Output = Expr;
    fn index(&self, i: u32) -> &Expr {
        &self.list[i as usize]
    }
}

/// Reads an expanded expression as a polynomial in atoms (symbols, calls, non-integer or
/// very large powers: anything that is not a sum, a product or a positive integer power).
#[doc(hidden)]
pub fn to_poly(e: &Expr, atoms: &mut Atoms) -> SparsePoly {
    let mut p = SparsePoly::default();
    for t in e.terms() {
        let (c, rest) = t.coeff_rest();
        let mut mono: Vec<(u32, Rational64)> = Vec::new();
        if !rest.is_one() {
            for f in rest.factors() {
                let (b, x) = f.base_exp();
                // Exponents stay small so that products of monomials cannot overflow.
                let (atom, k) =
                    match x.as_num().and_then(|r| if r.is_integer() { r.to_integer().to_u32() } else { None }) {
                        Some(k) if k > 0 && k <= MAX_POLY_DEGREE => (b, k),
                        _ => (f.clone(), 1),
                    };
                mono.push((atoms.id(&atom), Rational64::from_integer(i64::from(k))));
            }
        }
        mono.sort_by_key(|&(a, _)| a);
        mono.dedup_by(|next, kept| {
            let same = next.0 == kept.0;
            if same {
                kept.1 += next.1;
            }
            same
        });
        p.add_term(Key(mono), Coef::from_big(c));
    }
    p
}

/// Univariate GCD over ℚ by Euclid's algorithm, of two polynomials in the single atom `var`.
/// Monic result.
#[doc(hidden)]
pub fn univariate_gcd(a: &SparsePoly, b: &SparsePoly, var: u32) -> Option<SparsePoly> {
    // Keys are `[]` or `[(var, k)]` with a positive integer `k`.
    let exponent = |m: &Key| m.iter().find(|(v, _)| *v == var).map_or(0, |(_, k)| k.to_integer() as usize);
    let degree = |p: &SparsePoly| p.terms.keys().map(exponent).max().unwrap_or(0);
    if a.is_zero() || degree(a) > MAX_GCD_DEGREE || degree(b) > MAX_GCD_DEGREE {
        return None;
    }
    let to_dense = |p: &SparsePoly| -> Vec<Rational> {
        let mut v = vec![Rational::zero(); degree(p) + 1];
        for (m, c) in &p.terms {
            v[exponent(m)] = c.to_big();
        }
        v
    };
    let trim = |v: &mut Vec<Rational>| {
        while v.len() > 1 && v.last().is_some_and(Zero::is_zero) {
            v.pop();
        }
    };
    let mut x = to_dense(a);
    let mut y = to_dense(b);
    trim(&mut x);
    trim(&mut y);
    let is_zero = |v: &Vec<Rational>| v.iter().all(Zero::is_zero);
    // Euclid's remainders over ℚ grow past the final gcd's size, up to about the
    // subresultants' (degree times the input size plus log of the degree). The guard allows
    // that for the small coefficients of mechanics and stops the runaway growth of a divisor
    // with huge coefficients: (x^100 − 1) mod (10^308 x − 1) forms 10^30800 (found by
    // tests/it/robust/fuzz.rs), and a linear divisor has a gcd of 1 or itself anyway.
    let max_bits = 4 * (a.coefficient_bits() + b.coefficient_bits()) + 64 * (degree(a) + degree(b)) as u64 + 256;
    // And a budget for the arithmetic, as in `SparsePoly::div_exact` (b²/64 word operations per
    // gcd-normalised product of b-bit numbers): under the bit guard, (x^100 − 10^-3201) mod
    // (10^308 x − 1) still ran fifty steps of 50,000-bit gcds, 1.3 s per `simplify` (found by
    // the 10⁶ fuzz run).
    const MAX_WORK: u128 = 20_000_000;
    let mut work: u128 = 0;
    for _ in 0..10_000 {
        if x.iter().chain(&y).any(|c| rational_bits(c) > max_bits) {
            return None;
        }
        if is_zero(&y) {
            let lc = x.last()?.clone();
            if lc.is_zero() {
                return None;
            }
            let mut out = SparsePoly::default();
            for (k, c) in x.iter().enumerate() {
                if !c.is_zero() {
                    let m = if k == 0 { Key::default() } else { Key(vec![(var, Rational64::from_integer(k as i64))]) };
                    out.add_term(m, Coef::from_big(c / &lc));
                }
            }
            return Some(out);
        }
        // x mod y
        let ly = y.last()?.clone();
        while x.len() >= y.len() && !is_zero(&x) {
            let shift = x.len() - y.len();
            let q = x.last()?.clone() / &ly;
            let q_bits = rational_bits(&q);
            if q_bits > max_bits {
                return None;
            }
            let b = u128::from(q_bits + y.iter().map(rational_bits).max().unwrap_or(0));
            work += (y.len() as u128 + 1) * b * b / 64;
            if work > MAX_WORK {
                return None;
            }
            for (i, c) in y.iter().enumerate() {
                x[i + shift] = rat_add(&x[i + shift], &-rat_mul(c, &q));
            }
            x.pop();
            trim(&mut x);
            if x.len() < y.len() {
                break;
            }
        }
        trim(&mut x);
        std::mem::swap(&mut x, &mut y);
    }
    None
}

/// Cancels common factors of the numerator and denominator of `e` (see the module docs for
/// what is found). Returns `e` unchanged when it has no denominator or when expanding either
/// part would exceed the term budget.
pub fn cancel(e: &Expr) -> Expr {
    let (n, d) = numer_denom(e);
    if d.as_num().is_some() {
        return e.clone();
    }
    cancel_parts(&n, &d).unwrap_or_else(|| e.clone())
}

fn cancel_parts(n: &Expr, d: &Expr) -> Option<Expr> {
    const LIMIT: usize = 2_000;
    let ne = expand_with_limit(n, LIMIT).ok()?;
    let de = expand_with_limit(d, LIMIT).ok()?;
    let mut atoms = Atoms::default();
    let mut pn = to_poly(&ne, &mut atoms);
    let mut pd = to_poly(&de, &mut atoms);
    // Candidate divisors: the factors of the unexpanded denominator and numerator.
    let mut factor_polys = Vec::new();
    for f in d.factors().into_iter().chain(n.factors()) {
        let (b, x) = f.base_exp();
        let k = x.as_num().and_then(|r| if r.is_integer() { r.to_integer().to_u32() } else { None }).unwrap_or(1);
        let base = if x.as_num().is_some_and(|r| r.is_integer() && r.is_positive()) { b } else { f.clone() };
        if matches!(base.node(), Node::Add(_)) {
            if let Ok(be) = expand_with_limit(&base, LIMIT) {
                factor_polys.push((to_poly(&be, &mut atoms), k));
            }
        }
    }
    if pn.is_zero() {
        return Some(Expr::zero());
    }
    if pd.is_zero() {
        return None;
    }
    // Monomial and rational content.
    let (mn, _) = pn.content();
    let (md, _) = pd.content();
    let g = SparsePoly::monomial(key_min(&mn, &md), Rational::one());
    pn = pn.div_exact(&g, usize::MAX)?;
    pd = pd.div_exact(&g, usize::MAX)?;
    // Exact division by the sum factors of either side.
    let steps = 4 * LIMIT;
    for (f, k) in factor_polys {
        for _ in 0..k {
            match (pn.div_exact(&f, steps), pd.div_exact(&f, steps)) {
                (Some(a), Some(b)) => {
                    pn = a;
                    pd = b;
                }
                _ => break,
            }
        }
    }
    // Whole numerator or denominator dividing the other.
    if let Some(q) = pn.div_exact(&pd, steps) {
        pn = q;
        pd = SparsePoly::constant(Rational::one());
    } else if let Some(q) = pd.div_exact(&pn, steps) {
        pd = q;
        pn = SparsePoly::constant(Rational::one());
    }
    // Univariate gcd when both sides live in the same single atom.
    let (sn, sd) = (pn.support(), pd.support());
    if sn.len() == 1 && sn == sd {
        if let Some(g) = univariate_gcd(&pn, &pd, sn[0]) {
            if g.lead().is_some_and(|(m, _)| !m.is_empty()) {
                pn = pn.div_exact(&g, steps)?;
                pd = pd.div_exact(&g, steps)?;
            }
        }
    }
    // One rational coefficient in front of primitive numerator and denominator, so the
    // canonical form does not spread it over a sum.
    let (_, cn) = pn.content();
    let (_, cd) = pd.content();
    pn = pn.div_exact(&SparsePoly::constant(cn.clone()), usize::MAX)?;
    pd = pd.div_exact(&SparsePoly::constant(cd.clone()), usize::MAX)?;
    let num = factor_content(&pn.to_expr(&atoms));
    let den = factor_content(&pd.to_expr(&atoms));
    Some(Expr::mul([Expr::num(cn / cd), num, Expr::pow(den, Expr::int(-1))]))
}

// ----- content ---------------------------------------------------------------------------------

/// Pulls the common rational and monomial content out of every sum in `e`:
/// `2 a x + 4 a y` → `2 a (x + 2 y)`, `x/y + z/y` → `(x + z)/y`.
///
/// A bare rational content of a sum (`2 x + 4 y`) cannot be pulled out: the canonical form
/// distributes a rational over a single sum, so that sum is left as it is.
pub fn factor_content(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |x| match x.node() {
        Node::Add(ts) => factor_sum(ts),
        _ => None,
    })
}

fn factor_sum(ts: &[Expr]) -> Option<Expr> {
    // Rational content.
    let mut num = BigInt::zero();
    let mut den = BigInt::one();
    for t in ts {
        let (c, _) = t.coeff_rest();
        num = num.gcd(c.numer());
        den = den.lcm(c.denom());
    }
    if num.is_zero() {
        return None;
    }
    let mut content = Rational::new(num, den);
    let lead = ts.iter().find(|t| t.as_num().is_none()).unwrap_or(&ts[0]);
    if lead.is_negative_form() {
        content = -content;
    }
    // Monomial content: bases present in every term with numeric exponents, smallest power.
    let mut common: Vec<(Expr, Rational)> = Vec::new();
    for (i, t) in ts.iter().enumerate() {
        let (_, rest) = t.coeff_rest();
        let fs: Vec<(Expr, Rational)> = if rest.is_one() {
            Vec::new()
        } else {
            rest.factors()
                .into_iter()
                .map(|f| {
                    let (b, x) = f.base_exp();
                    match x.as_num() {
                        Some(r) => (b, r.clone()),
                        None => (f, Rational::one()),
                    }
                })
                .collect()
        };
        if i == 0 {
            common = fs;
        } else {
            common.retain_mut(|(b, k)| match fs.iter().find(|(b2, _)| b2 == b) {
                Some((_, k2)) => {
                    if k2 < k {
                        *k = k2.clone();
                    }
                    true
                }
                None => false,
            });
        }
        if common.is_empty() {
            break;
        }
    }
    if common.is_empty() && content.is_one() {
        return None;
    }
    let mut outer = vec![Expr::num(content)];
    outer.extend(common.into_iter().map(|(b, k)| Expr::pow(b, Expr::num(k))));
    let outer = Expr::mul(outer);
    let inner = Expr::add(ts.iter().map(|t| t.over(&outer)));
    let out = Expr::mul([outer, inner]);
    // The canonical form may redistribute; only report a change.
    Some(out)
}

/// Greedy multivariate Horner form of every sum in `e`: the factor that occurs in the most
/// terms (ties: the canonical order) is pulled out of those terms, `a x + a y + z` →
/// `a (x + y) + z`, recursively on both parts. A factor is a base with a positive numeric
/// exponent, pulled out to its smallest power among the terms that have it. This is how an
/// expanded Lagrangian or Hamiltonian gets its compact, cheap-to-evaluate shape back.
///
/// Each sum has a work budget ([`COLLECT_WORK`]); a sum whose collection would exceed it is
/// left (from that point) uncollected, which is still an equal form.
pub fn collect_common(e: &Expr) -> Expr {
    try_collect_common(e).unwrap_or_else(|_| e.clone())
}

/// [`collect_common`] that polls the cancellation token ([`crate::cancel::poll`]) at every
/// level of the greedy recursion and returns `Interrupted` once it is set ([`collect_common`]
/// then gives back its input, an equal form).
pub fn try_collect_common(e: &Expr) -> Result<Expr, crate::cancel::Interrupted> {
    let mut stopped = false;
    let out = e.map_bottom_up(&mut |x| match x.node() {
        _ if stopped => None,
        Node::Add(ts) => {
            let mut work = 0;
            let out = collect_terms(ts.clone(), 0, &mut work);
            if crate::cancel::check().is_err() {
                stopped = true;
                return None;
            }
            (out != *x).then_some(out)
        }
        _ => None,
    });
    if stopped {
        Err(crate::cancel::Interrupted)
    } else {
        Ok(out)
    }
}

/// Bases with a positive numeric exponent among the factors of a term.
fn positive_powers(t: &Expr) -> Vec<(Expr, Rational)> {
    let (_, rest) = t.coeff_rest();
    if rest.is_one() {
        return Vec::new();
    }
    rest.factors()
        .into_iter()
        .filter_map(|f| {
            let (b, x) = f.base_exp();
            x.as_num().filter(|r| r.is_positive()).map(|r| (b, r.clone()))
        })
        .collect()
}

/// The work [`collect_common`] may spend on one sum, in squared machine words of exact number
/// per term visited: a term with small numbers costs 1 at each level of the greedy recursion,
/// so a 2,000-term sum collected 64 levels deep costs about 1.3·10⁵. Dividing a term by the
/// pulled factor reduces rationals by gcd, whose cost grows with the square of their size, so
/// terms with 60,000-bit coefficients (within [`crate::expr::MAX_FOLD_BITS`]) cost about 10⁶
/// each: the 10⁶ fuzz run stalled for seconds at a time in that gcd, eight levels deep.
pub const COLLECT_WORK: u64 = 1 << 21;

/// Machine words of exact number in a term: its coefficient, surds and numeric exponents.
#[doc(hidden)]
pub fn term_words(t: &Expr) -> u64 {
    let exponent_bits: u64 = t
        .factors()
        .iter()
        .filter_map(|f| match f.node() {
            Node::Pow(_, x) => x.as_num().map(rational_bits),
            _ => None,
        })
        .fold(0, u64::saturating_add);
    1 + numeric_bits(t).saturating_add(exponent_bits) / 64
}

fn collect_terms(terms: Vec<Expr>, depth: usize, work: &mut u64) -> Expr {
    if terms.len() < 2 || depth > 64 || crate::cancel::poll().is_err() {
        return Expr::add(terms);
    }
    let level: u64 = terms.iter().map(|t| term_words(t).saturating_pow(2)).fold(0, u64::saturating_add);
    *work = work.saturating_add(level);
    if *work > COLLECT_WORK {
        return Expr::add(terms);
    }
    // (base, number of terms, smallest exponent), in order of first appearance.
    let mut counts: Vec<(Expr, usize, Rational)> = Vec::new();
    let mut position: HashMap<Expr, usize> = HashMap::new();
    for t in &terms {
        for (b, k) in positive_powers(t) {
            match position.get(&b) {
                Some(&i) => {
                    let entry = &mut counts[i];
                    entry.1 += 1;
                    if k < entry.2 {
                        entry.2 = k;
                    }
                }
                None => {
                    position.insert(b.clone(), counts.len());
                    counts.push((b, 1, k));
                }
            }
        }
    }
    let best = counts
        .into_iter()
        .filter(|(_, n, _)| *n >= 2)
        .max_by(|(b1, n1, _), (b2, n2, _)| n1.cmp(n2).then_with(|| b2.canonical_cmp(b1)));
    let Some((base, _, k)) = best else { return Expr::add(terms) };
    let factor = Expr::pow(base.clone(), Expr::num(k));
    let (with, without): (Vec<Expr>, Vec<Expr>) =
        terms.into_iter().partition(|t| positive_powers(t).iter().any(|(b, _)| *b == base));
    let inner: Vec<Expr> = with.iter().map(|t| t.over(&factor)).collect();
    let inner = collect_terms(inner, depth + 1, work);
    let pulled = Expr::mul([factor, inner]);
    let mut rest = collect_terms(without, depth + 1, work).terms();
    rest.push(pulled);
    Expr::add(rest)
}

// ----- trigonometric normalisation ------------------------------------------------------------

/// One identity `from² = a + s·to²` used to rewrite even powers.
#[derive(Clone, Copy)]
struct Square {
    from: Func,
    to: Func,
    constant: i64,
    sign: i64,
}

/// `cos² = 1 − sin²`, `sin² = 1 − cos²`, `cosh² = 1 + sinh²`, `sinh² = −1 + cosh²`.
const SQUARES: [(Square, Square); 2] = [
    (
        Square { from: Func::Cos, to: Func::Sin, constant: 1, sign: -1 },
        Square { from: Func::Sin, to: Func::Cos, constant: 1, sign: -1 },
    ),
    (
        Square { from: Func::Cosh, to: Func::Sinh, constant: 1, sign: 1 },
        Square { from: Func::Sinh, to: Func::Cosh, constant: -1, sign: 1 },
    ),
];

/// Whether `k` is an integer power the Pythagorean rewrite handles: from 2 up to 32 (`cos(x)^k`
/// becomes `k/2 + 1` terms, so larger powers are left alone).
fn rewritable_power(k: &Rational) -> bool {
    k.is_integer() && *k >= Rational::from_integer(2.into()) && *k <= Rational::from_integer(32.into())
}

/// Applies the Pythagorean identities inside every sum of `e` (see the module docs).
pub fn trig_normalize(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |x| match x.node() {
        Node::Add(_) => {
            let out = normalize_sum(x);
            (out != *x).then_some(out)
        }
        _ => None,
    })
}

/// Arguments `u` of `f(u)^k`, `k ≥ 2` an integer, among the factors of the terms of `sum`.
fn squared_args(sum: &Expr, funcs: [Func; 2]) -> Vec<Expr> {
    let mut out: Vec<Expr> = Vec::new();
    for t in sum.terms() {
        for f in t.factors() {
            let (b, x) = f.base_exp();
            if let (Node::Call(func, args), Some(k)) = (b.node(), x.as_num()) {
                if funcs.contains(func) && rewritable_power(k) && !out.contains(&args[0]) {
                    out.push(args[0].clone());
                }
            }
        }
    }
    out.sort_by(|a, b| a.canonical_cmp(b));
    out
}

fn normalize_sum(sum: &Expr) -> Expr {
    let pythagorean = normalize_squares(sum);
    let combined = combine_angles(&pythagorean);
    if combined.op_count() < pythagorean.op_count() {
        // Combining may leave a sum the Pythagorean step can shorten again.
        match combined.node() {
            Node::Add(_) => normalize_squares(&combined),
            _ => combined,
        }
    } else {
        pythagorean
    }
}

/// The angle-addition formulas read backwards, on pairs of terms of a sum with the same
/// coefficient up to sign and the same remaining factors:
/// `cos a cos b ± sin a sin b = cos(a ∓ b)`, `sin a cos b ± cos a sin b = sin(a ± b)`.
/// Pairs are taken greedily in term order, so the result is deterministic.
fn combine_angles(sum: &Expr) -> Expr {
    let terms = sum.terms();
    if terms.len() < 2 {
        return sum.clone();
    }
    let split: Vec<(Rational, Expr)> = terms.iter().map(Expr::coeff_rest).collect();
    let mut index: HashMap<Expr, Vec<usize>> = HashMap::new();
    for (i, (_, rest)) in split.iter().enumerate() {
        index.entry(rest.clone()).or_default().push(i);
    }
    let mut used = vec![false; terms.len()];
    let mut out: Vec<Expr> = Vec::new();
    let trig = |f: &Expr| -> Option<(Func, Expr)> {
        match f.node() {
            Node::Call(func @ (Func::Sin | Func::Cos), args) => Some((*func, args[0].clone())),
            _ => None,
        }
    };
    for i in 0..terms.len() {
        if used[i] {
            continue;
        }
        let (c, rest) = &split[i];
        let fs = rest.factors();
        let mut done = false;
        'pairs: for p in 0..fs.len() {
            for q in p + 1..fs.len() {
                let (Some((f1, a)), Some((f2, b))) = (trig(&fs[p]), trig(&fs[q])) else { continue };
                if a == b {
                    continue;
                }
                let others: Vec<Expr> =
                    fs.iter().enumerate().filter(|(k, _)| *k != p && *k != q).map(|(_, f)| f.clone()).collect();
                let other = Expr::mul(others);
                let swap = |f: Func| if f == Func::Sin { Func::Cos } else { Func::Sin };
                let partner = Expr::mul([
                    other.clone(),
                    Expr::call(swap(f1), vec![a.clone()]),
                    Expr::call(swap(f2), vec![b.clone()]),
                ]);
                let Some(js) = index.get(&partner) else { continue };
                let Some(&j) = js.iter().find(|&&j| j != i && !used[j]) else { continue };
                let cj = &split[j].0;
                let same = cj == c;
                if !same && *cj != -c.clone() {
                    continue;
                }
                let combined = match (f1, f2) {
                    // c (cos a cos b ± sin a sin b) = c cos(a ∓ b)
                    (Func::Cos, Func::Cos) | (Func::Sin, Func::Sin) => {
                        // The term with the cosines decides the sign of the pair.
                        let cos_first = f1 == Func::Cos;
                        let lead = if cos_first { c.clone() } else { cj.clone() };
                        let arg = if same { a.minus(&b) } else { a.plus(&b) };
                        Expr::mul([Expr::num(lead), other, Expr::call(Func::Cos, vec![arg])])
                    }
                    // c (sin a cos b ± cos a sin b) = c sin(a ± b)
                    _ => {
                        let (s_arg, c_arg) =
                            if f1 == Func::Sin { (a.clone(), b.clone()) } else { (b.clone(), a.clone()) };
                        let arg = if same { s_arg.plus(&c_arg) } else { s_arg.minus(&c_arg) };
                        Expr::mul([Expr::num(c.clone()), other, Expr::call(Func::Sin, vec![arg])])
                    }
                };
                used[i] = true;
                used[j] = true;
                out.push(combined);
                done = true;
                break 'pairs;
            }
        }
        if !done {
            used[i] = true;
            out.push(terms[i].clone());
        }
    }
    Expr::add(out)
}

fn normalize_squares(sum: &Expr) -> Expr {
    let mut best = sum.clone();
    for (one, other) in SQUARES {
        for u in squared_args(&best, [one.from, other.from]) {
            let mut cands = vec![best.clone()];
            for sq in [one, other] {
                cands.push(rewrite_squares(&best, &u, sq));
            }
            best = cands
                .into_iter()
                .enumerate()
                .min_by(|(i, a), (j, b)| a.op_count().cmp(&b.op_count()).then(i.cmp(j)))
                .map(|(_, e)| e)
                .unwrap_or(best);
        }
    }
    best
}

/// Rewrites every `from(u)^k` (`k ≥ 2`) in the terms of `sum` as
/// `(a + s·to(u)²)^⌊k/2⌋ · from(u)^(k mod 2)`, multiplied out by the binomial theorem.
fn rewrite_squares(sum: &Expr, u: &Expr, sq: Square) -> Expr {
    let target = Expr::call(sq.from, vec![u.clone()]);
    let to = Expr::call(sq.to, vec![u.clone()]);
    let mut out = Vec::new();
    for t in sum.terms() {
        let fs = t.factors();
        let hit = fs.iter().position(|f| {
            let (b, x) = f.base_exp();
            b == target && x.as_num().is_some_and(rewritable_power)
        });
        let Some(i) = hit else {
            out.push(t);
            continue;
        };
        let k = fs[i].base_exp().1.as_num().and_then(|r| r.to_integer().to_u32()).unwrap_or(2);
        let h = k / 2;
        let mut rest: Vec<Expr> = fs.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, f)| f.clone()).collect();
        if k % 2 == 1 {
            rest.push(target.clone());
        }
        let rest = Expr::mul(rest);
        // (a + s·to²)^h = Σ_j C(h, j) a^(h−j) s^j to^(2j)
        let mut binom = BigInt::one();
        for j in 0..=h {
            let c = &binom * BigInt::from(sq.constant).pow(h - j) * BigInt::from(sq.sign).pow(j);
            out.push(Expr::mul([
                Expr::num(Rational::from_integer(c)),
                Expr::pow(to.clone(), Expr::int(2 * i64::from(j))),
                rest.clone(),
            ]));
            binom = binom * BigInt::from(h - j) / BigInt::from(j + 1);
        }
    }
    Expr::add(out)
}

// ----- the sparse polynomial form ----------------------------------------------------------------

// The engine's one polynomial form, shared by the derivation stages and the rational tools:
// `mechanics::tidy` expands, contracts and collects in it, `mechanics::euler_lagrange` splits
// Lagrangians by velocity degree in it, and [`cancel`] divides exactly and takes content and
// univariate gcds in it. Atoms are numbered by the caller ([`Atoms`], one table per run), a
// monomial is a sorted list of `(atom, exponent)` with non-zero rational exponents, and
// coefficients are exact. It is built for speed on the large expansions of mechanics (the
// 30-link pendulum's forcing has tens of thousands of monomials): machine-word rationals while
// they fit, an integer hasher, no interning per monomial. Exact division needs a monomial
// order; it is the lexicographic order of [`lex_cmp`] on the same sparse keys, used by a
// sorted working copy of the remainder only while a division runs.

/// A fast, deterministic hasher for small integer keys (FxHash's multiply-rotate).
#[derive(Default, Clone, Copy)]
#[doc(hidden)]
pub struct Fx(u64);
impl Hasher for Fx {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }
    #[inline]
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    #[inline]
    fn write_u32(&mut self, x: u32) {
        self.write_u64(u64::from(x));
    }
    #[inline]
    fn write_i64(&mut self, x: i64) {
        self.write_u64(x as u64);
    }
    #[inline]
    fn write_usize(&mut self, x: usize) {
        self.write_u64(x as u64);
    }
}
#[doc(hidden)]
pub type FxMap<K, V> = HashMap<K, V, BuildHasherDefault<Fx>>;

/// A monomial without its coefficient: `(atom, exponent)` sorted by atom, exponents non-zero.
///
/// Hashed by the exponents' reduced numerator and denominator: `Ratio`'s own `Hash` expands a
/// continued fraction with a division per step, which was a tenth of the mechanics run.
#[derive(Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
#[doc(hidden)]
pub struct Key(pub Vec<(u32, Rational64)>);

impl std::hash::Hash for Key {
    #[inline]
    fn hash<H: Hasher>(&self, h: &mut H) {
        h.write_usize(self.0.len());
        for (a, r) in &self.0 {
            // `Rational64` is always stored reduced with a positive denominator.
            h.write_u32(*a);
            h.write_i64(*r.numer());
            h.write_i64(*r.denom());
        }
    }
}

impl std::ops::Deref for Key {
    type Target = Vec<(u32, Rational64)>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl std::ops::DerefMut for Key {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}

impl FromIterator<(u32, Rational64)> for Key {
    fn from_iter<I: IntoIterator<Item = (u32, Rational64)>>(it: I) -> Key {
        Key(it.into_iter().collect())
    }
}

/// An exact coefficient: a machine-word rational while it fits, a big rational after.
///
/// Almost every coefficient in a derivation is small (`1/2`, `-2`); `BigRational` arithmetic
/// allocates and takes a gcd of big integers for each product, which was a quarter of the
/// mechanics run. The representation is unique (`Big` only when the value does not fit), so
/// the derived equality is equality of values.
#[derive(Clone, PartialEq, Eq)]
#[doc(hidden)]
pub enum Coef {
    Small(Rational64),
    Big(Rational),
}

impl Coef {
    #[inline]
    pub fn from_big(r: Rational) -> Coef {
        match small_exp(&r) {
            Some(x) => Coef::Small(x),
            None => Coef::Big(r),
        }
    }

    #[inline]
    pub fn to_big(&self) -> Rational {
        match self {
            Coef::Small(x) => big(*x),
            Coef::Big(r) => r.clone(),
        }
    }

    #[inline]
    pub fn is_zero(&self) -> bool {
        match self {
            Coef::Small(x) => x.is_zero(),
            Coef::Big(r) => r.is_zero(),
        }
    }

    #[inline]
    pub fn add(&self, other: &Coef) -> Coef {
        if let (Coef::Small(a), Coef::Small(b)) = (self, other) {
            if let Some(c) = a.checked_add(b) {
                return Coef::Small(c);
            }
        }
        Coef::from_big(self.to_big() + other.to_big())
    }

    #[inline]
    pub fn mul(&self, other: &Coef) -> Coef {
        if let (Coef::Small(a), Coef::Small(b)) = (self, other) {
            if let Some(c) = a.checked_mul(b) {
                return Coef::Small(c);
            }
        }
        Coef::from_big(self.to_big() * other.to_big())
    }

    /// `-self`.
    #[inline]
    fn neg(&self) -> Coef {
        match self {
            Coef::Small(x) if *x.numer() != i64::MIN => Coef::Small(-*x),
            _ => Coef::from_big(-self.to_big()),
        }
    }

    /// `self / other` for a non-zero `other`.
    #[inline]
    fn div(&self, other: &Coef) -> Coef {
        if let Coef::Small(b) = other {
            // The reciprocal as a machine-word rational (its sign moved to the numerator),
            // unless negating the denominator would overflow.
            let (n, d) = (*b.numer(), *b.denom());
            if n != 0 && n != i64::MIN {
                let inv = if n < 0 { Rational64::new_raw(-d, -n) } else { Rational64::new_raw(d, n) };
                return self.mul(&Coef::Small(inv));
            }
        }
        Coef::from_big(self.to_big() / other.to_big())
    }

    /// The size in bits (the larger of numerator and denominator), as [`rational_bits`].
    #[inline]
    fn bits(&self) -> u64 {
        match self {
            Coef::Small(x) => {
                let b = |v: i64| u64::from(64 - v.unsigned_abs().leading_zeros());
                b(*x.numer()).max(b(*x.denom()))
            }
            Coef::Big(r) => rational_bits(r),
        }
    }
}

/// The size of a rational in bits (the larger of numerator and denominator).
fn rational_bits(r: &Rational) -> u64 {
    r.numer().bits().max(r.denom().bits())
}

/// A polynomial in the atoms: monomials with exact coefficients, no zero coefficients.
#[derive(Clone, Default)]
#[doc(hidden)]
pub struct SparsePoly {
    pub terms: FxMap<Key, Coef>,
}

impl SparsePoly {
    #[doc(hidden)]
    pub fn constant(c: Rational) -> SparsePoly {
        let mut terms = FxMap::default();
        if !c.is_zero() {
            terms.insert(Key::default(), Coef::from_big(c));
        }
        SparsePoly { terms }
    }

    pub fn atom(id: u32, exp: Rational64) -> SparsePoly {
        let mut terms = FxMap::default();
        terms.insert(Key(vec![(id, exp)]), Coef::Small(Rational64::one()));
        SparsePoly { terms }
    }

    #[inline]
    #[doc(hidden)]
    pub fn add_term(&mut self, key: Key, c: Coef) {
        match self.terms.entry(key) {
            std::collections::hash_map::Entry::Occupied(mut o) => {
                let v = o.get().add(&c);
                if v.is_zero() {
                    o.remove();
                } else {
                    *o.get_mut() = v;
                }
            }
            std::collections::hash_map::Entry::Vacant(v) => {
                if !c.is_zero() {
                    v.insert(c);
                }
            }
        }
    }

    #[inline]
    pub fn is_zero(&self) -> bool {
        self.terms.is_empty()
    }

    /// `self · c` for a rational `c`.
    pub fn scale(&self, c: &Rational) -> SparsePoly {
        let c = Coef::from_big(c.clone());
        let mut out = SparsePoly::default();
        for (k, v) in &self.terms {
            out.add_term(k.clone(), v.mul(&c));
        }
        out
    }

    #[inline]
    pub fn add(&mut self, other: &SparsePoly) {
        for (k, c) in &other.terms {
            self.add_term(k.clone(), c.clone());
        }
    }

    #[inline]
    pub fn mul(&self, other: &SparsePoly) -> SparsePoly {
        let mut out = SparsePoly::default();
        for (k1, c1) in &self.terms {
            for (k2, c2) in &other.terms {
                out.add_term(merge_keys(k1, k2), c1.mul(c2));
            }
        }
        out
    }

    /// Terms sorted by key, for deterministic processing.
    #[doc(hidden)]
    pub fn sorted(&self) -> Vec<(Key, Rational)> {
        let mut v: Vec<(Key, Rational)> = self.terms.iter().map(|(k, c)| (k.clone(), c.to_big())).collect();
        v.sort_by(|a, b| a.0.cmp(&b.0));
        v
    }
}

// ----- exact division, content, support ----------------------------------------------------------

/// Compares monomials in the lexicographic order of their dense exponent vectors: the
/// exponents of atom 0 first, then atom 1, …, a missing atom counting as exponent 0. In this
/// order the leading monomial of a product is the product of the leading monomials, which
/// makes a failed leading-term division a proof of non-divisibility.
#[doc(hidden)]
pub fn lex_cmp(a: &[(u32, Rational64)], b: &[(u32, Rational64)]) -> std::cmp::Ordering {
    use std::cmp::Ordering::{Equal, Greater, Less};
    let zero = Rational64::zero();
    let (mut i, mut j) = (0, 0);
    loop {
        let o = match (a.get(i), b.get(j)) {
            (None, None) => return Equal,
            (Some((_, e)), None) => e.cmp(&zero),
            (None, Some((_, f))) => zero.cmp(f),
            (Some((x, e)), Some((y, f))) => match x.cmp(y) {
                Less => e.cmp(&zero),
                Greater => zero.cmp(f),
                Equal => {
                    i += 1;
                    j += 1;
                    e.cmp(f)
                }
            },
        };
        if o != Equal {
            return o;
        }
    }
}

/// A monomial ordered by [`lex_cmp`] (keys hold no zero exponents, so the order is total and
/// agrees with equality).
#[derive(Clone, PartialEq, Eq)]
struct Lex(Key);

impl Ord for Lex {
    fn cmp(&self, other: &Lex) -> std::cmp::Ordering {
        lex_cmp(&self.0, &other.0)
    }
}

impl PartialOrd for Lex {
    fn partial_cmp(&self, other: &Lex) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// `a / b` when `b` divides `a` (every exponent of `b` at most `a`'s, a missing atom
/// counting as 0); `None` otherwise.
fn key_quotient(a: &[(u32, Rational64)], b: &[(u32, Rational64)]) -> Option<Key> {
    let mut out = Key(Vec::with_capacity(a.len()));
    let (mut i, mut j) = (0, 0);
    while j < b.len() {
        let (y, f) = b[j];
        match a.get(i) {
            Some(&(x, e)) if x < y => {
                if e.is_negative() {
                    return None;
                }
                out.push((x, e));
                i += 1;
            }
            Some(&(x, e)) if x == y => {
                let d = e - f;
                if d.is_negative() {
                    return None;
                }
                if !d.is_zero() {
                    out.push((x, d));
                }
                i += 1;
                j += 1;
            }
            _ => {
                if f.is_positive() {
                    return None;
                }
                out.push((y, -f));
                j += 1;
            }
        }
    }
    if a[i..].iter().any(|(_, e)| e.is_negative()) {
        return None;
    }
    out.extend_from_slice(&a[i..]);
    Some(out)
}

/// The exponent-wise minimum of two monomials (a missing atom counting as 0).
fn key_min(a: &[(u32, Rational64)], b: &[(u32, Rational64)]) -> Key {
    let mut out = Key(Vec::new());
    let zero = Rational64::zero();
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        let (atom, e) = match (a.get(i), b.get(j)) {
            (Some(&(x, e)), Some(&(y, f))) if x == y => {
                i += 1;
                j += 1;
                (x, e.min(f))
            }
            (Some(&(x, e)), Some(&(y, _))) if x < y => {
                i += 1;
                (x, e.min(zero))
            }
            (Some(&(x, e)), None) => {
                i += 1;
                (x, e.min(zero))
            }
            (_, Some(&(y, f))) => {
                j += 1;
                (y, f.min(zero))
            }
            (None, None) => break,
        };
        if !e.is_zero() {
            out.push((atom, e));
        }
    }
    out
}

impl SparsePoly {
    /// The single term `c · m`.
    pub fn monomial(m: Key, c: Rational) -> SparsePoly {
        let mut p = SparsePoly::default();
        p.add_term(m, Coef::from_big(c));
        p
    }

    /// The leading term in the lexicographic order ([`lex_cmp`]).
    #[doc(hidden)]
    pub fn lead(&self) -> Option<(&Key, &Coef)> {
        self.terms.iter().max_by(|a, b| lex_cmp(a.0, b.0))
    }

    /// The largest coefficient size in bits.
    fn coefficient_bits(&self) -> u64 {
        self.terms.values().map(Coef::bits).max().unwrap_or(0)
    }

    /// `self / d` if `d` divides `self` exactly (in the lexicographic monomial order the
    /// leading term of a multiple is the product of leading terms, so a failed leading-term
    /// division proves non-divisibility). Gives up after `steps` reduction steps.
    ///
    /// Also gives up when a quotient coefficient outgrows [`SparsePoly::coefficient_bits_bound`]:
    /// dividing `x^10000 − 1` by `10^308 x − 1` would otherwise form coefficients of millions of
    /// digits, one step slower than the last (a hang found by `tests/it/robust/fuzz.rs`).
    ///
    /// And it gives up when the arithmetic itself grows too costly: each step normalises
    /// rationals by a binary gcd, about b²/64 word operations for b-bit numbers, once per term
    /// of `d`. Dividing `x^10000 − 10^-3201` by `10/2308 x − 1` stays under the coefficient
    /// bound for thousands of steps of 20,000-bit gcds (minutes; the fuzzer's sixth hang).
    #[doc(hidden)]
    pub fn div_exact(&self, d: &SparsePoly, steps: usize) -> Option<SparsePoly> {
        /// About 0.02–0.05 s of gcd work; exact divisions met in practice use well under 10%
        /// of it. (It was 10× more until the 10⁶ fuzz run, under load, met divisions that spent
        /// the whole budget several times in one `simplify`: 1.4 s CPU for
        /// `(x^100 − 10^-3201)/(10^308 x − 1)`.)
        const MAX_WORK: u128 = 20_000_000;
        let (ld, lc) = d.lead()?;
        let max_bits = self.coefficient_bits_bound(d);
        let d_bits = u128::from(d.coefficient_bits());
        let d_terms = d.terms.len() as u128;
        let mut work: u128 = 0;
        // The remainder, sorted so that its leading term is at hand after each step.
        let mut r: BTreeMap<Lex, Coef> = self.terms.iter().map(|(k, c)| (Lex(k.clone()), c.clone())).collect();
        let mut q = SparsePoly::default();
        for _ in 0..steps {
            let Some((lm, c)) = r.last_key_value() else { return Some(q) };
            let shift = key_quotient(&lm.0, ld)?;
            let coeff = c.div(lc);
            let bits = coeff.bits();
            if bits > max_bits {
                return None;
            }
            let b = u128::from(bits) + d_bits;
            work += (d_terms + 1) * b * b / 64;
            if work > MAX_WORK {
                return None;
            }
            // r −= coeff · shift · d
            let minus = coeff.neg();
            for (m, c) in &d.terms {
                let v = c.mul(&minus);
                match r.entry(Lex(merge_keys(m, &shift))) {
                    std::collections::btree_map::Entry::Occupied(mut o) => {
                        let s = o.get().add(&v);
                        if s.is_zero() {
                            o.remove();
                        } else {
                            *o.get_mut() = s;
                        }
                    }
                    std::collections::btree_map::Entry::Vacant(e) => {
                        e.insert(v);
                    }
                }
            }
            q.add_term(shift, coeff);
        }
        None
    }

    /// The largest quotient coefficient, in bits, that an exact division of `self` by `d` is
    /// allowed to form: twice the inputs' sizes plus a margin. Exact quotients met in practice
    /// stay near their dividend's size (`(x+1)^400 / (x+1)`); a larger coefficient almost
    /// always means the division is not exact and is only growing numbers. (Mignotte's bound
    /// allows a factor of a degree-n polynomial 2ⁿ times its norm; such a rare division is not
    /// attempted, and the expression stays uncancelled, which is still correct.)
    fn coefficient_bits_bound(&self, d: &SparsePoly) -> u64 {
        2 * (self.coefficient_bits() + d.coefficient_bits()) + 256
    }

    /// The atoms that occur, in increasing order.
    #[doc(hidden)]
    pub fn support(&self) -> Vec<u32> {
        let mut s: Vec<u32> = self.terms.keys().flat_map(|m| m.iter().map(|&(a, _)| a)).collect();
        s.sort_unstable();
        s.dedup();
        s
    }

    /// The common monomial (smallest exponent of each atom, a missing atom counting as 0) and
    /// rational content (gcd of numerators over lcm of denominators, with the sign of the
    /// leading term).
    #[doc(hidden)]
    pub fn content(&self) -> (Key, Rational) {
        let mut mono: Option<Key> = None;
        let mut num = BigInt::zero();
        let mut den = BigInt::one();
        for (m, c) in &self.terms {
            mono = Some(match mono {
                None => m.clone(),
                Some(prev) => key_min(&prev, m),
            });
            match c {
                Coef::Small(x) => {
                    num = num.gcd(&BigInt::from(*x.numer()));
                    den = den.lcm(&BigInt::from(*x.denom()));
                }
                Coef::Big(r) => {
                    num = num.gcd(r.numer());
                    den = den.lcm(r.denom());
                }
            }
        }
        let mut r = Rational::new(num, den);
        if self.lead().is_some_and(|(_, c)| c.to_big().is_negative()) {
            r = -r;
        }
        (mono.unwrap_or_default(), r)
    }

    /// The polynomial as a canonical expression over the atoms of `atoms`.
    pub fn to_expr(&self, atoms: &Atoms) -> Expr {
        Expr::add(self.terms.iter().map(|(m, c)| {
            let mut fs = vec![Expr::num(c.to_big())];
            for &(a, k) in m.iter() {
                fs.push(Expr::pow(atoms[a].clone(), Expr::num(big(k))));
            }
            Expr::mul(fs)
        }))
    }
}

#[inline]
pub(crate) fn merge_keys(a: &[(u32, Rational64)], b: &[(u32, Rational64)]) -> Key {
    let mut out = Key(Vec::with_capacity(a.len() + b.len()));
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                let e = a[i].1 + b[j].1;
                if !e.is_zero() {
                    out.push((a[i].0, e));
                }
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// `r` as a machine-word rational, when it fits.
pub(crate) fn small_exp(r: &Rational) -> Option<Rational64> {
    Some(Rational64::new(r.numer().to_i64()?, r.denom().to_i64()?))
}

/// A machine-word rational as an exact big one.
pub(crate) fn big(r: Rational64) -> Rational {
    Rational::new((*r.numer()).into(), (*r.denom()).into())
}
