//! Poisson brackets (PHYSICS.md §4.4): `{f, g} = Σ_i (∂f/∂q_i ∂g/∂p_i − ∂f/∂p_i ∂g/∂q_i)`.

use crate::diff::Differentiator;
use crate::expr::Expr;

use super::reduce::{decide_zero, ZeroCheck};
use super::{simplified, time, PhaseSpace};

/// The Poisson bracket `{f, g}` over `ps`, in normal form.
pub fn poisson(f: &Expr, g: &Expr, ps: &PhaseSpace) -> Expr {
    simplified(&poisson_raw(f, g, ps, &mut Differentiator::new()))
}

/// The bracket without normalisation (the Lie series normalises once per order instead).
pub(crate) fn poisson_raw(f: &Expr, g: &Expr, ps: &PhaseSpace, d: &mut Differentiator) -> Expr {
    let mut terms = Vec::with_capacity(2 * ps.dof());
    for (q, p) in ps.pairs() {
        terms.push(d.diff(f, q).times(&d.diff(g, p)));
        terms.push(d.diff(f, p).times(&d.diff(g, q)).neg());
    }
    Expr::add(terms)
}

/// `df/dt = {f, H} + ∂f/∂t` along the flow of `h`.
pub fn time_derivative(f: &Expr, h: &Expr, ps: &PhaseSpace) -> Expr {
    let mut d = Differentiator::new();
    let raw = poisson_raw(f, h, ps, &mut d).plus(&d.diff(f, &time()));
    simplified(&raw)
}

/// Whether `f` is an integral of motion of `h`: `{f, H} + ∂f/∂t = 0`, proven or (if
/// simplification cannot decide) checked numerically, as the [`ZeroCheck`] says.
///
/// Poisson's theorem follows: if `f` and `g` are integrals, `is_integral(&poisson(f, g), h)`
/// holds too (tested in `tests/it/canonical/poisson.rs`).
pub fn is_integral(f: &Expr, h: &Expr, ps: &PhaseSpace) -> ZeroCheck {
    let mut d = Differentiator::new();
    decide_zero(&poisson_raw(f, h, ps, &mut d).plus(&d.diff(f, &time())))
}
