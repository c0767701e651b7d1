//! Differentiation: partial derivatives by a symbol and the total time derivative.
//!
//! Both are memoised per (node, variable) in a [`Differentiator`], so a DAG with shared
//! subexpressions is differentiated once per distinct node, and repeated derivatives of the
//! same Lagrangian (all the `∂L/∂q'_i`, then their `∂/∂q'_j`) reuse each other's work.

use std::collections::{BTreeSet, HashMap};
use std::sync::OnceLock;

use crate::expr::{Expr, Func, Node, Symbol};
use crate::func::SPECS;
use crate::parse::parse;

/// `f'(u)` for a built-in of one argument, from its row of the function table ([`SPECS`]):
/// the row's text is parsed once, in the argument `u`, and `u` replaced by the argument.
/// Undefined for a function without a derivative there (`atan2`, handled by its gradient).
fn outer_derivative(f: Func, u: &Expr) -> Expr {
    static PARSED: OnceLock<Vec<Option<Expr>>> = OnceLock::new();
    let parsed = PARSED.get_or_init(|| {
        // Every row parses (`func`'s tests); a row that did not would be undefined, not a panic.
        SPECS.iter().map(|spec| spec.derivative.map(|text| parse(text).unwrap_or_else(|_| Expr::undefined()))).collect()
    });
    match &parsed[f as usize] {
        Some(outer) => outer.subs1(&Symbol::new("u"), u),
        None => Expr::undefined(),
    }
}

/// A memo table for derivatives. Keep one alive across many derivatives of related
/// expressions to share work.
#[derive(Default)]
pub struct Differentiator {
    memo: HashMap<(Expr, Symbol), Expr>,
    /// Calls of [`Differentiator::diff`] in progress (it recurses through itself).
    depth: usize,
    /// Inside [`Differentiator::try_diff`]: the recursion polls the cancellation token.
    polling: bool,
    /// The token was found set: the derivative being formed is abandoned (nothing finished
    /// after this is memoised, so the table keeps only complete, correct derivatives).
    stopped: bool,
}

/// The memo entries a [`Differentiator`] keeps at most between outermost calls. A REPL's or a
/// kernel's session keeps one for its whole life, and each entry holds its nodes alive; past
/// this many the table starts afresh (only ever between derivatives, never during one, so a
/// DAG's sharing is kept within each).
#[doc(hidden)]
pub const MAX_MEMO: usize = 1 << 16;

impl Differentiator {
    /// An empty memo table.
    pub fn new() -> Differentiator {
        Differentiator::default()
    }

    /// Entries in the memo table and calls in progress, for the tests of its bound.
    #[doc(hidden)]
    pub fn memo_and_depth(&self) -> (usize, usize) {
        (self.memo.len(), self.depth)
    }

    /// `∂e/∂var`, treating every other symbol as independent of `var`.
    pub fn diff(&mut self, e: &Expr, var: &Symbol) -> Expr {
        let key = (e.clone(), var.clone());
        if let Some(d) = self.memo.get(&key) {
            return d.clone();
        }
        if self.depth == 0 && self.memo.len() > MAX_MEMO {
            self.memo.clear();
        }
        if self.polling && (self.stopped || crate::cancel::poll().is_err()) {
            self.stopped = true;
            return Expr::zero();
        }
        self.depth += 1;
        let d = self.diff_node(e, var);
        self.depth -= 1;
        if !self.stopped {
            self.memo.insert(key, d.clone());
        }
        d
    }

    /// [`Differentiator::diff`] that polls the cancellation token ([`crate::cancel::poll`],
    /// so also a [`crate::cancel::with_token`] token) every few nodes and returns
    /// `Interrupted` once it is set: a derivative of a huge expression is one step that
    /// would otherwise run to its end. The memo keeps what was finished before the stop.
    pub fn try_diff(&mut self, e: &Expr, var: &Symbol) -> Result<Expr, crate::cancel::Interrupted> {
        let outer = !self.polling;
        self.polling = true;
        let d = self.diff(e, var);
        if outer {
            self.polling = false;
        }
        if self.stopped {
            if outer {
                self.stopped = false;
            }
            return Err(crate::cancel::Interrupted);
        }
        Ok(d)
    }

    fn diff_node(&mut self, e: &Expr, var: &Symbol) -> Expr {
        match e.node() {
            Node::Num(_) | Node::Pi => Expr::zero(),
            Node::Undefined => Expr::undefined(),
            Node::Sym(s) => {
                if s == var {
                    Expr::one()
                } else {
                    Expr::zero()
                }
            }
            Node::Add(ts) => Expr::add(ts.iter().map(|t| self.diff(t, var))),
            Node::Mul(fs) => {
                let mut terms = Vec::new();
                for i in 0..fs.len() {
                    let d = self.diff(&fs[i], var);
                    if d.is_zero() {
                        continue;
                    }
                    let mut prod: Vec<Expr> = Vec::with_capacity(fs.len());
                    prod.extend(fs[..i].iter().cloned());
                    prod.push(d);
                    prod.extend(fs[i + 1..].iter().cloned());
                    terms.push(Expr::mul(prod));
                }
                Expr::add(terms)
            }
            Node::Pow(b, x) => {
                let db = self.diff(b, var);
                let dx = self.diff(x, var);
                let mut terms = Vec::new();
                if !db.is_zero() {
                    // x b^(x-1) b'
                    terms.push(Expr::mul([x.clone(), Expr::pow(b.clone(), x.minus(&Expr::one())), db]));
                }
                if !dx.is_zero() {
                    // b^x log(b) x'
                    terms.push(Expr::mul([e.clone(), Expr::call(Func::Log, vec![b.clone()]), dx]));
                }
                Expr::add(terms)
            }
            Node::Call(f, args) => self.diff_call(*f, args, var),
            Node::Apply { name, orders, args } => {
                let mut terms = Vec::new();
                for (i, a) in args.iter().enumerate() {
                    let da = self.diff(a, var);
                    if da.is_zero() {
                        continue;
                    }
                    let mut o = orders.clone();
                    o[i] += 1;
                    terms.push(Expr::apply(name, o, args.clone()).times(&da));
                }
                Expr::add(terms)
            }
        }
    }

    fn diff_call(&mut self, f: Func, args: &[Expr], var: &Symbol) -> Expr {
        let u = &args[0];
        if f == Func::Atan2 {
            // atan2(y, x)' = (x y' − y x') / (x² + y²)
            let (y, x) = (&args[0], &args[1]);
            let dy = self.diff(y, var);
            let dx = self.diff(x, var);
            if dy.is_zero() && dx.is_zero() {
                return Expr::zero();
            }
            let num = x.times(&dy).minus(&y.times(&dx));
            return num.over(&x.powi(2).plus(&y.powi(2)));
        }
        let du = self.diff(u, var);
        if du.is_zero() {
            return Expr::zero();
        }
        outer_derivative(f, u).times(&du)
    }

    /// The total time derivative
    /// `d/dt F = ∂F/∂t + Σ_s s' ∂F/∂s` over every time-dependent symbol `s` in `F`.
    ///
    /// A symbol depends on time when its base name is in `coordinates` or when it carries a
    /// prime (then its base must be a function of time too). Other symbols are constants.
    pub fn dt(&mut self, e: &Expr, coordinates: &BTreeSet<String>) -> Expr {
        let syms = e.free_symbols();
        let mut terms = Vec::new();
        for s in &syms {
            if s.is_time() {
                terms.push(self.diff(e, s));
            } else if s.primes() > 0 || coordinates.contains(s.name()) {
                let d = self.diff(e, s);
                if !d.is_zero() {
                    terms.push(Expr::sym(s.prime()).times(&d));
                }
            }
        }
        Expr::add(terms)
    }
}

/// `∂e/∂var` with a fresh memo table.
pub fn diff(e: &Expr, var: &Symbol) -> Expr {
    Differentiator::new().diff(e, var)
}

/// `∂e/∂var` with a fresh memo table, interruptible ([`Differentiator::try_diff`]).
pub fn try_diff(e: &Expr, var: &Symbol) -> Result<Expr, crate::cancel::Interrupted> {
    Differentiator::new().try_diff(e, var)
}

/// The names of all symbols in `e` that depend on time by the rule of [`Differentiator::dt`]
/// with no declared coordinates: those that appear with a prime somewhere in `e`.
pub fn primed_names(e: &Expr) -> BTreeSet<String> {
    e.free_symbols().into_iter().filter(|s| s.primes() > 0).map(|s| s.name().to_string()).collect()
}

/// `d/dt e`, where the time-dependent symbols are those that appear primed in `e` plus
/// `coordinates`.
pub fn dt(e: &Expr, coordinates: &BTreeSet<String>) -> Expr {
    let mut all = primed_names(e);
    all.extend(coordinates.iter().cloned());
    Differentiator::new().dt(e, &all)
}
