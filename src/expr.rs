//! The expression core: a hash-consed DAG in canonical form.
//!
//! Every [`Expr`] is built through the constructors here ([`Expr::add`], [`Expr::mul`],
//! [`Expr::pow`], [`Expr::call`], …), which keep one canonical form:
//!
//! * sums and products are n-ary, flattened and sorted by one deterministic order
//!   ([`Expr::canonical_cmp`]); there are no subtraction or division nodes (`a − b` is
//!   `a + (−1)·b`, `a/b` is `a·b⁻¹`);
//! * like terms are collected (`2x + 3x = 5x`) and so are like powers (`x·x² = x³`);
//! * a sum carries its rational constant first, a product its rational coefficient first;
//! * coefficients are exact [`BigRational`]s, so they never overflow.
//!
//! Associativity and commutativity are therefore never rewrite rules: the e-graph in
//! [`crate::simplify`] works on identities a canonical form cannot see.
//!
//! Nodes are interned while they are alive, so structurally equal live expressions are the same
//! pointer: equality and hashing are O(1) and derivative and evaluation memo tables key on
//! nodes. The interner holds only weak references: a node that nothing references any more is
//! freed, so a long-running host (a REPL, a notebook kernel, a server) does not grow without
//! bound. Dropping a node frees its unreferenced descendants with an explicit stack, never by
//! recursion, so deep expressions cannot overflow the stack when they go.

use std::cmp::Ordering;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::fmt;
use std::hash::{BuildHasher, BuildHasherDefault, Hash, Hasher};
use std::sync::{Arc, Mutex, OnceLock, Weak};

use num_bigint::BigInt;
use num_integer::Integer;
use num_rational::BigRational;
use num_traits::{One, Signed, ToPrimitive, Zero};

/// Exact rational numbers, the coefficients of every expression.
pub type Rational = BigRational;

/// The largest result, in bits, that a power of two rationals is folded into. Larger powers
/// (`2^(10^10)`, `10^99999999`) stay unevaluated instead of exhausting memory.
pub const MAX_FOLD_BITS: u64 = 1 << 16;

/// A real-valued variable. Primes count time derivatives: `x'` is the velocity of `x`.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Symbol {
    name: Arc<str>,
    primes: u8,
    positive: bool,
}

impl Symbol {
    /// A real symbol with no sign assumption.
    pub fn new(name: &str) -> Symbol {
        Symbol { name: Arc::from(name), primes: 0, positive: false }
    }

    /// A symbol known to be strictly positive (a mass, a length, `g`), which lets
    /// simplification use `sqrt(m^2) = m`.
    pub fn positive(name: &str) -> Symbol {
        Symbol { name: Arc::from(name), primes: 0, positive: true }
    }

    /// The same symbol with `primes` time derivatives (`x` → `x''` for 2).
    pub fn with_primes(&self, primes: u8) -> Symbol {
        Symbol { name: self.name.clone(), primes, positive: self.positive && primes == 0 }
    }

    /// The time derivative of this symbol: `x` → `x'`.
    pub fn prime(&self) -> Symbol {
        Symbol { name: self.name.clone(), primes: self.primes.saturating_add(1), positive: false }
    }

    /// The underlying symbol with no primes (`x''` → `x`).
    pub fn base(&self) -> Symbol {
        self.with_primes(0)
    }

    /// The name without primes.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// How many time derivatives the symbol carries.
    pub fn primes(&self) -> u8 {
        self.primes
    }

    /// Whether the symbol was declared positive.
    pub fn is_positive(&self) -> bool {
        self.positive
    }

    /// Whether this is the time variable `t`.
    pub fn is_time(&self) -> bool {
        self.primes == 0 && &*self.name == "t"
    }
}

impl PartialOrd for Symbol {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Symbol {
    fn cmp(&self, other: &Self) -> Ordering {
        self.name.cmp(&other.name).then(self.primes.cmp(&other.primes)).then(self.positive.cmp(&other.positive))
    }
}

impl fmt::Debug for Symbol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{}", self.name, "'".repeat(self.primes as usize))
    }
}

impl fmt::Display for Symbol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

pub use crate::func::Func;
use crate::func::Parity;

/// One node of the DAG. Build nodes only through the [`Expr`] constructors, which keep the
/// canonical form.
#[derive(Clone, PartialEq, Eq, Hash)]
pub enum Node {
    /// An exact rational number.
    Num(Rational),
    /// A variable.
    Sym(Symbol),
    /// The exact constant π. A number, not a symbol: it has no value to bind, no time
    /// derivative, and never appears among a system's parameters.
    Pi,
    /// A sum of at least two terms: constant first, no nested sums, like terms collected.
    Add(Vec<Expr>),
    /// A product of at least two factors: coefficient first (never 1), no nested products,
    /// like bases collected.
    Mul(Vec<Expr>),
    /// `base ^ exponent`.
    Pow(Expr, Expr),
    /// A built-in function applied to its arguments.
    Call(Func, Vec<Expr>),
    /// A declared but undefined function (`V(r)`) or one of its partial derivatives:
    /// `orders[i]` counts derivatives by argument `i` (`V'(r)` has `orders = [1]`).
    Apply { name: Arc<str>, orders: Vec<u32>, args: Vec<Expr> },
    /// The result of an undefined operation such as `1/0`; absorbs everything it touches.
    Undefined,
}

struct ExprData {
    node: Node,
    hash: u64,
    /// [`Expr::op_count`], computed once when the node is made: the simplifier compares the
    /// cost of candidates at every node of a bottom-up pass, and a walk per comparison made
    /// that pass quadratic in the depth (and exponential on a DAG with shared subtrees).
    ops: usize,
}

impl Drop for ExprData {
    /// Frees the children that this node held last without recursing: each is moved onto a
    /// local stack, and a child whose last reference that was gives up its own children the
    /// same way before it is freed. (A child still referenced elsewhere just loses a count.)
    fn drop(&mut self) {
        let mut stack = Vec::new();
        self.node.take_children(&mut stack);
        while let Some(child) = stack.pop() {
            if let Some(mut data) = Arc::into_inner(child.0) {
                data.node.take_children(&mut stack);
            }
        }
    }
}

impl Node {
    /// Moves this node's children onto `stack`, leaving it childless (only for a node that is
    /// being dropped: its power operands are replaced by a private placeholder).
    fn take_children(&mut self, stack: &mut Vec<Expr>) {
        match self {
            Node::Add(v) | Node::Mul(v) | Node::Call(_, v) | Node::Apply { args: v, .. } => stack.append(v),
            Node::Pow(base, exp) => {
                stack.push(std::mem::replace(base, placeholder()));
                stack.push(std::mem::replace(exp, placeholder()));
            }
            Node::Num(_) | Node::Sym(_) | Node::Pi | Node::Undefined => {}
        }
    }
}

/// A node outside the interner that stands in for the operands of a power being dropped. It is
/// built without touching the interner, so dropping never takes the interner's lock.
fn placeholder() -> Expr {
    static PLACEHOLDER: OnceLock<Expr> = OnceLock::new();
    PLACEHOLDER.get_or_init(|| Expr(Arc::new(ExprData { node: Node::Undefined, hash: 0, ops: 0 }))).clone()
}

/// A shared, immutable, canonical expression. Cloning is a reference-count increment.
#[derive(Clone)]
pub struct Expr(Arc<ExprData>);

impl PartialEq for Expr {
    fn eq(&self, other: &Self) -> bool {
        // Interning makes structural equality pointer equality.
        Arc::ptr_eq(&self.0, &other.0)
    }
}
impl Eq for Expr {}

impl Hash for Expr {
    fn hash<H: Hasher>(&self, state: &mut H) {
        state.write_u64(self.0.hash);
    }
}

/// Interning table: node hash → the live nodes with that hash. A node's children are already
/// interned, so comparing two nodes is shallow (children compare by pointer).
///
/// Entries are weak, so the table never keeps a node alive. Dead entries are dropped when their
/// bucket is next visited, and by a sweep of the whole table whenever it has doubled since the
/// last sweep, which keeps the cost amortised O(1) per node and the table proportional to the
/// live nodes.
struct Interner {
    table: HashMap<u64, Vec<Weak<ExprData>>, BuildHasherDefault<PassThrough>>,
    /// Entries in the table, live or dead.
    entries: usize,
    /// `entries` above which the next insertion sweeps the table.
    sweep_at: usize,
}

/// The smallest table size that triggers a sweep.
const MIN_SWEEP: usize = 1 << 12;

impl Interner {
    /// Drops every dead entry and sets the next sweep at twice the live count.
    fn sweep(&mut self) {
        self.table.retain(|_, bucket| {
            bucket.retain(|w| w.strong_count() > 0);
            !bucket.is_empty()
        });
        self.entries = self.table.values().map(Vec::len).sum();
        self.sweep_at = (2 * self.entries).max(MIN_SWEEP);
    }
}

/// The number of interned nodes alive now (diagnostics and memory tests; takes the interner's
/// lock and walks the table).
pub fn live_nodes() -> usize {
    let guard = match interner().lock() {
        Ok(guard) => guard,
        Err(poisoned) => poisoned.into_inner(),
    };
    guard.table.values().flatten().filter(|w| w.strong_count() > 0).count()
}

/// The interner's table is keyed by node hashes that are already well mixed; hashing them
/// again (SipHash) only costs time.
#[derive(Default)]
struct PassThrough(u64);
impl Hasher for PassThrough {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 = (self.0 << 8) ^ u64::from(*b);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = x;
    }
}

fn interner() -> &'static Mutex<Interner> {
    static INTERNER: OnceLock<Mutex<Interner>> = OnceLock::new();
    INTERNER.get_or_init(|| Mutex::new(Interner { table: HashMap::default(), entries: 0, sweep_at: MIN_SWEEP }))
}

/// A fixed hasher, so node hashes (and anything ordered by them) never vary between runs.
#[derive(Default, Clone, Copy)]
struct FixedState;
impl BuildHasher for FixedState {
    type Hasher = std::collections::hash_map::DefaultHasher;
    fn build_hasher(&self) -> Self::Hasher {
        std::collections::hash_map::DefaultHasher::new()
    }
}

/// The operations the printed tree of `node` spells out, from its children's counts
/// (saturating: a DAG with shared subtrees can print exponentially long).
fn ops_of(node: &Node) -> usize {
    let sum = |xs: &[Expr]| xs.iter().fold(0usize, |acc, x| acc.saturating_add(x.0.ops));
    match node {
        Node::Num(_) | Node::Sym(_) | Node::Pi | Node::Undefined => 0,
        Node::Add(xs) | Node::Mul(xs) => (xs.len() - 1).saturating_add(sum(xs)),
        Node::Pow(b, e) => 1usize.saturating_add(b.0.ops).saturating_add(e.0.ops),
        Node::Call(_, xs) | Node::Apply { args: xs, .. } => 1usize.saturating_add(sum(xs)),
    }
}

fn intern(node: Node) -> Expr {
    let hash = FixedState.hash_one(&node);
    let ops = ops_of(&node);
    let mut guard = match interner().lock() {
        Ok(guard) => guard,
        Err(poisoned) => poisoned.into_inner(),
    };
    let interner = &mut *guard;
    let bucket = interner.table.entry(hash).or_default();
    let mut found = None;
    let before = bucket.len();
    bucket.retain(|w| match w.upgrade() {
        Some(data) => {
            if found.is_none() && data.node == node {
                found = Some(Expr(data));
            }
            true
        }
        None => false,
    });
    let removed = before - bucket.len();
    if let Some(found) = found {
        interner.entries -= removed;
        return found;
    }
    let data = Arc::new(ExprData { node, hash, ops });
    bucket.push(Arc::downgrade(&data));
    interner.entries = interner.entries - removed + 1;
    if interner.entries > interner.sweep_at {
        interner.sweep();
    }
    Expr(data)
}

/// The range of the interned small numbers `n/d`: `|n| ≤ SMALL_NUM`, `1 ≤ d ≤ SMALL_DEN`.
const SMALL_NUM: i64 = 64;
const SMALL_DEN: i64 = 8;

/// The interned numbers `n/d` in that range, indexed by `(n + SMALL_NUM) · SMALL_DEN + d − 1`
/// (entries for unreduced pairs hold the reduced value and are never looked up: a `Rational`
/// is always reduced).
fn small_nums() -> &'static [Expr] {
    static SMALL: OnceLock<Vec<Expr>> = OnceLock::new();
    SMALL.get_or_init(|| {
        (-SMALL_NUM..=SMALL_NUM)
            .flat_map(|n| (1..=SMALL_DEN).map(move |d| intern(Node::Num(Rational::new(n.into(), d.into())))))
            .collect()
    })
}

/// `a · b`. `Ratio`'s own product reduces by two gcds even when a side is 1 or both are
/// integers, and num-bigint's gcd (Stein's) costs bits × words even against 1: multiplying a
/// 60,000-bit coefficient by 1 took ~20 ms, and collecting a sum's terms does that for every
/// term at every level (the 10⁶ fuzz run stalled there). These cases need no gcd.
pub(crate) fn rat_mul(a: &Rational, b: &Rational) -> Rational {
    if a.is_one() {
        return b.clone();
    }
    if b.is_one() {
        return a.clone();
    }
    if a.is_integer() && b.is_integer() {
        return Rational::from_integer(a.numer() * b.numer());
    }
    a * b
}

/// `a + b`, without `Ratio`'s gcd when a side is 0 or both are integers (see [`rat_mul`]).
pub(crate) fn rat_add(a: &Rational, b: &Rational) -> Rational {
    if a.is_zero() {
        return b.clone();
    }
    if b.is_zero() {
        return a.clone();
    }
    if a.is_integer() && b.is_integer() {
        return Rational::from_integer(a.numer() + b.numer());
    }
    a + b
}

/// Integer part and sign helpers on rationals.
fn is_integer(r: &Rational) -> bool {
    r.is_integer()
}

fn rational_bits(r: &Rational) -> u64 {
    r.numer().bits().max(r.denom().bits())
}

impl Expr {
    // ----- leaves -----------------------------------------------------------------------

    /// An exact rational constant.
    pub fn num(r: Rational) -> Expr {
        // Small numbers come from a table interned once: hashing a `BigRational` (its `Hash`
        // expands a continued fraction by big-integer division) was half the cost of
        // interning in the mechanics pipeline, where most nodes made are coefficients.
        if let (Some(n), Some(d)) = (r.numer().to_i64(), r.denom().to_i64()) {
            if (-SMALL_NUM..=SMALL_NUM).contains(&n) && (1..=SMALL_DEN).contains(&d) {
                return small_nums()[((n + SMALL_NUM) * SMALL_DEN + d - 1) as usize].clone();
            }
        }
        intern(Node::Num(r))
    }

    /// An integer constant.
    pub fn int(i: i64) -> Expr {
        Expr::num(Rational::from_integer(BigInt::from(i)))
    }

    /// The rational `n/d` (`d` must not be zero).
    pub fn frac(n: i64, d: i64) -> Expr {
        Expr::num(Rational::new(BigInt::from(n), BigInt::from(d)))
    }

    /// `0`.
    pub fn zero() -> Expr {
        Expr::int(0)
    }

    /// `1`.
    pub fn one() -> Expr {
        Expr::int(1)
    }

    /// A variable.
    pub fn sym(s: Symbol) -> Expr {
        intern(Node::Sym(s))
    }

    /// A variable with no assumptions, by name.
    pub fn var(name: &str) -> Expr {
        Expr::sym(Symbol::new(name))
    }

    /// The exact constant π.
    pub fn pi() -> Expr {
        intern(Node::Pi)
    }

    /// Whether this is exactly π.
    pub fn is_pi(&self) -> bool {
        matches!(self.node(), Node::Pi)
    }

    /// The undefined value (`1/0`).
    pub fn undefined() -> Expr {
        intern(Node::Undefined)
    }

    // ----- accessors --------------------------------------------------------------------

    /// The node behind this expression.
    pub fn node(&self) -> &Node {
        &self.0.node
    }

    /// The rational value, if this is a number.
    pub fn as_num(&self) -> Option<&Rational> {
        match self.node() {
            Node::Num(r) => Some(r),
            _ => None,
        }
    }

    /// The symbol, if this is a variable.
    pub fn as_sym(&self) -> Option<&Symbol> {
        match self.node() {
            Node::Sym(s) => Some(s),
            _ => None,
        }
    }

    /// Whether this is exactly the number `r`.
    pub fn is_num(&self, r: i64) -> bool {
        self.as_num().is_some_and(|v| *v == Rational::from_integer(BigInt::from(r)))
    }

    /// Whether this is `0`.
    pub fn is_zero(&self) -> bool {
        self.as_num().is_some_and(Zero::is_zero)
    }

    /// Whether this is `1`.
    pub fn is_one(&self) -> bool {
        self.as_num().is_some_and(One::is_one)
    }

    /// Whether this expression is (or contains) an undefined value.
    pub fn is_undefined(&self) -> bool {
        matches!(self.node(), Node::Undefined)
    }

    /// Terms of a sum (a non-sum is a one-term sum).
    pub fn terms(&self) -> Vec<Expr> {
        match self.node() {
            Node::Add(ts) => ts.clone(),
            _ => vec![self.clone()],
        }
    }

    /// Factors of a product (a non-product is a one-factor product).
    pub fn factors(&self) -> Vec<Expr> {
        match self.node() {
            Node::Mul(fs) => fs.clone(),
            _ => vec![self.clone()],
        }
    }

    /// Splits a term into its rational coefficient and the rest: `-3 x y` → `(-3, x y)`.
    pub fn coeff_rest(&self) -> (Rational, Expr) {
        match self.node() {
            Node::Num(r) => (r.clone(), Expr::one()),
            Node::Mul(fs) => match fs[0].node() {
                Node::Num(r) => {
                    let rest = if fs.len() == 2 { fs[1].clone() } else { intern(Node::Mul(fs[1..].to_vec())) };
                    (r.clone(), rest)
                }
                _ => (Rational::one(), self.clone()),
            },
            _ => (Rational::one(), self.clone()),
        }
    }

    /// Splits a factor into base and exponent: `x^3` → `(x, 3)`, `x` → `(x, 1)`.
    pub fn base_exp(&self) -> (Expr, Expr) {
        match self.node() {
            Node::Pow(b, e) => (b.clone(), e.clone()),
            _ => (self.clone(), Expr::one()),
        }
    }

    /// Whether the printed form would start with a minus sign: a negative number, or a
    /// product or sum led by one.
    pub fn is_negative_form(&self) -> bool {
        match self.node() {
            Node::Num(r) => r.is_negative(),
            Node::Mul(fs) => fs[0].as_num().is_some_and(Signed::is_negative),
            Node::Add(ts) => {
                let lead = ts.iter().find(|t| t.as_num().is_none()).unwrap_or(&ts[0]);
                lead.is_negative_form()
            }
            _ => false,
        }
    }

    // ----- canonical constructors -------------------------------------------------------

    /// The canonical sum of `terms`.
    pub fn add(terms: impl IntoIterator<Item = Expr>) -> Expr {
        let mut constant = Rational::zero();
        let mut collected: Vec<(Expr, Rational)> = Vec::new();
        let push = |t: &Expr, constant: &mut Rational, collected: &mut Vec<(Expr, Rational)>| match t.node() {
            Node::Num(r) => *constant = rat_add(constant, r),
            _ => {
                let (c, rest) = t.coeff_rest();
                collected.push((rest, c));
            }
        };
        for t in terms {
            match t.node() {
                Node::Undefined => return Expr::undefined(),
                Node::Add(ts) => {
                    for inner in ts {
                        push(inner, &mut constant, &mut collected);
                    }
                }
                _ => push(&t, &mut constant, &mut collected),
            }
        }
        collected.sort_by(|a, b| a.0.canonical_cmp(&b.0));
        let mut out: Vec<Expr> = Vec::with_capacity(collected.len() + 1);
        if !constant.is_zero() {
            out.push(Expr::num(constant));
        }
        let mut iter = collected.into_iter().peekable();
        while let Some((rest, mut c)) = iter.next() {
            while let Some((next, c2)) = iter.peek() {
                if *next == rest {
                    c = rat_add(&c, c2);
                    iter.next();
                } else {
                    break;
                }
            }
            if !c.is_zero() {
                out.push(Expr::scale(c, rest));
            }
        }
        match out.len() {
            0 => Expr::zero(),
            1 => out.pop().unwrap_or_else(Expr::zero),
            _ => intern(Node::Add(out)),
        }
    }

    /// `c · rest` where `rest` carries no coefficient of its own.
    fn scale(c: Rational, rest: Expr) -> Expr {
        if c.is_one() {
            return rest;
        }
        if rest.is_one() {
            return Expr::num(c);
        }
        let mut fs = vec![Expr::num(c)];
        match rest.node() {
            Node::Mul(inner) => fs.extend(inner.iter().cloned()),
            _ => fs.push(rest),
        }
        intern(Node::Mul(fs))
    }

    /// `a + b`.
    pub fn plus(&self, other: &Expr) -> Expr {
        Expr::add([self.clone(), other.clone()])
    }

    /// `a − b`.
    pub fn minus(&self, other: &Expr) -> Expr {
        Expr::add([self.clone(), other.neg()])
    }

    /// `−a`.
    pub fn neg(&self) -> Expr {
        Expr::mul([Expr::int(-1), self.clone()])
    }

    /// `a · b`.
    pub fn times(&self, other: &Expr) -> Expr {
        Expr::mul([self.clone(), other.clone()])
    }

    /// `a / b`.
    pub fn over(&self, other: &Expr) -> Expr {
        Expr::mul([self.clone(), Expr::pow(other.clone(), Expr::int(-1))])
    }

    /// `a ^ n` for an integer `n`.
    pub fn powi(&self, n: i64) -> Expr {
        Expr::pow(self.clone(), Expr::int(n))
    }

    /// `sqrt(a)`, i.e. `a^(1/2)`.
    pub fn sqrt(&self) -> Expr {
        Expr::pow(self.clone(), Expr::frac(1, 2))
    }

    /// The canonical product of `factors`.
    pub fn mul(factors: impl IntoIterator<Item = Expr>) -> Expr {
        let mut coeff = Rational::one();
        let mut collected: Vec<(Expr, Expr)> = Vec::new();
        let push = |f: &Expr, coeff: &mut Rational, collected: &mut Vec<(Expr, Expr)>| match f.node() {
            Node::Num(r) => *coeff = rat_mul(coeff, r),
            _ => collected.push(f.base_exp()),
        };
        for f in factors {
            match f.node() {
                Node::Undefined => return Expr::undefined(),
                Node::Mul(fs) => {
                    for inner in fs {
                        push(inner, &mut coeff, &mut collected);
                    }
                }
                _ => push(&f, &mut coeff, &mut collected),
            }
        }
        if coeff.is_zero() {
            return Expr::zero();
        }
        collected.sort_by(|a, b| a.0.canonical_cmp(&b.0));
        let mut out: Vec<Expr> = Vec::with_capacity(collected.len());
        let mut iter = collected.into_iter().peekable();
        let mut extra_coeff = Rational::one();
        while let Some((base, exp)) = iter.next() {
            let mut exps = vec![exp];
            while let Some((next, e2)) = iter.peek() {
                if *next == base {
                    exps.push(e2.clone());
                    iter.next();
                } else {
                    break;
                }
            }
            let exp = if exps.len() == 1 { exps.pop().unwrap_or_else(Expr::one) } else { Expr::add(exps) };
            let factor = Expr::pow(base, exp);
            match factor.node() {
                Node::Num(r) => extra_coeff = rat_mul(&extra_coeff, r),
                Node::Undefined => return Expr::undefined(),
                Node::Mul(fs) => {
                    // A power that split (e.g. 2^(3/2) = 2·2^(1/2)): fold its pieces in.
                    for f in fs {
                        match f.node() {
                            Node::Num(r) => extra_coeff = rat_mul(&extra_coeff, r),
                            _ => out.push(f.clone()),
                        }
                    }
                }
                _ => out.push(factor),
            }
        }
        coeff = rat_mul(&coeff, &extra_coeff);
        if coeff.is_zero() {
            return Expr::zero();
        }
        // Re-collect if splitting produced duplicates (rare); otherwise keep the order.
        out.sort_by(|a, b| a.base_exp().0.canonical_cmp(&b.base_exp().0));
        let dup = out.windows(2).any(|w| w[0].base_exp().0 == w[1].base_exp().0);
        if dup {
            let mut fs = vec![Expr::num(coeff)];
            fs.extend(out);
            return Expr::mul(fs);
        }
        // A rational coefficient times a single sum distributes: 2(x + y) = 2x + 2y. This keeps
        // `(x + y) − (x + y)` collapsing to 0 in the sum constructor.
        if !coeff.is_one() && out.len() == 1 {
            if let Node::Add(ts) = out[0].node() {
                let ts = ts.clone();
                return Expr::add(ts.into_iter().map(|t| Expr::mul([Expr::num(coeff.clone()), t])));
            }
        }
        match (out.len(), coeff.is_one()) {
            (0, _) => Expr::num(coeff),
            (1, true) => out.pop().unwrap_or_else(Expr::one),
            _ => {
                let mut fs = Vec::with_capacity(out.len() + 1);
                if !coeff.is_one() {
                    fs.push(Expr::num(coeff));
                }
                fs.extend(out);
                intern(Node::Mul(fs))
            }
        }
    }

    /// The canonical power `base ^ exp`.
    ///
    /// Rewrites applied here hold for every real value where both sides are defined:
    /// `(x^a)^n = x^(an)` for integer `n`; `(x^(2k))^b = |x|^(2kb)`; `(xy)^n = x^n y^n` for
    /// integer `n`, and for any `b` when the split-off factors are positive.
    pub fn pow(base: Expr, exp: Expr) -> Expr {
        if base.is_undefined() || exp.is_undefined() {
            return Expr::undefined();
        }
        if exp.is_zero() {
            return Expr::one();
        }
        if exp.is_one() || base.is_one() {
            return base;
        }
        if let (Some(b), Some(e)) = (base.as_num(), exp.as_num()) {
            if let Some(folded) = fold_num_pow(b, e) {
                return folded;
            }
            return intern(Node::Pow(base, exp));
        }
        if let Some(e) = exp.as_num() {
            let int_exp = is_integer(e);
            match base.node() {
                Node::Pow(b, a) => {
                    if int_exp || b.is_positive() {
                        return Expr::pow(b.clone(), a.times(&exp));
                    }
                    if let Some(ar) = a.as_num() {
                        if is_integer(ar) && ar.to_integer().is_even() {
                            let abs = Expr::call(Func::Abs, vec![b.clone()]);
                            return Expr::pow(abs, Expr::num(ar * e));
                        }
                    }
                }
                Node::Mul(fs) => {
                    if int_exp {
                        return Expr::mul(fs.iter().map(|f| Expr::pow(f.clone(), exp.clone())));
                    }
                    let (pos, rest): (Vec<Expr>, Vec<Expr>) = fs.iter().cloned().partition(|f| f.is_positive());
                    if !pos.is_empty() {
                        let mut out: Vec<Expr> = pos.into_iter().map(|f| Expr::pow(f, exp.clone())).collect();
                        if !rest.is_empty() {
                            out.push(intern_pow_raw(Expr::mul(rest), exp.clone()));
                        }
                        return Expr::mul(out);
                    }
                }
                Node::Call(Func::Abs, args) if int_exp && e.to_integer().is_even() => {
                    return Expr::pow(args[0].clone(), exp.clone());
                }
                _ => {}
            }
        }
        intern(Node::Pow(base, exp))
    }

    /// A built-in function call, with exact values and symmetries folded in.
    pub fn call(func: Func, args: Vec<Expr>) -> Expr {
        if args.iter().any(Expr::is_undefined) {
            return Expr::undefined();
        }
        let x = &args[0];
        if func == Func::Abs {
            if let Some(r) = x.as_num() {
                return Expr::num(r.abs());
            }
            if x.is_positive() {
                return x.clone();
            }
            if x.is_negative_form() {
                return Expr::call(Func::Abs, vec![x.neg()]);
            }
            if let Node::Call(Func::Abs, _) = x.node() {
                return x.clone();
            }
            return intern(Node::Call(func, args));
        }
        if let Some(folded) = at_pi_multiple(func, x) {
            return folded;
        }
        let spec = func.spec();
        if let Some(v) = spec.at_zero.filter(|_| x.is_zero()) {
            return Expr::int(v);
        }
        if let Some(v) = spec.at_one.filter(|_| x.is_one()) {
            return Expr::int(v);
        }
        if x.is_negative_form() {
            match spec.parity {
                Parity::Odd => return Expr::call(func, vec![x.neg()]).neg(),
                Parity::Even => return Expr::call(func, vec![x.neg()]),
                Parity::None => {}
            }
        }
        intern(Node::Call(func, args))
    }

    /// A declared function applied to arguments, with `orders[i]` partial derivatives by
    /// argument `i`.
    pub fn apply(name: &str, orders: Vec<u32>, args: Vec<Expr>) -> Expr {
        if args.iter().any(Expr::is_undefined) {
            return Expr::undefined();
        }
        intern(Node::Apply { name: Arc::from(name), orders, args })
    }

    // ----- queries ----------------------------------------------------------------------

    /// Whether the expression is known to be strictly positive: positive numbers, positive
    /// symbols, and products, sums and real powers of those, `exp`, `cosh`.
    pub fn is_positive(&self) -> bool {
        match self.node() {
            Node::Num(r) => r.is_positive(),
            Node::Sym(s) => s.positive,
            Node::Mul(fs) => fs.iter().all(Expr::is_positive),
            Node::Add(ts) => ts.iter().all(Expr::is_positive),
            Node::Pow(b, e) => {
                b.is_positive()
                    || e.as_num().is_some_and(|r| is_integer(r) && r.to_integer().is_even() && b.is_nonzero_known())
            }
            Node::Pi | Node::Call(Func::Exp | Func::Cosh, _) => true,
            _ => false,
        }
    }

    fn is_nonzero_known(&self) -> bool {
        self.is_positive() || self.as_num().is_some_and(|r| !r.is_zero())
    }

    /// The free symbols, in canonical order.
    pub fn free_symbols(&self) -> BTreeSet<Symbol> {
        let mut out = BTreeSet::new();
        let mut seen = HashSet::new();
        self.collect_symbols(&mut out, &mut seen);
        out
    }

    fn collect_symbols(&self, out: &mut BTreeSet<Symbol>, seen: &mut HashSet<Expr>) {
        if !seen.insert(self.clone()) {
            return;
        }
        match self.node() {
            Node::Sym(s) => {
                out.insert(s.clone());
            }
            _ => self.for_each_child(|c| c.collect_symbols(out, seen)),
        }
    }

    /// Whether `sym` occurs in the expression.
    pub fn contains(&self, sym: &Symbol) -> bool {
        self.free_symbols().contains(sym)
    }

    /// The names of the declared functions the expression applies (`V` in `V'(r)`).
    pub fn applied_functions(&self) -> BTreeSet<String> {
        let mut out = BTreeSet::new();
        let mut seen = HashSet::new();
        fn walk(e: &Expr, out: &mut BTreeSet<String>, seen: &mut HashSet<Expr>) {
            if !seen.insert(e.clone()) {
                return;
            }
            if let Node::Apply { name, .. } = e.node() {
                out.insert(name.to_string());
            }
            e.for_each_child(|c| walk(c, out, seen));
        }
        walk(self, &mut out, &mut seen);
        out
    }

    /// Calls `f` on each direct child.
    pub fn for_each_child(&self, mut f: impl FnMut(&Expr)) {
        match self.node() {
            Node::Num(_) | Node::Sym(_) | Node::Pi | Node::Undefined => {}
            Node::Add(xs) | Node::Mul(xs) | Node::Call(_, xs) | Node::Apply { args: xs, .. } => {
                xs.iter().for_each(&mut f)
            }
            Node::Pow(b, e) => {
                f(b);
                f(e);
            }
        }
    }

    /// Rebuilds this node from new children (in the order of [`Expr::for_each_child`]),
    /// through the canonical constructors.
    pub fn with_children(&self, children: Vec<Expr>) -> Expr {
        match self.node() {
            Node::Num(_) | Node::Sym(_) | Node::Pi | Node::Undefined => self.clone(),
            Node::Add(_) => Expr::add(children),
            Node::Mul(_) => Expr::mul(children),
            Node::Pow(..) => {
                let mut it = children.into_iter();
                match (it.next(), it.next()) {
                    (Some(b), Some(e)) => Expr::pow(b, e),
                    _ => Expr::undefined(),
                }
            }
            Node::Call(f, _) => Expr::call(*f, children),
            Node::Apply { name, orders, .. } => Expr::apply(name, orders.clone(), children),
        }
    }

    /// Rewrites the expression bottom-up: `f` sees each node after its children were
    /// rewritten and may replace it. Shared subexpressions are visited once.
    pub fn map_bottom_up(&self, f: &mut impl FnMut(&Expr) -> Option<Expr>) -> Expr {
        let mut memo: HashMap<Expr, Expr> = HashMap::new();
        self.map_rec(f, &mut memo)
    }

    fn map_rec(&self, f: &mut impl FnMut(&Expr) -> Option<Expr>, memo: &mut HashMap<Expr, Expr>) -> Expr {
        if let Some(done) = memo.get(self) {
            return done.clone();
        }
        let mut children = Vec::new();
        let mut changed = false;
        self.for_each_child(|c| children.push(c.clone()));
        for c in children.iter_mut() {
            let new = c.map_rec(f, memo);
            if new != *c {
                changed = true;
                *c = new;
            }
        }
        let rebuilt = if changed { self.with_children(children) } else { self.clone() };
        let out = f(&rebuilt).unwrap_or(rebuilt);
        memo.insert(self.clone(), out.clone());
        out
    }

    /// Substitutes expressions for symbols, simultaneously.
    pub fn subs(&self, map: &HashMap<Symbol, Expr>) -> Expr {
        if map.is_empty() {
            return self.clone();
        }
        // Not through `map_bottom_up`: that hands the rebuilt parent to the rewrite too, and a
        // parent that collapses to a substituted symbol (`r − a` under `r → a + r` rebuilds
        // as `r`) would be substituted a second time.
        let mut memo: HashMap<Expr, Expr> = HashMap::new();
        self.subs_rec(map, &mut memo)
    }

    fn subs_rec(&self, map: &HashMap<Symbol, Expr>, memo: &mut HashMap<Expr, Expr>) -> Expr {
        if let Node::Sym(s) = self.node() {
            return map.get(s).cloned().unwrap_or_else(|| self.clone());
        }
        if let Some(done) = memo.get(self) {
            return done.clone();
        }
        let mut children = Vec::new();
        self.for_each_child(|c| children.push(c.clone()));
        let new: Vec<Expr> = children.iter().map(|c| c.subs_rec(map, memo)).collect();
        let out = if new == children { self.clone() } else { self.with_children(new) };
        memo.insert(self.clone(), out.clone());
        out
    }

    /// Substitutes one expression for one symbol.
    pub fn subs1(&self, sym: &Symbol, value: &Expr) -> Expr {
        let mut map = HashMap::new();
        map.insert(sym.clone(), value.clone());
        self.subs(&map)
    }

    /// The number of distinct nodes in the DAG.
    pub fn dag_size(&self) -> usize {
        let mut seen = HashSet::new();
        fn walk(e: &Expr, seen: &mut HashSet<Expr>) {
            if seen.insert(e.clone()) {
                e.for_each_child(|c| walk(c, seen));
            }
        }
        walk(self, &mut seen);
        seen.len()
    }

    /// The number of arithmetic operations the printed tree spells out (each `+`, `−`, `·`,
    /// `/`, `^` and function call counts one): the figure compared against other systems.
    /// Kept with the node (saturating at `usize::MAX`), so this is O(1).
    pub fn op_count(&self) -> usize {
        self.0.ops
    }

    // ----- ordering ---------------------------------------------------------------------

    /// The deterministic total order used to sort sums and products. It never depends on
    /// pointers or hashes, so canonical forms are the same on every run.
    ///
    /// Powers sort by base then exponent (so `x`, `x^2`, `y` come in that order); products
    /// compare their factors from the left; numbers come first, then symbols, then compound
    /// expressions.
    pub fn canonical_cmp(&self, other: &Expr) -> Ordering {
        if self == other {
            return Ordering::Equal;
        }
        let (b1, e1) = self.base_exp();
        let (b2, e2) = other.base_exp();
        if b1 != *self || b2 != *other {
            return b1.canonical_cmp(&b2).then_with(|| e1.canonical_cmp(&e2));
        }
        let rank = |e: &Expr| match e.node() {
            Node::Num(_) => 0,
            Node::Pi => 1,
            Node::Sym(_) => 2,
            Node::Mul(_) => 3,
            Node::Add(_) => 4,
            Node::Pow(..) => 5,
            Node::Call(..) => 6,
            Node::Apply { .. } => 7,
            Node::Undefined => 8,
        };
        rank(self).cmp(&rank(other)).then_with(|| match (self.node(), other.node()) {
            (Node::Num(a), Node::Num(b)) => a.cmp(b),
            (Node::Sym(a), Node::Sym(b)) => a.cmp(b),
            // Products that differ only in their coefficient (`x/200`, `10^3008 x`) are
            // ordered by it: without this tie-break `(x/200 - 1)` and `(10^3008 x - 1)`
            // compared equal as factors, and their product kept whichever order it was
            // built in (found by the 10⁶ fuzz run: print → parse gave another node).
            (Node::Mul(a), Node::Mul(b)) => {
                cmp_lists(skip_coeff(a), skip_coeff(b)).then_with(|| coeff_of(a).cmp(&coeff_of(b)))
            }
            (Node::Add(a), Node::Add(b)) => cmp_lists(a, b),
            (Node::Call(f, a), Node::Call(g, b)) => cmp_lists(a, b).then(f.cmp(g)),
            (Node::Apply { name: n1, orders: o1, args: a1 }, Node::Apply { name: n2, orders: o2, args: a2 }) => {
                n1.cmp(n2).then_with(|| o1.cmp(o2)).then_with(|| cmp_lists(a1, a2))
            }
            _ => Ordering::Equal,
        })
    }
}

/// `k` when `e` is `k π` for a rational `k` (π itself gives 1).
fn pi_coefficient(e: &Expr) -> Option<Rational> {
    match e.coeff_rest() {
        (k, rest) if rest.is_pi() => Some(k),
        _ => None,
    }
}

/// `r` reduced into `[0, m)`.
fn rat_mod(r: &Rational, m: &Rational) -> Rational {
    r - m * (r / m).floor()
}

/// `sin(k π)` for `k` in `[0, 2)` when it has a short exact form (`k` a multiple of 1/4 or
/// 1/6): `0`, `±1/2`, `±√2/2`, `±√3/2`, `±1`.
fn sin_pi_exact(k: &Rational) -> Option<Expr> {
    let one = Rational::one();
    let (mut k, sign) = if *k >= one { (k - &one, -1) } else { (k.clone(), 1) };
    if k > Rational::new(1.into(), 2.into()) {
        k = &one - &k; // sin(π − x) = sin x
    }
    let half = Expr::frac(1, 2);
    let root = |n: i64| half.times(&Expr::pow(Expr::int(n), Expr::frac(1, 2)));
    let value = match (k.numer().to_i64()?, k.denom().to_i64()?) {
        (0, _) => Expr::zero(),
        (1, 6) => half,
        (1, 4) => root(2),
        (1, 3) => root(3),
        (1, 2) => Expr::one(),
        _ => return None,
    };
    Some(if sign < 0 { value.neg() } else { value })
}

/// The exact value of a trigonometric function at a rational multiple of π (`sin(π) = 0`,
/// `cos(π/3) = 1/2`, `tan(π/2)` undefined), the shift of its argument by a multiple of π/2
/// (`sin(x + π) = −sin x`, `cos(x + π/2) = −sin x`), or the inverse functions' values at the
/// points where they are such a multiple (`acos(−1) = π`, `atan(1) = π/4`). `None` otherwise.
///
/// π is exact, so these are identities rather than roundings; without them `sin(pi)` would be
/// left for the compiler to evaluate to 1.2e-16.
fn at_pi_multiple(func: Func, x: &Expr) -> Option<Expr> {
    let two = Rational::from_integer(2.into());
    let pi_times = |n: i64, d: i64| Expr::frac(n, d).times(&Expr::pi());
    match func {
        Func::Sin | Func::Cos | Func::Tan => {}
        // (argument n/d, value a π/b); negative arguments of asin fold by its parity.
        Func::Asin | Func::Acos => {
            let r = x.as_num()?;
            let table: &[(i64, i64, i64, i64)] = if func == Func::Asin {
                &[(1, 1, 1, 2), (1, 2, 1, 6)]
            } else {
                &[(0, 1, 1, 2), (-1, 1, 1, 1), (1, 2, 1, 3), (-1, 2, 2, 3)]
            };
            return table
                .iter()
                .find(|(n, d, _, _)| *r == Rational::new((*n).into(), (*d).into()))
                .map(|&(_, _, a, b)| pi_times(a, b));
        }
        Func::Atan => return x.is_one().then(|| pi_times(1, 4)),
        // The reciprocals of cos and sin at an exact rational multiple of π: undefined at a
        // zero of theirs (a pole). A shifted argument (`x + π`) is left as written.
        Func::Sec | Func::Csc => {
            if x.is_zero() {
                return Some(if func == Func::Sec { Expr::one() } else { Expr::undefined() });
            }
            pi_coefficient(x)?;
            let of = at_pi_multiple(if func == Func::Sec { Func::Cos } else { Func::Sin }, x)?;
            return Some(if of.is_zero() { Expr::undefined() } else { Expr::pow(of, Expr::int(-1)) });
        }
        _ => return None,
    }
    if let Some(k) = pi_coefficient(x) {
        return match func {
            Func::Sin => sin_pi_exact(&rat_mod(&k, &two)),
            Func::Cos => sin_pi_exact(&rat_mod(&(k + Rational::new(1.into(), 2.into())), &two)),
            _ => {
                let k = rat_mod(&k, &Rational::one());
                if k == Rational::new(1.into(), 2.into()) {
                    return Some(Expr::undefined()); // tan(π/2): a pole
                }
                let s = sin_pi_exact(&k)?;
                let c = sin_pi_exact(&rat_mod(&(k + Rational::new(1.into(), 2.into())), &two))?;
                Some(s.over(&c))
            }
        };
    }
    // A sum with a term `k π`, `k` a multiple of 1/2: shift it out.
    let Node::Add(ts) = x.node() else { return None };
    let (at, k) = ts.iter().enumerate().find_map(|(i, t)| pi_coefficient(t).map(|k| (i, k)))?;
    let rest = Expr::add(ts.iter().enumerate().filter(|&(i, _)| i != at).map(|(_, t)| t.clone()));
    let quarters = rat_mod(&(k * &two), &Rational::from_integer(4.into()));
    if !quarters.is_integer() {
        return None;
    }
    let n = quarters.to_integer().to_i64()?;
    let (sin, cos) = (Expr::call(Func::Sin, vec![rest.clone()]), Expr::call(Func::Cos, vec![rest.clone()]));
    Some(match (func, n) {
        (Func::Sin, 0) | (Func::Cos, 3) => sin,
        (Func::Sin, 1) | (Func::Cos, 0) => cos,
        (Func::Sin, 2) | (Func::Cos, 1) => sin.neg(),
        (Func::Sin, 3) | (Func::Cos, 2) => cos.neg(),
        (_, 0 | 2) => Expr::call(Func::Tan, vec![rest]),
        _ => Expr::pow(Expr::call(Func::Tan, vec![rest]), Expr::int(-1)).neg(), // tan(x + π/2) = −1/tan x
    })
}

fn skip_coeff(fs: &[Expr]) -> &[Expr] {
    match fs.first() {
        Some(f) if f.as_num().is_some() => &fs[1..],
        _ => fs,
    }
}

/// The numeric coefficient of a product's factor list (1 when it has none).
fn coeff_of(fs: &[Expr]) -> Rational {
    fs.first().and_then(Expr::as_num).cloned().unwrap_or_else(Rational::one)
}

fn cmp_lists(a: &[Expr], b: &[Expr]) -> Ordering {
    for (x, y) in a.iter().zip(b) {
        let c = x.canonical_cmp(y);
        if c != Ordering::Equal {
            return c;
        }
    }
    a.len().cmp(&b.len())
}

fn intern_pow_raw(base: Expr, exp: Expr) -> Expr {
    if exp.is_one() {
        return base;
    }
    intern(Node::Pow(base, exp))
}

/// Folds `b^e` for rationals when the result is rational and small enough.
fn fold_num_pow(b: &Rational, e: &Rational) -> Option<Expr> {
    if b.is_zero() {
        return Some(if e.is_negative() { Expr::undefined() } else { Expr::zero() });
    }
    if b.is_one() {
        return Some(Expr::one());
    }
    if is_integer(e) {
        let n = e.to_integer();
        let n_abs = n.abs().to_u64()?;
        if rational_bits(b).saturating_mul(n_abs) > MAX_FOLD_BITS {
            return None;
        }
        let n_abs = u32::try_from(n_abs).ok()?;
        let p = Rational::new(b.numer().pow(n_abs), b.denom().pow(n_abs));
        return Some(Expr::num(if n.is_negative() { p.recip() } else { p }));
    }
    // A rational root: exact when numerator and denominator are perfect powers.
    let k = e.denom().to_u32()?;
    if k > 64 || b.is_negative() && k % 2 == 0 {
        return None;
    }
    let root = |n: &BigInt| -> Option<BigInt> {
        let r = n.abs().nth_root(k);
        if r.pow(k) == n.abs() {
            Some(if n.is_negative() { -r } else { r })
        } else {
            None
        }
    };
    if let (Some(rn), Some(rd)) = (root(b.numer()), root(b.denom())) {
        let rooted = Rational::new(rn, rd);
        return fold_num_pow(&rooted, &Rational::from_integer(e.numer().clone()));
    }
    // Split off the integer part of the exponent: 2^(3/2) = 2 · 2^(1/2).
    let whole = e.floor();
    if !whole.is_zero() {
        let frac = e - &whole;
        let int_part = fold_num_pow(b, &whole)?;
        return Some(Expr::mul([int_part, intern(Node::Pow(Expr::num(b.clone()), Expr::num(frac)))]));
    }
    None
}
