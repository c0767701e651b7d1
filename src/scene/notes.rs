//! Scene-side rules for first-order (phase-space) Lagrangians `L = Σ a_i(z, t) z'_i − H(z, t)`
//! (§3.4): which `L` takes that route in `simulate`, and what its initial state and events
//! may mention. The equations are `mechanics::FirstOrder`'s; the session only routes.
//! Also the `variational` simulate methods (§4.7.2): which rule each names, the compiled
//! map, and what such a run refuses.

use std::collections::HashMap;

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use crate::mechanics::{Rule, System};

use super::ast::SimSpec;
use super::backend::BackendError;
use super::error::{ErrorKind, SceneError, Span};

/// Whether `L` is linear in every velocity of `coords` (every `∂L/∂q'_i` is free of
/// velocities, read off the canonical form without expanding), so that `simulate`
/// integrates `ω z' = ∂H/∂z + ∂a/∂t` instead of `W q'' = F` with `W ≡ 0`.
pub(super) fn is_first_order(l: &Expr, coords: &[Symbol]) -> bool {
    let velocities: Vec<Symbol> = coords.iter().map(Symbol::prime).collect();
    let free = l.free_symbols();
    if !velocities.iter().any(|v| free.contains(v)) {
        return false;
    }
    let mut d = Differentiator::new();
    velocities.iter().all(|v| {
        let a = d.diff(l, v).free_symbols();
        !velocities.iter().any(|w| a.contains(w))
    })
}

/// The state of a first-order Lagrangian is `z` alone: its velocities follow from
/// `ω z' = b` and are not initial data, and there are no momenta `p_z`.
pub(super) fn check_first_order_inits(
    coords: &[Symbol],
    given: &HashMap<String, (f64, Span)>,
) -> Result<(), SceneError> {
    for q in coords {
        for name in [format!("{}'", q.name()), format!("p_{}", q.name())] {
            if let Some((_, span)) = given.get(&name) {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    format!(
                        "`L` is first order in the velocities, so its state is {} alone: `{name}` is not initial data",
                        coords.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
                    ),
                )
                .at(*span)
                .hint(format!("remove `{name} = …`; the velocities follow from ω z' = ∂H/∂z")));
            }
        }
    }
    Ok(())
}

/// Events of a first-order run are functions of `z` and `t` (the velocity slots are filled
/// only at the kept states, not inside a step).
pub(super) fn check_first_order_event(e: &Expr, span: Span) -> Result<(), SceneError> {
    if let Some(v) = e.free_symbols().into_iter().find(|s| s.primes() > 0) {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("an event of a first-order Lagrangian's run must not use the velocity `{v}`"),
        )
        .at(span)
        .hint("write the event in the phase-space variables z and t"));
    }
    Ok(())
}

/// The discrete-mechanics rule a `variational…` method names.
pub(super) fn variational_rule(method: &str) -> Rule {
    match method {
        "variational_trapezoid" => Rule::Trapezoid,
        "variational_gauss2" => Rule::Gauss2,
        _ => Rule::Midpoint,
    }
}

/// Builds the variational map of `L` for a `variational…` method (§4.7.2: the discrete
/// Lagrangian's map as an integrator). The step is an input of the compiled map, so one
/// compilation serves every `dt`; the placeholder bound here is never stepped with.
pub(super) fn variational_map(
    l: &Expr,
    coords: &[Symbol],
    method: &str,
    params: &[(&str, f64)],
) -> Result<(crate::compile::VariationalMap, u32), BackendError> {
    let failed = |e: String| BackendError::Failed(e);
    let rule = variational_rule(method);
    let system = System::from_lagrangian_expr(l.clone(), coords).map_err(|e| failed(e.to_string()))?;
    let step = "h__variational";
    let d = system.discretize(rule, &Expr::var(step)).map_err(|e| failed(e.to_string()))?;
    let mut bound: Vec<(&str, f64)> = params.to_vec();
    bound.push((step, 1.0));
    let map = crate::compile::VariationalMap::new(&d, &bound).map_err(|e| failed(e.to_string()))?;
    Ok((map, rule.order()))
}

/// A `variational` run needs `L` and takes no events (the map has no continuous rate to
/// locate a crossing inside a step).
pub(super) fn check_variational_run(method: &str, spec: &SimSpec, has_l: bool, span: Span) -> Result<(), SceneError> {
    if let Some(ev) = spec.events.first() {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("`{method}` steps a discrete map and cannot locate events inside a step"),
        )
        .at(ev.span)
        .hint("drop the `record`/`stop` clause, or use `gauss4` or `dop853` for the event"));
    }
    if !has_l {
        return Err(SceneError::new(
            ErrorKind::Undeclared,
            format!("`{method}` discretizes the Lagrangian, and no `L` is defined"),
        )
        .at(span)
        .hint("define `L = …` first"));
    }
    Ok(())
}

/// `variational` with forces, dissipation or constraints.
pub(super) fn variational_dynamics_error(method: &str, spec: &SimSpec, span: Span) -> SceneError {
    SceneError::new(
        ErrorKind::Derivation,
        format!("`{method}` discretizes a Lagrangian alone; forces, dissipation and constraints are not part of L_d"),
    )
    .at(spec.method.as_ref().map_or(span, |m| m.span))
    .hint("use `dop853`, `rk4` or `gauss6`, which integrate the equations of motion with them")
}

/// `variational` with a first-order `L` (its discrete Legendre map is degenerate).
pub(super) fn variational_first_order_error(method: &str, spec: &SimSpec, span: Span) -> SceneError {
    SceneError::new(
        ErrorKind::Derivation,
        format!("`{method}` needs a regular L: this L is first order in the velocities, so its discrete Legendre map has no inverse"),
    )
    .at(spec.method.as_ref().map_or(span, |m| m.span))
    .hint("use `dop853` or `gauss6`, which integrate ω z' = ∂H/∂z")
}
