//! Simplification on an e-graph (egg), seeded with candidate forms from [`crate::algebra`].
//!
//! The canonical form of [`crate::expr`] already handles associativity, commutativity, like
//! terms and numeric folding, so the e-graph never sees those as rules (they make e-graphs
//! explode: DESIGN.md, "Known hard parts"). What it adds:
//!
//! 1. **Candidate forms.** Identities that range over whole n-ary sums — the Pythagorean
//!    identity among many terms, multiplying out, one common denominator with cancellation,
//!    common content, greedy Horner collection — are computed by the algebra tools, both for the whole expression and
//!    for every sum bottom-up, and each candidate is added to the e-graph in the root's class.
//! 2. **One table of named, sound rules** ([`rules`]) on fixed-arity nodes: `exp`/`log`
//!    inverses with their domain conditions, double angles, `tan = sin/cos`, inverse
//!    trigonometric compositions. Conditions only use what is known for sure (positivity
//!    declared on symbols or implied by the node, exact constants), never a value that a
//!    later merge could change.
//! 3. **Extraction** by a cost that counts printed operations, with ties broken by the
//!    canonical order, so the output is deterministic.
//!
//! Every default budget is a count (e-nodes, iterations, expansion terms), never a time: the
//! same input prints the same bytes on an idle laptop and on a loaded CI runner. A wall-clock
//! guard exists only on request ([`Budget::with_time`]); when it binds, the result says so
//! ([`Simplified::budget_limited`]) because it may then differ from run to run.
//!
//! Every result is checked by evaluation at a few fixed pseudo-random points against the
//! input; a disagreement (which would be a bug) falls back to the input.
//!
//! A sum of more than 64 terms is first split into parts whose terms share nothing with other
//! parts (no symbol, application or compound subexpression), and the parts are simplified
//! one by one: nothing above can join terms that share nothing, and whole-sum tools on a sum
//! of N unrelated terms cost about N^1.5.

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use egg::{Analysis, DidMerge, EGraph, Id, Runner, Subst, Var};
use num_traits::{Signed, Zero};

use crate::algebra;
use crate::eval::eval_with;
use crate::expr::{Expr, Func, Node, Rational, Symbol};

/// How much work one simplification may do. Running out is an outcome, not an error: the
/// best form found so far is returned together with the [`StopReason`].
///
/// The limits that decide an output are counts, so the output depends only on the input.
/// `time` is an opt-in guard for interactive callers who prefer an answer now to the same
/// answer every time; it is off by default.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Budget {
    /// Largest number of e-nodes in the e-graph.
    pub nodes: usize,
    /// Largest number of rule-application rounds.
    pub iterations: usize,
    /// Optional wall-clock guard for each e-graph run (`None`, the default: no clock at all).
    pub time: Option<Duration>,
    /// Largest number of terms a candidate expansion may produce.
    pub expand_terms: usize,
}

impl Default for Budget {
    fn default() -> Budget {
        Budget { nodes: 20_000, iterations: 12, time: None, expand_terms: 2_000 }
    }
}

impl Budget {
    /// Sets the e-node limit.
    pub fn with_nodes(mut self, nodes: usize) -> Budget {
        self.nodes = nodes;
        self
    }

    /// Sets the iteration limit.
    pub fn with_iterations(mut self, iterations: usize) -> Budget {
        self.iterations = iterations;
        self
    }

    /// Turns on the wall-clock guard: each e-graph run stops after `time`. A result it cut
    /// short is marked ([`Simplified::budget_limited`]) and may differ between runs.
    pub fn with_time(mut self, time: Duration) -> Budget {
        self.time = Some(time);
        self
    }

    /// Sets the largest expansion tried as a candidate form.
    pub fn with_expand_terms(mut self, terms: usize) -> Budget {
        self.expand_terms = terms;
        self
    }
}

/// Why the e-graph run stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StopReason {
    /// No rule could add anything new: the result is the best form the rules can reach.
    Saturated,
    /// The iteration budget ran out.
    IterationLimit,
    /// The e-node budget ran out.
    NodeLimit,
    /// The opt-in wall-clock guard ran out (never with the default budget).
    TimeLimit,
    /// Ctrl-C (the process-wide [`crate::cancel`] token) stopped the search; the result is
    /// the best form found so far, still equal to the input.
    Interrupted,
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StopReason::Saturated => "saturated",
            StopReason::IterationLimit => "iteration limit",
            StopReason::NodeLimit => "node limit",
            StopReason::TimeLimit => "time limit",
            StopReason::Interrupted => "interrupted",
        })
    }
}

/// A simplified expression and why the search stopped.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Simplified {
    /// The cheapest equivalent form found.
    pub expr: Expr,
    /// Why the search stopped: [`StopReason::TimeLimit`] if the wall-clock guard cut any
    /// e-graph run short, otherwise the last run's reason.
    pub stop: StopReason,
}

impl Simplified {
    /// True when the opt-in wall-clock guard (or an interrupt) decided this result: the same
    /// input may then simplify differently on another run. Never true under a budget
    /// without `time` when nothing is interrupted.
    pub fn budget_limited(&self) -> bool {
        matches!(self.stop, StopReason::TimeLimit | StopReason::Interrupted)
    }
}

/// Simplifies `e` with the default [`Budget`].
pub fn simplify(e: &Expr) -> Expr {
    simplify_with(e, &Budget::default()).expr
}

/// Simplifies `e` within `budget`.
///
/// Deterministic: the same input gives the same output bytes whenever `budget.time` is
/// `None` (the default). With the guard on, a result it cut short reports
/// [`Simplified::budget_limited`].
pub fn simplify_with(e: &Expr, budget: &Budget) -> Simplified {
    if matches!(e.node(), Node::Num(_) | Node::Sym(_) | Node::Pi | Node::Undefined) {
        return Simplified { expr: e.clone(), stop: StopReason::Saturated };
    }
    if let Some(parts) = independent_parts(e) {
        return simplify_parts(parts, budget);
    }
    let mut timed_out = false;
    // Arguments of declared functions are opaque to the e-graph; simplify them first.
    let e = e.map_bottom_up(&mut |x| match x.node() {
        Node::Apply { name, orders, args } => {
            let args: Vec<Expr> = args
                .iter()
                .map(|a| {
                    let inner = simplify_with(a, budget);
                    timed_out |= inner.budget_limited();
                    inner.expr
                })
                .collect();
            Some(Expr::apply(name, orders.clone(), args))
        }
        _ => None,
    });
    let mut best = e.clone();
    let mut stop = StopReason::Saturated;
    // Two rounds: rules can expose new sums for the candidate tools and vice versa.
    for _ in 0..2 {
        let (found, why) = egraph_round(&best, budget);
        stop = why;
        timed_out |= why == StopReason::TimeLimit;
        if cost(&found) < cost(&best) {
            best = found;
        } else {
            break;
        }
        if why == StopReason::Interrupted {
            break;
        }
    }
    if !same_values(&e, &best) || nesting(&best) > nesting(&e).max(MAX_NESTING) {
        best = e;
    }
    if timed_out && stop != StopReason::Interrupted {
        stop = StopReason::TimeLimit;
    }
    Simplified { expr: best, stop }
}

/// Sums with more terms than this are split into independent parts before anything else
/// looks at them (see [`independent_parts`]); up to this width a sum is simplified whole.
const WIDE: usize = 64;

/// The terms of a wide sum, split into parts that no candidate tool or rule can join, each
/// part small, or `None` when `e` is not a sum wider than [`WIDE`] or its terms are all
/// connected.
///
/// Why: every candidate tool and the e-graph look at a whole sum, and their cost on a sum of
/// N unrelated terms grew as N^1.5 (BENCHMARKS.md, "Large inputs"). Two terms can only
/// combine (a Pythagorean pair, a common factor, an angle sum, a rule's two-term pattern) if
/// they share a node other than a number: a symbol, a declared function's application, or a
/// compound such as `sqrt(2)`. So the terms are grouped by shared nodes (union–find, linear in
/// the size of the sum); terms with no symbol or application at all (numbers, `sin(1)`) form
/// one group, since constants can combine with each other.
/// Groups are then packed, in order of their first term, into parts of about [`WIDE`] terms
/// (a group wider than that is one part of its own), and each part is simplified as a sum:
/// the cost is linear in the number of parts, each bounded by the budget.
fn independent_parts(e: &Expr) -> Option<Vec<Expr>> {
    let Node::Add(ts) = e.node() else { return None };
    if ts.len() <= WIDE {
        return None;
    }
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut parent: Vec<usize> = (0..ts.len()).collect();
    let mut owner: HashMap<Expr, usize> = HashMap::new();
    // The first constant term (no symbol or application); later ones join it.
    let mut constant: Option<usize> = None;
    for (i, t) in ts.iter().enumerate() {
        let mut atoms: Vec<Expr> = Vec::new();
        let mut seen: std::collections::HashSet<Expr> = std::collections::HashSet::new();
        let mut stack = vec![t.clone()];
        let mut constant_term = true;
        while let Some(x) = stack.pop() {
            if !seen.insert(x.clone()) {
                continue;
            }
            match x.node() {
                Node::Num(_) | Node::Pi => {}
                Node::Sym(_) | Node::Apply { .. } | Node::Undefined => {
                    constant_term = false;
                    atoms.push(x.clone());
                }
                _ => {
                    // A compound node is a key too: `sqrt(2) x + sqrt(2) y` shares no symbol,
                    // but `factor_content` pulls out `sqrt(2)`.
                    atoms.push(x.clone());
                    x.for_each_child(|c| stack.push(c.clone()));
                }
            }
        }
        if constant_term {
            match constant {
                Some(j) => {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    parent[a] = b;
                }
                None => constant = Some(i),
            }
        }
        for a in atoms {
            match owner.get(&a) {
                Some(&j) => {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    parent[a] = b;
                }
                None => {
                    owner.insert(a, i);
                }
            }
        }
    }
    // Groups in order of their first term; terms keep their order within a group.
    let mut group_of: HashMap<usize, usize> = HashMap::new();
    let mut groups: Vec<Vec<Expr>> = Vec::new();
    for (i, t) in ts.iter().enumerate() {
        let r = root(&mut parent, i);
        let g = *group_of.entry(r).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(t.clone());
    }
    if groups.len() < 2 {
        return None;
    }
    let mut parts: Vec<Expr> = Vec::new();
    let mut part: Vec<Expr> = Vec::new();
    for g in groups {
        if !part.is_empty() && part.len() + g.len() > WIDE {
            parts.push(Expr::add(std::mem::take(&mut part)));
        }
        part.extend(g);
    }
    if !part.is_empty() {
        parts.push(Expr::add(part));
    }
    Some(parts)
}

/// Simplifies the independent parts of a wide sum one by one and adds the results. Each part
/// is checked against itself as any simplification is, so the sum is equal to the input.
/// Ctrl-C between parts keeps the parts not yet simplified as they are.
fn simplify_parts(parts: Vec<Expr>, budget: &Budget) -> Simplified {
    let mut out = Vec::with_capacity(parts.len());
    let mut stop = StopReason::Saturated;
    for part in parts {
        if stop == StopReason::Interrupted || crate::cancel::interrupted() {
            stop = StopReason::Interrupted;
            out.push(part);
            continue;
        }
        let s = simplify_with(&part, budget);
        // The report is the most telling reason among the parts: an interrupt or the clock
        // (the result may vary between runs), else a count limit that bound somewhere.
        let rank = |r: StopReason| match r {
            StopReason::Saturated => 0,
            StopReason::IterationLimit => 1,
            StopReason::NodeLimit => 2,
            StopReason::TimeLimit => 3,
            StopReason::Interrupted => 4,
        };
        if rank(s.stop) > rank(stop) {
            stop = s.stop;
        }
        out.push(s.expr);
    }
    Simplified { expr: Expr::add(out), stop }
}

/// The extraction cost of a canonical expression: printed operations first; then the number
/// of negated products of sums (`−a (c − 1)` reads worse than `a (1 − c)`, at the same count);
/// then size, so that remaining ties go to the smaller form.
fn cost(e: &Expr) -> (usize, usize, usize) {
    let mut awkward = 0;
    e.map_bottom_up(&mut |x| {
        if let Node::Mul(fs) = x.node() {
            let negative = fs[0].as_num().is_some_and(Signed::is_negative);
            if negative && fs.iter().any(|f| matches!(f.node(), Node::Add(_))) {
                awkward += 1;
            }
        }
        None
    });
    (e.op_count(), awkward, e.dag_size())
}

/// Picks the cheapest expression, ties broken by the canonical order.
///
/// The same choice as the minimum of [`cost`], but the walks behind its second and third
/// parts run only for the distinct candidates tied on the first, which is kept with each node:
/// the bottom-up pass asks this at every node, and walking every candidate there made the pass
/// quadratic in the depth of a nested input.
fn cheapest(cands: impl IntoIterator<Item = Expr>) -> Option<Expr> {
    let cands: Vec<Expr> = cands.into_iter().collect();
    let fewest = cands.iter().map(Expr::op_count).min()?;
    let mut tied: Vec<Expr> = Vec::new();
    for c in cands {
        if c.op_count() == fewest && !tied.contains(&c) {
            tied.push(c);
        }
    }
    if tied.len() == 1 {
        return tied.pop();
    }
    tied.into_iter().min_by(|a, b| cost(a).cmp(&cost(b)).then_with(|| a.canonical_cmp(b)))
}

/// Candidate forms of `e` from the algebra tools.
fn candidates(e: &Expr, budget: &Budget) -> Vec<Expr> {
    let expanded = algebra::expand_with_limit(e, budget.expand_terms);
    // An expansion to a number is the cheapest form there is (nothing costs less than a
    // number, and a different number would fail the value check), so the other tools are
    // not run on the input (`(x+1)^400 −` its expansion: 402 terms with 400-bit coefficients).
    if let Ok(x) = &expanded {
        if x.as_num().is_some() {
            return vec![e.clone(), x.clone()];
        }
    }
    let mut out = vec![e.clone(), algebra::trig_normalize(e)];
    let local = local_best(e, budget);
    out.push(local.clone());
    out.push(algebra::factor_content(&local));
    out.push(algebra::collect_common(&local));
    if let Ok(x) = expanded {
        let t = algebra::trig_normalize(&x);
        out.push(algebra::factor_content(&t));
        out.push(algebra::collect_common(&t));
        out.push(t);
        out.push(x);
    }
    if has_denominator(e) {
        let c = algebra::cancel(e);
        out.push(algebra::trig_normalize(&c));
        out.push(c);
    }
    // Horner forms of high-degree polynomials are the cheapest by operation count but nest
    // one level per degree; past `MAX_NESTING` they would print deeper than is readable (and,
    // for degree > 1000, deeper than the parser accepts). A candidate deeper than both that
    // bound and the input is dropped, so simplifying never makes an expression much deeper.
    let limit = nesting(e).max(MAX_NESTING);
    let mut unique: Vec<Expr> = Vec::new();
    for c in out {
        if !c.is_undefined() && !unique.contains(&c) && (unique.is_empty() || nesting(&c) <= limit) {
            unique.push(c);
        }
    }
    unique
}

/// The deepest nesting the simplifier creates on its own: a Horner form keeps at most this
/// many levels (`algebra::collect_common` stops at 64 per call; repeated rounds could stack).
pub(crate) const MAX_NESTING: usize = 64;

/// The depth of `e` as a tree (a leaf is 1), counted once per shared node.
fn nesting(e: &Expr) -> usize {
    fn walk(e: &Expr, memo: &mut HashMap<Expr, usize>) -> usize {
        if let Some(&d) = memo.get(e) {
            return d;
        }
        let mut deepest = 0;
        e.for_each_child(|c| deepest = deepest.max(walk(c, memo)));
        memo.insert(e.clone(), deepest + 1);
        deepest + 1
    }
    walk(e, &mut HashMap::new())
}

/// Whether a power with a negative exponent of something other than a lone symbol occurs,
/// i.e. whether `cancel` could find anything.
fn has_denominator(e: &Expr) -> bool {
    let mut found = false;
    e.map_bottom_up(&mut |x| {
        if let Node::Pow(_, k) = x.node() {
            if k.as_num().is_some_and(Signed::is_negative) {
                found = true;
            }
        }
        None
    });
    found
}

/// Rewrites every sum bottom-up into the cheapest of itself, its expansion, its
/// Pythagorean normal form and its factored content.
fn local_best(e: &Expr, budget: &Budget) -> Expr {
    let mut expansions = algebra::ExpandMemo::default();
    e.map_bottom_up(&mut |x| match x.node() {
        // Ctrl-C: the nodes not yet visited stay as they are (the e-graph round that follows
        // reports the interrupt).
        _ if crate::cancel::interrupted() => None,
        Node::Add(_) | Node::Pow(..) | Node::Mul(_) => {
            let mut cands = vec![x.clone()];
            if matches!(x.node(), Node::Add(_)) {
                cands.push(algebra::trig_normalize(x));
                cands.push(algebra::factor_content(x));
                cands.push(algebra::collect_common(x));
            }
            if let Ok(ex) = algebra::expand_with_memo(x, budget.expand_terms.min(200), &mut expansions) {
                cands.push(algebra::trig_normalize(&ex));
                cands.push(ex);
            }
            cheapest(cands).filter(|b| b != x)
        }
        _ => None,
    })
}

/// Checks `b` against the input `a` at fixed pseudo-random points: declared-positive symbols
/// in (0.3, 1.7), others in (−1.7, 1.7). Points where the input has no finite value are
/// skipped; expressions that cannot be evaluated (declared functions) pass.
#[doc(hidden)]
pub fn same_values(a: &Expr, b: &Expr) -> bool {
    if a == b {
        return true;
    }
    let syms: Vec<Symbol> = a.free_symbols().into_iter().chain(b.free_symbols()).collect();
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    for _ in 0..4 {
        let mut vals: HashMap<Symbol, f64> = HashMap::new();
        for s in &syms {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            let v = if s.is_positive() { 0.3 + 1.4 * unit } else { -1.7 + 3.4 * unit };
            vals.entry(s.clone()).or_insert(v);
        }
        let look = |s: &Symbol| vals.get(s).copied();
        let Ok(va) = eval_with(a, &look) else { return true };
        if !va.is_finite() {
            continue;
        }
        let Ok(vb) = eval_with(b, &look) else { return false };
        // A sum's value carries the rounding of its largest terms: `(x + 1)^400` minus its
        // expansion is 0 exactly but ~1e160 · ε in f64, so the scale is the sum of |terms|.
        let scale = match a.node() {
            Node::Add(ts) => ts.iter().map(|t| eval_with(t, &look).map_or(0.0, f64::abs)).sum::<f64>(),
            _ => 0.0,
        };
        let scale = if scale.is_finite() { scale } else { 0.0 };
        let close = (va - vb).abs() <= 1e-6 * (1.0 + va.abs().max(scale));
        if !close {
            return false;
        }
    }
    true
}

// ----- the e-graph ---------------------------------------------------------------------------

/// A leaf the e-graph does not look into: a symbol or a declared function's application,
/// numbered in a per-run table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LeafId(u32);

impl fmt::Display for LeafId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "leaf{}", self.0)
    }
}

impl FromStr for LeafId {
    type Err = ();
    fn from_str(s: &str) -> Result<LeafId, ()> {
        s.strip_prefix("leaf").and_then(|n| n.parse().ok()).map(LeafId).ok_or(())
    }
}

egg::define_language! {
    /// The e-graph's view of an expression: n-ary sums and products as in [`Node`], built-in
    /// functions by name, exact rationals, and opaque leaves.
    pub enum Math {
        "+" = Add(Box<[Id]>),
        "*" = Mul(Box<[Id]>),
        "^" = Pow([Id; 2]),
        "sin" = Sin(Id),
        "cos" = Cos(Id),
        "tan" = Tan(Id),
        "exp" = Exp(Id),
        "log" = Log(Id),
        "sinh" = Sinh(Id),
        "cosh" = Cosh(Id),
        "tanh" = Tanh(Id),
        "asin" = Asin(Id),
        "acos" = Acos(Id),
        "atan" = Atan(Id),
        "atan2" = Atan2([Id; 2]),
        "abs" = Abs(Id),
        "asinh" = Asinh(Id),
        "acosh" = Acosh(Id),
        "atanh" = Atanh(Id),
        "sec" = Sec(Id),
        "csc" = Csc(Id),
        "coth" = Coth(Id),
        "erf" = Erf(Id),
        Num(Rational),
        Leaf(LeafId),
    }
}

/// What the analysis knows about an e-class: its cheapest known canonical form.
///
/// Rule right-hand sides create e-nodes that are not canonical (`(1/2)·(2x)`); the
/// representative is rebuilt through the canonical constructors from the children's
/// representatives, so such a node is costed as what it really is (`x`). Merging keeps the
/// cheaper representative (ties: canonical order), which makes the root's representative the
/// extraction result, independent of the order of merges.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Facts {
    /// The cheapest canonical expression known for the class.
    pub repr: Expr,
    /// Its cost: printed operations, then negated products of sums, then size (the
    /// extraction cost of this module).
    pub cost: (usize, usize, usize),
    /// Whether the class is known to be strictly positive (from any of its forms).
    pub positive: bool,
}

impl Facts {
    fn of(repr: Expr) -> Facts {
        Facts { cost: cost(&repr), positive: repr.is_positive(), repr }
    }

    fn constant(&self) -> Option<&Rational> {
        self.repr.as_num()
    }
}

/// The analysis: canonical representatives, constant folding over exact rationals (a
/// representative that is a number puts that number in the class) and positivity.
#[derive(Default)]
pub struct Knowledge {
    leaves: Vec<Expr>,
    leaf_ids: HashMap<Expr, LeafId>,
}

type Graph = EGraph<Math, Knowledge>;

impl Analysis<Math> for Knowledge {
    type Data = Facts;

    fn make(egraph: &mut Graph, enode: &Math, _id: Id) -> Facts {
        let k = |i: &Id| egraph[*i].data.repr.clone();
        let call = |f: Func, i: &Id| Expr::call(f, vec![k(i)]);
        let repr = match enode {
            Math::Num(r) => Expr::num(r.clone()),
            Math::Leaf(LeafId(i)) => egraph.analysis.leaves.get(*i as usize).cloned().unwrap_or_else(Expr::undefined),
            Math::Add(xs) => Expr::add(xs.iter().map(k)),
            Math::Mul(xs) => Expr::mul(xs.iter().map(k)),
            Math::Pow([b, x]) => Expr::pow(k(b), k(x)),
            Math::Sin(a) => call(Func::Sin, a),
            Math::Cos(a) => call(Func::Cos, a),
            Math::Tan(a) => call(Func::Tan, a),
            Math::Exp(a) => call(Func::Exp, a),
            Math::Log(a) => call(Func::Log, a),
            Math::Sinh(a) => call(Func::Sinh, a),
            Math::Cosh(a) => call(Func::Cosh, a),
            Math::Tanh(a) => call(Func::Tanh, a),
            Math::Asin(a) => call(Func::Asin, a),
            Math::Acos(a) => call(Func::Acos, a),
            Math::Atan(a) => call(Func::Atan, a),
            Math::Abs(a) => call(Func::Abs, a),
            Math::Asinh(a) => call(Func::Asinh, a),
            Math::Acosh(a) => call(Func::Acosh, a),
            Math::Atanh(a) => call(Func::Atanh, a),
            Math::Sec(a) => call(Func::Sec, a),
            Math::Csc(a) => call(Func::Csc, a),
            Math::Coth(a) => call(Func::Coth, a),
            Math::Erf(a) => call(Func::Erf, a),
            Math::Atan2([a, b]) => Expr::call(Func::Atan2, vec![k(a), k(b)]),
        };
        let mut facts = Facts::of(repr);
        facts.positive |= match enode {
            Math::Add(xs) | Math::Mul(xs) => xs.iter().all(|i| egraph[*i].data.positive),
            Math::Pow([b, _]) => egraph[*b].data.positive,
            Math::Exp(_) | Math::Cosh(_) => true,
            _ => false,
        };
        facts
    }

    fn merge(&mut self, to: &mut Facts, from: Facts) -> DidMerge {
        let mut changed_to = false;
        let mut changed_from = false;
        let positive = to.positive || from.positive;
        changed_from |= positive != from.positive;
        changed_to |= positive != to.positive;
        let order = from.cost.cmp(&to.cost).then_with(|| from.repr.canonical_cmp(&to.repr));
        if order == std::cmp::Ordering::Less {
            *to = from;
            changed_to = true;
        } else if order == std::cmp::Ordering::Greater {
            changed_from = true;
        }
        to.positive = positive;
        DidMerge(changed_to, changed_from)
    }

    fn modify(egraph: &mut Graph, id: Id) {
        if let Some(r) = egraph[id].data.constant().cloned() {
            let added = egraph.add(Math::Num(r));
            egraph.union(id, added);
        }
    }
}

/// Adds a canonical expression to the e-graph (shared subexpressions once).
fn add_expr(g: &mut Graph, e: &Expr, memo: &mut HashMap<Expr, Id>) -> Id {
    if let Some(id) = memo.get(e) {
        return *id;
    }
    let mut kids = Vec::new();
    e.for_each_child(|c| kids.push(c.clone()));
    let node = match e.node() {
        Node::Num(r) => Math::Num(r.clone()),
        Node::Sym(_) | Node::Pi | Node::Apply { .. } | Node::Undefined => {
            let known = g.analysis.leaf_ids.get(e).copied();
            let l = known.unwrap_or_else(|| {
                let l = LeafId(g.analysis.leaves.len() as u32);
                g.analysis.leaves.push(e.clone());
                g.analysis.leaf_ids.insert(e.clone(), l);
                l
            });
            Math::Leaf(l)
        }
        Node::Add(_) => Math::Add(kids.iter().map(|c| add_expr(g, c, memo)).collect()),
        Node::Mul(_) => Math::Mul(kids.iter().map(|c| add_expr(g, c, memo)).collect()),
        Node::Pow(..) => Math::Pow([add_expr(g, &kids[0], memo), add_expr(g, &kids[1], memo)]),
        Node::Call(f, _) => {
            let a = add_expr(g, &kids[0], memo);
            match f {
                Func::Sin => Math::Sin(a),
                Func::Cos => Math::Cos(a),
                Func::Tan => Math::Tan(a),
                Func::Exp => Math::Exp(a),
                Func::Log => Math::Log(a),
                Func::Sinh => Math::Sinh(a),
                Func::Cosh => Math::Cosh(a),
                Func::Tanh => Math::Tanh(a),
                Func::Asin => Math::Asin(a),
                Func::Acos => Math::Acos(a),
                Func::Atan => Math::Atan(a),
                Func::Abs => Math::Abs(a),
                Func::Asinh => Math::Asinh(a),
                Func::Acosh => Math::Acosh(a),
                Func::Atanh => Math::Atanh(a),
                Func::Sec => Math::Sec(a),
                Func::Csc => Math::Csc(a),
                Func::Coth => Math::Coth(a),
                Func::Erf => Math::Erf(a),
                Func::Atan2 => Math::Atan2([a, add_expr(g, &kids[1], memo)]),
            }
        }
    };
    let id = g.add(node);
    memo.insert(e.clone(), id);
    id
}

/// A condition: the class bound to `var` is known to be positive.
fn is_positive(var: &str) -> impl Fn(&mut Graph, Id, &Subst) -> bool {
    let var: Var = var.parse().unwrap_or_else(|_| unreachable!("rule variables are literals"));
    move |egraph, _, subst| egraph[subst[var]].data.positive
}

/// A condition: the class bound to `var` is not the constant zero.
fn is_not_zero(var: &str) -> impl Fn(&mut Graph, Id, &Subst) -> bool {
    let var: Var = var.parse().unwrap_or_else(|_| unreachable!("rule variables are literals"));
    move |egraph, _, subst| egraph[subst[var]].data.constant().map_or(true, |r| !r.is_zero())
}

/// When a rule may fire.
#[derive(Clone, Copy, Debug)]
enum Cond {
    /// Always (the identity holds wherever both sides are defined).
    Always,
    /// When the class bound to `x` is known to be strictly positive.
    Positive,
    /// When the class bound to `x` is not the constant zero.
    NotZero,
}

/// The rule table: `(name, left side, right side, condition)`, both sides written in the
/// expression grammar with `x`, `y` as pattern variables. The left side is turned into a
/// pattern through the canonical constructors, so it has exactly the operand order the
/// canonical sums and products it must match have (sums and products are never reordered in
/// the e-graph). Every rule holds for all real values where both sides are defined, under its
/// condition.
#[rustfmt::skip]
const RULES: &[(&str, &str, &str, Cond)] = &[
    // exp and log: exp(log x) = x needs x > 0 (log is undefined otherwise);
    // log(exp x) = x for every real x.
    ("exp-log",        "exp(log(x))",         "x",           Cond::Positive),
    ("log-exp",        "log(exp(x))",         "x",           Cond::Always),
    ("log-square",     "log(x^2)",            "2 log(x)",    Cond::Positive),
    ("log-sqrt",       "log(sqrt(x))",        "log(x)/2",    Cond::Positive),
    ("exp-square",     "exp(x)^2",            "exp(2 x)",    Cond::Always),
    ("exp-sqrt",       "sqrt(exp(x))",        "exp(x/2)",    Cond::Always),
    ("exp-inverse",    "1/exp(x)",            "exp(-x)",     Cond::Always),
    ("exp-product",    "exp(x) exp(y)",       "exp(x + y)",  Cond::Always),
    // Quotients of sine and cosine.
    ("tan-quotient",   "sin(x)/cos(x)",       "tan(x)",      Cond::Always),
    ("tanh-quotient",  "sinh(x)/cosh(x)",     "tanh(x)",     Cond::Always),
    // Double angles, in the two-term forms canonical sums take.
    ("double-sin",     "2 sin(x) cos(x)",     "sin(2 x)",    Cond::Always),
    ("double-cos",     "cos(x)^2 - sin(x)^2", "cos(2 x)",    Cond::Always),
    ("double-cos-sin", "1 - 2 sin(x)^2",      "cos(2 x)",    Cond::Always),
    ("double-cos-cos", "2 cos(x)^2 - 1",      "cos(2 x)",    Cond::Always),
    ("double-sinh",    "2 sinh(x) cosh(x)",   "sinh(2 x)",   Cond::Always),
    ("double-cosh",    "cosh(x)^2 + sinh(x)^2", "cosh(2 x)", Cond::Always),
    // Inverse functions: f(f⁻¹(x)) = x wherever the left side is defined.
    ("sin-asin",       "sin(asin(x))",        "x",           Cond::Always),
    ("cos-acos",       "cos(acos(x))",        "x",           Cond::Always),
    ("tan-atan",       "tan(atan(x))",        "x",           Cond::Always),
    ("cos-asin",       "cos(asin(x))",        "sqrt(1 - x^2)", Cond::Always),
    ("sin-acos",       "sin(acos(x))",        "sqrt(1 - x^2)", Cond::Always),
    // Absolute values and square roots: |x| = x for x > 0; |x|^2 = x^2 is canonical already.
    ("abs-positive",   "abs(x)",              "x",           Cond::Positive),
    ("sqrt-square",    "sqrt(x^2)",           "x",           Cond::Positive),
    ("inverse-inverse", "1/(1/x)",            "x",           Cond::NotZero),
];

/// Converts a canonical expression over the pattern variables `x`, `y` into an egg pattern.
fn pattern_text(e: &Expr) -> String {
    let kids = |xs: &[Expr]| xs.iter().map(pattern_text).collect::<Vec<_>>().join(" ");
    match e.node() {
        Node::Num(r) => r.to_string(),
        Node::Sym(s) => format!("?{}", s.name()),
        Node::Add(xs) => format!("(+ {})", kids(xs)),
        Node::Mul(xs) => format!("(* {})", kids(xs)),
        Node::Pow(b, x) => format!("(^ {} {})", pattern_text(b), pattern_text(x)),
        Node::Call(f, xs) => format!("({} {})", f.name(), kids(xs)),
        Node::Pi | Node::Apply { .. } | Node::Undefined => "?unsupported".to_string(),
    }
}

fn pattern(text: &str) -> egg::Pattern<Math> {
    let e = crate::parse::parse(text).unwrap_or_else(|err| unreachable!("rule `{text}` does not parse: {err}"));
    pattern_text(&e).parse().unwrap_or_else(|err| unreachable!("rule `{text}` is not a pattern: {err}"))
}

/// The rule table, built once per process: building it parses every pattern (through the
/// expression parser and egg's s-expression reader), which costs far more than a typical small
/// simplification (tidying the 10-link pendulum's `W`, `F` simplifies dozens of short angle
/// arguments).
fn rule_set() -> &'static [egg::Rewrite<Math, Knowledge>] {
    static RULE_SET: std::sync::OnceLock<Vec<egg::Rewrite<Math, Knowledge>>> = std::sync::OnceLock::new();
    RULE_SET.get_or_init(rules)
}

/// The rewrite rules of this module's rule table, as egg rewrites.
pub fn rules() -> Vec<egg::Rewrite<Math, Knowledge>> {
    RULES
        .iter()
        .map(|(name, lhs, rhs, cond)| {
            let (l, r) = (pattern(lhs), pattern(rhs));
            let rewrite = match cond {
                Cond::Always => egg::Rewrite::new(*name, l, r),
                Cond::Positive => {
                    egg::Rewrite::new(*name, l, egg::ConditionalApplier { condition: is_positive("?x"), applier: r })
                }
                Cond::NotZero => {
                    egg::Rewrite::new(*name, l, egg::ConditionalApplier { condition: is_not_zero("?x"), applier: r })
                }
            };
            rewrite.unwrap_or_else(|err| unreachable!("rule `{name}`: {err}"))
        })
        .collect()
}

/// One e-graph run: candidates in the root class, the rule table, the root's representative.
fn egraph_round(e: &Expr, budget: &Budget) -> (Expr, StopReason) {
    let cands = candidates(e, budget);
    let mut g = Graph::new(Knowledge::default());
    let mut memo = HashMap::new();
    let root = add_expr(&mut g, e, &mut memo);
    for c in &cands[1..] {
        let id = add_expr(&mut g, c, &mut memo);
        g.union(root, id);
    }
    g.rebuild();
    let runner = Runner::default()
        .with_egraph(g)
        .with_node_limit(budget.nodes)
        .with_iter_limit(budget.iterations)
        // egg's runner has a 5 s clock by default; without the opt-in guard it must never bind.
        .with_time_limit(budget.time.unwrap_or(Duration::MAX))
        // Ctrl-C ends the search between iterations (the caller sees `interrupted()` and
        // reports it; the best form so far is still a correct result).
        .with_hook(|_| if crate::cancel::interrupted() { Err("interrupted".into()) } else { Ok(()) })
        .run(rule_set());
    let stop = match runner.stop_reason {
        Some(egg::StopReason::IterationLimit(_)) => StopReason::IterationLimit,
        Some(egg::StopReason::NodeLimit(_)) => StopReason::NodeLimit,
        Some(egg::StopReason::TimeLimit(_)) => StopReason::TimeLimit,
        // `Other` only comes from the interrupt hook above.
        Some(egg::StopReason::Other(_)) => StopReason::Interrupted,
        Some(egg::StopReason::Saturated) | None => StopReason::Saturated,
    };
    let best = runner.egraph[runner.egraph.find(root)].data.repr.clone();
    (best, stop)
}
