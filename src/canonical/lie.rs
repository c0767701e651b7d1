//! Lie series (PHYSICS.md §4.4.2): `exp(ε {·, G}) f = Σ_k ε^k/k! {…{f, G}, …, G}`, and the flow
//! of an autonomous `H` as the Lie series with `G = H`, `ε = t`: the Taylor expansion of
//! `f(q(t), p(t))` in `t`, because `df/dt = {f, H}`.

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::poisson::poisson_raw;
use super::reduce::normalize;
use super::{time, PhaseSpace};

/// The terms `ad_G^k f / k!` for `k = 0 ..= order`, with `ad_G f = {f, G}`, in normal form.
pub fn lie_terms(f: &Expr, g: &Expr, order: usize, ps: &PhaseSpace) -> Vec<Expr> {
    let mut d = Differentiator::new();
    let mut out = vec![f.clone()];
    let mut cur = f.clone();
    for k in 1..=order {
        cur = normalize(&poisson_raw(&cur, g, ps, &mut d));
        let k = i64::try_from(k).unwrap_or(i64::MAX);
        out.push(normalize(&cur.times(&Expr::num(factorial_inv(k)))));
        if cur.is_zero() {
            break;
        }
    }
    // `cur` accumulates without the 1/k!; the terms carry it.
    out
}

fn factorial_inv(k: i64) -> crate::expr::Rational {
    let mut f = crate::expr::Rational::from_integer(1.into());
    for i in 1..=k {
        f *= crate::expr::Rational::from_integer(i.into());
    }
    f.recip()
}

/// The highest order the command line and scenes accept: each order nests one more bracket.
pub const MAX_ORDER: usize = 40;

/// `exp(ε {·, G}) f` truncated after `ε^order`.
///
/// When `f` or `G` contains `ε` itself (a perturbed Hamiltonian `H₀ + ε H₁`, a generator
/// `ε G₁ + ε² G₂`), the k-th bracket term is not purely of order `ε^k`: cutting the sum after
/// `k = order` would keep part of the higher powers (the bracket of an `ε`-term of `f` with
/// `G` lands at `ε²` next to the `ε²` term of the next bracket, which is cut). The sum is then
/// truncated consistently: expanded in powers of `ε` and cut after `ε^order`, which is exact
/// to that order when `f` and `G` have power series in `ε`. When one of them has none (a
/// `1/ε` in `G`), `exp(ε{·,G})` is no power series in `ε` and the sum of the first
/// `order + 1` bracket terms is returned as it is.
pub fn lie_series(f: &Expr, g: &Expr, epsilon: &Symbol, order: usize, ps: &PhaseSpace) -> Expr {
    let eps = Expr::sym(epsilon.clone());
    let terms = lie_terms(f, g, order, ps);
    let sum = Expr::add(terms.into_iter().enumerate().map(|(k, t)| t.times(&eps.powi(k as i64))));
    if !(f.contains(epsilon) || g.contains(epsilon)) {
        return sum;
    }
    match crate::mechanics::series_terms(&sum, std::slice::from_ref(epsilon), order) {
        Ok(parts) => Expr::add(
            parts
                .into_iter()
                .enumerate()
                .map(|(k, t)| normalize(&t.times(&eps.powi(-(k as i64)))).times(&eps.powi(k as i64))),
        ),
        Err(_) => sum,
    }
}

/// The flow of an autonomous `h` applied to `f`, as a series in `t` up to `t^order`.
///
/// Refuses a Hamiltonian that depends on `t` explicitly (its flow is not `exp(t {·, H})`).
pub fn lie_flow(f: &Expr, h: &Expr, order: usize, ps: &PhaseSpace) -> Result<Expr, LieError> {
    if h.contains(&time()) || f.contains(&time()) {
        return Err(LieError::TimeDependent);
    }
    Ok(lie_series(f, h, &time(), order, ps))
}

/// Why a Lie series was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LieError {
    /// The flow of a time-dependent Hamiltonian is not a single Lie series.
    #[error("the flow as a Lie series exp(t{{·,H}}) needs an autonomous H and f; this one depends on t explicitly")]
    TimeDependent,
}
