//! Compact printed forms for the results of a transformation: `K`, and the maps both ways.
//!
//! [`normalize`](super::reduce::normalize) expands, which is right for deciding zero but leaves
//! a Hamiltonian such as the adiabatic oscillator's `K` as four terms over one denominator,
//! `(2 P t ε ω0 + P t² ε² ω0 + P ε sin Q cos Q + P ω0)/(t ε + 1)`, where the polynomial part
//! cancels to `P ω0 (t ε + 1)`. [`compact`] groups the terms of a sum by denominator, splits
//! each numerator by the factors that do not involve the denominator's symbols, cancels each
//! part against the denominator ([`crate::algebra::cancel`]) and pulls common content out of
//! what is left. It keeps the shorter of its result and the input (by operation count), so it
//! never makes an expression longer, and it only regroups exact terms, so the value is the
//! same expression.

use std::collections::BTreeSet;

use crate::algebra::{cancel, factor_content, numer_denom};
use crate::expr::{Expr, Symbol};

use super::reduce::expand;

/// A sum with each group of terms over one denominator cancelled; the shorter of that and `e`.
pub fn compact(e: &Expr) -> Expr {
    let expanded = expand(e);
    // Terms grouped by denominator, in the order of first appearance (deterministic: the
    // terms of a canonical sum are sorted).
    let mut groups: Vec<(Expr, Vec<Expr>)> = Vec::new();
    for t in expanded.terms() {
        let (n, d) = numer_denom(&t);
        match groups.iter_mut().find(|(g, _)| *g == d) {
            Some((_, ns)) => ns.push(n),
            None => groups.push((d, vec![n])),
        }
    }
    let mut out = Vec::new();
    for (d, ns) in groups {
        if d.as_num().is_some() {
            out.push(Expr::add(ns).over(&d));
            continue;
        }
        let dsyms: BTreeSet<Symbol> = d.free_symbols();
        // numerator = Σ outer_k · inner_k, with `outer_k` free of the denominator's symbols.
        let mut parts: Vec<(Expr, Vec<Expr>)> = Vec::new();
        for n in ns {
            for term in expand(&n).terms() {
                let (c, rest) = term.coeff_rest();
                let (mut outer, mut inner) = (Vec::new(), vec![Expr::num(c)]);
                for f in rest.factors() {
                    if f.free_symbols().iter().any(|s| dsyms.contains(s)) {
                        inner.push(f);
                    } else {
                        outer.push(f);
                    }
                }
                let key = Expr::mul(outer);
                match parts.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, v)) => v.push(Expr::mul(inner)),
                    None => parts.push((key, vec![Expr::mul(inner)])),
                }
            }
        }
        for (outer, inner) in parts {
            let q = cancel(&Expr::add(inner).over(&d));
            out.push(outer.times(&factor_content(&q)));
        }
    }
    let candidate = factor_content(&Expr::add(out));
    if candidate.op_count() < e.op_count() {
        candidate
    } else {
        e.clone()
    }
}
