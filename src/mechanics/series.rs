//! Series in named small quantities (§2.4.1: the small-angle Lagrangian `L_lin` of (2.29)).
//!
//! The series of `f` to order `n` in the small quantities `x_1 … x_m` is the Taylor polynomial
//! of `f(λ x_1, …, λ x_m)` in a scaling parameter `λ`, evaluated at `λ = 1`: the term of
//! order `k` is `(1/k!) ∂ᵏ/∂λᵏ f(λ x)|_{λ=0}`, which is homogeneous of total degree `k` in the
//! `x_i`. Going through `λ` rather than expanding term by term makes the truncation consistent
//! for any analytic `f` (a product of two series keeps exactly the terms of total degree ≤ n)
//! and finds the functions that have no such series: a derivative that is undefined at
//! `λ = 0` (`1/x`, `√x`) or an `abs` of a small quantity is refused, never expanded wrongly.
//!
//! About an equilibrium `q₀` of a Lagrangian the small quantities are the displacements
//! `η = q − q₀` and the velocities: [`series_about`] substitutes `q = q₀ + η` (keeping the name
//! `q` for the displacement) and expands in `(η, η')`.

use std::collections::HashMap;

use crate::diff::Differentiator;
use crate::expr::{Expr, Node, Symbol};

use super::tidy::tidy;

/// The highest order accepted: each order is one more derivative of the whole expression.
pub const MAX_SERIES_ORDER: usize = 12;

/// Why a series was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SeriesError {
    /// The expression has no Taylor series at 0 in the small quantities.
    #[error("error: {expr} has no power series in {small} about 0: its {what}; expand about another point or in other small quantities")]
    NotAnalytic {
        /// The expression.
        expr: String,
        /// The small quantities.
        small: String,
        /// What failed, e.g. "derivative of order 1 is undefined at 0".
        what: String,
    },
    /// `order` above [`MAX_SERIES_ORDER`].
    #[error(
        "error: order {order} is above the limit {limit}: each order differentiates the whole expression once more"
    )]
    OrderTooHigh {
        /// Asked.
        order: usize,
        /// Allowed.
        limit: usize,
    },
    /// No small quantities were named.
    #[error("error: no small quantities given (name at least one, e.g. --in x)")]
    NoSmallQuantities,
    /// A small quantity is the time or a number.
    #[error("error: `{0}` cannot be a small quantity (expected a variable name)")]
    BadSmallQuantity(String),
}

/// The terms of the series of `e` to order `order` in `small`: entry `k` is the part of total
/// degree `k` (tidied), for `k = 0 ..= order`.
pub fn series_terms(e: &Expr, small: &[Symbol], order: usize) -> Result<Vec<Expr>, SeriesError> {
    if small.is_empty() {
        return Err(SeriesError::NoSmallQuantities);
    }
    if order > MAX_SERIES_ORDER {
        return Err(SeriesError::OrderTooHigh { order, limit: MAX_SERIES_ORDER });
    }
    let names = || small.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", ");
    let refuse = |what: String| SeriesError::NotAnalytic { expr: e.to_string(), small: names(), what };
    let lambda = fresh_symbol(e, "λ_series");
    let l = Expr::sym(lambda.clone());
    let scaled: HashMap<Symbol, Expr> = small.iter().map(|s| (s.clone(), l.times(&Expr::sym(s.clone())))).collect();
    let mut cur = e.subs(&scaled);
    if let Some(bad) = non_smooth_in(&cur, &lambda) {
        let bad = bad.subs1(&lambda, &Expr::one());
        return Err(refuse(format!("factor {bad} is not differentiable where the small quantities vanish")));
    }
    let mut d = Differentiator::new();
    let mut out = Vec::with_capacity(order + 1);
    let mut factorial = crate::expr::Rational::from_integer(1.into());
    for k in 0..=order {
        if k > 0 {
            cur = d.diff(&cur, &lambda);
            factorial *= crate::expr::Rational::from_integer(k.into());
        }
        let at0 = cur.subs1(&lambda, &Expr::zero());
        if contains_undefined(&at0) {
            return Err(refuse(if k == 0 {
                "value is undefined there".to_string()
            } else {
                format!("derivative of order {k} is undefined there")
            }));
        }
        // Expanded: a term of a series reads as its monomials (`l² m θ'²/2 − g l m θ²/2`).
        let term = at0.times(&Expr::num(factorial.recip()));
        out.push(crate::algebra::expand(&term).unwrap_or_else(|_| tidy(&term)));
    }
    Ok(out)
}

/// The series of `e` to order `order` in the small quantities `small`: the sum of
/// [`series_terms`], each order tidied on its own (tidying the sum would nest the orders
/// into one another, Horner-like).
pub fn series(e: &Expr, small: &[Symbol], order: usize) -> Result<Expr, SeriesError> {
    let terms = series_terms(e, small, order)?;
    Ok(Expr::add(terms))
}

/// The series of a Lagrangian `l` about the point `q = q₀` (`about`: one value per coordinate)
/// to order `order` in the displacements and the velocities. The displacement from `q₀` keeps
/// the coordinate's name (`q` stands for `q − q₀` in the result). Returns the series and the
/// terms of each order.
pub fn series_about(
    l: &Expr,
    coords: &[Symbol],
    about: &[Expr],
    order: usize,
) -> Result<(Expr, Vec<Expr>), SeriesError> {
    // Through fresh names, so that no substituted `q₀ + q` is substituted again.
    let fresh: Vec<Symbol> = coords.iter().map(|q| fresh_symbol(l, &format!("{}_shift", q.name()))).collect();
    let shift: HashMap<Symbol, Expr> =
        coords.iter().zip(about).zip(&fresh).map(|((q, q0), f)| (q.clone(), q0.plus(&Expr::sym(f.clone())))).collect();
    let back: HashMap<Symbol, Expr> =
        fresh.iter().zip(coords).map(|(f, q)| (f.clone(), Expr::sym(q.clone()))).collect();
    let shifted = l.subs(&shift).subs(&back);
    let mut small: Vec<Symbol> = coords.to_vec();
    small.extend(coords.iter().map(Symbol::prime));
    let terms = series_terms(&shifted, &small, order)?;
    Ok((Expr::add(terms.clone()), terms))
}

/// A symbol named `base` (with `_` appended until it is) not occurring in `e`.
fn fresh_symbol(e: &Expr, base: &str) -> Symbol {
    let used = e.free_symbols();
    let mut name = base.to_string();
    while used.iter().any(|s| s.name() == name) {
        name.push('_');
    }
    Symbol::new(&name)
}

/// Whether `e` holds the undefined value anywhere.
fn contains_undefined(e: &Expr) -> bool {
    if e.is_undefined() {
        return true;
    }
    let mut found = false;
    e.for_each_child(|c| found = found || contains_undefined(c));
    found
}

/// An `abs(…)` (or a power of one) whose argument vanishes with `λ`: `|λ x|` has no Taylor
/// series at `λ = 0`, although its formal derivatives at 0 look harmless (`sign(0)·x`).
fn non_smooth_in(e: &Expr, lambda: &Symbol) -> Option<Expr> {
    if let Node::Call(crate::expr::Func::Abs, args) = e.node() {
        if args[0].contains(lambda) && args[0].subs1(lambda, &Expr::zero()).is_zero() {
            return Some(e.clone());
        }
    }
    let mut found = None;
    e.for_each_child(|c| {
        if found.is_none() {
            found = non_smooth_in(c, lambda);
        }
    });
    found
}

/// The Jacobian matrix `∂x_i/∂y_j` of a map of coordinates `x_i(y)` (§1.3: `x(r₀, t)` of the
/// ideal fluid, whose determinant `J` is the volume ratio), each entry tidied, and its
/// determinant. `None` when the map does not have as many components as variables.
pub fn jacobian(map: &[Expr], vars: &[Symbol]) -> Option<(Vec<Vec<Expr>>, Expr)> {
    if map.len() != vars.len() || map.is_empty() {
        return None;
    }
    let mut d = Differentiator::new();
    let m: Vec<Vec<Expr>> = map.iter().map(|x| vars.iter().map(|y| tidy(&d.diff(x, y))).collect()).collect();
    let det = tidy(&crate::simplify::simplify(&super::linalg::determinant(&m)));
    Some((m, det))
}
